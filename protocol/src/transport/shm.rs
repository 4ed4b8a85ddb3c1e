//! iceoryx2 shared-memory transport (docs/architecture.md): one iceoryx2 node per endpoint,
//! one publish-subscribe service of `[u8]` per topic (dynamically sized, power-of-two
//! segments, no silent overflow), and one event "bell" per endpoint that every publisher rings
//! after a send, so `recv` sleeps in the kernel instead of spinning. A quiet send rings no
//! bell (`Publisher::send_quiet`): a wake-up costs both processes a context switch, and a
//! batch of messages needs one.
//!
//! Every file a run creates carries the prefix `cx_<run>_` (see [`prefix`]), which is what
//! [`cleanup_run`] sweeps after a crash.

use super::{PeerWatch, Publisher, TopicId, Transport, TransportError, TransportSpec};
use crate::codec;
use crate::message::Message;
use iceoryx2::node::NodeView;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher as IoxPublisher;
use iceoryx2::port::subscriber::Subscriber as IoxSubscriber;
use iceoryx2::port::{BackpressureAction, BackpressureInfo, LoanError};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use std::collections::HashMap;
use std::mem::MaybeUninit;
use std::time::{Duration, Instant};

/// The service variant: the thread-safe one, because a `Publisher` must be `Send` (a node's
/// heartbeat thread owns one); `ipc::Service` ports are not. Its ports guard their state with
/// an uncontended mutex, which costs tens of nanoseconds per send (see the transport bench).
type Svc = ipc_threadsafe::Service;
type Factory = PubSubFactory<Svc, [u8], ()>;

/// Messages a subscriber of a data topic can queue before its publishers block (no silent
/// overflow): each sample may be a large field, and the publisher preallocates its pool for it.
pub const SUBSCRIBER_BUFFER: usize = 4;
/// The same for control topics (`Advance`, `Done`, heartbeats: small messages): deep enough
/// for the coordinator's batch of windows in flight ([`queue_depth`]).
pub const CONTROL_BUFFER: usize = 20;

/// How many messages a subscriber of `topic` queues: [`CONTROL_BUFFER`] for the control
/// topics (`…/cmd`, `…/ctrl`), [`SUBSCRIBER_BUFFER`] for the rest. Every endpoint derives it
/// from the name alone, so all of them open a topic's service with the same settings.
pub fn queue_depth(topic: &str) -> usize {
    if topic.ends_with("/cmd") || topic.ends_with("/ctrl") {
        CONTROL_BUFFER
    } else {
        SUBSCRIBER_BUFFER
    }
}
/// Samples a subscriber holds at once (`recv` releases each before taking the next).
const SUBSCRIBER_BORROWED: usize = 2;
/// Publishers per topic: the owner, a heartbeat thread and a test injector fit.
pub const MAX_PUBLISHERS: usize = 4;
/// Subscribers per topic: the reading node, the recording coordinator and one spare.
pub const MAX_SUBSCRIBERS: usize = 3;
/// Processes that may open one service (publishers + subscribers + the coordinator).
const MAX_NODES: usize = 16;
/// Notifiers per bell: every publisher of every peer that writes to the endpoint.
const MAX_NOTIFIERS: usize = 128;
/// First data segment of a publisher; it grows by powers of two as messages grow.
const INITIAL_SLICE: usize = 4096;
/// A send that cannot deliver for this long (a reader that stopped reading) fails instead
/// of hanging the sender forever.
pub const SEND_TIMEOUT: Duration = Duration::from_secs(30);

/// How long `recv` polls for a message before it sleeps on its bell: `COSIM_SPIN_US`
/// (microseconds, default [`SPIN_US`]; 0 sleeps at once). Polling spends a core while it
/// lasts, so it pays only where a reply usually comes that soon (fine coupling windows).
fn spin() -> Duration {
    static SPIN: std::sync::OnceLock<Duration> = std::sync::OnceLock::new();
    *SPIN.get_or_init(|| {
        let us = std::env::var("COSIM_SPIN_US")
            .ok()
            .and_then(|v| v.trim().parse::<u64>().ok())
            .unwrap_or(SPIN_US);
        Duration::from_micros(us.min(10_000))
    })
}

