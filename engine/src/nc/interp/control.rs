//! Control flow: LinuxCNC O-word subroutines, loops and branches (the pre-scan links every
//! control line to its partners; the run loop follows the links).

use super::macro_b::ModalCall;
use super::modal::Modal;
use super::{Interp, MAX_CALL_DEPTH, R};
use crate::nc::program::{MacroStatement, OKeyword, OName, OWord};
use crate::nc::view::ProgramView;
use crate::nc::Diagnostics;
use std::collections::HashMap;

/// Program flow: the call stack, loop counts, jumps, G66 modal calls and the program's end.
#[derive(Default)]
pub(super) struct Flow {
    pub(super) frames: Vec<Frame>,
    pub(super) repeat_counts: HashMap<(usize, usize), f64>,
    /// G66: the macro called after each moving block, until G67.
    /// Nested G66: the last one is called after the setting level's moves, each earlier one
    /// after the moves of the macro of the one after it.
    pub(super) modal_calls: Vec<ModalCall>,
    /// Where the run loop goes after the current block, when not to the next one (M98, M99,
    /// G65).
    pub(super) jump: Option<usize>,
    /// The `O` line of the main program (the first one run).
    pub(super) main_program: Option<usize>,
    /// Sequence numbers (N) of each Fanuc program searched so far, by the program's first
    /// block: number -> block.
    pub(super) sequences: HashMap<(u32, usize), HashMap<u32, usize>>,
    /// The last jump backwards (line, what), named when a runaway loop is stopped.
    pub(super) last_jump: Option<(u32, &'static str)>,
    pub(super) ended: bool,
}

pub(super) struct Frame {
    pub(super) return_pc: usize,
    /// The file of `return_pc` (see `units.rs`).
    pub(super) return_unit: u32,
    pub(super) saved: Vec<f64>,
    pub(super) sub: OName,
    /// M73: modal state to restore when the call returns.
    pub(super) auto_restore: Option<Modal>,
    /// A Fanuc M98/G65 call (None: a LinuxCNC o-word call).
    pub(super) fanuc: Option<FanucCall>,
}

/// What a Fanuc subprogram (M98) or macro (G65) call needs on return.
pub(super) struct FanucCall {
    /// The first block of the called program's body.
    pub(super) body: usize,
    /// Runs still to make (M98 L, the repeat digits of M98 P, G65 L).
    pub(super) repeats_left: u32,
    /// G65: the caller's local variables #1-#33, restored on return (M98 shares them).
    pub(super) locals: Option<Vec<f64>>,
    /// A G66 modal call's macro: its index in `Flow::modal_calls`.
    pub(super) modal_level: Option<usize>,
}

/// Control structure links found by the pre-scan, by block index.
#[derive(Clone, Debug)]
pub(super) enum Link {
    /// `sub`: its `endsub`.
    Sub {
        end: usize,
    },
    EndSub,
    /// `while` opening a while loop.
    While {
        end: usize,
    },
    EndWhile {
        start: usize,
    },
    Do,
    /// `while` closing a do loop.
    DoWhile {
        start: usize,
    },
    /// `if` / `elseif` / `else`: the next branch (None: none) and the `endif`.
    Branch {
        next: Option<usize>,
        end: usize,
    },
    EndIf,
    Repeat {
        end: usize,
    },
    EndRepeat {
        start: usize,
    },
    /// `break` / `continue`: the loop's start and end lines.
    Break {
        start: usize,
        end: usize,
    },
    Continue {
        start: usize,
        end: usize,
    },
    Return,
    Call,
    ProgramNumber,
    /// Fanuc `WHILE [..] DOm` / `DOm`: its `ENDm`.
    MacroLoop {
        end: usize,
    },
    /// Fanuc `ENDm`: its `WHILE` or `DO` line.
    MacroEnd {
        start: usize,
    },
}

pub(super) struct ControlMap {
    pub(super) links: HashMap<usize, Link>,
    pub(super) subs: HashMap<OName, usize>,
    /// Fanuc programs in the file: O number -> block of its `O` line.
    pub(super) programs: HashMap<u32, usize>,
    /// Blocks of the `O` program-number lines, in order (a program runs to the next one).
    pub(super) program_starts: Vec<usize>,
}

impl ControlMap {
    /// The map of a program whose only O word is its program number, on block `at` (the
    /// pre-scan's for it, without the blocks).
    pub(super) fn program_number_only(at: Option<usize>) -> ControlMap {
        ControlMap {
            links: at.map(|i| (i, Link::ProgramNumber)).into_iter().collect(),
            subs: HashMap::new(),
            programs: HashMap::new(),
            program_starts: at.into_iter().collect(),
        }
    }
}

pub(super) fn prescan(prog: &ProgramView) -> Result<ControlMap, Diagnostics> {
    #[derive(Clone)]
    struct Open {
        name: OName,
        kw: OKeyword,
        idx: usize,
        branches: Vec<usize>,
    }
    let mut stack: Vec<Open> = Vec::new();
    let mut links = HashMap::new();
    let mut subs = HashMap::new();
    let mut programs = HashMap::new();
    let mut program_starts = Vec::new();
    let mut errors = Vec::new();
    for &idx in &prog.summary().o_word_blocks {
        let Some(o) = prog.block(idx).o_word else {
            continue;
        };
        let at = |m: String| prog.diag(o.span.start, m);
        let top_is = |stack: &Vec<Open>, kw: OKeyword| {
            stack
                .last()
                .map(|t| t.kw == kw && t.name == o.name)
                .unwrap_or(false)
        };
        match o.keyword {
            OKeyword::Sub => {
                if stack.iter().any(|s| s.kw == OKeyword::Sub) {
                    errors.push(at(format!("{} sub inside another subroutine", o.name)));
                }
                if subs.insert(o.name.clone(), idx).is_some() {
                    errors.push(at(format!("subroutine {} defined twice", o.name)));
                }
                stack.push(Open {
                    name: o.name.clone(),
                    kw: OKeyword::Sub,
                    idx,
                    branches: vec![],
                });
            }
            OKeyword::EndSub => {
                if top_is(&stack, OKeyword::Sub) {
                    let s = stack.pop().expect("checked");
                    links.insert(s.idx, Link::Sub { end: idx });
                    links.insert(idx, Link::EndSub);
                } else {
                    errors.push(at(format!("{} endsub without matching sub", o.name)));
                }
            }
            OKeyword::Do => {
                stack.push(Open {
                    name: o.name.clone(),
                    kw: OKeyword::Do,
                    idx,
                    branches: vec![],
                });
                links.insert(idx, Link::Do);
            }
            OKeyword::While => {
                if top_is(&stack, OKeyword::Do) {
                    let s = stack.pop().expect("checked");
                    links.insert(idx, Link::DoWhile { start: s.idx });
                    // Record the do's end for break/continue resolution.
                    links.insert(s.idx, Link::Do);
                    resolve_loop_jumps(&mut links, s.idx, idx);
                } else {
                    stack.push(Open {
                        name: o.name.clone(),
                        kw: OKeyword::While,
                        idx,
                        branches: vec![],
                    });
                }
            }
            OKeyword::EndWhile => {
                if top_is(&stack, OKeyword::While) {
                    let s = stack.pop().expect("checked");
                    links.insert(s.idx, Link::While { end: idx });
                    links.insert(idx, Link::EndWhile { start: s.idx });
                    resolve_loop_jumps(&mut links, s.idx, idx);
                } else {
                    errors.push(at(format!("{} endwhile without matching while", o.name)));
                }
            }
            OKeyword::Repeat => {
                stack.push(Open {
                    name: o.name.clone(),
                    kw: OKeyword::Repeat,
                    idx,
                    branches: vec![],
                });
            }
            OKeyword::EndRepeat => {
                if top_is(&stack, OKeyword::Repeat) {
                    let s = stack.pop().expect("checked");
                    links.insert(s.idx, Link::Repeat { end: idx });
                    links.insert(idx, Link::EndRepeat { start: s.idx });
                    resolve_loop_jumps(&mut links, s.idx, idx);
                } else {
                    errors.push(at(format!("{} endrepeat without matching repeat", o.name)));
                }
            }
            OKeyword::If => {
                stack.push(Open {
                    name: o.name.clone(),
                    kw: OKeyword::If,
                    idx,
                    branches: vec![idx],
                });
            }
            OKeyword::ElseIf | OKeyword::Else => {
                if top_is(&stack, OKeyword::If) {
                    let t = stack.last_mut().expect("checked");
                    let last = *t.branches.last().expect("if has a branch");
                    if prog.block(last).o_word.as_ref().map(|o| o.keyword) == Some(OKeyword::Else) {
                        errors.push(at(format!("{} {} after else", o.name, kw_name(o.keyword))));
                    }
                    t.branches.push(idx);
                } else {
                    errors.push(at(format!(
                        "{} {} without matching if",
                        o.name,
                        kw_name(o.keyword)
                    )));
                }
            }
            OKeyword::EndIf => {
                if top_is(&stack, OKeyword::If) {
                    let s = stack.pop().expect("checked");
                    for (k, &bi) in s.branches.iter().enumerate() {
                        links.insert(
                            bi,
                            Link::Branch {
                                next: s.branches.get(k + 1).copied(),
                                end: idx,
                            },
                        );
                    }
                    links.insert(idx, Link::EndIf);
                } else {
                    errors.push(at(format!("{} endif without matching if", o.name)));
                }
            }
            OKeyword::Break | OKeyword::Continue => {
                let found = stack.iter().rev().find(|s| {
                    s.name == o.name
                        && matches!(s.kw, OKeyword::While | OKeyword::Do | OKeyword::Repeat)
                });
                if found.is_none() {
                    errors.push(at(format!(
                        "{} {} outside a loop named {}",
                        o.name,
                        kw_name(o.keyword),
                        o.name
                    )));
                } else {
                    // Resolved when the loop closes; placeholder keeps the keyword.
                    let l = if o.keyword == OKeyword::Break {
                        Link::Break {
                            start: usize::MAX,
                            end: usize::MAX,
                        }
                    } else {
                        Link::Continue {
                            start: usize::MAX,
                            end: usize::MAX,
                        }
                    };
                    links.insert(idx, l);
                }
            }
            OKeyword::Return => {
                // The return's name may be that of an enclosing if/loop (LinuxCNC allows it).
                if !stack.iter().any(|s| s.kw == OKeyword::Sub) {
                    errors.push(at(format!("{} return outside a subroutine", o.name)));
                }
                links.insert(idx, Link::Return);
            }
            OKeyword::Call => {
                links.insert(idx, Link::Call);
            }
            OKeyword::ProgramNumber => {
                links.insert(idx, Link::ProgramNumber);
                if let OName::Number(n) = o.name {
                    if programs.insert(n, idx).is_some() {
                        errors.push(at(format!("program O{n} defined twice in this file")));
                    }
                }
                program_starts.push(idx);
            }
        }
    }
    prescan_macro_loops(prog, &mut links, &mut errors);
    for s in stack {
        errors.push(prog.diag(
            prog.block(s.idx).span.start,
            format!("{} {} is never closed", s.name, kw_name(s.kw)),
        ));
    }
    // Break/continue must have been resolved by their loop.
    if errors.is_empty() {
        Ok(ControlMap {
            links,
            subs,
            programs,
            program_starts,
        })
    } else {
        errors.sort_by_key(|d| (d.line, d.col));
        Err(Diagnostics(errors))
    }
}

/// Link each Fanuc `WHILE [..] DOm` or `DOm` with its `ENDm`. Loops nest (the inner one
/// ends first) and do not cross.
fn prescan_macro_loops(
    prog: &ProgramView,
    links: &mut HashMap<usize, Link>,
    errors: &mut Vec<crate::nc::Diagnostic>,
) {
    let mut open: Vec<(u32, usize)> = Vec::new();
    for &idx in &prog.summary().macro_blocks {
        let Some(m) = prog.block(idx).macro_line else {
            continue;
        };
        let at = |msg: String| prog.diag(m.span.start, msg);
        match m.statement {
            MacroStatement::While { id, .. } | MacroStatement::Do { id } => open.push((id, idx)),
            MacroStatement::End { id } => match open.last() {
                Some(&(top, start)) if top == id => {
                    open.pop();
                    links.insert(start, Link::MacroLoop { end: idx });
                    links.insert(idx, Link::MacroEnd { start });
                }
                Some(&(top, start)) if open.iter().any(|o| o.0 == id) => {
                    errors.push(at(format!(
                        "END{id} while DO{top} (line {}) is still open: loops may nest but not cross",
                        prog.block(start).line
                    )));
                    return;
                }
                _ => errors.push(at(format!("END{id} without a matching DO{id}"))),
            },
            _ => {}
        }
    }
    for (id, idx) in open {
        let m = prog.block(idx).macro_line.expect("macro line");
        errors.push(prog.diag(
            m.span.start,
            format!("DO{id} is never closed (END{id} missing)"),
        ));
    }
}

/// Point unresolved break/continue lines between `start` and `end` at this loop. Inner loops
/// with the same name are not allowed by the pre-scan's name matching, so the first
/// unresolved ones in range belong here.
pub(super) fn resolve_loop_jumps(links: &mut HashMap<usize, Link>, start: usize, end: usize) {
    for (idx, l) in links.iter_mut() {
        if *idx <= start || *idx >= end {
            continue;
        }
        match l {
            Link::Break { start: s, end: e } | Link::Continue { start: s, end: e }
                if *s == usize::MAX =>
            {
                *s = start;
                *e = end;
            }
            _ => {}
        }
    }
}

pub(super) fn kw_name(k: OKeyword) -> &'static str {
    match k {
        OKeyword::Sub => "sub",
        OKeyword::EndSub => "endsub",
        OKeyword::Call => "call",
        OKeyword::Do => "do",
        OKeyword::While => "while",
        OKeyword::EndWhile => "endwhile",
        OKeyword::If => "if",
        OKeyword::ElseIf => "elseif",
        OKeyword::Else => "else",
        OKeyword::EndIf => "endif",
        OKeyword::Repeat => "repeat",
        OKeyword::EndRepeat => "endrepeat",
        OKeyword::Return => "return",
        OKeyword::Break => "break",
        OKeyword::Continue => "continue",
        OKeyword::ProgramNumber => "program number",
    }
}

