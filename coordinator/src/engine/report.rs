//! A node's report of one window as the recording's JSON (`/cosim/node/<name>`): the
//! report's own quantities and its scalars, dotted names nested.

use protocol::StepReport;

/// A node's report of one window as recorded on `/cosim/node/<name>` (schema
/// `cosim.NodeReport`): the window, its end time, the report's quantities and its named
/// scalars as keys of their own (a scalar named like a quantity replaces it). Written
/// straight from the report, without an intermediate `Value`.
pub(crate) struct NodeReportDoc<'a> {
    pub(super) window: u64,
    pub(super) time: f64,
    pub(super) r: &'a StepReport,
    /// How `r`'s scalars are recorded ([`RecordPlan::update`]d for `r`).
    pub(super) plan: &'a RecordPlan,
}

/// How a node's scalars are recorded (each alone, or a vector's components as one key),
/// worked out when its list of names changes and kept across windows: the rule of
/// [`vector`] takes a pass over the scalars per name, which for a node of a few hundred
/// scalars would cost a millisecond a window (measured here: 0.83 ms a window for 320
/// scalars, 59 µs with the plan, serialising included).
#[derive(Debug, Default)]
pub(crate) struct RecordPlan {
    names: Vec<String>,
    slots: Vec<Slot>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    /// Recorded under its own name (or nested, for a dotted name).
    Alone,
    /// The `_x` of a vector: the indices of its components, how many.
    Vector([usize; 3], usize),
    /// A later component, written with the `_x`.
    Component,
}

impl RecordPlan {
    /// Make the plan fit `r`'s scalars: nothing to do (and no allocation) while the names
    /// are those of the last window.
    pub(crate) fn update(&mut self, r: &StepReport) {
        let same = self.names.len() == r.scalars.len()
            && self.names.iter().zip(&r.scalars).all(|(a, (b, _))| a == b);
        if same {
            return;
        }
        self.names = r.scalars.iter().map(|(n, _)| n.clone()).collect();
        let is_key = |k: &str| BUILTIN_KEYS.contains(&k) || r.scalars.iter().any(|(n, _)| n == k);
        self.slots = r
            .scalars
            .iter()
            .map(|(name, _)| match vector(&r.scalars, name, is_key) {
                Some(Part::First(at, n)) => Slot::Vector(at, n),
                Some(Part::Later) => Slot::Component,
                None => Slot::Alone,
            })
            .collect();
    }

    /// Whether the plan was made for `r`'s names.
    fn fits(&self, r: &StepReport) -> bool {
        self.slots.len() == r.scalars.len()
    }
}

/// The keys a node report has besides its named scalars.
pub(super) const BUILTIN_KEYS: [&str; 13] = [
    "window",
    "time",
    "kinetic_energy",
    "internal_energy",
    "external_work",
    "interface_work",
    "momentum",
    "momentum_gross",
    "external_impulse",
    "interface_impulse",
    "substeps",
    "wall_s",
    "coupling_wait_s",
];

impl<'a> NodeReportDoc<'a> {
    /// Whether `k` is a key of the document besides the scalars' own (a built-in quantity,
    /// or a scalar's name): what a dotted name may not nest under.
    fn is_key(&self, k: &str) -> bool {
        BUILTIN_KEYS.contains(&k) || self.r.scalars.iter().any(|(n, _)| n == k)
    }

    /// The leaf names (dotted paths) the document records for its scalars, one per scalar:
    /// its own name, or for a vector's component the vector's (what the recorder checks its
    /// channel's schema against, without serialising).
    pub(crate) fn scalar_keys(&self) -> impl Iterator<Item = &'a str> + '_ {
        debug_assert!(self.plan.fits(self.r));
        self.r
            .scalars
            .iter()
            .zip(&self.plan.slots)
            .map(|((name, _), slot)| match slot {
                Slot::Alone => name.as_str(),
                Slot::Vector(..) | Slot::Component => &name[..name.len() - 2],
            })
    }
}