/// Default of `COSIM_SPIN_US`.
pub const SPIN_US: u64 = 0;

/// The file-name prefix of every shared-memory resource of `run`: `cx_<run>_`. Run ids are
/// `[A-Za-z0-9_-]`, at most 32 characters; anything else is replaced by `_`.
pub fn prefix(run: &str) -> String {
    let clean: String = run
        .chars()
        .take(32)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("cx_{clean}_")
}

/// The iceoryx2 configuration shared by every process of `run` (they must all agree).
fn run_config(run: &str) -> Result<Config, TransportError> {
    let mut c = Config::default();
    c.global.prefix = FileName::new(prefix(run).as_bytes()).map_err(|e| {
        TransportError::Setup(format!("run id '{run}' gives no valid file prefix: {e:?}"))
    })?;
    c.global.node.cleanup_dead_nodes_on_creation = true;
    c.global.node.cleanup_dead_nodes_on_destruction = true;
    Ok(c)
}

/// Name of the event service that wakes `endpoint`.
pub fn bell_name(run: &str, endpoint: &str) -> String {
    format!("cosim/{run}/{endpoint}/bell")
}

fn service_name(name: &str) -> Result<ServiceName, TransportError> {
    ServiceName::new(name)
        .map_err(|e| TransportError::Setup(format!("service name '{name}': {e:?}")))
}

fn quiet_logs() {
    set_log_level(LogLevel::Error);
}

fn open_bell(
    node: &Node<Svc>,
    run: &str,
    endpoint: &str,
) -> Result<EventFactory<Svc>, TransportError> {
    let name = bell_name(run, endpoint);
    node.service_builder(&service_name(&name)?)
        .event()
        .max_listeners(2)
        .max_notifiers(MAX_NOTIFIERS)
        .max_nodes(MAX_NOTIFIERS)
        .open_or_create()
        .map_err(|e| TransportError::Setup(format!("bell '{name}': {e:?}")))
}

/// Open (or create) `topic`'s service with [`queue_depth`]. A service created by a build
/// whose control topics queued fewer messages ([`SUBSCRIBER_BUFFER`]) is opened as it is:
/// ports then use its depth ([`depth_of`]), so a run mixing builds is slower, not refused.
fn open_topic(node: &Node<Svc>, topic: &str) -> Result<Factory, TransportError> {
    use iceoryx2::service::builder::publish_subscribe::{
        PublishSubscribeOpenError as Open, PublishSubscribeOpenOrCreateError as OpenOrCreate,
    };
    let name = service_name(topic)?;
    let open = |depth: usize| {
        node.service_builder(&name)
            .publish_subscribe::<[u8]>()
            .max_publishers(MAX_PUBLISHERS)
            .max_subscribers(MAX_SUBSCRIBERS)
            .max_nodes(MAX_NODES)
            .subscriber_max_buffer_size(depth)
            .subscriber_max_borrowed_samples(SUBSCRIBER_BORROWED)
            .history_size(0)
            .enable_safe_overflow(false)
            .open_or_create()
            .map_err(|e| (e, TransportError::Setup(format!("topic '{topic}': {e:?}"))))
    };
    let wanted = queue_depth(topic);
    match open(wanted) {
        Err((
            OpenOrCreate::PublishSubscribeOpenError(Open::DoesNotSupportRequestedMinBufferSize),
            _,
        )) if wanted > SUBSCRIBER_BUFFER => open(SUBSCRIBER_BUFFER).map_err(|e| e.1),
        r => r.map_err(|e| e.1),
    }
}

/// The queue depth ports of `topic` use: [`queue_depth`], or less where the service was
/// created with less ([`open_topic`]).
fn depth_of(service: &Factory, topic: &str) -> usize {
    queue_depth(topic).min(service.static_config().subscriber_max_buffer_size())
}

/// Every sample starts with the publisher's tag and the message's sequence number (u64 LE
/// each), so a message resent after a partial delivery is delivered once.
const FRAME_HEADER: usize = 16;

