//! What the interpreter reads of a program, borrowed either from a [`Program`] or from the
//! compact form that [`super::interpret`] parses into. The compact form keeps all words in one
//! vector and drops what only the lossless tree needs (comments, N words, line ends), so
//! parse + interpret allocates a few large vectors instead of one per block and uses about
//! half the memory.

use super::parser::{self, BlockSink};
use super::program::{Assignment, Block, Expr, MacroLine, OWord, Program, Span, Summary, Word};
use super::{Diagnostic, Diagnostics};
use std::ops::Range;

/// One block as the interpreter sees it.
pub(crate) struct BlockView<'a> {
    /// 1-based source line.
    pub line: u32,
    /// The line without its terminator.
    pub span: Span,
    pub block_delete: bool,
    pub after_end: bool,
    pub o_word: Option<&'a OWord>,
    pub macro_line: Option<&'a MacroLine>,
    pub words: &'a [Word],
    pub assignments: &'a [Assignment],
}

impl BlockView<'_> {
    /// True when the block has nothing to execute (blank or comment only).
    pub fn is_empty(&self) -> bool {
        self.o_word.is_none()
            && self.macro_line.is_none()
            && self.words.is_empty()
            && self.assignments.is_empty()
    }
}

/// A program as the interpreter sees it: blocks are made on request from whichever form holds
/// them, so neither form is copied.
pub(crate) struct ProgramView<'a> {
    source: &'a str,
    blocks: Blocks<'a>,
    summary: &'a Summary,
}

enum Blocks<'a> {
    Tree(&'a [Block]),
    Compact(&'a CompactProgram),
}

impl<'a> ProgramView<'a> {
    pub fn of(program: &'a Program) -> Self {
        ProgramView {
            source: program.source(),
            blocks: Blocks::Tree(program.blocks()),
            summary: program.summary(),
        }
    }

    /// Number of blocks (source lines).
    #[inline]
    pub fn len(&self) -> usize {
        match self.blocks {
            Blocks::Tree(blocks) => blocks.len(),
            Blocks::Compact(p) => p.base + p.blocks.len(),
        }
    }

    #[inline]
    pub fn block(&self, index: usize) -> BlockView<'a> {
        match self.blocks {
            Blocks::Tree(blocks) => {
                let b = &blocks[index];
                BlockView {
                    line: b.line,
                    span: b.span,
                    block_delete: b.block_delete,
                    after_end: b.after_end,
                    o_word: b.o_word.as_ref(),
                    macro_line: b.macro_line.as_deref(),
                    words: &b.words,
                    assignments: &b.assignments,
                }
            }
            Blocks::Compact(p) => {
                let b = &p.blocks[index - p.base];
                let range = |r: &Range<u32>| r.start as usize..r.end as usize;
                BlockView {
                    line: b.line,
                    span: b.span,
                    block_delete: b.block_delete,
                    after_end: b.after_end,
                    o_word: b.o_word.map(|i| &p.o_words[i as usize]),
                    macro_line: b.macro_line.map(|i| &p.macro_lines[i as usize]),
                    words: &p.words[range(&b.words)],
                    assignments: &p.assignments[range(&b.assignments)],
                }
            }
        }
    }

    #[inline]
    fn span(&self, index: usize) -> Span {
        match self.blocks {
            Blocks::Tree(blocks) => blocks[index].span,
            Blocks::Compact(p) => p.blocks[index - p.base].span,
        }
    }

    /// The first block held: 0, or the start of the window a streamed program holds.
    #[inline]
    fn first(&self) -> usize {
        match self.blocks {
            Blocks::Tree(_) => 0,
            Blocks::Compact(p) => p.base,
        }
    }

    pub fn summary(&self) -> &Summary {
        self.summary
    }

    /// Source text of a span.
    pub fn text(&self, span: Span) -> &'a str {
        &self.source[span.start..span.end]
    }

    /// The N number of a block, if it has a whole one (read from the source text: the compact
    /// form does not keep N words, and only sequence searches need them).
    pub fn sequence_number(&self, index: usize) -> Option<u32> {
        if let Blocks::Tree(blocks) = self.blocks {
            return match blocks[index].line_number.as_ref().map(|w| &w.value) {
                Some(Expr::Number { value, .. }) if value.fract() == 0.0 => Some(*value as u32),
                _ => None,
            };
        }
        let span = self.span(index);
        let bytes = &self.source.as_bytes()[span.start..span.end];
        let mut i = 0;
        let blanks = |i: &mut usize| {
            while matches!(bytes.get(*i), Some(b' ' | b'\t' | b'\r')) {
                *i += 1;
            }
        };
        blanks(&mut i);
        if bytes.get(i) == Some(&b'/') {
            i += 1;
            blanks(&mut i);
        }
        if !matches!(bytes.get(i), Some(b'N' | b'n')) {
            return None;
        }
        i += 1;
        blanks(&mut i);
        let digits = bytes[i..].iter().take_while(|b| b.is_ascii_digit()).count();
        if digits == 0 || digits > 9 || bytes.get(i + digits) == Some(&b'.') {
            return None;
        }
        std::str::from_utf8(&bytes[i..i + digits])
            .ok()?
            .parse()
            .ok()
    }

    /// A diagnostic at a byte offset, at the position [`Program::position`] gives.
    pub fn diag(&self, byte: usize, message: impl Into<String>) -> Diagnostic {
        let first = self.first();
        let held = self.len() - first;
        // The block starting at or before `byte` (the first block if none does).
        let first_after = first + partition_point(held, |i| self.span(first + i).start <= byte);
        let (line, col) = if first > 0 && (held == 0 || first_after == first) {
            // Before the window a streamed program holds (rare: errors are found on the
            // blocks being run): counted in the source.
            let byte = byte.min(self.source.len());
            let before = &self.source.as_bytes()[..byte];
            let line_start = before
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |i| i + 1);
            let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
            let col = self.source[line_start..byte].chars().count() + 1;
            (u32::try_from(line).unwrap_or(u32::MAX), col as u32)
        } else if held == 0 {
            (1, 1)
        } else {
            let idx = first_after.saturating_sub(1).max(first);
            let b = self.block(idx);
            let end = byte.min(self.source.len()).max(b.span.start);
            let col = self.source[b.span.start..end].chars().count() as u32 + 1;
            (b.line, col)
        };
        Diagnostic::new(line, col, message)
    }
}

