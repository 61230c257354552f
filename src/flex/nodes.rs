//! A node of a flexible body as a rigid body moved by the modal coordinates
//! η (docs/flexible.md, "The model"): its frame N_j relative to the body
//! frame R is placed at p_j = r_j + Φᵗ_j η and turned by Rot_j = exp(\[ρ_j\]×),
//! ρ_j = Φʳ_j η. In N_j's coordinates its velocity relative to R is Ψ_j η̇ with
//!
//!   Ψ_j = [ J_r(ρ_j) Φʳ_j ; Rot_jᵀ Φᵗ_j ]      (angular rows first),
//!
//! the exact derivative of that pose, so that a node is a joint of m dofs
//! with the motion subspace Ψ_j(η), shared by every node of the body. The
//! passes need Ψ_j and its rate along a motion, Ψ̇_j η̇, the joint's
//! velocity-product term.

use nalgebra::DMatrix;

use super::ModalBody;
use super::rotation::{right_jacobian, right_jacobian_rate, rotation};
use crate::math::{Mat3, Real, SpatialVec, Transform, Vec3, angular, linear, real, spatial};

/// Φᵗ_j η and Φʳ_j η: node `j`'s displacement and rotation vector.
pub fn displacement<S: Real>(body: &ModalBody, j: usize, eta: &[S]) -> (Vec3<S>, Vec3<S>) {
    body.modes.iter().zip(eta).fold((Vec3::zeros(), Vec3::zeros()), |(t, r), (mode, &e)| {
        (t + real::<S, 3, 1>(&mode.translation[j]) * e, r + real::<S, 3, 1>(&mode.rotation[j]) * e)
    })
}

/// ʲX_R: motion vectors from the body frame's coordinates to node `j`'s.
pub fn transform<S: Real>(body: &ModalBody, j: usize, eta: &[S]) -> Transform<S> {
    let (translation, rotation_vector) = displacement(body, j, eta);
    let position = real::<S, 3, 1>(&body.nodes[j].position) + translation;
    Transform::from_pose(&rotation(&rotation_vector), &position)
}

/// Ψ_j at η, written into `out` (6 × m).
pub fn subspace<S: Real>(body: &ModalBody, j: usize, eta: &[S], out: &mut DMatrix<S>) {
    let (_, rho) = displacement(body, j, eta);
    let (jacobian, turn_back) = (right_jacobian(&rho), rotation(&rho).transpose());
    for (k, mode) in body.modes.iter().enumerate() {
        let angular = jacobian * real::<S, 3, 1>(&mode.rotation[j]);
        let linear = turn_back * real::<S, 3, 1>(&mode.translation[j]);
        out.column_mut(k).copy_from(&spatial(&angular, &linear));
    }
}

/// Ψ_j v for a vector `v` of modal rates (or accelerations), without forming Ψ_j.
pub fn subspace_times<S: Real>(body: &ModalBody, j: usize, eta: &[S], v: &[S]) -> SpatialVec<S> {
    let (_, rho) = displacement(body, j, eta);
    let (translation, rotation_vector) = displacement(body, j, v);
    spatial(&(right_jacobian(&rho) * rotation_vector), &(rotation(&rho).transpose() * translation))
}

/// `out` += Ψ_jᵀ f · `scale` for a wrench `f` in node `j`'s coordinates
/// (about its origin): the modal forces of that wrench, without forming
/// Ψ_j. Column k of Ψ_j is [J_r Φʳ_k ; Rotᵀ Φᵗ_k], so its product with f is
/// Φʳ_k · J_rᵀ f_angular + Φᵗ_k · Rot f_linear.
pub fn add_subspace_transpose_times<S: Real>(
    body: &ModalBody,
    j: usize,
    eta: &[S],
    f: &SpatialVec<S>,
    scale: S,
    out: &mut [S],
) {
    let (_, rho) = displacement(body, j, eta);
    let torque = right_jacobian(&rho).transpose() * angular(f);
    let force = rotation(&rho) * linear(f);
    for (slot, mode) in out.iter_mut().zip(&body.modes) {
        let arm = real::<S, 3, 1>(&mode.rotation[j]).dot(&torque) + real::<S, 3, 1>(&mode.translation[j]).dot(&force);
        *slot += arm * scale;
    }
}

/// Ψ̇_j: the rate of Ψ_j's coordinates along η̇, written into `out` (6 × m);
/// as [`subspace_rate_times`], column by column.
pub fn subspace_rate<S: Real>(body: &ModalBody, j: usize, eta: &[S], eta_rate: &[S], out: &mut DMatrix<S>) {
    let (_, rho) = displacement(body, j, eta);
    let (_, rho_rate) = displacement(body, j, eta_rate);
    let omega = right_jacobian(&rho) * rho_rate;
    let jacobian_rate = right_jacobian_rate(&rho, &rho_rate);
    let turned: Mat3<S> = rotation(&rho).transpose();
    for (k, mode) in body.modes.iter().enumerate() {
        let angular = jacobian_rate * real::<S, 3, 1>(&mode.rotation[j]);
        let linear = -omega.cross(&(turned * real::<S, 3, 1>(&mode.translation[j])));
        out.column_mut(k).copy_from(&spatial(&angular, &linear));
    }
}