struct ShmSubscriber {
    sub: IoxSubscriber<Svc, [u8], ()>,
    /// Last sequence number seen per publisher tag (a handful of publishers per topic).
    last: Vec<(u64, u64)>,
}

impl ShmSubscriber {
    /// The message body, or `None` for a duplicate (or a frame too short to be ours).
    fn accept<'a>(&mut self, frame: &'a [u8]) -> Option<&'a [u8]> {
        let tag = u64::from_le_bytes(frame.get(..8)?.try_into().ok()?);
        let seq = u64::from_le_bytes(frame.get(8..FRAME_HEADER)?.try_into().ok()?);
        match self.last.iter_mut().find(|(t, _)| *t == tag) {
            Some((_, last)) if seq <= *last => return None,
            Some((_, last)) => *last = seq,
            None => self.last.push((tag, seq)),
        }
        Some(&frame[FRAME_HEADER..])
    }
}

/// One endpoint of a run on shared memory.
pub struct ShmTransport {
    run: String,
    endpoint: String,
    // Field order is drop order: ports before services before the node.
    subs: Vec<ShmSubscriber>,
    bell: Listener<Svc>,
    _bell_service: EventFactory<Svc>,
    topics: HashMap<String, Factory>,
    /// Where the next round-robin scan of `subs` starts.
    next: usize,
    node: Node<Svc>,
}

impl ShmTransport {
    pub fn open(spec: &TransportSpec) -> Result<Self, TransportError> {
        quiet_logs();
        let config = run_config(&spec.run)?;
        let name = NodeName::new(&spec.endpoint).map_err(|e| {
            TransportError::Setup(format!("endpoint name '{}': {e:?}", spec.endpoint))
        })?;
        let node = NodeBuilder::new()
            .name(&name)
            .config(&config)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .map_err(|e| {
                TransportError::Setup(format!("iceoryx2 node '{}': {e:?}", spec.endpoint))
            })?;
        let bell_service = open_bell(&node, &spec.run, &spec.endpoint)?;
        let bell = bell_service.listener_builder().create().map_err(|e| {
            TransportError::Setup(format!(
                "listener on the bell of '{}': {e:?}",
                spec.endpoint
            ))
        })?;
        Ok(ShmTransport {
            run: spec.run.clone(),
            endpoint: spec.endpoint.clone(),
            subs: Vec::new(),
            bell,
            _bell_service: bell_service,
            topics: HashMap::new(),
            next: 0,
            node,
        })
    }

    /// This endpoint's name.
    pub fn endpoint(&self) -> &str {
        &self.endpoint
    }

    /// Remove the resources of dead nodes of this run now (a crashed peer's segments).
    pub fn cleanup_dead_nodes(&self) -> u64 {
        self.node.try_cleanup_dead_nodes().cleanups
    }

    fn topic(&mut self, topic: &str) -> Result<&Factory, TransportError> {
        if !self.topics.contains_key(topic) {
            let f = open_topic(&self.node, topic)?;
            self.topics.insert(topic.to_string(), f);
        }
        self.topics
            .get(topic)
            .ok_or_else(|| TransportError::Setup(format!("topic '{topic}' vanished")))
    }
}

/// Writes one message into a loaned sample, in place (all of its bytes).
type Fill<'a> = dyn FnMut(&mut [MaybeUninit<u8>]) -> Result<(), TransportError> + 'a;

struct ShmPublisher {
    topic: String,
    /// Identifies this publisher in the frame header, for the readers' duplicate filter.
    tag: u64,
    seq: u64,
    publisher: IoxPublisher<Svc, [u8], ()>,
    service: Factory,
    bells: Vec<Notifier<Svc>>,
    _bell_services: Vec<EventFactory<Svc>>,
}

impl ShmPublisher {
    fn err(&self, reason: String) -> TransportError {
        TransportError::Send {
            topic: self.topic.clone(),
            reason,
        }
    }

