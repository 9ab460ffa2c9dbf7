//! NC programs: G-code (Fanuc/ISO and LinuxCNC RS274/NGC dialects) into machine moves.
//!
//! * [`Program`] is the syntax: every source line is a block, every word keeps its byte span, and
//!   the original text is kept so that writing it back gives the same bytes (and so F words can be
//!   rewritten in place, see [`Program::with_feeds`]).
//! * [`interpret`] runs a program with full modal state and gives [`Move`]s in the machine (G53)
//!   frame, in mm and degrees whatever the program's units.
//!
//! Anything the interpreter does not support is an error naming the line, column and word;
//! nothing is skipped silently.
//!
//! Semantics follow LinuxCNC 2.9's rs274ngc (checked move by move against it, see
//! `tests/nc_linuxcnc.rs`), with these deliberate differences:
//! * G84/G74 outside G17 tap at the programmed hole (LinuxCNC 2.9 swaps the axes there).
//! * G88's manual retract is emitted as a rapid to the clearance height (with a warning), so the
//!   path stays connected; LinuxCNC makes no move.
//! * `G0 ... G80` in one block is accepted (the Fanuc habit); nested `(...)` comments are
//!   accepted; O labels may be reused by sequential (non-nested) structures.
//! * Dialect Fanuc: G4 P in milliseconds (X in seconds), `,R`/`,C` corners, K as the cycle
//!   repeat count, G98 at start, `O1234` program numbers; implied decimals on request.
//!   Custom macro B: `IF [..] GOTO n`, `IF [..] THEN #i=..`, `WHILE [..] DOm`..`ENDm`, `GOTO n`,
//!   expressions without brackets (Fanuc precedence), vacant variables (#0), the modal and
//!   position system variables (#4001-#4120, #5001-#5046), #3000 alarms, G65 calls with
//!   arguments (specifications I and II), G66/G67 modal calls (after each moving block of the
//!   calling level; nested up to four: a move in the last G66's macro calls the earlier G66's
//!   macro, G67 ends the last first); `DPRNT`/`BPRNT`/`POPEN`/`PCLOS` make no motion (a warning).
//!   Subprograms: several `O` programs in one file, `M98 P.. L..` (and `P31234`), `M99`
//!   (`M99 Pn`), `M99` in the main program ends it (a warning; the control would loop).
//!   The manual's two-letter keywords (`WH[..]DO1`, `GO10`, `EN1`, `IF[..]TH`) are taken.
//!   A `D` on any block selects the radius offset G41/G42 take (`T1 D1 M6`); rotary axis
//!   words in a canned cycle block index with the hole positioning (`G91 A45.` in G81 mode);
//!   the control powers up in G00. `G30 P2..P4` (P3/P4 at the one G30 position, a warning);
//!   `M29` before G84 (rigid tapping) is read without a warning. Extended work offsets Fanuc `G54.1 P1..P48` and Haas
//!   `G154 P1..P99` (zero until `G10 L20 Pn` sets them, absolute in G90, added in G91;
//!   `#4014` reads 54.1 and `#4130` the P number; the #7001/#14001 offset variables are not
//!   readable). Canned cycle data (R, hole bottom, P, Q) carries over
//!   from one cycle code to the next until G80; after G80 a cycle without R has its R point
//!   at the initial level (the manual's R = 0 incremental; a warning) and no P no dwell. A
//!   cycle's P dwell is in ms, as G04 P.
//!   AND/OR/XOR work bit by bit on whole numbers and rank with `*` and `+` (LinuxCNC: logical,
//!   ranked last); the dialect decides when an expression mixes them with arithmetic.
//!
//! * Both dialects: a syntax error on a plain line (not an O-word or macro statement line,
//!   not an unclosed comment) stops the program only when the line is executed, as rs274
//!   reads a line only when it runs it; lines never reached are warnings. `:1234` program
//!   numbers, G10 L1/L10/L11 tool offsets (Fanuc G10 L10-L13
//!   offset memory), G38.2-G38.5 probing (Fanuc's G31 skip, for its block) as a feed move
//!   to the end point (a warning), a Fanuc
//!   G80 returns to the G0/G1/G2/G3 mode from before the cycle (with the dialect left to
//!   auto, also in a program without Fanuc syntax, with a warning: LinuxCNC refuses it),
//!   non-standard M codes run as no-ops with a warning (`strict_m_codes` refuses them).
//!   Look-ahead and smoothing modes (Fanuc G5 P, G5.1 Q, G8 P; Haas G103, G187) make no
//!   motion: a warning, the path as programmed.
//!
//! * Cutter radius compensation G41/G42 (radius from the tool table's diameter, a G10 radius
//!   or the Fanuc offset D, else the caller's tool of that number with a warning: control,
//!   not wear, compensation) and G41.1/G42.1 (D the diameter), G40, in the XY and XZ planes, as
//!   LinuxCNC 2.9 does it in both dialects (entry line or arc, arcs around outside corners,
//!   inside corners trimmed, gouges refused naming the line); checked against LinuxCNC.
//!   In the Fanuc dialect the start-up is the control's default type A: the entry line ends
//!   where the tool stands perpendicular to the next move's start (LinuxCNC: to the entry
//!   line itself, with a corner to the next move), so `G41 X-r` into a `G3 I r` helical hole
//!   works. Types B and C (parameters SUP/SUV) and Fanuc's cancel types are not modelled:
//!   the exit is LinuxCNC's (a line from the compensated point to the programmed end).
//!   The Fanuc dialect's gouge check on compensated arcs is the control's interference check:
//!   refused when the compensated arc turns more than 180 degrees from the programmed one
//!   (LinuxCNC refuses one longer than programmed, and runs one that goes round the other way).
//!
//! * Coordinate transforms (`interp/transforms.rs`, `interp/polar.rs`): LinuxCNC's G10 L2 R
//!   rotation of a coordinate system, G52 (LinuxCNC: the G92 offsets; Fanuc: a local offset of
//!   its own) and `@`/`^` polar words, checked against LinuxCNC; Fanuc G68/G69 rotation,
//!   G51/G50 scaling (P or I/J/K, thousandths without a decimal point), G51.1/G50.1 mirror
//!   image (applied mirror, scaling, rotation, as the manual orders them) and G16/G15 polar
//!   mode (in a G91 canned cycle the angle advances per repeat about the work origin, as
//!   the manual's bolt hole circle `G91 Y120.`; a G91 radius word there is refused). Arcs stay arcs where the transform is a similarity in their plane (a mirror
//!   reverses them); per-axis scaling of an arc or a rotation out of its plane is refused.
//!
//! * Splines (`interp/splines.rs`): G5, G5.1 and G5.2/G5.3 NURBS in G17 as LinuxCNC builds
//!   them, as straight feed moves through points on the curve within `spline_tolerance`.
//!
//! * Fanuc `H` without G43 (`G53 Z0 H0`): the active length compensation takes offset H (H0:
//!   zero).
//!
//! * A program library ([`ProgramLibrary`], `InterpretOptions::library`): calls to programs
//!   not in the file (Fanuc M98/G65/G66, LinuxCNC `o<name> call` to `name.ngc`) run the
//!   library's files; see `library.rs` and `interp/units.rs`. Checked against LinuxCNC run in
//!   the library folder.
//!
//! * Tilted working planes (`interp/tilted_plane.rs`): G68.2 X Y Z I J K (Euler angles, Fanuc's
//!   P0), G53.1 turning the rotary axes normal to the plane with `InterpretOptions::kinematics`,
//!   G69; moves in the plane are tool-tip moves, its G2/G3 chords.
//!
//! Refused with an error naming the feature: Haas G12/G13/G47/G150, G68.3/G68.4 and G68.2 P1-P4,
//! cutter radius compensation in G19, G33, G76, G7/G8 (LinuxCNC), U V W
//! axes, calls to programs neither in the file nor in the library, G66.1, M60,
//! non-standard M codes with `strict_m_codes`
//! (else a warning), writes to the parameters that hold machine state (#5161-#5425).

