//! Discretisation of continuous sections, one section at a time: Tustin (optionally prewarped),
//! zero-order hold, matched pole-zero, forward and backward Euler.

use nalgebra::{Complex, Matrix2, Matrix3};

use crate::continuous::{ContinuousSection, Quadratic};
use crate::sos::Section;

/// A discretisation method, as named in controller settings (`"method": "tustin"`, ...).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "method", rename_all = "snake_case", deny_unknown_fields)]
pub enum Method {
    /// Bilinear transform `s = (2/T)(z-1)/(z+1)`: stable for stable sections; warps frequency
    /// (`f_d = atan(pi f T)/(pi T)`).
    Tustin,
    /// Bilinear transform prewarped so that a named frequency maps exactly: each section uses
    /// the listed frequency closest (in log frequency) to its own poles.
    TustinPrewarped {
        /// The frequencies to keep exact, in Hz.
        prewarp_hz: Vec<f64>,
    },
    /// Zero-order hold (step invariant): exact poles `z = exp(s T)`.
    ZeroOrderHold,
    /// Matched pole-zero: poles and finite zeros mapped by `z = exp(s T)`, zeros at infinity
    /// to `z = -1`, gain matched at DC (or at 1 % of Nyquist when DC is a pole or zero).
    MatchedPoleZero,
    /// `s = (z-1)/T`: unstable for fast poles (`|1 + s T| > 1`); for comparison only.
    ForwardEuler,
    /// `s = (z-1)/(z T)`: always stable, damps lightly damped poles.
    BackwardEuler,
}

