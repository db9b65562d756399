//! What the sensor's receiver makes of a lit spot beyond where it is: how much light reaches
//! it (the spot's intensity) and the speckle error of the spot image's centroid.
//!
//! Two parts of a scene use it, each off unless listed (today's results unchanged without
//! them); the surface's finish is the scene's `surface_finish` section, the receiver's optics
//! fields of `sensor`:
//!
//! - **`receiver_intensity`**: each spot sample's light at the receiver, relative to a white
//!   matte surface facing the receiver at the middle of the range ([`intensity`]).
//!   A laser spot puts the beam's whole power on the surface whatever the incidence (the lit
//!   area grows as the irradiance falls), so the power reaching the lens is the surface's
//!   BRDF times `cos(view)` times the lens's solid angle: `I = pi BRDF cos(view) (L_ref/L)^2`.
//!   Matte share: `BRDF = reflectance / pi`. Gloss (optional): a Beckmann lobe of facet slopes
//!   with rms `tan(width)` around the half vector, `BRDF = share exp(-tan^2 h / m^2) /
//!   (pi m^2 cos^4 h 4 cos(inc) cos(view))`: a glint when the surface bisects the laser and
//!   the receiver. The spot's distance is then the intensity-weighted mean of its samples, an
//!   exposure's the intensity-weighted mean of its looks, and the sensor refuses a spot too
//!   dark or saturated ([`crate::sensor`]).
//! - **`speckle`**: a rough surface lit by a coherent laser images as a speckle pattern, and
//!   the centroid of the spot image moves with it. The uncertainty is Dorsch, Haeusler and
//!   Herrmann's (Applied Optics 33(7), 1994): `dz = C lambda / (2 pi sin(u) sin(theta))`,
//!   with `u` the receiver's aperture angle seen from the spot (`aperture / 2 / L`), `theta`
//!   the triangulation angle (laser to receiver path at the spot) and `C` the speckle
//!   contrast. `C` follows the surface's rms roughness `sigma`: the diffusely scattered share
//!   of the light is `1 - exp(-(4 pi sigma cos(inc) / lambda)^2)` (the total integrated
//!   scatter of a Gaussian surface), and `C` is its square root (fully developed speckle,
//!   `C = 1`, from about `sigma = lambda / 4`). The pattern belongs to the surface: it is the
//!   same wherever the same patch is lit and decorrelates as the spot moves by its own
//!   diameter. Here it is a fixed random field over the surface ([`speckle_field`]): unit rms
//!   Gaussian values on a cubic lattice of the spot's diameter, interpolated between.

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// The middle of the ILD 2300-100's range along the beam, mm: where `I = 1` for a white matte
/// surface facing the receiver.
pub const REFERENCE_DISTANCE_MM: f64 = 120.0;

fn default_reflectance() -> f64 {
    0.5
}
fn default_roughness_um() -> f64 {
    0.2
}

/// A gloss lobe on top of the matte reflectance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gloss {
    /// Share of the light reflected into the lobe (Fresnel's 0.04 for plastic at normal
    /// incidence), in [0, 1].
    pub share: f64,
    /// The lobe's width: rms angle of the surface's facets, degrees, in (0, 45].
    pub width_deg: f64,
}

/// The scene's `surface_finish` section: how the surface scatters the laser.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceFinish {
    /// Matte (Lambertian) reflectance, in [0, 1] (default 0.5: a coloured plastic).
    #[serde(default = "default_reflectance")]
    pub reflectance: f64,
    /// Rms height roughness, um (default 0.2: a moulded plastic face); sets the speckle
    /// contrast.
    #[serde(default = "default_roughness_um")]
    pub roughness_um: f64,
    /// A gloss lobe (absent: matte only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gloss: Option<Gloss>,
}

impl Default for SurfaceFinish {
    fn default() -> Self {
        SurfaceFinish {
            reflectance: default_reflectance(),
            roughness_um: default_roughness_um(),
            gloss: None,
        }
    }
}

impl SurfaceFinish {
    /// Checks every field; on failure, the field (`surface_finish.*`) and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let bad = |field: &str, value: f64, requirement: &str| {
            Err((
                format!("surface_finish.{field}"),
                format!("{value} must be {requirement}"),
            ))
        };
        if !(0.0..=1.0).contains(&self.reflectance) {
            return bad("reflectance", self.reflectance, "in [0, 1]");
        }
        if !(self.roughness_um.is_finite() && self.roughness_um >= 0.0) {
            return bad("roughness_um", self.roughness_um, "finite and >= 0");
        }
        if let Some(gloss) = self.gloss {
            if !(0.0..=1.0).contains(&gloss.share) {
                return bad("gloss.share", gloss.share, "in [0, 1]");
            }
            if !(gloss.width_deg > 0.0 && gloss.width_deg <= 45.0) {
                return bad("gloss.width_deg", gloss.width_deg, "in (0, 45] degrees");
            }
        }
        Ok(())
    }
}

