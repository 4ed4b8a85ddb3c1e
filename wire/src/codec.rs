//! Versioned envelope and codec (PROTOCOL.md, "Bytes"): a fixed 20-byte header (magic,
//! protocol version, message kind, body length, sequence number) followed by the bincode 2
//! body (`config::standard()`) of run, sender and message. Decoding checks every header field and
//! the exact body length before bincode sees a byte, and caps allocations, so no input panics.

use crate::message::Message;
use bincode::config;
use serde::{Deserialize, Serialize};
use thiserror::Error;

pub const MAGIC: [u8; 4] = *b"CSIM";
pub const PROTOCOL_VERSION: u16 = 4;
pub const HEADER_LEN: usize = 20;
/// Largest body accepted (1 GiB), also the cap on any allocation the decoder makes.
pub const MAX_BODY: usize = 1 << 30;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum CodecError {
    #[error("message too short: {0} bytes, the header alone is {HEADER_LEN}")]
    Truncated(usize),
    #[error("bad magic {0:02x?}: not a cosim message")]
    BadMagic([u8; 4]),
    #[error("protocol version {got}, this build speaks {PROTOCOL_VERSION}")]
    WrongVersion { got: u16 },
    #[error("message body of {0} bytes exceeds the limit of {MAX_BODY}")]
    Oversized(u64),
    #[error("header announces a {announced}-byte body, {actual} bytes follow")]
    LengthMismatch { announced: u64, actual: usize },
    #[error("header says kind {header}, body holds kind {body}")]
    KindMismatch { header: u8, body: u8 },
    #[error("body does not decode: {0}")]
    Body(String),
    #[error("{0} trailing bytes after the body")]
    Trailing(usize),
    #[error("encoding failed: {0}")]
    Encode(String),
}

/// A message with its routing information.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Envelope {
    pub run: String,
    pub sender: String,
    pub seq: u64,
    pub message: Message,
}

#[derive(Serialize)]
struct BodyRef<'a> {
    run: &'a str,
    sender: &'a str,
    message: &'a Message,
}

#[derive(Deserialize)]
struct Body {
    run: String,
    sender: String,
    message: Message,
}

/// Header fields readable without decoding the body (used by the recorder).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    pub version: u16,
    pub kind: u8,
    pub body_len: u32,
    pub seq: u64,
}

/// Encode into `buf` (cleared first, capacity reused).
pub fn encode_into(
    buf: &mut Vec<u8>,
    run: &str,
    sender: &str,
    seq: u64,
    message: &Message,
) -> Result<(), CodecError> {
    buf.clear();
    buf.extend_from_slice(&MAGIC);
    buf.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    buf.push(message.kind());
    buf.push(0);
    buf.extend_from_slice(&[0u8; 4]);
    buf.extend_from_slice(&seq.to_le_bytes());
    let body = BodyRef {
        run,
        sender,
        message,
    };
    bincode::serde::encode_into_std_write(&body, buf, config::standard())
        .map_err(|e| CodecError::Encode(e.to_string()))?;
    let len = buf.len() - HEADER_LEN;
    if len > MAX_BODY {
        return Err(CodecError::Oversized(len as u64));
    }
    buf[8..12].copy_from_slice(&(len as u32).to_le_bytes());
    Ok(())
}

/// The number of bytes [`encode_into`] writes for `message` (header included), found by
/// encoding into a counter: a large field is one block, so this costs no pass over its data.
pub fn encoded_len(run: &str, sender: &str, message: &Message) -> Result<usize, CodecError> {
    let body = BodyRef {
        run,
        sender,
        message,
    };
    let mut size = bincode::enc::write::SizeWriter::default();
    bincode::serde::encode_into_writer(&body, &mut size, config::standard())
        .map_err(|e| CodecError::Encode(e.to_string()))?;
    if size.bytes_written > MAX_BODY {
        return Err(CodecError::Oversized(size.bytes_written as u64));
    }
    Ok(HEADER_LEN + size.bytes_written)
}

