//! Collision checks at a tool position: what lies above the flutes (the cut reaching past
//! the flute length, the shank, the holder stack) against the remaining stock, and the
//! whole tool against an optional fixture.

use serde::{Deserialize, Serialize};

use super::dexel::{overlaps, DexelGrid};
use super::sweep::frame_around;
use crate::tool::Tool;

/// Per-block collision flags.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CheckFlags {
    /// A rapid (G0) move removed material.
    pub rapid_in_material: bool,
    /// Material within the cutting diameter above the flute length: the cut is deeper
    /// than the flutes.
    pub flute_length_exceeded: bool,
    /// Material touching the shank outside the cutting diameter (a shank wider than the
    /// cut).
    pub shank_contact: bool,
    /// Material touching the holder stack.
    pub holder_contact: bool,
    /// The tool or holder touching the fixture.
    pub fixture_contact: bool,
}

impl CheckFlags {
    pub fn merge(&mut self, o: &CheckFlags) {
        self.rapid_in_material |= o.rapid_in_material;
        self.flute_length_exceeded |= o.flute_length_exceeded;
        self.shank_contact |= o.shank_contact;
        self.holder_contact |= o.holder_contact;
        self.fixture_contact |= o.fixture_contact;
    }
    pub fn any(&self) -> bool {
        self.rapid_in_material
            || self.flute_length_exceeded
            || self.shank_contact
            || self.holder_contact
            || self.fixture_contact
    }
}

/// A piece of the tool's body: a frustum along the tool axis between heights z0 < z1
/// above the tip, radii r0 at z0 and r1 at z1; points nearer the axis than `r_inner` do
/// not count (to tell a wide shank from the cutting diameter below it).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frustum {
    pub z0: f64,
    pub z1: f64,
    pub r0: f64,
    pub r1: f64,
    pub r_inner: f64,
}

/// The bodies checked against the stock: above-flute cutting diameter, wide shank,
/// holder stack.
pub(crate) struct ToolChecks {
    pub flute: Option<Frustum>,
    pub shank: Option<Frustum>,
    pub holder: Vec<Frustum>,
    /// The whole tool for fixture checks.
    pub whole: Vec<Frustum>,
}

impl ToolChecks {
    pub fn new(tool: &Tool) -> ToolChecks {
        let r = tool.radius();
        let l = tool.flute_length;
        let so = tool.stick_out().max(l);
        let rs = tool.shank_diameter() / 2.0;
        let flute = (so > l).then_some(Frustum {
            z0: l,
            z1: so,
            r0: r,
            r1: r,
            r_inner: 0.0,
        });
        let shank = (so > l && rs > r).then_some(Frustum {
            z0: l,
            z1: so,
            r0: rs,
            r1: rs,
            r_inner: r,
        });
        let mut holder = Vec::new();
        let mut z = so;
        for seg in &tool.holder {
            holder.push(Frustum {
                z0: z,
                z1: z + seg.length,
                r0: seg.bottom_diameter / 2.0,
                r1: seg.top_diameter / 2.0,
                r_inner: 0.0,
            });
            z += seg.length;
        }
        let mut whole = vec![Frustum {
            z0: 0.0,
            z1: l,
            r0: r,
            r1: r,
            r_inner: 0.0,
        }];
        if so > l {
            whole.push(Frustum {
                z0: l,
                z1: so,
                r0: rs.max(r),
                r1: rs.max(r),
                r_inner: 0.0,
            });
        }
        whole.extend(holder.iter().copied());
        ToolChecks {
            flute,
            shank,
            holder,
            whole,
        }
    }
}

