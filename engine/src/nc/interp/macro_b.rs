//! Fanuc custom macro B: `IF [..] GOTO n`, `IF [..] THEN #i = ..`, `WHILE [..] DOm` ..
//! `ENDm`, `GOTO n`, external output (`DPRNT`, `POPEN`, `PCLOS`: no motion, a warning), and the
//! G65 macro call with its arguments as local variables #1-#26 (argument specification I).

use super::control::{FanucCall, Frame, Link};
use super::{Interp, MAX_CALL_DEPTH, R};
use crate::nc::expr::{is_vacant, vacant};
use crate::nc::program::{Expr, MacroLine, MacroStatement, OName};
use crate::nc::view::BlockView;

/// Local variables of a G65 call: #1-#33.
const LOCALS: usize = 33;

/// Argument specification I: the local variable each address sets (0: not an argument).
fn argument_variable(letter: char) -> usize {
    match letter {
        'A' => 1,
        'B' => 2,
        'C' => 3,
        'I' => 4,
        'J' => 5,
        'K' => 6,
        'D' => 7,
        'E' => 8,
        'F' => 9,
        'H' => 11,
        'M' => 13,
        'Q' => 17,
        'R' => 18,
        'S' => 19,
        'T' => 20,
        'U' => 21,
        'V' => 22,
        'W' => 23,
        'X' => 24,
        'Y' => 25,
        'Z' => 26,
        _ => 0,
    }
}

impl<'p> Interp<'p> {
    /// A condition's truth: a vacant value is false.
    fn truth(&self, e: &Expr, pos: usize) -> R<bool> {
        let v = self.eval(e, pos)?;
        Ok(!is_vacant(v) && v != 0.0)
    }

    /// Runs a macro statement line; returns the next block.
    pub(super) fn exec_macro(&mut self, pc: usize, b: &BlockView<'p>, m: &MacroLine) -> R<usize> {
        let at = m.span.start;
        if !self.fanuc {
            return Err(self.err_at(
                at,
                "Fanuc macro B statement (IF/WHILE/GOTO/END/DPRNT); not valid with dialect linuxcnc",
            ));
        }
        if self.pending_corner.is_some() {
            return Err(self.err_at(
                at,
                "macro statement between a corner rounding/chamfer block and its next move",
            ));
        }
        let link = || self.control.links.get(&pc);
        Ok(match &m.statement {
            MacroStatement::Goto(target) => self.goto(pc, target, at)?,
            MacroStatement::IfGoto { cond, target } => {
                if self.truth(cond, at)? {
                    self.goto(pc, target, at)?
                } else {
                    pc + 1
                }
            }
            MacroStatement::IfThen { cond } => {
                if self.truth(cond, at)? {
                    let mut vals = Vec::with_capacity(b.assignments.len());
                    for a in b.assignments {
                        vals.push(self.eval(&a.value, a.span.start)?);
                    }
                    for (a, v) in b.assignments.iter().zip(vals) {
                        self.assign(a, v)?;
                    }
                }
                pc + 1
            }
            MacroStatement::While { cond, id } => {
                let Some(&Link::MacroLoop { end }) = link() else {
                    return Err(self.err_at(at, format!("DO{id} without its END{id}")));
                };
                if self.truth(cond, at)? {
                    pc + 1
                } else {
                    end + 1
                }
            }
            MacroStatement::Do { id } => {
                if !matches!(link(), Some(Link::MacroLoop { .. })) {
                    return Err(self.err_at(at, format!("DO{id} without its END{id}")));
                }
                pc + 1
            }
            MacroStatement::End { id } => {
                let Some(&Link::MacroEnd { start }) = link() else {
                    return Err(self.err_at(at, format!("END{id} without its DO{id}")));
                };
                self.last_jump = Some((self.cur_line, "a WHILE/DO loop's END"));
                // A WHILE line tests its condition again; a bare DO loops for ever.
                match self.prog.block(start).macro_line.map(|m| &m.statement) {
                    Some(MacroStatement::While { .. }) => start,
                    _ => start + 1,
                }
            }
            MacroStatement::Output(keyword) => {
                self.warnings.push(self.err_at(
                    at,
                    format!("{keyword}: external output is not simulated (no motion)"),
                ));
                pc + 1
            }
        })
    }

