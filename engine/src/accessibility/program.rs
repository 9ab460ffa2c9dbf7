//! The 3+2 plunge roughing program: per segment, the machine's rotary axes set once for the
//! segment's axis (inverse kinematics of the machine), then plunges along the axis at every
//! plunge point: rapid above the part, rapid down to the approach height, feed to the
//! section, rapid back out. Every plunge point was checked with the tool's whole body
//! (allowance included) against the part, so the program cuts only what lies between the
//! walls. Fanuc-style G-code in machine axes (no tool-centre-point control).

use std::fmt::Write;

use serde::Serialize;

use super::choice::{computed_tool, CLEARANCE};
use super::{AccessError, AccessReport, AccessRequest};
use crate::geometry::Mesh;
use crate::machine::kinematics::{MachineKinematics, Pose, PoseIssue};
use crate::machine::{Kinematics, Machine};
use crate::tool::Tool;
use crate::vec3::{norm, sub};

/// Cutting data of the plunges.
#[derive(Clone, Debug)]
pub struct RoughingOptions {
    /// Plunge feed, mm/min.
    pub feed: f64,
    pub spindle_rpm: f64,
}

impl Default for RoughingOptions {
    fn default() -> Self {
        RoughingOptions {
            feed: 300.0,
            spindle_rpm: 6000.0,
        }
    }
}

/// A tool the program loads.
#[derive(Clone, Debug, Serialize)]
pub struct ProgramTool {
    pub number: u32,
    /// The list's tool (index) or the computed one (none).
    pub index: Option<usize>,
    #[serde(skip)]
    pub tool: Tool,
    pub diameter_mm: f64,
    pub segment: usize,
    pub plunges: usize,
}

#[derive(Clone, Debug)]
pub struct RoughingProgram {
    pub text: String,
    pub tools: Vec<ProgramTool>,
    /// Rotary positions outside the machine's limits, singular poses.
    pub issues: Vec<PoseIssue>,
    /// Machine Z every segment starts and ends at (above the part at any table angle).
    pub clear_z: f64,
}

fn num(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    let s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    match s.as_str() {
        "-0" | "" => "0".into(),
        _ => s,
    }
}

/// Machine Z above the part whatever the tables' angles: the part turns about the table
/// pivots, so it stays within its farthest corner's distance of them.
fn clear_z(mesh: &Mesh, machine: &Machine) -> f64 {
    let (lo, hi) = mesh.bounds();
    let chain = machine.kinematic_chain.clone().unwrap_or_default();
    let corners = (0..8).map(|k| {
        [
            if k & 1 == 0 { lo[0] } else { hi[0] },
            if k & 2 == 0 { lo[1] } else { hi[1] },
            if k & 4 == 0 { lo[2] } else { hi[2] },
        ]
    });
    let top = match machine.kinematics {
        Kinematics::Xyz | Kinematics::HeadTable => hi[2],
        Kinematics::XyzA | Kinematics::XyzB => {
            let p = chain.tilt_pivot;
            p[2] + corners.map(|c| norm(sub(c, p))).fold(0.0, f64::max)
        }
        Kinematics::XyzAc | Kinematics::XyzBc => {
            let (p, q) = (chain.tilt_pivot, chain.rotary_center);
            p[2] + norm(sub(q, p)) + corners.map(|c| norm(sub(c, q))).fold(0.0, f64::max)
        }
    };
    top + CLEARANCE
}

/// The program for `report`'s segments that have plunges, for `machine`.
pub fn roughing_program(
    mesh: &Mesh,
    request: &AccessRequest,
    report: &AccessReport,
    machine: &Machine,
    options: &RoughingOptions,
) -> Result<RoughingProgram, AccessError> {
    if !(options.feed.is_finite() && options.feed > 0.0) {
        return Err(super::invalid("feed_mm_min", "must be a positive feed"));
    }
    if !(options.spindle_rpm.is_finite() && options.spindle_rpm > 0.0) {
        return Err(super::invalid("spindle_rpm", "must be a positive speed"));
    }
    let kin = MachineKinematics::of(machine);
    let z_clear = clear_z(mesh, machine);
    let mut text = String::new();
    let mut tools = Vec::new();
    let mut issues = Vec::new();
    let p = |v: f64| num(v, 4);
    let _ = writeln!(text, "%");
    let _ = writeln!(text, "O1001 (MILLSIM ACCESSIBILITY 3+2 PLUNGE ROUGHING)");
    let _ = writeln!(text, "G21 G90 G94 G17 G40 G49 G80");
    let mut axes = [0.0; 6];
    let mut index = 0;
    for seg in &report.segments {
        if seg.plunges.is_empty() {
            continue;
        }
        let (number, list_index, tool) = match &seg.tool {
            Some(t) => (
                t.index as u32 + 1,
                Some(t.index),
                request.tools[t.index].clone(),
            ),
            None => match computed_tool(seg, request) {
                Some(t) => (seg.segment as u32, None, t),
                None => continue,
            },
        };
        let _ = writeln!(
            text,
            "(SEGMENT {} OF {}: AXIS {} {} {}, TOOL D{} , {} PLUNGES TO {} MM)",
            seg.segment,
            report.segments.len(),
            num(seg.axis[0], 5),
            num(seg.axis[1], 5),
            num(seg.axis[2], 5),
            num(tool.diameter, 3),
            seg.plunges.len(),
            num(seg.reach_mm, 2)
        );
        let _ = writeln!(text, "G0 Z{}", p(z_clear));
        axes[2] = z_clear;
        let _ = writeln!(text, "T{number} M6");
        let _ = writeln!(text, "S{} M3", num(options.spindle_rpm, 0));
        let mut first = true;
        for c in &seg.plunges {
            let at = |t: f64| -> [f64; 3] { std::array::from_fn(|k| c[k] + t * seg.axis[k]) };
            for (step, t) in [
                ("safe", seg.safe_height_mm),
                ("approach", seg.approach_height_mm),
                ("bottom", 0.0),
                ("approach", seg.approach_height_mm),
                ("safe", seg.safe_height_mm),
            ] {
                let pose = Pose {
                    tip: at(t),
                    axis: seg.axis,
                };
                let s = kin.inverse(&pose, &axes, index).map_err(|e| {
                    super::invalid("machine", format!("segment {}: {e}", seg.segment))
                })?;
                index += 1;
                issues.extend(s.issues);
                let mut words = String::new();
                if first {
                    // The tables turn first, the tool above the part at any angle.
                    for &slot in kin.rotary_slots() {
                        let _ = write!(words, " {}{}", ['A', 'B', 'C'][slot - 3], p(s.axes[slot]));
                    }
                    let _ = writeln!(text, "G0{words}");
                    words.clear();
                    first = false;
                }
                for (k, name) in ['X', 'Y', 'Z'].iter().enumerate() {
                    let _ = write!(words, " {name}{}", p(s.axes[k]));
                }
                if step == "bottom" {
                    let _ = writeln!(text, "G1{words} F{}", num(options.feed, 1));
                } else {
                    let _ = writeln!(text, "G0{words}");
                }
                axes = s.axes;
            }
        }
        let _ = writeln!(text, "G0 Z{}", p(z_clear));
        axes[2] = z_clear;
        let _ = writeln!(text, "M5");
        tools.push(ProgramTool {
            number,
            index: list_index,
            diameter_mm: tool.diameter,
            tool,
            segment: seg.segment,
            plunges: seg.plunges.len(),
        });
    }
    let _ = writeln!(text, "M30");
    let _ = writeln!(text, "%");
    Ok(RoughingProgram {
        text,
        tools,
        issues,
        clear_z: z_clear,
    })
}
