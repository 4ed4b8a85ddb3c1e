//! MCAP recorder (docs/architecture.md): one channel per topic carrying the exact envelope bytes
//! (message encoding `bincode`, schema `cosim.Envelope` whose data is the Rust source of the
//! message types), plus JSON channels (schema encoding `jsonschema`, listing every key their
//! messages carry) with per-window metrics for Foxglove. A message's log time is the
//! simulated time (Foxglove's timeline), its publish time the wall clock. Chunked and
//! zstd-compressed; chunks are flushed regularly so a killed coordinator leaves a file whose
//! completed chunks are readable.

use anyhow::Context;
use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions, Writer};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// The definition of the recorded bytes, stored as the schema of every bincode channel: the
/// header, the body and the Rust source of every message type (`wire/src/message.rs`).
pub const ENVELOPE_SCHEMA: &str = concat!(
    "// A cosim envelope: a 20-byte little-endian header (magic \"CSIM\", u16 protocol version,\n",
    "// u8 message kind, u8 reserved, u32 body length, u64 sequence number), then the body in\n",
    "// bincode 2 (serde, config::standard(): varint integers, little-endian floats):\n",
    "//     struct Body { run: String, sender: String, message: Message }\n",
    "// with Message and every type it holds defined below. The recording's metadata record\n",
    "// \"cosim\" names the protocol version.\n\n",
    include_str!("../../wire/src/message.rs")
);
pub const ENVELOPE_SCHEMA_NAME: &str = "cosim.Envelope";
pub const BINCODE_ENCODING: &str = "bincode";

pub struct Recorder {
    w: Writer<BufWriter<File>>,
    /// The file, named in every write error (a full disk says which file it stopped).
    path: std::path::PathBuf,
    bincode_schema: u16,
    /// Topic → (channel id, sequence, the keys its schema lists: JSON channels only).
    channels: HashMap<String, (u16, u32, BTreeMap<String, &'static str>)>,
    last_flush: Instant,
    pub messages: u64,
    pub bytes: u64,
}

fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0)
}

/// Simulation time in ns for MCAP's log time.
pub fn sim_ns(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round() as u64
    } else {
        0
    }
}

impl Recorder {
    pub fn create(path: &Path) -> anyhow::Result<Self> {
        let f = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
        let mut w = Writer::with_options(
            BufWriter::new(f),
            WriteOptions::new()
                .compression(Some(Compression::Zstd))
                .chunk_size(Some(1 << 20))
                // The fastest zstd level, on the recorder thread itself: compression worker
                // threads would only compete with the nodes for the cores.
                .compression_level(1)
                .compression_threads(0)
                .profile("cosim"),
        )?;
        w.write_metadata(&mcap::records::Metadata {
            name: "cosim".into(),
            metadata: BTreeMap::from([
                ("version".into(), env!("CARGO_PKG_VERSION").into()),
                ("git_commit".into(), env!("COSIM_GIT_COMMIT").into()),
                (
                    "wire_version".into(),
                    protocol::PROTOCOL_VERSION.to_string(),
                ),
                ("started_unix_ns".into(), now_ns().to_string()),
                (
                    "timeline".into(),
                    "log_time = simulated time (ns), publish_time = wall clock (ns since 1970)"
                        .into(),
                ),
            ]),
        })?;
        let bincode_schema = w.add_schema(
            ENVELOPE_SCHEMA_NAME,
            "rust-serde-bincode",
            ENVELOPE_SCHEMA.as_bytes(),
        )?;
        Ok(Recorder {
            w,
            path: path.to_path_buf(),
            bincode_schema,
            channels: HashMap::new(),
            last_flush: Instant::now(),
            messages: 0,
            bytes: 0,
        })
    }

    /// The channel of `topic`; for a JSON document, one whose schema lists all of `doc`'s
    /// keys (a document with a key its channel's schema lacks opens a new channel on the same
    /// topic, with the union of both).
    fn channel(
        &mut self,
        topic: &str,
        json: Option<(&str, &serde_json::Value)>,
    ) -> anyhow::Result<u16> {
        // Per window and node: the common case (a known channel, no new key) allocates nothing.
        if let Some((id, _, have)) = self.channels.get(topic) {
            let known = match json.map(|(_, doc)| doc) {
                None => true,
                Some(serde_json::Value::Object(m)) => all_known(m, have),
                Some(_) => true,
            };
            if known {
                return Ok(*id);
            }
        }
        let (id, keys) = match json {
            Some((name, doc)) => {
                let mut keys = keys_of(doc);
                if let Some((_, _, have)) = self.channels.get(topic) {
                    for (k, t) in have {
                        keys.entry(k.clone()).or_insert(t);
                    }
                }
                let schema = object_schema(name, &keys);
                let sid = self.w.add_schema(name, "jsonschema", schema.as_bytes())?;
                (
                    self.w.add_channel(sid, topic, "json", &BTreeMap::new())?,
                    keys,
                )
            }
            None => (
                self.w.add_channel(
                    self.bincode_schema,
                    topic,
                    BINCODE_ENCODING,
                    &BTreeMap::new(),
                )?,
                BTreeMap::new(),
            ),
        };
        let seq = self.channels.get(topic).map_or(0, |c| c.1);
        self.channels.insert(topic.to_string(), (id, seq, keys));
        Ok(id)
    }