    /// Loan a sample of `len` message bytes, write the frame header and let `fill` write the
    /// message into it in place (all `len` bytes), send it; returns how many subscribers
    /// took it.
    fn send_once(
        &self,
        len: usize,
        fill: &mut Fill,
        start: Instant,
        ring: bool,
    ) -> Result<usize, TransportError> {
        // All preallocated samples are in flight only while a reader lags behind: wait for
        // it (backpressure), never drop.
        let mut pause = Duration::from_micros(20);
        let mut sample = loop {
            match self.publisher.loan_slice_uninit(FRAME_HEADER + len) {
                Ok(s) => break s,
                Err(LoanError::OutOfMemory) | Err(LoanError::ExceedsMaxLoans) => {
                    if super::abandon::sends_abandoned() {
                        return Err(self.err("abandoned: the process is leaving".into()));
                    }
                    if start.elapsed() > SEND_TIMEOUT {
                        return Err(self.err(format!(
                            "no free sample for {SEND_TIMEOUT:?}: a reader stopped reading"
                        )));
                    }
                    std::thread::sleep(pause);
                    pause = (pause * 2).min(Duration::from_millis(5));
                }
                Err(e) => return Err(self.err(format!("loan of {len} bytes: {e:?}"))),
            }
        };
        let dst = sample.payload_mut();
        let mut header = [0u8; FRAME_HEADER];
        header[..8].copy_from_slice(&self.tag.to_le_bytes());
        header[8..].copy_from_slice(&self.seq.to_le_bytes());
        let (head, body) = dst.split_at_mut(FRAME_HEADER);
        head.write_copy_of_slice(&header);
        fill(body)?;
        // SAFETY: the loan holds exactly FRAME_HEADER + len elements: the header was written
        // above and `fill` wrote all `len` message bytes (its contract; it failed otherwise).
        let sample = unsafe { sample.assume_init() };
        let delivered = sample.send().map_err(|e| self.err(format!("{e:?}")))?;
        if ring {
            self.ring_bells()?;
        }
        Ok(delivered)
    }

    fn ring_bells(&self) -> Result<(), TransportError> {
        for bell in &self.bells {
            bell.notify()
                .map_err(|e| self.err(format!("ringing a reader: {e:?}")))?;
        }
        Ok(())
    }
}

impl ShmPublisher {
    /// Send one message of `len` bytes written by `fill` (again for a resend), ringing the
    /// readers' bells if `ring` (a resend always rings: the reader must connect).
    fn send_with(&mut self, len: usize, fill: &mut Fill, ring: bool) -> Result<(), TransportError> {
        let start = Instant::now();
        let mut pause = Duration::from_micros(50);
        self.seq += 1;
        let mut ring = ring;
        loop {
            let delivered = self.send_once(len, fill, start, ring)?;
            // iceoryx2 drops a sample for a subscriber that has not yet connected to this
            // publisher (it connects on its next receive) once that subscriber's buffer is
            // full. Detect it and send again after the bell has woken the reader; readers
            // that already took this sequence number drop the copy.
            if delivered >= self.service.dynamic_config().number_of_subscribers()
                || super::abandon::sends_abandoned()
            {
                return Ok(());
            }
            if start.elapsed() > SEND_TIMEOUT {
                return Err(self.err(format!(
                    "a subscriber did not connect within {SEND_TIMEOUT:?}"
                )));
            }
            std::thread::sleep(pause);
            pause = (pause * 2).min(Duration::from_millis(5));
            ring = true;
        }
    }
}

impl ShmPublisher {
    /// Send `bytes` as one message, ringing the readers if `ring`.
    fn send_bytes(&mut self, bytes: &[u8], ring: bool) -> Result<(), TransportError> {
        self.send_with(
            bytes.len(),
            &mut |dst| {
                dst.write_copy_of_slice(bytes);
                Ok(())
            },
            ring,
        )
    }
}

