//! ∂θ̈/∂Δ and ∂θ̈/∂θ̇ in closed form, for a rigid tree whose forces are
//! gravity, joint springs and dampers, an applied ε, constant joint
//! forces T and actuators on its hinges, slides and sites: the derivatives of the inverse dynamics τ = ID(θ, θ̇, θ̈) in
//! world coordinates, a few 6-vector products per pair of a joint and its
//! ancestor, then θ̈'s through the mass matrix,
//!
//!   ∂θ̈/∂x = M⁻¹ (∂τ_applied/∂x − ∂ID/∂x |θ̈ held),
//!
//! M⁻¹ = ℓᵀℓ from the factor of pass 1 (ℓ = m⁻¹: forces.rs's inward pass
//! from joint forces to ε, and ℓᵀ its adjoint outward, applied to the
//! columns by `FactorPasses`). The same derivatives as derivatives.rs's
//! dual numbers give (to round-off), at a fraction of their cost:
//! derivatives.rs runs every pass once per column; this runs the passes
//! once, then O(N·depth) products, then two O(N) passes per column.
//!
//! All quantities below are world vectors about the world origin, so that a
//! subtree's sums need no transforms. For link i with world motion subspace
//! S_i, λ its parent (the world's a_λ = −g):
//!
//!   v_i = v_λ + S_iθ̇_i,   a_i = a_λ + v_λ × S_iθ̇_i + S_iθ̈_i,
//!   f_i = Y_i a_i + v_i ×* Y_i v_i,   2B_i w = v_i ×* Y_i w − Y_i (v_i × w) + w ×* Y_i v_i,
//!
//! and I^C_i, 2B^C_i, F_i the sums of Y, 2B and f over i's subtree. Moving
//! θ of joint j by δ along a column s of S_j (the tangent direction Δ of
//! derivatives.rs) moves j's subtree rigidly by the twist sδ: its bodies'
//! Y and S turn with it (δY = s ×* Y − Y s×, δS = s × S), their velocities
//! change by s × (v_b − v_λ)δ and their accelerations by
//! [s × (a_b − a_λ) − (s × v_λ) × (v_b − v_λ)]δ. With Ψ̇ = v_λ × s and
//! Ψ̈ = a_λ × s + v_λ × Ψ̇ that gives, as the rigid turn of a force leaves
//! its joint component unchanged,
//!
//!   ∂τ_k/∂θ_j,s = S_kᵀ (I^C_k Ψ̈ + 2B^C_k Ψ̇)               k in j's subtree,
//!               = S_kᵀ (s ×* F_j + I^C_j Ψ̈ + 2B^C_j Ψ̇)     k an ancestor of j;
//!
//! and moving θ̇_j along s changes v_b by s and a_b by Ṡ + Ψ̇ + s × v_b
//! (Ṡ = v_j × s), so that
//!
//!   ∂τ_k/∂θ̇_j,s = S_kᵀ (I^C_k (Ṡ + Ψ̇) + 2B^C_k s)          k in j's subtree,
//!               = S_kᵀ (I^C_j (Ṡ + Ψ̇) + 2B^C_j s)          k an ancestor of j.
//!
//! Every other entry is zero. (The same formulas as Carpentier and
//! Mansard's derivatives of the recursive Newton–Euler algorithm, derived
//! here in this notation; docs/linearization.md, "In closed form".)
//!
//! An applied ε stands for the joint forces m(θ)ε, which change with the
//! configuration through the factor: `AppliedEps` adds their derivative
//! (the articulated inertias' change up each column's path, O(N·depth)
//! 6×6 products). Actuators on hinges and slides add their force's slopes
//! on their dof's diagonal; actuators on sites with a constant force are
//! wrenches fixed in their bodies, which turn with the subtree as ε's
//! forces do. Forces whose law reads the configuration otherwise (other
//! actuators, tendons, gravity compensation, constraint rows, flexible
//! bodies, springs on ball joints) are refused, and derivatives.rs serves
//! those models.

use nalgebra::{DMatrix, SMatrix, SVector};
use num_dual::Dual64;
use wide::f64x4;

use super::actuation;
use super::articulated::upper_triangular_inverse;
use super::bias::upper_half;
use super::derivatives::DerivativeError;
use super::{block, cols};
use crate::math::{Mat3, SpatialMat, SpatialVec, Vec3, angular, cross_force, cross_motion, linear, skew, spatial};
use crate::model::{Actuator, ActuatorTransmission, LinkJoint, Model};
use crate::vehicle::{BiasType, GainType};
use crate::workspace::{LinkCols, Workspace};

