//! Transport benchmark: the round trip of one coupling window as the coordinator sees it.
//! Per round the coordinator encodes and sends an `Advance` envelope to an echo endpoint,
//! which answers with a `Fields` envelope carrying the payload (n bytes of f64) on a data
//! topic, without waking it (as a node's data reaches the coordinator), and then a `Done`
//! that wakes it; the coordinator checks both with the full codec, reading the payload where
//! it lies ([`crate::codec::decode_fields_view`]). The table gives the median (and p10/p90) over
//! the measured rounds next to the median time of one plain memcpy of the payload bytes, the
//! floor any transport that copies the data has to pay, and (shared memory) a raw iceoryx2
//! round trip of the same bytes (the `Advance` down, the `Fields` envelope up), the floor of
//! the transport under it.
//!
//! Bench protocol: the echo side reads the payload length (number of f64 values) from
//! `Advance::t1`; `Advance` of window 0 is the start-up probe; `Finish` ends the echo side.

use super::local::LocalHub;
use super::{Publisher, TopicId, Transport, TransportError, TransportKind, TransportSpec};
use crate::codec::{
    CodecError, FIELDS_KIND, decode, decode_fields_view, encode_into, encoded_len, header,
};
use crate::message::{Advance, Done, Field, Fields, Finish, Message, StepReport, topic};
use std::fmt;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Environment variable through which the parent hands the echo child its `TransportSpec`
/// (JSON).
pub const ECHO_SPEC_ENV: &str = "COSIM_BENCH_ECHO_SPEC";
/// Payload sizes of the standard table: 1 KiB, 64 KiB, 1 MiB, 8 MiB.
pub const DEFAULT_SIZES: [usize; 4] = [1 << 10, 1 << 16, 1 << 20, 8 << 20];
/// The coupling the payload travels on (its data topic: `topic::data(run, "bench", "echo")`).
const BENCH_COUPLING: &str = "bench";
/// The echo side's endpoint name.
pub const ECHO_ENDPOINT: &str = "echo";
const COORDINATOR: &str = "coordinator";
/// How long one answer may take before the bench gives up.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(20);
/// How long the echo side waits for the next command before it exits on its own.
const ECHO_IDLE_TIMEOUT: Duration = Duration::from_secs(60);
/// Largest payload the echo side accepts (f64 values), below the codec's body limit.
const MAX_VALUES: usize = (crate::codec::MAX_BODY - 4096) / 8;

#[derive(Debug, Error)]
pub enum BenchError {
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error(transparent)]
    Codec(#[from] CodecError),
    #[error("echo process: {0}")]
    Io(#[from] std::io::Error),
    #[error("{0}")]
    Protocol(String),
}

/// One line of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchRow {
    pub transport: TransportKind,
    /// Payload bytes (f64 values × 8) inside the `Fields` answer.
    pub bytes: usize,
    pub rounds: usize,
    pub median_us: f64,
    pub p10_us: f64,
    pub p90_us: f64,
    /// Median time of one memcpy of `bytes` bytes.
    pub memcpy_us: f64,
    /// Median time of encoding plus decoding the `Fields` answer alone (no transport).
    pub codec_us: f64,
    /// Shared memory only: median round trip of the same bytes over raw iceoryx2 (the
    /// `Advance`'s bytes down, the `Fields` envelope's bytes up: loan, copy in, send, wake-up,
    /// read in place; [`iceoryx_variant_rtt_us`] with the transport's service variant),
    /// measured right after this row.
    pub raw_us: Option<f64>,
}

/// Rows rendered as a markdown table.
pub struct BenchTable<'a>(pub &'a [BenchRow]);

fn human_bytes(b: usize) -> String {
    if b >= 1 << 20 && b.is_multiple_of(1 << 20) {
        format!("{} MiB", b >> 20)
    } else if b >= 1 << 10 && b.is_multiple_of(1 << 10) {
        format!("{} KiB", b >> 10)
    } else {
        format!("{b} B")
    }
}