/// Whether the frustum at tip `pos` with unit `axis` meets material of `grid`.
/// `top_z` bounds the material from above (skips the search when the body is higher).
pub(crate) fn frustum_hits(
    grid: &DexelGrid,
    pos: [f64; 3],
    axis: [f64; 3],
    f: &Frustum,
    top_z: f64,
) -> bool {
    let rmax = f.r0.max(f.r1);
    if rmax <= f.r_inner || f.z1 <= f.z0 {
        return false;
    }
    let vertical = (axis[2] - 1.0).abs() < 1e-12;
    if vertical {
        if pos[2] + f.z0 >= top_z || pos[2] + f.z1 <= grid.origin[2] {
            return false;
        }
        let (i0, i1) = grid.index_range(0, pos[0] - rmax, pos[0] + rmax);
        let (j0, j1) = grid.index_range(1, pos[1] - rmax, pos[1] + rmax);
        let fam = &grid.families[2];
        for j in j0..j1 {
            let y = grid.center(1, j) - pos[1];
            for i in i0..i1 {
                let x = grid.center(0, i) - pos[0];
                let rho = (x * x + y * y).sqrt();
                if rho > rmax || rho <= f.r_inner {
                    continue;
                }
                // Heights of the frustum at this distance from the axis (radius linear in z).
                let (zlo, zhi) = if (f.r1 - f.r0).abs() < 1e-12 {
                    (f.z0, f.z1)
                } else {
                    let zr = f.z0 + (rho - f.r0) / (f.r1 - f.r0) * (f.z1 - f.z0);
                    if f.r1 > f.r0 {
                        (zr.max(f.z0), f.z1)
                    } else {
                        (f.z0, zr.min(f.z1))
                    }
                };
                if zlo < zhi && overlaps(&fam.rays[i + fam.nu * j], pos[2] + zlo, pos[2] + zhi) {
                    return true;
                }
            }
        }
        false
    } else {
        // Nothing to find when the frustum's lowest point is above the material.
        let lateral = (1.0 - axis[2] * axis[2]).max(0.0).sqrt() * rmax;
        let lowest = pos[2] + (axis[2] * f.z0).min(axis[2] * f.z1) - lateral;
        if lowest >= top_z {
            return false;
        }
        // Tilted axis: points on rings of the surface, spaced about one cell.
        let (e1, e2) = frame_around(axis);
        let h = grid.cell;
        let nzs = ((f.z1 - f.z0) / h).ceil().max(1.0) as usize;
        for k in 0..=nzs {
            let z = f.z0 + (f.z1 - f.z0) * k as f64 / nzs as f64;
            let r = f.r0 + (f.r1 - f.r0) * (z - f.z0) / (f.z1 - f.z0);
            // The lateral surface, plus the bottom face (rings) where the body meets
            // material first when it comes down.
            let nrad = if k == 0 {
                ((r - f.r_inner).max(0.0) / h).ceil().max(1.0) as usize
            } else {
                0
            };
            for q in 0..=nrad {
                let rr = if nrad == 0 {
                    r
                } else {
                    f.r_inner + (r - f.r_inner) * q as f64 / nrad as f64
                };
                if rr <= f.r_inner && f.r_inner > 0.0 {
                    continue;
                }
                let nang = ((2.0 * std::f64::consts::PI * rr / h).ceil() as usize).max(1);
                for m in 0..nang {
                    let t = 2.0 * std::f64::consts::PI * m as f64 / nang as f64;
                    let (s, c) = t.sin_cos();
                    let p = [
                        pos[0] + axis[0] * z + rr * (c * e1[0] + s * e2[0]),
                        pos[1] + axis[1] * z + rr * (c * e1[1] + s * e2[1]),
                        pos[2] + axis[2] * z + rr * (c * e1[2] + s * e2[2]),
                    ];
                    if grid.material_at(p) {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// Checks of the tool body above the flutes against the stock at one position.
pub(crate) fn check_position(
    grid: &DexelGrid,
    checks: &ToolChecks,
    pos: [f64; 3],
    axis: [f64; 3],
    top_z: f64,
    fixture: Option<&DexelGrid>,
    flags: &mut CheckFlags,
) {
    if !flags.flute_length_exceeded {
        if let Some(f) = &checks.flute {
            flags.flute_length_exceeded = frustum_hits(grid, pos, axis, f, top_z);
        }
    }
    if !flags.shank_contact {
        if let Some(f) = &checks.shank {
            flags.shank_contact = frustum_hits(grid, pos, axis, f, top_z);
        }
    }
    if !flags.holder_contact {
        flags.holder_contact = checks
            .holder
            .iter()
            .any(|f| frustum_hits(grid, pos, axis, f, top_z));
    }
    if let Some(fx) = fixture {
        if !flags.fixture_contact {
            let ftop = fx.max_corner()[2];
            flags.fixture_contact = checks
                .whole
                .iter()
                .any(|f| frustum_hits(fx, pos, axis, f, ftop));
        }
    }
}
