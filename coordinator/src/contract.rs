//! The bindings' contract on the data each node sends (PROTOCOL.md 4.2 and 5.3, `Field`):
//! per node and coupling, which fields its `Fields` must and may hold, at how many points and
//! with how many components each. Worked out once before set-up from the couplings and the
//! described interfaces; every `Fields` the coordinator receives is held against it as it is
//! read, comparing names and counts, so the window loop allocates nothing for it (only a
//! breach is written out). A breach names the sender — the node at fault, never its peer —
//! the coupling, the window, the field, and what was expected against what came.
//!
//! Lagrange sides are not covered here: their vectors are sized by the interface problem,
//! which the coordinator's hub checks as it reads them (`protocol::scheme::lagrange::Hub`).

use crate::case::{Case, CouplingConfig, Schedule};
use protocol::message::{CouplingKind, Role};
use protocol::scheme;

/// The point count and the fields provided of `member`'s interface, as validation read them
/// from its node's description (None: a remote node not described before the run).
fn described<'c>(case: &'c Case, member: &(String, String)) -> Option<(u64, &'c [String])> {
    let n = case.nodes.iter().find(|n| n.name == member.0)?;
    let pos = n.interfaces.as_ref()?.iter().position(|i| *i == member.1)?;
    Some((*n.points.get(pos)?, n.fields.get(pos)?.0.as_slice()))
}

/// One field a sender's contract names.
#[derive(Debug, Clone)]
struct Expected {
    name: String,
    /// Values per point (None: a name outside `scheme::FIELD_COMPONENTS`; its sender says).
    components: Option<u32>,
    /// Required in every window from 1 on.
    every_window: bool,
    /// Required at set-up (window 0).
    at_setup: bool,
}

/// What one node's `Fields` on one coupling must hold.
#[derive(Debug, Clone)]
pub struct Contract {
    /// The sender and its interface.
    pub node: String,
    pub interface: String,
    pub coupling: String,
    kind: CouplingKind,
    role: Role,
    /// The driver's (node, interface): its point count sizes the data both ways.
    driver: (String, String),
    /// Points of the driver's interface (data travel in the driver's layout); None until
    /// known (a remote driver before its `Describe`).
    points: Option<u64>,
    fields: Vec<Expected>,
}

/// How every breach's text begins (after it: the window, the coupling, what is wrong).
pub const BREACH: &str = "Fields of ";

/// Which of `fields` a `Fields` message held, as bits: a contract names at most this many
/// fields that are checked for presence (those after it are checked for size only).
const TRACKED: usize = 64;

impl Contract {
    /// The contract of the side with `role` of coupling `c` (not a lagrange one) under the
    /// serial or parallel schedule; `points` is the driver interface's point count if known.
    ///
    /// Each window from 1 on the side sends its `Binding.sends`, except where the scheme lets
    /// loads be absent (the immersed fluid). At set-up it sends its scheme's set-up fields
    /// (the kinematic responder's mass and stiffness), and its window fields too when its peer
    /// reads its set-up output as the input of window 1 (the kinematic driver takes the
    /// responder's set-up force at a lag of 1). It may add any field its interface
    /// `provides` by its description (a joint's moment beside its force); nothing else.
    pub fn of(
        c: &CouplingConfig,
        role: Role,
        serial: bool,
        points: Option<u64>,
        provides: &[String],
    ) -> Contract {
        let sch = scheme::of(c.kind);
        let (sends, (node, interface)) = match role {
            Role::Driver => (&c.driver_fields, &c.driver),
            Role::Responder => (&c.responder_fields, &c.responder),
        };
        let peer = match role {
            Role::Driver => Role::Responder,
            Role::Responder => Role::Driver,
        };
        let optional = sch.loads_may_be_absent() && role == Role::Responder;
        let peer_reads_setup =
            sch.input_window(peer, sch.input_lag(peer, serial), None, 1) == Some(0);
        let mut fields: Vec<Expected> = sends
            .iter()
            .map(|n| Expected {
                name: n.clone(),
                components: scheme::components_of(n),
                every_window: !optional,
                at_setup: !optional && peer_reads_setup,
            })
            .collect();
        for n in sch.setup_sends(role) {
            match fields.iter_mut().find(|f| f.name == *n) {
                Some(f) => f.at_setup = true,
                None => fields.push(Expected {
                    name: n.to_string(),
                    components: scheme::components_of(n),
                    every_window: false,
                    at_setup: true,
                }),
            }
        }
        let mut contract = Contract {
            node: node.clone(),
            interface: interface.clone(),
            coupling: c.name.clone(),
            kind: c.kind,
            role,
            driver: c.driver.clone(),
            points,
            fields,
        };
        contract.allow(provides);
        contract
    }

