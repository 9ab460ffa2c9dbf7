//! Post-processor: an APT/CLS file (tool tip and tool axis in the part frame) to Fanuc-style
//! G-code for one machine, with the rotary feed correction applied: one NC text per operation
//! (a new operation starts at each `LOADTL` and at each `TOOL PATH`, `OPERATION` or `OPNAME`
//! record that follows motion).
//!
//! Each CLS point goes through the machine's inverse kinematics (nearest the previous solution);
//! the output has decimal points on every coordinate, modal G0/G1 and axis words (only what
//! changes is written), F only when it changes (always in G93), optional N numbers. CLS arcs are
//! written as straight moves through points on the arc (chord tolerance `arc_tolerance`); the tool
//! tip of a posted move goes exactly through those points, while between points the machine
//! interpolates its axes linearly.

use super::kinematics::{KinematicsError, MachineKinematics, Pose, PoseIssue};
use super::rotary_feed::{correct_moves, FeedOutput, RotaryFeedOptions, RotaryFeedReport};
use super::Machine;
use crate::cl;
use crate::nc::{self, FeedMode, Move, MoveKind, SpindleDir};
use std::fmt::Write;

#[derive(Clone, Debug, PartialEq)]
pub struct PostOptions {
    /// `Some((first, step))`: number the blocks N first, N first+step, ...
    pub n_numbers: Option<(u32, u32)>,
    /// Decimals of X Y Z (mm).
    pub linear_decimals: usize,
    /// Decimals of A B C (degrees).
    pub angle_decimals: usize,
    /// Decimals of F.
    pub feed_decimals: usize,
    /// Chord tolerance for CLS arcs, mm.
    pub arc_tolerance: f64,
    pub feed: RotaryFeedOptions,
}

impl Default for PostOptions {
    fn default() -> Self {
        PostOptions {
            n_numbers: None,
            linear_decimals: 4,
            angle_decimals: 4,
            feed_decimals: 4,
            arc_tolerance: 1e-3,
            feed: RotaryFeedOptions::default(),
        }
    }
}

