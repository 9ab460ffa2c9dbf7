//! Theoretical (kinematic) surface roughness: the cusps the tool's shape leaves between
//! neighbouring passes (scallops, across the feed) and between neighbouring teeth (feed
//! marks, along the feed), with radial runout changing which tooth reaches furthest.
//!
//! Assumptions: tool axis normal to the floor; tooth paths approximated by circular arcs
//! (the trochoid's correction is of order N·fz/(π·R), below 1% for usual feeds); no
//! deflection, vibration or built-up edge. A flat end mill's ideal square corner leaves no
//! floor feed marks (real ones do through the dish angle, which the Tool does not describe).

use serde::{Deserialize, Serialize};

use super::{non_negative, PhysicsError};
use crate::tool::{Tool, ToolShape};

/// Scallop (cusp) height between two parallel passes `step_over` apart on a flat floor, mm.
pub fn scallop_height(tool: &Tool, step_over: f64) -> Result<f64, PhysicsError> {
    tool.validate()?;
    non_negative("step_over", step_over)?;
    if step_over > tool.diameter {
        return Err(PhysicsError::invalid(
            "step_over",
            format!(
                "{step_over} mm exceeds the tool diameter {} mm: ridges are left uncut",
                tool.diameter
            ),
        ));
    }
    Ok(match tool.shape {
        ToolShape::Flat => 0.0,
        ToolShape::Ball | ToolShape::BullNose => {
            // Corner arcs of the two passes meet half-way; the flat bottom (D − 2rc) covers the rest.
            let rc = tool.effective_corner_radius();
            cusp_height(rc, 0.5 * (step_over - (tool.diameter - 2.0 * rc)))
        }
        ToolShape::Chamfer | ToolShape::Drill => {
            let w = 0.5 * (step_over - tool.tip_diameter);
            if w <= 0.0 {
                0.0
            } else {
                w / tool.taper_half_angle_deg.to_radians().tan()
            }
        }
    })
}

/// Height of the cusp between two arcs of radius `r` whose centres are `2·half_spacing`
/// apart: r − sqrt(r² − half_spacing²), 0 when they do not meet above the centres' line.
pub fn cusp_height(r: f64, half_spacing: f64) -> f64 {
    if half_spacing <= 0.0 || r <= 0.0 {
        0.0
    } else {
        r - (r * r - half_spacing * half_spacing).max(0.0).sqrt()
    }
}

/// Peak-to-valley feed marks of `tool` at `feed_per_tooth`, mm: the larger of the floor's
/// (corner radius) and the wall's (periphery). Without runout each tooth cuts `fz` past the
/// one before, so the marks are the cusps of equal arcs; with it, [`feed_marks`]' envelope.
pub fn feed_mark_height(tool: &Tool, feed_per_tooth: f64) -> Result<f64, PhysicsError> {
    if tool.runout.offset == 0.0 {
        let half = 0.5 * non_negative("feed_per_tooth", feed_per_tooth)?;
        return Ok(
            cusp_height(tool.effective_corner_radius(), half).max(cusp_height(tool.radius(), half))
        );
    }
    let floor = feed_marks(tool, feed_per_tooth, SurfaceKind::Floor)?;
    let wall = feed_marks(tool, feed_per_tooth, SurfaceKind::Wall)?;
    Ok(floor.peak_to_valley.max(wall.peak_to_valley))
}

/// Which surface the feed marks are on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceKind {
    /// Floor cut by the corner radius: marks spaced by the feed per tooth.
    Floor,
    /// Side wall cut by the periphery (peripheral milling).
    Wall,
}

/// Feed-mark profile along the feed direction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeedMarks {
    /// Peak-to-valley height Rt, mm.
    pub peak_to_valley: f64,
    /// Arithmetic mean deviation Ra of the profile, mm.
    pub ra: f64,
    /// Largest spacing between neighbouring marks, mm: fz without runout, more with it
    /// (the tooth that reaches furthest removes more, the one after it less or nothing).
    pub max_effective_feed: f64,
}

