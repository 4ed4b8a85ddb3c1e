//! Dotted names as nested JSON objects in the recording: a node's named scalar
//! `point1.pressure` is recorded as `{"point1": {"pressure": …}}`, so that Foxglove's message
//! path `/cosim/node/gas.point1.pressure` (which cannot quote a key holding a dot) is our
//! series name. Our own readers flatten the objects back to the dotted names.

use serde::ser::{Serialize, SerializeMap, Serializer};
use serde_json::{Map, Value};

/// Whether the dotted `name` is recorded nested: it has no empty segment and none of its
/// prefixes (`a`, `a.b` of `a.b.c`) is itself a key of the same object (`is_key`), which
/// would need one key to be both a number and an object. Otherwise it stays a flat key.
pub fn nests(name: &str, is_key: impl Fn(&str) -> bool) -> bool {
    if !name.contains('.') || name.split('.').any(str::is_empty) {
        return false;
    }
    name.match_indices('.').all(|(i, _)| !is_key(&name[..i]))
}

/// The named scalars under one dotted prefix (empty: the top level, where only names that
/// [`nests`] are taken), as a JSON object: a name with no further dot is a number, the
/// others an object per next segment, each opened where its first name appears. Serialises
/// straight from the report, allocating nothing.
pub struct Group<'a> {
    pub scalars: &'a [(String, f64)],
    /// The prefix with its trailing dot (`point1.`), or empty.
    pub prefix: &'a str,
    /// Whether a name is a key of the top-level object (for [`nests`]).
    pub is_key: &'a dyn Fn(&str) -> bool,
}

impl Group<'_> {
    /// The names under the prefix that are recorded nested, with the rest after the prefix.
    fn members(&self) -> impl Iterator<Item = (usize, &str, f64)> + '_ {
        self.scalars
            .iter()
            .enumerate()
            .filter(|(_, (n, _))| n.starts_with(self.prefix) && nests(n, self.is_key))
            .map(|(i, (n, v))| (i, &n[self.prefix.len()..], *v))
    }

    /// Write this group's entries into `m`.
    pub fn entries<M: SerializeMap>(&self, m: &mut M) -> Result<(), M::Error> {
        for (i, rest, v) in self.members() {
            match rest.split_once('.') {
                None if !self.prefix.is_empty() => m.serialize_entry(rest, &v)?,
                None => {} // a flat top-level name is the caller's
                Some((seg, _)) => {
                    // opened once, where the first name of the segment appears
                    let len = self.prefix.len() + seg.len() + 1;
                    let full = &self.scalars[i].0[..len];
                    let first = self
                        .members()
                        .find(|(_, r, _)| r.split_once('.').is_some_and(|(s, _)| s == seg));
                    if first.is_some_and(|(j, _, _)| j == i) {
                        m.serialize_entry(
                            seg,
                            &Group {
                                scalars: self.scalars,
                                prefix: full,
                                is_key: self.is_key,
                            },
                        )?;
                    }
                }
            }
        }
        Ok(())
    }
}

impl Serialize for Group<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(None)?;
        self.entries(&mut m)?;
        m.end()
    }
}

/// Call `f` with the dotted path of every leaf (a value that is not a non-empty object) of
/// the object `v`: the inverse of the nesting.
pub fn for_each_leaf(v: &Map<String, Value>, f: &mut dyn FnMut(&str, &Value)) {
    fn walk(m: &Map<String, Value>, path: &mut String, f: &mut dyn FnMut(&str, &Value)) {
        for (k, x) in m {
            let len = path.len();
            if !path.is_empty() {
                path.push('.');
            }
            path.push_str(k);
            match x {
                Value::Object(inner) if !inner.is_empty() => walk(inner, path, f),
                _ => f(path, x),
            }
            path.truncate(len);
        }
    }
    walk(v, &mut String::new(), f);
}

/// Whether some value of `v` is a non-empty object (then [`flatten`] changes it).
pub fn has_nested(v: &Map<String, Value>) -> bool {
    v.values()
        .any(|x| matches!(x, Value::Object(m) if !m.is_empty()))
}

/// The object `v` with nested objects turned back into dotted keys, in order.
pub fn flatten(v: &Map<String, Value>) -> Map<String, Value> {
    let mut out = Map::new();
    for_each_leaf(v, &mut |k, x| {
        out.insert(k.to_string(), x.clone());
    });
    out
}