/// Writes into memory that is not initialised yet (a loaned shared-memory sample).
struct UninitWriter<'a> {
    dst: &'a mut [std::mem::MaybeUninit<u8>],
    at: usize,
}

impl bincode::enc::write::Writer for UninitWriter<'_> {
    fn write(&mut self, bytes: &[u8]) -> Result<(), bincode::error::EncodeError> {
        let end = self.at + bytes.len();
        let Some(dst) = self.dst.get_mut(self.at..end) else {
            return Err(bincode::error::EncodeError::UnexpectedEnd);
        };
        dst.write_copy_of_slice(bytes);
        self.at = end;
        Ok(())
    }
}

/// [`encode_into`] straight into `dst`, which must be exactly [`encoded_len`] bytes long
/// (a loaned shared-memory sample: no intermediate buffer). Every byte of `dst` is written
/// on success.
pub fn encode_into_uninit(
    dst: &mut [std::mem::MaybeUninit<u8>],
    run: &str,
    sender: &str,
    seq: u64,
    message: &Message,
) -> Result<(), CodecError> {
    if dst.len() < HEADER_LEN {
        return Err(CodecError::Truncated(dst.len()));
    }
    let len = dst.len() - HEADER_LEN;
    if len > MAX_BODY {
        return Err(CodecError::Oversized(len as u64));
    }
    let mut header = [0u8; HEADER_LEN];
    header[..4].copy_from_slice(&MAGIC);
    header[4..6].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    header[6] = message.kind();
    header[8..12].copy_from_slice(&(len as u32).to_le_bytes());
    header[12..20].copy_from_slice(&seq.to_le_bytes());
    let (head, body_dst) = dst.split_at_mut(HEADER_LEN);
    head.write_copy_of_slice(&header);
    let body = BodyRef {
        run,
        sender,
        message,
    };
    let mut w = UninitWriter {
        dst: body_dst,
        at: 0,
    };
    bincode::serde::encode_into_writer(&body, &mut w, config::standard())
        .map_err(|e| CodecError::Encode(e.to_string()))?;
    if w.at != len {
        return Err(CodecError::LengthMismatch {
            announced: len as u64,
            actual: w.at,
        });
    }
    Ok(())
}

pub fn encode(run: &str, sender: &str, seq: u64, message: &Message) -> Result<Vec<u8>, CodecError> {
    let mut buf = Vec::new();
    encode_into(&mut buf, run, sender, seq, message)?;
    Ok(buf)
}

/// Read and check the header only.
pub fn header(bytes: &[u8]) -> Result<Header, CodecError> {
    if bytes.len() < HEADER_LEN {
        return Err(CodecError::Truncated(bytes.len()));
    }
    let magic = [bytes[0], bytes[1], bytes[2], bytes[3]];
    if magic != MAGIC {
        return Err(CodecError::BadMagic(magic));
    }
    let version = u16::from_le_bytes([bytes[4], bytes[5]]);
    if version != PROTOCOL_VERSION {
        return Err(CodecError::WrongVersion { got: version });
    }
    let kind = bytes[6];
    let body_len = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
    if body_len as usize > MAX_BODY {
        return Err(CodecError::Oversized(body_len as u64));
    }
    let actual = bytes.len() - HEADER_LEN;
    if body_len as usize != actual {
        return Err(CodecError::LengthMismatch {
            announced: body_len as u64,
            actual,
        });
    }
    let mut s = [0u8; 8];
    s.copy_from_slice(&bytes[12..20]);
    Ok(Header {
        version,
        kind,
        body_len,
        seq: u64::from_le_bytes(s),
    })
}

