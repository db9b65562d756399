//! Simulated imaging through the emulator's own optics and ILD 2300 model: the same surfaces,
//! shading and sensor (noise, 18-bit quantisation, error values) the plant uses, with ideal
//! tracking (the mirror is exactly where the trajectory says). For scoring against a known
//! surface without running the loop.

use std::path::Path;

use scanhil_emulator::optics::{OpticalOutcome, Optics};
use scanhil_emulator::scene::{OpticalPathError, Scene};
use scanhil_emulator::sensor::Ild2300;
use scanhil_protocol::ild::IldValue;
use scanhil_protocol::plant_units::SensingPair;

use scanhil_controller::imaging::progressive::ScanScene;
use scanhil_controller::imaging::reconstruct::ScanSample;

/// The emulator's optics as a scan scene (the sensor's noise and quantisation left out).
impl ScanScene for EmulatedScanner {
    fn z_meas_mm(&self, d_alpha_rad: f64, d_beta_rad: f64) -> Option<f64> {
        match self
            .optics
            .observe(SensingPair {
                alpha: d_alpha_rad,
                beta: d_beta_rad,
            })
            .outcome
        {
            OpticalOutcome::Distance { z_meas_mm, .. } => Some(z_meas_mm),
            OpticalOutcome::Miss | OpticalOutcome::Shaded(_) => None,
        }
    }

    fn true_z_mm(&self, x_mm: f64, y_mm: f64) -> Option<f64> {
        self.optics.surface().height_at(x_mm, y_mm)
    }
}

/// The optical and sensing half of a scene file.
#[derive(Debug, Clone)]
pub struct EmulatedScanner {
    /// Optics over the scene's surface, shading as the scene says.
    pub optics: Optics,
    /// The sensor (noise as the scene says).
    pub sensor: Ild2300,
}

/// Why a scene could not be used for simulated imaging.
#[derive(Debug, thiserror::Error)]
pub enum EmulatedError {
    /// The scene file could not be loaded.
    #[error(transparent)]
    Scene(#[from] scanhil_emulator::scene::SceneError),
    /// The scene has no surface to image.
    #[error("{path}: the scene has no `surface`")]
    NoSurface {
        /// The scene file.
        path: String,
    },
    /// A part could not be built.
    #[error("{path}: {part}: {reason}")]
    Part {
        /// The scene file.
        path: String,
        /// `surface`, `optics` or `sensor`.
        part: &'static str,
        /// What failed.
        reason: String,
    },
}

impl EmulatedScanner {
    /// The surface, optics and sensor of the scene file at `path` (defaults where the scene
    /// leaves a section out; shading and sensor noise only if the scene lists those parts).
    pub fn from_scene_file(path: &Path) -> Result<EmulatedScanner, EmulatedError> {
        let scene = Scene::load(path)?;
        let name = path.display().to_string();
        let part = |part: &'static str| {
            let name = name.clone();
            move |e: &dyn std::fmt::Display| EmulatedError::Part {
                path: name,
                part,
                reason: e.to_string(),
            }
        };
        let optics = scene.optical_path().map_err(|e| match e {
            OpticalPathError::NoSurface => EmulatedError::NoSurface { path: name.clone() },
            OpticalPathError::Surface(e) => part("surface")(&e),
            OpticalPathError::Optics(e) => part("optics")(&e),
        })?;
        let sensor = scene
            .triangulation_sensor()
            .map_err(|e| part("sensor")(&e))?;
        Ok(EmulatedScanner { optics, sensor })
    }

    /// The samples of an ideal-tracking scan over `[0, duration_s)` on the sensor's own clock:
    /// each sample's angles from `angles_rad(t) = (d_alpha, d_beta)`, its distance through
    /// the optics and the sensor, converted back to mm from the raw value as a recording
    /// would be (error values: missing).
    pub fn simulate_samples(
        &mut self,
        angles_rad: impl Fn(f64) -> (f64, f64),
        duration_s: f64,
    ) -> Vec<ScanSample> {
        let range = self.sensor.range();
        let instants: Vec<_> = self
            .sensor
            .sample_instants(-1e-12, duration_s)
            .take_while(|i| i.t_s < duration_s)
            .collect();
        instants
            .into_iter()
            .map(|instant| {
                let (d_alpha_rad, d_beta_rad) = angles_rad(instant.t_s);
                let reading = self.optics.observe(SensingPair {
                    alpha: d_alpha_rad,
                    beta: d_beta_rad,
                });
                let sample = self.sensor.measure(instant, &reading.outcome);
                let z_meas_mm = match sample.value {
                    IldValue::Distance(d) => range.digital_to_mm(d),
                    IldValue::Error(_) => None,
                };
                ScanSample {
                    t_s: sample.t_s,
                    d_alpha_rad,
                    d_beta_rad,
                    z_meas_mm,
                }
            })
            .collect()
    }
}