/// The JSON Schema `properties` of objects whose leaves have these dotted paths and types
/// (the nesting rebuilt by [`nests`] over the same set of keys).
pub fn properties<'a>(
    keys: impl Iterator<Item = (&'a str, Value)>,
    is_key: &dyn Fn(&str) -> bool,
) -> Map<String, Value> {
    fn put(at: &mut Map<String, Value>, segs: &[&str], ty: Value) {
        match segs {
            [] => {}
            [last] => {
                at.insert(last.to_string(), ty);
            }
            [seg, rest @ ..] => {
                let entry = at
                    .entry(seg.to_string())
                    .or_insert_with(|| serde_json::json!({ "type": "object", "properties": {} }));
                // a prefix is never a key itself (nests), so the entry is one of ours
                if let Some(p) = entry.get_mut("properties").and_then(Value::as_object_mut) {
                    put(p, rest, ty);
                }
            }
        }
    }
    let mut props = Map::new();
    for (k, ty) in keys {
        if nests(k, is_key) {
            put(&mut props, &k.split('.').collect::<Vec<_>>(), ty);
        } else {
            props.insert(k.to_string(), ty);
        }
    }
    props
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(names: &[&str]) -> Vec<(String, f64)> {
        names
            .iter()
            .enumerate()
            .map(|(i, n)| (n.to_string(), i as f64))
            .collect()
    }

    /// Serialise the top level as NodeReportDoc does: flat names first-hand, nested ones
    /// through the group.
    fn doc(s: &[(String, f64)]) -> Value {
        struct Top<'a>(&'a [(String, f64)]);
        impl Serialize for Top<'_> {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                let is_key = |k: &str| k == "time" || self.0.iter().any(|(n, _)| n == k);
                let mut m = s.serialize_map(None)?;
                m.serialize_entry("time", &1.5)?;
                for (n, v) in self.0 {
                    if !nests(n, is_key) {
                        m.serialize_entry(n, v)?;
                    }
                }
                Group {
                    scalars: self.0,
                    prefix: "",
                    is_key: &is_key,
                }
                .entries(&mut m)?;
                m.end()
            }
        }
        serde_json::to_value(Top(s)).unwrap()
    }

    /// Dotted names become nested objects, grouped by segment whatever their order; names
    /// that cannot nest (an empty segment, a prefix that is a key itself) stay flat; and the
    /// flattening gives back exactly the names and values.
    #[test]
    fn dotted_names_nest_and_flatten_back() {
        let s = report(&[
            "point1.pressure",
            "tip",
            "point2.density",
            "point1.density",
            "a.b.c",
            "a.b.d",
            "a.e",
            "time.x",
            "tip.x",
            "bad..name",
            ".lead",
        ]);
        let v = doc(&s);
        let want = serde_json::json!({
            "time": 1.5,
            "tip": 1.0,
            "time.x": 7.0,
            "tip.x": 8.0,
            "bad..name": 9.0,
            ".lead": 10.0,
            "point1": { "pressure": 0.0, "density": 3.0 },
            "point2": { "density": 2.0 },
            "a": { "b": { "c": 4.0, "d": 5.0 }, "e": 6.0 },
        });
        assert_eq!(v, want);
        let flat = flatten(v.as_object().unwrap());
        assert_eq!(flat.len(), s.len() + 1);
        for (n, x) in &s {
            assert_eq!(flat[n], serde_json::json!(x), "{n}");
        }
        assert_eq!(flat["time"], 1.5);
    }

    /// The schema properties rebuilt from the dotted paths match the nested document.
    #[test]
    fn schema_properties_follow_the_nesting() {
        let num = serde_json::json!({ "type": "number" });
        let keys = [
            "time",
            "point1.pressure",
            "point1.density",
            "a.b.c",
            "time.x",
        ];
        let is_key = |k: &str| keys.contains(&k);
        let p = properties(keys.iter().map(|k| (*k, num.clone())), &is_key);
        let want = serde_json::json!({
            "time": num, "time.x": num,
            "point1": { "type": "object", "properties": { "pressure": num, "density": num } },
            "a": { "type": "object", "properties": {
                "b": { "type": "object", "properties": { "c": num } } } },
        });
        assert_eq!(Value::Object(p), want);
    }
}
