//! Scene files (`fixtures/scenes/*.json`): what is in front of the sensor, and which parts of
//! the plant are in play.
//!
//! A scene lists its active [`Part`]s; the plant builds and steps only those. Every section
//! other than `name` and `parts` is optional and defaults to the paper's values. A section
//! whose part is not listed is accepted and ignored, so a part is switched on or off by
//! editing `parts` alone. Relative file paths inside the scene (height maps) are resolved
//! against the scene file's directory ([`Scene::base_dir`]).

use std::fmt;
use std::path::{Path, PathBuf};

use scanhil_protocol::validation::Allowed;
use serde::{Deserialize, Serialize};

use crate::amplifier::AmplifierConfig;
use crate::angle_sensor::AngleSensorConfig;
use crate::cross_talk::CrossTalkConfig;
use crate::current_loop::CurrentLoopConfig;
use crate::integrator::IntegratorConfig;
use crate::mirror::MirrorConfig;
use crate::optics::receiver::{ReceiverOptics, Speckle, SurfaceFinish};
use crate::optics::{Optics, OpticsConfig, OpticsError, ReceiverModel};
use crate::power::PowerLimitConfig;
use crate::sensor::{Ild2300, SensorConfig, SensorError};
use scanhil_scene::json_file::{self, JsonFileError};
use scanhil_scene::surface::{Surface, SurfaceConfig, SurfaceError};

/// The paper's control rate, in Hz (Ta = 50 us).
pub const DEFAULT_CONTROL_RATE_HZ: f64 = 20_000.0;

/// A part of the plant a scene can switch on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    /// The mirror's mechanics (eq. 4) on the axes in `mirror.axes`.
    Axes,
    /// The mirror's second mechanical mode (`mirror.second_mode`).
    SecondMode,
    /// The coupling matrix between the sensing axes.
    CrossTalk,
    /// The angle sensor's pickup of the other axis's current: the cross-talk as a transfer
    /// function (`cross_talk.pickup_urad_per_a`).
    CrossTalkPickup,
    /// The current amplifiers: current limit and 10 kHz current loop.
    Amplifier,
    /// The amplifiers' PI current loop with the coil's R and L, back-EMF and the supply's
    /// voltage limit, in place of the first-order lag (`current_loop`).
    CurrentLoop,
    /// The coil power limit (clamp or fault).
    PowerLimit,
    /// The angle sensor's first-order bandwidth (`angle_sensor.bandwidth_hz`).
    AngleSensorBandwidth,
    /// The angle sensor's nonlinearity (`angle_sensor.nonlinearity_percent`).
    AngleSensorNonlinearity,
    /// Quantisation, noise and offset of the mirror angle sensor.
    AngleSensorNoise,
    /// Noise of the triangulation sensor.
    SensorNoise,
    /// The optical path from mirror angles to the spot on the surface.
    Optics,
    /// Blocking of the illumination and reflection paths.
    Shading,
    /// The ILD 2300 triangulation sensor on its own clock.
    Sensor,
    /// The light each spot sends the receiver (`surface_finish`): intensity-weighted spots
    /// and exposures, too dark and saturated spots refused.
    ReceiverIntensity,
    /// The surface's speckle moving the spot image's centroid (`surface_finish.roughness_um`).
    Speckle,
}

impl Part {
    /// Every part, in the order runs report them.
    pub const ALL: [Part; 16] = [
        Part::Axes,
        Part::SecondMode,
        Part::CrossTalk,
        Part::CrossTalkPickup,
        Part::Amplifier,
        Part::CurrentLoop,
        Part::PowerLimit,
        Part::AngleSensorBandwidth,
        Part::AngleSensorNonlinearity,
        Part::AngleSensorNoise,
        Part::SensorNoise,
        Part::Optics,
        Part::Shading,
        Part::Sensor,
        Part::ReceiverIntensity,
        Part::Speckle,
    ];

