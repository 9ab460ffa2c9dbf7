//! A program library: the other programs a program may call, as a control holds them in its
//! memory (Fanuc: `M98 P1234` / `G65 P9010` run program O1234 / O9010) or finds them on its
//! subroutine path (LinuxCNC: `o<drill> call` reads `drill.ngc`, `o100 call` reads `100.ngc`).
//!
//! A library is a set of named texts: the files of a folder (`millsim interpret --library`), or
//! programs uploaded beside the job's program. Which file holds a program:
//! * Fanuc O number N: a file named for it (`O1234`, `O1234.nc`, `o01234.NC`, `1234.nc`), else
//!   the first file (in name order) with an `O1234` (or `:1234`) program-number line. A file may
//!   hold several programs; each is callable.
//! * LinuxCNC subroutine `name`: the file `name.ngc` (letters compared without case, as
//!   LinuxCNC lower-cases o-word names), which defines `o<name> sub` .. `endsub`.

use std::path::Path;

/// One program of a library.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LibraryFile {
    /// The file name (no folder), as errors and moves name it.
    pub name: String,
    pub text: String,
}

/// Programs a program may call besides those in its own file. See the module documentation
/// for how a call finds its file.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ProgramLibrary {
    files: Vec<LibraryFile>,
}

/// LinuxCNC o-word keywords: a line `o100 sub` is not a Fanuc program number.
const O_KEYWORDS: [&str; 15] = [
    "sub",
    "endsub",
    "call",
    "do",
    "while",
    "endwhile",
    "if",
    "elseif",
    "else",
    "endif",
    "repeat",
    "endrepeat",
    "return",
    "break",
    "continue",
];

impl ProgramLibrary {
    /// A library of the given files, kept in name order (so which file answers a number
    /// does not depend on the order they were listed in).
    pub fn new(mut files: Vec<LibraryFile>) -> Self {
        files.sort_by(|a, b| a.name.cmp(&b.name));
        ProgramLibrary { files }
    }

    /// Every UTF-8 text file directly in `dir` (not in sub-folders). Files that are not text
    /// (an STL beside the programs) are left out; a folder that cannot be read is an error.
    pub fn from_dir(dir: &Path) -> Result<Self, String> {
        let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut files = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| format!("{}: {e}", dir.display()))?;
            let path = entry.path();
            if !path.is_file() {
                continue;
            }
            let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            if let Ok(text) = String::from_utf8(bytes) {
                files.push(LibraryFile {
                    name: entry.file_name().to_string_lossy().into_owned(),
                    text,
                });
            }
        }
        Ok(ProgramLibrary::new(files))
    }

    pub fn files(&self) -> &[LibraryFile] {
        &self.files
    }

    pub fn is_empty(&self) -> bool {
        self.files.is_empty()
    }

    /// The file holding Fanuc program O`number`.
    pub fn find_program(&self, number: u32) -> Option<usize> {
        self.files
            .iter()
            .position(|f| named_number(&f.name) == Some(number))
            .or_else(|| {
                self.files
                    .iter()
                    .position(|f| program_numbers(&f.text).any(|n| n == number))
            })
    }

    /// The file of LinuxCNC subroutine `name` (`name.ngc`).
    pub fn find_subroutine(&self, name: &str) -> Option<usize> {
        self.files.iter().position(|f| {
            f.name.len() == name.len() + 4
                && f.name[..name.len()].eq_ignore_ascii_case(name)
                && f.name[name.len()..].eq_ignore_ascii_case(".ngc")
        })
    }
}

/// The program number a file name gives: `O1234`, `o01234.nc`, `1234.NC`.
fn named_number(name: &str) -> Option<u32> {
    let stem = name.split('.').next().unwrap_or(name);
    let digits = stem.strip_prefix(['O', 'o']).unwrap_or(stem);
    if digits.is_empty() || digits.len() > 8 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// The numbers of the `O1234` / `:1234` program-number lines of a text.
fn program_numbers(text: &str) -> impl Iterator<Item = u32> + '_ {
    text.lines().filter_map(|line| {
        let l = line.trim_start();
        let l = l.strip_prefix(['O', 'o', ':'])?;
        let digits = l.bytes().take_while(u8::is_ascii_digit).count();
        if digits == 0 || digits > 8 {
            return None;
        }
        let rest = l[digits..].trim_start().to_ascii_lowercase();
        if O_KEYWORDS.iter().any(|k| rest.starts_with(k)) {
            return None;
        }
        l[..digits].parse().ok()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lib(files: &[(&str, &str)]) -> ProgramLibrary {
        ProgramLibrary::new(
            files
                .iter()
                .map(|(n, t)| LibraryFile {
                    name: n.to_string(),
                    text: t.to_string(),
                })
                .collect(),
        )
    }

    #[test]
    fn programs_are_found_by_file_name_then_by_their_o_line() {
        let l = lib(&[
            (
                "pocket.nc",
                "%\nO2000 (POCKET)\nG1 X1\nM99\nO2001\nM99\n%\n",
            ),
            ("O1000.NC", "G1 X1\nM99\n"),
            ("o00300", "M99\n"),
            ("drill.ngc", "o100 sub\no100 endsub\n"),
            ("Face.NGC", "o<face> sub\no<face> endsub\n"),
        ]);
        let name = |i: Option<usize>| i.map(|i| l.files()[i].name.as_str());
        assert_eq!(name(l.find_program(1000)), Some("O1000.NC"));
        assert_eq!(name(l.find_program(300)), Some("o00300"));
        assert_eq!(name(l.find_program(2000)), Some("pocket.nc"));
        assert_eq!(name(l.find_program(2001)), Some("pocket.nc"));
        // `o100 sub` is a LinuxCNC subroutine, not program O100.
        assert_eq!(l.find_program(100), None);
        assert_eq!(name(l.find_subroutine("drill")), Some("drill.ngc"));
        assert_eq!(name(l.find_subroutine("face")), Some("Face.NGC"));
        assert_eq!(l.find_subroutine("pocket"), None);
    }
}
