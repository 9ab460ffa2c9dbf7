//! Lines into blocks: words, parameter assignments, O-word control lines and comments, with
//! spans. A syntax error ends the parse of its line only, so every line's errors are reported.

use super::lexer::{LexError, Lexer, Tok, UNCLOSED_COMMENT};
use super::program::*;
use super::program::{fanuc_precedence, reduce};
use super::Diagnostic;

/// Deepest bracket nesting accepted; keeps the recursive parser off the stack limit.
const MAX_DEPTH: usize = 64;

struct LineParser<'a> {
    lx: Lexer<'a>,
    depth: usize,
    /// Binary operators on the line so far: bounds the depth of left-leaning expression trees.
    ops: usize,
}

/// Most binary operators accepted on one line.
const MAX_OPS: usize = 1000;

type PResult<T> = Result<T, LexError>;

fn err<T>(pos: usize, message: impl Into<String>) -> PResult<T> {
    Err(LexError {
        pos,
        message: message.into(),
        control: false,
    })
}

fn tok_name(t: &Tok) -> String {
    match t {
        Tok::Letter(c) => format!("'{c}'"),
        Tok::Ident(s) => format!("'{s}'"),
        Tok::Number { value, .. } => format!("number {value}"),
        Tok::Plus => "'+'".into(),
        Tok::Minus => "'-'".into(),
        Tok::Star => "'*'".into(),
        Tok::StarStar => "'**'".into(),
        Tok::Slash => "'/'".into(),
        Tok::LBracket => "'['".into(),
        Tok::RBracket => "']'".into(),
        Tok::Hash => "'#'".into(),
        Tok::Name(n) => format!("'<{n}>'"),
        Tok::Equals => "'='".into(),
        Tok::Comma => "','".into(),
        Tok::Comment(_) => "comment".into(),
        Tok::Percent => "'%'".into(),
        Tok::End => "end of line".into(),
    }
}

impl<'a> LineParser<'a> {
    /// The word whose letter `c` (at `start`) was just read.
    fn letter_word(&mut self, c: char, start: usize) -> PResult<Word> {
        if c == 'N' {
            return err(
                start,
                "N word (line number) must be at the start of the block",
            );
        }
        if c == 'O' {
            return err(start, "O word must be at the start of the block");
        }
        self.lx.skip_ws();
        let vstart = self.lx.pos;
        let value = self.value()?;
        Ok(Word {
            letter: c,
            comma: false,
            value,
            span: Span::new(start, self.lx.pos),
            value_span: Span::new(vstart, self.lx.pos),
        })
    }

    /// The common word shape `X-1.5`: a letter, an optional sign, then a number literal
    /// (blanks allowed after the letter only). Returns None, consuming nothing, for anything
    /// else, including errors; the general path then gives the same result or error.
    #[inline]
    fn plain_word(&mut self) -> Option<Word> {
        let start = self.lx.after_blanks(self.lx.pos);
        let letter = self.lx.byte(start)?.to_ascii_uppercase();
        if !letter.is_ascii_uppercase() || letter == b'N' || letter == b'O' {
            return None;
        }
        let value_start = self.lx.after_blanks(start + 1);
        let (negative, digits_start) = match self.lx.byte(value_start) {
            Some(b'-') => (true, value_start + 1),
            Some(b'+') => (false, value_start + 1),
            _ => (false, value_start),
        };
        if !matches!(self.lx.byte(digits_start), Some(b'0'..=b'9' | b'.')) {
            return None;
        }
        let (value, has_point, end) = self.lx.simple_number_at(digits_start)?;
        self.lx.pos = end;
        Some(Word {
            letter: char::from(letter),
            comma: false,
            value: Expr::Number {
                value: if negative { -value } else { value },
                has_point,
            },
            span: Span::new(start, end),
            value_span: Span::new(value_start, end),
        })
    }

