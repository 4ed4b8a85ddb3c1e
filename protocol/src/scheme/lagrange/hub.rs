//! The scheme's coordinator side: the coordinator's end of `kind = "lagrange"` couplings (seed 003 §4, docs/architecture.md.3):
//! collects every side's set-up and interface mesh, ties the sides' matching interface points
//! with multipliers, and drives the [`InterfaceSolver`] from the sides'
//! messages, answering each solved step with the multipliers (the wire:
//! [`wire`]). No I/O here: the coordinator publishes what it returns.

use super::{InterfaceSolver, Method, SideSetup, wire};
use crate::message::{Field, Fields, InterfaceMesh};

/// Two interface points are the same point when this close, relative to the interface's
/// extent (at least 1 m).
const MATCH_TOLERANCE: f64 = 1e-9;

/// A hub's state at a window end, for the coordinator's checkpoint: the window it is in and
/// the multipliers of the last system step (global, and each side's). The meshes, set-ups and
/// factorised interface matrices are built again by a restart's set-up.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HubState {
    pub coupling: String,
    pub current: u64,
    pub lambda: Vec<f64>,
    pub sides: Vec<Vec<f64>>,
}

/// One lagrange coupling as the coordinator drives it.
#[derive(Debug)]
pub struct Hub {
    pub coupling: String,
    method: Method,
    window: f64,
    /// Node names of the sides, in the case's order.
    pub sides: Vec<String>,
    meshes: Vec<Option<InterfaceMesh>>,
    setups: Vec<Option<Fields>>,
    scheme: Option<InterfaceSolver>,
    /// System step (window) the sides are in.
    current: u64,
    /// λ at the end of each finished window, oldest first (taken by [`Hub::take_finished`]).
    finished: Vec<(u64, Vec<f64>)>,
}

impl Hub {
    /// Coupling `coupling` of the side nodes `sides` (in the case's order), solved by
    /// `method` with the system step `window` (s).
    pub fn new(coupling: &str, method: Method, sides: &[String], window: f64) -> Self {
        let n = sides.len();
        Hub {
            coupling: coupling.to_string(),
            method,
            window,
            sides: sides.to_vec(),
            meshes: vec![None; n],
            setups: vec![None; n],
            scheme: None,
            current: 1,
            finished: Vec::new(),
        }
    }

    /// The set-up request every side gets first.
    pub fn request(&self) -> Fields {
        wire::request_fields(&self.coupling, self.method, self.window)
    }

    fn side(&self, node: &str) -> Result<usize, String> {
        self.sides
            .iter()
            .position(|s| s == node)
            .ok_or_else(|| format!("node '{node}' is not a side of this coupling"))
    }

    /// A side's interface mesh (sent once at set-up).
    pub fn on_mesh(&mut self, node: &str, mesh: InterfaceMesh) -> Result<Vec<Fields>, String> {
        let i = self.side(node)?;
        self.meshes[i] = Some(mesh);
        self.try_build()
    }

    /// A side's message: its set-up (window 0) or a free coupling step; returns the
    /// multiplier messages to publish.
    pub fn on_fields(&mut self, node: &str, f: Fields) -> Result<Vec<Fields>, String> {
        let i = self.side(node)?;
        if f.window == 0 {
            if self.setups[i].is_some() {
                return Err(format!("second set-up from side '{node}'"));
            }
            self.setups[i] = Some(f);
            return self.try_build();
        }
        let Some(scheme) = self.scheme.as_mut() else {
            return Err(format!(
                "side '{node}' stepped before the set-up was complete"
            ));
        };
        if f.window != self.current {
            return Err(format!(
                "side '{node}' sent window {} while window {} is being solved",
                f.window, self.current
            ));
        }
        let c = wire::step_of(&f).ok_or_else(|| format!("side '{node}': no valid 'step' field"))?;
        let get = |name: &str| {
            f.get(name)
                .map(|x| x.values.as_slice())
                .ok_or_else(|| format!("side '{node}': no '{name}' field"))
        };
        scheme
            .offer(i, c, get(wire::V_START)?, get(wire::V_FREE)?)
            .map_err(|e| e.to_string())?;
        let mut out = Vec::new();
        while let Some(j) = scheme.try_solve() {
            let fine = scheme.fine_steps();
            let t = (self.current - 1) as f64 * self.window
                + self.window * (j + 1) as f64 / fine as f64;
            let mut fields = vec![
                wire::scalar(wire::STEP, j as f64),
                vector(wire::LAMBDA, scheme.lambda().to_vec()),
            ];
            for (k, name) in self.sides.iter().enumerate() {
                if scheme.ends(k, j) {
                    fields.push(vector(name, scheme.side_lambda(k).to_vec()));
                }
            }
            out.push(Fields {
                coupling: self.coupling.clone(),
                window: self.current,
                time: t,
                fields,
            });
            if j + 1 == fine {
                self.finished.push((self.current, scheme.lambda().to_vec()));
                self.current += 1;
                break;
            }
        }
        Ok(out)
    }

