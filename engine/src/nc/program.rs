//! The syntax tree of an NC program. Every source line is one block; every word keeps the byte
//! span it came from, and the source text is kept whole, so the program can be written back
//! byte for byte and edited word by word.

use super::{Diagnostic, Diagnostics};
use std::fmt;

/// Byte range `[start, end)` in the program source.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Span {
    pub start: usize,
    pub end: usize,
}

impl Span {
    pub fn new(start: usize, end: usize) -> Self {
        Span { start, end }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinOp {
    Pow,
    Mul,
    Div,
    Mod,
    Add,
    Sub,
    Eq,
    Ne,
    Gt,
    Ge,
    Lt,
    Le,
    And,
    Or,
    Xor,
}

impl BinOp {
    /// LinuxCNC precedence: `**` > `* / MOD` > `+ -` > comparisons > `AND OR XOR`.
    pub fn precedence(self) -> u8 {
        match self {
            BinOp::Pow => 6,
            BinOp::Mul | BinOp::Div | BinOp::Mod => 5,
            BinOp::Add | BinOp::Sub => 4,
            BinOp::Eq | BinOp::Ne | BinOp::Gt | BinOp::Ge | BinOp::Lt | BinOp::Le => 3,
            BinOp::And | BinOp::Or | BinOp::Xor => 2,
        }
    }
}

/// Fanuc macro B precedence: functions, then `* / AND MOD`, then `+ - OR XOR`, then the
/// comparisons (`**` is not Fanuc; it stays first).
pub(crate) fn fanuc_precedence(op: BinOp) -> u8 {
    match op {
        BinOp::Pow => 4,
        BinOp::Mul | BinOp::Div | BinOp::Mod | BinOp::And => 3,
        BinOp::Add | BinOp::Sub | BinOp::Or | BinOp::Xor => 2,
        _ => 1,
    }
}

/// `first op1 e1 op2 e2 ...` into a tree, left-associative, by `prec`.
pub(crate) fn reduce(first: Expr, rest: Vec<(BinOp, Expr)>, prec: fn(BinOp) -> u8) -> Expr {
    fn apply(out: &mut Vec<Expr>, op: BinOp) {
        let r = out.pop().expect("operand");
        let l = out.pop().expect("operand");
        out.push(Expr::Binary(op, Box::new(l), Box::new(r)));
    }
    let mut out = vec![first];
    let mut ops: Vec<BinOp> = Vec::new();
    for (op, e) in rest {
        while let Some(&top) = ops.last() {
            if prec(top) >= prec(op) {
                ops.pop();
                apply(&mut out, top);
            } else {
                break;
            }
        }
        ops.push(op);
        out.push(e);
    }
    while let Some(top) = ops.pop() {
        apply(&mut out, top);
    }
    out.pop().expect("one expression")
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Func {
    Abs,
    Acos,
    Asin,
    Cos,
    Exp,
    Fix,
    Fup,
    Round,
    Ln,
    Sin,
    Sqrt,
    Tan,
}

impl Func {
    pub fn from_name(name: &str) -> Option<Func> {
        Some(match name {
            "ABS" => Func::Abs,
            "ACOS" => Func::Acos,
            "ASIN" => Func::Asin,
            "COS" => Func::Cos,
            "EXP" => Func::Exp,
            "FIX" => Func::Fix,
            "FUP" => Func::Fup,
            "ROUND" => Func::Round,
            "LN" => Func::Ln,
            "SIN" => Func::Sin,
            "SQRT" => Func::Sqrt,
            "TAN" => Func::Tan,
            _ => return None,
        })
    }
}

/// A value: a literal, a parameter or a bracketed expression.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// `has_point`: the literal was written with a decimal point (matters for Fanuc implied
    /// decimals).
    Number {
        value: f64,
        has_point: bool,
    },
    Param(Box<ParamRef>),
    Neg(Box<Expr>),
    Binary(BinOp, Box<Expr>, Box<Expr>),
    Func(Func, Box<Expr>),
    /// `ATAN[y]/[x]`
    Atan(Box<Expr>, Box<Expr>),
    /// `EXISTS[#<name>]`
    Exists(String),
    /// Operands and operators of one bracket level where AND/OR/XOR meet arithmetic: the
    /// dialect's precedence applies when it is evaluated (LinuxCNC: logical operators last;
    /// Fanuc: AND with `*`, OR/XOR with `+`).
    /// Boxed whole: every word's value is an `Expr`, so no variant may make it larger.
    Mixed(Box<(Expr, Vec<(BinOp, Expr)>)>),
}

/// `#123`, `#[expr]`, `##1` (numbered) or `#<name>` (named; lower case, blanks removed).
#[derive(Clone, Debug, PartialEq)]
pub enum ParamRef {
    Numbered(Expr),
    Named(String),
}

/// A letter word such as `X-1.5`, `G43.1`, `F#102`, or a Fanuc corner word `,R2`.
#[derive(Clone, Debug, PartialEq)]
pub struct Word {
    /// Upper-case letter.
    pub letter: char,
    /// Written with a leading comma (Fanuc `,R` / `,C`).
    pub comma: bool,
    pub value: Expr,
    /// The whole word, letter (and comma) included.
    pub span: Span,
    /// Just the value.
    pub value_span: Span,
}

/// `#1 = expr`
#[derive(Clone, Debug, PartialEq)]
pub struct Assignment {
    pub target: ParamRef,
    pub value: Expr,
    /// The value is an expression without brackets (`#1=#2*#3+1`): Fanuc macro B syntax,
    /// with Fanuc's precedence (`* / AND MOD` before `+ - OR XOR`).
    pub bare: bool,
    pub span: Span,
}

/// A Fanuc custom macro B control statement, a line of its own (after an optional N word).
#[derive(Clone, Debug, PartialEq)]
pub enum MacroStatement {
    /// `GOTO n`: sequence number search in the current program.
    Goto(Expr),
    /// `IF [cond] GOTO n`
    IfGoto { cond: Expr, target: Expr },
    /// `IF [cond] THEN #i = expr`: the assignment is the block's (see [`Block::assignments`]).
    IfThen { cond: Expr },
    /// `WHILE [cond] DOm`
    While { cond: Expr, id: u32 },
    /// `DOm` without WHILE: an endless loop, left by GOTO.
    Do { id: u32 },
    /// `ENDm`
    End { id: u32 },
    /// `DPRNT[..]`, `BPRNT[..]`, `POPEN`, `PCLOS`: external output, no motion (the keyword).
    Output(String),
}

/// A macro statement and where it is.
#[derive(Clone, Debug, PartialEq)]
pub struct MacroLine {
    pub statement: MacroStatement,
    /// From the keyword to the end of the statement.
    pub span: Span,
}

/// `( ... )` or `; ...`; `text` is without the delimiters.
#[derive(Clone, Debug, PartialEq)]
pub struct Comment {
    pub text: String,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum OName {
    Number(u32),
    Named(String),
}

impl OName {
    /// The number of a numbered name (0 for a named one).
    pub fn number(&self) -> u32 {
        match self {
            OName::Number(n) => *n,
            OName::Named(_) => 0,
        }
    }
}

impl fmt::Display for OName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OName::Number(n) => write!(f, "o{n}"),
            OName::Named(s) => write!(f, "o<{s}>"),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OKeyword {
    Sub,
    EndSub,
    Call,
    Do,
    While,
    EndWhile,
    If,
    ElseIf,
    Else,
    EndIf,
    Repeat,
    EndRepeat,
    Return,
    Break,
    Continue,
    /// A bare `O1234` line: a Fanuc program number.
    ProgramNumber,
}

impl OKeyword {
    pub fn from_name(s: &str) -> Option<OKeyword> {
        Some(match s {
            "SUB" => OKeyword::Sub,
            "ENDSUB" => OKeyword::EndSub,
            "CALL" => OKeyword::Call,
            "DO" => OKeyword::Do,
            "WHILE" => OKeyword::While,
            "ENDWHILE" => OKeyword::EndWhile,
            "IF" => OKeyword::If,
            "ELSEIF" => OKeyword::ElseIf,
            "ELSE" => OKeyword::Else,
            "ENDIF" => OKeyword::EndIf,
            "REPEAT" => OKeyword::Repeat,
            "ENDREPEAT" => OKeyword::EndRepeat,
            "RETURN" => OKeyword::Return,
            "BREAK" => OKeyword::Break,
            "CONTINUE" => OKeyword::Continue,
            _ => return None,
        })
    }
}

/// An O-word control line: `o100 sub`, `o<name> call [1] [2]`, `o101 while [#1 LT 3]`, ...
#[derive(Clone, Debug, PartialEq)]
pub struct OWord {
    pub name: OName,
    pub keyword: OKeyword,
    /// Call arguments, or the one condition / count / return value.
    pub args: Vec<Expr>,
    pub span: Span,
}

/// One source line.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Block {
    /// 1-based source line.
    pub line: u32,
    /// The line without its terminator.
    pub span: Span,
    /// End of the line including its terminator (`\n` or `\r\n`).
    pub end: usize,
    /// Starts with `/`.
    pub block_delete: bool,
    /// A `%` demarcation line.
    pub percent: bool,
    /// A `%` line with an `O1234` program number written on to it (`%O1234`, as some DNC
    /// senders join Fanuc's two start lines): Fanuc evidence, like a program number line.
    pub percent_program_number: bool,
    /// After the closing `%`: kept as text, not parsed and not run.
    pub after_end: bool,
    /// `N123`
    pub line_number: Option<Word>,
    pub o_word: Option<OWord>,
    /// A Fanuc macro statement (`IF`, `WHILE`, `GOTO`, `END`, `DPRNT`, ...).
    pub macro_line: Option<Box<MacroLine>>,
    pub words: Vec<Word>,
    pub assignments: Vec<Assignment>,
    pub comments: Vec<Comment>,
}

impl Block {
    /// True when the block has nothing to execute (blank or comment only).
    pub fn is_empty(&self) -> bool {
        self.o_word.is_none()
            && self.macro_line.is_none()
            && self.words.is_empty()
            && self.assignments.is_empty()
    }
}

/// Dialect evidence in one block: syntax that one dialect has and the other refuses.
/// Fanuc's: macro B statements, M97/M98/M99, G65, unbracketed expressions, an `O1234`
/// program number, `,R`/`,C` corners and the transform codes G15/G16, G50/G51 and
/// G68/G69; LinuxCNC's: O-word control lines, named parameters and polar words.
/// `#1=` assignments and bracketed expressions are in both, so they decide nothing: a
/// program number above them still says Fanuc.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct DialectEvidence {
    pub fanuc: bool,
    pub linuxcnc: bool,
}

fn dialect_syntax(block: &Block, words: &[Word]) -> DialectEvidence {
    let mut e = DialectEvidence {
        fanuc: block.macro_line.is_some() || block.percent_program_number,
        ..DialectEvidence::default()
    };
    if let Some(o) = &block.o_word {
        if o.keyword == OKeyword::ProgramNumber {
            e.fanuc = true;
        } else {
            e.linuxcnc = true;
        }
    }
    for a in &block.assignments {
        e.fanuc |= a.bare;
        e.linuxcnc |= matches!(a.target, ParamRef::Named(_)) || has_named(&a.value);
    }
    for w in words {
        e.fanuc |= w.comma;
        // Polar words are LinuxCNC's; Fanuc's transform codes (scaling, mirror, rotation,
        // polar mode) are not in LinuxCNC.
        e.linuxcnc |= matches!(w.letter, '@' | '^');
        if let Expr::Number { value, .. } = w.value {
            e.fanuc |= (w.letter == 'M' && [97.0, 98.0, 99.0].contains(&value))
                || (w.letter == 'G' && value == 65.0);
            e.fanuc |= w.letter == 'G'
                && [15.0, 16.0, 50.0, 51.0, 50.1, 51.1, 68.0, 69.0].contains(&value);
        } else if !matches!(w.value, Expr::Neg(_)) {
            e.linuxcnc |= has_named(&w.value);
        }
    }
    e
}

/// Whether an expression reads a named parameter (`#<name>`, LinuxCNC only).
fn has_named(e: &Expr) -> bool {
    match e {
        Expr::Number { .. } => false,
        Expr::Param(p) => match p.as_ref() {
            ParamRef::Named(_) => true,
            ParamRef::Numbered(i) => has_named(i),
        },
        Expr::Neg(x) | Expr::Func(_, x) => has_named(x),
        Expr::Binary(_, a, b) | Expr::Atan(a, b) => has_named(a) || has_named(b),
        Expr::Exists(_) => true,
        Expr::Mixed(m) => has_named(&m.0) || m.1.iter().any(|(_, e)| has_named(e)),
    }
}

/// Facts about the whole program gathered while parsing, so the interpreter need not walk
/// every block again before it starts.
#[derive(Clone, Debug, PartialEq, Default)]
pub(crate) struct Summary {
    /// Indices of the blocks with an O word, in order.
    pub o_word_blocks: Vec<usize>,
    /// Indices of the blocks with a Fanuc macro statement, in order.
    pub macro_blocks: Vec<usize>,
    /// What the blocks say about the dialect (see [`dialect_syntax`]), or-ed.
    pub dialect: DialectEvidence,
    /// Syntax errors of lines raised only when the line is executed (block index, error),
    /// in block order; see `parser::parse_blocks`.
    pub deferred: Vec<(usize, Diagnostic)>,
    /// A word that calls or returns (M97, M98, M99, G65, G66) or an M or G word whose number is
    /// computed (it might be one).
    pub calls: bool,
    /// An O word other than a program number (`O1234`): LinuxCNC control flow or calls.
    pub control_o_words: bool,
}

impl Summary {
    /// The syntax error of block `index`, raised when it is executed.
    #[inline]
    pub fn deferred_error(&self, index: usize) -> Option<&Diagnostic> {
        if self.deferred.is_empty() {
            return None;
        }
        self.deferred
            .binary_search_by_key(&index, |(i, _)| *i)
            .ok()
            .map(|k| &self.deferred[k].1)
    }

