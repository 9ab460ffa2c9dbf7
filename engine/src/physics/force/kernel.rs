//! The inner loop: per (slice, tooth) constants (`SliceConstants`), one tooth's forces over a run of
//! sample positions (`run_segment`), the sample-angle helpers, and the per-tooth buffers'
//! helpers of the accumulation.

use std::f64::consts::{FRAC_PI_2, TAU};

use super::edge::EdgeSlice;
use crate::physics::material::CuttingCoefficients;

/// Per (slice, tooth) constants of the inner loop. Each force component of the slice is
/// a·X + b0 + bv·V with X the chip's part across the axis (c_h·sin φ, plus runout) and V
/// its part along it (c_v); components: Ft, in-plane radial (outward), Fz, torque (N·mm).
/// With a size effect the cutting part of each direction (t, r, a) is scaled by h^(−m) of
/// the slice-centre chip h (`sized`), so it is kept per direction as well.
/// The axial force enters with the generalized transformation's sign (see the module doc of
/// `force`): −dFa·cos κ outward in the plane, −dFa·sin κ along the axis.
#[derive(Clone, Copy)]
pub(super) struct SliceConstants {
    /// A chip thinner than −eps is no cut.
    eps: f64,
    pub(super) sa: f64,
    pub(super) ca: f64,
    ch: f64,
    cv: f64,
    sk: f64,
    ck: f64,
    a: [f64; 4],
    b0: [f64; 4],
    bv: [f64; 4],
    /// Size effect: the exponents (t, r, a) and each direction's a and bv rows.
    sized: Option<SizeParts>,
}

#[derive(Clone, Copy)]
struct SizeParts {
    m: [f64; 3],
    a: [[f64; 4]; 3],
    bv: [[f64; 4]; 3],
}

/// The chip below which K(h) = K·h^(−m) is taken at this value (mm): the force K·h^(1−m)·b
/// goes to 0 with h, only the factor would overflow.
const SIZE_EFFECT_MIN_CHIP: f64 = 1e-6;

impl SliceConstants {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        g: &EdgeSlice,
        k: &CuttingCoefficients,
        (sa, ca): (f64, f64),
        ch: f64,
        cv: f64,
        eps: f64,
    ) -> SliceConstants {
        let sized = k.has_size_effect().then(|| SizeParts {
            m: k.exponents(),
            a: [
                [k.ktc * g.dz, 0.0, 0.0, k.ktc * g.int_r_dz],
                [0.0, -k.krc * g.int_sin, k.krc * g.int_cos, 0.0],
                [0.0, -k.kac * g.int_cos, -k.kac * g.int_sin, 0.0],
            ],
            bv: [
                [-k.ktc * g.int_cot, 0.0, 0.0, -k.ktc * g.int_r_cot],
                [0.0, k.krc * g.int_cos, -k.krc * g.int_cos2_sin, 0.0],
                [0.0, k.kac * g.int_cos2_sin, k.kac * g.int_cos, 0.0],
            ],
        });
        SliceConstants {
            sized,
            eps,
            sa,
            ca,
            ch,
            cv,
            sk: g.sin_kappa,
            ck: g.cos_kappa,
            a: [
                k.ktc * g.dz,
                -k.krc * g.int_sin - k.kac * g.int_cos,
                k.krc * g.int_cos - k.kac * g.int_sin,
                k.ktc * g.int_r_dz,
            ],
            b0: [
                k.kte * g.edge_length,
                -k.kre * g.dz - k.kae * g.radius_rise,
                k.kre * g.radius_rise - k.kae * g.dz,
                k.kte * g.int_r_ds,
            ],
            bv: [
                -k.ktc * g.int_cot,
                k.krc * g.int_cos + k.kac * g.int_cos2_sin,
                -k.krc * g.int_cos2_sin + k.kac * g.int_cos,
                -k.ktc * g.int_r_cot,
            ],
        }
    }

    /// (h at the slice centre, X, V) of the chip this tooth cuts at sin φ: the thinnest over
    /// the surfaces left 1..N teeth earlier.
    #[inline(always)]
    pub(super) fn chip(&self, steps: &[f64], sphi: f64) -> (f64, f64, f64) {
        let x0 = self.ch * sphi;
        if steps.is_empty() {
            return (x0 * self.sk - self.cv * self.ck, x0, self.cv);
        }
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for (m, d) in steps.iter().enumerate() {
            let mf = (m + 1) as f64;
            let x = mf * x0 + d;
            let v = mf * self.cv;
            let h = x * self.sk - v * self.ck;
            if h < best.0 {
                best = (h, x, v);
            }
        }
        best
    }

    /// Whether each sample needs its own chip (size effect): no affine shortcut.
    pub(super) fn is_sized(&self) -> bool {
        self.sized.is_some()
    }

    #[inline(always)]
    fn force(&self, x: f64, v: f64, sphi: f64, cphi: f64) -> [f64; 4] {
        if let Some(sz) = &self.sized {
            let h = (x * self.sk - v * self.ck).max(SIZE_EFFECT_MIN_CHIP);
            let mut f = self.b0;
            for d in 0..3 {
                let scale = h.powf(-sz.m[d]);
                for (i, fi) in f.iter_mut().enumerate() {
                    *fi += scale * (sz.a[d][i] * x + sz.bv[d][i] * v);
                }
            }
            let [ft, fp, fz, tq] = f;
            return [fp * sphi - ft * cphi, ft * sphi + fp * cphi, fz, tq];
        }
        let ft = self.a[0] * x + self.b0[0] + self.bv[0] * v;
        let fp = self.a[1] * x + self.b0[1] + self.bv[1] * v;
        let fz = self.a[2] * x + self.b0[2] + self.bv[2] * v;
        let tq = self.a[3] * x + self.b0[3] + self.bv[3] * v;
        [fp * sphi - ft * cphi, ft * sphi + fp * cphi, fz, tq]
    }

    /// Force at the immersion φ with sin φ = `s`, cos φ = `c`, zero where the tooth does not
    /// cut.
    #[inline]
    pub(super) fn force_at_sin_cos(&self, steps: &[f64], s: f64, c: f64) -> [f64; 4] {
        let (h, x, v) = self.chip(steps, s);
        if h >= -self.eps {
            self.force(x, v, s, c)
        } else {
            [0.0; 4]
        }
    }
}

