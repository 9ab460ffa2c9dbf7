//! Export of the stock as a closed triangle mesh (binary STL).
//!
//! Method: the Z dexels are sampled at the cell centres into voxels (a cell is material
//! when its centre lies in a material interval of its Z ray), and the boundary faces
//! between material and empty cells become two triangles each. Every vertex is a grid
//! corner computed the same way on both sides of a face, so the mesh is closed
//! (watertight); its volume is the voxel volume, within a cell layer of the dexel volume.

use std::io::Write;

use super::stock::Stock;
use super::GeometryError;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExportStats {
    pub triangles: u64,
    /// Volume enclosed by the exported mesh, mm³.
    pub volume: f64,
}

/// Writes the stock as a binary STL.
pub fn export_stl<W: Write>(stock: &Stock, out: &mut W) -> Result<ExportStats, GeometryError> {
    let g = &stock.grid;
    let [nx, ny, nz] = g.n;
    let words = nz.div_ceil(64);
    // Voxel columns as bit sets.
    let mut cols = vec![0u64; nx * ny * words];
    let fam = &g.families[2];
    for j in 0..ny {
        for i in 0..nx {
            let col = &mut cols[(i + nx * j) * words..(i + nx * j + 1) * words];
            for iv in fam.rays[i + fam.nu * j].iter() {
                let k0 = ((iv[0] - g.origin[2]) / g.cell - 0.5).ceil().max(0.0) as usize;
                let k1 = ((iv[1] - g.origin[2]) / g.cell - 0.5).floor();
                if k1 < 0.0 {
                    continue;
                }
                let k1 = (k1 as usize).min(nz - 1);
                for k in k0..=k1 {
                    col[k / 64] |= 1 << (k % 64);
                }
            }
        }
    }
    let bit = |i: isize, j: isize, k: isize| -> bool {
        if i < 0 || j < 0 || k < 0 || i >= nx as isize || j >= ny as isize || k >= nz as isize {
            return false;
        }
        let (i, j, k) = (i as usize, j as usize, k as usize);
        cols[(i + nx * j) * words + k / 64] >> (k % 64) & 1 == 1
    };
    let corner = |i: isize, j: isize, k: isize| -> [f32; 3] {
        [
            (g.origin[0] + i as f64 * g.cell) as f32,
            (g.origin[1] + j as f64 * g.cell) as f32,
            (g.origin[2] + k as f64 * g.cell) as f32,
        ]
    };
    let mut body: Vec<u8> = Vec::new();
    let mut count: u64 = 0;
    let mut emit = |n: [f32; 3], q: [[f32; 3]; 4], body: &mut Vec<u8>| {
        for tri in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            for c in n {
                body.extend_from_slice(&c.to_le_bytes());
            }
            for v in tri {
                for c in v {
                    body.extend_from_slice(&c.to_le_bytes());
                }
            }
            body.extend_from_slice(&[0, 0]);
            count += 1;
        }
    };
    let cell_vol = g.cell * g.cell * g.cell;
    let mut voxels: u64 = 0;
    for k in 0..nz as isize {
        for j in 0..ny as isize {
            for i in 0..nx as isize {
                if !bit(i, j, k) {
                    continue;
                }
                voxels += 1;
                let c = |di: isize, dj: isize, dk: isize| corner(i + di, j + dj, k + dk);
                // Quads wound counter-clockwise seen from outside.
                if !bit(i - 1, j, k) {
                    emit(
                        [-1.0, 0.0, 0.0],
                        [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)],
                        &mut body,
                    );
                }
                if !bit(i + 1, j, k) {
                    emit(
                        [1.0, 0.0, 0.0],
                        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)],
                        &mut body,
                    );
                }
                if !bit(i, j - 1, k) {
                    emit(
                        [0.0, -1.0, 0.0],
                        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)],
                        &mut body,
                    );
                }
                if !bit(i, j + 1, k) {
                    emit(
                        [0.0, 1.0, 0.0],
                        [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)],
                        &mut body,
                    );
                }
                if !bit(i, j, k - 1) {
                    emit(
                        [0.0, 0.0, -1.0],
                        [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)],
                        &mut body,
                    );
                }
                if !bit(i, j, k + 1) {
                    emit(
                        [0.0, 0.0, 1.0],
                        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)],
                        &mut body,
                    );
                }
            }
        }
    }
    let mut header = [0u8; 80];
    let title = b"millsim stock (voxel boundary of the tri-dexel grid)";
    header[..title.len()].copy_from_slice(title);
    out.write_all(&header)?;
    let n = u32::try_from(count)
        .map_err(|_| GeometryError::InvalidGrid("too many triangles for STL".into()))?;
    out.write_all(&n.to_le_bytes())?;
    out.write_all(&body)?;
    Ok(ExportStats {
        triangles: count,
        volume: voxels as f64 * cell_vol,
    })
}
