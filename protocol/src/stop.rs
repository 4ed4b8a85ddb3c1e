//! Stop requests from signals. SIGINT and SIGTERM only record that they came (async-signal-safe
//! atomics); the coordinator and the nodes act on it at a safe point, a window boundary, so a
//! stopped run still ends with its recording finalised and its shared memory removed.
//!
//! iceoryx2 captures SIGINT, SIGTERM and a few more process-wide the first time it creates
//! shared memory, whatever a node's `SignalHandlingMode` (it then swallows Ctrl-C). [`install`]
//! therefore makes iceoryx2 set its handlers up first and replaces them afterwards.

use std::sync::atomic::{AtomicI32, AtomicU32, Ordering};

static FIRST: AtomicI32 = AtomicI32::new(0);
static COUNT: AtomicU32 = AtomicU32::new(0);

extern "C" fn on_signal(sig: libc::c_int) {
    let _ = FIRST.compare_exchange(0, sig, Ordering::SeqCst, Ordering::SeqCst);
    COUNT.fetch_add(1, Ordering::SeqCst);
}

fn set_handler(sig: libc::c_int, handler: libc::sighandler_t) -> std::io::Result<()> {
    // SAFETY: a zeroed sigaction with an empty mask is valid; the handler only touches
    // lock-free atomics (async-signal-safe), or is SIG_IGN.
    unsafe {
        let mut sa: libc::sigaction = std::mem::zeroed();
        sa.sa_sigaction = handler;
        sa.sa_flags = libc::SA_RESTART;
        libc::sigemptyset(&mut sa.sa_mask);
        if libc::sigaction(sig, &sa, std::ptr::null_mut()) != 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    Ok(())
}

/// Let iceoryx2 install its process-wide signal capture now (it does so once, lazily), so
/// that the handlers set after this call stay in place.
fn settle_iceoryx2() {
    let _ = iceoryx2_bb_posix::signal::SignalHandler::last_signal();
}

/// Record `signals` (e.g. SIGINT, SIGTERM) as stop requests instead of dying of them.
pub fn install(signals: &[libc::c_int]) -> std::io::Result<()> {
    settle_iceoryx2();
    for &s in signals {
        set_handler(s, on_signal as *const () as libc::sighandler_t)?;
    }
    Ok(())
}

/// Ignore `sig` (a node launched by `cosim` leaves Ctrl-C to its coordinator, which gets it
/// from the same terminal and stops the run at a window boundary).
pub fn ignore(sig: libc::c_int) -> std::io::Result<()> {
    settle_iceoryx2();
    set_handler(sig, libc::SIG_IGN)
}

/// The first stop signal received, if any.
pub fn requested() -> Option<libc::c_int> {
    match FIRST.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// How many stop signals arrived (a second Ctrl-C stops at once).
pub fn count() -> u32 {
    COUNT.load(Ordering::SeqCst)
}

/// `SIGINT`, `SIGTERM`, ... for messages.
pub fn name(sig: libc::c_int) -> String {
    match sig {
        libc::SIGINT => "SIGINT".into(),
        libc::SIGTERM => "SIGTERM".into(),
        libc::SIGHUP => "SIGHUP".into(),
        libc::SIGKILL => "SIGKILL".into(),
        s => format!("signal {s}"),
    }
}

/// The shell's exit status for a process ended by `sig`: 128 + the signal number (130 for
/// SIGINT, 143 for SIGTERM).
pub fn exit_code(sig: libc::c_int) -> i32 {
    128 + sig
}
