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
