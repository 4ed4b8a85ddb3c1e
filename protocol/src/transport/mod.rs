//! Transports (docs/architecture.md): one trait, three implementations chosen by the case config.
//! A transport moves opaque byte messages (encoded envelopes) on named topics; each process
//! opens one transport as one *endpoint* (its node name, or `coordinator`) and receives
//! everything it subscribed to through a single `recv`, which blocks without spinning.

mod abandon;
pub mod bench;
pub mod local;
pub mod shm;
pub mod zenoh;

use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};
use std::time::Duration;
use thiserror::Error;

pub use abandon::{abandon_sends, sends_abandoned};

#[derive(Debug, Error)]
pub enum TransportError {
    #[error("transport set-up failed: {0}")]
    Setup(String),
    #[error("send on '{topic}' failed: {reason}")]
    Send { topic: String, reason: String },
    #[error("receive failed: {0}")]
    Recv(String),
    #[error("the process was asked to terminate")]
    Terminated,
    #[error("cannot encode the message: {0}")]
    Encode(String),
}

/// Which transport a run uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TransportKind {
    Shm,
    Zenoh,
    Local,
}

impl TransportKind {
    pub fn as_str(self) -> &'static str {
        match self {
            TransportKind::Shm => "shm",
            TransportKind::Zenoh => "zenoh",
            TransportKind::Local => "local",
        }
    }
}

impl std::str::FromStr for TransportKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "shm" => Ok(TransportKind::Shm),
            "zenoh" => Ok(TransportKind::Zenoh),
            "local" => Ok(TransportKind::Local),
            other => Err(format!("unknown transport '{other}' (shm | zenoh | local)")),
        }
    }
}

/// Everything needed to open one endpoint of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransportSpec {
    pub kind: TransportKind,
    /// Run id: namespaces shared-memory files and topics, so runs never collide.
    pub run: String,
    /// This process's endpoint name (a node name, or `coordinator`).
    pub endpoint: String,
    /// zenoh only: endpoints to listen on (the coordinator) ...
    pub listen: Vec<String>,
    /// ... and to connect to (the nodes).
    pub connect: Vec<String>,
}

/// Index of a subscription in the order `subscribe` was called.
pub type TopicId = usize;

/// Sends bytes on one topic. `Send` so a node's heartbeat thread can own one.
pub trait Publisher: Send {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError>;

    /// Encode `message` as an envelope (run, sender, sequence number) and send it. By
    /// default it is encoded into `scratch` (capacity reused) and its bytes sent; shared
    /// memory encodes straight into the loaned sample instead.
    fn send_message(
        &mut self,
        run: &str,
        sender: &str,
        seq: u64,
        message: &crate::message::Message,
        scratch: &mut Vec<u8>,
    ) -> Result<(), TransportError> {
        self.send_message_ringing(run, sender, seq, message, scratch, true)
    }

    /// Send without waking the readers: on shared memory no bell rings, so a reader asleep in
    /// `recv` takes the message when something else wakes it (a later send, a [`ring`]).
    /// For messages nobody waits on alone — the `Advance`s of a batch before its [`ring`], a
    /// `Done` the coordinator reads with a later one. Transports whose every delivery wakes
    /// the reader (zenoh, local) send as usual.
    ///
    /// [`ring`]: Publisher::ring
    fn send_quiet(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.send(bytes)
    }

    /// [`Publisher::send_message`], waking the readers only if `ring`
    /// ([`Publisher::send_quiet`]). Transports that encode in place override this one.
    fn send_message_ringing(
        &mut self,
        run: &str,
        sender: &str,
        seq: u64,
        message: &crate::message::Message,
        scratch: &mut Vec<u8>,
        ring: bool,
    ) -> Result<(), TransportError> {
        crate::codec::encode_into(scratch, run, sender, seq, message)
            .map_err(|e| TransportError::Encode(e.to_string()))?;
        if ring {
            self.send(scratch)
        } else {
            self.send_quiet(scratch)
        }
    }

