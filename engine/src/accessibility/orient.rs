//! The part's triangles with every shell turned outward (its signed volume positive), so
//! that a triangle facing the tool axis is one where a line along the axis leaves the
//! material. Seen along the axis, a closed shell clipped above the section covers exactly
//! what its faces facing the axis cover (a line through it leaves it last through one of
//! them; it may enter through the cut, which is no face), so only those are projected:
//! about half the triangles, the same walls. A void's shell turned outward adds faces that
//! lie inside what the outer shell covers: it changes nothing.

/// The triangles, shells (vertex-connected pieces) with a negative volume reversed.
pub fn outward(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    // Union-find over vertices.
    let mut parent: Vec<u32> = (0..vertices.len() as u32).collect();
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            let up = parent[parent[a as usize] as usize];
            parent[a as usize] = up;
            a = up;
        }
        a
    }
    for t in triangles {
        for k in 1..3 {
            let (a, b) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    // Six times each shell's signed volume (about the first vertex: well conditioned).
    let o = vertices.first().copied().unwrap_or([0.0; 3]);
    let mut volume = vec![0.0f64; vertices.len()];
    let roots: Vec<u32> = triangles
        .iter()
        .map(|t| {
            let r = find(&mut parent, t[0]);
            let [a, b, c] = t.map(|i| {
                let v = vertices[i as usize];
                [v[0] - o[0], v[1] - o[1], v[2] - o[2]]
            });
            volume[r as usize] += a[0] * (b[1] * c[2] - b[2] * c[1])
                - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            r
        })
        .collect();
    triangles
        .iter()
        .zip(roots)
        .map(|(t, r)| {
            if volume[r as usize] < 0.0 {
                [t[0], t[2], t[1]]
            } else {
                *t
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_inward_shell_is_turned_and_an_outward_one_kept() {
        // Two unit tetrahedra, the second listed inside out.
        let v = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [5.0, 0.0, 0.0],
            [6.0, 0.0, 0.0],
            [5.0, 1.0, 0.0],
            [5.0, 0.0, 1.0],
        ];
        let out = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        let inward: Vec<[u32; 3]> = out
            .iter()
            .map(|t| [t[0] + 4, t[1] + 4, t[2] + 4])
            .map(|t| [t[0], t[2], t[1]])
            .collect();
        let mut all = out.to_vec();
        all.extend(&inward);
        let got = outward(&v, &all);
        assert_eq!(&got[..4], &out);
        for (g, t) in got[4..].iter().zip(&out) {
            assert_eq!(*g, [t[0] + 4, t[1] + 4, t[2] + 4]);
        }
    }
}
