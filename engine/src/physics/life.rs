//! Tool life by the extended Taylor equation and linear damage accumulation.
//!
//! Form used: v · T^n · h^a = C, with v the cutting speed (m/min), T the tool life (min)
//! and h the uncut chip thickness (mm); hence T = (C / (v · h^a))^(1/n). With a = 0 this is
//! the classic Taylor equation. A block that cuts for t minutes at (v, h) uses t / T of the
//! tool (Palmgren–Miner rule: fractions add up; the tool is worn out when they reach 1).
//! No constants ship: none of the sources in docs/reference.md gives them; users supply
//! them with their material.

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

use super::{finite, non_negative, positive, PhysicsError};
use crate::engagement::Engagement;
use crate::tool::Tool;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaylorLife {
    /// C, in the units of v·T^n·h^a (m/min · min^n · mm^a).
    pub c: f64,
    /// Speed exponent n, in (0, 1].
    pub n: f64,
    /// Chip-thickness exponent a ≥ 0 (0: classic Taylor).
    #[serde(default)]
    pub a: f64,
    /// Where the constants come from.
    #[serde(default)]
    pub source: String,
}

impl TaylorLife {
    pub fn validate(&self) -> Result<(), PhysicsError> {
        positive("taylor.c", self.c)?;
        positive("taylor.n", self.n)?;
        if self.n > 1.0 {
            return Err(PhysicsError::invalid(
                "taylor.n",
                format!("must be in (0, 1], got {}", self.n),
            ));
        }
        non_negative("taylor.a", self.a)?;
        Ok(())
    }

    /// Tool life in minutes at cutting speed `v` (m/min) and chip thickness `h` (mm); None
    /// when the edge does not wear (not cutting: v = 0, or h = 0 with a > 0).
    pub fn life_minutes(&self, v: f64, h: f64) -> Option<f64> {
        let load = v * if self.a > 0.0 { h.powf(self.a) } else { 1.0 };
        if load.is_nan() || load <= 0.0 {
            return None;
        }
        Some((self.c / load).powf(1.0 / self.n))
    }
}

/// Cutting speed at diameter `d` (mm) and spindle speed `rpm`, m/min.
pub fn cutting_speed_m_per_min(d: f64, rpm: f64) -> f64 {
    PI * d * rpm / 1000.0
}

/// Diameter of the widest engaged edge point of a step, mm: the speed that wears the tool
/// on a ball at small depth is well below π·D·n.
pub fn effective_diameter(tool: &Tool, e: &Engagement) -> f64 {
    e.slices
        .iter()
        .filter(|s| !s.arcs.is_empty())
        .filter_map(|s| tool.edge_point((s.z + 0.5 * s.dz).min(tool.flute_length)))
        .map(|p| 2.0 * p.radius)
        .fold(0.0, f64::max)
}

/// What one block asks of the tool.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockWear {
    /// The caller's block id (e.g. the NC block index).
    pub block: usize,
    /// m/min.
    pub cutting_speed: f64,
    /// Chip thickness that drives wear (typically the block's max or mean max chip), mm.
    pub chip_thickness: f64,
    /// Time the edge is in the cut, s.
    pub engaged_time: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockLife {
    pub block: usize,
    /// Tool life at this block's conditions, min (None: no wear).
    pub life_minutes: Option<f64>,
    /// Fraction of a new tool's life this block uses.
    pub consumed: f64,
    /// Fraction used after this block (including the starting wear).
    pub cumulative: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LifeReport {
    pub blocks: Vec<BlockLife>,
    /// Fraction used by the blocks given.
    pub consumed: f64,
    /// Fraction left after them (negative: the tool wore out before the end).
    pub remaining: f64,
    /// Block id of the block that uses the most life (None when nothing wears).
    pub most_wearing_block: Option<usize>,
    /// Block id during which the cumulative use reaches 1.
    pub worn_out_at_block: Option<usize>,
}

/// Life consumed per block by a tool that starts with `already_used` (fraction in [0, 1])
/// of its life gone.
pub fn tool_life(
    taylor: &TaylorLife,
    blocks: &[BlockWear],
    already_used: f64,
) -> Result<LifeReport, PhysicsError> {
    taylor.validate()?;
    non_negative("already_used", already_used)?;
    let mut cumulative = finite("already_used", already_used)?;
    let mut out = Vec::with_capacity(blocks.len());
    let mut most: Option<(usize, f64)> = None;
    let mut worn_out = if cumulative >= 1.0 {
        blocks.first().map(|b| b.block)
    } else {
        None
    };
    for (i, b) in blocks.iter().enumerate() {
        non_negative(format!("blocks[{i}].cutting_speed"), b.cutting_speed)?;
        non_negative(format!("blocks[{i}].chip_thickness"), b.chip_thickness)?;
        non_negative(format!("blocks[{i}].engaged_time"), b.engaged_time)?;
        let life = if b.engaged_time > 0.0 {
            taylor.life_minutes(b.cutting_speed, b.chip_thickness)
        } else {
            None
        };
        let consumed = life.map_or(0.0, |t| b.engaged_time / 60.0 / t);
        let before = cumulative;
        cumulative += consumed;
        if before < 1.0 && cumulative >= 1.0 {
            worn_out = Some(b.block);
        }
        // Strictly greater: the first of equals wins, deterministically.
        if consumed > 0.0 && most.is_none_or(|(_, c)| consumed > c) {
            most = Some((b.block, consumed));
        }
        out.push(BlockLife {
            block: b.block,
            life_minutes: life,
            consumed,
            cumulative,
        });
    }
    Ok(LifeReport {
        consumed: cumulative - already_used,
        remaining: 1.0 - cumulative,
        blocks: out,
        most_wearing_block: most.map(|m| m.0),
        worn_out_at_block: worn_out,
    })
}
