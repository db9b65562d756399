//! Discrete second-order sections and their cascade, run in direct form II transposed (f64).

use nalgebra::{Complex, DMatrix};

use crate::continuous::quadratic_roots;

/// One discrete section `(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)`. First-order
/// sections have `b2 = a2 = 0`; a pure gain has `b1 = b2 = a1 = a2 = 0`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Section {
    /// Numerator coefficients `[b0, b1, b2]`.
    pub b: [f64; 3],
    /// Denominator coefficients `[a1, a2]` (`a0 = 1`).
    pub a: [f64; 2],
}

/// The state of one section in direct form II transposed.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SectionState {
    s1: f64,
    s2: f64,
}

impl Section {
    /// A constant gain.
    #[must_use]
    pub fn gain(k: f64) -> Self {
        Self {
            b: [k, 0.0, 0.0],
            a: [0.0, 0.0],
        }
    }

    /// A one-period delay `z^-1`.
    #[must_use]
    pub fn delay() -> Self {
        Self {
            b: [0.0, 1.0, 0.0],
            a: [0.0, 0.0],
        }
    }

    /// The number of state variables (0, 1 or 2).
    #[must_use]
    pub fn order(&self) -> usize {
        if self.a[1] != 0.0 || self.b[2] != 0.0 {
            2
        } else if self.a[0] != 0.0 || self.b[1] != 0.0 {
            1
        } else {
            0
        }
    }

    /// One sample through the section: returns the output and updates `state`.
    #[inline]
    pub fn step(&self, state: &mut SectionState, x: f64) -> f64 {
        let y = self.b[0] * x + state.s1;
        state.s1 = self.b[1] * x - self.a[0] * y + state.s2;
        state.s2 = self.b[2] * x - self.a[1] * y;
        y
    }

    /// The response at `z` (on the unit circle: `z = exp(j omega T)`).
    #[must_use]
    pub fn eval(&self, z: Complex<f64>) -> Complex<f64> {
        let zi = z.inv();
        let num = (zi * self.b[2] + self.b[1]) * zi + self.b[0];
        let den = (zi * self.a[1] + self.a[0]) * zi + 1.0;
        num / den
    }

    /// The poles in the z-plane (as many as the order).
    #[must_use]
    pub fn poles(&self) -> Vec<Complex<f64>> {
        match self.order() {
            2 => quadratic_roots(1.0, self.a[0], self.a[1]),
            1 => vec![Complex::new(-self.a[0], 0.0)],
            _ => Vec::new(),
        }
    }

    /// The finite zeros in the z-plane (a zero at infinity, i.e. a leading delay, is left out).
    #[must_use]
    pub fn zeros(&self) -> Vec<Complex<f64>> {
        // In z: b0 z^n + b1 z^(n-1) + ... ; roots of that polynomial of the section's order.
        match self.order() {
            2 => quadratic_roots(self.b[0], self.b[1], self.b[2]),
            1 => quadratic_roots(0.0, self.b[0], self.b[1]),
            _ => Vec::new(),
        }
    }

    /// The sum of two sections of order at most one, as one section of order at most two
    /// (used to join a PID's parallel paths).
    ///
    /// # Panics
    /// If either section is of second order (a caller bug).
    #[must_use]
    pub fn parallel_sum(&self, other: &Section) -> Section {
        assert!(
            self.order() <= 1 && other.order() <= 1,
            "parallel_sum of second-order sections"
        );
        let (p, q) = (self, other);
        Section {
            b: [
                p.b[0] + q.b[0],
                p.b[0] * q.a[0] + p.b[1] + q.b[0] * p.a[0] + q.b[1],
                p.b[1] * q.a[0] + q.b[1] * p.a[0],
            ],
            a: [p.a[0] + q.a[0], p.a[0] * q.a[0]],
        }
    }

    /// A state-space realisation `(A, B, C, D)` of the section, matching [`Section::step`]'s
    /// states.
    #[must_use]
    pub fn state_space(&self) -> StateSpace {
        let n = self.order();
        let mut sys = StateSpace::gain(self.b[0]);
        if n == 0 {
            return sys;
        }
        sys.a = DMatrix::zeros(n, n);
        sys.b = DMatrix::zeros(n, 1);
        sys.c = DMatrix::zeros(1, n);
        sys.c[(0, 0)] = 1.0;
        for i in 0..n {
            sys.a[(i, 0)] = -self.a[i];
            if i + 1 < n {
                sys.a[(i, i + 1)] = 1.0;
            }
            sys.b[(i, 0)] = self.b[i + 1] - self.a[i] * self.b[0];
        }
        sys
    }
}

/// A single-input single-output discrete state-space system `x' = A x + B u, y = C x + D u`.
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    /// State matrix (n x n).
    pub a: DMatrix<f64>,
    /// Input matrix (n x 1).
    pub b: DMatrix<f64>,
    /// Output matrix (1 x n).
    pub c: DMatrix<f64>,
    /// Feed-through (1 x 1).
    pub d: f64,
}

