//! pd-correspondence's bond kernels in explicit AVX-512 (pass-1 family sums, and the force
//! loop for damage laws that are a pure critical stretch or none). Each particle's X, u, v,
//! V and its bond side (Â, κ) are packed in cache-line records once per step; eight
//! neighbours are loaded with one load per record and transposed in registers
//! ([`crate::pd::avx512`]), and each lane of the eight-lane sums of
//! [`crate::pd::bond::lane_tree`] is one vector lane. The per-bond operations and their
//! order are the multiversioned kernels'; only the summation order differs (eight lanes
//! instead of row order, which the SSE2/AVX2 kernels keep: a lane order would cost them
//! about 20 %, with 19 × 8 pass-1 accumulators on 16 registers). So these kernels equal a
//! lane-order reference bit for bit and the row-order kernels to rounding (tested in
//! `correspondence.rs`); results stay identical for any thread count.
// The kernels name the bond quantities as the scalar loops do (x, e, y, q, w, il).
#![allow(clippy::too_many_arguments, clippy::many_single_char_names)]

use super::{BondSide, FamilySums};
use crate::pd::avx512::{
    Pair, Record, gather_pairs, gather8, lane_mask, load_lanes, pack, reduce, splat3,
};
use crate::pd::family::spare_mask;
use crate::pd::model::Kinematics;
use std::arch::x86_64::*;

/// The per-particle records of one step.
#[derive(Debug, Clone, Default)]
pub struct Packed {
    /// `[X₀, X₁, X₂, u₀, u₁, u₂, v₀, v₁]`
    kin: Vec<Record>,
    /// `[v₂, V]`
    kin2: Vec<Pair>,
    /// Â row by row, its first eight entries
    side: Vec<Record>,
    /// `[Â₂₂, κ]`
    side2: Vec<Pair>,
}

impl Packed {
    /// X, u, v and V of every particle (before pass 1).
    pub fn pack_particles(&mut self, k: &Kinematics) {
        let n = k.x0.len();
        pack(n, &mut self.kin, |i, r| {
            let (x, u, v) = (k.x0[i], k.disp[i], k.vel[i]);
            r.0 = [x[0], x[1], x[2], u[0], u[1], u[2], v[0], v[1]];
        });
        pack(n, &mut self.kin2, |i, r| r.0 = [k.vel[i][2], k.vol[i]]);
    }

    /// Â and κ of every particle (after pass 1).
    pub fn pack_sides(&mut self, side: &[BondSide]) {
        let n = side.len();
        pack(n, &mut self.side, |i, r| {
            let a = side[i].ahat;
            r.0 = [
                a[0][0], a[0][1], a[0][2], a[1][0], a[1][1], a[1][2], a[2][0], a[2][1],
            ];
        });
        pack(n, &mut self.side2, |i, r| {
            r.0 = [side[i].ahat[2][2], side[i].kappa]
        });
    }
}