/// The receiver's optics, as the sensor section gives them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReceiverOptics {
    /// The laser's wavelength, nm.
    pub wavelength_nm: f64,
    /// The receiving lens's clear aperture, mm.
    pub aperture_mm: f64,
}

/// The speckle of one surface under one receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Speckle {
    /// The laser's wavelength, mm.
    wavelength_mm: f64,
    /// Half the receiving lens's aperture, mm.
    half_aperture_mm: f64,
    /// The surface's rms roughness, mm.
    roughness_mm: f64,
    /// The lattice pitch of the field: the spot's diameter, mm.
    pitch_mm: f64,
    seed: u64,
}

impl Speckle {
    /// The speckle of `finish` seen by `receiver`, decorrelating over `spot_diameter_mm`, its
    /// pattern drawn from `seed`.
    #[must_use]
    pub fn new(
        finish: &SurfaceFinish,
        receiver: &ReceiverOptics,
        spot_diameter_mm: f64,
        seed: u64,
    ) -> Speckle {
        Speckle {
            wavelength_mm: receiver.wavelength_nm * 1e-6,
            half_aperture_mm: receiver.aperture_mm / 2.0,
            roughness_mm: finish.roughness_um * 1e-3,
            pitch_mm: spot_diameter_mm,
            seed,
        }
    }

    /// The speckle contrast for light arriving at `cos_incidence` to the normal.
    #[must_use]
    pub fn contrast(&self, cos_incidence: f64) -> f64 {
        let phase_rms =
            4.0 * std::f64::consts::PI * self.roughness_mm * cos_incidence / self.wavelength_mm;
        (-(-phase_rms * phase_rms).exp_m1()).sqrt()
    }

    /// The rms centroid error, mm, for a spot `distance_mm` from the receiver with the
    /// triangulation angle's sine `sin_triangulation` and the laser at `cos_incidence`.
    #[must_use]
    pub fn rms_mm(&self, distance_mm: f64, sin_triangulation: f64, cos_incidence: f64) -> f64 {
        let sin_aperture = self.half_aperture_mm / self.half_aperture_mm.hypot(distance_mm);
        self.contrast(cos_incidence) * self.wavelength_mm
            / (2.0 * std::f64::consts::PI * sin_aperture * sin_triangulation.max(1e-3))
    }

    /// The centroid error of a spot at `point_mm`, mm: [`Speckle::rms_mm`] times the surface's
    /// speckle field there.
    #[must_use]
    pub fn error_mm(
        &self,
        point_mm: &Point3<f64>,
        distance_mm: f64,
        sin_triangulation: f64,
        cos_incidence: f64,
    ) -> f64 {
        self.rms_mm(distance_mm, sin_triangulation, cos_incidence)
            * speckle_field(self.seed, point_mm, self.pitch_mm)
    }
}

/// The relative intensity at the receiver of light from a spot with unit normal `normal`, lit
/// along `to_laser` (unit, from the spot back towards the laser) and seen along
/// `to_receiver` (unit), `distance_mm` from the receiver. 0 for a spot facing away.
#[must_use]
pub fn intensity(
    finish: &SurfaceFinish,
    normal: &Vector3<f64>,
    to_laser: &Vector3<f64>,
    to_receiver: &Vector3<f64>,
    distance_mm: f64,
) -> f64 {
    let cos_view = normal.dot(to_receiver);
    let cos_incidence = normal.dot(to_laser);
    if cos_view <= 0.0 || cos_incidence <= 0.0 || distance_mm.is_nan() || distance_mm <= 0.0 {
        return 0.0;
    }
    let mut pi_brdf = finish.reflectance;
    if let Some(gloss) = finish.gloss {
        let m = gloss.width_deg.to_radians().tan();
        let Some(half) = (to_laser + to_receiver).try_normalize(1e-12) else {
            return 0.0;
        };
        let cos_h = normal.dot(&half).max(1e-9);
        let tan2_h = (1.0 - cos_h * cos_h).max(0.0) / (cos_h * cos_h);
        pi_brdf += gloss.share * (-tan2_h / (m * m)).exp()
            / (m * m * cos_h.powi(4) * 4.0 * cos_incidence * cos_view);
    }
    let near = REFERENCE_DISTANCE_MM / distance_mm;
    pi_brdf * cos_view * near * near
}

