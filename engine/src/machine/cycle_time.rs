//! Cycle time of a move list on a machine with finite acceleration.
//!
//! Model (a continuous-path control in G64 blending mode, like grbl or LinuxCNC's planner):
//!
//! * Every motion move gets a trapezoidal velocity profile: accelerate at `a`, cruise at the
//!   nominal speed, decelerate at `a`. The path is the XYZ path (degrees on a move without XYZ
//!   travel). `a` is the path acceleration the axes allow along the move,
//!   `a = min over moving axes of a_axis / |u_axis|` (u the unit direction), so no axis exceeds
//!   its own limit.
//! * Nominal speed: rapids at `rapid_rate`; feed moves at the rate their F gives along the path
//!   as the machine's control reads it ([`super::feed_reading`]: G95 is mm/rev × rpm, G93 lasts
//!   1/F min, a G94 move with rotary travel lasts the distance of the machine's
//!   `rotary_feed_reading` over F), clamped to `max_feed`. Arcs also obey the centripetal limit v² ≤ a_n·r (a_n the smaller acceleration of the
//!   arc plane's axes).
//! * Junction speed between consecutive moves follows the junction-deviation model of grbl:
//!   v_j² = a_j·δ·sin(θ/2)/(1 − sin(θ/2)), θ the angle between the reversed incoming and the
//!   outgoing direction (θ = π: straight on, no limit; θ = 0: reversal, stop), a_j the acceleration
//!   allowed along the direction change, δ the junction deviation ([`CycleTimeOptions`]).
//!   It is also limited by both moves' nominal speeds.
//! * Look-ahead over the whole list (a backward and a forward pass), so every move's entry and
//!   exit speeds are reachable with its acceleration; the program starts and ends at rest, and
//!   dwells and tool changes stop the motion and add their own time.
//!
//! * With `Machine::jerk` given (mm/s³, projected on the move like the acceleration), every
//!   speed change is a symmetric S-curve (trapezoidal acceleration): Δv takes Δv/a + a/J when
//!   Δv ≥ a²/J, else 2·sqrt(Δv/J), over the distance (v0 + v1)/2 times that; the look-ahead
//!   and the profiles use these ramps (peak speeds found by bisection). Without jerk the ramps
//!   are the constant-acceleration closed forms.
//!
//! * Where rotary axes turn, the machine's rotary speed and acceleration (deg/min, deg/s²)
//!   bound the path's speed and acceleration in proportion to the fastest rotary axis's share
//!   of the move (a pure rotary move without a rotary acceleration uses the smallest linear
//!   one, in deg/s²).
//!
//! Not modelled: finite look-ahead buffers, exact-stop modes (G61).

use super::feed_reading::{self, RotaryFeedReading};
use super::Machine;
use crate::nc::{Move, MoveKind};
use crate::vec3::norm;

/// Tunables of the cycle-time model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleTimeOptions {
    /// Junction deviation δ, mm: how far the controller may round a corner (grbl's default
    /// 0.01 mm). 0 stops at every corner that is not exactly straight.
    pub junction_deviation: f64,
}

impl Default for CycleTimeOptions {
    fn default() -> Self {
        CycleTimeOptions {
            junction_deviation: 0.01,
        }
    }
}

