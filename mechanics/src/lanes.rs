//! Several doubles computed side by side: the value type of kernels that run `W` elements (or
//! particles) at once, one per lane. A kernel written over a [`Lane`] type reads as the
//! scalar formula and is compiled once per lane type: `f64` (one element alone), the
//! portable [`Lanes<W>`] (plain loops the compiler may vectorise) and, on x86-64, `Avx4`
//! (four doubles in one AVX register, for functions compiled with AVX2). Only correctly
//! rounded IEEE-754 operations are used (add, sub, mul, div, sqrt, compare, select), so lane
//! `k` of a kernel run side by side is bit for bit the kernel run on that lane alone, with
//! any lane type.
//!
//! The portable type's operations are plain loops, not `std::array::from_fn` or `map`:
//! those are separate functions the compiler may leave out of line, and a function left out
//! of line is compiled without the caller's instruction set (measured: half of a kernel's
//! instructions went to such calls). Even so the compiler vectorised a kernel over
//! `Lanes<4>` mostly two wide (measured on the hexahedron kernel, AVX2); `Avx4` uses the
//! four-wide instructions by name.

// The operators are written once for every operator by a macro (`a = a op b`), and lane
// loops index several arrays at once.
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// A value of `W` lanes with the arithmetic of `f64` lane by lane. Constants go on the right
/// (`x * 2.0`, not `2.0 * x`) so that kernels stay generic.
pub trait Lane:
    Copy
    + Add<Output = Self>
    + Add<f64, Output = Self>
    + Sub<Output = Self>
    + Sub<f64, Output = Self>
    + Mul<Output = Self>
    + Mul<f64, Output = Self>
    + Div<Output = Self>
    + Div<f64, Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign<f64>
    + DivAssign<f64>
{
    /// Lanes in one value.
    const W: usize;
    /// Every lane `x`.
    fn splat(x: f64) -> Self;
    /// Every lane 0.
    #[inline(always)]
    fn zero() -> Self {
        Self::splat(0.0)
    }
    /// Lane `k` is `f(k)`.
    fn from_lanes(f: impl Fn(usize) -> f64) -> Self;
    /// Lane `k`.
    fn lane(self, k: usize) -> f64;
    /// The lanes into `out[..W]`.
    fn store(self, out: &mut [f64]);
    /// Lane `k` from `a[k]`, for `k < W`.
    fn load(a: &[f64]) -> Self;
    fn sqrt(self) -> Self;
    /// `1 / x` lane by lane.
    fn recip(self) -> Self;
    /// `a` in the lanes where `self > 0`, else `b` (NaN is not above 0).
    fn where_positive(self, a: Self, b: Self) -> Self;
}

impl Lane for f64 {
    const W: usize = 1;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn from_lanes(f: impl Fn(usize) -> f64) -> Self {
        f(0)
    }
    #[inline(always)]
    fn lane(self, _: usize) -> f64 {
        self
    }
    #[inline(always)]
    fn store(self, out: &mut [f64]) {
        out[0] = self;
    }
    #[inline(always)]
    fn load(a: &[f64]) -> Self {
        a[0]
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn recip(self) -> Self {
        1.0 / self
    }
    #[inline(always)]
    fn where_positive(self, a: Self, b: Self) -> Self {
        if self > 0.0 { a } else { b }
    }
}

impl<const W: usize> Lane for Lanes<W> {
    const W: usize = W;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Lanes([x; W])
    }
    #[inline(always)]
    fn from_lanes(f: impl Fn(usize) -> f64) -> Self {
        let mut r = [0.0; W];
        for (k, r) in r.iter_mut().enumerate() {
            *r = f(k);
        }
        Lanes(r)
    }
    #[inline(always)]
    fn lane(self, k: usize) -> f64 {
        self.0[k]
    }
    #[inline(always)]
    fn store(self, out: &mut [f64]) {
        out[..W].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn load(a: &[f64]) -> Self {
        let mut r = [0.0; W];
        r.copy_from_slice(&a[..W]);
        Lanes(r)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = x.sqrt();
        }
        Lanes(r)
    }
    #[inline(always)]
    fn recip(self) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = 1.0 / *x;
        }
        Lanes(r)
    }
    #[inline(always)]
    fn where_positive(self, a: Self, b: Self) -> Self {
        let mut r = b.0;
        for k in 0..W {
            if self.0[k] > 0.0 {
                r[k] = a.0[k];
            }
        }
        Lanes(r)
    }
}

