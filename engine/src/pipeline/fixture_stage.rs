//! The fixture stage: every piece of every move the removal sweeps (rapids included, and the
//! first move from where the machine starts) checked against the fixture's bodies with
//! the whole tool; each move that meets one is flagged with the first body it meets, and
//! listed with the point.

use serde::Serialize;

use super::removal::RemovalPlan;
use super::rows::{kind_name, MoveRow, MAX_LISTED_COLLISIONS};
use super::spec::SimulateError;
use super::tools::ToolLookup;
use crate::geometry::fixture::{ToolEnvelope, ToolPart};
use crate::geometry::{Fixture, GeometryError};
use crate::nc::Move;

/// A move whose tool meets a fixture body: the first contact along the move.
#[derive(Clone, Debug, Serialize)]
pub struct FixtureCollision {
    /// The body's name.
    pub body: String,
    pub block: usize,
    pub line: u32,
    /// rapid, linear or arc.
    pub kind: &'static str,
    /// The T number cutting.
    pub tool: u32,
    /// flutes, shank or holder.
    pub part: ToolPart,
    /// The tool tip at the first contact and the body's point it meets, part frame, mm.
    pub tip: [f64; 3],
    pub point: [f64; 3],
}

/// What the fixture check found.
#[derive(Clone, Debug, Serialize)]
pub struct FixtureSummary {
    /// The bodies checked, by name.
    pub bodies: Vec<String>,
    /// Moves whose tool meets a body.
    pub collision_moves: usize,
    /// The first contact of each such move (the first 1000).
    pub collisions: Vec<FixtureCollision>,
}

/// Checks every planned piece against `fixture`; flags the rows.
pub(super) fn check_fixture(
    fixture: &Fixture,
    plan: &RemovalPlan,
    moves: &[Move],
    tools: &ToolLookup,
    rows: &mut [MoveRow],
) -> Result<FixtureSummary, SimulateError> {
    let mut envelopes: std::collections::BTreeMap<u32, ToolEnvelope> = Default::default();
    let mut collisions = Vec::new();
    let mut count = 0;
    for (move_index, segment) in plan.pieces() {
        let row = &mut rows[move_index];
        if row.fixture_contact {
            continue; // an earlier piece of this move met a body first
        }
        let m = &moves[move_index];
        let tool = tools.tool_for(m)?;
        let env = envelopes
            .entry(m.tool)
            .or_insert_with(|| ToolEnvelope::new(tool));
        let contact = fixture.first_contact(env, segment).map_err(|message| {
            SimulateError::Geometry(GeometryError::InvalidSegment {
                index: move_index,
                block: m.block,
                message,
            })
        })?;
        let Some(c) = contact else { continue };
        row.fixture_contact = true;
        row.fixture_body = Some(c.name.clone());
        count += 1;
        if collisions.len() < MAX_LISTED_COLLISIONS {
            collisions.push(FixtureCollision {
                body: c.name,
                block: m.block,
                line: m.line,
                kind: kind_name(m.kind),
                tool: tools.number(m),
                part: c.part,
                tip: c.tip,
                point: c.point,
            });
        }
    }
    Ok(FixtureSummary {
        bodies: fixture.names().map(str::to_string).collect(),
        collision_moves: count,
        collisions,
    })
}

/// One sentence for the summary's warnings: how many moves meet the fixture, and the first.
pub(super) fn warning(summary: &FixtureSummary) -> Option<String> {
    let c = summary.collisions.first()?;
    let p = |v: [f64; 3]| format!("({:.3}, {:.3}, {:.3})", v[0], v[1], v[2]);
    Some(format!(
        "the tool meets the fixture on {} move(s); the first on line {}: the {} of T{} meets `{}` on a {} move with the tip at {}, at {}",
        summary.collision_moves,
        c.line,
        c.part.name(),
        c.tool,
        c.body,
        c.kind,
        p(c.tip),
        p(c.point)
    ))
}
