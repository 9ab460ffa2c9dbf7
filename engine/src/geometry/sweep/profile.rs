//! The cutting part of a tool as a solid of revolution: its profile r(z), the inverse
//! profile and the support function the sweeps use.

use super::solvers::Frustum;
use crate::tool::{Tool, ToolShape};

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Profile {
    Flat,
    /// Ball or bull-nose: corner arc of radius rc centred at (R − rc, rc) in (ρ, z).
    Corner {
        rc: f64,
    },
    /// Cone from `rtip` at z = 0 widening with slope `tan` until z = `ztop`.
    Cone {
        rtip: f64,
        tan: f64,
        ztop: f64,
    },
}

/// The cutting part of a tool as a convex solid of revolution, z up from the tip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolBody {
    /// Cutting radius, mm.
    pub radius: f64,
    /// Height of the cutting part (the flute length), mm.
    pub length: f64,
    /// Radius at the top of the cutting part (= radius unless the flutes end below the
    /// profile's top).
    pub top_radius: f64,
    pub(super) profile: Profile,
    /// The cutting part as a stack of frustums from the tip up (`n_pieces` of them): exact
    /// for flat and chamfer profiles; a bull-nose's corner arc by chords whose inner
    /// vertices stand out by half their sagitta (so the error is ± half a sagitta, at
    /// most `radius / CHORD_TOLERANCE_DIVISOR`). Tilted sweeps of these are closed forms.
    pub(super) pieces: [Frustum; MAX_PIECES],
    pub(super) n_pieces: usize,
}

/// At most this many frustums stand for a profile.
pub(super) const MAX_PIECES: usize = 10;

/// A corner arc's chords deviate from it by at most the tool radius over this.
const CHORD_TOLERANCE_DIVISOR: f64 = 200.0;

impl ToolBody {
    pub fn cutting_part(tool: &Tool) -> ToolBody {
        let r = tool.radius();
        let profile = match tool.shape {
            ToolShape::Flat => Profile::Flat,
            ToolShape::Ball | ToolShape::BullNose => Profile::Corner {
                rc: tool.effective_corner_radius(),
            },
            ToolShape::Chamfer | ToolShape::Drill => Profile::Cone {
                rtip: tool.tip_diameter / 2.0,
                tan: tool.taper_half_angle_deg.to_radians().tan(),
                ztop: tool.profile_top(),
            },
        };
        let mut b = ToolBody {
            radius: r,
            length: tool.flute_length,
            top_radius: r,
            profile,
            pieces: [Frustum::default(); MAX_PIECES],
            n_pieces: 0,
        };
        b.top_radius = b.radius_at(b.length);
        b.stack_pieces();
        b
    }

    /// Fills `pieces`: the profile's vertices (r, z) from the tip up, joined by frustums,
    /// cut at the flute length.
    fn stack_pieces(&mut self) {
        let r = self.radius;
        let mut verts: Vec<(f64, f64)> = Vec::with_capacity(MAX_PIECES + 1);
        match self.profile {
            Profile::Flat => verts.push((r, 0.0)),
            Profile::Corner { rc } => {
                // Chords of the arc (centre (r − rc, rc)) within the tolerance, the inner
                // vertices moved out by half the sagitta.
                let tol = r / CHORD_TOLERANCE_DIVISOR;
                let half = (1.0 - tol / rc).clamp(-1.0, 1.0).acos().max(1e-3);
                let n = ((std::f64::consts::FRAC_PI_2 / (2.0 * half)).ceil() as usize)
                    .clamp(1, MAX_PIECES - 1);
                let dpsi = std::f64::consts::FRAC_PI_2 / n as f64;
                let grow = 1.0 + 0.5 * (1.0 - (0.5 * dpsi).cos());
                for i in 0..=n {
                    let psi = i as f64 * dpsi;
                    let rr = if i == 0 || i == n { rc } else { rc * grow };
                    verts.push((r - rc + rr * psi.sin(), rc - rr * psi.cos()));
                }
            }
            Profile::Cone { rtip, ztop, .. } => {
                verts.push((rtip, 0.0));
                verts.push((r, ztop));
            }
        }
        let top = verts.last().map_or(0.0, |v| v.1);
        if top < self.length {
            verts.push((r, self.length));
        }
        self.n_pieces = 0;
        for w in verts.windows(2) {
            let ((r0, z0), (r1, z1)) = (w[0], w[1]);
            if z0 >= self.length || z1 <= z0 {
                continue;
            }
            let z1c = z1.min(self.length);
            let r1c = r0 + (r1 - r0) * (z1c - z0) / (z1 - z0);
            self.pieces[self.n_pieces] = Frustum {
                z0,
                z1: z1c,
                r0,
                r1: r1c,
            };
            self.n_pieces += 1;
        }
    }

