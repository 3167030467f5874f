//! Command-line overrides: `path=value` pairs (`radar.address=10.0.0.2:6317`,
//! `sim.pacing=as-fast-as-possible`, `sim.faults.stall_ms=500`) applied to the settings as
//! written, before validation, so an override is checked exactly like the same key in a file.

use std::str::FromStr;

use crate::error::ConfigError;
use crate::RawConfig;

/// Deepest dotted path accepted (the deepest real key, `sim.faults.stall_ms`, has 3 parts).
const MAX_PATH_PARTS: usize = 8;

/// One `path=value` override.
///
/// The value is read as a TOML value (`true`, `3`, `1.5e-3`, `"text"`, `[1, 2]`,
/// `{ range_m = 1.0, gain_db = 0.0 }`); anything that is not one is taken as a string, so
/// `radar.address=10.0.0.2:6317` needs no quotes.
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    path: Vec<String>,
    value: toml::Value,
    text: String,
}

impl Override {
    /// The dotted path, e.g. `radar.address`.
    pub fn path(&self) -> String {
        self.path.join(".")
    }
    /// The value as TOML.
    pub fn value(&self) -> &toml::Value {
        &self.value
    }
}

fn bad(text: &str, message: impl Into<String>) -> ConfigError {
    ConfigError::Override {
        text: text.to_owned(),
        message: message.into(),
    }
}

impl FromStr for Override {
    type Err = ConfigError;

    fn from_str(text: &str) -> Result<Self, ConfigError> {
        let (path, value) = text.split_once('=').ok_or_else(|| {
            bad(
                text,
                "expected `path=value`, e.g. `radar.address=10.0.0.2:6317`",
            )
        })?;
        let path: Vec<String> = path
            .trim()
            .split('.')
            .map(|p| p.trim().to_owned())
            .collect();
        if path.len() > MAX_PATH_PARTS {
            return Err(bad(
                text,
                format!("a key path has at most {MAX_PATH_PARTS} parts"),
            ));
        }
        let key_ok = |part: &String| {
            !part.is_empty()
                && part
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        };
        if !path.iter().all(key_ok) {
            return Err(bad(
                text,
                "the key path must be dotted bare keys, e.g. `sim.faults.stall_ms`",
            ));
        }
        let value = value.trim();
        if value.contains(['\n', '\r']) {
            return Err(bad(text, "the value must be on one line"));
        }
        let parsed = toml::from_str::<toml::Table>(&format!("v = {value}"))
            .ok()
            .and_then(|mut table| table.remove("v"));
        Ok(Self {
            path,
            value: parsed.unwrap_or_else(|| toml::Value::String(value.to_owned())),
            text: text.to_owned(),
        })
    }
}

impl RawConfig {
    /// Applies overrides in order (a later one wins). An unknown key or a value of the wrong
    /// type is an error naming the override; values are validated later, with the file.
    pub fn apply_overrides(&mut self, overrides: &[Override]) -> Result<(), ConfigError> {
        if overrides.is_empty() {
            return Ok(());
        }
        let mut table = toml::Table::try_from(&*self)
            .map_err(|e| bad("<settings>", format!("cannot represent the settings: {e}")))?;
        for o in overrides {
            set(&mut table, o)?;
            // Checked one at a time so that an error names the override that caused it.
            toml::Value::Table(table.clone())
                .try_into::<RawConfig>()
                .map_err(|e| bad(&o.text, format!("`{}`: {}", o.path(), e.message().trim())))?;
        }
        *self = toml::Value::Table(table)
            .try_into()
            .map_err(|e: toml::de::Error| bad("<settings>", e.message().trim()))?;
        Ok(())
    }
}

fn set(table: &mut toml::Table, o: &Override) -> Result<(), ConfigError> {
    let Some((last, parents)) = o.path.split_last() else {
        return Err(bad(&o.text, "empty key path"));
    };
    let mut here = table;
    for (depth, part) in parents.iter().enumerate() {
        let entry = here
            .entry(part.clone())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        here = match entry {
            toml::Value::Table(t) => t,
            _ => {
                return Err(bad(
                    &o.text,
                    format!(
                        "`{}` is a value, not a table",
                        parents.get(..=depth).unwrap_or(parents).join(".")
                    ),
                ))
            }
        };
    }
    here.insert(last.clone(), o.value.clone());
    Ok(())
}
