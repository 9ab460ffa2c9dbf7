//! Rotary-axis feed correction (a rotary move's F read as the machine reads it, and the feed that gives the tip its speed).
//!
//! A control without a 5-axis feed mode reads F as the rate of a machine distance `I`: the XYZ
//! distance of the move, or the combined XYZ and rotary distance, as the machine's
//! `rotary_feed_reading` says (or the rotary distance in degrees when X, Y and Z do not move;
//! see [`super::feed_reading`]). When a rotary axis moves too, the tool tip moves through the
//! part at a different speed. For every feed move, split into steps, we take the tool-tip
//! distance `i` in the part frame (forward kinematics of the linearly interpolated machine axes,
//! which is the path the machine really cuts), the machine distance `I`, the intended time
//! `t = i/f` and the corrected feed `F = I/t` (G94), or the inverse-time feed `F = 1/t` (G93). The time is
//! lengthened where the machine's rotary speed or max feed would be exceeded, and the move says
//! which limit bound.
//!
//! The intended tool-tip feed `f` of a move is its programmed feed in mm/min (G94), feed × spindle
//! speed (G95), or, for a G93 move, `F·I`: the rate a programmer who computed the inverse time
//! from the machine distance meant.

use super::cycle_time::move_length;
use super::feed_reading::RotaryFeedReading;
use super::kinematics::MachineKinematics;
use super::Machine;
use crate::nc::{self, FeedMode, InterpretOptions, Move, MoveKind, Program};
use serde::{Deserialize, Serialize};

/// The feed words the correction writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum FeedOutput {
    /// F in mm/min (G94): F = I/t.
    #[default]
    PerMin,
    /// F in 1/min (G93): F = 1/t.
    InverseTime,
}

#[derive(Clone, Debug, PartialEq)]
pub struct RotaryFeedOptions {
    pub output: FeedOutput,
    /// Largest rotary change per step, degrees.
    pub max_step_deg: f64,
    /// Largest machine XYZ distance per step, mm.
    pub max_step_mm: f64,
    /// Fewest steps per move.
    pub min_steps: usize,
}

impl Default for RotaryFeedOptions {
    fn default() -> Self {
        RotaryFeedOptions {
            output: FeedOutput::PerMin,
            max_step_deg: 0.25,
            max_step_mm: 0.5,
            min_steps: 8,
        }
    }
}

/// One step of a move.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FeedStep {
    /// Tool-tip distance in the part frame, mm.
    pub tip_length: f64,
    /// Machine distance as the control reads it (the machine's `rotary_feed_reading`: mm,
    /// degrees for a rotary-only move, or both combined).
    pub machine_length: f64,
    /// Intended time i/f, min.
    pub time_min: f64,
    /// The step's own corrected feed before limits: I/t (mm/min) or 1/t (G93, 1/min); the
    /// move's single F is computed from the sums over its steps.
    pub feed: f64,
}

/// What made a move slower than the intended tool-tip feed.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "limit")]
pub enum FeedLimit {
    /// The rotary axis would have turned faster than the machine's max rotary speed.
    RotarySpeed { axis: char, required_deg_min: f64 },
    /// The machine axes would have moved faster than the machine's max feed.
    MaxFeed { required_mm_min: f64 },
}

/// The correction of one move.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RotaryMoveFeed {
    pub move_index: usize,
    pub block: usize,
    pub line: u32,
    /// Intended tool-tip feed f, mm/min.
    pub intended_feed: f64,
    /// Σ i, mm.
    pub tip_length: f64,
    /// I, as the machine's `rotary_feed_reading` reads it.
    pub machine_length: f64,
    /// Time of the move after the correction, min (i/f unless a limit binds).
    pub time_min: f64,
    /// Corrected F in the output's unit (mm/min or 1/min).
    pub feed: f64,
    pub output: FeedOutput,
    /// Tool-tip speed the uncorrected program gives, mm/min.
    pub uncorrected_tip_speed: f64,
    /// Fastest rotary rate after the correction, degrees/min.
    pub rotary_rate_deg_min: f64,
    pub limited_by: Option<FeedLimit>,
    pub steps: Vec<FeedStep>,
}