impl Method {
    /// A short name for reports.
    #[must_use]
    pub fn name(&self) -> String {
        match self {
            Method::Tustin => "tustin".into(),
            Method::TustinPrewarped { prewarp_hz } => format!(
                "tustin_prewarped({} Hz)",
                prewarp_hz
                    .iter()
                    .map(|f| format!("{f}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Method::ZeroOrderHold => "zero_order_hold".into(),
            Method::MatchedPoleZero => "matched_pole_zero".into(),
            Method::ForwardEuler => "forward_euler".into(),
            Method::BackwardEuler => "backward_euler".into(),
        }
    }

    /// Every method, with `prewarp_hz` for the prewarped Tustin.
    #[must_use]
    pub fn all(prewarp_hz: &[f64]) -> Vec<Method> {
        vec![
            Method::Tustin,
            Method::TustinPrewarped {
                prewarp_hz: prewarp_hz.to_vec(),
            },
            Method::ZeroOrderHold,
            Method::MatchedPoleZero,
            Method::ForwardEuler,
            Method::BackwardEuler,
        ]
    }
}

/// Discretises one continuous section with `method` at sampling period `period_s`.
#[must_use]
pub fn discretise(section: &ContinuousSection, method: &Method, period_s: f64) -> Section {
    let t = period_s;
    if section.order() == 0 {
        return Section::gain(section.num.s0 / section.den.s0);
    }
    match method {
        // s = (alpha z + beta) / (gamma z + delta)
        Method::Tustin => substitute(section, [2.0 / t, -2.0 / t, 1.0, 1.0]),
        Method::TustinPrewarped { prewarp_hz } => {
            let w0 = prewarp_for(section, prewarp_hz);
            let c = if w0 > 0.0 {
                w0 / (w0 * t / 2.0).tan()
            } else {
                2.0 / t
            };
            substitute(section, [c, -c, 1.0, 1.0])
        }
        Method::ForwardEuler => substitute(section, [1.0, -1.0, 0.0, t]),
        Method::BackwardEuler => substitute(section, [1.0, -1.0, t, 0.0]),
        Method::ZeroOrderHold => zero_order_hold(section, t),
        Method::MatchedPoleZero => matched_pole_zero(section, t),
    }
}

/// The prewarp frequency (rad/s) a section uses: the listed one closest to its poles.
fn prewarp_for(section: &ContinuousSection, prewarp_hz: &[f64]) -> f64 {
    let w_section = section.den.characteristic_rad_s();
    prewarp_hz
        .iter()
        .map(|f| std::f64::consts::TAU * f)
        .filter(|w| *w > 0.0)
        .min_by(|a, b| {
            let d = |w: f64| {
                if w_section > 0.0 {
                    (w / w_section).ln().abs()
                } else {
                    0.0
                }
            };
            d(*a).total_cmp(&d(*b))
        })
        .unwrap_or(0.0)
}

/// Polynomial coefficients, lowest power first.
type Poly = Vec<f64>;

fn poly_mul(p: &[f64], q: &[f64]) -> Poly {
    let mut out = vec![0.0; p.len() + q.len() - 1];
    for (i, a) in p.iter().enumerate() {
        for (j, b) in q.iter().enumerate() {
            out[i + j] += a * b;
        }
    }
    out
}

fn poly_pow(p: &[f64], n: usize) -> Poly {
    (0..n).fold(vec![1.0], |acc, _| poly_mul(&acc, p))
}

/// `q(s) (gamma z + delta)^n` with `s = (alpha z + beta)/(gamma z + delta)`, as a polynomial
/// in z (lowest power first, length n + 1).
fn map_polynomial(q: &Quadratic, n: usize, [alpha, beta, gamma, delta]: [f64; 4]) -> Poly {
    let num = [beta, alpha];
    let den = [delta, gamma];
    let mut out = vec![0.0; n + 1];
    for (i, c) in [q.s0, q.s1, q.s2].into_iter().enumerate().take(n + 1) {
        if c == 0.0 {
            continue;
        }
        let term = poly_mul(&poly_pow(&num, i), &poly_pow(&den, n - i));
        for (k, v) in term.into_iter().enumerate() {
            out[k] += c * v;
        }
    }
    out
}

/// A section from numerator and denominator polynomials in z (lowest power first, degree n).
fn section_from_z(num: &[f64], den: &[f64], n: usize) -> Section {
    let lead = den[n];
    // In z^-1: coefficient of z^(n-k) becomes that of z^-k.
    let b = |k: usize| if k <= n { num[n - k] / lead } else { 0.0 };
    let a = |k: usize| if k <= n { den[n - k] / lead } else { 0.0 };
    Section {
        b: [b(0), b(1), b(2)],
        a: [a(1), a(2)],
    }
}

fn substitute(section: &ContinuousSection, map: [f64; 4]) -> Section {
    let n = section.order();
    let num = map_polynomial(&section.num, n, map);
    let den = map_polynomial(&section.den, n, map);
    section_from_z(&num, &den, n)
}

/// Exact step-invariant discretisation through the matrix exponential of the section's
/// controllable canonical form.
fn zero_order_hold(section: &ContinuousSection, t: f64) -> Section {
    let (d2, d1, d0) = (section.den.s2, section.den.s1, section.den.s0);
    if section.order() == 1 {
        let (c0, m1, m0) = (d0 / d1, section.num.s1 / d1, section.num.s0 / d1);
        let (feed, r0) = (m1, m0 - m1 * c0);
        // x' = -c0 x + u: Ad = exp(-c0 T), Bd = (1 - Ad)/c0 (or T when c0 = 0).
        let ad = (-c0 * t).exp();
        let bd = if c0 == 0.0 {
            t
        } else {
            -(-c0 * t).exp_m1() / c0
        };
        return Section {
            b: [feed, r0 * bd - feed * ad, 0.0],
            a: [-ad, 0.0],
        };
    }
    let (c1, c0) = (d1 / d2, d0 / d2);
    let (m2, m1, m0) = (
        section.num.s2 / d2,
        section.num.s1 / d2,
        section.num.s0 / d2,
    );
    let feed = m2;
    let (r1, r0) = (m1 - m2 * c1, m0 - m2 * c0);
    let augmented = Matrix3::new(0.0, 1.0, 0.0, -c0, -c1, 1.0, 0.0, 0.0, 0.0) * t;
    let e = augmented.exp();
    let ad = Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]);
    let bd = nalgebra::Vector2::new(e[(0, 2)], e[(1, 2)]);
    let c = nalgebra::RowVector2::new(r0, r1);
    let (tr, det) = (ad.trace(), ad.determinant());
    let adj_const = Matrix2::new(-ad[(1, 1)], ad[(0, 1)], ad[(1, 0)], -ad[(0, 0)]);
    let cb = (c * bd)[0];
    let k0 = (c * adj_const * bd)[0];
    Section {
        b: [feed, cb - feed * tr, k0 + feed * det],
        a: [-tr, det],
    }
}

/// The zero-order-hold sampling of a strictly proper `section` whose held input steps arrive
/// `delay_s` late (`0 <= delay_s < period_s`): over `[kT, kT + d)` the input is still `u[k-1]`,
/// over `[kT + d, (k+1)T)` it is `u[k]`. Returns the section `S` with the sampled map
/// `y[k] = (z^-1 S) u[k]` (the modified z-transform); for `delay_s = 0` that is the plain
/// zero-order hold.
///
/// # Panics
/// If `section` is not strictly proper or the delay is outside `[0, period_s)` (caller bugs).
#[must_use]
pub fn zero_order_hold_delayed(
    section: &ContinuousSection,
    period_s: f64,
    delay_s: f64,
) -> Section {
    let n = section.order();
    assert!(
        (1..=2).contains(&n) && section.num.degree() < n,
        "delayed zero-order hold of a section that is not strictly proper"
    );
    assert!(
        (0.0..period_s).contains(&delay_s),
        "delay {delay_s} s outside [0, {period_s}) s"
    );
    let lead = if n == 2 {
        section.den.s2
    } else {
        section.den.s1
    };
    let (c0, c1) = (section.den.s0 / lead, section.den.s1 / lead);
    let (m1, m0) = (section.num.s1 / lead, section.num.s0 / lead);
    if n == 1 {
        // x' = -c0 x + u, y = m0 x.
        let held = |tau: f64| {
            if c0 == 0.0 {
                tau
            } else {
                -(-c0 * tau).exp_m1() / c0
            }
        };
        let late = (-c0 * (period_s - delay_s)).exp();
        return Section {
            b: [
                m0 * held(period_s - delay_s),
                m0 * late * held(delay_s),
                0.0,
            ],
            a: [-(-c0 * period_s).exp(), 0.0],
        };
    }
    // Controllable canonical form: x' = [0 1; -c0 -c1] x + [0; 1] u, y = [m0 m1] x.
    let hold = |tau: f64| {
        let e = (Matrix3::new(0.0, 1.0, 0.0, -c0, -c1, 1.0, 0.0, 0.0, 0.0) * tau).exp();
        (
            Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]),
            nalgebra::Vector2::new(e[(0, 2)], e[(1, 2)]),
        )
    };
    let (phi, _) = hold(period_s);
    let (late, gamma_late) = hold(period_s - delay_s);
    let gamma_early = late * hold(delay_s).1;
    let c = nalgebra::RowVector2::new(m0, m1);
    let adj_const = Matrix2::new(-phi[(1, 1)], phi[(0, 1)], phi[(1, 0)], -phi[(0, 0)]);
    // C adj(zI - Phi) g = z (C g) + C adj_const g, over det(zI - Phi) = z^2 - tr z + det.
    let (cg1, k1) = ((c * gamma_late)[0], (c * adj_const * gamma_late)[0]);
    let (cg0, k0) = ((c * gamma_early)[0], (c * adj_const * gamma_early)[0]);
    Section {
        b: [cg1, k1 + cg0, k0],
        a: [-phi.trace(), phi.determinant()],
    }
}