/// The passes at the point and the buffers of the closed form, allocated
/// once, so that a Jacobian allocates nothing.
#[derive(Clone, Debug)]
pub struct QaccJacobian {
    ws: Workspace,
    /// ε of the joint forces T, ℓ(θ)T.
    eps_of_torque: Vec<f64>,
    /// Per dof (a column s of its link's S), world coordinates: s.
    subspace: Vec<SpatialVec>,
    /// Ψ̇ = v_λ × s.
    psi_dot: Vec<SpatialVec>,
    /// Ψ̈ = a_λ × s + v_λ × Ψ̇.
    psi_ddot: Vec<SpatialVec>,
    /// Ṡ + Ψ̇, the change of the subtree's accelerations per unit θ̇ but for s × v_b.
    rate_terms: Vec<SpatialVec>,
    /// Per dof of link k, after the inward sweep: I^C_k s and (2B^C_k)ᵀ s
    /// (s ᵀI^C_k and sᵀ2B^C_k, the rows of k's subtree), and what its column
    /// gives an ancestor's row: s ×* F_k + I^C_k Ψ̈ + 2B^C_k Ψ̇ in Δ, I^C_k(Ṡ + Ψ̇) + 2B^C_k s in θ̇.
    inertia_s: Vec<SpatialVec>,
    coriolis_t_s: Vec<SpatialVec>,
    ancestor_by_delta: Vec<SpatialVec>,
    ancestor_by_qvel: Vec<SpatialVec>,
    velocity: Vec<SpatialVec>,
    acceleration: Vec<SpatialVec>,
    /// I^C, 2B^C and F: each link's own term, then (after the inward sweep) its subtree's.
    inertia: Vec<SpatialMat>,
    coriolis: Vec<SpatialMat>,
    force: Vec<SpatialVec>,
    /// ∂τ_passive/∂Δ − ∂ID/∂Δ and the same in θ̇ (nv × nv).
    torque_by_delta: DMatrix<f64>,
    torque_by_qvel: DMatrix<f64>,
    factor: FactorPasses,
    /// M⁻¹ = ℓᵀℓ or ℓᵀ when asked (nv × nv), and the identity they are taken of.
    asked: DMatrix<f64>,
    identity: DMatrix<f64>,
    applied: AppliedEps,
}

/// An applied ε as the joint forces T_ε = m(θ)ε it stands for: the
/// inward pass of forces.rs gives T_ε,i = S_iᵀ Σ_{k in i's subtree} f_k with
/// f_k = G_k R_k ε_k = U_k z_k (U = I^A S, z = R⁻ᵀε), a spatial force at
/// each link, but for its own row, whose term is R_iε_i. Turning joint j
/// along s turns the f_k of j's subtree with it (which changes only its
/// ancestors' rows, by S_iᵀ(s ×* F^ε_j), F^ε_j the sum of those f: taken
/// with the inertial forces' turn, [`QaccJacobian::compute`]), and changes
/// the articulated inertia of each strict
/// ancestor k by δI^A_λ(j) = s ×* I^a_j − I^a_j s× and then
/// δI^A_λ(k) = P_k δI^A_k P_kᵀ (P = 1 − G Sᵀ), so its f_k by
/// δU z + U δz, with δD = SᵀδI^A S, δR = R Φ(R⁻¹δD R⁻ᵀ) (bias.rs's Φ) and
/// δz = −R⁻ᵀδRᵀz; an ancestor i's row takes δR_i ε_i for its own term
/// (forces.rs's T_i = R_iε_i + S_iᵀp_i: Rε, not Sᵀf, as D holds the
/// armature) and S_iᵀ of the sum of the f's changed below it, down to j's
/// parent. World coordinates, per link.
#[derive(Clone, Debug)]
struct AppliedEps {
    /// I^a (a link's share of its parent's I^A), U, R and z (G is
    /// [`FactorPasses`]'s).
    reduced_inertia: Vec<SpatialMat>,
    joint_force: Vec<LinkCols>,
    r: Vec<Mat3>,
    z: Vec<Vec3>,
    /// f at each link.
    link_force: Vec<SpatialVec>,
}

impl QaccJacobian {
    /// Whether the closed form covers `model`: what it has that the form leaves out.
    pub fn check(model: &Model) -> Result<(), DerivativeError> {
        let ball_springs =
            !model.shortcuts.no_springs && model.links.iter().any(|l| l.joint == LinkJoint::Ball && l.stiffness != 0.0);
        // Actuators without activation states on hinges and slides, whose
        // forces are functions of one dof's θ and θ̇ (joint_actuator_slopes),
        // and on sites with a force that reads neither length nor velocity
        // (thrusters: a wrench fixed in its body, turning with it: compute).
        let covered = |a: &Actuator| {
            let constant = (a.gain_type == GainType::Fixed || a.gain[1..] == [0.0, 0.0])
                && (a.bias_type == BiasType::None || a.bias[1..] == [0.0, 0.0]);
            let transmission = match a.transmission {
                ActuatorTransmission::Scalar { .. } => true,
                ActuatorTransmission::Site { .. } => constant,
                _ => false,
            };
            transmission && a.activation.is_none() && a.setpoint_period == 0.0
        };
        let unsupported = [
            (!model.flexible.is_empty(), "flexible bodies"),
            (
                !model.actuators.iter().all(covered),
                "actuators other than on hinges, slides or sites (with a force that reads neither length nor \
                 velocity), or with activation states",
            ),
            (!model.actuator_force_limits.is_empty(), "joints' actuatorfrcrange"),
            (!model.tendons.is_empty(), "tendons"),
            (!model.constraints.is_empty() || model.couples_beyond_tree(), "constraint rows"),
            (!model.gravity_compensation.is_empty(), "gravity compensation"),
            (ball_springs, "springs on ball joints"),
        ];
        match unsupported.iter().find(|(has, _)| *has) {
            Some((_, what)) => Err(DerivativeError::Unsupported(what)),
            None => Ok(()),
        }
    }

