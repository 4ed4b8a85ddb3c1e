//! Deterministic results for any thread count: a 2-D two-material
//! shock run gives bit-identical states on 1 and 2 rayon threads; every instruction set the
//! row kernels can be compiled for (`fluid_node::simd`) gives bit-identical states too.

use crate::common;
use common::solver;

fn run(threads: usize) -> Vec<f64> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| {
        let mut s = solver(
            r#"
            [grid]
            cells = [40, 30, 1]
            lower = [0.0, 0.0, 0.0]
            upper = [1.0, 0.75, 1.0]
            [materials.air]
            eos = "ideal"
            gamma = 1.4
            [materials.helium]
            eos = "ideal"
            gamma = 1.67
            [[regions]]
            shape = "all"
            material = "air"
            density = 1.0
            pressure = 1.0
            [[regions]]
            shape = "sphere"
            center = [0.5, 0.3, 0.0]
            radius = 0.2
            material = "helium"
            density = 0.138
            pressure = 1.0
            [[regions]]
            shape = "half_space"
            point = [0.8, 0.0, 0.0]
            normal = [1.0, 0.0, 0.0]
            material = "air"
            density = 1.3764
            pressure = 1.5698
            velocity = [-0.394, 0.0, 0.0]
            [boundaries]
            y_lower = "wall"
            y_upper = "wall"
        "#,
        );
        s.advance_to(0.3).expect("run");
        s.fluid.cons.clone()
    })
}

#[test]
fn bit_identical_on_one_and_two_threads() {
    let a = run(1);
    let b = run(2);
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
}

/// The `Solver::stable_dt` query (which must not touch the model, so it recomputes the
/// primitives into scratch) returns exactly the step the time loop takes next, for one and
/// two materials.
#[test]
fn stable_dt_query_matches_the_step() {
    use protocol::Solver;
    for two in [false, true] {
        let mut s = solver(&format!(
            r#"
            [grid]
            cells = [30, 20, 1]
            lower = [0.0, 0.0, 0.0]
            upper = [1.0, 0.75, 1.0]
            [materials.air]
            eos = "ideal"
            gamma = 1.4
            {}
            [[regions]]
            shape = "all"
            material = "air"
            density = 1.0
            pressure = 1.0
            velocity = [0.3, 0.1, 0.0]
            [[regions]]
            shape = "sphere"
            center = [0.5, 0.4, 0.0]
            radius = 0.2
            material = "{}"
            density = 0.3
            pressure = 4.0
        "#,
            if two {
                "[materials.helium]\n eos = \"ideal\"\n gamma = 1.67"
            } else {
                ""
            },
            if two { "helium" } else { "air" }
        ));
        assert_eq!(s.fluid.nmat(), if two { 2 } else { 1 });
        for _ in 0..5 {
            let q = s.stable_dt();
            let mut copy = s.fluid.clone();
            let dt = fluid_node::step::stable_dt(&mut copy).expect("dt");
            assert_eq!(q, dt, "query vs step (two materials: {two})");
            let taken = fluid_node::step::step(&mut s.fluid, f64::INFINITY).expect("step");
            assert_eq!(taken, dt);
        }
    }
}

#[test]
fn bit_identical_for_every_instruction_set() {
    use fluid_node::simd::Simd;
    let available = Simd::available();
    for (nd, two, limiter) in [
        (2, false, "van_leer"),
        (2, false, "minmod"),
        (2, false, "mc"),
        (2, true, "van_leer"),
        (3, false, "van_leer"),
    ] {
        let cells = if nd == 3 { [14, 12, 10] } else { [34, 30, 1] };
        let text = common::walled_blast_case(cells, two, limiter);
        let runs: Vec<Vec<f64>> = available
            .iter()
            .map(|&simd| {
                let mut s = solver(&text);
                s.fluid.simd = simd;
                for _ in 0..25 {
                    fluid_node::step::step(&mut s.fluid, f64::INFINITY).expect("step");
                }
                s.fluid.cons.clone()
            })
            .collect();
        for (k, r) in runs.iter().enumerate().skip(1) {
            let same = r
                .iter()
                .zip(&runs[0])
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "{nd}-D, two materials {two}, {limiter}: {:?} differs from {:?}",
                available[k], available[0]
            );
        }
        println!("{nd}-D two {two} {limiter}: {available:?} bit-identical");
    }
}