/// Decode a whole envelope. Never panics; every malformed input is an error.
pub fn decode(bytes: &[u8]) -> Result<Envelope, CodecError> {
    let h = header(bytes)?;
    let body = &bytes[HEADER_LEN..];
    // The limit bounds every length prefix inside the body, so a forged vector length
    // cannot make bincode allocate more than the bytes that are actually there allow.
    let cfg = config::standard().with_limit::<MAX_BODY>();
    let (b, used): (Body, usize) = bincode::serde::borrow_decode_from_slice(body, cfg)
        .map_err(|e| CodecError::Body(e.to_string()))?;
    if used != body.len() {
        return Err(CodecError::Trailing(body.len() - used));
    }
    if b.message.kind() != h.kind {
        return Err(CodecError::KindMismatch {
            header: h.kind,
            body: b.message.kind(),
        });
    }
    Ok(Envelope {
        run: b.run,
        sender: b.sender,
        seq: h.seq,
        message: b.message,
    })
}

/// The `Fields` message of an envelope read in place (issue 22): strings and values borrow the
/// received bytes (a shared-memory sample), so a large field is never copied out of it. The
/// header, lengths, kind and trailing bytes are checked exactly as [`decode`] checks them.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldsView<'a> {
    pub run: &'a str,
    pub sender: &'a str,
    pub seq: u64,
    pub coupling: &'a str,
    pub window: u64,
    pub time: f64,
    pub fields: Vec<FieldView<'a>>,
}

/// One field of a [`FieldsView`]: its values as the little-endian bytes on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
pub struct FieldView<'a> {
    pub name: &'a str,
    pub components: u32,
    #[serde(borrow)]
    bytes: &'a [u8],
}

impl<'a> FieldView<'a> {
    /// Number of values (points × components).
    pub fn len(&self) -> usize {
        self.bytes.len() / 8
    }

    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Value `i`, read from the bytes in place.
    pub fn get(&self, i: usize) -> Option<f64> {
        let at = i.checked_mul(8)?;
        let b = self.bytes.get(at..at.checked_add(8)?)?;
        Some(f64::from_le_bytes([
            b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7],
        ]))
    }

    /// Every value in order, read in place.
    pub fn values(&self) -> impl ExactSizeIterator<Item = f64> + 'a {
        self.bytes
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
    }

    /// The values' bytes as sent (little-endian f64).
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }
}

/// The body of an envelope holding `Message::Fields`, field by field as bincode lays it out:
/// the enum's variant index is a varint like a `u32`, then the `Fields` struct.
#[derive(Deserialize)]
struct FieldsBody<'a> {
    run: &'a str,
    sender: &'a str,
    variant: u32,
    coupling: &'a str,
    window: u64,
    time: f64,
    #[serde(borrow)]
    fields: Vec<FieldView<'a>>,
}

/// `Message::Fields`'s variant index in the enum (its declaration order).
const FIELDS_VARIANT: u32 = 6;
/// `Message::Fields`'s kind in the header.
pub const FIELDS_KIND: u8 = 7;

