//! `cosim conformance --kind lagrange`: the node as one side of a Lagrange-multiplier
//! coupling (PROTOCOL.md 4.6), `cosim` as the coordinator that solves the interface problem,
//! with a scripted second side: a rigid body that moves every interface point at 1 mm/s
//! along x and does not yield (its operator, set-up acceleration and inverse mass are zero).
//! The multipliers then make the node's interface follow it, and the node's next message
//! shows whether it corrected as its stated operator says: a side whose operator misstates
//! its response is solved for the wrong multipliers, and the coupled run drifts apart.

use super::*;
use protocol::scheme::lagrange::{Hub, Method, wire};

/// The rules of a lagrange side, in the order a run meets them: (name, section).
pub(super) const RULES: [(&str, &str); 12] = [
    ("describe", "§2 --describe"),
    ("hello", "§4.2 item 2"),
    ("welcome-describe", "§4.2 item 4"),
    ("mesh", "§4.2 item 6"),
    ("lagrange-set-up", "§4.6 items 2-3"),
    ("lagrange-steps", "§4.6 item 4"),
    ("lagrange-correction", "§4.6 item 4"),
    ("windows-in-order", "§4.2 items 7-8"),
    ("heartbeat", "§4.4 Heartbeat"),
    ("checkpoint", "§4.5"),
    ("finish", "§4.2 item 9"),
    ("cleanup", "§3 Cleanup"),
];

/// The scripted side's node name.
pub(super) const SIDE: &str = "rigid";

/// A corrected velocity agrees with the operator's prediction within this share of the
/// velocities involved (the correction is linear: round-off is far below it).
const CORRECTION_TOLERANCE: f64 = 1e-6;

/// A stated operator is symmetric within this share of its largest entry (a linear
/// mechanical side's is, by reciprocity).
const SYMMETRY_TOLERANCE: f64 = 1e-8;

/// Drive the node of `o` as a lagrange side (gs4, one exchange per window) and check it.
pub(super) fn check(o: &Options) -> anyhow::Result<Vec<Verdict>> {
    let o = &Options {
        role: Role::Driver,
        ..o.clone()
    };
    check_with(o, &RULES, |coupling, iface, window| Drive {
        o,
        binding: binding_of(o, &coupling),
        described: iface,
        window,
        checkpoint_at: o.windows.saturating_sub(1).max(1),
    })
}

struct Drive<'a> {
    o: &'a Options,
    binding: Binding,
    described: InterfaceDescription,
    window: f64,
    checkpoint_at: u64,
}

/// What the node stated at set-up and has been sent since: its operator (n × n), and the
/// multipliers it was last given (its local order).
struct Side {
    n: usize,
    operator: Vec<f64>,
    lambda: Vec<f64>,
}

impl Driven for Drive<'_> {
    fn binding(&self) -> &Binding {
        &self.binding
    }

    fn run(&self, s: &mut Session, sheet: &mut Sheet) -> anyhow::Result<()> {
        let mut sent = vec![false; self.o.windows as usize + 1];
        let mut hub = Hub::new(
            &self.binding.coupling,
            Method::Gs4,
            &["node".to_string(), SIDE.to_string()],
            self.window,
        );
        let (mesh, mut side) = self.set_up(s, sheet, &mut hub, &mut sent)?;
        let rigid = rigid_velocity(&mesh, side.n);
        // The velocity the node's next free step should start from: v_free + H Δλ of the
        // window before (None before the first window).
        let mut predicted: Option<Vec<f64>> = None;
        let mut judged = 0;
        for k in 1..=self.o.windows {
            let t1 = advance(s, k, self.window, k == self.checkpoint_at)?;
            let f = self.node_fields(s, k, &mut sent)?;
            let (v_start, v_free) = match steps_of(&f, side.n) {
                Ok(v) => v,
                Err(why) => {
                    sheet.fail("lagrange-steps", format!("window {k}: {why}"));
                    anyhow::bail!("window {k}: {why}");
                }
            };
            if let Some(p) = predicted.take() {
                judged += 1;
                if let Some(why) = disagreement(&v_start, &p, &rigid) {
                    sheet.fail(
                        "lagrange-correction",
                        format!(
                            "window {k} starts from interface velocities {why} than its \
                             free step of window {} corrected by its stated operator gives",
                            k - 1
                        ),
                    );
                }
            }
            let answer = self.solve(&mut hub, f, &rigid, k)?;
            let lambda = own_multipliers(&answer, side.n)
                .ok_or_else(|| anyhow::anyhow!("window {k}: the hub gave no multipliers"))?;
            let dl: Vec<f64> = lambda
                .iter()
                .zip(&side.lambda)
                .map(|(a, b)| a - b)
                .collect();
            predicted = Some(
                (0..side.n)
                    .map(|r| {
                        v_free[r]
                            + (0..side.n)
                                .map(|c| side.operator[r * side.n + c] * dl[c])
                                .sum::<f64>()
                    })
                    .collect(),
            );
            side.lambda = lambda;
            s.send_peer(0, wire::PEER, &Message::Fields(answer))?;
            await_done(s, sheet, &self.o.output, k, t1, k == self.checkpoint_at)?;
            idle(s)?;
        }
        if sheet.outcome("lagrange-steps") == Outcome::NotReached {
            sheet.pass(
                "lagrange-steps",
                format!(
                    "one Fields per window with step 0 and {} finite v_start and v_free",
                    side.n
                ),
            );
        }
        if sheet.outcome("lagrange-correction") == Outcome::NotReached {
            sheet.pass(
                "lagrange-correction",
                format!(
                    "in {judged} window(s) the corrected interface velocity is its free one plus its \
                     stated operator times the multipliers' increment (within {CORRECTION_TOLERANCE:e})"
                ),
            );
        }
        judge_order(s, sheet, &sent, self.o.windows);
        judge_heartbeat(s, sheet);
        Ok(())
    }
}

