//! zenoh transport (docs/architecture.md): the coordinator's session is a zenoh router
//! listening on loopback (or where the case says), every node is a client connected to it, so
//! all traffic passes the router. Scouting is off. Subscriptions feed one channel, so `recv`
//! waits on all topics at once; liveliness tokens under `cosim/<run>/alive/<endpoint>` let the
//! coordinator see a node die (its socket closes) within milliseconds.

use super::{PeerWatch, Publisher, TopicId, Transport, TransportError, TransportSpec};
use std::collections::BTreeSet;
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, TryRecvError, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::bytes::ZBytes;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::SampleKind;
use zenoh::{Config, Session, Wait};

/// Environment variable with extra zenoh settings, `key=json5value;...` (zenoh config paths
/// such as `transport/link/tls/root_ca_certificate="ca.pem"`), applied by every endpoint.
pub const ZENOH_CONFIG_ENV: &str = "COSIM_ZENOH_CONFIG";

/// Key expression of the liveliness token of `endpoint`.
pub fn alive_key(run: &str, endpoint: &str) -> String {
    format!("cosim/{run}/alive/{endpoint}")
}

/// A TCP port on 127.0.0.1 that was free a moment ago (zenoh's bound locator is only exposed
/// by its unstable API, so the coordinator picks the port itself and passes
/// `tcp/127.0.0.1:<port>` to the nodes). Another process could take it in between; opening
/// the router then fails with a clear error.
pub fn free_tcp_port() -> Result<u16, TransportError> {
    let l = std::net::TcpListener::bind(("127.0.0.1", 0))
        .map_err(|e| TransportError::Setup(format!("no free TCP port on 127.0.0.1: {e}")))?;
    l.local_addr()
        .map(|a| a.port())
        .map_err(|e| TransportError::Setup(format!("no free TCP port on 127.0.0.1: {e}")))
}

/// The loopback endpoint for `port`, as `listen`/`connect` take it.
pub fn loopback_endpoint(port: u16) -> String {
    format!("tcp/127.0.0.1:{port}")
}

fn json_list(items: &[String]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| format!("{s:?}")).collect();
    format!("[{}]", quoted.join(","))
}

fn config(spec: &TransportSpec) -> Result<Config, TransportError> {
    let mode = if !spec.listen.is_empty() {
        "router"
    } else if !spec.connect.is_empty() {
        "client"
    } else {
        return Err(TransportError::Setup(
            "a zenoh endpoint needs `listen` (the coordinator) or `connect` (a node)".into(),
        ));
    };
    let mut c = Config::default();
    let set = |c: &mut Config, key: &str, value: &str| {
        c.insert_json5(key, value)
            .map_err(|e| TransportError::Setup(format!("zenoh config {key} = {value}: {e}")))
    };
    set(&mut c, "mode", &format!("{mode:?}"))?;
    set(&mut c, "scouting/multicast/enabled", "false")?;
    set(&mut c, "scouting/gossip/enabled", "false")?;
    set(&mut c, "listen/endpoints", &json_list(&spec.listen))?;
    set(&mut c, "connect/endpoints", &json_list(&spec.connect))?;
    // Site-specific settings (TLS, interfaces, timeouts, ...): `key=json5;key=json5` in
    // COSIM_ZENOH_CONFIG, applied on top of the above.
    if let Ok(extra) = std::env::var(ZENOH_CONFIG_ENV) {
        for item in extra.split(';').map(str::trim).filter(|s| !s.is_empty()) {
            let Some((k, v)) = item.split_once('=') else {
                return Err(TransportError::Setup(format!(
                    "{ZENOH_CONFIG_ENV}: '{item}' is not key=value"
                )));
            };
            set(&mut c, k.trim(), v.trim())?;
        }
    }
    Ok(c)
}

type Inbox = (TopicId, ZBytes);

#[derive(Default)]
struct Liveliness {
    /// Endpoint → instances (one per process that declared it) with a live token.
    alive: std::collections::BTreeMap<String, BTreeSet<String>>,
    lost: Vec<String>,
}

/// One endpoint of a run over zenoh.
pub struct ZenohTransport {
    endpoint: String,
    run: String,
    tx: Sender<Inbox>,
    rx: Receiver<Inbox>,
    subs: Vec<Subscriber<()>>,
    token: Option<LivelinessToken>,
    liveliness: Arc<Mutex<Liveliness>>,
    _alive_sub: Option<Subscriber<()>>,
    /// Liveliness subscribers behind [`Transport::watch`].
    watches: Vec<Subscriber<()>>,
    /// Reused when a payload arrives in several fragments and must be made contiguous.
    scratch: Vec<u8>,
    /// How long `recv` polls before it blocks.
    spin: Duration,
    session: Session,
}