    fn write(
        &mut self,
        topic: &str,
        json: Option<(&str, &serde_json::Value)>,
        sim_t: f64,
        data: &[u8],
    ) -> anyhow::Result<()> {
        self.write_at(topic, json, sim_t, data, now_ns())
    }

    /// [`Recorder::write`] with the publish time given: when the coordinator saw the message,
    /// not when a thread wrote it.
    fn write_at(
        &mut self,
        topic: &str,
        json: Option<(&str, &serde_json::Value)>,
        sim_t: f64,
        data: &[u8],
        publish_ns: u64,
    ) -> anyhow::Result<()> {
        let id = self.channel(topic, json)?;
        let seq = {
            let e = self.channels.get_mut(topic).map(|e| &mut e.1);
            match e {
                Some(s) => {
                    *s += 1;
                    *s
                }
                None => 0,
            }
        };
        self.w.write_to_known_channel(
            &MessageHeader {
                channel_id: id,
                sequence: seq,
                log_time: sim_ns(sim_t),
                publish_time: publish_ns,
            },
            data,
        )?;
        self.messages += 1;
        self.bytes += data.len() as u64;
        if self.last_flush.elapsed().as_millis() > 500 {
            self.flush()?;
        }
        Ok(())
    }

    /// Record the exact bytes of a protocol message seen on `topic`.
    pub fn message(&mut self, topic: &str, sim_t: f64, bytes: &[u8]) -> anyhow::Result<()> {
        self.write(topic, None, sim_t, bytes)
    }

    /// Record a JSON object on a metrics channel whose schema (`schema_name`) lists its keys.
    pub fn json(
        &mut self,
        topic: &str,
        schema_name: &str,
        sim_t: f64,
        v: &serde_json::Value,
    ) -> anyhow::Result<()> {
        self.json_at(topic, schema_name, sim_t, v, now_ns())
    }

    /// [`Recorder::json`] with the publish time given.
    fn json_at(
        &mut self,
        topic: &str,
        schema_name: &str,
        sim_t: f64,
        v: &serde_json::Value,
        publish_ns: u64,
    ) -> anyhow::Result<()> {
        let data = serde_json::to_vec(v)?;
        self.write_at(topic, Some((schema_name, v)), sim_t, &data, publish_ns)
    }

    /// Close the current chunk and push it to disk.
    pub fn flush(&mut self) -> anyhow::Result<()> {
        self.w.flush()?;
        self.last_flush = Instant::now();
        Ok(())
    }

    /// Close the current chunk if the last flush is older than `age` (called at window
    /// boundaries: a killed coordinator loses at most the windows of that last stretch).
    pub fn flush_if_older(&mut self, age: std::time::Duration) -> anyhow::Result<()> {
        if self.last_flush.elapsed() >= age {
            self.flush()?;
        }
        Ok(())
    }

    /// Write summary and footer.
    pub fn finish(mut self) -> anyhow::Result<()> {
        let path = self.path.clone();
        let cannot = || format!("cannot write {}", path.display());
        self.w.finish().with_context(cannot)?;
        // The last buffered bytes are written here, not when the buffer is dropped, where
        // an error (a full disk) would be lost.
        self.w.into_inner().flush().with_context(cannot)?;
        Ok(())
    }
}

/// The JSON Schema type of each leaf of an object, by dotted path (nested objects are
/// walked, see [`crate::nest`]; empty for anything else).
fn keys_of(doc: &serde_json::Value) -> BTreeMap<String, &'static str> {
    use serde_json::Value;
    let Value::Object(m) = doc else {
        return BTreeMap::new();
    };
    let mut out = BTreeMap::new();
    crate::nest::for_each_leaf(m, &mut |k, v| {
        let ty = match v {
            // serde_json writes a NaN or infinite f64 as null
            Value::Null | Value::Number(_) => "number",
            Value::Bool(_) => "boolean",
            Value::String(_) => "string",
            Value::Array(_) => "array",
            Value::Object(_) => "object",
        };
        out.insert(k.to_string(), ty);
    });
    out
}

