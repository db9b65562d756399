//! Continuous-time transfer functions kept as factors, and their grouping into second-order
//! sections: the form controllers are designed in (eq. 4, eq. 5, Table II) before discretisation.

use nalgebra::Complex;

/// A polynomial in `s` of degree at most two: `s2 s^2 + s1 s + s0`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Quadratic {
    /// Coefficient of `s^2`.
    pub s2: f64,
    /// Coefficient of `s`.
    pub s1: f64,
    /// Constant coefficient.
    pub s0: f64,
}

impl Quadratic {
    /// The constant polynomial `c`.
    #[must_use]
    pub fn constant(c: f64) -> Self {
        Self {
            s2: 0.0,
            s1: 0.0,
            s0: c,
        }
    }

    /// `s + corner_rad_s` (a real root at `-corner_rad_s`; a negative corner is a right half
    /// plane root).
    #[must_use]
    pub fn first_order(corner_rad_s: f64) -> Self {
        Self {
            s2: 0.0,
            s1: 1.0,
            s0: corner_rad_s,
        }
    }

    /// `s`: a root at the origin (an integrator when it is a pole).
    #[must_use]
    pub fn integrator() -> Self {
        Self::first_order(0.0)
    }

    /// `s^2 + 2 damping natural_rad_s s + natural_rad_s^2`.
    #[must_use]
    pub fn second_order(natural_rad_s: f64, damping: f64) -> Self {
        Self {
            s2: 1.0,
            s1: 2.0 * damping * natural_rad_s,
            s0: natural_rad_s * natural_rad_s,
        }
    }

    /// The degree (0, 1 or 2) of the polynomial.
    #[must_use]
    pub fn degree(&self) -> usize {
        if self.s2 != 0.0 {
            2
        } else if self.s1 != 0.0 {
            1
        } else {
            0
        }
    }

    /// The product of two polynomials whose degrees add up to at most two.
    ///
    /// # Panics
    /// If the product would have degree three or more (a caller bug: sections are grouped
    /// by degree before they are multiplied).
    #[must_use]
    pub fn times(&self, other: &Quadratic) -> Quadratic {
        assert!(
            self.degree() + other.degree() <= 2,
            "product of degree {} and {} does not fit a section",
            self.degree(),
            other.degree()
        );
        Quadratic {
            s2: self.s2 * other.s0 + self.s1 * other.s1 + self.s0 * other.s2,
            s1: self.s1 * other.s0 + self.s0 * other.s1,
            s0: self.s0 * other.s0,
        }
    }

    /// The value at the complex frequency `s`.
    #[must_use]
    pub fn eval(&self, s: Complex<f64>) -> Complex<f64> {
        (s * self.s2 + self.s1) * s + self.s0
    }

    /// The roots (none, one or a pair), computed without cancellation.
    #[must_use]
    pub fn roots(&self) -> Vec<Complex<f64>> {
        quadratic_roots(self.s2, self.s1, self.s0)
    }

    /// A frequency that characterises the factor, for pairing poles with zeros: the magnitude
    /// of its roots (geometric mean), or zero for a constant or a root at the origin.
    #[must_use]
    pub fn characteristic_rad_s(&self) -> f64 {
        match self.degree() {
            2 => (self.s0 / self.s2).abs().sqrt(),
            1 => (self.s0 / self.s1).abs(),
            _ => 0.0,
        }
    }
}

/// Roots of `a x^2 + b x + c` (degree taken from the leading non-zero coefficient), with the
/// numerically stable form of the quadratic formula.
#[must_use]
pub fn quadratic_roots(a: f64, b: f64, c: f64) -> Vec<Complex<f64>> {
    if a == 0.0 {
        if b == 0.0 {
            return Vec::new();
        }
        return vec![Complex::new(-c / b, 0.0)];
    }
    let disc = b * b - 4.0 * a * c;
    if disc >= 0.0 {
        let q = -0.5 * (b + b.signum() * disc.sqrt());
        if q == 0.0 {
            return vec![Complex::new(0.0, 0.0); 2];
        }
        let (r1, r2) = (q / a, c / q);
        vec![Complex::new(r1, 0.0), Complex::new(r2, 0.0)]
    } else {
        let re = -b / (2.0 * a);
        let im = (-disc).sqrt() / (2.0 * a.abs());
        vec![Complex::new(re, im), Complex::new(re, -im)]
    }
}

/// One continuous second-order section `num(s) / den(s)`, proper (`deg num <= deg den`,
/// `deg den` 1 or 2, or 0 for a pure gain).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ContinuousSection {
    /// Numerator polynomial.
    pub num: Quadratic,
    /// Denominator polynomial.
    pub den: Quadratic,
}

impl ContinuousSection {
    /// The section's order (degree of its denominator).
    #[must_use]
    pub fn order(&self) -> usize {
        self.den.degree()
    }

    /// The frequency response at `s`.
    #[must_use]
    pub fn eval(&self, s: Complex<f64>) -> Complex<f64> {
        self.num.eval(s) / self.den.eval(s)
    }
}

/// A continuous transfer function as a gain times products of factors:
/// `gain * prod(zeros) / prod(poles)`.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FactoredTf {
    /// The constant in front.
    pub gain: f64,
    /// Numerator factors, each of degree 1 or 2.
    pub zeros: Vec<Quadratic>,
    /// Denominator factors, each of degree 1 or 2.
    pub poles: Vec<Quadratic>,
}

/// Why factors could not be grouped into proper second-order sections.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("transfer function is improper: {zeros} zeros against {poles} poles")]
pub struct ImproperError {
    /// Total numerator degree.
    pub zeros: usize,
    /// Total denominator degree.
    pub poles: usize,
}