impl ZenohTransport {
    /// `listen` non-empty: a router listening there (the coordinator), which also watches
    /// the liveliness of the run's endpoints. Otherwise a client connected to `connect`.
    pub fn open(spec: &TransportSpec) -> Result<Self, TransportError> {
        let session = zenoh::open(config(spec)?).wait().map_err(|e| {
            TransportError::Setup(format!("zenoh session for '{}': {e}", spec.endpoint))
        })?;
        let (tx, rx) = channel();
        let liveliness = Arc::new(Mutex::new(Liveliness::default()));
        let alive_sub = if spec.listen.is_empty() {
            None
        } else {
            let prefix = alive_key(&spec.run, "");
            let live = liveliness.clone();
            let sub = session
                .liveliness()
                .declare_subscriber(format!("cosim/{}/alive/**", spec.run))
                .history(true)
                .callback(move |sample| {
                    // Tokens are `<endpoint>/<pid>`: a process that was turned away under a
                    // node's name must not make the accepted one look lost.
                    let key = sample.key_expr().as_str();
                    let rest = key.strip_prefix(&prefix).unwrap_or(key);
                    let (name, instance) = rest.split_once('/').unwrap_or((rest, ""));
                    let Ok(mut l) = live.lock() else { return };
                    match sample.kind() {
                        SampleKind::Put => {
                            l.alive
                                .entry(name.to_string())
                                .or_default()
                                .insert(instance.to_string());
                        }
                        SampleKind::Delete => {
                            let empty = l.alive.get_mut(name).is_some_and(|set| {
                                set.remove(instance);
                                set.is_empty()
                            });
                            if empty {
                                l.alive.remove(name);
                                l.lost.push(name.to_string());
                            }
                        }
                    }
                })
                .wait()
                .map_err(|e| TransportError::Setup(format!("liveliness subscriber: {e}")))?;
            Some(sub)
        };
        Ok(ZenohTransport {
            endpoint: spec.endpoint.clone(),
            run: spec.run.clone(),
            tx,
            rx,
            subs: Vec::new(),
            token: None,
            liveliness,
            _alive_sub: alive_sub,
            watches: Vec::new(),
            scratch: Vec::new(),
            spin: spin_time(),
            session,
        })
    }

    /// Endpoints whose liveliness token is currently declared (router side only).
    pub fn alive_endpoints(&self) -> Vec<String> {
        self.liveliness
            .lock()
            .map(|l| l.alive.keys().cloned().collect())
            .unwrap_or_default()
    }

    /// This endpoint's name.
    pub fn endpoint(&self) -> &str {
        &self.endpoint
    }

    /// Next message within `timeout`: polled (yielding the CPU between polls) for up to
    /// `spin` first, then a blocking wait. On a virtual machine an idle CPU sleeps deeply and
    /// waking it costs ~50 µs per message; polling for a short while keeps an answer that
    /// comes quickly (a window exchange) off that path, at the price of that much CPU per wait.
    fn poll(&mut self, timeout: Duration) -> Result<Inbox, RecvTimeoutError> {
        let start = Instant::now();
        let spin = self.spin.min(timeout);
        loop {
            match self.rx.try_recv() {
                Ok(m) => return Ok(m),
                Err(TryRecvError::Disconnected) => return Err(RecvTimeoutError::Disconnected),
                Err(TryRecvError::Empty) => {}
            }
            let waited = start.elapsed();
            if waited >= spin {
                return self.rx.recv_timeout(timeout.saturating_sub(waited));
            }
            std::thread::yield_now();
        }
    }
}

/// Polling time of [`ZenohTransport`]'s receive before it blocks, µs (environment
/// `COSIM_ZENOH_SPIN_US`, default 200; 0 blocks at once).
fn spin_time() -> Duration {
    let us = std::env::var("COSIM_ZENOH_SPIN_US")
        .ok()
        .and_then(|v| v.trim().parse::<u64>().ok())
        .unwrap_or(200);
    Duration::from_micros(us)
}

impl Drop for ZenohTransport {
    fn drop(&mut self) {
        self.token = None;
        self.subs.clear();
        self.watches.clear();
        if let Err(e) = self.session.close().wait() {
            tracing::warn!("closing the zenoh session of '{}': {e}", self.endpoint);
        }
    }
}