/// Whether every leaf of `doc` is one of `have`'s keys (allocates only for nested objects).
fn all_known<V>(
    doc: &serde_json::Map<String, serde_json::Value>,
    have: &BTreeMap<String, V>,
) -> bool {
    if !crate::nest::has_nested(doc) {
        return doc.keys().all(|k| have.contains_key(k));
    }
    let mut all = true;
    crate::nest::for_each_leaf(doc, &mut |k, _| all &= have.contains_key(k));
    all
}

/// A JSON Schema (draft 2020-12) of an object with these keys (dotted paths of nested
/// objects, as [`keys_of`] gives them) and types; a number may be null (a NaN or infinite
/// value), an array is a vector: its components `[x, y, z]` (`[x, y]` in 2-D) as numbers
/// (Foxglove plots `KEY[0]`; the flat tables name them `KEY_x`, `KEY_y`, `KEY_z`).
pub fn object_schema(title: &str, keys: &BTreeMap<String, &'static str>) -> String {
    let props = crate::nest::properties(
        keys.iter().map(|(k, ty)| {
            let v = match *ty {
                "number" => serde_json::json!({ "type": ["number", "null"] }),
                "array" => serde_json::json!({
                    "type": "array",
                    "description": "a vector: [x, y, z], or [x, y] in 2-D",
                    "items": { "type": ["number", "null"] },
                    "minItems": 2,
                    "maxItems": 3,
                }),
                t => serde_json::json!({ "type": t }),
            };
            (k.as_str(), v)
        }),
        &|k| keys.contains_key(k),
    );
    serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "type": "object",
        "properties": props,
    })
    .to_string()
}

/// One recorded message, as read back.
pub struct Recorded {
    pub topic: String,
    /// Simulated time (ns).
    pub log_time: u64,
    pub data: Vec<u8>,
    pub json: bool,
}

/// The JSON messages of a recording (balance, node reports, case), in file order; the binary
/// coupling traffic is skipped without being copied. `complete` as for [`read_all`].
pub fn read_json(path: &Path) -> anyhow::Result<(Vec<Recorded>, bool)> {
    read_where(path, true)
}

/// Read every message of a recording in file order; `complete` is false when the file ended
/// early (a killed writer): the messages of its completed chunks are still returned. A
/// restarted run's segments are read as one run (see [`segments`]). Node reports come back
/// flat: a scalar recorded nested (`{"point1": {"pressure": …}}`) as `point1.pressure`.
pub fn read_all(path: &Path) -> anyhow::Result<(Vec<Recorded>, bool)> {
    read_where(path, false)
}

/// JSON channel of the checkpoint marks: `{window, time, dir}` once every node and the
/// coordinator have written their state at the end of `window`.
pub const CHECKPOINT_TOPIC: &str = "/cosim/checkpoint";
/// JSON channel marking where a restarted segment's windows begin: `{window}` of the
/// checkpoint it continues from. What precedes it in the segment (the new handshake, set-up
/// and restore) is not part of the run's history.
pub const RESUMED_TOPIC: &str = "/cosim/resumed";

/// The segments of a recording: `run.mcap`, then the `run.1.mcap`, `run.2.mcap`, ... that
/// restarts wrote beside it, in order.
pub fn segments(path: &Path) -> Vec<std::path::PathBuf> {
    let mut v = vec![path.to_path_buf()];
    if let (Some(dir), Some(stem), Some("mcap")) = (
        path.parent(),
        path.file_stem().and_then(|s| s.to_str()),
        path.extension().and_then(|e| e.to_str()),
    ) {
        for i in 1.. {
            let p = dir.join(format!("{stem}.{i}.mcap"));
            if !p.exists() {
                break;
            }
            v.push(p);
        }
    }
    v
}

fn json_window(m: &Recorded) -> Option<u64> {
    serde_json::from_slice::<serde_json::Value>(&m.data)
        .ok()?
        .get("window")?
        .as_u64()
}

/// The window of a recorded `Fields` message (None for anything else).
fn fields_window(m: &Recorded) -> Option<u64> {
    if m.json {
        return None;
    }
    match protocol::decode(&m.data).ok()?.message {
        protocol::Message::Fields(f) => Some(f.window),
        _ => None,
    }
}

