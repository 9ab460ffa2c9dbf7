//! Collision checks at a tool position: what lies above the flutes (the cut reaching past
//! the flute length, the shank, the holder stack) against the remaining stock, and the
//! whole tool against an optional fixture.

use serde::{Deserialize, Serialize};

use super::dexel::{overlaps, DexelGrid};
use super::sweep::{self, frame_around, swept_frustum};
use crate::tool::Tool;
use crate::vec3::dot;

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
    /// Material bounds of the stock's and the fixture's Z rays.
    tops: ColumnTops,
    fixture_tops: ColumnTops,
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
            tops: ColumnTops::default(),
            fixture_tops: ColumnTops::default(),
        }
    }
}

/// Whether the frustum at tip `pos` with unit `axis` meets material of `grid`.
/// `top_z` bounds the material from above (skips the search when the body is higher);
/// `tops` keeps bounds of the grid's material between calls (material only goes away).
pub(crate) fn frustum_hits(
    grid: &DexelGrid,
    pos: [f64; 3],
    axis: [f64; 3],
    f: &Frustum,
    top_z: f64,
    tops: &mut ColumnTops,
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
        // Blocks of rays whose material stays below the body's bottom are skipped whole
        // (a turned grid's top is far above much of the stock).
        tops.fit(grid);
        let lowest = pos[2] + f.z0;
        for bj in j0 / TOP_BLOCK..j1.div_ceil(TOP_BLOCK) {
            for bi in i0 / TOP_BLOCK..i1.div_ceil(TOP_BLOCK) {
                if !tops.may_rise_above(grid, (bi, bj), lowest) {
                    continue;
                }
                for j in (bj * TOP_BLOCK).max(j0)..((bj + 1) * TOP_BLOCK).min(j1) {
                    let y = grid.center(1, j) - pos[1];
                    for i in (bi * TOP_BLOCK).max(i0)..((bi + 1) * TOP_BLOCK).min(i1) {
                        let x = grid.center(0, i) - pos[0];
                        let rho = (x * x + y * y).sqrt();
                        if rho > rmax || rho <= f.r_inner {
                            continue;
                        }
                        // Heights of the frustum at this distance from the axis (radius
                        // linear in z).
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
                        if zlo < zhi
                            && overlaps(&fam.rays[i + fam.nu * j], pos[2] + zlo, pos[2] + zhi)
                        {
                            return true;
                        }
                    }
                }
            }
        }
        false
    } else {
        tilted_hits(grid, pos, axis, f, top_z, tops)
    }
}

/// Z rays per side of a block of [`ColumnTops`].
const TOP_BLOCK: usize = 8;

/// Per block of Z rays, a height no material of the block rises above. Material only goes
/// away, so a value once true stays true: it is refreshed from the rays only when a body
/// reaches below it.
#[derive(Default)]
pub(crate) struct ColumnTops {
    nb: [usize; 2],
    top: Vec<f64>,
}

impl ColumnTops {
    fn fit(&mut self, grid: &DexelGrid) {
        let nb = [0, 1].map(|a| grid.n[a].div_ceil(TOP_BLOCK));
        if nb != self.nb || self.top.len() != nb[0] * nb[1] {
            self.nb = nb;
            self.top = vec![f64::INFINITY; nb[0] * nb[1]];
        }
    }

    /// Whether block (bi, bj) may hold material above `z`, its bound refreshed if needed.
    fn may_rise_above(&mut self, grid: &DexelGrid, (bi, bj): (usize, usize), z: f64) -> bool {
        let k = bi + self.nb[0] * bj;
        if self.top[k] <= z {
            return false;
        }
        let fam = &grid.families[2];
        let mut top = f64::NEG_INFINITY;
        for j in bj * TOP_BLOCK..((bj + 1) * TOP_BLOCK).min(fam.nv) {
            for i in bi * TOP_BLOCK..((bi + 1) * TOP_BLOCK).min(fam.nu) {
                if let Some(iv) = fam.rays[i + fam.nu * j].last() {
                    top = top.max(iv[1]);
                }
            }
        }
        self.top[k] = top;
        top > z
    }
}

