//! The M-code steps of a block: 8-10 (tool change, spindle, modal state), 11-13 (codes
//! without effect on motion) and 25 (stops, subprogram calls, modal macro calls).

use super::super::words::Words;
use super::super::{Interp, R};
use crate::nc::{MoveKind, SpindleDir, ToolChangeTo};

impl Interp<'_> {
    /// 8. M6 and M61.
    pub(super) fn change_tool(&mut self, w: &mut Words) -> R<()> {
        if let Some(i) = w.m(6).filter(|_| self.comp.active.is_some()) {
            return Err(self.err_at(
                self.word_pos(i),
                "tool change with cutter radius compensation on (G40 first)",
            ));
        }
        if w.m(6).is_some() {
            let t = self.tool.selected.unwrap_or(self.tool.current);
            self.tool.current = t;
            let p = self.to_machine(self.cur);
            let m = self.base_move(MoveKind::ToolChange, p, p);
            self.push(m)?;
            // The change takes the tip where the machine changes tools: the next move
            // starts there, not where the last tool stopped.
            if let Some(to) = self.opts.tool_change {
                let mut q = p;
                match to {
                    ToolChangeTo::Position([x, y, z]) => {
                        q[0] = x;
                        q[1] = y;
                        q[2] = z;
                    }
                    ToolChangeTo::RaiseTo(z) => q[2] = q[2].max(z),
                }
                self.cur = self.from_machine(q);
            }
        }
        if let Some(i) = w.m(61) {
            let Some(q) = w.take('Q') else {
                return Err(self.err_at(self.word_pos(i), "M61 needs a Q word (tool number)"));
            };
            if q < 0.0 || q.fract() != 0.0 || q > u32::MAX as f64 {
                return Err(self.err_word(w, 'Q', format!("Q{q} is not a tool number")));
            }
            self.tool.current = q as u32;
        }
        Ok(())
    }

    /// 9. M3, M4, M5, and M19 (orient: the spindle stopped at an angle; its R, Q and P, the
    /// angle, LinuxCNC's timeout and direction or Haas's angle in whole degrees, move no axis).
    pub(super) fn set_spindle_direction(&mut self, w: &mut Words) {
        if w.m(3).is_some() {
            self.modal.spindle = SpindleDir::Cw;
        }
        if w.m(4).is_some() {
            self.modal.spindle = SpindleDir::Ccw;
        }
        if w.m(5).is_some() {
            self.modal.spindle = SpindleDir::Off;
        }
        if w.m(19).is_some() {
            self.modal.spindle = SpindleDir::Off;
            for c in ['R', 'Q', 'P'] {
                w.take(c);
            }
        }
    }

    /// 10. M70 save, M71 forget, M72 restore the modal state; M73 restores it when the
    /// subroutine returns.
    pub(super) fn save_restore_state(&mut self, w: &Words) -> R<()> {
        if w.m(70).is_some() {
            self.saved_modal = Some(self.modal.clone());
        }
        if w.m(71).is_some() {
            self.saved_modal = None;
        }
        if let Some(i) = w.m(72) {
            let Some(m) = self.saved_modal.clone() else {
                return Err(self.err_at(self.word_pos(i), "M72 without state saved by M70"));
            };
            self.restore_modal(&m);
        }
        if let Some(i) = w.m(73) {
            let m = self.modal.clone();
            let Some(f) = self.flow.frames.last_mut() else {
                return Err(self.err_at(self.word_pos(i), "M73 outside a subroutine"));
            };
            f.auto_restore = Some(m);
        }
        Ok(())
    }

    pub(super) fn read_override_words(&mut self, w: &mut Words) {
        // 11-13. coolant, overrides, passthrough M codes: no effect on motion. M50-M53
        // (feed and spindle override, adaptive feed, feed stop) take P0/P1: read, no effect
        // (a block with G codes leaves its P to them).
        if !w.ms.is_empty() && w.gs.is_empty() && w.ms.iter().any(|m| (50..=53).contains(&m.0)) {
            w.take('P');
        }
    }

    /// 25. Stops, and Fanuc subprogram calls and returns (after the block's motion); a G66
    /// modal macro runs after a block that `moved`.
    pub(super) fn stop_and_calls(&mut self, w: &mut Words, moved: bool) -> R<()> {
        if w.m(2).is_some() || w.m(30).is_some() {
            self.flow.ended = true;
        }
        if !w.ms.is_empty() {
            if let Some(i) = w.m(97) {
                self.call_local_subprogram(w, i)?;
            }
            if let Some(i) = w.m(98) {
                self.call_subprogram(w, i)?;
            }
            if let Some(i) = w.m(99) {
                self.return_subprogram(w, i)?;
            }
        }
        if w.transform && w.g(670).is_some() {
            if !self.fanuc {
                return Err(self.err_at(
                    self.word_pos(w.g(670).expect("in block")),
                    "G67 cancels a Fanuc G66 modal macro call; not valid with dialect linuxcnc",
                ));
            }
            // The last G66 first (nested modal calls end in reverse order).
            self.flow.modal_calls.pop();
        } else if moved && !self.flow.modal_calls.is_empty() {
            self.modal_macro_after_move()?;
        }
        if w.m(60).is_some() {
            return Err(self.err_block("M60 pallet change is not supported"));
        }
        Ok(())
    }
}
