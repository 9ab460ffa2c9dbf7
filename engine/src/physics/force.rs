//! Mechanistic milling force model (Altintas, *Manufacturing Automation*, ch. 2).
//!
//! The cutting edge is cut into axial slices along the real edge (flat, ball, bull-nose,
//! chamfer via [`Tool::edge_point`]). For slice s and tooth j at spindle angle θ the
//! immersion is
//!
//! φ_j(θ, z) = θ − j·2π/N − ψ(z),  ψ(z) = z·tan β / R0,  R0 = D/2,
//!
//! i.e. tooth j trails tooth j−1 by one pitch, and the helix lag ψ is the constant-lead
//! model: a helix of lead 2π·R0/tan β wound on the nominal cylinder, which is also what
//! Altintas uses on the ball part. θ is tooth 1's immersion at the tip.
//!
//! Chip thickness is the feed per tooth projected on the edge's outward normal
//! n = (sin κ sin φ, sin κ cos φ, −cos κ):
//!
//! h = c_h·sin φ·sin κ − c_v·cos κ  (+ runout),
//!
//! c_h and c_v the parts of the feed per tooth across and along the tool axis (c_v ≠ 0 when
//! ramping or 5-axis with the feed not perpendicular to the axis). With radial runout tooth j
//! sweeps r + Δ_j, Δ_j = ρ·cos(λ + j·2π/N) (first order in ρ/r), and cuts the surface left by
//! the last tooth that reached further: h_j = min over m = 1..N of (m·h + (Δ_j − Δ_{j−m})·sin κ)
//! (Kline–DeVor / Altintas). No cut (and no edge force) where h < 0.
//!
//! Elemental forces on the tool: dFt = Ktc·h·db + Kte·ds, dFr = Krc·h·db + Kre·ds,
//! dFa = Kac·h·db + Kae·ds, with db = ds = dz / sin κ (chip width, edge length), rotated
//! into the tool frame:
//!
//! dFx = −dFt·cos φ + (−dFr·sin κ + dFa·cos κ)·sin φ
//! dFy = +dFt·sin φ + (−dFr·sin κ + dFa·cos κ)·cos φ
//! dFz = dFr·cos κ + dFa·sin κ
//!
//! which is Altintas' ball-end transformation with the axial term's sign chosen so that on a
//! cylindrical flank (κ = 90°) it reduces to the flat end mill relations and the closed form in
//! ../shared/REFERENCE.md (F̄z = +(N·a/2π)[−Kac·c·cos φ + Kae·φ]). Within a slice these are
//! integrated over z exactly (see [`EdgeSlice`]) rather than taken at the slice centre: at a
//! ball's tip 1/sin κ is singular and the midpoint value is off by tens of percent on the first
//! slices. The chip's sign (cut or not) is decided at the slice centre.
//!
//! Torque T = Σ dFt·r; power P = T·ω, which is Ft·v with the local cutting speed of each edge
//! point (for a flat end mill exactly Ft·π·D·n/60000).
//!
//! Runout simplifications: the radius change enters the chip only (the torque arm and the
//! tooth's angular position keep their nominal values: effects of order ρ/r).
//!
//! Speed: per-slice geometry comes from a [`ToolEdgeTable`] built once per tool; only the
//! positions where a tooth is inside an engaged arc are visited; without runout, when the
//! tooth pitch is a whole number of positions (360 positions and 1–6, 8, 9, 10, 12 … teeth),
//! tooth 1 is computed and the others are copies shifted by whole pitches.
//!
//! Means are exact time averages up to the midpoint rule: the samples at the bin centres are
//! weighted 1, and the two bins an engaged arc cuts through are integrated over their covered
//! part only, so a 10%-immersion arc is not rounded to whole degrees. Instantaneous samples
//! include a tooth exactly on an arc boundary.

use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, TAU};

use super::material::CuttingCoefficients;
use super::{non_negative, positive, PhysicsError};
use crate::engagement::Engagement;
use crate::tool::{Tool, ToolShape};
use crate::vec3::{cross, dot, norm, scale, sub};

/// Angular positions per revolution when the caller has no preference (1° steps).
pub const DEFAULT_POSITIONS: usize = 360;

/// Relative tolerance, in sample-index units, for a tooth exactly on an arc boundary.
const BOUNDARY_EPS: f64 = 1e-9;

/// A tooth on the φ = 0 or π boundary has h = ±1e-17 from rounding; count it as cutting
/// (edge forces on) consistently wherever it is evaluated. With runout the chip carries
/// the teeth's radius steps, so the margin is in mm; without, every chip is the feed per
/// tooth times a shape factor, and the margin scales with the feed so that which samples
/// cut does not depend on the feed (the forces are then exactly affine in it).
const CHIP_EPS: f64 = 1e-12;
/// The margin per mm of feed per tooth without runout.
const CHIP_EPS_PER_FEED: f64 = 1e-10;

/// Spindle speed and feed of one step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CuttingConditions {
    /// Spindle speed, rev/min (clockwise, M3).
    pub spindle_rpm: f64,
    /// Feed per tooth along the feed direction, mm.
    pub feed_per_tooth: f64,
}

impl CuttingConditions {
    pub fn validate(&self) -> Result<(), PhysicsError> {
        positive("spindle_rpm", self.spindle_rpm)?;
        non_negative("feed_per_tooth", self.feed_per_tooth)?;
        Ok(())
    }

    /// Angular speed of the spindle, rad/s.
    pub fn omega(&self) -> f64 {
        self.spindle_rpm * TAU / 60.0
    }
}

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
            ToolShape::Chamfer => {
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
    flutes: usize,
    pitch: f64,
    slice_height: f64,
    slices: Vec<EdgeSlice>,
    tooth_offsets: Vec<f64>,
    /// Row j: Δ_j − Δ_{j−m} for m = 1..=N; empty without runout.
    runout_steps: Vec<f64>,
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
        let h = self.slice_height;
        let tol = 1e-9 * h.max(1.0);
        let i = (z / h).floor();
        if i >= 0.0 && (i as usize) < self.slices.len() && (dz - h).abs() <= tol {
            let s = &self.slices[i as usize];
            if (s.z - z).abs() <= tol && (s.dz - dz).abs() <= tol {
                return Some(*s);
            }
        }
        EdgeSlice::compute(&self.tool, z - 0.5 * dz, z + 0.5 * dz)
    }
}