/// Drop from `msgs` what came after the checkpoint of window `k` (the windows a restart runs
/// again), keeping the coupling data of windows up to `k` that arrived late.
fn cut_after_checkpoint(msgs: &mut Vec<Recorded>, k: u64) {
    let mark = msgs
        .iter()
        .rposition(|m| m.topic == CHECKPOINT_TOPIC && json_window(m) == Some(k))
        .map(|j| j + 1);
    // Without its mark (not expected: it is flushed before the coordinator's state is
    // written), the first Advance past k bounds the windows up to k.
    let at = mark.or_else(|| {
        msgs.iter().position(|m| {
            !m.json
                && matches!(protocol::decode(&m.data),
                    Ok(e) if matches!(e.message, protocol::Message::Advance(a) if a.window > k))
        })
    });
    let Some(at) = at else { return };
    let tail = msgs.split_off(at);
    msgs.extend(
        tail.into_iter()
            .filter(|m| fields_window(m).is_some_and(|w| w <= k)),
    );
}

fn read_where(path: &Path, json_only: bool) -> anyhow::Result<(Vec<Recorded>, bool)> {
    let segs = segments(path);
    if segs.len() == 1 {
        return read_segment(path, json_only);
    }
    // A restarted run: each later segment continues from a checkpoint of what precedes it.
    let (mut out, mut complete) = read_segment(&segs[0], false)?;
    for s in &segs[1..] {
        let (msgs, c) = read_segment(s, false)?;
        let Some(i) = msgs.iter().position(|m| m.topic == RESUMED_TOPIC) else {
            // a restart that ended before it resumed adds nothing
            complete = false;
            continue;
        };
        let Some(k) = json_window(&msgs[i]) else {
            anyhow::bail!("{}: its resume mark names no window", s.display());
        };
        cut_after_checkpoint(&mut out, k);
        // The restore sends the `Fields` of window k again, recorded before the mark (while
        // the coordinator awaits the restores) or after it: keep them only where the earlier
        // segment lost its own (a coordinator killed before it recorded them).
        let have: std::collections::HashSet<(String, u64)> = out
            .iter()
            .filter_map(|m| Some((m.topic.clone(), fields_window(m)?)))
            .collect();
        out.extend(msgs.into_iter().enumerate().filter_map(|(j, m)| {
            let keep = match fields_window(&m) {
                Some(w) if w <= k => !have.contains(&(m.topic.clone(), w)),
                _ => j > i,
            };
            keep.then_some(m)
        }));
        complete = c;
    }
    if json_only {
        out.retain(|m| m.json);
    }
    Ok((out, complete))
}

/// Prefix of the JSON channels of the node reports (`/cosim/node/<name>`).
pub const NODE_TOPIC_PREFIX: &str = "/cosim/node/";

/// A node report recorded with nested objects (dotted scalar names, [`crate::nest`]) as the
/// flat object of dotted names our readers use; `None` when it has none (or is no object).
fn flat_report(data: &[u8]) -> Option<Vec<u8>> {
    let v: serde_json::Map<String, serde_json::Value> = serde_json::from_slice(data).ok()?;
    if !crate::nest::has_nested(&v) {
        return None;
    }
    serde_json::to_vec(&crate::nest::flatten(&v)).ok()
}

fn read_segment(path: &Path, json_only: bool) -> anyhow::Result<(Vec<Recorded>, bool)> {
    let buf = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    // Not a recording, or a damaged one, is refused here, before a misread byte reaches a
    // reader; a file cut short is read as far as its complete chunks go.
    let checked = crate::integrity::check(path, &buf)?;
    let mut out = Vec::new();
    let mut complete = checked.complete;
    let stream = mcap::MessageStream::new(&buf).context("not an MCAP file")?;
    for m in stream {
        match m {
            Ok(m) => {
                let json = m.channel.message_encoding == "json";
                if json || !json_only {
                    let topic = &m.channel.topic;
                    let data = if json && topic.starts_with(NODE_TOPIC_PREFIX) {
                        flat_report(&m.data).unwrap_or_else(|| m.data.into_owned())
                    } else {
                        m.data.into_owned()
                    };
                    out.push(Recorded {
                        topic: topic.clone(),
                        log_time: m.log_time,
                        data,
                        json,
                    });
                }
            }
            Err(_) => {
                complete = false;
                break;
            }
        }
    }
    if complete && mcap::Summary::read(&buf).ok().flatten().is_none() {
        complete = false;
    }
    Ok((out, complete))
}

