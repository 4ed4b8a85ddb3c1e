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
        let is_key = |k: &str| BUILTIN_KEYS.contains(&k) || shadowed(k);
        for (name, val) in &r.scalars {
            if !crate::nest::nests(name, is_key) {
                m.serialize_entry(name, val)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

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

    /// `BUILTIN_KEYS` (what a dotted scalar name may not nest under) lists exactly the keys
    /// the serializer writes besides the scalars: a key added to one and not the other fails.
    #[test]
    fn builtin_keys_are_the_keys_of_a_report_without_scalars() {
        let r = StepReport::default();
        let doc = NodeReportDoc {
            window: 1,
            time: 0.0,
            r: &r,
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
        let doc = NodeReportDoc {
            window: 7,
            time: 3.5e-6,
            r: &r,
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
