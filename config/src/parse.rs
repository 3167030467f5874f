//! From TOML text to [`RawConfig`], with parser errors turned into [`ConfigError`]s that say
//! which key, where.

use std::ops::Range;

use crate::error::{ConfigError, Location};
use crate::RawConfig;

/// Parses TOML text; `origin` names the text in errors (a file path or `<string>`).
pub(crate) fn raw_from_str(text: &str, origin: &str) -> Result<RawConfig, ConfigError> {
    toml::from_str::<RawConfig>(text).map_err(|e| classify(&e, text, origin))
}

fn classify(error: &toml::de::Error, text: &str, origin: &str) -> ConfigError {
    let message = error
        .message()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(": ");
    let span = error.span();
    let location = span.as_ref().map(|s| location_of(text, s.start));
    let key_path = span.as_ref().and_then(|s| key_path_at(text, s));
    match (unknown_field_name(&message), key_path, location) {
        (Some(name), key_path, Some(location)) => ConfigError::UnknownKey {
            origin: origin.to_owned(),
            key_path: match key_path {
                // A key inside an inline table: the line's key names the table.
                Some(path) if path.rsplit('.').next() != Some(name.as_str()) => {
                    format!("{path}.{name}")
                }
                Some(path) => path,
                None => name,
            },
            location,
            message,
        },
        (_, key_path, location) => ConfigError::Parse {
            origin: origin.to_owned(),
            key_path,
            location,
            message,
        },
    }
}

/// The field name in serde's "unknown field `name`, expected ..." message.
fn unknown_field_name(message: &str) -> Option<String> {
    let rest = message.strip_prefix("unknown field `")?;
    let end = rest.find('`')?;
    rest.get(..end).map(str::to_owned)
}

/// 1-based line and column (in characters) of a byte offset.
pub(crate) fn location_of(text: &str, offset: usize) -> Location {
    let mut cut = offset.min(text.len());
    while !text.is_char_boundary(cut) {
        cut -= 1;
    }
    let before = text.get(..cut).unwrap_or("");
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    Location {
        line: before.matches('\n').count() + 1,
        column: before.get(line_start..).map_or(0, |s| s.chars().count()) + 1,
    }
}

/// The dotted key path of the key written on the line of `span`: a table header line
/// (`[a.b]`, `[[a.b]]`) names itself; a `key = value` line is the nearest header above it
/// joined with `key`.
///
/// This reads the text line by line, so keys inside multi-line inline tables or arrays are
/// named by their header and the key on the error's line only.
fn key_path_at(text: &str, span: &Range<usize>) -> Option<String> {
    let start = span.start.min(text.len());
    let line_start = text.get(..start)?.rfind('\n').map_or(0, |i| i + 1);
    let line_end = text
        .get(start..)?
        .find('\n')
        .map_or(text.len(), |i| start + i);
    let line = text.get(line_start..line_end)?.trim();
    if line.starts_with('[') {
        return header_name(line);
    }
    let (left, _) = line.split_once('=')?;
    let key: String = left.trim().chars().filter(|c| *c != '"').collect();
    if key.is_empty() {
        return None;
    }
    let header = text
        .get(..line_start)?
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .and_then(header_name);
    Some(match header {
        Some(h) => format!("{h}.{key}"),
        None => key,
    })
}

/// `a.b` from a `[a.b]` or `[[a.b]]` line (a trailing comment is ignored).
fn header_name(line: &str) -> Option<String> {
    let inner = line.trim_start_matches('[');
    let name = inner.split(']').next()?.trim();
    (!name.is_empty()).then(|| name.chars().filter(|c| *c != '"').collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_count_characters_not_bytes() {
        let text = "# héllo\n  größe = 1\n";
        let offset = text.find("= 1").unwrap();
        assert_eq!(location_of(text, offset), Location { line: 2, column: 9 });
    }

    #[test]
    fn an_offset_past_the_end_or_inside_a_character_is_clamped() {
        assert_eq!(location_of("ab\ncd", 99), Location { line: 2, column: 3 });
        let text = "é";
        assert_eq!(location_of(text, 1), Location { line: 1, column: 1 });
    }

    #[test]
    fn a_key_is_named_under_its_nearest_header() {
        let text = "[radar]\na = 1\n[sim.faults] # faults\nstall_ms = 3\n";
        let start = text.find("stall_ms").unwrap();
        assert_eq!(
            key_path_at(text, &(start..start + 8)).as_deref(),
            Some("sim.faults.stall_ms")
        );
        let header = text.find("sim.faults").unwrap();
        assert_eq!(
            key_path_at(text, &(header..header + 3)).as_deref(),
            Some("sim.faults")
        );
    }

    #[test]
    fn quoted_keys_and_array_table_headers_are_unquoted() {
        let text = "[[\"model\".points]]\n\"gain_db\" = x\n";
        let start = text.find("x").unwrap();
        assert_eq!(
            key_path_at(text, &(start..start + 1)).as_deref(),
            Some("model.points.gain_db")
        );
    }

    #[test]
    fn a_line_without_a_key_names_nothing() {
        let text = "[radar]\n\n";
        assert_eq!(key_path_at(text, &(8..8)), None);
    }
}