mod arc;
mod conversational;
mod expr;
mod interp;
mod lexer;
mod library;
mod parser;
mod program;
mod tooltable;
mod view;

pub use arc::{sample_arc, ArcGeometry};
pub use interp::interpret_program;
pub use library::{LibraryFile, ProgramLibrary};
pub(crate) use program::format_feed;
pub use program::{
    Assignment, Block, Comment, Expr, MacroLine, MacroStatement, OKeyword, OName, OWord, ParamRef,
    Program, Span, Word,
};
pub use tooltable::{parse_tool_table, ToolEntry, ToolTable};

use serde::{Deserialize, Serialize};
use std::fmt;

/// Which control's rules apply where Fanuc and LinuxCNC differ (G4 P units, program numbers,
/// `,R`/`,C` corners, canned cycle repeat word, initial retract mode).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Dialect {
    /// Decide from the program: Fanuc-only syntax (program number `O1234`, `,R`/`,C` corners,
    /// `M98`/`M99`) selects Fanuc, anything else LinuxCNC rules.
    #[default]
    Auto,
    Fanuc,
    #[serde(rename = "linuxcnc")]
    LinuxCnc,
}

/// Options of one interpretation.
#[derive(Clone, Debug)]
pub struct InterpretOptions {
    pub dialect: Dialect,
    pub tool_table: ToolTable,
    /// Diameters of the tools the caller cuts with, by number (mm): the radius cutter
    /// compensation takes for a number with no diameter in the tool table and no G10 radius.
    /// Under 0: the caller's one tool, which serves every number (not Fanuc's D0, the zero
    /// offset).
    pub tool_diameters: std::collections::BTreeMap<u32, f64>,
    /// Fanuc "implied decimal": a length/angle word written without a decimal point counts in
    /// least input increments (0.001 mm, 0.0001 inch, 0.001 degree). Off: the LinuxCNC rule
    /// (`X10` is 10 mm).
    pub fanuc_implied_decimal: bool,
    /// Guard against runaway loops: interpretation fails after this many moves.
    pub max_moves: usize,
    /// Guard against loops that make no moves: interpretation fails after executing this many
    /// blocks (each loop iteration counts its blocks again).
    pub max_blocks: usize,
    /// Fanuc parameter CCR (No. 3405#4): corner rounding `R` and chamfer `C` written without the
    /// comma on G1 blocks. With it set, C is no longer an axis address.
    pub fanuc_corners_without_comma: bool,
    /// M codes that are known to the caller's machine but do nothing we can model (e.g. the
    /// LinuxCNC sim's remapped `M428`/`M429` kinematics switches). They are accepted as no-ops
    /// without a word; any other non-standard M code is accepted with a warning (once per code),
    /// or refused with `strict_m_codes`.
    pub passthrough_m_codes: Vec<u32>,
    /// Refuse non-standard M codes not listed in `passthrough_m_codes` instead of warning.
    pub strict_m_codes: bool,
    /// Splines (G5, G5.1, G5.2/G5.3) become straight feed moves whose chords stay within
    /// this distance of the curve, mm.
    pub spline_tolerance: f64,
    /// State of the control's block-delete switch: when on, blocks starting with `/` are skipped.
    pub block_delete: bool,
    /// Checked every few thousand executed blocks: once set, interpretation stops with an
    /// error (the caller, who set it, knows it was a cancel). A runaway loop is thus
    /// stopped at once, not at the move cap.
    pub cancel: Option<crate::job::CancelFlag>,
    /// Programs that calls to programs not in the file run (`M98`, `G65`, `G66`, LinuxCNC
    /// `o<name> call`); see [`ProgramLibrary`]. Shared, as options are cloned per job stage.
    pub library: Option<std::sync::Arc<ProgramLibrary>>,
    /// Where the tool tip stands (machine frame, mm) before the first block: a real machine
    /// starts where the last job or the operator left it, not at program zero. It is also the
    /// G28 and G30 home (until G28.1/G30.1 store others): a machine's reference position is
    /// retracted above the work. None: at program zero, homes at machine zero, as LinuxCNC's
    /// `rs274` starts (the `interpret` job's default).
    pub start_position: Option<[f64; 3]>,
    /// Where an M6 tool change leaves the tip (the next move starts there). None: where it was.
    pub tool_change: Option<ToolChangeTo>,
    /// The machine's kinematics: G53.1 turns its rotary axes so that the tool is normal to
    /// the G68.2 plane. None (or a 3-axis machine): G53.1 is refused.
    pub kinematics: Option<crate::machine::MachineKinematics>,
    /// The job reads X Y Z as the tool tip on every move (`axes: tool_tip`), not only under
    /// G43.4/G68.2. Decides whether G69 with the rotary axes turned has to hand the position
    /// back as machine axes.
    pub tool_tip_reading: bool,
    /// The setup's work offsets before the program starts (what the control's offset table
    /// holds: where each work coordinate system's zero is in the machine frame), mm, by
    /// [`work_offset_index`] (G54 = 0 ... G59.3 = 8). Unlisted systems start at zero; the
    /// program's own G10 L2 / L20 still change them.
    pub work_offsets: Vec<(usize, [f64; 3])>,
    /// Where machine Z zero is (machine frame, mm) for `G53` moves: a mill's Z home is the
    /// top of its travel, above the work, and posts retract there with `G53 G0 Z0.`. None:
    /// at zero, the frame's own (LinuxCNC's `rs274`; a setup that gives its work offsets).
    /// A simulation without work offsets puts it at its start height.
    pub machine_z_home: Option<f64>,
}

