//! The dual-tone controller of eq. 5 with Table I's coefficients, as continuous factors:
//! `k (s + waz1)(s + waz2) / (s + wap1) * prod_i(s^2 + 2 zbz_i wbz_i s + wbz_i^2) /
//! prod_i(s^2 + 2 zbp_i wbp_i s + wbp_i^2)`. The right half plane zeros (waz2 < 0,
//! zbz1 < 0) are kept as printed.

use scanhil_protocol::validation::Allowed;

use crate::continuous::{FactoredTf, Quadratic};

/// The largest |frequency| of a factor, rad/s (16 MHz, far beyond any loop's Nyquist).
pub const MAX_FREQ_RAD_S: f64 = 1e8;

/// The largest |damping ratio| of a quadratic factor.
pub const MAX_DAMPING: f64 = 1e3;

/// The largest |k|.
pub const MAX_GAIN: f64 = 1e12;

/// Eq. 5's coefficients (Table I), and optionally the tone poles moved to exact frequencies.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DualToneParams {
    /// The gain k (179.75).
    pub k: f64,
    /// Real zeros' corners waz_i, rad/s (`s + waz`; negative is a right half plane zero).
    pub waz_rad_s: Vec<f64>,
    /// Real poles' corners wap_i, rad/s.
    pub wap_rad_s: Vec<f64>,
    /// Complex zero pairs' damping ratios zbz_i.
    pub zeta_bz: Vec<f64>,
    /// Complex zero pairs' natural frequencies wbz_i, rad/s.
    pub wbz_rad_s: Vec<f64>,
    /// Complex pole pairs' damping ratios zbp_i.
    pub zeta_bp: Vec<f64>,
    /// Complex pole pairs' natural frequencies wbp_i, rad/s.
    pub wbp_rad_s: Vec<f64>,
    /// When set, the most lightly damped pole pairs (one per entry) are moved to exactly
    /// `2 pi f` for these frequencies (Table I's 170/327 rad/s are 27.056/52.044 Hz).
    #[serde(default)]
    pub tone_poles_at_hz: Option<Vec<f64>>,
}

impl DualToneParams {
    /// Table I as printed.
    #[must_use]
    pub fn paper() -> Self {
        Self {
            k: 179.75,
            waz_rad_s: vec![1.26e6, -7.87],
            wap_rad_s: vec![4.07e4],
            zeta_bz: vec![-2.65e-3, 2.55e-2],
            wbz_rad_s: vec![2.35e2, 1.41e2],
            zeta_bp: vec![6.67e-1, 1.00e-4, 9.96e-5],
            wbp_rad_s: vec![1.13e4, 3.27e2, 1.70e2],
            tone_poles_at_hz: None,
        }
    }

    /// Checks that paired lists have equal lengths; names the offending field.
    pub fn check(&self) -> Result<(), (String, String)> {
        if self.zeta_bz.len() != self.wbz_rad_s.len() {
            return Err(("zeta_bz".into(), "needs one entry per wbz_rad_s".into()));
        }
        if self.zeta_bp.len() != self.wbp_rad_s.len() {
            return Err(("zeta_bp".into(), "needs one entry per wbp_rad_s".into()));
        }
        // Values a discretisation can take: a damping of 1e95 once overflowed the section's
        // matrix to NaN, on which the matrix exponential never finished.
        let frequency = Allowed::closed(-MAX_FREQ_RAD_S, MAX_FREQ_RAD_S, "rad/s");
        let damping = Allowed::closed(-MAX_DAMPING, MAX_DAMPING, "");
        for (field, allowed, values) in [
            ("waz_rad_s", frequency, &self.waz_rad_s),
            ("wap_rad_s", frequency, &self.wap_rad_s),
            ("wbz_rad_s", frequency, &self.wbz_rad_s),
            ("wbp_rad_s", frequency, &self.wbp_rad_s),
            ("zeta_bz", damping, &self.zeta_bz),
            ("zeta_bp", damping, &self.zeta_bp),
        ] {
            for (i, value) in values.iter().enumerate() {
                allowed
                    .check(field, *value)
                    .map_err(|invalid| (format!("{field}[{i}]"), invalid.reason))?;
            }
        }
        Allowed::closed(-MAX_GAIN, MAX_GAIN, "")
            .check("k", self.k)
            .map_err(|invalid| (invalid.field, invalid.reason))?;
        for (i, f_hz) in self.tone_poles_at_hz.iter().flatten().enumerate() {
            Allowed::above(0.0, MAX_FREQ_RAD_S / std::f64::consts::TAU, "Hz")
                .check("tone_poles_at_hz", *f_hz)
                .map_err(|invalid| (format!("tone_poles_at_hz[{i}]"), invalid.reason))?;
        }
        let tones = self.tone_poles_at_hz.as_ref().map_or(0, Vec::len);
        if tones > self.wbp_rad_s.len() {
            return Err((
                "tone_poles_at_hz".into(),
                format!("{tones} tones but only {} pole pairs", self.wbp_rad_s.len()),
            ));
        }
        Ok(())
    }

