//! Fanuc subprograms: several `O` programs in one file, `M98 P.. L..` calls, `M99` returns,
//! the sequence (N) search that GOTO and `M99 P` use.
//!
//! Rules (Fanuc 0i/30i manuals):
//! * `M98 P1234 L3` runs O1234 three times. Without L, a P of five to eight digits whose
//!   number is not a program in the file is the older form: the digits before the last four
//!   are the repeat count (`M98 P31234` = O1234 three times).
//! * `M99` returns to the block after the call; `M99 Pn` to block Nn of the caller.
//! * `M99` in the main program restarts it on a real control (an endless loop, stopped by the
//!   operator or a counter); here it ends the program, with a warning.
//! * The main program is the first one run; reaching the `O` line of another program ends it
//!   (with a warning); a subprogram that runs into another program's `O` line has no M99.
//! * A program not in the file is looked for in the program library (`units.rs`); a call to a
//!   program in neither is an error naming it.

use super::control::{FanucCall, Frame};
use super::words::Words;
use super::{Interp, MAX_CALL_DEPTH, R};
use crate::nc::expr::is_vacant;
use crate::nc::program::{OName, OWord};
use std::collections::HashMap;

impl Interp<'_> {
    /// A program number from a P value (whole, 1..99999999).
    pub(super) fn program_number(&self, p: f64, at: usize, what: &str) -> R<u32> {
        if is_vacant(p) || p.fract() != 0.0 || !(0.0..=99_999_999.0).contains(&p) {
            return Err(self.err_at(
                at,
                format!("{what} P{p}: a program number is a whole number 0..99999999"),
            ));
        }
        Ok(p as u32)
    }

    /// The file (unit) and first block of program `number`'s body: in the running file, else
    /// in the program itself or its library.
    pub(super) fn resolve_program(
        &mut self,
        number: u32,
        at: usize,
        what: &str,
    ) -> R<(u32, usize)> {
        if let Some(&start) = self.control.programs.get(&number) {
            return Ok((self.units.unit, start + 1));
        }
        match self.program_elsewhere(number, at, what)? {
            Some(found) => Ok(found),
            None => {
                // Fanuc keeps O8000-O9999 for the machine's own macros (probing, tool setting,
                // pallets), resident in the control rather than in a part program's file.
                let resident = if (8000..=9999).contains(&number) {
                    let probing = if (9700..=9899).contains(&number) {
                        " (Renishaw's probing macros are O97xx and O98xx)"
                    } else {
                        ""
                    };
                    format!(
                        "; O8000-O9999 are macros the control keeps in its own memory{probing}: \
                         put their files in the program library (inputs library/<file name>, or \
                         --library DIR offline), or simulate the program without the blocks that \
                         call them"
                    )
                } else {
                    String::new()
                };
                Err(self.err_at(
                    at,
                    format!(
                        "{what}: program O{number} is not in this file nor in its program library{resident}"
                    ),
                ))
            }
        }
    }

    /// The blocks of the Fanuc program containing block `pc` of unit `unit`: from its `O`
    /// line (or the start of the file) to the next `O` line.
    fn program_range(&self, unit: u32, pc: usize) -> (usize, usize) {
        let (prog, control) = self.unit_files(unit);
        let starts = &control.program_starts;
        let k = starts.partition_point(|&s| s <= pc);
        let start = if k == 0 { 0 } else { starts[k - 1] };
        let end = starts.get(k).copied().unwrap_or(prog.len());
        (start, end)
    }

    /// The block numbered `Nn` in the program containing block `pc` of unit `unit` (the
    /// first such block).
    pub(super) fn find_sequence(&mut self, unit: u32, pc: usize, n: u32) -> Option<usize> {
        let (start, end) = self.program_range(unit, pc);
        let prog = self.unit_files(unit).0;
        let map = self.flow.sequences.entry((unit, start)).or_insert_with(|| {
            let mut m = HashMap::new();
            for i in start..end {
                if let Some(n) = prog.sequence_number(i) {
                    m.entry(n).or_insert(i);
                }
            }
            m
        });
        map.get(&n).copied()
    }

    /// The run reaches an `O1234` line.
    pub(super) fn reach_program_start(&mut self, pc: usize, o: &OWord) -> R<usize> {
        if self.flow.main_program.is_none() && self.flow.frames.is_empty() {
            self.flow.main_program = Some(pc);
            return Ok(pc + 1);
        }
        if let Some(f) = self.flow.frames.last().filter(|f| f.fanuc.is_some()) {
            return Err(self.err_at(
                o.span.start,
                format!(
                    "program O{} (called on line {}) runs into {} without M99",
                    f.sub.number(),
                    self.unit_files(f.return_unit).0.block(f.return_pc).line,
                    o.name.to_string().to_uppercase()
                ),
            ));
        }
        if self.flow.frames.is_empty() {
            self.out.warnings.push(self.err_at(
                o.span.start,
                format!(
                    "the main program ends where {} starts (no M30/M02 before it)",
                    o.name.to_string().to_uppercase()
                ),
            ));
            self.flow.ended = true;
        }
        Ok(pc + 1)
    }

    /// `M98 P.. L..`: call a subprogram after the block's motion.
    pub(super) fn call_subprogram(&mut self, w: &mut Words, m98: usize) -> R<()> {
        let at = self.word_pos(m98);
        let Some(p) = w.take('P') else {
            return Err(self.err_at(at, "M98 needs P (the subprogram number)"));
        };
        let l = self.repeat_count(w, "M98")?;
        let mut number = self.program_number(p, at, "M98")?;
        let mut repeats = l.unwrap_or(1);
        if l.is_none() && number > 9999 && !self.program_exists(number) {
            repeats = number / 10_000;
            number %= 10_000;
        }
        let (unit, body) = self.resolve_program(number, at, &format!("M98 P{p}"))?;
        self.call_fanuc_program(number, unit, body, repeats, None, at)
    }

    /// Haas `M97 P.. L..`: call the local subprogram at block `N<P>` of the running program
    /// (after its M30, most often), `L` times; its M99 returns after the call.
    pub(super) fn call_local_subprogram(&mut self, w: &mut Words, m97: usize) -> R<()> {
        let at = self.word_pos(m97);
        let Some(p) = w.take('P') else {
            return Err(self.err_at(
                at,
                "M97 needs P (the block number N of the local subprogram)",
            ));
        };
        let n = self.program_number(p, at, "M97")?;
        let repeats = self.repeat_count(w, "M97")?.unwrap_or(1);
        let unit = self.units.unit;
        let Some(body) = self.find_sequence(unit, self.cur_block, n) else {
            return Err(self.err_at(at, format!("M97 P{n}: no block N{n} in this program")));
        };
        self.call_fanuc_program(n, unit, body, repeats, None, at)
    }

    /// A subprogram call's `L` repeat count (0..9999), `None` without L.
    fn repeat_count(&self, w: &mut Words, what: &str) -> R<Option<u32>> {
        match w.take('L') {
            Some(l) if l.fract() != 0.0 || !(0.0..=9999.0).contains(&l) => Err(self.err_word(
                w,
                'L',
                format!("{what} L{l}: the repeat count must be 0..9999"),
            )),
            l => Ok(l.map(|l| l as u32)),
        }
    }

    /// Whether program `number` is in the running file, the program or its library.
    fn program_exists(&self, number: u32) -> bool {
        self.control.programs.contains_key(&number)
            || self.main_control.programs.contains_key(&number)
            || self
                .opts
                .library
                .as_deref()
                .is_some_and(|l| l.find_program(number).is_some())
    }

    /// Runs program `number` (first block `body` of unit `unit`) `repeats` times from the
    /// next block on,
    /// then returns after the current block (M98, G65, G66). `locals`: the caller's local
    /// variables to restore on return (a macro call's new level).
    pub(super) fn call_fanuc_program(
        &mut self,
        number: u32,
        unit: u32,
        body: usize,
        repeats: u32,
        locals: Option<Vec<f64>>,
        at: usize,
    ) -> R<()> {
        if repeats == 0 {
            return Ok(());
        }
        if self.flow.frames.len() >= MAX_CALL_DEPTH {
            return Err(self.err_at(at, format!("calls nested deeper than {MAX_CALL_DEPTH}")));
        }
        self.flow.frames.push(Frame {
            return_pc: self.cur_block,
            return_unit: self.units.unit,
            saved: Vec::new(),
            sub: OName::Number(number),
            auto_restore: None,
            fanuc: Some(FanucCall {
                body,
                repeats_left: repeats - 1,
                locals,
                modal_level: None,
            }),
        });
        self.flow.jump = Some(body);
        if unit != self.units.unit {
            self.units.next_unit = Some(unit);
        }
        Ok(())
    }

    /// `M99` (or `M99 Pn`): end of a subprogram run: again if repeats are left, else back to
    /// the caller.
    pub(super) fn return_subprogram(&mut self, w: &mut Words, m99: usize) -> R<()> {
        let at = self.word_pos(m99);
        let p = w.take('P');
        let Some(frame) = self.flow.frames.last_mut() else {
            self.out.warnings.push(self.err_at(
                at,
                "M99 in the main program: a Fanuc control would restart it from the top (an endless loop); simulated once, as the program end",
            ));
            self.flow.ended = true;
            return Ok(());
        };
        let Some(call) = frame.fanuc.as_mut() else {
            let name = frame.sub.clone();
            return Err(self.err_at(
                at,
                format!("M99 inside subroutine {name} (an o-word subroutine ends with endsub)"),
            ));
        };
        if call.repeats_left > 0 {
            call.repeats_left -= 1;
            self.flow.jump = Some(call.body);
            self.flow.last_jump = Some((self.cur_line, "M99 (repeated subprogram)"));
            return Ok(());
        }
        let frame = self.flow.frames.pop().expect("checked");
        if let Some(locals) = frame.fanuc.and_then(|c| c.locals) {
            self.params.numbered[1..=locals.len()].copy_from_slice(&locals);
        }
        if frame.return_unit != self.units.unit {
            self.units.next_unit = Some(frame.return_unit);
        }
        self.flow.jump = Some(match p {
            None => frame.return_pc + 1,
            Some(p) => {
                let n = self.program_number(p, at, "M99")?;
                self.find_sequence(frame.return_unit, frame.return_pc, n)
                    .ok_or_else(|| {
                        self.err_at(
                            at,
                            format!("M99 P{n}: no block N{n} in the calling program"),
                        )
                    })?
            }
        });
        Ok(())
    }
}
