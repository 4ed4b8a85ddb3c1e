//! A C solver's parameters: typed look-ups by dotted key in the node's TOML table, with the
//! top-level keys that were read remembered, so a key the solver never asked for is refused
//! as unknown (the C counterpart of `#[serde(deny_unknown_fields)]`).

use protocol::SolverError;
use std::collections::BTreeSet;

pub(crate) struct Params {
    table: toml::Table,
    used: BTreeSet<String>,
}

impl Params {
    pub(crate) fn new(table: toml::Table) -> Self {
        Params {
            table,
            used: BTreeSet::new(),
        }
    }

    /// The value at dotted `key`, marking its top-level key as read.
    fn get(&mut self, key: &str) -> Option<&toml::Value> {
        let mut parts = key.split('.');
        let first = parts.next()?;
        self.used.insert(first.to_string());
        let mut v = self.table.get(first)?;
        for p in parts {
            v = v.as_table()?.get(p)?;
        }
        Some(v)
    }

    fn wrong(key: &str, want: &str, v: &toml::Value) -> SolverError {
        SolverError::config(key, format!("must be {want}, got {}", v.type_str()))
    }

    pub(crate) fn f64(&mut self, key: &str) -> Result<Option<f64>, SolverError> {
        match self.get(key) {
            None => Ok(None),
            Some(toml::Value::Float(x)) => Ok(Some(*x)),
            Some(toml::Value::Integer(i)) => Ok(Some(*i as f64)),
            Some(v) => Err(Self::wrong(key, "a number", v)),
        }
    }

    pub(crate) fn i64(&mut self, key: &str) -> Result<Option<i64>, SolverError> {
        match self.get(key) {
            None => Ok(None),
            Some(toml::Value::Integer(i)) => Ok(Some(*i)),
            Some(v) => Err(Self::wrong(key, "an integer", v)),
        }
    }

    pub(crate) fn bool(&mut self, key: &str) -> Result<Option<bool>, SolverError> {
        match self.get(key) {
            None => Ok(None),
            Some(toml::Value::Boolean(b)) => Ok(Some(*b)),
            Some(v) => Err(Self::wrong(key, "true or false", v)),
        }
    }

    pub(crate) fn str(&mut self, key: &str) -> Result<Option<String>, SolverError> {
        match self.get(key) {
            None => Ok(None),
            Some(toml::Value::String(s)) => Ok(Some(s.clone())),
            Some(v) => Err(Self::wrong(key, "a string", v)),
        }
    }

    pub(crate) fn table_key(
        &mut self,
        key: &str,
        index: usize,
    ) -> Result<Option<String>, SolverError> {
        match self.get(key) {
            None => Ok(None),
            Some(toml::Value::Table(t)) => Ok(t.keys().nth(index).cloned()),
            Some(v) => Err(Self::wrong(key, "a table", v)),
        }
    }

    /// The first top-level key the solver never read, as a configuration error.
    pub(crate) fn check_all_read(&self) -> Result<(), SolverError> {
        match self.table.keys().find(|k| !self.used.contains(*k)) {
            None => Ok(()),
            Some(k) => {
                let read: Vec<&str> = self.used.iter().map(String::as_str).collect();
                Err(SolverError::config(
                    k,
                    format!(
                        "unknown parameter (this solver reads: {})",
                        if read.is_empty() {
                            "none".to_string()
                        } else {
                            read.join(", ")
                        }
                    ),
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str) -> Params {
        Params::new(toml::from_str(s).unwrap())
    }

    #[test]
    fn typed_look_ups_name_the_key_and_the_wrong_type() {
        let mut q = p("young = \"abc\"\nelements = 3\nt = { a = \"x\" }");
        let e = q.f64("young").unwrap_err().to_string();
        assert_eq!(e, "young: must be a number, got string");
        assert_eq!(q.f64("elements").unwrap(), Some(3.0));
        assert_eq!(q.i64("elements").unwrap(), Some(3));
        assert_eq!(q.str("t.a").unwrap().as_deref(), Some("x"));
        assert_eq!(q.table_key("t", 0).unwrap().as_deref(), Some("a"));
        assert_eq!(q.table_key("t", 1).unwrap(), None);
        assert_eq!(q.f64("missing").unwrap(), None);
        let e = q.i64("t").unwrap_err().to_string();
        assert_eq!(e, "t: must be an integer, got table");
    }

    #[test]
    fn a_key_never_read_is_refused_as_unknown() {
        let mut q = p("length = 1.0\nlenght = 2.0");
        q.f64("length").unwrap();
        let e = q.check_all_read().unwrap_err().to_string();
        assert_eq!(e, "lenght: unknown parameter (this solver reads: length)");
        q.f64("lenght").unwrap();
        assert!(q.check_all_read().is_ok());
    }
}