    /// Let the sender add the fields `provides` (its described interface's) to those it must
    /// send.
    fn allow(&mut self, provides: &[String]) {
        for n in provides {
            if !self.fields.iter().any(|f| f.name == *n) {
                self.fields.push(Expected {
                    name: n.clone(),
                    components: scheme::components_of(n),
                    every_window: false,
                    at_setup: false,
                });
            }
        }
    }

    /// The contract of the side with `role` of coupling `c` in `case`, from what validation
    /// read of its nodes' descriptions (a remote node not described before the run: its
    /// [`Contract::learn`] when it joins).
    pub fn in_case(case: &Case, c: &CouplingConfig, role: Role) -> Contract {
        let serial = case.run.schedule == Schedule::Serial;
        let sender = match role {
            Role::Driver => &c.driver,
            Role::Responder => &c.responder,
        };
        let points = described(case, &c.driver).map(|d| d.0);
        let provides = described(case, sender).map(|d| d.1).unwrap_or_default();
        Contract::of(c, role, serial, points, provides)
    }

    /// Node `node` described its interface `d` (a remote node's `Describe`): its points size
    /// the data when it is this contract's driver, and it may send what it provides when it
    /// is the sender.
    pub fn learn(&mut self, node: &str, d: &protocol::message::InterfaceDescription) {
        if self.driver.0 == node && self.driver.1 == d.name {
            self.points = Some(d.points);
        }
        if self.node == node && self.interface == d.name {
            self.allow(&d.provides);
        }
    }

    /// The points every field must have, if known.
    pub fn points(&self) -> Option<u64> {
        self.points
    }

    /// The fields required in window `window` (0: set-up).
    pub fn required(&self, window: u64) -> impl Iterator<Item = &str> {
        self.fields
            .iter()
            .filter(move |f| {
                if window == 0 {
                    f.at_setup
                } else {
                    f.every_window
                }
            })
            .map(|f| f.name.as_str())
    }

    /// The components per point of field `name` by this contract (None: not named here, or a
    /// name whose sender says).
    pub fn components(&self, name: &str) -> Option<u32> {
        self.fields
            .iter()
            .find(|f| f.name == name)
            .and_then(|f| f.components)
    }

    /// Start checking one `Fields` message: hand it each field, then [`Check::finish`].
    pub fn check(&self) -> Check<'_> {
        Check {
            c: self,
            seen: 0,
            breach: None,
        }
    }

    fn names(&self) -> String {
        let v: Vec<&str> = self.fields.iter().map(|f| f.name.as_str()).collect();
        v.join(", ")
    }
}

/// One `Fields` message being checked against a [`Contract`].
pub struct Check<'c> {
    c: &'c Contract,
    seen: u64,
    /// The first breach of a single field, without the window (read after the fields).
    breach: Option<String>,
}

