//! The interpreter: runs a [`Program`] block by block with full modal state and produces
//! [`Move`]s in the machine frame. It follows LinuxCNC 2.9's rs274ngc interpreter (order of
//! execution within a block, canned cycle motions, arc tolerances), which the tests compare
//! against, plus the Fanuc differences selected by the dialect.

use super::expr::Params;
use super::program::Program;
use super::view::ProgramView;
use super::{
    Diagnostic, Diagnostics, Dialect, FeedMode, InterpretOptions, Interpretation, Move, MoveKind,
    SpindleDir,
};

mod arcs;
mod block;
mod comp;
mod control;
mod coords;
mod corners;
mod cycles;
mod macro_b;
mod modal;
mod params;
mod polar;
mod splines;
mod stream;
mod subprograms;
mod tilted_plane;
mod tool;
mod transforms;
mod units;
mod words;

use control::{prescan, ControlMap};
use corners::PendingCorner;
use modal::{Modal, Motion, Plane};
pub(crate) use stream::{interpret_streamed, scan, Scan};
use words::{letter_index, Words};

/// Executed blocks between two looks at the cancel flag: an atomic load is cheap, but not
/// free on every block, and a few thousand blocks take well under a millisecond.
const CANCEL_CHECK_BLOCKS: usize = 4096;

const MM_PER_INCH: f64 = 25.4;
/// LinuxCNC's retract between pecks in G73/G83, inches.
const G83_RAPID_DELTA_INCH: f64 = 0.010;
const MAX_CALL_DEPTH: usize = 64;
/// Extended work offset sets (Haas G154 P1..P99; Fanuc G54.1 P1..P48).
const EXTENDED_CS: usize = 99;
/// Work coordinate systems: G54..G59.3 then the extended sets.
const CS_COUNT: usize = 9 + EXTENDED_CS;
/// Most full turns accepted in one arc (P word).
const MAX_ARC_TURNS: f64 = 10_000.0;

struct Interp<'p> {
    /// The file being run: the program itself or a library file (`units.unit`).
    prog: &'p ProgramView<'p>,
    /// `prog` has lines with a syntax error raised when executed (one flag read per block).
    deferred_here: bool,
    /// Control structure links, subroutines and Fanuc programs of `prog`.
    control: &'p ControlMap,
    /// The program itself and its links (unit 0).
    main: &'p ProgramView<'p>,
    main_control: &'p ControlMap,
    /// Library files loaded for this run: unit k is `lib[k - 1]`.
    lib: &'p [units::LibUnit<'p>],
    /// Which file runs, and where its moves are attributed.
    units: units::UnitState,
    opts: &'p InterpretOptions,
    fanuc: bool,
    corners_without_comma: bool,
    /// Modal state that M70/M72 save and restore (units, distance and feed modes, plane,
    /// retract mode, coordinate system, F, S and spindle).
    modal: Modal,
    /// M70 saved state.
    saved_modal: Option<Modal>,
    /// The motion mode, the one before the current block and the last G0/G1/G2/G3 mode.
    motion: modal::MotionModes,
    /// Current position, program coordinates in program units (as LinuxCNC keeps it).
    cur: [f64; 6],
    /// Where program coordinates are in the machine frame, and the home positions.
    coords: coords::Coords,
    /// Fanuc G16 polar mode.
    polar: polar::PolarState,
    /// A G5.2 NURBS being defined.
    nurbs: Option<splines::NurbsInProgress>,
    /// The tool in the spindle, the ones selected, its offsets and the offsets' table.
    tool: tool::ToolState,
    /// Cutter radius compensation (G41/G42, G40).
    comp: comp::CompState,
    /// Canned cycle values kept between blocks.
    cycle: cycles::CycleState,
    params: Params,
    /// Calls, loops, jumps and the program's end.
    flow: control::Flow,
    /// The moves and warnings made so far.
    out: Output,
    pending_corner: Option<PendingCorner>,
    /// Block being executed (index, line) for moves and errors.
    cur_block: usize,
    cur_line: u32,
    /// Storage for the next block's G and M lists.
    spare: block::SpareLists,
}

/// What a run makes: moves and warnings.
struct Output {
    moves: Vec<Move>,
    /// Moves already handed out of `moves` (a streamed program's, see `stream.rs`).
    moves_sent: usize,
    warnings: Vec<Diagnostic>,
    /// Non-standard M codes already warned about.
    warned_m_codes: std::collections::HashSet<u32>,
    /// Tool numbers whose compensation radius came from the job's tools, warned about.
    warned_radii: std::collections::HashSet<u32>,
}