/// Pass-1 sums of particle `i` over its row (`nbr`, `intact` the row's slices), in the
/// eight-lane order. A broken bond, and a lane past the row's end, loads particle i itself
/// with ω = 0: ξ = 0 and ω V = 0, so it adds +0.0 to every lane, as the scalar kernel's
/// broken bond does.
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
pub fn family_sums(i: usize, p: &Packed, nbr: &[u32], intact: &[f64]) -> FamilySums {
    let (me, me2) = (p.kin[i].0, p.kin2[i].0);
    let bx = splat3(me[0], me[1], me[2]);
    let bu = splat3(me[3], me[4], me[5]);
    let bv = splat3(me[6], me[7], me2[0]);
    let zero = _mm512_setzero_pd();
    let mut nn = [[zero; 3]; 3];
    let mut nd = [[zero; 3]; 3];
    let mut w0 = zero;
    let len = nbr.len().min(intact.len());
    let mut start = 0;
    while start < len {
        let n = (len - start).min(8);
        let (nb, om) = (&nbr[start..start + n], &intact[start..start + n]);
        let j = |b: usize| {
            if b < n && om[b] != 0.0 {
                nb[b] as usize
            } else {
                i
            }
        };
        let js = [j(0), j(1), j(2), j(3), j(4), j(5), j(6), j(7)];
        let [gx0, gx1, gx2, gu0, gu1, gu2, gv0, gv1] = gather8(&p.kin, &js);
        let (gv2, gvol) = gather_pairs(&p.kin2, &js);
        // ω V (0 for a broken bond and past the row's end: ω is loaded as 0 there)
        let w = _mm512_mul_pd(load_lanes(om, n), gvol);
        let x = [
            _mm512_sub_pd(gx0, bx[0]),
            _mm512_sub_pd(gx1, bx[1]),
            _mm512_sub_pd(gx2, bx[2]),
        ];
        let wy = [
            _mm512_mul_pd(w, _mm512_sub_pd(gu0, bu[0])),
            _mm512_mul_pd(w, _mm512_sub_pd(gu1, bu[1])),
            _mm512_mul_pd(w, _mm512_sub_pd(gu2, bu[2])),
        ];
        let wv = [
            _mm512_mul_pd(w, _mm512_sub_pd(gv0, bv[0])),
            _mm512_mul_pd(w, _mm512_sub_pd(gv1, bv[1])),
            _mm512_mul_pd(w, _mm512_sub_pd(gv2, bv[2])),
        ];
        w0 = _mm512_add_pd(w0, w);
        for a in 0..3 {
            for c in 0..3 {
                nn[a][c] = _mm512_add_pd(nn[a][c], _mm512_mul_pd(wy[a], x[c]));
                nd[a][c] = _mm512_add_pd(nd[a][c], _mm512_mul_pd(wv[a], x[c]));
            }
        }
        start += n;
    }
    let mut sums = FamilySums::default();
    for a in 0..3 {
        for c in 0..3 {
            sums.nn[a][c] = reduce(nn[a][c]);
            sums.nd[a][c] = reduce(nd[a][c]);
        }
    }
    sums.w0 = reduce(w0);
    sums
}

