//! Versioned envelope and codec (PROTOCOL.md, "Bytes"): a fixed 20-byte header (magic,
//! protocol version, message kind, body length, sequence number) followed by the bincode 2
//! body (`config::standard()`) of run, sender and message. Decoding checks every header field and
//! the exact body length before bincode sees a byte, and caps allocations, so no input panics.

use crate::message::{Message, StepReport};
use bincode::config;
use serde::de::{DeserializeSeed, Deserializer, SeqAccess, Visitor};
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
struct Body<'a> {
    run: &'a str,
    sender: &'a str,
    message: Message,
}

/// An envelope whose run and sender borrow the received bytes ([`decode_ref`]): a message
/// without strings of its own (a heartbeat, say) is read without allocating.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvelopeRef<'a> {
    pub run: &'a str,
    pub sender: &'a str,
    pub seq: u64,
    pub message: Message,
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
    decode_ref(bytes).map(|e| Envelope {
        run: e.run.to_string(),
        sender: e.sender.to_string(),
        seq: e.seq,
        message: e.message,
    })
}

/// [`decode`] with the run and sender left in `bytes`. Never panics.
pub fn decode_ref(bytes: &[u8]) -> Result<EnvelopeRef<'_>, CodecError> {
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
    Ok(EnvelopeRef {
        run: b.run,
        sender: b.sender,
        seq: h.seq,
        message: b.message,
    })
}

/// The `Fields` message of an envelope read in place: strings and values borrow the
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
/// `F` holds the fields: a vector of views.
#[derive(Deserialize)]
#[serde(bound(deserialize = "F: Deserialize<'de>"))]
struct FieldsBody<'a, F> {
    run: &'a str,
    sender: &'a str,
    variant: u32,
    coupling: &'a str,
    window: u64,
    time: f64,
    fields: F,
}

/// A field's bytes must be a whole number of f64 values.
fn whole_values(f: &FieldView) -> Result<(), String> {
    if f.bytes.len().is_multiple_of(8) {
        return Ok(());
    }
    Err(format!(
        "field '{}': {} bytes is not a whole number of f64 values",
        f.name,
        f.bytes.len()
    ))
}

/// The header and body of a `Fields` envelope, checked as [`decode`] checks them.
fn read_fields<'a, F: Deserialize<'a>>(
    bytes: &'a [u8],
) -> Result<(Header, FieldsBody<'a, F>), CodecError> {
    let (h, body) = header_of_kind(bytes, FIELDS_KIND)?;
    let cfg = config::standard().with_limit::<MAX_BODY>();
    let (b, used): (FieldsBody<F>, usize) = bincode::serde::borrow_decode_from_slice(body, cfg)
        .map_err(|e| CodecError::Body(e.to_string()))?;
    body_read(&h, b.variant, FIELDS_VARIANT, used, body.len())?;
    Ok((h, b))
}

/// The checked header of a message that must be of `kind`, and its body.
fn header_of_kind(bytes: &[u8], kind: u8) -> Result<(Header, &[u8]), CodecError> {
    let h = header(bytes)?;
    if h.kind != kind {
        return Err(CodecError::KindMismatch {
            header: h.kind,
            body: kind,
        });
    }
    Ok((h, &bytes[HEADER_LEN..]))
}

/// A body read up to `used` of its `len` bytes holds the variant the header announced
/// (`expected`) and nothing after it.
fn body_read(
    h: &Header,
    variant: u32,
    expected: u32,
    used: usize,
    len: usize,
) -> Result<(), CodecError> {
    if variant != expected {
        return Err(CodecError::KindMismatch {
            header: h.kind,
            body: u8::try_from(variant + 1).unwrap_or(u8::MAX),
        });
    }
    if used != len {
        return Err(CodecError::Trailing(len - used));
    }
    Ok(())
}

/// What [`decode_fields_head`] reads of a `Fields` envelope: all but the values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldsHead<'a> {
    pub run: &'a str,
    pub sender: &'a str,
    pub seq: u64,
    pub coupling: &'a str,
    pub window: u64,
    pub time: f64,
}

/// Check a `Fields` envelope as [`decode_fields_view`] does, keeping only its routing and
/// window (the coordinator records peer data it does not read, every window): nothing is
/// allocated. Never panics.
pub fn decode_fields_head(bytes: &[u8]) -> Result<FieldsHead<'_>, CodecError> {
    decode_fields_each(bytes, &mut |_| {})
}

