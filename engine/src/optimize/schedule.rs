//! [`optimize_feeds`]: every move solved, the entry and rubbing-floor policies applied in
//! execution order, and the block feeds ([`FeedSchedule`], [`MoveFeed`], [`BlockFeed`]) with
//! the per-move velocities for the cycle time.

use rayon::prelude::*;
use serde::Serialize;

use super::engagement::{Cutter, MoveEngagement};
use super::limits::{FeedLimits, Governing, OptimizeError};
use super::scale::FeedScale;
use super::solve::solve_move;
use crate::machine::cycle_time::{feed_velocity, move_length};
use crate::nc::{FeedMode, Move, MoveKind};
use crate::physics::ForceResult;

/// Result for one move engagement. Feeds in machine-axis mm/min.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MoveFeed {
    pub move_index: usize,
    pub block: usize,
    pub engaged: bool,
    /// The move's scale: its feeds are machine-axis feeds.
    pub scale: FeedScale,
    /// Largest feed in [min_feed, max_feed] keeping every limit at every step (air: the air
    /// feed or the programmed feed).
    pub limit_feed: f64,
    /// The quantity that sets `limit_feed`.
    pub limit_governing: Governing,
    /// Governing ratio (quantity/target) at `limit_feed`.
    pub ratio: f64,
    /// Feed from the rubbing floor (0 without one).
    pub floor_feed: f64,
    /// Enters material after air or a rapid.
    pub entry: bool,
    /// The feed this move should run at after entry reduction and floor.
    pub feed: f64,
    pub governing: Governing,
    /// Limiting feed of each step (same order as the steps; air steps: `max_feed`); a lower
    /// bound for steps that do not bind unless `exact_step_limits` is set.
    pub step_limits: Vec<f64>,
    /// Force-model evaluations spent.
    pub evaluations: usize,
}

/// Result for one block. Feeds in the block's own mode, mm-based: mm/min (G94), 1/min (G93) or
/// mm/rev (G95).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BlockFeed {
    pub block: usize,
    pub line: u32,
    pub feed_mode: FeedMode,
    /// Programmed feed (smallest over the block's executions).
    pub original: f64,
    /// Optimized feed (smallest over the block's executions).
    pub feed: f64,
    /// Whether F should be rewritten (false: below `min_change`, or no engagement data).
    pub changed: bool,
    pub governing: Governing,
    /// Feed moves of this block (executions, parts counted once per move).
    pub executions: usize,
}

/// The optimizer's answer.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FeedSchedule {
    pub moves: Vec<MoveFeed>,
    /// Blocks with feed moves, by block index.
    pub blocks: Vec<BlockFeed>,
    /// Largest single tool-tip feed keeping every cutting move under the limits, mm/min.
    pub best_constant_feed: f64,
    pub evaluations: usize,
}

/// Native (block mode, mm-based) feed of velocity `v` mm/min on move `m`.
fn native_of(m: &Move, v: f64) -> f64 {
    match m.feed_mode {
        FeedMode::PerMin => v,
        FeedMode::PerRev => v / m.spindle,
        FeedMode::InverseTime => v / move_length(m),
    }
}

/// Velocity (mm/min) of native feed `f` on move `m`.
fn velocity_of(m: &Move, f: f64) -> f64 {
    match m.feed_mode {
        FeedMode::PerMin => f,
        FeedMode::PerRev => f * m.spindle,
        FeedMode::InverseTime => f * move_length(m),
    }
}

fn is_feed_move(m: &Move) -> bool {
    matches!(m.kind, MoveKind::Linear | MoveKind::Arc)
}

/// Optimize the feeds of `moves` given their `engagements` (any order of the parts of a move
/// is kept; the engagements of different moves must be in move order for the entry rule).
pub fn optimize_feeds(
    moves: &[Move],
    engagements: &[MoveEngagement],
    cutters: &[Cutter],
    limits: &FeedLimits,
) -> Result<FeedSchedule, OptimizeError> {
    optimize_feeds_per_cutter(
        moves,
        engagements,
        cutters,
        limits,
        &vec![limits.clone(); cutters.len()],
    )
}

