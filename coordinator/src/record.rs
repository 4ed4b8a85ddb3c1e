//! MCAP recorder (ARCHITECTURE §7): one channel per topic carrying the exact envelope bytes
//! (message encoding `bincode`, schema `cosim.Envelope` whose data is the Rust source of the
//! message types), plus JSON channels (schema encoding `jsonschema`) with per-window metrics
//! for Foxglove. Chunked and zstd-compressed; chunks are flushed regularly so a killed
//! coordinator leaves a file whose completed chunks are readable.

use anyhow::Context;
use mcap::records::MessageHeader;
use mcap::{Compression, WriteOptions, Writer};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// The Rust definition of the recorded messages, stored as the schema of every bincode channel.
pub const ENVELOPE_SCHEMA: &str = include_str!("../../wire/src/message.rs");
pub const ENVELOPE_SCHEMA_NAME: &str = "cosim.Envelope";
pub const BINCODE_ENCODING: &str = "bincode";

pub struct Recorder {
    w: Writer<BufWriter<File>>,
    bincode_schema: u16,
    channels: HashMap<String, (u16, u32)>,
    json_schemas: HashMap<String, u16>,
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

/// Simulation time in ns for MCAP's publish time.
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
        let bincode_schema = w.add_schema(
            ENVELOPE_SCHEMA_NAME,
            "rust-serde-bincode",
            ENVELOPE_SCHEMA.as_bytes(),
        )?;
        Ok(Recorder {
            w,
            bincode_schema,
            channels: HashMap::new(),
            json_schemas: HashMap::new(),
            last_flush: Instant::now(),
            messages: 0,
            bytes: 0,
        })
    }

    fn channel(&mut self, topic: &str, json_schema: Option<(&str, &str)>) -> anyhow::Result<u16> {
        if let Some(&(id, _)) = self.channels.get(topic) {
            return Ok(id);
        }
        let id = match json_schema {
            None => self.w.add_channel(
                self.bincode_schema,
                topic,
                BINCODE_ENCODING,
                &BTreeMap::new(),
            )?,
            Some((name, schema)) => {
                let sid = match self.json_schemas.get(name) {
                    Some(&s) => s,
                    None => {
                        let s = self.w.add_schema(name, "jsonschema", schema.as_bytes())?;
                        self.json_schemas.insert(name.to_string(), s);
                        s
                    }
                };
                self.w.add_channel(sid, topic, "json", &BTreeMap::new())?
            }
        };
        self.channels.insert(topic.to_string(), (id, 0));
        Ok(id)
    }

    fn write(
        &mut self,
        topic: &str,
        json: Option<(&str, &str)>,
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
                log_time: now_ns(),
                publish_time: sim_ns(sim_t),
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

    /// Record a JSON document on a metrics channel.
    pub fn json(
        &mut self,
        topic: &str,
        schema_name: &str,
        schema: &str,
        sim_t: f64,
        v: &serde_json::Value,
    ) -> anyhow::Result<()> {
        let data = serde_json::to_vec(v)?;
        self.write(topic, Some((schema_name, schema)), sim_t, &data)
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

/// A permissive JSON schema: an object of numbers and strings (Foxglove plots the numbers).
pub fn object_schema(title: &str, numeric: &[&str]) -> String {
    let props: Vec<String> = numeric
        .iter()
        .map(|k| format!("\"{k}\":{{\"type\":\"number\"}}"))
        .collect();
    format!(
        "{{\"$schema\":\"https://json-schema.org/draft/2020-12/schema\",\"title\":\"{title}\",\"type\":\"object\",\"properties\":{{{}}}}}",
        props.join(",")
    )
}

/// One recorded message, as read back.
pub struct Recorded {
    pub topic: String,
    pub publish_time: u64,
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
                        publish_time: m.publish_time,
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
