//! What a scan will hold and write, worked out before any link opens, so a value that would
//! fill the memory or the disk is refused naming its field instead of being found after the
//! loop (a 1e-5 mm pitch once ran the whole scan and then failed with no report; 0.0013 mm
//! ran 220 s, took 9.9 GB and wrote a 2.79 GB height map).
//!
//! Pure: the free disk and the available memory are arguments; [`super::run_scan`] reads
//! them.
//! - [`ScanArea::of_rig`]: the area the scan's points can cover: the reconstruction of the
//!   trajectory's extreme angles (with [`ANGLE_MARGIN`], through the rig's calibration) over
//!   the sensor's whole measuring range.
//! - [`check_grid`]: the height map's cells over that area against
//!   [`MAX_CELLS`] and the memory imaging would hold.
//! - [`OutputBytes`]: the recordings and the height map's bytes against the free disk.

use scanhil_geometry::Scanner;
use scanhil_protocol::ild::value::MeasuringRange;
use scanhil_protocol::validation::{Invalid, number};

use crate::imaging::grid::{
    BYTES_PER_CELL, CSV_BYTES_PER_CELL, MAX_CELLS, cells_over, smallest_pitch_mm,
};
use crate::imaging::reconstruct::ScanSample;
use crate::rig::Calibration;

/// Measured angles may exceed the reference (overshoot, tracking error, the lead-in's
/// transient): the area takes half as much again as the trajectory's peaks.
pub const ANGLE_MARGIN: f64 = 1.5;

/// `fsm.log`'s bytes per control period, an upper bound: a lockstep period's Step,
/// CoilCommand and AngleReading lines take 100 bytes on the Duplo stud scan (2 500 648 bytes
/// for 25 000 periods); status lines and longer stamps are within the rest.
pub const FSM_LOG_BYTES_PER_PERIOD: f64 = 128.0;

/// `sensor.ild`'s bytes per value: three bytes on the RS422 line.
pub const ILD_BYTES_PER_VALUE: f64 = 3.0;

/// `points.ply`'s bytes per point (binary: position, time, angles and distance), an upper
/// bound (51 on the Duplo stud scan).
pub const PLY_BYTES_PER_POINT: f64 = 64.0;

/// The rectangle a scan's points can fall in, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanArea {
    /// The lowest and highest x, mm.
    pub x_mm: (f64, f64),
    /// The lowest and highest y, mm.
    pub y_mm: (f64, f64),
}

impl ScanArea {
    /// The points' area for mirror readings up to `ANGLE_MARGIN` times `peaks_rad` (alpha,
    /// beta), corrected by `calibration`, over every distance of `range` (corrected too),
    /// reconstructed with `model`. The extremes are taken over a 9 x 9 grid of angles at both
    /// ends of the range: the mapping is smooth and monotonic in each angle over a mirror's
    /// range, so they lie on its edges.
    #[must_use]
    pub fn of_rig(
        scanner: &Scanner,
        calibration: &Calibration,
        peaks_rad: (f64, f64),
        range: MeasuringRange,
    ) -> ScanArea {
        const STEPS: usize = 8;
        let mut area = ScanArea {
            x_mm: (f64::INFINITY, f64::NEG_INFINITY),
            y_mm: (f64::INFINITY, f64::NEG_INFINITY),
        };
        let along =
            |peak: f64, i: usize| ANGLE_MARGIN * peak * (2.0 * i as f64 / STEPS as f64 - 1.0);
        for i in 0..=STEPS {
            for j in 0..=STEPS {
                for z_mm in [range.start_mm, range.start_mm + range.span_mm] {
                    let sample = calibration.apply(ScanSample {
                        t_s: 0.0,
                        d_alpha_rad: along(peaks_rad.0, i),
                        d_beta_rad: along(peaks_rad.1, j),
                        z_meas_mm: Some(z_mm),
                    });
                    let Some(z) = sample.z_meas_mm else { continue };
                    let p = scanner.point(sample.d_alpha_rad, sample.d_beta_rad, z);
                    area.x_mm = (area.x_mm.0.min(p.x), area.x_mm.1.max(p.x));
                    area.y_mm = (area.y_mm.0.min(p.y), area.y_mm.1.max(p.y));
                }
            }
        }
        area
    }

    /// Width (x) and height (y), mm; infinite when a corner was not a number.
    #[must_use]
    pub fn size_mm(&self) -> (f64, f64) {
        let span = |(lo, hi): (f64, f64)| {
            let d = hi - lo;
            if d.is_finite() {
                d.max(0.0)
            } else {
                f64::INFINITY
            }
        };
        (span(self.x_mm), span(self.y_mm))
    }

    /// Cells of a grid of `pitch_mm` over the area.
    #[must_use]
    pub fn cells(&self, pitch_mm: f64) -> f64 {
        let (w, h) = self.size_mm();
        cells_over(w, h, pitch_mm)
    }

