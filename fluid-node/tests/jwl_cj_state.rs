//! JWL detonation products, TNT (the README's case sections): the Hugoniot from E0 meets the Rayleigh line
//! at the Chapman–Jouguet state V/V0 0.7317, p 21.0 GPa, D 6929 m/s — within 0.5 %. Also
//! checks the EOS's sound speed against a finite-difference isentrope derivative.

use fluid_node::eos::{Eos, Jwl};

#[test]
fn chapman_jouguet_state_of_tnt() {
    let j = Jwl::tnt();
    let (v, p, d) = j.cj_state();
    println!(
        "CJ: V/V0 {v:.5} (0.7317), p {:.4} GPa (21.0), D {d:.1} m/s (6929)",
        p / 1e9
    );
    assert!((v / 0.7317 - 1.0).abs() < 0.005, "V/V0 {v}");
    assert!((p / 21.0e9 - 1.0).abs() < 0.005, "p {p}");
    assert!((d / 6929.0 - 1.0).abs() < 0.005, "D {d}");
    // tangency: the Rayleigh line slope equals the Hugoniot slope at CJ
    let h = 1e-6;
    let slope_h = (j.hugoniot_pressure(v + h) - j.hugoniot_pressure(v - h)) / (2.0 * h);
    let slope_r = -p / (1.0 - v);
    assert!(
        (slope_h / slope_r - 1.0).abs() < 1e-4,
        "{slope_h} vs {slope_r}"
    );
}

#[test]
fn jwl_sound_speed_matches_isentrope() {
    let j = Jwl::tnt();
    for &(rho, p) in &[(2200.0, 2.1e10), (1630.0, 5.0e9), (100.0, 1.0e7)] {
        let e = j.internal_energy(rho, p);
        assert!((j.pressure(rho, e) / p - 1.0).abs() < 1e-12);
        // c² = (∂p/∂ρ)_s along de = p/ρ² dρ
        let h = 1e-6 * rho;
        let pp = j.pressure(rho + h, e + p / (rho * rho) * h);
        let pm = j.pressure(rho - h, e - p / (rho * rho) * h);
        let c2_fd = (pp - pm) / (2.0 * h);
        let c2 = j.rho_c2(rho, p) / rho;
        assert!(
            (c2_fd / c2 - 1.0).abs() < 1e-5,
            "rho {rho}: {c2_fd} vs {c2}"
        );
    }
}