    /// The buffers for `model`, or what it has that the closed form leaves out.
    pub fn new(model: &Model) -> Result<Self, DerivativeError> {
        Self::check(model)?;
        let (n, nv) = (model.links.len(), model.nv);
        Ok(QaccJacobian {
            ws: model.workspace(),
            eps_of_torque: vec![0.0; nv],
            subspace: vec![SpatialVec::zeros(); nv],
            psi_dot: vec![SpatialVec::zeros(); nv],
            psi_ddot: vec![SpatialVec::zeros(); nv],
            rate_terms: vec![SpatialVec::zeros(); nv],
            inertia_s: vec![SpatialVec::zeros(); nv],
            coriolis_t_s: vec![SpatialVec::zeros(); nv],
            ancestor_by_delta: vec![SpatialVec::zeros(); nv],
            ancestor_by_qvel: vec![SpatialVec::zeros(); nv],
            velocity: vec![SpatialVec::zeros(); n],
            acceleration: vec![SpatialVec::zeros(); n],
            inertia: vec![SpatialMat::zeros(); n],
            coriolis: vec![SpatialMat::zeros(); n],
            force: vec![SpatialVec::zeros(); n],
            torque_by_delta: DMatrix::zeros(nv, nv),
            torque_by_qvel: DMatrix::zeros(nv, nv),
            factor: FactorPasses::new(model),
            asked: DMatrix::zeros(nv, nv),
            identity: DMatrix::identity(nv, nv),
            applied: AppliedEps {
                reduced_inertia: vec![SpatialMat::zeros(); n],
                joint_force: vec![LinkCols::zeros(); n],
                r: vec![Mat3::zeros(); n],
                z: vec![Vec3::zeros(); n],
                link_force: vec![SpatialVec::zeros(); n],
            },
        })
    }

    /// ∂θ̈/∂Δ (Δ in the tangent space, as derivatives.rs's) into `by_delta`
    /// and ∂θ̈/∂θ̇ into `by_qvel` (nv × nv each) at (θ, θ̇) under an applied
    /// ε, constant joint forces `torque` and the actuators' `ctrl`.
    pub fn compute(
        &mut self,
        model: &Model,
        (theta, qvel): (&[f64], &[f64]),
        (eps, torque, ctrl): (&[f64], &[f64], &[f64]),
        (by_delta, by_qvel): (&mut DMatrix<f64>, &mut DMatrix<f64>),
    ) -> Result<(), DerivativeError> {
        super::check_input("eps", eps, model.nv)?;
        super::check_input("torque", torque, model.nv)?;
        super::check_input("ctrl", ctrl, model.actuators.len())?;
        let ws = &mut self.ws;
        ws.set_configuration(model, theta)?;
        ws.set_qvel(model, qvel)?;
        if torque.iter().any(|t| *t != 0.0) {
            ws.eps_from_forces(model, torque, None, &mut self.eps_of_torque)?;
        } else {
            self.eps_of_torque.fill(0.0);
        }
        let applied_eps = eps.iter().any(|e| *e != 0.0);
        for (total, e) in self.eps_of_torque.iter_mut().zip(eps) {
            *total += e;
        }
        if model.actuators.is_empty() {
            ws.compute_qacc(model, &self.eps_of_torque)?;
        } else {
            ws.compute_qacc_actuated(model, &self.eps_of_torque, ctrl)?;
        }
        ws.world_transforms(model);
        self.factor.prepare(model, &self.ws);
        self.outward_sweep(model);
        // Forces applied at the links and turning with them (site
        // actuators' wrenches fixed in their bodies, ε's f): turning joint j
        // turns those of j's subtree, which changes j's strict ancestors'
        // rows by S_iᵀ(s ×* F^applied_j), as the inertial forces' turn
        // does with the opposite sign; so they come off F before its sums.
        if self.ws.actuators_apply_wrenches {
            for (i, force) in self.force.iter_mut().enumerate() {
                *force -= self.ws.x_world[i].apply_transpose_force(&self.ws.link_wrench[i]);
            }
        }
        if applied_eps {
            self.applied.prepare(model, &self.ws, &self.factor.gain, eps);
            for (force, applied) in self.force.iter_mut().zip(&self.applied.link_force) {
                *force -= applied;
            }
        }
        self.inward_sweep(model);
        self.torque_derivatives(model);
        for (k, actuator) in model.actuators.iter().enumerate() {
            let slopes = joint_actuator_slopes(model, actuator, &self.ws, ctrl[k]);
            if let Some((dof, slopes)) = slopes {
                self.torque_by_delta[(dof, dof)] += slopes.by_length;
                self.torque_by_qvel[(dof, dof)] += slopes.by_velocity;
            }
        }
        if applied_eps {
            self.applied.add_derivatives(model, &self.subspace, &self.factor.gain, &mut self.torque_by_delta);
        }
        let ts = [&self.torque_by_delta, &self.torque_by_qvel];
        self.factor.apply(model, &self.subspace, ts, [by_delta, by_qvel], false);
        Ok(())
    }

    /// M⁻¹ = ℓᵀℓ at the last [`QaccJacobian::compute`]'s θ: ∂θ̈/∂T.
    pub fn mass_inverse(&mut self, model: &Model) -> &DMatrix<f64> {
        self.factor.apply(model, &self.subspace, [&self.identity], [&mut self.asked], false);
        &self.asked
    }

    /// ∂θ̈/∂ctrl (nv × actuators) at the last [`QaccJacobian::compute`]'s
    /// point and `ctrl`: M⁻¹ times each joint actuator's force per unit ctrl.
    pub fn by_ctrl(&mut self, model: &Model, ctrl: &[f64]) -> DMatrix<f64> {
        let mass_inverse = self.mass_inverse(model).clone();
        let mut out = DMatrix::zeros(model.nv, model.actuators.len());
        let mut moment = vec![0.0; model.nv];
        for (k, actuator) in model.actuators.iter().enumerate() {
            if let Some((dof, slopes)) = joint_actuator_slopes(model, actuator, &self.ws, ctrl[k]) {
                out.column_mut(k).axpy(slopes.by_ctrl, &mass_inverse.column(dof), 0.0);
            } else if let Some(per_ctrl) = site_force_per_ctrl(model, actuator, ctrl[k]) {
                // The generalized force of a unit force of the actuator (its
                // moment arms) times the force per unit ctrl.
                self.ws.actuator_moment(model, k, &mut moment).expect("the passes ran at this point");
                let moment = nalgebra::DVector::from_column_slice(&moment);
                out.column_mut(k).gemv(per_ctrl, &mass_inverse, &moment, 0.0);
            }
        }
        out
    }