impl serde::Serialize for NodeReportDoc<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let r = self.r;
        let mut m = s.serialize_map(None)?;
        let shadowed = |k: &str| r.scalars.iter().any(|(n, _)| n == k);
        macro_rules! put {
            ($k:expr, $v:expr) => {
                if !shadowed($k) {
                    m.serialize_entry($k, $v)?;
                }
            };
        }
        put!("window", &self.window);
        put!("time", &self.time);
        put!("kinetic_energy", &r.kinetic_energy);
        put!("internal_energy", &r.internal_energy);
        put!("external_work", &r.external_work);
        put!("interface_work", &r.interface_work);
        put!("momentum", &r.momentum);
        put!("momentum_gross", &r.momentum_gross);
        put!("external_impulse", &r.external_impulse);
        put!("interface_impulse", &r.interface_impulse);
        put!("substeps", &r.substeps);
        put!("wall_s", &r.wall_s);
        put!("coupling_wait_s", &r.coupling_wait_s);
        // A dotted name is recorded nested (`point1.pressure` as `{"point1": {"pressure": …}}`,
        // Foxglove's path syntax), unless a prefix of it is a key itself.
        let is_key = |k: &str| self.is_key(k);
        debug_assert!(self.plan.fits(r));
        for ((name, val), slot) in r.scalars.iter().zip(&self.plan.slots) {
            if crate::nest::nests(name, is_key) {
                continue;
            }
            // A vector is one key, `K: [x, y, z]`, as `momentum` is (see [`vector`]).
            match *slot {
                Slot::Vector(at, n) => {
                    let v = [r.scalars[at[0]].1, r.scalars[at[1]].1, r.scalars[at[2]].1];
                    m.serialize_entry(&name[..name.len() - 2], &v[..n])?
                }
                Slot::Component => {}
                Slot::Alone => m.serialize_entry(name, val)?,
            }
        }
        crate::nest::Group {
            scalars: &r.scalars,
            prefix: "",
            is_key: &is_key,
        }
        .entries(&mut m)?;
        m.end()
    }
}

/// What a scalar is to the vector it belongs to (see [`vector`]).
enum Part {
    /// The `_x` component (the vector's name is the name less `_x`): the indices of its
    /// components among the scalars, how many (2 or 3).
    First([usize; 3], usize),
    /// The `_y` or `_z` component, written with the `_x` one.
    Later,
}

