//! Post-processor: an APT/CLS file (tool tip and tool axis in the part frame) to Fanuc-style
//! G-code for one machine, with the rotary feed correction applied: one NC text per operation
//! (a new operation starts at each `LOADTL` and at each `TOOL PATH`, `OPERATION` or `OPNAME`
//! record that follows motion).
//!
//! Each CLS point goes through the machine's inverse kinematics (nearest the previous solution);
//! the output has decimal points on every coordinate, modal G0/G1 and axis words (only what
//! changes is written), F only when it changes (always in G93), optional N numbers.
//!
//! Feeds are computed for the axes as written (rounded to the output's decimals; an axis that
//! moves less than one output step keeps its last written value), so a residue of X, Y or Z is
//! no move at all and a rotation about the tool tip is a rotary-only move, in degrees/min. In G94 output, F is read as the machine's `rotary_feed_reading` reads
//! it; a move that turns a rotary axis is written in G93 (inverse time, then back to G94) where
//! the machine needs it or a G94 F would be ill-conditioned (see
//! [`RotaryFeedReading::g94_sound`]). A move that only turns the tool about its tip runs at the
//! CLS feed in mm/min of XYZ and in degrees/min of the rotary axes, whichever is slower. CLS arcs are
//! written as straight moves through points on the arc (chord tolerance `arc_tolerance`); the tool
//! tip of a posted move goes exactly through those points, while between points the machine
//! interpolates its axes linearly.

use super::feed_reading::{self, RotaryFeedReading};
use super::kinematics::{KinematicsError, MachineKinematics, Pose, PoseIssue};
use super::rotary_feed::{
    block_feeds, correct_moves, FeedOutput, RotaryFeedOptions, RotaryFeedReport,
};
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
    /// Machine axes of the posted moves as written (rounded to the output's decimals), in order.
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

/// The axes as the control reads them back from the written words. An axis that has moved
/// less than one output step from where it was last written (`previous`) stays there: a
/// residue of the inverse kinematics that happens to cross a rounding boundary is no move,
/// so it cannot become the distance a G94 F is read against. The written axes stay within
/// one step of the exact ones.
fn as_written(axes: [f64; 6], previous: Option<&[f64; 6]>, opts: &PostOptions) -> [f64; 6] {
    std::array::from_fn(|k| {
        let dec = if k < 3 {
            opts.linear_decimals
        } else {
            opts.angle_decimals
        };
        match previous {
            Some(p) if (axes[k] - p[k]).abs() < 10f64.powi(-(dec as i32)) => p[k],
            _ => fmt_num(axes[k], dec).parse().unwrap_or(axes[k]),
        }
    })
}

/// The feed word of one posted feed move: its mode (G93, G94 or G95) and F.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FeedWord {
    mode: FeedMode,
    f: f64,
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
    // Where the control is: the axes as last written.
    let mut prev_written = [0.0f64; 6];
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
                prev_written = as_written(prev_axes, None, opts);
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
            // IK continues from the exact solution; the move runs between the written axes.
            let written = as_written(s.axes, Some(&prev_written), opts);
            mv.start = prev_written;
            mv.end = written;
            mv.arc = None;
            mv.center = None;
            mv.normal = None;
            mv.clockwise = None;
            mv.tool_axis = None;
            prev_axes = s.axes;
            prev_written = written;
            axes_list.push(written);
            machine_moves.push(mv);
        }
        let (feeds, feed_of) = feed_words(&machine_moves, machine, opts);
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

