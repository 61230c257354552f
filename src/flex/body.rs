//! The equations of one flexible body in its own coordinates (V_R, η):
//!
//!   𝓘(η) [A_R; η̈] + b(V_R, η, η̇) = [F_R; Q_η],
//!
//! F_R the spatial force on the body frame R (R's coordinates), Q_η the
//! modal forces. Each node j is a rigid body of spatial inertia I_j (its
//! mass at its origin, its rotary inertia in its axes) moving with
//! V_j = ʲX_R V_R + Ψ_j η̇ (`nodes`), so that
//!
//!   𝓘 = Σ_j B_jᵀ I_j B_j,   B_j = [ʲX_R  Ψ_j],
//!   b = Σ_j B_jᵀ (I_j c_j + V_j ×* I_j V_j),   c_j = Ψ̇_j η̇ + V_j × Ψ_j η̇,
//!
//! Newton–Euler for each node with its acceleration
//! A_j = ʲX_R A_R + Ψ_j η̈ + c_j, gathered by virtual power. This is the
//! (6 + m)-square block that pass 1 eliminates the modes from
//! (docs/flexible.md); written dense here, per body.

use nalgebra::{DMatrix, DVector};

use super::{ModalBody, nodes};
use crate::math::{Real, SpatialMat, SpatialVec, Vec3, cross_force, cross_motion, real, rigid_inertia};

/// Node `j`'s spatial inertia about its origin, in its axes.
pub fn node_inertia(body: &ModalBody, j: usize) -> SpatialMat {
    let node = &body.nodes[j];
    rigid_inertia(node.mass, &Vec3::zeros(), &node.rotary_inertia)
}

