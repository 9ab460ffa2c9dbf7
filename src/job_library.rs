//! A simulate/optimize job's `tool_library` input: the tools it gives for the T numbers no
//! tool input names, and what the job's summary says about the ones that cut (the import
//! report's notes on them, one `tool_warnings` line per tool with any).

use std::collections::{BTreeMap, BTreeSet};

use serde_json::{json, Value};

use millsim_engine::tool::Tool;
use millsim_engine::tool_library::{Note, ToolLibrary};

use crate::jobs::LoadedInput;
use crate::problem::Problem;

/// A library as a job uses it.
pub struct JobLibrary {
    file: String,
    library: ToolLibrary,
    /// The T numbers it gave (those no tool input names).
    given: BTreeSet<u32>,
}

impl JobLibrary {
    /// Reads the stored library (the problem of the upload if it no longer reads).
    pub fn load(input: LoadedInput) -> Result<JobLibrary, Problem> {
        let file = input.file_name.unwrap_or_else(|| "tools".into());
        let library = crate::validate::read_tool_library(&input.content, &file)?;
        Ok(JobLibrary {
            file,
            library,
            given: BTreeSet::new(),
        })
    }

    /// Adds the library's tool for every T number `tools` has none for. Explicit tools win:
    /// one tool for every number (key 0) leaves no number to the library.
    pub fn fill(&mut self, tools: &mut BTreeMap<u32, Tool>) {
        if tools.contains_key(&0) {
            return;
        }
        for (&n, tool) in &self.library.tools {
            // T0 is "no tool" in a program; key 0 would mean every number.
            if n != 0 && !tools.contains_key(&n) {
                tools.insert(n, tool.clone());
                self.given.insert(n);
            }
        }
    }

    /// What the summary says: the library's file, format and the T numbers of `cut` (the
    /// job's cutting tools) it gave, with the report's notes on those; and a warning line
    /// per such tool with notes, naming its place in the file.
    pub fn report(&self, cut: &[u32]) -> (Value, Vec<String>) {
        let used: Vec<u32> = cut
            .iter()
            .copied()
            .filter(|n| self.given.contains(n))
            .collect();
        let about = |notes: &[Note], n: u32| -> Vec<Note> {
            let prefix = format!("T{n} ");
            notes
                .iter()
                .filter(|x| x.tool.starts_with(&prefix))
                .cloned()
                .collect()
        };
        let report = &self.library.report;
        let mut unmodelled = Vec::new();
        let mut assumed = Vec::new();
        let mut warnings = Vec::new();
        for &n in &used {
            let (a, u) = (about(&report.assumed, n), about(&report.unmodelled, n));
            if let Some(origin) = a.iter().chain(&u).next().map(|x| x.tool.clone()) {
                let notes: Vec<String> = a
                    .iter()
                    .chain(&u)
                    .map(|x| format!("{}: {}", x.field, x.note))
                    .collect();
                warnings.push(format!(
                    "{origin}: from the tool library `{}`; {}",
                    self.file,
                    notes.join("; ")
                ));
            }
            assumed.extend(a);
            unmodelled.extend(u);
        }
        let section = json!({
            "file": self.file,
            "format": self.library.format,
            "tools": used.iter().map(|n| format!("T{n}")).collect::<Vec<_>>(),
            "unmodelled": unmodelled,
            "assumed": assumed,
        });
        (section, warnings)
    }
}
