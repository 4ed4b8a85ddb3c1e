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

use std::arch::x86_64::*;

/// One particle's reference position and displacement in one cache line:
/// `[X₀, X₁, X₂, u₀, u₁, u₂, 0, 0]`.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(64))]
pub struct Record(pub [f64; 8]);

/// Packs X and u into `out` (resized to the particle count), in parallel.
pub fn pack(x0: &[[f64; 3]], disp: &[[f64; 3]], out: &mut Vec<Record>) {
    use rayon::prelude::*;
    let n = x0.len().min(disp.len());
    out.resize(n, Record::default());
    out.par_iter_mut()
        .with_min_len(4096)
        .zip(x0.par_iter().zip(disp.par_iter()))
        .for_each(|(r, (x, u))| {
            r.0 = [x[0], x[1], x[2], u[0], u[1], u[2], 0.0, 0.0];
        });
}

/// Loads one record.
#[inline]
#[target_feature(enable = "avx512f")]
fn load_record(r: &Record) -> __m512d {
    // SAFETY: `r` is a reference to 8 initialised, 64-byte-aligned doubles.
    unsafe { _mm512_load_pd(r.0.as_ptr()) }
}

/// The first `n ≤ 8` values of `v` in a vector, zeros above (those lanes are not read).
#[inline]
#[target_feature(enable = "avx512f")]
fn load_lanes(v: &[f64], n: usize) -> __m512d {
    assert!(n <= 8 && v.len() >= n);
    if n == 8 {
        // SAFETY: `v` has at least 8 elements (asserted).
        unsafe { _mm512_loadu_pd(v.as_ptr()) }
    } else {
        // SAFETY: only the lanes set in the mask, the first n < v.len() + 1 elements, are
        // read; masked-off lanes are neither read nor faulted on.
        unsafe { _mm512_maskz_loadu_pd(((1u32 << n) - 1) as u8, v.as_ptr()) }
    }
}

/// Index vector of `_mm512_permutex2var_pd` (lane k takes element `e[k]`; 8–15 = 2nd source).
#[inline]
#[target_feature(enable = "avx512f")]
fn idx(e: [i64; 8]) -> __m512i {
    _mm512_set_epi64(e[7], e[6], e[5], e[4], e[3], e[2], e[1], e[0])
}