    /// The frustums that make up the cutting part, from the tip up.
    pub(super) fn pieces(&self) -> &[Frustum] {
        &self.pieces[..self.n_pieces]
    }

    /// A flat end mill's body.
    pub fn is_flat(&self) -> bool {
        matches!(self.profile, Profile::Flat)
    }

    /// The sphere's radius when the cutting part swept along a straight move is a capsule's
    /// union with the swept cylinder above it: a ball whose flutes reach above its sphere.
    pub(super) fn ball_radius(&self) -> Option<f64> {
        match self.profile {
            Profile::Corner { rc }
                if (rc - self.radius).abs() <= 1e-12 * self.radius && self.length >= 2.0 * rc =>
            {
                Some(rc)
            }
            _ => None,
        }
    }

    /// Height above the tip where the profile reaches the full radius.
    pub fn profile_top(&self) -> f64 {
        match self.profile {
            Profile::Flat => 0.0,
            Profile::Corner { rc } => rc,
            Profile::Cone { ztop, .. } => ztop,
        }
    }

    /// r(z) on [0, length].
    #[inline]
    pub fn radius_at(&self, z: f64) -> f64 {
        let r = self.radius;
        match self.profile {
            Profile::Flat => r,
            Profile::Corner { rc } => {
                if z >= rc {
                    r
                } else {
                    let dz = rc - z;
                    r - rc + (rc * rc - dz * dz).max(0.0).sqrt()
                }
            }
            Profile::Cone { rtip, tan, ztop } => {
                if z >= ztop {
                    r
                } else {
                    rtip + z.max(0.0) * tan
                }
            }
        }
    }

    /// Length of the profile curve (the cutting edge's trace in a plane through the
    /// axis) between heights z0 < z1.
    pub fn profile_length(&self, z0: f64, z1: f64) -> f64 {
        let (z0, z1) = (z0.max(0.0), z1.min(self.length));
        if z1 <= z0 {
            return 0.0;
        }
        match self.profile {
            Profile::Flat => z1 - z0,
            Profile::Corner { rc } => {
                // On the corner arc z = rc − rc·cos ψ, so the arc length is rc·Δψ.
                let psi = |z: f64| ((rc - z.min(rc)) / rc).clamp(-1.0, 1.0).acos();
                rc * (psi(z1) - psi(z0)) + (z1 - z0.max(rc)).max(0.0)
            }
            Profile::Cone { tan, ztop, .. } => {
                let cone = (z1.min(ztop) - z0).max(0.0);
                cone * (1.0 + tan * tan).sqrt() + (z1 - z0.max(ztop)).max(0.0)
            }
        }
    }

    /// Lowest height where the profile reaches radius ρ (ρ ≤ top_radius).
    #[inline]
    pub(super) fn zlow(&self, rho: f64) -> f64 {
        match self.profile {
            Profile::Flat => 0.0,
            Profile::Corner { rc } => {
                let c = self.radius - rc;
                if rho <= c {
                    0.0
                } else {
                    let d = (rho - c).min(rc);
                    rc - (rc * rc - d * d).max(0.0).sqrt()
                }
            }
            Profile::Cone { rtip, tan, ztop } => {
                if rho <= rtip {
                    0.0
                } else {
                    ((rho - rtip) / tan).min(ztop)
                }
            }
        }
    }

    /// Support point in the tool frame (axis = +z, tip at the origin) for direction d.
    pub(super) fn support(&self, d: [f64; 3]) -> [f64; 3] {
        let dxy = (d[0] * d[0] + d[1] * d[1]).sqrt();
        let score = |rho: f64, z: f64| dxy * rho + d[2] * z;
        let mut best = (self.radius_at(0.0), 0.0);
        let mut cand = |rho: f64, z: f64| {
            if score(rho, z) > score(best.0, best.1) {
                best = (rho, z);
            }
        };
        cand(self.top_radius, self.length);
        match self.profile {
            Profile::Flat => {}
            Profile::Corner { rc } => {
                if d[2] < 0.0 {
                    let n = (dxy * dxy + d[2] * d[2]).sqrt();
                    let z = rc + rc * d[2] / n;
                    if z <= self.length {
                        cand(self.radius - rc + rc * dxy / n, z);
                    }
                }
                if rc <= self.length {
                    cand(self.radius, rc);
                }
            }
            Profile::Cone { ztop, .. } => {
                if ztop <= self.length {
                    cand(self.radius, ztop);
                }
            }
        }
        if dxy > 0.0 {
            [best.0 * d[0] / dxy, best.0 * d[1] / dxy, best.1]
        } else {
            [0.0, 0.0, best.1]
        }
    }
}