    /// `GOTO n`: the block numbered Nn in the current program.
    fn goto(&mut self, pc: usize, target: &Expr, at: usize) -> R<usize> {
        let v = self.eval(target, at)?;
        if is_vacant(v) || v.fract() != 0.0 || !(1.0..=99_999_999.0).contains(&v) {
            return Err(self.err_at(
                at,
                format!(
                    "GOTO {}: the target must be a sequence number 1..99999999",
                    crate::nc::expr::num_text(v)
                ),
            ));
        }
        let n = v as u32;
        let to = self.find_sequence(pc, n).ok_or_else(|| {
            self.err_at(
                at,
                format!("GOTO {n}: no block N{n} in this program (sequence search failed)"),
            )
        })?;
        if to <= pc {
            self.last_jump = Some((self.cur_line, "GOTO"));
        }
        Ok(to)
    }

    /// Whether the block is a G65 call: G65 first (Fanuc requires it before the arguments).
    pub(super) fn is_macro_call(&self, b: &BlockView<'p>) -> bool {
        self.fanuc
            && b.words.first().is_some_and(|w| {
                w.letter == 'G' && matches!(w.value, Expr::Number { value, .. } if value == 65.0)
            })
    }

    /// `G65 P<program> L<repeats> <arguments>`: a call with a new level of local variables,
    /// #1-#26 set from the argument addresses (specification I), the others vacant.
    pub(super) fn macro_call(&mut self, b: &BlockView<'p>) -> R<()> {
        let g65 = b.words[0].span.start;
        if let Some(a) = b.assignments.first() {
            return Err(self.err_at(
                a.span.start,
                "a variable assignment on a G65 line; put it on a line of its own",
            ));
        }
        let mut program = None;
        let mut repeats = 1.0;
        let mut args = [None; LOCALS + 1];
        for word in &b.words[1..] {
            let pos = word.span.start;
            let c = word.letter;
            if word.comma {
                return Err(self.err_at(pos, format!("G65: ,{c} is not an argument")));
            }
            let v = self.eval(&word.value, word.value_span.start)?;
            match c {
                'P' => program = Some(v),
                'L' => repeats = v,
                _ => {
                    let k = argument_variable(c);
                    if k == 0 {
                        return Err(self.err_at(
                            pos,
                            format!("G65: {c} cannot be an argument (G, L, N, O and P are not argument addresses)"),
                        ));
                    }
                    if args[k].is_some() {
                        return Err(self.err_at(pos, format!("G65: two {c} arguments")));
                    }
                    args[k] = Some(v);
                }
            }
        }
        let Some(p) = program else {
            return Err(self.err_at(g65, "G65 needs P (the number of the macro program)"));
        };
        if is_vacant(repeats) || repeats.fract() != 0.0 || !(0.0..=9999.0).contains(&repeats) {
            return Err(self.err_at(
                g65,
                format!("G65 L{repeats}: the repeat count must be 0..9999"),
            ));
        }
        let number = self.program_number(p, g65, "G65")?;
        let body = self.resolve_program(number, g65, "G65")?;
        if repeats == 0.0 {
            return Ok(());
        }
        if self.frames.len() >= MAX_CALL_DEPTH {
            return Err(self.err_at(g65, format!("calls nested deeper than {MAX_CALL_DEPTH}")));
        }
        let saved = self.params.numbered[1..=LOCALS].to_vec();
        for (k, arg) in args.iter().enumerate().skip(1) {
            self.params.numbered[k] = arg.unwrap_or_else(vacant);
        }
        self.frames.push(Frame {
            return_pc: self.cur_block,
            saved: Vec::new(),
            sub: OName::Number(number),
            auto_restore: None,
            fanuc: Some(FanucCall {
                body,
                repeats_left: repeats as u32 - 1,
                locals: Some(saved),
            }),
        });
        self.jump = Some(body);
        Ok(())
    }
}
