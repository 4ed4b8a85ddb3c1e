//! Files written whole or not at all: into a hidden file beside the target, renamed over it
//! once every byte is written. A reader (ParaView, `cosim render`, a script reading
//! `summary.json`) never meets a half-written file, even when the disk fills up.

use std::path::Path;

/// Write `bytes` to `path` whole or not at all: into a hidden file beside it, renamed over
/// `path` once every byte is written. On failure (a full disk) the partial file is removed
/// and the error names `path`, so neither a half-written frame nor a series listing one is
/// ever left.
pub fn write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.part"));
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    written.map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        std::io::Error::new(e.kind(), format!("cannot write {}: {e}", path.display()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A write that fails leaves nothing behind, neither the file nor its partial copy, and
    /// says which file it could not write.
    #[test]
    fn a_failed_write_leaves_no_partial_file_and_names_the_path() {
        let dir = std::env::temp_dir().join(format!("node-kit-{}-whole", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // A directory in the way of the rename: the bytes are written, the rename fails.
        let path = dir.join("p_000001.vtu");
        std::fs::create_dir_all(path.join("occupied")).unwrap();
        let e = write(&path, b"frame").unwrap_err();
        assert!(e.to_string().contains("p_000001.vtu"), "{e}");
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(
            left,
            ["p_000001.vtu"],
            "only the directory that was in the way"
        );
        assert!(path.is_dir());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
