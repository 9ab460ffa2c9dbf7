//! The stages after the forces: energy drawn per move, the chatter margin, the tool life
//! used and the roughness left.

use std::collections::BTreeMap;

use super::forces::turning_rpm;
use super::rows::{EnergyTotals, MoveRow, ToolLife};
use super::spec::{ChatterSpec, SimulateError, SimulateSpec};
use super::tools::ToolLookup;
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

/// The chatter model of each tooth count and the conditions of every row that cuts.
pub(crate) struct ChatterSetup {
    pub models: BTreeMap<u32, crate::physics::chatter::ChatterModel>,
    pub cutting: Vec<CuttingCondition>,
}

/// A row that cuts with the spindle turning: the tooth count of its tool, its speed, and
/// the immersion and direction of its engagement.
#[derive(Clone, Copy)]
pub(crate) struct CuttingCondition {
    pub row: usize,
    pub teeth: u32,
    pub rpm: f64,
    pub immersion: f64,
    pub milling: crate::physics::stability::Milling,
}

/// Chatter margin of every move that cuts, at its spindle speed and the immersion and
/// direction of its engagement; returns the number of moves over 1 and the largest margin,
/// and the models and conditions (with which the spindle speed choice evaluates the same
/// margins at other speeds).
pub(super) fn chatter_margins(
    c: &ChatterSpec,
    spec: &SimulateSpec,
    moves: &[Move],
    rows: &mut [MoveRow],
    tools: &ToolLookup,
) -> Result<((usize, f64), ChatterSetup), SimulateError> {
    use crate::physics::chatter::{arc_immersion, ChatterModel};
    let k = spec.material.coefficients;
    // With a size effect the lobes take the coefficients linearized at the operating chip:
    // here the median of the cutting moves' thickest chip per tooth count.
    let mut chips: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
    for (m, row) in moves.iter().zip(rows.iter()) {
        if row.removed_volume > 0.0 && row.max_chip_thickness > 0.0 {
            chips
                .entry(tools.tool_for(m)?.flutes)
                .or_default()
                .push(row.max_chip_thickness);
        }
    }
    for list in chips.values_mut() {
        list.sort_by(f64::total_cmp);
    }
    let operating_chip = |teeth: u32| chips.get(&teeth).map_or(0.0, |l| l[l.len() / 2]);
    // One model per tooth count (the tools of the program may differ).
    let mut models: BTreeMap<u32, ChatterModel> = BTreeMap::new();
    let mut conditions: BTreeMap<u32, Vec<(f64, f64, crate::physics::stability::Milling)>> =
        BTreeMap::new();
    let mut cutting: Vec<CuttingCondition> = Vec::new();
    for (i, (m, row)) in moves.iter().zip(rows.iter()).enumerate() {
        let (Some(entry), Some(exit)) = (row.entry_angle_deg, row.exit_angle_deg) else {
            continue;
        };
        let rpm = turning_rpm(m);
        if row.removed_volume <= 0.0 || rpm < 1.0 {
            continue;
        }
        let tool = tools.tool_for(m)?;
        let (immersion, milling) = arc_immersion(entry.to_radians(), exit.to_radians());
        if !models.contains_key(&tool.flutes) {
            let (kt, kr) = k.linearized_at(operating_chip(tool.flutes));
            let model = ChatterModel::new(
                c.modes_x.clone(),
                c.modes_y.clone(),
                tool.flutes,
                kt,
                kr,
                c.method,
                c.steps_per_period,
            )?;
            models.insert(tool.flutes, model);
        }
        conditions
            .entry(tool.flutes)
            .or_default()
            .push((rpm, immersion, milling));
        cutting.push(CuttingCondition {
            row: i,
            teeth: tool.flutes,
            rpm,
            immersion,
            milling,
        });
    }
    for (teeth, list) in &conditions {
        models[teeth].prefetch(list)?;
    }
    let (mut over, mut max) = (0, 0.0f64);
    for &CuttingCondition {
        row: i,
        teeth,
        rpm,
        immersion,
        milling,
    } in &cutting
    {
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
    Ok(((over, max), ChatterSetup { models, cutting }))
}

/// Tool life used per move with the material's extended Taylor constants (each tool starts
/// new), and the scallop and feed marks every cutting move leaves, from each move's widest
/// engaged diameter (where the edge runs fastest) and median scallop. Returns the life per
/// tool number, or why there is none.
pub(super) fn wear_and_roughness(
    spec: &SimulateSpec,
    moves: &[Move],
    rows: &mut [MoveRow],
    (diameter, scallops): (&[f64], &[f64]),
    tools: &ToolLookup,
) -> Result<Result<Vec<ToolLife>, String>, SimulateError> {
    use crate::physics::life::{cutting_speed_m_per_min, tool_life, BlockWear};
    use crate::physics::roughness::feed_mark_height;
    let mut wear: BTreeMap<u32, Vec<BlockWear>> = BTreeMap::new();
    for (i, m) in moves.iter().enumerate() {
        let r = &rows[i];
        let cutting =
            r.removed_volume > 0.0 && turning_rpm(m) > 0.0 && matches!(r.kind, "linear" | "arc");
        if !cutting {
            continue;
        }
        let tool = tools.tool_for(m)?;
        let row = &rows[i];
        let fz = row.tip_speed_mm_min / (m.spindle * tool.flutes as f64);
        let scallop = scallops[i];
        let marks = feed_mark_height(tool, fz)?;
        let row = &mut rows[i];
        row.scallop_um = scallop * 1000.0;
        row.feed_mark_um = marks * 1000.0;
        wear.entry(m.tool).or_default().push(BlockWear {
            block: i,
            cutting_speed: cutting_speed_m_per_min(diameter[i], m.spindle),
            chip_thickness: row.max_chip_thickness,
            engaged_time: row.time_s * (1.0 - row.air_fraction),
        });
    }
    let Some(taylor) = &spec.material.taylor else {
        return Ok(Err(format!(
            "the material {} has no Taylor constants (`taylor`: c, n, a and their source)",
            spec.material.name
        )));
    };
    for row in rows.iter_mut() {
        row.tool_life_used = Some(0.0);
    }
    let mut out = Vec::new();
    for (tool, blocks) in wear {
        let report = tool_life(taylor, &blocks, 0.0)?;
        for b in &report.blocks {
            rows[b.block].tool_life_used = Some(b.consumed);
        }
        out.push(ToolLife {
            tool,
            life_used: report.consumed,
            life_left: report.remaining,
            most_wearing_line: report.most_wearing_block.map(|i| moves[i].line),
            worn_out_line: report.worn_out_at_block.map(|i| moves[i].line),
        });
    }
    Ok(Ok(out))
}

/// The scallop a step leaves beside the pass before it, mm: beside an earlier pass the
/// engaged width is the step-over; a lone groove engages its whole footprint at its depth
/// (within the grid: 90 % of it is taken as alone) and leaves none.
pub(super) fn scallop_of(
    tool: &crate::tool::Tool,
    m: &crate::geometry::engagement::StepMetrics,
) -> Result<f64, crate::physics::PhysicsError> {
    let footprint = tool
        .edge_point(m.axial_depth.min(tool.flute_length))
        .map_or(tool.diameter, |p| 2.0 * p.radius);
    if m.radial_width > 0.0 && m.radial_width < 0.9 * footprint {
        crate::physics::roughness::scallop_height(tool, m.radial_width)
    } else {
        Ok(0.0)
    }
}