impl Check<'_> {
    /// One field of the message: `values` values, `components` per point.
    pub fn field(&mut self, name: &str, components: u32, values: usize) {
        if self.breach.is_some() {
            return;
        }
        let c = self.c;
        let Some(k) = c.fields.iter().position(|f| f.name == name) else {
            self.breach = Some(format!(
                "field '{name}' is not one its binding sends (it sends: {})",
                c.names()
            ));
            return;
        };
        if k < TRACKED {
            if self.seen & (1 << k) != 0 {
                self.breach = Some(format!("field '{name}' is sent twice"));
                return;
            }
            self.seen |= 1 << k;
        }
        let want = c.fields[k].components;
        if want.is_some_and(|w| w != components) || components == 0 {
            self.breach = Some(format!(
                "field '{name}' has {components} components per point, expected {}",
                want.map_or_else(|| "at least 1".to_string(), |w| w.to_string())
            ));
            return;
        }
        if let Some(p) = c.points
            && values as u64 != p * u64::from(components)
        {
            self.breach = Some(format!(
                "field '{name}' has {values} values, expected {p} points × {components} components = {} (the points of {}'s interface '{}')",
                p * u64::from(components),
                c.driver.0,
                c.driver.1
            ));
        }
    }

    /// The verdict on the message of window `window`: the first breach, named with the
    /// coupling and the window, or a field its window requires that did not come.
    pub fn finish(self, window: u64) -> Result<(), String> {
        let c = self.c;
        let breach = self.breach.or_else(|| {
            let missing: Vec<&str> = c
                .fields
                .iter()
                .enumerate()
                .filter(|&(k, f)| {
                    k < TRACKED
                        && self.seen & (1 << k) == 0
                        && if window == 0 {
                            f.at_setup
                        } else {
                            f.every_window
                        }
                })
                .map(|(_, f)| f.name.as_str())
                .collect();
            (!missing.is_empty()).then(|| {
                format!(
                    "field{} '{}' missing",
                    if missing.len() > 1 { "s" } else { "" },
                    missing.join("', '")
                )
            })
        });
        match breach {
            None => Ok(()),
            Some(b) => Err(format!(
                "{BREACH}{} on coupling '{}' break its binding ({} {}; PROTOCOL.md 4.2, 5.3): {b}",
                if window == 0 {
                    "the set-up (window 0)".to_string()
                } else {
                    format!("window {window}")
                },
                c.coupling,
                c.kind.as_str(),
                match c.role {
                    Role::Driver => "driver",
                    Role::Responder => "responder",
                },
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinematic() -> CouplingConfig {
        crate::case::split_bar_coupling()
    }

    fn verdict(c: &Contract, window: u64, fields: &[(&str, u32, usize)]) -> Result<(), String> {
        let mut k = c.check();
        for &(n, comps, values) in fields {
            k.field(n, comps, values);
        }
        k.finish(window)
    }

    #[test]
    fn the_kinematic_responder_sends_its_force_mass_and_stiffness_at_set_up() {
        let r = Contract::of(&kinematic(), Role::Responder, true, Some(1), &[]);
        let setup: Vec<&str> = r.required(0).collect();
        assert_eq!(setup, ["force", "mass", "stiffness"]);
        assert_eq!(r.required(1).collect::<Vec<_>>(), ["force"]);
        let ok = [("mass", 1, 1), ("stiffness", 1, 1), ("force", 3, 3)];
        assert_eq!(verdict(&r, 0, &ok), Ok(()));
        // The stale set-up fields may come again in a window; the force must.
        assert_eq!(verdict(&r, 4, &ok), Ok(()));
        let e = verdict(&r, 0, &ok[..2]).unwrap_err();
        assert!(
            e.contains("set-up (window 0)") && e.contains("'force' missing"),
            "{e}"
        );
        assert!(e.contains("coupling 'mid'"), "{e}");
    }

    #[test]
    fn the_serial_driver_owes_nothing_at_set_up() {
        let d = Contract::of(&kinematic(), Role::Driver, true, Some(2), &[]);
        assert_eq!(d.required(0).count(), 0);
        assert_eq!(d.required(3).collect::<Vec<_>>(), ["position", "velocity"]);
        assert_eq!(verdict(&d, 0, &[]), Ok(()));
    }

    #[test]
    fn a_wrong_component_count_point_count_or_name_is_a_breach() {
        let r = Contract::of(&kinematic(), Role::Responder, true, Some(2), &[]);
        let e = verdict(&r, 7, &[("force", 1, 2)]).unwrap_err();
        assert!(
            e.contains("window 7") && e.contains("'force' has 1 components per point, expected 3"),
            "{e}"
        );
        let e = verdict(&r, 7, &[("force", 3, 3)]).unwrap_err();
        assert!(
            e.contains("3 values, expected 2 points × 3 components = 6"),
            "{e}"
        );
        let e = verdict(&r, 7, &[("forse", 3, 6)]).unwrap_err();
        assert!(e.contains("'forse' is not one its binding sends"), "{e}");
        // A field its interface provides may come besides, sized like the rest.
        let moment = ["force".to_string(), "moment".to_string()];
        let j = Contract::of(&kinematic(), Role::Responder, true, Some(2), &moment);
        assert_eq!(verdict(&j, 7, &[("force", 3, 6), ("moment", 3, 6)]), Ok(()));
        assert!(verdict(&j, 7, &[("force", 3, 6), ("moment", 1, 2)]).is_err());
        let e = verdict(&r, 7, &[("force", 3, 6), ("force", 3, 6)]).unwrap_err();
        assert!(e.contains("sent twice"), "{e}");
    }

    #[test]
    fn the_immersed_fluid_may_send_nothing_but_what_it_sends_is_sized() {
        let mut c = kinematic();
        c.kind = CouplingKind::Immersed;
        let r = Contract::of(&c, Role::Responder, true, None, &[]);
        assert_eq!(verdict(&r, 0, &[]), Ok(()));
        assert_eq!(verdict(&r, 5, &[]), Ok(()));
        // Sizes are checked once the driver's points are known.
        assert_eq!(verdict(&r, 5, &[("force", 3, 9)]), Ok(()));
        let mut r = r;
        r.learn(
            "left",
            &protocol::message::InterfaceDescription {
                name: "tip".into(),
                points: 4,
                provides: Vec::new(),
                accepts: Vec::new(),
            },
        );
        assert!(verdict(&r, 5, &[("force", 3, 9)]).is_err());
        assert_eq!(verdict(&r, 5, &[("force", 3, 12)]), Ok(()));
    }
}
