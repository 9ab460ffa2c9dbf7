//! The interpreter: runs a [`Program`] block by block with full modal state and produces
//! [`Move`]s in the machine frame. It follows LinuxCNC 2.9's rs274ngc interpreter (order of
//! execution within a block, canned cycle motions, arc tolerances), which the tests compare
//! against, plus the Fanuc differences selected by the dialect.

use super::arc::ArcGeometry;
use super::expr::{self, Env, Params};
use super::program::*;
use super::view::{BlockView, ProgramView};
use super::{
    Diagnostic, Diagnostics, Dialect, FeedMode, InterpretOptions, Interpretation, Move, MoveKind,
    SpindleDir,
};
use std::collections::HashMap;

/// Executed blocks between two looks at the cancel flag: an atomic load is cheap, but not
/// free on every block, and a few thousand blocks take well under a millisecond.
const CANCEL_CHECK_BLOCKS: usize = 4096;

const MM_PER_INCH: f64 = 25.4;
/// LinuxCNC's retract between pecks in G73/G83, inches.
const G83_RAPID_DELTA_INCH: f64 = 0.010;
const MAX_CALL_DEPTH: usize = 64;
/// Most full turns accepted in one arc (P word).
const MAX_ARC_TURNS: f64 = 10_000.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Plane {
    XY,
    XZ,
    YZ,
}

impl Plane {
    /// First and second axis of the plane, then the normal axis (right-handed).
    fn axes(self) -> [usize; 3] {
        match self {
            Plane::XY => [0, 1, 2],
            Plane::XZ => [2, 0, 1],
            Plane::YZ => [1, 2, 0],
        }
    }
    fn normal(self) -> [f64; 3] {
        match self {
            Plane::XY => [0.0, 0.0, 1.0],
            Plane::XZ => [0.0, 1.0, 0.0],
            Plane::YZ => [1.0, 0.0, 0.0],
        }
    }
    /// Arc centre offset letters for the first and second axis.
    fn ijk(self) -> [char; 2] {
        match self {
            Plane::XY => ['I', 'J'],
            Plane::XZ => ['K', 'I'],
            Plane::YZ => ['J', 'K'],
        }
    }
    /// The offset letter not allowed in this plane.
    fn forbidden_ijk(self) -> char {
        match self {
            Plane::XY => 'K',
            Plane::XZ => 'J',
            Plane::YZ => 'I',
        }
    }
    fn name(self) -> &'static str {
        match self {
            Plane::XY => "G17",
            Plane::XZ => "G18",
            Plane::YZ => "G19",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Motion {
    Rapid,
    Linear,
    Arc {
        cw: bool,
    },
    RigidTap,
    /// G73, G81..G89 (the G number)
    Cycle(u16),
}

const AXES: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

fn letter_index(c: char) -> usize {
    (c as u8 - b'A') as usize
}

/// The evaluated words of one block.
struct Words {
    vals: [Option<(f64, usize)>; 26],
    used: [bool; 26],
    /// G codes times ten (G43.1 -> 431) with the word index.
    gs: Vec<(u16, usize)>,
    ms: Vec<(u32, usize)>,
    corner_r: Option<(f64, usize)>,
    corner_c: Option<(f64, usize)>,
}

impl Words {
    fn get(&self, c: char) -> Option<f64> {
        self.vals[letter_index(c)].map(|v| v.0)
    }
    fn take(&mut self, c: char) -> Option<f64> {
        let i = letter_index(c);
        if self.vals[i].is_some() {
            self.used[i] = true;
        }
        self.vals[i].map(|v| v.0)
    }
    fn has(&self, c: char) -> bool {
        self.vals[letter_index(c)].is_some()
    }
    /// Axis words not yet used by an earlier step of the block (G4 X, G43.1 Z).
    fn has_axis(&self) -> bool {
        AXES.iter()
            .any(|&c| self.has(c) && !self.used[letter_index(c)])
    }
    fn g(&self, code: u16) -> Option<usize> {
        self.gs.iter().find(|g| g.0 == code).map(|g| g.1)
    }
    fn m(&self, code: u32) -> Option<usize> {
        self.ms.iter().find(|m| m.0 == code).map(|m| m.1)
    }
}

/// Modal group of a G code (times ten), LinuxCNC numbering; None: unsupported.
fn g_group(code: u16) -> Option<u8> {
    Some(match code {
        40 | 100 | 280 | 281 | 300 | 301 | 530 | 920 | 921 | 922 | 923 => 0,
        0 | 10 | 20 | 30 | 331 | 730 | 740 | 800 | 810 | 820 | 830 | 840 | 850 | 860 | 870
        | 880 | 890 => 1,
        170 | 180 | 190 => 2,
        900 | 910 => 3,
        901 | 911 => 4,
        930 | 940 | 950 => 5,
        200 | 210 => 6,
        400 | 410 | 420 | 411 | 421 => 7,
        430 | 431 | 490 => 8,
        980 | 990 => 10,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => 12,
        610 | 611 | 640 => 13,
        _ => return None,
    })
}

fn g_name(code: u16) -> String {
    if code % 10 == 0 {
        format!("G{}", code / 10)
    } else {
        format!("G{}.{}", code / 10, code % 10)
    }
}

/// Why a G code is refused, for the error message.
fn g_refusal(code: u16) -> &'static str {
    match code {
        50..=59 => "spline/NURBS motion (G5.x) is not supported",
        70 | 80 => "lathe diameter/radius mode is not supported",
        150 | 160 => "polar coordinates (G15/G16) are not supported",
        330 => "spindle-synchronized motion (G33) is not supported",
        380..=389 => "probing (G38.x) cannot be simulated without a probe model",
        510 | 511 | 500 => "scaling (G50/G51) is not supported",
        680 | 690 => "coordinate rotation (G68/G69) is not supported",
        760 => "threading cycle G76 is not supported",
        _ => "is not a supported G code",
    }
}

/// M code modal group (LinuxCNC numbering); None: not a known M code.
fn m_group(code: u32) -> Option<u8> {
    Some(match code {
        0 | 1 | 2 | 30 | 60 => 4,
        6 | 61 => 6,
        3 | 4 | 5 => 7,
        7 | 8 | 9 => 8,
        48 | 49 | 50 | 51 | 52 | 53 => 9,
        70 | 71 | 72 | 73 => 5,
        _ => return None,
    })
}

struct Frame {
    return_pc: usize,
    saved: Vec<f64>,
    sub: OName,
    /// M73: modal state to restore when the call returns.
    auto_restore: Option<Modal>,
}

/// Modal state saved by M70/M73 and restored by M72 (LinuxCNC).
#[derive(Clone, Debug)]
struct Modal {
    metric: bool,
    absolute: bool,
    arc_absolute: bool,
    feed_mode: FeedMode,
    plane: Plane,
    retract_r_plane: bool,
    cs: usize,
    feed_word: f64,
    feed_factor: f64,
    speed: f64,
    spindle: SpindleDir,
}

/// Control structure links found by the pre-scan, by block index.
#[derive(Clone, Debug)]
enum Link {
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
}

struct ControlMap {
    links: HashMap<usize, Link>,
    subs: HashMap<OName, usize>,
}

fn prescan(prog: &ProgramView) -> Result<ControlMap, Diagnostics> {
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
            }
        }
    }
    for s in stack {
        errors.push(prog.diag(
            prog.block(s.idx).span.start,
            format!("{} {} is never closed", s.name, kw_name(s.kw)),
        ));
    }
    // Break/continue must have been resolved by their loop.
    if errors.is_empty() {
        Ok(ControlMap { links, subs })
    } else {
        errors.sort_by_key(|d| (d.line, d.col));
        Err(Diagnostics(errors))
    }
}