/// What the window loop asks of the recorder thread.
enum Cmd {
    /// Bytes to write on a topic (a protocol message, or a JSON document whose channel
    /// already lists its keys); the buffer goes back to the pool afterwards.
    Write {
        topic: std::sync::Arc<str>,
        sim_t: f64,
        data: Vec<u8>,
        /// When the window loop handed it in (the record's publish time, ns since 1970).
        at: u64,
    },
    /// A JSON document that may open a channel or add keys to its schema.
    Json {
        topic: std::sync::Arc<str>,
        schema: String,
        sim_t: f64,
        doc: serde_json::Value,
        at: u64,
    },
    FlushIfOlder(std::time::Duration),
    /// Close the current chunk; answer once it is written.
    Flush(std::sync::mpsc::SyncSender<Result<(), String>>),
    /// Several of the above, in order: what the window loop gathered since its last hand-over
    /// (one wake-up of the thread instead of one per message); the vector comes back empty.
    Batch(Vec<Cmd>),
}

/// Commands gathered before they go to the thread without waiting for
/// [`RecorderThread::commit`] (a long wait gathers heartbeats).
const BATCH: usize = 64;
/// Message bytes gathered before they go to the thread at once (large fields).
const BATCH_BYTES: usize = 8 << 20;
/// The least time between two hand-overs at window ends ([`RecorderThread::window_end`]):
/// short windows go over several at a time, one wake-up of the thread for them all.
const HANDOVER: std::time::Duration = std::time::Duration::from_millis(1);

/// Commands queued for the recorder thread before the window loop waits for it (a full queue
/// holds the loop back: nothing is ever dropped).
const QUEUE: usize = 4096;
/// Message buffers in the pool before the first message, and their capacity (a node's
/// report as JSON is about 600 bytes): a recorder thread lagging by a thousand messages (a
/// busy machine) finds them there instead of the window loop allocating new ones.
const POOLED: usize = 1024;
const POOLED_BYTES: usize = 1024;
/// Emptied batch vectors kept for reuse (and made before the first window): as many as may
/// be on their way to the thread while it lags.
const BATCHES: usize = 64;

/// The recorder on a thread of its own: the window loop hands it each message's
/// bytes through a bounded queue and goes on, so MCAP writes, compression and flushes never
/// delay an `Advance`. The messages of a window go over in one batch at its end, or of several
/// windows where they are shorter than [`HANDOVER`] (one wake-up of the thread for them, not
/// one per message). Buffers come back through a pool, so
/// steady state allocates nothing.
/// Order is kept (one queue, one writer); [`RecorderThread::flush`] and
/// [`RecorderThread::finish`] wait until everything queued before them is written.
pub struct RecorderThread {
    tx: Option<std::sync::mpsc::SyncSender<Cmd>>,
    pool: std::sync::mpsc::Receiver<Vec<u8>>,
    /// Commands gathered for the next hand-over ([`RecorderThread::commit`]), and the
    /// message bytes among them.
    batch: Vec<Cmd>,
    batch_bytes: usize,
    /// When the last hand-over happened.
    handed: std::time::Instant,
    /// Emptied batch vectors coming back from the thread.
    batches: std::sync::mpsc::Receiver<Vec<Cmd>>,
    handle: Option<std::thread::JoinHandle<anyhow::Result<(u64, u64)>>>,
    /// Interned topic names (one allocation per topic, ever).
    topics: HashMap<String, std::sync::Arc<str>>,
    /// Keys each JSON topic's channel lists, as far as this side has sent them.
    json_keys: HashMap<String, std::collections::BTreeSet<String>>,
    /// Buffers and batch vectors made because the pool was empty: the thread lagged behind
    /// the window loop by more than the pool holds (one allocation each).
    pub lag_allocations: u64,
}

/// The recorder thread: every command of `rx` applied to `rec` in order, each written
/// buffer and emptied batch handed back to its pool, then the recording finished. The first
/// failure is warned of at once and ends `finish` with an error: a recording that lost
/// messages (a full disk) is not a recording of the run.
fn serve(
    mut rec: Recorder,
    rx: std::sync::mpsc::Receiver<Cmd>,
    back: std::sync::mpsc::SyncSender<Vec<u8>>,
    batches_back: std::sync::mpsc::SyncSender<Vec<Cmd>>,
) -> anyhow::Result<(u64, u64)> {
    let mut failed: Option<anyhow::Error> = None;
    let mut one = |cmd: Cmd, rec: &mut Recorder| {
        if let Err(e) = apply(cmd, rec, &back)
            && failed.is_none()
        {
            let e = e.context(format!("cannot write {}", rec.path.display()));
            tracing::warn!("recording: {e:#}");
            failed = Some(e);
        }
    };
    for cmd in rx {
        match cmd {
            Cmd::Batch(mut cmds) => {
                for c in cmds.drain(..) {
                    one(c, &mut rec);
                }
                let _ = batches_back.try_send(cmds);
            }
            c => one(c, &mut rec),
        }
    }
    let counts = (rec.messages, rec.bytes);
    let finished = rec.finish();
    if let Some(e) = failed {
        return Err(e);
    }
    finished.map(|()| counts)
}

