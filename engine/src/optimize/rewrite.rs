//! The output program: the input with F words changed or inserted (the pipeline's last step), through
//! [`Program::with_feeds`], so every other byte stays as it was.
//!
//! Modal F: a block without an F word inherits the last F executed. When an earlier block's F
//! changes, a later block that should keep its old feed gets an F word with that feed. The walk
//! follows the move list (execution order, loops and subroutines unrolled); F words on blocks that
//! make no move are not in the move list, so where one may have run in between (by source
//! position, or any jump when such blocks exist), both possible modal values are considered and
//! the block gets an F unless both equal the feed it needs. The walk repeats until no block
//! needs a new F word.
//!
//! Units: F is written in the block's units (G20: inch; the active unit is followed in source
//! order) and mode (G93 inverse time, G95 per revolution). Written values are rounded down:
//! per-minute feeds to `feed_step` when given, all feeds to 4 decimals, so the written feed is
//! never above the computed one.

use std::collections::{BTreeMap, BTreeSet};

use super::FeedSchedule;
use crate::machine::cycle_time::move_length;
use crate::nc::{Diagnostics, Expr, FeedMode, Move, MoveKind, Program};

/// Axis letters in the order of a move's positions.
const AXES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

#[derive(Clone, Debug, Default, PartialEq)]
pub struct RewriteOptions {
    /// Rounding step of per-minute feeds in program units (e.g. 1 mm/min); None: 4 decimals.
    pub feed_step: Option<f64>,
}

/// One block whose F word is written.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BlockChange {
    pub block: usize,
    /// The value written, in program units and the block's feed mode.
    pub written: f64,
    /// The same feed in the interpreter's units (mm/min, 1/min, mm/rev).
    pub native: f64,
    /// Only restores the modal feed the block had (the optimizer did not change it).
    pub restore: bool,
    /// The block had no F word.
    pub inserted: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Rewrite {
    pub text: String,
    pub changes: Vec<BlockChange>,
    /// Blocks that get a restoring F although their executions had different modal feeds; the
    /// smallest is written (safe, but those executions run slower).
    pub ambiguous: Vec<usize>,
}

fn number(e: &Expr) -> Option<f64> {
    match e {
        Expr::Number { value, .. } => Some(*value),
        Expr::Neg(x) => number(x).map(|v| -v),
        _ => None,
    }
}

fn round_down(x: f64, step: Option<f64>, per_min: bool) -> f64 {
    let mut v = x;
    if let (Some(s), true) = (step, per_min) {
        let r = (v / s).floor() * s;
        if r > 0.0 {
            v = r;
        }
    }
    // 4 decimals as `with_feeds` prints them, downward; the tiny lift absorbs representation
    // error of values that are already on the grid.
    let r = ((v * 1e4) * (1.0 + 1e-12)).floor() / 1e4;
    if r > 0.0 {
        r
    } else {
        v
    }
}

/// Per block, in source order: mm per program unit (G20/G21) and absolute distance mode
/// (G90/G91), as they stand after the block.
fn units_and_distance_mode(blocks: &[crate::nc::Block]) -> (Vec<f64>, Vec<bool>) {
    let (mut unit, mut absolute) = (1.0, true);
    blocks
        .iter()
        .map(|b| {
            for w in &b.words {
                match (w.letter, number(&w.value)) {
                    ('G', Some(20.0)) => unit = 25.4,
                    ('G', Some(21.0)) => unit = 1.0,
                    ('G', Some(90.0)) => absolute = true,
                    ('G', Some(91.0)) => absolute = false,
                    _ => {}
                }
            }
            (unit, absolute)
        })
        .unzip()
}

fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-12)
}

