//! Sends abandoned by a leaving process.

use std::sync::atomic::{AtomicBool, Ordering};

static ABANDON: AtomicBool = AtomicBool::new(false);

/// Make every send that waits for a reader fail at once from now on (the process is leaving
/// because its coordinator died: a dead reader's full queue would hold it for the send timeout).
pub fn abandon_sends() {
    ABANDON.store(true, Ordering::SeqCst);
}

/// Whether [`abandon_sends`] was called.
pub fn sends_abandoned() -> bool {
    ABANDON.load(Ordering::SeqCst)
}
