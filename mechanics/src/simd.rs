//! Run-time choice of the instruction set for hot row kernels, shared by the solver nodes
//! (first written in fluid-node for throughput; moved here so
//! solid-node and fluid-node use one copy). Each kernel is written once as an `#[inline(always)]` body over
//! slices and compiled three times: baseline x86-64 (SSE2), AVX2 and AVX-512, so its loops
//! vectorise 2, 4 or 8 doubles wide; [`multiversion!`] generates the dispatching wrapper.
//!
//! Results are bit-identical on every path: only IEEE-754 operations that are correctly
//! rounded at any vector width are used (add, sub, mul, div, sqrt, compare, select), and FMA
//! is deliberately not enabled (Rust never contracts a·b + c by itself, but leaving the
//! feature out makes that certain). The GPU shaders therefore still match the CPU.

/// Widest instruction set the row kernels may use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Simd {
    /// Baseline x86-64 (or any other architecture).
    Base,
    /// AVX2 (4 doubles per vector).
    Avx2,
    /// AVX-512 F/DQ/VL (8 doubles per vector).
    Avx512,
}

impl Simd {
    /// The widest instruction set this CPU supports.
    pub fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if has_avx512() {
                return Simd::Avx512;
            }
            if has_avx2() {
                return Simd::Avx2;
            }
        }
        Simd::Base
    }

    /// Every instruction set this CPU supports, narrowest first (for tests that compare
    /// the paths bit for bit).
    pub fn available() -> Vec<Self> {
        let mut v = vec![Simd::Base];
        #[cfg(target_arch = "x86_64")]
        {
            if has_avx2() {
                v.push(Simd::Avx2);
            }
            if has_avx512() {
                v.push(Simd::Avx512);
            }
        }
        v
    }
}

/// True when the CPU runs the AVX-512 kernels (cached by the standard library).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub fn has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("avx512vl")
        && has_avx2()
}

/// True when the CPU runs the AVX2 kernels (cached by the standard library).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub fn has_avx2() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// `multiversion! { fn name<const N: usize>(a: A, ...) -> R = body; }` defines
/// `name::<N>(simd: Simd, a, ...)`, which runs `body::<N>(a, ...)` compiled for the widest
/// instruction set allowed by `simd` that the CPU has (checked again on every call, so a
/// `Simd` value the CPU lacks falls back safely). `body` must be `#[inline(always)]`.
/// A kernel generic over one type (e.g. a damage law) takes it first:
/// `fn name<D: Trait, const N: usize>(...) = body;`, and `fn name<>(...)` has no parameters.
/// Exported at the crate root; other crates write `use mechanics::simd::multiversion;`
/// (the generated code names `$crate::simd::Simd`, so the caller needs no other import).
///
/// ```
/// use mechanics::simd::{multiversion, Simd};
///
/// #[inline(always)]
/// fn scale_body<const K: usize>(x: &mut [f64]) {
///     for v in x.iter_mut() {
///         *v = (*v * K as f64).sqrt();
///     }
/// }
/// multiversion! {
///     fn scale<const K: usize>(x: &mut [f64]) = scale_body;
/// }
/// let mut x = vec![2.0; 9];
/// scale::<2>(Simd::detect(), &mut x);
/// assert!(x.iter().all(|v| *v == 2.0));
/// ```
#[macro_export]
macro_rules! multiversion {
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident<$(const $cp:ident: $ct:ty),*>($($arg:ident: $ty:ty),* $(,)?)
            $(-> $ret:ty)? = $body:ident;
    ) => {
        $(#[$meta])*
        #[inline]
        $vis fn $name<$(const $cp: $ct),*>(simd: $crate::simd::Simd, $($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
                fn avx512<$(const $cp: $ct),*>($($arg: $ty),*) $(-> $ret)? {
                    $body::<$($cp),*>($($arg),*)
                }
                #[target_feature(enable = "avx2,avx")]
                fn avx2<$(const $cp: $ct),*>($($arg: $ty),*) $(-> $ret)? {
                    $body::<$($cp),*>($($arg),*)
                }
                match simd {
                    $crate::simd::Simd::Avx512 if $crate::simd::has_avx512() => {
                        // SAFETY: the CPU has every feature `avx512` enables (checked just
                        // above), the only requirement of calling a target-feature function.
                        return unsafe { avx512::<$($cp),*>($($arg),*) };
                    }
                    $crate::simd::Simd::Avx512 | $crate::simd::Simd::Avx2
                        if $crate::simd::has_avx2() =>
                    {
                        // SAFETY: as above, for AVX2.
                        return unsafe { avx2::<$($cp),*>($($arg),*) };
                    }
                    _ => {}
                }
            }
            let _ = simd;
            $body::<$($cp),*>($($arg),*)
        }
    };
    // The same with one type parameter before the const ones (a kernel generic over, e.g.,
    // a damage law): `fn name<D: Trait, const N: usize>(...) = body;`.
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident<$tp:ident: $tb:path $(, const $cp:ident: $ct:ty)*>($($arg:ident: $ty:ty),* $(,)?)
            $(-> $ret:ty)? = $body:ident;
    ) => {
        $(#[$meta])*
        #[inline]
        $vis fn $name<$tp: $tb $(, const $cp: $ct)*>(simd: $crate::simd::Simd, $($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,avx")]
                fn avx512<$tp: $tb $(, const $cp: $ct)*>($($arg: $ty),*) $(-> $ret)? {
                    $body::<$tp $(, $cp)*>($($arg),*)
                }
                #[target_feature(enable = "avx2,avx")]
                fn avx2<$tp: $tb $(, const $cp: $ct)*>($($arg: $ty),*) $(-> $ret)? {
                    $body::<$tp $(, $cp)*>($($arg),*)
                }
                match simd {
                    $crate::simd::Simd::Avx512 if $crate::simd::has_avx512() => {
                        // SAFETY: the CPU has every feature `avx512` enables (checked just
                        // above), the only requirement of calling a target-feature function.
                        return unsafe { avx512::<$tp $(, $cp)*>($($arg),*) };
                    }
                    $crate::simd::Simd::Avx512 | $crate::simd::Simd::Avx2
                        if $crate::simd::has_avx2() =>
                    {
                        // SAFETY: as above, for AVX2.
                        return unsafe { avx2::<$tp $(, $cp)*>($($arg),*) };
                    }
                    _ => {}
                }
            }
            let _ = simd;
            $body::<$tp $(, $cp)*>($($arg),*)
        }
    };
}
pub use crate::multiversion;