impl Interp<'_> {
    pub(super) fn cond(&self, o: &OWord) -> R<f64> {
        match o.args.first() {
            Some(e) => self.eval(e, o.span.start),
            None => Err(self.err_at(o.span.start, "missing [condition]")),
        }
    }

    pub(super) fn exec_oword(&mut self, control: &ControlMap, pc: usize, o: &OWord) -> R<usize> {
        if self.pending_corner.is_some() {
            return Err(self.err_at(
                o.span.start,
                "O-word line between a corner rounding/chamfer block and its next move",
            ));
        }
        let link = control.links.get(&pc).cloned().ok_or_else(|| {
            self.err_at(
                o.span.start,
                "O-word is not part of a complete control structure",
            )
        })?;
        let depth = self.flow.frames.len();
        Ok(match link {
            Link::ProgramNumber => {
                if !self.fanuc {
                    return Err(self.err_at(
                        o.span.start,
                        format!("{} without a keyword is a Fanuc program number; not valid with dialect linuxcnc", o.name),
                    ));
                }
                return self.reach_program_start(pc, o);
            }
            Link::Sub { end } => end + 1,
            Link::EndSub | Link::Return => {
                let value = match o.args.first() {
                    Some(e) => Some(self.eval(e, o.span.start)?),
                    None => None,
                };
                if let Some(f) = self.flow.frames.last().filter(|f| f.fanuc.is_some()) {
                    return Err(self.err_at(
                        o.span.start,
                        format!(
                            "{} {} inside Fanuc program O{} (called by M98/G65; it returns with M99)",
                            o.name,
                            kw_name(o.keyword),
                            f.sub.number()
                        ),
                    ));
                }
                let Some(frame) = self.flow.frames.pop() else {
                    return Err(self.err_at(o.span.start, "endsub/return reached outside a call"));
                };
                if o.keyword == OKeyword::EndSub && frame.sub != o.name {
                    return Err(self.err_at(
                        o.span.start,
                        format!(
                            "{} {} inside subroutine {}",
                            o.name,
                            kw_name(o.keyword),
                            frame.sub
                        ),
                    ));
                }
                self.params.numbered[1..=30].copy_from_slice(&frame.saved);
                if let Some(m) = &frame.auto_restore {
                    self.restore_modal(m);
                }
                self.params.locals.pop();
                self.flow
                    .repeat_counts
                    .retain(|k, _| k.0 <= self.flow.frames.len());
                match value {
                    Some(v) => {
                        self.params.globals.insert("_value".into(), v);
                        self.params.globals.insert("_value_returned".into(), 1.0);
                    }
                    None => {
                        self.params.globals.insert("_value".into(), 0.0);
                        self.params.globals.insert("_value_returned".into(), 0.0);
                    }
                }
                if frame.return_unit != self.units.unit {
                    self.units.next_unit = Some(frame.return_unit);
                }
                frame.return_pc + 1
            }
            Link::Call => {
                let (unit, start) = match control.subs.get(&o.name) {
                    Some(&start) => (self.units.unit, start),
                    None => self.sub_elsewhere(&o.name, o.span.start)?.ok_or_else(|| {
                        self.err_at(
                            o.span.start,
                            format!("subroutine {} is not defined in this program nor in its library (a file {}.ngc)", o.name, match &o.name { OName::Number(n) => n.to_string(), OName::Named(s) => s.clone() }),
                        )
                    })?,
                };
                if self.flow.frames.len() >= MAX_CALL_DEPTH {
                    return Err(self.err_at(
                        o.span.start,
                        format!("calls nested deeper than {MAX_CALL_DEPTH}"),
                    ));
                }
                if o.args.len() > 30 {
                    return Err(self.err_at(o.span.start, "more than 30 call arguments"));
                }
                let mut args = Vec::with_capacity(o.args.len());
                for a in &o.args {
                    args.push(self.eval(a, o.span.start)?);
                }
                let saved = self.params.numbered[1..=30].to_vec();
                for i in 0..30 {
                    self.params.numbered[i + 1] = args.get(i).copied().unwrap_or(0.0);
                }
                self.params.locals.push(HashMap::new());
                self.flow.frames.push(Frame {
                    return_pc: pc,
                    return_unit: self.units.unit,
                    saved,
                    sub: o.name.clone(),
                    auto_restore: None,
                    fanuc: None,
                });
                self.params.globals.insert("_value_returned".into(), 0.0);
                if unit != self.units.unit {
                    self.units.next_unit = Some(unit);
                }
                start + 1
            }
            Link::While { end } => {
                if self.cond(o)? != 0.0 {
                    pc + 1
                } else {
                    end + 1
                }
            }
            Link::EndWhile { start } => start,
            Link::Do => pc + 1,
            Link::DoWhile { start } => {
                if self.cond(o)? != 0.0 {
                    start + 1
                } else {
                    pc + 1
                }
            }
            Link::Branch { next, end } => {
                // Reached in sequence from a taken branch: else/elseif lines end it.
                if o.keyword != OKeyword::If {
                    return Ok(end + 1);
                }
                let mut at = pc;
                let mut nxt = next;
                loop {
                    let ow = self.prog.block(at).o_word.expect("branch line");
                    let taken = match ow.keyword {
                        OKeyword::Else => true,
                        _ => self.cond(ow)? != 0.0,
                    };
                    if taken {
                        break at + 1;
                    }
                    match nxt {
                        Some(n) => {
                            at = n;
                            nxt = match control.links.get(&n) {
                                Some(Link::Branch { next, .. }) => *next,
                                _ => None,
                            };
                        }
                        None => break end + 1,
                    }
                }
            }
            Link::EndIf => pc + 1,
            Link::Repeat { end } => {
                let n = self.cond(o)?;
                if n.round() >= 1.0 {
                    self.flow.repeat_counts.insert((depth, pc), n.round());
                    pc + 1
                } else {
                    end + 1
                }
            }
            Link::EndRepeat { start } => {
                let left = self
                    .flow
                    .repeat_counts
                    .get(&(depth, start))
                    .copied()
                    .unwrap_or(1.0)
                    - 1.0;
                if left >= 1.0 {
                    self.flow.repeat_counts.insert((depth, start), left);
                    start + 1
                } else {
                    self.flow.repeat_counts.remove(&(depth, start));
                    pc + 1
                }
            }
            Link::Break { start, end } => {
                self.flow.repeat_counts.remove(&(depth, start));
                end + 1
            }
            Link::MacroLoop { .. } | Link::MacroEnd { .. } => {
                return Err(self.err_at(o.span.start, "O-word line linked as a macro loop"))
            }
            Link::Continue { start, end } => {
                // A while loop re-tests at its top; do-while and repeat at their closing line.
                match control.links.get(&start) {
                    Some(Link::While { .. }) => start,
                    _ => end,
                }
            }
        })
    }
}
