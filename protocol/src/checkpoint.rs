//! Checkpoints of a run (docs/architecture.md): the one container every node's state is written in
//! by the participant runtime (never by the node itself), its place in the run directory, and
//! the serde helpers a node uses to turn its state into the payload. PROTOCOL.md §7.
//!
//! Container: `COSIMCKP`, format version (u16 LE), then the [`Checkpoint`] record in bincode
//! (standard config), then an FNV-1a 64 of everything before it (u64 LE). Written to a
//! temporary file that is renamed into place, so a checkpoint file is whole or absent.

use crate::message::Fields;
use crate::solver::{SolverError, SolverResult};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// First bytes of every checkpoint file.
pub const MAGIC: [u8; 8] = *b"COSIMCKP";
/// Version of the container layout and of the built-in nodes' payloads; a reader refuses any
/// other. 2: the joint node's coupling state holds the shared sync-force `Follow`. 3: the
/// peridynamic node's state in the same serde encoding as every other node's.
pub const FORMAT_VERSION: u16 = 3;
/// File name of the coordinator's own state in a checkpoint directory.
pub const COORDINATOR: &str = "coordinator";

/// One node's state at the end of a window, with what identifies it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// Node name in the case (`coordinator` for the coordinator's own state).
    pub node: String,
    /// Solver model (`bar-1d`, `euler`, ...).
    pub model: String,
    /// The window at whose end the state was taken.
    pub window: u64,
    /// Its end time, s.
    pub time: f64,
    /// [`params_hash`] of the node's parameters: a restart with other parameters is refused.
    pub params_hash: u64,
    /// What the node sent its peers at the end of that window: sent again on restore, so a
    /// peer that uses it in the next window (a lagged input) finds it.
    pub sent: Vec<Fields>,
    /// The solver's own state (`Solver::save_state`).
    pub payload: Vec<u8>,
}

#[derive(Debug, Error)]
pub enum CheckpointError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {reason}")]
    Bad { path: PathBuf, reason: String },
}

/// FNV-1a, 64 bits: the integrity check of a container and the hash of a parameter text.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Hash of a node's parameters as the `Welcome` carries them (`params_toml`).
pub fn params_hash(params_toml: &str) -> u64 {
    fnv1a(params_toml.as_bytes())
}

/// Directory of the checkpoint taken at the end of `window` in run directory `run_dir`.
pub fn dir(run_dir: &Path, window: u64) -> PathBuf {
    run_dir.join("checkpoints").join(format!("w{window:010}"))
}

/// File of `node`'s checkpoint at the end of `window`.
pub fn file(run_dir: &Path, window: u64, node: &str) -> PathBuf {
    dir(run_dir, window).join(format!("{node}.ckpt"))
}

/// The windows that have a checkpoint directory in `run_dir`, newest first.
pub fn windows(run_dir: &Path) -> Vec<u64> {
    let mut v: Vec<u64> = std::fs::read_dir(run_dir.join("checkpoints"))
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .filter_map(|e| {
                    let name = e.file_name();
                    let s = name.to_str()?;
                    s.strip_prefix('w')?.parse::<u64>().ok()
                })
                .collect()
        })
        .unwrap_or_default();
    v.sort_unstable_by(|a, b| b.cmp(a));
    v
}

impl Checkpoint {
    /// The container's bytes.
    pub fn to_bytes(&self) -> Result<Vec<u8>, String> {
        let mut b = Vec::with_capacity(self.payload.len() + 256);
        b.extend_from_slice(&MAGIC);
        b.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        bincode::serde::encode_into_std_write(self, &mut b, bincode::config::standard())
            .map_err(|e| e.to_string())?;
        let h = fnv1a(&b);
        b.extend_from_slice(&h.to_le_bytes());
        Ok(b)
    }

    /// Read a container, checking magic, version, length and integrity.
    pub fn from_bytes(b: &[u8]) -> Result<Self, String> {
        if b.len() < MAGIC.len() + 2 + 8 || b[..MAGIC.len()] != MAGIC {
            return Err("not a cosim checkpoint (bad magic)".into());
        }
        let v = u16::from_le_bytes([b[8], b[9]]);
        if v != FORMAT_VERSION {
            return Err(format!(
                "checkpoint format version {v}, this build reads {FORMAT_VERSION}"
            ));
        }
        let (body, tail) = b.split_at(b.len() - 8);
        let mut h = [0u8; 8];
        h.copy_from_slice(tail);
        if u64::from_le_bytes(h) != fnv1a(body) {
            return Err("checksum mismatch (truncated or corrupted)".into());
        }
        let (c, used): (Checkpoint, usize) =
            bincode::serde::decode_from_slice(&body[10..], bincode::config::standard())
                .map_err(|e| format!("undecodable record: {e}"))?;
        if used != body.len() - 10 {
            return Err(format!("{} trailing bytes", body.len() - 10 - used));
        }
        Ok(c)
    }

