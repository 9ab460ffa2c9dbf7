//! Identification from steady test cuts of any tool the force model takes: each cut's
//! engagement is built from its depth and immersion, the model evaluates it with unit
//! coefficients, and [`fit_unit_forces`] solves for the coefficients.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::lsq::{fit_unit_forces, ForceLaw, ModelIdentification, UnitForces};
use crate::engagement::{EngagedSlice, Engagement};
use crate::physics::force::{CuttingConditions, ForceModel, ForceResult, DEFAULT_POSITIONS};
use crate::physics::material::CuttingCoefficients;
use crate::physics::{finite, positive, PhysicsError};
use crate::tool::Tool;

/// Most cuts one identification takes: a test campaign has tens.
pub const MAX_CUTS: usize = 10_000;

/// Axial slices per mm of depth of a test cut's engagement (at least 40 per cut, at most
/// 1000): at 0.025 mm a ball slot's small kae came out 0.9% off the same model at 0.01 mm,
/// at 0.01 mm 0.2% (the rest from the angular grid).
const SLICES_PER_MM: f64 = 100.0;

/// Where a straight steady cut engages the tool.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Immersion {
    /// The same immersion interval at every height (rad, docs/reference.md convention: a slot is
    /// 0 to π, down-milling half immersion π/2 to π, up-milling 0 to π/2).
    Angles { entry: f64, exit: f64 },
    /// A side cut against a vertical wall of the stock `width` mm into it (from the tool's
    /// largest radius), the floor at the depth: each height's ring of radius r(z) engages
    /// where it reaches past the wall, so a ball or bull-nose engages less near its tip.
    /// Down milling (climb, material on the −y side, teeth leave the cut at π) or up.
    Width { width: f64, down_milling: bool },
}

/// One steady straight test cut and the mean force measured on it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct IdentificationCut {
    /// Axial depth of cut from the tool's tip, mm.
    pub depth: f64,
    pub immersion: Immersion,
    /// mm.
    pub feed_per_tooth: f64,
    /// Mean force on the tool over a revolution in the Engagement frame (x feed, y = z × x,
    /// z the tool axis), N: a dynamometer under the part measures the reaction.
    pub force: [f64; 3],
}

/// The engagement of a steady straight cut at `depth` with `immersion` (horizontal feed
/// along x, vertical tool axis): uniform slices from the tip up, the slices that do not
/// reach material left out.
pub fn steady_cut_engagement(
    tool: &Tool,
    depth: f64,
    immersion: Immersion,
) -> Result<Engagement, PhysicsError> {
    tool.validate()?;
    positive("depth", depth)?;
    if depth > tool.flute_length + 1e-9 {
        return Err(PhysicsError::invalid(
            "depth",
            format!(
                "{depth} mm is deeper than the tool's flute length {} mm",
                tool.flute_length
            ),
        ));
    }
    let count = (depth * SLICES_PER_MM).ceil().clamp(40.0, 1000.0) as usize;
    let dz = depth / count as f64;
    let r_max = tool.radius();
    let mut slices = Vec::with_capacity(count);
    match immersion {
        Immersion::Angles { entry, exit } => {
            finite("entry", entry)?;
            finite("exit", exit)?;
            if !(0.0 <= entry && entry < exit && exit <= PI + 1e-12) {
                return Err(PhysicsError::invalid(
                    "exit",
                    format!("need 0 ≤ entry < exit ≤ π, got {entry} and {exit}"),
                ));
            }
        }
        Immersion::Width { width, .. } => {
            positive("width", width)?;
            if width > 2.0 * r_max + 1e-9 {
                return Err(PhysicsError::invalid(
                    "width",
                    format!(
                        "{width} mm is wider than the tool's diameter {} mm",
                        2.0 * r_max
                    ),
                ));
            }
        }
    }
    for i in 0..count {
        let z = (i as f64 + 0.5) * dz;
        let arc = match immersion {
            Immersion::Angles { entry, exit } => Some((entry, exit.min(PI))),
            Immersion::Width {
                width,
                down_milling,
            } => {
                // The wall at distance R − w from the axis; the ring reaches past it over
                // |cos φ| ≥ (R − w)/r on the material's side, ahead of the tool (φ ≤ π).
                let r = tool.profile_radius(z);
                let wall = r_max - width;
                if r <= 0.0 || wall >= r {
                    None
                } else {
                    let c = (wall / r).clamp(-1.0, 1.0);
                    if down_milling {
                        Some(((-c).acos(), PI))
                    } else {
                        Some((0.0, c.acos()))
                    }
                }
            }
        };
        if let Some((a, b)) = arc.filter(|(a, b)| b > a) {
            slices.push(EngagedSlice {
                z,
                dz,
                arcs: vec![(a, b)].into(),
            });
        }
    }
    Ok(Engagement {
        slices,
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    })
}