/// The work offsets a setup can define: G54 ... G59, G59.1, G59.2, G59.3.
pub const WORK_OFFSET_NAMES: [&str; 9] = [
    "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
];

/// The index of work offset `name` (`G54` = 0 ... `G59.3` = 8) for
/// [`InterpretOptions::work_offsets`].
pub fn work_offset_index(name: &str) -> Option<usize> {
    WORK_OFFSET_NAMES.iter().position(|n| *n == name)
}

/// Where a tool change leaves the tool tip, machine frame, mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ToolChangeTo {
    /// This position.
    Position([f64; 3]),
    /// X and Y stay; Z rises to this height (or stays, when it is already higher).
    RaiseTo(f64),
}

impl Default for InterpretOptions {
    fn default() -> Self {
        InterpretOptions {
            dialect: Dialect::Auto,
            tool_table: ToolTable::default(),
            tool_diameters: Default::default(),
            fanuc_implied_decimal: false,
            max_moves: 10_000_000,
            max_blocks: 50_000_000,
            fanuc_corners_without_comma: false,
            passthrough_m_codes: Vec::new(),
            strict_m_codes: false,
            spline_tolerance: 1e-3,
            block_delete: false,
            cancel: None,
            library: None,
            start_position: None,
            tool_change: None,
            kinematics: None,
            tool_tip_reading: false,
            work_offsets: Vec::new(),
            machine_z_home: None,
        }
    }
}