    /// The state to checkpoint at a window end (None before the set-up is complete).
    pub fn save(&self) -> Option<HubState> {
        let scheme = self.scheme.as_ref()?;
        Some(HubState {
            coupling: self.coupling.clone(),
            current: self.current,
            lambda: scheme.lambda().to_vec(),
            sides: (0..self.sides.len())
                .map(|k| scheme.side_lambda(k).to_vec())
                .collect(),
        })
    }

    /// Continue from a checkpoint's `st`, once a restart's set-up has built the scheme again.
    pub fn restore(&mut self, st: &HubState) -> Result<(), String> {
        if st.coupling != self.coupling {
            return Err(format!(
                "checkpoint of coupling '{}', not '{}'",
                st.coupling, self.coupling
            ));
        }
        let Some(scheme) = self.scheme.as_mut() else {
            return Err("restored before the set-up was complete".into());
        };
        scheme
            .restore(&st.lambda, &st.sides)
            .map_err(|e| e.to_string())?;
        self.current = st.current;
        self.finished.clear();
        Ok(())
    }

    /// λ at the end of the windows finished since the last call.
    pub fn take_finished(&mut self) -> Vec<(u64, Vec<f64>)> {
        std::mem::take(&mut self.finished)
    }

    /// Once every side's mesh and set-up are in: the multipliers, the scheme, λ₀.
    fn try_build(&mut self) -> Result<Vec<Fields>, String> {
        if self.scheme.is_some()
            || self.meshes.iter().any(Option::is_none)
            || self.setups.iter().any(Option::is_none)
        {
            return Ok(Vec::new());
        }
        let mut local = Vec::with_capacity(self.sides.len());
        for (i, (m, f)) in self.meshes.iter().zip(&self.setups).enumerate() {
            let (Some(m), Some(f)) = (m, f) else {
                return Ok(Vec::new());
            };
            local.push(side_setup(&self.sides[i], m, f)?);
        }
        let (n, ids, signs) = tie(&self.sides, &self.meshes, &local)?;
        let setups: Vec<SideSetup> = local
            .into_iter()
            .zip(ids.into_iter().zip(signs))
            .map(|(mut s, (ids, signs))| {
                s.ids = ids;
                s.signs = signs;
                s
            })
            .collect();
        let scheme =
            InterfaceSolver::from_setups(self.method, n, setups).map_err(|e| e.to_string())?;
        let mut fields = vec![
            wire::scalar(wire::STEP, 0.0),
            vector(wire::LAMBDA, scheme.lambda().to_vec()),
        ];
        for (k, name) in self.sides.iter().enumerate() {
            fields.push(vector(name, scheme.side_lambda(k).to_vec()));
        }
        self.scheme = Some(scheme);
        Ok(vec![Fields {
            coupling: self.coupling.clone(),
            window: 0,
            time: 0.0,
            fields,
        }])
    }
}

fn vector(name: &str, values: Vec<f64>) -> Field {
    Field {
        name: name.to_string(),
        components: 1,
        values,
    }
}

/// A side's set-up message as a [`SideSetup`] without its multipliers (ids, signs) yet.
fn side_setup(node: &str, mesh: &InterfaceMesh, f: &Fields) -> Result<SideSetup, String> {
    let get = |name: &str| {
        f.get(name)
            .map(|x| x.values.clone())
            .ok_or_else(|| format!("side '{node}': set-up without '{name}'"))
    };
    let count = |name: &str| -> Result<usize, String> {
        let v = get(name)?.first().copied().unwrap_or(-1.0);
        if v >= 1.0 && v.fract() == 0.0 && v <= 1e6 {
            Ok(v as usize)
        } else {
            Err(format!(
                "side '{node}': '{name}' must be a whole number ≥ 1, got {v}"
            ))
        }
    };
    let dofs = count(wire::DOFS)?;
    if mesh.is_empty() || !dofs.is_multiple_of(mesh.len()) {
        return Err(format!(
            "side '{node}': {dofs} interface unknowns on {} interface points",
            mesh.len()
        ));
    }
    Ok(SideSetup {
        ids: Vec::new(),
        signs: Vec::new(),
        steps: count(wire::STEPS)?,
        operator: get(wire::OPERATOR)?,
        free0: get(wire::FREE0)?,
        mass0: get(wire::MASS0)?,
    })
}