/// Point unresolved break/continue lines between `start` and `end` at this loop. Inner loops
/// with the same name are not allowed by the pre-scan's name matching, so the first
/// unresolved ones in range belong here.
fn resolve_loop_jumps(links: &mut HashMap<usize, Link>, start: usize, end: usize) {
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

fn kw_name(k: OKeyword) -> &'static str {
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

/// A Fanuc corner (`,R` / `,C`) waiting for the next block's direction.
#[derive(Clone, Debug)]
struct PendingCorner {
    /// Index in `moves` of the linear move to shorten.
    move_index: usize,
    block: usize,
    word_pos: usize,
    chamfer: bool,
    /// Program units.
    size: f64,
    /// Corner point (program coordinates, the end of that move).
    corner: [f64; 6],
    plane: Plane,
}

struct Interp<'p> {
    prog: &'p ProgramView<'p>,
    opts: &'p InterpretOptions,
    fanuc: bool,
    corners_without_comma: bool,
    // Modal state.
    metric: bool,
    absolute: bool,
    arc_absolute: bool,
    feed_mode: FeedMode,
    plane: Plane,
    motion: Option<Motion>,
    /// Motion mode before the current block (decides whether a cycle's words are sticky).
    motion_prev: Option<Motion>,
    retract_r_plane: bool,
    /// 0 = G54 ... 8 = G59.3
    cs: usize,
    /// Current position, program coordinates in program units (as LinuxCNC keeps it).
    cur: [f64; 6],
    /// Work offsets, mm/deg.
    g5x: [[f64; 6]; 9],
    g92: [f64; 6],
    g92_applied: bool,
    g28: [f64; 6],
    g30: [f64; 6],
    /// Active tool length offset (mm), None: G49.
    tlo: Option<f64>,
    /// F as programmed and the mm-per-unit factor when it was given.
    feed_word: f64,
    feed_factor: f64,
    speed: f64,
    spindle: SpindleDir,
    tool: u32,
    selected_tool: Option<u32>,
    /// Each T number selected, with the line of its first selection.
    selected_tools: Vec<(u32, u32)>,
    // Canned cycle sticky values (program units).
    cycle_r: f64,
    cycle_cc: f64,
    cycle_p: f64,
    cycle_q: f64,
    cycle_i: f64,
    cycle_j: f64,
    cycle_k: f64,
    cycle_il: Option<f64>,
    params: Params,
    frames: Vec<Frame>,
    repeat_counts: HashMap<(usize, usize), f64>,
    moves: Vec<Move>,
    warnings: Vec<Diagnostic>,
    pending_corner: Option<PendingCorner>,
    /// M70 saved state.
    saved_modal: Option<Modal>,
    ended: bool,
    /// Block being executed (index, line) for moves and errors.
    cur_block: usize,
    cur_line: u32,
    warned_tools: std::collections::HashSet<u32>,
    /// Storage for the next block's G and M lists.
    spare_gs: Vec<(u16, usize)>,
    spare_ms: Vec<(u32, usize)>,
}

type R<T> = Result<T, Diagnostic>;

/// Interpret a parsed program.
pub fn interpret_program(
    prog: &Program,
    options: &InterpretOptions,
) -> Result<Interpretation, Diagnostics> {
    interpret_view(&ProgramView::of(prog), options)
}

pub(crate) fn interpret_view(
    prog: &ProgramView,
    options: &InterpretOptions,
) -> Result<Interpretation, Diagnostics> {
    let control = prescan(prog)?;
    let fanuc = match options.dialect {
        Dialect::Fanuc => true,
        Dialect::LinuxCnc => false,
        Dialect::Auto => detect_fanuc(prog),
    };
    let mut it = Interp {
        prog,
        opts: options,
        fanuc,
        corners_without_comma: options.fanuc_corners_without_comma,
        metric: true,
        absolute: true,
        arc_absolute: false,
        feed_mode: FeedMode::PerMin,
        plane: Plane::XY,
        motion: None,
        motion_prev: None,
        // LinuxCNC starts in G99 (rs274 retracts to R); a Fanuc control powers up in G98.
        retract_r_plane: !fanuc,
        cs: 0,
        cur: [0.0; 6],
        g5x: [[0.0; 6]; 9],
        g92: [0.0; 6],
        g92_applied: true,
        g28: [0.0; 6],
        g30: [0.0; 6],
        tlo: None,
        feed_word: 0.0,
        feed_factor: 1.0,
        speed: 0.0,
        spindle: SpindleDir::Off,
        tool: 0,
        selected_tool: None,
        selected_tools: Vec::new(),
        cycle_r: 0.0,
        cycle_cc: 0.0,
        cycle_p: 0.0,
        cycle_q: 0.0,
        cycle_i: 0.0,
        cycle_j: 0.0,
        cycle_k: 0.0,
        cycle_il: None,
        params: Params::new(),
        frames: Vec::new(),
        repeat_counts: HashMap::new(),
        // Most programs make about one move per block.
        moves: Vec::with_capacity(prog.len().min(options.max_moves)),
        warnings: Vec::new(),
        pending_corner: None,
        saved_modal: None,
        ended: false,
        cur_block: 0,
        cur_line: 1,
        warned_tools: Default::default(),
        spare_gs: Vec::new(),
        spare_ms: Vec::new(),
    };
    match it.run(&control) {
        Ok(()) => Ok(Interpretation {
            moves: it.moves,
            warnings: it.warnings,
            block_count: prog.len(),
            selected_tools: it.selected_tools,
        }),
        Err(d) => Err(Diagnostics(vec![d])),
    }
}

/// Fanuc-only syntax, and no LinuxCNC-only syntax.
fn detect_fanuc(prog: &ProgramView) -> bool {
    let summary = prog.summary();
    summary.fanuc_syntax && !summary.linuxcnc_syntax
}

/// Read-only view used while evaluating expressions.
struct EnvView<'a> {
    it: &'a Interp<'a>,
}

impl Env for EnvView<'_> {
    fn numbered(&self, n: usize) -> Result<f64, String> {
        Ok(self.it.read_numbered(n))
    }
    fn named(&self, name: &str) -> Result<f64, String> {
        if let Some(v) = self.it.read_special(name) {
            return Ok(v);
        }
        self.it
            .params
            .get_named(name)
            .ok_or_else(|| format!("named parameter #<{name}> is not defined"))
    }
    fn exists(&self, name: &str) -> bool {
        self.it.read_special(name).is_some() || self.it.params.get_named(name).is_some()
    }
}

impl<'p> Interp<'p> {
    fn unit(&self) -> f64 {
        if self.metric {
            1.0
        } else {
            MM_PER_INCH
        }
    }

    fn err_at(&self, byte: usize, msg: impl Into<String>) -> Diagnostic {
        self.prog.diag(byte, msg)
    }

    /// Error at the start of the current block.
    fn err_block(&self, msg: impl Into<String>) -> Diagnostic {
        let b = self.prog.block(self.cur_block);
        self.prog.diag(b.span.start, msg)
    }

    fn word_pos(&self, idx: usize) -> usize {
        self.prog.block(self.cur_block).words[idx].span.start
    }

    fn err_word(&self, w: &Words, letter: char, msg: impl Into<String>) -> Diagnostic {
        match w.vals[letter_index(letter)] {
            Some((_, i)) => self.err_at(self.word_pos(i), msg),
            None => self.err_block(msg),
        }
    }

    // ----- parameters -----

    fn offset_param(&self, v: f64, linear: bool) -> f64 {
        if linear {
            v / self.unit()
        } else {
            v
        }
    }

    /// Numbered parameters; the 5xxx system parameters reflect the live state.
    fn read_numbered(&self, n: usize) -> f64 {
        let axis = |base: usize| -> Option<usize> {
            if n > base && n <= base + 6 {
                Some(n - base - 1)
            } else {
                None
            }
        };
        if let Some(i) = axis(5160) {
            return self.offset_param(self.g28[i], i < 3);
        }
        if let Some(i) = axis(5180) {
            return self.offset_param(self.g30[i], i < 3);
        }
        if n == 5210 {
            return if self.g92_applied && self.g92.iter().any(|&v| v != 0.0) {
                1.0
            } else {
                0.0
            };
        }
        if let Some(i) = axis(5210) {
            return self.offset_param(self.g92[i], i < 3);
        }
        if n == 5220 {
            return (self.cs + 1) as f64;
        }
        if (5221..=5400).contains(&n) {
            let k = (n - 5221) / 20;
            let i = (n - 5221) % 20;
            if k < 9 && i < 6 {
                return self.offset_param(self.g5x[k][i], i < 3);
            }
        }
        if n == 5400 {
            return self.tool as f64;
        }
        if n == 5403 {
            return self.tlo.unwrap_or(0.0) / self.unit();
        }
        if let Some(i) = axis(5420) {
            return self.cur[i];
        }
        self.params.numbered[n]
    }