    /// ℓ* = ℓᵀ at the last [`QaccJacobian::compute`]'s θ: ∂θ̈/∂ε.
    pub fn factor_inverse_adjoint(&mut self, model: &Model) -> &DMatrix<f64> {
        self.factor.apply(model, &self.subspace, [&self.identity], [&mut self.asked], true);
        &self.asked
    }

    /// Base to tip: each link's world S, v, a, Ψ̇, Ψ̈, Ṡ + Ψ̇, and its own Y, 2B, f.
    fn outward_sweep(&mut self, model: &Model) {
        let ws = &self.ws;
        let gravity =
            if model.shortcuts.no_gravity { SpatialVec::zeros() } else { spatial(&Vec3::zeros(), &model.gravity) };
        for (i, link) in model.links.iter().enumerate() {
            let x = &ws.x_world[i];
            let (v_parent, a_parent) = match link.parent {
                Some(p) => (self.velocity[p], self.acceleration[p]),
                None => (SpatialVec::zeros(), -gravity),
            };
            let (mut joint_velocity, mut joint_acceleration) = (SpatialVec::zeros(), SpatialVec::zeros());
            let dofs = link.dof_adr..link.dof_adr + link.ndof;
            for (k, d) in dofs.clone().enumerate() {
                let s = x.apply_inverse_motion(&link.motion_subspace.column(k).into_owned());
                let psi_dot = cross_motion(&v_parent, &s);
                self.subspace[d] = s;
                self.psi_dot[d] = psi_dot;
                self.psi_ddot[d] = cross_motion(&a_parent, &s) + cross_motion(&v_parent, &psi_dot);
                joint_velocity += s * ws.qvel[d];
                joint_acceleration += s * ws.qacc[d];
            }
            let v = v_parent + joint_velocity;
            for d in dofs {
                self.rate_terms[d] = cross_motion(&v, &self.subspace[d]) + self.psi_dot[d];
            }
            let a = a_parent + cross_motion(&v_parent, &joint_velocity) + joint_acceleration;
            let y = world_inertia(link, x);
            let momentum = inertia_times(&y, &v);
            self.force[i] = inertia_times(&y, &a) + cross_force(&v, &momentum);
            self.coriolis[i] = coriolis_matrix(&y, &v, &momentum);
            self.inertia[i] = y;
            self.velocity[i] = v;
            self.acceleration[i] = a;
        }
    }

    /// Tip to base: I^C, 2B^C and F over each subtree (plain sums: one frame).
    fn inward_sweep(&mut self, model: &Model) {
        for i in (0..model.links.len()).rev() {
            if let Some(p) = model.links[i].parent {
                let (parents, children) = self.inertia.split_at_mut(i);
                parents[p] += children[0];
                let (parents, children) = self.coriolis.split_at_mut(i);
                parents[p] += children[0];
                let child_force = self.force[i];
                self.force[p] += child_force;
            }
        }
    }

    /// ∂τ_passive/∂x − ∂ID/∂x for x = Δ and θ̇: for each dof a (row) of
    /// link k and each dof b of an ancestor-or-self j of k, entry (a, b)
    /// (a in b's subtree) and, when j is a strict ancestor, entry (b, a).
    fn torque_derivatives(&mut self, model: &Model) {
        for (k, link) in model.links.iter().enumerate() {
            let (inertia, coriolis) = (&self.inertia[k], &self.coriolis[k]);
            for d in link.dof_adr..link.dof_adr + link.ndof {
                let s = &self.subspace[d];
                self.inertia_s[d] = inertia_times(inertia, s);
                self.coriolis_t_s[d] = coriolis_transpose_times(coriolis, s);
                self.ancestor_by_delta[d] = cross_force(s, &self.force[k])
                    + inertia_times(inertia, &self.psi_ddot[d])
                    + coriolis_times(coriolis, &self.psi_dot[d]);
                self.ancestor_by_qvel[d] = inertia_times(inertia, &self.rate_terms[d]) + coriolis_times(coriolis, s);
            }
        }
        let nv = model.nv;
        let by_delta = self.torque_by_delta.as_mut_slice();
        let by_qvel = self.torque_by_qvel.as_mut_slice();
        by_delta.fill(0.0);
        by_qvel.fill(0.0);
        for (k, link) in model.links.iter().enumerate() {
            let mut ancestor = Some(k);
            while let Some(j) = ancestor {
                let ancestor_link = &model.links[j];
                for a in link.dof_adr..link.dof_adr + link.ndof {
                    let (inertia_s, coriolis_t_s) = (&self.inertia_s[a], &self.coriolis_t_s[a]);
                    for b in ancestor_link.dof_adr..ancestor_link.dof_adr + ancestor_link.ndof {
                        by_delta[a + b * nv] = -(inertia_s.dot(&self.psi_ddot[b]) + coriolis_t_s.dot(&self.psi_dot[b]));
                        by_qvel[a + b * nv] =
                            -(inertia_s.dot(&self.rate_terms[b]) + coriolis_t_s.dot(&self.subspace[b]));
                        if j != k {
                            by_delta[b + a * nv] = -self.subspace[b].dot(&self.ancestor_by_delta[a]);
                            by_qvel[b + a * nv] = -self.subspace[b].dot(&self.ancestor_by_qvel[a]);
                        }
                    }
                }
                ancestor = ancestor_link.parent;
            }
            // Springs −k(θ − θ_spring) (ball joints' are refused) and dampers −b θ̇.
            for d in link.dof_adr..link.dof_adr + link.ndof {
                if !model.shortcuts.no_springs {
                    by_delta[d + d * nv] -= link.stiffness;
                }
                if !model.shortcuts.no_dampers {
                    by_qvel[d + d * nv] -= link.damping;
                }
            }
        }
    }
}

