//! Building blocks of the explicit AVX-512 bond kernels (`bond/avx512.rs`,
//! `correspondence/avx512.rs`): per-particle data packed in cache-line records, eight
//! neighbours' records transposed in registers (one load per record, two-source permutes),
//! and the tree that ends the eight-lane row sums ([`super::bond`]'s `lane_tree`). Data
//! movement only: the kernels' arithmetic is the scalar loops' own.

use std::arch::x86_64::*;

/// Eight doubles in one 64-byte cache line.
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(64))]
pub struct Record(pub [f64; 8]);

/// Two doubles, 16-byte aligned (the fields that do not fit a [`Record`]).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(16))]
pub struct Pair(pub [f64; 2]);

/// Fills `out` (resized to `n`) in parallel with `fill(i, &mut out[i])`.
pub fn pack<T: Default + Clone + Send>(
    n: usize,
    out: &mut Vec<T>,
    fill: impl Fn(usize, &mut T) + Sync,
) {
    use rayon::prelude::*;
    out.resize(n, T::default());
    out.par_iter_mut()
        .with_min_len(4096)
        .enumerate()
        .for_each(|(i, r)| fill(i, r));
}

/// Loads one record.
#[inline]
#[target_feature(enable = "avx512f")]
pub fn load_record(r: &Record) -> __m512d {
    // SAFETY: `r` is a reference to 8 initialised, 64-byte-aligned doubles.
    unsafe { _mm512_load_pd(r.0.as_ptr()) }
}

/// Three values, each broadcast to a vector.
#[inline]
#[target_feature(enable = "avx512f")]
pub fn splat3(a: f64, b: f64, c: f64) -> [__m512d; 3] {
    [_mm512_set1_pd(a), _mm512_set1_pd(b), _mm512_set1_pd(c)]
}

/// The first `n ≤ 8` values of `v` in a vector, zeros above.
#[inline]
#[target_feature(enable = "avx512f")]
pub fn load_lanes(v: &[f64], n: usize) -> __m512d {
    assert!(n <= 8 && v.len() >= n);
    if n == 8 {
        // SAFETY: `v` has at least 8 elements (asserted).
        unsafe { _mm512_loadu_pd(v.as_ptr()) }
    } else {
        // SAFETY: only the lanes set in the mask, the first n ≤ v.len() elements, are read;
        // masked-off lanes are neither read nor faulted on.
        unsafe { _mm512_maskz_loadu_pd(lane_mask(n), v.as_ptr()) }
    }
}

/// The mask of the first `n ≤ 8` lanes.
#[inline]
pub fn lane_mask(n: usize) -> u8 {
    ((1u32 << n.min(8)) - 1) as u8
}

/// Index vector of `_mm512_permutex2var_pd` (lane k takes element `e[k]`; 8–15 = 2nd source).
#[inline]
#[target_feature(enable = "avx512f")]
fn idx(e: [i64; 8]) -> __m512i {
    _mm512_set_epi64(e[7], e[6], e[5], e[4], e[3], e[2], e[1], e[0])
}

/// Eight records transposed: `out[f]` lane `b` = record `b` field `f` (24 permutes; a caller
/// that uses fewer fields lets the compiler drop the rest).
#[inline]
#[target_feature(enable = "avx512f")]
pub fn transpose8(r: [__m512d; 8]) -> [__m512d; 8] {
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
        _mm512_permutex2var_pd(s1, qhi, s5),
        _mm512_permutex2var_pd(s3, qhi, s7),
    ]
}

/// The records of particles `js`, transposed (see [`transpose8`]).
#[inline]
#[target_feature(enable = "avx512f")]
pub fn gather8(recs: &[Record], js: &[usize; 8]) -> [__m512d; 8] {
    transpose8([
        load_record(&recs[js[0]]),
        load_record(&recs[js[1]]),
        load_record(&recs[js[2]]),
        load_record(&recs[js[3]]),
        load_record(&recs[js[4]]),
        load_record(&recs[js[5]]),
        load_record(&recs[js[6]]),
        load_record(&recs[js[7]]),
    ])
}

/// The pairs of particles `js`, transposed (see [`transpose_pairs`]).
#[inline]
#[target_feature(enable = "avx512f,avx512dq")]
pub fn gather_pairs(pairs: &[Pair], js: &[usize; 8]) -> (__m512d, __m512d) {
    transpose_pairs(js.map(|j| &pairs[j]))
}

/// Eight pairs transposed: (lane b = pair b's first value, lane b = its second).
#[inline]
#[target_feature(enable = "avx512f,avx512dq")]
pub fn transpose_pairs(p: [&Pair; 8]) -> (__m512d, __m512d) {
    // SAFETY: each reference is to 2 initialised, 16-byte-aligned doubles.
    let l = |k: usize| unsafe { _mm_load_pd(p[k].0.as_ptr()) };
    // even pairs in one vector, odd pairs in the other: [p0 p2 p4 p6], [p1 p3 p5 p7]
    let even = _mm512_insertf64x2::<3>(
        _mm512_insertf64x2::<2>(
            _mm512_insertf64x2::<1>(_mm512_castpd128_pd512(l(0)), l(2)),
            l(4),
        ),
        l(6),
    );
    let odd = _mm512_insertf64x2::<3>(
        _mm512_insertf64x2::<2>(
            _mm512_insertf64x2::<1>(_mm512_castpd128_pd512(l(1)), l(3)),
            l(5),
        ),
        l(7),
    );
    (_mm512_unpacklo_pd(even, odd), _mm512_unpackhi_pd(even, odd))
}

/// ((S₀ + S₄) + (S₂ + S₆)) + ((S₁ + S₅) + (S₃ + S₇)): the lane tree of the row sums.
#[inline]
#[target_feature(enable = "avx512f,avx")]
pub fn reduce(a: __m512d) -> f64 {
    // [S₀ + S₄, S₁ + S₅, S₂ + S₆, S₃ + S₇]
    let h = _mm256_add_pd(_mm512_castpd512_pd256(a), _mm512_extractf64x4_pd::<1>(a));
    // [(S₀ + S₄) + (S₂ + S₆), (S₁ + S₅) + (S₃ + S₇)]
    let g = _mm_add_pd(_mm256_castpd256_pd128(h), _mm256_extractf128_pd::<1>(h));
    _mm_cvtsd_f64(g) + _mm_cvtsd_f64(_mm_unpackhi_pd(g, g))
}
