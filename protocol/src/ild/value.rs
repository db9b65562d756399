//! ILD 2300 measured values: the 18-bit raw value, its distance in millimetres for a
//! measuring range, and the error codes that are kept distinct from distances.
//!
//! From the operating manual (see `docs/protocol.md`, Formats): a raw value `digital` in
//! `0..=65519` is a distance, `x = (digital * 1.02 / 65520 - 0.01) * MR` millimetres from the
//! start of the measuring range (MR = the range's span). `0..=642` is the start-of-range
//! reserve, `643..=64876` the measuring range, `64877..=65519` the end-of-range reserve.
//! Values from 65520 up to `2^18 - 1` are error codes.

/// The largest value an 18-bit raw field can carry.
pub const RAW_MAX: u32 = (1 << 18) - 1;
/// The largest raw value that is a distance; everything above is an error code.
pub const DIGITAL_MAX: u32 = 65_519;
/// The first raw value inside the measuring range (below: start-of-range reserve).
pub const DIGITAL_RANGE_START: u32 = 643;
/// The last raw value inside the measuring range (above: end-of-range reserve).
pub const DIGITAL_RANGE_END: u32 = 64_876;
/// Scale factor of the distance formula: `digital * SCALE_NUM / SCALE_DEN`.
const SCALE_NUM: f64 = 1.02;
const SCALE_DEN: f64 = 65_520.0;
const OFFSET: f64 = 0.01;

/// The sensor's measuring range: where it starts and how long it is, in millimetres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeasuringRange {
    /// Distance from the sensor's reference to the start of the range (SMR), in mm.
    pub start_mm: f64,
    /// Length of the range (MR), in mm.
    pub span_mm: f64,
}

impl MeasuringRange {
    /// The ILD 2300-100: 100 mm of range starting 70 mm from the sensor.
    pub const ILD2300_100: MeasuringRange = MeasuringRange {
        start_mm: 70.0,
        span_mm: 100.0,
    };

    /// The absolute distance (from the sensor reference) that a raw distance value stands
    /// for, in millimetres. `digital` above [`DIGITAL_MAX`] is not a distance: `None`.
    #[must_use]
    pub fn digital_to_mm(&self, digital: u32) -> Option<f64> {
        (digital <= DIGITAL_MAX).then(|| {
            self.start_mm + (f64::from(digital) * SCALE_NUM / SCALE_DEN - OFFSET) * self.span_mm
        })
    }

    /// The raw value the sensor outputs for an absolute distance in millimetres, rounded to
    /// the nearest step and clamped to `0..=DIGITAL_MAX` (the reserves included); `None` for a
    /// distance that is not finite.
    #[must_use]
    pub fn mm_to_digital(&self, distance_mm: f64) -> Option<u32> {
        if !distance_mm.is_finite() {
            return None;
        }
        let relative = (distance_mm - self.start_mm) / self.span_mm;
        let digital = ((relative + OFFSET) * SCALE_DEN / SCALE_NUM).round();
        Some(digital.clamp(0.0, f64::from(DIGITAL_MAX)) as u32)
    }

    /// One raw step in millimetres (the resolution of the digital output).
    #[must_use]
    pub fn mm_per_digit(&self) -> f64 {
        self.span_mm * SCALE_NUM / SCALE_DEN
    }
}

/// The error codes an ILD 2300 sends in place of a distance on RS422.
///
/// These code values are not yet confirmed against a manual (they are the family's codes as
/// remembered; see `docs/decisions.md`, unchecked ILD 2300 facts), so they live here as named
/// constants only.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum IldError {
    /// 262075: more data than the baud rate can carry.
    TooMuchData,
    /// 262076: no peak on the detector (nothing there, or the path is shaded).
    NoPeak,
    /// 262077: peak before the start of the measuring range (too close).
    PeakBeforeRange,
    /// 262078: peak after the end of the measuring range (too far).
    PeakAfterRange,
    /// 262079: the value cannot be evaluated.
    CannotEvaluate,
    /// 262080: the peak is too wide.
    PeakTooWide,
    /// 262081: the laser is off.
    LaserOff,
    /// Any other value above [`DIGITAL_MAX`]; the raw code is kept.
    Unknown(u32),
}