/// One name for a vector everywhere: a node's scalars `K_x`, `K_y` (and `K_z`) are recorded
/// as one key `K` holding `[x, y, z]` (or `[x, y]`), as a report's `momentum` is, so the
/// recording's schema lists the vector once, Foxglove plots `/cosim/node/NODE.K[0]`, and the
/// readers give the same (windows, n) array `K` in NPZ and Python and the columns `K_x`, `K_y`,
/// `K_z` in the flat tables that they give for `momentum`. The rule is the readers' own for
/// recordings made before it (`export::fold_vectors`): the components are consecutive from
/// `_x` (at least `_x` and `_y`), and `K` has no dot, is not itself a key of the report
/// (`is_key`) and names no nested object (`K.p` among the scalars) — otherwise the scalars
/// stay as they are. `None` for a scalar that is no vector's component. Compares names in
/// place, a pass over the scalars per name: [`RecordPlan`] runs it only when a node's names
/// change.
fn vector<'a>(
    scalars: &'a [(String, f64)],
    name: &'a str,
    is_key: impl Fn(&str) -> bool,
) -> Option<Part> {
    const AXES: [&str; 3] = ["_x", "_y", "_z"];
    let axis = AXES.iter().position(|a| name.ends_with(a))?;
    let base = &name[..name.len() - 2];
    // `K` must be free: not a key of the report, and not the object of dotted names `K.…`
    let nested =
        |n: &str| n.len() > base.len() && n.starts_with(base) && n[base.len()..].starts_with('.');
    if base.is_empty()
        || base.contains('.')
        || is_key(base)
        || scalars.iter().any(|(n, _)| nested(n))
    {
        return None;
    }
    let index = |a: &str| {
        scalars
            .iter()
            .position(|(n, _)| n.len() == name.len() && n.starts_with(base) && n.ends_with(a))
    };
    let mut at = [0; 3];
    let mut n = 0;
    for (d, a) in AXES.iter().enumerate() {
        match index(a) {
            Some(i) => at[d] = i,
            None => break,
        }
        n += 1;
    }
    match (n, axis) {
        (0 | 1, _) => None,
        (_, 0) => Some(Part::First(at, n)),
        (_, a) if a < n => Some(Part::Later),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn plan_for(r: &StepReport) -> RecordPlan {
        let mut plan = RecordPlan::default();
        plan.update(r);
        plan
    }

    fn report() -> StepReport {
        StepReport {
            kinetic_energy: 1.5,
            internal_energy: 2.5,
            external_work: 3.0,
            interface_work: -0.25,
            momentum: [0.1, -0.2, 0.3],
            momentum_gross: 4.0,
            external_impulse: [1.0, 0.0, 0.0],
            interface_impulse: [0.0, 2.0, 0.0],
            substeps: 3,
            wall_s: 1e-5,
            coupling_wait_s: 2e-6,
            scalars: vec![
                ("tip_displacement".into(), 7e-4),
                ("internal_energy".into(), 9.0),
                ("probe".into(), f64::NAN),
            ],
            ..Default::default()
        }
    }

    /// A node's `K_x`, `K_y` (`K_z`) are recorded as one vector `K`; scalars that are not a
    /// whole vector's components stay as they are; the readers' tables and the plots' series
    /// are what they were for the components.
    #[test]
    fn a_vector_is_recorded_as_one_key() {
        let mut r = StepReport::default();
        let names = [
            ("force_x", 1.0),
            ("force_y", -2.0),
            ("force_z", f64::NAN),
            ("crack_tip_x", 0.25),
            ("crack_tip_y", 0.5),
            ("lonely_x", 3.0),
            ("gap_x", 4.0),
            ("gap_z", 5.0),
            ("momentum_x", 6.0),
            ("point1.v_x", 7.0),
            ("point1.v_y", 8.0),
            ("twice", 9.0),
            ("twice_x", 10.0),
            ("twice_y", 11.0),
            ("probe.pressure", 12.0),
            ("probe_x", 13.0),
            ("probe_y", 14.0),
        ];
        r.scalars = names.iter().map(|(n, v)| (n.to_string(), *v)).collect();
        let plan = plan_for(&r);
        let doc = NodeReportDoc {
            window: 2,
            time: 1e-3,
            r: &r,
            plan: &plan,
        };
        let v: serde_json::Value =
            serde_json::from_slice(&serde_json::to_vec(&doc).expect("serialize")).expect("parse");
        assert_eq!(v["force"], json!([1.0, -2.0, null]));
        assert_eq!(v["crack_tip"], json!([0.25, 0.5]));
        for gone in [
            "force_x",
            "force_y",
            "force_z",
            "crack_tip_x",
            "crack_tip_y",
        ] {
            assert!(v.get(gone).is_none(), "{gone}");
        }
        // one component, components not from x on, a key of the report (`momentum`), a
        // dotted name (nested instead), a name that is itself a scalar, a name of nested
        // scalars: left alone
        for (k, x) in [
            ("lonely_x", 3.0),
            ("gap_x", 4.0),
            ("gap_z", 5.0),
            ("momentum_x", 6.0),
            ("twice", 9.0),
            ("twice_x", 10.0),
            ("twice_y", 11.0),
            ("probe_x", 13.0),
            ("probe_y", 14.0),
        ] {
            assert_eq!(v[k], json!(x), "{k}");
        }
        // `probe` is the object of `probe.pressure`, so `probe_x`, `probe_y` stay apart
        assert_eq!(v["probe"], json!({ "pressure": 12.0 }));
        assert_eq!(v["point1"], json!({ "v_x": 7.0, "v_y": 8.0 }));
        // the names the recorder checks its schema with are the document's leaves
        let mut leaves = Vec::new();
        crate::nest::for_each_leaf(v.as_object().unwrap(), &mut |k, _| {
            leaves.push(k.to_string())
        });
        for k in doc.scalar_keys() {
            assert!(leaves.iter().any(|l| l == k), "{k} is not recorded");
        }
        assert!(doc.scalar_keys().any(|k| k == "force"));
        assert!(!doc.scalar_keys().any(|k| k == "force_y"));
        assert!(v["momentum"].is_array());
        // the plots' series from the recorded vector are the live report's components
        let flat = serde_json::Value::Object(crate::nest::flatten(v.as_object().unwrap()));
        let mut recorded = crate::plot::Histories::new();
        crate::plot::add_report(&mut recorded, "n", &flat);
        let mut live = crate::plot::Histories::new();
        crate::plot::add_node_report(&mut live, "n", 1e-3, &r, 1);
        assert_eq!(recorded, live);
        assert_eq!(live["n"]["crack_tip_y"], vec![(1e-3, 0.5)]);
    }

    /// `BUILTIN_KEYS` (what a dotted scalar name may not nest under) lists exactly the keys
    /// the serializer writes besides the scalars: a key added to one and not the other fails.
    #[test]
    fn builtin_keys_are_the_keys_of_a_report_without_scalars() {
        let r = StepReport::default();
        let plan = plan_for(&r);
        let doc = NodeReportDoc {
            window: 1,
            time: 0.0,
            r: &r,
            plan: &plan,
        };
        let v = serde_json::to_value(&doc).expect("serialize");
        let mut got: Vec<&str> = v
            .as_object()
            .expect("an object")
            .keys()
            .map(String::as_str)
            .collect();
        let mut want = BUILTIN_KEYS.to_vec();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want);
    }

    /// The record written straight from the report is the document the coordinator built
    /// with `json!` before (written out here as it did: quantities, then the scalars set over
    /// them), and gives the same plot histories.
    #[test]
    fn node_report_doc_is_the_json_report() {
        let mut r = report();
        r.scalars.push(("point1.pressure".into(), 2e5));
        r.scalars.push(("point1.density".into(), 1.2));
        let mut old = json!({
            "window": 7, "time": 3.5e-6,
            "kinetic_energy": r.kinetic_energy, "internal_energy": r.internal_energy,
            "external_work": r.external_work, "interface_work": r.interface_work,
            "momentum": r.momentum, "momentum_gross": r.momentum_gross,
            "external_impulse": r.external_impulse,
            "interface_impulse": r.interface_impulse,
            "substeps": r.substeps, "wall_s": r.wall_s,
            "coupling_wait_s": r.coupling_wait_s,
        });
        for (name, val) in &r.scalars {
            old[name] = json!(val);
        }
        let plan = plan_for(&r);
        let doc = NodeReportDoc {
            window: 7,
            time: 3.5e-6,
            r: &r,
            plan: &plan,
        };
        let bytes = serde_json::to_vec(&doc).expect("serialize");
        let new: serde_json::Value = serde_json::from_slice(&bytes).expect("parse");
        // the dotted names nested as Foxglove addresses them, the same document flattened
        assert_eq!(new["point1"], json!({ "pressure": 2e5, "density": 1.2 }));
        let flat = crate::nest::flatten(new.as_object().expect("an object"));
        assert_eq!(serde_json::Value::Object(flat), old);
        assert_eq!(new["internal_energy"], json!(9.0));
        assert!(new["probe"].is_null());
        let mut h_old = crate::plot::Histories::new();
        crate::plot::add_report(&mut h_old, "left", &old);
        let mut h_new = crate::plot::Histories::new();
        crate::plot::add_node_report(&mut h_new, "left", 3.5e-6, &r, 10);
        assert_eq!(h_new, h_old);
        // kinetic, internal (the scalar), external and interface work, gross momentum,
        // three momentum components, the tip displacement, the two point values; not the
        // NaN probe
        assert_eq!(h_new["left"].len(), 11, "{:?}", h_new["left"].keys());
    }
}