/// Rewrite `program` (whose interpretation gave `moves`) with the schedule's block feeds.
pub fn rewrite_program(
    program: &Program,
    moves: &[Move],
    schedule: &FeedSchedule,
    options: &RewriteOptions,
) -> Result<Rewrite, Diagnostics> {
    // Moves of a library program are set by F words in another file, which is not rewritten.
    if let Some(m) = moves.iter().find(|m| m.source.is_some()) {
        return Err(crate::nc::Diagnostic::new(
            m.line,
            1,
            "this block runs a program of the program library (another file): the optimizer rewrites the F words of this program only, so a program whose calls run library programs is simulated but not optimized",
        )
        .into());
    }
    let blocks = program.blocks();
    let nb = blocks.len();
    let (factor, _) = units_and_distance_mode(blocks);
    let mut has_f = vec![false; nb];
    let mut f_literal = vec![None; nb];
    let mut jump = vec![false; nb];
    for (i, b) in blocks.iter().enumerate() {
        for w in &b.words {
            match (w.letter, number(&w.value)) {
                ('M', Some(v)) if v == 98.0 || v == 99.0 => jump[i] = true,
                ('F', v) if !w.comma => {
                    has_f[i] = true;
                    f_literal[i] = v;
                }
                _ => {}
            }
        }
        if b.o_word.is_some() {
            jump[i] = true;
        }
    }
    let in_units = |m: &Move, native: f64| match m.feed_mode {
        FeedMode::InverseTime => native,
        _ => native / factor[m.block],
    };
    // F-bearing blocks that make no move: invisible in the move list.
    let mut makes_move = vec![false; nb];
    for m in moves {
        if m.block < nb {
            makes_move[m.block] = true;
        }
    }
    let mut hidden_prefix = vec![0usize; nb + 1];
    let mut jump_prefix = vec![0usize; nb + 1];
    for i in 0..nb {
        hidden_prefix[i + 1] = hidden_prefix[i] + usize::from(has_f[i] && !makes_move[i]);
        jump_prefix[i + 1] = jump_prefix[i] + usize::from(jump[i]);
    }
    let any_hidden = hidden_prefix[nb] > 0;
    // Could an unseen F word run between moves of blocks p and b?
    let unseen = |p: usize, b: usize| -> bool {
        if !any_hidden {
            return false;
        }
        if b <= p {
            return true;
        }
        hidden_prefix[b] - hidden_prefix[p + 1] > 0 || jump_prefix[b + 1] - jump_prefix[p] > 0
    };

    // Written values of the optimized blocks.
    let mut written: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
    let step = options.feed_step;
    let mut first_move: BTreeMap<usize, &Move> = BTreeMap::new();
    for m in moves {
        first_move.entry(m.block).or_insert(m);
    }
    for bf in schedule.blocks.iter().filter(|b| b.changed) {
        let Some(&m) = first_move.get(&bf.block) else {
            continue;
        };
        let per_min = bf.feed_mode == FeedMode::PerMin;
        let w = round_down(in_units(m, bf.feed), step, per_min);
        let orig = f_literal.get(bf.block).copied().flatten();
        if orig.is_some_and(|o| same(o, w)) {
            continue;
        }
        let native = match bf.feed_mode {
            FeedMode::InverseTime => w,
            _ => w * factor[bf.block],
        };
        written.insert(bf.block, (w, native));
    }
    // Smallest and largest original modal feed per block (program units), for restoring.
    let mut orig_range: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
    for m in moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Linear | MoveKind::Arc))
    {
        let v = in_units(m, m.feed);
        let e = orig_range.entry(m.block).or_insert((v, v));
        e.0 = e.0.min(v);
        e.1 = e.1.max(v);
    }
    let mut restored: BTreeSet<usize> = BTreeSet::new();
    loop {
        let mut added = false;
        let mut cand: Vec<f64> = Vec::new();
        let mut prev: Option<(usize, f64)> = None;
        for m in moves {
            let b = m.block;
            let orig_here = in_units(m, m.feed);
            let value_of = |b: usize| -> Option<f64> {
                if let Some(&(w, _)) = written.get(&b) {
                    Some(w)
                } else if restored.contains(&b) {
                    orig_range.get(&b).map(|r| r.0)
                } else if has_f.get(b).copied().unwrap_or(false) {
                    Some(orig_here)
                } else {
                    None
                }
            };
            if let Some(v) = value_of(b) {
                cand = vec![v];
            } else {
                let cand_in = match prev {
                    None => vec![orig_here],
                    Some((_, op)) if !same(op, orig_here) => vec![orig_here],
                    Some((pb, _)) if unseen(pb, b) => {
                        let mut c = cand.clone();
                        if !c.iter().any(|&x| same(x, orig_here)) {
                            c.push(orig_here);
                        }
                        c
                    }
                    _ => cand.clone(),
                };
                let feed_move = matches!(m.kind, MoveKind::Linear | MoveKind::Arc);
                if feed_move && cand_in.iter().any(|&c| !same(c, orig_here)) {
                    restored.insert(b);
                    added = true;
                    cand = vec![orig_range.get(&b).map(|r| r.0).unwrap_or(orig_here)];
                } else {
                    cand = cand_in;
                }
            }
            prev = Some((b, orig_here));
        }
        if !added {
            break;
        }
    }
    let mut changes: Vec<BlockChange> = Vec::new();
    let mut ambiguous = Vec::new();
    for (&b, &(w, native)) in &written {
        changes.push(BlockChange {
            block: b,
            written: w,
            native,
            restore: false,
            inserted: !has_f[b],
        });
    }
    for &b in &restored {
        let Some(&(lo, hi)) = orig_range.get(&b) else {
            continue;
        };
        if !same(lo, hi) {
            ambiguous.push(b);
        }
        let mode = first_move.get(&b).map(|m| m.feed_mode).unwrap_or_default();
        let native = match mode {
            FeedMode::InverseTime => lo,
            _ => lo * factor[b],
        };
        changes.push(BlockChange {
            block: b,
            written: lo,
            native,
            restore: true,
            inserted: true,
        });
    }
    changes.sort_by_key(|c| c.block);
    let list: Vec<(usize, f64)> = changes.iter().map(|c| (c.block, c.written)).collect();
    let text = program.with_feeds(&list)?;
    Ok(Rewrite {
        text,
        changes,
        ambiguous,
    })
}