/// Orthonormal tool frame of a step, in part coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ToolFrame {
    /// Feed direction projected perpendicular to the axis (x of the Engagement frame).
    pub x: [f64; 3],
    pub y: [f64; 3],
    /// Tool axis, tip to spindle.
    pub z: [f64; 3],
    /// Component of the unit feed direction across the axis (cos of the ramp angle).
    pub feed_across: f64,
    /// Component of the unit feed direction along the axis (positive: moving up).
    pub feed_along: f64,
}

impl ToolFrame {
    pub const IDENTITY: ToolFrame = ToolFrame {
        x: [1.0, 0.0, 0.0],
        y: [0.0, 1.0, 0.0],
        z: [0.0, 0.0, 1.0],
        feed_across: 1.0,
        feed_along: 0.0,
    };

    /// The Engagement frame: z the tool axis, x the feed direction projected perpendicular to it,
    /// y = z × x. A pure plunge has no such x; then x is the part X (or Y) projected.
    pub fn from_engagement(e: &Engagement) -> Result<ToolFrame, PhysicsError> {
        let z = unit("tool_axis", e.tool_axis)?;
        let f = unit("feed_dir", e.feed_dir)?;
        let along = dot(f, z);
        let h = sub(f, scale(z, along));
        let across = norm(h);
        let x = if across > 1e-9 {
            scale(h, 1.0 / across)
        } else {
            let e = if z[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let p = sub(e, scale(z, dot(e, z)));
            scale(p, 1.0 / norm(p))
        };
        let y = cross(z, x);
        Ok(ToolFrame {
            x,
            y,
            z,
            feed_across: across,
            feed_along: along,
        })
    }

    /// A tool-frame vector in part coordinates.
    pub fn to_part(&self, v: [f64; 3]) -> [f64; 3] {
        [
            v[0] * self.x[0] + v[1] * self.y[0] + v[2] * self.z[0],
            v[0] * self.x[1] + v[1] * self.y[1] + v[2] * self.z[1],
            v[0] * self.x[2] + v[1] * self.y[2] + v[2] * self.z[2],
        ]
    }
}

fn unit(field: &str, v: [f64; 3]) -> Result<[f64; 3], PhysicsError> {
    for (i, c) in v.iter().enumerate() {
        if !c.is_finite() {
            return Err(PhysicsError::NotFinite {
                field: format!("{field}[{i}]"),
                value: *c,
            });
        }
    }
    let n = norm(v);
    if n.is_nan() || n <= 1e-12 || !n.is_finite() {
        return Err(PhysicsError::invalid(field, "must be a non-zero vector"));
    }
    Ok(scale(v, 1.0 / n))
}

/// Mean, minimum and maximum of one force component over a revolution, N.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AxisStats {
    pub mean: f64,
    pub min: f64,
    pub max: f64,
}

impl AxisStats {
    /// Largest magnitude reached.
    pub fn peak(&self) -> f64 {
        self.min.abs().max(self.max.abs())
    }
}

/// Mean and peak of a non-negative quantity (|F|, torque, power).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MagnitudeStats {
    pub mean: f64,
    pub peak: f64,
}

/// What one tooth does over the revolution.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ToothStats {
    /// 1-based tooth number (tooth 1 is the runout angle's reference).
    pub tooth: usize,
    /// Largest |F| of this tooth's own contribution, N.
    pub peak_force: f64,
    /// Largest chip thickness this tooth cuts, mm.
    pub max_chip_thickness: f64,
}

/// The force at one angular position, in the tool (Engagement) frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ForceSample {
    /// Spindle angle θ (tooth 1's immersion at the tip), rad.
    pub angle: f64,
    pub fx: f64,
    pub fy: f64,
    pub fz: f64,
    /// N·m.
    pub torque: f64,
}

/// Forces of one engagement state over one spindle revolution.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ForceResult {
    pub positions: usize,
    /// One sample per angular position (empty when the model was told not to keep them).
    pub samples: Vec<ForceSample>,
    /// Tool frame (x feed, z tool axis): components.
    pub fx: AxisStats,
    pub fy: AxisStats,
    pub fz: AxisStats,
    /// |F|: mean of the sampled magnitude, and peak.
    pub force: MagnitudeStats,
    /// |F| in the plane perpendicular to the tool axis (what bends the tool).
    pub force_xy: MagnitudeStats,
    /// Part-frame X, Y, Z components.
    pub part: [AxisStats; 3],
    /// Mean force vector in part coordinates, N.
    pub mean_force_part: [f64; 3],
    /// Force vector at the sample with the largest |F|, part coordinates, N.
    pub peak_force_part: [f64; 3],
    /// Spindle torque, N·m.
    pub torque: MagnitudeStats,
    /// Cutting power P = T·ω, W.
    pub power: MagnitudeStats,
    /// Largest uncut chip thickness over teeth, slices and positions, mm.
    pub max_chip_thickness: f64,
    pub per_tooth: Vec<ToothStats>,
    /// The tool frame in part coordinates.
    pub frame: Option<ToolFrame>,
    /// Engagement slices that contributed / that lay outside the flutes (no edge there).
    pub engaged_slices: usize,
    pub skipped_slices: usize,
}

impl ForceResult {
    /// No tooth cut anything.
    pub fn is_air(&self) -> bool {
        self.engaged_slices == 0
    }
}

/// Per (slice, tooth) constants of the inner loop. Each force component of the slice is
/// a·X + b0 + bv·V with X the chip's part across the axis (c_h·sin φ, plus runout) and V
/// its part along it (c_v); components: Ft, in-plane radial (outward), Fz, torque (N·mm).
#[derive(Clone, Copy)]
struct Pass {
    /// A chip thinner than −eps is no cut.
    eps: f64,
    sa: f64,
    ca: f64,
    ch: f64,
    cv: f64,
    sk: f64,
    ck: f64,
    a: [f64; 4],
    b0: [f64; 4],
    bv: [f64; 4],
}

impl Pass {
    #[allow(clippy::too_many_arguments)]
    fn new(
        g: &EdgeSlice,
        k: &CuttingCoefficients,
        (sa, ca): (f64, f64),
        ch: f64,
        cv: f64,
        eps: f64,
    ) -> Pass {
        Pass {
            eps,
            sa,
            ca,
            ch,
            cv,
            sk: g.sin_kappa,
            ck: g.cos_kappa,
            a: [
                k.ktc * g.dz,
                -k.krc * g.int_sin + k.kac * g.int_cos,
                k.krc * g.int_cos + k.kac * g.int_sin,
                k.ktc * g.int_r_dz,
            ],
            b0: [
                k.kte * g.edge_length,
                -k.kre * g.dz + k.kae * g.radius_rise,
                k.kre * g.radius_rise + k.kae * g.dz,
                k.kte * g.int_r_ds,
            ],
            bv: [
                -k.ktc * g.int_cot,
                k.krc * g.int_cos - k.kac * g.int_cos2_sin,
                -k.krc * g.int_cos2_sin - k.kac * g.int_cos,
                -k.ktc * g.int_r_cot,
            ],
        }
    }