type R<T> = Result<T, Diagnostic>;

/// Where a run stands: the next block and the blocks run so far (`max_blocks`).
#[derive(Clone, Copy, Debug, Default)]
struct RunPosition {
    pc: usize,
    steps: usize,
}

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
        Dialect::Auto => detect_fanuc(prog.summary()),
    };
    let Some(library) = options.library.as_deref().filter(|l| !l.is_empty()) else {
        return run_units(prog, &control, &[], fanuc, options).map_err(|(d, _)| d);
    };
    // The library files the program's calls name, loaded before the run; a call computed
    // at run time to a file not loaded makes the run start again with it (rare, and
    // interpretation is fast).
    let mut wanted = units::called_files(prog, library, fanuc);
    loop {
        let parsed = units::parse_files(library, &wanted);
        let lib = units::load(library, &wanted, &parsed);
        match run_units(prog, &control, &lib, fanuc, options) {
            Err((_, Some(file))) if !wanted.contains(&file) => {
                wanted.push(file);
                for f in units::called_files_of(library, file, fanuc) {
                    if !wanted.contains(&f) {
                        wanted.push(f);
                    }
                }
            }
            r => return r.map_err(|(d, _)| d),
        }
    }
}

/// One run over the program, with `lib` the library files loaded. On error, also the
/// library file a call needed that `lib` does not hold.
fn run_units(
    prog: &ProgramView,
    control: &ControlMap,
    lib: &[units::LibUnit],
    fanuc: bool,
    options: &InterpretOptions,
) -> Result<Interpretation, (Diagnostics, Option<usize>)> {
    let mut it = Interp::new(
        prog,
        control,
        lib,
        fanuc,
        options,
        !prog.summary().deferred.is_empty(),
        // Most programs make about one move per block.
        prog.len(),
    );
    match it.run() {
        Ok(()) => Ok(it.into_interpretation(prog.summary(), prog.len())),
        Err(d) => Err((Diagnostics(vec![d]), it.units.missing)),
    }
}

impl<'p> Interp<'p> {
    /// The interpreter at the program's start: power-up modal state, the setup's work
    /// offsets and start position. `deferred_here`: the program has lines whose syntax
    /// error is raised when they run; `move_capacity`: moves expected.
    fn new(
        prog: &'p ProgramView<'p>,
        control: &'p ControlMap,
        lib: &'p [units::LibUnit<'p>],
        fanuc: bool,
        options: &'p InterpretOptions,
        deferred_here: bool,
        move_capacity: usize,
    ) -> Interp<'p> {
        let mut it = Interp {
            prog,
            deferred_here,
            control,
            main: prog,
            main_control: control,
            lib,
            units: Default::default(),
            opts: options,
            fanuc,
            corners_without_comma: options.fanuc_corners_without_comma,
            modal: Modal {
                metric: true,
                absolute: true,
                arc_absolute: false,
                feed_mode: FeedMode::PerMin,
                plane: Plane::XY,
                // LinuxCNC starts in G99 (rs274 retracts to R); a Fanuc control powers up in G98.
                retract_r_plane: !fanuc,
                cs: 0,
                feed_word: 0.0,
                feed_factor: 1.0,
                speed: 0.0,
                spindle: SpindleDir::Off,
            },
            saved_modal: None,
            // A Fanuc (or Haas) control powers up in G00 (parameter 3402#0 clear): `G43 H1 Z50.`
            // before any G0 moves at rapid. LinuxCNC starts with no motion mode.
            motion: modal::MotionModes {
                mode: fanuc.then_some(Motion::Rapid),
                prev: None,
                mode_01: fanuc.then_some(Motion::Rapid),
            },
            cur: [0.0; 6],
            coords: coords::Coords {
                g5x: [[0.0; 6]; CS_COUNT],
                g92: [0.0; 6],
                g92_applied: true,
                g52: [0.0; 6],
                rot_xy: [0.0; CS_COUNT],
                prog_xf: Default::default(),
                tilt: None,
                plain: true,
                g28: [0.0; 6],
                g30: [0.0; 6],
            },
            polar: Default::default(),
            nurbs: None,
            tool: Default::default(),
            comp: comp::CompState {
                active: None,
                plane: Plane::XY,
                exit_start: None,
            },
            cycle: Default::default(),
            params: Params::new(),
            flow: Default::default(),
            out: Output {
                // Most programs make about one move per block.
                moves: Vec::with_capacity(move_capacity.min(options.max_moves)),
                moves_sent: 0,
                warnings: Vec::new(),
                warned_m_codes: Default::default(),
                warned_radii: Default::default(),
            },
            pending_corner: None,
            cur_block: 0,
            cur_line: 1,
            spare: Default::default(),
        };
        if fanuc {
            it.params.init_fanuc();
        }
        // The setup's offsets are there before the first block (and before the start position
        // is read in the active G54 system), as on the control.
        for &(k, [x, y, z]) in &options.work_offsets {
            if k < 9 {
                it.coords.g5x[k][..3].copy_from_slice(&[x, y, z]);
            }
        }
        if let Some([x, y, z]) = options.start_position {
            // Only the setup's work offsets can be active yet (the program's have not run).
            it.cur = it.from_machine([x, y, z, 0.0, 0.0, 0.0]);
            // The machine's reference position is where it stands retracted, never machine
            // zero in the stock: `G91 G28 Z0` retracts Z there, as on the control (G28.1 and
            // G30.1 still store their own).
            it.coords.g28 = [x, y, z, 0.0, 0.0, 0.0];
            it.coords.g30 = it.coords.g28;
        }
        it
    }
}