/// Read a `Fields` envelope in place; any other message, or malformed bytes, is an error.
/// Never panics.
pub fn decode_fields_view(bytes: &[u8]) -> Result<FieldsView<'_>, CodecError> {
    let h = header(bytes)?;
    if h.kind != FIELDS_KIND {
        return Err(CodecError::KindMismatch {
            header: h.kind,
            body: FIELDS_KIND,
        });
    }
    let body = &bytes[HEADER_LEN..];
    let cfg = config::standard().with_limit::<MAX_BODY>();
    let (b, used): (FieldsBody, usize) = bincode::serde::borrow_decode_from_slice(body, cfg)
        .map_err(|e| CodecError::Body(e.to_string()))?;
    if b.variant != FIELDS_VARIANT {
        return Err(CodecError::KindMismatch {
            header: h.kind,
            body: u8::try_from(b.variant + 1).unwrap_or(u8::MAX),
        });
    }
    if used != body.len() {
        return Err(CodecError::Trailing(body.len() - used));
    }
    if let Some(f) = b.fields.iter().find(|f| !f.bytes.len().is_multiple_of(8)) {
        return Err(CodecError::Body(format!(
            "field '{}': {} bytes is not a whole number of f64 values",
            f.name,
            f.bytes.len()
        )));
    }
    Ok(FieldsView {
        run: b.run,
        sender: b.sender,
        seq: h.seq,
        coupling: b.coupling,
        window: b.window,
        time: b.time,
        fields: b.fields,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::*;
    use proptest::prelude::*;

    /// Encoding in place gives the bytes of `encode_into`, at the length `encoded_len` says,
    /// and refuses a destination of another length.
    #[test]
    fn in_place_encoding_gives_the_same_bytes() {
        for m in [
            sample(),
            Message::Finish(Finish {
                reason: "end".into(),
            }),
        ] {
            let mut buf = Vec::new();
            encode_into(&mut buf, "run-1", "left", 42, &m).expect("encode");
            let n = encoded_len("run-1", "left", &m).expect("len");
            assert_eq!(n, buf.len());
            let mut dst = vec![std::mem::MaybeUninit::<u8>::uninit(); n];
            encode_into_uninit(&mut dst, "run-1", "left", 42, &m).expect("in place");
            // SAFETY: encode_into_uninit wrote every byte (it succeeded at the full length).
            let got: Vec<u8> = dst.iter().map(|b| unsafe { b.assume_init() }).collect();
            assert_eq!(got, buf);
            let mut short = vec![std::mem::MaybeUninit::<u8>::uninit(); n - 1];
            assert!(encode_into_uninit(&mut short, "run-1", "left", 42, &m).is_err());
            let mut long = vec![std::mem::MaybeUninit::<u8>::uninit(); n + 1];
            assert!(encode_into_uninit(&mut long, "run-1", "left", 42, &m).is_err());
        }
    }

    /// Reading a `Fields` envelope in place gives what the full decode gives, value for
    /// value; other kinds, cut or altered bytes are errors.
    #[test]
    fn fields_view_reads_what_decode_reads() {
        let m = Message::Fields(Fields {
            coupling: "mid".into(),
            window: 42,
            time: 1.5e-3,
            fields: vec![
                Field {
                    name: "velocity".into(),
                    components: 3,
                    values: vec![1.0, -2.5, f64::MIN_POSITIVE, 1e300, 0.0, -0.0],
                },
                Field {
                    name: "empty".into(),
                    components: 1,
                    values: vec![],
                },
            ],
        });
        let bytes = encode("run7", "left", 9, &m).unwrap();
        let full = decode(&bytes).unwrap();
        let v = decode_fields_view(&bytes).unwrap();
        let Message::Fields(f) = &full.message else {
            panic!("decoded {full:?}")
        };
        assert_eq!((v.run, v.sender, v.seq), ("run7", "left", 9));
        assert_eq!((v.coupling, v.window, v.time), ("mid", 42, 1.5e-3));
        assert_eq!(v.fields.len(), 2);
        for (a, b) in v.fields.iter().zip(&f.fields) {
            assert_eq!(
                (a.name, a.components, a.len()),
                (b.name.as_str(), b.components, b.values.len())
            );
            let got: Vec<u64> = a.values().map(f64::to_bits).collect();
            let want: Vec<u64> = b.values.iter().map(|x| x.to_bits()).collect();
            assert_eq!(got, want);
            assert_eq!(a.get(a.len()), None);
        }
        assert_eq!(v.fields[0].get(1), Some(-2.5));
        // Another kind, a cut message, trailing bytes.
        let done = encode(
            "run7",
            "left",
            1,
            &Message::Done(Done {
                window: 1,
                report: StepReport::default(),
            }),
        )
        .unwrap();
        assert!(matches!(
            decode_fields_view(&done),
            Err(CodecError::KindMismatch { .. })
        ));
        assert!(decode_fields_view(&bytes[..bytes.len() - 1]).is_err());
        let mut longer = bytes.clone();
        longer.push(0);
        let n = (longer.len() - HEADER_LEN) as u32;
        longer[8..12].copy_from_slice(&n.to_le_bytes());
        assert!(matches!(
            decode_fields_view(&longer),
            Err(CodecError::Trailing(1))
        ));
    }

    fn sample() -> Message {
        Message::Fields(Fields {
            coupling: "c".into(),
            window: 7,
            time: 1.5e-6,
            fields: vec![Field {
                name: "velocity".into(),
                components: 1,
                values: vec![1.0, -2.0, 3.5],
            }],
        })
    }

    #[test]
    fn round_trip_keeps_every_field() {
        let bytes = encode("run", "left", 42, &sample()).unwrap();
        let env = decode(&bytes).unwrap();
        assert_eq!(env.run, "run");
        assert_eq!(env.sender, "left");
        assert_eq!(env.seq, 42);
        assert_eq!(env.message, sample());
    }

    #[test]
    fn truncated_wrong_version_and_oversized_are_errors() {
        let bytes = encode("run", "left", 1, &sample()).unwrap();
        for n in 0..bytes.len() {
            assert!(decode(&bytes[..n]).is_err(), "prefix of {n} bytes accepted");
        }
        let mut v = bytes.clone();
        v[4] = 9;
        assert_eq!(decode(&v), Err(CodecError::WrongVersion { got: 9 }));
        let mut v = bytes.clone();
        v[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(decode(&v), Err(CodecError::Oversized(_))));
        let mut v = bytes.clone();
        v[0] = b'X';
        assert!(matches!(decode(&v), Err(CodecError::BadMagic(_))));
        let mut v = bytes.clone();
        v[6] = 3;
        assert!(matches!(decode(&v), Err(CodecError::KindMismatch { .. })));
        let mut v = bytes;
        v.push(0);
        assert!(matches!(decode(&v), Err(CodecError::LengthMismatch { .. })));
    }

    #[test]
    fn forged_vector_length_is_an_error_not_an_allocation() {
        // A Fields body whose values vector claims 2^60 elements.
        let mut bytes = encode("r", "s", 0, &sample()).unwrap();
        let n = bytes.len();
        // The last 3*8 bytes are the f64s; the byte before them is the varint length 24.
        assert_eq!(bytes[n - 25], 24);
        bytes.truncate(n - 25);
        bytes.push(255); // varint marker: u64 follows
        bytes.extend_from_slice(&(1u64 << 60).to_le_bytes());
        let len = (bytes.len() - HEADER_LEN) as u32;
        bytes[8..12].copy_from_slice(&len.to_le_bytes());
        assert!(decode(&bytes).is_err());
    }

    proptest! {
        #[test]
        fn random_bytes_never_panic(data in proptest::collection::vec(any::<u8>(), 0..512)) {
            let _ = decode(&data);
            let _ = decode_fields_view(&data);
        }

        #[test]
        fn random_bodies_behind_a_valid_header_never_panic(
            kind in 0u8..16, body in proptest::collection::vec(any::<u8>(), 0..512)) {
            let mut v = Vec::new();
            v.extend_from_slice(&MAGIC);
            v.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
            v.push(kind);
            v.push(0);
            v.extend_from_slice(&(body.len() as u32).to_le_bytes());
            v.extend_from_slice(&0u64.to_le_bytes());
            v.extend_from_slice(&body);
            let _ = decode(&v);
            let _ = decode_fields_view(&v);
        }

        #[test]
        fn flipped_bytes_of_a_valid_message_never_panic(pos in 0usize..200, val in any::<u8>()) {
            let mut bytes = encode("run", "left", 1, &sample()).unwrap();
            let p = pos % bytes.len();
            bytes[p] = val;
            let _ = decode(&bytes);
            let _ = decode_fields_view(&bytes);
        }
    }
}