/// Fields 0–5 of eight records, transposed: `out[f]` lane `b` = record `b` field `f`.
#[inline]
#[target_feature(enable = "avx512f")]
fn transpose6(r: [__m512d; 8]) -> [__m512d; 6] {
    // stage 1: pairs of records, even and odd fields
    let t0 = _mm512_unpacklo_pd(r[0], r[1]);
    let t1 = _mm512_unpackhi_pd(r[0], r[1]);
    let t2 = _mm512_unpacklo_pd(r[2], r[3]);
    let t3 = _mm512_unpackhi_pd(r[2], r[3]);
    let t4 = _mm512_unpacklo_pd(r[4], r[5]);
    let t5 = _mm512_unpackhi_pd(r[4], r[5]);
    let t6 = _mm512_unpacklo_pd(r[6], r[7]);
    let t7 = _mm512_unpackhi_pd(r[6], r[7]);
    // stage 2: quads of records; s0 = [f0 of r0..r3 | f4 of r0..r3], s1 = [f2 | f6],
    // s2 = [f1 | f5], s3 = [f3 | f7]; s4..s7 the same for r4..r7
    let (plo, phi) = (
        idx([0, 1, 8, 9, 4, 5, 12, 13]),
        idx([2, 3, 10, 11, 6, 7, 14, 15]),
    );
    let s0 = _mm512_permutex2var_pd(t0, plo, t2);
    let s1 = _mm512_permutex2var_pd(t0, phi, t2);
    let s2 = _mm512_permutex2var_pd(t1, plo, t3);
    let s3 = _mm512_permutex2var_pd(t1, phi, t3);
    let s4 = _mm512_permutex2var_pd(t4, plo, t6);
    let s5 = _mm512_permutex2var_pd(t4, phi, t6);
    let s6 = _mm512_permutex2var_pd(t5, plo, t7);
    let s7 = _mm512_permutex2var_pd(t5, phi, t7);
    // stage 3: the low or high halves of a quad of r0..r3 and of r4..r7
    let (qlo, qhi) = (
        idx([0, 1, 2, 3, 8, 9, 10, 11]),
        idx([4, 5, 6, 7, 12, 13, 14, 15]),
    );
    [
        _mm512_permutex2var_pd(s0, qlo, s4),
        _mm512_permutex2var_pd(s2, qlo, s6),
        _mm512_permutex2var_pd(s1, qlo, s5),
        _mm512_permutex2var_pd(s3, qlo, s7),
        _mm512_permutex2var_pd(s0, qhi, s4),
        _mm512_permutex2var_pd(s2, qhi, s6),
    ]
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
) -> [f64; 3] {
    let ri = rec[i].0;
    let (bx0, bx1, bx2) = (
        _mm512_set1_pd(ri[0]),
        _mm512_set1_pd(ri[1]),
        _mm512_set1_pd(ri[2]),
    );
    let (bu0, bu1, bu2) = (
        _mm512_set1_pd(ri[3]),
        _mm512_set1_pd(ri[4]),
        _mm512_set1_pd(ri[5]),
    );
    let two = _mm512_set1_pd(2.0);
    let zero = _mm512_setzero_pd();
    let neg_zero = _mm512_set1_pd(-0.0);
    let crit = _mm512_set1_pd(critical);
    let len = nbr.len().min(inv_len.len()).min(coef.len());
    // lane l sums bonds l, l + 8, l + 16, … of the row ([`super::lane_tree`])
    let (mut ax, mut ay, mut az) = (zero, zero, zero);
    let mut start = 0;
    while start < len {
        let n = (len - start).min(8);
        let nb = &nbr[start..start + n];
        // lanes past the row's end load particle i itself (any valid record; not summed)
        let j = |b: usize| if b < n { nb[b] as usize } else { i };
        let r = [
            load_record(&rec[j(0)]),
            load_record(&rec[j(1)]),
            load_record(&rec[j(2)]),
            load_record(&rec[j(3)]),
            load_record(&rec[j(4)]),
            load_record(&rec[j(5)]),
            load_record(&rec[j(6)]),
            load_record(&rec[j(7)]),
        ];
        let [gx0, gx1, gx2, gu0, gu1, gu2] = transpose6(r);
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
        let lanes = ((1u32 << n) - 1) as u8;
        let qil = _mm512_mul_pd(q, il);
        let broken = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(_mm512_mul_pd(qil, il), crit) & lanes;
        let ly = _mm512_sqrt_pd(q);
        let t = _mm512_mul_pd(_mm512_mul_pd(num, il), il);
        let m = _mm512_div_pd(_mm512_mul_pd(cb, t), _mm512_add_pd(qil, ly));
        let live = _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(cb, zero) & !broken & lanes;
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
    [reduce(ax), reduce(ay), reduce(az)]
}

/// ((S₀ + S₄) + (S₂ + S₆)) + ((S₁ + S₅) + (S₃ + S₇)), the tree of [`super::lane_tree`].
#[inline]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
fn reduce(a: __m512d) -> f64 {
    // [S₀ + S₄, S₁ + S₅, S₂ + S₆, S₃ + S₇]
    let h = _mm256_add_pd(_mm512_castpd512_pd256(a), _mm512_extractf64x4_pd::<1>(a));
    // [(S₀ + S₄) + (S₂ + S₆), (S₁ + S₅) + (S₃ + S₇)]
    let g = _mm_add_pd(_mm256_castpd256_pd128(h), _mm256_extractf128_pd::<1>(h));
    _mm_cvtsd_f64(g) + _mm_cvtsd_f64(_mm_unpackhi_pd(g, g))
}

/// The force densities of the block of particles `lo..lo + f.len()`; `coef` holds those
/// rows' bonds. Call only on a CPU with AVX-512 F/DQ/VL.
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
) {
    let base = offsets[lo];
    for (k, fi) in f.iter_mut().enumerate() {
        let i = lo + k;
        let r = offsets[i]..offsets[i + 1];
        *fi = row_force(
            i,
            rec,
            &nbr[r.clone()],
            &inv_len[r.clone()],
            &mut coef[r.start - base..r.end - base],
            critical,
        );
    }
}
