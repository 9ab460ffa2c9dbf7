//! The validated problem: task, tool, coefficients, machine, and the bounds of the search.

use std::collections::HashMap;
use std::f64::consts::PI;

use super::forces::ForceStats;
use super::{EnergySearchOptions, Range, SearchSpace, DEFAULT_MAX_AXIAL_PASSES};
use crate::job::CancelFlag;
use crate::machine::Machine;
use crate::physics::energy::EnergyModel;
use crate::physics::force::ForceModel;
use crate::physics::material::CuttingCoefficients;
use crate::physics::stability::LobePoint;
use crate::physics::PhysicsError;
use crate::tool::Tool;

/// A validated energy search problem: task, tool, cutting coefficients, machine, the lobe
/// tables and the force model with its cache.
///
/// The model at a point (n, fz, axial passes pz, radial passes pw), P = pz·pw passes:
/// - forces from [`ForceModel`] on a straight-cut [`Engagement`] of height ap (slices of
///   at most 0.1 mm; at each slice the arc where the local edge radius reaches into the band
///   of width ae on the down- or up-milling side), independent of n;
/// - feed rate vf = fz·N·n; cutting power P_cut = mean torque·2πn/60;
/// - time = P·(L + approach)/vf + (P − 1)·t_rep, t_rep = (L + approach + 2·clearance)/rapid;
/// - E_cut = P·P_cut·L/vf (the approach is in air), E_idle = P_idle(n)·time,
///   E_aux = P_aux·time, E_in = their sum, U = E_cut/E_in;
/// - constraints: n within the cutting-speed and spindle ranges, fz within its range, vf
///   within the feed range and the machine's max_feed, peak |F| ≤ axis_thrust_limit (the
///   resultant: conservative for every axis), peak torque ≤ torque_limit, mean P_cut ≤
///   η·P_rated (the rating is continuous power), and with modes ap ≤ λ·a_lim(n, ae/D), a_lim
///   interpolated linearly on a lobe table computed per radial width at
///   `stability_rpm_points` speeds spread evenly over the spindle range.
///
/// [`Engagement`]: crate::engagement::Engagement
pub struct EnergyProblem {
    pub(super) opts: EnergySearchOptions,
    pub(super) k: CuttingCoefficients,
    pub(super) energy: EnergyModel,
    pub(super) teeth: f64,
    pub(super) diameter: f64,
    pub(super) n_range: (f64, f64),
    pub(super) fz_range: (f64, f64),
    pub(super) vf_range: (f64, f64),
    pub(super) pz_range: (u32, u32),
    pub(super) pw_range: (u32, u32),
    pub(super) approach: f64,
    pub(super) reposition_s: f64,
    pub(super) thrust: Option<f64>,
    pub(super) torque: Option<f64>,
    pub(super) power_limit: f64,
    pub(super) lobes: HashMap<u32, Vec<LobePoint>>,
    pub(super) stability_note: String,
    pub(super) tool: Tool,
    pub(super) models: HashMap<u32, ForceModel>,
    pub(super) cache: HashMap<(u32, u32, u64), ForceStats>,
    pub(super) evaluations: usize,
    /// Looked at before every lobe depth and every feed the search tries.
    pub(super) cancel: CancelFlag,
}

impl EnergyProblem {
    /// Validates everything and computes the lobe tables (when modes are given). Errors name
    /// the field: options fields by name, `machine.energy`, `tool.…`, and for a task that
    /// cannot fit the tool or the machine the option that would have to change.
    pub fn new(
        opts: &EnergySearchOptions,
        tool: &Tool,
        k: &CuttingCoefficients,
        machine: &Machine,
    ) -> Result<EnergyProblem, PhysicsError> {
        Self::new_with(opts, tool, k, machine, &CancelFlag::new())
    }

