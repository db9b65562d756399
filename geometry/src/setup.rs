//! The mechanical setup of sensor, mirror and receiver, as a scene or controller file states it.

use serde::{Deserialize, Serialize};

/// The paper's `y_FSM`: laser exit (sensor reference) to mirror along the laser, in mm.
pub const PAPER_Y_FSM_MM: f64 = 10.0;
/// The paper's `z_FSM`: height of the mirror's pivot above the laser line, in mm.
pub const PAPER_Z_FSM_MM: f64 = 16.5;
/// The paper's mirror orientation about x at zero deflection, in degrees.
pub const PAPER_ALPHA_DEG: f64 = 45.0;
/// The paper's reflected-beam angle (receiver ray against the horizontal) at the near end of
/// the range, in degrees (section V: "varies between 71 and 79.1 deg").
pub const PAPER_RECEIVER_ANGLE_NEAR_DEG: f64 = 71.0;
/// The paper's reflected-beam angle at the far end of the range, in degrees.
pub const PAPER_RECEIVER_ANGLE_FAR_DEG: f64 = 79.1;
/// Sensor distance at which [`PAPER_RECEIVER_ANGLE_NEAR_DEG`] holds: start of the ILD 2300-100
/// range, in mm.
pub const RECEIVER_NEAR_Z_MEAS_MM: f64 = 70.0;
/// Sensor distance at which [`PAPER_RECEIVER_ANGLE_FAR_DEG`] holds: end of the range, in mm.
pub const RECEIVER_FAR_Z_MEAS_MM: f64 = 170.0;

/// Where the mirror and the sensor's receiver sit relative to the sensor's laser.
///
/// The receiver is an effective pinhole (the projection centre of the ILD's receiving lens),
/// `receiver_setback_mm` behind the reference point along the laser axis and
/// `receiver_baseline_mm` above it (+z), in the plane of the laser and the mirror normal, so the
/// triangulation plane is the yz plane after the fold, as in the paper (the reflection path is
/// blocked by edges along y). The defaults are derived from the paper's 71 deg / 79.1 deg with
/// [`ScannerSetup::receiver_from_angles`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScannerSetup {
    /// `y_FSM`: sensor reference to the mirror hit point along the laser at zero deflection, mm.
    pub y_fsm_mm: f64,
    /// `z_FSM`: height of the mirror's pivot (its rotation centre, on the reflecting surface)
    /// above the laser line, mm.
    pub z_fsm_mm: f64,
    /// `alpha`: the mirror's angle against the vertical (z axis) at zero deflection, degrees.
    pub alpha_deg: f64,
    /// Receiver pinhole's offset from the laser axis, towards +z (the triangulation base), mm.
    pub receiver_baseline_mm: f64,
    /// Receiver pinhole's distance behind the reference point along the laser axis (+y), mm.
    pub receiver_setback_mm: f64,
}

impl Default for ScannerSetup {
    fn default() -> Self {
        let (receiver_baseline_mm, receiver_setback_mm) = ScannerSetup::receiver_from_angles(
            PAPER_RECEIVER_ANGLE_NEAR_DEG,
            RECEIVER_NEAR_Z_MEAS_MM,
            PAPER_RECEIVER_ANGLE_FAR_DEG,
            RECEIVER_FAR_Z_MEAS_MM,
        );
        ScannerSetup {
            y_fsm_mm: PAPER_Y_FSM_MM,
            z_fsm_mm: PAPER_Z_FSM_MM,
            alpha_deg: PAPER_ALPHA_DEG,
            receiver_baseline_mm,
            receiver_setback_mm,
        }
    }
}

impl ScannerSetup {
    /// `alpha` in radians.
    #[must_use]
    pub fn alpha_rad(&self) -> f64 {
        self.alpha_deg.to_radians()
    }

