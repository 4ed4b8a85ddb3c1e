//! What a recording's bytes say about it, checked before anything reads its messages: MCAP's
//! magic, every record's length, each chunk's CRC of its uncompressed records, the data
//! section's CRC (in the data end record) and the summary's (in the footer).
//!
//! * A file that does not begin with the magic is not a recording (an empty file, random
//!   bytes, another format).
//! * A file that ends with the magic was closed by its writer: any check that fails there is
//!   corruption, reported at the byte where the failing record begins.
//! * A file without the end magic whose last record runs past its end was cut short by its
//!   writer (a killed run): it reads as incomplete, its complete chunks still checked.
//!
//! The `mcap` crate's readers leave chunk CRCs unchecked by default and their errors carry no
//! offset, so the records are walked here (the layout of the MCAP specification: an opcode
//! byte, a u64 little-endian length, the body).

use std::io::Read;
use std::path::{Path, PathBuf};

/// The bytes every MCAP file begins and ends with.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

const OP_HEADER: u8 = 0x01;
const OP_FOOTER: u8 = 0x02;
const OP_CHUNK: u8 = 0x06;
const OP_DATA_END: u8 = 0x0F;
/// Opcode byte and u64 length in front of every record body.
const RECORD_HEAD: usize = 9;

#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("{}: not a recording: {why}", path.display())]
    NotARecording { path: PathBuf, why: String },
    #[error("{}: corrupt at byte {byte}: {why}", path.display())]
    Corrupt {
        path: PathBuf,
        byte: u64,
        why: String,
    },
    /// A CRC over a whole section that no smaller check locates within it.
    #[error("{}: corrupt between bytes {from} and {to}: {why}", path.display())]
    CorruptSection {
        path: PathBuf,
        from: u64,
        to: u64,
        why: String,
    },
}

/// A recording that passed the checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Checked {
    /// Closed by its writer (end magic, footer); false for a file cut short.
    pub complete: bool,
    /// Chunks whose CRC was computed (all of them where the data section's CRC failed or is
    /// absent, or the file is cut short; none where the data section's CRC vouches for them).
    pub chunks_checked: usize,
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

/// One record of the file: its opcode, where it begins and where its body lies.
struct Record {
    op: u8,
    at: usize,
    body: std::ops::Range<usize>,
}

/// Check the recording `buf` read from `path` (see the module doc).
pub fn check(path: &Path, buf: &[u8]) -> Result<Checked, RecordingError> {
    let not = |why: &str| RecordingError::NotARecording {
        path: path.to_path_buf(),
        why: why.to_string(),
    };
    let corrupt = |(byte, why): (usize, String)| RecordingError::Corrupt {
        path: path.to_path_buf(),
        byte: byte as u64,
        why,
    };
    if buf.is_empty() {
        return Err(not("the file is empty"));
    }
    if buf.len() < MAGIC.len() || &buf[..MAGIC.len()] != MAGIC {
        return Err(not("it does not begin with MCAP's magic bytes"));
    }
    let closed = buf.len() >= 2 * MAGIC.len() && &buf[buf.len() - MAGIC.len()..] == MAGIC;
    let end = if closed {
        buf.len() - MAGIC.len()
    } else {
        buf.len()
    };
    // Pass 1: the records' framing, and the data section's CRC.
    let f = frame(buf, end, closed).map_err(corrupt)?;
    let data_end = f.records.iter().find(|r| r.op == OP_DATA_END);
    let data_crc = match data_end {
        Some(r) => data_crc(buf, r).map_err(corrupt)?,
        None => DataCrc::Absent,
    };
    if closed {
        let footer = closing(&f, end, data_end.is_some()).map_err(corrupt)?;
        check_summary(path, buf, footer)?;
    }
    // Pass 2: each chunk's own CRC, where the data section's CRC does not vouch for them
    // (and to locate the damage where it failed).
    let mut chunks_checked = 0;
    if data_crc != DataCrc::Vouches {
        for r in f.records.iter().filter(|r| r.op == OP_CHUNK) {
            chunks_checked += 1;
            check_chunk(&buf[r.body.clone()]).map_err(|why| {
                corrupt((
                    r.at,
                    format!("the chunk of bytes {}..{} {why}", r.at, r.body.end),
                ))
            })?;
        }
    }
    if let DataCrc::Failed(to) = data_crc {
        return Err(RecordingError::CorruptSection {
            path: path.to_path_buf(),
            from: 0,
            to: to as u64,
            why: "the data section does not match its CRC (every chunk matches its own: the damage lies outside them)".into(),
        });
    }
    Ok(Checked {
        complete: closed && !f.cut_short,
        chunks_checked,
    })
}

/// The records between the magic and `end`, as far as their framing holds.
struct Framing {
    records: Vec<Record>,
    /// Where the walk stopped: `end`, or past the footer, or the record cut short.
    stop: usize,
    /// The last record runs past the end of a file without the end magic.
    cut_short: bool,
}