/// [`decode_fields_head`], handing each field to `each` as it is read (its name, components
/// and values in place; the fields before a decoding error included): a reader checks what
/// a `Fields` holds without keeping it, allocating nothing. Never panics.
pub fn decode_fields_each<'a>(
    bytes: &'a [u8],
    each: &mut dyn FnMut(&FieldView<'a>),
) -> Result<FieldsHead<'a>, CodecError> {
    let (h, body) = header_of_kind(bytes, FIELDS_KIND)?;
    let cfg = config::standard().with_limit::<MAX_BODY>();
    let (b, used) = bincode::serde::seed_decode_from_slice(FieldsSeed(each), body, cfg)
        .map_err(|e| CodecError::Body(e.to_string()))?;
    body_read(&h, b.variant, FIELDS_VARIANT, used, body.len())?;
    Ok(FieldsHead {
        run: b.run,
        sender: b.sender,
        seq: h.seq,
        coupling: b.coupling,
        window: b.window,
        time: b.time,
    })
}

/// The body of a `Fields` envelope as bincode lays it out (run, sender, the enum's variant
/// index, then the `Fields` struct), each field handed to the callback and not kept.
struct FieldsSeed<'f, 'a>(&'f mut dyn FnMut(&FieldView<'a>));

/// What [`FieldsSeed`] keeps of a `Fields` body: all but the fields.
struct FieldsRouting<'a> {
    run: &'a str,
    sender: &'a str,
    variant: u32,
    coupling: &'a str,
    window: u64,
    time: f64,
}

impl<'a> DeserializeSeed<'a> for FieldsSeed<'_, 'a> {
    type Value = FieldsRouting<'a>;

    fn deserialize<D: Deserializer<'a>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_tuple(ANY_LEN, self)
    }
}

impl<'a> Visitor<'a> for FieldsSeed<'_, 'a> {
    type Value = FieldsRouting<'a>;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a Fields envelope body")
    }

    fn visit_seq<A: SeqAccess<'a>>(self, mut s: A) -> Result<Self::Value, A::Error> {
        let mut b = FieldsRouting {
            run: s.next_element()?.ok_or_else(|| missing("the run"))?,
            sender: s.next_element()?.ok_or_else(|| missing("the sender"))?,
            variant: s.next_element()?.ok_or_else(|| missing("the kind"))?,
            coupling: "",
            window: 0,
            time: 0.0,
        };
        if b.variant != FIELDS_VARIANT {
            return Ok(b);
        }
        b.coupling = s.next_element()?.ok_or_else(|| missing("the coupling"))?;
        b.window = s.next_element()?.ok_or_else(|| missing("the window"))?;
        b.time = s.next_element()?.ok_or_else(|| missing("the time"))?;
        s.next_element_seed(EachField(self.0))?
            .ok_or_else(|| missing("the fields"))?;
        Ok(b)
    }
}

/// The fields of a `Fields` body, each checked to be a whole number of f64 values and
/// handed to the callback.
struct EachField<'f, 'a>(&'f mut dyn FnMut(&FieldView<'a>));

impl<'a> DeserializeSeed<'a> for EachField<'_, 'a> {
    type Value = ();

    fn deserialize<D: Deserializer<'a>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'a> Visitor<'a> for EachField<'_, 'a> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("fields")
    }

    fn visit_seq<A: SeqAccess<'a>>(self, mut s: A) -> Result<(), A::Error> {
        while let Some(f) = s.next_element::<FieldView<'a>>()? {
            whole_values(&f).map_err(serde::de::Error::custom)?;
            (self.0)(&f);
        }
        Ok(())
    }
}

/// `Message::Fields`'s variant index in the enum (its declaration order).
const FIELDS_VARIANT: u32 = 6;
/// `Message::Fields`'s kind in the header.
pub const FIELDS_KIND: u8 = 7;

/// Read a `Fields` envelope in place; any other message, or malformed bytes, is an error.
/// Never panics.
pub fn decode_fields_view(bytes: &[u8]) -> Result<FieldsView<'_>, CodecError> {
    let (h, b) = read_fields::<Vec<FieldView>>(bytes)?;
    for f in &b.fields {
        whole_values(f).map_err(CodecError::Body)?;
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

/// The routing of a `Done` envelope read by [`decode_done_into`]; its report went into the
/// caller's `StepReport`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DoneHead<'a> {
    pub run: &'a str,
    pub sender: &'a str,
    pub seq: u64,
    pub window: u64,
}

/// `Message::Done`'s variant index in the enum (its declaration order).
const DONE_VARIANT: u32 = 7;
/// `Message::Done`'s kind in the header.
pub const DONE_KIND: u8 = 8;

/// Read a `Done` envelope, its report into `report` in place (the coordinator reads
/// a `Done` from every node every window). The report's scalars vector and their names keep
/// their buffers, so once `report` has held a report with the same scalar names nothing is
/// allocated. The header, kind, lengths and trailing bytes are checked exactly as [`decode`]
/// checks them; `report` holds the decoded report only on success. Never panics.
pub fn decode_done_into<'a>(
    bytes: &'a [u8],
    report: &mut StepReport,
) -> Result<DoneHead<'a>, CodecError> {
    let (h, body) = header_of_kind(bytes, DONE_KIND)?;
    let cfg = config::standard().with_limit::<MAX_BODY>();
    let ((run, sender, variant, window), used) =
        bincode::serde::seed_decode_from_slice(DoneSeed(report), body, cfg)
            .map_err(|e| CodecError::Body(e.to_string()))?;
    body_read(&h, variant, DONE_VARIANT, used, body.len())?;
    Ok(DoneHead {
        run,
        sender,
        seq: h.seq,
        window,
    })
}

