//! Eigenvalues of a real square matrix after balancing.
//!
//! A loop's state matrix mixes entries of very different sizes when a gain is extreme (a PID
//! with `kp = 1e200` puts 1e200 beside the plant's 1e-5): the QR iteration on the matrix as it
//! stands then converges to poles that are wrong by hundreds of orders of magnitude (the
//! largest came out at |z| 2.0 where it is 5.3e97). Balancing first (Parlett and Reinsch, as
//! LAPACK's `dgebal` scales) makes each row's and column's off-diagonal norms comparable by a
//! diagonal similarity `D^-1 A D` with powers of two, which changes no eigenvalue and loses no
//! bit, so the iteration sees a matrix it can solve.

use nalgebra::{Complex, DMatrix};

/// Powers of this radix scale the rows and columns: exact in binary floating point.
const RADIX: f64 = 2.0;

/// At most this many sweeps over the rows (each sweep scales by at most the matrix's dynamic
/// range; 2^11 sweeps would span every finite f64).
const MAX_SWEEPS: usize = 64;

/// The eigenvalues of `a`, balanced first ([`balance`]). A matrix with a non-finite entry
/// is not balanced (its eigenvalues are not numbers either way).
#[must_use]
pub fn eigenvalues(mut a: DMatrix<f64>) -> Vec<Complex<f64>> {
    if a.nrows() == 0 {
        return Vec::new();
    }
    if a.iter().all(|v| v.is_finite()) {
        balance(&mut a);
    }
    a.complex_eigenvalues().iter().copied().collect()
}

/// Balances `a` in place by a diagonal similarity of powers of two: afterwards no
/// row's off-diagonal sum differs from its column's by much more than the radix, and the
/// eigenvalues are those of the `a` given. Entries must be finite.
pub fn balance(a: &mut DMatrix<f64>) {
    let n = a.nrows();
    for _ in 0..MAX_SWEEPS {
        let mut converged = true;
        for i in 0..n {
            let (mut column, mut row) = (0.0, 0.0);
            for j in (0..n).filter(|&j| j != i) {
                column += a[(j, i)].abs();
                row += a[(i, j)].abs();
            }
            if column == 0.0 || row == 0.0 {
                continue;
            }
            let sum = column + row;
            let mut factor = 1.0;
            while column < row / RADIX {
                factor *= RADIX;
                column *= RADIX * RADIX;
            }
            while column > row * RADIX {
                factor /= RADIX;
                column /= RADIX * RADIX;
            }
            if (column + row) / factor < 0.95 * sum {
                converged = false;
                a.row_mut(i).scale_mut(1.0 / factor);
                a.column_mut(i).scale_mut(factor);
            }
        }
        if converged {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The roots of `z^2 - t z + d` (trace t, determinant d), computed without cancellation.
    fn quadratic_roots(t: f64, d: f64) -> [Complex<f64>; 2] {
        let disc = t * t / 4.0 - d;
        if disc >= 0.0 {
            let big = t / 2.0 + t.signum() * disc.sqrt();
            [Complex::new(big, 0.0), Complex::new(d / big, 0.0)]
        } else {
            let im = (-disc).sqrt();
            [Complex::new(t / 2.0, im), Complex::new(t / 2.0, -im)]
        }
    }

    fn sorted(mut z: Vec<Complex<f64>>) -> Vec<Complex<f64>> {
        z.sort_by(|a, b| (a.re, a.im).partial_cmp(&(b.re, b.im)).unwrap());
        z
    }

    #[test]
    fn a_badly_scaled_matrix_keeps_its_eigenvalues_and_gets_comparable_norms() {
        // D^-1 A D of a well-scaled A with D = diag(1, 2^-300): the same eigenvalues.
        let scale = 2f64.powi(-300);
        let a = DMatrix::from_row_slice(2, 2, &[1.0, 3.0 * scale, -2.0 / scale, 0.5]);
        let mut balanced = a.clone();
        balance(&mut balanced);
        let off = |m: &DMatrix<f64>| (m[(0, 1)].abs(), m[(1, 0)].abs());
        let (upper, lower) = off(&balanced);
        assert!(upper / lower < 4.0 && lower / upper < 4.0, "{balanced}");
        assert_eq!(balanced[(0, 0)], 1.0);
        assert_eq!(balanced[(1, 1)], 0.5);
        // Trace 1.5, determinant 0.5 + 6 = 6.5.
        let expected = quadratic_roots(1.5, 6.5);
        let found = sorted(eigenvalues(a));
        for (got, want) in found.iter().zip(sorted(expected.to_vec())) {
            assert!((got - want).norm() < 1e-12 * want.norm(), "{got} vs {want}");
        }
    }

    #[test]
    fn huge_gains_give_the_poles_of_the_characteristic_polynomial() {
        // A companion-like loop matrix with a 1e200 entry: z^2 - t z + d with t = 4.8 and
        // d = 1e200 * 2.78e-5: poles 2.4 +- 5.27e97 j.
        let k = 1e200;
        let a = DMatrix::from_row_slice(2, 2, &[2.4, k, -2.78e-5, 2.4]);
        let d = 2.4 * 2.4 + k * 2.78e-5;
        let expected = sorted(quadratic_roots(4.8, d).to_vec());
        let found = sorted(eigenvalues(a));
        for (got, want) in found.iter().zip(&expected) {
            assert!(
                (got.im - want.im).abs() < 1e-9 * want.im.abs(),
                "{got} vs {want}"
            );
            assert!((got.re - want.re).abs() < 1e-6, "{got} vs {want}");
        }
    }

    #[test]
    fn a_matrix_already_balanced_or_with_a_zero_row_is_left_as_it_is() {
        let a = DMatrix::from_row_slice(3, 3, &[1.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 3.0]);
        let mut b = a.clone();
        balance(&mut b);
        assert_eq!(a, b);
    }

    #[test]
    fn non_finite_entries_and_the_empty_matrix_do_not_hang() {
        let a = DMatrix::from_row_slice(2, 2, &[f64::INFINITY, 1.0, 1.0, 0.0]);
        assert_eq!(eigenvalues(a).len(), 2);
        assert!(eigenvalues(DMatrix::zeros(0, 0)).is_empty());
    }
}