    /// The name used in scene files and output.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Part::Axes => "axes",
            Part::SecondMode => "second_mode",
            Part::CrossTalk => "cross_talk",
            Part::CrossTalkPickup => "cross_talk_pickup",
            Part::Amplifier => "amplifier",
            Part::CurrentLoop => "current_loop",
            Part::PowerLimit => "power_limit",
            Part::AngleSensorBandwidth => "angle_sensor_bandwidth",
            Part::AngleSensorNonlinearity => "angle_sensor_nonlinearity",
            Part::AngleSensorNoise => "angle_sensor_noise",
            Part::SensorNoise => "sensor_noise",
            Part::Optics => "optics",
            Part::Shading => "shading",
            Part::Sensor => "sensor",
            Part::ReceiverIntensity => "receiver_intensity",
            Part::Speckle => "speckle",
        }
    }

    /// Whether the part is a block of the linear drive model ([`crate::drive_model`]), the
    /// dynamics the integrators step.
    #[must_use]
    pub fn is_linear_drive(self) -> bool {
        matches!(
            self,
            Part::Axes
                | Part::SecondMode
                | Part::CrossTalk
                | Part::CrossTalkPickup
                | Part::Amplifier
                | Part::CurrentLoop
                | Part::AngleSensorBandwidth
        )
    }

    /// The part this one needs, if any.
    #[must_use]
    pub fn requires(self) -> Option<Part> {
        match self {
            Part::CrossTalk | Part::SecondMode | Part::AngleSensorBandwidth => Some(Part::Axes),
            Part::CrossTalkPickup => Some(Part::CrossTalk),
            Part::CurrentLoop => Some(Part::Amplifier),
            Part::Shading | Part::Sensor => Some(Part::Optics),
            Part::SensorNoise | Part::ReceiverIntensity | Part::Speckle => Some(Part::Sensor),
            _ => None,
        }
    }
}

impl fmt::Display for Part {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One scene file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// A short name, echoed by every run.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// The control rate (one plant step per period), in Hz.
    #[serde(default = "default_control_rate_hz")]
    pub control_rate_hz: f64,
    /// The seed every random part derives its stream from.
    #[serde(default)]
    pub seed: u64,
    /// The active parts; nothing else is built or stepped.
    pub parts: Vec<Part>,
    /// Eq. 4 parameters and moving axes (part `axes`).
    #[serde(default)]
    pub mirror: MirrorConfig,
    /// The integrator of the drive dynamics.
    #[serde(default)]
    pub integrator: IntegratorConfig,
    /// Coupling between the axes (part `cross_talk`).
    #[serde(default)]
    pub cross_talk: CrossTalkConfig,
    /// Current amplifiers (part `amplifier`).
    #[serde(default)]
    pub amplifier: AmplifierConfig,
    /// The amplifiers' current loop with the coil (part `current_loop`).
    #[serde(default)]
    pub current_loop: CurrentLoopConfig,
    /// Coil resistance and power limit (part `power_limit`; the resistance is also used for
    /// the power every step reports).
    #[serde(default)]
    pub power_limit: PowerLimitConfig,
    /// Mirror angle sensor imperfections (part `angle_sensor_noise`).
    #[serde(default)]
    pub angle_sensor: AngleSensorConfig,
    /// What is in front of the sensor (required with part `optics`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<SurfaceConfig>,
    /// The optical geometry (part `optics`; paper geometry when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub optics: Option<OpticsConfig>,
    /// The triangulation sensor (part `sensor`; ILD 2300-100 defaults when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<SensorConfig>,
    /// How the surface scatters the laser (parts `receiver_intensity` and `speckle`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface_finish: Option<SurfaceFinish>,
    /// The directory of the file the scene came from (not part of the JSON).
    #[serde(skip)]
    base_dir: Option<PathBuf>,
}