/// The body of a `Done` envelope as bincode lays it out (run, sender, the enum's variant
/// index, then the `Done` struct), its report read into the target.
struct DoneSeed<'r>(&'r mut StepReport);

/// The number of elements a reader may ask of a bincode tuple: bincode ignores it.
const ANY_LEN: usize = usize::MAX;

fn missing<E: serde::de::Error>(what: &str) -> E {
    E::custom(format_args!("the body ends before {what}"))
}

impl<'de> DeserializeSeed<'de> for DoneSeed<'_> {
    type Value = (&'de str, &'de str, u32, u64);

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Self::Value, D::Error> {
        d.deserialize_tuple(ANY_LEN, self)
    }
}

impl<'de> Visitor<'de> for DoneSeed<'_> {
    type Value = (&'de str, &'de str, u32, u64);

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a Done envelope body")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut s: A) -> Result<Self::Value, A::Error> {
        let run: &str = s.next_element()?.ok_or_else(|| missing("the run"))?;
        let sender: &str = s.next_element()?.ok_or_else(|| missing("the sender"))?;
        let variant: u32 = s.next_element()?.ok_or_else(|| missing("the kind"))?;
        if variant != DONE_VARIANT {
            return Ok((run, sender, variant, 0));
        }
        let window: u64 = s.next_element()?.ok_or_else(|| missing("the window"))?;
        s.next_element_seed(ReportSeed(self.0))?
            .ok_or_else(|| missing("the report"))?;
        Ok((run, sender, variant, window))
    }
}

/// A `StepReport` read into an existing one, field by field in declaration order. A field
/// added to `StepReport` and not here leaves its bytes unread: the read fails with trailing
/// bytes, and so does the test `done_read_in_place_equals_decode`.
struct ReportSeed<'r>(&'r mut StepReport);

impl<'de> DeserializeSeed<'de> for ReportSeed<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_tuple(ANY_LEN, self)
    }
}

impl<'de> Visitor<'de> for ReportSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a step report")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut s: A) -> Result<(), A::Error> {
        let r = self.0;
        fn next<'de, T: Deserialize<'de>, A: SeqAccess<'de>>(
            s: &mut A,
            what: &str,
        ) -> Result<T, A::Error> {
            s.next_element()?.ok_or_else(|| missing(what))
        }
        r.kinetic_energy = next(&mut s, "kinetic_energy")?;
        r.internal_energy = next(&mut s, "internal_energy")?;
        r.external_work = next(&mut s, "external_work")?;
        r.interface_work = next(&mut s, "interface_work")?;
        r.momentum = next(&mut s, "momentum")?;
        r.momentum_gross = next(&mut s, "momentum_gross")?;
        r.external_impulse = next(&mut s, "external_impulse")?;
        r.applied_impulse = next(&mut s, "applied_impulse")?;
        r.interface_impulse = next(&mut s, "interface_impulse")?;
        r.substeps = next(&mut s, "substeps")?;
        r.wall_s = next(&mut s, "wall_s")?;
        r.coupling_wait_s = next(&mut s, "coupling_wait_s")?;
        r.idle_s = next(&mut s, "idle_s")?;
        s.next_element_seed(ScalarsSeed(&mut r.scalars))?
            .ok_or_else(|| missing("the scalars"))
    }
}

/// Named scalars read into an existing vector: a name equal to the one already in its place
/// is left alone, another overwrites that place's `String` (its buffer reused).
struct ScalarsSeed<'r>(&'r mut Vec<(String, f64)>);

