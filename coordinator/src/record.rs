//! MCAP recorder (ARCHITECTURE §7): one channel per topic carrying the exact envelope bytes
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
use std::io::BufWriter;
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
    bincode_schema: u16,
    /// Topic → (channel id, sequence, the keys its schema lists: JSON channels only).
    channels: HashMap<String, (u16, u32, BTreeMap<String, &'static str>)>,
    last_flush: Instant,
    /// The bytes of the JSON document being written (reused: no allocation per record).
    scratch: Vec<u8>,
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
            bincode_schema,
            channels: HashMap::new(),
            last_flush: Instant::now(),
            scratch: Vec::with_capacity(1024),
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
                Some(serde_json::Value::Object(m)) => m.keys().all(|k| have.contains_key(k)),
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
                publish_time: now_ns(),
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
        let data = serde_json::to_vec(v)?;
        self.write(topic, Some((schema_name, v)), sim_t, &data)
    }

    /// [`Recorder::json`] for a document that serializes as an object with a fixed set of
    /// keys (a struct) plus `extra_keys` (its named scalars, say): once its channel exists
    /// and knows every extra key, it is written without building a `Value` or allocating.
    pub fn json_doc<T: serde::Serialize>(
        &mut self,
        topic: &str,
        schema_name: &str,
        sim_t: f64,
        doc: &T,
        extra_keys: &mut dyn Iterator<Item = &str>,
    ) -> anyhow::Result<()> {
        let known = match self.channels.get(topic) {
            Some((_, _, have)) if !have.is_empty() => {
                let mut all = true;
                for k in extra_keys {
                    all &= have.contains_key(k);
                }
                all
            }
            _ => false,
        };
        if !known {
            return self.json(topic, schema_name, sim_t, &serde_json::to_value(doc)?);
        }
        let mut data = std::mem::take(&mut self.scratch);
        data.clear();
        let r = serde_json::to_writer(&mut data, doc)
            .map_err(anyhow::Error::from)
            .and_then(|_| self.write(topic, None, sim_t, &data));
        self.scratch = data;
        r
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
        self.w.finish()?;
        Ok(())
    }
}

/// The JSON Schema type of each key of an object (empty for anything else).
fn keys_of(doc: &serde_json::Value) -> BTreeMap<String, &'static str> {
    use serde_json::Value;
    let Value::Object(m) = doc else {
        return BTreeMap::new();
    };
    m.iter()
        .map(|(k, v)| {
            let ty = match v {
                // serde_json writes a NaN or infinite f64 as null
                Value::Null | Value::Number(_) => "number",
                Value::Bool(_) => "boolean",
                Value::String(_) => "string",
                Value::Array(_) => "array",
                Value::Object(_) => "object",
            };
            (k.clone(), ty)
        })
        .collect()
}

/// A JSON Schema (draft 2020-12) of an object with these keys and types; a number may be
/// null (a NaN or infinite value), arrays hold numbers (Foxglove plots the numbers).
pub fn object_schema(title: &str, keys: &BTreeMap<String, &'static str>) -> String {
    let props: serde_json::Map<String, serde_json::Value> = keys
        .iter()
        .map(|(k, ty)| {
            let v = match *ty {
                "number" => serde_json::json!({ "type": ["number", "null"] }),
                "array" => serde_json::json!({
                    "type": "array",
                    "items": { "type": ["number", "null"] }
                }),
                t => serde_json::json!({ "type": t }),
            };
            (k.clone(), v)
        })
        .collect();
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
/// restarted run's segments are read as one run (see [`segments`]).
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
        // The restore sends the `Fields` of window k again, and they may be recorded after
        // the mark: keep them only where the earlier segment lost its own.
        let have: std::collections::HashSet<(String, u64)> = out
            .iter()
            .filter_map(|m| Some((m.topic.clone(), fields_window(m)?)))
            .collect();
        out.extend(msgs.into_iter().skip(i + 1).filter(|m| {
            fields_window(m).is_none_or(|w| w > k || !have.contains(&(m.topic.clone(), w)))
        }));
        complete = c;
    }
    if json_only {
        out.retain(|m| m.json);
    }
    Ok((out, complete))
}

fn read_segment(path: &Path, json_only: bool) -> anyhow::Result<(Vec<Recorded>, bool)> {
    let buf = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut out = Vec::new();
    let mut complete = true;
    let stream = mcap::MessageStream::new(&buf).context("not an MCAP file")?;
    for m in stream {
        match m {
            Ok(m) => {
                let json = m.channel.message_encoding == "json";
                if json || !json_only {
                    out.push(Recorded {
                        topic: m.channel.topic.clone(),
                        log_time: m.log_time,
                        data: m.data.into_owned(),
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
