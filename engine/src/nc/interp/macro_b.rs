//! Fanuc custom macro B: `IF [..] GOTO n`, `IF [..] THEN #i = ..`, `WHILE [..] DOm` ..
//! `ENDm`, `GOTO n`, external output (`DPRNT`, `POPEN`, `PCLOS`: no motion, a warning), and the
//! G65 macro call with its arguments as local variables (argument specifications I and II),
//! and the G66/G67 modal call (nested: a move in one G66's macro calls the macro of the G66
//! before it).

use super::control::Link;
use super::{Interp, R};
use crate::nc::expr::{is_vacant, vacant};
use crate::nc::program::{Expr, MacroLine, MacroStatement};
use crate::nc::view::BlockView;

/// Local variables of a G65 call: #1-#33.
const LOCALS: usize = 33;

/// Nested G66 modal calls a Fanuc control takes (its macro call nesting: four levels).
const MAX_MODAL_CALLS: usize = 4;

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
                self.flow.last_jump = Some((self.cur_line, "a WHILE/DO loop's END"));
                // A WHILE line tests its condition again; a bare DO loops for ever.
                match self.prog.block(start).macro_line.map(|m| &m.statement) {
                    Some(MacroStatement::While { .. }) => start,
                    _ => start + 1,
                }
            }
            MacroStatement::Output(keyword) => {
                self.out.warnings.push(self.err_at(
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
        let to = self.find_sequence(self.units.unit, pc, n).ok_or_else(|| {
            self.err_at(
                at,
                format!("GOTO {n}: no block N{n} in this program (sequence search failed)"),
            )
        })?;
        if to <= pc {
            self.flow.last_jump = Some((self.cur_line, "GOTO"));
        }
        Ok(to)
    }

    /// Whether the block is a G65 call or a G66 modal call: the code first (Fanuc requires it
    /// before the arguments).
    pub(super) fn is_macro_call(&self, b: &BlockView<'p>) -> bool {
        self.fanuc && b.words.first().is_some_and(|w| {
            w.letter == 'G'
                && matches!(w.value, Expr::Number { value, .. } if value == 65.0 || value == 66.0)
        })
    }

    /// `G65 P<program> L<repeats> <arguments>`: a call with a new level of local variables
    /// set from the argument addresses, the others vacant. `G66` with the same words makes
    /// it a modal call: after every later block that moves an axis, until G67.
    pub(super) fn macro_call(&mut self, b: &BlockView<'p>) -> R<()> {
        let at = b.words[0].span.start;
        let modal = matches!(b.words[0].value, Expr::Number { value, .. } if value == 66.0);
        let what = if modal { "G66" } else { "G65" };
        if let Some(a) = b.assignments.first() {
            return Err(self.err_at(
                a.span.start,
                format!("a variable assignment on a {what} line; put it on a line of its own"),
            ));
        }
        let call = self.call_arguments(b, what)?;
        if modal {
            if self.flow.modal_calls.len() >= MAX_MODAL_CALLS {
                return Err(self.err_at(
                    at,
                    format!("G66 nested more than {MAX_MODAL_CALLS} deep (the control's limit; G67 first)"),
                ));
            }
            self.flow.modal_calls.push(ModalCall {
                call,
                depth: self.flow.frames.len(),
                at,
            });
            return Ok(());
        }
        self.enter_macro(&call, at, None)
    }

    /// A G66 call after a block that moved an axis (Fanuc: the move first, then the macro).
    /// A move of the level that set the last G66 calls its macro; with nested G66 (the
    /// manual's G66 P9100 .. G66 P9200), a move in a modal macro calls the macro of the G66
    /// before its own; the first G66's macro calls none (its moves do not call it again).
    pub(super) fn modal_macro_after_move(&mut self) -> R<()> {
        if self.flow.jump.is_some() {
            return Ok(());
        }
        let in_modal = self
            .flow
            .frames
            .last()
            .and_then(|f| f.fanuc.as_ref())
            .and_then(|c| c.modal_level);
        let level = match in_modal {
            Some(k) => match k.checked_sub(1) {
                Some(k) => k,
                None => return Ok(()),
            },
            None => {
                let top = self.flow.modal_calls.len() - 1;
                if self.flow.modal_calls[top].depth != self.flow.frames.len() {
                    return Ok(());
                }
                top
            }
        };
        let Some(mc) = self.flow.modal_calls.get(level) else {
            return Ok(());
        };
        let (call, at) = (mc.call.clone(), mc.at);
        self.enter_macro(&call, at, Some(level))
    }

    /// The program, repeat count and arguments of a G65/G66 block. I, J and K may repeat
    /// (argument specification II: up to ten sets, I J K of set n are #4+3(n-1)..#6+3(n-1));
    /// where the two specifications give one variable, the later word wins (as the manual
    /// says).
    fn call_arguments(&mut self, b: &BlockView<'p>, what: &str) -> R<MacroCall> {
        let at = b.words[0].span.start;
        let mut program = None;
        let mut repeats = 1.0;
        let mut args = [None; LOCALS + 1];
        let mut seen = [false; 26];
        let (mut set, mut last_ijk) = (0usize, None);
        for word in &b.words[1..] {
            let pos = word.span.start;
            let c = word.letter;
            if word.comma {
                return Err(self.err_at(pos, format!("{what}: ,{c} is not an argument")));
            }
            let v = self.eval(&word.value, word.value_span.start)?;
            match c {
                'P' => program = Some(v),
                'L' => repeats = v,
                'I' | 'J' | 'K' => {
                    let o = (c as u8 - b'I') as usize;
                    if last_ijk.is_some_and(|l| o <= l) {
                        set += 1;
                    }
                    last_ijk = Some(o);
                    if set >= 10 {
                        return Err(self
                            .err_at(pos, format!("{what}: more than 10 sets of I J K arguments")));
                    }
                    args[4 + 3 * set + o] = Some(v);
                }
                _ => {
                    let k = argument_variable(c);
                    if k == 0 {
                        return Err(self.err_at(
                            pos,
                            format!("{what}: {c} cannot be an argument (G, L, N, O and P are not argument addresses)"),
                        ));
                    }
                    let li = (c as u8 - b'A') as usize;
                    if seen[li] {
                        return Err(self.err_at(pos, format!("{what}: two {c} arguments")));
                    }
                    seen[li] = true;
                    args[k] = Some(v);
                }
            }
        }
        let Some(p) = program else {
            return Err(self.err_at(
                at,
                format!("{what} needs P (the number of the macro program)"),
            ));
        };
        if is_vacant(repeats) || repeats.fract() != 0.0 || !(0.0..=9999.0).contains(&repeats) {
            return Err(self.err_at(
                at,
                format!("{what} L{repeats}: the repeat count must be 0..9999"),
            ));
        }
        let number = self.program_number(p, at, what)?;
        let (unit, body) = self.resolve_program(number, at, what)?;
        Ok(MacroCall {
            number,
            unit,
            body,
            repeats: repeats as u32,
            args,
        })
    }

    /// Calls the macro program: a new level of local variables from the arguments.
    /// `modal_level`: the G66 (index in `flow.modal_calls`) whose macro this is.
    fn enter_macro(&mut self, call: &MacroCall, at: usize, modal_level: Option<usize>) -> R<()> {
        if call.repeats == 0 {
            return Ok(());
        }
        let saved = self.params.numbered[1..=LOCALS].to_vec();
        self.call_fanuc_program(
            call.number,
            call.unit,
            call.body,
            call.repeats,
            Some(saved),
            at,
        )?;
        for (k, arg) in call.args.iter().enumerate().skip(1) {
            self.params.numbered[k] = arg.unwrap_or_else(vacant);
        }
        if let Some(c) = self.flow.frames.last_mut().and_then(|f| f.fanuc.as_mut()) {
            c.modal_level = modal_level;
        }
        Ok(())
    }
}

/// A macro call's program (its number and first block), repeat count and arguments.
#[derive(Clone, Debug)]
pub(super) struct MacroCall {
    number: u32,
    /// The file of `body` (see `units.rs`).
    unit: u32,
    body: usize,
    repeats: u32,
    args: [Option<f64>; LOCALS + 1],
}

/// A G66 modal call, made after each moving block at the call level `depth`.
#[derive(Clone, Debug)]
pub(super) struct ModalCall {
    call: MacroCall,
    depth: usize,
    /// The G66 word, named by errors of its calls.
    at: usize,
}