/// The F of one block (the slowest of its moves: safe for every execution).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RotaryBlockFeed {
    pub block: usize,
    pub line: u32,
    pub feed: f64,
    pub output: FeedOutput,
    pub limited: bool,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RotaryFeedReport {
    pub moves: Vec<RotaryMoveFeed>,
    pub blocks: Vec<RotaryBlockFeed>,
    /// Feed moves left as they were, with the reason (move index, line, reason).
    pub skipped: Vec<(usize, u32, String)>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RotaryFeedError {
    #[error("program: {0}")]
    Program(#[from] nc::Diagnostics),
    #[error("line {line}: {message}")]
    Unsupported { line: u32, message: String },
}

/// Machine axes at parameter s of a move (arcs along the arc, rotary axes linear).
pub fn axes_at(m: &Move, s: f64) -> [f64; 6] {
    if let Some(arc) = &m.arc {
        return arc.point_at(s);
    }
    let mut p = [0.0; 6];
    for (k, v) in p.iter_mut().enumerate() {
        *v = m.start[k] + (m.end[k] - m.start[k]) * s;
    }
    p
}

fn step_count(m: &Move, opts: &RotaryFeedOptions) -> usize {
    let rot = m.rotary_travel();
    let lin = move_length(m);
    let n = (rot / opts.max_step_deg.max(1e-6))
        .ceil()
        .max((lin / opts.max_step_mm.max(1e-6)).ceil())
        .max(opts.min_steps.max(1) as f64);
    n.min(100_000.0) as usize
}

/// Tool-tip path length of a move in the part frame (forward kinematics at `n` steps).
pub fn tip_length(kin: &MachineKinematics, m: &Move, n: usize) -> f64 {
    let mut prev = kin.forward(&axes_at(m, 0.0)).tip;
    let mut len = 0.0;
    for k in 1..=n {
        let p = kin.forward(&axes_at(m, k as f64 / n as f64)).tip;
        len +=
            ((p[0] - prev[0]).powi(2) + (p[1] - prev[1]).powi(2) + (p[2] - prev[2]).powi(2)).sqrt();
        prev = p;
    }
    len
}

/// Tool-tip speed of one feed move as the control runs it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TipSpeed {
    pub move_index: usize,
    pub block: usize,
    pub line: u32,
    pub tip_length: f64,
    pub time_min: f64,
    /// mm/min
    pub speed: f64,
}

/// Tool-tip speed (part frame) of every feed move of an interpreted program on this machine,
/// its F read as the machine's control reads it.
pub fn tool_tip_speeds(
    moves: &[Move],
    machine: &Machine,
    opts: &RotaryFeedOptions,
) -> Vec<TipSpeed> {
    let kin = MachineKinematics::of(machine);
    let mut out = Vec::new();
    for (i, m) in moves.iter().enumerate() {
        if !matches!(m.kind, MoveKind::Linear | MoveKind::Arc) {
            continue;
        }
        let Some(t) = machine.rotary_feed_reading.programmed_time_min(m) else {
            continue;
        };
        let len = tip_length(&kin, m, step_count(m, opts));
        out.push(TipSpeed {
            move_index: i,
            block: m.block,
            line: m.line,
            tip_length: len,
            time_min: t,
            speed: if t > 0.0 { len / t } else { f64::NAN },
        });
    }
    out
}

/// Corrected feeds for moves in machine axes (an interpreted G-code program, or a CLS path after
/// inverse kinematics).
pub fn correct_moves(
    moves: &[Move],
    machine: &Machine,
    opts: &RotaryFeedOptions,
) -> RotaryFeedReport {
    let kin = MachineKinematics::of(machine);
    let names = ['A', 'B', 'C'];
    let mut report = RotaryFeedReport::default();
    for (idx, m) in moves.iter().enumerate() {
        if !matches!(m.kind, MoveKind::Linear | MoveKind::Arc) {
            continue;
        }
        let reading = machine.rotary_feed_reading;
        let big_i = reading.read_length(m);
        let f = reading.per_min_feed(m);
        if !(f > 0.0 && f.is_finite()) {
            report.skipped.push((idx, m.line, "no usable feed".into()));
            continue;
        }
        let n = step_count(m, opts);
        let mut steps = Vec::with_capacity(n);
        let mut prev = kin.forward(&axes_at(m, 0.0)).tip;
        let mut i_sum = 0.0;
        for k in 1..=n {
            let p = kin.forward(&axes_at(m, k as f64 / n as f64)).tip;
            let d =
                ((p[0] - prev[0]).powi(2) + (p[1] - prev[1]).powi(2) + (p[2] - prev[2]).powi(2))
                    .sqrt();
            prev = p;
            i_sum += d;
            steps.push(FeedStep {
                tip_length: d,
                machine_length: big_i / n as f64,
                time_min: d / f,
                feed: match opts.output {
                    _ if d <= 0.0 => f64::INFINITY,
                    FeedOutput::PerMin => big_i / n as f64 / (d / f),
                    FeedOutput::InverseTime => f / d,
                },
            });
        }
        let mut t = i_sum / f;
        let mut limited_by = None;
        if let Some(max_rot) = machine.max_rotary_speed_deg_min {
            for k in 3..6 {
                let d = (m.end[k] - m.start[k]).abs();
                if d > 0.0 && d / max_rot > t {
                    limited_by = Some(FeedLimit::RotarySpeed {
                        axis: names[k - 3],
                        required_deg_min: if t > 0.0 { d / t } else { f64::INFINITY },
                    });
                    t = d / max_rot;
                }
            }
        }
        let xyz = (0..3)
            .map(|k| (m.end[k] - m.start[k]).powi(2))
            .sum::<f64>()
            .sqrt();
        if xyz > 1e-12 && xyz / machine.max_feed > t {
            limited_by = Some(FeedLimit::MaxFeed {
                required_mm_min: if t > 0.0 { xyz / t } else { f64::INFINITY },
            });
            t = xyz / machine.max_feed;
        }
        if !(t > 0.0) {
            report.skipped.push((
                idx,
                m.line,
                "the tool tip does not move and no limit sets a time".into(),
            ));
            continue;
        }
        let feed = match opts.output {
            FeedOutput::PerMin if m.feed_mode == FeedMode::PerRev => big_i / t / m.spindle,
            FeedOutput::PerMin => big_i / t,
            FeedOutput::InverseTime => 1.0 / t,
        };
        let rot_rate = (3..6)
            .map(|k| (m.end[k] - m.start[k]).abs() / t)
            .fold(0.0, f64::max);
        let uncorrected = reading
            .programmed_time_min(m)
            .map_or(f64::NAN, |tc| i_sum / tc);
        report.moves.push(RotaryMoveFeed {
            move_index: idx,
            block: m.block,
            line: m.line,
            intended_feed: f,
            tip_length: i_sum,
            machine_length: big_i,
            time_min: t,
            feed,
            output: opts.output,
            uncorrected_tip_speed: uncorrected,
            rotary_rate_deg_min: rot_rate,
            limited_by,
            steps,
        });
    }
    report.blocks = block_feeds(&report.moves);
    report
}

/// One F per block: the slowest of its moves.
pub fn block_feeds(moves: &[RotaryMoveFeed]) -> Vec<RotaryBlockFeed> {
    let mut blocks: Vec<RotaryBlockFeed> = Vec::new();
    let mut at: std::collections::HashMap<usize, usize> = std::collections::HashMap::new();
    for mf in moves {
        match at.get(&mf.block) {
            Some(&k) => {
                let b = &mut blocks[k];
                b.feed = b.feed.min(mf.feed);
                b.limited |= mf.limited_by.is_some();
            }
            None => {
                at.insert(mf.block, blocks.len());
                blocks.push(RotaryBlockFeed {
                    block: mf.block,
                    line: mf.line,
                    feed: mf.feed,
                    output: mf.output,
                    limited: mf.limited_by.is_some(),
                });
            }
        }
    }
    blocks
}

/// The F value `with_feeds` writes (4 decimals), for comparisons.
fn written(feed: f64) -> f64 {
    (feed * 1e4).round() / 1e4
}

/// Correct a G-code program in place: only F words change (or are added where the modal feed
/// would otherwise carry a corrected value into a block that needs another). A G94 program gets
/// mm/min, a G93 program inverse times; a G94 program asked for inverse time is converted (see
/// `to_inverse_time`); other mode changes are refused. Inch programs are refused (the rewrite
/// would need inch feeds).
pub fn correct_program(
    source: &str,
    interpret: &InterpretOptions,
    machine: &Machine,
    opts: &RotaryFeedOptions,
) -> Result<(String, RotaryFeedReport), RotaryFeedError> {
    let program = Program::parse(source)?;
    for b in program.blocks() {
        for w in &b.words {
            if w.letter == 'G' && matches!(w.value, nc::Expr::Number { value, .. } if value == 20.0)
            {
                return Err(RotaryFeedError::Unsupported {
                    line: b.line,
                    message: "inch programs (G20) are not corrected".into(),
                });
            }
        }
    }
    let interp = nc::interpret_program(&program, interpret)?;
    let per_min = |m: &&Move| m.feed_mode == FeedMode::PerMin;
    let feed_moves: Vec<&Move> = interp
        .moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Linear | MoveKind::Arc))
        .collect();
    let g94_rotary = feed_moves
        .iter()
        .find(|m| m.feed_mode != FeedMode::InverseTime && m.turns_rotary());
    if let (FeedOutput::PerMin, RotaryFeedReading::InverseTimeOnly, Some(m)) =
        (opts.output, machine.rotary_feed_reading, g94_rotary)
    {
        return Err(RotaryFeedError::Unsupported {
            line: m.line,
            message: "the machine's rotary_feed_reading is inverse_time_only: its control runs a move that turns a rotary axis only in G93; ask for inverse_time output".into(),
        });
    }
    if opts.output == FeedOutput::InverseTime
        && !feed_moves.is_empty()
        && feed_moves.iter().all(per_min)
    {
        return to_inverse_time(&program, &interp.moves, machine, opts);
    }
    for m in &interp.moves {
        if !matches!(m.kind, MoveKind::Linear | MoveKind::Arc) {
            continue;
        }
        let ok = matches!(
            (opts.output, m.feed_mode),
            (FeedOutput::PerMin, FeedMode::PerMin | FeedMode::PerRev)
                | (FeedOutput::InverseTime, FeedMode::InverseTime)
        );
        if !ok {
            return Err(RotaryFeedError::Unsupported {
                line: m.line,
                message: format!(
                    "feed move in {:?} mode but {:?} output asked: changing the feed mode needs G93/G94 words, not only F words",
                    m.feed_mode, opts.output
                ),
            });
        }
    }
    let report = correct_moves(&interp.moves, machine, opts);
    let block_feed: std::collections::HashMap<usize, f64> =
        report.blocks.iter().map(|b| (b.block, b.feed)).collect();
    let has_f = |block: usize| {
        program
            .blocks()
            .get(block)
            .is_some_and(|b| b.words.iter().any(|w| w.letter == 'F' && !w.comma))
    };
    let mut listed: std::collections::BTreeMap<usize, f64> = std::collections::BTreeMap::new();
    let mut modal: Option<f64> = None;
    for m in &interp.moves {
        let feed_move = matches!(m.kind, MoveKind::Linear | MoveKind::Arc);
        if feed_move {
            let needed = block_feed.get(&m.block).copied().unwrap_or(m.feed);
            if let Some(&v) = listed.get(&m.block) {
                modal = Some(v);
                continue;
            }
            let effective = if has_f(m.block) {
                m.feed
            } else {
                modal.unwrap_or(m.feed)
            };
            if (written(effective) - written(needed)).abs() > 0.0 {
                listed.insert(m.block, needed);
                modal = Some(needed);
            } else {
                modal = Some(effective);
            }
        } else if let Some(&v) = listed.get(&m.block) {
            modal = Some(v);
        } else if has_f(m.block) {
            modal = Some(m.feed);
        }
    }
    let changes: Vec<(usize, f64)> = listed.into_iter().collect();
    let text = program.with_feeds(&changes)?;
    Ok((text, report))
}

