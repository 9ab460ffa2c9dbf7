//! Running across files: the program itself (unit 0) and the library files its calls reach
//! (see [`crate::nc::ProgramLibrary`]). Each file keeps its own blocks and control links; a
//! call switches the running file after the calling block, a return switches back.
//!
//! A library file's moves are attributed to the program's outermost call block (so per-block
//! figures stay on the program's own blocks) and carry their file and line in
//! [`Move::source`]. Its errors and warnings are placed at that call, naming the file, line
//! and column in the library file.

use super::control::{prescan, ControlMap};
use super::{Interp, R};
use crate::nc::program::OName;
use crate::nc::view::{CompactProgram, ProgramView};
use crate::nc::{Diagnostic, Diagnostics, Expr, Move, MoveSource, ProgramLibrary};

/// Which file runs and where its moves go (see the module's doc).
#[derive(Default)]
pub(super) struct UnitState {
    /// Which file runs (0: the program itself), and the one to run from the next block on
    /// (a call into or a return from another file).
    pub(super) unit: u32,
    pub(super) next_unit: Option<u32>,
    /// While a library file runs: the block and line of the outermost call in the program,
    /// to which its moves are attributed.
    pub(super) site: Option<(usize, u32)>,
    /// A library file that a call needs and this run did not load (the run is made again
    /// with it).
    pub(super) missing: Option<usize>,
}

/// A library file loaded for a run: its blocks and links, or why it does not read (an error
/// only when a call reaches it).
pub(super) struct LibUnit<'p> {
    /// Index in the library's files.
    pub(super) file: usize,
    pub(super) name: &'p str,
    pub(super) loaded: Result<(ProgramView<'p>, ControlMap), Diagnostics>,
}

/// The library files named by `prog`'s calls with a written program number or subroutine
/// name, and by theirs in turn.
pub(super) fn called_files(
    prog: &ProgramView,
    library: &ProgramLibrary,
    fanuc: bool,
) -> Vec<usize> {
    let mut wanted = Vec::new();
    let mut todo = calls_of(prog, library, fanuc);
    while let Some(f) = todo.pop() {
        if !wanted.contains(&f) {
            wanted.push(f);
            todo.extend(called_files_of(library, f, fanuc));
        }
    }
    wanted
}

/// The library files named by the calls in library file `file` (none if it does not parse).
pub(super) fn called_files_of(library: &ProgramLibrary, file: usize, fanuc: bool) -> Vec<usize> {
    let text = &library.files()[file].text;
    match CompactProgram::parse(text) {
        Ok(p) => calls_of(&p.view(text), library, fanuc),
        Err(_) => Vec::new(),
    }
}

/// Library files of the calls written in one file: `M98 P..` (also the `P31234` form),
/// `G65 P..`, `G66 P..` with a number, and LinuxCNC `o.. call`.
fn calls_of(prog: &ProgramView, library: &ProgramLibrary, fanuc: bool) -> Vec<usize> {
    let mut out = Vec::new();
    let summary = prog.summary();
    for &i in &summary.o_word_blocks {
        if let Some(o) = prog.block(i).o_word {
            if o.keyword == crate::nc::OKeyword::Call {
                if let Some(f) = library.find_subroutine(&sub_file_stem(&o.name)) {
                    out.push(f);
                }
            }
        }
    }
    if !fanuc {
        return out;
    }
    let literal = |e: &Expr| match e {
        Expr::Number { value, .. } if value.fract() == 0.0 && *value >= 0.0 => Some(*value),
        _ => None,
    };
    for i in 0..prog.len() {
        let b = prog.block(i);
        let calls = b.words.iter().any(|w| {
            matches!((w.letter, literal(&w.value)), ('M', Some(v)) if v == 98.0)
                || matches!((w.letter, literal(&w.value)), ('G', Some(v)) if v == 65.0 || v == 66.0)
        });
        if !calls {
            continue;
        }
        for w in b.words.iter().filter(|w| w.letter == 'P') {
            if let Some(p) = literal(&w.value).filter(|p| *p <= 99_999_999.0) {
                let p = p as u32;
                for n in [p, p % 10_000] {
                    if let Some(f) = library.find_program(n) {
                        out.push(f);
                    }
                }
            }
        }
    }
    out
}

/// The file stem LinuxCNC reads a subroutine from: `o<drill>` from `drill.ngc`, `o100` from
/// `100.ngc`.
fn sub_file_stem(name: &OName) -> String {
    match name {
        OName::Number(n) => n.to_string(),
        OName::Named(s) => s.clone(),
    }
}

/// Parses the wanted library files (in `wanted`'s order).
pub(super) fn parse_files(
    library: &ProgramLibrary,
    wanted: &[usize],
) -> Vec<Result<CompactProgram, Diagnostics>> {
    wanted
        .iter()
        .map(|&f| CompactProgram::parse(&library.files()[f].text))
        .collect()
}

/// The run's view of the parsed files, with their control links.
pub(super) fn load<'p>(
    library: &'p ProgramLibrary,
    wanted: &[usize],
    parsed: &'p [Result<CompactProgram, Diagnostics>],
) -> Vec<LibUnit<'p>> {
    wanted
        .iter()
        .zip(parsed)
        .map(|(&file, p)| {
            let f = &library.files()[file];
            let loaded = p.as_ref().map_err(Clone::clone).and_then(|p| {
                let view = p.view(&f.text);
                let control = prescan(&view)?;
                Ok((view, control))
            });
            LibUnit {
                file,
                name: &f.name,
                loaded,
            }
        })
        .collect()
}

