//! pd-bond's force kernel in explicit AVX-512 (the path this crate's benchmark machine takes).
//!
//! The auto-vectorised chunk kernel spends most of its time moving data: six scalar loads
//! and six stores per bond to gather the neighbour's X and u into structure-of-arrays
//! scratch, which is read back for the arithmetic. Here each particle's X and u sit in one
//! 64-byte [`Record`]; eight neighbours are loaded with one load each and transposed in
//! registers (22 two-source permutes for eight bonds), and the arithmetic runs on the
//! registers directly; each lane of the eight-lane sum of [`super::lane_tree`] is one vector
//! lane. The per-bond operations, their order and the summation order are those of the
//! scalar loop, so the forces and bond states are bit-identical with every other path
//! (tested in `bond.rs`).
// The kernel names the bond quantities as the scalar loop does (x, e, y, q, il, cb).
#![allow(clippy::too_many_arguments, clippy::many_single_char_names)]

use crate::pd::avx512::{Record, gather8, lane_mask, load_lanes, reduce, splat3};
use crate::pd::family::spare_mask;
use std::arch::x86_64::*;

/// Packs X and u into `out` (resized to the particle count): `[X₀, X₁, X₂, u₀, u₁, u₂, 0, 0]`.
pub fn pack(x0: &[[f64; 3]], disp: &[[f64; 3]], out: &mut Vec<Record>) {
    crate::pd::avx512::pack(x0.len().min(disp.len()), out, |i, r| {
        let (x, u) = (x0[i], disp[i]);
        r.0 = [x[0], x[1], x[2], u[0], u[1], u[2], 0.0, 0.0];
    });
}

/// The force density of particle `i` over its row (`nbr`, `inv_len`, `coef` are the row's
/// slices), breaking bonds first as the scalar loop does; `critical` = (1 + s0)².
#[inline]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
fn row_force(
    i: usize,
    rec: &[Record],
    nbr: &[u32],
    inv_len: &[f64],
    coef: &mut [f64],
    critical: f64,
    no_fail: &[bool],
) -> ([f64; 3], u32) {
    let ri = rec[i].0;
    let [bx0, bx1, bx2] = splat3(ri[0], ri[1], ri[2]);
    let [bu0, bu1, bu2] = splat3(ri[3], ri[4], ri[5]);
    let two = _mm512_set1_pd(2.0);
    let zero = _mm512_setzero_pd();
    let neg_zero = _mm512_set1_pd(-0.0);
    let crit = _mm512_set1_pd(critical);
    let zones = !no_fail.is_empty();
    let len = nbr.len().min(inv_len.len()).min(coef.len());
    // lane l sums bonds l, l + 8, l + 16, … of the row ([`super::lane_tree`])
    let (mut ax, mut ay, mut az) = (zero, zero, zero);
    let mut breaks = 0u32;
    let mut start = 0;
    while start < len {
        let n = (len - start).min(8);
        let nb = &nbr[start..start + n];
        // lanes past the row's end load particle i itself (any valid record; not summed)
        let j = |b: usize| if b < n { nb[b] as usize } else { i };
        let js = [j(0), j(1), j(2), j(3), j(4), j(5), j(6), j(7)];
        let [gx0, gx1, gx2, gu0, gu1, gu2, _, _] = gather8(rec, &js);
        let il = load_lanes(&inv_len[start..], n);
        let cb = load_lanes(&coef[start..], n);
        // the scalar loop's operations, in its order (no FMA)
        let (x0, x1, x2) = (
            _mm512_sub_pd(gx0, bx0),
            _mm512_sub_pd(gx1, bx1),
            _mm512_sub_pd(gx2, bx2),
        );
        let (ex, ey, ez) = (
            _mm512_sub_pd(gu0, bu0),
            _mm512_sub_pd(gu1, bu1),
            _mm512_sub_pd(gu2, bu2),
        );
        let num = _mm512_add_pd(
            _mm512_add_pd(
                _mm512_mul_pd(ex, _mm512_add_pd(_mm512_mul_pd(two, x0), ex)),
                _mm512_mul_pd(ey, _mm512_add_pd(_mm512_mul_pd(two, x1), ey)),
            ),
            _mm512_mul_pd(ez, _mm512_add_pd(_mm512_mul_pd(two, x2), ez)),
        );
        let (yx, yy, yz) = (
            _mm512_add_pd(x0, ex),
            _mm512_add_pd(x1, ey),
            _mm512_add_pd(x2, ez),
        );
        let q = _mm512_add_pd(
            _mm512_add_pd(_mm512_mul_pd(yx, yx), _mm512_mul_pd(yy, yy)),
            _mm512_mul_pd(yz, yz),
        );
        let lanes = lane_mask(n);
        let qil = _mm512_mul_pd(q, il);
        let broken = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(_mm512_mul_pd(qil, il), crit) & lanes;
        // less what a no-fail zone keeps (looked at only when some bond breaks)
        let broken = if zones && broken != 0 {
            spare_mask(no_fail, i, nb, broken)
        } else {
            broken
        };
        let ly = _mm512_sqrt_pd(q);
        let t = _mm512_mul_pd(_mm512_mul_pd(num, il), il);
        let m = _mm512_div_pd(_mm512_mul_pd(cb, t), _mm512_add_pd(qil, ly));
        let intact = _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(cb, zero);
        let live = intact & !broken & lanes;
        breaks += (intact & broken).count_ones();
        if broken != 0 {
            // SAFETY: only lanes set in `broken` ⊆ the first n are written, and
            // coef[start..start + n] is in bounds (n ≤ len − start).
            unsafe { _mm512_mask_storeu_pd(coef[start..].as_mut_ptr(), broken, zero) };
        }
        // a lane that is not a live bond adds −0.0, the identity of addition
        ax = _mm512_add_pd(ax, _mm512_mask_mul_pd(neg_zero, live, m, yx));
        ay = _mm512_add_pd(ay, _mm512_mask_mul_pd(neg_zero, live, m, yy));
        az = _mm512_add_pd(az, _mm512_mask_mul_pd(neg_zero, live, m, yz));
        start += n;
    }
    ([reduce(ax), reduce(ay), reduce(az)], breaks)
}

/// The force densities of the block of particles `lo..lo + f.len()`; `coef` holds those
/// rows' bonds; returns how many bonds broke. Call only on a CPU with AVX-512 F/DQ/VL.
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
pub fn block_force(
    lo: usize,
    f: &mut [[f64; 3]],
    coef: &mut [f64],
    offsets: &[usize],
    rec: &[Record],
    nbr: &[u32],
    inv_len: &[f64],
    critical: f64,
    no_fail: &[bool],
) -> u32 {
    let base = offsets[lo];
    let mut breaks = 0;
    for (k, fi) in f.iter_mut().enumerate() {
        let i = lo + k;
        let r = offsets[i]..offsets[i + 1];
        let (fr, nb) = row_force(
            i,
            rec,
            &nbr[r.clone()],
            &inv_len[r.clone()],
            &mut coef[r.start - base..r.end - base],
            critical,
            no_fail,
        );
        *fi = fr;
        breaks += nb;
    }
    breaks
}
