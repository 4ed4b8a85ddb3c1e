//! Sizes checked against memory before a node allocates: a model whose state would need more
//! bytes than the machine has available is refused at `--describe`, naming the key that sets
//! the size, instead of being aborted by the allocator (or the OOM killer) while it builds.
//! "Available" is Linux's `MemAvailable` in `/proc/meminfo` (free memory plus what the kernel
//! can reclaim); where it cannot be read, nothing is refused.

use crate::solver::{SolverError, SolverResult};

/// `MemAvailable` of `/proc/meminfo` in bytes, if readable.
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_mem_available(&text)
}

/// `MemAvailable: N kB` of a `/proc/meminfo` text, in bytes.
fn parse_mem_available(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let mut words = line["MemAvailable:".len()..].split_whitespace();
    let n: u64 = words.next()?.parse().ok()?;
    match words.next() {
        Some("kB") => n.checked_mul(1024),
        None => Some(n),
        Some(_) => None,
    }
}

/// Refuse a model whose state needs `bytes` (what `how` says they are) when more than the
/// available memory: a config error on `key`, naming both numbers.
pub fn check_fits(key: &str, bytes: u128, how: &str) -> SolverResult<()> {
    check_fits_in(key, bytes, how, available_bytes())
}

fn check_fits_in(key: &str, bytes: u128, how: &str, available: Option<u64>) -> SolverResult<()> {
    match available {
        Some(a) if bytes > a as u128 => Err(SolverError::config(
            key,
            format!(
                "needs {bytes} bytes ({:.1} GB: {how}) but only {a} bytes ({:.1} GB) of memory are available (MemAvailable in /proc/meminfo)",
                gb(bytes),
                gb(a as u128)
            ),
        )),
        _ => Ok(()),
    }
}

/// Decimal gigabytes.
fn gb(bytes: u128) -> f64 {
    bytes as f64 / 1e9
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_available_is_read_in_kibibytes() {
        let text =
            "MemTotal:       16384000 kB\nMemFree:          100 kB\nMemAvailable:    2000000 kB\n";
        assert_eq!(parse_mem_available(text), Some(2_048_000_000));
        assert_eq!(parse_mem_available("MemTotal: 1 kB\n"), None);
        assert_eq!(parse_mem_available("MemAvailable: x kB\n"), None);
    }

    #[test]
    fn a_state_larger_than_the_memory_is_refused_by_key_with_both_sizes() {
        let e = check_fits_in("grid.cells", 3_000_000_001, "cells", Some(3_000_000_000))
            .expect_err("refused");
        let text = e.to_string();
        assert!(
            text.starts_with("grid.cells: needs 3000000001 bytes (3.0 GB: cells)"),
            "{text}"
        );
        assert!(text.contains("only 3000000000 bytes (3.0 GB)"), "{text}");
        assert!(check_fits_in("grid.cells", 3_000_000_000, "cells", Some(3_000_000_000)).is_ok());
        assert!(check_fits_in("grid.cells", u128::MAX, "cells", None).is_ok());
    }
}
