//! Levenberg-Marquardt least squares on real residuals (the complex response's real and
//! imaginary parts), with the Jacobian by central differences and the parameters' covariance
//! from the Jacobian at the optimum.
//!
//! Each step solves `(J'J + lambda diag(J'J)) delta = -J'r` (Marquardt's scaling, so
//! parameters of different units step alike); a step that lowers the cost is taken and
//! `lambda` shrinks, one that does not is retried with `lambda` grown. The covariance is
//! `(J'J)^-1 s^2` with `s^2 = cost / (n - p)`, the residuals' own scatter (a model that misses
//! the data gets wider intervals), from the pseudo-inverse so a parameter the data does not
//! fix shows as a large variance instead of a failure.

use nalgebra::{DMatrix, DVector};

/// The residual function: `None` where the parameters are unusable (treated as an infinite
/// cost).
pub type Residuals<'a> = dyn Fn(&DVector<f64>) -> Option<DVector<f64>> + 'a;

/// The optimum and what it rests on.
#[derive(Debug, Clone, PartialEq)]
pub struct LeastSquares {
    /// The parameters at the optimum.
    pub params: DVector<f64>,
    /// The residuals there.
    pub residuals: DVector<f64>,
    /// `sum r^2` there.
    pub cost: f64,
    /// The parameters' covariance (`(J'J)^-1 s^2`).
    pub covariance: DMatrix<f64>,
    /// Steps taken.
    pub iterations: usize,
}

/// The largest number of Levenberg-Marquardt steps.
const MAX_ITERATIONS: usize = 500;

/// Minimises `sum r(p)^2` from `start`. `None` when the residuals are unusable at `start`.
#[must_use]
pub fn minimise(residuals: &Residuals<'_>, start: DVector<f64>) -> Option<LeastSquares> {
    let mut params = start;
    let mut r = residuals(&params)?;
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut jacobian = jacobian(residuals, &params, &r)?;
    while iterations < MAX_ITERATIONS && cost > 0.0 {
        iterations += 1;
        let jtj = jacobian.transpose() * &jacobian;
        let gradient = jacobian.transpose() * &r;
        let mut stepped = false;
        while lambda < 1e16 {
            let mut damped = jtj.clone();
            for i in 0..damped.nrows() {
                damped[(i, i)] += lambda * jtj[(i, i)].max(1e-300);
            }
            let Some(delta) = damped.cholesky().map(|c| c.solve(&(-&gradient))) else {
                lambda *= 4.0;
                continue;
            };
            let trial = &params + &delta;
            match residuals(&trial) {
                Some(trial_r) if trial_r.norm_squared() < cost => {
                    let trial_cost = trial_r.norm_squared();
                    let improvement = (cost - trial_cost) / cost;
                    params = trial;
                    r = trial_r;
                    cost = trial_cost;
                    lambda = (lambda * 0.3).max(1e-12);
                    stepped = improvement > 1e-15 && delta.norm() > 1e-15 * params.norm().max(1.0);
                    break;
                }
                _ => lambda *= 4.0,
            }
        }
        if !stepped {
            break;
        }
        jacobian = self::jacobian(residuals, &params, &r)?;
    }
    let jtj = jacobian.transpose() * &jacobian;
    let dof = (r.len() as f64 - params.len() as f64).max(1.0);
    let inverse = jtj
        .clone()
        .pseudo_inverse(1e-14 * jtj.norm())
        .unwrap_or_else(|_| DMatrix::from_element(jtj.nrows(), jtj.ncols(), f64::INFINITY));
    Some(LeastSquares {
        covariance: inverse * (cost / dof),
        params,
        residuals: r,
        cost,
        iterations,
    })
}

/// The Jacobian by central differences, each step relative to its parameter.
fn jacobian(
    residuals: &Residuals<'_>,
    params: &DVector<f64>,
    at: &DVector<f64>,
) -> Option<DMatrix<f64>> {
    let mut j = DMatrix::zeros(at.len(), params.len());
    for k in 0..params.len() {
        let h = 1e-6 * params[k].abs().max(1e-3);
        let mut up = params.clone();
        up[k] += h;
        let mut down = params.clone();
        down[k] -= h;
        let column = (residuals(&up)? - residuals(&down)?) / (2.0 * h);
        j.set_column(k, &column);
    }
    Some(j)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential_exactly_and_its_covariance_scales_with_the_noise() {
        // y = a exp(-b t) at 20 points: noise-free, the optimum is exact.
        let t: Vec<f64> = (0..20).map(|i| f64::from(i) * 0.1).collect();
        let (a, b) = (3.0, 1.7);
        let data: Vec<f64> = t.iter().map(|t| a * (-b * t).exp()).collect();
        let model = |noise: f64| {
            let data = data.clone();
            let t = t.clone();
            move |p: &DVector<f64>| -> Option<DVector<f64>> {
                Some(DVector::from_iterator(
                    t.len(),
                    t.iter().zip(&data).enumerate().map(|(i, (t, y))| {
                        let wiggle = if i % 2 == 0 { noise } else { -noise };
                        p[0] * (-p[1] * t).exp() - (y + wiggle)
                    }),
                ))
            }
        };
        let exact = minimise(&model(0.0), DVector::from_vec(vec![1.0, 0.5])).unwrap();
        assert!((exact.params[0] - a).abs() < 1e-9, "{:?}", exact.params);
        assert!((exact.params[1] - b).abs() < 1e-9, "{:?}", exact.params);
        let noisy = minimise(&model(0.01), DVector::from_vec(vec![1.0, 0.5])).unwrap();
        let quiet = minimise(&model(0.001), DVector::from_vec(vec![1.0, 0.5])).unwrap();
        let ratio = (noisy.covariance[(0, 0)] / quiet.covariance[(0, 0)]).sqrt();
        assert!((ratio - 10.0).abs() < 0.5, "sigma ratio {ratio}");
    }

    #[test]
    fn unusable_parameters_are_stepped_around() {
        // sqrt(p) - 2 = 0 from p = 9: steps that go negative are refused, p ends at 4.
        let residuals =
            |p: &DVector<f64>| (p[0] >= 0.0).then(|| DVector::from_vec(vec![p[0].sqrt() - 2.0]));
        let fit = minimise(&residuals, DVector::from_vec(vec![9.0])).unwrap();
        assert!((fit.params[0] - 4.0).abs() < 1e-8, "{:?}", fit.params);
    }
}