/// Raw code of [`IldError::TooMuchData`]; the others follow in the order of the enum.
pub const ERROR_CODE_FIRST: u32 = 262_075;

impl IldError {
    /// The errors the sensor names, in the order of their codes from [`ERROR_CODE_FIRST`].
    pub const KNOWN: [IldError; 7] = [
        IldError::TooMuchData,
        IldError::NoPeak,
        IldError::PeakBeforeRange,
        IldError::PeakAfterRange,
        IldError::CannotEvaluate,
        IldError::PeakTooWide,
        IldError::LaserOff,
    ];

    /// The raw value the sensor sends for this error.
    #[must_use]
    pub fn code(self) -> u32 {
        match self {
            IldError::Unknown(raw) => raw,
            known => {
                ERROR_CODE_FIRST + Self::KNOWN.iter().position(|&k| k == known).unwrap_or(0) as u32
            }
        }
    }

    /// A stable snake_case name, used in JSON output.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            IldError::TooMuchData => "too_much_data",
            IldError::NoPeak => "no_peak",
            IldError::PeakBeforeRange => "peak_before_range",
            IldError::PeakAfterRange => "peak_after_range",
            IldError::CannotEvaluate => "cannot_evaluate",
            IldError::PeakTooWide => "peak_too_wide",
            IldError::LaserOff => "laser_off",
            IldError::Unknown(_) => "unknown_error",
        }
    }
}

/// One measured value as the sensor sends it: a distance (raw digital value) or an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum IldValue {
    /// A raw distance value, `0..=DIGITAL_MAX`.
    Distance(u32),
    /// An error code in place of a distance.
    Error(IldError),
}

impl IldValue {
    /// Classifies an 18-bit raw value (bits above bit 17 are ignored).
    #[must_use]
    pub fn from_raw(raw: u32) -> IldValue {
        let raw = raw & RAW_MAX;
        if raw <= DIGITAL_MAX {
            return IldValue::Distance(raw);
        }
        let error = raw
            .checked_sub(ERROR_CODE_FIRST)
            .and_then(|i| IldError::KNOWN.get(i as usize).copied())
            .unwrap_or(IldError::Unknown(raw));
        IldValue::Error(error)
    }

    /// The 18-bit raw value on the wire.
    #[must_use]
    pub fn raw(self) -> u32 {
        match self {
            IldValue::Distance(digital) => digital.min(DIGITAL_MAX),
            IldValue::Error(e) => e.code() & RAW_MAX,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_ends_map_to_range_ends() {
        let r = MeasuringRange::ILD2300_100;
        let start = r.digital_to_mm(DIGITAL_RANGE_START).unwrap();
        let end = r.digital_to_mm(DIGITAL_RANGE_END).unwrap();
        assert!((start - 70.0).abs() < 2.0 * r.mm_per_digit(), "{start}");
        assert!((end - 170.0).abs() < 2.0 * r.mm_per_digit(), "{end}");
        assert_eq!(r.digital_to_mm(DIGITAL_MAX + 1), None);
    }

    #[test]
    fn mm_round_trips_within_half_a_digit() {
        let r = MeasuringRange::ILD2300_100;
        for mm in [70.0, 100.123, 130.0, 169.99] {
            let back = r.digital_to_mm(r.mm_to_digital(mm).unwrap()).unwrap();
            assert!(
                (back - mm).abs() <= 0.5 * r.mm_per_digit() + 1e-12,
                "{mm} -> {back}"
            );
        }
        assert_eq!(r.mm_to_digital(1e9), Some(DIGITAL_MAX));
        assert_eq!(r.mm_to_digital(f64::NAN), None);
    }

    #[test]
    fn errors_are_distinct_from_distances_and_round_trip() {
        for e in IldError::KNOWN {
            assert_eq!(IldValue::from_raw(e.code()), IldValue::Error(e));
        }
        assert_eq!(
            IldValue::from_raw(70_000),
            IldValue::Error(IldError::Unknown(70_000))
        );
        assert_eq!(IldValue::from_raw(65_519), IldValue::Distance(65_519));
        assert_eq!(IldValue::Error(IldError::NoPeak).raw(), 262_076);
    }
}