/// Fanuc-only syntax (macro B, subprogram calls, a program number, `,R` corners, ...) and
/// no LinuxCNC-only syntax (O-word control lines, named parameters, polar words): the
/// reading under which the program can run (see `DialectEvidence`).
fn detect_fanuc(summary: &super::program::Summary) -> bool {
    let d = &summary.dialect;
    d.fanuc && !d.linuxcnc
}

impl Interp<'_> {
    /// The result of a run that ended well; `summary` is the whole program's.
    fn into_interpretation(
        mut self,
        summary: &super::program::Summary,
        block_count: usize,
    ) -> Interpretation {
        // The lines with a syntax error the run never reached: the user should know.
        self.out
            .warnings
            .extend(summary.deferred.iter().map(|(_, d)| {
                Diagnostic::new(
                    d.line,
                    d.col,
                    format!(
                        "{} (this line is never executed, so it does not stop the program)",
                        d.message
                    ),
                )
            }));
        Interpretation {
            moves: self.out.moves,
            warnings: self.out.warnings,
            block_count,
            selected_tools: self.tool.selected_tools,
            library_files: self.lib.iter().map(|u| u.name.to_string()).collect(),
        }
    }

    fn unit(&self) -> f64 {
        if self.modal.metric {
            1.0
        } else {
            MM_PER_INCH
        }
    }

    /// A diagnostic at a byte of the running file. In a library file it is placed at the call
    /// in the program, naming the file, line and column.
    fn err_at(&self, byte: usize, msg: impl Into<String>) -> Diagnostic {
        let d = self.prog.diag(byte, msg);
        if self.units.unit == 0 {
            d
        } else {
            self.in_library(d)
        }
    }

    /// Error at the start of the current block.
    fn err_block(&self, msg: impl Into<String>) -> Diagnostic {
        let b = self.prog.block(self.cur_block);
        self.err_at(b.span.start, msg)
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

    // ----- moves -----

    fn out_feed(&self) -> f64 {
        match self.modal.feed_mode {
            FeedMode::InverseTime => self.modal.feed_word,
            _ => self.modal.feed_word * self.modal.feed_factor,
        }
    }

    fn base_move(&self, kind: MoveKind, start: [f64; 6], end: [f64; 6]) -> Move {
        let mut m = Move {
            block: self.cur_block,
            line: self.cur_line,
            kind,
            end,
            feed: self.out_feed(),
            feed_mode: self.modal.feed_mode,
            spindle: self.modal.speed,
            tool: self.tool.current,
            center: None,
            normal: None,
            clockwise: None,
            tool_length: self.tool.tlo,
            seconds: None,
            tool_axis: None,
            // Under G68.2 the tip is placed in the feature frame whatever the angles.
            tool_tip: self.tool.tcp || self.coords.tilt.is_some(),
            start,
            spindle_dir: self.modal.spindle,
            arc: None,
            source: None,
        };
        // One return path, so the move is built in place (it is large).
        if self.units.unit != 0 {
            self.attribute(&mut m);
        }
        m
    }

    /// Adds a move; with cutter compensation waiting on a move, after it (in order).
    fn push(&mut self, m: Move) -> R<()> {
        if let Some(c) = self.comp.active.as_mut() {
            if !c.queue.is_empty() {
                c.queue.push(comp::Queued {
                    mv: m,
                    kind: comp::QueuedKind::Other,
                });
                return Ok(());
            }
        }
        self.push_now(m)
    }

    fn push_now(&mut self, m: Move) -> R<()> {
        if self.out.moves_sent + self.out.moves.len() >= self.opts.max_moves {
            return Err(self.err_block(format!(
                "program makes more than {} moves (runaway loop?); interpretation stopped",
                self.opts.max_moves
            )));
        }
        self.out.moves.push(m);
        Ok(())
    }

    /// The first move after G40 starts where compensation left the tool.
    #[cold]
    fn take_exit_start(&mut self) -> [f64; 6] {
        self.comp.exit_start.take().expect("checked")
    }

    /// Straight move to `to` (program coordinates).
    fn straight(&mut self, rapid: bool, to: [f64; 6]) -> R<()> {
        if !rapid {
            self.check_feed()?;
        }
        // After G40 the tool is still where compensation left it.
        let start = if self.comp.exit_start.is_some() {
            self.take_exit_start()
        } else {
            self.to_machine(self.cur)
        };
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
        if self.modal.feed_word <= 0.0 {
            return Err(self.err_block(match self.modal.feed_mode {
                FeedMode::InverseTime => {
                    "feed move in inverse time mode (G93) without an F word".to_string()
                }
                // A control's feed at power-on (Fanuc parameter 1411) is not assumed: the
                // program must say it, as LinuxCNC requires.
                _ => "feed move with zero feed rate (no F word yet): give the feed with an F word on this block or before it (a control's feed at power-on is not assumed)".to_string(),
            }));
        }
        if self.modal.feed_mode == FeedMode::PerRev && self.modal.speed <= 0.0 {
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

    fn run(&mut self) -> R<()> {
        self.run_blocks(&mut RunPosition::default())?;
        self.finish()
    }

    /// Runs blocks from `at` on while they are held, and leaves `at` at the next block to
    /// run. True when the program stopped (M2/M30, past its end `%`), false when it ran past
    /// the last block held (a streamed program's window, see `stream.rs`).
    fn run_blocks(&mut self, at: &mut RunPosition) -> R<bool> {
        let RunPosition { mut pc, mut steps } = *at;
        while pc < self.prog.len() && !self.flow.ended {
            steps += 1;
            let b = self.prog.block(pc);
            self.cur_block = pc;
            self.cur_line = b.line;
            if steps.is_multiple_of(CANCEL_CHECK_BLOCKS)
                && self.opts.cancel.as_ref().is_some_and(|c| c.is_cancelled())
            {
                return Err(self.err_block("interpretation cancelled"));
            }
            if steps > self.opts.max_blocks {
                let last = match self.flow.last_jump {
                    Some((line, what)) => format!("; the last jump back was {what} on line {line}"),
                    None => String::new(),
                };
                return Err(self.err_block(format!(
                    "program executed more than {} blocks (endless loop?){last}; interpretation stopped",
                    self.opts.max_blocks
                )));
            }
            if b.after_end {
                *at = RunPosition { pc, steps };
                return Ok(true);
            }
            if b.block_delete && self.opts.block_delete {
                pc += 1;
                continue;
            }
            if self.deferred_here {
                if let Some(d) = self.prog.summary().deferred_error(pc) {
                    return Err(if self.units.unit == 0 {
                        d.clone()
                    } else {
                        self.in_library(d.clone())
                    });
                }
            }
            if let Some(o) = &b.o_word {
                pc = self.exec_oword(self.control, pc, o)?;
            } else if let Some(m) = b.macro_line {
                pc = self.exec_macro(pc, &b, m)?;
            } else {
                if !b.is_empty() {
                    self.exec_block(&b)?;
                }
                pc = match self.flow.jump.take() {
                    Some(to) => to,
                    None => pc + 1,
                };
            }
            if let Some(u) = self.units.next_unit.take() {
                self.enter_unit(u)?;
            }
        }
        *at = RunPosition { pc, steps };
        Ok(self.flow.ended)
    }

    /// The checks at the end of the program, and the moves compensation still holds.
    fn finish(&mut self) -> R<()> {
        if self.units.unit != 0 && !self.flow.ended {
            return Err(self.err_block(
                "the library program ends without M99 (or endsub) returning to its caller",
            ));
        }
        self.comp_finish()?;
        if let Some(pc) = &self.pending_corner {
            return Err(self.err_at(
                pc.word_pos,
                "corner rounding/chamfer at the end of the program: it needs a following G1 move",
            ));
        }
        Ok(())
    }
}