/// The force pass over the block of particles `lo..lo + f.len()` (rows' intact fractions in
/// `intact`) for a damage law that breaks a bond for good when |y|²/|ξ|² > `lim` = (1 + s0)²
/// (∞: never), as the scalar `force_block_body` does it. Returns how many bonds broke.
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
pub fn force_block(
    lo: usize,
    f: &mut [[f64; 3]],
    intact: &mut [f64],
    offsets: &[usize],
    nbr: &[u32],
    inv_len: &[f64],
    p: &Packed,
    lim: f64,
    no_fail: &[bool],
    inv_h: f64,
) -> u32 {
    let base = offsets[lo];
    let mut broke = 0;
    let zero = _mm512_setzero_pd();
    let neg_zero = _mm512_set1_pd(-0.0);
    let (lim, inv_h) = (_mm512_set1_pd(lim), _mm512_set1_pd(inv_h));
    let zones = !no_fail.is_empty();
    for (pi, fi) in f.iter_mut().enumerate() {
        let i = lo + pi;
        let me = p.kin[i].0;
        let bx = splat3(me[0], me[1], me[2]);
        let bu = splat3(me[3], me[4], me[5]);
        let (s, s2) = (p.side[i].0, p.side2[i].0);
        let ai = [
            splat3(s[0], s[1], s[2]),
            splat3(s[3], s[4], s[5]),
            splat3(s[6], s[7], s2[0]),
        ];
        let kappa_i = _mm512_set1_pd(s2[1]);
        let r = offsets[i]..offsets[i + 1];
        let (nb, il_row) = (&nbr[r.clone()], &inv_len[r.clone()]);
        let om_row = &mut intact[r.start - base..r.end - base];
        let len = nb.len().min(il_row.len()).min(om_row.len());
        let mut acc = [zero; 3];
        let mut start = 0;
        while start < len {
            let n = (len - start).min(8);
            // lanes past the row's end load particle i itself (not summed)
            let j = |b: usize| if b < n { nb[start + b] as usize } else { i };
            let js = [j(0), j(1), j(2), j(3), j(4), j(5), j(6), j(7)];
            let [gx0, gx1, gx2, gu0, gu1, gu2, _, _] = gather8(&p.kin, &js);
            let (_, gvol) = gather_pairs(&p.kin2, &js);
            let [a00, a01, a02, a10, a11, a12, a20, a21] = gather8(&p.side, &js);
            let (a22, kappa_j) = gather_pairs(&p.side2, &js);
            let aj = [[a00, a01, a02], [a10, a11, a12], [a20, a21, a22]];
            let om = load_lanes(&om_row[start..], n);
            let il = load_lanes(&il_row[start..], n);
            let x = [
                _mm512_sub_pd(gx0, bx[0]),
                _mm512_sub_pd(gx1, bx[1]),
                _mm512_sub_pd(gx2, bx[2]),
            ];
            let e = [
                _mm512_sub_pd(gu0, bu[0]),
                _mm512_sub_pd(gu1, bu[1]),
                _mm512_sub_pd(gu2, bu[2]),
            ];
            let y = [
                _mm512_add_pd(x[0], e[0]),
                _mm512_add_pd(x[1], e[1]),
                _mm512_add_pd(x[2], e[2]),
            ];
            let q = _mm512_add_pd(
                _mm512_add_pd(_mm512_mul_pd(y[0], y[0]), _mm512_mul_pd(y[1], y[1])),
                _mm512_mul_pd(y[2], y[2]),
            );
            let lanes = lane_mask(n);
            let broken =
                _mm512_cmp_pd_mask::<_CMP_GT_OQ>(_mm512_mul_pd(_mm512_mul_pd(q, il), il), lim)
                    & lanes;
            // the scalar loop skips ω = 0, and breaks (ω = 0) or keeps ω otherwise
            let nonzero = _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(om, zero) & lanes;
            // less what a no-fail zone keeps (looked at only when an intact bond breaks)
            let broken = if zones && nonzero & broken != 0 {
                spare_mask(no_fail, i, &nb[start..start + n], broken)
            } else {
                broken
            };
            let breaks = nonzero & broken;
            broke += breaks.count_ones();
            if breaks != 0 {
                // SAFETY: only lanes set in `breaks` ⊆ the first n are written, and
                // om_row[start..start + n] is in bounds (n ≤ len − start).
                unsafe { _mm512_mask_storeu_pd(om_row[start..].as_mut_ptr(), breaks, zero) };
            }
            let live = nonzero & !broken;
            let w = _mm512_mul_pd(om, gvol);
            let ks = _mm512_mul_pd(_mm512_add_pd(kappa_i, kappa_j), inv_h);
            for c in 0..3 {
                // eq. (183) with (186): T_i⟨ξ⟩ − T_j⟨−ξ⟩
                let t = _mm512_add_pd(
                    _mm512_add_pd(
                        _mm512_mul_pd(_mm512_add_pd(ai[c][0], aj[c][0]), x[0]),
                        _mm512_mul_pd(_mm512_add_pd(ai[c][1], aj[c][1]), x[1]),
                    ),
                    _mm512_mul_pd(_mm512_add_pd(ai[c][2], aj[c][2]), x[2]),
                );
                let term = _mm512_mask_mul_pd(
                    neg_zero,
                    live,
                    w,
                    _mm512_add_pd(t, _mm512_mul_pd(ks, e[c])),
                );
                acc[c] = _mm512_add_pd(acc[c], term);
            }
            start += n;
        }
        *fi = [reduce(acc[0]), reduce(acc[1]), reduce(acc[2])];
    }
    broke
}
