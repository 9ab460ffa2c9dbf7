//! Machine energy: input power P_in = P_cut + P_idle(n) + P_aux, energy per block and per
//! program with the energy utilization U = E_cut/E_in. The parameter search of the `energy`
//! job is an optimization: [`crate::optimize::energy_search`].
//!
//! - [`IdlePowerCurve`]: idle spindle power, one quadratic in the speed up to a base speed and
//!   another above it (the form of the fits in docs/reference.md).
//! - [`EnergyModel`]: idle curve and auxiliary power (coolant, hydraulics, controls: drawn
//!   whenever the program runs). P_idle is drawn only while the spindle turns.
//! - [`program_energy`]: per-block and total E_idle, E_aux, E_cut, E_in and U from each
//!   block's time, spindle speed and cutting energy ([`EnergyBlock::from_mrr`] is the
//!   fallback P_cut = K·MRR when no force model applies).
//!
//! Units: W, J, s, rpm, mm, mm/min, N, N·m.

use serde::{Deserialize, Serialize};

use super::{finite, non_negative, positive, PhysicsError};

/// Idle spindle power as a function of spindle speed n (rpm):
/// P_idle(n) = c0 + c1·n + c2·n² with `below` = [c0, c1, c2] for n ≤ `base_rpm` and `above`
/// for n > `base_rpm`; 0 when the spindle is stopped (n = 0).
///
/// JSON: `{"base_rpm":3000,"below":[823.3,0.0149,2e-6],"above":[881.5,-0.0034,3e-6]}`
/// (coefficients in W, W/rpm, W/rpm²).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdlePowerCurve {
    /// Speed up to which `below` applies (inclusive), rpm.
    pub base_rpm: f64,
    /// [c0 (W), c1 (W/rpm), c2 (W/rpm²)] for n ≤ base_rpm.
    pub below: [f64; 3],
    /// [c0, c1, c2] for n > base_rpm.
    pub above: [f64; 3],
}

impl IdlePowerCurve {
    /// Idle power at `rpm`, W (0 for a stopped spindle, rpm ≤ 0).
    pub fn power_w(&self, rpm: f64) -> f64 {
        if rpm <= 0.0 {
            return 0.0;
        }
        let c = if rpm <= self.base_rpm {
            &self.below
        } else {
            &self.above
        };
        c[0] + c[1] * rpm + c[2] * rpm * rpm
    }

    /// Finite coefficients and a positive base speed; names the field (`idle.below[0]`, …).
    pub fn validate(&self) -> Result<(), PhysicsError> {
        positive("idle.base_rpm", self.base_rpm)?;
        for (name, c) in [("below", &self.below), ("above", &self.above)] {
            for (i, v) in c.iter().enumerate() {
                finite(format!("idle.{name}[{i}]"), *v)?;
            }
        }
        Ok(())
    }
}

/// The machine's energy description: idle spindle power and auxiliary power.
///
/// JSON (the `energy` field of a machine):
/// `{"idle":{"base_rpm":3000,"below":[823.3,0.0149,2e-6],"above":[881.5,-0.0034,3e-6]},"aux_power_w":804}`
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnergyModel {
    pub idle: IdlePowerCurve,
    /// Power drawn whenever the program runs (coolant pump, hydraulics, controls), W.
    pub aux_power_w: f64,
}

impl EnergyModel {
    /// The example fit of docs/reference.md (high-speed milling study, 45 steel):
    /// P_idle = 2e-6·n² + 0.0149·n + 823.3 W up to 3000 rpm, 3e-6·n² − 0.0034·n + 881.5 W
    /// above, auxiliary power 804 W. An example, not a property of any particular machine.
    pub fn reference_example() -> EnergyModel {
        EnergyModel {
            idle: IdlePowerCurve {
                base_rpm: 3000.0,
                below: [823.3, 0.0149, 2e-6],
                above: [881.5, -0.0034, 3e-6],
            },
            aux_power_w: 804.0,
        }
    }

    /// Checks the numbers; field names are relative to the model (`idle.below[0]`,
    /// `aux_power_w`).
    pub fn validate(&self) -> Result<(), PhysicsError> {
        self.idle.validate()?;
        non_negative("aux_power_w", self.aux_power_w)?;
        Ok(())
    }