/// [`optimize_feeds`] with each cutter held to its own limits (`per_cutter[i]` for
/// `cutters[i]`: the job's with the tool's own entries, see [`FeedLimits::for_tool`]);
/// `limits` bounds the best constant feed.
pub fn optimize_feeds_per_cutter(
    moves: &[Move],
    engagements: &[MoveEngagement],
    cutters: &[Cutter],
    limits: &FeedLimits,
    per_cutter: &[FeedLimits],
) -> Result<FeedSchedule, OptimizeError> {
    limits.validate()?;
    for l in per_cutter {
        l.validate()?;
    }
    for (i, s) in engagements.iter().enumerate() {
        if s.move_index >= moves.len() {
            return Err(OptimizeError::NoSuchMove {
                index: i,
                move_index: s.move_index,
                moves: moves.len(),
            });
        }
        if s.cutter >= cutters.len() {
            return Err(OptimizeError::NoSuchCutter {
                index: i,
                cutter: s.cutter,
            });
        }
    }
    // Independent per move: parallel, each worker with its own models; results do not
    // depend on the split (deterministic).
    let mut solved: Vec<MoveFeed> = engagements
        .par_iter()
        .enumerate()
        .with_min_len(16)
        .map_init(
            || (cutters.to_vec(), ForceResult::default()),
            |(cs, out), (i, seg)| {
                let m = &moves[seg.move_index];
                let own = per_cutter.get(seg.cutter).unwrap_or(limits);
                solve_move(seg, m, &mut cs[seg.cutter], own, out).map_err(|source| {
                    OptimizeError::Physics {
                        index: i,
                        move_index: seg.move_index,
                        line: m.line,
                        source,
                    }
                })
            },
        )
        .collect::<Result<_, _>>()?;

    // Segments of each move, in input order.
    let mut per_move: Vec<Vec<usize>> = vec![Vec::new(); moves.len()];
    for (i, s) in solved.iter().enumerate() {
        per_move[s.move_index].push(i);
    }
    // Sequence policies, in execution order: entry reduction and rubbing floor. Rapids, dwells,
    // tool changes and moves without engagement data count as out of material.
    let mut prev_engaged = false;
    for (mi, m) in moves.iter().enumerate() {
        if !is_feed_move(m) || per_move[mi].is_empty() {
            prev_engaged = false;
            continue;
        }
        for &i in &per_move[mi] {
            // The policies of the move's own tool (its entry factor and feed range).
            let limits = per_cutter.get(engagements[i].cutter).unwrap_or(limits);
            let s = &mut solved[i];
            if !s.engaged {
                s.feed = s.limit_feed;
                // A cut the model did not see stays what it was; it is not air.
                s.governing = if s.limit_governing == Governing::Unmodelled {
                    Governing::Unmodelled
                } else {
                    Governing::Air
                };
                prev_engaged = s.governing == Governing::Unmodelled;
                continue;
            }
            s.entry = !prev_engaged;
            let mut f = s.limit_feed;
            s.governing = s.limit_governing;
            if s.entry && limits.entry_feed_factor < 1.0 {
                f *= limits.entry_feed_factor;
                s.governing = Governing::Entry;
            }
            let min_feed = s.scale.limits(limits).min_feed;
            if f < min_feed {
                f = min_feed.min(s.limit_feed);
            }
            if s.floor_feed > f {
                // Never above the limit: safety wins over rubbing.
                if s.floor_feed < s.limit_feed {
                    f = s.floor_feed;
                    s.governing = Governing::RubbingFloor;
                } else {
                    f = s.limit_feed;
                    s.governing = s.limit_governing;
                }
            }
            s.feed = f;
            prev_engaged = true;
        }
    }

    // A constant feed at the tool tip (the same on every move whatever its axes do).
    let best_constant_feed = solved
        .iter()
        .filter(|s| s.engaged)
        .map(|s| s.limit_feed * s.scale.tip_ratio)
        .fold(limits.max_feed, f64::min);

    // Blocks: the smallest feed over executions, in the block's own feed mode.
    let mut blocks: std::collections::BTreeMap<usize, (BlockFeed, bool, f64)> = Default::default();
    for (mi, m) in moves.iter().enumerate() {
        if !is_feed_move(m) {
            continue;
        }
        let e = blocks.entry(m.block).or_insert_with(|| {
            (
                BlockFeed {
                    block: m.block,
                    line: m.line,
                    feed_mode: m.feed_mode,
                    original: f64::INFINITY,
                    feed: f64::INFINITY,
                    changed: false,
                    governing: Governing::Unknown,
                    executions: 0,
                },
                true,
                f64::INFINITY,
            )
        });
        let (b, known, safe) = e;
        b.executions += 1;
        b.original = b.original.min(m.feed);
        if per_move[mi].is_empty() {
            *known = false;
            continue;
        }
        for &si in &per_move[mi] {
            let s = &solved[si];
            let f = native_of(m, s.feed);
            if f < b.feed {
                b.feed = f;
                b.governing = s.governing;
            }
            if s.engaged {
                *safe = safe.min(native_of(m, s.limit_feed));
            }
        }
        if m.feed_mode != b.feed_mode {
            *known = false; // one F word cannot serve two feed modes
        }
    }
    let blocks = blocks
        .into_values()
        .map(|(mut b, known, safe)| {
            if !known || !b.feed.is_finite() {
                b.feed = b.original;
                b.governing = Governing::Unknown;
                b.changed = false;
            } else {
                let small = (b.feed - b.original).abs() <= limits.min_change * b.original;
                let original_safe = b.original <= safe;
                b.changed = !(small && original_safe) && b.feed != b.original;
            }
            b
        })
        .collect();
    let evaluations = solved.iter().map(|s| s.evaluations).sum();
    Ok(FeedSchedule {
        moves: solved,
        blocks,
        best_constant_feed,
        evaluations,
    })
}

