//! `cosim info` checks a file's bytes before it reads them: a file that is not MCAP is "not a
//! recording" and a damaged one "corrupt at byte N" (both exit 1, with nothing invented about
//! a run), a recording cut short by a killed run reads as INCOMPLETE as far as it goes, an
//! intact one passes. Where a chunk lies is read from the `mcap` crate's chunk index, not from
//! cosim's own reader, and the official Python reader (`tools/check_mcap.py --crc`) confirms
//! that each damaged file really fails a CRC.

use cosim_tests::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One recorded split-bar run shared by the tests of this file.
fn recorded() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let (dir, id) = scratch("rc-rec");
        let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 0.5);
        let out = dir.join("out");
        let o = run_case(&case, &out, &id, &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out.join("run.mcap")
    })
}

/// `cosim info [--json] FILE`: (exit code, stdout, stderr).
fn info(path: &Path, json: bool) -> (Option<i32>, String, String) {
    let p = path.to_str().expect("utf-8 path");
    let args: Vec<&str> = if json {
        vec!["info", "--json", p]
    } else {
        vec!["info", p]
    };
    let o = cosim(&args);
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// What the official reader says of `path` with its CRC checks on: Some(passed), or None
/// after [`skip_or_fail`] where its package is missing.
fn official_crc(path: &Path, test: &str) -> Option<(bool, String)> {
    let (ok, text) = check_mcap(path, "--crc");
    if text.contains("package is missing") {
        skip_or_fail(test, &text);
        return None;
    }
    Some((ok, text))
}

/// Refused as not a recording, in text and JSON, without a word about a run.
fn assert_not_a_recording(path: &Path) {
    for json in [false, true] {
        let (code, out, err) = info(path, json);
        println!("json {json}: {out}{err}");
        assert_eq!(code, Some(1), "{err}");
        assert!(err.contains("not a recording"), "{err}");
        assert!(
            out.is_empty(),
            "a summary invented for a file with none: {out}"
        );
        assert!(!err.contains("INCOMPLETE"), "{err}");
    }
}

#[test]
fn an_empty_file_is_not_a_recording() {
    let (dir, _) = scratch("rc-empty");
    let p = dir.join("empty.mcap");
    std::fs::write(&p, b"").unwrap();
    assert_not_a_recording(&p);
}

#[test]
fn random_bytes_are_not_a_recording() {
    let (dir, _) = scratch("rc-random");
    let p = dir.join("random.mcap");
    let mut draw = Draw::seeded();
    println!("COSIM_TEST_SEED={}", draw.0);
    let bytes: Vec<u8> = (0..65_536)
        .map(|_| (draw.uniform() * 256.0) as u8)
        .collect();
    std::fs::write(&p, &bytes).unwrap();
    assert_not_a_recording(&p);
}

/// One byte of a chunk's compressed records flipped, for the first, a middle and the last
/// chunk: `cosim info` names the byte where that chunk begins, the official reader fails
/// the file too, and a replay refuses it rather than compare against damaged data.
#[test]
fn a_flipped_byte_inside_a_chunk_is_corrupt_at_that_chunk() {
    let test = "a_flipped_byte_inside_a_chunk_is_corrupt_at_that_chunk";
    let bytes = std::fs::read(recorded()).unwrap();
    let summary = mcap::Summary::read(&bytes)
        .expect("the mcap crate reads the summary")
        .expect("a finished recording has a summary");
    let chunks = &summary.chunk_indexes;
    assert!(chunks.len() >= 3, "{} chunks", chunks.len());
    let (dir, _) = scratch("rc-flip");
    for (n, c) in [0, chunks.len() / 2, chunks.len() - 1]
        .into_iter()
        .map(|i| (i, &chunks[i]))
    {
        // A chunk record ends with its compressed records.
        let end = c.chunk_start_offset + c.chunk_length;
        let at = (end - c.compressed_size + c.compressed_size / 2) as usize;
        let mut flipped = bytes.clone();
        flipped[at] ^= 0xff;
        let p = dir.join(format!("flipped-{n}.mcap"));
        std::fs::write(&p, &flipped).unwrap();
        let (code, out, err) = info(&p, false);
        println!(
            "chunk {n} at byte {}, flip at {at}: {out}{err}",
            c.chunk_start_offset
        );
        assert_eq!(code, Some(1), "{out}{err}");
        assert!(
            err.contains(&format!("corrupt at byte {}", c.chunk_start_offset)),
            "chunk {n}: {err}"
        );
        assert!(out.is_empty(), "{out}");
        let Some((ok, text)) = official_crc(&p, test) else {
            return;
        };
        assert!(!ok, "the official reader passed the flipped file: {text}");
        let (_, id) = scratch("rc-flip-rp");
        let (ok, out, err) = replay_node(&p, "right", &id, &[]);
        assert!(!ok, "a corrupt recording replayed: {out}");
        assert!(err.contains("corrupt at byte"), "{err}");
        nothing_left(&id);
    }
}

/// A byte of the header record (outside every chunk) flipped: only the data section's CRC
/// covers it, and it fails.
#[test]
fn a_flipped_byte_outside_the_chunks_fails_the_data_section_crc() {
    let test = "a_flipped_byte_outside_the_chunks_fails_the_data_section_crc";
    let mut bytes = std::fs::read(recorded()).unwrap();
    // magic (8), opcode (1), length (8), profile length (4), then the profile "cosim"
    assert_eq!(&bytes[21..26], b"cosim", "the header's profile");
    bytes[22] ^= 0xff;
    let (dir, _) = scratch("rc-header");
    let p = dir.join("header.mcap");
    std::fs::write(&p, &bytes).unwrap();
    let (code, out, err) = info(&p, false);
    println!("{out}{err}");
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(err.contains("corrupt between bytes 0 and"), "{err}");
    assert!(err.contains("data section"), "{err}");
    let Some((ok, text)) = official_crc(&p, test) else {
        return;
    };
    assert!(!ok, "the official reader passed the flipped file: {text}");
}

#[test]
fn an_intact_recording_passes_and_one_cut_short_reads_incomplete() {
    let test = "an_intact_recording_passes_and_one_cut_short_reads_incomplete";
    let (code, out, err) = info(recorded(), false);
    println!("{out}{err}");
    assert_eq!(code, Some(0), "{err}");
    assert!(
        out.contains("complete") && !out.contains("INCOMPLETE"),
        "{out}"
    );
    assert!(out.contains("schedule serial, transport shm"), "{out}");
    if let Some((ok, text)) = official_crc(recorded(), test) {
        assert!(ok, "the official reader fails the intact recording: {text}");
    }
    // What a killed run leaves: the file ends inside a record, without the end magic.
    let bytes = std::fs::read(recorded()).unwrap();
    let (dir, _) = scratch("rc-cut");
    let p = dir.join("cut.mcap");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let (code, out, err) = info(&p, false);
    println!("{out}{err}");
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("INCOMPLETE: writer stopped early"), "{out}");
    assert!(out.contains("schedule serial, transport shm"), "{out}");
    let windows: u64 = out
        .lines()
        .find_map(|l| {
            l.strip_prefix("windows")?
                .trim()
                .split(' ')
                .next()?
                .parse()
                .ok()
        })
        .expect("a windows line");
    assert!(windows > 0, "{out}");
}