impl Publisher for ShmPublisher {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.send_bytes(bytes, true)
    }

    fn send_quiet(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.send_bytes(bytes, false)
    }

    fn ring(&mut self) -> Result<(), TransportError> {
        self.ring_bells()
    }

    /// Encodes straight into the loaned sample: the message's only copy on this side.
    fn send_message_ringing(
        &mut self,
        run: &str,
        sender: &str,
        seq: u64,
        message: &Message,
        _scratch: &mut Vec<u8>,
        ring: bool,
    ) -> Result<(), TransportError> {
        let len = codec::encoded_len(run, sender, message)
            .map_err(|e| self.err(format!("cannot encode: {e}")))?;
        self.send_with(
            len,
            &mut |dst| {
                codec::encode_into_uninit(dst, run, sender, seq, message)
                    .map_err(|e| TransportError::Encode(e.to_string()))
            },
            ring,
        )
    }
}

impl Transport for ShmTransport {
    fn publisher(
        &mut self,
        topic: &str,
        readers: &[String],
    ) -> Result<Box<dyn Publisher>, TransportError> {
        let service = self.topic(topic)?;
        let depth = depth_of(service, topic);
        let publisher = service
            .publisher_builder()
            .initial_max_slice_len(INITIAL_SLICE)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .max_loaned_samples(1)
            // Samples are shared by all subscribers, so the distinct samples in flight are
            // bounded by one reader's buffer + borrowed + the one being written; preallocating
            // the worst case of iceoryx2 (subscribers × (buffer + borrowed)) would multiply
            // /dev/shm use by the number of subscribers.
            .override_sample_preallocation(move |_| depth + SUBSCRIBER_BORROWED + 1)
            .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
            .set_backpressure_handler(|info: &BackpressureInfo| {
                if info.elapsed_time > SEND_TIMEOUT || super::abandon::sends_abandoned() {
                    BackpressureAction::DiscardDataAndFail
                } else {
                    BackpressureAction::Retry
                }
            })
            .create()
            .map_err(|e| TransportError::Setup(format!("publisher on '{topic}': {e:?}")))?;
        let mut bells = Vec::with_capacity(readers.len());
        let mut bell_services = Vec::with_capacity(readers.len());
        for reader in readers {
            let svc = open_bell(&self.node, &self.run, reader)?;
            let n = svc
                .notifier_builder()
                .create()
                .map_err(|e| TransportError::Setup(format!("notifier for '{reader}': {e:?}")))?;
            bells.push(n);
            bell_services.push(svc);
        }
        let tag = publisher.id().value() as u64 ^ (publisher.id().value() >> 64) as u64;
        Ok(Box::new(ShmPublisher {
            topic: topic.to_string(),
            tag,
            seq: 0,
            publisher,
            service: open_topic(&self.node, topic)?,
            bells,
            _bell_services: bell_services,
        }))
    }

    fn subscribe(&mut self, topic: &str) -> Result<TopicId, TransportError> {
        let service = self.topic(topic)?;
        let sub = service
            .subscriber_builder()
            .buffer_size(depth_of(service, topic))
            .create()
            .map_err(|e| TransportError::Setup(format!("subscriber on '{topic}': {e:?}")))?;
        self.subs.push(ShmSubscriber {
            sub,
            last: Vec::new(),
        });
        Ok(self.subs.len() - 1)
    }

