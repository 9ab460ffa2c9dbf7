//! The tool state: the tool in the spindle and the ones selected, its length and radius
//! offsets in force, and the offsets written by G10.

use std::collections::{HashMap, HashSet};

/// The tool in the spindle, the ones selected, and the tool offsets.
#[derive(Default)]
pub(super) struct ToolState {
    /// The tool in the spindle (T number, 0: none).
    pub(super) current: u32,
    /// The tool the last T word selected (M6 loads it).
    pub(super) selected: Option<u32>,
    /// Each T number selected, with the line of its first selection.
    pub(super) selected_tools: Vec<(u32, u32)>,
    /// Active tool length offset (mm), None: G49.
    pub(super) tlo: Option<f64>,
    /// G43.4/G43.5 tool-centre-point control in force (G43, G43.1 and G49 end it).
    pub(super) tcp: bool,
    /// Fanuc's modal D: the radius offset number a G41/G42 without D takes (set by D on a
    /// G41/G42 block or on a G43 block, as Fanuc posts write `G43 H1 D1`).
    pub(super) radius_offset: Option<u32>,
    /// Tool offsets written by G10 (mm), by tool/offset number: length, Fanuc length wear,
    /// radius, Fanuc radius wear. They take precedence over the tool table.
    pub(super) lengths: HashMap<u32, f64>,
    pub(super) length_wear: HashMap<u32, f64>,
    pub(super) radii: HashMap<u32, f64>,
    pub(super) radius_wear: HashMap<u32, f64>,
    /// Length offset numbers (H) already warned about as missing from the tool table.
    pub(super) warned: HashSet<u32>,
}