    /// A real value after a word letter or as an operand: number, `#param`, `[expr]`,
    /// `FUNC[expr]` or a signed one of these.
    fn value(&mut self) -> PResult<Expr> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return err(self.lx.pos, "expression nested too deeply");
        }
        let r = self.value_inner();
        self.depth -= 1;
        r
    }

    fn value_inner(&mut self) -> PResult<Expr> {
        // A function name is alphabetic; look ahead so single letters stay word addresses.
        if let Some(b) = self.lx.peek_byte() {
            if b.is_ascii_alphabetic() {
                let save = self.lx.clone();
                let (tok, span) = self.lx.next(true)?;
                if let Tok::Ident(name) = tok {
                    if let Some(e) = self.function(&name, span.start)? {
                        return Ok(e);
                    }
                }
                self.lx = save;
                return err(
                    span.start,
                    "expected a value (number, #parameter or [expression])",
                );
            }
        }
        let (tok, span) = self.lx.next(false)?;
        match tok {
            Tok::Number { value, has_point } => Ok(Expr::Number { value, has_point }),
            // A negative literal stays a literal (no allocation for the common `X-1.5`).
            Tok::Minus => Ok(match self.value()? {
                Expr::Number { value, has_point } => Expr::Number {
                    value: -value,
                    has_point,
                },
                e => Expr::Neg(Box::new(e)),
            }),
            Tok::Plus => self.value(),
            Tok::LBracket => {
                let e = self.expr(0)?;
                self.expect_rbracket()?;
                Ok(e)
            }
            Tok::Hash => Ok(Expr::Param(Box::new(self.param_ref()?))),
            t => err(
                span.start,
                format!(
                    "expected a value (number, #parameter or [expression]), found {}",
                    tok_name(&t)
                ),
            ),
        }
    }

    /// `NAME[expr]`; `None` when the name is not a function.
    fn function(&mut self, name: &str, at: usize) -> PResult<Option<Expr>> {
        let func = Func::from_name(name);
        if func.is_none() && name != "ATAN" && name != "EXISTS" {
            return Ok(None);
        }
        let (t, s) = self.lx.next(true)?;
        if t != Tok::LBracket {
            return err(s.start, format!("expected '[' after {name}"));
        }
        if name == "EXISTS" {
            let (t, s) = self.lx.next(true)?;
            if t != Tok::Hash {
                return err(s.start, "EXISTS needs a named parameter: EXISTS[#<name>]");
            }
            let (t, s) = self.lx.next(true)?;
            let Tok::Name(n) = t else {
                return err(s.start, "EXISTS needs a named parameter: EXISTS[#<name>]");
            };
            self.expect_rbracket()?;
            return Ok(Some(Expr::Exists(n)));
        }
        let arg = self.expr(0)?;
        self.expect_rbracket()?;
        if name == "ATAN" {
            let (t, s) = self.lx.next(true)?;
            if t != Tok::Slash {
                return err(s.start, "ATAN needs two arguments: ATAN[y]/[x]");
            }
            let (t, s) = self.lx.next(true)?;
            if t != Tok::LBracket {
                return err(s.start, "ATAN needs two arguments: ATAN[y]/[x]");
            }
            let x = self.expr(0)?;
            self.expect_rbracket()?;
            return Ok(Some(Expr::Atan(Box::new(arg), Box::new(x))));
        }
        let _ = at;
        Ok(Some(Expr::Func(
            func.expect("checked above"),
            Box::new(arg),
        )))
    }

    fn expect_rbracket(&mut self) -> PResult<()> {
        let (t, s) = self.lx.next(true)?;
        if t != Tok::RBracket {
            return err(s.start, format!("expected ']', found {}", tok_name(&t)));
        }
        Ok(())
    }

    /// Operand inside brackets.
    fn operand(&mut self) -> PResult<Expr> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return err(self.lx.pos, "expression nested too deeply");
        }
        let (tok, span) = self.lx.next(true)?;
        let r = match tok {
            Tok::Number { value, has_point } => Ok(Expr::Number { value, has_point }),
            Tok::Minus => self.operand().map(|e| Expr::Neg(Box::new(e))),
            Tok::Plus => self.operand(),
            Tok::LBracket => {
                let e = self.expr(0);
                match e {
                    Ok(e) => self.expect_rbracket().map(|_| e),
                    Err(e) => Err(e),
                }
            }
            Tok::Hash => self.param_ref().map(|p| Expr::Param(Box::new(p))),
            Tok::Ident(name) => match self.function(&name, span.start)? {
                Some(e) => Ok(e),
                None => err(span.start, format!("unknown function or operator '{name}'")),
            },
            t => err(
                span.start,
                format!("expected a value, found {}", tok_name(&t)),
            ),
        };
        self.depth -= 1;
        r
    }

    fn binop(&mut self) -> PResult<Option<BinOp>> {
        let save = self.lx.clone();
        let (tok, span) = self.lx.next(true)?;
        let op = match tok {
            Tok::StarStar => BinOp::Pow,
            Tok::Star => BinOp::Mul,
            Tok::Slash => BinOp::Div,
            Tok::Plus => BinOp::Add,
            Tok::Minus => BinOp::Sub,
            Tok::Ident(ref s) => match s.as_str() {
                "MOD" => BinOp::Mod,
                "EQ" => BinOp::Eq,
                "NE" => BinOp::Ne,
                "GT" => BinOp::Gt,
                "GE" => BinOp::Ge,
                "LT" => BinOp::Lt,
                "LE" => BinOp::Le,
                "AND" => BinOp::And,
                "OR" => BinOp::Or,
                "XOR" => BinOp::Xor,
                _ => return err(span.start, format!("unknown operator '{s}'")),
            },
            _ => {
                self.lx = save;
                return Ok(None);
            }
        };
        Ok(Some(op))
    }

    /// Precedence climbing; all binary operators are left-associative (as in LinuxCNC).
    /// The operands and operators of one bracket level, then the tree by LinuxCNC's
    /// precedence; when AND/OR/XOR meet arithmetic operators at one level the two dialects'
    /// precedences disagree, and the flat list is kept for evaluation ([`Expr::Mixed`]).
    fn expr(&mut self, _min_prec: u8) -> PResult<Expr> {
        let first = self.operand()?;
        let mut rest = Vec::new();
        while let Some(op) = self.binop()? {
            self.ops += 1;
            if self.ops > MAX_OPS {
                return err(self.lx.pos, "expression too long");
            }
            rest.push((op, self.operand()?));
        }
        if rest.is_empty() {
            return Ok(first);
        }
        let logical = rest
            .iter()
            .any(|(op, _)| matches!(op, BinOp::And | BinOp::Or | BinOp::Xor));
        let arithmetic = rest.iter().any(|(op, _)| {
            matches!(
                op,
                BinOp::Pow | BinOp::Mul | BinOp::Div | BinOp::Mod | BinOp::Add | BinOp::Sub
            )
        });
        if logical && arithmetic {
            return Ok(Expr::Mixed(Box::new((first, rest))));
        }
        Ok(reduce(first, rest, BinOp::precedence))
    }

    /// After `#` (at `start`): `target = value`. The value may be an expression without
    /// brackets (Fanuc macro B: `#1=#2*#3+1`), read with Fanuc's precedence.
    fn assignment(&mut self, start: usize) -> PResult<Assignment> {
        let target = self.param_ref()?;
        let (t, s) = self.lx.next(false)?;
        if t != Tok::Equals {
            return err(
                s.start,
                "expected '=' after a parameter (a parameter can only be set here)",
            );
        }
        let (value, bare) = self.bare_expr()?;
        Ok(Assignment {
            target,
            value,
            bare,
            span: Span::new(start, self.lx.pos),
        })
    }

    /// A value, then any `+ - * / MOD AND OR XOR` and further values without brackets (Fanuc
    /// macro B). Fanuc precedence: `* / AND MOD` before `+ - OR XOR`, left to right. True
    /// when there was at least one operator.
    fn bare_expr(&mut self) -> PResult<(Expr, bool)> {
        let first = self.value()?;
        let mut rest: Vec<(BinOp, Expr)> = Vec::new();
        loop {
            let at = self.lx.after_blanks(self.lx.pos);
            let (op, len) = match self.lx.byte(at) {
                Some(b'+') => (BinOp::Add, 1),
                Some(b'-') => (BinOp::Sub, 1),
                Some(b'*') if self.lx.byte(at + 1) != Some(b'*') => (BinOp::Mul, 1),
                Some(b'/') => (BinOp::Div, 1),
                Some(c) if c.is_ascii_alphabetic() => match self.lx.peek_ident().as_str() {
                    "MOD" => (BinOp::Mod, 3),
                    "AND" => (BinOp::And, 3),
                    "OR" => (BinOp::Or, 2),
                    "XOR" => (BinOp::Xor, 3),
                    _ => break,
                },
                _ => break,
            };
            self.ops += 1;
            if self.ops > MAX_OPS {
                return err(at, "expression too long");
            }
            self.lx.pos = at + len;
            rest.push((op, self.value()?));
        }
        if rest.is_empty() {
            return Ok((first, false));
        }
        Ok((reduce(first, rest, fanuc_precedence), true))
    }

    /// `[condition]` after IF or WHILE.
    fn condition(&mut self, keyword: &str) -> PResult<Expr> {
        let (t, s) = self.lx.next(false)?;
        if t != Tok::LBracket {
            return err(s.start, format!("{keyword} needs a [condition]"));
        }
        let e = self.expr(0)?;
        self.expect_rbracket()?;
        Ok(e)
    }

    /// The loop number after DO or END: a whole number 1..=99.
    fn loop_id(&mut self, keyword: &str) -> PResult<u32> {
        self.lx.skip_ws();
        let at = self.lx.pos;
        match self.lx.byte(at) {
            Some(b'0'..=b'9') => {
                let (v, point, end) = self.lx.number_at(at)?;
                if point || !(1.0..=99.0).contains(&v) {
                    return err(at, format!("{keyword}{v}: the loop number must be 1..99"));
                }
                self.lx.pos = end;
                Ok(v as u32)
            }
            _ => err(
                at,
                format!("{keyword} needs a loop number ({keyword}1, {keyword}2, ...)"),
            ),
        }
    }

    /// After `#`: `123`, `<name>`, `[expr]`, or `#...` (indirect).
    fn param_ref(&mut self) -> PResult<ParamRef> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return err(self.lx.pos, "parameter reference nested too deeply");
        }
        let (tok, span) = self.lx.next(false)?;
        let r = match tok {
            Tok::Number { value, has_point } => {
                Ok(ParamRef::Numbered(Expr::Number { value, has_point }))
            }
            Tok::Name(n) => Ok(ParamRef::Named(n)),
            Tok::LBracket => {
                let e = self.expr(0)?;
                self.expect_rbracket()?;
                Ok(ParamRef::Numbered(e))
            }
            Tok::Hash => {
                let inner = self.param_ref()?;
                Ok(ParamRef::Numbered(Expr::Param(Box::new(inner))))
            }
            t => err(
                span.start,
                format!(
                    "expected a parameter number or <name> after '#', found {}",
                    tok_name(&t)
                ),
            ),
        };
        self.depth -= 1;
        r
    }
}