fn default_control_rate_hz() -> f64 {
    DEFAULT_CONTROL_RATE_HZ
}

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read, or its JSON is malformed or does not match the scene
    /// format (file, line and column).
    #[error(transparent)]
    File(#[from] JsonFileError),
    /// A field has a value the plant cannot use.
    #[error("scene {path}: field `{field}`: {reason}")]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// The field, as a dotted path.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

/// Why a scene's optical path could not be built.
#[derive(Debug, thiserror::Error)]
pub enum OpticalPathError {
    /// The scene has no `surface` section.
    #[error("the scene has no `surface`")]
    NoSurface,
    /// The surface could not be built (e.g. a height map file is unreadable).
    #[error("surface: {0}")]
    Surface(SurfaceError),
    /// The optics section is unusable.
    #[error("optics: {0}")]
    Optics(OpticsError),
}

/// The fastest a scene's plant may be stepped, Hz (ten megahertz: integrator studies step
/// the plant at MHz; beyond it the buffers sized in periods outgrow any memory).
pub const MAX_PLANT_RATE_HZ: f64 = 1e7;

/// The most samples a power window may hold (16 MB of them).
pub const MAX_POWER_WINDOW_SAMPLES: f64 = 2_097_152.0;

impl Scene {
    /// Reads, parses and validates a scene file.
    ///
    /// # Errors
    /// [`SceneError`] naming the file (and line and column for a parse error).
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::from_json_str(&json_file::read_text(path, "scene")?, path)
    }

    /// Parses and validates scene JSON; `origin` names it in errors and sets the base
    /// directory for relative paths.
    ///
    /// # Errors
    /// [`SceneError::File`] (parse) or [`SceneError::Invalid`].
    pub fn from_json_str(text: &str, origin: &Path) -> Result<Scene, SceneError> {
        let mut scene: Scene = json_file::parse(text, origin)?;
        scene.base_dir = origin.parent().map(Path::to_path_buf);
        scene
            .validate()
            .map_err(|(field, reason)| SceneError::Invalid {
                path: origin.to_path_buf(),
                field,
                reason,
            })?;
        Ok(scene)
    }

    /// Whether `part` is active.
    #[must_use]
    pub fn has(&self, part: Part) -> bool {
        self.parts.contains(&part)
    }

    /// The control period, in s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        1.0 / self.control_rate_hz
    }

    /// The directory the scene file is in, for relative paths inside it.
    #[must_use]
    pub fn base_dir(&self) -> Option<&Path> {
        self.base_dir.as_deref()
    }

    /// The coil resistance per actuator axis, in ohm: `power_limit.coil_resistance_ohm`, or
    /// derived from the mirror ([`crate::power::coil_resistance_ohm`]).
    #[must_use]
    pub fn coil_resistance_ohm(&self) -> f64 {
        self.power_limit
            .coil_resistance_ohm
            .unwrap_or_else(|| crate::power::coil_resistance_ohm(&self.mirror))
    }

    /// The scene's optical path: its surface under its optics, with shading and the receiver's
    /// intensity and speckle as its parts say (the part `optics` itself is not looked at).
    ///
    /// # Errors
    /// [`OpticalPathError`]: no surface, or the surface or optics fault.
    pub fn optical_path(&self) -> Result<Optics, OpticalPathError> {
        let config = self.surface.as_ref().ok_or(OpticalPathError::NoSurface)?;
        let base_dir = self.base_dir().unwrap_or(Path::new("."));
        let surface = Surface::from_config(config, base_dir).map_err(OpticalPathError::Surface)?;
        Ok(
            Optics::new(&self.optics.clone().unwrap_or_default(), surface)
                .map_err(OpticalPathError::Optics)?
                .with_shading(self.has(Part::Shading))
                .with_receiver(self.receiver_model()),
        )
    }

    /// The scene's triangulation sensor, with its noise and its receiver's limits as its parts
    /// say (the part `sensor` itself is not looked at).
    ///
    /// # Errors
    /// [`SensorError`] naming the bad field of the `sensor` section.
    pub fn triangulation_sensor(&self) -> Result<Ild2300, SensorError> {
        Ok(Ild2300::new(
            &self.sensor.unwrap_or_default(),
            self.seed,
            self.has(Part::SensorNoise),
        )?
        .with_intensity_limits(self.has(Part::ReceiverIntensity)))
    }

    /// What the receiver adds to the optics: the finish's intensities with
    /// `receiver_intensity`, its speckle with `speckle` (pattern drawn from the scene's seed,
    /// decorrelating over the spot's diameter).
    fn receiver_model(&self) -> ReceiverModel {
        let finish = self.surface_finish.unwrap_or_default();
        let sensor = self.sensor.unwrap_or_default();
        let spot_diameter_mm = self
            .optics
            .as_ref()
            .and_then(|optics| optics.spot)
            .map_or(crate::optics::DEFAULT_SPOT_DIAMETER_MM, |spot| {
                spot.diameter_mm
            });
        let receiver = ReceiverOptics {
            wavelength_nm: sensor.wavelength_nm,
            aperture_mm: sensor.receiver_aperture_mm,
        };
        ReceiverModel {
            intensity: self.has(Part::ReceiverIntensity).then_some(finish),
            speckle: self
                .has(Part::Speckle)
                .then(|| Speckle::new(&finish, &receiver, spot_diameter_mm, self.seed)),
        }
    }

    /// The active parts in the canonical order of [`Part::ALL`].
    #[must_use]
    pub fn active_parts(&self) -> Vec<Part> {
        Part::ALL.into_iter().filter(|p| self.has(*p)).collect()
    }

    /// Checks values and part dependencies; on failure, the field and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        // A plant may be stepped far faster than any loop runs (integrator studies at MHz).
        Allowed::above(0.0, MAX_PLANT_RATE_HZ, "Hz")
            .check("control_rate_hz", self.control_rate_hz)
            .map_err(|invalid| (invalid.field, invalid.reason))?;
        for (i, part) in self.parts.iter().enumerate() {
            if self.parts[..i].contains(part) {
                return Err(("parts".into(), format!("part `{part}` is listed twice")));
            }
            if let Some(needed) = part.requires()
                && !self.has(needed)
            {
                return Err((
                    "parts".into(),
                    format!("part `{part}` needs part `{needed}`, which is not listed"),
                ));
            }
        }
        if self.has(Part::Optics) && self.surface.is_none() {
            return Err((
                "surface".into(),
                "part `optics` needs a `surface` section".into(),
            ));
        }
        if self.integrator.substeps == 0 {
            return Err(("integrator.substeps".into(), "must be at least 1".into()));
        }
        self.mirror.validate(self.period_s())?;
        if self.has(Part::CrossTalk) {
            self.cross_talk.validate()?;
        }
        if self.has(Part::Amplifier) {
            self.amplifier.validate()?;
        }
        if self.has(Part::CurrentLoop) {
            self.current_loop.validate()?;
        }
        self.power_limit.validate()?;
        // The power window is held a sample a period (a scene at 2e25 Hz once asked for a
        // 1.6e14-byte window).
        let window_samples = self.power_limit.window_s * self.control_rate_hz;
        if self.has(Part::PowerLimit) && window_samples > MAX_POWER_WINDOW_SAMPLES {
            return Err((
                "power_limit.window_s".into(),
                format!(
                    "{} s at {} Hz is {window_samples:.3e} samples, more than the {:e} a \
                     window may hold",
                    self.power_limit.window_s, self.control_rate_hz, MAX_POWER_WINDOW_SAMPLES
                ),
            ));
        }
        if [
            Part::AngleSensorNoise,
            Part::AngleSensorBandwidth,
            Part::AngleSensorNonlinearity,
        ]
        .iter()
        .any(|part| self.has(*part))
        {
            self.angle_sensor.validate()?;
        }
        if self.has(Part::ReceiverIntensity) || self.has(Part::Speckle) {
            self.surface_finish.unwrap_or_default().validate()?;
        }
        Ok(())
    }
}