/// `[e(0), e(1), …]` written out, with `$i` a constant in each entry:
/// `unrolled!(i in [0, 1, 2] => f(i))`. An array built so stays in registers where a zeroed
/// array overwritten in a loop is cleared in memory first (measured: a fifth of a kernel's
/// instructions went to such clearing).
#[macro_export]
macro_rules! unrolled {
    ($i:ident in [$($n:literal),* $(,)?] => $e:expr) => {
        [$({
            let $i: usize = $n;
            $e
        }),*]
    };
}
pub use crate::unrolled;

/// `W` doubles, one per lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lanes<const W: usize>(pub [f64; W]);

macro_rules! lane_op {
    ($tr:ident, $f:ident, $atr:ident, $af:ident, $op:tt) => {
        impl<const W: usize> $tr for Lanes<W> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                let mut r = self.0;
                for k in 0..W {
                    r[k] = r[k] $op o.0[k];
                }
                Lanes(r)
            }
        }
        impl<const W: usize> $tr<f64> for Lanes<W> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: f64) -> Self {
                let mut r = self.0;
                for x in &mut r {
                    *x = *x $op o;
                }
                Lanes(r)
            }
        }
        impl<const W: usize> $tr<Lanes<W>> for f64 {
            type Output = Lanes<W>;
            #[inline(always)]
            fn $f(self, o: Lanes<W>) -> Lanes<W> {
                let mut r = o.0;
                for x in &mut r {
                    *x = self $op *x;
                }
                Lanes(r)
            }
        }
        impl<const W: usize> $atr for Lanes<W> {
            #[inline(always)]
            fn $af(&mut self, o: Self) {
                for k in 0..W {
                    self.0[k] = self.0[k] $op o.0[k];
                }
            }
        }
        impl<const W: usize> $atr<f64> for Lanes<W> {
            #[inline(always)]
            fn $af(&mut self, o: f64) {
                for x in &mut self.0 {
                    *x = *x $op o;
                }
            }
        }
    };
}
lane_op!(Add, add, AddAssign, add_assign, +);
lane_op!(Sub, sub, SubAssign, sub_assign, -);
lane_op!(Mul, mul, MulAssign, mul_assign, *);
lane_op!(Div, div, DivAssign, div_assign, /);

impl<const W: usize> Neg for Lanes<W> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = -*x;
        }
        Lanes(r)
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::{Avx4, Avx8};

#[cfg(target_arch = "x86_64")]
mod avx {
    //! Four doubles in one AVX register. Every operation is an AVX instruction, so a value
    //! of this type may only be made and used inside a function compiled with AVX enabled
    //! (`#[target_feature(enable = "avx2,avx")]`), called after checking the CPU has it: the
    //! crate's SIMD dispatch does. It is not exported for that reason. `Avx8` is the same
    //! for eight doubles in one AVX-512 register (AVX-512 F and DQ).
    use super::Lane;
    use std::arch::x86_64::*;
    use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

    #[derive(Clone, Copy, Debug)]
    pub struct Avx4(__m256d);