/// Where parsed lines go: [`BlockList`] keeps every block whole (for [`Program`]);
/// `view::CompactProgram` keeps only what the interpreter runs.
pub(crate) trait BlockSink {
    /// The vector the parser appends the next line's words to.
    fn words(&mut self) -> &mut Vec<Word>;
    /// Takes the parsed line (whatever it needs of it); its words are those appended to
    /// `words()` since the previous call.
    fn push(&mut self, block: &mut Block);
}

/// Every block, whole.
pub(crate) struct BlockList {
    pub blocks: Vec<Block>,
    /// Words of the current line, moved into an exactly sized Vec per block: blocks have few
    /// words, and growing each block's Vec would reserve room for four.
    words: Vec<Word>,
}

impl BlockList {
    pub fn with_capacity(lines: usize) -> Self {
        BlockList {
            blocks: Vec::with_capacity(lines),
            words: Vec::new(),
        }
    }
}

impl BlockSink for BlockList {
    fn words(&mut self) -> &mut Vec<Word> {
        &mut self.words
    }
    fn push(&mut self, block: &mut Block) {
        let mut block = std::mem::take(block);
        block.words = self.words.drain(..).collect();
        self.blocks.push(block);
    }
}

/// Number of lines (blocks) in a source.
pub(crate) fn line_count(source: &str) -> usize {
    count_newlines(source.as_bytes()) + 1
}

