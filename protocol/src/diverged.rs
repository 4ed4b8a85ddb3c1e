//! The divergence rule (PROTOCOL.md, "Divergence"): a node never sends a non-finite value.
//! Before its coupling data or its window report leave, the participant runtime looks for a
//! NaN or an infinity in them (they are in cache then, so the scan is cheap); if it finds
//! one, the node sends `Failed` with a reason of the form `diverged: window <k>: <what>`
//! instead, and the coordinator ends the run with the status `diverged`, naming the node,
//! the window and the quantity. The peer never receives the bad values, so it is never the
//! one blamed for them.
//!
//! The coordinator applies the same report check to every `Done` it receives (a node written
//! without this runtime may not check itself), and bounds the run's total energy besides.

use crate::message::{Fields, StepReport};

/// How every divergence reason starts, in a `Failed` message and in the coordinator's
/// messages.
pub const PREFIX: &str = "diverged: ";

/// A non-finite value a node was about to send: in which window, and what it was.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("diverged: window {window}: {what}")]
pub struct Divergence {
    pub window: u64,
    /// The quantity and where it was: `field 'velocity' on coupling 'mid' is NaN at point 3
    /// (component 0 of 3)`, `kinetic_energy is inf`.
    pub what: String,
}

impl Divergence {
    /// Reads a `Failed` reason written by [`Divergence`]'s `Display` (a node's own words may
    /// follow, e.g. where its log is); `None` for any other failure.
    pub fn parse(reason: &str) -> Option<Divergence> {
        let rest = reason.strip_prefix(PREFIX)?.strip_prefix("window ")?;
        let (window, what) = rest.split_once(": ")?;
        Some(Divergence {
            window: window.parse().ok()?,
            what: what.to_string(),
        })
    }
}

/// `NaN`, `inf` or `-inf`, as a message names them.
fn shown(v: f64) -> &'static str {
    if v.is_nan() {
        "NaN"
    } else if v > 0.0 {
        "inf"
    } else {
        "-inf"
    }
}

/// The first non-finite value of `f`'s fields, if any.
pub fn check_fields(f: &Fields) -> Result<(), Divergence> {
    for field in &f.fields {
        if let Some(j) = field.values.iter().position(|v| !v.is_finite()) {
            let c = field.components.max(1) as usize;
            return Err(Divergence {
                window: f.window,
                what: format!(
                    "field '{}' on coupling '{}' is {} at point {} (component {} of {c})",
                    field.name,
                    f.coupling,
                    shown(field.values[j]),
                    j / c,
                    j % c,
                ),
            });
        }
    }
    Ok(())
}

/// The first non-finite quantity of a window's report that the energy and momentum balance
/// reads (its energies, works, momenta, impulses and dissipated energies). Other named
/// scalars are probes a node may leave undefined (NaN) and are not checked.
pub fn check_report(window: u64, r: &StepReport) -> Result<(), Divergence> {
    let scalars = [
        ("kinetic_energy", r.kinetic_energy),
        ("internal_energy", r.internal_energy),
        ("external_work", r.external_work),
        ("interface_work", r.interface_work),
        ("momentum_gross", r.momentum_gross),
        ("applied_impulse", r.applied_impulse),
    ];
    let vectors = [
        ("momentum", r.momentum),
        ("external_impulse", r.external_impulse),
        ("interface_impulse", r.interface_impulse),
    ];
    let dissipated = r
        .scalars
        .iter()
        .filter(|(n, _)| crate::message::DISSIPATED_SCALARS.contains(&n.as_str()))
        .map(|(n, v)| (n.as_str(), *v));
    let bad = scalars
        .into_iter()
        .chain(dissipated)
        .find(|(_, v)| !v.is_finite())
        .map(|(name, v)| format!("{name} is {}", shown(v)))
        .or_else(|| {
            vectors.iter().find_map(|(name, v)| {
                let d = v.iter().position(|x| !x.is_finite())?;
                Some(format!("{name}[{d}] is {}", shown(v[d])))
            })
        });
    match bad {
        Some(what) => Err(Divergence { window, what }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::Field;

    fn fields(values: Vec<f64>, components: u32) -> Fields {
        Fields {
            coupling: "mid".into(),
            window: 7,
            time: 1.0,
            fields: vec![
                Field {
                    name: "mass".into(),
                    components: 1,
                    values: vec![1.0, 2.0],
                },
                Field {
                    name: "velocity".into(),
                    components,
                    values,
                },
            ],
        }
    }

    #[test]
    fn a_non_finite_field_value_is_named_by_field_point_and_component() {
        assert_eq!(check_fields(&fields(vec![0.0; 9], 3)), Ok(()));
        let mut v = vec![0.0; 9];
        v[7] = f64::NAN;
        let e = check_fields(&fields(v, 3)).unwrap_err();
        assert_eq!(e.window, 7);
        assert_eq!(
            e.what,
            "field 'velocity' on coupling 'mid' is NaN at point 2 (component 1 of 3)"
        );
        let mut v = vec![0.0; 2];
        v[0] = f64::NEG_INFINITY;
        let e = check_fields(&fields(v, 1)).unwrap_err();
        assert_eq!(
            e.what,
            "field 'velocity' on coupling 'mid' is -inf at point 0 (component 0 of 1)"
        );
    }

    #[test]
    fn every_balance_quantity_of_a_report_is_checked_and_probes_are_not() {
        let ok = StepReport {
            scalars: vec![("gap".into(), f64::NAN)],
            ..Default::default()
        };
        assert_eq!(check_report(3, &ok), Ok(()));
        type Spoil = fn(&mut StepReport);
        let cases: [(Spoil, &str); 9] = [
            (|r| r.kinetic_energy = f64::NAN, "kinetic_energy is NaN"),
            (
                |r| r.internal_energy = f64::INFINITY,
                "internal_energy is inf",
            ),
            (|r| r.external_work = f64::NAN, "external_work is NaN"),
            (|r| r.interface_work = f64::NAN, "interface_work is NaN"),
            (|r| r.momentum[2] = f64::NAN, "momentum[2] is NaN"),
            (|r| r.momentum_gross = f64::NAN, "momentum_gross is NaN"),
            (
                |r| r.external_impulse[0] = f64::NEG_INFINITY,
                "external_impulse[0] is -inf",
            ),
            (
                |r| r.interface_impulse[1] = f64::NAN,
                "interface_impulse[1] is NaN",
            ),
            (
                |r| r.scalars.push(("plastic_work".into(), f64::NAN)),
                "plastic_work is NaN",
            ),
        ];
        for (spoil, what) in cases {
            let mut r = ok.clone();
            spoil(&mut r);
            let e = check_report(3, &r).unwrap_err();
            assert_eq!((e.window, e.what.as_str()), (3, what));
        }
    }

    #[test]
    fn a_failed_reason_reads_back_as_the_divergence_it_was() {
        let d = Divergence {
            window: 41,
            what: "kinetic_energy is NaN".into(),
        };
        assert_eq!(Divergence::parse(&d.to_string()), Some(d.clone()));
        let with_log = format!("{d} (its log: out/x/right.log)");
        assert_eq!(
            Divergence::parse(&with_log).map(|d| d.window),
            Some(41),
            "{with_log}"
        );
        assert_eq!(Divergence::parse("solver: bad mass"), None);
        assert_eq!(Divergence::parse("diverged: window x: y"), None);
    }
}
