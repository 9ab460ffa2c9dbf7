//! Fanuc corner rounding and chamfer (`,R` / `,C`): the corner block's move is shortened once
//! the next block gives the outgoing direction.

use super::modal::Plane;
use super::{Interp, R};
use crate::nc::MoveKind;

/// A Fanuc corner (`,R` / `,C`) waiting for the next block's direction.
#[derive(Clone, Debug)]
pub(super) struct PendingCorner {
    /// Index in `moves` of the linear move to shorten.
    pub(super) move_index: usize,
    pub(super) block: usize,
    pub(super) word_pos: usize,
    pub(super) chamfer: bool,
    /// Program units.
    pub(super) size: f64,
    /// Corner point (program coordinates, the end of that move).
    pub(super) corner: [f64; 6],
    pub(super) plane: Plane,
}

impl Interp<'_> {
    /// Shorten the pending corner's move and add the fillet arc or chamfer line.
    pub(super) fn resolve_corner(&mut self, p: PendingCorner, next_end: [f64; 6]) -> R<()> {
        let [a, b, _] = p.plane.axes();
        let prev_start_m = self.out.moves[p.move_index].start;
        let prev_start = self.from_machine(prev_start_m);
        let c = p.corner;
        let fail = |s: &Self, m: &str| s.err_at(p.word_pos, m.to_string());
        if p.plane != self.modal.plane {
            return Err(fail(
                self,
                "plane changed between a corner block and its next move",
            ));
        }
        for i in 0..6 {
            if i != a && i != b && (prev_start[i] != c[i] || next_end[i] != c[i]) {
                return Err(fail(
                    self,
                    "corner rounding/chamfer needs both moves in the selected plane only",
                ));
            }
        }
        let d1 = [c[a] - prev_start[a], c[b] - prev_start[b]];
        let d2 = [next_end[a] - c[a], next_end[b] - c[b]];
        let l1 = d1[0].hypot(d1[1]);
        let l2 = d2[0].hypot(d2[1]);
        if l1 < 1e-9 || l2 < 1e-9 {
            return Err(fail(
                self,
                "corner rounding/chamfer next to a zero-length move",
            ));
        }
        let u1 = [d1[0] / l1, d1[1] / l1];
        let u2 = [d2[0] / l2, d2[1] / l2];
        let cross = u1[0] * u2[1] - u1[1] * u2[0];
        let dot = (u1[0] * u2[0] + u1[1] * u2[1]).clamp(-1.0, 1.0);
        let turn = cross.atan2(dot); // signed turning angle
        if turn.abs() < 1e-9 || (std::f64::consts::PI - turn.abs()) < 1e-9 {
            return Err(fail(
                self,
                "corner rounding/chamfer between collinear moves",
            ));
        }
        let dist = if p.chamfer {
            p.size
        } else {
            p.size * (turn.abs() / 2.0).tan()
        };
        if dist > l1 + 1e-9 || dist > l2 + 1e-9 {
            return Err(fail(
                self,
                "corner rounding/chamfer larger than the moves it joins",
            ));
        }
        let mut t1 = c;
        t1[a] = c[a] - u1[0] * dist;
        t1[b] = c[b] - u1[1] * dist;
        let mut t2 = c;
        t2[a] = c[a] + u2[0] * dist;
        t2[b] = c[b] + u2[1] * dist;
        // Shorten the corner block's line; its end becomes T1.
        let t1m = self.to_machine(t1);
        let t2m = self.to_machine(t2);
        self.out.moves[p.move_index].end = t1m;
        let (blk, line) = (self.cur_block, self.cur_line);
        self.cur_block = p.block;
        self.cur_line = self.prog.block(p.block).line;
        let mut m = if p.chamfer {
            self.base_move(MoveKind::Linear, t1m, t2m)
        } else {
            // Centre: from T1 perpendicular to u1 towards the turn.
            let side = if turn < 0.0 { -1.0 } else { 1.0 };
            let centre = [t1[a] - u1[1] * p.size * side, t1[b] + u1[0] * p.size * side];
            match self.arc_move_machine(p.plane, t1, t2, centre, turn, 1) {
                Ok(m) => m,
                Err(e) => {
                    self.cur_block = blk;
                    self.cur_line = line;
                    return Err(e);
                }
            }
        };
        // The corner belongs to the corner block, at the corner block's feed.
        let corner_move = &self.out.moves[p.move_index];
        m.feed = corner_move.feed;
        m.feed_mode = corner_move.feed_mode;
        m.spindle = corner_move.spindle;
        let res = self.push(m);
        self.cur_block = blk;
        self.cur_line = line;
        res?;
        self.cur = t2;
        Ok(())
    }
}