/// A G94 program written in inverse time: a `G93` line before the first feed block and a `G94`
/// line after the last one, and every feed block an F = 1/t with t the move's intended time
/// (tool-tip distance / programmed feed, or what a machine limit imposes). Refused when the
/// program changes the feed mode itself between its first and last feed moves, or when a
/// block runs several times with different times.
fn to_inverse_time(
    program: &Program,
    moves: &[Move],
    machine: &Machine,
    opts: &RotaryFeedOptions,
) -> Result<(String, RotaryFeedReport), RotaryFeedError> {
    let report = correct_moves(moves, machine, opts);
    let feed_blocks: Vec<usize> = moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Linear | MoveKind::Arc))
        .map(|m| m.block)
        .collect();
    let (first, last) = match (feed_blocks.iter().min(), feed_blocks.iter().max()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => return Ok((program.source().to_string(), report)),
    };
    for b in &program.blocks()[first..=last] {
        for w in &b.words {
            if w.letter == 'G'
                && matches!(w.value, nc::Expr::Number { value, .. } if value == 93.0 || value == 94.0 || value == 95.0)
            {
                return Err(RotaryFeedError::Unsupported {
                    line: b.line,
                    message: "the program sets its own feed mode between its feed moves; convert it to inverse time by hand or post the CLS".into(),
                });
            }
        }
    }
    if let Some((_, line, why)) = report.skipped.first() {
        return Err(RotaryFeedError::Unsupported {
            line: *line,
            message: format!("no inverse time for this move: {why}"),
        });
    }
    // G93 needs an F on every feed block; one value per block.
    let mut per_block: std::collections::BTreeMap<usize, f64> = Default::default();
    for b in &report.blocks {
        match per_block.get(&b.block) {
            Some(&v) if written(v) != written(b.feed) => {
                return Err(RotaryFeedError::Unsupported {
                    line: b.line,
                    message: "the block runs several times with different times (G93 needs one F per block)".into(),
                })
            }
            _ => {
                per_block.insert(b.block, b.feed);
            }
        }
    }
    let changes: Vec<(usize, f64)> = per_block.into_iter().collect();
    let text = program.with_feeds(&changes)?;
    let nl = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut out = String::with_capacity(text.len() + 16);
    for (index, line) in text.split_inclusive('\n').enumerate() {
        if index == first {
            out.push_str("G93");
            out.push_str(nl);
        }
        out.push_str(line);
        if index == last {
            if !line.ends_with('\n') {
                out.push_str(nl);
            }
            out.push_str("G94");
            out.push_str(nl);
        }
    }
    Ok((out, report))
}