/// Check a rewrite against the re-interpretation of its text: same moves (kind, block, end
/// points bit for bit), feed moves of changed blocks at the written feed, every other move at its
/// original feed. Returns the first difference.
pub fn verify_rewrite(
    original: &[Move],
    rewritten: &[Move],
    rewrite: &Rewrite,
) -> Result<(), String> {
    if original.len() != rewritten.len() {
        return Err(format!(
            "{} moves before, {} after",
            original.len(),
            rewritten.len()
        ));
    }
    let changed: BTreeMap<usize, &BlockChange> =
        rewrite.changes.iter().map(|c| (c.block, c)).collect();
    for (i, (a, b)) in original.iter().zip(rewritten).enumerate() {
        if a.kind != b.kind || a.block != b.block || a.end != b.end || a.start != b.start {
            return Err(format!("move {i} (line {}): geometry differs", a.line));
        }
        if a.spindle != b.spindle || a.tool != b.tool || a.feed_mode != b.feed_mode {
            return Err(format!(
                "move {i} (line {}): spindle/tool/mode differs",
                a.line
            ));
        }
        if !matches!(a.kind, MoveKind::Linear | MoveKind::Arc) {
            continue;
        }
        let want = match changed.get(&a.block) {
            // Ambiguous restore: the smallest original, never above this execution's own.
            Some(c) if c.restore && rewrite.ambiguous.contains(&c.block) && b.feed > a.feed => {
                return Err(format!(
                    "move {i} (line {}): restored feed above original",
                    a.line
                ));
            }
            Some(c) => c.native,
            None => a.feed,
        };
        if !same(b.feed, want) {
            return Err(format!(
                "move {i} (line {}): feed {} after, {} expected",
                a.line, b.feed, want
            ));
        }
    }
    Ok(())
}

