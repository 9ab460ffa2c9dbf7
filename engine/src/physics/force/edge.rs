//! The cutting edge cut into axial slices: [`EdgeSlice`] (one slice's geometry and exact
//! slice integrals) and [`ToolEdgeTable`] (a tool's slices and teeth, built once per tool).

use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

use crate::physics::{positive, PhysicsError};
use crate::tool::{Tool, ToolShape};

/// Geometry of one axial slice of the cutting edge, with the slice integrals the
/// elemental forces need.
///
/// Over a slice, h·db = (X·sin κ − V·cos κ)·dz/sin κ = (X − V·cot κ)·dz (X, V the chip's
/// parts across and along the axis), and the edge terms carry ds, ds·sin κ = dz and
/// ds·cos κ = dr. Summing dFt, the in-plane radial part (−dFr·sin κ + dFa·cos κ) and dFz over
/// the slice therefore needs only ∫sin κ dz, ∫cos κ dz, ∫cot κ dz, ∫cos²κ/sin κ dz, the edge
/// length and the radius rise, all integrated exactly on arcs and cones. The midpoint rule
/// would be poor at a ball's tip, where 1/sin κ is singular.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EdgeSlice {
    /// Centre height above the tip of the part of the slice that lies on the flutes, mm.
    pub z: f64,
    /// Height of that part, mm.
    pub dz: f64,
    /// Edge radius at z, mm.
    pub radius: f64,
    /// κ at z (chip-thickness reporting and the cut/no-cut test).
    pub sin_kappa: f64,
    pub cos_kappa: f64,
    /// Helix lag ψ(z) = z·tan β / R0, rad.
    pub lag: f64,
    /// Edge length ds = ∫ dz / sin κ, mm.
    pub edge_length: f64,
    /// Radius gained over the slice, ∫ ds·cos κ, mm.
    pub radius_rise: f64,
    /// ∫ sin κ dz, ∫ cos κ dz, ∫ cot κ dz, ∫ cos²κ / sin κ dz, mm.
    pub int_sin: f64,
    pub int_cos: f64,
    pub int_cot: f64,
    pub int_cos2_sin: f64,
    /// Torque arms: ∫ r dz, ∫ r·cot κ dz, ∫ r ds, mm².
    pub int_r_dz: f64,
    pub int_r_cot: f64,
    pub int_r_ds: f64,
}

impl EdgeSlice {
    /// The ring [r0, r1] of a flat end (κ = 0, at the tip, no helix lag): the κ → 0 limit
    /// of a cone slice, where dz → 0 and dz·cot κ → dr. The chip is the axial feed per tooth
    /// (h = −V), its width and the edge length are dr, and the torque arm is ∫ r dr; the
    /// flank integrals (∫ sin κ dz, ∫ cos κ dz, ∫ r dz) vanish.
    pub fn end_ring(r0: f64, r1: f64) -> EdgeSlice {
        let dr = r1 - r0;
        let r_dr = 0.5 * (r1 * r1 - r0 * r0);
        EdgeSlice {
            z: 0.0,
            dz: 0.0,
            radius: 0.5 * (r0 + r1),
            sin_kappa: 0.0,
            cos_kappa: 1.0,
            lag: 0.0,
            edge_length: dr,
            radius_rise: dr,
            int_sin: 0.0,
            int_cos: 0.0,
            int_cot: dr,
            int_cos2_sin: dr,
            int_r_dz: 0.0,
            int_r_cot: r_dr,
            int_r_ds: r_dr,
        }
    }

