//! How every program says a value cannot run: what (the field, or the flag), where (the file,
//! or the command line), the value, and what is allowed.
//!
//! A check names the field alone and returns [`Invalid`]; its caller places it, in a file
//! ([`Invalid::in_file`]) or on the command line ([`Invalid::as_flag`]), so one check serves a
//! scenario's field and the flag that overrides it. [`Allowed`] states a range with its unit
//! once, and every message made from it reads the same way:
//!
//! ```text
//! fixtures/scenarios/x.json: field `timing.lockstep_answer_allowance_s`: 1e300 s is not within (0, 60] s
//! --lockstep-answer-allowance-s: NaN s is not within (0, 60] s
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

/// A value that cannot run, named by its field (a dotted path below the document: `timing.
/// watchdog_periods`), with why: the value and what is allowed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("field `{field}`: {reason}")]
pub struct Invalid {
    /// The field, as a dotted path.
    pub field: String,
    /// The value and what is allowed.
    pub reason: String,
}

impl Invalid {
    /// `field` is invalid because of `reason`.
    pub fn new(field: impl Into<String>, reason: impl Into<String>) -> Invalid {
        Invalid {
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// The same error for a field one level down: `parent.field`.
    #[must_use]
    pub fn under(self, parent: &str) -> Invalid {
        Invalid {
            field: format!("{parent}.{}", self.field),
            reason: self.reason,
        }
    }

    /// The error placed in `file`.
    #[must_use]
    pub fn in_file(self, file: &Path) -> InvalidValue {
        InvalidValue::Field {
            file: file.to_owned(),
            field: self.field,
            reason: self.reason,
        }
    }

    /// The error placed on the command line, as the value of `flag` (`--duration-s`).
    #[must_use]
    pub fn as_flag(self, flag: &str) -> InvalidValue {
        InvalidValue::Flag {
            flag: flag.to_owned(),
            reason: self.reason,
        }
    }

    /// The error as the value of the flag spelled like its field (`probe_s` -> `--probe-s`).
    #[must_use]
    pub fn as_own_flag(self) -> InvalidValue {
        let flag = flag_of(&self.field);
        self.as_flag(&flag)
    }
}

/// The command-line flag spelled like a field's last part: `timing.probe_s` -> `--probe-s`.
#[must_use]
pub fn flag_of(field: &str) -> String {
    let last = field.rsplit('.').next().unwrap_or(field);
    format!("--{}", last.replace('_', "-"))
}

/// A value that cannot run, placed in a file or on the command line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InvalidValue {
    /// A field of a file.
    #[error("{}: field `{field}`: {reason}", file.display())]
    Field {
        /// The file.
        file: PathBuf,
        /// The field, as a dotted path.
        field: String,
        /// The value and what is allowed.
        reason: String,
    },
    /// The value of a command-line flag.
    #[error("{flag}: {reason}")]
    Flag {
        /// The flag, with its dashes.
        flag: String,
        /// The value and what is allowed.
        reason: String,
    },
}

/// A range of allowed values and their unit: `(0, 60] s`, `[1, 99]`, `finite` values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Allowed {
    /// The lowest value (`-inf`: no bound below).
    pub min: f64,
    /// Whether `min` itself is allowed.
    pub min_included: bool,
    /// The highest value (`inf`: no bound above).
    pub max: f64,
    /// Whether `max` itself is allowed.
    pub max_included: bool,
    /// The unit, as messages print it after a value (`""`: none).
    pub unit: &'static str,
}

impl Allowed {
    /// `[min, max]`.
    #[must_use]
    pub const fn closed(min: f64, max: f64, unit: &'static str) -> Allowed {
        Allowed {
            min,
            min_included: true,
            max,
            max_included: true,
            unit,
        }
    }

    /// `(min, max]`: above `min`, up to `max`.
    #[must_use]
    pub const fn above(min: f64, max: f64, unit: &'static str) -> Allowed {
        Allowed {
            min,
            min_included: false,
            max,
            max_included: true,
            unit,
        }
    }

    /// Any finite value.
    #[must_use]
    pub const fn finite(unit: &'static str) -> Allowed {
        Allowed::closed(f64::NEG_INFINITY, f64::INFINITY, unit)
    }

    /// Whether `value` is finite and in the range.
    #[must_use]
    pub fn contains(&self, value: f64) -> bool {
        let above_min = if self.min_included {
            value >= self.min
        } else {
            value > self.min
        };
        let below_max = if self.max_included {
            value <= self.max
        } else {
            value < self.max
        };
        value.is_finite() && above_min && below_max
    }

    /// `Ok` when `value` is allowed, else [`Invalid`] for `field` stating the value and the
    /// range.
    ///
    /// # Errors
    /// A value outside the range, infinite or NaN.
    pub fn check(&self, field: &str, value: f64) -> Result<(), Invalid> {
        if self.contains(value) {
            Ok(())
        } else {
            Err(Invalid::new(
                field,
                format!(
                    "{}{} is not within {self}",
                    number(value),
                    unit_suffix(self.unit)
                ),
            ))
        }
    }

    /// [`Self::check`] for an optional value (`None` is always allowed).
    ///
    /// # Errors
    /// As [`Self::check`].
    pub fn check_some(&self, field: &str, value: Option<f64>) -> Result<(), Invalid> {
        value.map_or(Ok(()), |value| self.check(field, value))
    }
}