impl StateSpace {
    /// A stateless gain.
    #[must_use]
    pub fn gain(k: f64) -> Self {
        Self {
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, 1),
            c: DMatrix::zeros(1, 0),
            d: k,
        }
    }

    /// The number of states.
    #[must_use]
    pub fn order(&self) -> usize {
        self.a.nrows()
    }

    /// `next` after `self` (the output of `self` drives `next`).
    #[must_use]
    pub fn then(&self, next: &StateSpace) -> StateSpace {
        let (n1, n2) = (self.order(), next.order());
        let mut a = DMatrix::zeros(n1 + n2, n1 + n2);
        a.view_mut((0, 0), (n1, n1)).copy_from(&self.a);
        a.view_mut((n1, n1), (n2, n2)).copy_from(&next.a);
        a.view_mut((n1, 0), (n2, n1))
            .copy_from(&(&next.b * &self.c));
        let mut b = DMatrix::zeros(n1 + n2, 1);
        b.view_mut((0, 0), (n1, 1)).copy_from(&self.b);
        b.view_mut((n1, 0), (n2, 1)).copy_from(&(&next.b * self.d));
        let mut c = DMatrix::zeros(1, n1 + n2);
        c.view_mut((0, 0), (1, n1)).copy_from(&(&self.c * next.d));
        c.view_mut((0, n1), (1, n2)).copy_from(&next.c);
        StateSpace {
            a,
            b,
            c,
            d: self.d * next.d,
        }
    }

    /// The eigenvalues of `A` (the system's poles).
    #[must_use]
    pub fn poles(&self) -> Vec<Complex<f64>> {
        crate::eigen::eigenvalues(self.a.clone())
    }
}

/// A gain followed by second-order sections in series, with its run state.
#[derive(Debug, Clone, PartialEq)]
pub struct Cascade {
    gain: f64,
    sections: Vec<Section>,
    states: Vec<SectionState>,
}

impl Cascade {
    /// A cascade at rest.
    #[must_use]
    pub fn new(gain: f64, sections: Vec<Section>) -> Self {
        let states = vec![SectionState::default(); sections.len()];
        Self {
            gain,
            sections,
            states,
        }
    }

    /// The gain in front of the sections.
    #[must_use]
    pub fn gain(&self) -> f64 {
        self.gain
    }

    /// The sections, in signal order.
    #[must_use]
    pub fn sections(&self) -> &[Section] {
        &self.sections
    }

    /// One sample through the gain and every section.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        let mut v = self.gain * x;
        for (section, state) in self.sections.iter().zip(&mut self.states) {
            v = section.step(state, v);
        }
        v
    }

    /// Sets every state to zero.
    pub fn reset(&mut self) {
        self.states.fill(SectionState::default());
    }

    /// The response at frequency `f_hz` for sampling period `period_s`.
    #[must_use]
    pub fn response(&self, f_hz: f64, period_s: f64) -> Complex<f64> {
        let z = Complex::from_polar(1.0, std::f64::consts::TAU * f_hz * period_s);
        self.eval(z)
    }

    /// The response at `z`.
    #[must_use]
    pub fn eval(&self, z: Complex<f64>) -> Complex<f64> {
        self.sections
            .iter()
            .map(|s| s.eval(z))
            .product::<Complex<f64>>()
            * self.gain
    }

    /// Every section's poles, in section order.
    #[must_use]
    pub fn poles(&self) -> Vec<Complex<f64>> {
        self.sections.iter().flat_map(Section::poles).collect()
    }

    /// Every section's finite zeros, in section order.
    #[must_use]
    pub fn zeros(&self) -> Vec<Complex<f64>> {
        self.sections.iter().flat_map(Section::zeros).collect()
    }

    /// A state-space realisation of the whole cascade.
    #[must_use]
    pub fn state_space(&self) -> StateSpace {
        self.sections
            .iter()
            .fold(StateSpace::gain(self.gain), |sys, s| {
                sys.then(&s.state_space())
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_state_space(sys: &StateSpace, input: &[f64]) -> Vec<f64> {
        let mut x = DMatrix::zeros(sys.order(), 1);
        input
            .iter()
            .map(|&u| {
                let y = (&sys.c * &x)[(0, 0)] + sys.d * u;
                x = &sys.a * &x + &sys.b * u;
                y
            })
            .collect()
    }

    #[test]
    fn step_matches_state_space_and_response() {
        let mut cascade = Cascade::new(
            2.0,
            vec![
                Section {
                    b: [0.5, -0.2, 0.1],
                    a: [-1.2, 0.5],
                },
                Section {
                    b: [0.0, 1.0, 0.0],
                    a: [-0.3, 0.0],
                },
            ],
        );
        let input: Vec<f64> = (0..50).map(|k| ((k * 7) % 5) as f64 - 2.0).collect();
        let expected = run_state_space(&cascade.state_space(), &input);
        let got: Vec<f64> = input.iter().map(|&u| cascade.step(u)).collect();
        for (g, e) in got.iter().zip(&expected) {
            assert!((g - e).abs() < 1e-12, "{g} vs {e}");
        }
        // DC gain: 2 * (0.4 / 0.3) * (1 / 0.7).
        let dc = cascade.eval(Complex::new(1.0, 0.0));
        assert!((dc.re - 2.0 * 0.4 / 0.3 / 0.7).abs() < 1e-12);
        let mut poles: Vec<f64> = cascade
            .state_space()
            .poles()
            .iter()
            .map(|p| p.norm())
            .collect();
        poles.sort_by(f64::total_cmp);
        assert!((poles[0] - 0.3).abs() < 1e-12 && (poles[2] - 0.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn parallel_sum_adds_responses() {
        let p = Section {
            b: [0.3, 0.1, 0.0],
            a: [-0.5, 0.0],
        };
        let q = Section {
            b: [0.2, 0.2, 0.0],
            a: [-1.0, 0.0],
        };
        let z = Complex::from_polar(1.0, 0.3);
        assert!((p.parallel_sum(&q).eval(z) - (p.eval(z) + q.eval(z))).norm() < 1e-14);
    }
}
