//! The HLLC flux and the slope limiters on their own: the flux is consistent with the physical
//! flux, resolves a stationary contact exactly and is mirror-symmetric; every limiter is TVD,
//! symmetric in its arguments and second order on equal differences.

use fluid_node::limiter::Limiter;
use fluid_node::riemann::FaceState;
use fluid_node::riemann::hllc::flux;

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

fn st(rho: f64, u: f64, p: f64) -> FaceState<1> {
    let g = 1.4;
    FaceState {
        ar: [rho],
        al: [1.0],
        vel: [u, 0.0, 0.0],
        p,
        rho,
        e: p / (g - 1.0) + 0.5 * rho * u * u,
        c: (g * p / rho).sqrt(),
    }
}

#[test]
fn consistent_with_physical_flux() {
    let s = st(1.3, 0.4, 2.0);
    let f = flux(&s, &s, 0);
    assert!((f[0] - 1.3 * 0.4).abs() < 1e-14);
    assert!((f[1] - (1.3 * 0.16 + 2.0)).abs() < 1e-14);
    assert!((f[4] - (s.e + 2.0) * 0.4).abs() < 1e-14);
}

#[test]
fn resolves_stationary_contact_exactly() {
    let f = flux(&st(1.0, 0.0, 1.0), &st(0.1, 0.0, 1.0), 0);
    assert_eq!(f[0], 0.0);
    assert!((f[1] - 1.0).abs() < 1e-15);
    assert_eq!(f[4], 0.0);
}

#[test]
fn mirror_symmetric() {
    let l = st(1.0, 0.3, 1.0);
    let r = st(0.2, -0.7, 0.4);
    let f = flux(&l, &r, 0);
    let ml = st(0.2, 0.7, 0.4);
    let mr = st(1.0, -0.3, 1.0);
    let g = flux(&ml, &mr, 0);
    assert_eq!(f[0], -g[0]);
    assert_eq!(f[1], g[1]);
    assert_eq!(f[4], -g[4]);
}