    /// The smallest pitch whose grid over the area has at most `cells` cells, mm.
    #[must_use]
    pub fn smallest_pitch_mm(&self, cells: f64) -> f64 {
        let (w, h) = self.size_mm();
        smallest_pitch_mm(w, h, cells)
    }
}

/// Checks the height map's grid of `pitch_mm` over `area`: at most [`MAX_CELLS`] cells, and
/// imaging's memory for them ([`BYTES_PER_CELL`]) within `available_memory_bytes`. Returns
/// the cells.
///
/// # Errors
/// [`Invalid`] naming `imaging.pitch_mm`, with the cells, the area and the smallest pitch
/// that fits.
pub fn check_grid(
    area: &ScanArea,
    pitch_mm: f64,
    available_memory_bytes: f64,
) -> Result<f64, Invalid> {
    let cells = area.cells(pitch_mm);
    let memory_cells = (available_memory_bytes / BYTES_PER_CELL).floor();
    let limit = (MAX_CELLS as f64).min(memory_cells);
    if cells <= limit {
        return Ok(cells);
    }
    let (w, h) = area.size_mm();
    let why = if limit < MAX_CELLS as f64 {
        format!(
            "imaging would hold about {} bytes where {} are available",
            number(cells * BYTES_PER_CELL),
            number(available_memory_bytes)
        )
    } else {
        format!("more than the limit of {MAX_CELLS} cells")
    };
    Err(Invalid::new(
        "imaging.pitch_mm",
        format!(
            "{} mm makes a height map of about {} cells over the {:.1} x {:.1} mm the scan can \
             cover ({why}): the pitch must be at least {} mm",
            number(pitch_mm),
            number(cells),
            w,
            h,
            number(area.smallest_pitch_mm(limit))
        ),
    ))
}

/// What a run writes into its output folder, bytes (upper bounds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputBytes {
    /// `fsm.log`: every period's frames.
    pub fsm_log: f64,
    /// `sensor.ild`: every cycle's values.
    pub sensor_ild: f64,
    /// `points.ply` and `height_map.csv`.
    pub imaging: f64,
}

impl OutputBytes {
    /// The outputs of `periods` control periods, `sensor_cycles` sensor cycles of
    /// `values_per_cycle` values each (0 without a sensor), and a height map of `cells`.
    #[must_use]
    pub fn of_run(periods: u64, sensor_cycles: f64, values_per_cycle: usize, cells: f64) -> Self {
        OutputBytes {
            fsm_log: periods as f64 * FSM_LOG_BYTES_PER_PERIOD,
            sensor_ild: sensor_cycles * values_per_cycle as f64 * ILD_BYTES_PER_VALUE,
            imaging: if values_per_cycle > 0 {
                sensor_cycles * PLY_BYTES_PER_POINT + cells * CSV_BYTES_PER_CELL
            } else {
                0.0
            },
        }
    }

    /// The same outputs, the recordings left out unless `kept` (`outputs.recordings`).
    #[must_use]
    pub fn with_recordings(self, kept: bool) -> Self {
        if kept {
            self
        } else {
            OutputBytes {
                fsm_log: 0.0,
                sensor_ild: 0.0,
                ..self
            }
        }
    }

    /// All of it.
    #[must_use]
    pub fn total(&self) -> f64 {
        self.fsm_log + self.sensor_ild + self.imaging
    }

