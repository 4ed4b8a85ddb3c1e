//! What the couplings make of the nodes: each node's bindings, the order of the nodes within
//! a window, the fields each coupling member must provide and accept, and the rule that an
//! interface takes one coupling. Pure functions of the resolved [`Case`].

use super::resolved::{Case, ConfigError, CouplingConfig, Schedule, err};
use protocol::scheme;
use std::collections::BTreeMap;

/// Refuse an interface that two couplings take: each would apply its own loads and count its
/// own interface work, so the run would move and book the same interface twice.
pub(super) fn check_one_coupling_per_interface(
    couplings: &[CouplingConfig],
) -> Result<(), ConfigError> {
    let mut taken: BTreeMap<&(String, String), (usize, &str)> = BTreeMap::new();
    for (i, c) in couplings.iter().enumerate() {
        for (key, m) in c.keyed_members() {
            if let Some((j, other)) = taken.insert(m, (i, &c.name)) {
                return Err(err(
                    format!("couplings[{i}].{key}"),
                    format!(
                        "interface {}.{} is already coupled by couplings[{j}] ('{other}'): an interface takes one coupling",
                        m.0, m.1
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// One field list a coupling member must offer (the scheme's declaration, docs/architecture.md).
#[derive(Debug, Clone, PartialEq)]
pub struct Need<'a> {
    /// The key that sets the list (`driver_fields`, `sides[1]`, ...).
    pub key: String,
    pub member: &'a (String, String),
    /// True: the member must provide the fields; false: accept them.
    pub provide: bool,
    pub fields: Vec<String>,
}

/// What each member of coupling `c` must provide and accept: a kinematic or immersed driver
/// provides the driver fields and accepts the responder's, the responder the other way
/// round; every side of a lagrange coupling provides and accepts what
/// `protocol::scheme::lagrange` declares.
pub fn required_fields(c: &CouplingConfig) -> Vec<Need<'_>> {
    let need = |key: String, member, provide, fields: Vec<String>| Need {
        key,
        member,
        provide,
        fields,
    };
    if scheme::of(c.kind).coordinator_solved() {
        let (provides, accepts) = scheme::of(c.kind).default_fields();
        let own = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        return c
            .sides
            .iter()
            .enumerate()
            .flat_map(|(k, s)| {
                [
                    need(format!("sides[{k}]"), s, true, own(provides)),
                    need(format!("sides[{k}]"), s, false, own(accepts)),
                ]
            })
            .collect();
    }
    let (d, r) = ("driver_fields".to_string(), "responder_fields".to_string());
    vec![
        need(d.clone(), &c.driver, true, c.driver_fields.clone()),
        need(r.clone(), &c.driver, false, c.responder_fields.clone()),
        need(r, &c.responder, true, c.responder_fields.clone()),
        need(d, &c.responder, false, c.driver_fields.clone()),
    ]
}

/// Bindings of one node: its side of every coupling.
pub fn bindings_of(case: &Case, node: &str) -> Vec<protocol::Binding> {
    let mut v = Vec::new();
    for c in &case.couplings {
        if scheme::of(c.kind).coordinator_solved() {
            // Every side exchanges with the coordinator, which solves the interface problem.
            for (n, iface) in c.sides.iter().filter(|s| s.0 == node) {
                let _ = n;
                v.push(protocol::Binding {
                    coupling: c.name.clone(),
                    kind: c.kind,
                    interface: iface.clone(),
                    role: protocol::Role::Driver,
                    peer: protocol::scheme::lagrange::wire::PEER.to_string(),
                    peer_interface: String::new(),
                    sends: c.driver_fields.clone(),
                    receives: c.responder_fields.clone(),
                    input_lag: scheme::of(c.kind).input_lag(protocol::Role::Driver, true),
                });
            }
            continue;
        }
        // The lags are the scheme's (serial: the driver's motion feeds the responder in the
        // same window; the responder's force reaches the driver at the next sync time).
        let sch = scheme::of(c.kind);
        let serial = case.run.schedule == Schedule::Serial;
        if c.driver.0 == node {
            v.push(protocol::Binding {
                coupling: c.name.clone(),
                kind: c.kind,
                interface: c.driver.1.clone(),
                role: protocol::Role::Driver,
                peer: c.responder.0.clone(),
                peer_interface: c.responder.1.clone(),
                sends: c.driver_fields.clone(),
                receives: c.responder_fields.clone(),
                input_lag: sch.input_lag(protocol::Role::Driver, serial),
            });
        }
        if c.responder.0 == node {
            v.push(protocol::Binding {
                coupling: c.name.clone(),
                kind: c.kind,
                interface: c.responder.1.clone(),
                role: protocol::Role::Responder,
                peer: c.driver.0.clone(),
                peer_interface: c.driver.1.clone(),
                sends: c.responder_fields.clone(),
                receives: c.driver_fields.clone(),
                input_lag: sch.input_lag(protocol::Role::Responder, serial),
            });
        }
    }
    v
}

/// Node order within a window implied by the same-window dependencies (drivers before their
/// responders); an error if they form a cycle.
pub fn window_order(case: &Case) -> Result<Vec<String>, ConfigError> {
    let names: Vec<String> = case.nodes.iter().map(|n| n.name.clone()).collect();
    let mut deps: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    let serial = case.run.schedule == Schedule::Serial;
    for c in case
        .couplings
        .iter()
        .filter(|c| scheme::of(c.kind).responder_after_driver(serial))
    {
        deps.entry(c.responder.0.as_str())
            .or_default()
            .push(c.driver.0.as_str());
    }
    let mut order: Vec<String> = Vec::new();
    let mut left: Vec<&str> = names.iter().map(String::as_str).collect();
    while !left.is_empty() {
        let ready: Vec<&str> = left
            .iter()
            .copied()
            .filter(|n| {
                deps.get(n)
                    .is_none_or(|d| d.iter().all(|x| order.iter().any(|o| o == x)))
            })
            .collect();
        if ready.is_empty() {
            return Err(err(
                "couplings",
                format!(
                    "the serial schedule has a cycle of same-window dependencies among {}",
                    left.join(", ")
                ),
            ));
        }
        for r in &ready {
            order.push(r.to_string());
        }
        left.retain(|n| !ready.contains(n));
    }
    Ok(order)
}