    /// The receiver pinhole (baseline, setback) in mm that makes the ray from the spot to the
    /// receiver (unfolded by the resting mirror) rise at `near_deg` above the horizontal for a
    /// spot at sensor distance `near_mm`, and at `far_deg` at `far_mm`, for zero deflection:
    /// `tan(angle) = (z_meas + setback) / baseline`.
    ///
    /// With the paper's 71 deg at 70 mm and 79.1 deg at 170 mm this gives a baseline of
    /// 43.69 mm and a setback of 56.89 mm (triangulation angle 19 deg near, 10.9 deg far).
    #[must_use]
    pub fn receiver_from_angles(
        near_deg: f64,
        near_mm: f64,
        far_deg: f64,
        far_mm: f64,
    ) -> (f64, f64) {
        let (tan_near, tan_far) = (near_deg.to_radians().tan(), far_deg.to_radians().tan());
        let baseline = (far_mm - near_mm) / (tan_far - tan_near);
        (baseline, baseline * tan_near - near_mm)
    }

    /// Checks that every field is finite and physically possible; names the first bad field.
    ///
    /// # Errors
    /// [`SetupError`] naming the field and its value.
    pub fn validate(&self) -> Result<(), SetupError> {
        let fields = [
            ("y_fsm_mm", self.y_fsm_mm, 0.0),
            ("z_fsm_mm", self.z_fsm_mm, 0.0),
            ("receiver_baseline_mm", self.receiver_baseline_mm, 0.0),
        ];
        for (field, value, min_exclusive) in fields {
            if !value.is_finite() || value <= min_exclusive {
                return Err(SetupError {
                    field,
                    value,
                    requirement: "finite and > 0",
                });
            }
        }
        if !self.receiver_setback_mm.is_finite() {
            return Err(SetupError {
                field: "receiver_setback_mm",
                value: self.receiver_setback_mm,
                requirement: "finite",
            });
        }
        if !(self.alpha_deg.is_finite() && self.alpha_deg > 10.0 && self.alpha_deg < 80.0) {
            return Err(SetupError {
                field: "alpha_deg",
                value: self.alpha_deg,
                requirement: "finite, between 10 and 80 degrees",
            });
        }
        Ok(())
    }
}

/// A [`ScannerSetup`] field that is not usable.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("scanner setup field `{field}` = {value} must be {requirement}")]
pub struct SetupError {
    /// The field's name as written in a scene file.
    pub field: &'static str,
    /// The value found.
    pub value: f64,
    /// What the value must be.
    pub requirement: &'static str,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_receiver_reproduces_its_angles() {
        let s = ScannerSetup::default();
        assert_eq!((s.y_fsm_mm, s.z_fsm_mm, s.alpha_deg), (10.0, 16.5, 45.0));
        let angle = |z: f64| {
            ((z + s.receiver_setback_mm) / s.receiver_baseline_mm)
                .atan()
                .to_degrees()
        };
        assert!((angle(70.0) - 71.0).abs() < 1e-9);
        assert!((angle(170.0) - 79.1).abs() < 1e-9);
        assert!(
            (s.receiver_baseline_mm - 43.69).abs() < 0.01,
            "{}",
            s.receiver_baseline_mm
        );
        assert!(
            (s.receiver_setback_mm - 56.89).abs() < 0.01,
            "{}",
            s.receiver_setback_mm
        );
    }

    #[test]
    fn serde_fills_defaults_and_rejects_unknown_fields() {
        let s: ScannerSetup = serde_json::from_str(r#"{"y_fsm_mm": 12.0}"#).unwrap();
        assert_eq!(s.y_fsm_mm, 12.0);
        assert_eq!(s.z_fsm_mm, 16.5);
        assert!(serde_json::from_str::<ScannerSetup>(r#"{"y_fsm": 12.0}"#).is_err());
    }

    #[test]
    fn validate_names_the_bad_field() {
        let s = ScannerSetup {
            z_fsm_mm: f64::NAN,
            ..ScannerSetup::default()
        };
        assert_eq!(s.validate().unwrap_err().field, "z_fsm_mm");
        let s = ScannerSetup {
            alpha_deg: 90.0,
            ..ScannerSetup::default()
        };
        assert_eq!(s.validate().unwrap_err().field, "alpha_deg");
        assert!(ScannerSetup::default().validate().is_ok());
    }
}