/// Walks the records of `buf` up to `end`: in a closed file a record running past the end
/// is corruption (its byte and why), in an open one the file cut short.
fn frame(buf: &[u8], end: usize, closed: bool) -> Result<Framing, (usize, String)> {
    let mut records = Vec::new();
    let mut cut_short = false;
    let mut at = MAGIC.len();
    while at < end {
        let (op, len) = match (buf.get(at), u64_at(buf, at + 1)) {
            (Some(&op), Some(len)) if at + RECORD_HEAD <= end => (op, len),
            _ if closed => return Err((at, "a record's header runs past the end".into())),
            _ => {
                cut_short = true;
                break;
            }
        };
        let body_end = usize::try_from(len)
            .ok()
            .and_then(|l| (at + RECORD_HEAD).checked_add(l))
            .filter(|&e| e <= end);
        let Some(body_end) = body_end else {
            if closed {
                return Err((
                    at,
                    format!("a record (opcode 0x{op:02x}) of {len} bytes runs past the end"),
                ));
            }
            cut_short = true;
            break;
        };
        if records.is_empty() && op != OP_HEADER {
            return Err((at, "the first record is not MCAP's header".into()));
        }
        records.push(Record {
            op,
            at,
            body: at + RECORD_HEAD..body_end,
        });
        at = body_end;
        if op == OP_FOOTER {
            break;
        }
    }
    if records.is_empty() && !cut_short && closed {
        return Err((MAGIC.len(), "no record".into()));
    }
    Ok(Framing {
        records,
        stop: at,
        cut_short,
    })
}

/// What the data end record's CRC (of every byte before it) says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum DataCrc {
    /// No data end record, or a CRC of 0 (not computed by the writer).
    Absent,
    Vouches,
    /// It does not match: the data section up to this byte is damaged somewhere.
    Failed(usize),
}

fn data_crc(buf: &[u8], data_end: &Record) -> Result<DataCrc, (usize, String)> {
    let saved = u32_at(buf, data_end.body.start)
        .ok_or_else(|| (data_end.at, "a data end record without its CRC".to_string()))?;
    Ok(if saved == 0 {
        DataCrc::Absent
    } else if crc32fast::hash(&buf[..data_end.at]) == saved {
        DataCrc::Vouches
    } else {
        DataCrc::Failed(data_end.at)
    })
}

/// A closed file's end: its footer, right before the end magic, after a data end record.
fn closing(f: &Framing, end: usize, has_data_end: bool) -> Result<&Record, (usize, String)> {
    let Some(footer) = f.records.last().filter(|r| r.op == OP_FOOTER) else {
        return Err((f.stop, "the file ends with the magic but no footer".into()));
    };
    if f.stop != end {
        return Err((f.stop, "bytes between the footer and the end magic".into()));
    }
    if !has_data_end {
        return Err((footer.at, "a footer without a data end record".into()));
    }
    Ok(footer)
}

/// The footer's CRC of the summary section and of its own first fields.
fn check_summary(path: &Path, buf: &[u8], footer: &Record) -> Result<(), RecordingError> {
    let corrupt = |why: &str| RecordingError::Corrupt {
        path: path.to_path_buf(),
        byte: footer.at as u64,
        why: why.to_string(),
    };
    let b = footer.body.start;
    let (Some(start), Some(saved)) = (u64_at(buf, b), u32_at(buf, b + 16)) else {
        return Err(corrupt("a footer shorter than its fields"));
    };
    if saved == 0 {
        return Ok(());
    }
    // No summary section (start 0): the CRC covers the footer's fields alone.
    let from = match usize::try_from(start) {
        Ok(0) => footer.at,
        Ok(s) if s <= footer.at => s,
        _ => return Err(corrupt("the footer's summary start lies beyond it")),
    };
    if crc32fast::hash(&buf[from..b + 16]) != saved {
        return Err(RecordingError::CorruptSection {
            path: path.to_path_buf(),
            from: from as u64,
            to: (b + 20) as u64,
            why: "the summary section does not match the footer's CRC".into(),
        });
    }
    Ok(())
}

/// Why a chunk's body fails its checks: its fields' lengths, the decompression of its
/// records, their size and CRC against the chunk's header.
fn check_chunk(body: &[u8]) -> Result<(), String> {
    // start time, end time, uncompressed size, uncompressed CRC, compression (u32 + name),
    // records (u64 + bytes)
    let fields = || "is shorter than its fields".to_string();
    let size = u64_at(body, 16).ok_or_else(fields)?;
    let saved = u32_at(body, 24).ok_or_else(fields)?;
    let name_len = u32_at(body, 28).ok_or_else(fields)? as usize;
    let name = body.get(32..32 + name_len).ok_or_else(fields)?;
    let at = 32 + name_len;
    let len = u64_at(body, at).ok_or_else(fields)?;
    let records = usize::try_from(len)
        .ok()
        .and_then(|l| body.get(at + 8..at + 8 + l))
        .ok_or_else(|| format!("holds records of {len} bytes, past its end"))?;
    // Read at most one byte more than the header promises: a damaged size allocates no more
    // than the data it really yields.
    let limited = |r: &mut dyn Read| -> Result<Vec<u8>, String> {
        let mut out = Vec::new();
        r.take(size.saturating_add(1))
            .read_to_end(&mut out)
            .map_err(|e| format!("does not decompress: {e}"))?;
        Ok(out)
    };
    let data = match name {
        b"" => records.to_vec(),
        b"zstd" => {
            let mut d = zstd::stream::read::Decoder::new(records)
                .map_err(|e| format!("does not decompress: {e}"))?;
            limited(&mut d)?
        }
        b"lz4" => {
            let mut d =
                lz4::Decoder::new(records).map_err(|e| format!("does not decompress: {e}"))?;
            limited(&mut d)?
        }
        // A compression this reader does not know: the data section's CRC still covers it.
        _ => return Ok(()),
    };
    if data.len() as u64 != size {
        return Err(format!(
            "decompresses to {} bytes where its header says {size}",
            data.len()
        ));
    }
    if saved != 0 && crc32fast::hash(&data) != saved {
        return Err("does not match its CRC".into());
    }
    Ok(())
}