/// Feed marks of `tool` at `feed_per_tooth` on `surface`, including the tool's runout.
pub fn feed_marks(
    tool: &Tool,
    feed_per_tooth: f64,
    surface: SurfaceKind,
) -> Result<FeedMarks, PhysicsError> {
    tool.validate()?;
    non_negative("feed_per_tooth", feed_per_tooth)?;
    let n = tool.flutes as usize;
    let pitch = std::f64::consts::TAU / n as f64;
    let rho = tool.runout.offset;
    let lambda = tool.runout.angle_deg.to_radians();
    // Same tooth numbering as the force model: tooth j trails by j pitches and passes the
    // front j·fz later; its radius is longer by Δ_j.
    let delta: Vec<f64> = (0..n)
        .map(|j| rho * (lambda + j as f64 * pitch).cos())
        .collect();
    let arcs: Vec<(f64, f64)> = match surface {
        SurfaceKind::Floor => {
            let rc = match tool.shape {
                ToolShape::Ball | ToolShape::BullNose => tool.effective_corner_radius(),
                ToolShape::Flat | ToolShape::Chamfer | ToolShape::Drill => 0.0,
            };
            // Radial runout moves each corner arc along the feed where it cuts the floor.
            (0..n)
                .map(|j| (j as f64 * feed_per_tooth + delta[j], rc))
                .collect()
        }
        SurfaceKind::Wall => (0..n)
            .map(|j| (j as f64 * feed_per_tooth, tool.radius() + delta[j]))
            .collect(),
    };
    let period = n as f64 * feed_per_tooth;
    if period <= 0.0 || arcs.iter().all(|a| a.1 <= 0.0) {
        return Ok(FeedMarks {
            peak_to_valley: 0.0,
            ra: 0.0,
            max_effective_feed: feed_per_tooth,
        });
    }
    Ok(envelope(&arcs, period))
}

/// Profile y(x) = max over arcs (and their copies one revolution apart) of
/// sqrt(r² − (x − x0)²), sampled over one period; depth 0 where no arc reaches.
fn envelope(arcs: &[(f64, f64)], period: f64) -> FeedMarks {
    const M: usize = 4096;
    let mut ys = Vec::with_capacity(M);
    let mut winners: Vec<f64> = Vec::new();
    for i in 0..M {
        let x = (i as f64 + 0.5) / M as f64 * period;
        let mut best = 0.0f64;
        let mut who = f64::NAN;
        for &(x0, r) in arcs {
            for p in -2..=2 {
                let d = x - (x0 + p as f64 * period);
                if d.abs() < r {
                    let y = (r * r - d * d).sqrt();
                    if y > best {
                        best = y;
                        who = (x0 + p as f64 * period).rem_euclid(period);
                    }
                }
            }
        }
        ys.push(best);
        if who.is_finite() {
            winners.push(who);
        }
    }
    let max = ys.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let min = ys.iter().cloned().fold(f64::INFINITY, f64::min);
    let mean = ys.iter().sum::<f64>() / M as f64;
    let ra = ys.iter().map(|y| (y - mean).abs()).sum::<f64>() / M as f64;
    winners.sort_by(f64::total_cmp);
    winners.dedup_by(|a, b| (*a - *b).abs() < 1e-9 * period);
    let max_gap = if winners.len() <= 1 {
        period
    } else {
        let wrap = winners[0] + period - winners[winners.len() - 1];
        winners.windows(2).map(|w| w[1] - w[0]).fold(wrap, f64::max)
    };
    FeedMarks {
        peak_to_valley: max - min,
        ra,
        max_effective_feed: max_gap,
    }
}

/// Roughness estimate of a finishing pass.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Roughness {
    /// Across the feed, between passes, mm.
    pub scallop_height: f64,
    /// Along the feed on the floor, mm.
    pub floor: FeedMarks,
    /// Along the feed on a side wall, mm.
    pub wall: FeedMarks,
    /// The larger of the two floor cusps (they run in perpendicular directions), mm.
    pub floor_peak_to_valley: f64,
}

pub fn surface_roughness(
    tool: &Tool,
    step_over: f64,
    feed_per_tooth: f64,
) -> Result<Roughness, PhysicsError> {
    let scallop_height = scallop_height(tool, step_over)?;
    let floor = feed_marks(tool, feed_per_tooth, SurfaceKind::Floor)?;
    let wall = feed_marks(tool, feed_per_tooth, SurfaceKind::Wall)?;
    Ok(Roughness {
        scallop_height,
        floor,
        wall,
        floor_peak_to_valley: scallop_height.max(floor.peak_to_valley),
    })
}
