//! Field overrides (`nimbus render --set render.width=640`): changes made to the scene's
//! TOML tables *before* validation, so an overridden value passes exactly the checks a
//! value written in the file passes (the camera is checked at every frame of an
//! overridden `frames`, a `spp` out of range names the field, …).
//!
//! A key is a dotted path of table names and field names; a whole-number segment `N`
//! picks the N-th entry (from 1, as in error messages) of an array of tables:
//! `light.2.irradiance`, `medium.1.density_scale`, `integrator.restir.candidates`.
//! Missing tables on the way are created; missing array entries are an error. The value
//! is TOML (`640`, `0.5`, `[1, 2, 3]`, `true`, `"baseline"`); a bare word that is not
//! TOML is taken as a string, so `integrator.volume=baseline` works.

use anyhow::{anyhow, bail, Result};
use toml::Value;

/// One `key=value` override.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldOverride {
    /// The dotted key as given.
    pub key: String,
    pub value: Value,
    /// Where the value came from, for messages (`--width 0`); `None`: `--set KEY=VALUE`.
    pub origin: Option<String>,
}

impl FieldOverride {
    /// An override of `key` with an already typed value.
    pub fn new(key: &str, value: impl Into<Value>) -> FieldOverride {
        FieldOverride {
            key: key.to_owned(),
            value: value.into(),
            origin: None,
        }
    }

    /// An override given by a command-line flag of its own (`--width 640` for
    /// `render.width`): a refusal of the value names the flag, not `--set`.
    pub fn from_flag(flag: &str, key: &str, value: impl Into<Value>) -> FieldOverride {
        let value = value.into();
        FieldOverride {
            origin: Some(format!("{flag} {value}")),
            key: key.to_owned(),
            value,
        }
    }

    /// How the override was given: `--width 0`, or `--set KEY=VALUE`.
    pub fn describe(&self) -> String {
        self.origin
            .clone()
            .unwrap_or_else(|| format!("--set {}={}", self.key, self.value))
    }

    /// Parses `key=value` (see the module docs).
    pub fn parse(text: &str) -> Result<FieldOverride> {
        let Some((key, value)) = text.split_once('=') else {
            bail!("--set {text:?}: expected KEY=VALUE, e.g. render.width=640");
        };
        let key = key.trim();
        if key.is_empty() || key.split('.').any(|s| s.trim().is_empty()) {
            bail!("--set {text:?}: the key must be a dotted path such as render.width or light.2.irradiance");
        }
        let value = value.trim();
        let parsed = format!("v = {value}")
            .parse::<toml::Table>()
            .ok()
            .and_then(|mut t| t.remove("v"));
        let value = match parsed {
            Some(v) => v,
            None if !value.is_empty()
                && value
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c)) =>
            {
                Value::String(value.to_owned())
            }
            None => bail!(
                "--set {text:?}: the value is not TOML (quote strings: key=\"text\"; arrays: key=[1, 2, 3])"
            ),
        };
        Ok(FieldOverride {
            key: key.to_owned(),
            value,
            origin: None,
        })
    }
}

/// Applies `overrides` in order to the scene's top-level table.
pub(crate) fn apply(root: &mut toml::Table, overrides: &[FieldOverride]) -> Result<()> {
    for o in overrides {
        let segments: Vec<&str> = o.key.split('.').map(str::trim).collect();
        set(root, &segments, o.value.clone()).map_err(|e| anyhow!("--set {}: {e}", o.key))?;
    }
    Ok(())
}

/// Sets `path` (at least one segment) under `table` to `value`.
fn set(table: &mut toml::Table, path: &[&str], value: Value) -> Result<()> {
    let Some((first, rest)) = path.split_first() else {
        bail!("empty key");
    };
    if rest.is_empty() {
        match table.get_mut(*first) {
            // `--set 'render={width=8}'` sets width and keeps the table's other fields (it
            // replaced the whole [render] table, silently resetting them to defaults).
            Some(existing @ Value::Table(_)) if value.is_table() => merge(existing, value),
            _ => {
                table.insert((*first).to_owned(), value);
            }
        }
        return Ok(());
    }
    // An array of tables indexed by the next segment.
    if let Ok(n) = rest[0].parse::<usize>() {
        let Some(Value::Array(items)) = table.get_mut(*first) else {
            bail!("there is no [[{first}]] in the scene to index");
        };
        let count = items.len();
        let Some(item) = n.checked_sub(1).and_then(|i| items.get_mut(i)) else {
            bail!("[[{first}]] #{n} does not exist; the scene has {count} (numbered from 1)");
        };
        let Value::Table(entry) = item else {
            bail!("[[{first}]] #{n} is not a table");
        };
        if rest.len() == 1 {
            bail!("[[{first}]] #{n}: name a field of it, e.g. {first}.{n}.<field>");
        }
        return set(entry, &rest[1..], value);
    }
    let child = table
        .entry((*first).to_owned())
        .or_insert_with(|| Value::Table(toml::Table::new()));
    match child {
        Value::Table(t) => set(t, rest, value),
        Value::Array(_) => bail!(
            "{first} is an array of tables: pick one, e.g. {first}.1.{}",
            rest[0]
        ),
        _ => bail!("{first} is a value, not a table"),
    }
}