    /// (h at the slice centre, X, V) of the chip this tooth cuts at sin φ: the thinnest over
    /// the surfaces left 1..N teeth earlier.
    #[inline(always)]
    fn chip(&self, steps: &[f64], sphi: f64) -> (f64, f64, f64) {
        let x0 = self.ch * sphi;
        if steps.is_empty() {
            return (x0 * self.sk - self.cv * self.ck, x0, self.cv);
        }
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for (m, d) in steps.iter().enumerate() {
            let mf = (m + 1) as f64;
            let x = mf * x0 + d;
            let v = mf * self.cv;
            let h = x * self.sk - v * self.ck;
            if h < best.0 {
                best = (h, x, v);
            }
        }
        best
    }

    #[inline(always)]
    fn force(&self, x: f64, v: f64, sphi: f64, cphi: f64) -> [f64; 4] {
        let ft = self.a[0] * x + self.b0[0] + self.bv[0] * v;
        let fp = self.a[1] * x + self.b0[1] + self.bv[1] * v;
        let fz = self.a[2] * x + self.b0[2] + self.bv[2] * v;
        let tq = self.a[3] * x + self.b0[3] + self.bv[3] * v;
        [fp * sphi - ft * cphi, ft * sphi + fp * cphi, fz, tq]
    }

    /// Force at the immersion φ with sin φ = `s`, cos φ = `c`, zero where the tooth does not
    /// cut.
    #[inline]
    fn force_at_sin_cos(&self, steps: &[f64], s: f64, c: f64) -> [f64; 4] {
        let (h, x, v) = self.chip(steps, s);
        if h >= -self.eps {
            self.force(x, v, s, c)
        } else {
            [0.0; 4]
        }
    }
}

/// Adds one tooth's forces over a contiguous run of sample positions (sin θ, cos θ in
/// `st`, `ct`). Without runout every component is affine in sin φ; branch-free and without
/// reductions so it vectorizes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn run_segment(
    p: &Pass,
    steps: &[f64],
    st: &[f64],
    ct: &[f64],
    fx: &mut [f64],
    fy: &mut [f64],
    fz: &mut [f64],
    tq: &mut [f64],
    scratch: &mut [f64],
) {
    let n = st.len();
    let (ct, fx, fy, fz, tq) = (
        &ct[..n],
        &mut fx[..n],
        &mut fy[..n],
        &mut fz[..n],
        &mut tq[..n],
    );
    let (sa, ca) = (p.sa, p.ca);
    if steps.is_empty() {
        let (hs, hv) = (p.ch * p.sk, p.cv * p.ck);
        let a = p.a.map(|v| v * p.ch);
        let b = [0, 1, 2, 3].map(|i| p.b0[i] + p.bv[i] * p.cv);
        for i in 0..n {
            let s = st[i] * ca - ct[i] * sa;
            let c = ct[i] * ca + st[i] * sa;
            let on = if hs * s - hv >= -p.eps { 1.0 } else { 0.0 };
            let ft = (a[0] * s + b[0]) * on;
            let fp = (a[1] * s + b[1]) * on;
            fx[i] += fp * s - ft * c;
            fy[i] += ft * s + fp * c;
            fz[i] += (a[2] * s + b[2]) * on;
            tq[i] += (a[3] * s + b[3]) * on;
        }
    } else {
        // Runout: the thinnest of the N candidate chips, found one candidate at a time over
        // the whole run (branch-free selects that vectorize) in scratch buffers.
        let (sb, rest) = scratch.split_at_mut(n);
        let (cb, rest) = rest.split_at_mut(n);
        let (bh, rest) = rest.split_at_mut(n);
        let (bm, rest) = rest.split_at_mut(n);
        let bd = &mut rest[..n];
        for i in 0..n {
            sb[i] = st[i] * ca - ct[i] * sa;
            cb[i] = ct[i] * ca + st[i] * sa;
            bh[i] = f64::INFINITY;
            bm[i] = 0.0;
            bd[i] = 0.0;
        }
        let (hs, hv) = (p.ch * p.sk, p.cv * p.ck);
        for (m, &d) in steps.iter().enumerate() {
            let mf = (m + 1) as f64;
            let e = d * p.sk;
            for i in 0..n {
                let h = mf * (hs * sb[i] - hv) + e;
                let better = h < bh[i];
                bh[i] = if better { h } else { bh[i] };
                bm[i] = if better { mf } else { bm[i] };
                bd[i] = if better { d } else { bd[i] };
            }
        }
        for i in 0..n {
            let (s, c) = (sb[i], cb[i]);
            let on = if bh[i] >= -p.eps { 1.0 } else { 0.0 };
            let x = bm[i] * p.ch * s + bd[i];
            let v = bm[i] * p.cv;
            let f = p.force(x, v, s, c);
            fx[i] += f[0] * on;
            fy[i] += f[1] * on;
            fz[i] += f[2] * on;
            tq[i] += f[3] * on;
        }
    }
}

/// (sin φ, cos φ) at sample position `k` for a tooth at α (φ = k·Δ − α), from the tables
/// of the positions' sin and cos and (sin α, cos α): the rotation `run_segment` uses,
/// without a call to sin or cos.
#[inline]
fn sample_sin_cos(st: &[f64], ct: &[f64], k: i64, sa: f64, ca: f64) -> (f64, f64) {
    let i = k.rem_euclid(st.len() as i64) as usize;
    (st[i] * ca - ct[i] * sa, ct[i] * ca + st[i] * sa)
}