/// Ties matching interface points: each point of a later side that coincides with a point of
/// an earlier side gets one multiplier per component (+ on the earlier side, − on the later:
/// λ is the force on the earlier one). Every point must be tied exactly once. Returns the
/// multiplier count and each side's ids and signs per local unknown.
#[allow(clippy::type_complexity)]
fn tie(
    names: &[String],
    meshes: &[Option<InterfaceMesh>],
    setups: &[SideSetup],
) -> Result<(usize, Vec<Vec<usize>>, Vec<Vec<f64>>), String> {
    let pts: Vec<&[[f64; 3]]> = meshes
        .iter()
        .map(|m| m.as_ref().map_or(&[][..], |m| m.positions.as_slice()))
        .collect();
    let comps: Vec<usize> = setups
        .iter()
        .zip(&pts)
        .map(|(s, p)| s.free0.len() / p.len().max(1))
        .collect();
    let extent = pts
        .iter()
        .flat_map(|p| p.iter())
        .flat_map(|x| x.iter())
        .fold(1.0f64, |m, x| m.max(x.abs()));
    let tol = MATCH_TOLERANCE * extent;
    let same = |a: &[f64; 3], b: &[f64; 3]| (0..3).all(|d| (a[d] - b[d]).abs() <= tol);
    let mut ids: Vec<Vec<Option<usize>>> =
        setups.iter().map(|s| vec![None; s.free0.len()]).collect();
    let mut signs: Vec<Vec<f64>> = setups.iter().map(|s| vec![0.0; s.free0.len()]).collect();
    let mut n = 0;
    for i in 1..pts.len() {
        for (p, x) in pts[i].iter().enumerate() {
            let hit = (0..i).find_map(|j| pts[j].iter().position(|y| same(x, y)).map(|q| (j, q)));
            let Some((j, q)) = hit else { continue };
            if comps[i] != comps[j] {
                return Err(format!(
                    "sides '{}' and '{}' have {} and {} unknowns per interface point",
                    names[j], names[i], comps[j], comps[i]
                ));
            }
            for d in 0..comps[i] {
                let (a, b) = (q * comps[j] + d, p * comps[i] + d);
                if ids[j][a].is_some() || ids[i][b].is_some() {
                    return Err(format!(
                        "interface point {x:?} is shared by more than two sides"
                    ));
                }
                ids[j][a] = Some(n);
                ids[i][b] = Some(n);
                signs[j][a] = 1.0;
                signs[i][b] = -1.0;
                n += 1;
            }
        }
    }
    let mut out = Vec::with_capacity(ids.len());
    for (i, v) in ids.into_iter().enumerate() {
        let mut row = Vec::with_capacity(v.len());
        for (k, id) in v.into_iter().enumerate() {
            let p = k / comps[i].max(1);
            row.push(id.ok_or_else(|| {
                format!(
                    "interface point {:?} of side '{}' matches no point of another side",
                    pts[i].get(p).copied().unwrap_or_default(),
                    names[i]
                )
            })?);
        }
        out.push(row);
    }
    Ok((n, out, signs))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(xs: &[f64]) -> Option<InterfaceMesh> {
        Some(InterfaceMesh::points(
            xs.iter().map(|&x| [x, 0.0, 0.0]).collect(),
        ))
    }

    fn setup(dofs: usize) -> SideSetup {
        SideSetup {
            ids: Vec::new(),
            signs: Vec::new(),
            steps: 1,
            operator: vec![0.0; dofs * dofs],
            free0: vec![0.0; dofs],
            mass0: vec![0.0; dofs * dofs],
        }
    }

    #[test]
    fn a_chain_of_three_ties_each_cut_once_with_opposite_signs() {
        // a | b | c with b's interface holding both of its ends (x = 1 and x = 2), listed
        // right end first: each cut gets one multiplier, + on the earlier side.
        let names: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        let meshes = [mesh(&[1.0]), mesh(&[2.0, 1.0]), mesh(&[2.0])];
        let (n, ids, signs) = tie(&names, &meshes, &[setup(1), setup(2), setup(1)]).unwrap();
        assert_eq!(n, 2);
        assert_eq!(ids, vec![vec![0], vec![1, 0], vec![1]]);
        assert_eq!(signs, vec![vec![1.0], vec![1.0, -1.0], vec![-1.0]]);
    }

    #[test]
    fn two_components_per_point_tie_per_component() {
        let names: Vec<String> = ["a", "b"].iter().map(|s| s.to_string()).collect();
        let (n, ids, signs) = tie(
            &names,
            &[mesh(&[0.0, 1.0]), mesh(&[1.0, 0.0])],
            &[setup(4), setup(4)],
        )
        .unwrap();
        assert_eq!(n, 4);
        assert_eq!(ids, vec![vec![2, 3, 0, 1], vec![0, 1, 2, 3]]);
        assert_eq!(signs[1], vec![-1.0; 4]);
    }

    #[test]
    fn an_untied_or_thrice_shared_point_is_refused_by_name() {
        let names: Vec<String> = ["a", "b", "c"].iter().map(|s| s.to_string()).collect();
        let e = tie(
            &names[..2],
            &[mesh(&[1.0]), mesh(&[1.5])],
            &[setup(1), setup(1)],
        )
        .unwrap_err();
        assert!(
            e.contains("side 'a'") && e.contains("matches no point"),
            "{e}"
        );
        let e = tie(
            &names,
            &[mesh(&[1.0]), mesh(&[1.0]), mesh(&[1.0])],
            &[setup(1), setup(1), setup(1)],
        )
        .unwrap_err();
        assert!(e.contains("more than two sides"), "{e}");
    }
}