/// A tilted frustum against the Z rays through its footprint: each ray meets it in one
/// interval (minus the inner cylinder's), exactly, from the same line-frustum solver as
/// the removal. Only the part of the frustum between the grid's floor and `top_z` is
/// walked, and blocks of rays whose material stays below the frustum are skipped whole.
fn tilted_hits(
    grid: &DexelGrid,
    pos: [f64; 3],
    axis: [f64; 3],
    f: &Frustum,
    top_z: f64,
    tops: &mut ColumnTops,
) -> bool {
    let rmax = f.r0.max(f.r1);
    let az = axis[2];
    let lateral = (1.0 - az * az).max(0.0).sqrt();
    let r_at = |z: f64| f.r0 + (f.r1 - f.r0) * (z - f.z0) / (f.z1 - f.z0);
    // Heights along the axis whose ring can reach between the floor and `top_z`.
    let (mut za, mut zb) = (f.z0, f.z1);
    if az.abs() > 1e-9 {
        let floor = grid.origin[2];
        let (a, b) = (
            (top_z - pos[2] + lateral * rmax) / az,
            (floor - pos[2] - lateral * rmax) / az,
        );
        let (lo, hi) = if az > 0.0 { (b, a) } else { (a, b) };
        za = za.max(lo);
        zb = zb.min(hi);
    }
    if !(za < zb) {
        return false;
    }
    let (ra, rb) = (r_at(za), r_at(zb));
    let (e1, e2) = frame_around(axis);
    // The footprint: the frustum is the hull of its end discs.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut lowest = f64::INFINITY;
    for (z, r) in [(za, ra), (zb, rb)] {
        for a in 0..2 {
            let c = pos[a] + axis[a] * z;
            let half = r * (1.0 - axis[a] * axis[a]).max(0.0).sqrt();
            lo[a] = lo[a].min(c - half);
            hi[a] = hi[a].max(c + half);
        }
        lowest = lowest.min(pos[2] + az * z - lateral * r);
    }
    let (i0, i1) = grid.index_range(0, lo[0], hi[0]);
    let (j0, j1) = grid.index_range(1, lo[1], hi[1]);
    if i0 >= i1 || j0 >= j1 {
        return false;
    }
    tops.fit(grid);
    let body = sweep::Frustum {
        z0: za,
        z1: zb,
        r0: ra,
        r1: rb,
    };
    let inner = (f.r_inner > 0.0).then_some(sweep::Frustum {
        z0: za,
        z1: zb,
        r0: f.r_inner,
        r1: f.r_inner,
    });
    // World +Z in the tool frame; a ray through (x, y) is o + s·e with s its world z.
    let e = [e1[2], e2[2], az];
    let fam = &grid.families[2];
    for bj in j0 / TOP_BLOCK..=(j1 - 1) / TOP_BLOCK {
        for bi in i0 / TOP_BLOCK..=(i1 - 1) / TOP_BLOCK {
            if !tops.may_rise_above(grid, (bi, bj), lowest) {
                continue;
            }
            for j in (bj * TOP_BLOCK).max(j0)..((bj + 1) * TOP_BLOCK).min(j1) {
                let y = grid.center(1, j) - pos[1];
                for i in (bi * TOP_BLOCK).max(i0)..((bi + 1) * TOP_BLOCK).min(i1) {
                    let ray = &fam.rays[i + fam.nu * j];
                    let Some(top) = ray.last().map(|iv| iv[1]) else {
                        continue;
                    };
                    if top <= lowest {
                        continue;
                    }
                    let x = grid.center(0, i) - pos[0];
                    let w = [x, y, -pos[2]];
                    let o = [dot(w, e1), dot(w, e2), dot(w, axis)];
                    let Some((s0, s1)) = swept_frustum(o, e, [0.0; 3], &body) else {
                        continue;
                    };
                    // Outside the inner cylinder: below it and above it on the ray.
                    let hit = match inner.and_then(|c| swept_frustum(o, e, [0.0; 3], &c)) {
                        Some((c0, c1)) => {
                            let (below, above) = (c0.min(s1), c1.max(s0));
                            (s0 < below && overlaps(ray, s0, below))
                                || (above < s1 && overlaps(ray, above, s1))
                        }
                        None => overlaps(ray, s0, s1),
                    };
                    if hit {
                        return true;
                    }
                }
            }
        }
    }
    false
}