/// Monic polynomial in z (lowest power first) with the given roots (conjugate pairs whole).
fn monic_from_roots(roots: &[Complex<f64>]) -> Poly {
    let mut p = vec![1.0];
    let mut i = 0;
    while i < roots.len() {
        let r = roots[i];
        if r.im.abs() > 0.0 {
            p = poly_mul(&p, &[r.norm_sqr(), -2.0 * r.re, 1.0]);
            i += 2; // the conjugate follows its partner
        } else {
            p = poly_mul(&p, &[-r.re, 1.0]);
            i += 1;
        }
    }
    p
}

fn poly_eval(p: &[f64], z: Complex<f64>) -> Complex<f64> {
    p.iter()
        .rev()
        .fold(Complex::new(0.0, 0.0), |acc, c| acc * z + c)
}

fn matched_pole_zero(section: &ContinuousSection, t: f64) -> Section {
    let n = section.order();
    let map = |r: &Complex<f64>| (r * t).exp();
    let poles: Vec<Complex<f64>> = section.den.roots().iter().map(map).collect();
    let mut zeros: Vec<Complex<f64>> = section.num.roots().iter().map(map).collect();
    zeros.resize(n, Complex::new(-1.0, 0.0));
    let num = monic_from_roots(&zeros);
    let den = monic_from_roots(&poles);
    let dc_is_root = section.num.s0 == 0.0 || section.den.s0 == 0.0;
    let w_match = if dc_is_root {
        0.01 * std::f64::consts::PI / t
    } else {
        0.0
    };
    let continuous = section.eval(Complex::new(0.0, w_match));
    let z = Complex::from_polar(1.0, w_match * t);
    let discrete = poly_eval(&num, z) / poly_eval(&den, z);
    let ratio = continuous / discrete;
    let gain = ratio.norm() * ratio.re.signum();
    let scaled: Poly = num.iter().map(|c| c * gain).collect();
    section_from_z(&scaled, &den, n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sos::SectionState;

    const T: f64 = 50e-6;

    fn resonant() -> ContinuousSection {
        ContinuousSection {
            num: Quadratic::constant(140.68f64.powi(2)),
            den: Quadratic::second_order(140.68, 3.21e-2),
        }
    }

    #[test]
    fn every_method_keeps_the_dc_gain_of_a_resonance() {
        for method in Method::all(&[22.0]) {
            let d = discretise(&resonant(), &method, T);
            let dc = d.eval(Complex::new(1.0, 0.0));
            assert!((dc.re - 1.0).abs() < 1e-9, "{}: {dc}", method.name());
        }
    }

    #[test]
    fn zoh_and_matched_poles_are_exp_s_t() {
        let s_pole = resonant().den.roots()[0];
        let expected = (s_pole * T).exp();
        for method in [Method::ZeroOrderHold, Method::MatchedPoleZero] {
            let p = discretise(&resonant(), &method, T).poles();
            let best = p
                .iter()
                .map(|z| (z - expected).norm())
                .fold(f64::MAX, f64::min);
            assert!(best < 1e-12, "{}: {p:?}", method.name());
        }
    }

    #[test]
    fn zoh_step_response_samples_the_continuous_one() {
        // First order 1/(s + a): step response (1 - exp(-a t)) / a exactly at the samples.
        let a = 4.07e4;
        let section = ContinuousSection {
            num: Quadratic::constant(1.0),
            den: Quadratic::first_order(a),
        };
        let d = discretise(&section, &Method::ZeroOrderHold, T);
        let mut state = crate::sos::SectionState::default();
        for k in 0..10 {
            let y = d.step(&mut state, 1.0);
            let exact = (1.0 - (-a * T * k as f64).exp()) / a;
            assert!((y - exact).abs() < 1e-15, "k={k}: {y} vs {exact}");
        }
    }

    #[test]
    fn delayed_hold_without_delay_is_the_plain_hold() {
        for section in [
            resonant(),
            ContinuousSection {
                num: Quadratic::constant(3.0),
                den: Quadratic::first_order(4.07e4),
            },
        ] {
            let plain = discretise(&section, &Method::ZeroOrderHold, T);
            let delayed = zero_order_hold_delayed(&section, T, 0.0);
            // z^-1 S against the plain section (whose b0 is zero: strictly proper).
            assert_eq!(plain.b[0], 0.0);
            for (got, want) in [delayed.b[0], delayed.b[1], delayed.b[2]]
                .iter()
                .zip([plain.b[1], plain.b[2], 0.0])
            {
                assert!(
                    (got - want).abs() < 1e-15 * plain.b[1].abs().max(1.0),
                    "{delayed:?} {plain:?}"
                );
            }
            assert_eq!(delayed.a, plain.a);
        }
    }

    #[test]
    fn delayed_hold_samples_a_finely_held_input() {
        // A delay of 3 of 8 sub-periods is exactly a plain hold at T/8 fed the input a little
        // late: sample every eighth output of that.
        let (sub, late) = (8usize, 3usize);
        for section in [
            resonant(),
            ContinuousSection {
                num: Quadratic::constant(2.0e3),
                den: Quadratic::first_order(1.0e3),
            },
        ] {
            let fine = discretise(&section, &Method::ZeroOrderHold, T / sub as f64);
            let coarse = zero_order_hold_delayed(&section, T, late as f64 * T / sub as f64);
            let input: Vec<f64> = (0..40).map(|k| ((k * 7) % 5) as f64 - 2.0).collect();
            let (mut fine_state, mut coarse_state) =
                (SectionState::default(), SectionState::default());
            let (mut previous, mut fine_out) = (0.0, Vec::new());
            for &u in &input {
                for j in 0..sub {
                    let held = if j < late { previous } else { u };
                    let y = fine.step(&mut fine_state, held);
                    if j == 0 {
                        fine_out.push(y);
                    }
                }
                previous = u;
            }
            // y[k] = (z^-1 S) u: the coarse section's output one period later.
            let mut coarse_out = vec![0.0];
            coarse_out.extend(input.iter().map(|&u| coarse.step(&mut coarse_state, u)));
            for (k, (f, c)) in fine_out.iter().zip(&coarse_out).enumerate() {
                assert!(
                    (f - c).abs() < 1e-9 * (1.0 + f.abs()),
                    "k = {k}: {f} vs {c}"
                );
            }
        }
    }

    #[test]
    fn prewarped_tustin_is_exact_at_its_frequency() {
        let f = 52.0;
        let s = Complex::new(0.0, std::f64::consts::TAU * f);
        let z = Complex::from_polar(1.0, std::f64::consts::TAU * f * T);
        let section = ContinuousSection {
            num: Quadratic::first_order(300.0),
            den: Quadratic::second_order(327.0, 0.3),
        };
        let d = discretise(
            &section,
            &Method::TustinPrewarped {
                prewarp_hz: vec![27.0, f],
            },
            T,
        );
        assert!((d.eval(z) - section.eval(s)).norm() < 1e-9 * section.eval(s).norm());
        let plain = discretise(&section, &Method::Tustin, T);
        assert!((plain.eval(z) - section.eval(s)).norm() > 1e-7 * section.eval(s).norm());
    }

    #[test]
    fn forward_euler_puts_a_fast_pole_outside_the_unit_circle() {
        let section = ContinuousSection {
            num: Quadratic::constant(1.0),
            den: Quadratic::first_order(4.07e4),
        };
        let p = discretise(&section, &Method::ForwardEuler, T).poles();
        assert!((p[0].re - (1.0 - 4.07e4 * T)).abs() < 1e-12 && p[0].norm() > 1.0);
        let p = discretise(&section, &Method::BackwardEuler, T).poles();
        assert!((p[0].re - 1.0 / (1.0 + 4.07e4 * T)).abs() < 1e-12);
    }
}
