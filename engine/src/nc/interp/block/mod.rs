//! One block: its steps in LinuxCNC's order of execution (`execute_block` in LinuxCNC's
//! interpreter; the step numbers are those of the order of execution in its G-code manual).
//! [`Interp::exec_words`] is the list, one call per step; the steps live by concern:
//! `settings` (feed mode, F, S, T), `m_codes` (tool change, spindle, modal state, stops and
//! subprogram calls), `g_codes` (dwell, plane, units, compensation, offsets, modes, Fanuc
//! transforms), `motion` (group 0 codes and the motion itself).

mod g_codes;
mod m_codes;
mod motion;
mod settings;

use super::modal::{g_group, m_group, Motion};
use super::words::{letter_index, Words};
use super::{Interp, R};
use crate::nc::view::BlockView;

/// Storage for the next block's G and M lists, kept between blocks.
#[derive(Default)]
pub(super) struct SpareLists {
    pub(super) gs: Vec<(u16, usize)>,
    pub(super) ms: Vec<(u32, usize)>,
}

impl<'p> Interp<'p> {
    pub(super) fn exec_block(&mut self, b: &BlockView<'p>) -> R<()> {
        if self.is_macro_call(b) {
            return self.macro_call(b);
        }
        // The G and M lists keep their allocations from block to block.
        let mut w = Words {
            vals: [None; 26],
            used: [false; 26],
            gs: std::mem::take(&mut self.spare.gs),
            ms: std::mem::take(&mut self.spare.ms),
            corner_r: None,
            corner_c: None,
            polar_r: None,
            polar_a: None,
            polar_any: false,
            polar_open: false,
            transform: false,
            machine_mode: false,
        };
        w.gs.clear();
        w.ms.clear();
        let result = self.exec_words(b, &mut w);
        self.spare.gs = w.gs;
        self.spare.ms = w.ms;
        result
    }

    /// The block's steps in LinuxCNC's order; the first error ends the block.
    ///
    /// Steps 8-10 act on M codes only and 14-22 on G codes only: most CAM blocks have neither,
    /// and skip them.
    pub(super) fn exec_words(&mut self, b: &BlockView<'p>, w: &mut Words) -> R<()> {
        self.read_block(b, w)?; // 1-2. words, parameters, corner words
        self.set_feed_mode(w); // 3. G93 G94 G95
        self.set_feed_rate(w)?; // 4. F
        self.set_spindle_speed(w)?; // 5. S
        self.select_tool(w)?; // 6. T
        if !w.ms.is_empty() {
            self.change_tool(w)?; // 8. M6 M61
            self.set_spindle_direction(w); // 9. M3 M4 M5
            self.save_restore_state(w)?; // 10. M70 M71 M72 M73
        }
        self.read_override_words(w); // 11-13. coolant, overrides, passthrough M codes
        if !w.gs.is_empty() {
            self.spindle_mode(w)?; // G96 G97 (with S in LinuxCNC's order; only a refusal)
            self.dwell_code(w)?; // 14. G4
            self.set_plane(w)?; // 15. G17 G18 G19
            self.set_units(w); // 16. G20 G21
            self.set_cutter_comp(w)?; // 17. G40 G41 G42
            self.set_tool_length_offset(w)?; // 18. G43 G43.1 G43.4 G43.5 G49
            self.select_coordinate_system(w)?; // 19. G54..G59.3, G54.1, G154
            self.set_path_control(w); // 20. G64
            self.set_distance_modes(w); // 21. G90 G91 G90.1 G91.1
            self.set_retract_mode(w); // 22. G98 G99
        }
        self.fanuc_h_word_alone(w)?; // Fanuc: H without G43
        self.fanuc_transforms(w)?; // 22a. G51 G50.1 G68 G16 and polar words
        let moved = self.group0_and_motion(w)?; // 23-24. G10 G28 G92 …, then the motion
        self.stop_and_calls(w, moved)?; // 25. M2 M30, M98 M99, G66 G67, M60
        self.leftover_words(w)
    }

    /// Steps 1-2: the words and parameter assignments, then the polar and the corner words.
    fn read_block(&mut self, b: &BlockView<'p>, w: &mut Words) -> R<()> {
        self.motion.prev = self.motion.mode;
        let avals = self.read_words(b, w)?;
        for (a, v) in b.assignments.iter().zip(avals) {
            self.assign(a, v)?;
        }
        if w.polar_any {
            self.check_polar_words(w)?;
        }
        // Fanuc comma-less corners: R and C on a G1 block (CCR parameter).
        if self.fanuc && self.corners_without_comma {
            self.comma_less_corners(w)?;
        }
        if w.corner_r.is_some() && w.corner_c.is_some() {
            let (_, i) = w.corner_c.expect("checked");
            return Err(self.err_at(
                self.word_pos(i),
                "corner rounding and chamfer in the same block",
            ));
        }
        Ok(())
    }

    fn comma_less_corners(&mut self, w: &mut Words) -> R<()> {
        let g1 = w.g(10).is_some()
            || (self.motion.mode == Some(Motion::Linear)
                && !w.gs.iter().any(|g| g_group(g.0) == Some(1)));
        if g1 {
            for c in ['R', 'C'] {
                let li = letter_index(c);
                if let Some(v) = w.vals[li].take() {
                    let slot = if c == 'R' {
                        &mut w.corner_r
                    } else {
                        &mut w.corner_c
                    };
                    if slot.is_some() {
                        return Err(self.err_at(
                            self.word_pos(v.1),
                            format!("both {c} and ,{c} in one block"),
                        ));
                    }
                    *slot = Some(v);
                }
            }
        }
        if w.has('C') {
            return Err(self.err_word(w, 'C', "C word: with comma-less corners (CCR) C is a chamfer, only on G1 blocks; the C axis is not available"));
        }
        Ok(())
    }

    /// What no step took: polar words left over, a Fanuc D anywhere, then any other word is an
    /// error.
    fn leftover_words(&mut self, w: &mut Words) -> R<()> {
        if w.polar_any {
            self.unused_polar(w)?;
        }
        // Fanuc: a D anywhere (`T1 D1 M6`) selects the radius offset later G41/G42 take.
        if self.fanuc && !w.used[letter_index('D')] {
            if let Some(d) = w.take('D') {
                if d < 0.0 || d.fract() != 0.0 || d > u32::MAX as f64 {
                    return Err(self.err_word(w, 'D', format!("D{d} is not an offset number")));
                }
                self.tool.radius_offset = Some(d as u32);
            }
        }
        // Every word must have been used by something; E, L, P and Q go with a machine's own
        // M code (M62 P1, M66 P0 L3 Q5, M67 E0 Q50: I/O we cannot interpret).
        if !w.ms.is_empty() && w.ms.iter().any(|m| m_group(m.0).is_none()) {
            for c in ['E', 'L', 'P', 'Q'] {
                w.used[letter_index(c)] = true;
            }
        }
        if w.machine_mode {
            for c in ['P', 'Q', 'R', 'E'] {
                w.used[letter_index(c)] = true;
            }
        }
        for li in 0..26 {
            if let Some((v, i)) = w.vals[li] {
                if !w.used[li] {
                    let c = (b'A' + li as u8) as char;
                    let hint = if c == 'R' && self.motion.mode == Some(Motion::Linear) {
                        " (Fanuc corner rounding is written ,R; for controls that take R/C without the comma set fanuc_corners_without_comma)"
                    } else {
                        ""
                    };
                    return Err(self.err_at(
                        self.word_pos(i),
                        format!("{c}{v} is not used by any code in this block{hint}"),
                    ));
                }
            }
        }
        Ok(())
    }
}
