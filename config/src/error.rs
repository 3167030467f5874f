//! The errors a configuration can produce: unreadable file, TOML that does not parse or has
//! an unknown key, and values that parse but are not valid settings.

use std::fmt;
use std::path::PathBuf;

use crate::values::ValueError;

/// Everything that can go wrong loading a configuration.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The file could not be opened or read (missing, permissions, not UTF-8).
    #[error("cannot read config file {path}: {source}")]
    Io {
        /// The file asked for.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The file is larger than any configuration has reason to be.
    #[error("config file {path} is larger than the {max_bytes} bytes a configuration may hold")]
    TooLarge {
        /// The file asked for.
        path: PathBuf,
        /// The limit, [`crate::MAX_CONFIG_BYTES`].
        max_bytes: u64,
    },
    /// A key that no section knows: usually a misspelling.
    #[error("{origin}: {location}: unknown key `{key_path}`; {message}")]
    UnknownKey {
        /// The file path, or `<string>` for text given directly.
        origin: String,
        /// The dotted path of the key, e.g. `filter.sigma_rnage_m`.
        key_path: String,
        /// Where the key is written.
        location: Location,
        /// The parser's message, which lists the keys that are known there.
        message: String,
    },
    /// Text that is not TOML, or a value of the wrong type (a string where a number belongs,
    /// an unknown choice such as `drop_policy = "drop-newst"`).
    #[error("{origin}: {}{}{message}", location.map(|l| format!("{l}: ")).unwrap_or_default(), key_path.as_ref().map(|k| format!("key `{k}`: ")).unwrap_or_default())]
    Parse {
        /// The file path, or `<string>` for text given directly.
        origin: String,
        /// The dotted path of the key the error is at, when the parser says where.
        key_path: Option<String>,
        /// Where the error is, when the parser says.
        location: Option<Location>,
        /// The parser's message.
        message: String,
    },
    /// A command-line override (`path=value`) that is malformed, names an unknown key or
    /// gives a value of the wrong type.
    #[error("override `{text}`: {message}")]
    Override {
        /// The override as given.
        text: String,
        /// What is wrong.
        message: String,
    },
    /// The TOML parsed, but one or more values are not valid settings. Every invalid field
    /// is listed, not only the first.
    #[error("{origin}: invalid settings: {errors}")]
    Invalid {
        /// The file path, or `<string>` for text given directly.
        origin: String,
        /// One entry per invalid field.
        errors: FieldErrors,
    },
}

impl ConfigError {
    /// The field errors, when this is a validation error (empty otherwise).
    pub fn field_errors(&self) -> &[FieldError] {
        match self {
            ConfigError::Invalid { errors, .. } => &errors.0,
            _ => &[],
        }
    }
}

/// A 1-based line and column in the configuration text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Location {
    /// Line, counting from 1.
    pub line: usize,
    /// Column in characters, counting from 1.
    pub column: usize,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}, column {}", self.line, self.column)
    }
}

/// One invalid field: its full dotted path and what is wrong with it.
///
/// Displays as e.g. `filter.sigma_range_m must be > 0, got -1`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{path} {problem}")]
pub struct FieldError {
    /// The dotted path, e.g. `radar.reconnect_jitter`.
    pub path: String,
    /// What is wrong.
    pub problem: ValueError,
}

/// All the invalid fields of one configuration, in the order they were checked.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FieldErrors(pub Vec<FieldError>);

impl FieldErrors {
    /// The errors.
    pub fn as_slice(&self) -> &[FieldError] {
        &self.0
    }
    /// The error for a given dotted path, if that field was rejected.
    pub fn for_path(&self, path: &str) -> Option<&FieldError> {
        self.0.iter().find(|e| e.path == path)
    }
}

impl fmt::Display for FieldErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, e) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str("; ")?;
            }
            write!(f, "{e}")?;
        }
        Ok(())
    }
}

impl std::error::Error for FieldErrors {}