/// Split the source into lines, parse each one and hand it to `sink`. Returns the summary and
/// the syntax errors that fail the whole program: those of O-word and macro statement lines
/// (the control flow is laid out before the program runs) and unclosed comments (LinuxCNC
/// checks those on every line it reads, skipped or not). Any other line's error goes to
/// [`Summary::deferred`], raised only if the line is executed: rs274 parses a line when it
/// runs it, so a typo in a branch never taken does not stop the program.
pub(crate) fn parse_blocks(source: &str, sink: &mut impl BlockSink) -> (Summary, Vec<Diagnostic>) {
    parse_lines(source, &mut LineCursor::default(), usize::MAX, sink)
}

/// Where a parse of part of a source stopped: the next line's byte, index, and the `%`
/// lines seen (after the second, every line is after the end).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct LineCursor {
    pub start: usize,
    pub index: usize,
    pub percents: u32,
}

impl LineCursor {
    /// No line is left.
    pub fn at_end(&self, source: &str) -> bool {
        self.start >= source.len()
    }
}

/// [`parse_blocks`] of at most `max_lines` lines from `cursor`, which is left at the next
/// line: a program is parsed a window at a time (see `view::CompactProgram::parse_window`).
/// Block indices, lines and spans are those of the whole source.
pub(crate) fn parse_lines(
    source: &str,
    cursor: &mut LineCursor,
    max_lines: usize,
    sink: &mut impl BlockSink,
) -> (Summary, Vec<Diagnostic>) {
    let mut errors = Vec::new();
    let mut summary = Summary::default();
    let bytes = source.as_bytes();
    let LineCursor {
        mut start,
        mut index,
        mut percents,
    } = *cursor;
    let mut lines = 0;
    while start < source.len() && lines < max_lines {
        lines += 1;
        // A plain loop: G-code lines are short, shorter than memchr's set-up pays for.
        let nl = bytes[start..].iter().position(|&b| b == b'\n');
        let (content_end, end) = match nl {
            Some(i) => {
                let e = start + i;
                let ce = if e > start && bytes[e - 1] == b'\r' {
                    e - 1
                } else {
                    e
                };
                (ce, e + 1)
            }
            None => (source.len(), source.len()),
        };
        let line = index as u32 + 1;
        let mut block = Block {
            line,
            span: Span::new(start, content_end),
            end,
            ..Block::default()
        };
        let words = sink.words();
        let first_word = words.len();
        if percents >= 2 {
            block.after_end = true;
        } else {
            if let Err(e) = parse_line(source, &mut block, words) {
                let col = source[start..e.pos.min(content_end).max(start)]
                    .chars()
                    .count() as u32
                    + 1;
                let d = Diagnostic::new(line, col, e.message);
                if e.control || d.message.starts_with(UNCLOSED_COMMENT) {
                    errors.push(d);
                } else {
                    summary.deferred.push((index, d));
                }
            }
        }
        if block.percent {
            percents += 1;
        }
        summary.add(index, &block, &sink.words()[first_word..]);
        sink.push(&mut block);
        start = end;
        index += 1;
    }
    *cursor = LineCursor {
        start,
        index,
        percents,
    };
    (summary, errors)
}

