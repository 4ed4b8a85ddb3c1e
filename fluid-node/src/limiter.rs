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