    /// The program runs front to back: no control flow, no calls and at most one program
    /// number (where the main program starts), so the interpreter may read it a window of
    /// blocks at a time (see `interp::interpret_streamed`).
    pub fn straight_line(&self) -> bool {
        self.macro_blocks.is_empty()
            && !self.calls
            && !self.control_o_words
            && self.o_word_blocks.len() <= 1
    }

    /// Adds the summary of the lines parsed after this one's.
    pub fn merge(&mut self, later: Summary) {
        self.o_word_blocks.extend(later.o_word_blocks);
        self.macro_blocks.extend(later.macro_blocks);
        let (d, e) = (&mut self.dialect, later.dialect);
        d.fanuc |= e.fanuc;
        d.linuxcnc |= e.linuxcnc;
        self.deferred.extend(later.deferred);
        self.calls |= later.calls;
        self.control_o_words |= later.control_o_words;
    }

    /// Adds block `index`, whose words are `words` (they may not be in `block.words` yet).
    #[inline]
    pub fn add(&mut self, index: usize, block: &Block, words: &[Word]) {
        if let Some(o) = &block.o_word {
            self.o_word_blocks.push(index);
            self.control_o_words |= o.keyword != OKeyword::ProgramNumber;
        }
        self.calls |= words.iter().any(|w| match w.value {
            Expr::Number { value, .. } => {
                (w.letter == 'M' && [97.0, 98.0, 99.0].contains(&value))
                    || (w.letter == 'G' && (value == 65.0 || value == 66.0 || value == 66.1))
            }
            _ => matches!(w.letter, 'M' | 'G'),
        });
        if block.macro_line.is_some() {
            self.macro_blocks.push(index);
        }
        let e = dialect_syntax(block, words);
        let d = &mut self.dialect;
        d.fanuc |= e.fanuc;
        d.linuxcnc |= e.linuxcnc;
    }
}

/// A parsed program: the original text and its blocks.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    source: String,
    blocks: Vec<Block>,
    summary: Summary,
}

