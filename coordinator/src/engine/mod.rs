//! The engine of `cosim run`: the coordinator's state between launch and summary
//! ([`Coord`]), the nodes' start and hand-shake ([`start`]), the window loop and its
//! pipelining ([`window`]), what comes in ([`pump`]) and who is alive ([`health`]), the
//! audit ([`audit`]), checkpoints ([`checkpoint`]) and the summary ([`summary`]).
//!
//! Within a window the coordinator sends `Advance` to every node in the coupling graph's
//! order and waits for every `Done`; the serial data dependencies (a responder needs its
//! driver's motion of the same window) are enforced by the nodes themselves, which wait for
//! their inputs, so the same loop serves the serial and the parallel schedules.
//!
//! The coordinator is kept off the window's critical path: the next window's
//! `Advance` goes out before the last window is audited and recorded (two windows in flight,
//! [`WINDOWS_AHEAD`]), so the nodes exchange peer to peer and never wait for the audit or
//! the recorder; it waits where a window's end decides the next (checkpoint, decoupling rule,
//! lagrange hub, stop request). Reports of a window ahead are kept until its own audit.

pub mod audit;
mod checkpoint;
pub mod coord;
mod health;
mod pump;
pub mod report;
mod start;
pub mod summary;
mod window;

pub use audit::{Audit, BalanceRow};
pub use coord::MAX_AHEAD;
pub(crate) use coord::{Closed, Coord};
pub use coord::{Fault, RunOptions};
pub use window::WINDOWS_AHEAD;

use crate::case;
use coord::fault;
use std::path::Path;

/// Drive run `c` from launch to its summary: start the nodes (`out`: the output folder,
/// `listen`: the endpoint remote nodes connect to), run the windows, finish the nodes.
pub(crate) fn drive(
    c: &mut Coord,
    out: &Path,
    listen: &str,
    opts: &RunOptions,
) -> Result<serde_json::Value, Fault> {
    let order = case::window_order(c.case).map_err(|e| fault("coordinator", e.to_string()))?;
    start::launch(c, out, listen, opts)?;
    start::hand_shake(c, out)?;
    start::set_up(c)?;
    let w = window::run_windows(c, out, &order, opts)?;
    window::finish_nodes(c, &w)?;
    Ok(summary::run_summary(c, &w))
}