impl fmt::Display for BenchTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "| transport | payload | rounds | median µs | p10 µs | p90 µs | memcpy µs | codec µs | median / (2 memcpy) | raw iceoryx2 µs | median / raw |"
        )?;
        writeln!(f, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")?;
        for r in self.0 {
            let raw = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.1}"));
            writeln!(
                f,
                "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} |",
                r.transport.as_str(),
                human_bytes(r.bytes),
                r.rounds,
                r.median_us,
                r.p10_us,
                r.p90_us,
                r.memcpy_us,
                r.codec_us,
                r.median_us / (2.0 * r.memcpy_us.max(1e-3)),
                raw(r.raw_us),
                r.raw_us
                    .map_or("–".to_string(), |v| format!("{:.2}", r.median_us / v)),
            )?;
        }
        Ok(())
    }
}

/// Percentile `p` in [0, 1] of sorted samples (nearest rank).
fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Median time (µs) of copying `bytes` bytes between two preallocated buffers.
pub fn memcpy_median_us(bytes: usize, rounds: usize) -> f64 {
    let src: Vec<u8> = (0..bytes).map(|i| i as u8).collect();
    let mut dst = vec![0u8; bytes];
    dst.copy_from_slice(&src);
    let mut t = Vec::with_capacity(rounds);
    for _ in 0..rounds.max(1) {
        let t0 = Instant::now();
        dst.copy_from_slice(std::hint::black_box(&src));
        std::hint::black_box(&mut dst);
        t.push(t0.elapsed().as_secs_f64() * 1e6);
    }
    t.sort_by(f64::total_cmp);
    percentile(&t, 0.5)
}

/// Median time (µs) of encoding a `Fields` envelope of `bytes` payload bytes into a reused
/// buffer and decoding it again: the codec's share of a window exchange.
pub fn codec_median_us(bytes: usize, rounds: usize) -> Result<f64, BenchError> {
    let values = bytes / 8;
    let m = payload(1, (0..values).map(|i| i as f64).collect());
    let mut buf = Vec::new();
    encode_into(&mut buf, "run", ECHO_ENDPOINT, 1, &m)?;
    let mut t = Vec::with_capacity(rounds);
    for _ in 0..rounds.max(1) {
        let t0 = Instant::now();
        encode_into(&mut buf, "run", ECHO_ENDPOINT, 1, std::hint::black_box(&m))?;
        let back = decode(std::hint::black_box(&buf))?;
        std::hint::black_box(&back);
        drop(back);
        t.push(t0.elapsed().as_secs_f64() * 1e6);
    }
    t.sort_by(f64::total_cmp);
    Ok(percentile(&t, 0.5))
}

static BENCH_COUNTER: AtomicU32 = AtomicU32::new(0);

