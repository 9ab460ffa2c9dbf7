//! The 3+2 roughing program: per segment, the machine's rotary axes set once for the
//! segment's axis (inverse kinematics of the machine), then either
//! - the spiral clearing (the default): depth by depth from the top of the part near the
//!   passes down to the section, a helical descent about the free region's centre, the
//!   offset spiral out to the walls, and the region's other pieces each plunged into and
//!   looped; or
//! - plunges along the axis at every plunge point: rapid down to the approach height, feed
//!   to the section, rapid back out.
//!
//! Every point and move was checked with the tool's whole body (allowance included) against
//! the walls seen from the section, which cover the walls seen from any depth above it, so
//! the program cuts only what lies between the walls. Fanuc-style G-code in machine axes
//! (no tool-centre-point control); helices are written as short lines.

use std::fmt::Write;

use serde::Serialize;

use super::choice::{computed_tool, CLEARANCE};
use super::clearing::{Clearing, Entry};
use super::{AccessError, AccessReport, AccessRequest, SegmentReach};
use crate::geometry::Mesh;
use crate::machine::kinematics::{MachineKinematics, Pose, PoseIssue};
use crate::machine::{Kinematics, Machine};
use crate::tool::Tool;
use crate::vec3::{norm, sub};

/// How the free region is cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Strategy {
    /// Helical entry and the offset spiral, depth by depth.
    Spiral,
    /// Plunges on a lattice, each to the section.
    Plunge,
}

/// Cutting data.
#[derive(Clone, Debug)]
pub struct RoughingOptions {
    /// Plunge (and helix) feed, mm/min.
    pub feed: f64,
    /// Feed along the spiral and loops, mm/min.
    pub cutting_feed: f64,
    pub spindle_rpm: f64,
    pub strategy: Strategy,
    /// Depth of cut per spiral level, as a fraction of the tool diameter.
    pub stepdown: f64,
}

impl Default for RoughingOptions {
    fn default() -> Self {
        RoughingOptions {
            feed: 300.0,
            cutting_feed: 1000.0,
            spindle_rpm: 6000.0,
            strategy: Strategy::Spiral,
            stepdown: 0.5,
        }
    }
}

/// Ramp angle of a helical descent, degrees.
const HELIX_RAMP_DEG: f64 = 3.0;
/// Lines a helix turn is written as.
const HELIX_LINES_PER_TURN: usize = 48;
/// Rapids stop this far above the floor cut at the depth before, mm.
const REAPPROACH: f64 = 1.0;

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
    /// Spiral strategy: depths cut, passes per depth, helical entries, feed length, mm.
    pub depths: usize,
    pub passes: usize,
    pub helices: usize,
    pub feed_length_mm: f64,
}

#[derive(Clone, Debug)]
pub struct RoughingProgram {
    pub strategy: Strategy,
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

/// Writes moves in part coordinates as machine axes for one segment's fixed axis.
struct Writer<'a> {
    kin: MachineKinematics,
    text: &'a mut String,
    issues: &'a mut Vec<PoseIssue>,
    axes: [f64; 6],
    index: usize,
    first: bool,
    segment: usize,
    axis: [f64; 3],
    /// Feed length so far, mm, and the last tip position.
    fed: f64,
    last: Option<[f64; 3]>,
}

impl Writer<'_> {
    /// A move of the tip to `tip`: rapid when `feed` is `None`.
    fn go(&mut self, tip: [f64; 3], feed: Option<f64>) -> Result<(), AccessError> {
        let pose = Pose {
            tip,
            axis: self.axis,
        };
        let s = self
            .kin
            .inverse(&pose, &self.axes, self.index)
            .map_err(|e| super::invalid("machine", format!("segment {}: {e}", self.segment)))?;
        self.index += 1;
        self.issues.extend(s.issues);
        let p = |v: f64| num(v, 4);
        let mut words = String::new();
        if self.first {
            // The tables turn first, the tool above the part at any angle.
            for &slot in self.kin.rotary_slots() {
                let _ = write!(words, " {}{}", ['A', 'B', 'C'][slot - 3], p(s.axes[slot]));
            }
            let _ = writeln!(self.text, "G0{words}");
            words.clear();
            self.first = false;
        }
        for (k, name) in ['X', 'Y', 'Z'].iter().enumerate() {
            let _ = write!(words, " {name}{}", p(s.axes[k]));
        }
        match feed {
            Some(f) => {
                let _ = writeln!(self.text, "G1{words} F{}", num(f, 1));
                if let Some(l) = self.last {
                    self.fed += norm(sub(tip, l));
                }
            }
            None => {
                let _ = writeln!(self.text, "G0{words}");
            }
        }
        self.last = Some(tip);
        self.axes = s.axes;
        Ok(())
    }
}

