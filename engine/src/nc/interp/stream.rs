//! Programs that run front to back (no control flow, no calls: `Summary::straight_line`) are
//! read a window of blocks at a time. A first pass checks the whole source and keeps no
//! block (the errors that fail a program, the dialect, the lines whose error is raised only
//! if run); a second parses and runs one window after another and hands moves out as they
//! are made. The interpreter's memory is then a window's, however long the program; a
//! program that jumps is held whole (`interpret_view`), as its jumps may go anywhere.

use super::control::ControlMap;
use super::{detect_fanuc, Interp, RunPosition};
use crate::nc::parser::{self, BlockSink, LineCursor};
use crate::nc::program::{Block, Summary, Word};
use crate::nc::view::{CompactProgram, ProgramView};
use crate::nc::{Diagnostics, Dialect, InterpretOptions, Interpretation, Move};

/// Lines parsed and run at a time: enough that a window's set-up is nothing next to its
/// run, few enough that its blocks stay small (a few hundred kB). Unit tests use windows
/// of 5 lines, so that their programs cross windows.
const WINDOW_LINES: usize = if cfg!(test) { 5 } else { 4096 };

/// What the first pass found.
pub(crate) enum Scan {
    /// The program runs front to back: the summary of all its lines, and their number.
    Straight(Summary, usize),
    /// It has control flow or calls: it is parsed whole.
    Jumps,
}

/// Parsed lines dropped as soon as the summary has them.
struct Discard {
    words: Vec<Word>,
}

impl BlockSink for Discard {
    fn words(&mut self) -> &mut Vec<Word> {
        &mut self.words
    }
    fn push(&mut self, _block: &mut Block) {
        self.words.clear();
    }
}

/// The first pass: stops at the first window with control flow or calls (the whole parse
/// then finds the program's errors).
pub(crate) fn scan(source: &str) -> Result<Scan, Diagnostics> {
    let mut sink = Discard { words: Vec::new() };
    let mut cursor = LineCursor::default();
    let mut summary = Summary::default();
    let mut errors = Vec::new();
    while !cursor.at_end(source) {
        let (s, e) = parser::parse_lines(source, &mut cursor, WINDOW_LINES, &mut sink);
        summary.merge(s);
        errors.extend(e);
        if !summary.straight_line() {
            return Ok(Scan::Jumps);
        }
    }
    if !errors.is_empty() {
        return Err(Diagnostics(errors));
    }
    Ok(Scan::Straight(summary, cursor.index))
}

/// Runs a program the first pass found straight (`summary`, `lines`: what it found), a
/// window at a time; each move goes to `sink` once nothing can change it any more. The
/// result holds no moves.
pub(crate) fn interpret_streamed(
    source: &str,
    summary: &Summary,
    lines: usize,
    options: &InterpretOptions,
    sink: &mut dyn FnMut(Move),
) -> Result<Interpretation, Diagnostics> {
    let fanuc = match options.dialect {
        Dialect::Fanuc => true,
        Dialect::LinuxCnc => false,
        Dialect::Auto => detect_fanuc(summary),
    };
    let control = ControlMap::program_number_only(summary.o_word_blocks.first().copied());
    // What the interpreter points at between two windows.
    let parked = CompactProgram::empty();
    let parked_view = parked.view(source);
    let deferred = !summary.deferred.is_empty();
    let mut it = Interp::new(
        &parked_view,
        &control,
        &[],
        fanuc,
        options,
        deferred,
        WINDOW_LINES,
    );
    let mut window = CompactProgram::empty();
    let mut cursor = LineCursor::default();
    let mut at = RunPosition::default();
    let mut append = false;
    loop {
        window.parse_window(source, &mut cursor, WINDOW_LINES, append)?;
        let view = window.view(source);
        let mut live = it.rebind(&view, &control, options);
        let stopped = live.run_blocks(&mut at)?;
        if stopped || cursor.at_end(source) {
            live.finish()?;
            live.send_moves(sink);
            return Ok(live.into_interpretation(summary, lines));
        }
        // A corner rounding waiting for its next move still changes its block's move and
        // names its block: the window grows until the corner is made.
        append = live.pending_corner.is_some();
        if !append {
            live.send_moves(sink);
        }
        it = live.rebind(&parked_view, &control, options);
    }
}

impl Interp<'_> {
    /// Hands the moves made so far to `sink`.
    fn send_moves(&mut self, sink: &mut dyn FnMut(Move)) {
        self.out.moves_sent += self.out.moves.len();
        for m in self.out.moves.drain(..) {
            sink(m);
        }
    }

    /// The same interpreter reading another window (`prog`): a streamed program calls no
    /// other file, so the program is the only unit.
    fn rebind<'q>(
        self,
        prog: &'q ProgramView<'q>,
        control: &'q ControlMap,
        opts: &'q InterpretOptions,
    ) -> Interp<'q> {
        Interp {
            prog,
            control,
            main: prog,
            main_control: control,
            lib: &[],
            opts,
            deferred_here: self.deferred_here,
            units: self.units,
            fanuc: self.fanuc,
            corners_without_comma: self.corners_without_comma,
            modal: self.modal,
            saved_modal: self.saved_modal,
            motion: self.motion,
            cur: self.cur,
            coords: self.coords,
            polar: self.polar,
            nurbs: self.nurbs,
            tool: self.tool,
            comp: self.comp,
            cycle: self.cycle,
            params: self.params,
            flow: self.flow,
            out: self.out,
            pending_corner: self.pending_corner,
            cur_block: self.cur_block,
            cur_line: self.cur_line,
            spare: self.spare,
        }
    }
}

