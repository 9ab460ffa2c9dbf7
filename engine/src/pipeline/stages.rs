//! The stages after the forces: energy drawn per move, and the chatter margin.

use std::collections::BTreeMap;

use super::forces::turning_rpm;
use super::rows::{EnergyTotals, MoveRow};
use super::spec::{ChatterSpec, SimulateError, SimulateSpec};
use crate::nc::Move;

/// Energy drawn per move (cutting from the force model, idle spindle at the move's speed
/// while it turns, auxiliary always) and the program's totals.
pub(super) fn block_energy(
    model: &crate::physics::energy::EnergyModel,
    moves: &[Move],
    rows: &mut [MoveRow],
) -> Result<EnergyTotals, SimulateError> {
    use crate::physics::energy::{program_energy, EnergyBlock};
    let blocks: Vec<EnergyBlock> = moves
        .iter()
        .zip(rows.iter())
        .map(|(m, r)| EnergyBlock {
            time_s: r.time_s,
            spindle_rpm: turning_rpm(m),
            cutting_energy_j: r.cutting_energy_j,
        })
        .collect();
    let e = program_energy(model, &blocks)?;
    for (row, b) in rows.iter_mut().zip(&e.blocks) {
        row.energy_in_j = Some(b.input_j);
    }
    Ok(EnergyTotals {
        idle_j: e.idle_j,
        aux_j: e.aux_j,
        cut_j: e.cut_j,
        input_j: e.input_j,
        utilization: e.utilization,
    })
}

/// Chatter margin of every move that cuts, at its spindle speed and the immersion and
/// direction of its engagement; returns the number of moves over 1 and the largest margin.
pub(super) fn chatter_margins(
    c: &ChatterSpec,
    spec: &SimulateSpec,
    moves: &[Move],
    rows: &mut [MoveRow],
) -> Result<(usize, f64), SimulateError> {
    use crate::physics::chatter::{arc_immersion, ChatterModel};
    let k = spec.material.coefficients;
    // One model per tooth count (the tools of the program may differ).
    let mut models: BTreeMap<u32, ChatterModel> = BTreeMap::new();
    let mut conditions: BTreeMap<u32, Vec<(f64, f64, crate::physics::stability::Milling)>> =
        BTreeMap::new();
    let mut cutting: Vec<(usize, u32, f64, f64, crate::physics::stability::Milling)> = Vec::new();
    for (i, (m, row)) in moves.iter().zip(rows.iter()).enumerate() {
        let (Some(entry), Some(exit)) = (row.entry_angle_deg, row.exit_angle_deg) else {
            continue;
        };
        let rpm = turning_rpm(m);
        if row.removed_volume <= 0.0 || rpm < 1.0 {
            continue;
        }
        let tool = spec
            .tools
            .get(&m.tool)
            .or_else(|| spec.tools.get(&0))
            .expect("a swept move has a tool");
        let (immersion, milling) = arc_immersion(entry.to_radians(), exit.to_radians());
        if !models.contains_key(&tool.flutes) {
            let model = ChatterModel::new(
                c.modes_x.clone(),
                c.modes_y.clone(),
                tool.flutes,
                k.ktc,
                k.krc,
                c.method,
                c.steps_per_period,
            )?;
            models.insert(tool.flutes, model);
        }
        conditions
            .entry(tool.flutes)
            .or_default()
            .push((rpm, immersion, milling));
        cutting.push((i, tool.flutes, rpm, immersion, milling));
    }
    for (teeth, list) in &conditions {
        models[teeth].prefetch(list)?;
    }
    let (mut over, mut max) = (0, 0.0f64);
    for (i, teeth, rpm, immersion, milling) in cutting {
        let row = &mut rows[i];
        let m = models[&teeth].margin(row.max_axial_depth, rpm, immersion, milling)?;
        row.chatter_margin = Some(m.margin);
        row.critical_depth_mm = m
            .critical_depth_mm
            .is_finite()
            .then_some(m.critical_depth_mm);
        if m.chatter {
            over += 1;
        }
        max = max.max(m.margin);
    }
    Ok((over, max))
}