/// The first index in `0..len` for which `pred` is false (`pred` true then false, as for
/// `slice::partition_point`).
fn partition_point(len: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, len);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// A block of [`CompactProgram`]: indices into its shared vectors (u32: a source with 2^32
/// words would not fit in memory).
struct CompactBlock {
    line: u32,
    span: Span,
    block_delete: bool,
    after_end: bool,
    o_word: Option<u32>,
    macro_line: Option<u32>,
    words: Range<u32>,
    assignments: Range<u32>,
}

/// The parsed program without the lossless tree: what [`ProgramView`] needs, in a few vectors.
pub(crate) struct CompactProgram {
    /// Index of `blocks[0]` in the whole program: 0, or where a window starts (a streamed
    /// program is held a window of blocks at a time).
    base: usize,
    blocks: Vec<CompactBlock>,
    words: Vec<Word>,
    assignments: Vec<Assignment>,
    o_words: Vec<OWord>,
    macro_lines: Vec<MacroLine>,
    summary: Summary,
    /// Start in `words` of the line being parsed.
    line_words: usize,
}

impl CompactProgram {
    /// Parse a program; the same syntax errors (and deferred ones) as [`Program::parse`].
    pub fn parse(source: &str) -> Result<CompactProgram, Diagnostics> {
        let lines = parser::line_count(source);
        let mut program = CompactProgram {
            base: 0,
            blocks: Vec::with_capacity(lines),
            // CAM output has one or two words per line; the vector grows if not.
            words: Vec::with_capacity(2 * lines),
            assignments: Vec::new(),
            o_words: Vec::new(),
            macro_lines: Vec::new(),
            summary: Summary::default(),
            line_words: 0,
        };
        let (summary, errors) = parser::parse_blocks(source, &mut program);
        if !errors.is_empty() {
            return Err(Diagnostics(errors));
        }
        program.summary = summary;
        Ok(program)
    }

    /// No blocks: a window before its first parse.
    pub fn empty() -> CompactProgram {
        CompactProgram {
            base: 0,
            blocks: Vec::new(),
            words: Vec::new(),
            assignments: Vec::new(),
            o_words: Vec::new(),
            macro_lines: Vec::new(),
            summary: Summary::default(),
            line_words: 0,
        }
    }

    /// Parse up to `max_lines` lines of `source` from `cursor` (left at the next line), in
    /// place of the blocks held (their vectors reused) or, with `append`, after them. The
    /// syntax errors that fail a whole program are returned (a streamed program was checked
    /// for them before it runs); deferred ones are in the window's summary.
    pub fn parse_window(
        &mut self,
        source: &str,
        cursor: &mut parser::LineCursor,
        max_lines: usize,
        append: bool,
    ) -> Result<(), Diagnostics> {
        if !append || self.blocks.is_empty() {
            self.base = cursor.index;
            self.blocks.clear();
            self.words.clear();
            self.assignments.clear();
            self.o_words.clear();
            self.macro_lines.clear();
            self.summary = Summary::default();
            self.line_words = 0;
        }
        let (summary, errors) = parser::parse_lines(source, cursor, max_lines, self);
        self.summary.merge(summary);
        if errors.is_empty() {
            Ok(())
        } else {
            Err(Diagnostics(errors))
        }
    }

