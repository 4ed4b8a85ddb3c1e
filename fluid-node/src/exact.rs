//! Exact solutions of the radial verification problems, for the tests and for anyone who
//! compares a run with them (docs/physics.md §11): Sedov's point blast and Noh's implosion.
//! Neither uses any of the solver's code.

/// The strong-shock similarity solution of the point blast (Sedov; Kamm & Timmes, LA-UR-07-2849,
/// give the same equations in closed form): u = U f(ξ), ρ = ρ0 g(ξ), p = ρ0 U² h(ξ) behind
/// the shock, ξ = r/R, with R = (E/(α ρ0))^{1/(ν+2)} t^{2/(ν+2)} and U = dR/dt. The ODEs are
/// integrated by RK4 from the Rankine–Hugoniot state at ξ = 1 to ξ = 1e-6; α is the
/// energy integral of the same profile.
pub struct Sedov {
    pub nu: usize,
    pub gamma: f64,
    pub alpha: f64,
    /// (ξ, f, g, h), ξ decreasing from 1.
    pub table: Vec<[f64; 4]>,
}

impl Sedov {
    pub fn new(nu: usize, g: f64) -> Self {
        let nuf = nu as f64;
        let d = 2.0 / (nuf + 2.0);
        let rhs = |x: f64, y: [f64; 3]| -> [f64; 3] {
            let [f, gg, h] = y;
            let ff = f - x;
            let fp = (-(d - 1.0) * f * ff / d
                + (h / gg) * (2.0 * (d - 1.0) / d + g * (nuf - 1.0) * f / x))
                / (ff * ff - g * h / gg);
            let gp = (-(nuf - 1.0) * gg * f / x - gg * fp) / ff;
            let hp = h * (-2.0 * (d - 1.0) / d / ff + g * gp / gg);
            [fp, gp, hp]
        };
        let integrand = |x: f64, y: [f64; 3]| {
            (y[2] / (g - 1.0) + 0.5 * y[1] * y[0] * y[0]) * x.powi(nu as i32 - 1)
        };
        let mut y = [2.0 / (g + 1.0), (g + 1.0) / (g - 1.0), 2.0 / (g + 1.0)];
        let mut x = 1.0;
        let n = 20000;
        let dx = -(1.0 - 1e-6) / n as f64;
        let mut integral = 0.0;
        let mut table = vec![[x, y[0], y[1], y[2]]];
        let add =
            |a: [f64; 3], k: [f64; 3], s: f64| [a[0] + s * k[0], a[1] + s * k[1], a[2] + s * k[2]];
        for _ in 0..n {
            let k1 = rhs(x, y);
            let k2 = rhs(x + 0.5 * dx, add(y, k1, 0.5 * dx));
            let k3 = rhs(x + 0.5 * dx, add(y, k2, 0.5 * dx));
            let k4 = rhs(x + dx, add(y, k3, dx));
            let mut yn = y;
            for j in 0..3 {
                yn[j] += dx / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
            integral += -dx * 0.5 * (integrand(x, y) + integrand(x + dx, yn));
            x += dx;
            y = yn;
            table.push([x, y[0], y[1], y[2]]);
        }
        let sigma = match nu {
            1 => 2.0,
            2 => 2.0 * std::f64::consts::PI,
            _ => 4.0 * std::f64::consts::PI,
        };
        Sedov {
            nu,
            gamma: g,
            alpha: d * d * sigma * integral,
            table,
        }
    }

    /// Shock radius at time t for energy e (per unit length when ν = 2) into density rho0.
    pub fn radius(&self, e: f64, rho0: f64, t: f64) -> f64 {
        let k = 1.0 / (self.nu as f64 + 2.0);
        (e / (self.alpha * rho0)).powf(k) * t.powf(2.0 * k)
    }

    /// (ρ, u, p) at radius r and time t; `p0` ahead of the shock (the solution neglects it).
    pub fn state(&self, e: f64, rho0: f64, p0: f64, r: f64, t: f64) -> (f64, f64, f64) {
        let big_r = self.radius(e, rho0, t);
        let xi = r / big_r;
        if xi >= 1.0 {
            return (rho0, 0.0, p0);
        }
        let u_s = 2.0 / (self.nu as f64 + 2.0) * big_r / t;
        let tb = &self.table;
        // the table's ξ falls in equal steps from 1
        let step = (tb[0][0] - tb[tb.len() - 1][0]) / (tb.len() - 1) as f64;
        let s = ((1.0 - xi) / step).min((tb.len() - 2) as f64);
        let k = s.floor() as usize;
        let w = s - k as f64;
        let at = |c: usize| tb[k][c] * (1.0 - w) + tb[k + 1][c] * w;
        (rho0 * at(2), u_s * at(1), rho0 * u_s * u_s * at(3))
    }
}

/// Noh's implosion (Noh 1987): a cold ideal gas of density ρ0 moving toward the axis or
/// centre at speed |u0| stagnates behind a shock that runs out at D = (γ − 1)|u0|/2. Returns
/// (ρ, u, p) at radius r and time t for ν = 1 (planar), 2 (cylindrical), 3 (spherical).
pub fn noh(nu: usize, gamma: f64, rho0: f64, u0: f64, r: f64, t: f64) -> (f64, f64, f64) {
    let speed = u0.abs();
    let shock = 0.5 * (gamma - 1.0) * speed * t;
    if r < shock {
        let rho = rho0 * ((gamma + 1.0) / (gamma - 1.0)).powi(nu as i32);
        (rho, 0.0, 0.5 * (gamma - 1.0) * rho * speed * speed)
    } else {
        let rho = rho0 * (1.0 + speed * t / r).powi(nu as i32 - 1);
        (rho, -speed, 0.0)
    }
}