impl<'p> Interp<'p> {
    /// The blocks and links of unit `u`.
    pub(super) fn unit_files(&self, u: u32) -> (&'p ProgramView<'p>, &'p ControlMap) {
        if u == 0 {
            return (self.main, self.main_control);
        }
        let lib: &'p [LibUnit<'p>] = self.lib;
        match &lib[u as usize - 1].loaded {
            Ok((view, control)) => (view, control),
            Err(_) => unreachable!("a call only enters a library file that reads"),
        }
    }

    /// Runs unit `u` from the next block on.
    pub(super) fn enter_unit(&mut self, u: u32) -> R<()> {
        if u == self.units.unit {
            return Ok(());
        }
        if self.pending_corner.is_some() {
            return Err(self.err_block(
                "corner rounding/chamfer before a call to or a return from another file: it needs its next move in the same file",
            ));
        }
        if self.units.unit == 0 {
            self.units.site = Some((self.cur_block, self.cur_line));
        }
        if u == 0 {
            self.units.site = None;
        }
        self.units.unit = u;
        (self.prog, self.control) = self.unit_files(u);
        self.deferred_here = !self.prog.summary().deferred.is_empty();
        Ok(())
    }

    /// A diagnostic made in a library file, placed at the program's call.
    #[cold]
    pub(super) fn in_library(&self, d: Diagnostic) -> Diagnostic {
        let (block, _) = self.units.site.expect("a library file runs from a call");
        let name = self.lib[self.units.unit as usize - 1].name;
        let at = self.main.block(block).span.start;
        self.main.diag(
            at,
            format!(
                "in library file \"{name}\", line {}, column {}: {}",
                d.line, d.col, d.message
            ),
        )
    }

    /// A move made in a library file: on the call's block, with its own file and line.
    #[cold]
    pub(super) fn attribute(&self, m: &mut Move) {
        let (block, line) = self.units.site.expect("a library file runs from a call");
        m.source = Some(MoveSource {
            file: self.units.unit - 1,
            line: m.line,
        });
        m.block = block;
        m.line = line;
    }

    /// The program's line of the running block (the call's line in a library file).
    pub(super) fn program_line(&self) -> u32 {
        match self.units.site {
            Some((_, line)) if self.units.unit != 0 => line,
            _ => self.cur_line,
        }
    }

    /// Fanuc program `number` outside the running file: in the program itself, in a loaded
    /// library file, or in the library (then `missing` asks for a run with it loaded).
    pub(super) fn program_elsewhere(
        &mut self,
        number: u32,
        at: usize,
        what: &str,
    ) -> R<Option<(u32, usize)>> {
        if self.units.unit != 0 {
            if let Some(&s) = self.main_control.programs.get(&number) {
                return Ok(Some((0, s + 1)));
            }
        }
        for (k, u) in self.lib.iter().enumerate() {
            if let Ok((_, c)) = &u.loaded {
                if let Some(&s) = c.programs.get(&number) {
                    return Ok(Some((k as u32 + 1, s + 1)));
                }
            }
        }
        let Some(file) = self
            .opts
            .library
            .as_deref()
            .and_then(|l| l.find_program(number))
        else {
            return Ok(None);
        };
        let k = self.library_unit(file, at, &format!("{what}: program O{number}"))?;
        // A file named for the program without its `O` line is the program from its start.
        let body = match &self.lib[k as usize - 1].loaded {
            Ok((_, c)) => c.programs.get(&number).map_or(0, |s| s + 1),
            Err(_) => 0,
        };
        Ok(Some((k, body)))
    }

    /// LinuxCNC subroutine `name` outside the running file: in the program itself or in its
    /// library file `name.ngc`. The block of its `sub` line.
    pub(super) fn sub_elsewhere(&mut self, name: &OName, at: usize) -> R<Option<(u32, usize)>> {
        if self.units.unit != 0 {
            if let Some(&s) = self.main_control.subs.get(name) {
                return Ok(Some((0, s)));
            }
        }
        let Some(file) = self
            .opts
            .library
            .as_deref()
            .and_then(|l| l.find_subroutine(&sub_file_stem(name)))
        else {
            return Ok(None);
        };
        let k = self.library_unit(file, at, &format!("subroutine {name}"))?;
        match self.unit_files(k).1.subs.get(name) {
            Some(&s) => Ok(Some((k, s))),
            None => Err(self.err_at(
                at,
                format!(
                    "subroutine {name}: library file \"{}\" does not define it ({name} sub .. {name} endsub)",
                    self.lib[k as usize - 1].name
                ),
            )),
        }
    }

    /// The unit of library file `file`, which must read.
    fn library_unit(&mut self, file: usize, at: usize, what: &str) -> R<u32> {
        let library = self
            .opts
            .library
            .as_deref()
            .expect("a library file was found");
        let name = &library.files()[file].name;
        let Some(k) = self.lib.iter().position(|u| u.file == file) else {
            self.units.missing = Some(file);
            return Err(self.err_at(at, format!("{what}: library file \"{name}\" is not loaded")));
        };
        match &self.lib[k].loaded {
            Ok(_) => Ok(k as u32 + 1),
            Err(d) => {
                let first = d.0.first().map(|e| e.to_string()).unwrap_or_default();
                Err(self.err_at(
                    at,
                    format!("{what}: library file \"{name}\" does not read: {first}"),
                ))
            }
        }
    }
}
