//! Which tool cuts each move: one tool for a program that uses one tool number, or a tool
//! per T number; a T number with no tool given is derived from the program's own header
//! comments (with a warning naming every assumed value), or refused.

use std::collections::BTreeMap;

use super::spec::{SimulateError, SimulateSpec};
use crate::nc::{Move, MoveKind};
use crate::tool::Tool;
use crate::tool_library::tools_from_header;

pub(super) struct ToolLookup {
    /// The tools given and the ones derived from the header, by T number.
    tools: BTreeMap<u32, Tool>,
    /// The tool given under key 0, alone: it serves every move.
    single: bool,
    /// The one T number a program selects without loading it (M6), however its tool came.
    selected_number: Option<u32>,
    /// The T numbers whose tools cut, in the order the program first uses them.
    pub(super) numbers: Vec<u32>,
    /// What was assumed for the derived tools, one line each.
    pub(super) warnings: Vec<String>,
}

impl ToolLookup {
    /// Checks that the tools given fit the program's tool numbers; `selected` are the T
    /// numbers the program's T words select, with their lines.
    pub(super) fn new(
        spec: &SimulateSpec,
        moves: &[Move],
        selected: &[(u32, u32)],
    ) -> Result<Self, SimulateError> {
        let mut used: Vec<(u32, u32)> = Vec::new();
        for m in moves
            .iter()
            .filter(|m| m.tool != 0 && m.kind != MoveKind::Dwell)
        {
            if !used.iter().any(|(t, _)| *t == m.tool) {
                used.push((m.tool, m.line));
            }
        }
        let mut tools = spec.tools.clone();
        // One numbered tool and a program that names no tool at all: it is the tool in the
        // spindle. (A program that names another number is refused, naming it.)
        if used.is_empty() && selected.is_empty() && tools.len() == 1 && !tools.contains_key(&0) {
            let (_, tool) = tools.pop_first().expect("one tool");
            tools.insert(0, tool);
        }
        let single = match (tools.len(), tools.get(&0)) {
            (1, Some(_)) => true,
            (_, None) => false,
            _ => return Err(SimulateError::ToolZeroWithOthers),
        };
        // One tool serves a program that uses one tool number; a second number would be cut
        // with the wrong tool, so it is an error, never a guess.
        if single {
            if let Some(&(tool, line)) = used.get(1) {
                let list: Vec<String> = used.iter().map(|(t, _)| format!("T{t}")).collect();
                return Err(SimulateError::OneToolForSeveral {
                    tool,
                    line,
                    used: list.join(", "),
                });
            }
        }
        // A program that selects one tool (T1) but never loads it (no M6, as Fusion's posts
        // write a one-tool program): its moves carry no number and are cut with that tool.
        // The number such a program's moves carry in the rows and reports, whether its tool
        // came as the job's one `tool` or from a library: the T number it selects.
        let selected_number = match selected {
            [(t, _)] if used.is_empty() => Some(*t),
            _ => None,
        };
        let unloaded = selected_number.filter(|_| !single);
        let mut numbers: Vec<u32> = match unloaded {
            Some(t) => vec![t],
            None => used.iter().map(|(t, _)| *t).collect(),
        };
        let mut single = single;
        let mut warnings = Vec::new();
        let mut missing: Vec<u32> = numbers
            .iter()
            .copied()
            .filter(|t| !single && !tools.contains_key(t))
            .collect();
        let header =
            (!missing.is_empty() || tools.is_empty()).then(|| tools_from_header(&spec.program));
        if let Some(header) = header {
            // A program that never changes tools (a T word without M6, or none) and whose
            // header describes one tool is cut with that tool.
            let only = (header.tools.len() == 1 && used.is_empty() && tools.is_empty())
                .then(|| *header.tools.keys().next().expect("one tool"));
            if let Some(t) = only {
                missing = vec![t];
                numbers = vec![t];
                single = true;
            }
            for t in missing {
                let Some(tool) = header.tools.get(&t) else {
                    continue; // refused where it is first used, naming the line
                };
                tools.insert(if single { 0 } else { t }, tool.clone());
                let prefix = format!("T{t} ");
                let notes: Vec<String> = header
                    .report
                    .assumed
                    .iter()
                    .filter(|n| n.tool.starts_with(&prefix))
                    .map(|n| format!("{}: {}", n.field, n.note))
                    .collect();
                let origin = header
                    .report
                    .assumed
                    .iter()
                    .find(|n| n.tool.starts_with(&prefix))
                    .map_or(format!("T{t}"), |n| n.tool.clone());
                warnings.push(format!(
                    "{origin}: no tool given, derived from the program's comment `{}`; {}",
                    tool.name.as_deref().unwrap_or(""),
                    notes.join("; ")
                ));
            }
        }
        // The selected number's tool, given or derived, serves every move.
        if let Some(tool) = unloaded.filter(|_| !single).and_then(|t| tools.remove(&t)) {
            tools = BTreeMap::from([(0, tool)]);
            single = true;
        }
        // Only the tools that cut: a library's others must not set the grid or be checked.
        tools.retain(|t, _| {
            if single {
                *t == 0
            } else {
                used.iter().any(|u| u.0 == *t)
            }
        });
        Ok(ToolLookup {
            tools,
            single,
            selected_number,
            numbers,
            warnings,
        })
    }

    /// The tool cutting move `m`.
    pub(super) fn tool_for(&self, m: &Move) -> Result<&Tool, SimulateError> {
        let key = if self.single { 0 } else { m.tool };
        self.tools.get(&key).ok_or(SimulateError::UnknownTool {
            tool: m.tool,
            line: m.line,
        })
    }

    /// The T number move `m` is cut with: its own, else the one the program selects
    /// without loading (0: none).
    pub(super) fn number(&self, m: &Move) -> u32 {
        if m.tool == 0 {
            self.selected_number.unwrap_or(0)
        } else {
            m.tool
        }
    }

    /// The T number of the moves whose own number is `key` (the key of their cutter):
    /// the number a program selects without loading it for key 0.
    pub(super) fn key_number(&self, key: u32) -> u32 {
        if key == 0 {
            self.selected_number.unwrap_or(0)
        } else {
            key
        }
    }

    /// Every tool that may cut.
    pub(super) fn all(&self) -> impl Iterator<Item = &Tool> {
        self.tools.values()
    }

    /// Before the first tool change no cutter is in the spindle: positioning moves then
    /// sweep nothing; a feed move then is an error (it would cut with nothing).
    pub(super) fn sweeps(&self, m: &Move) -> bool {
        self.single || m.tool != 0
    }
}
