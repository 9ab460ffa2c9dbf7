//! The output program: the input with F words changed or inserted (DESIGN.md step 7), through
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
use crate::nc::{Diagnostics, Expr, FeedMode, Move, MoveKind, Program};

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
    let blocks = program.blocks();
    let nb = blocks.len();
    // Unit factor (mm per program unit) per block, in source order.
    let mut factor = vec![1.0; nb];
    let mut f = 1.0;
    let mut has_f = vec![false; nb];
    let mut f_literal = vec![None; nb];
    let mut jump = vec![false; nb];
    for (i, b) in blocks.iter().enumerate() {
        for w in &b.words {
            match (w.letter, number(&w.value)) {
                ('G', Some(v)) if v == 20.0 => f = 25.4,
                ('G', Some(v)) if v == 21.0 => f = 1.0,
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
        factor[i] = f;
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
    for bf in schedule.blocks.iter().filter(|b| b.changed) {
        let Some(m) = moves.iter().find(|m| m.block == bf.block) else {
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
        let mode = moves
            .iter()
            .find(|m| m.block == b)
            .map(|m| m.feed_mode)
            .unwrap_or_default();
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