/// How a joint actuator's force on its dof changes: per unit of the dof's
/// θ, θ̇ and of ctrl (each 0 where a clamp holds the piece, as the passes'
/// own clamps give it).
struct JointActuatorSlopes {
    by_length: f64,
    by_velocity: f64,
    by_ctrl: f64,
}

/// An actuator's force per unit of ctrl, length and velocity: actuation.rs's
/// force law and clamps in dual numbers, seeded in each in turn.
fn force_slopes(model: &Model, actuator: &Actuator, ctrl: f64, length: f64, velocity: f64) -> [f64; 3] {
    std::array::from_fn(|seeded| {
        let at = |value: f64, k: usize| Dual64::new(value, if k == seeded { 1.0 } else { 0.0 });
        let input = actuation::clamped_ctrl(actuator, model.actuation.clamp_ctrl, at(ctrl, 0));
        actuation::clamp_force(actuator, actuation::unclamped_force(actuator, input, at(length, 1), at(velocity, 2)))
            .eps
    })
}

/// A joint actuator's slopes and its dof (None for another actuator or when
/// actuation is off): its force on the dof is gear × the force of length
/// gear·θ and velocity gear·θ̇.
fn joint_actuator_slopes(
    model: &Model,
    actuator: &Actuator,
    ws: &Workspace,
    ctrl: f64,
) -> Option<(usize, JointActuatorSlopes)> {
    let ActuatorTransmission::Scalar { dof, qpos } = actuator.transmission else { return None };
    if !model.actuation.enabled {
        return None;
    }
    let gear = actuator.gear[0];
    let [by_ctrl, by_length, by_velocity] =
        force_slopes(model, actuator, ctrl, gear * ws.theta[qpos], gear * ws.qvel[dof]);
    Some((
        dof,
        JointActuatorSlopes {
            by_length: gear * by_length * gear,
            by_velocity: gear * by_velocity * gear,
            by_ctrl: gear * by_ctrl,
        },
    ))
}

/// A site actuator's force per unit ctrl (None for another actuator or when
/// actuation is off); the covered ones read neither length nor velocity.
fn site_force_per_ctrl(model: &Model, actuator: &Actuator, ctrl: f64) -> Option<f64> {
    let site = matches!(actuator.transmission, ActuatorTransmission::Site { .. });
    (site && model.actuation.enabled).then(|| force_slopes(model, actuator, ctrl, 0.0, 0.0)[0])
}

impl AppliedEps {
    /// Each link's world I^a, U, R, z and f for `eps`, given the world G.
    fn prepare(&mut self, model: &Model, ws: &Workspace, gain: &[LinkCols], eps: &[f64]) {
        for (i, link) in model.links.iter().enumerate() {
            match link.ndof {
                1 => self.prepare_link::<1>(model, ws, &gain[i], i, eps),
                _ => self.prepare_link::<3>(model, ws, &gain[i], i, eps),
            }
        }
    }

    /// [`AppliedEps::prepare`] for link i with N dofs.
    fn prepare_link<const N: usize>(&mut self, model: &Model, ws: &Workspace, gain: &LinkCols, i: usize, eps: &[f64]) {
        let (link, x) = (&model.links[i], &ws.x_world[i]);
        let r = block::<_, N>(&ws.r_joint[i]);
        let gain_n = cols::<_, N>(gain);
        let e = SVector::<f64, N>::from_column_slice(&eps[link.dof_adr..link.dof_adr + N]);
        let z = block::<_, N>(&ws.r_inv_joint[i]).transpose() * e;
        let joint_force = gain_n * (r * r.transpose());
        self.link_force[i] = gain_n * (r * e);
        self.joint_force[i].fixed_columns_mut::<N>(0).copy_from(&joint_force);
        self.r[i].fixed_view_mut::<N, N>(0, 0).copy_from(&r);
        self.z[i].fixed_rows_mut::<N>(0).copy_from(&z);
        if link.parent.is_some() {
            x.add_inertia_to_parent(&ws.ia_reduced[i], &mut self.reduced_inertia[i], true);
        }
    }

    /// Adds ∂T_ε/∂Δ to `by_delta`, column by column: each dof's walk up its
    /// link's ancestors.
    fn add_derivatives(&self, model: &Model, subspace: &[SpatialVec], gain: &[LinkCols], by_delta: &mut DMatrix<f64>) {
        for (j, link) in model.links.iter().enumerate() {
            let Some(parent) = link.parent else { continue };
            for column in link.dof_adr..link.dof_adr + link.ndof {
                let s = &subspace[column];
                let mut turned = SpatialMat::zeros();
                for c in 0..6 {
                    turned.set_column(c, &cross_force(s, &self.reduced_inertia[j].column(c).into_owned()));
                }
                // δI^A of j's parent: s ×* I^a_j − I^a_j s× = turned + turnedᵀ.
                let mut inertia_change = turned + turned.transpose();
                let mut force_changes = SpatialVec::zeros();
                let mut ancestor = Some(parent);
                while let Some(k) = ancestor {
                    let ancestor_link = &model.links[k];
                    let subspace_k = &subspace[ancestor_link.dof_adr..ancestor_link.dof_adr + ancestor_link.ndof];
                    let (force_change, own_change) = match ancestor_link.ndof {
                        1 => self.force_change::<1>(k, subspace_k, &inertia_change),
                        _ => self.force_change::<3>(k, subspace_k, &inertia_change),
                    };
                    // k's own row takes its own term as δ(Rε), the others' f through S.
                    for (r, s_k) in subspace_k.iter().enumerate() {
                        by_delta[(ancestor_link.dof_adr + r, column)] += s_k.dot(&force_changes) + own_change[r];
                    }
                    force_changes += force_change;
                    ancestor = ancestor_link.parent;
                    if ancestor.is_some() {
                        inertia_change = match ancestor_link.ndof {
                            1 => project::<1>(&gain[k], subspace_k, &inertia_change),
                            _ => project::<3>(&gain[k], subspace_k, &inertia_change),
                        };
                    }
                }
            }
        }
    }

