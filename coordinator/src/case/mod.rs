//! Case files (docs/architecture.md), read in steps before any process starts: [`parse`]
//! reads the TOML into typed sections (every key known, its path named on error);
//! [`variants`] applies `[variants.NAME]` and `--set` to the document, which is then read
//! again whole; [`validate`] checks what the values mean into the [`resolved`] case and asks
//! each node executable to describe itself ([`describe`]); [`graph`] derives what the
//! couplings make of the nodes (bindings, window order, required fields). Every error names the key path and the reason, e.g.
//! `run.window: must be > 0 and ≤ run.end_time (0.001), got 0`.

pub mod describe;
pub mod graph;
pub mod parse;
pub mod resolved;
pub mod validate;
pub mod variants;

pub use graph::{Need, bindings_of, required_fields, window_order};
pub use resolved::*;
pub use validate::{check_joined, default_fields, point_spacing};
pub use variants::apply_sets;

use std::path::Path;

/// Read, check and describe the case file at `path`.
pub fn load(path: &Path) -> Result<Case, ConfigError> {
    load_variant(path, None, &[])
}

/// Read, check and describe a case file's text (`path` names it in errors and locates what
/// the case refers to: params files, solver paths).
pub fn parse(text: &str, path: &Path) -> Result<Case, ConfigError> {
    let (_doc, file) = parse::read(text)?;
    let mut case = validate::settle(file, path, text)?;
    validate::describe(&mut case)?;
    Ok(case)
}

/// Load a case, apply the settings of variant `variant` (if any), then `sets`.
pub fn load_variant(
    path: &Path,
    variant: Option<&str>,
    sets: &[String],
) -> Result<Case, ConfigError> {
    // the key is the file itself, which every caller names already
    let text = std::fs::read_to_string(path).map_err(|e| err("", format!("cannot read: {e}")))?;
    load_variant_text(&text, path, variant, sets)
}

/// As [`load_variant`], with the case file's text in hand (`path` names it in errors and
/// locates what the case refers to).
pub fn load_variant_text(
    text: &str,
    path: &Path,
    variant: Option<&str>,
    sets: &[String],
) -> Result<Case, ConfigError> {
    if sets.is_empty() && variant.is_none() {
        return parse(text, path);
    }
    // The file as written is checked whole first (its variants included).
    let (mut doc, file) = parse::read(text)?;
    variants::apply(&mut doc, &file, path, variant, sets)?;
    let text = toml::to_string(&doc).map_err(|e| err("--set", e.to_string()))?;
    parse(&text, path)
}