/// The feed word of every posted feed move, and the correction report with the F and mode
/// each move is written with.
fn feed_words(
    moves: &[Move],
    machine: &Machine,
    opts: &PostOptions,
) -> (RotaryFeedReport, Vec<Option<FeedWord>>) {
    let reading = machine.rotary_feed_reading;
    let step = |d: usize| 10f64.powi(-(d as i32));
    let (lin, ang, fst) = (
        step(opts.linear_decimals),
        step(opts.angle_decimals),
        step(opts.feed_decimals),
    );
    let inverse_time = opts.feed.output == FeedOutput::InverseTime;
    // G94 (or G95 as programmed) where sound, else G93; the move lasts `t` min either way.
    let word = |m: &Move, t: f64, g94_f: f64| {
        if inverse_time || !reading.g94_sound(m, t, lin, ang, fst) {
            FeedWord {
                mode: FeedMode::InverseTime,
                f: 1.0 / t,
            }
        } else {
            FeedWord {
                mode: if m.feed_mode == FeedMode::PerRev {
                    FeedMode::PerRev
                } else {
                    FeedMode::PerMin
                },
                f: g94_f,
            }
        }
    };
    let mut feeds = correct_moves(moves, machine, &opts.feed);
    let mut out: Vec<Option<FeedWord>> = vec![None; moves.len()];
    for mf in &mut feeds.moves {
        let m = &moves[mf.move_index];
        let w = word(m, mf.time_min, mf.feed);
        if w.mode == FeedMode::InverseTime {
            mf.feed = w.f;
            mf.output = FeedOutput::InverseTime;
        }
        out[mf.move_index] = Some(w);
    }
    feeds.blocks = block_feeds(&feeds.moves);
    // Moves the correction leaves (the tip does not move): the CLS feed as mm/min of XYZ and
    // degrees/min of the rotary axes, whichever is slower.
    for (i, m) in moves.iter().enumerate() {
        if out[i].is_some() || !matches!(m.kind, MoveKind::Linear | MoveKind::Arc) {
            continue;
        }
        let f = RotaryFeedReading::LinearOnly.per_min_feed(m);
        let t = feed_reading::linear_length(m).max(feed_reading::rotary_length(m)) / f;
        out[i] = Some(if t > 0.0 && t.is_finite() {
            word(m, t, reading.read_length(m) / t / per_rev_divisor(m))
        } else {
            // No usable feed: written as programmed, the control's own reading.
            FeedWord {
                mode: m.feed_mode,
                f: m.feed,
            }
        });
    }
    (feeds, out)
}

/// What a G94 F is divided by to give the G95 F (the spindle speed for a per-rev move).
fn per_rev_divisor(m: &Move) -> f64 {
    if m.feed_mode == FeedMode::PerRev && m.spindle > 0.0 {
        m.spindle
    } else {
        1.0
    }
}

fn write_program(
    op: usize,
    tool: u32,
    machine: &Machine,
    kin: &MachineKinematics,
    moves: &[Move],
    feed_of: &[Option<FeedWord>],
    opts: &PostOptions,
) -> String {
    let mut lines: Vec<String> = Vec::new();
    let inverse_time = opts.feed.output == FeedOutput::InverseTime;
    let program_mode = if inverse_time { "G93" } else { "G94" };
    let mut mode_word = program_mode;
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
        // The feed move's own mode (G93 where G94 is unsound); rapids keep the modal one.
        let fw = feed_of[i].filter(|_| m.kind != MoveKind::Rapid);
        let want_mode = match fw.map(|w| w.mode) {
            Some(FeedMode::InverseTime) => "G93",
            Some(FeedMode::PerRev) => "G95",
            Some(FeedMode::PerMin) => "G94",
            None => mode_word,
        };
        if want_mode != mode_word {
            words.push(want_mode.to_string());
            mode_word = want_mode;
            last_f = None;
        }
        if last_g != Some(g) {
            words.push(g.to_string());
            last_g = Some(g);
        }
        words.extend(axis_words);
        if let Some(w) = fw {
            let f = fmt_num(w.f, opts.feed_decimals);
            // G93 needs an F on every block.
            if w.mode == FeedMode::InverseTime || last_f.as_deref() != Some(f.as_str()) {
                words.push(format!("F{f}"));
                last_f = Some(f);
            }
        }
        lines.push(words.join(" "));
    }
    if mode_word != program_mode {
        // Leave the control in the program's feed mode.
        lines.push(program_mode.into());
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