/// A move written as several blocks.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WrittenSplit {
    /// The move (index in the original move list) and its block and line.
    pub move_index: usize,
    pub block: usize,
    pub line: u32,
    /// Where the parts meet, from the move's start in machine-axis length (mm, or degrees
    /// on a rotary-only move).
    pub points: Vec<f64>,
    /// End of each part, every axis (the last is the move's end): mm and degrees.
    pub ends: Vec<[f64; 6]>,
    /// Machine-axis feed of each part as written, mm/min.
    pub feeds: Vec<f64>,
    /// The F of each part as the interpreter reads it (the block's mode: mm/min or 1/min).
    pub words: Vec<f64>,
}

/// Why a planned split was not written.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SkippedSplit {
    pub line: u32,
    pub reason: String,
}

/// Writes the split plans into `rewritten` (the output of [`rewrite_program`], whose moves are
/// `after`, one for one with the original `moves`): a planned move's block gets new `G1` lines
/// before it that end at the split points, each with its own F, and the block itself keeps
/// all its characters but its F, which becomes the last part's feed. The next feed block
/// gets its modal F written out if it had none, so nothing after the split changes speed.
///
/// Only plain blocks are split: one execution, a G1 move at a per-minute (G94) or
/// inverse-time (G93) feed in G90 with the moving axes written as numbers, and no other
/// words but N, G1, X, Y, Z, A, B, C and F. Every axis is interpolated linearly to the split
/// point, as the control does (rotary axes too); in G93 each part gets the inverse of its
/// own time. Others are reported in the second list with the reason. Coordinates are written
/// with the block's own decimals (at least 3, at most 6).
pub fn write_splits(
    rewritten: &str,
    moves: &[Move],
    after: &[Move],
    plans: &[super::SplitPlan],
    feed_step: Option<f64>,
) -> Result<(String, Vec<WrittenSplit>, Vec<SkippedSplit>), Diagnostics> {
    let program = Program::parse(rewritten)?;
    let blocks = program.blocks();
    let nb = blocks.len();
    let (factor, absolute) = units_and_distance_mode(blocks);
    let mut executions = vec![0usize; nb];
    for m in moves {
        if m.block < nb {
            executions[m.block] += 1;
        }
    }
    let mut feeds: Vec<(usize, f64)> = Vec::new();
    let mut inserts: BTreeMap<usize, Vec<String>> = BTreeMap::new();
    let mut written = Vec::new();
    let mut skipped = Vec::new();
    let mut fixed_next: BTreeSet<usize> = BTreeSet::new();
    for plan in plans {
        let i = plan.move_index;
        let (Some(m), Some(a)) = (moves.get(i), after.get(i)) else {
            continue;
        };
        let mut skip = |reason: &str| {
            skipped.push(SkippedSplit {
                line: m.line,
                reason: reason.to_string(),
            })
        };
        let b = m.block;
        let inverse_time = m.feed_mode == FeedMode::InverseTime;
        if m.kind != MoveKind::Linear || m.feed_mode == FeedMode::PerRev {
            skip("only G1 moves at a per-minute or inverse-time feed are split");
            continue;
        }
        let rotary = m.turns_rotary();
        if rotary && factor[b] != 1.0 {
            skip("rotary axes move in an inch program");
            continue;
        }
        if executions.get(b) != Some(&1) {
            skip("the block runs more than once");
            continue;
        }
        if !absolute[b] {
            skip("incremental distance mode (G91)");
            continue;
        }
        let block = &blocks[b];
        let plain = block.o_word.is_none()
            && block.assignments.is_empty()
            && block.words.iter().all(|w| {
                !w.comma
                    && match (w.letter, number(&w.value)) {
                        // Not G93 here: the parts come before the block that sets it.
                        ('G', Some(g)) => g == 1.0,
                        ('X' | 'Y' | 'Z' | 'A' | 'B' | 'C' | 'F', Some(_)) => true,
                        _ => false,
                    }
            });
        if !plain {
            skip("the block has words other than N, G1, X, Y, Z, A, B, C and F");
            continue;
        }
        // Program-frame end from the block's own words; the start is the end minus the
        // machine-frame travel (work offsets are translations).
        let unit = factor[b];
        let mut end = [0.0; 6];
        let mut moving = [false; 6];
        let mut decimals = 3usize;
        let mut ok = true;
        for (k, letter) in AXES.into_iter().enumerate() {
            moving[k] = (m.end[k] - m.start[k]).abs() > 1e-9;
            match block.words.iter().find(|w| w.letter == letter) {
                Some(w) => {
                    end[k] = number(&w.value).unwrap_or(0.0);
                    let text = program.text(w.value_span);
                    if let Some((_, frac)) = text.split_once('.') {
                        decimals = decimals.max(frac.len().min(6));
                    }
                }
                None if moving[k] => ok = false,
                None => {}
            }
        }
        if !ok {
            skip("a moving axis is not written in the block");
            continue;
        }
        let length = move_length(m);
        if plan.feeds.len() != plan.points.len() + 1 || length <= 0.0 {
            skip("empty plan");
            continue;
        }
        // Neighbouring parts at the same written feed are one part (in G93 the written
        // value depends on the part's length too: compare the feeds themselves).
        let written_feed = |f: f64| {
            if inverse_time {
                f
            } else {
                round_down(f / unit, feed_step, true)
            }
        };
        let mut points = Vec::new();
        let mut part_feeds_mm = vec![plan.feeds[0]];
        for (&p, &f) in plan.points.iter().zip(&plan.feeds[1..]) {
            let prev = *part_feeds_mm.last().expect("starts with one");
            if same(written_feed(f), written_feed(prev)) {
                continue;
            }
            points.push(p);
            part_feeds_mm.push(f);
        }
        if points.is_empty() {
            skip("every part gets the same feed");
            continue;
        }
        let nl = line_ending(&program, b);
        let mut lines = Vec::new();
        let mut ends = Vec::new();
        let mut part_feeds = Vec::new();
        let mut words = Vec::new();
        // The F of the part from `from` to `to` (fractions of the move) at `feed` mm/min, as
        // written and as read (G93: the inverse of the part's time, rounded down).
        let part_word = |from: f64, to: f64, feed: f64| -> (f64, f64) {
            if inverse_time {
                let w = round_down(feed / ((to - from) * length), None, false);
                (w, w * (to - from) * length)
            } else {
                let w = written_feed(feed);
                (w, w * unit)
            }
        };
        let mut from = 0.0;
        for (&d, &feed) in points.iter().zip(&part_feeds_mm) {
            let u = (d / length).clamp(0.0, 1.0);
            let mut line = String::from("G1");
            let mut machine_end = [0.0; 6];
            for k in 0..6 {
                let travel = m.end[k] - m.start[k];
                machine_end[k] = m.start[k] + u * travel;
                if moving[k] {
                    let scale = if k < 3 { unit } else { 1.0 };
                    let at = end[k] - (1.0 - u) * travel / scale;
                    line.push_str(&format!(" {}{:.*}", AXES[k], decimals, at));
                }
            }
            let (w, velocity) = part_word(from, u, feed);
            line.push_str(&format!(" F{}", crate::nc::format_feed(w, false)));
            line.push_str(nl);
            lines.push(line);
            ends.push(machine_end);
            part_feeds.push(velocity);
            words.push(if inverse_time { w } else { w * unit });
            from = u;
        }
        let last_feed = part_feeds_mm.last().copied().unwrap_or(a.feed);
        let (last, velocity) = part_word(from, 1.0, last_feed);
        ends.push(m.end);
        part_feeds.push(velocity);
        words.push(if inverse_time { last } else { last * unit });
        feeds.push((b, last));
        // The next feed move must not inherit the last part's feed.
        if let Some(j) = (i + 1..moves.len())
            .find(|&j| matches!(moves[j].kind, MoveKind::Linear | MoveKind::Arc))
        {
            let nb_ = moves[j].block;
            let has_f = blocks[nb_]
                .words
                .iter()
                .any(|w| w.letter == 'F' && !w.comma);
            if !has_f && nb_ != b && fixed_next.insert(nb_) {
                let native = after[j].feed;
                let value = match after[j].feed_mode {
                    FeedMode::InverseTime => native,
                    _ => native / factor[nb_],
                };
                feeds.push((nb_, value));
            }
        }
        inserts.insert(b, lines);
        written.push(WrittenSplit {
            move_index: i,
            block: b,
            line: m.line,
            points,
            ends,
            feeds: part_feeds,
            words,
        });
    }
    // A block listed both as split and as the next block of another split keeps the split's F.
    let mut seen = BTreeSet::new();
    feeds.retain(|(b, _)| seen.insert(*b));
    let text = if feeds.is_empty() {
        rewritten.to_string()
    } else {
        program.with_feeds(&feeds)?
    };
    // Insert the new lines before their blocks (lines are blocks, one for one).
    let mut out = String::with_capacity(text.len() + inserts.len() * 40);
    for (index, line) in text.split_inclusive('\n').enumerate() {
        if let Some(new) = inserts.get(&index) {
            for l in new {
                out.push_str(l);
            }
        }
        out.push_str(line);
    }
    Ok((out, written, skipped))
}