    /// Checks that the idle power is not negative anywhere on [min_rpm, max_rpm] (the two
    /// ends, the base speed and 200 speeds between). Field `idle`.
    pub fn validate_speed_range(&self, min_rpm: f64, max_rpm: f64) -> Result<(), PhysicsError> {
        let lo = min_rpm.max(1e-9);
        let mut speeds: Vec<f64> = (0..=200)
            .map(|i| lo + (max_rpm - lo) * i as f64 / 200.0)
            .collect();
        if self.idle.base_rpm >= lo && self.idle.base_rpm <= max_rpm {
            speeds.push(self.idle.base_rpm);
        }
        for n in speeds {
            let p = self.idle.power_w(n);
            if p.is_nan() || p < 0.0 {
                return Err(PhysicsError::invalid(
                    "idle",
                    format!("gives a negative idle power {p:.1} W at {n:.0} rpm"),
                ));
            }
        }
        Ok(())
    }

    /// Idle spindle power at `rpm` (0 when stopped), W.
    pub fn idle_power_w(&self, rpm: f64) -> f64 {
        self.idle.power_w(rpm)
    }

    /// P_in = P_cut + P_idle(n) + P_aux, W.
    pub fn input_power_w(&self, cutting_power_w: f64, rpm: f64) -> f64 {
        cutting_power_w + self.idle_power_w(rpm) + self.aux_power_w
    }
}

/// What the energy model needs to know about one block of a program.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnergyBlock {
    /// Duration of the block, s.
    pub time_s: f64,
    /// Spindle speed, rpm (0 = spindle stopped).
    pub spindle_rpm: f64,
    /// Energy spent cutting (mean cutting power × time, from the force model), J.
    pub cutting_energy_j: f64,
}

impl EnergyBlock {
    /// Fallback when no force model applies: P_cut = K·MRR with the specific cutting energy
    /// K (J/mm³) and the material removal rate MRR (mm³/s), so E_cut = K·MRR·t.
    pub fn from_mrr(
        time_s: f64,
        spindle_rpm: f64,
        mrr_mm3_s: f64,
        specific_energy_j_mm3: f64,
    ) -> EnergyBlock {
        EnergyBlock {
            time_s,
            spindle_rpm,
            cutting_energy_j: specific_energy_j_mm3 * mrr_mm3_s * time_s,
        }
    }
}

/// Energy of one block, J.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BlockEnergy {
    pub idle_j: f64,
    pub aux_j: f64,
    pub cut_j: f64,
    /// E_in = E_cut + E_idle + E_aux.
    pub input_j: f64,
}

/// Energy of a program: per block and totals.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProgramEnergy {
    pub blocks: Vec<BlockEnergy>,
    pub time_s: f64,
    pub idle_j: f64,
    pub aux_j: f64,
    pub cut_j: f64,
    pub input_j: f64,
    /// U = E_cut / E_in (0 for an empty program).
    pub utilization: f64,
}

/// Per-block and program energy. Every block draws P_aux for its time; blocks with the
/// spindle turning (rpm > 0) also P_idle(rpm); the cutting energy is the caller's.
/// Errors name the block field (`blocks[3].time_s`); cutting energy with the spindle
/// stopped is an error.
pub fn program_energy(
    model: &EnergyModel,
    blocks: &[EnergyBlock],
) -> Result<ProgramEnergy, PhysicsError> {
    model.validate()?;
    let mut out = ProgramEnergy {
        blocks: Vec::with_capacity(blocks.len()),
        ..ProgramEnergy::default()
    };
    for (i, b) in blocks.iter().enumerate() {
        non_negative(format!("blocks[{i}].time_s"), b.time_s)?;
        non_negative(format!("blocks[{i}].spindle_rpm"), b.spindle_rpm)?;
        non_negative(format!("blocks[{i}].cutting_energy_j"), b.cutting_energy_j)?;
        if b.cutting_energy_j > 0.0 && b.spindle_rpm == 0.0 {
            return Err(PhysicsError::invalid(
                format!("blocks[{i}].cutting_energy_j"),
                "is positive while the spindle is stopped",
            ));
        }
        let idle_j = model.idle_power_w(b.spindle_rpm) * b.time_s;
        let aux_j = model.aux_power_w * b.time_s;
        let cut_j = b.cutting_energy_j;
        let e = BlockEnergy {
            idle_j,
            aux_j,
            cut_j,
            input_j: idle_j + aux_j + cut_j,
        };
        out.time_s += b.time_s;
        out.idle_j += e.idle_j;
        out.aux_j += e.aux_j;
        out.cut_j += e.cut_j;
        out.input_j += e.input_j;
        out.blocks.push(e);
    }
    out.utilization = if out.input_j > 0.0 {
        out.cut_j / out.input_j
    } else {
        0.0
    };
    Ok(out)
}