    /// Write to `path` atomically: a temporary file beside it, synced, then renamed.
    pub fn write(&self, path: &Path) -> Result<(), CheckpointError> {
        let io = |source| CheckpointError::Io {
            path: path.to_path_buf(),
            source,
        };
        let bytes = self.to_bytes().map_err(|reason| CheckpointError::Bad {
            path: path.to_path_buf(),
            reason,
        })?;
        if let Some(d) = path.parent() {
            std::fs::create_dir_all(d).map_err(io)?;
        }
        let tmp = path.with_extension("ckpt.tmp");
        {
            let mut f = std::fs::File::create(&tmp).map_err(io)?;
            f.write_all(&bytes).map_err(io)?;
            f.sync_all().map_err(io)?;
        }
        std::fs::rename(&tmp, path).map_err(io)?;
        if let Some(d) = path.parent()
            && let Ok(f) = std::fs::File::open(d)
        {
            let _ = f.sync_all();
        }
        Ok(())
    }

    /// Read and check the container at `path`.
    pub fn read(path: &Path) -> Result<Self, CheckpointError> {
        let b = std::fs::read(path).map_err(|source| CheckpointError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_bytes(&b).map_err(|reason| CheckpointError::Bad {
            path: path.to_path_buf(),
            reason,
        })
    }
}

/// A node's state as a payload: any serde type, in bincode (standard config). The node kit's
/// one encoding for `Solver::save_state`.
pub fn encode_state<T: Serialize>(state: &T) -> SolverResult<Vec<u8>> {
    bincode::serde::encode_to_vec(state, bincode::config::standard())
        .map_err(|e| SolverError::Other(format!("save_state: {e}")))
}

/// The inverse of [`encode_state`] for `Solver::load_state`: refuses a payload that does not
/// decode to exactly one `T` (a truncated one says so).
pub fn decode_state<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> SolverResult<T> {
    let (v, used): (T, usize) =
        bincode::serde::decode_from_slice(bytes, bincode::config::standard()).map_err(|e| {
            SolverError::Other(match e {
                bincode::error::DecodeError::UnexpectedEnd { .. } => {
                    format!("load_state: truncated state ({} bytes)", bytes.len())
                }
                e => format!("load_state: {e}"),
            })
        })?;
    if used != bytes.len() {
        return Err(SolverError::Other(format!(
            "load_state: {} trailing bytes",
            bytes.len() - used
        )));
    }
    Ok(v)
}

/// Check that a loaded array has the length of the one it replaces (a state of another mesh
/// is refused, not half-loaded).
pub fn check_len(what: &str, got: usize, expected: usize) -> SolverResult<()> {
    if got != expected {
        return Err(SolverError::Other(format!(
            "load_state: {what} has {got} values, this node has {expected}"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::Field;

    fn sample() -> Checkpoint {
        Checkpoint {
            node: "left".into(),
            model: "bar-1d".into(),
            window: 20,
            time: 2.0e-5,
            params_hash: params_hash("length = 1.0\n"),
            sent: vec![Fields {
                coupling: "c".into(),
                window: 20,
                time: 2.0e-5,
                fields: vec![Field {
                    name: "force".into(),
                    components: 3,
                    values: vec![1.5, -0.0, f64::MIN_POSITIVE],
                }],
            }],
            payload: (0..=255u8).collect(),
        }
    }

    #[test]
    fn a_container_reads_back_to_the_same_record() {
        let c = sample();
        let b = c.to_bytes().unwrap();
        assert_eq!(&b[..8], b"COSIMCKP");
        assert_eq!(u16::from_le_bytes([b[8], b[9]]), FORMAT_VERSION);
        assert_eq!(Checkpoint::from_bytes(&b).unwrap(), c);
    }

    #[test]
    fn damaged_containers_are_refused_with_a_reason() {
        let b = sample().to_bytes().unwrap();
        let mut flipped = b.clone();
        flipped[40] ^= 1;
        assert!(
            Checkpoint::from_bytes(&flipped)
                .unwrap_err()
                .contains("checksum")
        );
        assert!(
            Checkpoint::from_bytes(&b[..b.len() - 3])
                .unwrap_err()
                .contains("checksum")
        );
        let mut version = b.clone();
        version[8] = 9;
        assert!(
            Checkpoint::from_bytes(&version)
                .unwrap_err()
                .contains("version 9")
        );
        assert!(
            Checkpoint::from_bytes(b"COSIMCK")
                .unwrap_err()
                .contains("magic")
        );
    }

    #[test]
    fn write_is_atomic_and_leaves_no_temporary() {
        let d = std::env::temp_dir().join(format!("ckpt-test-{}", std::process::id()));
        let p = file(&d, 20, "left");
        sample().write(&p).unwrap();
        assert_eq!(Checkpoint::read(&p).unwrap(), sample());
        assert!(!p.with_extension("ckpt.tmp").exists());
        assert_eq!(windows(&d), vec![20]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn state_payloads_refuse_trailing_bytes() {
        let mut b = encode_state(&(1u64, vec![2.5f64])).unwrap();
        assert_eq!(decode_state::<(u64, Vec<f64>)>(&b).unwrap(), (1, vec![2.5]));
        b.push(0);
        assert!(decode_state::<(u64, Vec<f64>)>(&b).is_err());
    }
}