impl FactoredTf {
    /// The frequency response at `s`.
    #[must_use]
    pub fn eval(&self, s: Complex<f64>) -> Complex<f64> {
        let num: Complex<f64> = self.zeros.iter().map(|q| q.eval(s)).product();
        let den: Complex<f64> = self.poles.iter().map(|q| q.eval(s)).product();
        num / den * self.gain
    }

    /// Groups the factors into proper second-order sections (the gain stays separate).
    ///
    /// Pole factors are taken most lightly damped first (complex pairs, then real poles paired
    /// two by two); each takes the unassigned zero factor closest to it in log frequency that
    /// fits, so resonant poles sit with their neighbouring zeros, as in zpk-to-sos designs.
    /// Real zeros left over are paired into quadratics before they are placed.
    pub fn sections(&self) -> Result<Vec<ContinuousSection>, ImproperError> {
        let degree = |fs: &[Quadratic]| fs.iter().map(Quadratic::degree).sum::<usize>();
        let (nz, np) = (degree(&self.zeros), degree(&self.poles));
        if nz > np {
            return Err(ImproperError {
                zeros: nz,
                poles: np,
            });
        }
        let mut pole_groups = pair_first_order(&self.poles);
        pole_groups.sort_by(|a, b| damping_key(a).total_cmp(&damping_key(b)));
        let mut zero_items = pair_first_order(&self.zeros);
        let mut sections: Vec<ContinuousSection> = pole_groups
            .iter()
            .map(|&den| ContinuousSection {
                num: Quadratic::constant(1.0),
                den,
            })
            .collect();
        // Place the zero items with the largest degree first, each into the fitting section
        // closest in log frequency.
        zero_items.sort_by_key(|z| std::cmp::Reverse(z.degree()));
        for zero in zero_items {
            let free = |s: &ContinuousSection| s.den.degree() - s.num.degree();
            let best = sections
                .iter_mut()
                .filter(|s| free(s) >= zero.degree())
                .min_by(|a, b| log_distance(&a.den, &zero).total_cmp(&log_distance(&b.den, &zero)));
            match best {
                Some(section) => section.num = section.num.times(&zero),
                None => {
                    return Err(ImproperError {
                        zeros: nz,
                        poles: np,
                    });
                }
            }
        }
        Ok(sections)
    }
}

/// Keeps quadratics, pairs first-order factors two by two (in order of their corner).
fn pair_first_order(factors: &[Quadratic]) -> Vec<Quadratic> {
    let mut out: Vec<Quadratic> = factors
        .iter()
        .filter(|f| f.degree() == 2)
        .copied()
        .collect();
    let mut firsts: Vec<Quadratic> = factors
        .iter()
        .filter(|f| f.degree() == 1)
        .copied()
        .collect();
    firsts.sort_by(|a, b| {
        a.characteristic_rad_s()
            .total_cmp(&b.characteristic_rad_s())
    });
    for pair in firsts.chunks(2) {
        out.push(match pair {
            [a, b] => a.times(b),
            [a] => *a,
            _ => unreachable!("chunks(2) yields one or two"),
        });
    }
    out
}

/// Sort key: lightly damped complex pairs first, real factors last.
fn damping_key(q: &Quadratic) -> f64 {
    if q.degree() == 2 && q.s1 * q.s1 < 4.0 * q.s0 * q.s2 {
        q.s1 / (2.0 * (q.s0 * q.s2).sqrt())
    } else {
        f64::INFINITY
    }
}

fn log_distance(a: &Quadratic, b: &Quadratic) -> f64 {
    let (wa, wb) = (a.characteristic_rad_s(), b.characteristic_rad_s());
    if wa == 0.0 || wb == 0.0 {
        return if wa == wb { 0.0 } else { f64::MAX / 2.0 };
    }
    (wa / wb).ln().abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_roots_are_accurate_for_spread_roots() {
        // (s + 1.26e6)(s - 7.87): roots 20 octaves apart.
        let q = Quadratic::first_order(1.26e6).times(&Quadratic::first_order(-7.87));
        let mut r: Vec<f64> = q.roots().iter().map(|c| c.re).collect();
        r.sort_by(f64::total_cmp);
        assert!(
            (r[0] + 1.26e6).abs() < 1e-6 && (r[1] - 7.87).abs() < 1e-12,
            "{r:?}"
        );
    }

    #[test]
    fn sections_keep_the_response_and_are_proper() {
        let tf = FactoredTf {
            gain: 3.0,
            zeros: vec![
                Quadratic::first_order(5.0),
                Quadratic::second_order(100.0, 0.1),
            ],
            poles: vec![
                Quadratic::integrator(),
                Quadratic::first_order(1e3),
                Quadratic::second_order(90.0, 0.01),
            ],
        };
        let sections = tf.sections().unwrap();
        assert_eq!(sections.len(), 2);
        assert!(sections.iter().all(|s| s.num.degree() <= s.den.degree()));
        let s = Complex::new(0.0, 37.0);
        let product: Complex<f64> =
            sections.iter().map(|x| x.eval(s)).product::<Complex<f64>>() * 3.0;
        assert!((product - tf.eval(s)).norm() < 1e-12 * tf.eval(s).norm());
        // The resonant pole pair gets the resonant zero pair next to it.
        assert_eq!(sections[0].den, Quadratic::second_order(90.0, 0.01));
        assert_eq!(sections[0].num, Quadratic::second_order(100.0, 0.1));
    }

    #[test]
    fn improper_factors_are_refused() {
        let tf = FactoredTf {
            gain: 1.0,
            zeros: vec![Quadratic::second_order(1.0, 0.5)],
            poles: vec![Quadratic::first_order(1.0)],
        };
        assert_eq!(tf.sections().unwrap_err().zeros, 2);
    }
}