/// One posted operation.
#[derive(Clone, Debug)]
pub struct PostedProgram {
    /// 1-based operation number.
    pub operation: usize,
    pub tool: u32,
    pub text: String,
    /// Tool-tip targets of the posted moves, in order (part frame), for checking.
    pub tip_targets: Vec<[f64; 3]>,
    /// Machine axes of the posted moves, in order.
    pub axes: Vec<[f64; 6]>,
    pub feeds: RotaryFeedReport,
    /// Singularities and limit violations; `index` is the CLS source line (1-based).
    pub issues: Vec<PoseIssue>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PostError {
    #[error("CLS: {0}")]
    Cls(#[from] nc::Diagnostics),
    #[error("CLS line {line}: {source}")]
    Kinematics {
        line: u32,
        #[source]
        source: KinematicsError,
    },
    #[error("CLS holds no motion")]
    Empty,
}

fn fmt_num(v: f64, decimals: usize) -> String {
    let mut s = format!("{v:.decimals$}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
    } else {
        s.push('.');
    }
    if s == "-." || s == "-0." {
        s = "0.".into();
    }
    // Fanuc style keeps the leading zero and the point: `0.5`, `10.`.
    s
}

/// A CLS point to post: tip, axis, kind, feed, source line and spindle state.
struct Target {
    tip: [f64; 3],
    axis: [f64; 3],
    rapid: bool,
    src: Move,
}

fn is_boundary_record(line: &str) -> bool {
    let t = line.trim_start().to_ascii_uppercase();
    let major = t.split('/').next().unwrap_or("").trim();
    major.starts_with("TOOL PATH") || major == "OPERATION" || major == "OPNAME"
}

/// Post a CLS text for a machine: one program per operation.
pub fn post_cls(
    cls_text: &str,
    machine: &Machine,
    opts: &PostOptions,
) -> Result<Vec<PostedProgram>, PostError> {
    let interp = cl::read_cls(cls_text)?;
    let boundary_lines: Vec<usize> = cls_text
        .lines()
        .enumerate()
        .filter(|(_, l)| is_boundary_record(l))
        .map(|(i, _)| i)
        .collect();
    // Split into operations.
    let mut ops: Vec<Vec<&Move>> = vec![Vec::new()];
    let mut next_boundary = 0;
    for m in &interp.moves {
        let mut crossed = false;
        while next_boundary < boundary_lines.len() && boundary_lines[next_boundary] < m.block {
            crossed = true;
            next_boundary += 1;
        }
        let cur_has_motion = ops
            .last()
            .unwrap()
            .iter()
            .any(|x| x.kind != MoveKind::ToolChange);
        if (m.kind == MoveKind::ToolChange || crossed) && cur_has_motion {
            ops.push(Vec::new());
        }
        ops.last_mut().unwrap().push(m);
    }
    ops.retain(|o| {
        o.iter()
            .any(|m| matches!(m.kind, MoveKind::Rapid | MoveKind::Linear | MoveKind::Arc))
    });
    if ops.is_empty() {
        return Err(PostError::Empty);
    }
    let kin = MachineKinematics::of(machine);
    let mut prev_axes = [0.0f64; 6];
    let mut first = true;
    let mut out = Vec::new();
    for (k, op) in ops.iter().enumerate() {
        // Targets (arcs as points on the arc).
        let mut targets = Vec::new();
        let mut tool = 0;
        for m in op {
            tool = m.tool;
            let axis = m.tool_axis.unwrap_or([0.0, 0.0, 1.0]);
            match m.kind {
                MoveKind::Rapid | MoveKind::Linear => targets.push(Target {
                    tip: [m.end[0], m.end[1], m.end[2]],
                    axis,
                    rapid: m.kind == MoveKind::Rapid,
                    src: (*m).clone(),
                }),
                MoveKind::Arc => {
                    let arc = m.arc.as_ref().expect("CLS arcs carry geometry");
                    for p in nc::sample_arc(arc, opts.arc_tolerance).into_iter().skip(1) {
                        targets.push(Target {
                            tip: [p[0], p[1], p[2]],
                            axis,
                            rapid: false,
                            src: (*m).clone(),
                        });
                    }
                }
                _ => {}
            }
        }
        if first {
            if let Some(t0) = op
                .iter()
                .find(|m| matches!(m.kind, MoveKind::Rapid | MoveKind::Linear | MoveKind::Arc))
            {
                let pose = Pose {
                    tip: [t0.start[0], t0.start[1], t0.start[2]],
                    axis: t0.tool_axis.unwrap_or([0.0, 0.0, 1.0]),
                };
                prev_axes = kin
                    .inverse(&pose, &prev_axes, t0.line as usize)
                    .map_err(|source| PostError::Kinematics {
                        line: t0.line,
                        source,
                    })?
                    .axes;
            }
            first = false;
        }
        // Machine moves.
        let mut issues = Vec::new();
        let mut machine_moves: Vec<Move> = Vec::new();
        let mut axes_list = Vec::new();
        for (ti, t) in targets.iter().enumerate() {
            let s = kin
                .inverse(
                    &Pose {
                        tip: t.tip,
                        axis: t.axis,
                    },
                    &prev_axes,
                    t.src.line as usize,
                )
                .map_err(|source| PostError::Kinematics {
                    line: t.src.line,
                    source,
                })?;
            issues.extend(s.issues);
            let mut mv = t.src.clone();
            mv.block = ti;
            mv.kind = if t.rapid {
                MoveKind::Rapid
            } else {
                MoveKind::Linear
            };
            mv.start = prev_axes;
            mv.end = s.axes;
            mv.arc = None;
            mv.center = None;
            mv.normal = None;
            mv.clockwise = None;
            mv.tool_axis = None;
            prev_axes = s.axes;
            axes_list.push(s.axes);
            machine_moves.push(mv);
        }
        let feeds = correct_moves(&machine_moves, machine, &opts.feed);
        let mut feed_of: Vec<Option<f64>> = vec![None; machine_moves.len()];
        for mf in &feeds.moves {
            feed_of[mf.move_index] = Some(mf.feed);
        }
        let text = write_program(k + 1, tool, machine, &kin, &machine_moves, &feed_of, opts);
        out.push(PostedProgram {
            operation: k + 1,
            tool,
            text,
            tip_targets: targets.iter().map(|t| t.tip).collect(),
            axes: axes_list,
            feeds,
            issues,
        });
    }
    Ok(out)
}

fn write_program(
    op: usize,
    tool: u32,
    machine: &Machine,
    kin: &MachineKinematics,
    moves: &[Move],
    feed_of: &[Option<f64>],
    opts: &PostOptions,
) -> String {
    let mut lines: Vec<String> = Vec::new();
    let inverse_time = opts.feed.output == FeedOutput::InverseTime;
    let mut mode_word = if inverse_time { "G93" } else { "G94" };
    let name = machine.name.replace(['(', ')'], "");
    lines.push(format!(
        "(MILLSIM POST OPERATION {op} TOOL {tool} MACHINE {name})"
    ));
    lines.push(format!("G21 G90 G17 {mode_word}"));
    if tool > 0 {
        lines.push(format!("T{tool} M6"));
    }
    let letters = ['X', 'Y', 'Z', 'A', 'B', 'C'];
    let mut slots: Vec<usize> = vec![0, 1, 2];
    slots.extend_from_slice(kin.rotary_slots());
    let mut last_words: [Option<String>; 6] = Default::default();
    let mut last_g: Option<&str> = None;
    let mut last_f: Option<String> = None;
    let mut spindle: Option<(String, SpindleDir)> = None;
    for (i, m) in moves.iter().enumerate() {
        let s_word = fmt_num(m.spindle, 0).trim_end_matches('.').to_string();
        if m.spindle > 0.0 && m.spindle_dir != SpindleDir::Off {
            let want = (s_word.clone(), m.spindle_dir);
            if spindle.as_ref() != Some(&want) {
                let mc = if m.spindle_dir == SpindleDir::Ccw {
                    "M4"
                } else {
                    "M3"
                };
                lines.push(format!("S{s_word} {mc}"));
                spindle = Some(want);
            }
        }
        let mut words = Vec::new();
        let g = if m.kind == MoveKind::Rapid {
            "G0"
        } else {
            "G1"
        };
        // Feed mode word when a per-rev feed needs G95 (per-min output only).
        let want_mode = if inverse_time {
            "G93"
        } else if m.feed_mode == FeedMode::PerRev && m.kind != MoveKind::Rapid {
            "G95"
        } else if m.kind != MoveKind::Rapid {
            "G94"
        } else {
            mode_word
        };
        if want_mode != mode_word {
            words.push(want_mode.to_string());
            mode_word = want_mode;
            last_f = None;
        }
        let mut axis_words = Vec::new();
        for &s in &slots {
            let dec = if s < 3 {
                opts.linear_decimals
            } else {
                opts.angle_decimals
            };
            let w = fmt_num(m.end[s], dec);
            if last_words[s].as_deref() != Some(w.as_str()) {
                axis_words.push(format!("{}{}", letters[s], w));
                last_words[s] = Some(w);
            }
        }
        if axis_words.is_empty() {
            continue;
        }
        if last_g != Some(g) {
            words.push(g.to_string());
            last_g = Some(g);
        }
        words.extend(axis_words);
        if m.kind != MoveKind::Rapid {
            let f = feed_of[i].unwrap_or_else(|| {
                // Not corrected (the tip does not move): the control's own reading.
                if inverse_time {
                    let l = super::cycle_time::move_length(m);
                    let v = super::cycle_time::feed_velocity(m);
                    if l > 0.0 {
                        v / l
                    } else {
                        v
                    }
                } else {
                    m.feed
                }
            });
            let fw = fmt_num(f, opts.feed_decimals);
            if inverse_time || last_f.as_deref() != Some(fw.as_str()) {
                words.push(format!("F{fw}"));
                last_f = Some(fw);
            }
        }
        lines.push(words.join(" "));
    }
    lines.push("M5".into());
    lines.push("M30".into());
    let mut text = String::from("%\n");
    let mut n = opts.n_numbers.map(|(a, _)| a);
    for l in lines {
        if let (Some(v), Some((_, step))) = (n, opts.n_numbers) {
            if !l.starts_with('(') {
                let _ = write!(text, "N{v} ");
                n = Some(v + step);
            }
        }
        text.push_str(&l);
        text.push('\n');
    }
    text.push_str("%\n");
    text
}