impl FeedSchedule {
    pub fn block(&self, block: usize) -> Option<&BlockFeed> {
        self.blocks
            .binary_search_by_key(&block, |b| b.block)
            .ok()
            .map(|i| &self.blocks[i])
    }

    /// Per-move feed (mm/min) of the optimized blocks, unrounded, for
    /// [`crate::machine::cycle_time()`]'s override (other moves keep their programmed feed).
    pub fn optimized_velocities(&self, moves: &[Move]) -> Vec<f64> {
        moves
            .iter()
            .map(|m| match self.block(m.block) {
                Some(b) if b.changed && is_feed_move(m) => velocity_of(m, b.feed),
                _ => feed_velocity(m),
            })
            .collect()
    }

    /// The ideal bound: every move at its own feed (no block sharing, no rounding).
    pub fn ideal_velocities(&self, moves: &[Move]) -> Vec<f64> {
        let mut v: Vec<f64> = moves.iter().map(feed_velocity).collect();
        let mut seen = vec![false; moves.len()];
        for s in &self.moves {
            let i = s.move_index;
            v[i] = if seen[i] { v[i].min(s.feed) } else { s.feed };
            seen[i] = true;
        }
        v
    }

    /// Every feed move with its tip at the best constant feed (as machine-axis feeds, within
    /// what the axes allow).
    pub fn constant_velocities(&self, moves: &[Move]) -> Vec<f64> {
        self.constant_velocities_per_move(moves, &vec![Some(self.best_constant_feed); moves.len()])
    }

    /// As [`constant_velocities`](Self::constant_velocities) with a tip feed of its own for
    /// each move (None: the move keeps its programmed feed), e.g. each tool's own best
    /// constant feed on the moves of that tool.
    pub fn constant_velocities_per_move(
        &self,
        moves: &[Move],
        tip_feeds: &[Option<f64>],
    ) -> Vec<f64> {
        let mut scale = vec![FeedScale::UNIT; moves.len()];
        for s in &self.moves {
            scale[s.move_index] = s.scale;
        }
        moves
            .iter()
            .zip(&scale)
            .zip(tip_feeds)
            .map(|((m, s), tip)| match tip {
                Some(tip) if is_feed_move(m) => {
                    if s.schedulable() {
                        (tip / s.tip_ratio).min(s.max_axis_feed)
                    } else {
                        *tip
                    }
                }
                _ => feed_velocity(m),
            })
            .collect()
    }
}