/// Number of `\n` bytes; counts in byte-wide lanes so that it vectorises.
fn count_newlines(bytes: &[u8]) -> usize {
    bytes
        .chunks(255)
        .map(|chunk| usize::from(chunk.iter().fold(0u8, |n, &b| n + u8::from(b == b'\n'))))
        .sum::<usize>()
}

fn parse_line(source: &str, block: &mut Block, words: &mut Vec<Word>) -> PResult<()> {
    let mut p = LineParser {
        lx: Lexer::new(source, block.span.start, block.span.end),
        depth: 0,
        ops: 0,
    };
    // A UTF-8 byte-order mark (Windows editors write one) is no part of the first block.
    if block.span.start == 0 && source[..block.span.end].starts_with('\u{feff}') {
        p.lx.pos = '\u{feff}'.len_utf8();
    }
    if p.lx.peek_byte() == Some(b'/') {
        p.lx.next(false)?;
        block.block_delete = true;
    }
    if p.lx.peek_byte() == Some(b'%') {
        let percent_at = p.lx.pos;
        p.lx.next(false)?;
        block.percent = true;
        // A program number or name written on to it (`%123`, `%O1234`: the start line of
        // NUM and Fagor ISO programs and of some DNC senders) names the program; only
        // comments may follow.
        let mut i = p.lx.pos;
        while matches!(p.lx.byte(i), Some(c) if c.is_ascii_alphanumeric() || matches!(c, b'_' | b'-' | b'.'))
        {
            i += 1;
        }
        let name = &source.as_bytes()[p.lx.pos..i];
        block.percent_program_number = name.len() > 1
            && matches!(name[0], b'O' | b'o')
            && name[1..].iter().all(u8::is_ascii_digit);
        p.lx.pos = i;
        // `%name = value` is a CNCjs (or bCNC) sender's macro line, not G-code.
        let eq = p.lx.after_blanks(i);
        if p.lx.byte(eq) == Some(b'=') {
            return err(
                percent_at,
                "a '%' line with an assignment is a CNCjs or bCNC sender macro, not G-code: \
                 not supported (the sender evaluates it; remove it or run the program through \
                 the sender's output)",
            );
        }
        return rest_comments(
            &mut p,
            block,
            " ('%' marks the start or end of the program and stands alone on its line)",
        );
    }
    // N word: only first in the block.
    if matches!(p.lx.peek_byte(), Some(b'n' | b'N')) {
        let letter_start = p.lx.pos;
        let vstart = p.lx.after_blanks(letter_start + 1);
        p.lx.pos = vstart;
        if !matches!(p.lx.byte(vstart), Some(b'0'..=b'9' | b'.')) {
            let (_, s) = p.lx.next(false)?;
            return err(s.start, "N must be followed by a line number");
        }
        let (value, has_point, end) = match p.lx.simple_number_at(vstart) {
            Some(number) => number,
            None => p.lx.number_at(vstart)?,
        };
        p.lx.pos = end;
        block.line_number = Some(Word {
            letter: 'N',
            comma: false,
            value: Expr::Number { value, has_point },
            span: Span::new(letter_start, end),
            value_span: Span::new(vstart, end),
        });
    }
    if matches!(p.lx.peek_byte(), Some(b'o' | b'O' | b':')) {
        return o_line(&mut p, block).map_err(LexError::in_control_line);
    }
    let first_word = words.len();
    loop {
        if let Some(word) = p.plain_word() {
            words.push(word);
            continue;
        }
        if p.lx.peek_byte().is_none() {
            break;
        }
        // A word is a letter then a value, so two letters in a row at the start of a line
        // begin a macro statement (if anything). Off the fast path: plain words never get here.
        if words.len() == first_word && block.assignments.is_empty() {
            let at = p.lx.pos;
            if p.lx.byte(at + 1).is_some_and(|b| b.is_ascii_alphabetic()) {
                if let Some(kw) = MACRO_KEYWORDS.iter().find(|kw| p.lx.keyword_at(at, kw)) {
                    return macro_line(&mut p, block, kw, kw.len())
                        .map_err(LexError::in_control_line);
                }
                if let Some((abbr, kw)) = MACRO_ABBREVIATIONS
                    .iter()
                    .find(|(abbr, _)| p.lx.keyword_at(at, abbr))
                {
                    return macro_line(&mut p, block, kw, abbr.len())
                        .map_err(LexError::in_control_line);
                }
            }
        }
        let (tok, span) = p.lx.next(false)?;
        match tok {
            Tok::End => break,
            Tok::Comment(text) => block.comments.push(Comment { text, span }),
            Tok::Letter(c) => {
                let word = p.letter_word(c, span.start)?;
                words.push(word);
            }
            Tok::Comma => {
                let (t, s) = p.lx.next(false)?;
                let Tok::Letter(c) = t else {
                    return err(s.start, "expected R or C after ',' (Fanuc corner word)");
                };
                if c != 'R' && c != 'C' {
                    return err(
                        s.start,
                        format!("',{c}' is not a corner word (only ,R and ,C)"),
                    );
                }
                p.lx.skip_ws();
                let vstart = p.lx.pos;
                let value = p.value()?;
                words.push(Word {
                    letter: c,
                    comma: true,
                    value,
                    span: Span::new(span.start, p.lx.pos),
                    value_span: Span::new(vstart, p.lx.pos),
                });
            }
            Tok::Hash => {
                let a = p.assignment(span.start)?;
                block.assignments.push(a);
            }
            Tok::Slash => {
                return err(
                    span.start,
                    "unexpected '/': block delete '/' only starts a block (before its N word); '//' comments are not G-code",
                )
            }
            t => return err(span.start, format!("unexpected {}", tok_name(&t))),
        }
    }
    Ok(())
}