struct ZenohPublisher {
    topic: String,
    publisher: zenoh::pubsub::Publisher<'static>,
}

impl Publisher for ZenohPublisher {
    fn send(&mut self, bytes: &[u8]) -> Result<(), TransportError> {
        self.publisher
            .put(ZBytes::from(bytes))
            .wait()
            .map_err(|e| TransportError::Send {
                topic: self.topic.clone(),
                reason: e.to_string(),
            })
    }
}

impl Transport for ZenohTransport {
    fn publisher(
        &mut self,
        topic: &str,
        _readers: &[String],
    ) -> Result<Box<dyn Publisher>, TransportError> {
        let publisher = self
            .session
            .declare_publisher(topic.to_string())
            // Coupling data must never be dropped; express: no batching delay.
            .congestion_control(CongestionControl::Block)
            .priority(Priority::RealTime)
            .express(true)
            .wait()
            .map_err(|e| TransportError::Setup(format!("publisher on '{topic}': {e}")))?;
        Ok(Box::new(ZenohPublisher {
            topic: topic.to_string(),
            publisher,
        }))
    }

    fn subscribe(&mut self, topic: &str) -> Result<TopicId, TransportError> {
        let id = self.subs.len();
        let tx = self.tx.clone();
        let sub = self
            .session
            .declare_subscriber(topic.to_string())
            .callback(move |sample| {
                // The receiving transport may be gone while zenoh still delivers: not an error.
                let _ = tx.send((id, sample.payload().clone()));
            })
            .wait()
            .map_err(|e| TransportError::Setup(format!("subscriber on '{topic}': {e}")))?;
        self.subs.push(sub);
        Ok(id)
    }

    fn recv(
        &mut self,
        timeout: Duration,
        f: &mut dyn FnMut(TopicId, &[u8]),
    ) -> Result<bool, TransportError> {
        let (id, payload) = match self.poll(timeout) {
            Ok(m) => m,
            Err(RecvTimeoutError::Timeout) => return Ok(false),
            Err(RecvTimeoutError::Disconnected) => {
                return Err(TransportError::Recv("zenoh inbox closed".into()));
            }
        };
        let mut slices = payload.slices();
        match (slices.next(), slices.next()) {
            (Some(one), None) => f(id, one),
            (None, _) => f(id, &[]),
            (Some(_), Some(_)) => {
                // Fragmented on the wire: gather into a reused buffer.
                self.scratch.clear();
                self.scratch.reserve(payload.len());
                for s in payload.slices() {
                    self.scratch.extend_from_slice(s);
                }
                f(id, &self.scratch);
            }
        }
        Ok(true)
    }

    fn declare_alive(&mut self) -> Result<(), TransportError> {
        if self.token.is_none() {
            let key = format!(
                "{}/{}",
                alive_key(&self.run, &self.endpoint),
                std::process::id()
            );
            let token = self
                .session
                .liveliness()
                .declare_token(key.clone())
                .wait()
                .map_err(|e| TransportError::Setup(format!("liveliness token '{key}': {e}")))?;
            self.token = Some(token);
        }
        Ok(())
    }

    fn watch(&mut self, endpoint: &str) -> Result<Option<PeerWatch>, TransportError> {
        let watch = PeerWatch::default();
        let w = watch.clone();
        let key = format!("{}/**", alive_key(&self.run, endpoint));
        // The endpoint's token goes when its process dies or its connection (to this
        // client's router, which is the coordinator itself) closes.
        let sub = self
            .session
            .liveliness()
            .declare_subscriber(key.clone())
            .history(true)
            .callback(move |sample| match sample.kind() {
                SampleKind::Put => w.seen_alive(),
                SampleKind::Delete => w.seen_gone(),
            })
            .wait()
            .map_err(|e| TransportError::Setup(format!("liveliness subscriber '{key}': {e}")))?;
        self.watches.push(sub);
        Ok(Some(watch))
    }

    fn lost_endpoints(&mut self) -> Vec<String> {
        self.liveliness
            .lock()
            .map(|mut l| {
                // An endpoint that is alive again by now (another process of that name, e.g.
                // after one was turned away for a wrong token) is not lost.
                let lost = std::mem::take(&mut l.lost);
                lost.into_iter()
                    .filter(|n| !l.alive.contains_key(n))
                    .collect()
            })
            .unwrap_or_default()
    }
}