impl<'de> DeserializeSeed<'de> for ScalarsSeed<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for ScalarsSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("named scalars")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut s: A) -> Result<(), A::Error> {
        let v = self.0;
        let mut n = 0;
        while let Some((name, x)) = s.next_element::<(&str, f64)>()? {
            match v.get_mut(n) {
                Some(slot) => {
                    if slot.0 != name {
                        slot.0.clear();
                        slot.0.push_str(name);
                    }
                    slot.1 = x;
                }
                None => v.push((name.to_string(), x)),
            }
            n += 1;
        }
        v.truncate(n);
        Ok(())
    }
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

    /// A `Done` read into an existing report gives what the full decode gives, whatever the
    /// report held before (no scalars, more, fewer, other names); a report with the same
    /// names keeps their buffers (no allocation); other kinds, cut, extended or relabelled
    /// bytes are errors.
    #[test]
    fn done_read_in_place_equals_decode() {
        let report = StepReport {
            kinetic_energy: 1.5,
            internal_energy: -2.25,
            external_work: 3.0e-7,
            interface_work: 4.0,
            momentum: [5.0, 6.0, -7.0],
            momentum_gross: 8.5,
            external_impulse: [9.0, 10.0, 11.0],
            applied_impulse: 12.0,
            interface_impulse: [13.0, -14.0, 15.0],
            substeps: 16,
            wall_s: 17.0,
            coupling_wait_s: 18.0,
            idle_s: 19.0,
            scalars: vec![("tip".into(), 20.0), ("plastic_work".into(), 21.0)],
        };
        let m = Message::Done(Done {
            window: 77,
            report: report.clone(),
        });
        let bytes = encode("run-9", "right", 5, &m).unwrap();
        let full = decode(&bytes).unwrap();
        assert_eq!(full.message, m);
        let held = [
            StepReport::default(),
            StepReport {
                scalars: vec![("a".into(), 1.0), ("b".into(), 2.0), ("c".into(), 3.0)],
                ..StepReport::default()
            },
            StepReport {
                scalars: vec![("x".into(), 1.0)],
                ..report.clone()
            },
        ];
        for mut r in held {
            let h = decode_done_into(&bytes, &mut r).unwrap();
            assert_eq!(
                h,
                DoneHead {
                    run: "run-9",
                    sender: "right",
                    seq: 5,
                    window: 77
                }
            );
            assert_eq!(r, report);
            // Again into itself: the names are kept where they lie.
            let at: Vec<*const u8> = r.scalars.iter().map(|(n, _)| n.as_ptr()).collect();
            decode_done_into(&bytes, &mut r).unwrap();
            assert_eq!(r, report);
            let again: Vec<*const u8> = r.scalars.iter().map(|(n, _)| n.as_ptr()).collect();
            assert_eq!(at, again);
        }
        let mut r = StepReport::default();
        // Another kind in the header, or another message under a forged Done header.
        let fields = encode("run-9", "right", 5, &sample()).unwrap();
        assert!(matches!(
            decode_done_into(&fields, &mut r),
            Err(CodecError::KindMismatch { .. })
        ));
        let beat = Message::Heartbeat(Heartbeat {
            window: 3,
            substeps: 4,
            waiting: false,
        });
        let mut forged = encode("run-9", "right", 5, &beat).unwrap();
        forged[6] = DONE_KIND;
        assert!(decode_done_into(&forged, &mut r).is_err());
        // Every cut is refused (the header's length no longer matches, or the body ends).
        for n in 0..bytes.len() {
            assert!(decode_done_into(&bytes[..n], &mut r).is_err(), "cut at {n}");
        }
        // A byte more, with the header's length saying so: trailing bytes.
        let mut longer = bytes.clone();
        longer.push(0);
        let len = (longer.len() - HEADER_LEN) as u32;
        longer[8..12].copy_from_slice(&len.to_le_bytes());
        assert_eq!(
            decode_done_into(&longer, &mut r),
            Err(CodecError::Trailing(1))
        );
        assert_eq!(decode(&longer).err(), Some(CodecError::Trailing(1)));
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
        // The head checks what the view checks, keeping only the routing and the window.
        let head = decode_fields_head(&bytes).unwrap();
        assert_eq!(
            head,
            FieldsHead {
                run: "run7",
                sender: "left",
                seq: 9,
                coupling: "mid",
                window: 42,
                time: 1.5e-3
            }
        );
        assert!(matches!(
            decode_fields_head(&done),
            Err(CodecError::KindMismatch { .. })
        ));
        for n in 0..bytes.len() {
            assert!(decode_fields_head(&bytes[..n]).is_err(), "cut at {n}");
        }
        assert_eq!(decode_fields_head(&longer), Err(CodecError::Trailing(1)));
        // A field of 7 bytes (the last value cut, its length and the header's adjusted) is
        // refused by all three readers.
        let one = encode("run7", "left", 9, &sample()).unwrap();
        let mut odd = one.clone();
        odd.pop();
        let at = odd.len() - 24;
        assert_eq!(
            odd[at], 24,
            "the values' length prefix (3 values, 24 bytes)"
        );
        odd[at] = 23;
        let n = (odd.len() - HEADER_LEN) as u32;
        odd[8..12].copy_from_slice(&n.to_le_bytes());
        assert!(decode(&odd).is_err());
        let why = decode_fields_view(&odd).unwrap_err().to_string();
        assert!(why.contains("23 bytes is not a whole number"), "{why}");
        let why = decode_fields_head(&odd).unwrap_err().to_string();
        assert!(why.contains("23 bytes is not a whole number"), "{why}");
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