/// The surface's speckle pattern at `point_mm`: a fixed random field of unit rms, correlated
/// over `pitch_mm`. Gaussian values drawn from `seed` at the corners of a cubic lattice of
/// that pitch, interpolated smoothly (smoothstep weights) within each cell and scaled back
/// to unit rms.
#[must_use]
pub fn speckle_field(seed: u64, point_mm: &Point3<f64>, pitch_mm: f64) -> f64 {
    let scaled = point_mm.coords / pitch_mm;
    if !scaled.iter().all(|v| v.is_finite() && v.abs() < 1e15) {
        return 0.0;
    }
    let cell = scaled.map(f64::floor);
    let frac = scaled - cell;
    let weight = |t: f64, corner: i64| {
        let s = t * t * (3.0 - 2.0 * t);
        if corner == 0 { 1.0 - s } else { s }
    };
    let mut sum = 0.0;
    let mut sum_w2 = 0.0;
    for corner in 0..8i64 {
        let c = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
        let w = weight(frac.x, c[0]) * weight(frac.y, c[1]) * weight(frac.z, c[2]);
        let index = [
            cell.x as i64 + c[0],
            cell.y as i64 + c[1],
            cell.z as i64 + c[2],
        ];
        sum += w * lattice_gaussian(seed, index);
        sum_w2 += w * w;
    }
    // Each point's value is a weighted sum of independent unit Gaussians: dividing by the
    // weights' norm keeps it unit rms everywhere (not only on average over the cell).
    sum / sum_w2.sqrt()
}

