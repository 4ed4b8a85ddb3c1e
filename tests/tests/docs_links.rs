//! The project's documents hold up in a fresh clone: every relative link of
//! README.md, PROTOCOL.md and docs/*.md names a file the repository tracks (an anchor, a
//! heading of it), no link leaves the repository, and the licences the crates declare are
//! there.

use cosim_tests::workspace_root;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The targets of the markdown links of `text`: inline `[..](target)` and `![..](target)`,
/// and reference definitions `[name]: target`.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("](") {
        let tail = &rest[i + 2..];
        if let Some(j) = tail.find(')') {
            out.push(
                tail[..j]
                    .split_whitespace()
                    .next()
                    .unwrap_or("")
                    .to_string(),
            );
        }
        rest = tail;
    }
    for line in text.lines() {
        let l = line.trim_start();
        if l.starts_with('[')
            && let Some(k) = l.find("]: ")
        {
            out.push(
                l[k + 3..]
                    .split_whitespace()
                    .next()
                    .unwrap_or("")
                    .to_string(),
            );
        }
    }
    out
}

/// GitHub's anchor of a heading: lower case, spaces to '-', punctuation dropped.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

fn anchors(file: &Path) -> Vec<String> {
    std::fs::read_to_string(file)
        .unwrap_or_default()
        .lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| slug(l.trim_start_matches('#')))
        .collect()
}

fn tracked(root: &Path) -> Option<Vec<PathBuf>> {
    let o = Command::new("git")
        .args(["ls-files", "-z"])
        .current_dir(root)
        .output()
        .ok()?;
    if !o.status.success() {
        return None;
    }
    Some(
        o.stdout
            .split(|b| *b == 0)
            .filter(|s| !s.is_empty())
            .map(|s| root.join(String::from_utf8_lossy(s).as_ref()))
            .collect(),
    )
}

#[test]
fn every_document_link_resolves_inside_the_repository() {
    let root = workspace_root();
    let tracked = tracked(&root);
    let mut docs = vec![root.join("README.md"), root.join("PROTOCOL.md")];
    for e in std::fs::read_dir(root.join("docs")).unwrap().flatten() {
        if e.path().extension().is_some_and(|x| x == "md") {
            docs.push(e.path());
        }
    }
    let mut checked = 0;
    let mut bad = Vec::new();
    for doc in &docs {
        let text = std::fs::read_to_string(doc).unwrap();
        for target in links(&text) {
            if target.is_empty()
                || target.starts_with("http://")
                || target.starts_with("https://")
                || target.starts_with("mailto:")
            {
                continue;
            }
            checked += 1;
            let (path, anchor) = match target.split_once('#') {
                Some((p, a)) => (p, Some(a)),
                None => (target.as_str(), None),
            };
            let file = if path.is_empty() {
                doc.clone()
            } else {
                doc.parent().unwrap().join(path)
            };
            let Ok(file) = file.canonicalize() else {
                bad.push(format!("{}: {target} does not exist", doc.display()));
                continue;
            };
            if !file.starts_with(root.canonicalize().unwrap()) {
                bad.push(format!("{}: {target} leaves the repository", doc.display()));
                continue;
            }
            if let Some(t) = &tracked
                && file.is_file()
                && !t
                    .iter()
                    .any(|p| p.canonicalize().ok().as_ref() == Some(&file))
            {
                bad.push(format!("{}: {target} is not tracked by git", doc.display()));
            }
            if let Some(a) = anchor
                && !anchors(&file).iter().any(|h| h == a)
            {
                bad.push(format!("{}: {target}: no heading #{a}", doc.display()));
            }
        }
    }
    println!("{checked} relative links in {} documents", docs.len());
    assert!(checked >= 7, "only {checked} relative links found");
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

#[test]
fn the_declared_licences_are_present() {
    let root = workspace_root();
    let cargo = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    assert!(
        cargo.contains("license = \"MIT OR Apache-2.0\""),
        "the workspace declares another licence"
    );
    for (file, needle) in [
        (
            "LICENSE-MIT",
            "Permission is hereby granted, free of charge",
        ),
        ("LICENSE-APACHE", "Apache License"),
    ] {
        let text = std::fs::read_to_string(root.join(file)).unwrap_or_default();
        assert!(
            text.contains(needle),
            "{file} is missing or not the licence"
        );
    }
}