/// One command (not a batch) applied to the recording; a written buffer goes back to the
/// pool, and a flush is answered.
fn apply(
    cmd: Cmd,
    rec: &mut Recorder,
    back: &std::sync::mpsc::SyncSender<Vec<u8>>,
) -> anyhow::Result<()> {
    match cmd {
        Cmd::Write {
            topic,
            sim_t,
            data,
            at,
        } => {
            let written = rec.write_at(&topic, None, sim_t, &data, at);
            let _ = back.try_send(data);
            written
        }
        Cmd::Json {
            topic,
            schema,
            sim_t,
            doc,
            at,
        } => rec.json_at(&topic, &schema, sim_t, &doc, at),
        Cmd::FlushIfOlder(age) => rec.flush_if_older(age),
        Cmd::Flush(done) => {
            let _ = done.send(
                rec.flush()
                    .map_err(|e| format!("cannot write {}: {e:#}", rec.path.display())),
            );
            Ok(())
        }
        // Batches are never nested (`RecorderThread::push`).
        Cmd::Batch(_) => Ok(()),
    }
}

impl RecorderThread {
    /// Start the thread around `rec`.
    pub fn spawn(rec: Recorder) -> anyhow::Result<Self> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Cmd>(QUEUE);
        let (back, pool) = std::sync::mpsc::sync_channel::<Vec<u8>>(QUEUE);
        let (batches_back, batches) = std::sync::mpsc::sync_channel::<Vec<Cmd>>(BATCHES);
        for _ in 0..POOLED {
            let _ = back.try_send(Vec::with_capacity(POOLED_BYTES));
        }
        for _ in 0..BATCHES {
            let _ = batches_back.try_send(Vec::with_capacity(BATCH));
        }
        let handle = std::thread::Builder::new()
            .name("cosim-recorder".into())
            .spawn(move || serve(rec, rx, back, batches_back))
            .context("starting the recorder thread")?;
        Ok(RecorderThread {
            tx: Some(tx),
            pool,
            batch: Vec::with_capacity(BATCH),
            batch_bytes: 0,
            handed: std::time::Instant::now(),
            batches,
            handle: Some(handle),
            topics: HashMap::new(),
            json_keys: HashMap::new(),
            lag_allocations: 0,
        })
    }

    fn send(&mut self, cmd: Cmd) -> anyhow::Result<()> {
        self.tx
            .as_ref()
            .and_then(|tx| tx.send(cmd).ok())
            .ok_or_else(|| anyhow::anyhow!("the recorder thread has stopped"))
    }

    /// Gather `cmd` for the next hand-over; a full batch goes at once.
    fn push(&mut self, cmd: Cmd) -> anyhow::Result<()> {
        if let Cmd::Write { data, .. } = &cmd {
            self.batch_bytes += data.len();
        }
        self.batch.push(cmd);
        if self.batch.len() >= BATCH || self.batch_bytes >= BATCH_BYTES {
            self.commit()?;
        }
        Ok(())
    }

    /// Hand what was gathered to the thread (one wake-up); the window loop calls it once per
    /// window and whenever it waits idle, and every flush calls it first, so order is kept.
    pub fn commit(&mut self) -> anyhow::Result<()> {
        if self.batch.is_empty() {
            return Ok(());
        }
        let next = self.batches.try_recv().unwrap_or_else(|_| {
            self.lag_allocations += 1;
            Vec::with_capacity(BATCH)
        });
        let cmds = std::mem::replace(&mut self.batch, next);
        self.batch_bytes = 0;
        self.handed = std::time::Instant::now();
        self.send(Cmd::Batch(cmds))
    }

    /// At a window's end: [`RecorderThread::flush_if_older`] once the last hand-over is
    /// [`HANDOVER`] old, else nothing (the next window's end, a full batch or an idle wait
    /// hands the window over).
    pub fn window_end(&mut self, age: std::time::Duration) -> anyhow::Result<()> {
        if self.handed.elapsed() < HANDOVER {
            return Ok(());
        }
        self.flush_if_older(age)
    }

    fn topic(&mut self, topic: &str) -> std::sync::Arc<str> {
        if let Some(t) = self.topics.get(topic) {
            return t.clone();
        }
        let t: std::sync::Arc<str> = topic.into();
        self.topics.insert(topic.to_string(), t.clone());
        t
    }

    /// A buffer from the pool (or a new one while the pool is empty), cleared.
    fn buffer(&mut self) -> Vec<u8> {
        let mut b = self.pool.try_recv().unwrap_or_else(|_| {
            self.lag_allocations += 1;
            Vec::with_capacity(POOLED_BYTES)
        });
        b.clear();
        b
    }

    /// Record the exact bytes of a protocol message seen on `topic`.
    pub fn message(&mut self, topic: &str, sim_t: f64, bytes: &[u8]) -> anyhow::Result<()> {
        let mut data = self.buffer();
        data.extend_from_slice(bytes);
        let topic = self.topic(topic);
        self.push(Cmd::Write {
            topic,
            sim_t,
            data,
            at: now_ns(),
        })
    }

    /// [`Recorder::json`] on the thread.
    pub fn json(
        &mut self,
        topic: &str,
        schema_name: &str,
        sim_t: f64,
        v: &serde_json::Value,
    ) -> anyhow::Result<()> {
        if let serde_json::Value::Object(m) = v {
            let known = self.json_keys.entry(topic.to_string()).or_default();
            crate::nest::for_each_leaf(m, &mut |k, _| {
                if !known.contains(k) {
                    known.insert(k.to_string());
                }
            });
        }
        let topic = self.topic(topic);
        self.push(Cmd::Json {
            topic,
            schema: schema_name.to_string(),
            sim_t,
            doc: v.clone(),
            at: now_ns(),
        })
    }

    /// [`RecorderThread::json`] for a document that serializes as an object with a fixed set
    /// of keys (a struct) plus `extra_keys` (its named scalars, say): once its channel lists
    /// every key, it is serialised here into a pooled buffer and written there without
    /// building a `Value` or allocating; otherwise it goes as a `Value`.
    pub fn json_doc<T: serde::Serialize>(
        &mut self,
        topic: &str,
        schema_name: &str,
        sim_t: f64,
        doc: &T,
        extra_keys: &mut dyn Iterator<Item = &str>,
    ) -> anyhow::Result<()> {
        let known = match self.json_keys.get(topic) {
            Some(have) => {
                let mut all = true;
                for k in extra_keys {
                    all &= have.contains(k);
                }
                all
            }
            None => false,
        };
        if !known {
            return self.json(topic, schema_name, sim_t, &serde_json::to_value(doc)?);
        }
        let mut data = self.buffer();
        serde_json::to_writer(&mut data, doc)?;
        let topic = self.topic(topic);
        self.push(Cmd::Write {
            topic,
            sim_t,
            data,
            at: now_ns(),
        })
    }

    /// Close the current chunk once it is older than `age` (on the thread; returns at once).
    pub fn flush_if_older(&mut self, age: std::time::Duration) -> anyhow::Result<()> {
        self.push(Cmd::FlushIfOlder(age))?;
        self.commit()
    }

    /// Write everything queued so far and close the chunk; returns once it is on disk.
    pub fn flush(&mut self) -> anyhow::Result<()> {
        let (done, wait) = std::sync::mpsc::sync_channel(1);
        self.commit()?;
        self.send(Cmd::Flush(done))?;
        wait.recv()
            .map_err(|_| anyhow::anyhow!("the recorder thread has stopped"))?
            .map_err(|e| anyhow::anyhow!(e))
    }

    /// Write everything queued, the summary and the footer; returns the messages and bytes
    /// recorded.
    pub fn finish(mut self) -> anyhow::Result<(u64, u64)> {
        self.commit()?;
        drop(self.tx.take());
        match self.handle.take().map(|h| h.join()) {
            Some(Ok(r)) => r,
            Some(Err(_)) => anyhow::bail!("the recorder thread panicked"),
            None => anyhow::bail!("the recorder thread was already finished"),
        }
    }
}