fn bench_run_id() -> String {
    format!(
        "bench{}x{}",
        std::process::id(),
        BENCH_COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// Kills the echo child if the bench returns early.
struct ChildGuard(Option<Child>);

impl ChildGuard {
    /// Wait up to `d` for a clean exit, then kill.
    fn finish(&mut self, d: Duration) {
        if let Some(mut c) = self.0.take() {
            let end = Instant::now() + d;
            while Instant::now() < end {
                if let Ok(Some(_)) = c.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(5));
            }
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Measure `rounds` window round trips per payload size over `kind`. `echo_cmd` starts the
/// echo side in a child process (it must end up calling [`echo_main`] with the spec from
/// [`echo_spec_from_env`]); for `TransportKind::Local` the echo runs in a thread instead and
/// `echo_cmd` is not used.
pub fn bench_transport(
    kind: TransportKind,
    payload_sizes: &[usize],
    rounds: usize,
    echo_cmd: &mut Command,
) -> Result<Vec<BenchRow>, BenchError> {
    let run = bench_run_id();
    if kind == TransportKind::Local {
        return bench_local(&run, payload_sizes, rounds);
    }
    let (mine, theirs) = match kind {
        TransportKind::Zenoh => {
            let ep = super::zenoh::loopback_endpoint(super::zenoh::free_tcp_port()?);
            (
                spec(kind, &run, COORDINATOR, vec![ep.clone()], vec![]),
                spec(kind, &run, ECHO_ENDPOINT, vec![], vec![ep]),
            )
        }
        _ => (
            spec(kind, &run, COORDINATOR, vec![], vec![]),
            spec(kind, &run, ECHO_ENDPOINT, vec![], vec![]),
        ),
    };
    super::cleanup(kind, &run);
    let json = serde_json::to_string(&theirs)
        .map_err(|e| BenchError::Protocol(format!("echo spec does not serialise: {e}")))?;
    let result = (|| {
        // The router (zenoh) must be up before the child connects to it.
        let mut t = super::open(&mine)?;
        let child = echo_cmd
            .env(ECHO_SPEC_ENV, &json)
            .stdin(Stdio::null())
            .spawn()?;
        let mut guard = ChildGuard(Some(child));
        let rows = drive(&mut *t, kind, &run, payload_sizes, rounds)?;
        guard.finish(Duration::from_secs(5));
        Ok(rows)
    })();
    super::cleanup(kind, &run);
    result
}

fn spec(
    kind: TransportKind,
    run: &str,
    endpoint: &str,
    listen: Vec<String>,
    connect: Vec<String>,
) -> TransportSpec {
    TransportSpec {
        kind,
        run: run.to_string(),
        endpoint: endpoint.to_string(),
        listen,
        connect,
    }
}

fn bench_local(run: &str, sizes: &[usize], rounds: usize) -> Result<Vec<BenchRow>, BenchError> {
    let hub = LocalHub::new();
    let mut me = hub.endpoint(COORDINATOR);
    let mut echo = hub.endpoint(ECHO_ENDPOINT);
    let run_echo = run.to_string();
    let handle = std::thread::spawn(move || echo_loop(&mut echo, &run_echo, ECHO_ENDPOINT));
    let rows = drive(&mut me, TransportKind::Local, run, sizes, rounds);
    // On success the echo thread has received Finish; on failure it ends at its idle timeout,
    // so it is detached rather than joined.
    if rows.is_ok() {
        match handle.join() {
            Ok(r) => r?,
            Err(_) => return Err(BenchError::Protocol("echo thread panicked".into())),
        }
    }
    rows
}

/// The echo side of a child process: open the transport described by `spec` and answer
/// until `Finish`.
pub fn echo_main(spec: &TransportSpec) -> Result<(), BenchError> {
    let mut t = super::open(spec)?;
    t.declare_alive()?;
    echo_loop(&mut *t, &spec.run, &spec.endpoint)
}

/// The spec the parent passed to the echo child.
pub fn echo_spec_from_env() -> Result<TransportSpec, BenchError> {
    let json = std::env::var(ECHO_SPEC_ENV)
        .map_err(|_| BenchError::Protocol(format!("{ECHO_SPEC_ENV} is not set")))?;
    serde_json::from_str(&json).map_err(|e| BenchError::Protocol(format!("{ECHO_SPEC_ENV}: {e}")))
}

fn echo_loop(t: &mut dyn Transport, run: &str, me: &str) -> Result<(), BenchError> {
    t.subscribe(&topic::down(run, me))?;
    let mut up = t.publisher(&topic::up(run, me), &[COORDINATOR.to_string()])?;
    // The payload goes on a data topic, as a node's coupling data does (its queue depth and
    // sample pool are a data topic's).
    let mut data = t.publisher(
        &topic::data(run, BENCH_COUPLING, me),
        &[COORDINATOR.to_string()],
    )?;
    let mut answer = payload(0, Vec::new());
    let mut done = Message::Done(Done {
        window: 0,
        report: StepReport::default(),
    });
    let mut buf = Vec::new();
    let mut seq = 0u64;
    loop {
        let mut cmd = None;
        let got = t.recv(ECHO_IDLE_TIMEOUT, &mut |_, bytes| cmd = Some(decode(bytes)))?;
        let Some(cmd) = cmd else {
            if got {
                continue;
            }
            return Err(BenchError::Protocol(format!(
                "no command for {ECHO_IDLE_TIMEOUT:?}"
            )));
        };
        match cmd?.message {
            Message::Advance(a) => {
                let n = a.t1;
                if !(n.is_finite() && n >= 0.0 && n <= MAX_VALUES as f64) {
                    return Err(BenchError::Protocol(format!("bad payload length {n}")));
                }
                let n = n as usize;
                if let Message::Fields(fl) = &mut answer {
                    fl.window = a.window;
                    let v = &mut fl.fields[0].values;
                    if v.len() != n {
                        v.clear();
                        v.extend((0..n).map(|i| i as f64));
                    }
                }
                if let Message::Done(d) = &mut done {
                    d.window = a.window;
                }
                // As a node sends its coupling data (participant runtime): in place where
                // the transport allows, and without waking the coordinator, which the `Done`
                // after it wakes (the runtime's data topics ring the peer only).
                seq += 1;
                data.send_message_ringing(run, me, seq, &answer, &mut buf, false)?;
                seq += 1;
                up.send_message(run, me, seq, &done, &mut buf)?;
            }
            Message::Finish(_) => return Ok(()),
            _ => {}
        }
    }
}

/// What the coordinator side saw of one window's answers.
#[derive(Default)]
struct Answers {
    fields: bool,
    done: bool,
    error: Option<String>,
}

fn await_window(
    t: &mut dyn Transport,
    window: u64,
    values: usize,
    timeout: Duration,
) -> Result<bool, BenchError> {
    let mut a = Answers::default();
    let end = Instant::now() + timeout;
    while !(a.fields && a.done) {
        let now = Instant::now();
        if now >= end {
            return Ok(false);
        }
        t.recv(end - now, &mut |_: TopicId, bytes: &[u8]| {
            // The payload is read where it lies (a shared-memory sample), never copied out.
            if header(bytes).is_ok_and(|h| h.kind == FIELDS_KIND) {
                match decode_fields_view(bytes) {
                    Ok(fl) if fl.window == window => {
                        let ok = fl.fields.len() == 1
                            && fl.fields[0].len() == values
                            && (values == 0
                                || fl.fields[0].get(values - 1) == Some((values - 1) as f64));
                        if ok {
                            a.fields = true;
                        } else {
                            a.error = Some(format!("window {window}: payload arrived altered"));
                        }
                    }
                    // Answers to earlier probes.
                    Ok(_) => {}
                    Err(e) => a.error = Some(e.to_string()),
                }
                return;
            }
            match decode(bytes) {
                Ok(env) => match env.message {
                    Message::Done(d) if d.window == window => a.done = true,
                    _ => {}
                },
                Err(e) => a.error = Some(e.to_string()),
            }
        })?;
        if let Some(e) = a.error.take() {
            return Err(BenchError::Protocol(e));
        }
    }
    Ok(true)
}

/// Bytes of the window's `Advance` and of its `Fields` answer of `values` values, as
/// encoded on the wire: what the raw round trip moves.
/// The benchmarks' window data: one `Fields` message of coupling `bench` holding `values`.
fn payload(window: u64, values: Vec<f64>) -> Message {
    Message::Fields(Fields {
        coupling: BENCH_COUPLING.into(),
        window,
        time: 0.0,
        fields: vec![Field {
            name: "payload".into(),
            components: 1,
            values,
        }],
    })
}

fn envelope_lens(run: &str, values: usize) -> Result<(usize, usize), BenchError> {
    let advance = Message::Advance(Advance {
        window: 1,
        t0: 0.0,
        t1: values as f64,
        write_output: false,
        checkpoint: false,
    });
    let fields = payload(1, vec![0.0; values]);
    Ok((
        encoded_len(run, COORDINATOR, &advance)?,
        encoded_len(run, ECHO_ENDPOINT, &fields)?,
    ))
}

fn drive(
    t: &mut dyn Transport,
    kind: TransportKind,
    run: &str,
    sizes: &[usize],
    rounds: usize,
) -> Result<Vec<BenchRow>, BenchError> {
    t.subscribe(&topic::up(run, ECHO_ENDPOINT))?;
    t.subscribe(&topic::data(run, BENCH_COUPLING, ECHO_ENDPOINT))?;
    let mut down = t.publisher(
        &topic::down(run, ECHO_ENDPOINT),
        &[ECHO_ENDPOINT.to_string()],
    )?;
    let mut buf = Vec::new();
    let mut seq = 0u64;
    let mut send =
        |down: &mut Box<dyn Publisher>, window: u64, values: usize| -> Result<(), BenchError> {
            seq += 1;
            let m = Message::Advance(Advance {
                window,
                t0: 0.0,
                t1: values as f64,
                write_output: false,
                checkpoint: false,
            });
            encode_into(&mut buf, run, COORDINATOR, seq, &m)?;
            down.send(&buf)?;
            Ok(())
        };

    // Start-up: probe until the echo side answers (messages sent before it subscribed are
    // lost by design, so probe again rather than wait on one).
    let start = Instant::now();
    loop {
        send(&mut down, 0, 0)?;
        if await_window(t, 0, 0, Duration::from_millis(100))? {
            break;
        }
        if start.elapsed() > ANSWER_TIMEOUT {
            return Err(BenchError::Protocol(format!(
                "the echo side did not answer within {ANSWER_TIMEOUT:?}"
            )));
        }
    }

    let mut rows = Vec::new();
    let mut window = 0u64;
    let warmup = (rounds / 10).max(20);
    for &bytes in sizes {
        let values = bytes / 8;
        let mut times = Vec::with_capacity(rounds);
        for r in 0..warmup + rounds {
            window += 1;
            let t0 = Instant::now();
            send(&mut down, window, values)?;
            if !await_window(t, window, values, ANSWER_TIMEOUT)? {
                return Err(BenchError::Protocol(format!(
                    "no answer to window {window} within {ANSWER_TIMEOUT:?}"
                )));
            }
            if r >= warmup {
                times.push(t0.elapsed().as_secs_f64() * 1e6);
            }
        }
        times.sort_by(f64::total_cmp);
        rows.push(BenchRow {
            transport: kind,
            bytes: values * 8,
            rounds,
            median_us: percentile(&times, 0.5),
            p10_us: percentile(&times, 0.1),
            p90_us: percentile(&times, 0.9),
            memcpy_us: memcpy_median_us(values * 8, rounds),
            codec_us: codec_median_us(values * 8, rounds.min(50))?,
            raw_us: if kind == TransportKind::Shm {
                let (request, answer) = envelope_lens(run, values)?;
                Some(iceoryx_variant_rtt_us::<
                    iceoryx2::service::ipc_threadsafe::Service,
                >(request, answer, rounds)?)
            } else {
                None
            },
        });
    }
    seq += 1;
    encode_into(
        &mut buf,
        run,
        COORDINATOR,
        seq,
        &Message::Finish(Finish {
            reason: "bench done".into(),
        }),
    )?;
    down.send(&buf)?;
    Ok(rows)
}

/// Median round trip (µs) over raw iceoryx2 between two threads, pub/sub plus event
/// wake-ups with service variant `S`: one side sends `request` bytes, the other answers with
/// `answer` bytes, as a window exchange does (an `Advance` down, the `Fields` envelope up).
/// Each side does the least any user of the transport must: the answer's bytes are copied
/// into the loaned sample (as encoding into it does) and read where they lie on arrival (its
/// length and last value checked, as the bench's reader of the `Fields` view does).
pub fn iceoryx_variant_rtt_us<S: iceoryx2::service::Service>(
    request: usize,
    answer: usize,
    rounds: usize,
) -> Result<f64, TransportError> {
    use iceoryx2::prelude::*;
    let run = bench_run_id();
    let setup = |e: &dyn std::fmt::Debug| TransportError::Setup(format!("{e:?}"));
    let mut config = Config::default();
    config.global.prefix =
        FileName::new(super::shm::prefix(&run).as_bytes()).map_err(|e| setup(&e))?;
    let total = rounds + (rounds / 10).max(20);
    let side = move |config: Config,
                     me: &'static str,
                     other: &'static str,
                     lead: bool|
          -> Result<Vec<f64>, TransportError> {
        let setup = |e: &dyn std::fmt::Debug| TransportError::Setup(format!("{e:?}"));
        let (send_len, recv_len) = if lead {
            (request, answer)
        } else {
            (answer, request)
        };
        let node = NodeBuilder::new()
            .config(&config)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<S>()
            .map_err(|e| setup(&e))?;
        // One publisher and one subscriber with small queues, as the shm transport sets its
        // topics up: the sample pool stays small, so its pages are warm after the warm-up
        // rounds (iceoryx2's defaults preallocate dozens of samples, each faulted in on first
        // use, which would time the page faults rather than the transport).
        let topic = |n: &str| -> Result<_, TransportError> {
            node.service_builder(&ServiceName::new(n).map_err(|e| setup(&e))?)
                .publish_subscribe::<[u8]>()
                .max_publishers(1)
                .max_subscribers(1)
                .subscriber_max_buffer_size(2)
                .subscriber_max_borrowed_samples(1)
                .history_size(0)
                .enable_safe_overflow(false)
                .open_or_create()
                .map_err(|e| setup(&e))
        };
        let bell = |n: &str| -> Result<_, TransportError> {
            node.service_builder(&ServiceName::new(n).map_err(|e| setup(&e))?)
                .event()
                .open_or_create()
                .map_err(|e| setup(&e))
        };
        let out_svc = topic(other)?;
        let in_svc = topic(me)?;
        let publisher = out_svc
            .publisher_builder()
            .initial_max_slice_len(send_len.max(1))
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .max_loaned_samples(1)
            .create()
            .map_err(|e| setup(&e))?;
        let sub = in_svc
            .subscriber_builder()
            .create()
            .map_err(|e| setup(&e))?;
        let my_bell = bell(&format!("{me}/bell"))?;
        let their_bell = bell(&format!("{other}/bell"))?;
        let listener = my_bell.listener_builder().create().map_err(|e| setup(&e))?;
        let notifier = their_bell
            .notifier_builder()
            .create()
            .map_err(|e| setup(&e))?;
        while out_svc.dynamic_config().number_of_subscribers() == 0
            || their_bell.dynamic_config().number_of_listeners() == 0
        {
            std::thread::sleep(Duration::from_millis(1));
        }
        std::thread::sleep(Duration::from_millis(20));
        let data: Vec<u8> = (0..send_len).map(|i| i as u8).collect();
        let mut times = Vec::with_capacity(total);
        let send = || -> Result<(), TransportError> {
            let s = publisher
                .loan_slice_uninit(send_len)
                .map_err(|e| setup(&e))?;
            s.write_from_slice(&data).send().map_err(|e| setup(&e))?;
            notifier.notify().map_err(|e| setup(&e))?;
            Ok(())
        };
        for _ in 0..total {
            let t0 = Instant::now();
            if lead {
                send()?;
            }
            loop {
                if let Some(s) = sub.receive().map_err(|e| setup(&e))? {
                    let got = s.payload();
                    let want_last = (recv_len > 0).then(|| (recv_len - 1) as u8);
                    if got.len() != recv_len
                        || std::hint::black_box(got.last().copied()) != want_last
                    {
                        return Err(TransportError::Recv(format!(
                            "raw round trip: {} bytes arrived, {recv_len} sent",
                            got.len()
                        )));
                    }
                    break;
                }
                listener
                    .timed_wait(|_| {}, ANSWER_TIMEOUT)
                    .map_err(|e| setup(&e))?;
            }
            if !lead {
                send()?;
            }
            times.push(t0.elapsed().as_secs_f64() * 1e6);
        }
        Ok(times)
    };
    let c2 = config.clone();
    let echo = std::thread::spawn(move || side(c2, "raw/pong", "raw/ping", false));
    let times = side(config, "raw/ping", "raw/pong", true);
    let echoed = echo.join();
    cleanup_run_files(&run);
    let mut times = times?;
    match echoed {
        Ok(r) => {
            r?;
        }
        Err(_) => return Err(TransportError::Setup("echo thread panicked".into())),
    }
    let mut t = times.split_off(total - rounds);
    t.sort_by(f64::total_cmp);
    Ok(percentile(&t, 0.5))
}

fn cleanup_run_files(run: &str) {
    super::shm::cleanup_run(run);
}