    /// [`new`](Self::new) for a job: the lobe tables and every later search stop with
    /// [`PhysicsError::Cancelled`] soon after `cancel` is set.
    pub fn new_with(
        opts: &EnergySearchOptions,
        tool: &Tool,
        k: &CuttingCoefficients,
        machine: &Machine,
        cancel: &CancelFlag,
    ) -> Result<EnergyProblem, PhysicsError> {
        opts.validate()?;
        tool.validate()?;
        k.validate()?;
        machine
            .validate()
            .map_err(|e| PhysicsError::invalid(format!("machine.{}", e.field), e.message))?;
        let energy = machine.energy.ok_or_else(|| {
            PhysicsError::invalid(
                "machine.energy",
                "the machine has no energy model (idle power curve and auxiliary power)",
            )
        })?;
        let d = tool.diameter;
        let teeth = tool.flutes as f64;
        let n_lo = machine
            .spindle_min_rpm
            .max(opts.cutting_speed_m_min.min * 1000.0 / (PI * d));
        let n_hi = machine
            .spindle_max_rpm
            .min(opts.cutting_speed_m_min.max * 1000.0 / (PI * d));
        if n_lo > n_hi {
            return Err(PhysicsError::invalid(
                "cutting_speed_m_min",
                format!(
                    "{}–{} m/min with a {d} mm tool needs {:.0}–{:.0} rpm, outside the machine's spindle range {}–{} rpm",
                    opts.cutting_speed_m_min.min,
                    opts.cutting_speed_m_min.max,
                    opts.cutting_speed_m_min.min * 1000.0 / (PI * d),
                    opts.cutting_speed_m_min.max * 1000.0 / (PI * d),
                    machine.spindle_min_rpm,
                    machine.spindle_max_rpm
                ),
            ));
        }
        let n_lo = n_lo.max(1.0);
        let feed = opts.feed_mm_min.unwrap_or(Range {
            min: 0.0,
            max: machine.max_feed,
        });
        let vf_range = (feed.min, feed.max.min(machine.max_feed));
        if vf_range.0 > vf_range.1 {
            return Err(PhysicsError::invalid(
                "feed_mm_min.min",
                format!(
                    "{} mm/min is above the machine's max_feed {} mm/min",
                    feed.min, machine.max_feed
                ),
            ));
        }
        let pz_min = ((opts.depth_mm / tool.flute_length) * (1.0 - 1e-12))
            .ceil()
            .max(1.0) as u32;
        let pz_max = opts.max_axial_passes.unwrap_or(DEFAULT_MAX_AXIAL_PASSES);
        if pz_min > pz_max {
            return Err(PhysicsError::invalid(
                "max_axial_passes",
                format!(
                    "depth {} mm needs at least {pz_min} axial passes with a {} mm flute length, max_axial_passes is {pz_max}",
                    opts.depth_mm, tool.flute_length
                ),
            ));
        }
        let max_ae = opts.max_radial_immersion.unwrap_or(1.0) * d;
        let pw_min = ((opts.width_mm / max_ae) * (1.0 - 1e-12)).ceil().max(1.0) as u32;
        let pw_max = opts.max_radial_passes.unwrap_or(pw_min + 3);
        if pw_min > pw_max {
            return Err(PhysicsError::invalid(
                "max_radial_passes",
                format!(
                    "width {} mm needs at least {pw_min} radial passes with ae ≤ {max_ae} mm, max_radial_passes is {pw_max}",
                    opts.width_mm
                ),
            ));
        }
        let approach = opts.approach_mm.unwrap_or(d);
        let reposition_s =
            (opts.length_mm + approach + 2.0 * opts.clearance_mm) * 60.0 / machine.rapid_rate;
        let mut problem = EnergyProblem {
            opts: opts.clone(),
            k: *k,
            energy,
            teeth,
            diameter: d,
            n_range: (n_lo, n_hi),
            fz_range: (opts.feed_per_tooth_mm.min, opts.feed_per_tooth_mm.max),
            vf_range,
            pz_range: (pz_min, pz_max),
            pw_range: (pw_min, pw_max),
            approach,
            reposition_s,
            thrust: machine.axis_thrust_limit,
            torque: machine.torque_limit,
            power_limit: machine.efficiency * machine.rated_power,
            lobes: HashMap::new(),
            stability_note: String::new(),
            tool: tool.clone(),
            models: HashMap::new(),
            cache: HashMap::new(),
            evaluations: 0,
            cancel: cancel.clone(),
        };
        problem.build_lobes()?;
        Ok(problem)
    }

    /// The bounds of the search space.
    pub fn space(&self) -> SearchSpace {
        SearchSpace {
            spindle_rpm: [self.n_range.0, self.n_range.1],
            feed_per_tooth_mm: [self.fz_range.0, self.fz_range.1],
            feed_mm_min: [self.vf_range.0, self.vf_range.1],
            axial_passes: [self.pz_range.0, self.pz_range.1],
            radial_passes: [self.pw_range.0, self.pw_range.1],
            reposition_s: self.reposition_s,
            power_limit_w: self.power_limit,
            thrust_limit_n: self.thrust,
            torque_limit_nm: self.torque,
        }
    }

    /// Number of points evaluated so far.
    pub fn evaluations(&self) -> usize {
        self.evaluations
    }

    /// How stability is handled, in words.
    pub fn stability_note(&self) -> &str {
        &self.stability_note
    }
}