impl Drop for RecorderThread {
    /// Without `finish` (an early return): the queue is still written and the file closed.
    fn drop(&mut self) {
        let _ = self.commit();
        drop(self.tx.take());
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The recorder thread writes every message it is handed, in that order, with its topic,
    /// log time and bytes, also when the window loop outruns its queue (the loop then waits:
    /// nothing is dropped); a JSON document's first record opens its channel, the next ones
    /// go as plain bytes on it.
    #[test]
    fn the_recorder_thread_keeps_every_message_in_order() {
        let dir = std::env::temp_dir().join(format!("cosim-rec-thread-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.mcap");
        let mut rec = RecorderThread::spawn(Recorder::create(&path).unwrap()).unwrap();
        let n = 3 * QUEUE + 7;
        let topic = |i: usize| if i.is_multiple_of(3) { "a" } else { "b" };
        for i in 0..n {
            rec.message(topic(i), i as f64 * 1e-9, &(i as u64).to_le_bytes())
                .unwrap();
            if i == n / 2 {
                rec.flush().unwrap();
            }
        }
        #[derive(serde::Serialize)]
        struct Doc {
            window: u64,
        }
        for w in 1..=2 {
            rec.json_doc("/j", "J", 0.0, &Doc { window: w }, &mut std::iter::empty())
                .unwrap();
        }
        let (messages, _) = rec.finish().unwrap();
        assert_eq!(messages, n as u64 + 2);
        let (all, complete) = read_all(&path).unwrap();
        assert!(complete);
        let bin: Vec<&Recorded> = all.iter().filter(|m| !m.json).collect();
        assert_eq!(bin.len(), n);
        for (i, m) in bin.iter().enumerate() {
            assert_eq!(m.data, (i as u64).to_le_bytes(), "message {i}");
            assert_eq!((m.topic.as_str(), m.log_time), (topic(i), i as u64));
        }
        let docs: Vec<serde_json::Value> = all
            .iter()
            .filter(|m| m.topic == "/j")
            .map(|m| serde_json::from_slice(&m.data).unwrap())
            .collect();
        assert_eq!(
            docs,
            vec![
                serde_json::json!({ "window": 1 }),
                serde_json::json!({ "window": 2 })
            ]
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A coordinator killed after the checkpoint of window 2 had not recorded node b's data
    /// of window 2; the restart sends it again while the coordinator awaits the restores,
    /// before the resume mark. Read as one run, the recording holds every node's data of
    /// every window once: a's window-2 data from the first segment (its resent copy dropped),
    /// b's from the second, and the windows after the checkpoint from the second only.
    #[test]
    fn a_restart_fills_the_data_the_killed_run_lost_wherever_it_lies() {
        let dir = std::env::temp_dir().join(format!("cosim-rec-resume-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("run.mcap");
        let fields = |node: &str, window: u64, v: f64| {
            let m = protocol::Message::Fields(protocol::message::Fields {
                coupling: "c".into(),
                window,
                time: window as f64,
                fields: vec![protocol::message::Field {
                    name: "force".into(),
                    components: 1,
                    values: vec![v],
                }],
            });
            protocol::encode("r", node, window, &m).unwrap()
        };
        let mark = |rec: &mut Recorder, topic: &str, w: u64| {
            rec.json(topic, "M", w as f64, &serde_json::json!({ "window": w }))
                .unwrap();
        };
        // The killed run: windows 1..=3 of a, 1..=1 and 3 of b (window 2 lost), mark of 2.
        let mut rec = Recorder::create(&path).unwrap();
        for w in 1..=2 {
            rec.message("/a", 0.0, &fields("a", w, 1.0)).unwrap();
        }
        rec.message("/b", 0.0, &fields("b", 1, 1.0)).unwrap();
        mark(&mut rec, CHECKPOINT_TOPIC, 2);
        rec.message("/a", 0.0, &fields("a", 3, 1.0)).unwrap();
        rec.message("/b", 0.0, &fields("b", 3, 1.0)).unwrap();
        rec.finish().unwrap();
        // The restart: both resend window 2 before the mark, then run windows 3 and 4.
        let mut rec = Recorder::create(&dir.join("run.1.mcap")).unwrap();
        rec.message("/a", 0.0, &fields("a", 2, 2.0)).unwrap();
        rec.message("/b", 0.0, &fields("b", 2, 2.0)).unwrap();
        mark(&mut rec, RESUMED_TOPIC, 2);
        for w in 3..=4 {
            rec.message("/a", 0.0, &fields("a", w, 2.0)).unwrap();
            rec.message("/b", 0.0, &fields("b", w, 2.0)).unwrap();
        }
        rec.finish().unwrap();

        let (all, complete) = read_all(&path).unwrap();
        assert!(complete);
        let mut got: Vec<(String, u64, f64)> = all
            .iter()
            .filter(|m| !m.json)
            .map(|m| match protocol::decode(&m.data).unwrap().message {
                protocol::Message::Fields(f) => (m.topic.clone(), f.window, f.fields[0].values[0]),
                _ => unreachable!(),
            })
            .collect();
        got.sort_by(|x, y| x.partial_cmp(y).unwrap());
        let want: Vec<(String, u64, f64)> = [
            ("/a", 1, 1.0),
            ("/a", 2, 1.0),
            ("/a", 3, 2.0),
            ("/a", 4, 2.0),
            ("/b", 1, 1.0),
            ("/b", 2, 2.0),
            ("/b", 3, 2.0),
            ("/b", 4, 2.0),
        ]
        .iter()
        .map(|(t, w, v)| (t.to_string(), *w, *v))
        .collect();
        assert_eq!(got, want);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
