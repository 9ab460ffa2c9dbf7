//! [`split_plan`]: where a long move whose engagement varies would be split, and the feed of
//! each part ([`SplitPlan`]).

use serde::Serialize;

use super::engagement::MoveEngagement;
use super::schedule::MoveFeed;

/// Where to split one move whose engagement varies, and the feed of each part.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SplitPlan {
    pub move_index: usize,
    /// Split distances from the move's start, mm, increasing.
    pub points: Vec<f64>,
    /// Feed of each part (points.len() + 1), mm/min.
    pub feeds: Vec<f64>,
    /// Time at the single block feed and with the split, s (constant-speed estimate).
    pub time_single_s: f64,
    pub time_split_s: f64,
}

/// Split decision for one solved move: parts of at least `min_length` mm, at most
/// `max_parts`, each at the smallest step limit inside it and at its end; proposed only when it saves at least
/// `min_saving` (fraction) of the move's time. Steps are taken to cover the move from their
/// `at` to the next step's `at` (the last to the move's end). Solve with `exact_step_limits`:
/// with lower bounds the plan is safe but finds less.
pub fn split_plan(
    seg: &MoveEngagement,
    solved: &MoveFeed,
    move_len: f64,
    max_parts: usize,
    min_length: f64,
    min_saving: f64,
) -> Option<SplitPlan> {
    let n = seg.steps.len();
    if n < 2 || max_parts < 2 || solved.step_limits.len() != n || !solved.engaged {
        return None;
    }
    // Interval of step i along the move.
    let bounds: Vec<f64> = (0..=n)
        .map(|i| {
            if i == 0 {
                0.0
            } else if i == n {
                move_len
            } else {
                seg.steps[i].at.clamp(0.0, move_len)
            }
        })
        .collect();
    // Part time of steps [i, j): length / the smallest step limit in it.
    let part = |i: usize, j: usize| -> Option<(f64, f64)> {
        let len = bounds[j] - bounds[i];
        if len < min_length {
            return None;
        }
        // The engagement of a step is measured at its start; where it grows (entering
        // material) the part's end sees the next step's engagement, so that step's limit
        // bounds this part too.
        let f = solved.step_limits[i..(j + 1).min(n)]
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        Some((len / (f / 60.0), f))
    };
    // DP over (end index, parts used): minimal time.
    let inf = f64::INFINITY;
    let mut best = vec![vec![(inf, usize::MAX, 0.0); max_parts + 1]; n + 1];
    best[0][0] = (0.0, 0, 0.0);
    for j in 1..=n {
        for k in 1..=max_parts {
            for i in 0..j {
                if best[i][k - 1].0 == inf {
                    continue;
                }
                if let Some((t, f)) = part(i, j) {
                    let c = best[i][k - 1].0 + t;
                    if c < best[j][k].0 {
                        best[j][k] = (c, i, f);
                    }
                }
            }
        }
    }
    let single = part(0, n)?.0;
    let (k, &(t, _, _)) = best[n]
        .iter()
        .enumerate()
        .skip(1)
        .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0))?;
    if k < 2 || t > single * (1.0 - min_saving) {
        return None;
    }
    let mut points = Vec::new();
    let mut feeds = Vec::new();
    let (mut j, mut kk) = (n, k);
    while kk > 0 {
        let (_, i, f) = best[j][kk];
        feeds.push(f);
        if i > 0 {
            points.push(bounds[i]);
        }
        j = i;
        kk -= 1;
    }
    points.reverse();
    feeds.reverse();
    Some(SplitPlan {
        move_index: seg.move_index,
        points,
        feeds,
        time_single_s: single,
        time_split_s: t,
    })
}