/// Mean tool-frame forces of steady cuts with one coefficient at 1.
struct CutResponses {
    model: ForceModel,
    engagements: Vec<Engagement>,
    feeds: Vec<f64>,
    out: ForceResult,
}

impl UnitForces for CutResponses {
    fn observations(&self) -> usize {
        self.engagements.len()
    }

    fn column(&mut self, j: usize, exponent: f64) -> Result<Vec<[f64; 3]>, PhysicsError> {
        let k = unit_coefficients(j, exponent);
        let mut col = Vec::with_capacity(self.engagements.len());
        for (e, &c) in self.engagements.iter().zip(&self.feeds) {
            // The mean force does not depend on the spindle speed.
            let conditions = CuttingConditions {
                spindle_rpm: 1000.0,
                feed_per_tooth: c,
            };
            self.model
                .evaluate_into(e, &k, &conditions, &mut self.out)?;
            col.push([self.out.fx.mean, self.out.fy.mean, self.out.fz.mean]);
        }
        Ok(col)
    }
}

/// Coefficient `j` (ktc, krc, kac, kte, kre, kae) at 1, the others 0; a cutting one with
/// `exponent` as its size-effect exponent.
pub fn unit_coefficients(j: usize, exponent: f64) -> CuttingCoefficients {
    let mut unit = [0.0; 6];
    unit[j] = 1.0;
    let mut k = CuttingCoefficients::linear(unit);
    match j {
        0 => k.mtc = exponent,
        1 => k.mrc = exponent,
        2 => k.mac = exponent,
        _ => {}
    }
    k
}

/// A test cut's feed, depth and forces within a milling test's range (see
/// [`super::check_feed`]), named `cuts[i].…`; what can be told without the tool.
pub fn check_cut(i: usize, cut: &IdentificationCut) -> Result<(), PhysicsError> {
    super::check_feed(format!("cuts[{i}].feed_per_tooth"), cut.feed_per_tooth)?;
    super::check_depth(format!("cuts[{i}].depth"), cut.depth)?;
    for (c, v) in cut.force.iter().enumerate() {
        super::check_force(format!("cuts[{i}].{}", ["fx", "fy", "fz"][c]), *v)?;
    }
    Ok(())
}

/// Identifies the coefficients of `law` from steady test cuts with `tool` (any shape,
/// helix and runout as the tool has them).
pub fn identify_from_cuts(
    tool: &Tool,
    cuts: &[IdentificationCut],
    law: ForceLaw,
) -> Result<ModelIdentification, PhysicsError> {
    if cuts.len() > MAX_CUTS {
        return Err(PhysicsError::invalid(
            "cuts",
            format!("at most {MAX_CUTS} cuts, got {}", cuts.len()),
        ));
    }
    let mut engagements = Vec::with_capacity(cuts.len());
    for (i, cut) in cuts.iter().enumerate() {
        check_cut(i, cut)?;
        let e = steady_cut_engagement(tool, cut.depth, cut.immersion).map_err(|e| match e {
            PhysicsError::Invalid { field, message } => PhysicsError::Invalid {
                field: format!("cuts[{i}].{field}"),
                message,
            },
            PhysicsError::NotFinite { field, value } => PhysicsError::NotFinite {
                field: format!("cuts[{i}].{field}"),
                value,
            },
            e => e,
        })?;
        if e.is_air() {
            return Err(PhysicsError::invalid(
                format!("cuts[{i}]"),
                "the tool does not reach the material in this cut",
            ));
        }
        engagements.push(e);
    }
    let mut source = CutResponses {
        model: ForceModel::new(tool, 100, DEFAULT_POSITIONS)?.keep_samples(false),
        feeds: cuts.iter().map(|c| c.feed_per_tooth).collect(),
        engagements,
        out: ForceResult::default(),
    };
    let measured: Vec<[f64; 3]> = cuts.iter().map(|c| c.force).collect();
    let feeds = source.feeds.clone();
    fit_unit_forces(&mut source, &measured, &feeds, law, "cuts")
}