impl fmt::Display for Allowed {
    /// `(0, 60] s`; an unbounded side reads `finite values above 0 s`, `finite values`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unit = unit_suffix(self.unit);
        match (self.min.is_finite(), self.max.is_finite()) {
            (true, true) => write!(
                f,
                "{}{}, {}{}{unit}",
                if self.min_included { '[' } else { '(' },
                number(self.min),
                number(self.max),
                if self.max_included { ']' } else { ')' },
            ),
            (true, false) => write!(
                f,
                "finite values {} {}{unit}",
                if self.min_included { "from" } else { "above" },
                number(self.min)
            ),
            (false, true) => write!(
                f,
                "finite values {} {}{unit}",
                if self.max_included { "up to" } else { "below" },
                number(self.max)
            ),
            (false, false) => write!(f, "finite values{unit}"),
        }
    }
}

/// `Ok` when the count `value` is within `min..=max`, else [`Invalid`] for `field` stating
/// the value and the range (`0 periods is not within [1, 10000000] periods`).
///
/// # Errors
/// A count outside the range.
pub fn check_count(
    field: &str,
    value: u64,
    min: u64,
    max: u64,
    unit: &'static str,
) -> Result<(), Invalid> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        let unit = unit_suffix(unit);
        Err(Invalid::new(
            field,
            format!("{value}{unit} is not within [{min}, {max}]{unit}"),
        ))
    }
}

fn unit_suffix(unit: &str) -> String {
    if unit.is_empty() {
        String::new()
    } else {
        format!(" {unit}")
    }
}

/// A number as messages print it: plainly where that is short (`0.05`, `20000`), in
/// scientific notation where it is not (`1e300`, `1e-9`).
#[must_use]
pub fn number(value: f64) -> String {
    let magnitude = value.abs();
    if value == 0.0 || !value.is_finite() || (1e-4..1e9).contains(&magnitude) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_range_names_the_value_and_its_bounds_with_the_unit() {
        let allowance = Allowed::above(0.0, 60.0, "s");
        assert!(allowance.contains(60.0) && allowance.contains(1e-9));
        for bad in [0.0, -1.0, 60.000_001, f64::NAN, f64::INFINITY] {
            assert!(!allowance.contains(bad), "{bad}");
        }
        let error = allowance.check("timing.allowance_s", 1e300).unwrap_err();
        assert_eq!(
            error.to_string(),
            "field `timing.allowance_s`: 1e300 s is not within (0, 60] s"
        );
        assert_eq!(
            allowance.check("x", f64::NAN).unwrap_err().reason,
            "NaN s is not within (0, 60] s"
        );
        assert_eq!(
            Allowed::closed(1.0, 99.0, "")
                .check("p", 0.5)
                .unwrap_err()
                .reason,
            "0.5 is not within [1, 99]"
        );
    }

    #[test]
    fn unbounded_sides_read_as_words_and_still_refuse_infinity() {
        assert_eq!(Allowed::finite("mm").to_string(), "finite values mm");
        let positive = Allowed {
            max: f64::INFINITY,
            ..Allowed::above(0.0, 0.0, "mm")
        };
        assert_eq!(positive.to_string(), "finite values above 0 mm");
        assert!(!positive.contains(f64::INFINITY) && !positive.contains(0.0));
        assert!(positive.contains(f64::MAX));
        let below = Allowed {
            min: f64::NEG_INFINITY,
            ..Allowed::closed(0.0, 5.0, "")
        };
        assert_eq!(below.to_string(), "finite values up to 5");
        assert!(below.contains(-1e300) && below.contains(5.0) && !below.contains(5.5));
        let open_below = Allowed {
            max_included: false,
            ..below
        };
        assert!(!open_below.contains(5.0));
        assert_eq!(open_below.to_string(), "finite values below 5");
        let from = Allowed {
            max: f64::INFINITY,
            ..Allowed::closed(1.0, 0.0, "Hz")
        };
        assert_eq!(from.to_string(), "finite values from 1 Hz");
    }

    #[test]
    fn a_check_is_placed_in_a_file_or_on_the_command_line() {
        let error = Allowed::above(0.0, 3600.0, "s")
            .check("duration_s", -1.0)
            .unwrap_err();
        assert_eq!(
            error.clone().in_file(Path::new("a/b.json")).to_string(),
            "a/b.json: field `duration_s`: -1 s is not within (0, 3600] s"
        );
        assert_eq!(
            error.clone().as_own_flag().to_string(),
            "--duration-s: -1 s is not within (0, 3600] s"
        );
        assert_eq!(
            error.under("lead_in").as_flag("--lead-in-s").to_string(),
            "--lead-in-s: -1 s is not within (0, 3600] s"
        );
        assert_eq!(
            flag_of("timing.lockstep_answer_allowance_s"),
            "--lockstep-answer-allowance-s"
        );
    }

    #[test]
    fn counts_and_optional_values() {
        assert!(check_count("n", 1, 1, 10, "periods").is_ok());
        assert!(check_count("n", 10, 1, 10, "periods").is_ok());
        assert_eq!(
            check_count("n", 0, 1, 10, "periods").unwrap_err().reason,
            "0 periods is not within [1, 10] periods"
        );
        assert!(check_count("n", 11, 1, 10, "").is_err());
        let rate = Allowed::above(0.0, 1e3, "Hz");
        assert!(rate.check_some("r", None).is_ok());
        assert!(rate.check_some("r", Some(-1.0)).is_err());
    }

    #[test]
    fn numbers_are_short() {
        assert_eq!(number(0.05), "0.05");
        assert_eq!(number(20000.0), "20000");
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(1e-9), "1e-9");
        assert_eq!(number(-2.5e12), "-2.5e12");
        assert_eq!(number(0.0), "0");
        assert_eq!(number(f64::NEG_INFINITY), "-inf");
    }
}