    /// δf_k = δU z + U δz for link k with N dofs (world S `subspace`) whose
    /// I^A changes by `change`, and the change δR ε of its own row's term
    /// Rε (which is not Sᵀf: D has the armature, SᵀU does not).
    fn force_change<const N: usize>(
        &self,
        k: usize,
        subspace: &[SpatialVec],
        change: &SpatialMat,
    ) -> (SpatialVec, Vec3) {
        let s = SMatrix::<f64, 6, N>::from_fn(|row, col| subspace[col][row]);
        let joint_force_change = change * s;
        let d_change = s.transpose() * joint_force_change;
        let r = block::<_, N>(&self.r[k]);
        let (r_inv, z) =
            (upper_triangular_inverse(&r), SVector::<f64, N>::from_column_slice(&self.z[k].as_slice()[..N]));
        let r_change = r * upper_half(&(r_inv * d_change * r_inv.transpose()));
        let z_change = -(r_inv.transpose() * (r_change.transpose() * z));
        // ε = Rᵀz.
        let own = r_change * (r.transpose() * z);
        let mut own_change = Vec3::zeros();
        own_change.fixed_rows_mut::<N>(0).copy_from(&own);
        (joint_force_change * z + cols::<_, N>(&self.joint_force[k]) * z_change, own_change)
    }
}

/// P δI^A Pᵀ, P = 1 − G Sᵀ: a link's change (its world G and S) handed to its parent.
#[inline(always)]
fn project<const N: usize>(gain: &LinkCols, subspace: &[SpatialVec], change: &SpatialMat) -> SpatialMat {
    let s = SMatrix::<f64, 6, N>::from_fn(|row, col| subspace[col][row]);
    let p = SpatialMat::identity() - cols::<_, N>(gain) * s.transpose();
    p * change * p.transpose()
}

/// Columns taken together by [`FactorPasses`]: independent sums enough to
/// hide the latency of each path's chain of sums, few enough for a link's
/// six rows to stay in the first-level cache.
const LANES: usize = 8;
/// A row of a block: its columns, in 4-wide vectors (`wide`: explicit
/// SIMD, which the compiler did not find in plain loops over the columns).
type Lanes = [f64x4; LANES / 4];
const ZERO_LANES: Lanes = [f64x4::ZERO; LANES / 4];

/// acc += a x over the first W vectors of a row (a block of 4·W columns).
#[inline(always)]
fn add_scaled<const W: usize>(acc: &mut Lanes, a: f64, x: &Lanes) {
    let a = f64x4::splat(a);
    for (s, v) in acc.iter_mut().zip(x).take(W) {
        *s += a * *v;
    }
}

/// The entry of `row` in column `w`.
#[inline(always)]
fn lane(row: &mut Lanes, w: usize) -> &mut f64 {
    &mut row[w / 4].as_array_mut()[w % 4]
}

/// ℓ = m⁻¹ and ℓᵀ applied to a matrix by passes over the links, a block
/// of [`LANES`] columns at a time: forces.rs's inward pass from joint
/// forces to ε (ℓ) and its adjoint outward (ℓᵀ), both in world
/// coordinates, where a link hands its sums to its parent without a
/// transform. Per link i and column, ℓ:
///
///   u = t_i − S_iᵀ p_i,   (ℓt)_i = R_i⁻¹ u,   p_λ += p_i + G_i u;
///
/// ℓᵀ, base to tip, a_0 = 0:
///
///   (ℓᵀx)_i = R_i⁻ᵀ x_i + G_iᵀ a_λ,   a_i = a_λ − S_i (ℓᵀx)_i.
///
/// About 13 products per dof and column each, against a dense product's
/// nv/2 per dof (a chain's ℓ is a full triangle).
#[derive(Clone, Debug)]
struct FactorPasses {
    /// Each link's G (6 × its dofs) in world coordinates, and R⁻¹.
    gain: Vec<LinkCols>,
    r_inv: Vec<Mat3>,
    /// Per link: the inward pass's p (its children's sums) and the
    /// outward pass's a.
    inward: Vec<[Lanes; 6]>,
    outward: Vec<[Lanes; 6]>,
    /// Per link: whether it has children (else its p is zero, and its slot
    /// is not read), and whether it is the first of its parent's children
    /// the inward pass reaches (which writes the parent's p, the others add).
    has_children: Vec<bool>,
    first_child: Vec<bool>,
    /// Per dof, the block's rows: t, then ℓt, then ℓᵀℓt.
    rows: Vec<Lanes>,
}

impl FactorPasses {
    fn new(model: &Model) -> Self {
        let n = model.links.len();
        let (mut has_children, mut first_child) = (vec![false; n], vec![false; n]);
        for i in (0..n).rev() {
            if let Some(p) = model.links[i].parent {
                first_child[i] = !has_children[p];
                has_children[p] = true;
            }
        }
        FactorPasses {
            gain: vec![LinkCols::zeros(); n],
            r_inv: vec![Mat3::zeros(); n],
            inward: vec![[ZERO_LANES; 6]; n],
            outward: vec![[ZERO_LANES; 6]; n],
            rows: vec![ZERO_LANES; model.nv],
            has_children,
            first_child,
        }
    }