    // SAFETY (every `unsafe` block below): AVX instructions on registers, no memory access
    // but through references to local arrays of 4 doubles; the caller runs with AVX (the
    // type's contract above).
    macro_rules! avx_op {
        ($tr:ident, $f:ident, $atr:ident, $af:ident, $intr:ident) => {
            impl $tr for Avx4 {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: Self) -> Self {
                    Avx4(unsafe { $intr(self.0, o.0) })
                }
            }
            impl $tr<f64> for Avx4 {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: f64) -> Self {
                    Avx4(unsafe { $intr(self.0, _mm256_set1_pd(o)) })
                }
            }
            impl $atr for Avx4 {
                #[inline(always)]
                fn $af(&mut self, o: Self) {
                    self.0 = unsafe { $intr(self.0, o.0) };
                }
            }
            impl $atr<f64> for Avx4 {
                #[inline(always)]
                fn $af(&mut self, o: f64) {
                    self.0 = unsafe { $intr(self.0, _mm256_set1_pd(o)) };
                }
            }
        };
    }
    avx_op!(Add, add, AddAssign, add_assign, _mm256_add_pd);
    avx_op!(Sub, sub, SubAssign, sub_assign, _mm256_sub_pd);
    avx_op!(Mul, mul, MulAssign, mul_assign, _mm256_mul_pd);
    avx_op!(Div, div, DivAssign, div_assign, _mm256_div_pd);

    impl Neg for Avx4 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            // flips the sign bit, as scalar negation does
            Avx4(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    impl Lane for Avx4 {
        const W: usize = 4;
        #[inline(always)]
        fn splat(x: f64) -> Self {
            Avx4(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        fn from_lanes(f: impl Fn(usize) -> f64) -> Self {
            // in registers (a store of four and a load of the vector would stall)
            Avx4(unsafe { _mm256_set_pd(f(3), f(2), f(1), f(0)) })
        }
        #[inline(always)]
        fn lane(self, k: usize) -> f64 {
            let mut a = [0.0; 4];
            unsafe { _mm256_storeu_pd(a.as_mut_ptr(), self.0) };
            a[k]
        }
        #[inline(always)]
        fn store(self, out: &mut [f64]) {
            let out = &mut out[..4];
            // SAFETY: `out` holds four doubles (checked by the slice above).
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) };
        }
        #[inline(always)]
        fn load(a: &[f64]) -> Self {
            let a = &a[..4];
            // SAFETY: `a` holds four doubles (checked by the slice above).
            Avx4(unsafe { _mm256_loadu_pd(a.as_ptr()) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Avx4(unsafe { _mm256_sqrt_pd(self.0) })
        }
        #[inline(always)]
        fn recip(self) -> Self {
            Avx4(unsafe { _mm256_div_pd(_mm256_set1_pd(1.0), self.0) })
        }
        #[inline(always)]
        fn where_positive(self, a: Self, b: Self) -> Self {
            unsafe {
                // ordered, quiet: false where self is NaN
                let m = _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, _mm256_setzero_pd());
                Avx4(_mm256_blendv_pd(b.0, a.0, m))
            }
        }
    }

    #[derive(Clone, Copy, Debug)]
    pub struct Avx8(__m512d);

    macro_rules! avx512_op {
        ($tr:ident, $f:ident, $atr:ident, $af:ident, $intr:ident) => {
            impl $tr for Avx8 {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: Self) -> Self {
                    Avx8(unsafe { $intr(self.0, o.0) })
                }
            }
            impl $tr<f64> for Avx8 {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: f64) -> Self {
                    Avx8(unsafe { $intr(self.0, _mm512_set1_pd(o)) })
                }
            }
            impl $atr for Avx8 {
                #[inline(always)]
                fn $af(&mut self, o: Self) {
                    self.0 = unsafe { $intr(self.0, o.0) };
                }
            }
            impl $atr<f64> for Avx8 {
                #[inline(always)]
                fn $af(&mut self, o: f64) {
                    self.0 = unsafe { $intr(self.0, _mm512_set1_pd(o)) };
                }
            }
        };
    }
    avx512_op!(Add, add, AddAssign, add_assign, _mm512_add_pd);
    avx512_op!(Sub, sub, SubAssign, sub_assign, _mm512_sub_pd);
    avx512_op!(Mul, mul, MulAssign, mul_assign, _mm512_mul_pd);
    avx512_op!(Div, div, DivAssign, div_assign, _mm512_div_pd);

    impl Neg for Avx8 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            Avx8(unsafe { _mm512_xor_pd(self.0, _mm512_set1_pd(-0.0)) })
        }
    }

    impl Lane for Avx8 {
        const W: usize = 8;
        #[inline(always)]
        fn splat(x: f64) -> Self {
            Avx8(unsafe { _mm512_set1_pd(x) })
        }
        #[inline(always)]
        fn from_lanes(f: impl Fn(usize) -> f64) -> Self {
            Avx8(unsafe { _mm512_set_pd(f(7), f(6), f(5), f(4), f(3), f(2), f(1), f(0)) })
        }
        #[inline(always)]
        fn lane(self, k: usize) -> f64 {
            let mut a = [0.0; 8];
            self.store(&mut a);
            a[k]
        }
        #[inline(always)]
        fn store(self, out: &mut [f64]) {
            let out = &mut out[..8];
            // SAFETY: `out` holds eight doubles (checked by the slice above).
            unsafe { _mm512_storeu_pd(out.as_mut_ptr(), self.0) };
        }
        #[inline(always)]
        fn load(a: &[f64]) -> Self {
            let a = &a[..8];
            // SAFETY: `a` holds eight doubles (checked by the slice above).
            Avx8(unsafe { _mm512_loadu_pd(a.as_ptr()) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Avx8(unsafe { _mm512_sqrt_pd(self.0) })
        }
        #[inline(always)]
        fn recip(self) -> Self {
            Avx8(unsafe { _mm512_div_pd(_mm512_set1_pd(1.0), self.0) })
        }
        #[inline(always)]
        fn where_positive(self, a: Self, b: Self) -> Self {
            unsafe {
                let m = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(self.0, _mm512_setzero_pd());
                Avx8(_mm512_mask_blend_pd(m, b.0, a.0))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check<L: Lane>(a: [f64; 8], b: [f64; 8]) {
        let n = L::W;
        let al = L::from_lanes(|k| a[k]);
        let bl = L::from_lanes(|k| b[k]);
        type Scalar = fn(f64, f64) -> f64;
        let cases: [(L, Scalar); 8] = [
            (al + bl, |x, y| x + y),
            (al - bl, |x, y| x - y),
            (al * bl, |x, y| x * y),
            (al / bl, |x, y| x / y),
            (al * 2.0 - 1.0, |x, _| x * 2.0 - 1.0),
            (bl.recip(), |_, y| 1.0 / y),
            ((-bl).sqrt(), |_, y| (-y).sqrt()),
            (
                al.where_positive(al, bl),
                |x, y| if x > 0.0 { x } else { y },
            ),
        ];
        let mut out = [0.0; 8];
        al.store(&mut out);
        for k in 0..n {
            assert_eq!(out[k].to_bits(), a[k].to_bits());
            assert_eq!(L::load(&b).lane(k).to_bits(), b[k].to_bits());
        }
        for (i, (got, want)) in cases.iter().enumerate() {
            for k in 0..n {
                assert_eq!(
                    got.lane(k).to_bits(),
                    want(a[k], b[k]).to_bits(),
                    "case {i}, lane {k}"
                );
            }
        }
    }

    #[test]
    fn each_lane_is_the_scalar_operation() {
        let a = [1.5, -2.0, f64::NAN, 9.0, 0.0, -0.0, 1e-300, -7.25];
        let b = [0.5, 4.0, -3.0, -0.0, 2.0, -1.0, 1e300, f64::INFINITY];
        check::<f64>(a, b);
        check::<Lanes<4>>(a, b);
        check::<Lanes<3>>(a, b);
        check::<Lanes<8>>(a, b);
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx2,avx")]
            fn with_avx(a: [f64; 8], b: [f64; 8]) {
                check::<Avx4>(a, b);
            }
            #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
            fn with_avx512(a: [f64; 8], b: [f64; 8]) {
                check::<Avx8>(a, b);
            }
            if crate::simd::has_avx2() {
                // SAFETY: the CPU has AVX2 (checked just above).
                unsafe { with_avx(a, b) };
            }
            if crate::simd::has_avx512() {
                // SAFETY: the CPU has AVX-512 F, DQ and VL (checked just above).
                unsafe { with_avx512(a, b) };
            }
        }
    }
}