/// Largest sin φ over the samples k = k0..k0+count (φ = k·Δ − α): at the sample nearest a
/// crest φ ≡ π/2 inside the run, else at an end (sin is unimodal between troughs). The chip
/// grows with sin φ (with runout too), so this gives the largest chip without a reduction in
/// the inner loop.
fn max_sin(st: &[f64], ct: &[f64], k0: i64, count: usize, sa: f64, ca: f64, alpha: f64) -> f64 {
    let delta = TAU / st.len() as f64;
    let sin_at = |j: i64| sample_sin_cos(st, ct, k0 + j, sa, ca).0;
    let last = count as i64 - 1;
    let mut best = sin_at(0).max(sin_at(last));
    let phi0 = k0 as f64 * delta - alpha;
    let phi1 = phi0 + last as f64 * delta;
    let crest = FRAC_PI_2 + TAU * ((phi0 - FRAC_PI_2) / TAU).ceil();
    if crest <= phi1 {
        let i = ((crest - phi0) / delta).floor() as i64;
        for j in [i, i + 1] {
            if (0..=last).contains(&j) {
                best = best.max(sin_at(j));
            }
        }
    }
    best
}

/// The four component blocks (fx, fy, fz, torque) of `len` each of a sample buffer (empty
/// slices for an unused buffer).
fn four_blocks(buf: &mut [f64], len: usize) -> [&mut [f64]; 4] {
    if buf.is_empty() {
        return [&mut [], &mut [], &mut [], &mut []];
    }
    let (x, rest) = buf.split_at_mut(len);
    let (y, rest) = rest.split_at_mut(len);
    let (z, t) = rest.split_at_mut(len);
    [x, y, z, t]
}

/// What one accumulation over the engagement's slices gives besides the per-tooth samples.
#[derive(Clone, Copy)]
struct Accumulated {
    /// Boundary-bin corrections that turn the sample sum into the time integral.
    corr: [f64; 4],
    engaged: usize,
    skipped: usize,
    /// Only tooth 1 was computed; tooth j is it shifted by j pitches.
    symmetric: bool,
}

/// Sums the teeth's samples (`acc`: four blocks of N·K) into `tot` (four blocks of K); with
/// the symmetry shortcut tooth j is row 1 shifted by j pitches.
fn tooth_totals(acc: &[f64], n: usize, kpos: usize, symmetric: bool, tot: &mut [f64]) {
    let nk = n * kpos;
    let shift = if symmetric { kpos / n } else { 0 };
    tot.fill(0.0);
    for c in 0..4 {
        let tot = &mut tot[c * kpos..(c + 1) * kpos];
        for j in 0..n {
            let (row, s) = if symmetric {
                (&acc[c * nk..c * nk + kpos], (j * shift) % kpos)
            } else {
                (&acc[c * nk + j * kpos..c * nk + (j + 1) * kpos], 0)
            };
            for (t, r) in tot[s..].iter_mut().zip(&row[..kpos - s]) {
                *t += r;
            }
            for (t, r) in tot[..s].iter_mut().zip(&row[kpos - s..]) {
                *t += r;
            }
        }
    }
}

/// Peak |F|, peak torque and the thickest chip of one engagement as functions of the feed
/// per tooth fz over a range, for a tool without runout: each sample's force is fz·A + E,
/// so |F|² = a·fz² + 2b·fz + c and the torque a·fz + b. Only the samples that can hold
/// the peak somewhere in the range are kept: a sample is dropped when one of the samples
/// that peak at a few feeds across the range is at least as large over the whole range,
/// so the maximum over the kept samples is the maximum over all of them.
#[derive(Clone, Debug, PartialEq)]
pub struct PeakResponse {
    range: (f64, f64),
    force: Vec<[f64; 3]>,
    /// Torque, N·mm.
    torque: Vec<[f64; 2]>,
    /// Thickest chip per unit feed per tooth.
    chip: f64,
}

/// What [`PeakResponse::at`] gives: peak |F| (N), peak torque (N·m), thickest chip (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peaks {
    pub force: f64,
    pub torque: f64,
    pub chip: f64,
}

impl PeakResponse {
    fn new(
        tot_a: &[f64],
        tot_e: &[f64],
        kpos: usize,
        tooth_hmax: &[f64],
        range: (f64, f64),
    ) -> PeakResponse {
        let comp = |t: &[f64], c: usize, i: usize| t[c * kpos + i];
        let mut quads = Vec::with_capacity(kpos);
        let mut lines = Vec::with_capacity(kpos);
        for i in 0..kpos {
            let a = [0, 1, 2].map(|c| comp(tot_a, c, i));
            let e = [0, 1, 2].map(|c| comp(tot_e, c, i));
            quads.push([dot(a, a), dot(a, e), dot(e, e)]);
            lines.push([comp(tot_a, 3, i), comp(tot_e, 3, i)]);
        }
        let (lo, hi) = range;
        let quad = |q: &[f64; 3], t: f64| (q[0] * t + 2.0 * q[1]) * t + q[2];
        let line = |l: &[f64; 2], t: f64| l[0] * t + l[1];
        // Leaders: the largest sample at a few feeds across the range.
        const PROBES: usize = 5;
        let probes: [f64; PROBES] = [0.0, 1.0, 0.5, 0.25, 0.75].map(|w| lo + w * (hi - lo));
        let (mut fl, mut fv) = ([0usize; PROBES], [f64::NEG_INFINITY; PROBES]);
        let (mut tl, mut tv) = ([0usize; PROBES], [f64::NEG_INFINITY; PROBES]);
        for i in 0..kpos {
            for p in 0..PROBES {
                let (q, l) = (quad(&quads[i], probes[p]), line(&lines[i], probes[p]));
                if q > fv[p] {
                    (fv[p], fl[p]) = (q, i);
                }
                if l > tv[p] {
                    (tv[p], tl[p]) = (l, i);
                }
            }
        }
        // A lower bound of the envelope over the range: the largest leader minimum. |F|² is
        // convex in the feed and the torque affine, so a sample's maximum over the range is
        // at an end; a sample whose ends stay under that bound cannot hold the peak.
        let quad_min = |q: &[f64; 3]| {
            let mut m = quad(q, lo).min(quad(q, hi));
            if q[0] > 0.0 {
                let v = -q[1] / q[0];
                if v > lo && v < hi {
                    m = m.min(quad(q, v));
                }
            }
            m
        };
        let force_floor = fl
            .iter()
            .map(|&j| quad_min(&quads[j]))
            .fold(f64::NEG_INFINITY, f64::max);
        let torque_floor = tl
            .iter()
            .map(|&j| line(&lines[j], lo).min(line(&lines[j], hi)))
            .fold(f64::NEG_INFINITY, f64::max);
        // q_j ≥ q_i over [lo, hi]: the difference, a parabola, is ≥ 0 at the ends and, when it
        // opens upwards with its vertex inside, at the vertex.
        let covers = |j: usize, i: usize| {
            let (qj, qi) = (&quads[j], &quads[i]);
            quad_min(&[qj[0] - qi[0], qj[1] - qi[1], qj[2] - qi[2]]) >= 0.0
        };
        let force = (0..kpos)
            .filter(|&i| {
                if fl.contains(&i) {
                    return true;
                }
                let top = quad(&quads[i], lo).max(quad(&quads[i], hi));
                top > force_floor && !fl.iter().any(|&j| covers(j, i))
            })
            .map(|i| quads[i])
            .collect();
        let torque = (0..kpos)
            .filter(|&i| {
                if tl.contains(&i) {
                    return true;
                }
                let (a, b) = (line(&lines[i], lo), line(&lines[i], hi));
                a.max(b) > torque_floor
                    && !tl
                        .iter()
                        .any(|&j| line(&lines[j], lo) >= a && line(&lines[j], hi) >= b)
            })
            .map(|i| lines[i])
            .collect();
        PeakResponse {
            range,
            force,
            torque,
            chip: tooth_hmax.iter().copied().fold(0.0, f64::max),
        }
    }