    /// The tone pole pairs' natural frequencies actually used (after `tone_poles_at_hz`).
    #[must_use]
    pub fn pole_frequencies_rad_s(&self) -> Vec<f64> {
        let mut w = self.wbp_rad_s.clone();
        if let Some(tones) = &self.tone_poles_at_hz {
            let mut by_damping: Vec<usize> = (0..w.len()).collect();
            by_damping.sort_by(|&a, &b| self.zeta_bp[a].abs().total_cmp(&self.zeta_bp[b].abs()));
            let mut lightest: Vec<usize> = by_damping.into_iter().take(tones.len()).collect();
            lightest.sort_by(|&a, &b| w[a].total_cmp(&w[b]));
            let mut sorted_tones = tones.clone();
            sorted_tones.sort_by(f64::total_cmp);
            for (i, f) in lightest.into_iter().zip(sorted_tones) {
                w[i] = std::f64::consts::TAU * f;
            }
        }
        w
    }

    /// The continuous controller as factors.
    #[must_use]
    pub fn continuous(&self) -> FactoredTf {
        let mut zeros: Vec<Quadratic> = self
            .waz_rad_s
            .iter()
            .map(|&w| Quadratic::first_order(w))
            .collect();
        zeros.extend(
            self.wbz_rad_s
                .iter()
                .zip(&self.zeta_bz)
                .map(|(&w, &z)| Quadratic::second_order(w, z)),
        );
        let mut poles: Vec<Quadratic> = self
            .wap_rad_s
            .iter()
            .map(|&w| Quadratic::first_order(w))
            .collect();
        poles.extend(
            self.pole_frequencies_rad_s()
                .iter()
                .zip(&self.zeta_bp)
                .map(|(&w, &z)| Quadratic::second_order(w, z)),
        );
        FactoredTf {
            gain: self.k,
            zeros,
            poles,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_no_discretisation_can_take_are_refused_naming_the_entry() {
        // A damping of 1e95 once overflowed the section's matrix to NaN, and the zero-order
        // hold's matrix exponential of it never finished (found by AFL++).
        let field = |edit: fn(&mut DualToneParams)| {
            let mut params = DualToneParams::paper();
            edit(&mut params);
            params.check().err().map(|(field, _)| field)
        };
        assert_eq!(field(|_| {}), None);
        assert_eq!(
            field(|p| p.zeta_bp[2] = 9.96e95).as_deref(),
            Some("zeta_bp[2]")
        );
        assert_eq!(
            field(|p| p.zeta_bz[0] = f64::NAN).as_deref(),
            Some("zeta_bz[0]")
        );
        assert_eq!(
            field(|p| p.wbp_rad_s[1] = 1e9).as_deref(),
            Some("wbp_rad_s[1]")
        );
        assert_eq!(
            field(|p| p.waz_rad_s[0] = -1e9).as_deref(),
            Some("waz_rad_s[0]")
        );
        assert_eq!(
            field(|p| p.wap_rad_s[0] = f64::INFINITY).as_deref(),
            Some("wap_rad_s[0]")
        );
        assert_eq!(
            field(|p| p.wbz_rad_s[0] = 2e8).as_deref(),
            Some("wbz_rad_s[0]")
        );
        assert_eq!(field(|p| p.k = 1e13).as_deref(), Some("k"));
        assert_eq!(
            field(|p| p.tone_poles_at_hz = Some(vec![52.0, 0.0])).as_deref(),
            Some("tone_poles_at_hz[1]")
        );
        // A tone's limit is the factors' 1e8 rad/s in Hz (15.9 MHz).
        assert_eq!(
            field(|p| p.tone_poles_at_hz = Some(vec![1.6e7])).as_deref(),
            Some("tone_poles_at_hz[0]")
        );
        assert_eq!(field(|p| p.tone_poles_at_hz = Some(vec![1.59e7])), None);
        // The limits themselves are taken.
        assert_eq!(
            field(|p| {
                p.zeta_bp[0] = MAX_DAMPING;
                p.wbp_rad_s[0] = -MAX_FREQ_RAD_S;
                p.k = MAX_GAIN;
            }),
            None
        );
    }
}
