//! Verification fixtures of the Lagrange-multiplier coupling, shared by the solid node's
//! tests and examples and the end-to-end tests: the split bar and the three-bar chain built
//! in process, with the references they are judged against. The node itself uses none of it.

/// The larger of `a` and `b`, NaN if either is: error folds over a run's samples use it, so a
/// NaN error stays visible where `f64::max` would drop it and let a comparison pass.
pub fn nan_max(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// The split bar of `examples/split_bar.toml` (L = 1 m cut at 0.5 m, 100 elements left,
/// 300 right, E 200 GPa, ρ 7860 kg/m³, A 1e-4 m², fixed at x = 0) under a tip load ramped
/// smoothly from 0 to F₀ over T, then held: the verification case of the scheme.
///
/// Why the ramp must be C³ ([`Ramp::Septic`]) for second order to show in a on a fixed mesh:
/// a jump J in the k-th derivative of the load gives every mode ω of the mesh an acceleration
/// of order J/ω^k. A step Δt misses the phase of the modes with ωΔt ≳ 1 (up to the mesh's
/// ω_max), and their sum, ∫ dω/ω^k from 1/Δt, is an error of order Δt^(k−1) in a; the
/// resolved modes add Δt² ∫ ω^(2−k) dω. `sin²` jumps in F'' (k = 2): a is then first order
/// even on one domain. The septic ramp jumps in F'''' (k = 4): second order.
pub mod split_bar {
    use super::nan_max;
    use crate::bar::chain_system;
    use crate::lagrange::SubdomainSide;
    use mechanics::time::{
        CouplingMethod, Gs4, InterfaceDof, LinearSystem, State, Stepper, Subdomain,
    };
    use protocol::scheme::lagrange::{InterfaceSolver, LagrangeSide, Method};

    pub const YOUNG: f64 = 200e9;
    pub const DENSITY: f64 = 7860.0;
    pub const AREA: f64 = 1e-4;
    pub const LEFT_ELEMENTS: usize = 100;
    pub const RIGHT_ELEMENTS: usize = 300;
    pub const F0: f64 = 1000.0;

    /// Wave speed (m/s).
    pub fn wave_speed() -> f64 {
        (YOUNG / DENSITY).sqrt()
    }
    /// Left element transit time h/c: the left half's critical step (s).
    pub fn left_transit() -> f64 {
        0.5 / LEFT_ELEMENTS as f64 / wave_speed()
    }
    /// Load ramp time T: three transits of the whole bar (s).
    pub fn ramp_time() -> f64 {
        3.0 / wave_speed()
    }
    /// The load ramp over [0, T].
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Ramp {
        /// F₀ sin²(πt/2T): continuous F', jumps in F'' at 0 and T.
        Sin2,
        /// F₀ (35x⁴ − 84x⁵ + 70x⁶ − 20x⁷), x = t/T: F' … F''' vanish at both ends.
        Septic,
    }

    /// F(t): the ramp for t < T, then F₀.
    pub fn load(ramp: Ramp, t: f64) -> f64 {
        let r = match ramp {
            Ramp::Sin2 => crate::bar::Ramp::Sin2,
            Ramp::Septic => crate::bar::Ramp::Septic,
        };
        F0 * r.factor(t, ramp_time())
    }

    /// Node positions as `bar-1d` places them (x₀ + i h), so that a run through `cosim run`
    /// builds the same matrices to the bit.
    fn positions(from: f64, to: f64, elements: usize) -> Vec<f64> {
        let h = (to - from) / elements as f64;
        (0..=elements).map(|i| from + i as f64 * h).collect()
    }

    /// Histories sampled at every system step: u, v, a at the interface (left side) and at
    /// the tip, and the multiplier (the force on the left half at the cut, N).
    #[derive(Debug, Clone, Default)]
    pub struct Histories {
        pub dt: f64,
        pub interface: [Vec<f64>; 3],
        pub tip: [Vec<f64>; 3],
        pub lambda: Vec<f64>,
        /// Net interface work Σᵢ Wᵢ at each sample (J); −ΔE_Γ.
        pub interface_work: Vec<f64>,
    }

    impl Histories {
        fn push(&mut self, iface: [f64; 3], tip: [f64; 3], lambda: f64, work: f64) {
            for k in 0..3 {
                self.interface[k].push(iface[k]);
                self.tip[k].push(tip[k]);
            }
            self.lambda.push(lambda);
            self.interface_work.push(work);
        }
    }

    /// One half: its integrator and its steps per system step.
    #[derive(Debug, Clone, Copy)]
    pub struct Half {
        pub coef: Gs4,
        pub substeps: usize,
    }

    /// The whole bar on one mesh with one integrator at step `dt`, sampled every `every`
    /// steps up to `steps` steps: the reference.
    pub fn single(ramp: Ramp, coef: Gs4, dt: f64, steps: usize, every: usize) -> Histories {
        let mut x = positions(0.0, 0.5, LEFT_ELEMENTS);
        x.extend(positions(0.5, 1.0, RIGHT_ELEMENTS).into_iter().skip(1));
        let (sys, dof) = chain_system(&x, YOUNG, DENSITY, AREA, &[0]);
        let (gi, tip) = (LEFT_ELEMENTS - 1, sys.len() - 1);
        let h = 0.5 / LEFT_ELEMENTS as f64;
        let (k_left, m_left) = (YOUNG * AREA / h, 0.5 * DENSITY * AREA * h);
        debug_assert_eq!(dof[LEFT_ELEMENTS], Some(gi));
        let mut stepper = match Stepper::new(coef, dt, &sys) {
            Ok(s) => s,
            Err(e) => panic!("reference stepper: {e}"),
        };
        let mut s = State::zeros(sys.len());
        let mut f = vec![0.0; sys.len()];
        let mut out = Histories {
            dt: dt * every as f64,
            ..Default::default()
        };
        let sample = |s: &State, out: &mut Histories| {
            // The force the right half exerts on the left one at the cut.
            let lam = m_left * s.a[gi] + k_left * (s.u[gi] - s.u[gi - 1]);
            out.push(
                [s.u[gi], s.v[gi], s.a[gi]],
                [s.u[tip], s.v[tip], s.a[tip]],
                lam,
                0.0,
            );
        };
        sample(&s, &mut out);
        for n in 0..steps {
            let t0 = n as f64 * dt;
            f[tip] = (1.0 - coef.w1) * load(ramp, t0) + coef.w1 * load(ramp, t0 + dt);
            stepper.step(&sys, &mut s, &f);
            if (n + 1) % every == 0 {
                sample(&s, &mut out);
            }
        }
        out
    }

    #[allow(clippy::too_many_arguments)]
    fn half(
        ramp: Ramp,
        x: &[f64],
        fixed: &[usize],
        spec: Half,
        dt_system: f64,
        method: CouplingMethod,
        iface: InterfaceDof,
        tip: Option<usize>,
    ) -> Result<(Subdomain, LinearSystem), String> {
        let (sys, _) = chain_system(x, YOUNG, DENSITY, AREA, fixed);
        let mut shape = vec![0.0; sys.len()];
        if let Some(t) = tip {
            shape[t] = 1.0;
        }
        let sub = Subdomain::new(
            sys.clone(),
            spec.coef,
            dt_system,
            spec.substeps,
            method,
            vec![iface],
            shape,
            Box::new(move |t| load(ramp, t)),
        )
        .map_err(|e| e.to_string())?;
        Ok((sub, sys))
    }

    /// The split bar coupled by `method`, `steps` system steps of `dt_system`.
    pub fn split(
        ramp: Ramp,
        method: Method,
        left: Half,
        right: Half,
        dt_system: f64,
        steps: usize,
    ) -> Result<Histories, String> {
        let cm = match method {
            Method::Gs4 => CouplingMethod::Gs4,
            Method::Gc => CouplingMethod::Gc,
            Method::Ph => CouplingMethod::Ph,
        };
        let gl = LEFT_ELEMENTS - 1;
        let (l, _) = half(
            ramp,
            &positions(0.0, 0.5, LEFT_ELEMENTS),
            &[0],
            left,
            dt_system,
            cm,
            InterfaceDof {
                dof: gl,
                sign: 1.0,
                lambda: 0,
            },
            None,
        )?;
        let (r, _) = half(
            ramp,
            &positions(0.5, 1.0, RIGHT_ELEMENTS),
            &[],
            right,
            dt_system,
            cm,
            InterfaceDof {
                dof: 0,
                sign: -1.0,
                lambda: 0,
            },
            Some(RIGHT_ELEMENTS),
        )?;
        let (mut l, mut r) = (SubdomainSide(l), SubdomainSide(r));
        let mut scheme = {
            let mut sides: [&mut dyn LagrangeSide; 2] = [&mut l, &mut r];
            InterfaceSolver::new(method, 1, &mut sides).map_err(|e| e.to_string())?
        };
        let mut out = Histories {
            dt: dt_system,
            ..Default::default()
        };
        let tip = RIGHT_ELEMENTS;
        let sample = |l: &SubdomainSide, r: &SubdomainSide, lam: f64, out: &mut Histories| {
            let (a, b) = (&l.0.state, &r.0.state);
            out.push(
                [a.u[gl], a.v[gl], a.a[gl]],
                [b.u[tip], b.v[tip], b.a[tip]],
                lam,
                l.interface_work() + r.interface_work(),
            );
        };
        sample(&l, &r, scheme.lambda()[0], &mut out);
        for _ in 0..steps {
            let mut sides: [&mut dyn LagrangeSide; 2] = [&mut l, &mut r];
            scheme.step(&mut sides).map_err(|e| e.to_string())?;
            sample(&l, &r, scheme.lambda()[0], &mut out);
        }
        Ok(out)
    }

    /// Largest difference over the samples of `a` that coincide with samples of `reference`
    /// (a's sample interval is a whole multiple of the reference's), per quantity:
    /// [u, v, a at the interface, u, v, a at the tip, λ], each divided by the reference's
    /// largest magnitude; a NaN difference makes that quantity's error NaN. Also returns the
    /// fewest samples compared over the seven quantities, so a series that is short or missing
    /// shows in the count.
    pub fn errors(a: &Histories, reference: &Histories) -> ([f64; 7], usize) {
        let ratio = (a.dt / reference.dt).round() as usize;
        let series = |h: &Histories| -> [Vec<f64>; 7] {
            [
                h.interface[0].clone(),
                h.interface[1].clone(),
                h.interface[2].clone(),
                h.tip[0].clone(),
                h.tip[1].clone(),
                h.tip[2].clone(),
                h.lambda.clone(),
            ]
        };
        let (sa, sr) = (series(a), series(reference));
        let mut e = [0.0f64; 7];
        let mut fewest = usize::MAX;
        for k in 0..7 {
            let scale = sr[k].iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let mut count = 0;
            for (n, x) in sa[k].iter().enumerate() {
                let Some(y) = sr[k].get(n * ratio) else { break };
                e[k] = nan_max(e[k], (x - y).abs() / scale);
                count += 1;
            }
            fewest = fewest.min(count);
        }
        (e, fewest)
    }
}

/// A chain of three `bar-1d` subdomains (`examples/split_bar_chain.toml`, small variant):
/// steel, A = 1e-4 m², L = 1 m, the left bar [0, 0.3] m fixed at x = 0 (30 elements, average
/// acceleration, one step per system step), the middle bar [0.3, 0.6] m with both ends in one
/// interface (60 elements, central differences, four steps) and the right bar [0.6, 1] m
/// (40 elements, average acceleration, two steps) loaded at its end by F₀ along the C³ ramp
/// over three transits of the whole bar; and the same mesh as one domain, the reference.
pub mod bar_chain {
    use super::nan_max;
    use crate::bar::{Bar, chain_system};
    use crate::lagrange::SubdomainSide;
    use mechanics::time::{CouplingMethod, Design, Gs4, State, Stepper};
    use protocol::scheme::lagrange::{InterfaceSolver, LagrangeSide, Method};

    pub const YOUNG: f64 = 200e9;
    pub const DENSITY: f64 = 7860.0;
    pub const AREA: f64 = 1e-4;
    pub const F0: f64 = 1000.0;
    /// (from, to, elements) of each bar.
    pub const BARS: [(f64, f64, usize); 3] = [(0.0, 0.3, 30), (0.3, 0.6, 60), (0.6, 1.0, 40)];
    /// Steps per system step of each bar.
    pub const SUBSTEPS: [usize; 3] = [1, 4, 2];
    /// The sampled quantities: u and v at both cuts (cut 1 from the left bar, cut 2 from the
    /// middle one) and at the tip, and both multipliers as the force on the part left of
    /// their cut (N).
    pub const NAMES: [&str; 8] = [
        "u_cut1", "v_cut1", "u_cut2", "v_cut2", "u_tip", "v_tip", "λ_cut1", "λ_cut2",
    ];

    pub fn wave_speed() -> f64 {
        (YOUNG / DENSITY).sqrt()
    }
    /// The left bar's element transit time h/c: the coarsest system step (s).
    pub fn transit() -> f64 {
        (BARS[0].1 - BARS[0].0) / BARS[0].2 as f64 / wave_speed()
    }
    /// T of the load ramp: three transits of the whole bar (s).
    pub fn ramp_time() -> f64 {
        3.0 / wave_speed()
    }
    /// System steps at `transit()` to t = 2T.
    pub fn steps0() -> usize {
        (2.0 * ramp_time() / transit()).round() as usize
    }

    /// One series per name of [`NAMES`], sampled every system step from t = 0.
    #[derive(Debug, Clone)]
    pub struct Histories {
        pub dt: f64,
        pub series: Vec<Vec<f64>>,
    }

    impl Histories {
        fn new(dt: f64) -> Self {
            Histories {
                dt,
                series: vec![Vec::new(); NAMES.len()],
            }
        }
        fn push(&mut self, row: [f64; 8]) {
            for (s, v) in self.series.iter_mut().zip(row) {
                s.push(v);
            }
        }
    }

    /// The cut force on the part left of a cut at node g whose left element is `h` long:
    /// m a_g + k (u_g − u_{g−1}) with that element's half mass and stiffness (N).
    fn cut_force(h: f64, s: &State, g: usize) -> f64 {
        0.5 * DENSITY * AREA * h * s.a[g] + YOUNG * AREA / h * (s.u[g] - s.u[g - 1])
    }

    fn h(k: usize) -> f64 {
        (BARS[k].1 - BARS[k].0) / BARS[k].2 as f64
    }

    /// The whole bar on one mesh (nodes as `bar-1d` places them) in average acceleration at
    /// step `dt`, `steps` steps, sampled every `every`.
    pub fn single(dt: f64, steps: usize, every: usize) -> Result<Histories, String> {
        let mut x = Vec::new();
        for (k, &(from, _, n)) in BARS.iter().enumerate() {
            x.extend((usize::from(k > 0)..=n).map(|i| from + i as f64 * h(k)));
        }
        let (sys, dof) = chain_system(&x, YOUNG, DENSITY, AREA, &[0]);
        let node = |i: usize| dof[i].ok_or_else(|| format!("node {i} is held"));
        let (g1, g2) = (node(BARS[0].2)?, node(BARS[0].2 + BARS[1].2)?);
        let tip = sys.len() - 1;
        let coef = Gs4::u0(Design {
            rho1: 1.0,
            rho2: 1.0,
            rho_s: 0.0,
        });
        let mut stepper = Stepper::new(coef, dt, &sys).map_err(|e| e.to_string())?;
        let mut s = State::zeros(sys.len());
        let mut f = vec![0.0; sys.len()];
        let mut out = Histories::new(dt * every as f64);
        let sample = |s: &State, out: &mut Histories| {
            out.push([
                s.u[g1],
                s.v[g1],
                s.u[g2],
                s.v[g2],
                s.u[tip],
                s.v[tip],
                cut_force(h(0), s, g1),
                cut_force(h(1), s, g2),
            ]);
        };
        sample(&s, &mut out);
        for n in 0..steps {
            // Average acceleration balances the load at the step end (W₁ = 1).
            f[tip] = F0 * crate::bar::Ramp::Septic.factor((n + 1) as f64 * dt, ramp_time());
            stepper.step(&sys, &mut s, &f);
            if (n + 1) % every == 0 {
                sample(&s, &mut out);
            }
        }
        Ok(out)
    }

    /// Bar `k` as `bar-1d` builds it from a case file's params, implicit (average
    /// acceleration) or explicit (central differences).
    fn bar(k: usize, implicit: bool, params: &str) -> Result<Bar, String> {
        let (from, to, n) = BARS[k];
        let text = format!(
            "x0 = {from}\nlength = {}\nelements = {n}\nyoung = {YOUNG}\ndensity = {DENSITY}\n\
             area = {AREA}\nintegrator = {{ scheme = \"gs4\", design = \"U0(1,1,0)\", \
             implicit = {implicit} }}\n{params}",
            to - from
        );
        let table = text.parse::<toml::Table>().map_err(|e| e.to_string())?;
        Bar::from_params(&table).map_err(|e| e.to_string())
    }

    /// The chain coupled by `method` at system step `dt` for `steps` steps (each bar at its
    /// [`SUBSTEPS`], the middle one explicit): the histories and ΔE_Γ = −Σᵢ Wᵢ after each
    /// step (J).
    pub fn chain(method: Method, dt: f64, steps: usize) -> Result<(Histories, Vec<f64>), String> {
        chain_with(method, [true, false, true], SUBSTEPS, dt, steps)
    }

    /// [`chain`] with each bar implicit or not and at `substeps` per system step.
    pub fn chain_with(
        method: Method,
        implicit: [bool; 3],
        substeps: [usize; 3],
        dt: f64,
        steps: usize,
    ) -> Result<(Histories, Vec<f64>), String> {
        let cm = match method {
            Method::Gs4 => CouplingMethod::Gs4,
            Method::Gc => CouplingMethod::Gc,
            Method::Ph => CouplingMethod::Ph,
        };
        let outer = "fixed = \"none\"\nload_end = \"none\"\n";
        let bars = [
            bar(
                0,
                implicit[0],
                "fixed = \"left\"\nload_end = \"none\"\ninterfaces = { cut = \"right\" }\n",
            )?,
            bar(
                1,
                implicit[1],
                &format!("{outer}interfaces = {{ cuts = \"left+right\" }}\n"),
            )?,
            bar(
                2,
                implicit[2],
                &format!(
                    "fixed = \"none\"\ntip_force = {F0}\nramp = \"septic\"\nramp_time = {}\n\
                     interfaces = {{ cut = \"left\" }}\n",
                    ramp_time()
                ),
            )?,
        ];
        // +1 on the middle bar, −1 on the outer ones: λ is the force on the middle bar; the
        // middle bar's multipliers are its left end's (cut 1) then its right end's (cut 2).
        let side = |k: usize, name: &str, sign: f64, first: usize| {
            bars[k]
                .subdomain(name, sign, first, dt, substeps[k], cm)
                .map(SubdomainSide)
                .map_err(|e| e.to_string())
        };
        let mut s1 = side(0, "cut", -1.0, 0)?;
        let mut s2 = side(1, "cuts", 1.0, 0)?;
        let mut s3 = side(2, "cut", -1.0, 1)?;
        let mut scheme = {
            let mut sides: [&mut dyn LagrangeSide; 3] = [&mut s1, &mut s2, &mut s3];
            InterfaceSolver::new(method, 2, &mut sides).map_err(|e| e.to_string())?
        };
        let (g1, g2, tip) = (BARS[0].2 - 1, BARS[1].2, BARS[2].2);
        let mut out = Histories::new(dt);
        let mut energy = Vec::with_capacity(steps + 1);
        let sample = |s: [&SubdomainSide; 3], lam: &[f64], out: &mut Histories| {
            let (a, b, c) = (&s[0].0.state, &s[1].0.state, &s[2].0.state);
            out.push([
                a.u[g1], a.v[g1], b.u[g2], b.v[g2], c.u[tip], c.v[tip], -lam[0], lam[1],
            ]);
        };
        sample([&s1, &s2, &s3], scheme.lambda(), &mut out);
        energy.push(0.0);
        for _ in 0..steps {
            let mut sides: [&mut dyn LagrangeSide; 3] = [&mut s1, &mut s2, &mut s3];
            scheme.step(&mut sides).map_err(|e| e.to_string())?;
            sample([&s1, &s2, &s3], scheme.lambda(), &mut out);
            energy.push(-(s1.interface_work() + s2.interface_work() + s3.interface_work()));
        }
        Ok((out, energy))
    }

    /// Per series: the largest difference over the samples of `a` that coincide with
    /// samples of `reference` (a's interval a whole multiple of the reference's), divided by
    /// the reference's largest magnitude, NaN if any value is NaN; and that series' own count
    /// of samples compared.
    pub fn errors(a: &Histories, reference: &Histories) -> Vec<(f64, usize)> {
        let ratio = (a.dt / reference.dt).round() as usize;
        a.series
            .iter()
            .zip(&reference.series)
            .map(|(x, r)| {
                let scale = r.iter().fold(0.0f64, |m, v| nan_max(m, v.abs()));
                let mut e = 0.0f64;
                let mut n = 0;
                for (k, xv) in x.iter().enumerate() {
                    let Some(y) = r.get(k * ratio) else { break };
                    e = nan_max(e, (xv - y).abs() / scale);
                    n += 1;
                }
                (e, n)
            })
            .collect()
    }
}
