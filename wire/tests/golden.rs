//! The golden vectors of the wire contract (`wire/golden/`, written once by
//! `cargo run -p wire --example write_golden`): every `.bin` decodes to exactly its `.json`,
//! and every `.json` encodes back to exactly its `.bin`, so a change to any wire type that
//! alters a byte fails here. Two vectors are also checked against bytes derived by hand
//! from PROTOCOL.md, independently of the codec.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use wire::codec::{HEADER_LEN, decode, encode, header};
use wire::{Envelope, Message, kind_name};

fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden")
}

/// Every vector as (stem, bytes, JSON), in file-name order.
fn vectors() -> Vec<(String, Vec<u8>, serde_json::Value)> {
    let dir = golden_dir();
    let mut stems: Vec<String> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "bin"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    stems.sort();
    stems
        .into_iter()
        .map(|s| {
            let bin = std::fs::read(dir.join(format!("{s}.bin"))).unwrap();
            let text = std::fs::read_to_string(dir.join(format!("{s}.json")))
                .unwrap_or_else(|e| panic!("{s}.json: {e}"));
            let json: serde_json::Value =
                serde_json::from_str(&text).unwrap_or_else(|e| panic!("{s}.json: {e}"));
            (s, bin, json)
        })
        .collect()
}

#[test]
fn every_vector_decodes_to_its_json_and_encodes_back_to_its_bytes() {
    let vs = vectors();
    let mut kinds = BTreeSet::new();
    for (stem, bin, json) in &vs {
        let env = decode(bin).unwrap_or_else(|e| panic!("{stem}.bin does not decode: {e}"));
        let got = serde_json::to_value(&env).unwrap();
        assert_eq!(
            &got, json,
            "{stem}.bin decodes to something else than {stem}.json"
        );
        let h = header(bin).unwrap();
        assert_eq!(h.kind, env.message.kind(), "{stem}: header kind");
        assert_eq!(
            h.body_len as usize,
            bin.len() - HEADER_LEN,
            "{stem}: body length"
        );
        kinds.insert(env.message.kind());

        let from_json: Envelope = serde_json::from_value(json.clone())
            .unwrap_or_else(|e| panic!("{stem}.json is not an envelope: {e}"));
        let bytes = encode(
            &from_json.run,
            &from_json.sender,
            from_json.seq,
            &from_json.message,
        )
        .unwrap();
        assert!(
            bytes == *bin,
            "{stem}.json encodes to other bytes than {stem}.bin:\n got  {bytes:02x?}\n want {bin:02x?}"
        );
    }
    assert!(vs.len() >= 20, "only {} golden vectors checked", vs.len());
    // Every kind the codec names (a new message needs a name, hence a vector here too).
    let all: BTreeSet<u8> = (0..=u8::MAX)
        .filter(|&k| kind_name(k) != "cosim.Unknown")
        .collect();
    assert_eq!(all.len(), 13);
    assert_eq!(kinds, all, "message kinds covered by the golden vectors");
}

#[test]
fn no_json_without_its_bytes() {
    let dir = golden_dir();
    let mut json = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "json") {
            json += 1;
            assert!(
                p.with_extension("bin").exists(),
                "{} has no .bin",
                p.display()
            );
        }
    }
    assert_eq!(json, vectors().len());
}

fn read(stem: &str) -> Vec<u8> {
    std::fs::read(golden_dir().join(format!("{stem}.bin"))).unwrap()
}

/// Header: magic, version 4 (u16 LE), kind, reserved 0, body length (u32 LE), seq (u64 LE).
fn header_bytes(kind: u8, body_len: u32, seq: u64) -> Vec<u8> {
    let mut v = b"CSIM".to_vec();
    v.extend_from_slice(&[4, 0, kind, 0]);
    v.extend_from_slice(&body_len.to_le_bytes());
    v.extend_from_slice(&seq.to_le_bytes());
    v
}

#[test]
fn heartbeat_bytes_match_the_written_layout() {
    // Heartbeat { window: 3, substeps: 300, waiting: true } from "right", seq 7, run "demo-1".
    let body: Vec<u8> = [
        &[6u8][..],
        b"demo-1", // run: varint length 6, UTF-8 bytes
        &[5],
        b"right",            // sender
        &[8],                // Message variant index 8 = Heartbeat (kind 9)
        &[3],                // window: varint < 251, one byte
        &[0xfb, 0x2c, 0x01], // substeps 300: marker 251, then u16 LE
        &[1],                // waiting: bool as one byte
    ]
    .concat();
    let want = [header_bytes(9, body.len() as u32, 7), body].concat();
    assert_eq!(want.len(), 20 + 19);
    assert_eq!(read("09_heartbeat"), want);
}

#[test]
fn advance_bytes_match_the_written_layout() {
    // Advance { window: 2^40, t0: 0.5, t1: 1.0, write_output, checkpoint } from
    // "coordinator", seq 0x0102030405060708.
    let body: Vec<u8> = [
        &[6u8][..],
        b"demo-1",
        &[11],
        b"coordinator",
        &[5],                            // variant index 5 = Advance (kind 6)
        &[0xfd, 0, 0, 0, 0, 0, 1, 0, 0], // 2^40: marker 253, then u64 LE
        &[0, 0, 0, 0, 0, 0, 0xe0, 0x3f], // 0.5 = 0x3FE0000000000000, LE
        &[0, 0, 0, 0, 0, 0, 0xf0, 0x3f], // 1.0 = 0x3FF0000000000000, LE
        &[1, 1],
    ]
    .concat();
    assert_eq!(body.len(), 47);
    let want = [header_bytes(6, 47, 0x0102_0304_0506_0708), body].concat();
    assert_eq!(&want[12..20], &[8, 7, 6, 5, 4, 3, 2, 1]);
    assert_eq!(read("19_advance_varints"), want);
}

#[test]
fn field_values_are_one_byte_string_on_the_wire_and_numbers_in_json() {
    // Fields { coupling "tip", window 1, time 4.956e-7, [velocity, 1 component, [-0.25]] }.
    let bin = read("07_fields");
    let tail: Vec<u8> = [
        &[8u8][..],
        b"velocity",
        &[1],                            // components
        &[8],                            // the byte string: 8 bytes ...
        &[0, 0, 0, 0, 0, 0, 0xd0, 0xbf], // ... -0.25 = 0xBFD0000000000000, LE
    ]
    .concat();
    assert!(bin.ends_with(&tail), "{bin:02x?}");
    let env = decode(&bin).unwrap();
    let json = serde_json::to_value(&env).unwrap();
    assert_eq!(
        json["message"]["Fields"]["fields"][0]["values"],
        serde_json::json!([-0.25])
    );
    let Message::Fields(f) = env.message else {
        panic!("07_fields is not a Fields message")
    };
    assert_eq!(f.fields[0].values, vec![-0.25]);
}