/// A standard Gaussian value for one lattice corner, the same for the same seed and corner.
fn lattice_gaussian(seed: u64, index: [i64; 3]) -> f64 {
    let mut h = seed ^ 0x005E_C1E5_EC1E;
    for i in index {
        h = splitmix64(h ^ (i as u64));
    }
    let u1 = ((h >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = ((splitmix64(h) >> 11) as f64) / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// One step of the SplitMix64 generator: a well-mixed 64-bit hash of `x`.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn receiver() -> ReceiverOptics {
        ReceiverOptics {
            wavelength_nm: 670.0,
            aperture_mm: 12.0,
        }
    }

    #[test]
    fn a_white_matte_surface_facing_the_receiver_at_mid_range_is_the_reference() {
        let white = SurfaceFinish {
            reflectance: 1.0,
            ..SurfaceFinish::default()
        };
        let up = Vector3::z();
        assert!((intensity(&white, &up, &up, &up, REFERENCE_DISTANCE_MM) - 1.0).abs() < 1e-15);
        // Inverse square in distance, cosine in viewing angle, none in incidence.
        let tilted = Vector3::new(0.0, 0.6, 0.8);
        let i = intensity(&white, &up, &tilted, &tilted, 2.0 * REFERENCE_DISTANCE_MM);
        assert!((i - 0.8 / 4.0).abs() < 1e-15, "{i}");
        let half = SurfaceFinish {
            reflectance: 0.5,
            ..white
        };
        let lit_obliquely = intensity(&half, &up, &tilted, &up, REFERENCE_DISTANCE_MM);
        assert!((lit_obliquely - 0.5).abs() < 1e-15);
        // Facing away from either: dark.
        assert_eq!(intensity(&white, &up, &-up, &up, 100.0), 0.0);
        assert_eq!(intensity(&white, &up, &up, &-up, 100.0), 0.0);
        // No distance, no light.
        assert_eq!(intensity(&white, &up, &up, &up, 0.0), 0.0);
        assert_eq!(intensity(&white, &up, &up, &up, f64::NAN), 0.0);
    }

    #[test]
    fn a_gloss_lobe_glints_where_the_surface_bisects_laser_and_receiver() {
        let glossy = SurfaceFinish {
            reflectance: 0.0,
            roughness_um: 0.2,
            gloss: Some(Gloss {
                share: 0.04,
                width_deg: 3.0,
            }),
        };
        let up = Vector3::z();
        // Laser and receiver symmetric about the normal, 8 degrees each side: the half vector
        // is the normal, the lobe's peak: share / (4 m^2 cos(inc)) (cos h = 1).
        let (s, c) = 8f64.to_radians().sin_cos();
        let (laser, seen) = (Vector3::new(0.0, s, c), Vector3::new(0.0, -s, c));
        let m = 3f64.to_radians().tan();
        let peak = intensity(&glossy, &up, &laser, &seen, REFERENCE_DISTANCE_MM);
        assert!((peak - 0.04 / (4.0 * m * m * c)).abs() < 1e-12, "{peak}");
        // Laser and receiver on the same side: the half vector 8 deg off the normal, nearly
        // nothing (exp(-tan^2(8 deg) / m^2)).
        let aside = intensity(&glossy, &up, &laser, &laser, REFERENCE_DISTANCE_MM);
        let h = 8f64.to_radians();
        let expected = 0.04 * (-(h.tan() / m).powi(2)).exp() / (m * m * h.cos().powi(4) * 4.0 * c);
        assert!(
            (aside - expected).abs() < 1e-15 && aside < 1e-3 * peak,
            "{aside}"
        );
    }

    #[test]
    fn speckle_contrast_grows_with_roughness_and_saturates_at_one() {
        let speckle = |roughness_um| {
            Speckle::new(
                &SurfaceFinish {
                    roughness_um,
                    ..SurfaceFinish::default()
                },
                &receiver(),
                0.13,
                1,
            )
        };
        assert_eq!(speckle(0.0).contrast(1.0), 0.0);
        // sigma = lambda / (4 pi): phase rms 1 rad, contrast sqrt(1 - 1/e).
        let one_radian = speckle(0.670 / (4.0 * std::f64::consts::PI));
        assert!((one_radian.contrast(1.0) - (1.0 - (-1.0f64).exp()).sqrt()).abs() < 1e-12);
        // Light arriving obliquely sees the heights foreshortened: half the phase at 60 deg.
        assert!((one_radian.contrast(0.5) - (1.0 - (-0.25f64).exp()).sqrt()).abs() < 1e-12);
        assert!((speckle(1.0).contrast(1.0) - 1.0).abs() < 1e-12);
        // Dorsch et al.'s uncertainty: lambda / (2 pi sin u sin theta) at C = 1.
        let rough = speckle(5.0);
        let (distance, sin_theta) = (140.0, 0.3);
        let sin_u = 6.0 / 6f64.hypot(distance);
        let expected = 670e-6 / (2.0 * std::f64::consts::PI * sin_u * sin_theta);
        assert!((rough.rms_mm(distance, sin_theta, 1.0) - expected).abs() < 1e-12);
        assert!((0.005..0.02).contains(&expected), "{expected} mm");
    }

    #[test]
    fn the_speckle_field_is_fixed_unit_rms_and_decorrelates_over_its_pitch() {
        let pitch = 0.13;
        let at = |x: f64, y: f64| speckle_field(3, &Point3::new(x, y, -130.0), pitch);
        // Fixed: the same point gives the same value; another seed another pattern.
        assert_eq!(at(1.234, -5.6), at(1.234, -5.6));
        assert_ne!(
            speckle_field(4, &Point3::new(1.234, -5.6, -130.0), pitch),
            at(1.234, -5.6)
        );
        let n = 20_000;
        let points: Vec<(f64, f64)> = (0..n)
            .map(|k| (f64::from(k % 200) * 0.37, f64::from(k / 200) * 0.41))
            .collect();
        let values: Vec<f64> = points.iter().map(|&(x, y)| at(x, y)).collect();
        let mean = values.iter().sum::<f64>() / f64::from(n);
        let rms = (values.iter().map(|v| v * v).sum::<f64>() / f64::from(n)).sqrt();
        assert!(
            mean.abs() < 0.03 && (rms - 1.0).abs() < 0.03,
            "{mean} {rms}"
        );
        // Correlation with a point a tenth of the pitch away: high; two pitches away: none.
        let correlation = |dx: f64| {
            points
                .iter()
                .map(|&(x, y)| at(x, y) * at(x + dx, y))
                .sum::<f64>()
                / f64::from(n)
        };
        assert!(
            correlation(0.1 * pitch) > 0.9,
            "{}",
            correlation(0.1 * pitch)
        );
        assert!(
            correlation(2.0 * pitch).abs() < 0.05,
            "{}",
            correlation(2.0 * pitch)
        );
        // Never NaN, even far away or at non-finite points; beyond 1e15 pitches, none.
        assert_eq!(
            speckle_field(1, &Point3::new(f64::NAN, 0.0, 0.0), pitch),
            0.0
        );
        assert!(speckle_field(1, &Point3::new(1e12, -1e12, 3.0), pitch).is_finite());
        assert_eq!(speckle_field(1, &Point3::new(0.0, 1e15, 0.0), 0.5), 0.0);
        // Seeds differing in any low bit give other patterns.
        let pattern = |seed| speckle_field(seed, &Point3::new(0.37, 0.41, -130.0), pitch);
        assert!(pattern(0) != pattern(1) && pattern(0) != pattern(2) && pattern(1) != pattern(2));
    }

    #[test]
    fn the_speckle_field_interpolates_its_lattice_values_at_unit_variance() {
        let (seed, pitch) = (9, 0.5);
        let g = |i: i64, j: i64, k: i64| lattice_gaussian(seed, [i, j, k]);
        let at = |x: f64, y: f64, z: f64| speckle_field(seed, &Point3::new(x, y, z), pitch);
        // On a lattice corner: that corner's value.
        assert_eq!(at(1.0, -1.5, 2.0), g(2, -3, 4));
        // A quarter of the way along x: smoothstep weights 1 - s and s, s = 5/32, normalised.
        let s = 5.0 / 32.0;
        let expected =
            ((1.0 - s) * g(2, -3, 4) + s * g(3, -3, 4)) / ((1.0 - s).powi(2) + s * s).sqrt();
        assert!((at(1.125, -1.5, 2.0) - expected).abs() < 1e-12);
        // A cell's centre: the mean of its eight corners times sqrt(8).
        let corners: f64 = (0..8)
            .map(|c| g(2 + (c & 1), -3 + ((c >> 1) & 1), 4 + ((c >> 2) & 1)))
            .sum();
        assert!((at(1.25, -1.25, 2.25) - corners / 8f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn lattice_values_are_independent_standard_gaussians() {
        let values: Vec<f64> = (0..40_000i64)
            .map(|k| lattice_gaussian(3, [k % 200, k / 200, -7]))
            .collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let rms = (values.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
        let within = |sigmas: f64| values.iter().filter(|v| v.abs() < sigmas).count() as f64 / n;
        assert!(
            mean.abs() < 0.02 && (rms - 1.0).abs() < 0.02,
            "{mean} {rms}"
        );
        assert!((within(1.0) - 0.6827).abs() < 0.01, "{}", within(1.0));
        assert!((within(2.0) - 0.9545).abs() < 0.005, "{}", within(2.0));
        let neighbours = values.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / n;
        assert!(neighbours.abs() < 0.02, "{neighbours}");
    }

    #[test]
    fn splitmix64_is_the_reference_generator() {
        // SplitMix64 seeded with 0 (Steele, Lea and Flood; the sequence Java's
        // SplittableRandom and Vigna's reference code give): state k * gamma, mixed.
        let gamma = 0x9E37_79B9_7F4A_7C15u64;
        assert_eq!(splitmix64(0), 0xE220_A839_7B1D_CDAF);
        assert_eq!(splitmix64(gamma), 0x6E78_9E6A_A1B9_65F4);
        assert_eq!(splitmix64(gamma.wrapping_mul(2)), 0x06C4_5D18_8009_454F);
    }

    #[test]
    fn a_finish_out_of_its_domain_is_refused_naming_the_field() {
        for (finish, field) in [
            (
                SurfaceFinish {
                    reflectance: 1.5,
                    ..SurfaceFinish::default()
                },
                "surface_finish.reflectance",
            ),
            (
                SurfaceFinish {
                    roughness_um: f64::NAN,
                    ..SurfaceFinish::default()
                },
                "surface_finish.roughness_um",
            ),
            (
                SurfaceFinish {
                    gloss: Some(Gloss {
                        share: 0.04,
                        width_deg: 0.0,
                    }),
                    ..SurfaceFinish::default()
                },
                "surface_finish.gloss.width_deg",
            ),
            (
                SurfaceFinish {
                    gloss: Some(Gloss {
                        share: -0.1,
                        width_deg: 3.0,
                    }),
                    ..SurfaceFinish::default()
                },
                "surface_finish.gloss.share",
            ),
            (
                SurfaceFinish {
                    roughness_um: -1.0,
                    ..SurfaceFinish::default()
                },
                "surface_finish.roughness_um",
            ),
            (
                SurfaceFinish {
                    gloss: Some(Gloss {
                        share: 0.04,
                        width_deg: 46.0,
                    }),
                    ..SurfaceFinish::default()
                },
                "surface_finish.gloss.width_deg",
            ),
        ] {
            assert_eq!(finish.validate().unwrap_err().0, field);
        }
        let glossy = SurfaceFinish {
            gloss: Some(Gloss {
                share: 0.04,
                width_deg: 45.0,
            }),
            ..SurfaceFinish::default()
        };
        assert!(glossy.validate().is_ok());
        assert!(SurfaceFinish::default().validate().is_ok());
    }

    #[test]
    fn a_finish_left_out_is_a_matte_plastic_face() {
        let finish: SurfaceFinish = serde_json::from_str("{}").unwrap();
        assert_eq!(finish, SurfaceFinish::default());
        assert_eq!(
            (finish.reflectance, finish.roughness_um, finish.gloss),
            (0.5, 0.2, None)
        );
    }
}