impl Program {
    /// Parse a program. The syntax errors of O-word and macro statement lines and unclosed
    /// comments are reported at once; any other line's error is kept with its block
    /// ([`Program::deferred_errors`]) and raised by the interpreter only if it executes the
    /// line, as LinuxCNC reads a line only when it runs it.
    pub fn parse(source: &str) -> Result<Program, Diagnostics> {
        super::conversational::refuse_conversational(source)?;
        let mut list = super::parser::BlockList::with_capacity(super::parser::line_count(source));
        let (summary, errors) = super::parser::parse_blocks(source, &mut list);
        if errors.is_empty() {
            Ok(Program {
                source: source.to_string(),
                blocks: list.blocks,
                summary,
            })
        } else {
            Err(Diagnostics(errors))
        }
    }

    pub fn source(&self) -> &str {
        &self.source
    }

    /// True when the program has O-word or macro statement lines: which of its lines run
    /// depends on the run.
    pub fn has_control_flow(&self) -> bool {
        !self.summary.o_word_blocks.is_empty() || !self.summary.macro_blocks.is_empty()
    }

    /// Syntax errors of lines that fail only if executed (see [`Program::parse`]), in line
    /// order.
    pub fn deferred_errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.summary.deferred.iter().map(|(_, d)| d)
    }

    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }

    pub(crate) fn summary(&self) -> &Summary {
        &self.summary
    }

    /// Text of a span.
    pub fn text(&self, span: Span) -> &str {
        &self.source[span.start..span.end]
    }

    /// 1-based (line, column) of a byte offset; the column counts characters.
    pub fn position(&self, byte: usize) -> (u32, u32) {
        let idx = match self.blocks.binary_search_by(|b| b.span.start.cmp(&byte)) {
            Ok(i) => i,
            Err(0) => 0,
            Err(i) => i - 1,
        };
        match self.blocks.get(idx) {
            Some(b) => {
                let end = byte.min(self.source.len()).max(b.span.start);
                let col = self.source[b.span.start..end].chars().count() as u32 + 1;
                (b.line, col)
            }
            None => (1, 1),
        }
    }

    /// A diagnostic at a byte offset.
    pub fn diag(&self, byte: usize, message: impl Into<String>) -> Diagnostic {
        let (line, col) = self.position(byte);
        Diagnostic::new(line, col, message)
    }

    /// The program text with the F word of each listed block set to the given feed (in the
    /// block's own feed unit and mode). A block without an F word gets one appended after its
    /// last word (before any comment); every other byte stays as it was.
    pub fn with_feeds(&self, changes: &[(usize, f64)]) -> Result<String, Diagnostics> {
        let mut edits: Vec<(usize, usize, String)> = Vec::new();
        let mut errors = Vec::new();
        let mut seen = std::collections::HashSet::new();
        for &(index, feed) in changes {
            let Some(block) = self.blocks.get(index) else {
                errors.push(Diagnostic::new(
                    0,
                    0,
                    format!(
                        "block {index} does not exist (program has {} blocks)",
                        self.blocks.len()
                    ),
                ));
                continue;
            };
            let at = |m: String| self.diag(block.span.start, m);
            if !seen.insert(index) {
                errors.push(at(format!("block {index} listed twice")));
                continue;
            }
            if !(feed.is_finite() && feed > 0.0) {
                errors.push(at(format!("feed {feed} is not a positive number")));
                continue;
            }
            if block.o_word.is_some()
                || block.macro_line.is_some()
                || block.percent
                || block.after_end
            {
                errors.push(at("an F word cannot be put on this line".to_string()));
                continue;
            }
            let fwords: Vec<&Word> = block
                .words
                .iter()
                .filter(|w| w.letter == 'F' && !w.comma)
                .collect();
            match fwords.as_slice() {
                [w] => {
                    let had_point = self.text(w.value_span).contains('.');
                    edits.push((
                        w.value_span.start,
                        w.value_span.end,
                        format_feed(feed, had_point),
                    ));
                }
                [] => {
                    // After the last word or assignment, else after N, else at line start.
                    let last = block
                        .words
                        .iter()
                        .map(|w| w.span.end)
                        .chain(block.assignments.iter().map(|a| a.span.end))
                        .chain(block.line_number.iter().map(|w| w.span.end))
                        .max();
                    let (pos, text) = match last {
                        Some(p) => (p, format!(" F{}", format_feed(feed, false))),
                        None => {
                            // Keep the block-delete slash first.
                            let mut p = block.span.start;
                            let line = &self.source[block.span.start..block.span.end];
                            let trimmed = line.trim_start();
                            if block.block_delete {
                                p += line.len() - trimmed.len() + 1;
                            }
                            let sep = if p < block.span.end { " " } else { "" };
                            (p, format!("F{}{}", format_feed(feed, false), sep))
                        }
                    };
                    edits.push((pos, pos, text));
                }
                _ => errors.push(at("block has more than one F word".to_string())),
            }
        }
        if !errors.is_empty() {
            return Err(Diagnostics(errors));
        }
        edits.sort_by_key(|e| (e.0, e.1));
        let mut out = String::with_capacity(self.source.len() + edits.len() * 8);
        let mut pos = 0;
        for (s, e, text) in edits {
            out.push_str(&self.source[pos..s]);
            out.push_str(&text);
            pos = e;
        }
        out.push_str(&self.source[pos..]);
        Ok(out)
    }
}

/// Feed with at most 4 decimals, trailing zeros dropped.
/// A feed as `with_feeds` writes it: up to 4 decimals, no trailing zeros, and a trailing
/// point for a whole number only `with_point`.
pub(crate) fn format_feed(feed: f64, with_point: bool) -> String {
    let mut s = format!("{feed:.4}");
    while s.ends_with('0') {
        s.pop();
    }
    if s.ends_with('.') && !with_point {
        s.pop();
    }
    s
}

impl fmt::Display for Program {
    /// The original text, byte for byte.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.source)
    }
}

#[cfg(test)]
mod size_tests {
    /// Every word holds an `Expr`: keep it three words wide (parse and interpret speed).
    #[test]
    fn expr_stays_small() {
        assert!(
            std::mem::size_of::<super::Expr>() <= 32,
            "{}",
            std::mem::size_of::<super::Expr>()
        );
    }
}