fn line_ending(program: &Program, block: usize) -> &'static str {
    let b = &program.blocks()[block];
    if program.text(crate::nc::Span {
        start: b.span.end,
        end: b.end,
    }) == "\r\n"
    {
        "\r\n"
    } else {
        "\n"
    }
}

/// Checks the split program's moves against the un-split rewrite's: every move the same (kind,
/// end point, feed of feed moves), except each split move, which must come as its parts (G1,
/// ending at the split points within 1e-3 mm and at the move's own end exactly, at the part
/// feeds). Returns, for each move of the split program, the index of the move it belongs to.
pub fn verify_splits(
    after: &[Move],
    split: &[Move],
    written: &[WrittenSplit],
) -> Result<Vec<usize>, String> {
    let by_move: BTreeMap<usize, &WrittenSplit> =
        written.iter().map(|w| (w.move_index, w)).collect();
    let mut owner = Vec::with_capacity(split.len());
    let mut j = 0;
    let next = |j: usize| {
        split
            .get(j)
            .ok_or_else(|| format!("the split program ends early (move {j})"))
    };
    for (i, a) in after.iter().enumerate() {
        match by_move.get(&i) {
            Some(w) => {
                for (k, (end, feed)) in w.ends.iter().zip(&w.words).enumerate() {
                    let b = next(j)?;
                    let last = k + 1 == w.ends.len();
                    // mm and degrees alike: both are written with the same decimals.
                    let d = (0..6)
                        .map(|c| (b.end[c] - end[c]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    let end_ok = if last { b.end == a.end } else { d <= 1e-3 };
                    if b.kind != MoveKind::Linear || !end_ok || !same(b.feed, *feed) {
                        return Err(format!(
                            "line {}: part {} of the split differs (end off by {d:.2e} mm, feed {} for {})",
                            a.line,
                            k + 1,
                            b.feed,
                            feed
                        ));
                    }
                    owner.push(i);
                    j += 1;
                }
            }
            None => {
                let b = next(j)?;
                let feed_move = matches!(a.kind, MoveKind::Linear | MoveKind::Arc);
                if b.kind != a.kind || b.end != a.end || (feed_move && !same(b.feed, a.feed)) {
                    return Err(format!(
                        "line {}: the move after splitting differs from the rewrite's",
                        a.line
                    ));
                }
                owner.push(i);
                j += 1;
            }
        }
    }
    if j != split.len() {
        return Err(format!(
            "{} moves after splitting, {} expected",
            split.len(),
            j
        ));
    }
    Ok(owner)
}
