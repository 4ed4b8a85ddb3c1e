//! A node's watch on its coordinator (docs/architecture.md): whatever ends the coordinator, even
//! SIGKILL, its nodes stop within a second and remove their shared memory. A node launched by
//! `cosim` asks the kernel for SIGTERM when its parent dies and checks its parent pid; a node
//! that joined from elsewhere follows the coordinator's liveliness through the transport.
//!
//! The watch runs on its own thread and only raises a flag: the main loop sees it at its next
//! receive (at most 100 ms) and leaves through the normal exit path, dropping its transport.
//! A node stuck in a long computation is ended after a grace period instead.

use crate::stop;
use crate::transport::{self, PeerState, PeerWatch};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::time::{Duration, Instant};

/// Environment variable through which `cosim` tells a node it launched the coordinator's pid.
pub const PARENT_ENV: &str = "COSIM_COORDINATOR_PID";
/// How often the watch looks.
const TICK: Duration = Duration::from_millis(10);
/// Time the main loop has to leave on its own once told to stop.
const GRACE: Duration = Duration::from_millis(600);
/// A node under a live coordinator that gets SIGTERM (a scheduler signals the whole job)
/// leaves the coordinator this long to end the run at a window boundary.
const SIGNAL_WAIT: Duration = Duration::from_secs(3);
/// A node that joined from elsewhere gives up when no coordinator of its run shows this long.
const UNSEEN: Duration = Duration::from_secs(60);

const RUNNING: u8 = 0;
const REQUESTED: u8 = 1;
const GONE: u8 = 2;

static STATE: AtomicU8 = AtomicU8::new(RUNNING);
static REASON: Mutex<String> = Mutex::new(String::new());
static DONE: AtomicBool = AtomicBool::new(false);

/// Why the node must stop.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stop {
    /// A stop signal to this node; the coordinator is alive and is told.
    Requested(String),
    /// The coordinator is gone: nobody to tell.
    CoordinatorGone(String),
}

impl Stop {
    pub fn reason(&self) -> &str {
        match self {
            Stop::Requested(r) | Stop::CoordinatorGone(r) => r,
        }
    }

    /// The node's exit status: 128 + the signal for a signal, 1 when its coordinator died.
    pub fn exit_code(&self) -> i32 {
        match self {
            Stop::Requested(_) => stop::requested().map_or(1, stop::exit_code),
            Stop::CoordinatorGone(_) => 1,
        }
    }
}

/// Whether (and why) the node must stop now.
pub fn stop() -> Option<Stop> {
    let reason = || REASON.lock().map(|r| r.clone()).unwrap_or_default();
    match STATE.load(Ordering::SeqCst) {
        REQUESTED => Some(Stop::Requested(reason())),
        GONE => Some(Stop::CoordinatorGone(reason())),
        _ => None,
    }
}

fn raise(state: u8, reason: String) {
    if STATE
        .compare_exchange(RUNNING, state, Ordering::SeqCst, Ordering::SeqCst)
        .is_ok()
    {
        if let Ok(mut r) = REASON.lock() {
            *r = reason;
        }
        // Sends that wait for a reader (a dead coordinator's full queue) give up now.
        if state == GONE {
            transport::abandon_sends();
        }
    }
}

/// The main loop has left (transport dropped): the watch ends, nothing is cut short.
pub fn finished() {
    DONE.store(true, Ordering::SeqCst);
}

fn parent_pid() -> u32 {
    // SAFETY: getppid has no preconditions.
    unsafe { libc::getppid() as u32 }
}

/// Whether the coordinator that launched this node (`parent`, from [`arm_parent_death`]) is
/// still its parent; false for a node started by hand.
pub fn parent_alive(parent: Option<u32>) -> bool {
    parent.is_some_and(|p| parent_pid() == p)
}

/// For a node launched by `cosim` (the environment names its pid): ask for SIGTERM when the
/// parent dies, then check that it has not died already (the request only covers deaths
/// after it). Returns the coordinator's pid, `None` for a node started by hand.
pub fn arm_parent_death() -> Result<Option<u32>, String> {
    let Some(pid) = std::env::var(PARENT_ENV)
        .ok()
        .and_then(|v| v.trim().parse::<u32>().ok())
    else {
        return Ok(None);
    };
    // SAFETY: prctl(PR_SET_PDEATHSIG) takes a signal number and touches no memory of ours.
    unsafe {
        libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
    }
    if parent_pid() != pid {
        return Err(format!("the coordinator (pid {pid}) is already gone"));
    }
    Ok(Some(pid))
}

/// Start the watch. `parent`: the coordinator's pid for a node it launched; `peer`: the
/// coordinator's liveliness for a node that joined from elsewhere.
pub fn start(parent: Option<u32>, peer: Option<PeerWatch>) {
    let spawned = std::thread::Builder::new()
        .name("cosim-watchdog".into())
        .spawn(move || watch(parent, peer));
    if let Err(e) = spawned {
        tracing::warn!("cannot start the watch on the coordinator: {e}");
    }
}

fn watch(parent: Option<u32>, peer: Option<PeerWatch>) {
    let started = Instant::now();
    let mut signalled: Option<Instant> = None;
    let mut stopping: Option<Instant> = None;
    while !DONE.load(Ordering::SeqCst) {
        std::thread::sleep(TICK);
        if let Some(t) = stopping {
            if t.elapsed() > GRACE && !DONE.load(Ordering::SeqCst) {
                let s = stop().unwrap_or(Stop::CoordinatorGone(String::new()));
                crate::log_line!(
                    "cosim node: {}; still busy {} ms later, exiting now",
                    s.reason(),
                    GRACE.as_millis()
                );
                // SAFETY: _exit ends the process at once, without running destructors of
                // other threads' state (the main thread is busy and must not be waited for).
                unsafe { libc::_exit(s.exit_code()) };
            }
            continue;
        }
        if let Some(pid) = parent
            && parent_pid() != pid
        {
            raise(GONE, format!("the coordinator (pid {pid}) is gone"));
        } else if let Some(p) = &peer {
            match p.state() {
                PeerState::Lost => raise(GONE, "the coordinator is gone (liveliness lost)".into()),
                PeerState::Unknown if started.elapsed() > UNSEEN => raise(
                    GONE,
                    format!(
                        "no coordinator of this run seen within {} s",
                        UNSEEN.as_secs()
                    ),
                ),
                _ => {}
            }
        }
        if STATE.load(Ordering::SeqCst) == RUNNING
            && let Some(sig) = stop::requested()
        {
            let since = *signalled.get_or_insert_with(Instant::now);
            if parent.is_none() {
                raise(REQUESTED, format!("stopped by {}", stop::name(sig)));
            } else if since.elapsed() > SIGNAL_WAIT {
                raise(
                    REQUESTED,
                    format!(
                        "stopped by {} (the coordinator did not end the run within {} s)",
                        stop::name(sig),
                        SIGNAL_WAIT.as_secs()
                    ),
                );
            }
        }
        if STATE.load(Ordering::SeqCst) != RUNNING {
            stopping = Some(Instant::now());
        }
    }
}