impl Drive<'_> {
    /// Hello, Welcome, the coordinator's request, set-up up to `Done{0}`: the "hello",
    /// "welcome-describe", "mesh" and "lagrange-set-up" rules. Returns the node's interface
    /// mesh and what it stated.
    fn set_up(
        &self,
        s: &mut Session,
        sheet: &mut Sheet,
        hub: &mut Hub,
        sent: &mut [bool],
    ) -> anyhow::Result<(InterfaceMesh, Side)> {
        greet(s, sheet, self.o, &self.binding, &self.described)?;
        // The request goes before Advance{0}, once the node listens for it.
        s.wait_readers(0, wire::PEER, 1, Duration::from_secs(60))?;
        s.send_peer(0, wire::PEER, &Message::Fields(hub.request()))?;
        s.set_up()?;
        let mesh = take_mesh(s, sheet, &self.binding, self.described.points)?;
        let b = &self.binding;
        let f = self.node_fields(s, 0, sent)?;
        let side = match set_up_of(&f, mesh.len()) {
            Ok(side) => side,
            Err(why) => {
                sheet.fail("lagrange-set-up", why.clone());
                anyhow::bail!("set-up: {why}");
            }
        };
        let fail = |sheet: &mut Sheet, why: String| {
            sheet.fail("lagrange-set-up", why.clone());
            anyhow::anyhow!("set-up: {why}")
        };
        let mut answer = hub
            .on_mesh("node", mesh.clone())
            .and_then(|_| hub.on_fields("node", f))
            .and_then(|_| hub.on_mesh(SIDE, mesh.clone()))
            .and_then(|_| hub.on_fields(SIDE, rigid_set_up(&b.coupling, side.n)))
            .map_err(|e| fail(sheet, e))?;
        let Some(lambda0) = answer.first().and_then(|a| own_multipliers(a, side.n)) else {
            return Err(fail(sheet, "no initial multipliers could be solved".into()));
        };
        for a in answer.drain(..) {
            s.send_peer(0, wire::PEER, &Message::Fields(a))?;
        }
        s.wait("Done of the set-up", Some(Duration::from_secs(60)), |s| {
            s.done.as_ref().is_some_and(|d| d.0 == 0)
        })?;
        idle(s)?;
        sheet.pass(
            "lagrange-set-up",
            format!(
                "{} unknowns, one coupling step, a symmetric operator with a positive \
                 diagonal; initial multipliers applied before Done{{0}}",
                side.n
            ),
        );
        Ok((
            mesh,
            Side {
                lambda: lambda0,
                ..side
            },
        ))
    }

    /// The node's `Fields` of window `k` (waiting for it), checked to be the only one.
    fn node_fields(&self, s: &mut Session, k: u64, sent: &mut [bool]) -> anyhow::Result<Fields> {
        s.wait(
            &format!("the side's Fields of window {k}"),
            Some(Duration::from_secs(60)),
            |s| s.arrived.iter().any(|f| f.window == k),
        )?;
        let mut mine: Vec<Fields> = Vec::new();
        for f in std::mem::take(&mut s.arrived) {
            if f.window == k {
                mine.push(f);
            } else {
                anyhow::bail!(
                    "the side sent Fields of window {} while window {k} was due",
                    f.window
                );
            }
        }
        if let Some(x) = sent.get_mut(k as usize) {
            *x = true;
        }
        if mine.len() != 1 {
            anyhow::bail!("{} Fields of window {k}; one expected", mine.len());
        }
        Ok(mine.remove(0))
    }

    /// The node's step of window `k` and the rigid side's to the hub: the multipliers.
    fn solve(&self, hub: &mut Hub, f: Fields, rigid: &[f64], k: u64) -> anyhow::Result<Fields> {
        let c = self.binding.coupling.clone();
        hub.on_fields("node", f)
            .map_err(|e| anyhow::anyhow!("window {k}: {e}"))?;
        let step = Fields {
            coupling: c,
            window: k,
            time: k as f64 * self.window,
            fields: vec![
                wire::scalar(wire::STEP, 0.0),
                vector(wire::V_START, rigid.to_vec()),
                vector(wire::V_FREE, rigid.to_vec()),
            ],
        };
        let mut out = hub
            .on_fields(SIDE, step)
            .map_err(|e| anyhow::anyhow!("window {k}: {e}"))?;
        if out.len() != 1 {
            anyhow::bail!("window {k}: {} answers of the hub", out.len());
        }
        Ok(out.remove(0))
    }
}