#[cfg(test)]
mod tests {
    //! Unit tests run with 5-line windows (`WINDOW_LINES`): these programs cross several.
    use crate::nc::{
        interpret, interpret_each, interpret_program, Dialect, InterpretOptions, Program,
    };

    fn options(dialect: Dialect) -> InterpretOptions {
        InterpretOptions {
            dialect,
            ..InterpretOptions::default()
        }
    }

    /// The streamed run gives the moves, warnings and errors of the whole-program run
    /// (`Program::parse` + `interpret_program` holds every block).
    fn assert_streams_like_the_whole(name: &str, source: &str, dialect: Dialect) {
        assert!(
            matches!(super::scan(source), Ok(super::Scan::Straight(..))),
            "{name}: should be streamed"
        );
        let opts = options(dialect);
        let streamed = interpret(source, &opts);
        let whole = Program::parse(source).and_then(|p| interpret_program(&p, &opts));
        match (streamed, whole) {
            (Ok(a), Ok(b)) => {
                assert_eq!(a.moves, b.moves, "{name}");
                assert_eq!(a.warnings, b.warnings, "{name}");
                assert_eq!(a.block_count, b.block_count, "{name}");
                assert_eq!(a.selected_tools, b.selected_tools, "{name}");
            }
            (Err(a), Err(b)) => assert_eq!(a, b, "{name}"),
            (a, b) => panic!("{name}: {:?} vs {:?}", a.err(), b.err()),
        }
    }

    #[test]
    fn windows_give_the_whole_programs_result() {
        let cases = [
            (
                // The ,R corner on line 5 waits past the window's end (lines 6-9 make no
                // move): the window grows until line 10's move makes the corner.
                "corner across windows",
                "O1234\nG21 G90 G17\nG0 X0 Y0\nG1 F100 X5\nG1 X10 ,R2\nM8\n(a)\n(b)\nM9\nG1 Y10\nM30\n",
                Dialect::Auto,
            ),
            (
                // Line 12's syntax error is raised when it runs, in the third window.
                "deferred error in a later window",
                "G21\nG0 X0\nG0 X1\nG0 X2\nG0 X3\nG0 X4\nG0 X5\nG0 X6\nG0 X7\nG0 X8\nG0 X9\nG1 X1 Z\n",
                Dialect::LinuxCnc,
            ),
            (
                // A run-time error in a later window names its line and column.
                "run-time error in a later window",
                "G21\nG0 X0\nG0 X1\nG0 X2\nG0 X3\nG0 X4\nG0 X5\nG0 X6\nG1 X7\n",
                Dialect::LinuxCnc,
            ),
            (
                "lines after M30 and a syntax error never reached",
                "G21\nG0 X1\nG0 X2\nG0 X3\nG0 X4\nG0 X5\nM30\nG0 X9\nG1 X1 Z\n",
                Dialect::LinuxCnc,
            ),
            (
                "after the second %",
                "%\nG21\nG0 X1\nG0 X2\nG0 X3\nG0 X4\nG0 X5\n%\nG0 X9\nG1 X1 Z\n",
                Dialect::Fanuc,
            ),
            (
                "parameters and a chamfer",
                "#1=3\nG21 G0 X0 Y0\nG1 F200 X#1\n#2=[#1*2]\nG1 X#2 ,C1\n\n\nG1 Y5\nG2 X0 Y5 R3\nM2\n",
                Dialect::Fanuc,
            ),
            (
                "corner rounding at the end",
                "G21\nG0 X0 Y0\nG1 F100 X5\nG1 X9\nG1 X10 ,R2\n(end)\n",
                Dialect::Fanuc,
            ),
        ];
        for (name, source, dialect) in cases {
            assert_streams_like_the_whole(name, source, dialect);
        }
        // The run-time error is where the whole run puts it.
        let err = interpret(cases[2].1, &options(Dialect::LinuxCnc)).unwrap_err();
        assert_eq!((err.0[0].line, err.0[0].col), (9, 1), "{err}");
    }

    #[test]
    fn moves_leave_before_the_program_ends_and_the_move_cap_counts_them() {
        // Line 12 fails when run: a streamed program has handed out the moves of the
        // windows before (lines 1-10; a program held whole hands out none).
        let mut source = String::from("G21\n");
        for i in 0..10 {
            source.push_str(&format!("G0 X{i}\n"));
        }
        source.push_str("G1 X10\n");
        let mut handed = Vec::new();
        let err = interpret_each(&source, &options(Dialect::LinuxCnc), &mut |m| {
            handed.push(m.line)
        })
        .unwrap_err();
        assert!(err.0[0].message.contains("feed"), "{err}");
        assert_eq!(handed, (2..=10).collect::<Vec<u32>>());
        // The cap counts the moves already handed out.
        let capped = InterpretOptions {
            max_moves: 7,
            ..options(Dialect::LinuxCnc)
        };
        let err = interpret(&source, &capped).unwrap_err();
        assert!(err.0[0].message.contains("more than 7 moves"), "{err}");
        assert_eq!(err.0[0].line, 9);
    }

    #[test]
    fn programs_that_jump_are_held_whole() {
        for source in [
            "O1\nM98 P2\nM30\nO2\nG0 X1\nM99\n",
            "G0 X1\no100 if [1]\nG0 X2\no100 endif\n",
            "#1=0\nWHILE [#1 LT 2] DO1\n#1=#1+1\nEND1\n",
            "G0 X1\nM[90+8] P5\n",
        ] {
            assert!(
                matches!(super::scan(source), Ok(super::Scan::Jumps)),
                "{source}"
            );
        }
        // A program number alone does not jump.
        assert!(matches!(
            super::scan("O1234\nG0 X1\nM30\n"),
            Ok(super::Scan::Straight(_, 3))
        ));
    }
}
