//! Collects every invalid field of a configuration instead of stopping at the first.
//!
//! A section validator asks the [`Checker`] to check each field; a valid field's value comes
//! back, an invalid one is recorded with its dotted path and a valid placeholder comes back so
//! validation can carry on. Placeholders never escape: [`Checker::finish`] returns the errors
//! instead of the value whenever one was recorded.

use std::net::{Ipv4Addr, SocketAddr};
use std::time::Duration;

use crate::error::{FieldError, FieldErrors};
use crate::values::{
    Capacity, FiniteF64, NonNegativeF64, OpenProbability, PlacementShare, PositiveF64, Probability,
    ValueError,
};

/// A valid value to carry on with after an invalid field has been recorded.
pub(crate) trait Placeholder {
    fn placeholder() -> Self;
}

macro_rules! placeholder {
    ($($t:ty => $e:expr),* $(,)?) => {
        $(impl Placeholder for $t {
            fn placeholder() -> Self {
                $e
            }
        })*
    };
}

placeholder! {
    FiniteF64 => FiniteF64::ZERO,
    PositiveF64 => PositiveF64::ONE,
    NonNegativeF64 => NonNegativeF64::ZERO,
    Probability => Probability::HALF,
    PlacementShare => PlacementShare::ZERO,
    OpenProbability => OpenProbability::HALF,
    Capacity => Capacity::ONE,
    Duration => Duration::from_secs(1),
    SocketAddr => SocketAddr::from((Ipv4Addr::LOCALHOST, 0)),
    u64 => 0,
    [f64; 3] => [1.0; 3],
    usize => 0,
    std::path::PathBuf => std::path::PathBuf::from("placeholder"),
    f64 => 0.0,
}

impl<T> Placeholder for Option<T> {
    fn placeholder() -> Self {
        None
    }
}

/// Records field errors with their dotted paths.
#[derive(Debug, Default)]
pub(crate) struct Checker {
    errors: Vec<FieldError>,
}

impl Checker {
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// The value, or a placeholder after recording `path`'s error.
    pub(crate) fn check<T: Placeholder>(&mut self, path: &str, result: Result<T, ValueError>) -> T {
        match result {
            Ok(value) => value,
            Err(problem) => {
                self.fail(path, problem);
                T::placeholder()
            }
        }
    }

    /// The value, or `None` after recording `path`'s error. For fields that take part in a
    /// rule across fields: the rule is checked only when each of its fields is valid, so one
    /// mistake is reported once.
    pub(crate) fn check_ok<T>(&mut self, path: &str, result: Result<T, ValueError>) -> Option<T> {
        match result {
            Ok(value) => Some(value),
            Err(problem) => {
                self.fail(path, problem);
                None
            }
        }
    }

    /// Checks an optional raw value; `None` stays `None`.
    pub(crate) fn check_opt<R, T>(
        &mut self,
        path: &str,
        raw: Option<R>,
        make: impl FnOnce(R) -> Result<T, ValueError>,
    ) -> Option<T> {
        match raw.map(make) {
            None => None,
            Some(Ok(value)) => Some(value),
            Some(Err(problem)) => {
                self.fail(path, problem);
                None
            }
        }
    }

    /// Records a rule that involves more than one field (named by the first argument).
    pub(crate) fn fail(&mut self, path: &str, problem: ValueError) {
        self.errors.push(FieldError {
            path: path.to_owned(),
            problem,
        });
    }

    /// Whether nothing has been rejected so far.
    pub(crate) fn is_clean(&self) -> bool {
        self.errors.is_empty()
    }

    /// The value if every field was valid, else all the errors.
    pub(crate) fn finish<T>(self, value: T) -> Result<T, FieldErrors> {
        if self.errors.is_empty() {
            Ok(value)
        } else {
            Err(FieldErrors(self.errors))
        }
    }
}