    /// The feed-per-tooth range the response holds for, mm.
    pub fn range(&self) -> (f64, f64) {
        self.range
    }

    /// Peaks at feed per tooth `fz` (mm), None outside the range.
    pub fn at(&self, fz: f64) -> Option<Peaks> {
        let (lo, hi) = self.range;
        if !(fz >= lo * (1.0 - 1e-12) && fz <= hi * (1.0 + 1e-12)) {
            return None;
        }
        let f2 = self
            .force
            .iter()
            .map(|q| (q[0] * fz + 2.0 * q[1]) * fz + q[2])
            .fold(0.0, f64::max);
        let t = self
            .torque
            .iter()
            .map(|l| l[0] * fz + l[1])
            .fold(f64::NEG_INFINITY, f64::max);
        Some(Peaks {
            force: f2.sqrt(),
            torque: t * 1e-3,
            chip: (self.chip * fz).max(0.0),
        })
    }
}

/// The force model for one tool: edge table, angular grid and reusable buffers. Build
/// once per tool, then call [`ForceModel::evaluate`] (or `evaluate_into`, which reuses the
/// result's buffers) at every engagement step. Single-threaded and deterministic; run
/// several models on several threads to go wider.
#[derive(Clone, Debug)]
pub struct ForceModel {
    table: ToolEdgeTable,
    positions: usize,
    sin_t: Vec<f64>,
    cos_t: Vec<f64>,
    /// Per tooth, per position: fx, fy, fz, torque (N·mm), in four blocks of N·K.
    acc: Vec<f64>,
    /// Totals over teeth per position, four blocks of K.
    tot: Vec<f64>,
    /// The edge part's samples and totals for `evaluate_with_response`.
    acc_edge: Vec<f64>,
    tot_edge: Vec<f64>,
    /// Five buffers of K for the runout kernel.
    scratch: Vec<f64>,
    tooth_hmax: Vec<f64>,
    keep_samples: bool,
}

impl ForceModel {
    /// `slice_count` uniform slices over the flute length for the table (engagement slices
    /// on another grid still work) and `positions` angular positions per revolution.
    pub fn new(
        tool: &Tool,
        slice_count: usize,
        positions: usize,
    ) -> Result<ForceModel, PhysicsError> {
        ForceModel::from_table(ToolEdgeTable::new(tool, slice_count)?, positions)
    }

    pub fn from_table(table: ToolEdgeTable, positions: usize) -> Result<ForceModel, PhysicsError> {
        if !(4..=1_000_000).contains(&positions) {
            return Err(PhysicsError::invalid(
                "positions",
                format!("must be in 4..=1000000, got {positions}"),
            ));
        }
        let d = TAU / positions as f64;
        let (sin_t, cos_t) = (0..positions).map(|k| (k as f64 * d).sin_cos()).unzip();
        let n = table.flutes;
        Ok(ForceModel {
            positions,
            sin_t,
            cos_t,
            acc: vec![0.0; 4 * n * positions],
            tot: vec![0.0; 4 * positions],
            acc_edge: Vec::new(),
            tot_edge: Vec::new(),
            scratch: vec![0.0; 5 * positions],
            tooth_hmax: vec![0.0; n],
            table,
            keep_samples: true,
        })
    }

    /// Whether results carry the per-position samples (default true). Turning them off
    /// saves the copy when only the statistics are needed.
    pub fn keep_samples(mut self, keep: bool) -> ForceModel {
        self.keep_samples = keep;
        self
    }

    pub fn table(&self) -> &ToolEdgeTable {
        &self.table
    }

    pub fn positions(&self) -> usize {
        self.positions
    }

    pub fn evaluate(
        &mut self,
        engagement: &Engagement,
        coefficients: &CuttingCoefficients,
        conditions: &CuttingConditions,
    ) -> Result<ForceResult, PhysicsError> {
        let mut out = ForceResult::default();
        self.evaluate_into(engagement, coefficients, conditions, &mut out)?;
        Ok(out)
    }

    /// As [`evaluate`](Self::evaluate), writing into `out` and reusing its allocations.
    pub fn evaluate_into(
        &mut self,
        engagement: &Engagement,
        k: &CuttingCoefficients,
        conditions: &CuttingConditions,
        out: &mut ForceResult,
    ) -> Result<(), PhysicsError> {
        k.validate()?;
        conditions.validate()?;
        validate_slices(engagement)?;
        let frame = Self::frame_of(engagement)?;
        let fz = conditions.feed_per_tooth;
        let (acc, _) = self.accumulate(engagement, k, None, &frame, fz);
        self.summarize(frame, conditions, acc, out);
        Ok(())
    }

