//! The orientation error of a pose target and its Jacobian.
//!
//! With R the body's rotation (body → world) and R̂ the target's, the error
//! is the rotation vector of the body relative to the target,
//!
//!   φ = log(R̂ᵀR),  i.e.  R = R̂ exp(\[φ\]×),  |φ| ≤ π (the shorter way round),
//!
//! in the target frame's axes (which are also the body's: R̂ᵀR φ = φ). The
//! controlled quantity is Y_rot = φ with Ŷ_rot = 0, so ΔY_rot = −φ.
//!
//! Its rate is φ̇ = J_r⁻¹(φ) ω, ω the body-frame angular velocity and J_r
//! the right Jacobian of SO(3) (exp(φ + δ) = exp(φ) exp(J_r(φ) δ)), so the
//! Jacobian of Y_rot is J_r⁻¹(φ) J_ω and the generalized force of
//! U = ½ φᵀKφ is the body-frame moment −J_r⁻ᵀ(φ) K φ. Since J_r⁻¹(φ)φ = φ,
//! an isotropic K gives just −Kφ; a diagonal one needs the full J_r⁻ᵀ for
//! V = K + U to be a Lyapunov function. At |φ| = π the error jumps to −φ:
//! U is continuous there (it is even in φ), its gradient is not, as for any
//! orientation error on SO(3).

use crate::math::Mat3;
use crate::math::{Quat, Vec3, quat_difference, skew};

/// Below this angle J_r⁻¹'s coefficient is its Taylor series (its closed
/// form loses digits as 1/θ² − cot(θ/2)/(2θ) cancels).
const SERIES_ANGLE: f64 = 1e-3;

/// φ = log(R̂ᵀR) of the body orientation `current` relative to `target`.
pub fn rotation_error(current: &Quat, target: &Quat) -> Vec3 {
    quat_difference(current, target)
}

/// J_r⁻ᵀ(φ) = I − ½\[φ\]× + β(θ)\[φ\]×², θ = |φ|, β = 1/θ² − cot(θ/2)/(2θ)
/// (→ 1/12 + θ²/720 as θ → 0); finite for θ < 2π.
pub fn right_jacobian_inverse_transpose(phi: &Vec3) -> Mat3 {
    let angle = phi.norm();
    let beta = if angle < SERIES_ANGLE {
        1.0 / 12.0 + angle * angle / 720.0
    } else {
        1.0 / (angle * angle) - 1.0 / (2.0 * angle * (0.5 * angle).tan())
    };
    let k = skew(phi);
    Mat3::identity() - 0.5 * k + beta * k * k
}

#[cfg(test)]
mod tests {
    use super::*;

    /// exp(φ + δ) = exp(φ) exp(J_r(φ) δ) to first order, so
    /// J_r(φ) δ = log(exp(φ)ᵀ exp(φ + δ)) / 1: check J_r⁻¹ against that.
    #[test]
    fn inverse_right_jacobian_matches_finite_differences() {
        for phi in [
            Vec3::new(0.3, -1.1, 0.7),
            Vec3::new(1e-5, 2e-5, -1e-5),
            Vec3::new(0.0, 0.0, 3.0),
            Vec3::new(2.0, 1.0, -1.5),
        ] {
            let jr_inv_t = right_jacobian_inverse_transpose(&phi);
            let h = 1e-6;
            for c in 0..3 {
                let mut delta = Vec3::zeros();
                delta[c] = h;
                let plus = Quat::from_scaled_axis(phi + delta);
                let minus = Quat::from_scaled_axis(phi - delta);
                // ω-column: the body-frame rotation that moves φ by δ.
                let omega = quat_difference(&plus, &minus) / (2.0 * h);
                // J_r⁻¹ ω = δ/h (unit vector e_c).
                let back = jr_inv_t.transpose() * omega;
                let mut e = Vec3::zeros();
                e[c] = 1.0;
                assert!((back - e).norm() < 1e-8, "phi {phi:?}, column {c}: {back:?}");
            }
        }
    }

    #[test]
    fn phi_is_a_fixed_point_of_the_jacobian() {
        let phi = Vec3::new(0.4, 0.9, -2.1);
        assert!((right_jacobian_inverse_transpose(&phi) * phi - phi).norm() < 1e-14);
    }

    #[test]
    fn rotation_error_takes_the_shorter_way() {
        let target = Quat::from_scaled_axis(Vec3::new(0.1, 0.2, 0.3));
        let phi = Vec3::new(0.0, 0.0, 2.5);
        let current = target * Quat::from_scaled_axis(phi);
        assert!((rotation_error(&current, &target) - phi).norm() < 1e-12);
        let flipped = Quat::new_unchecked(-current.into_inner());
        assert!((rotation_error(&flipped, &target) - phi).norm() < 1e-12, "q and −q are the same rotation");
    }
}