/// Let the node idle a moment: its heartbeats must go on.
fn idle(s: &mut Session) -> anyhow::Result<()> {
    let until = Instant::now() + IDLE;
    while Instant::now() < until {
        s.pump(Duration::from_millis(10))?;
    }
    Ok(())
}

fn vector(name: &str, values: Vec<f64>) -> Field {
    Field {
        name: name.to_string(),
        components: 1,
        values,
    }
}

/// The rigid side's velocity in the node's local order: per point, its unknowns take the
/// components of [`PEER_VELOCITY`] in turn (x first).
fn rigid_velocity(mesh: &InterfaceMesh, n: usize) -> Vec<f64> {
    let per = n / mesh.len().max(1);
    (0..n)
        .map(|k| PEER_VELOCITY.get(k % per).copied().unwrap_or(0.0))
        .collect()
}

/// The rigid side's set-up: n unknowns, one step, and a body that does not yield.
fn rigid_set_up(coupling: &str, n: usize) -> Fields {
    Fields {
        coupling: coupling.to_string(),
        window: 0,
        time: 0.0,
        fields: vec![
            wire::scalar(wire::DOFS, n as f64),
            wire::scalar(wire::STEPS, 1.0),
            vector(wire::OPERATOR, vec![0.0; n * n]),
            vector(wire::FREE0, vec![0.0; n]),
            vector(wire::MASS0, vec![0.0; n * n]),
        ],
    }
}

/// The multipliers the hub's answer gives the node.
fn own_multipliers(answer: &Fields, n: usize) -> Option<Vec<f64>> {
    answer
        .get("node")
        .map(|f| f.values.clone())
        .filter(|v| v.len() == n)
}

/// What a side's set-up `Fields` states, checked: sizes, finite values, one coupling step
/// (gs4), a symmetric operator with a positive diagonal.
fn set_up_of(f: &Fields, points: usize) -> Result<Side, String> {
    let get = |name: &str| {
        f.get(name)
            .map(|x| x.values.clone())
            .ok_or_else(|| format!("no '{name}' in its set-up Fields"))
    };
    let dofs = get(wire::DOFS)?;
    let n = match dofs.as_slice() {
        [v] if *v >= 1.0 && v.fract() == 0.0 && *v <= 1e6 => *v as usize,
        other => {
            return Err(format!(
                "'{}' must be one whole number ≥ 1, got {other:?}",
                wire::DOFS
            ));
        }
    };
    if points == 0 || !n.is_multiple_of(points) {
        return Err(format!("{n} unknowns on {points} interface points"));
    }
    let steps = get(wire::STEPS)?;
    if steps != [1.0] {
        return Err(format!(
            "'{}' is {steps:?}: one coupling step per window under gs4",
            wire::STEPS
        ));
    }
    let operator = get(wire::OPERATOR)?;
    for (name, v, len) in [
        (wire::OPERATOR, &operator, n * n),
        (wire::FREE0, &get(wire::FREE0)?, n),
        (wire::MASS0, &get(wire::MASS0)?, n * n),
    ] {
        if v.len() != len {
            return Err(format!(
                "'{name}' has {} values for {n} unknowns ({len} expected)",
                v.len()
            ));
        }
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(format!("'{name}' holds {x}"));
        }
    }
    let scale = operator.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for r in 0..n {
        if operator[r * n + r] <= 0.0 {
            return Err(format!(
                "its operator's diagonal entry {r} is {:e}: a force must move its own unknown along it",
                operator[r * n + r]
            ));
        }
        for c in r + 1..n {
            let (a, b) = (operator[r * n + c], operator[c * n + r]);
            if (a - b).abs() > SYMMETRY_TOLERANCE * scale {
                return Err(format!(
                    "its operator is not symmetric: entries ({r}, {c}) and ({c}, {r}) are {a:e} and {b:e}"
                ));
            }
        }
    }
    Ok(Side {
        n,
        operator,
        lambda: Vec::new(),
    })
}