    /// The forces of `engagement` at `conditions` into `out`, as `evaluate_into` gives them,
    /// and, for a tool without runout, the peak |F|, torque and chip as exact functions of
    /// the feed per tooth for feeds in `fz_range` (mm): every chip is then the feed per tooth
    /// times a shape factor, so each sample's force is fz·A + E (cutting and edge parts).
    /// With runout the response is None (the chip is not proportional to the feed).
    pub fn evaluate_with_response(
        &mut self,
        engagement: &Engagement,
        k: &CuttingCoefficients,
        conditions: &CuttingConditions,
        fz_range: (f64, f64),
        out: &mut ForceResult,
    ) -> Result<Option<PeakResponse>, PhysicsError> {
        if !self.table.runout_steps.is_empty() {
            self.evaluate_into(engagement, k, conditions, out)?;
            return Ok(None);
        }
        k.validate()?;
        conditions.validate()?;
        validate_slices(engagement)?;
        let (lo, hi) = fz_range;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi >= lo) {
            return Err(PhysicsError::invalid(
                "fz_range",
                format!("must be 0 < low <= high, got {lo}..{hi}"),
            ));
        }
        let frame = Self::frame_of(engagement)?;
        // Cutting part at unit feed per tooth, then the edge part: same samples cut in both.
        let cutting = CuttingCoefficients {
            kte: 0.0,
            kre: 0.0,
            kae: 0.0,
            ..*k
        };
        let edge = CuttingCoefficients {
            ktc: 0.0,
            krc: 0.0,
            kac: 0.0,
            ..*k
        };
        let (a, corr_e) = self.accumulate(engagement, &cutting, Some(&edge), &frame, 1.0);
        let fz = conditions.feed_per_tooth;
        // The totals per sample of each part, for the response.
        let (kpos, n) = (self.positions, self.table.flutes);
        let mut tot_a = std::mem::take(&mut self.tot);
        let mut tot_e = std::mem::take(&mut self.tot_edge);
        tot_a.resize(4 * kpos, 0.0);
        tot_e.resize(4 * kpos, 0.0);
        tooth_totals(&self.acc, n, kpos, a.symmetric, &mut tot_a);
        tooth_totals(&self.acc_edge, n, kpos, a.symmetric, &mut tot_e);
        let response = PeakResponse::new(&tot_a, &tot_e, kpos, &self.tooth_hmax, (lo, hi));
        self.tot = tot_a;
        self.tot_edge = tot_e;
        // The result at this feed: fz·A + E sample by sample.
        for (x, y) in self.acc.iter_mut().zip(&self.acc_edge) {
            *x = fz * *x + y;
        }
        for h in self.tooth_hmax.iter_mut() {
            *h *= fz;
        }
        let acc = Accumulated {
            corr: [0, 1, 2, 3].map(|c| fz * a.corr[c] + corr_e[c]),
            ..a
        };
        self.summarize(frame, conditions, acc, out);
        Ok(Some(response))
    }

    fn frame_of(engagement: &Engagement) -> Result<ToolFrame, PhysicsError> {
        if engagement.is_air() {
            Ok(ToolFrame::IDENTITY)
        } else {
            ToolFrame::from_engagement(engagement)
        }
    }

    /// Per tooth and sample, the forces of the engaged slices into `acc`, the thickest chip
    /// per tooth into `tooth_hmax`, with the boundary-bin corrections of the mean. With
    /// `edge` coefficients too, those go into `acc_edge` in the same pass (their corrections
    /// in the second entry): the slices' geometry is looked up once for both.
    fn accumulate(
        &mut self,
        engagement: &Engagement,
        k: &CuttingCoefficients,
        edge: Option<&CuttingCoefficients>,
        frame: &ToolFrame,
        fz: f64,
    ) -> (Accumulated, [f64; 4]) {
        let kpos = self.positions;
        let n = self.table.flutes;
        let delta = TAU / kpos as f64;
        let c_h = fz * frame.feed_across;
        let c_v = fz * frame.feed_along;
        let eps = if self.table.runout_steps.is_empty() {
            CHIP_EPS_PER_FEED * fz
        } else {
            CHIP_EPS
        };
        let channels = if edge.is_some() { 2 } else { 1 };
        for buf in [&mut self.acc, &mut self.acc_edge]
            .into_iter()
            .take(channels)
        {
            if buf.len() != 4 * n * kpos {
                *buf = vec![0.0; 4 * n * kpos];
            }
            buf.fill(0.0);
        }
        self.tooth_hmax.fill(f64::NEG_INFINITY);
        let mut bufs = [
            four_blocks(&mut self.acc, n * kpos),
            four_blocks(&mut self.acc_edge, n * kpos),
        ];
        let coefficients = [Some(k), edge];
        // Boundary-bin corrections that turn the sample sum into the time integral.
        let mut corr = [[0.0f64; 4]; 2];
        let mut engaged = 0usize;
        let mut skipped = 0usize;
        let no_steps: [f64; 0] = [];
        // Without runout every tooth repeats tooth 1 one pitch later; when the pitch is a
        // whole number of positions, compute tooth 1 only and copy it shifted.
        let symmetric = self.table.runout_steps.is_empty() && kpos.is_multiple_of(n);
        let computed_teeth = if symmetric { 1 } else { n };

        for s in &engagement.slices {
            if s.arcs.is_empty() {
                continue;
            }
            let Some(g) = self.table.slice(s.z, s.dz) else {
                skipped += 1;
                continue;
            };
            engaged += 1;
            for j in 0..computed_teeth {
                let alpha = j as f64 * self.table.pitch + g.lag;
                let sc = alpha.sin_cos();
                let passes = coefficients.map(|k| k.map(|k| Pass::new(&g, k, sc, c_h, c_v, eps)));
                let steps: &[f64] = if self.table.runout_steps.is_empty() {
                    &no_steps
                } else {
                    &self.table.runout_steps[j * n..(j + 1) * n]
                };
                let row = j * kpos..(j + 1) * kpos;
                for &(a, b) in &s.arcs {
                    // Sample k sees this tooth at φ = k·Δ − α: the arc covers index range [u, v].
                    let u = (a + alpha) / delta;
                    let v = (b + alpha) / delta;
                    let k_lo = (u - BOUNDARY_EPS).ceil();
                    let k_hi = (v + BOUNDARY_EPS).floor().min(k_lo + (kpos - 1) as f64);
                    if k_hi >= k_lo {
                        let count = (k_hi - k_lo) as usize + 1;
                        let start = (k_lo as i64).rem_euclid(kpos as i64) as usize;
                        let first = count.min(kpos - start);
                        let pieces = [start..start + first, 0..count - first];
                        for (p, [fx, fy, fz, tq]) in passes.iter().zip(bufs.iter_mut()) {
                            let Some(p) = p else { continue };
                            for seg in pieces.iter().filter(|r| !r.is_empty()) {
                                let at = |r: &std::ops::Range<usize>| {
                                    row.start + r.start..row.start + r.end
                                };
                                run_segment(
                                    p,
                                    steps,
                                    &self.sin_t[seg.clone()],
                                    &self.cos_t[seg.clone()],
                                    &mut fx[at(seg)],
                                    &mut fy[at(seg)],
                                    &mut fz[at(seg)],
                                    &mut tq[at(seg)],
                                    &mut self.scratch,
                                );
                            }
                        }
                        let p = passes[0].as_ref().expect("the first channel is always on");
                        let top = max_sin(
                            &self.sin_t,
                            &self.cos_t,
                            k_lo as i64,
                            count,
                            p.sa,
                            p.ca,
                            alpha,
                        );
                        let (h, _, _) = p.chip(steps, top);
                        self.tooth_hmax[j] = self.tooth_hmax[j].max(h);
                    }
                    // Bins k cover [k − ½, k + ½]; the two the arc's ends fall in are partly covered.
                    let kb0 = (u + 0.5).floor();
                    let kb1 = (v + 0.5).floor();
                    for (i, kb) in [kb0, kb1].into_iter().enumerate() {
                        if i == 1 && kb == kb0 {
                            break;
                        }
                        let lo = (kb - 0.5).max(u);
                        let hi = (kb + 0.5).min(v);
                        let w = hi - lo;
                        if w >= 1.0 - 1e-12 {
                            continue;
                        }
                        let sample = (kb >= k_lo && kb <= k_hi).then(|| {
                            sample_sin_cos(&self.sin_t, &self.cos_t, kb as i64, sc.0, sc.1)
                        });
                        let mid = (w > 0.0).then(|| (0.5 * (lo + hi) * delta - alpha).sin_cos());
                        for (p, corr) in passes.iter().zip(corr.iter_mut()) {
                            let Some(p) = p else { continue };
                            if let Some((sk, ck)) = sample {
                                let f = p.force_at_sin_cos(steps, sk, ck);
                                for c in 0..4 {
                                    corr[c] -= f[c];
                                }
                            }
                            if let Some((sm, cm)) = mid {
                                let f = p.force_at_sin_cos(steps, sm, cm);
                                for c in 0..4 {
                                    corr[c] += w * f[c];
                                }
                            }
                        }
                    }
                }
            }
        }
        if symmetric && n > 1 {
            let h0 = self.tooth_hmax[0];
            self.tooth_hmax.fill(h0);
            for c in corr.iter_mut().flatten() {
                *c *= n as f64;
            }
        }
        let [corr, corr_edge] = corr;
        (
            Accumulated {
                corr,
                engaged,
                skipped,
                symmetric,
            },
            corr_edge,
        )
    }

    fn summarize(
        &mut self,
        frame: ToolFrame,
        conditions: &CuttingConditions,
        acc: Accumulated,
        out: &mut ForceResult,
    ) {
        let Accumulated {
            corr,
            engaged,
            skipped,
            symmetric,
        } = acc;
        let kpos = self.positions;
        let n = self.table.flutes;
        let delta = TAU / kpos as f64;
        let omega = conditions.omega();
        let nk = n * kpos;
        tooth_totals(&self.acc, n, kpos, symmetric, &mut self.tot);
        let rows = if symmetric { 1 } else { n };
        let mut tooth_peak = [0.0f64; 64];
        for (j, peak) in tooth_peak.iter_mut().enumerate().take(rows) {
            let row = |c: usize| &self.acc[c * nk + j * kpos..c * nk + (j + 1) * kpos];
            let (x, y, z) = (row(0), row(1), row(2));
            let mut m = 0.0f64;
            for k in 0..kpos {
                m = m.max(x[k] * x[k] + y[k] * y[k] + z[k] * z[k]);
            }
            *peak = m.sqrt();
        }
        if symmetric {
            let p = tooth_peak[0];
            tooth_peak[..n].fill(p);
        }
        let (tx, rest) = self.tot.split_at(kpos);
        let (ty, rest) = rest.split_at(kpos);
        let (tz, tt) = rest.split_at(kpos);

        out.positions = kpos;
        out.samples.clear();
        out.per_tooth.clear();
        out.per_tooth.extend((0..n).map(|j| ToothStats {
            tooth: j + 1,
            peak_force: tooth_peak[j],
            max_chip_thickness: self.tooth_hmax[j].max(0.0),
        }));
        let mut sum = [0.0f64; 4];
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut plo = [f64::INFINITY; 3];
        let mut phi = [f64::NEG_INFINITY; 3];
        let (mut fsum, mut fpeak, mut xysum, mut xypeak, mut tpeak) =
            (0.0, 0.0, 0.0, 0.0, f64::NEG_INFINITY);
        let mut peak_vec = [0.0; 3];
        for k in 0..kpos {
            let f = [tx[k], ty[k], tz[k], tt[k]];
            for c in 0..4 {
                sum[c] += f[c];
            }
            let v = [f[0], f[1], f[2]];
            let p = frame.to_part(v);
            for c in 0..3 {
                lo[c] = lo[c].min(f[c]);
                hi[c] = hi[c].max(f[c]);
                plo[c] = plo[c].min(p[c]);
                phi[c] = phi[c].max(p[c]);
            }
            let m = norm(v);
            fsum += m;
            if m > fpeak {
                fpeak = m;
                peak_vec = p;
            }
            let mxy = (f[0] * f[0] + f[1] * f[1]).sqrt();
            xysum += mxy;
            xypeak = f64::max(xypeak, mxy);
            tpeak = f64::max(tpeak, f[3]);
            if self.keep_samples {
                out.samples.push(ForceSample {
                    angle: k as f64 * delta,
                    fx: f[0],
                    fy: f[1],
                    fz: f[2],
                    torque: f[3] * 1e-3,
                });
            }
        }
        let kf = kpos as f64;
        let mean: Vec<f64> = (0..4).map(|c| (sum[c] + corr[c]) / kf).collect();
        out.fx = AxisStats {
            mean: mean[0],
            min: lo[0],
            max: hi[0],
        };
        out.fy = AxisStats {
            mean: mean[1],
            min: lo[1],
            max: hi[1],
        };
        out.fz = AxisStats {
            mean: mean[2],
            min: lo[2],
            max: hi[2],
        };
        let mp = frame.to_part([mean[0], mean[1], mean[2]]);
        out.part = [0, 1, 2].map(|c| AxisStats {
            mean: mp[c],
            min: plo[c],
            max: phi[c],
        });
        out.mean_force_part = mp;
        out.peak_force_part = peak_vec;
        out.force = MagnitudeStats {
            mean: fsum / kf,
            peak: fpeak,
        };
        out.force_xy = MagnitudeStats {
            mean: xysum / kf,
            peak: xypeak,
        };
        let t_mean = mean[3] * 1e-3;
        let t_peak = tpeak * 1e-3;
        out.torque = MagnitudeStats {
            mean: t_mean,
            peak: t_peak,
        };
        out.power = MagnitudeStats {
            mean: t_mean * omega,
            peak: t_peak * omega,
        };
        out.max_chip_thickness = out
            .per_tooth
            .iter()
            .map(|t| t.max_chip_thickness)
            .fold(0.0, f64::max);
        out.frame = Some(frame);
        out.engaged_slices = engaged;
        out.skipped_slices = skipped;
    }
}

