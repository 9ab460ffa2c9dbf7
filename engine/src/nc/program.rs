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
    /// After the closing `%`: kept as text, not parsed and not run.
    pub after_end: bool,
    /// `N123`
    pub line_number: Option<Word>,
    pub o_word: Option<OWord>,
    pub words: Vec<Word>,
    pub assignments: Vec<Assignment>,
    pub comments: Vec<Comment>,
}

impl Block {
    /// True when the block has nothing to execute (blank or comment only).
    pub fn is_empty(&self) -> bool {
        self.o_word.is_none() && self.words.is_empty() && self.assignments.is_empty()
    }
}

/// Dialect evidence in one block: (Fanuc-only syntax, LinuxCNC-only syntax). Fanuc-only: an
/// `O1234` program number, `,R`/`,C` corners, M98/M99. LinuxCNC-only: O-word control lines,
/// parameter assignments, word values that are not plain numbers.
fn dialect_syntax(block: &Block, words: &[Word]) -> (bool, bool) {
    let mut fanuc = false;
    let mut linuxcnc = !block.assignments.is_empty();
    if let Some(o) = &block.o_word {
        if o.keyword == OKeyword::ProgramNumber {
            fanuc = true;
        } else {
            linuxcnc = true;
        }
    }
    for w in words {
        fanuc |= w.comma;
        if let Expr::Number { value, .. } = w.value {
            fanuc |= w.letter == 'M' && (value == 98.0 || value == 99.0);
        } else if !matches!(w.value, Expr::Neg(_)) {
            linuxcnc = true;
        }
    }
    (fanuc, linuxcnc)
}

/// Facts about the whole program gathered while parsing, so the interpreter need not walk
/// every block again before it starts.
#[derive(Clone, Debug, PartialEq, Default)]
pub(crate) struct Summary {
    /// Indices of the blocks with an O word, in order.
    pub o_word_blocks: Vec<usize>,
    /// Some block has Fanuc-only syntax (see [`dialect_syntax`]).
    pub fanuc_syntax: bool,
    /// Some block has LinuxCNC-only syntax.
    pub linuxcnc_syntax: bool,
}

impl Summary {
    /// Adds block `index`, whose words are `words` (they may not be in `block.words` yet).
    pub fn add(&mut self, index: usize, block: &Block, words: &[Word]) {
        if block.o_word.is_some() {
            self.o_word_blocks.push(index);
        }
        let (fanuc, linuxcnc) = dialect_syntax(block, words);
        self.fanuc_syntax |= fanuc;
        self.linuxcnc_syntax |= linuxcnc;
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
    /// Parse a program. All syntax errors are reported at once.
    pub fn parse(source: &str) -> Result<Program, Diagnostics> {
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
            if block.o_word.is_some() || block.percent || block.after_end {
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
