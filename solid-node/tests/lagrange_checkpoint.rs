//! Checkpoints of a lagrange coupling in process (seed 003 §4): the split bar as two
//! subdomains (average acceleration | central differences in 4 substeps, `gs4`) stopped after
//! some system steps, its sides' states (`LagrangeSide::save_state`) and the interface
//! problem's multipliers taken, then set up afresh, restored and run on: bit-identical to the
//! uninterrupted run. A state of another subdomain is refused. `tests/tests/restart.rs` does
//! the same through `cosim run` with a SIGKILL.

use mechanics::time::{CouplingMethod, Design, Gs4, InterfaceDof, Subdomain};
use protocol::scheme::lagrange::{InterfaceSolver, LagrangeSide, Method};
use solid_node::bar::chain_system;
use solid_node::fixtures::split_bar::{self, Ramp};
use solid_node::lagrange::SubdomainSide;

fn positions(from: f64, to: f64, elements: usize) -> Vec<f64> {
    let h = (to - from) / elements as f64;
    (0..=elements).map(|i| from + i as f64 * h).collect()
}

/// The left half (`elements` of them, fixed at x = 0) and the right half (loaded at its tip).
fn sides(left_elements: usize) -> (SubdomainSide, SubdomainSide) {
    let dt = split_bar::left_transit();
    let side = |x: Vec<f64>, fixed: &[usize], coef: Gs4, substeps, dof, sign, tip: bool| {
        let (sys, _) = chain_system(
            &x,
            split_bar::YOUNG,
            split_bar::DENSITY,
            split_bar::AREA,
            fixed,
        );
        let mut shape = vec![0.0; sys.len()];
        if tip {
            *shape.last_mut().expect("nodes") = 1.0;
        }
        let iface = InterfaceDof {
            dof,
            sign,
            lambda: 0,
        };
        let load = Box::new(|t: f64| split_bar::load(Ramp::Septic, t));
        match Subdomain::new(
            sys,
            coef,
            dt,
            substeps,
            CouplingMethod::Gs4,
            vec![iface],
            shape,
            load,
        ) {
            Ok(s) => SubdomainSide(s),
            Err(e) => panic!("subdomain: {e}"),
        }
    };
    let average = Gs4::u0(Design {
        rho1: 1.0,
        rho2: 1.0,
        rho_s: 0.0,
    });
    let left = side(
        positions(0.0, 0.5, left_elements),
        &[0],
        average,
        1,
        left_elements - 1,
        1.0,
        false,
    );
    let right = side(
        positions(0.5, 1.0, split_bar::RIGHT_ELEMENTS),
        &[],
        Gs4::central_difference(),
        4,
        0,
        -1.0,
        true,
    );
    (left, right)
}

fn scheme(l: &mut SubdomainSide, r: &mut SubdomainSide) -> InterfaceSolver {
    let mut s: [&mut dyn LagrangeSide; 2] = [l, r];
    match InterfaceSolver::new(Method::Gs4, 1, &mut s) {
        Ok(x) => x,
        Err(e) => panic!("scheme: {e}"),
    }
}

fn run(sc: &mut InterfaceSolver, l: &mut SubdomainSide, r: &mut SubdomainSide, steps: usize) {
    for _ in 0..steps {
        let mut s: [&mut dyn LagrangeSide; 2] = [&mut *l, &mut *r];
        if let Err(e) = sc.step(&mut s) {
            panic!("step: {e}");
        }
    }
}

/// Everything that must continue bit for bit: both states, clocks, audit sums and λ.
fn bits(sc: &InterfaceSolver, l: &SubdomainSide, r: &SubdomainSide) -> Vec<u64> {
    let mut v: Vec<u64> = sc.lambda().iter().map(|x| x.to_bits()).collect();
    for s in [&l.0, &r.0] {
        let st = s.save();
        for x in
            st.u.iter()
                .chain(&st.v)
                .chain(&st.a)
                .chain(&st.interface_impulse)
        {
            v.push(x.to_bits());
        }
        for x in [
            st.time,
            st.interface_work,
            st.external_work,
            st.load_integral,
        ] {
            v.push(x.to_bits());
        }
    }
    v
}

#[test]
fn a_restored_lagrange_coupling_continues_bit_identically() {
    let (total, at) = (600, 250);
    let (mut l, mut r) = sides(split_bar::LEFT_ELEMENTS);
    let mut sc = scheme(&mut l, &mut r);
    run(&mut sc, &mut l, &mut r, total);
    let uninterrupted = bits(&sc, &l, &r);

    let (mut l, mut r) = sides(split_bar::LEFT_ELEMENTS);
    let mut sc = scheme(&mut l, &mut r);
    run(&mut sc, &mut l, &mut r, at);
    let saved = (
        l.save_state().expect("left saves"),
        r.save_state().expect("right saves"),
        sc.lambda().to_vec(),
        vec![sc.side_lambda(0).to_vec(), sc.side_lambda(1).to_vec()],
    );
    // The load has moved the bar by then: the state restored is not the one at rest.
    assert!(l.0.state.u.iter().any(|&u| u != 0.0));

    let (mut l, mut r) = sides(split_bar::LEFT_ELEMENTS);
    let mut sc = scheme(&mut l, &mut r);
    l.load_state(&saved.0).expect("left loads");
    r.load_state(&saved.1).expect("right loads");
    sc.restore(&saved.2, &saved.3)
        .expect("the interface problem restores");
    run(&mut sc, &mut l, &mut r, total - at);
    let restored = bits(&sc, &l, &r);
    assert_eq!(uninterrupted.len(), restored.len());
    assert!(
        uninterrupted == restored,
        "{} of {} values differ",
        uninterrupted
            .iter()
            .zip(&restored)
            .filter(|(a, b)| a != b)
            .count(),
        uninterrupted.len()
    );
}

#[test]
fn a_state_of_another_subdomain_or_interface_is_refused() {
    let (l, _) = sides(split_bar::LEFT_ELEMENTS);
    let (mut other, mut r) = sides(split_bar::LEFT_ELEMENTS / 2);
    let e = other
        .load_state(&l.save_state().expect("saves"))
        .expect_err("a state of 101 nodes loaded into 51");
    assert!(e.contains("u has"), "{e}");
    assert!(other.load_state(b"junk").is_err());
    let mut sc = scheme(&mut other, &mut r);
    let e = sc
        .restore(&[1.0, 2.0], &[vec![1.0], vec![-1.0]])
        .expect_err("two multipliers for one");
    assert!(e.to_string().contains("2 multipliers"), "{e}");
    let e = sc
        .restore(&[f64::NAN], &[vec![1.0], vec![-1.0]])
        .expect_err("non-finite");
    assert!(e.to_string().contains("non-finite"), "{e}");
}
