//! What a deadlock is waiting for: when every running node has been blocked on a peer's input
//! for the stall timeout, the coordinator names the messages that are missing and who owes
//! them. It sees every peer `Fields` on its way (it records them), so it knows the last window
//! each side sent on each coupling; a node's bindings say which window of its peer's output
//! each of its windows consumes (docs/architecture.md, "Schedules").

use protocol::Binding;
use protocol::scheme;

/// One input a waiting node lacks.
#[derive(Debug, Clone, PartialEq)]
pub struct Missing {
    /// The node that owes it.
    pub sender: String,
    /// Its description, e.g. `'left' waits for the Fields of window 3 on coupling 'mid' from
    /// 'right', which sent up to window 2`.
    pub what: String,
}

/// The inputs that node `node`, working on window `window` (0: set-up) with `bindings`, has
/// not had: `last(coupling, sender)` is the last window of `Fields` the coordinator saw
/// `sender` send on `coupling` (None: none yet), `until(coupling)` the window before which
/// the coupling ended (None: it goes on), after which only earlier outputs are consumed.
/// Lagrange sides wait for the coordinator's own multipliers and are left out.
pub fn missing(
    node: &str,
    window: u64,
    bindings: &[Binding],
    last: impl Fn(&str, &str) -> Option<u64>,
    until: impl Fn(&str) -> Option<u64>,
) -> Vec<Missing> {
    let mut v = Vec::new();
    for b in bindings {
        if b.peer == scheme::lagrange::wire::PEER {
            continue;
        }
        let ended = until(&b.coupling);
        let Some(k) = scheme::of(b.kind).input_window(b.role, b.input_lag, ended, window) else {
            continue;
        };
        let sent = last(&b.coupling, &b.peer);
        if sent.is_some_and(|s| s >= k) {
            continue;
        }
        let label = |w: u64| {
            if w == 0 {
                "the set-up (window 0)".to_string()
            } else {
                format!("window {w}")
            }
        };
        let had = match sent {
            Some(s) => format!("which sent up to {}", label(s)),
            None => "which has sent none".to_string(),
        };
        v.push(Missing {
            sender: b.peer.clone(),
            what: format!(
                "'{node}' waits for the Fields of {} on coupling '{}' from '{}', {had}",
                label(k),
                b.coupling,
                b.peer
            ),
        });
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::{CouplingKind, Role};

    fn binding(role: Role, peer: &str, lag: u64) -> Binding {
        Binding {
            coupling: "mid".into(),
            kind: CouplingKind::Kinematic,
            interface: "tip".into(),
            role,
            peer: peer.into(),
            peer_interface: "root".into(),
            sends: vec![],
            receives: vec![],
            input_lag: lag,
        }
    }

    #[test]
    fn a_withheld_force_is_named_with_its_sender_and_window() {
        // The split bar, serial: the driver's window 4 consumes the responder's window 3,
        // which never came (the responder stopped sending after window 2).
        let driver = [binding(Role::Driver, "right", 1)];
        let m = missing(
            "left",
            4,
            &driver,
            |c, s| (c == "mid" && s == "right").then_some(2),
            |_| None,
        );
        assert_eq!(
            m,
            vec![Missing {
                sender: "right".into(),
                what: "'left' waits for the Fields of window 3 on coupling 'mid' from 'right', which sent up to window 2".into()
            }]
        );
        // Had it come, nothing would be missing.
        assert!(missing("left", 4, &driver, |_, _| Some(3), |_| None).is_empty());
        // Nor if the coupling ended before window 3: the peer owes nothing after it.
        assert!(missing("left", 4, &driver, |_, _| Some(2), |_| Some(3)).is_empty());
    }

    #[test]
    fn the_set_up_and_a_silent_peer_are_said_as_such() {
        // At set-up the driver waits for its responder's set-up fields.
        let driver = [binding(Role::Driver, "right", 1)];
        let m = missing("left", 0, &driver, |_, _| None, |_| None);
        assert_eq!(m.len(), 1);
        assert!(
            m[0].what.ends_with(
                "the Fields of the set-up (window 0) on coupling 'mid' from 'right', which has sent none"
            ),
            "{m:?}"
        );
        // The serial responder consumes its driver's motion of the same window.
        let responder = [binding(Role::Responder, "left", 0)];
        let m = missing("right", 5, &responder, |_, _| Some(4), |_| None);
        assert_eq!(m[0].sender, "left");
        assert!(
            m[0].what
                .contains("window 5 on coupling 'mid' from 'left', which sent up to window 4")
        );
        // The responder's set-up needs nothing.
        assert!(missing("right", 0, &responder, |_, _| None, |_| None).is_empty());
    }

    #[test]
    fn a_lagrange_side_waits_for_the_coordinator_and_is_left_out() {
        let mut b = binding(Role::Driver, scheme::lagrange::wire::PEER, 1);
        b.kind = CouplingKind::Lagrange;
        assert!(missing("one", 3, &[b], |_, _| None, |_| None).is_empty());
    }
}