/// Keywords that start a Fanuc macro B statement line.
const MACRO_KEYWORDS: [&str; 9] = [
    "IF", "WHILE", "GOTO", "END", "DO", "DPRNT", "BPRNT", "POPEN", "PCLOS",
];

/// The two-letter forms a Fanuc control takes for its statement keywords (the custom macro
/// manual's abbreviations: `WH[#1 GT 0]DO1`, `GO10`, `EN1`, `IF[..]TH #1=2`). Each is two
/// letters no G-code word can start with.
const MACRO_ABBREVIATIONS: [(&str, &str); 3] = [("WH", "WHILE"), ("GO", "GOTO"), ("EN", "END")];

/// A Fanuc macro B statement line starting with `kw` (upper case), written in `len` bytes
/// (the keyword or its abbreviation), not yet consumed.
fn macro_line(p: &mut LineParser, block: &mut Block, kw: &str, len: usize) -> PResult<()> {
    p.lx.skip_ws();
    let start = p.lx.pos;
    p.lx.pos += len;
    let statement = match kw {
        "GOTO" => MacroStatement::Goto(p.value()?),
        "IF" => {
            let cond = p.condition("IF")?;
            let at = p.lx.after_blanks(p.lx.pos);
            let ident = p.lx.peek_ident();
            match ident.as_str() {
                "GOTO" | "GO" => {
                    p.lx.pos = at + ident.len();
                    MacroStatement::IfGoto {
                        cond,
                        target: p.value()?,
                    }
                }
                "THEN" | "TH" => {
                    p.lx.pos = at + ident.len();
                    let (t, s) = p.lx.next(false)?;
                    if t != Tok::Hash {
                        return err(s.start, "IF [..] THEN needs an assignment: THEN #i = value");
                    }
                    let a = p.assignment(s.start)?;
                    block.assignments.push(a);
                    MacroStatement::IfThen { cond }
                }
                _ => {
                    return err(
                        at,
                        "IF [condition] must be followed by GOTO n or THEN #i = value",
                    )
                }
            }
        }
        "WHILE" => {
            let cond = p.condition("WHILE")?;
            let at = p.lx.after_blanks(p.lx.pos);
            if p.lx.peek_ident() != "DO" {
                return err(at, "WHILE [condition] must be followed by DO1, DO2 or DO3");
            }
            p.lx.pos = at + 2;
            MacroStatement::While {
                cond,
                id: p.loop_id("DO")?,
            }
        }
        "DO" => MacroStatement::Do {
            id: p.loop_id("DO")?,
        },
        "END" => MacroStatement::End {
            id: p.loop_id("END")?,
        },
        "DPRNT" | "BPRNT" => {
            // The argument is free text with its own format syntax: skip to the closing ']'.
            let open = p.lx.after_blanks(p.lx.pos);
            if p.lx.byte(open) != Some(b'[') {
                return err(open, format!("{kw} needs [ .. ]"));
            }
            let mut depth = 0;
            let mut i = open;
            loop {
                match p.lx.byte(i) {
                    Some(b'[') => depth += 1,
                    Some(b']') => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    Some(_) => {}
                    None => return err(open, format!("{kw}[ is not closed: missing ']'")),
                }
                i += 1;
            }
            p.lx.pos = i + 1;
            MacroStatement::Output(kw.to_string())
        }
        _ => MacroStatement::Output(kw.to_string()),
    };
    block.macro_line = Some(Box::new(MacroLine {
        statement,
        span: Span::new(start, p.lx.pos),
    }));
    rest_comments(
        p,
        block,
        " (a macro statement stands alone in its block: one IF, WHILE, GOTO, DO or END per line)",
    )
}