    /// Checks the total against `free_bytes` on the output folder's disk.
    ///
    /// # Errors
    /// [`Invalid`] naming `duration_s` (the recordings are most of it) or `imaging.pitch_mm`
    /// (the height map is), with each output's bytes and the free space.
    pub fn check(&self, free_bytes: f64) -> Result<(), Invalid> {
        if self.total() <= free_bytes {
            return Ok(());
        }
        let field = if self.imaging > self.fsm_log + self.sensor_ild {
            "imaging.pitch_mm"
        } else {
            "duration_s"
        };
        Err(Invalid::new(
            field,
            format!(
                "the run would write about {} bytes (fsm.log {}, sensor.ild {}, points and \
                 height map {}) where the output folder's disk has {} free",
                number(self.total()),
                number(self.fsm_log),
                number(self.sensor_ild),
                number(self.imaging),
                number(free_bytes)
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scanhil_geometry::GeometryModel;

    const DUPLO_PEAKS: (f64, f64) = (0.015, 0.0523);

    /// The area of a scan with `model` on the paper's setup.
    fn paper_area(model: GeometryModel, peaks_rad: (f64, f64), range: MeasuringRange) -> ScanArea {
        ScanArea::of_rig(
            &Scanner::paper(model),
            &Calibration::default(),
            peaks_rad,
            range,
        )
    }

    fn duplo_area() -> ScanArea {
        paper_area(
            GeometryModel::ExactReflection,
            DUPLO_PEAKS,
            MeasuringRange::ILD2300_100,
        )
    }

    #[test]
    fn the_area_covers_every_point_a_reading_within_the_margin_can_give() {
        let area = duplo_area();
        let scanner = Scanner::paper(GeometryModel::ExactReflection);
        // Points inside the margin's angles and the range fall inside; the reference's own
        // peaks at the range's far end are well inside.
        for (a, b, z) in [
            (0.015, 0.0523, 170.0),
            (-0.0225, 0.078, 70.0),
            (0.0, 0.0, 120.0),
        ] {
            let p = scanner.point(a, b, z);
            assert!(area.x_mm.0 <= p.x && p.x <= area.x_mm.1, "{p:?} {area:?}");
            assert!(area.y_mm.0 <= p.y && p.y <= area.y_mm.1, "{p:?} {area:?}");
        }
        // And the area is no larger than the box of the margin's corners (the mapping is
        // monotonic in each angle: the sides bulge by the pincushion, 7 % in y here).
        let (mut x, mut y) = ((f64::MAX, f64::MIN), (f64::MAX, f64::MIN));
        for a in [-0.0225, 0.0225] {
            for b in [-0.07845, 0.07845] {
                for z in [70.0, 170.0] {
                    let p = scanner.point(a, b, z);
                    (x, y) = ((x.0.min(p.x), x.1.max(p.x)), (y.0.min(p.y), y.1.max(p.y)));
                }
            }
        }
        let (w, h) = area.size_mm();
        assert!(
            w <= 1.05 * (x.1 - x.0) && w >= (x.1 - x.0) * (1.0 - 1e-9),
            "{w} vs {x:?}"
        );
        assert!(
            h <= 1.1 * (y.1 - y.0) && h >= (y.1 - y.0) * (1.0 - 1e-9),
            "{h} vs {y:?}"
        );
    }

    #[test]
    fn a_pitch_the_grid_cannot_hold_is_refused_naming_the_field_and_the_smallest_pitch() {
        let area = duplo_area();
        let plenty = 1e12;
        let error = check_grid(&area, 1e-5, plenty).unwrap_err();
        assert_eq!(error.field, "imaging.pitch_mm");
        assert!(error.reason.contains("1e-5 mm"), "{}", error.reason);
        let smallest: f64 = error
            .reason
            .rsplit("at least ")
            .next()
            .and_then(|rest| rest.trim_end_matches(" mm").parse().ok())
            .expect("the smallest pitch");
        assert!(area.cells(smallest) <= MAX_CELLS as f64);
        assert!(area.cells(smallest * 0.99) > MAX_CELLS as f64 * 0.97);
        assert!(check_grid(&area, smallest, plenty).is_ok());
        assert_eq!(check_grid(&area, 0.1, plenty), Ok(area.cells(0.1)));
    }

    #[test]
    fn memory_lowers_the_limit_below_the_cell_count() {
        let area = duplo_area();
        let cells = area.cells(0.05);
        assert!(check_grid(&area, 0.05, cells * BYTES_PER_CELL).is_ok());
        let error = check_grid(&area, 0.05, cells * BYTES_PER_CELL * 0.5).unwrap_err();
        assert!(error.reason.contains("available"), "{}", error.reason);
    }

    #[test]
    fn a_calibration_far_off_makes_an_area_no_grid_can_hold() {
        let calibration = Calibration {
            distance_offset_mm: 1e300,
            ..Calibration::default()
        };
        let area = ScanArea::of_rig(
            &Scanner::paper(GeometryModel::SmallAngle),
            &calibration,
            DUPLO_PEAKS,
            MeasuringRange::ILD2300_100,
        );
        assert!(check_grid(&area, 0.1, 1e12).is_err());
    }

    #[test]
    fn outputs_beyond_the_free_disk_name_what_makes_them() {
        // An hour at 20 kHz: 72 M periods of fsm.log, 9.2 GB.
        let hour = OutputBytes::of_run(72_000_000, 72e6, 1, 1e4);
        assert!(hour.fsm_log > 9e9);
        assert_eq!(hour.check(1e9).unwrap_err().field, "duration_s");
        assert!(hour.check(1e11).is_ok());
        let fine_map = OutputBytes::of_run(1000, 1000.0, 1, 4e6);
        assert_eq!(fine_map.check(1e6).unwrap_err().field, "imaging.pitch_mm");
        let no_sensor = OutputBytes::of_run(1000, 0.0, 0, 4e6);
        assert_eq!(hour.with_recordings(true), hour);
        assert_eq!(
            hour.with_recordings(false).total(),
            hour.imaging,
            "no recording counted"
        );
        assert_eq!(no_sensor.imaging, 0.0);
        assert_eq!(no_sensor.total(), 1000.0 * FSM_LOG_BYTES_PER_PERIOD);
    }
}