/// Adds one tooth's forces over a contiguous run of sample positions (sin θ, cos θ in
/// `st`, `ct`). Without runout every component is affine in sin φ; branch-free and without
/// reductions so it vectorizes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn run_segment(
    p: &SliceConstants,
    steps: &[f64],
    st: &[f64],
    ct: &[f64],
    fx: &mut [f64],
    fy: &mut [f64],
    fz: &mut [f64],
    tq: &mut [f64],
    scratch: &mut [f64],
) {
    let n = st.len();
    let (ct, fx, fy, fz, tq) = (
        &ct[..n],
        &mut fx[..n],
        &mut fy[..n],
        &mut fz[..n],
        &mut tq[..n],
    );
    let (sa, ca) = (p.sa, p.ca);
    if steps.is_empty() && !p.is_sized() {
        let (hs, hv) = (p.ch * p.sk, p.cv * p.ck);
        let a = p.a.map(|v| v * p.ch);
        let b = [0, 1, 2, 3].map(|i| p.b0[i] + p.bv[i] * p.cv);
        for i in 0..n {
            let s = st[i] * ca - ct[i] * sa;
            let c = ct[i] * ca + st[i] * sa;
            let on = if hs * s - hv >= -p.eps { 1.0 } else { 0.0 };
            let ft = (a[0] * s + b[0]) * on;
            let fp = (a[1] * s + b[1]) * on;
            fx[i] += fp * s - ft * c;
            fy[i] += ft * s + fp * c;
            fz[i] += (a[2] * s + b[2]) * on;
            tq[i] += (a[3] * s + b[3]) * on;
        }
    } else {
        // Runout: the thinnest of the N candidate chips, found one candidate at a time over
        // the whole run (branch-free selects that vectorize) in scratch buffers.
        let (sb, rest) = scratch.split_at_mut(n);
        let (cb, rest) = rest.split_at_mut(n);
        let (bh, rest) = rest.split_at_mut(n);
        let (bm, rest) = rest.split_at_mut(n);
        let bd = &mut rest[..n];
        for i in 0..n {
            sb[i] = st[i] * ca - ct[i] * sa;
            cb[i] = ct[i] * ca + st[i] * sa;
            bh[i] = f64::INFINITY;
            bm[i] = 0.0;
            bd[i] = 0.0;
        }
        let (hs, hv) = (p.ch * p.sk, p.cv * p.ck);
        // Without runout (a size effect brings us here) the one chip is this tooth's own.
        let steps = if steps.is_empty() { &[0.0][..] } else { steps };
        for (m, &d) in steps.iter().enumerate() {
            let mf = (m + 1) as f64;
            let e = d * p.sk;
            for i in 0..n {
                let h = mf * (hs * sb[i] - hv) + e;
                let better = h < bh[i];
                bh[i] = if better { h } else { bh[i] };
                bm[i] = if better { mf } else { bm[i] };
                bd[i] = if better { d } else { bd[i] };
            }
        }
        for i in 0..n {
            let (s, c) = (sb[i], cb[i]);
            let on = if bh[i] >= -p.eps { 1.0 } else { 0.0 };
            let x = bm[i] * p.ch * s + bd[i];
            let v = bm[i] * p.cv;
            let f = p.force(x, v, s, c);
            fx[i] += f[0] * on;
            fy[i] += f[1] * on;
            fz[i] += f[2] * on;
            tq[i] += f[3] * on;
        }
    }
}