/// A window's step message checked: step 0, and n finite `v_start` and `v_free`.
fn steps_of(f: &Fields, n: usize) -> Result<(Vec<f64>, Vec<f64>), String> {
    match wire::step_of(f) {
        Some(0) => {}
        Some(c) => return Err(format!("step {c}, but gs4 takes one coupling step (0)")),
        None => return Err("no valid 'step' field".into()),
    }
    let get = |name: &str| -> Result<Vec<f64>, String> {
        let v = f
            .get(name)
            .map(|x| x.values.clone())
            .ok_or_else(|| format!("no '{name}'"))?;
        if v.len() != n {
            return Err(format!("'{name}' has {} values for {n} unknowns", v.len()));
        }
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(format!("'{name}' holds {x}"));
        }
        Ok(v)
    };
    Ok((get(wire::V_START)?, get(wire::V_FREE)?))
}

/// How far `got` is from `want`, said, when more than the tolerance of the velocities
/// involved (`rigid`: the velocity the coupling drives toward); None when they agree.
fn disagreement(got: &[f64], want: &[f64], rigid: &[f64]) -> Option<String> {
    let scale = got
        .iter()
        .chain(want)
        .chain(rigid)
        .fold(0.0f64, |m, x| m.max(x.abs()));
    // NaN anywhere makes the difference NaN (f64::max would drop it).
    let diff = got.iter().zip(want).fold(0.0f64, |m, (a, b)| {
        let d = (a - b).abs();
        if d.is_nan() || m.is_nan() {
            f64::NAN
        } else {
            m.max(d)
        }
    });
    (diff.is_nan() || diff > CORRECTION_TOLERANCE * scale).then(|| {
        format!(
            "farther by {diff:.3e} m/s ({:.2e} of the velocities {scale:.3e} m/s)",
            diff / scale
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set_up(op: Vec<f64>) -> Fields {
        let n = (op.len() as f64).sqrt() as usize;
        Fields {
            coupling: "c".into(),
            window: 0,
            time: 0.0,
            fields: vec![
                wire::scalar(wire::DOFS, n as f64),
                wire::scalar(wire::STEPS, 1.0),
                vector(wire::OPERATOR, op),
                vector(wire::FREE0, vec![0.0; n]),
                vector(wire::MASS0, vec![1.0; n * n]),
            ],
        }
    }

    #[test]
    fn a_set_up_is_held_to_its_sizes_and_a_symmetric_operator() {
        let side = set_up_of(&set_up(vec![2.0, 0.5, 0.5, 3.0]), 2).unwrap();
        assert_eq!((side.n, side.operator.len()), (2, 4));
        let e = set_up_of(&set_up(vec![2.0, 0.5, 0.6, 3.0]), 2)
            .err()
            .unwrap();
        assert!(e.contains("not symmetric"), "{e}");
        let e = set_up_of(&set_up(vec![-2.0, 0.0, 0.0, 3.0]), 2)
            .err()
            .unwrap();
        assert!(e.contains("diagonal entry 0"), "{e}");
        let e = set_up_of(&set_up(vec![2.0, 0.0, 0.0, 3.0]), 3)
            .err()
            .unwrap();
        assert!(e.contains("2 unknowns on 3"), "{e}");
        let mut f = set_up(vec![1.0]);
        f.fields[1] = wire::scalar(wire::STEPS, 4.0);
        let e = set_up_of(&f, 1).err().unwrap();
        assert!(e.contains("one coupling step"), "{e}");
    }

    #[test]
    fn a_correction_off_its_operator_is_caught() {
        let rigid = [1e-3, 0.0];
        assert!(disagreement(&[1e-3, 1e-12], &[1e-3, 0.0], &rigid).is_none());
        let why = disagreement(&[2e-3, 0.0], &[1e-3, 0.0], &rigid).unwrap();
        assert!(why.contains("1.000e-3 m/s"), "{why}");
        assert!(disagreement(&[f64::NAN, 0.0], &[1e-3, 0.0], &rigid).is_some());
    }
}