/// Cycle time of a move list, s.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CycleTime {
    pub total_s: f64,
    /// One entry per move, in order (motion time plus any dwell or tool change time).
    pub per_move_s: Vec<f64>,
    /// Linear and arc feed moves.
    pub cutting_s: f64,
    pub rapid_s: f64,
    pub dwell_s: f64,
    pub tool_change_s: f64,
    /// Σ length / nominal speed with infinite acceleration (the naive estimate), s.
    pub nominal_s: f64,
    /// Per move: speed at the move's start and end, mm/min.
    pub entry_speed: Vec<f64>,
    pub exit_speed: Vec<f64>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CycleTimeError {
    #[error("feed_override has {got} entries for {expected} moves")]
    OverrideLength { got: usize, expected: usize },
    #[error("feed_override[{index}] = {value} is not a positive feed")]
    OverrideValue { index: usize, value: f64 },
    #[error("junction_deviation must be a non-negative number, got {0}")]
    Deviation(f64),
    #[error(transparent)]
    Machine(#[from] super::MachineError),
}

/// Cycle time with the default options. `feed_override`, when given, has one entry per move: the
/// rate along [`move_length`] per minute (mm/min; G93, G95 and the machine's rotary feed reading
/// already converted) that the move should run at instead of its programmed one; it is used for
/// linear and arc moves only.
pub fn cycle_time(
    moves: &[Move],
    machine: &Machine,
    feed_override: Option<&[f64]>,
) -> Result<CycleTime, CycleTimeError> {
    cycle_time_with(moves, machine, feed_override, &CycleTimeOptions::default())
}

/// Path length of a move in mm (XYZ; arcs by arc length), or its rotary distance in degrees
/// when X, Y and Z do not move: what the planner moves along ([`feed_reading::path_length`]).
pub fn move_length(m: &Move) -> f64 {
    feed_reading::path_length(m)
}

/// Rate of a feed move along [`move_length`] per minute (G93 and G95 converted), before the
/// machine's clamp, read as a `linear_only` control reads F. For callers without a machine;
/// with one, use `machine.rotary_feed_reading.path_rate(m)` (the two differ only on a
/// `combined` machine's moves with XYZ and rotary travel).
pub fn feed_velocity(m: &Move) -> f64 {
    RotaryFeedReading::LinearOnly.path_rate(m)
}

/// Per-move planning data.
struct Seg {
    /// Motion move (vs a stop: dwell, tool change, zero-length move).
    motion: bool,
    len: f64,
    /// Nominal (cruise) speed and path acceleration, mm/s and mm/s².
    v: f64,
    a: f64,
    /// Path jerk, mm/s³ (infinite without a jerk limit).
    j: f64,
    u_in: [f64; 3],
    u_out: [f64; 3],
    fixed: f64,
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = norm(v);
    (n > 1e-12).then(|| [v[0] / n, v[1] / n, v[2] / n])
}

/// Largest acceleration along unit direction u that keeps every axis within its limit.
fn axis_limited(acc: [f64; 3], u: [f64; 3]) -> f64 {
    (0..3)
        .filter(|&i| u[i].abs() > 1e-12)
        .map(|i| acc[i] / u[i].abs())
        .fold(f64::INFINITY, f64::min)
}

/// Tangent of an arc at parameter t (0 start, 1 end), unit, in XYZ.
fn arc_tangent(m: &Move, t: f64) -> Option<[f64; 3]> {
    let g = m.arc.as_ref()?;
    let [a, b, n] = g.axes;
    let th0 = (g.start[b] - g.center[b]).atan2(g.start[a] - g.center[a]);
    let th = th0 + g.sweep * t;
    let r = g.start_radius + (g.end_radius - g.start_radius) * t;
    let dr = g.end_radius - g.start_radius;
    let mut d = [0.0; 3];
    d[a] = dr * th.cos() - r * g.sweep * th.sin();
    d[b] = dr * th.sin() + r * g.sweep * th.cos();
    d[n] = g.end[n] - g.start[n];
    unit(d)
}

fn plan_seg(m: &Move, machine: &Machine, over: Option<f64>) -> Seg {
    let acc = machine.acceleration;
    let stop = |fixed: f64| Seg {
        motion: false,
        len: 0.0,
        v: 0.0,
        a: 1.0,
        j: f64::INFINITY,
        u_in: [0.0; 3],
        u_out: [0.0; 3],
        fixed,
    };
    let len = move_length(m);
    match m.kind {
        MoveKind::Dwell => return stop(m.seconds.unwrap_or(0.0).max(0.0)),
        MoveKind::ToolChange => return stop(machine.tool_change_time),
        _ if len.is_nan() || len <= 1e-9 => return stop(0.0),
        _ => {}
    }
    let v_prog = match m.kind {
        MoveKind::Rapid => machine.rapid_rate,
        _ => over
            .unwrap_or_else(|| machine.rotary_feed_reading.path_rate(m))
            .min(machine.max_feed),
    };
    let mut v = v_prog / 60.0;
    let min_acc = acc.iter().cloned().fold(f64::INFINITY, f64::min);
    let jerk = machine.jerk.unwrap_or([f64::INFINITY; 3]);
    let min_jerk = jerk.iter().cloned().fold(f64::INFINITY, f64::min);
    let (mut a, j, u_in, u_out) = if let (Some(g), Some(ti), Some(to)) =
        (m.arc.as_ref(), arc_tangent(m, 0.0), arc_tangent(m, 1.0))
    {
        let [pa, pb, pn] = g.axes;
        // The tangent sweeps the plane: the weaker plane axis bounds both the tangential and
        // the centripetal acceleration; a helix's normal axis is limited in proportion.
        let a_plane = acc[pa].min(acc[pb]);
        let un = (g.end[pn] - g.start[pn]).abs() / len;
        let (a_t, j_t) = if un > 1e-12 {
            (
                a_plane.min(acc[pn] / un),
                jerk[pa].min(jerk[pb]).min(jerk[pn] / un),
            )
        } else {
            (a_plane, jerk[pa].min(jerk[pb]))
        };
        let r = g.start_radius.max(g.end_radius);
        if r > 0.0 {
            v = v.min((a_plane * r).sqrt());
        }
        (a_t, j_t, ti, to)
    } else {
        let d = [
            m.end[0] - m.start[0],
            m.end[1] - m.start[1],
            m.end[2] - m.start[2],
        ];
        match unit(d) {
            Some(u) => (axis_limited(acc, u), axis_limited(jerk, u), u, u),
            // Pure rotary move without a rotary acceleration: the slowest linear axis's.
            None => (min_acc, min_jerk, [0.0; 3], [0.0; 3]),
        }
    };
    // The path runs over `len` (mm, or degrees on a rotary-only move) while the fastest
    // rotary axis turns `rotary` degrees: its speed and acceleration bound the path's.
    let rotary = m.rotary_travel();
    if rotary > 1e-9 {
        if let Some(w) = machine.max_rotary_speed_deg_min {
            v = v.min(len * w / rotary / 60.0);
        }
        if let Some(alpha) = machine.max_rotary_acceleration_deg_s2 {
            let a_rot = len * alpha / rotary;
            a = if u_in == [0.0; 3] {
                a_rot
            } else {
                a.min(a_rot)
            };
        }
    }
    Seg {
        motion: true,
        len,
        v,
        a,
        j,
        u_in,
        u_out,
        fixed: 0.0,
    }
}

/// Largest speed at the junction from `p` into `q`, mm/s (before the reachability passes).
fn junction_speed(p: &Seg, q: &Seg, acc: [f64; 3], delta: f64) -> f64 {
    let cap = p.v.min(q.v);
    if norm(p.u_out) == 0.0 || norm(q.u_in) == 0.0 {
        return 0.0; // rotary-only moves: no direction to blend
    }
    let cos_t = -(p.u_out[0] * q.u_in[0] + p.u_out[1] * q.u_in[1] + p.u_out[2] * q.u_in[2]);
    if cos_t <= -1.0 + 1e-9 {
        return cap; // straight on
    }
    if cos_t >= 1.0 - 1e-9 {
        return 0.0; // full reversal
    }
    let sin_half = (0.5 * (1.0 - cos_t)).sqrt();
    let ju = [
        q.u_in[0] - p.u_out[0],
        q.u_in[1] - p.u_out[1],
        q.u_in[2] - p.u_out[2],
    ];
    let a_j = unit(ju)
        .map(|u| axis_limited(acc, u))
        .unwrap_or(f64::INFINITY);
    let v2 = a_j * delta * sin_half / (1.0 - sin_half);
    v2.sqrt().min(cap)
}

/// Time to change speed by `dv` with acceleration `a` and jerk `j` (S-curve; `j` infinite: Δv/a).
pub fn ramp_time(dv: f64, a: f64, j: f64) -> f64 {
    let dv = dv.abs();
    if j.is_infinite() || dv >= a * a / j {
        dv / a + if j.is_infinite() { 0.0 } else { a / j }
    } else {
        2.0 * (dv / j).sqrt()
    }
}

/// Distance covered while changing speed from v0 to v1 (symmetric ramp: mean speed × time).
pub fn ramp_distance(v0: f64, v1: f64, a: f64, j: f64) -> f64 {
    0.5 * (v0 + v1) * ramp_time(v1 - v0, a, j)
}

/// Largest speed reachable from `v_from` within `len`.
fn reach(v_from: f64, len: f64, a: f64, j: f64) -> f64 {
    let hi = (v_from * v_from + 2.0 * a * len).sqrt();
    if j.is_infinite() {
        return hi;
    }
    // Jerk only slows the ramp: bisection below the constant-acceleration answer.
    let (mut lo, mut hi) = (v_from, hi);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if ramp_distance(v_from, mid, a, j) <= len {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi.max(1.0) {
            break;
        }
    }
    lo
}

/// Time of a profile over `len` from v0 to v1, cruise speed `v`, acceleration `a`, jerk `j`
/// (S-curve ramps; see the module doc). v0, v1 must be reachable.
pub fn profile_time_jerk(len: f64, v0: f64, v1: f64, v: f64, a: f64, j: f64) -> f64 {
    if j.is_infinite() {
        return profile_time(len, v0, v1, v, a);
    }
    if len <= 0.0 {
        return 0.0;
    }
    let d = ramp_distance(v0, v, a, j) + ramp_distance(v, v1, a, j);
    if d <= len {
        return ramp_time(v - v0, a, j) + ramp_time(v - v1, a, j) + (len - d) / v;
    }
    // No cruise: the peak speed where both ramps fill the move.
    let (mut lo, mut hi) = (v0.max(v1), v);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if ramp_distance(v0, mid, a, j) + ramp_distance(mid, v1, a, j) <= len {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi.max(1.0) {
            break;
        }
    }
    ramp_time(lo - v0, a, j) + ramp_time(lo - v1, a, j)
}

/// Time of a trapezoidal (or triangular) profile over `len` from speed v0 to v1 with cruise speed
/// `v` and acceleration `a`; v0, v1 must be reachable (the look-ahead passes ensure it).
pub fn profile_time(len: f64, v0: f64, v1: f64, v: f64, a: f64) -> f64 {
    if len <= 0.0 {
        return 0.0;
    }
    let peak2 = a * len + 0.5 * (v0 * v0 + v1 * v1);
    if peak2 <= v * v {
        let vp = peak2.sqrt();
        ((vp - v0).max(0.0) + (vp - v1).max(0.0)) / a
    } else {
        let d_acc = (v * v - v0 * v0) / (2.0 * a);
        let d_dec = (v * v - v1 * v1) / (2.0 * a);
        (v - v0) / a + (v - v1) / a + (len - d_acc - d_dec).max(0.0) / v
    }
}

/// Cycle time with explicit options.
pub fn cycle_time_with(
    moves: &[Move],
    machine: &Machine,
    feed_override: Option<&[f64]>,
    options: &CycleTimeOptions,
) -> Result<CycleTime, CycleTimeError> {
    machine.validate()?;
    let delta = options.junction_deviation;
    if !(delta.is_finite() && delta >= 0.0) {
        return Err(CycleTimeError::Deviation(delta));
    }
    if let Some(o) = feed_override {
        if o.len() != moves.len() {
            return Err(CycleTimeError::OverrideLength {
                got: o.len(),
                expected: moves.len(),
            });
        }
        for (i, m) in moves.iter().enumerate() {
            let feed_move = matches!(m.kind, MoveKind::Linear | MoveKind::Arc);
            if feed_move && !(o[i].is_finite() && o[i] > 0.0) {
                return Err(CycleTimeError::OverrideValue {
                    index: i,
                    value: o[i],
                });
            }
        }
    }
    let segs: Vec<Seg> = moves
        .iter()
        .enumerate()
        .map(|(i, m)| plan_seg(m, machine, feed_override.map(|o| o[i])))
        .collect();
    let n = segs.len();
    // Junction limit at the start of each move (entry) from the last motion move before it;
    // stops in between force rest. Zero-length moves are transparent.
    let mut v_entry_max = vec![0.0f64; n];
    let mut prev: Option<usize> = None;
    for i in 0..n {
        let s = &segs[i];
        if !s.motion {
            if s.fixed > 0.0
                || !matches!(
                    moves[i].kind,
                    MoveKind::Linear | MoveKind::Arc | MoveKind::Rapid
                )
            {
                prev = None;
            }
            continue;
        }
        v_entry_max[i] = match prev {
            Some(p) => junction_speed(&segs[p], s, machine.acceleration, delta),
            None => 0.0,
        };
        prev = Some(i);
    }
    // Exit speed of each motion move = entry speed of the next motion move (0 at a stop/end).
    let next_motion: Vec<Option<usize>> = {
        let mut nxt = vec![None; n];
        let mut following: Option<usize> = None;
        for i in (0..n).rev() {
            nxt[i] = following;
            let s = &segs[i];
            if s.motion {
                following = Some(i);
            } else if s.fixed > 0.0
                || !matches!(
                    moves[i].kind,
                    MoveKind::Linear | MoveKind::Arc | MoveKind::Rapid
                )
            {
                following = None;
            }
        }
        nxt
    };
    let mut v_in = v_entry_max.clone();
    // Backward pass: each entry speed must allow stopping/slowing to the next entry.
    for i in (0..n).rev() {
        if !segs[i].motion {
            continue;
        }
        let exit = next_motion[i].map(|j| v_in[j]).unwrap_or(0.0);
        let s = &segs[i];
        v_in[i] = v_in[i].min(reach(exit, s.len, s.a, s.j));
    }
    // Forward pass: each next entry must be reachable from this entry.
    for i in 0..n {
        if !segs[i].motion {
            continue;
        }
        if let Some(j) = next_motion[i] {
            let s = &segs[i];
            v_in[j] = v_in[j].min(reach(v_in[i], s.len, s.a, s.j));
        }
    }
    let mut out = CycleTime {
        per_move_s: Vec::with_capacity(n),
        entry_speed: Vec::with_capacity(n),
        exit_speed: Vec::with_capacity(n),
        ..Default::default()
    };
    for i in 0..n {
        let s = &segs[i];
        let (t, v0, v1) = if s.motion {
            let v0 = v_in[i];
            let v1 = next_motion[i].map(|j| v_in[j]).unwrap_or(0.0);
            out.nominal_s += s.len / s.v;
            (profile_time_jerk(s.len, v0, v1, s.v, s.a, s.j), v0, v1)
        } else {
            (0.0, 0.0, 0.0)
        };
        let t = t + s.fixed;
        match moves[i].kind {
            MoveKind::Rapid => out.rapid_s += t,
            MoveKind::Linear | MoveKind::Arc => out.cutting_s += t,
            MoveKind::Dwell => out.dwell_s += t,
            MoveKind::ToolChange => out.tool_change_s += t,
        }
        out.nominal_s += s.fixed;
        out.total_s += t;
        out.per_move_s.push(t);
        out.entry_speed.push(v0 * 60.0);
        out.exit_speed.push(v1 * 60.0);
    }
    Ok(out)
}
