//! The fields a solver takes in and gives out per interface (`Inbox`, `Outbox`).

use crate::error::{SolverError, SolverResult};
use crate::message::Field;

/// Named per-interface fields, in the solver's own layout. Used both ways: the runtime fills
/// an `Inbox` before `advance`, the solver fills an `Outbox` during it. Buffers are kept
/// between windows so a steady run allocates nothing.
#[derive(Debug, Default, Clone)]
pub struct FieldSet {
    entries: Vec<(String, Field)>,
}

pub type Inbox = FieldSet;
pub type Outbox = FieldSet;

impl FieldSet {
    pub fn new() -> Self {
        Self::default()
    }

    /// The field `name` of `interface`, if present.
    pub fn get(&self, interface: &str, name: &str) -> Option<&Field> {
        self.entries
            .iter()
            .find(|(i, f)| i == interface && f.name == name)
            .map(|(_, f)| f)
    }

    /// The values of a field that must be there with `len` values.
    pub fn require(&self, interface: &str, name: &str, len: usize) -> SolverResult<&[f64]> {
        let f = self.get(interface, name).ok_or_else(|| {
            SolverError::interface(interface, format!("no '{name}' field received"))
        })?;
        if f.values.len() != len {
            return Err(SolverError::interface(
                interface,
                format!("'{name}' has {} values, expected {len}", f.values.len()),
            ));
        }
        Ok(&f.values)
    }

    /// A writable buffer of `points * components` values for `name` on `interface`, reused
    /// from the previous window when present (contents then hold the old values).
    pub fn put(
        &mut self,
        interface: &str,
        name: &str,
        components: u32,
        points: usize,
    ) -> &mut [f64] {
        let n = points * components as usize;
        let idx = match self
            .entries
            .iter()
            .position(|(i, f)| i == interface && f.name == name)
        {
            Some(i) => i,
            None => {
                self.entries.push((
                    interface.to_string(),
                    Field {
                        name: name.to_string(),
                        components,
                        values: Vec::with_capacity(n),
                    },
                ));
                self.entries.len() - 1
            }
        };
        let f = &mut self.entries[idx].1;
        f.components = components;
        f.values.resize(n, 0.0);
        &mut f.values
    }

    /// Insert a whole field.
    pub fn insert(&mut self, interface: &str, field: Field) {
        match self
            .entries
            .iter_mut()
            .find(|(i, f)| i == interface && f.name == field.name)
        {
            Some(e) => e.1 = field,
            None => self.entries.push((interface.to_string(), field)),
        }
    }

    /// Every field of one interface.
    pub fn fields_of<'a>(&'a self, interface: &'a str) -> impl Iterator<Item = &'a Field> + 'a {
        self.entries
            .iter()
            .filter(move |(i, _)| i == interface)
            .map(|(_, f)| f)
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, &Field)> {
        self.entries.iter().map(|(i, f)| (i.as_str(), f))
    }

    /// Forget every field (keeps nothing; use between runs, not between windows).
    /// Drop every field of `interface` (a decoupled coupling: nothing stale may linger).
    pub fn remove_interface(&mut self, interface: &str) {
        self.entries.retain(|(i, _)| i != interface);
    }

    pub fn clear(&mut self) {
        self.entries.clear();
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}
