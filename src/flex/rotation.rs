//! The rotation of a node of a flexible body by its rotation vector
//! ρ = Φʳ η (docs/flexible.md, "The model"): Rot = exp(\[ρ\]×), the right
//! Jacobian J_r that maps ρ̇ to the node's angular velocity in its own axes,
//! and J_r's rate along a motion, for the velocity-product terms.
//!
//! With θ = |ρ| and s = θ²:
//!
//!   Rot = 1 + c\[ρ\]× + a\[ρ\]×²,   J_r = 1 − a\[ρ\]× + b\[ρ\]×²,
//!   c = sin θ / θ,  a = (1 − cos θ)/θ²,  b = (θ − sin θ)/θ³,
//!
//! each a function of s, smooth through s = 0 (their Taylor series there:
//! the closed forms lose every digit to cancellation as θ → 0). Generic
//! over the scalar, so that the passes in dual numbers differentiate them.

use crate::math::{Mat3, Real, Vec3, skew};

/// Below this θ² the series are used: their first omitted term is below
/// 1e-19 there, while the closed forms of da/ds and db/ds still lose 1e-11
/// to cancellation at θ² = 1e-2.
const SERIES_BELOW: f64 = 1.0;

/// Terms of each series (to s⁹).
const SERIES_TERMS: usize = 10;

/// c, a, b and their derivatives da/ds, db/ds, at s = θ².
fn coefficients<S: Real>(s: S) -> [S; 5] {
    if s.value() < SERIES_BELOW {
        // Σ (−s)^k / (2k+1)!, Σ (−s)^k / (2k+2)!, Σ (−s)^k / (2k+3)!.
        let series = |first: u32| {
            let terms: [f64; SERIES_TERMS] = std::array::from_fn(|k| {
                let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                sign / (1..=first + 2 * k as u32).map(f64::from).product::<f64>()
            });
            let value = terms.iter().rev().fold(S::zero(), |sum, &t| sum * s + t);
            let slope = terms.iter().enumerate().skip(1).rev().fold(S::zero(), |sum, (k, &t)| sum * s + t * k as f64);
            (value, slope)
        };
        let ((c, _), (a, da), (b, db)) = (series(1), series(2), series(3));
        return [c, a, b, da, db];
    }
    let theta = s.sqrt();
    let (sin, cos) = theta.sin_cos();
    let c = sin / theta;
    let a = (S::one() - cos) / s;
    let b = (theta - sin) / (s * theta);
    // d/ds = (1/2θ) d/dθ.
    let da = (theta * sin - (S::one() - cos) * 2.0) / (s * s * 2.0);
    let db = (theta * (S::one() - cos) - (theta - sin) * 3.0) / (s * s * theta * 2.0);
    [c, a, b, da, db]
}

/// exp(\[ρ\]×).
pub fn rotation<S: Real>(rho: &Vec3<S>) -> Mat3<S> {
    let [c, a, ..] = coefficients(rho.norm_squared());
    let k = skew(rho);
    Mat3::identity() + k * c + k * k * a
}

/// J_r(ρ): the angular velocity, in the rotated axes, of exp([ρ(t)]×) is J_r ρ̇.
pub fn right_jacobian<S: Real>(rho: &Vec3<S>) -> Mat3<S> {
    let [_, a, b, ..] = coefficients(rho.norm_squared());
    let k = skew(rho);
    Mat3::identity() - k * a + k * k * b
}

/// dJ_r/dt along ρ̇.
pub fn right_jacobian_rate<S: Real>(rho: &Vec3<S>, rho_rate: &Vec3<S>) -> Mat3<S> {
    let [_, a, b, da, db] = coefficients(rho.norm_squared());
    let s_rate = rho.dot(rho_rate) * 2.0;
    let (k, k_rate) = (skew(rho), skew(rho_rate));
    k * -(da * s_rate) - k_rate * a + k * k * (db * s_rate) + (k_rate * k + k * k_rate) * b
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    fn vectors() -> Vec<Vec3> {
        // Through the series' range, its edge and beyond.
        let mut out = vec![Vec3::new(1e-9, -2e-9, 5e-10), Vec3::new(0.003, -0.02, 0.01), Vec3::new(0.06, 0.05, -0.04)];
        out.extend([0.0999, 0.5, 0.9999, 1.0001, 2.0, 3.0].map(|t: f64| Vec3::new(0.6, -0.48, 0.64) * t));
        out
    }

    #[test]
    fn the_rotation_is_nalgebras_exponential() {
        for rho in vectors() {
            let error = (rotation(&rho) - Rotation3::new(rho).into_inner()).norm();
            assert!(error < 2e-16 * 4.0, "{rho:?}: {error:e}");
        }
    }

    #[test]
    fn the_right_jacobian_gives_the_angular_velocity_in_the_rotated_axes() {
        let rate = Vec3::new(-0.3, 0.7, 0.2);
        for rho in vectors() {
            // Rotᵀ dRot/dt = [J_r ρ̇]×, by central differences.
            let h = 1e-6;
            let derivative = (rotation(&(rho + rate * h)) - rotation(&(rho - rate * h))) / (2.0 * h);
            let omega = rotation(&rho).transpose() * derivative;
            let expected = skew(&(right_jacobian(&rho) * rate));
            assert!((omega - expected).norm() < 1e-9, "{rho:?}: {:e}", (omega - expected).norm());
        }
    }

    #[test]
    fn the_rate_of_the_right_jacobian_is_its_derivative_along_the_motion() {
        let rate = Vec3::new(0.4, -0.1, 0.9);
        for rho in vectors() {
            let h = 1e-5;
            let derivative = (right_jacobian(&(rho + rate * h)) - right_jacobian(&(rho - rate * h))) / (2.0 * h);
            let error = (right_jacobian_rate(&rho, &rate) - derivative).norm();
            assert!(error < 1e-9, "{rho:?}: {error:e}");
        }
    }

    #[test]
    fn in_dual_numbers_the_right_jacobian_carries_its_rate() {
        use num_dual::Dual64;
        let rate = Vec3::new(0.4, -0.1, 0.9);
        for rho in vectors() {
            let dual = Vec3::from_fn(|k, _| Dual64::new(rho[k], rate[k]));
            let carried = right_jacobian(&dual).map(|d| d.eps);
            let error = (carried - right_jacobian_rate(&rho, &rate)).norm();
            assert!(error < 1e-14, "{rho:?}: {error:e}");
        }
    }

    #[test]
    fn the_series_and_the_closed_forms_meet() {
        // One ulp apart: the series just below, the closed forms at the edge.
        let below = coefficients(SERIES_BELOW - f64::EPSILON / 2.0);
        let above = coefficients(SERIES_BELOW);
        for (x, y) in below.iter().zip(&above) {
            assert!((x - y).abs() < 1e-14 * x.abs(), "{below:?} {above:?}");
        }
    }
}