/// Sets every field of table `new` in table `existing`, recursing into tables both have.
fn merge(existing: &mut Value, new: Value) {
    match (existing, new) {
        (Value::Table(old), Value::Table(new)) => {
            for (key, value) in new {
                match old.get_mut(&key) {
                    Some(slot @ Value::Table(_)) if value.is_table() => merge(slot, value),
                    _ => {
                        old.insert(key, value);
                    }
                }
            }
        }
        (slot, new) => *slot = new,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(text: &str) -> toml::Table {
        text.parse().expect("valid TOML")
    }

    #[test]
    fn values_are_toml_or_bare_words() {
        let o = FieldOverride::parse("render.width = 640").unwrap();
        assert_eq!(
            (o.key.as_str(), o.value),
            ("render.width", Value::Integer(640))
        );
        let o = FieldOverride::parse("integrator.volume=baseline").unwrap();
        assert_eq!(o.value, Value::String("baseline".into()));
        let o = FieldOverride::parse("light.1.irradiance=[1, 2.5, 3]").unwrap();
        assert!(matches!(o.value, Value::Array(ref a) if a.len() == 3));
        let o = FieldOverride::parse("render.pixel_jitter=false").unwrap();
        assert_eq!(o.value, Value::Boolean(false));
        for bad in [
            "render.width",
            "=3",
            "render..width=3",
            "a.b=[1,",
            "a=two words",
        ] {
            assert!(FieldOverride::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn paths_create_tables_and_index_arrays_from_one() {
        let mut t = table("[[light]]\ntype = \"point\"\n[[light]]\ntype = \"sphere\"\n");
        apply(
            &mut t,
            &[
                FieldOverride::new("light.2.radius", 0.5),
                FieldOverride::new("integrator.restir.candidates", 8),
            ],
        )
        .unwrap();
        assert_eq!(t["light"][1]["radius"].as_float(), Some(0.5));
        assert_eq!(
            t["integrator"]["restir"]["candidates"].as_integer(),
            Some(8)
        );
        let err = apply(&mut t, &[FieldOverride::new("light.3.radius", 1.0)]).unwrap_err();
        assert!(err.to_string().contains("the scene has 2"), "{err}");
        let err = apply(&mut t, &[FieldOverride::new("light.radius", 1.0)]).unwrap_err();
        assert!(err.to_string().contains("light.1.radius"), "{err}");
        let err = apply(&mut t, &[FieldOverride::new("medium.1.g", 0.1)]).unwrap_err();
        assert!(err.to_string().contains("no [[medium]]"), "{err}");
    }

    #[test]
    fn an_inline_table_sets_its_fields_and_keeps_the_others() {
        let mut t =
            table("[render]\nwidth = 640\nheight = 360\nspp = 4\n[integrator.restir]\nQ = 1\n");
        apply(&mut t, &[FieldOverride::parse("render={width=8}").unwrap()]).unwrap();
        let render = t["render"].as_table().unwrap();
        assert_eq!(render["width"].as_integer(), Some(8));
        assert_eq!(render["height"].as_integer(), Some(360));
        assert_eq!(render["spp"].as_integer(), Some(4));
        // Nested tables merge too; a value replaced by a table is replaced.
        apply(
            &mut t,
            &[FieldOverride::parse("integrator={restir={candidates=8}}").unwrap()],
        )
        .unwrap();
        let restir = t["integrator"]["restir"].as_table().unwrap();
        assert_eq!(restir["Q"].as_integer(), Some(1));
        assert_eq!(restir["candidates"].as_integer(), Some(8));
    }
}
