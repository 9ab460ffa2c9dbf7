//! [`ForceModel`] (one tool's force model and its evaluations), [`CuttingConditions`], and
//! the one-shot [`cutting_forces`].

use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

use super::edge::ToolEdgeTable;
use super::frame::ToolFrame;
use super::kernel::{tooth_totals, Accumulated};
use super::peak_response::PeakResponse;
use super::stats::ForceResult;
use crate::engagement::Engagement;
use crate::physics::material::CuttingCoefficients;
use crate::physics::{non_negative, positive, PhysicsError};
use crate::tool::Tool;

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

/// The force model for one tool: edge table, angular grid and reusable buffers. Build
/// once per tool, then call [`ForceModel::evaluate`] (or `evaluate_into`, which reuses the
/// result's buffers) at every engagement step. Single-threaded and deterministic; run
/// several models on several threads to go wider.
#[derive(Clone, Debug)]
pub struct ForceModel {
    pub(super) table: ToolEdgeTable,
    pub(super) positions: usize,
    pub(super) sin_t: Vec<f64>,
    pub(super) cos_t: Vec<f64>,
    /// Per tooth, per position: fx, fy, fz, torque (N·mm), in four blocks of N·K.
    pub(super) acc: Vec<f64>,
    /// Totals over teeth per position, four blocks of K.
    pub(super) tot: Vec<f64>,
    /// The edge part's samples and totals for `evaluate_with_response`.
    pub(super) acc_edge: Vec<f64>,
    tot_edge: Vec<f64>,
    /// Five buffers of K for the runout kernel.
    pub(super) scratch: Vec<f64>,
    pub(super) tooth_hmax: Vec<f64>,
    pub(super) keep_samples: bool,
    /// The tool as a beam, for the deflection (see `bending`); None: no deflection.
    pub(super) beam: Option<crate::physics::deflection::ToolBeam>,
    /// The bending channels per tooth and position (four blocks of N·K each, x and y used):
    /// Σ arm·F, Σ a·F, Σ b·F over the slices; and their totals over the teeth.
    pub(super) acc_bend: [Vec<f64>; 3],
    pub(super) tot_bend: [Vec<f64>; 3],
    /// One slice's samples before they are weighted into the channels (four blocks of K).
    pub(super) bend_tmp: Vec<f64>,
    /// The beam's weights of each of the table's slices (computed once with the beam).
    pub(super) bend_weights: Vec<crate::physics::deflection::SliceWeights>,
    /// A thin wall's compliance by allowance, for the form error (None: a rigid part).
    pub(super) wall: Option<crate::physics::deflection::WallCompliance>,
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
            beam: None,
            acc_bend: Default::default(),
            tot_bend: Default::default(),
            bend_tmp: vec![0.0; 4 * positions],
            bend_weights: Vec::new(),
            wall: None,
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
        let (acc, _) = self.accumulate(engagement, k, None, Some((k, fz)), &frame, fz);
        self.summarize(frame, conditions, acc, out);
        self.bend(engagement, k, &frame, fz, &acc, out);
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
        // With runout or a size effect the chip or the force is not proportional to the feed.
        if !self.table.runout_steps.is_empty() || k.has_size_effect() {
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
        let fz = conditions.feed_per_tooth;
        let (a, corr_e) = self.accumulate(
            engagement,
            &cutting,
            Some(&edge),
            Some((k, fz)),
            &frame,
            1.0,
        );
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
        self.bend(engagement, k, &frame, fz, &acc, out);
        Ok(Some(response))
    }

    fn frame_of(engagement: &Engagement) -> Result<ToolFrame, PhysicsError> {
        if engagement.is_air() {
            Ok(ToolFrame::IDENTITY)
        } else {
            ToolFrame::from_engagement(engagement)
        }
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