    fn read_special(&self, name: &str) -> Option<f64> {
        let b = |c: bool| if c { 1.0 } else { 0.0 };
        Some(match name {
            "_x" => self.cur[0],
            "_y" => self.cur[1],
            "_z" => self.cur[2],
            "_a" => self.cur[3],
            "_b" => self.cur[4],
            "_c" => self.cur[5],
            "_metric" => b(self.metric),
            "_imperial" => b(!self.metric),
            "_absolute" => b(self.absolute),
            "_incremental" => b(!self.absolute),
            "_inverse_time" => b(self.feed_mode == FeedMode::InverseTime),
            "_units_per_minute" => b(self.feed_mode == FeedMode::PerMin),
            "_units_per_rev" => b(self.feed_mode == FeedMode::PerRev),
            "_feed" => self.feed_word,
            "_rpm" => self.speed,
            "_current_tool" => self.tool as f64,
            "_selected_tool" => self.selected_tool.map(|t| t as f64).unwrap_or(-1.0),
            "_coord_system" => [
                540.0, 550.0, 560.0, 570.0, 580.0, 590.0, 591.0, 592.0, 593.0,
            ][self.cs],
            "_line" => self.cur_line as f64,
            "_spindle_on" => b(self.spindle != SpindleDir::Off),
            "_spindle_cw_dir" => b(self.spindle == SpindleDir::Cw),
            "_retract_r_plane" => b(self.retract_r_plane),
            "_retract_old_z" => b(!self.retract_r_plane),
            "_plane" => match self.plane {
                Plane::XY => 170.0,
                Plane::XZ => 180.0,
                Plane::YZ => 190.0,
            },
            "_motion_mode" => match self.motion {
                None => 800.0,
                Some(Motion::Rapid) => 0.0,
                Some(Motion::Linear) => 10.0,
                Some(Motion::Arc { cw: true }) => 20.0,
                Some(Motion::Arc { cw: false }) => 30.0,
                Some(Motion::RigidTap) => 331.0,
                Some(Motion::Cycle(g)) => g as f64 * 10.0,
            },
            _ => return None,
        })
    }

    fn eval(&self, e: &Expr, pos: usize) -> R<f64> {
        let env = EnvView { it: self };
        expr::eval(e, &env).map_err(|m| self.err_at(pos, m))
    }

    fn assign(&mut self, a: &Assignment, v: f64) -> R<()> {
        match &a.target {
            ParamRef::Named(n) => {
                if self.read_special(n).is_some() {
                    return Err(self.err_at(a.span.start, format!("#<{n}> is read-only")));
                }
                self.params.set_named(n, v);
            }
            ParamRef::Numbered(e) => {
                let env = EnvView { it: self };
                let n = expr::resolve_index(e, &env).map_err(|m| self.err_at(a.span.start, m))?;
                if (5161..=5166).contains(&n)
                    || (5181..=5186).contains(&n)
                    || (5210..=5400).contains(&n)
                    || n == 5403
                    || (5421..=5426).contains(&n)
                {
                    return Err(self.err_at(
                        a.span.start,
                        format!("parameter #{n} holds machine state (offsets, home positions, tool) and cannot be assigned here; use G10/G92/G28.1"),
                    ));
                }
                self.params.numbered[n] = v;
            }
        }
        Ok(())
    }

    // ----- frames -----

    fn g92_eff(&self) -> [f64; 6] {
        if self.g92_applied {
            self.g92
        } else {
            [0.0; 6]
        }
    }

    /// Program coordinates -> machine frame, mm/deg.
    fn to_machine(&self, p: [f64; 6]) -> [f64; 6] {
        let u = self.unit();
        let g92 = self.g92_eff();
        let mut m = [0.0; 6];
        for i in 0..6 {
            let s = if i < 3 { u } else { 1.0 };
            m[i] = p[i] * s + self.g5x[self.cs][i] + g92[i];
        }
        m
    }

    fn from_machine(&self, m: [f64; 6]) -> [f64; 6] {
        let u = self.unit();
        let g92 = self.g92_eff();
        let mut p = [0.0; 6];
        for i in 0..6 {
            let s = if i < 3 { u } else { 1.0 };
            p[i] = (m[i] - self.g5x[self.cs][i] - g92[i]) / s;
        }
        p
    }

    /// Change offsets keeping the tool where it physically is.
    fn change_offsets(&mut self, f: impl FnOnce(&mut Self)) {
        let phys = self.to_machine(self.cur);
        f(self);
        self.cur = self.from_machine(phys);
    }

    // ----- moves -----

    fn out_feed(&self) -> f64 {
        match self.feed_mode {
            FeedMode::InverseTime => self.feed_word,
            _ => self.feed_word * self.feed_factor,
        }
    }

    fn base_move(&self, kind: MoveKind, start: [f64; 6], end: [f64; 6]) -> Move {
        Move {
            block: self.cur_block,
            line: self.cur_line,
            kind,
            end,
            feed: self.out_feed(),
            feed_mode: self.feed_mode,
            spindle: self.speed,
            tool: self.tool,
            center: None,
            normal: None,
            clockwise: None,
            tool_length: self.tlo,
            seconds: None,
            tool_axis: None,
            start,
            spindle_dir: self.spindle,
            arc: None,
        }
    }

    fn push(&mut self, m: Move) -> R<()> {
        if self.moves.len() >= self.opts.max_moves {
            return Err(self.err_block(format!(
                "program makes more than {} moves (runaway loop?); interpretation stopped",
                self.opts.max_moves
            )));
        }
        self.moves.push(m);
        Ok(())
    }

    /// Straight move to `to` (program coordinates).
    fn straight(&mut self, rapid: bool, to: [f64; 6]) -> R<()> {
        if !rapid {
            self.check_feed()?;
        }
        let start = self.to_machine(self.cur);
        let end = self.to_machine(to);
        let kind = if rapid {
            MoveKind::Rapid
        } else {
            MoveKind::Linear
        };
        let m = self.base_move(kind, start, end);
        self.push(m)?;
        self.cur = to;
        Ok(())
    }

    fn check_feed(&self) -> R<()> {
        if self.feed_word <= 0.0 {
            return Err(self.err_block(match self.feed_mode {
                FeedMode::InverseTime => {
                    "feed move in inverse time mode (G93) without an F word".to_string()
                }
                _ => "feed move with zero feed rate (no F word yet)".to_string(),
            }));
        }
        if self.feed_mode == FeedMode::PerRev && self.speed <= 0.0 {
            return Err(self.err_block("feed per revolution (G95) with zero spindle speed"));
        }
        Ok(())
    }

    fn dwell(&mut self, seconds: f64) -> R<()> {
        let p = self.to_machine(self.cur);
        let mut m = self.base_move(MoveKind::Dwell, p, p);
        m.seconds = Some(seconds);
        self.push(m)
    }

    // ----- main loop -----

    fn run(&mut self, control: &ControlMap) -> R<()> {
        let prog = self.prog;
        let mut pc = 0usize;
        let mut steps = 0usize;
        while pc < prog.len() && !self.ended {
            steps += 1;
            let b = prog.block(pc);
            self.cur_block = pc;
            self.cur_line = b.line;
            if steps.is_multiple_of(CANCEL_CHECK_BLOCKS)
                && self.opts.cancel.as_ref().is_some_and(|c| c.is_cancelled())
            {
                return Err(self.err_block("interpretation cancelled"));
            }
            if steps > self.opts.max_blocks {
                return Err(self.err_block(format!(
                    "program executed more than {} blocks (endless loop?); interpretation stopped",
                    self.opts.max_blocks
                )));
            }
            if b.after_end {
                break;
            }
            if b.block_delete && self.opts.block_delete {
                pc += 1;
                continue;
            }
            if let Some(o) = &b.o_word {
                pc = self.exec_oword(control, pc, o)?;
                continue;
            }
            if !b.is_empty() {
                self.exec_block(pc, &b)?;
            }
            pc += 1;
        }
        if let Some(pc) = &self.pending_corner {
            return Err(self.err_at(
                pc.word_pos,
                "corner rounding/chamfer at the end of the program: it needs a following G1 move",
            ));
        }
        Ok(())
    }

    fn cond(&self, o: &OWord) -> R<f64> {
        match o.args.first() {
            Some(e) => self.eval(e, o.span.start),
            None => Err(self.err_at(o.span.start, "missing [condition]")),
        }
    }