/// 𝓘 and b of `body` at η, η̇ with the body frame moving at `v_body`.
pub fn equations<S: Real>(
    body: &ModalBody,
    eta: &[S],
    eta_rate: &[S],
    v_body: &SpatialVec<S>,
) -> (DMatrix<S>, DVector<S>) {
    let m = body.modes.len();
    let (mut inertia, mut bias) = (DMatrix::zeros(6 + m, 6 + m), DVector::zeros(6 + m));
    let mut psi = DMatrix::zeros(6, m);
    let rate = DVector::from_column_slice(eta_rate);
    for j in 0..body.nodes.len() {
        let x = nodes::transform(body, j, eta);
        nodes::subspace(body, j, eta, &mut psi);
        let mut b = DMatrix::zeros(6, 6 + m);
        b.view_mut((0, 0), (6, 6)).copy_from(&x.motion_matrix());
        b.view_mut((0, 6), (6, m)).copy_from(&psi);
        let i_node: SpatialMat<S> = real(&node_inertia(body, j));
        let relative = SpatialVec::from_iterator((&psi * &rate).iter().copied());
        let v_node = x.apply_motion(v_body) + relative;
        let c = nodes::subspace_rate_times(body, j, eta, eta_rate) + cross_motion(&v_node, &relative);
        let force = i_node * c + cross_force(&v_node, &(i_node * v_node));
        let i_dense = DMatrix::from_iterator(6, 6, i_node.iter().copied());
        inertia += b.transpose() * &i_dense * &b;
        bias += b.transpose() * DVector::from_iterator(6, force.iter().copied());
    }
    (inertia, bias)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flex::{Mode, Node};
    use crate::math::{Mat3, angular, linear};

    /// Four nodes with rotary inertia and three modes using every
    /// component: a body whose nodes turn and move with the modes.
    fn body() -> ModalBody {
        let node = |x: f64, m: f64| Node {
            name: format!("n{x}"),
            position: Vec3::new(x, 0.2 * x, -0.1),
            mass: m,
            rotary_inertia: Mat3::from_diagonal(&Vec3::new(0.02, 0.03, 0.04)) * m,
        };
        let mode = |seed: f64| Mode {
            angular_frequency: 2.0 + seed,
            damping_ratio: 0.0,
            translation: (0..4)
                .map(|j| Vec3::new((seed + j as f64).sin(), (2.0 * seed - j as f64).cos(), 0.3) * 0.3)
                .collect(),
            rotation: (0..4).map(|j| Vec3::new(0.2, (seed * j as f64).sin(), -0.4) * 0.5).collect(),
        };
        let nodes = vec![node(0.0, 2.0), node(0.4, 1.0), node(0.8, 0.7), node(1.2, 0.5)];
        ModalBody { body: "b".into(), nodes, modes: vec![mode(0.1), mode(1.3), mode(2.2)] }
    }

    /// A free flexible body in its own coordinates: R's twist, η, η̇ (the
    /// equations do not involve R's pose).
    #[derive(Clone)]
    struct State {
        twist: SpatialVec,
        eta: Vec<f64>,
        eta_rate: Vec<f64>,
    }

    /// The state's rates: A_R and η̈ from the equations with F_R = 0 and
    /// Q = −ω²η (no damping), and η̇. (For R's own twist in R's coordinates
    /// d/dt V_R = A_R.)
    fn rates(body: &ModalBody, s: &State) -> State {
        let (inertia, bias) = equations(body, &s.eta, &s.eta_rate, &s.twist);
        let mut rhs = -bias;
        for (k, mode) in body.modes.iter().enumerate() {
            rhs[6 + k] -= mode.angular_frequency.powi(2) * s.eta[k];
        }
        let acc = inertia.lu().solve(&rhs).expect("𝓘 is positive definite");
        State {
            twist: SpatialVec::from_iterator(acc.rows(0, 6).iter().copied()),
            eta: s.eta_rate.clone(),
            eta_rate: acc.rows(6, body.modes.len()).iter().copied().collect(),
        }
    }

    /// s + h·Σ wᵢ kᵢ.
    fn advanced(s: &State, stages: &[(&State, f64)], h: f64) -> State {
        let step = |x: &[f64], of: fn(&State) -> &[f64]| -> Vec<f64> {
            (0..x.len()).map(|k| x[k] + h * stages.iter().map(|(d, w)| of(d)[k] * w).sum::<f64>()).collect()
        };
        State {
            twist: s.twist + stages.iter().map(|(d, w)| d.twist * *w).sum::<SpatialVec>() * h,
            eta: step(&s.eta, |d| &d.eta),
            eta_rate: step(&s.eta_rate, |d| &d.eta_rate),
        }
    }

    /// Kinetic plus strain energy, and three invariants of the nodes'
    /// spatial momentum that need no world pose: |p|², L·p (the same about
    /// any point) and |L_c|², the angular momentum about the centre of mass.
    fn invariants(body: &ModalBody, s: &State) -> (f64, [f64; 3]) {
        let (mut energy, mut momentum) = (0.0, SpatialVec::zeros());
        let (mut mass, mut first_moment) = (0.0, Vec3::zeros());
        let mut psi = DMatrix::zeros(6, body.modes.len());
        for j in 0..body.nodes.len() {
            let x = nodes::transform(body, j, &s.eta);
            nodes::subspace(body, j, &s.eta, &mut psi);
            let v = x.apply_motion(&s.twist)
                + SpatialVec::from_iterator((&psi * DVector::from_column_slice(&s.eta_rate)).iter().copied());
            let h = node_inertia(body, j) * v;
            energy += 0.5 * v.dot(&h);
            momentum += x.apply_transpose_force(&h);
            mass += body.nodes[j].mass;
            first_moment += x.trans * body.nodes[j].mass;
        }
        let strain: f64 =
            body.modes.iter().zip(&s.eta).map(|(mode, e)| 0.5 * (mode.angular_frequency * e).powi(2)).sum();
        let (l, p) = (angular(&momentum), linear(&momentum));
        let about_centre = l - (first_moment / mass).cross(&p);
        (energy + strain, [p.norm_squared(), l.dot(&p), about_centre.norm_squared()])
    }

    #[test]
    fn a_free_flexible_body_keeps_its_energy_and_momentum() {
        let body = body();
        let mut s = State {
            twist: SpatialVec::from_column_slice(&[0.3, -0.5, 0.8, 0.1, 0.2, -0.1]),
            eta: vec![0.05, -0.08, 0.03],
            eta_rate: vec![0.4, 0.2, -0.5],
        };
        let (energy, momentum) = invariants(&body, &s);
        let h = 1e-3;
        for _ in 0..2000 {
            let k1 = rates(&body, &s);
            let k2 = rates(&body, &advanced(&s, &[(&k1, 0.5)], h));
            let k3 = rates(&body, &advanced(&s, &[(&k2, 0.5)], h));
            let k4 = rates(&body, &advanced(&s, &[(&k3, 1.0)], h));
            s = advanced(&s, &[(&k1, 1.0 / 6.0), (&k2, 1.0 / 3.0), (&k3, 1.0 / 3.0), (&k4, 1.0 / 6.0)], h);
        }
        let (energy_after, momentum_after) = invariants(&body, &s);
        assert!(s.eta.iter().map(|e| e.abs()).sum::<f64>() > 1e-3, "the modes must move: {:?}", s.eta);
        assert!(((energy_after - energy) / energy).abs() < 1e-10, "energy {energy} → {energy_after}");
        for (before, after) in momentum.iter().zip(&momentum_after) {
            assert!(((after - before) / before).abs() < 1e-10, "momentum invariants {momentum:?} → {momentum_after:?}");
        }
    }
}
