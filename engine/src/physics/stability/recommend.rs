//! Spindle speed recommendation: the widest stable pocket on a lobe curve.

use serde::{Deserialize, Serialize};

use super::LobePoint;

/// A recommended spindle speed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SpeedRecommendation {
    /// Centre of the pocket, rpm.
    pub rpm: f64,
    /// Critical depth at that speed (interpolated on the curve), mm.
    pub stable_depth_mm: f64,
    /// The pocket: speeds from..to where the critical depth exceeds the requested depth.
    pub pocket_from_rpm: f64,
    pub pocket_to_rpm: f64,
}

/// The centre of the widest stable pocket near `requested_rpm`: among the maximal runs of
/// grid speeds within `requested_rpm ± window_rpm` whose critical depth exceeds `depth_mm`,
/// the widest (ties: the one whose centre is nearest the requested speed); its centre and
/// the critical depth there. `None` if no speed in the window is stable at `depth_mm`.
/// `curve` must be sorted by speed.
pub fn recommend_spindle_speed(
    curve: &[LobePoint],
    requested_rpm: f64,
    depth_mm: f64,
    window_rpm: f64,
) -> Option<SpeedRecommendation> {
    let inside: Vec<&LobePoint> = curve
        .iter()
        .filter(|p| (p.rpm - requested_rpm).abs() <= window_rpm)
        .collect();
    let mut best: Option<(f64, f64, f64)> = None; // (width, from, to)
    let mut i = 0;
    while i < inside.len() {
        if inside[i].depth_mm <= depth_mm {
            i += 1;
            continue;
        }
        let start = i;
        while i + 1 < inside.len() && inside[i + 1].depth_mm > depth_mm {
            i += 1;
        }
        let (from, to) = (inside[start].rpm, inside[i].rpm);
        let width = to - from;
        let centre = 0.5 * (from + to);
        let better = match best {
            None => true,
            Some((w, f, t)) => {
                width > w
                    || (width == w
                        && (centre - requested_rpm).abs() < (0.5 * (f + t) - requested_rpm).abs())
            }
        };
        if better {
            best = Some((width, from, to));
        }
        i += 1;
    }
    let (_, from, to) = best?;
    let rpm = 0.5 * (from + to);
    Some(SpeedRecommendation {
        rpm,
        stable_depth_mm: interpolate(curve, rpm),
        pocket_from_rpm: from,
        pocket_to_rpm: to,
    })
}

/// Critical depth at `rpm` by linear interpolation on a curve sorted by speed.
pub fn interpolate(curve: &[LobePoint], rpm: f64) -> f64 {
    let j = curve.partition_point(|p| p.rpm < rpm);
    if j == 0 {
        return curve.first().map_or(f64::NAN, |p| p.depth_mm);
    }
    if j >= curve.len() {
        return curve.last().map_or(f64::NAN, |p| p.depth_mm);
    }
    let (p0, p1) = (curve[j - 1], curve[j]);
    if p1.rpm == p0.rpm {
        return p0.depth_mm.min(p1.depth_mm);
    }
    p0.depth_mm + (p1.depth_mm - p0.depth_mm) * (rpm - p0.rpm) / (p1.rpm - p0.rpm)
}