    fn recv(
        &mut self,
        timeout: Duration,
        f: &mut dyn FnMut(TopicId, &[u8]),
    ) -> Result<bool, TransportError> {
        let start = Instant::now();
        let deadline = start + timeout;
        // A reply that comes within the spin window is taken without sleeping on the bell
        // (a sleep and a wake-up cost the kernel's scheduling latency each time).
        let spin_until = start + spin().min(timeout);
        let n = self.subs.len();
        loop {
            // Round robin: start after the topic served last, so a busy topic cannot starve
            // the others; each subscriber delivers its own topic in order.
            for k in 0..n {
                let i = (self.next + k) % n;
                let s = &mut self.subs[i];
                while let Some(sample) = s
                    .sub
                    .receive()
                    .map_err(|e| TransportError::Recv(format!("{e:?}")))?
                {
                    let Some(body) = s.accept(sample.payload()) else {
                        continue; // a resent duplicate
                    };
                    self.next = (i + 1) % n;
                    f(i, body);
                    return Ok(true);
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(false);
            }
            if now < spin_until {
                std::hint::spin_loop();
                continue;
            }
            // A bell rung after the scan above is still pending here, so nothing is missed.
            match self.bell.timed_wait(|_| {}, deadline - now) {
                Ok(_) | Err(ListenerWaitError::InterruptSignal) => {}
                Err(e) => return Err(TransportError::Recv(format!("waiting on the bell: {e:?}"))),
            }
        }
    }

    fn watch(&mut self, endpoint: &str) -> Result<Option<PeerWatch>, TransportError> {
        let config = run_config(&self.run)?;
        let watch = PeerWatch::default();
        let w = watch.clone();
        let name = endpoint.to_string();
        // iceoryx2 knows whether a node's process lives (its monitoring token): look at the
        // run's node list a few times a second, for as long as anyone holds the watch.
        std::thread::Builder::new()
            .name("cosim-shm-watch".into())
            .spawn(move || {
                while w.watched() {
                    let mut alive = false;
                    let _ = Node::<Svc>::list(&config, |state| {
                        if let NodeState::Alive(v) = &state
                            && v.details()
                                .as_ref()
                                .is_some_and(|d| d.name().as_str() == name)
                        {
                            alive = true;
                        }
                        CallbackProgression::Continue
                    });
                    if alive {
                        w.seen_alive();
                    } else {
                        w.seen_gone();
                    }
                    std::thread::sleep(Duration::from_millis(100));
                }
            })
            .map_err(|e| TransportError::Setup(format!("watch thread: {e}")))?;
        Ok(Some(watch))
    }

    fn readers(&self, topic: &str) -> Option<usize> {
        if let Some(f) = self.topics.get(topic) {
            return Some(f.dynamic_config().number_of_subscribers());
        }
        let f = open_topic(&self.node, topic).ok()?;
        Some(f.dynamic_config().number_of_subscribers())
    }
}

/// Remove what dead processes of `run` left in shared memory: first the stale resources of
/// every dead iceoryx2 node of the run (iceoryx2's own cleanup), then, if no node of the run
/// is alive any more, every remaining `/dev/shm/cx_<run>_*` file (iceoryx2 keeps a small
/// management file, and a process killed mid-creation can leave half-made segments).
///
/// Call it when no process of the run is running (the coordinator does so before launching
/// nodes and after they have all exited); while a node of the run is alive (still listed so
/// after a second) the file sweep is skipped and the living nodes are named in a warning, so a
/// live run is never damaged. Returns the number of dead nodes cleaned up.
pub fn cleanup_run(run: &str) -> usize {
    quiet_logs();
    let Ok(config) = run_config(run) else {
        return 0;
    };
    let mut cleaned = 0;
    // A process that has just been reaped can still be listed alive for a moment; give the
    // list a second to agree before leaving the files in place.
    let deadline = Instant::now() + Duration::from_secs(1);
    loop {
        let mut alive = Vec::new();
        let listed = Node::<Svc>::list(&config, |state| {
            match state {
                NodeState::Dead(d) => {
                    let id = *d.id();
                    match d.try_remove_stale_resources() {
                        Ok(()) => cleaned += 1,
                        Err(e) => {
                            tracing::warn!("iceoryx2 cleanup of dead node {id:?} failed: {e:?}")
                        }
                    }
                }
                NodeState::Alive(v) => alive.push(v.details().as_ref().map_or_else(
                    || format!("{:?}", v.id()),
                    |d| d.name().as_str().to_string(),
                )),
                NodeState::Inaccessible(_) | NodeState::Undefined(_) => {}
            }
            CallbackProgression::Continue
        });
        if let Err(e) = listed {
            tracing::warn!("listing the iceoryx2 nodes of run '{run}' failed: {e:?}");
        }
        if alive.is_empty() {
            sweep_files(run);
            return cleaned;
        }
        if Instant::now() >= deadline {
            tracing::warn!(
                "shared memory of run '{run}' left in place: its nodes {alive:?} are alive"
            );
            return cleaned;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Files in /dev/shm that belong to `run` (by prefix).
pub fn shm_files(run: &str) -> Vec<std::path::PathBuf> {
    let p = prefix(run);
    let Ok(dir) = std::fs::read_dir("/dev/shm") else {
        return Vec::new();
    };
    dir.filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(&p))
        .map(|e| e.path())
        .collect()
}

fn sweep_files(run: &str) {
    for path in shm_files(run) {
        if let Err(e) = std::fs::remove_file(&path) {
            tracing::warn!("removing {}: {e}", path.display());
        }
    }
    // iceoryx2's node and service descriptions live under its root path (the temp dir).
    let Ok(config) = run_config(run) else { return };
    let p = prefix(run);
    for dir in [config.global.node_dir(), config.global.service_dir()] {
        let dir = std::path::PathBuf::from(dir.to_string());
        sweep_dir(&dir, &p);
    }
}

fn sweep_dir(dir: &std::path::Path, prefix: &str) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.filter_map(|e| e.ok()) {
        let name = e.file_name().to_string_lossy().into_owned();
        let path = e.path();
        if path.is_dir() {
            sweep_dir(&path, prefix);
            if name.starts_with(prefix) {
                let _ = std::fs::remove_dir(&path);
            }
        } else if name.starts_with(prefix) {
            let _ = std::fs::remove_file(&path);
        }
    }
}

/// What [`cleanup_stale_runs`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Swept {
    /// Ended runs whose files were removed.
    pub runs: usize,
    /// Files removed (in /dev/shm and iceoryx2's directories).
    pub files: usize,
    /// Runs left alone because a process of theirs is alive.
    pub live: usize,
}

/// Run ids that a file name `cx_<run>_<rest>` may belong to (a run id may hold `_`).
fn run_candidates(name: &str) -> Vec<String> {
    let Some(rest) = name.strip_prefix("cx_") else {
        return Vec::new();
    };
    rest.char_indices()
        .filter(|&(i, c)| c == '_' && (1..=32).contains(&i))
        .map(|(i, _)| rest[..i].to_string())
        .take_while(|r| {
            r.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        })
        .collect()
}

/// Every file (recursively) under `dir` whose name starts with `cx_`.
fn our_files(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.filter_map(|e| e.ok()) {
        let path = e.path();
        if path.is_dir() {
            our_files(&path, out);
        } else if e.file_name().to_string_lossy().starts_with("cx_") {
            out.push(path);
        }
    }
}

/// Remove what runs whose processes are all gone left in shared memory (a killed `cosim`, a
/// node killed with it): first iceoryx2's own cleanup of every dead node, then every remaining
/// file of ours (`cx_<run>_*` in /dev/shm and in iceoryx2's node and service directories) of a
/// run with no live process. A file is kept while any run it may belong to has a live node,
/// or when it is less than a second old, so a running or starting run is never touched.
pub fn cleanup_stale_runs() -> Swept {
    quiet_logs();
    let mut files = Vec::new();
    our_files(std::path::Path::new("/dev/shm"), &mut files);
    let defaults = Config::default();
    let node_dir = std::path::PathBuf::from(defaults.global.node_dir().to_string());
    let service_dir = std::path::PathBuf::from(defaults.global.service_dir().to_string());
    our_files(&node_dir, &mut files);
    our_files(&service_dir, &mut files);
    // Every run a file may belong to, judged (and its dead nodes cleaned by iceoryx2) first.
    let names: Vec<String> = files
        .iter()
        .map(|p| {
            p.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        })
        .collect();
    let mut alive: HashMap<String, usize> = HashMap::new();
    for r in names.iter().flat_map(|n| run_candidates(n)) {
        alive
            .entry(r)
            .or_insert_with_key(|r| live_nodes_after_cleanup(r));
    }
    let mut swept = Swept::default();
    let mut runs = std::collections::BTreeSet::new();
    for (path, name) in files.iter().zip(&names) {
        let candidates = run_candidates(name);
        // A file made in the last second may belong to a run that is starting right now
        // (its first node not yet listed as alive): leave it for the next sweep.
        let fresh = match std::fs::metadata(path) {
            Err(_) => false, // already removed by iceoryx2's cleanup of its dead node
            Ok(m) => m
                .modified()
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_none_or(|age| age < Duration::from_secs(1)),
        };
        if candidates.is_empty() || fresh {
            continue;
        }
        if candidates
            .iter()
            .any(|r| alive.get(r).is_none_or(|&n| n > 0))
        {
            continue;
        }
        // iceoryx2's dead-node cleanup may have removed it already.
        if !path.exists() {
            swept.files += 1;
        } else {
            match std::fs::remove_file(path) {
                Ok(()) => swept.files += 1,
                Err(e) => tracing::warn!("removing {}: {e}", path.display()),
            }
        }
        if let Some(dir) = path.parent()
            && dir != std::path::Path::new("/dev/shm")
            && dir != node_dir
            && dir != service_dir
        {
            // A dead node's own directory; removal fails (as meant) while anything is left.
            let _ = std::fs::remove_dir(dir);
        }
        runs.insert(candidates[0].clone());
    }
    swept.runs = runs.len();
    swept.live = alive.values().filter(|&&n| n > 0).count();
    swept
}

/// iceoryx2's cleanup of the dead nodes of `run`; returns how many of its nodes are alive
/// (or cannot be judged: counted as alive).
fn live_nodes_after_cleanup(run: &str) -> usize {
    let Ok(config) = run_config(run) else {
        return 1;
    };
    let mut alive = 0;
    let listed = Node::<Svc>::list(&config, |state| {
        match state {
            NodeState::Dead(d) => {
                let _ = d.try_remove_stale_resources();
            }
            NodeState::Alive(_) | NodeState::Inaccessible(_) | NodeState::Undefined(_) => {
                alive += 1
            }
        }
        CallbackProgression::Continue
    });
    if listed.is_err() {
        return 1;
    }
    alive
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::topic;
    use crate::transport::TransportKind;

    /// A control topic whose service an older build created with 4 places per queue is opened
    /// at that depth (not refused), and carries messages in order both ways of sending.
    #[test]
    fn a_control_topic_created_with_the_old_depth_is_opened_at_it() {
        let run = format!("depth{}", std::process::id());
        let topic = topic::down(&run, "a");
        assert_eq!(queue_depth(&topic), CONTROL_BUFFER);
        let config = run_config(&run).expect("config");
        let old_node = NodeBuilder::new()
            .config(&config)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<Svc>()
            .expect("node");
        let old = old_node
            .service_builder(&service_name(&topic).expect("name"))
            .publish_subscribe::<[u8]>()
            .max_publishers(MAX_PUBLISHERS)
            .max_subscribers(MAX_SUBSCRIBERS)
            .max_nodes(MAX_NODES)
            .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
            .subscriber_max_borrowed_samples(SUBSCRIBER_BORROWED)
            .history_size(0)
            .enable_safe_overflow(false)
            .create()
            .expect("the old build's service");
        let spec = TransportSpec {
            kind: TransportKind::Shm,
            run: run.clone(),
            endpoint: "a".into(),
            listen: vec![],
            connect: vec![],
        };
        let mut t = ShmTransport::open(&spec).expect("transport");
        t.subscribe(&topic).expect("opened at the old depth");
        let mut p = t.publisher(&topic, &["a".to_string()]).expect("publisher");
        for i in 0..SUBSCRIBER_BUFFER as u8 {
            if i % 2 == 0 {
                p.send(&[i]).expect("send");
            } else {
                p.send_quiet(&[i]).expect("quiet send");
            }
        }
        p.ring().expect("ring");
        let mut got = Vec::new();
        while t
            .recv(Duration::from_millis(50), &mut |_, b| got.push(b.to_vec()))
            .expect("recv")
        {}
        let want: Vec<Vec<u8>> = (0..SUBSCRIBER_BUFFER as u8).map(|i| vec![i]).collect();
        assert_eq!(got, want);
        assert_eq!(
            old.static_config().subscriber_max_buffer_size(),
            SUBSCRIBER_BUFFER
        );
        drop((p, t, old, old_node));
        cleanup_run(&run);
    }
}