/// Ψ̇_j η̇: the rate of Ψ_j's coordinates along η̇, times η̇. With
/// Ω = J_r ρ̇ the node's angular velocity relative to R (in its axes),
/// d(Rotᵀ)/dt = −\[Ω\]× Rotᵀ.
pub fn subspace_rate_times<S: Real>(body: &ModalBody, j: usize, eta: &[S], eta_rate: &[S]) -> SpatialVec<S> {
    let (_, rho) = displacement(body, j, eta);
    let (translation_rate, rho_rate) = displacement(body, j, eta_rate);
    let omega = right_jacobian(&rho) * rho_rate;
    let angular = right_jacobian_rate(&rho, &rho_rate) * rho_rate;
    let turned: Mat3<S> = rotation(&rho).transpose();
    let linear = -omega.cross(&(turned * translation_rate));
    spatial(&angular, &linear)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flex::{Mode, Node};

    /// Three nodes and two modes with every component in use (the
    /// kinematics need no orthogonality).
    fn body() -> ModalBody {
        let node = |x: f64| Node {
            name: format!("n{x}"),
            position: Vec3::new(x, 0.1, -0.2),
            mass: 1.0,
            rotary_inertia: Mat3::identity(),
        };
        let mode = |s: f64| Mode {
            angular_frequency: 1.0,
            damping_ratio: 0.0,
            translation: vec![
                Vec3::new(0.1, -0.3, 0.2) * s,
                Vec3::new(0.0, 0.5, -0.1) * s,
                Vec3::new(-0.2, 0.1, 0.7) * s,
            ],
            rotation: vec![Vec3::new(0.4, 0.1, -0.2) * s, Vec3::new(-0.3, 0.6, 0.2), Vec3::new(0.2, -0.1, 0.9) * s],
        };
        ModalBody { body: "b".into(), nodes: vec![node(0.0), node(0.5), node(1.0)], modes: vec![mode(1.0), mode(-0.7)] }
    }

    const ETA: [f64; 2] = [0.3, -0.8];
    const RATE: [f64; 2] = [-1.1, 0.4];

    fn moved(by: f64) -> Vec<f64> {
        ETA.iter().zip(RATE).map(|(e, r)| e + r * by).collect()
    }

    #[test]
    fn psi_times_the_rate_is_the_nodes_velocity_relative_to_the_body() {
        let body = body();
        let h = 1e-6;
        for j in 0..3 {
            let (before, after) = (transform(&body, j, &moved(-h)), transform(&body, j, &moved(h)));
            let at = transform(&body, j, &ETA);
            // In N's axes: Rotᵀ dRot/dt = [ω]×, and Rotᵀ dp/dt.
            // A transform's `rot` is Rotᵀ, its `trans` the node's origin p.
            let turn = at.rot * (after.rot.transpose() - before.rot.transpose()) / (2.0 * h);
            let omega = Vec3::new(turn[(2, 1)], turn[(0, 2)], turn[(1, 0)]);
            let velocity = at.rot * (after.trans - before.trans) / (2.0 * h);
            let mut psi = DMatrix::zeros(6, 2);
            subspace(&body, j, &ETA, &mut psi);
            let v = &psi * nalgebra::DVector::from_column_slice(&RATE);
            let v = SpatialVec::from_column_slice(v.as_slice());
            assert!((angular(&v) - omega).norm() < 1e-9, "node {j}: {:?} {omega:?}", angular(&v));
            assert!((linear(&v) - velocity).norm() < 1e-9, "node {j}: {:?} {velocity:?}", linear(&v));
        }
    }

    #[test]
    fn the_rate_term_is_psis_derivative_along_the_motion_times_the_rate() {
        let body = body();
        let h = 1e-6;
        for j in 0..3 {
            let (mut before, mut after) = (DMatrix::zeros(6, 2), DMatrix::zeros(6, 2));
            subspace(&body, j, &moved(-h), &mut before);
            subspace(&body, j, &moved(h), &mut after);
            let expected = (after - before) / (2.0 * h) * nalgebra::DVector::from_column_slice(&RATE);
            let term = subspace_rate_times(&body, j, &ETA, &RATE);
            assert!((term - SpatialVec::from_column_slice(expected.as_slice())).norm() < 1e-8, "node {j}");
        }
    }

    #[test]
    fn the_rate_of_psi_is_its_derivative_along_the_motion() {
        let body = body();
        let h = 1e-6;
        for j in 0..3 {
            let (mut before, mut after, mut rate) = (DMatrix::zeros(6, 2), DMatrix::zeros(6, 2), DMatrix::zeros(6, 2));
            subspace(&body, j, &moved(-h), &mut before);
            subspace(&body, j, &moved(h), &mut after);
            subspace_rate(&body, j, &ETA, &RATE, &mut rate);
            assert!((rate - (after - before) / (2.0 * h)).norm() < 1e-8, "node {j}");
        }
    }

    #[test]
    fn the_modal_forces_of_a_wrench_are_psi_transposed_times_it() {
        let body = body();
        let f = SpatialVec::from_column_slice(&[0.3, -1.2, 0.7, 2.0, 0.4, -0.9]);
        for j in 0..3 {
            let mut psi = DMatrix::zeros(6, 2);
            subspace(&body, j, &ETA, &mut psi);
            let expected = psi.transpose() * nalgebra::DVector::from_column_slice(f.as_slice()) * 2.0;
            let mut out = [1.0, -1.0];
            add_subspace_transpose_times(&body, j, &ETA, &f, 2.0, &mut out);
            assert!((out[0] - 1.0 - expected[0]).abs() < 1e-14, "node {j}");
            assert!((out[1] + 1.0 - expected[1]).abs() < 1e-14, "node {j}");
        }
    }
}
