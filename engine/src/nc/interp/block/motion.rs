//! Steps 23-24 of a block: its group 0 code (G10, G28, G30, G52, G92, …) and its motion.

use super::super::corners::PendingCorner;
use super::super::modal::{g_group, g_name, Motion};
use super::super::words::Words;
use super::super::{Interp, R};
use crate::nc::{Dialect, FeedMode};

impl Interp<'_> {
    /// 23. The group 0 code (G80 has cancelled the motion mode first, and a group 0 code and a
    /// motion may not share the axis words), then 24. the motion mode and the motion. Whether the
    /// block moved.
    pub(super) fn group0_and_motion(&mut self, w: &mut Words) -> R<bool> {
        let group0 =
            w.gs.iter()
                .find(|g| g_group(g.0) == Some(0) && g.0 != 40 && g.0 != 530)
                .copied();
        // G80: LinuxCNC cancels the motion mode; on a Fanuc control canned cycles are a group
        // of their own, so the G0/G1/G2/G3 mode from before the cycle is back.
        if w.g(800).is_some() {
            self.motion.mode = self.after_g80();
            self.cycle.il = None;
        }
        let block_motion =
            w.gs.iter()
                .find(|g| g_group(g.0) == Some(1) && g.0 != 800)
                .or_else(|| w.gs.iter().find(|g| g.0 == 800))
                .copied();
        let g53 = w.g(530);
        if let (Some((g0, i0)), Some((gm, _))) = (group0, block_motion) {
            // Fanuc: G0/G1 with G28, G30, G92… (`G00 G28 G91 Z1`) sets the motion mode, and
            // the group 0 code takes the axis words (LinuxCNC refuses the pair).
            let fanuc_mode_only = self.fanuc && matches!(gm, 0 | 10);
            if matches!(g0, 100 | 280 | 282 | 300 | 520 | 920)
                && gm != 800
                && w.has_axis()
                && !fanuc_mode_only
            {
                return Err(self.err_at(
                    self.word_pos(i0),
                    format!("{} and {} both use axis words", g_name(g0), g_name(gm)),
                ));
            }
        }
        if let Some((g0, i0)) = group0 {
            if self.comp.active.is_some()
                && matches!(g0, 100 | 280 | 282 | 300 | 520 | 920 | 921 | 922 | 923)
            {
                return Err(self.err_at(
                    self.word_pos(i0),
                    format!(
                        "{} with cutter radius compensation on (G40 first)",
                        g_name(g0)
                    ),
                ));
            }
            self.exec_group0(w, g0, i0)?;
        }
        if let Some((gm, _)) = block_motion {
            self.set_motion_mode(w, gm, group0)?;
        }
        self.perform_motion(w, group0, block_motion, g53)
    }

    /// 24. The block's motion code (group 1, or G80) sets the motion mode from here on.
    fn set_motion_mode(&mut self, w: &Words, gm: u16, group0: Option<(u16, usize)>) -> R<()> {
        self.motion.mode = match gm {
            0 => Some(Motion::Rapid),
            10 => Some(Motion::Linear),
            20 => Some(Motion::Arc { cw: true }),
            30 => Some(Motion::Arc { cw: false }),
            331 => Some(Motion::RigidTap),
            382..=385 => Some(Motion::Probe(gm)),
            50 => Some(Motion::Spline { cubic: true }),
            51 => Some(Motion::Spline { cubic: false }),
            52 => Some(Motion::Nurbs),
            53 => {
                self.nurbs_end(self.word_pos(w.g(53).expect("in block")))?;
                None
            }
            800 => self.after_g80(),
            g => Some(Motion::Cycle(g / 10)),
        };
        if matches!(gm, 0 | 10 | 20 | 30) {
            self.motion.mode_01 = self.motion.mode;
        }
        if gm == 800 {
            self.cycle.il = None;
            if w.has_axis()
                && self.motion.mode.is_none()
                && !matches!(group0, Some((100 | 280 | 282 | 300 | 520 | 920, _)))
            {
                return Err(self.err_block("axis words with G80 (motion cancelled)"));
            }
        }
        Ok(())
    }

    /// 24. The block's move, if it has one: axis words under the motion mode, a G5.2 weight
    /// or order, an explicit G0-G3 without axis words. Whether the block moved.
    fn perform_motion(
        &mut self,
        w: &mut Words,
        group0: Option<(u16, usize)>,
        block_motion: Option<(u16, usize)>,
        g53: Option<usize>,
    ) -> R<bool> {
        let axis_users = matches!(group0, Some((100 | 280 | 282 | 300 | 520 | 920, _)));
        let mut moved = false;
        let corner = w
            .corner_r
            .or(w.corner_c)
            .map(|(v, i)| (v, i, w.corner_c.is_some()));
        if let Some((310, i)) = group0 {
            // Fanuc's skip function: a feed move that stops where the probe trips, for this
            // block only (the motion mode stays).
            if !w.has_axis() {
                return Err(self.err_at(self.word_pos(i), "G31 needs axis words"));
            }
            w.take('P'); // the skip signal's number (G31 P1..P4)
            self.probe(w, 310)?;
            return Ok(true);
        }
        if w.has_axis() && !axis_users {
            let motion = match self.motion.mode {
                Some(m) => m,
                None => self.motion_after_g80()?,
            };
            if let Some(i) = g53 {
                if !matches!(motion, Motion::Rapid | Motion::Linear) {
                    return Err(self.err_at(self.word_pos(i), "G53 needs G0 or G1"));
                }
            }
            self.exec_motion(w, motion, g53.is_some(), corner)?;
            moved = true;
        } else if matches!(block_motion, Some((52, _))) && !axis_users {
            // G5.2 with only a weight for its first point (P) or an order (L).
            self.exec_motion(w, Motion::Nurbs, false, None)?;
        } else if matches!(block_motion, Some((0 | 10 | 20 | 30, _)))
            && !axis_users
            && corner.is_none()
        {
            // LinuxCNC: an explicit G0/G1 without axis words still makes a (zero-length) move,
            // and G2/G3 with only a centre makes a full circle.
            let motion = self.motion.mode.expect("set above");
            self.exec_motion(w, motion, g53.is_some(), None)?;
        } else if let Some(i) = g53 {
            if !axis_users {
                return Err(self.err_at(self.word_pos(i), "G53 without axis words"));
            }
        } else if let Some((_, i, _)) = corner {
            return Err(self.err_at(
                self.word_pos(i),
                "corner rounding/chamfer on a block without a G1 move",
            ));
        }
        Ok(moved)
    }

    pub(super) fn exec_motion(
        &mut self,
        w: &mut Words,
        motion: Motion,
        g53: bool,
        corner: Option<(f64, usize, bool)>,
    ) -> R<()> {
        if !matches!(motion, Motion::Cycle(_)) {
            self.cycle.il = None;
        }
        if self.modal.feed_mode == FeedMode::InverseTime
            && matches!(motion, Motion::Linear | Motion::Arc { .. })
            && self.modal.feed_word <= 0.0
        {
            return Err(self.err_block(
                "G1/G2/G3 in inverse time mode (G93) needs an F word in the same block",
            ));
        }
        if self.comp.active.is_some() {
            if g53 {
                return Err(self.err_block("G53 with cutter radius compensation on"));
            }
            if let Some((_, i, _)) = corner {
                return Err(self.err_at(
                    self.word_pos(i),
                    "corner rounding/chamfer with cutter radius compensation on",
                ));
            }
            return match motion {
                Motion::Rapid | Motion::Linear => {
                    let to = self.comp_target(w)?;
                    self.comp_straight(matches!(motion, Motion::Rapid), to)
                }
                Motion::Arc { cw } => self.comp_arc(w, cw),
                _ => Err(self.err_block(
                    "canned cycles, tapping and probing are not allowed with cutter radius compensation on (G40 first)",
                )),
            };
        }
        if self.comp.exit_start.is_some() && matches!(motion, Motion::Arc { .. }) {
            return Err(self.err_block(
                "the move just after G40 (cutter compensation off) must be a line, not an arc",
            ));
        }
        let pending = self.pending_corner.take();
        if pending.is_some() && !matches!(motion, Motion::Linear) {
            let p = pending.expect("checked");
            return Err(self.err_at(
                p.word_pos,
                "corner rounding/chamfer must be followed by a G1 move (the next move here is not G1)",
            ));
        }
        match motion {
            Motion::Rapid | Motion::Linear => {
                let to = self.target(w, g53)?;
                if let Some(p) = pending {
                    self.resolve_corner(p, to)?;
                }
                if let Some((size, i, chamfer)) = corner {
                    if g53 {
                        return Err(
                            self.err_at(self.word_pos(i), "corner rounding/chamfer with G53")
                        );
                    }
                    if motion != Motion::Linear {
                        return Err(
                            self.err_at(self.word_pos(i), "corner rounding/chamfer needs G1")
                        );
                    }
                    if size <= 0.0 {
                        return Err(self.err_at(self.word_pos(i), "corner size must be positive"));
                    }
                    self.straight(false, to)?;
                    self.pending_corner = Some(PendingCorner {
                        move_index: self.out.moves.len() - 1,
                        block: self.cur_block,
                        word_pos: self.word_pos(i),
                        chamfer,
                        size,
                        corner: to,
                        plane: self.modal.plane,
                    });
                    return Ok(());
                }
                self.straight(matches!(motion, Motion::Rapid), to)
            }
            Motion::Arc { cw } => self.arc(w, cw),
            Motion::RigidTap => self.rigid_tap(w),
            Motion::Probe(g) => self.probe(w, g),
            Motion::Cycle(g) => self.cycle(w, g),
            Motion::Spline { cubic } => self.spline(w, cubic),
            Motion::Nurbs => {
                let starts = self.motion.prev != Some(Motion::Nurbs);
                self.nurbs_point(w, starts)
            }
        }
    }

    /// Axis words with no motion mode. A post for a Fanuc-type control writes `G80` then
    /// `Z5.` meaning the G0/G1 of before the cycle (canned cycles are a group of their own
    /// there); LinuxCNC refuses the block. With the dialect left to `auto` the Fanuc rule
    /// applies, with a warning.
    #[cold]
    fn motion_after_g80(&mut self) -> R<Motion> {
        match self.motion.mode_01 {
            Some(m) if self.opts.dialect == Dialect::Auto => {
                self.out.warnings.push(self.err_block(format!(
                    "axis words after G80 with no motion mode: the Fanuc rule is applied (G80 keeps the {} of before the cycle); LinuxCNC refuses this block (set the dialect to choose)",
                    motion_name(m)
                )));
                self.motion.mode = Some(m);
                Ok(m)
            }
            _ => Err(self.err_block(
                "axis words but no motion mode (G80 is active); give G0/G1/G2/G3 or a cycle",
            )),
        }
    }

    /// The motion mode after G80: none (LinuxCNC), or the G0/G1/G2/G3 mode from before the
    /// cycle (Fanuc: canned cycles are a modal group of their own).
    fn after_g80(&self) -> Option<Motion> {
        if self.fanuc {
            self.motion.mode_01
        } else {
            None
        }
    }
}

/// The G code of a group 01 motion mode, for messages.
fn motion_name(m: Motion) -> &'static str {
    match m {
        Motion::Rapid => "G0",
        Motion::Linear => "G1",
        Motion::Arc { cw: true } => "G2",
        Motion::Arc { cw: false } => "G3",
        _ => "motion mode",
    }
}