    /// The view of this program; `source` is the text it was parsed from.
    pub fn view<'a>(&'a self, source: &'a str) -> ProgramView<'a> {
        ProgramView {
            source,
            blocks: Blocks::Compact(self),
            summary: &self.summary,
        }
    }
}

impl BlockSink for CompactProgram {
    fn words(&mut self) -> &mut Vec<Word> {
        &mut self.words
    }

    fn push(&mut self, block: &mut Block) {
        let index = |i: usize| u32::try_from(i).expect("fewer than 2^32 words in a program");
        let words = index(self.line_words)..index(self.words.len());
        self.line_words = self.words.len();
        let first_assignment = index(self.assignments.len());
        self.assignments.append(&mut block.assignments);
        let o_word = block.o_word.take().map(|o| {
            self.o_words.push(o);
            index(self.o_words.len() - 1)
        });
        let macro_line = if block.macro_line.is_some() {
            block.macro_line.take().map(|m| {
                self.macro_lines.push(*m);
                index(self.macro_lines.len() - 1)
            })
        } else {
            None
        };
        self.blocks.push(CompactBlock {
            line: block.line,
            span: block.span,
            block_delete: block.block_delete,
            after_end: block.after_end,
            o_word,
            macro_line,
            words,
            assignments: first_assignment..index(self.assignments.len()),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::super::{interpret, interpret_program, InterpretOptions, Program};

    /// `interpret` (compact form) and `Program::parse` + `interpret_program` (lossless tree)
    /// give the same moves, warnings and errors.
    fn assert_same(name: &str, source: &str) {
        for dialect in [super::super::Dialect::Auto, super::super::Dialect::LinuxCnc] {
            let opts = InterpretOptions {
                dialect,
                ..InterpretOptions::default()
            };
            let compact = interpret(source, &opts);
            let tree = Program::parse(source).and_then(|p| interpret_program(&p, &opts));
            match (compact, tree) {
                (Ok(a), Ok(b)) => {
                    assert_eq!(a.moves, b.moves, "{name}");
                    assert_eq!(a.warnings, b.warnings, "{name}");
                    assert_eq!(a.block_count, b.block_count, "{name}");
                }
                (Err(a), Err(b)) => assert_eq!(a, b, "{name}"),
                (a, b) => panic!("{name}: {:?} vs {:?}", a.err(), b.err()),
            }
        }
    }

    #[test]
    fn compact_form_interprets_like_the_tree() {
        for (name, source) in [
            ("empty", ""),
            ("syntax errors", "G1 X(\nG1 Y2 Z\n#1=\n"),
            ("error at end", "G21 G90\nG1 X10 F100\nG2 X0 Y0 R1\n"),
            (
                "subs and loops",
                "o100 sub\nG1 X#1 F200\no100 endsub\n#2=0\no101 while [#2 LT 3]\n\
                 o100 call [#2]\n#2=[#2+1]\no101 endwhile\n/G0 Z5 (skipped?)\nM2\n",
            ),
            (
                "fanuc",
                "O1234\nG0 X1 Y1\nG1 X2 ,R0.5 F100\nG1 Y3\nG4 P500\n%\nG1 X5\n%\nG1 Y9\n",
            ),
            ("late error", "G0 X0\nG1 X1 F10\nG1 Q3\n"),
            (
                "fanuc macro",
                "O1\n#1=0\nN10 #1=#1+1\nWHILE [#1 LT 3] DO1\n#1=#1+1\nEND1\n\
                 IF [#1 GE 3] GOTO 20\nG0 X9\nN20 G0 X#1\nG65 P2 A1\nM98 P2 L2\nDPRNT[X#1]\nM30\n\
                 O2\nG91 G0 Y#1\nG90\nM99\n",
            ),
            ("goto missing", "O1\nGOTO 5\nN6 G0 X1\n"),
        ] {
            assert_same(name, source);
        }
        // The G-code corpus and LinuxCNC's sample programs, where installed.
        let mut checked = 0;
        let corpus = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/corpus/gcode");
        for dir in [corpus, "/usr/share/linuxcnc/ncfiles"] {
            for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
                let path = entry.path();
                if let Ok(source) = std::fs::read_to_string(&path) {
                    assert_same(&path.display().to_string(), &source);
                    checked += 1;
                }
            }
        }
        eprintln!("{checked} program files checked");
    }
}