/// (sin φ, cos φ) at sample position `k` for a tooth at α (φ = k·Δ − α), from the tables
/// of the positions' sin and cos and (sin α, cos α): the rotation `run_segment` uses,
/// without a call to sin or cos.
#[inline]
pub(super) fn sample_sin_cos(st: &[f64], ct: &[f64], k: i64, sa: f64, ca: f64) -> (f64, f64) {
    let i = k.rem_euclid(st.len() as i64) as usize;
    (st[i] * ca - ct[i] * sa, ct[i] * ca + st[i] * sa)
}

/// Largest sin φ over the samples k = k0..k0+count (φ = k·Δ − α): at the sample nearest a
/// crest φ ≡ π/2 inside the run, else at an end (sin is unimodal between troughs). The chip
/// grows with sin φ (with runout too), so this gives the largest chip without a reduction in
/// the inner loop.
pub(super) fn max_sin(
    st: &[f64],
    ct: &[f64],
    k0: i64,
    count: usize,
    sa: f64,
    ca: f64,
    alpha: f64,
) -> f64 {
    let delta = TAU / st.len() as f64;
    let sin_at = |j: i64| sample_sin_cos(st, ct, k0 + j, sa, ca).0;
    let last = count as i64 - 1;
    let mut best = sin_at(0).max(sin_at(last));
    let phi0 = k0 as f64 * delta - alpha;
    let phi1 = phi0 + last as f64 * delta;
    let crest = FRAC_PI_2 + TAU * ((phi0 - FRAC_PI_2) / TAU).ceil();
    if crest <= phi1 {
        let i = ((crest - phi0) / delta).floor() as i64;
        for j in [i, i + 1] {
            if (0..=last).contains(&j) {
                best = best.max(sin_at(j));
            }
        }
    }
    best
}

/// The four component blocks (fx, fy, fz, torque) of `len` each of a sample buffer (empty
/// slices for an unused buffer).
pub(super) fn four_blocks(buf: &mut [f64], len: usize) -> [&mut [f64]; 4] {
    if buf.is_empty() {
        return [&mut [], &mut [], &mut [], &mut []];
    }
    let (x, rest) = buf.split_at_mut(len);
    let (y, rest) = rest.split_at_mut(len);
    let (z, t) = rest.split_at_mut(len);
    [x, y, z, t]
}

/// What one accumulation over the engagement's slices gives besides the per-tooth samples.
#[derive(Clone, Copy)]
pub(super) struct Accumulated {
    /// Boundary-bin corrections that turn the sample sum into the time integral.
    pub(super) corr: [f64; 4],
    pub(super) engaged: usize,
    pub(super) skipped: usize,
    /// Only tooth 1 was computed; tooth j is it shifted by j pitches.
    pub(super) symmetric: bool,
    /// Height above the tip of the lowest cutting point, mm (infinite when nothing cuts).
    pub(super) lowest: f64,
}

/// Sums the teeth's samples (`acc`: four blocks of N·K) into `tot` (four blocks of K); with
/// the symmetry shortcut tooth j is row 1 shifted by j pitches.
pub(super) fn tooth_totals(acc: &[f64], n: usize, kpos: usize, symmetric: bool, tot: &mut [f64]) {
    let nk = n * kpos;
    let shift = if symmetric { kpos / n } else { 0 };
    tot.fill(0.0);
    for c in 0..4 {
        let tot = &mut tot[c * kpos..(c + 1) * kpos];
        for j in 0..n {
            let (row, s) = if symmetric {
                (&acc[c * nk..c * nk + kpos], (j * shift) % kpos)
            } else {
                (&acc[c * nk + j * kpos..c * nk + (j + 1) * kpos], 0)
            };
            for (t, r) in tot[s..].iter_mut().zip(&row[..kpos - s]) {
                *t += r;
            }
            for (t, r) in tot[..s].iter_mut().zip(&row[kpos - s..]) {
                *t += r;
            }
        }
    }
}