    /// G in world coordinates and R⁻¹ from the passes at the point.
    fn prepare(&mut self, model: &Model, ws: &Workspace) {
        for (i, link) in model.links.iter().enumerate() {
            for k in 0..link.ndof {
                let column = ws.x_world[i].apply_transpose_force(&ws.gain[i].column(k).into_owned());
                self.gain[i].set_column(k, &column);
            }
            self.r_inv[i] = ws.r_inv_joint[i];
        }
    }

    /// `outs` = ℓᵀℓ `ts` = M⁻¹ `ts` (each pair nv × the same columns), or
    /// ℓᵀ `ts` alone when `adjoint_only`; the pairs' columns taken as one
    /// matrix's, so that small vehicles fill a block.
    fn apply<const K: usize>(
        &mut self,
        model: &Model,
        subspace: &[SpatialVec],
        ts: [&DMatrix<f64>; K],
        outs: [&mut DMatrix<f64>; K],
        adjoint_only: bool,
    ) {
        let (nv, per) = ts[0].shape();
        let columns = per * K;
        for first in (0..columns).step_by(LANES) {
            let width = LANES.min(columns - first);
            for w in 0..LANES {
                if w < width {
                    let column = &ts[(first + w) / per].as_slice()[(first + w) % per * nv..][..nv];
                    for (row, x) in self.rows.iter_mut().zip(column) {
                        *lane(row, w) = *x;
                    }
                } else {
                    self.rows.iter_mut().for_each(|row| *lane(row, w) = 0.0);
                }
            }
            // A last block of at most four columns takes half the work.
            match width {
                5.. => self.passes::<{ LANES / 4 }>(model, subspace, adjoint_only),
                _ => self.passes::<1>(model, subspace, adjoint_only),
            }
            for w in 0..width {
                let column = &mut outs[(first + w) / per].as_mut_slice()[(first + w) % per * nv..][..nv];
                for (x, row) in column.iter_mut().zip(self.rows.iter_mut()) {
                    *x = *lane(row, w);
                }
            }
        }
    }

    /// ℓ (unless `adjoint_only`), then ℓᵀ, on the block's first 4·W columns.
    #[inline(always)]
    fn passes<const W: usize>(&mut self, model: &Model, subspace: &[SpatialVec], adjoint_only: bool) {
        if !adjoint_only {
            for i in (0..model.links.len()).rev() {
                match model.links[i].ndof {
                    1 => self.inward_link::<1, W>(model, subspace, i),
                    _ => self.inward_link::<3, W>(model, subspace, i),
                }
            }
        }
        for i in 0..model.links.len() {
            match model.links[i].ndof {
                1 => self.outward_link::<1, W>(model, subspace, i),
                _ => self.outward_link::<3, W>(model, subspace, i),
            }
        }
    }

    /// ℓ's step at link i with N dofs.
    #[inline(always)]
    fn inward_link<const N: usize, const W: usize>(&mut self, model: &Model, subspace: &[SpatialVec], i: usize) {
        let link = &model.links[i];
        let adr = link.dof_adr;
        let (before, from_i) = self.inward.split_at_mut(i);
        let p = self.has_children[i].then_some(&from_i[0]);
        let mut u = [ZERO_LANES; N];
        for (d, u_d) in u.iter_mut().enumerate() {
            *u_d = self.rows[adr + d];
            if let Some(p) = p {
                for (s, p_k) in subspace[adr + d].iter().zip(p) {
                    add_scaled::<W>(u_d, -s, p_k);
                }
            }
        }
        for d in 0..N {
            let mut e = ZERO_LANES;
            for (c, u_c) in u.iter().enumerate() {
                add_scaled::<W>(&mut e, self.r_inv[i][(d, c)], u_c);
            }
            self.rows[adr + d] = e;
        }
        let Some(parent) = link.parent else { return };
        for (k, handed) in before[parent].iter_mut().enumerate() {
            let mut sum = p.map_or(ZERO_LANES, |p| p[k]);
            for (c, u_c) in u.iter().enumerate() {
                add_scaled::<W>(&mut sum, self.gain[i][(k, c)], u_c);
            }
            if self.first_child[i] {
                *handed = sum;
            } else {
                for (x, y) in handed.iter_mut().zip(&sum).take(W) {
                    *x += *y;
                }
            }
        }
    }

    /// ℓᵀ's step at link i with N dofs.
    #[inline(always)]
    fn outward_link<const N: usize, const W: usize>(&mut self, model: &Model, subspace: &[SpatialVec], i: usize) {
        let link = &model.links[i];
        let adr = link.dof_adr;
        let (before, from_i) = self.outward.split_at_mut(i);
        let a_parent = link.parent.map(|parent| &before[parent]);
        let mut y = [ZERO_LANES; N];
        for (d, y_d) in y.iter_mut().enumerate() {
            for c in 0..N {
                add_scaled::<W>(y_d, self.r_inv[i][(c, d)], &self.rows[adr + c]);
            }
            if let Some(a_parent) = a_parent {
                for (k, a_k) in a_parent.iter().enumerate() {
                    add_scaled::<W>(y_d, self.gain[i][(k, d)], a_k);
                }
            }
        }
        for (k, a_k) in from_i[0].iter_mut().enumerate() {
            let mut sum = a_parent.map_or(ZERO_LANES, |a| a[k]);
            for (d, y_d) in y.iter().enumerate() {
                add_scaled::<W>(&mut sum, -subspace[adr + d][k], y_d);
            }
            *a_k = sum;
        }
        self.rows[adr..adr + N].copy_from_slice(&y);
    }
}

