//! Where a window's wall time goes on the coordinator's side: time per phase of
//! the window loop and the heap allocations made on its thread, reported per window in
//! `summary.json` (`window_breakdown`) and by `cosim bench --only window`.
//!
//! Phases are timed with `Instant` (tens of ns per reading, a few readings per message). The
//! allocations are counted by [`CountingAlloc`] when the binary installs it as its global
//! allocator (`cosim` does); elsewhere the count is absent.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Instant;

/// What the window loop spends its time on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Encoding, recording and sending the `Advance` commands.
    Advance,
    /// Blocked in the transport's `recv`, waiting for the nodes (their compute and the hops).
    Blocked,
    /// Decoding what arrived and acting on it (Done, Heartbeat, lagrange inputs).
    Handle,
    /// Handing the nodes' messages to the recorder thread (a copy into a pooled buffer; the
    /// MCAP writing and compression happen on that thread).
    RecordMessages,
    /// Liveness checks between receives (child status, heartbeats, stalls).
    Health,
    /// The momentum and energy balance of the window.
    Audit,
    /// The per-window JSON records (balance, node reports, multipliers) and plot histories.
    Reports,
    /// Asking the recorder thread to close a chunk, checkpoints (which wait for the
    /// recording to reach the disk), the progress line.
    Flush,
}

impl Phase {
    pub const ALL: [Phase; 8] = [
        Phase::Advance,
        Phase::Blocked,
        Phase::Handle,
        Phase::RecordMessages,
        Phase::Health,
        Phase::Audit,
        Phase::Reports,
        Phase::Flush,
    ];

    /// The key in `summary.json`.
    pub fn key(self) -> &'static str {
        match self {
            Phase::Advance => "advance_send_us",
            Phase::Blocked => "blocked_on_nodes_us",
            Phase::Handle => "handle_messages_us",
            Phase::RecordMessages => "record_messages_us",
            Phase::Health => "health_checks_us",
            Phase::Audit => "audit_us",
            Phase::Reports => "reports_us",
            Phase::Flush => "flush_progress_checkpoint_us",
        }
    }
}

/// Accumulated phase times of the window loop.
#[derive(Debug, Clone)]
pub struct Profile {
    ns: [u64; Phase::ALL.len()],
    /// Allocations on this thread when the window loop started (None: not counted).
    allocs_at_start: Option<u64>,
    allocs: Option<u64>,
    /// Of those, made inside the transport (iceoryx2 allocates a small shared state for every
    /// sample it loans; zenoh allocates per message).
    transport_allocs: u64,
    /// Of those, buffers made for the recorder while its thread lagged behind the loop by
    /// more than its pool holds (a busy machine).
    recorder_lag_allocs: u64,
}

impl Default for Profile {
    fn default() -> Self {
        Profile {
            ns: [0; Phase::ALL.len()],
            allocs_at_start: None,
            allocs: None,
            transport_allocs: 0,
            recorder_lag_allocs: 0,
        }
    }
}

impl Profile {
    /// Start counting the window loop's allocations from here.
    pub fn start(&mut self) {
        self.allocs_at_start = thread_allocations();
    }

    /// Stop counting (the window loop ended).
    pub fn stop(&mut self) {
        self.allocs = match (self.allocs_at_start, thread_allocations()) {
            (Some(a), Some(b)) => Some(b - a),
            _ => None,
        };
    }

    /// Count `n` of this thread's allocations as made for a lagging recorder.
    pub fn add_recorder_lag_allocs(&mut self, n: u64) {
        self.recorder_lag_allocs += n;
    }

    /// Count `n` of this thread's allocations as the transport's.
    pub fn add_transport_allocs(&mut self, n: u64) {
        self.transport_allocs += n;
    }

    /// Add the time since `since` to `phase`; returns now, for the next phase.
    pub fn lap(&mut self, phase: Phase, since: Instant) -> Instant {
        let now = Instant::now();
        self.add_ns(phase, now.duration_since(since).as_nanos() as u64);
        now
    }

    pub fn add_ns(&mut self, phase: Phase, ns: u64) {
        self.ns[phase as usize] += ns;
    }

    /// `phase`'s total (s).
    pub fn seconds(&self, phase: Phase) -> f64 {
        self.ns[phase as usize] as f64 * 1e-9
    }

    /// The breakdown per window, for `summary.json`.
    pub fn per_window(&self, windows: u64) -> serde_json::Value {
        let w = windows.max(1) as f64;
        let mut m = serde_json::Map::new();
        m.insert("windows".into(), windows.into());
        for p in Phase::ALL {
            m.insert(p.key().into(), (self.seconds(p) * 1e6 / w).into());
        }
        // The window loop's own (bookkeeping, audit, reports, recording), the transport's,
        // and the recorder's buffers made while its thread lagged.
        let apart = self.transport_allocs + self.recorder_lag_allocs;
        m.insert(
            "allocations_per_window".into(),
            self.allocs.map_or(serde_json::Value::Null, |a| {
                (a.saturating_sub(apart) as f64 / w).into()
            }),
        );
        m.insert(
            "recorder_lag_allocations_per_window".into(),
            self.allocs.map_or(serde_json::Value::Null, |_| {
                (self.recorder_lag_allocs as f64 / w).into()
            }),
        );
        m.insert(
            "transport_allocations_per_window".into(),
            self.allocs.map_or(serde_json::Value::Null, |_| {
                (self.transport_allocs as f64 / w).into()
            }),
        );
        serde_json::Value::Object(m)
    }
}

thread_local! {
    /// Heap allocations (and reallocations) made by this thread, once the counting allocator
    /// is installed. No destructor, so it is usable from inside the allocator.
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

/// The system allocator, counting each thread's allocations (install it with
/// `#[global_allocator]`). Costs one thread-local increment per allocation.
pub struct CountingAlloc;

fn count() {
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
}

// SAFETY: every call is forwarded unchanged to the system allocator.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: forwarded with the caller's guarantees.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations made by this thread so far (0 when [`CountingAlloc`] is not installed).
pub fn allocations_now() -> u64 {
    ALLOCS.try_with(|c| c.get()).unwrap_or(0)
}

/// Allocations made by this thread so far; None when [`CountingAlloc`] is not installed
/// (nothing counted: every thread allocates before it runs a window loop).
pub fn thread_allocations() -> Option<u64> {
    let n = ALLOCS.try_with(|c| c.get()).unwrap_or(0);
    (n > 0).then_some(n)
}
