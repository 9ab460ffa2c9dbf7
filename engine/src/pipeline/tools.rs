//! Which tool cuts each move: one tool for a program that uses one tool number, or a tool
//! per T number.

use super::spec::{SimulateError, SimulateSpec};
use crate::nc::{Move, MoveKind};
use crate::tool::Tool;

pub(super) struct ToolLookup<'a> {
    spec: &'a SimulateSpec,
    /// The tool given under key 0, alone: it serves every move.
    single: Option<&'a Tool>,
}

impl<'a> ToolLookup<'a> {
    /// Checks that the tools given fit the program's tool numbers.
    pub(super) fn new(spec: &'a SimulateSpec, moves: &[Move]) -> Result<Self, SimulateError> {
        let single = match (spec.tools.len(), spec.tools.get(&0)) {
            (1, Some(t)) => Some(t),
            (_, None) => None,
            _ => return Err(SimulateError::ToolZeroWithOthers),
        };
        // One tool serves a program that uses one tool number; a second number would be cut
        // with the wrong tool, so it is an error, never a guess.
        if single.is_some() {
            let mut used: Vec<(u32, u32)> = Vec::new();
            for m in moves
                .iter()
                .filter(|m| m.tool != 0 && m.kind != MoveKind::Dwell)
            {
                if !used.iter().any(|(t, _)| *t == m.tool) {
                    used.push((m.tool, m.line));
                }
            }
            if let Some(&(tool, line)) = used.get(1) {
                let list: Vec<String> = used.iter().map(|(t, _)| format!("T{t}")).collect();
                return Err(SimulateError::OneToolForSeveral {
                    tool,
                    line,
                    used: list.join(", "),
                });
            }
        }
        Ok(ToolLookup { spec, single })
    }

    /// The tool cutting move `m`.
    pub(super) fn tool_for(&self, m: &Move) -> Result<&'a Tool, SimulateError> {
        self.single
            .or_else(|| self.spec.tools.get(&m.tool))
            .ok_or(SimulateError::UnknownTool {
                tool: m.tool,
                line: m.line,
            })
    }

    /// Before the first tool change no cutter is in the spindle: positioning moves then
    /// sweep nothing; a feed move then is an error (it would cut with nothing).
    pub(super) fn sweeps(&self, m: &Move) -> bool {
        self.single.is_some() || m.tool != 0
    }
}