/// The link's spatial inertia in world coordinates about the world origin,
/// from its ten numbers (the congruence Xᵀ Y X for a rigid body): with E
/// the link's rotation and r its origin (world), h = Eᵀh_link + m r and
/// Ī = Eᵀ Ī_link E − ĥ′ r̂ − r̂ ĥ′ − m r̂ r̂ (h′ = Eᵀh_link, the parallel-axis
/// shift), the last three terms by âb̂ = b aᵀ − (a·b) 1.
fn world_inertia(link: &crate::model::Link, x: &crate::math::Transform) -> SpatialMat {
    let rotated_moment = x.rot.transpose() * link.mass_moment;
    let r = &x.trans;
    let rotated = x.rot.transpose() * link.rotational_inertia * x.rot;
    let outer = r * rotated_moment.transpose();
    let mut rotational =
        (rotated + rotated.transpose()) * 0.5 - outer - outer.transpose() - r * r.transpose() * link.mass;
    let diagonal = 2.0 * rotated_moment.dot(r) + link.mass * r.norm_squared();
    for k in 0..3 {
        rotational[(k, k)] += diagonal;
    }
    let moment = skew(&(rotated_moment + r * link.mass));
    let mut out = SpatialMat::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotational);
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&moment);
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&moment.transpose());
    out.fixed_view_mut::<3, 3>(3, 3).fill_with_identity();
    out.fixed_view_mut::<3, 3>(3, 3).scale_mut(link.mass);
    out
}

/// h of a spatial inertia Y = [Ī ĥ; ĥᵀ m1], read off ĥ's entries.
#[inline(always)]
fn first_moment(y: &SpatialMat) -> Vec3 {
    Vec3::new(y[(2, 4)], y[(0, 5)], y[(1, 3)])
}

/// Y m for a spatial inertia Y = [Ī ĥ; ĥᵀ m1] (a body's, or a subtree's sum
/// of them) from its blocks: (Ī ω + h × u, m u − h × ω) for m = (ω, u).
#[inline(always)]
fn inertia_times(y: &SpatialMat, motion: &SpatialVec) -> SpatialVec {
    let h = first_moment(y);
    let (omega, u) = (angular(motion), linear(motion));
    spatial(&(y.fixed_view::<3, 3>(0, 0) * omega + h.cross(&u)), &(u * y[(3, 3)] - h.cross(&omega)))
}

/// 2B w, 2B's lower right block being zero ([`coriolis_matrix`]).
#[inline(always)]
fn coriolis_times(b: &SpatialMat, w: &SpatialVec) -> SpatialVec {
    let (top, bottom) = (angular(w), linear(w));
    spatial(
        &(b.fixed_view::<3, 3>(0, 0) * top + b.fixed_view::<3, 3>(0, 3) * bottom),
        &(b.fixed_view::<3, 3>(3, 0) * top),
    )
}

/// (2B)ᵀ s, as [`coriolis_times`].
#[inline(always)]
fn coriolis_transpose_times(b: &SpatialMat, s: &SpatialVec) -> SpatialVec {
    let (top, bottom) = (angular(s), linear(s));
    spatial(
        &(b.fixed_view::<3, 3>(0, 0).tr_mul(&top) + b.fixed_view::<3, 3>(3, 0).tr_mul(&bottom)),
        &b.fixed_view::<3, 3>(0, 3).tr_mul(&top),
    )
}

/// 2B for inertia `y` at velocity `v` (`momentum` = Y v): the matrix of
/// w ↦ v ×* Y w − Y (v × w) + w ×* Y v, the change of f = Y a + v ×* Y v
/// with v along w when a changes by −v × w. As (v×)ᵀ = −v×*, the first two
/// terms are P + Pᵀ with P = v ×* Y, built from Y's blocks [Ī ĥ; ĥᵀ m]:
/// with v = (ω, u), P = [ω̂Ī − ûĥ, ω̂ĥ + m û; −ω̂ĥ, m ω̂], where
/// âĥ = h aᵀ − (a·h) 1.
fn coriolis_matrix(y: &SpatialMat, v: &SpatialVec, momentum: &SpatialVec) -> SpatialMat {
    let (omega, u) = (angular(v), linear(v));
    let rotational = y.fixed_view::<3, 3>(0, 0);
    let h = first_moment(y);
    let mass = y[(3, 3)];
    let skew_product = |a: &Vec3| {
        let mut out = h * a.transpose();
        let dot = a.dot(&h);
        for k in 0..3 {
            out[(k, k)] -= dot;
        }
        out
    };
    let (omega_h, u_h) = (skew_product(&omega), skew_product(&u));
    let mut omega_rotational = Mat3::zeros();
    for k in 0..3 {
        omega_rotational.set_column(k, &omega.cross(&rotational.column(k)));
    }
    let u_hat = skew(&u);
    let top_left = omega_rotational - u_h;
    let top_right = omega_h + u_hat * mass;
    // P + Pᵀ by blocks, then w ×* h = [−ĥ_ang −ĥ_lin; −ĥ_lin 0] w.
    let (h_ang, h_lin) = (skew(&angular(momentum)), skew(&linear(momentum)));
    let mut out = SpatialMat::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(top_left + top_left.transpose() - h_ang));
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(top_right - omega_h.transpose() - h_lin));
    out.fixed_view_mut::<3, 3>(3, 0).copy_from(&(top_right.transpose() - omega_h - h_lin));
    // m ω̂ + (m ω̂)ᵀ = 0.
    out
}