/// Comments to the end of the line; anything else is an error, `why` saying what may not
/// share the line.
fn rest_comments(p: &mut LineParser, block: &mut Block, why: &str) -> PResult<()> {
    loop {
        let (tok, span) = p.lx.next(false)?;
        match tok {
            Tok::End => return Ok(()),
            Tok::Comment(text) => block.comments.push(Comment { text, span }),
            t => {
                return err(
                    span.start,
                    format!("unexpected {} on this line{why}", tok_name(&t)),
                )
            }
        }
    }
}

fn o_line(p: &mut LineParser, block: &mut Block) -> PResult<()> {
    // `:1234` is the ISO form of a program number `O1234`.
    let colon = p.lx.peek_byte() == Some(b':');
    let os = if colon {
        let start = p.lx.pos;
        p.lx.pos += 1;
        Span::new(start, start + 1)
    } else {
        p.lx.next(false)?.1
    };
    let (t, s) = p.lx.next(false)?;
    let name = match t {
        Tok::Number { value, .. } if value.fract() == 0.0 && value <= u32::MAX as f64 => {
            OName::Number(value as u32)
        }
        Tok::Name(n) => OName::Named(n),
        t => {
            return err(
                s.start,
                format!("O word needs a number or <name>, found {}", tok_name(&t)),
            )
        }
    };
    let mut kw_text = p.lx.peek_ident();
    if colon && (!kw_text.is_empty() || !matches!(name, OName::Number(_))) {
        return err(
            os.start,
            "':' starts a program number (:1234, the same as O1234); it takes no name or keyword",
        );
    }
    let keyword = if kw_text.is_empty() {
        OKeyword::ProgramNumber
    } else {
        let at = p.lx.pos;
        // LinuxCNC reads a line without its blanks: `else if` is `elseif`, `end while`
        // `endwhile`. Words are joined while they make a longer keyword.
        let mut end = at + kw_text.len();
        loop {
            let j = p.lx.after_blanks(end);
            let mut k = j;
            let mut next = String::new();
            while let Some(b) = p.lx.byte(k).filter(u8::is_ascii_alphabetic) {
                next.push(b.to_ascii_uppercase() as char);
                k += 1;
            }
            let joined = format!("{kw_text}{next}");
            if j == end || next.is_empty() || OKeyword::from_name(&joined).is_none() {
                break;
            }
            kw_text = joined;
            end = k;
        }
        let Some(k) = OKeyword::from_name(&kw_text) else {
            return err(at, format!("unknown O-word keyword '{kw_text}'"));
        };
        p.lx.pos = end;
        k
    };
    let mut args = Vec::new();
    // Bracketed arguments: any number for call, at most one for the others.
    loop {
        match p.lx.peek_byte() {
            Some(b'[') => {
                let at = p.lx.pos;
                p.lx.next(false)?;
                let e = p.expr(0)?;
                p.expect_rbracket()?;
                let allowed = match keyword {
                    OKeyword::Call => usize::MAX,
                    OKeyword::While
                    | OKeyword::If
                    | OKeyword::ElseIf
                    | OKeyword::Repeat
                    | OKeyword::Return
                    | OKeyword::EndSub => 1,
                    _ => 0,
                };
                if args.len() >= allowed {
                    return err(at, format!("unexpected argument after {kw_text}"));
                }
                args.push(e);
            }
            _ => break,
        }
    }
    if matches!(
        keyword,
        OKeyword::While | OKeyword::If | OKeyword::ElseIf | OKeyword::Repeat
    ) && args.is_empty()
    {
        return err(p.lx.pos, format!("{kw_text} needs a condition in brackets"));
    }
    block.o_word = Some(OWord {
        name,
        keyword,
        args,
        span: Span::new(os.start, p.lx.pos),
    });
    rest_comments(
        p,
        block,
        " (an O-word line holds only the O-word and comments)",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Wherever the fast path takes a word, the general path reads the same word and ends at
    /// the same place.
    fn line_parser(line: &str) -> LineParser<'_> {
        LineParser {
            lx: Lexer::new(line, 0, line.len()),
            depth: 0,
            ops: 0,
        }
    }

    #[test]
    fn plain_word_agrees_with_general_path() {
        const CHARS: &[u8] = b"XxYGgNOSF0123456789..--+  \t[]#<>*()eE";
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut taken = 0;
        for _ in 0..300_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let len = 1 + (x % 12) as usize;
            let line: String = (0..len)
                .map(|k| CHARS[((x >> (5 * k)) % CHARS.len() as u64) as usize] as char)
                .collect();
            let mut fast = line_parser(&line);
            let Some(word) = fast.plain_word() else {
                assert_eq!(fast.lx.pos, 0, "{line:?}: consumed input without a word");
                continue;
            };
            taken += 1;
            let mut general = line_parser(&line);
            let Ok((Tok::Letter(c), span)) = general.lx.next(false) else {
                panic!("{line:?}: no letter");
            };
            let expected = general.letter_word(c, span.start).ok();
            assert_eq!(Some(&word), expected.as_ref(), "{line:?}");
            if let (Expr::Number { value: a, .. }, Some(Expr::Number { value: b, .. })) =
                (&word.value, expected.as_ref().map(|w| &w.value))
            {
                assert_eq!(a.to_bits(), b.to_bits(), "{line:?}");
            }
            assert_eq!(fast.lx.pos, general.lx.pos, "{line:?}");
        }
        assert!(taken > 10_000, "only {taken} lines took the fast path");
    }
}