fn validate_slices(e: &Engagement) -> Result<(), PhysicsError> {
    for (i, s) in e.slices.iter().enumerate() {
        if !s.z.is_finite() {
            return Err(PhysicsError::NotFinite {
                field: format!("slices[{i}].z"),
                value: s.z,
            });
        }
        if !(s.dz.is_finite() && s.dz > 0.0) {
            return Err(PhysicsError::invalid(
                format!("slices[{i}].dz"),
                format!("must be a positive number, got {}", s.dz),
            ));
        }
        for (a, &(p, q)) in s.arcs.iter().enumerate() {
            if !(p.is_finite() && q.is_finite()) {
                return Err(PhysicsError::NotFinite {
                    field: format!("slices[{i}].arcs[{a}]"),
                    value: if p.is_finite() { q } else { p },
                });
            }
            // The Engagement keeps arcs within [0, 2π); allow a wrapped copy either side.
            if !(q > p && q - p <= TAU + 1e-9 && p >= -TAU && q <= 2.0 * TAU) {
                return Err(PhysicsError::invalid(
                    format!("slices[{i}].arcs[{a}]"),
                    format!(
                        "must satisfy −2π ≤ entry < exit ≤ min(entry + 2π, 4π), got ({p}, {q})"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// One-shot convenience: evaluates once with every slice's geometry computed from the
/// engagement (no table to build). For repeated use keep a [`ForceModel`].
pub fn cutting_forces(
    tool: &Tool,
    engagement: &Engagement,
    coefficients: &CuttingCoefficients,
    conditions: &CuttingConditions,
    positions: usize,
) -> Result<ForceResult, PhysicsError> {
    let table = ToolEdgeTable::with_slice_height(tool, tool.flute_length)?;
    ForceModel::from_table(table, positions)?.evaluate(engagement, coefficients, conditions)
}

/// One point of a block's down-sampled force trace: the steps it stands for and their
/// extremes, for plotting.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TracePoint {
    /// First step (0-based within the block) and number of steps merged into this point.
    pub first_step: usize,
    pub steps: usize,
    /// Largest peak |F| among them, N.
    pub peak_force: f64,
    /// Average of their mean |F|, N.
    pub mean_force: f64,
    /// Largest peak power, W.
    pub peak_power: f64,
}

/// Aggregates of the force results of one block's steps plus a down-sampled trace of at
/// most `capacity` points (adjacent points merge pairwise when it fills; extremes survive).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockForces {
    pub steps: usize,
    pub air_steps: usize,
    /// Part-frame X, Y, Z: mean over steps, extremes over all samples.
    pub part: [AxisStats; 3],
    pub force: MagnitudeStats,
    pub torque: MagnitudeStats,
    pub power: MagnitudeStats,
    pub max_chip_thickness: f64,
    pub trace: Vec<TracePoint>,
    capacity: usize,
    stride: usize,
    pending: Option<TracePoint>,
}

impl BlockForces {
    pub fn new(capacity: usize) -> BlockForces {
        BlockForces {
            steps: 0,
            air_steps: 0,
            part: [AxisStats {
                mean: 0.0,
                min: f64::INFINITY,
                max: f64::NEG_INFINITY,
            }; 3],
            force: MagnitudeStats::default(),
            torque: MagnitudeStats::default(),
            power: MagnitudeStats::default(),
            max_chip_thickness: 0.0,
            trace: Vec::new(),
            capacity: capacity.max(2),
            stride: 1,
            pending: None,
        }
    }

    /// Adds the next step (steps are taken as equally long).
    pub fn push(&mut self, r: &ForceResult) {
        let i = self.steps;
        self.steps += 1;
        if r.is_air() {
            self.air_steps += 1;
        }
        let w = 1.0 / self.steps as f64;
        let run = |m: &mut f64, x: f64| *m += (x - *m) * w;
        for c in 0..3 {
            let a = &mut self.part[c];
            run(&mut a.mean, r.part[c].mean);
            a.min = a.min.min(r.part[c].min);
            a.max = a.max.max(r.part[c].max);
        }
        run(&mut self.force.mean, r.force.mean);
        run(&mut self.torque.mean, r.torque.mean);
        run(&mut self.power.mean, r.power.mean);
        self.force.peak = self.force.peak.max(r.force.peak);
        self.torque.peak = self.torque.peak.max(r.torque.peak);
        self.power.peak = self.power.peak.max(r.power.peak);
        self.max_chip_thickness = self.max_chip_thickness.max(r.max_chip_thickness);
        let point = TracePoint {
            first_step: i,
            steps: 1,
            peak_force: r.force.peak,
            mean_force: r.force.mean,
            peak_power: r.power.peak,
        };
        let merged = match self.pending.take() {
            Some(p) => merge(p, point),
            None => point,
        };
        if merged.steps >= self.stride {
            self.trace.push(merged);
            if self.trace.len() >= self.capacity {
                self.trace = self
                    .trace
                    .chunks(2)
                    .map(|c| {
                        if c.len() == 2 {
                            merge(c[0], c[1])
                        } else {
                            c[0]
                        }
                    })
                    .collect();
                self.stride *= 2;
            }
        } else {
            self.pending = Some(merged);
        }
    }

    /// The trace including a partly filled last point.
    pub fn finish(mut self) -> BlockForces {
        if let Some(p) = self.pending.take() {
            self.trace.push(p);
        }
        if self.steps == 0 {
            self.part = [AxisStats::default(); 3];
        }
        self
    }
}

fn merge(a: TracePoint, b: TracePoint) -> TracePoint {
    let steps = a.steps + b.steps;
    TracePoint {
        first_step: a.first_step,
        steps,
        peak_force: a.peak_force.max(b.peak_force),
        mean_force: (a.mean_force * a.steps as f64 + b.mean_force * b.steps as f64) / steps as f64,
        peak_power: a.peak_power.max(b.peak_power),
    }
}