    fn exec_oword(&mut self, control: &ControlMap, pc: usize, o: &OWord) -> R<usize> {
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
        let depth = self.frames.len();
        Ok(match link {
            Link::ProgramNumber => {
                if !self.fanuc {
                    return Err(self.err_at(
                        o.span.start,
                        format!("{} without a keyword is a Fanuc program number; not valid with dialect linuxcnc", o.name),
                    ));
                }
                pc + 1
            }
            Link::Sub { end } => end + 1,
            Link::EndSub | Link::Return => {
                let value = match o.args.first() {
                    Some(e) => Some(self.eval(e, o.span.start)?),
                    None => None,
                };
                let Some(frame) = self.frames.pop() else {
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
                self.repeat_counts.retain(|k, _| k.0 <= self.frames.len());
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
                frame.return_pc + 1
            }
            Link::Call => {
                let Some(&start) = control.subs.get(&o.name) else {
                    return Err(self.err_at(
                        o.span.start,
                        format!("subroutine {} is not defined in this program (external subroutine files are not supported)", o.name),
                    ));
                };
                if self.frames.len() >= MAX_CALL_DEPTH {
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
                self.frames.push(Frame {
                    return_pc: pc,
                    saved,
                    sub: o.name.clone(),
                    auto_restore: None,
                });
                self.params.globals.insert("_value_returned".into(), 0.0);
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
                    self.repeat_counts.insert((depth, pc), n.round());
                    pc + 1
                } else {
                    end + 1
                }
            }
            Link::EndRepeat { start } => {
                let left = self
                    .repeat_counts
                    .get(&(depth, start))
                    .copied()
                    .unwrap_or(1.0)
                    - 1.0;
                if left >= 1.0 {
                    self.repeat_counts.insert((depth, start), left);
                    start + 1
                } else {
                    self.repeat_counts.remove(&(depth, start));
                    pc + 1
                }
            }
            Link::Break { start, end } => {
                self.repeat_counts.remove(&(depth, start));
                end + 1
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

    // ----- one block -----

    /// Evaluate the block's words into `w` (filled in place: it is large to move around).
    fn read_words(&mut self, b: &BlockView<'p>, w: &mut Words) -> R<Vec<f64>> {
        let implied = self.opts.fanuc_implied_decimal;
        for (i, word) in b.words.iter().enumerate() {
            let mut v = match word.value {
                // Most words are plain numbers: skip the expression evaluator.
                Expr::Number { value, .. } if value.is_finite() => value,
                ref e => self.eval(e, word.value_span.start)?,
            };
            let c = word.letter;
            if implied
                && matches!(
                    c,
                    'X' | 'Y'
                        | 'Z'
                        | 'A'
                        | 'B'
                        | 'C'
                        | 'I'
                        | 'J'
                        | 'K'
                        | 'R'
                        | 'Q'
                        | 'U'
                        | 'V'
                        | 'W'
                )
            {
                if let Expr::Number {
                    has_point: false, ..
                } = strip_neg(&word.value)
                {
                    let inc = if matches!(c, 'A' | 'B' | 'C') || self.metric {
                        1000.0
                    } else {
                        10000.0
                    };
                    v /= inc;
                }
            }
            let pos = word.span.start;
            if word.comma {
                if !self.fanuc {
                    return Err(self.err_at(
                        pos,
                        format!(",{c} is Fanuc corner syntax; not valid with dialect linuxcnc"),
                    ));
                }
                let slot = if c == 'R' {
                    &mut w.corner_r
                } else {
                    &mut w.corner_c
                };
                if slot.is_some() {
                    return Err(self.err_at(pos, format!("two ,{c} words in one block")));
                }
                *slot = Some((v, i));
                continue;
            }
            match c {
                'G' => {
                    let code = (v * 10.0).round();
                    if (v * 10.0 - code).abs() > 1e-6 || !(0.0..=9999.0).contains(&code) {
                        return Err(self.err_at(pos, format!("G{v} is not a G code")));
                    }
                    let code = code as u16;
                    let Some(group) = g_group(code) else {
                        return Err(
                            self.err_at(pos, format!("{} {}", g_name(code), g_refusal(code)))
                        );
                    };
                    // G80 beside another motion code just cancels the cycle first (Fanuc
                    // programs write `G00 ... G80`; LinuxCNC accepts it too).
                    if let Some(&(other, _)) = w.gs.iter().find(|g| {
                        g_group(g.0) == Some(group) && !(group == 1 && (g.0 == 800 || code == 800))
                    }) {
                        return Err(self.err_at(
                            pos,
                            format!(
                                "{} and {} are in the same modal group; only one per block",
                                g_name(other),
                                g_name(code)
                            ),
                        ));
                    }
                    w.gs.push((code, i));
                }
                'M' => {
                    if v.fract() != 0.0 || !(0.0..=99999.0).contains(&v) {
                        return Err(self.err_at(pos, format!("M{v} is not an M code")));
                    }
                    let code = v as u32;
                    // Passthrough codes each get a group of their own, above every real one
                    // (u32: M codes run into the thousands).
                    let group = match m_group(code) {
                        Some(g) => u32::from(g),
                        None if self.opts.passthrough_m_codes.contains(&code) => 1000 + code,
                        None => {
                            let why = match code {
                                98 | 99 => "Fanuc subprogram calls (M98/M99) are not supported".to_string(),
                                100..=199 => "user M codes run external programs; list it in passthrough_m_codes if it does not move the machine".to_string(),
                                62..=68 => "digital/analog output codes are not supported".to_string(),
                                _ => "is not supported (list it in passthrough_m_codes if it does not move the machine)".to_string(),
                            };
                            return Err(self.err_at(pos, format!("M{code}: {why}")));
                        }
                    };
                    if let Some(&(other, _)) = w.ms.iter().find(|m| {
                        let og = m_group(m.0).map(u32::from).unwrap_or(1000 + m.0);
                        og == group
                            && !(group == 8
                                && (m.0 == 7 || m.0 == 8)
                                && (code == 7 || code == 8)
                                && m.0 != code)
                    }) {
                        return Err(self.err_at(pos, format!("M{other} and M{code} are in the same modal group; only one per block")));
                    }
                    if w.ms.len() >= 4 {
                        return Err(self.err_at(pos, "more than four M words in one block"));
                    }
                    w.ms.push((code, i));
                }
                'N' | 'O' => {
                    return Err(self.err_at(pos, format!("{c} word in the middle of a block")))
                }
                'U' | 'V' | 'W' => {
                    return Err(self.err_at(
                        pos,
                        format!("{c} axis is not supported (axes are X Y Z A B C)"),
                    ))
                }
                'E' => return Err(self.err_at(pos, "E word is not supported")),
                _ => {
                    let li = letter_index(c);
                    if w.vals[li].is_some() {
                        return Err(self.err_at(pos, format!("two {c} words in one block")));
                    }
                    w.vals[li] = Some((v, i));
                }
            }
        }
        // Parameter assignments are evaluated with the values from before the block and take
        // effect after all of the block's words are read (LinuxCNC rule).
        let mut vals = Vec::with_capacity(b.assignments.len());
        for a in b.assignments {
            vals.push(self.eval(&a.value, a.span.start)?);
        }
        Ok(vals)
    }

    fn exec_block(&mut self, idx: usize, b: &BlockView<'p>) -> R<()> {
        // The G and M lists keep their allocations from block to block.
        let mut w = Words {
            vals: [None; 26],
            used: [false; 26],
            gs: std::mem::take(&mut self.spare_gs),
            ms: std::mem::take(&mut self.spare_ms),
            corner_r: None,
            corner_c: None,
        };
        w.gs.clear();
        w.ms.clear();
        let result = self.exec_words(idx, b, &mut w);
        self.spare_gs = w.gs;
        self.spare_ms = w.ms;
        result
    }

    fn exec_words(&mut self, idx: usize, b: &BlockView<'p>, w: &mut Words) -> R<()> {
        self.motion_prev = self.motion;
        let avals = self.read_words(b, w)?;
        for (a, v) in b.assignments.iter().zip(avals) {
            self.assign(a, v)?;
        }
        // Fanuc comma-less corners: R and C on a G1 block (CCR parameter).
        if self.fanuc && self.corners_without_comma {
            let g1 = w.g(10).is_some()
                || (self.motion == Some(Motion::Linear)
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
        }
        if w.corner_r.is_some() && w.corner_c.is_some() {
            let (_, i) = w.corner_c.expect("checked");
            return Err(self.err_at(
                self.word_pos(i),
                "corner rounding and chamfer in the same block",
            ));
        }

        // 3. feed mode
        for (code, mode) in [
            (930, FeedMode::InverseTime),
            (940, FeedMode::PerMin),
            (950, FeedMode::PerRev),
        ] {
            if w.g(code).is_some() {
                if self.feed_mode != mode
                    && (mode == FeedMode::InverseTime || self.feed_mode == FeedMode::InverseTime)
                {
                    // LinuxCNC: entering or leaving G93 forgets the feed, so an inverse-time F
                    // is never taken as a feed per minute (or the reverse).
                    self.feed_word = 0.0;
                }
                self.feed_mode = mode;
            }
        }
        // 4. F
        if let Some(f) = w.take('F') {
            if f < 0.0 {
                return Err(self.err_word(w, 'F', "negative F word"));
            }
            self.feed_word = f;
            self.feed_factor = self.unit();
        } else if self.feed_mode == FeedMode::InverseTime {
            // Inverse time: F applies to its own block only.
            self.feed_word = 0.0;
        }
        // 5. S
        if let Some(s) = w.take('S') {
            if s < 0.0 {
                return Err(self.err_word(w, 'S', "negative S word"));
            }
            self.speed = s;
        }
        // 6. T
        if let Some(t) = w.take('T') {
            if t < 0.0 || t.fract() != 0.0 || t > u32::MAX as f64 {
                return Err(self.err_word(w, 'T', format!("T{t} is not a tool number")));
            }
            self.selected_tool = Some(t as u32);
            if !self.selected_tools.iter().any(|&(n, _)| n == t as u32) {
                self.selected_tools.push((t as u32, self.cur_line));
            }
        }
        // 8-10 act on M codes only; most CAM blocks have none.
        if !w.ms.is_empty() {
            // 8. M6 / M61
            if w.m(6).is_some() {
                let t = self.selected_tool.unwrap_or(self.tool);
                self.tool = t;
                let p = self.to_machine(self.cur);
                let m = self.base_move(MoveKind::ToolChange, p, p);
                self.push(m)?;
            }
            if let Some(i) = w.m(61) {
                let Some(q) = w.take('Q') else {
                    return Err(self.err_at(self.word_pos(i), "M61 needs a Q word (tool number)"));
                };
                if q < 0.0 || q.fract() != 0.0 || q > u32::MAX as f64 {
                    return Err(self.err_word(w, 'Q', format!("Q{q} is not a tool number")));
                }
                self.tool = q as u32;
            }
            // 9. spindle
            if w.m(3).is_some() {
                self.spindle = SpindleDir::Cw;
            }
            if w.m(4).is_some() {
                self.spindle = SpindleDir::Ccw;
            }
            if w.m(5).is_some() {
                self.spindle = SpindleDir::Off;
            }
            // 10. save / restore modal state
            if w.m(70).is_some() {
                self.saved_modal = Some(self.modal());
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
                let m = self.modal();
                let Some(f) = self.frames.last_mut() else {
                    return Err(self.err_at(self.word_pos(i), "M73 outside a subroutine"));
                };
                f.auto_restore = Some(m);
            }
        }
        // 11-13. coolant, overrides, passthrough M codes: no effect on motion.
        // 14-22 act on G codes only; most CAM blocks have none.
        if !w.gs.is_empty() {
            // 14. dwell
            if let Some(i) = w.g(40) {
                let secs = if self.fanuc {
                    match (w.take('P'), w.take('X')) {
                        (Some(_), Some(_)) => {
                            return Err(self.err_at(self.word_pos(i), "G4 with both P and X"))
                        }
                        (Some(p), None) => p / 1000.0,
                        (None, Some(x)) => x,
                        (None, None) => {
                            return Err(self.err_at(self.word_pos(i), "G4 needs P (ms) or X (s)"))
                        }
                    }
                } else {
                    match w.take('P') {
                        Some(p) => p,
                        None => {
                            return Err(self.err_at(self.word_pos(i), "G4 needs a P word (seconds)"))
                        }
                    }
                };
                if secs < 0.0 {
                    return Err(self.err_at(self.word_pos(i), "negative dwell time"));
                }
                self.dwell(secs)?;
            }
            // 15. plane
            for (code, plane) in [(170, Plane::XY), (180, Plane::XZ), (190, Plane::YZ)] {
                if w.g(code).is_some() {
                    self.plane = plane;
                }
            }
            // 16. units
            for (code, metric) in [(200, false), (210, true)] {
                if w.g(code).is_some() && self.metric != metric {
                    let f = if metric {
                        MM_PER_INCH
                    } else {
                        1.0 / MM_PER_INCH
                    };
                    for i in 0..3 {
                        self.cur[i] *= f;
                    }
                    self.metric = metric;
                }
            }
            // 17. cutter radius compensation: refused.
            for code in [410u16, 420, 411, 421] {
                if let Some(i) = w.g(code) {
                    return Err(self.err_at(
                        self.word_pos(i),
                        format!("{}: cutter radius compensation is not supported; program the tool centre path (CAM 'computer' compensation) or remove {}", g_name(code), g_name(code)),
                    ));
                }
            }
            // 18. tool length offset
            if let Some(i) = w.g(430) {
                let h = match w.take('H') {
                    Some(h) => {
                        if h < 0.0 || h.fract() != 0.0 || h > u32::MAX as f64 {
                            return Err(self.err_word(
                                w,
                                'H',
                                format!("H{h} is not a tool number"),
                            ));
                        }
                        h as u32
                    }
                    None => self.tool,
                };
                let off = match self.opts.tool_table.get(h) {
                    Some(t) => t.z_offset,
                    None => {
                        if self.warned_tools.insert(h) {
                            self.warnings.push(self.err_at(
                                self.word_pos(i),
                                format!(
                                    "G43: tool {h} is not in the tool table; tool length 0 used"
                                ),
                            ));
                        }
                        0.0
                    }
                };
                self.set_tlo(Some(off));
            }
            if w.g(431).is_some() {
                // G43.1: the offset comes from the Z word (program units).
                let Some(z) = w.take('Z') else {
                    return Err(self.err_block("G43.1 needs a Z word (tool length)"));
                };
                if AXES.iter().any(|&c| c != 'Z' && w.has(c)) {
                    return Err(self.err_block("G43.1 takes only a Z offset here"));
                }
                let z = z * self.unit();
                self.set_tlo(Some(z));
            }
            if w.g(490).is_some() {
                self.set_tlo(None);
            }
            // 19. coordinate system
            for (k, code) in [540u16, 550, 560, 570, 580, 590, 591, 592, 593]
                .iter()
                .enumerate()
            {
                if w.g(*code).is_some() {
                    self.change_offsets(|s| s.cs = k);
                }
            }
            // 20. path control: blending changes no end point.
            if w.g(640).is_some() {
                w.take('P');
                w.take('Q');
            }
            // 21. distance modes
            if w.g(900).is_some() {
                self.absolute = true;
            }
            if w.g(910).is_some() {
                self.absolute = false;
            }
            if w.g(901).is_some() {
                self.arc_absolute = true;
            }
            if w.g(911).is_some() {
                self.arc_absolute = false;
            }
            // 22. retract mode
            if w.g(980).is_some() {
                self.retract_r_plane = false;
            }
            if w.g(990).is_some() {
                self.retract_r_plane = true;
            }
        }
        // 23. group 0 codes that use axis words, and 24. motion.
        let group0 =
            w.gs.iter()
                .find(|g| g_group(g.0) == Some(0) && g.0 != 40 && g.0 != 530)
                .copied();
        if w.g(800).is_some() {
            self.motion = None;
            self.cycle_il = None;
        }
        let block_motion =
            w.gs.iter()
                .find(|g| g_group(g.0) == Some(1) && g.0 != 800)
                .or_else(|| w.gs.iter().find(|g| g.0 == 800))
                .copied();
        let g53 = w.g(530);
        if let (Some((g0, i0)), Some((gm, _))) = (group0, block_motion) {
            if matches!(g0, 100 | 280 | 300 | 920) && gm != 800 && w.has_axis() {
                return Err(self.err_at(
                    self.word_pos(i0),
                    format!("{} and {} both use axis words", g_name(g0), g_name(gm)),
                ));
            }
        }
        if let Some((g0, i0)) = group0 {
            self.exec_group0(w, g0, i0)?;
        }
        if let Some((gm, _)) = block_motion {
            self.motion = match gm {
                0 => Some(Motion::Rapid),
                10 => Some(Motion::Linear),
                20 => Some(Motion::Arc { cw: true }),
                30 => Some(Motion::Arc { cw: false }),
                331 => Some(Motion::RigidTap),
                800 => None,
                g => Some(Motion::Cycle(g / 10)),
            };
            if gm == 800 {
                self.cycle_il = None;
                if w.has_axis() && !matches!(group0, Some((100 | 280 | 300 | 920, _))) {
                    return Err(self.err_block("axis words with G80 (motion cancelled)"));
                }
            }
        }
        let axis_users = matches!(group0, Some((100 | 280 | 300 | 920, _)));
        let corner = w
            .corner_r
            .or(w.corner_c)
            .map(|(v, i)| (v, i, w.corner_c.is_some()));
        if w.has_axis() && !axis_users {
            let Some(motion) = self.motion else {
                return Err(self.err_block(
                    "axis words but no motion mode (G80 is active); give G0/G1/G2/G3 or a cycle",
                ));
            };
            if let Some(i) = g53 {
                if !matches!(motion, Motion::Rapid | Motion::Linear) {
                    return Err(self.err_at(self.word_pos(i), "G53 needs G0 or G1"));
                }
            }
            self.exec_motion(w, motion, g53.is_some(), corner)?;
        } else if matches!(block_motion, Some((0 | 10 | 20 | 30, _)))
            && !axis_users
            && corner.is_none()
        {
            // LinuxCNC: an explicit G0/G1 without axis words still makes a (zero-length) move,
            // and G2/G3 with only a centre makes a full circle.
            let motion = self.motion.expect("set above");
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
        if self
            .pending_corner
            .as_ref()
            .map(|p| p.block != idx)
            .unwrap_or(false)
            && w.has_axis()
        {
            // exec_motion resolved it or failed; anything left is an error below.
        }
        // 25. stops
        if w.m(2).is_some() || w.m(30).is_some() {
            self.ended = true;
        }
        if w.m(60).is_some() {
            return Err(self.err_block("M60 pallet change is not supported"));
        }
        // Every word must have been used by something.
        for li in 0..26 {
            if let Some((v, i)) = w.vals[li] {
                if !w.used[li] {
                    let c = (b'A' + li as u8) as char;
                    let hint = if c == 'R' && self.motion == Some(Motion::Linear) {
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

    fn modal(&self) -> Modal {
        Modal {
            metric: self.metric,
            absolute: self.absolute,
            arc_absolute: self.arc_absolute,
            feed_mode: self.feed_mode,
            plane: self.plane,
            retract_r_plane: self.retract_r_plane,
            cs: self.cs,
            feed_word: self.feed_word,
            feed_factor: self.feed_factor,
            speed: self.speed,
            spindle: self.spindle,
        }
    }

    fn restore_modal(&mut self, m: &Modal) {
        if self.metric != m.metric {
            let f = if m.metric {
                MM_PER_INCH
            } else {
                1.0 / MM_PER_INCH
            };
            for i in 0..3 {
                self.cur[i] *= f;
            }
            self.metric = m.metric;
        }
        if self.cs != m.cs {
            self.change_offsets(|s| s.cs = m.cs);
        }
        self.absolute = m.absolute;
        self.arc_absolute = m.arc_absolute;
        self.feed_mode = m.feed_mode;
        self.plane = m.plane;
        self.retract_r_plane = m.retract_r_plane;
        self.feed_word = m.feed_word;
        self.feed_factor = m.feed_factor;
        self.speed = m.speed;
        self.spindle = m.spindle;
    }

    fn set_tlo(&mut self, tlo: Option<f64>) {
        // The spindle does not move; the controlled point (tool tip) is now elsewhere.
        let old = self.tlo.unwrap_or(0.0);
        let new = tlo.unwrap_or(0.0);
        self.cur[2] += (old - new) / self.unit();
        self.tlo = tlo;
    }

    fn exec_group0(&mut self, w: &mut Words, g: u16, i: usize) -> R<()> {
        let u = self.unit();
        match g {
            100 => {
                let l = w
                    .take('L')
                    .ok_or_else(|| self.err_at(self.word_pos(i), "G10 needs an L word"))?;
                let p = w
                    .take('P')
                    .ok_or_else(|| self.err_at(self.word_pos(i), "G10 needs a P word"))?;
                if l != 2.0 && l != 20.0 {
                    return Err(self.err_at(
                        self.word_pos(i),
                        format!("G10 L{l} is not supported (only L2 and L20 work offsets)"),
                    ));
                }
                if w.has('R') {
                    return Err(self.err_word(
                        w,
                        'R',
                        "G10 coordinate system rotation (R) is not supported",
                    ));
                }
                if p.fract() != 0.0 || !(0.0..=9.0).contains(&p) {
                    return Err(self.err_word(
                        w,
                        'P',
                        format!("G10 P{p}: coordinate system must be 0..9"),
                    ));
                }
                let k = if p == 0.0 { self.cs } else { p as usize - 1 };
                let phys = self.to_machine(self.cur);
                let g92 = self.g92_eff();
                let mut new = self.g5x[k];
                for (ai, &c) in AXES.iter().enumerate() {
                    if let Some(v) = w.take(c) {
                        let s = if ai < 3 { u } else { 1.0 };
                        new[ai] = if l == 2.0 {
                            v * s
                        } else {
                            phys[ai] - g92[ai] - v * s
                        };
                    }
                }
                self.change_offsets(|st| st.g5x[k] = new);
            }
            280 | 300 => {
                let home = if g == 280 { self.g28 } else { self.g30 };
                if w.has_axis() {
                    let mut mid = self.cur;
                    let mut which = [false; 6];
                    for (ai, &c) in AXES.iter().enumerate() {
                        if let Some(v) = w.take(c) {
                            mid[ai] = if self.absolute { v } else { self.cur[ai] + v };
                            which[ai] = true;
                        }
                    }
                    self.straight(true, mid)?;
                    let hp = self.from_machine(home);
                    let mut end = self.cur;
                    for ai in 0..6 {
                        if which[ai] {
                            end[ai] = hp[ai];
                        }
                    }
                    self.straight(true, end)?;
                } else {
                    // LinuxCNC still makes the (zero-length) move to the intermediate point.
                    self.straight(true, self.cur)?;
                    let hp = self.from_machine(home);
                    self.straight(true, hp)?;
                }
            }
            281 | 301 => {
                let m = self.to_machine(self.cur);
                if g == 281 {
                    self.g28 = m;
                } else {
                    self.g30 = m;
                }
            }
            920 => {
                if !w.has_axis() {
                    return Err(self.err_at(self.word_pos(i), "G92 needs at least one axis word"));
                }
                let phys = self.to_machine(self.cur);
                let mut new = self.g92_eff();
                for (ai, &c) in AXES.iter().enumerate() {
                    if let Some(v) = w.take(c) {
                        let s = if ai < 3 { u } else { 1.0 };
                        new[ai] = phys[ai] - self.g5x[self.cs][ai] - v * s;
                    }
                }
                self.change_offsets(|st| {
                    st.g92 = new;
                    st.g92_applied = true;
                });
            }
            921 => self.change_offsets(|st| {
                st.g92 = [0.0; 6];
                st.g92_applied = true;
            }),
            922 => self.change_offsets(|st| st.g92_applied = false),
            923 => self.change_offsets(|st| st.g92_applied = true),
            _ => {}
        }
        Ok(())
    }

    /// Target of a straight or arc move in program coordinates.
    fn target(&self, w: &mut Words, g53: bool) -> R<[f64; 6]> {
        let mut t = self.cur;
        if g53 && !self.absolute {
            return Err(self.err_block("G53 in incremental mode (G91)"));
        }
        for (ai, &c) in AXES.iter().enumerate() {
            if let Some(v) = w.take(c) {
                t[ai] = if g53 {
                    let s = if ai < 3 { self.unit() } else { 1.0 };
                    (v * s - self.g5x[self.cs][ai] - self.g92_eff()[ai]) / s
                } else if self.absolute {
                    v
                } else {
                    self.cur[ai] + v
                };
            }
        }
        Ok(t)
    }

    fn exec_motion(
        &mut self,
        w: &mut Words,
        motion: Motion,
        g53: bool,
        corner: Option<(f64, usize, bool)>,
    ) -> R<()> {
        if !matches!(motion, Motion::Cycle(_)) {
            self.cycle_il = None;
        }
        if self.feed_mode == FeedMode::InverseTime
            && matches!(motion, Motion::Linear | Motion::Arc { .. })
            && self.feed_word <= 0.0
        {
            return Err(self.err_block(
                "G1/G2/G3 in inverse time mode (G93) needs an F word in the same block",
            ));
        }
        let pending = self.pending_corner.take();
        if pending.is_some() && motion != Motion::Linear {
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
                        move_index: self.moves.len() - 1,
                        block: self.cur_block,
                        word_pos: self.word_pos(i),
                        chamfer,
                        size,
                        corner: to,
                        plane: self.plane,
                    });
                    return Ok(());
                }
                self.straight(motion == Motion::Rapid, to)
            }
            Motion::Arc { cw } => self.arc(w, cw),
            Motion::RigidTap => self.rigid_tap(w),
            Motion::Cycle(g) => self.cycle(w, g),
        }
    }

    fn arc(&mut self, w: &mut Words, cw: bool) -> R<()> {
        self.check_feed()?;
        let plane = self.plane;
        let [a, b, _n] = plane.axes();
        let bad = plane.forbidden_ijk();
        if w.has(bad) {
            return Err(self.err_word(w, bad, format!("{bad} word in a {} arc", plane.name())));
        }
        let start = self.cur;
        let end = self.target(w, false)?;
        let turns = match w.take('P') {
            Some(p) => {
                if p.fract() != 0.0 || p < 1.0 || p > MAX_ARC_TURNS {
                    return Err(self.err_word(
                        w,
                        'P',
                        format!("arc P{p}: turns must be a whole number 1..{MAX_ARC_TURNS}"),
                    ));
                }
                p as u32
            }
            None => 1,
        };
        let [li, lj] = plane.ijk();
        let has_ijk = w.has(li) || w.has(lj);
        let inch = !self.metric;
        let (cx, cy) = if let Some(r) = w.take('R') {
            if has_ijk {
                return Err(self.err_block("arc with both R and I/J/K"));
            }
            let (sx, sy, ex, ey) = (start[a], start[b], end[a], end[b]);
            if ex == sx && ey == sy {
                return Err(self.err_word(
                    w,
                    'R',
                    "R-format arc with the end point equal to the start point",
                ));
            }
            let tol = if inch { 0.00005 } else { 0.00005 * MM_PER_INCH };
            let abs_r = r.abs();
            let (mx, my) = ((ex + sx) / 2.0, (ey + sy) / 2.0);
            let mut half = (mx - ex).hypot(my - ey);
            if half - abs_r > tol {
                return Err(self.err_word(
                    w,
                    'R',
                    format!("arc radius {abs_r} too small to reach the end point"),
                ));
            }
            if half / abs_r > 1.0 - 1e-12 {
                half = abs_r;
            }
            let theta = if (cw && r > 0.0) || (!cw && r < 0.0) {
                (ey - sy).atan2(ex - sx) - std::f64::consts::FRAC_PI_2
            } else {
                (ey - sy).atan2(ex - sx) + std::f64::consts::FRAC_PI_2
            };
            let turn2 = (half / abs_r).asin();
            let off = abs_r * turn2.cos();
            (mx + off * theta.cos(), my + off * theta.sin())
        } else {
            if !has_ijk {
                return Err(self.err_block("arc needs I/J/K (centre) or R (radius)"));
            }
            let i = w.take(li).unwrap_or(0.0);
            let j = w.take(lj).unwrap_or(0.0);
            let c = if self.arc_absolute {
                (i, j)
            } else {
                (start[a] + i, start[b] + j)
            };
            let r1 = (c.0 - start[a]).hypot(c.1 - start[b]);
            let r2 = (c.0 - end[a]).hypot(c.1 - end[b]);
            let rtol = if inch { 0.00005 } else { 0.00005 * MM_PER_INCH };
            if r1 < rtol || r2 < rtol {
                return Err(self.err_block(format!("zero-radius arc (r1={r1:.4}, r2={r2:.4})")));
            }
            let abs_err = (r1 - r2).abs();
            let rel = abs_err / r1.max(r2);
            let atol = if inch {
                2.0 * 0.001 * std::f64::consts::SQRT_2
            } else {
                2.0 * 0.01 * std::f64::consts::SQRT_2
            };
            // LinuxCNC 2.9: a small spiral is accepted; large or relatively large ones are not.
            if abs_err > atol * 100.0 || (rel > 0.001 && abs_err > atol) {
                return Err(self.err_block(format!(
                    "radius to end of arc differs from radius to start: r1={r1:.4} r2={r2:.4} (difference {abs_err:.4})"
                )));
            }
            c
        };
        // Sweep: LinuxCNC counts turns CCW; equal start and end angles make a full circle.
        let a0 = (start[b] - cy).atan2(start[a] - cx);
        let a1 = (end[b] - cy).atan2(end[a] - cx);
        let tau = std::f64::consts::TAU;
        let same = (end[a] - start[a]).abs() < 1e-9 && (end[b] - start[b]).abs() < 1e-9;
        let mut sweep = if same { 0.0 } else { a1 - a0 };
        if cw {
            if sweep >= 0.0 {
                sweep -= tau;
            }
            sweep -= tau * (turns - 1) as f64;
        } else {
            if sweep <= 0.0 {
                sweep += tau;
            }
            sweep += tau * (turns - 1) as f64;
        }
        let ms = self.to_machine(start);
        let me = self.to_machine(end);
        let mut cprog = start;
        cprog[a] = cx;
        cprog[b] = cy;
        let mc = self.to_machine(cprog);
        let center = [mc[0], mc[1], mc[2]];
        let u = self.unit();
        let geom = ArcGeometry {
            start: ms,
            end: me,
            center,
            normal: plane.normal(),
            axes: plane.axes(),
            sweep,
            start_radius: (start[a] - cx).hypot(start[b] - cy) * u,
            end_radius: (end[a] - cx).hypot(end[b] - cy) * u,
            clockwise: cw,
            turns,
        };
        let mut m = self.base_move(MoveKind::Arc, ms, me);
        m.center = Some(center);
        m.normal = Some(plane.normal());
        m.clockwise = Some(cw);
        m.arc = Some(Box::new(geom));
        self.push(m)?;
        self.cur = end;
        Ok(())
    }

    /// G33.1: feed to the target synchronized with the spindle (K = pitch), then back out.
    fn rigid_tap(&mut self, w: &mut Words) -> R<()> {
        let Some(k) = w.take('K') else {
            return Err(self.err_block("G33.1 needs a K word (thread pitch)"));
        };
        if k <= 0.0 {
            return Err(self.err_word(w, 'K', "G33.1 pitch K must be positive"));
        }
        if self.speed <= 0.0 || self.spindle == SpindleDir::Off {
            return Err(self.err_block("G33.1 with the spindle stopped"));
        }
        let start = self.cur;
        let to = self.target(w, false)?;
        if (0..2).any(|i| to[i] != start[i]) || (3..6).any(|i| to[i] != start[i]) {
            return Err(self.err_block("G33.1 moves Z only here (X/Y/A/B/C must not change)"));
        }
        let (mode, word, factor) = (self.feed_mode, self.feed_word, self.feed_factor);
        self.feed_mode = FeedMode::PerRev;
        self.feed_word = k;
        self.feed_factor = self.unit();
        let r = (|| {
            self.straight(false, to)?;
            self.straight(false, start)
        })();
        self.feed_mode = mode;
        self.feed_word = word;
        self.feed_factor = factor;
        r
    }

    /// Canned cycles, as LinuxCNC 2.9 (`convert_cycle_xy/yz/zx`).
    fn cycle(&mut self, w: &mut Words, g: u16) -> R<()> {
        if self.feed_mode == FeedMode::InverseTime {
            return Err(self.err_block("canned cycle in inverse time mode (G93)"));
        }
        self.check_feed()?;
        let same = self.motion_was_cycle(g);
        let plane = self.plane;
        let [ia, ib, ic] = plane.axes();
        let (la, lb, lc) = (AXES[ia], AXES[ib], AXES[ic]);
        if AXES[3..].iter().any(|&c| w.has(c)) {
            return Err(self.err_block("rotary axis words in a canned cycle"));
        }
        let r_word = w.take('R');
        let r_num = match r_word {
            Some(r) => r,
            None if same => self.cycle_r,
            None => return Err(self.err_block(format!("G{g} needs an R word (retract plane)"))),
        };
        // Repeats: L (LinuxCNC); Fanuc uses K except in G87 where K is the bore top.
        let mut l = w.take('L');
        if self.fanuc && g != 87 {
            if let Some(k) = w.take('K') {
                if l.is_some() {
                    return Err(self.err_word(w, 'K', "both L and K repeat counts"));
                }
                l = Some(k);
            }
        }
        let repeats = match l {
            Some(v) if v.fract() != 0.0 || v < 1.0 => {
                return Err(self.err_block(format!(
                    "repeat count L{v} must be a whole number of at least 1"
                )))
            }
            Some(v) => v,
            None => 1.0,
        };
        let cc_word = w.get(lc);
        if !same && cc_word.is_none() {
            return Err(self.err_block(format!(
                "G{g} needs a {lc} word (hole bottom) in {}",
                plane.name()
            )));
        }
        w.take(lc);
        let cc_num = cc_word.unwrap_or(self.cycle_cc);
        let current_cc0 = self.cur[ic];
        let mut current_cc = current_cc0;
        let mut old_cc = match self.cycle_il {
            Some(v) => v,
            None => {
                self.cycle_il = Some(current_cc0);
                current_cc0
            }
        };
        let (mut aa, mut bb, aa_inc, bb_inc, r, cc);
        let wa = w.take(la);
        let wb = w.take(lb);
        if self.absolute {
            aa_inc = 0.0;
            bb_inc = 0.0;
            r = r_num;
            cc = cc_num;
            aa = wa.unwrap_or(self.cur[ia]);
            bb = wb.unwrap_or(self.cur[ib]);
        } else {
            aa_inc = wa.unwrap_or(0.0);
            bb_inc = wb.unwrap_or(0.0);
            r = r_num + old_cc;
            cc = r + cc_num;
            aa = self.cur[ia];
            bb = self.cur[ib];
        }
        if r < cc {
            return Err(
                self.err_block(format!("R ({r}) below the hole bottom {lc} ({cc}) in G{g}"))
            );
        }
        // Cycle-specific words (sticky when the cycle repeats).
        let mut p = 0.0;
        let mut q = 0.0;
        let (mut ci, mut cj, mut ck) = (0.0, 0.0, 0.0);
        match g {
            82 | 86 | 88 | 89 => {
                p = match w.take('P') {
                    Some(v) => v,
                    None if same => self.cycle_p,
                    None => return Err(self.err_block(format!("G{g} needs a P word (dwell)"))),
                };
                self.cycle_p = p;
            }
            74 | 84 => {
                p = w.take('P').unwrap_or(self.cycle_p);
                self.cycle_p = p;
                let (need, m) = if g == 84 {
                    (SpindleDir::Cw, "clockwise (M3)")
                } else {
                    (SpindleDir::Ccw, "counterclockwise (M4)")
                };
                if self.spindle != need {
                    return Err(self.err_block(format!("G{g} needs the spindle turning {m}")));
                }
            }
            73 | 83 => {
                q = match w.take('Q') {
                    Some(v) => v,
                    None if same => self.cycle_q,
                    None => return Err(self.err_block(format!("G{g} needs a Q word (peck depth)"))),
                };
                if q <= 0.0 {
                    return Err(self.err_block(format!("G{g} peck depth Q must be positive")));
                }
                self.cycle_q = q;
            }
            87 => {
                // I J K of the XY plane; in other planes the letters follow the plane's axes.
                let [li, lj] = [['I', 'J', 'K'][ia], ['I', 'J', 'K'][ib]];
                let lk = ['I', 'J', 'K'][ic];
                if !same {
                    for c in [li, lj, lk] {
                        if !w.has(c) {
                            return Err(
                                self.err_block(format!("G87 needs {li}, {lj} and {lk} words"))
                            );
                        }
                    }
                }
                ci = w.take(li).unwrap_or(self.cycle_i);
                cj = w.take(lj).unwrap_or(self.cycle_j);
                ck = w.take(lk).unwrap_or(self.cycle_k);
                self.cycle_i = ci;
                self.cycle_j = cj;
                self.cycle_k = ck;
                if !self.absolute {
                    ck += cc;
                }
            }
            _ => {}
        }
        if matches!(g, 86 | 87 | 88) && self.spindle == SpindleDir::Off {
            return Err(self.err_block(format!("G{g} needs the spindle turning")));
        }
        // Below the R plane: rapid up to it first.
        if old_cc < r {
            let mut t = self.cur;
            t[ic] = r;
            self.straight(true, t)?;
            old_cc = r;
            current_cc = old_cc;
        }
        let clear = if self.retract_r_plane { r } else { old_cc };
        // rs274 (2.9) never positions at or below the R plane: from there it positions at
        // the clearance height (R in G99, the initial level in G98).
        if current_cc <= r {
            current_cc = clear;
        }
        let mut repeat = repeats;
        while repeat >= 1.0 {
            aa += aa_inc;
            bb += bb_inc;
            self.cyc_move(true, plane, aa, bb, current_cc)?;
            // rs274 (2.9) moves down to R whenever the positioning height is not R.
            if current_cc != r {
                self.cyc_move(true, plane, aa, bb, r)?;
            }
            match g {
                81 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                82 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                73 | 83 => {
                    let delta = G83_RAPID_DELTA_INCH * if self.metric { MM_PER_INCH } else { 1.0 };
                    let mut depth = r - q;
                    while depth > cc {
                        self.cyc_move(false, plane, aa, bb, depth)?;
                        if g == 83 {
                            self.cyc_move(true, plane, aa, bb, r)?;
                        }
                        self.cyc_move(true, plane, aa, bb, depth + delta)?;
                        depth -= q;
                    }
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                74 | 84 => {
                    // Tap in, reverse the spindle, dwell, feed out, restore the direction.
                    let (dir, rev) = if g == 84 {
                        (SpindleDir::Cw, SpindleDir::Ccw)
                    } else {
                        (SpindleDir::Ccw, SpindleDir::Cw)
                    };
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.spindle = rev;
                    self.dwell(p)?;
                    self.cyc_move(false, plane, aa, bb, clear)?;
                    self.spindle = dir;
                }
                85 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.cyc_move(false, plane, aa, bb, r)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                }
                86 => {
                    let dir = self.spindle;
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.spindle = SpindleDir::Off;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                    self.spindle = dir;
                }
                87 => {
                    let dir = self.spindle;
                    let (oa, ob) = (aa + ci, bb + cj);
                    self.cyc_move(true, plane, oa, ob, r)?;
                    self.spindle = SpindleDir::Off;
                    self.cyc_move(true, plane, oa, ob, cc)?;
                    self.cyc_move(true, plane, aa, bb, cc)?;
                    self.spindle = dir;
                    self.cyc_move(false, plane, aa, bb, ck)?;
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.spindle = SpindleDir::Off;
                    self.cyc_move(true, plane, oa, ob, cc)?;
                    self.cyc_move(true, plane, oa, ob, clear)?;
                    self.cyc_move(true, plane, aa, bb, clear)?;
                    self.spindle = dir;
                }
                88 => {
                    // The control stops at the bottom and the operator retracts by hand; the
                    // program then goes on as if the tool were at the clearance height. That
                    // retract is emitted as a rapid (spindle stopped) so the path stays connected.
                    let dir = self.spindle;
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.spindle = SpindleDir::Off;
                    self.warnings.push(self.err_block(
                        "G88: program stop at the hole bottom; the operator's manual retract is modelled as a rapid to the clearance height",
                    ));
                    self.cyc_move(true, plane, aa, bb, clear)?;
                    self.spindle = dir;
                }
                89 => {
                    self.cyc_move(false, plane, aa, bb, cc)?;
                    self.dwell(p)?;
                    self.cyc_move(false, plane, aa, bb, clear)?;
                }
                _ => return Err(self.err_block(format!("G{g} is not a supported canned cycle"))),
            }
            // Later repeats position at the clearance height.
            current_cc = clear;
            repeat -= 1.0;
        }
        // LinuxCNC leaves the third axis at the clearance value whatever the last move was
        // (for G88 the operator's manual retract, emitted as a rapid below).
        self.cur[ia] = aa;
        self.cur[ib] = bb;
        self.cur[ic] = clear;
        self.cycle_cc = cc_num;
        self.cycle_r = r_num;
        Ok(())
    }

    fn motion_was_cycle(&self, g: u16) -> bool {
        self.motion_prev == Some(Motion::Cycle(g))
    }

    fn cyc_move(&mut self, rapid: bool, plane: Plane, aa: f64, bb: f64, cc: f64) -> R<()> {
        let [ia, ib, ic] = plane.axes();
        let mut t = self.cur;
        t[ia] = aa;
        t[ib] = bb;
        t[ic] = cc;
        self.straight(rapid, t)
    }

    /// Shorten the pending corner's move and add the fillet arc or chamfer line.
    fn resolve_corner(&mut self, p: PendingCorner, next_end: [f64; 6]) -> R<()> {
        let [a, b, _] = p.plane.axes();
        let prev_start_m = self.moves[p.move_index].start;
        let prev_start = self.from_machine(prev_start_m);
        let c = p.corner;
        let fail = |s: &Self, m: &str| s.err_at(p.word_pos, m.to_string());
        if p.plane != self.plane {
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
        self.moves[p.move_index].end = t1m;
        let (blk, line) = (self.cur_block, self.cur_line);
        self.cur_block = p.block;
        self.cur_line = self.prog.block(p.block).line;
        let mut m = self.base_move(
            if p.chamfer {
                MoveKind::Linear
            } else {
                MoveKind::Arc
            },
            t1m,
            t2m,
        );
        // The corner belongs to the corner block, at the corner block's feed.
        let corner_move = &self.moves[p.move_index];
        m.feed = corner_move.feed;
        m.feed_mode = corner_move.feed_mode;
        m.spindle = corner_move.spindle;
        if !p.chamfer {
            let cw = turn < 0.0;
            // Centre: from T1 perpendicular to u1 towards the turn.
            let side = if cw { -1.0 } else { 1.0 };
            let mut cp = t1;
            cp[a] = t1[a] - u1[1] * p.size * side;
            cp[b] = t1[b] + u1[0] * p.size * side;
            let cm = self.to_machine(cp);
            let center = [cm[0], cm[1], cm[2]];
            let r = p.size * self.unit();
            m.center = Some(center);
            m.normal = Some(p.plane.normal());
            m.clockwise = Some(cw);
            m.arc = Some(Box::new(ArcGeometry {
                start: t1m,
                end: t2m,
                center,
                normal: p.plane.normal(),
                axes: p.plane.axes(),
                sweep: turn,
                start_radius: r,
                end_radius: r,
                clockwise: cw,
                turns: 1,
            }));
        }
        let res = self.push(m);
        self.cur_block = blk;
        self.cur_line = line;
        res?;
        self.cur = t2;
        Ok(())
    }
}

fn strip_neg(e: &Expr) -> &Expr {
    match e {
        Expr::Neg(x) => strip_neg(x),
        other => other,
    }
}
