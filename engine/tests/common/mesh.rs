//! Meshes the tests build by hand.

/// A closed, outward-oriented box mesh.
pub fn box_mesh(lo: [f64; 3], hi: [f64; 3]) -> millsim_engine::geometry::Mesh {
    let v = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut triangles = Vec::new();
    for q in quads {
        triangles.push([q[0], q[1], q[2]]);
        triangles.push([q[0], q[2], q[3]]);
    }
    let mesh = millsim_engine::geometry::Mesh {
        vertices: (0..8).map(v).collect(),
        triangles,
    };
    assert!(mesh.volume() > 0.0, "outward orientation");
    mesh
}

/// The triangles of [`box_mesh`] from `lo` with sides `size`, as an STL gives them (corners
/// in float32).
pub fn box_triangles(lo: [f32; 3], size: [f32; 3]) -> Vec<[[f32; 3]; 3]> {
    let lo64 = lo.map(f64::from);
    let hi = [0, 1, 2].map(|a| lo64[a] + f64::from(size[a]));
    let mesh = box_mesh(lo64, hi);
    mesh.triangles
        .iter()
        .map(|t| t.map(|i| mesh.vertices[i as usize].map(|c| c as f32)))
        .collect()
}

/// A binary STL of triangles given by their corners (zero normals and attributes).
pub fn binary_stl(tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(tris.len() as u32).to_le_bytes());
    for t in tris {
        b.extend_from_slice(&[0u8; 12]);
        for c in t.iter().flatten() {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}