    /// The slice [z0, z1] of `tool`'s edge, clipped to the flutes (0, flute_length];
    /// None when nothing of it is on the flutes.
    pub fn compute(tool: &Tool, z0: f64, z1: f64) -> Option<EdgeSlice> {
        let za = z0.max(0.0);
        let zb = z1.min(tool.flute_length);
        if zb - za <= 1e-12 || zb.is_nan() || za.is_nan() {
            return None;
        }
        let z = 0.5 * (za + zb);
        let ep = tool.edge_point(z)?;
        let (sin_kappa, cos_kappa) = ep.kappa.sin_cos();
        let mut s = EdgeSlice {
            z,
            dz: zb - za,
            radius: ep.radius,
            sin_kappa,
            cos_kappa,
            lag: z * tool.helix_deg.to_radians().tan() / tool.radius(),
            edge_length: 0.0,
            radius_rise: 0.0,
            int_sin: 0.0,
            int_cos: 0.0,
            int_cot: 0.0,
            int_cos2_sin: 0.0,
            int_r_dz: 0.0,
            int_r_cot: 0.0,
            int_r_ds: 0.0,
        };
        let r = tool.radius();
        match tool.shape {
            ToolShape::Flat => s.add_flank(r, za, zb),
            ToolShape::Ball | ToolShape::BullNose => {
                let rc = tool.effective_corner_radius();
                let split = rc.clamp(za, zb);
                if split > za {
                    // On the corner arc z = rc·(1 − cos κ).
                    let kappa = |z: f64| ((rc - z) / rc).clamp(-1.0, 1.0).acos();
                    s.add_arc(rc, r - rc, kappa(za), kappa(split));
                }
                s.add_flank(r, split, zb);
            }
            ToolShape::Chamfer | ToolShape::Drill => {
                let split = tool.profile_top().clamp(za, zb);
                if split > za {
                    let alpha = tool.taper_half_angle_deg.to_radians();
                    let r_mid = tool.tip_diameter / 2.0 + 0.5 * (za + split) * alpha.tan();
                    s.add_cone(alpha, r_mid, split - za);
                }
                s.add_flank(r, split, zb);
            }
        }
        Some(s)
    }

    fn add_flank(&mut self, r: f64, za: f64, zb: f64) {
        let dz = zb - za;
        if dz > 0.0 {
            self.edge_length += dz;
            self.int_sin += dz;
            self.int_r_dz += r * dz;
            self.int_r_ds += r * dz;
        }
    }

    /// Cone at half-angle α from the axis (κ = 90° − α); r is linear in z so its midpoint
    /// value integrates exactly.
    fn add_cone(&mut self, alpha: f64, r_mid: f64, dz: f64) {
        let (c0, s0) = alpha.sin_cos();
        let cot = c0 / s0;
        self.edge_length += dz / s0;
        self.radius_rise += cot * dz;
        self.int_sin += s0 * dz;
        self.int_cos += c0 * dz;
        self.int_cot += cot * dz;
        self.int_cos2_sin += c0 * cot * dz;
        self.int_r_dz += r_mid * dz;
        self.int_r_cot += r_mid * cot * dz;
        self.int_r_ds += r_mid * dz / s0;
    }

    /// Corner arc of radius rc whose centre is r_off from the axis, from κa to κb; with
    /// dz = rc·sin κ dκ, ds = rc dκ and r = r_off + rc·sin κ every integral is elementary.
    fn add_arc(&mut self, rc: f64, r_off: f64, ka: f64, kb: f64) {
        let e = |f: &dyn Fn(f64) -> f64| rc * (f(kb) - f(ka));
        let dz = e(&|k| -k.cos());
        let len = e(&|k| k);
        let i_sin = e(&|k| 0.5 * k - 0.25 * (2.0 * k).sin());
        let i_cos = e(&|k| 0.5 * k.sin() * k.sin());
        let i_cot = e(&|k| k.sin());
        let i_cc = e(&|k| 0.5 * k + 0.25 * (2.0 * k).sin());
        self.edge_length += len;
        self.radius_rise += i_cot;
        self.int_sin += i_sin;
        self.int_cos += i_cos;
        self.int_cot += i_cot;
        self.int_cos2_sin += i_cc;
        self.int_r_dz += r_off * dz + rc * i_sin;
        self.int_r_cot += r_off * i_cot + rc * i_cos;
        self.int_r_ds += r_off * len + rc * dz;
    }
}

