//! One run per output folder. `cosim run` and `cosim restart` hold an advisory lock on
//! `<folder>/.cosim.lock` for as long as they write there, so that a second run, a restart or
//! a replay refuses the folder, naming the live run, instead of mixing its files with it.
//!
//! The lock is the kernel's `flock` (through `std::fs::File::try_lock`, no crate needed): it
//! belongs to the open file, which the kernel closes when the process ends however it ends,
//! so a killed run never leaves a stale lock behind. The file is opened close-on-exec, so the
//! nodes a run launches do not inherit it and cannot keep it alive after `cosim` is gone. The
//! file itself stays in the folder (removing it would let a process that opened it before the
//! removal lock an orphan while a third locks a new file).

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

/// The lock file's name inside an output folder.
pub const LOCK_FILE: &str = ".cosim.lock";

#[derive(Debug, thiserror::Error)]
pub enum LockError {
    #[error(
        "{} is the output folder of a run still in progress ({holder}); nothing there was touched: wait for that run to end (or stop it), or write elsewhere with --output DIR",
        dir.display()
    )]
    Busy { dir: PathBuf, holder: String },
    #[error("cannot lock {}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The held lock; dropping it releases the folder.
#[derive(Debug)]
pub struct OutputLock {
    _file: File,
}

/// Lock `dir` (created if absent) for this process, which `what` describes (its command
/// line); refused with [`LockError::Busy`] while another process holds it.
pub fn acquire(dir: &Path, what: &str) -> Result<OutputLock, LockError> {
    let path = dir.join(LOCK_FILE);
    let io = |source| LockError::Io {
        path: path.clone(),
        source,
    };
    std::fs::create_dir_all(dir).map_err(io)?;
    // Not truncated on open: until this process holds the lock, the text is the holder's.
    let mut file = OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(io)?;
    match file.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => {
            let mut text = String::new();
            let _ = file.read_to_string(&mut text);
            let holder = holder(&text);
            return Err(LockError::Busy {
                dir: dir.to_path_buf(),
                holder,
            });
        }
        Err(TryLockError::Error(e)) => return Err(io(e)),
    }
    // Who holds it, for the message a refused process prints.
    let note = format!("pid {}\n{what}\n", std::process::id());
    file.set_len(0)
        .and_then(|()| file.rewind())
        .and_then(|()| file.write_all(note.as_bytes()))
        .map_err(io)?;
    Ok(OutputLock { _file: file })
}

/// Refuse `dir` while another process holds its lock, without creating or writing anything
/// there (for a caller that has more to check before it takes the folder).
pub fn check_free(dir: &Path) -> Result<(), LockError> {
    let path = dir.join(LOCK_FILE);
    let mut file = match File::open(&path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(source) => return Err(LockError::Io { path, source }),
    };
    match file.try_lock_shared() {
        Ok(()) => Ok(()),
        Err(TryLockError::WouldBlock) => {
            let mut text = String::new();
            let _ = file.read_to_string(&mut text);
            Err(LockError::Busy {
                dir: dir.to_path_buf(),
                holder: holder(&text),
            })
        }
        Err(TryLockError::Error(source)) => Err(LockError::Io { path, source }),
    }
}

/// The holder as its lock file describes it: `cosim pid N: COMMAND`.
fn holder(text: &str) -> String {
    let mut lines = text.lines();
    match (
        lines.next().and_then(|l| l.strip_prefix("pid ")),
        lines.next(),
    ) {
        (Some(pid), Some(cmd)) => format!("pid {pid}: {cmd}"),
        (Some(pid), None) => format!("pid {pid}"),
        _ => "another cosim process, just starting".to_string(),
    }
}

/// This process's command line, as the lock file records it.
pub fn command_line() -> String {
    std::env::args().collect::<Vec<_>>().join(" ")
}

/// Whether `dir` holds a run of its own (a variant's output inside the base case's).
pub fn holds_a_run(dir: &Path) -> bool {
    dir.join("summary.json").exists() || dir.join("run.mcap").exists()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("cosim-lock-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// Two opens of the lock file are two `flock` holders even in one process, as in two.
    #[test]
    fn a_held_folder_is_refused_naming_the_holder_and_free_once_released() {
        let dir = scratch("held");
        let first = acquire(&dir, "cosim run first.toml").unwrap();
        match acquire(&dir, "cosim run second.toml") {
            Err(LockError::Busy { dir: d, holder }) => {
                assert_eq!(d, dir);
                assert_eq!(
                    holder,
                    format!("pid {}: cosim run first.toml", std::process::id())
                );
            }
            other => panic!("a held folder was not refused: {other:?}"),
        }
        assert!(matches!(check_free(&dir), Err(LockError::Busy { .. })));
        drop(first);
        assert!(check_free(&dir).is_ok());
        let again = acquire(&dir, "cosim run third.toml");
        assert!(again.is_ok(), "{again:?}");
        drop(again);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
