//! What plunges along the axis, as clearance levels: part material at heights at or above
//! a level's height (above the section) must stay the level's radius (plus the allowance)
//! away from the axis. The cutter is the level at height 0; a wider shank starts at the
//! flute length; each holder piece starts where it sits above the tip. Whatever passes a
//! height on its way down to the section sweeps every height above it, so a level covers
//! all heights above its own: the whole plunge is checked, not only the final pose.

use crate::tool::{HolderSegment, Tool};

use super::walls::Walls;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    pub height: f64,
    pub radius: f64,
}

/// Slices a conical holder piece is cut into, each taken at its widest (conservative by at
/// most a quarter of the piece's change in radius).
const CONE_SLICES: usize = 4;

/// The holder stack's levels, its bottom `stickout` above the tip.
pub fn holder_levels(stickout: f64, holder: &[HolderSegment]) -> Vec<Level> {
    let mut out = Vec::new();
    let mut z = stickout;
    for seg in holder {
        let (rb, rt) = (seg.bottom_diameter / 2.0, seg.top_diameter / 2.0);
        if rb == rt {
            out.push(Level {
                height: z,
                radius: rb,
            });
        } else {
            for k in 0..CONE_SLICES {
                let s0 = k as f64 / CONE_SLICES as f64;
                let s1 = (k + 1) as f64 / CONE_SLICES as f64;
                out.push(Level {
                    height: z + s0 * seg.length,
                    radius: (rb + s0 * (rt - rb)).max(rb + s1 * (rt - rb)),
                });
            }
        }
        z += seg.length;
    }
    out
}

/// A tool's levels: cutter, a shank wider than the cutter, and its holder (the tool's own,
/// else the request's `holder` at the request's `stickout`).
pub fn tool_levels(tool: &Tool, stickout: Option<f64>, holder: &[HolderSegment]) -> Vec<Level> {
    let mut out = vec![Level {
        height: 0.0,
        radius: tool.radius(),
    }];
    if tool.shank_diameter() > tool.diameter {
        out.push(Level {
            height: tool.flute_length,
            radius: tool.shank_diameter() / 2.0,
        });
    }
    if !tool.holder.is_empty() {
        out.extend(holder_levels(tool.stick_out(), &tool.holder));
    } else if let Some(s) = tool.stick_out.or(stickout) {
        out.extend(holder_levels(s, holder));
    }
    out
}

/// The walls of every distinct level height of a set of bodies.
pub struct LevelWalls {
    pub levels: Vec<(f64, Walls)>,
}

impl LevelWalls {
    pub fn walls_at(&self, height: f64) -> &Walls {
        &self
            .levels
            .iter()
            .find(|(h, _)| *h == height)
            .expect("walls built for every level height")
            .1
    }

    /// Whether every level clears at `c` with `allowance`.
    pub fn fits(&self, levels: &[Level], allowance: f64, c: [f64; 2]) -> bool {
        levels.iter().all(|l| {
            let need = l.radius + allowance;
            // Any wall nearer than `need` settles it.
            self.walls_at(l.height)
                .clearance_within(c, need * (1.0 - 1e-12), need)
                >= need
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cone_is_sliced_at_its_widest_and_pieces_stack_up() {
        let holder = vec![
            HolderSegment {
                length: 20.0,
                bottom_diameter: 20.0,
                top_diameter: 40.0,
            },
            HolderSegment {
                length: 30.0,
                bottom_diameter: 50.0,
                top_diameter: 50.0,
            },
        ];
        let l = holder_levels(35.0, &holder);
        assert_eq!(l.len(), 5);
        assert_eq!(
            l[0],
            Level {
                height: 35.0,
                radius: 12.5
            }
        );
        assert_eq!(
            l[3],
            Level {
                height: 50.0,
                radius: 20.0
            }
        );
        assert_eq!(
            l[4],
            Level {
                height: 55.0,
                radius: 25.0
            }
        );
    }
}
