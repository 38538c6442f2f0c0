//! The shutdown grace window: how long a node's shutdown hooks may take,
//! all of them together. One rule for every reader of it (the node, the
//! launcher that must not signal it again while its hooks run, and the
//! Python runtime, which checks the same bounds against
//! `tests/golden/wire.json`), so no two of them can disagree on a value.

use std::time::Duration;

/// The environment variable that sets a node's window (seconds, above 0),
/// over its runtime config and its code.
pub const SHUTDOWN_GRACE_ENV: &str = "PEPPY_SHUTDOWN_GRACE_SECS";

/// The window of a node that sets none (PeppyOS's default).
pub const DEFAULT_SHUTDOWN_GRACE: Duration = Duration::from_secs(5);

/// The longest window: a year, so a deadline computed from it fits any
/// clock. Anything a robot's hooks could need is below it.
pub const MAX_SHUTDOWN_GRACE_SECS: f64 = 31_536_000.0;

/// Why a value is not a grace window.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GraceError {
    /// The text is not a number.
    #[error("`{0}` is not a number of seconds")]
    NotANumber(String),
    /// Not finite, not above 0, or above a year.
    #[error(
        "{0} is not a number of seconds above 0 and at most a year ({MAX_SHUTDOWN_GRACE_SECS})"
    )]
    OutOfRange(f64),
}

/// `secs` as a window: finite, above 0, at most [`MAX_SHUTDOWN_GRACE_SECS`].
pub fn grace_window(secs: f64) -> Result<Duration, GraceError> {
    if secs.is_finite() && secs > 0.0 && secs <= MAX_SHUTDOWN_GRACE_SECS {
        Ok(Duration::from_secs_f64(secs))
    } else {
        Err(GraceError::OutOfRange(secs))
    }
}

/// A window written as text, as [`SHUTDOWN_GRACE_ENV`] holds it.
pub fn grace_window_text(text: &str) -> Result<Duration, GraceError> {
    let secs: f64 = text
        .trim()
        .parse()
        .map_err(|_| GraceError::NotANumber(text.to_string()))?;
    grace_window(secs)
}

/// The window [`SHUTDOWN_GRACE_ENV`] sets, given its value: unset or blank
/// sets none.
pub fn grace_window_env(value: Option<&str>) -> Result<Option<Duration>, GraceError> {
    match value {
        Some(text) if !text.trim().is_empty() => grace_window_text(text).map(Some),
        _ => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_are_finite_seconds_above_zero_up_to_a_year() {
        assert_eq!(grace_window_text("7200"), Ok(Duration::from_secs(7200)));
        assert_eq!(grace_window_text(" 0.5 "), Ok(Duration::from_millis(500)));
        assert_eq!(
            grace_window(MAX_SHUTDOWN_GRACE_SECS),
            Ok(Duration::from_secs(31_536_000))
        );
        for bad in [
            0.0,
            -1.0,
            f64::NAN,
            f64::INFINITY,
            MAX_SHUTDOWN_GRACE_SECS + 1.0,
        ] {
            assert!(grace_window(bad).is_err(), "{bad}");
        }
        assert_eq!(grace_window_env(Some(" ")), Ok(None));
        assert_eq!(grace_window_env(None), Ok(None));
        assert_eq!(
            grace_window_text("soon"),
            Err(GraceError::NotANumber("soon".into()))
        );
    }
}