    /// Wake the readers for what was sent quietly; a no-op where every send wakes them.
    fn ring(&mut self) -> Result<(), TransportError> {
        Ok(())
    }
}

pub trait Transport {
    /// A publisher on `topic`. `readers` names the endpoints that subscribe to it, so that
    /// a transport that needs explicit wake-ups (shared memory) can ring them.
    fn publisher(
        &mut self,
        topic: &str,
        readers: &[String],
    ) -> Result<Box<dyn Publisher>, TransportError>;

    /// Subscribe to `topic`; messages sent before this call may be lost.
    fn subscribe(&mut self, topic: &str) -> Result<TopicId, TransportError>;

    /// Wait up to `timeout` for the next message on any subscription and pass its bytes to
    /// `f`. Returns `Ok(false)` on timeout. Messages of one topic arrive in order.
    fn recv(
        &mut self,
        timeout: Duration,
        f: &mut dyn FnMut(TopicId, &[u8]),
    ) -> Result<bool, TransportError>;

    /// Number of readers connected to `topic` now, if the transport can tell (used to wait
    /// until a peer is listening before the first send).
    fn readers(&self, topic: &str) -> Option<usize> {
        let _ = topic;
        None
    }

    /// Announce this endpoint as alive (zenoh liveliness token); no-op where the transport
    /// has no such notion.
    fn declare_alive(&mut self) -> Result<(), TransportError> {
        Ok(())
    }

    /// Endpoints whose liveliness was lost since the last call.
    fn lost_endpoints(&mut self) -> Vec<String> {
        Vec::new()
    }

    /// Watch whether `endpoint` (a node watches its `coordinator`) is alive, from another
    /// thread; `None` where the transport cannot tell.
    fn watch(&mut self, endpoint: &str) -> Result<Option<PeerWatch>, TransportError> {
        let _ = endpoint;
        Ok(None)
    }
}

/// What is known of a watched endpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PeerState {
    /// Not seen yet.
    Unknown,
    Alive,
    /// Seen alive, then gone (its process died or its connection closed).
    Lost,
}

/// Liveness of another endpoint, updated by the transport and read from any thread.
#[derive(Debug, Clone, Default)]
pub struct PeerWatch(Arc<AtomicU8>);

impl PeerWatch {
    pub fn state(&self) -> PeerState {
        match self.0.load(Ordering::SeqCst) {
            0 => PeerState::Unknown,
            1 => PeerState::Alive,
            _ => PeerState::Lost,
        }
    }

    pub(crate) fn seen_alive(&self) {
        let _ = self
            .0
            .compare_exchange(0, 1, Ordering::SeqCst, Ordering::SeqCst);
    }

    /// Gone: only once it was seen alive (a token withdrawn before we looked is not news).
    pub(crate) fn seen_gone(&self) {
        let _ = self
            .0
            .compare_exchange(1, 2, Ordering::SeqCst, Ordering::SeqCst);
    }

    /// Whether anyone but the transport's watcher still holds this watch.
    pub(crate) fn watched(&self) -> bool {
        Arc::strong_count(&self.0) > 1
    }
}

/// Open an endpoint of the given kind. `local` needs a hub: use [`local::LocalHub::endpoint`].
pub fn open(spec: &TransportSpec) -> Result<Box<dyn Transport>, TransportError> {
    match spec.kind {
        TransportKind::Shm => Ok(Box::new(shm::ShmTransport::open(spec)?)),
        TransportKind::Zenoh => Ok(Box::new(zenoh::ZenohTransport::open(spec)?)),
        TransportKind::Local => Err(TransportError::Setup(
            "the local transport is in-process only: open it from a LocalHub".into(),
        )),
    }
}

/// Remove every shared-memory resource a run left behind (dead nodes' files). Safe to call
/// at start and at exit; a no-op for transports without such resources.
pub fn cleanup(kind: TransportKind, run: &str) {
    if kind == TransportKind::Shm {
        shm::cleanup_run(run);
    }
}