/// Checks of the tool body above the flutes against the stock at one position.
pub(crate) fn check_position(
    grid: &DexelGrid,
    checks: &mut ToolChecks,
    pos: [f64; 3],
    axis: [f64; 3],
    top_z: f64,
    fixture: Option<&DexelGrid>,
    flags: &mut CheckFlags,
) {
    if !flags.flute_length_exceeded {
        if let Some(f) = &checks.flute {
            flags.flute_length_exceeded = frustum_hits(grid, pos, axis, f, top_z, &mut checks.tops);
        }
    }
    if !flags.shank_contact {
        if let Some(f) = &checks.shank {
            flags.shank_contact = frustum_hits(grid, pos, axis, f, top_z, &mut checks.tops);
        }
    }
    if !flags.holder_contact {
        flags.holder_contact = checks
            .holder
            .iter()
            .any(|f| frustum_hits(grid, pos, axis, f, top_z, &mut checks.tops));
    }
    if let Some(fx) = fixture {
        if !flags.fixture_contact {
            let ftop = fx.max_corner()[2];
            flags.fixture_contact = checks
                .whole
                .iter()
                .any(|f| frustum_hits(fx, pos, axis, f, ftop, &mut checks.fixture_tops));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sweep::{remove_sweep, SubMove, ToolBody};
    use crate::geometry::{GridOptions, Stock, StockShape};
    use crate::tool::Tool;

    /// Brute force: points of the frustum (between its inner and outer radius) every
    /// `dz` along each Z ray of the grid; `grow` widens or narrows the body by that much.
    fn sampled_hit(
        grid: &DexelGrid,
        pos: [f64; 3],
        axis: [f64; 3],
        f: &Frustum,
        grow: f64,
    ) -> bool {
        let (e1, e2) = frame_around(axis);
        let fam = &grid.families[2];
        let dz = grid.cell / 10.0;
        let r_at = |z: f64| f.r0 + (f.r1 - f.r0) * (z - f.z0) / (f.z1 - f.z0);
        let reach = f.z1 + f.r0.max(f.r1) + grow;
        for j in 0..fam.nv {
            for i in 0..fam.nu {
                let (x, y) = (grid.center(0, i), grid.center(1, j));
                if (x - pos[0]).abs() > reach || (y - pos[1]).abs() > reach {
                    continue;
                }
                for iv in &fam.rays[i + fam.nu * j] {
                    let mut z = iv[0] + 0.5 * dz;
                    while z < iv[1] {
                        let w = [x - pos[0], y - pos[1], z - pos[2]];
                        let o = [dot(w, e1), dot(w, e2), dot(w, axis)];
                        let rho = (o[0] * o[0] + o[1] * o[1]).sqrt();
                        if o[2] >= f.z0 - grow
                            && o[2] <= f.z1 + grow
                            && rho <= r_at(o[2].clamp(f.z0, f.z1)) + grow
                            && rho > f.r_inner - grow
                        {
                            return true;
                        }
                        z += dz;
                    }
                }
            }
        }
        false
    }

    #[test]
    fn tilted_bodies_meet_the_material_the_brute_force_finds() {
        let mut stock = Stock::from_shape(
            &StockShape::Block {
                min: [0.0, 0.0, -6.0],
                max: [12.0, 12.0, 0.0],
            },
            &GridOptions {
                cell: Some(0.25),
                ..GridOptions::default()
            },
        )
        .unwrap();
        // Pockets and slots so that walls, floors and islands face the bodies.
        let ball = ToolBody::cutting_part(&Tool::ball(3.0, 2));
        for (p0, p1) in [
            ([2.0, 2.0, -3.0], [10.0, 3.0, -3.0]),
            ([6.0, 4.0, -5.0], [6.5, 11.0, -4.0]),
            ([1.0, 9.0, -1.0], [11.0, 10.0, -2.5]),
        ] {
            remove_sweep(
                &mut stock.grid,
                &ball,
                &SubMove {
                    p0,
                    p1,
                    axis: [0.0, 0.0, 1.0],
                },
            );
        }
        let mut seed = 0x5eed_u64;
        let mut next = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut tops = ColumnTops::default();
        let (mut hits, mut misses) = (0, 0);
        for k in 0..400 {
            if k % 100 == 50 {
                // Material goes away between checks: the kept bounds must stay bounds.
                let (x, y) = (next() * 12.0, next() * 12.0);
                let mv = SubMove {
                    p0: [x, y, -5.0],
                    p1: [12.0 - x, y, -0.5],
                    axis: [0.0, 0.0, 1.0],
                };
                remove_sweep(&mut stock.grid, &ball, &mv);
            }
            let grid = &stock.grid;
            let tilt = next() * 1.2;
            let turn = next() * std::f64::consts::TAU;
            let axis = [tilt.sin() * turn.cos(), tilt.sin() * turn.sin(), tilt.cos()];
            let pos = [next() * 14.0 - 1.0, next() * 14.0 - 1.0, next() * 8.0 - 9.0];
            let z0 = next() * 4.0;
            let f = Frustum {
                z0,
                z1: z0 + 0.5 + next() * 5.0,
                r0: 0.5 + next() * 2.0,
                r1: 0.5 + next() * 2.0,
                r_inner: if next() < 0.3 { 0.4 } else { 0.0 },
            };
            let margin = 0.02;
            let (sure, maybe) = (
                sampled_hit(grid, pos, axis, &f, -margin),
                sampled_hit(grid, pos, axis, &f, margin),
            );
            if sure != maybe {
                continue; // material within the margin of the body's surface
            }
            let found = frustum_hits(grid, pos, axis, &f, grid.max_z(), &mut tops);
            assert_eq!(found, sure, "axis {axis:?} tip {pos:?} {f:?}");
            if found {
                hits += 1;
            } else {
                misses += 1;
            }
        }
        assert!(hits > 50 && misses > 50, "{hits} hits, {misses} misses");
    }
}
