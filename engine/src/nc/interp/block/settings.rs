//! Steps 3-6 of a block: feed mode, feed rate, spindle speed, tool selection.

use super::super::words::Words;
use super::super::{Interp, R};
use crate::nc::FeedMode;

impl Interp<'_> {
    /// 3. G93, G94, G95.
    pub(super) fn set_feed_mode(&mut self, w: &Words) {
        for (code, mode) in [
            (930, FeedMode::InverseTime),
            (940, FeedMode::PerMin),
            (950, FeedMode::PerRev),
        ] {
            if w.g(code).is_some() {
                if self.modal.feed_mode != mode
                    && (mode == FeedMode::InverseTime
                        || self.modal.feed_mode == FeedMode::InverseTime)
                {
                    // LinuxCNC: entering or leaving G93 forgets the feed, so an inverse-time F
                    // is never taken as a feed per minute (or the reverse).
                    self.modal.feed_word = 0.0;
                }
                self.modal.feed_mode = mode;
            }
        }
    }

    /// 4. F.
    pub(super) fn set_feed_rate(&mut self, w: &mut Words) -> R<()> {
        if let Some(f) = w.take('F') {
            if f < 0.0 {
                return Err(self.err_word(w, 'F', "negative F word"));
            }
            self.modal.feed_word = f;
            self.modal.feed_factor = self.unit();
        } else if self.modal.feed_mode == FeedMode::InverseTime {
            // Inverse time: F applies to its own block only.
            self.modal.feed_word = 0.0;
        }
        Ok(())
    }

    /// 5. S.
    pub(super) fn set_spindle_speed(&mut self, w: &mut Words) -> R<()> {
        if let Some(s) = w.take('S') {
            if s < 0.0 {
                return Err(self.err_word(w, 'S', "negative S word"));
            }
            self.modal.speed = s;
        }
        Ok(())
    }

    /// 6. T: selects; M6 changes.
    pub(super) fn select_tool(&mut self, w: &mut Words) -> R<()> {
        if let Some(t) = w.take('T') {
            if t < 0.0 || t.fract() != 0.0 || t > u32::MAX as f64 {
                return Err(self.err_word(w, 'T', format!("T{t} is not a tool number")));
            }
            self.tool.selected = Some(t as u32);
            if !self.tool.selected_tools.iter().any(|&(n, _)| n == t as u32) {
                self.tool
                    .selected_tools
                    .push((t as u32, self.program_line()));
            }
        }
        Ok(())
    }
}
