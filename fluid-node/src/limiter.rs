//! TVD slope limiters for the MUSCL reconstruction (seed 002 §2.3). Each is symmetric in its
//! arguments, so a mirrored flow gives a mirrored reconstruction.

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limiter {
    Minmod,
    VanLeer,
    /// Monotonised central (van Leer 1977).
    Mc,
}

impl Limiter {
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "minmod" => Some(Limiter::Minmod),
            "van_leer" | "vanleer" => Some(Limiter::VanLeer),
            "mc" => Some(Limiter::Mc),
            _ => None,
        }
    }

    /// Limited slope from the backward and forward differences `a`, `b`.
    #[inline(always)]
    pub fn slope(self, a: f64, b: f64) -> f64 {
        match self {
            Limiter::Minmod => minmod(a, b),
            Limiter::VanLeer => van_leer(a, b),
            Limiter::Mc => mc(a, b),
        }
    }
}

#[inline(always)]
pub fn minmod(a: f64, b: f64) -> f64 {
    if a * b <= 0.0 {
        0.0
    } else if a.abs() < b.abs() {
        a
    } else {
        b
    }
}

#[inline(always)]
pub fn van_leer(a: f64, b: f64) -> f64 {
    let ab = a * b;
    if ab <= 0.0 { 0.0 } else { 2.0 * ab / (a + b) }
}

#[inline(always)]
pub fn mc(a: f64, b: f64) -> f64 {
    if a * b <= 0.0 {
        return 0.0;
    }
    let c = 0.5 * (a + b);
    let m = (2.0 * a.abs()).min(2.0 * b.abs()).min(c.abs());
    m.copysign(a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limiters_are_tvd_and_symmetric() {
        for l in [Limiter::Minmod, Limiter::VanLeer, Limiter::Mc] {
            assert_eq!(l.slope(1.0, -1.0), 0.0);
            assert_eq!(l.slope(0.3, 0.7), l.slope(0.7, 0.3));
            // second-order: equal differences give that difference
            assert!((l.slope(0.5, 0.5) - 0.5).abs() < 1e-15);
            // TVD region: slope between 0 and 2·min
            let s = l.slope(0.1, 1.0);
            assert!(s > 0.0 && s <= 0.2 + 1e-15);
        }
    }
}