/// One problem in a program, at a 1-based line and column (column counted in characters).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Diagnostic {
    pub line: u32,
    pub col: u32,
    pub message: String,
}

impl Diagnostic {
    pub fn new(line: u32, col: u32, message: impl Into<String>) -> Self {
        Diagnostic {
            line,
            col,
            message: message.into(),
        }
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.line, self.col, self.message)
    }
}

/// All problems found, in source order.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct Diagnostics(pub Vec<Diagnostic>);

impl fmt::Display for Diagnostics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, d) in self.0.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(f, "{d}")?;
        }
        Ok(())
    }
}

impl From<Diagnostic> for Diagnostics {
    fn from(d: Diagnostic) -> Self {
        Diagnostics(vec![d])
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MoveKind {
    Rapid,
    Linear,
    Arc,
    Dwell,
    ToolChange,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum FeedMode {
    /// mm/min
    #[default]
    PerMin,
    /// 1/min: the move takes 1/F minutes.
    InverseTime,
    /// mm per spindle revolution
    PerRev,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SpindleDir {
    #[default]
    Off,
    Cw,
    Ccw,
}

/// One move. `end` (and `start`) are the tool tip in the machine G53 frame: X Y Z in mm,
/// A B C in degrees. Serializes to the JSON-lines row of the `interpret` job.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Move {
    /// 0-based index of the block (= source line - 1) that produced the move.
    pub block: usize,
    /// 1-based source line.
    pub line: u32,
    pub kind: MoveKind,
    pub end: [f64; 6],
    /// mm/min, 1/min (inverse time) or mm/rev after `feed_mode`; the modal value on rapids.
    pub feed: f64,
    pub feed_mode: FeedMode,
    /// Programmed spindle speed, rev/min (see `spindle_dir` for whether it turns).
    pub spindle: f64,
    /// Tool in the spindle (0: none).
    pub tool: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub center: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clockwise: Option<bool>,
    /// Active G43 tool length offset, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool_length: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    /// Tool axis unit vector (APT/CLS input, part frame).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool_axis: Option<[f64; 3]>,
    /// Tool-centre-point control (G43.4/G43.5) in force: X Y Z are the tool tip on the part
    /// and A/B/C only orient the tool, as `axes: tool_tip` reads a whole program.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub tool_tip: bool,
    #[serde(skip)]
    pub start: [f64; 6],
    #[serde(skip)]
    pub spindle_dir: SpindleDir,
    /// Full arc geometry (arcs only).
    #[serde(skip)]
    pub arc: Option<Box<ArcGeometry>>,
    /// Set when the move's block is in a library program: that file and line. `block` and
    /// `line` are then those of the call in the program itself (the outermost call), so
    /// per-block figures stay on the program's own blocks. Serialized flat, as
    /// `source_file` and `source_line` (a CSV row has a column for each).
    #[serde(flatten)]
    pub source: Option<MoveSource>,
}

/// Where a move from a library program comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MoveSource {
    /// Index into [`Interpretation::library_files`].
    #[serde(rename = "source_file")]
    pub file: u32,
    /// 1-based line in that file.
    #[serde(rename = "source_line")]
    pub line: u32,
}

impl Move {
    /// The largest travel of a rotary axis (A, B or C) over the move, degrees.
    pub fn rotary_travel(&self) -> f64 {
        (3..6)
            .map(|i| (self.end[i] - self.start[i]).abs())
            .fold(0.0, f64::max)
    }

    /// Whether a rotary axis turns during the move.
    pub fn turns_rotary(&self) -> bool {
        self.rotary_travel() > 1e-9
    }
}

/// Result of interpreting a program.
#[derive(Clone, Debug, Default)]
pub struct Interpretation {
    pub moves: Vec<Move>,
    pub warnings: Vec<Diagnostic>,
    /// Number of blocks (source lines) in the program.
    pub block_count: usize,
    /// Every T number a T word selects, with the line of its first selection, in program
    /// order: a program that selects a tool but never loads it (no M6) is cut with it.
    pub selected_tools: Vec<(u32, u32)>,
    /// The library files the program called, as [`MoveSource::file`] indexes them.
    pub library_files: Vec<String>,
}

/// Parse and interpret a program (a program without control flow or calls a window of
/// blocks at a time, see [`interpret_each`]). Same result as [`Program::parse`] then
/// [`interpret_program`], without building the lossless tree the interpreter does not need.
pub fn interpret(source: &str, options: &InterpretOptions) -> Result<Interpretation, Diagnostics> {
    let mut moves = Vec::new();
    let mut out = interpret_each(source, options, &mut |m| moves.push(m))?;
    out.moves = moves;
    Ok(out)
}

/// [`interpret`], handing each move to `on_move` in program order as soon as it is final
/// (the result's `moves` is empty). A program without control flow or calls is read a
/// window of blocks at a time, so the interpreter's memory does not grow with its length;
/// on an error, the moves before it have been handed out.
pub fn interpret_each(
    source: &str,
    options: &InterpretOptions,
    on_move: &mut dyn FnMut(Move),
) -> Result<Interpretation, Diagnostics> {
    conversational::refuse_conversational(source)?;
    match interp::scan(source)? {
        interp::Scan::Straight(summary, lines) => {
            interp::interpret_streamed(source, &summary, lines, options, on_move)
        }
        interp::Scan::Jumps => {
            let program = view::CompactProgram::parse(source)?;
            let mut out = interp::interpret_view(&program.view(source), options)?;
            for m in out.moves.drain(..) {
                on_move(m);
            }
            Ok(out)
        }
    }
}