/// The program for `report`'s segments that have plunges, for `machine`.
pub fn roughing_program(
    mesh: &Mesh,
    request: &AccessRequest,
    report: &AccessReport,
    machine: &Machine,
    options: &RoughingOptions,
) -> Result<RoughingProgram, AccessError> {
    for (field, v) in [
        ("feed_mm_min", options.feed),
        ("cutting_feed_mm_min", options.cutting_feed),
        ("spindle_rpm", options.spindle_rpm),
        ("stepdown", options.stepdown),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(super::invalid(field, "must be a positive number"));
        }
    }
    let kin = MachineKinematics::of(machine);
    let z_clear = clear_z(mesh, machine);
    let mut text = String::new();
    let mut tools = Vec::new();
    let mut issues = Vec::new();
    let p = |v: f64| num(v, 4);
    let _ = writeln!(text, "%");
    let title = match options.strategy {
        Strategy::Spiral => "HELICAL ENTRY AND OFFSET SPIRAL",
        Strategy::Plunge => "PLUNGE",
    };
    let _ = writeln!(text, "O1001 (MILLSIM ACCESSIBILITY 3+2 {title} ROUGHING)");
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
        let clearing = seg
            .clearing
            .as_ref()
            .filter(|_| options.strategy == Strategy::Spiral);
        let _ = writeln!(
            text,
            "(SEGMENT {} OF {}: AXIS {} {} {}, TOOL D{} , {} TO {} MM)",
            seg.segment,
            report.segments.len(),
            num(seg.axis[0], 5),
            num(seg.axis[1], 5),
            num(seg.axis[2], 5),
            num(tool.diameter, 3),
            match clearing {
                Some(c) => format!("{} SPIRAL PASSES", c.passes.len()),
                None => format!("{} PLUNGES", seg.plunges.len()),
            },
            num(seg.reach_mm, 2)
        );
        let _ = writeln!(text, "G0 Z{}", p(z_clear));
        axes[2] = z_clear;
        let _ = writeln!(text, "T{number} M6");
        let _ = writeln!(text, "S{} M3", num(options.spindle_rpm, 0));
        let mut w = Writer {
            kin: kin.clone(),
            text: &mut text,
            issues: &mut issues,
            axes,
            index,
            first: true,
            segment: seg.segment,
            axis: seg.axis,
            fed: 0.0,
            last: None,
        };
        let mut tool_row = ProgramTool {
            number,
            index: list_index,
            diameter_mm: tool.diameter,
            tool: tool.clone(),
            segment: seg.segment,
            plunges: 0,
            depths: 0,
            passes: 0,
            helices: 0,
            feed_length_mm: 0.0,
        };
        match clearing {
            Some(c) => spiral_moves(&mut w, seg, c, &tool, options, &mut tool_row)?,
            None => {
                for c in &seg.plunges {
                    let at =
                        |t: f64| -> [f64; 3] { std::array::from_fn(|k| c[k] + t * seg.axis[k]) };
                    w.go(at(seg.safe_height_mm), None)?;
                    w.go(at(seg.approach_height_mm), None)?;
                    w.go(at(0.0), Some(options.feed))?;
                    w.go(at(seg.approach_height_mm), None)?;
                    w.go(at(seg.safe_height_mm), None)?;
                }
                tool_row.plunges = seg.plunges.len();
            }
        }
        tool_row.feed_length_mm = w.fed;
        axes = w.axes;
        index = w.index;
        let _ = writeln!(text, "G0 Z{}", p(z_clear));
        axes[2] = z_clear;
        let _ = writeln!(text, "M5");
        tools.push(tool_row);
    }
    let _ = writeln!(text, "M30");
    let _ = writeln!(text, "%");
    Ok(RoughingProgram {
        strategy: options.strategy,
        text,
        tools,
        issues,
        clear_z: z_clear,
    })
}

/// The spiral strategy for one segment: depth by depth, each pass entered by its helix or
/// plunge from just above the floor the depth before left, cut, then lifted to the
/// approach height.
fn spiral_moves(
    w: &mut Writer,
    seg: &SegmentReach,
    c: &Clearing,
    tool: &Tool,
    options: &RoughingOptions,
    row: &mut ProgramTool,
) -> Result<(), AccessError> {
    let s = &c.section;
    // The top of the part near the passes (the approach height less its clearance).
    let top = (seg.approach_height_mm - CLEARANCE).max(0.0);
    let step = options.stepdown * tool.diameter;
    let depths = ((top / step).ceil() as usize).max(1);
    let first = c.passes[0].points[0];
    w.go(s.point(first, seg.safe_height_mm), None)?;
    for d in 1..=depths {
        let h = top * (1.0 - d as f64 / depths as f64);
        let above =
            (top * (1.0 - (d - 1) as f64 / depths as f64) + REAPPROACH).min(seg.approach_height_mm);
        for pass in &c.passes {
            let start = pass.points[0];
            w.go(s.point(start, seg.approach_height_mm), None)?;
            match pass.entry {
                Entry::Helix { center, radius } => {
                    // Whole turns from the start angle 0 (the pass's first point), then a
                    // level turn to flatten the floor.
                    let pitch = std::f64::consts::TAU * radius * HELIX_RAMP_DEG.to_radians().tan();
                    let turns = ((above - h) / pitch).ceil().max(1.0) as usize;
                    w.go(s.point(start, above), None)?;
                    let n = (turns + 1) * HELIX_LINES_PER_TURN;
                    for i in 1..=n {
                        let a = std::f64::consts::TAU * i as f64 / HELIX_LINES_PER_TURN as f64;
                        let t = (i as f64 / (turns * HELIX_LINES_PER_TURN) as f64).min(1.0);
                        let q = [center[0] + radius * a.cos(), center[1] + radius * a.sin()];
                        w.go(s.point(q, above + t * (h - above)), Some(options.feed))?;
                    }
                    row.helices += 1;
                }
                Entry::Plunge => {
                    w.go(s.point(start, above), None)?;
                    w.go(s.point(start, h), Some(options.feed))?;
                    row.plunges += 1;
                }
            }
            // The helix's last line ends on the circle at angle 0: the pass's first point.
            for &q in &pass.points[1..] {
                w.go(s.point(q, h), Some(options.cutting_feed))?;
            }
            let end = *pass.points.last().unwrap();
            w.go(s.point(end, seg.approach_height_mm), None)?;
        }
    }
    let end = *c.passes.last().unwrap().points.last().unwrap();
    w.go(s.point(end, seg.safe_height_mm), None)?;
    row.depths = depths;
    row.passes = c.passes.len();
    Ok(())
}