/// Per-tool precomputation: slice geometry on a uniform grid over the flute length and
/// the runout offsets of the teeth. Build once per tool; lookups for engagement slices
/// on the same grid are free, others are computed on the fly (still correct).
#[derive(Clone, Debug)]
pub struct ToolEdgeTable {
    tool: Tool,
    pub(super) flutes: usize,
    pub(super) pitch: f64,
    slice_height: f64,
    slices: Vec<EdgeSlice>,
    tooth_offsets: Vec<f64>,
    /// Row j: Δ_j − Δ_{j−m} for m = 1..=N; empty without runout.
    pub(super) runout_steps: Vec<f64>,
}

impl ToolEdgeTable {
    /// `slice_count` uniform slices over the flute length.
    pub fn new(tool: &Tool, slice_count: usize) -> Result<ToolEdgeTable, PhysicsError> {
        tool.validate()?;
        if slice_count == 0 || slice_count > 1_000_000 {
            return Err(PhysicsError::invalid(
                "slice_count",
                format!("must be in 1..=1000000, got {slice_count}"),
            ));
        }
        ToolEdgeTable::with_slice_height(tool, tool.flute_length / slice_count as f64)
    }

    /// Slices of height `slice_height` from the tip up (the last one clipped to the flutes).
    pub fn with_slice_height(
        tool: &Tool,
        slice_height: f64,
    ) -> Result<ToolEdgeTable, PhysicsError> {
        tool.validate()?;
        positive("slice_height", slice_height)?;
        let count = (tool.flute_length / slice_height - 1e-9).ceil().max(1.0);
        if count > 1e6 {
            return Err(PhysicsError::invalid(
                "slice_height",
                "gives more than 1000000 slices",
            ));
        }
        let slices = (0..count as usize)
            .filter_map(|i| {
                EdgeSlice::compute(tool, i as f64 * slice_height, (i + 1) as f64 * slice_height)
            })
            .collect();
        let n = tool.flutes as usize;
        let pitch = TAU / n as f64;
        let rho = tool.runout.offset;
        let lambda = tool.runout.angle_deg.to_radians();
        // Tooth j sits at −j·pitch from tooth 1 in the rotating frame; the axis offset at λ
        // lengthens it by ρ·cos(λ − (−j·pitch)).
        let tooth_offsets: Vec<f64> = (0..n)
            .map(|j| rho * (lambda + j as f64 * pitch).cos())
            .collect();
        let runout_steps = if rho > 0.0 {
            (0..n)
                .flat_map(|j| {
                    let offs = &tooth_offsets;
                    (1..=n).map(move |m| offs[j] - offs[(j + n * m - m) % n])
                })
                .collect()
        } else {
            Vec::new()
        };
        Ok(ToolEdgeTable {
            tool: tool.clone(),
            flutes: n,
            pitch,
            slice_height,
            slices,
            tooth_offsets,
            runout_steps,
        })
    }

    pub fn tool(&self) -> &Tool {
        &self.tool
    }

    pub fn flutes(&self) -> usize {
        self.flutes
    }

    pub fn slice_height(&self) -> f64 {
        self.slice_height
    }

    /// The precomputed grid slices, from the tip up.
    pub fn slices(&self) -> &[EdgeSlice] {
        &self.slices
    }

    /// Radial deviation of each tooth's radius caused by runout, mm (tooth 1 first).
    pub fn tooth_offsets(&self) -> &[f64] {
        &self.tooth_offsets
    }

    /// Geometry of the engagement slice centred at `z` with height `dz`.
    pub fn slice(&self, z: f64, dz: f64) -> Option<EdgeSlice> {
        match self.slice_index(z, dz) {
            Some(i) => Some(self.slices[i]),
            None => EdgeSlice::compute(&self.tool, z - 0.5 * dz, z + 0.5 * dz),
        }
    }

    /// The table's own slice that the engagement slice (`z`, `dz`) is, if it is on the grid.
    pub fn slice_index(&self, z: f64, dz: f64) -> Option<usize> {
        let h = self.slice_height;
        let tol = 1e-9 * h.max(1.0);
        let i = (z / h).floor();
        if i >= 0.0 && (i as usize) < self.slices.len() && (dz - h).abs() <= tol {
            let s = &self.slices[i as usize];
            if (s.z - z).abs() <= tol && (s.dz - dz).abs() <= tol {
                return Some(i as usize);
            }
        }
        None
    }
}