#[cfg(test)]
mod tests {
    use super::Simd;

    /// A bond-stretch-like chain (sub, mul, add, sqrt, div) that vectorises.
    #[inline(always)]
    fn chain_body<const K: usize>(a: &[f64], b: &[f64], out: &mut [f64]) {
        let n = a.len().min(b.len()).min(out.len());
        let (a, b, out) = (&a[..n], &b[..n], &mut out[..n]);
        for i in 0..n {
            let mut x = a[i];
            for _ in 0..K {
                let y = (x * x + b[i]).sqrt();
                x = (y - x) / (y + b[i] + 1.0);
            }
            out[i] = x;
        }
    }

    multiversion! {
        fn chain<const K: usize>(a: &[f64], b: &[f64], out: &mut [f64]) = chain_body;
    }

    /// A law the kernel is generic over (as the PD force kernels are over damage laws).
    trait Law {
        fn apply(&self, x: f64) -> f64;
    }
    struct Damped(f64);
    impl Law for Damped {
        #[inline]
        fn apply(&self, x: f64) -> f64 {
            (x * self.0).min(1.0) / (x.abs() + 1.0).sqrt()
        }
    }

    #[inline(always)]
    fn law_body<L: Law, const K: usize>(law: &L, a: &[f64], out: &mut [f64]) {
        for (o, &x) in out.iter_mut().zip(a) {
            let mut y = x;
            for _ in 0..K {
                y = law.apply(y) - x;
            }
            *o = y;
        }
    }

    multiversion! {
        fn law_kernel<L: Law, const K: usize>(law: &L, a: &[f64], out: &mut [f64]) = law_body;
    }

    #[test]
    fn the_type_generic_form_is_bit_identical_too() {
        let a: Vec<f64> = (0..517).map(|i| (i as f64 * 0.37).sin() * 3.0).collect();
        let mut reference = vec![0.0; a.len()];
        law_body::<Damped, 4>(&Damped(0.7), &a, &mut reference);
        for simd in Simd::available() {
            let mut out = vec![0.0; a.len()];
            law_kernel::<Damped, 4>(simd, &Damped(0.7), &a, &mut out);
            assert!(
                out.iter()
                    .zip(&reference)
                    .all(|(x, r)| x.to_bits() == r.to_bits()),
                "{simd:?}"
            );
        }
    }

    #[test]
    fn every_instruction_set_is_bit_identical() {
        let n = 1037;
        let a: Vec<f64> = (0..n)
            .map(|i| ((i * 7919) % 1000) as f64 * 1.37e-3 - 0.6)
            .collect();
        let b: Vec<f64> = (0..n)
            .map(|i| ((i * 104_729) % 997) as f64 * 2.1e-3 + 0.1)
            .collect();
        let mut reference = vec![0.0; n];
        chain_body::<3>(&a, &b, &mut reference);
        let avail = Simd::available();
        assert_eq!(avail[0], Simd::Base);
        assert!(avail.contains(&Simd::detect()));
        for simd in avail {
            let mut out = vec![0.0; n];
            chain::<3>(simd, &a, &b, &mut out);
            for (i, (x, r)) in out.iter().zip(&reference).enumerate() {
                assert_eq!(
                    x.to_bits(),
                    r.to_bits(),
                    "{simd:?} differs at {i}: {x} vs {r}"
                );
            }
        }
    }
}
