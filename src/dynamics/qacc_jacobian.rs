//! ∂θ̈/∂Δ and ∂θ̈/∂θ̇ in closed form, for a rigid tree whose forces are
//! gravity, joint springs and dampers and constant joint forces T: the
//! derivatives of the inverse dynamics τ = ID(θ, θ̇, θ̈) in world
//! coordinates, a few 6-vector products per pair of a joint and its
//! ancestor, then θ̈'s through the mass matrix,
//!
//!   ∂θ̈/∂x = M⁻¹ (∂τ_passive/∂x − ∂ID/∂x |θ̈ held),
//!
//! M⁻¹ from the factor of pass 1 (ℓ*ℓ: one inward and one outward pass per
//! column). The same derivatives as derivatives.rs's dual numbers give (to
//! round-off), at a fraction of their cost: derivatives.rs runs every pass
//! once per column; this runs the passes once and then O(N·depth) products.
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
//! An applied ε, whose joint forces m(θ)ε turn with the configuration,
//! would need the factor's own derivatives, as would every force whose
//! law reads the configuration beyond the joints' springs (actuators,
//! tendons, gravity compensation, constraint rows, flexible bodies): such
//! models and points are refused, and derivatives.rs serves them.

use nalgebra::{DMatrix, SVector};

use super::derivatives::DerivativeError;
use super::forces::eps_of_torque;
use super::{block, cols};
use crate::math::{
    SpatialMat, SpatialVec, Vec3, angular, cross_force, cross_motion, linear, mul_cross_motion, skew, spatial,
};
use crate::model::{LinkJoint, Model};
use crate::workspace::{LinkCols, Workspace};

/// The passes at the point and the buffers of the closed form, allocated
/// once so that a Jacobian allocates nothing.
#[derive(Clone, Debug)]
pub struct QaccJacobian {
    ws: Workspace,
    /// ε of the joint forces T, ℓ(θ)T.
    eps_of_torque: Vec<f64>,
    /// Per link, world coordinates: S (its first `ndof` columns).
    subspace: Vec<LinkCols>,
    /// Ψ̇ = v_λ × S.
    psi_dot: Vec<LinkCols>,
    /// Ψ̈ = a_λ × S + v_λ × Ψ̇.
    psi_ddot: Vec<LinkCols>,
    /// Ṡ + Ψ̇, the change of the subtree's accelerations per unit θ̇ but for s × v_b.
    rate_terms: Vec<LinkCols>,
    velocity: Vec<SpatialVec>,
    acceleration: Vec<SpatialVec>,
    /// I^C, 2B^C and F: each link's own term, then (after the inward sweep) its subtree's.
    inertia: Vec<SpatialMat>,
    coriolis: Vec<SpatialMat>,
    force: Vec<SpatialVec>,
    /// ∂τ_passive/∂Δ − ∂ID/∂Δ and the same in θ̇ (nv × nv).
    torque_by_delta: DMatrix<f64>,
    torque_by_qvel: DMatrix<f64>,
    mass_inverse: DMatrix<f64>,
    /// A unit joint force, its ε, and the outward pass's accelerations.
    unit: Vec<f64>,
    unit_eps: Vec<f64>,
    outward: Vec<SpatialVec>,
}

impl QaccJacobian {
    /// Whether the closed form covers `model`: what it has that the form leaves out.
    pub fn check(model: &Model) -> Result<(), DerivativeError> {
        let ball_springs =
            !model.shortcuts.no_springs && model.links.iter().any(|l| l.joint == LinkJoint::Ball && l.stiffness != 0.0);
        let unsupported = [
            (!model.flexible.is_empty(), "flexible bodies"),
            (!model.actuators.is_empty(), "actuators"),
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
            subspace: vec![LinkCols::zeros(); n],
            psi_dot: vec![LinkCols::zeros(); n],
            psi_ddot: vec![LinkCols::zeros(); n],
            rate_terms: vec![LinkCols::zeros(); n],
            velocity: vec![SpatialVec::zeros(); n],
            acceleration: vec![SpatialVec::zeros(); n],
            inertia: vec![SpatialMat::zeros(); n],
            coriolis: vec![SpatialMat::zeros(); n],
            force: vec![SpatialVec::zeros(); n],
            torque_by_delta: DMatrix::zeros(nv, nv),
            torque_by_qvel: DMatrix::zeros(nv, nv),
            mass_inverse: DMatrix::zeros(nv, nv),
            unit: vec![0.0; nv],
            unit_eps: vec![0.0; nv],
            outward: vec![SpatialVec::zeros(); n],
        })
    }

    /// ∂θ̈/∂Δ (Δ in the tangent space, as derivatives.rs's) into `by_delta`
    /// and ∂θ̈/∂θ̇ into `by_qvel` (nv × nv each) at (θ, θ̇) under constant
    /// joint forces `torque`; `eps` must be zero (see the module's text).
    pub fn compute(
        &mut self,
        model: &Model,
        (theta, qvel): (&[f64], &[f64]),
        (eps, torque): (&[f64], &[f64]),
        (by_delta, by_qvel): (&mut DMatrix<f64>, &mut DMatrix<f64>),
    ) -> Result<(), DerivativeError> {
        if eps.iter().any(|e| *e != 0.0) {
            return Err(DerivativeError::Unsupported("an applied ε (its joint forces m(θ)ε turn with θ)"));
        }
        let ws = &mut self.ws;
        ws.set_configuration(model, theta)?;
        ws.set_qvel(model, qvel)?;
        ws.eps_from_forces(model, torque, None, &mut self.eps_of_torque)?;
        ws.compute_qacc(model, &self.eps_of_torque)?;
        ws.world_transforms(model);
        self.outward_sweep(model);
        self.inward_sweep(model);
        self.torque_derivatives(model);
        self.mass_inverse(model);
        by_delta.gemm(1.0, &self.mass_inverse, &self.torque_by_delta, 0.0);
        by_qvel.gemm(1.0, &self.mass_inverse, &self.torque_by_qvel, 0.0);
        Ok(())
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
            for k in 0..link.ndof {
                let s = x.apply_inverse_motion(&link.motion_subspace.column(k).into_owned());
                let psi_dot = cross_motion(&v_parent, &s);
                self.subspace[i].set_column(k, &s);
                self.psi_dot[i].set_column(k, &psi_dot);
                self.psi_ddot[i].set_column(k, &(cross_motion(&a_parent, &s) + cross_motion(&v_parent, &psi_dot)));
                joint_velocity += s * ws.qvel[link.dof_adr + k];
                joint_acceleration += s * ws.qacc[link.dof_adr + k];
            }
            let v = v_parent + joint_velocity;
            for k in 0..link.ndof {
                let s = self.subspace[i].column(k).into_owned();
                self.rate_terms[i].set_column(k, &(cross_motion(&v, &s) + self.psi_dot[i].column(k)));
            }
            let a = a_parent + cross_motion(&v_parent, &joint_velocity) + joint_acceleration;
            let mut y = SpatialMat::zeros();
            x.add_inertia_to_parent(&link.spatial_inertia(), &mut y, true);
            let momentum = y * v;
            self.force[i] = y * a + cross_force(&v, &momentum);
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

    /// ∂τ_passive/∂x − ∂ID/∂x for x = Δ and θ̇: for each link k, the
    /// entries of its rows and each ancestor-or-self j's columns (k in j's
    /// subtree), and of j's rows and k's columns (j a strict ancestor).
    fn torque_derivatives(&mut self, model: &Model) {
        self.torque_by_delta.fill(0.0);
        self.torque_by_qvel.fill(0.0);
        for (k, link) in model.links.iter().enumerate() {
            let (adr_k, n_k) = (link.dof_adr, link.ndof);
            let s_k = &self.subspace[k];
            // I^C_k S_k and (2B^C_k)ᵀ S_k: S_kᵀ I^C_k and S_kᵀ 2B^C_k as columns.
            let inertia_s: LinkCols = self.inertia[k] * s_k;
            let coriolis_t_s: LinkCols = self.coriolis[k].transpose() * s_k;
            // k's columns seen from its strict ancestors' rows.
            let mut by_delta_terms = LinkCols::zeros();
            let mut by_qvel_terms = LinkCols::zeros();
            for c in 0..n_k {
                let s = s_k.column(c).into_owned();
                by_delta_terms.set_column(
                    c,
                    &(cross_force(&s, &self.force[k])
                        + self.inertia[k] * self.psi_ddot[k].column(c)
                        + self.coriolis[k] * self.psi_dot[k].column(c)),
                );
                by_qvel_terms.set_column(c, &(self.inertia[k] * self.rate_terms[k].column(c) + self.coriolis[k] * s));
            }
            let mut ancestor = Some(k);
            while let Some(j) = ancestor {
                let (adr_j, n_j) = (model.links[j].dof_adr, model.links[j].ndof);
                for r in 0..n_k {
                    for c in 0..n_j {
                        self.torque_by_delta[(adr_k + r, adr_j + c)] -=
                            inertia_s.column(r).dot(&self.psi_ddot[j].column(c))
                                + coriolis_t_s.column(r).dot(&self.psi_dot[j].column(c));
                        self.torque_by_qvel[(adr_k + r, adr_j + c)] -=
                            inertia_s.column(r).dot(&self.rate_terms[j].column(c))
                                + coriolis_t_s.column(r).dot(&self.subspace[j].column(c));
                    }
                }
                if j != k {
                    for r in 0..n_j {
                        let s_j = self.subspace[j].column(r);
                        for c in 0..n_k {
                            self.torque_by_delta[(adr_j + r, adr_k + c)] -= s_j.dot(&by_delta_terms.column(c));
                            self.torque_by_qvel[(adr_j + r, adr_k + c)] -= s_j.dot(&by_qvel_terms.column(c));
                        }
                    }
                }
                ancestor = model.links[j].parent;
            }
            // Springs −k(θ − θ_spring) (ball joints' are refused) and dampers −b θ̇.
            for d in adr_k..adr_k + n_k {
                if !model.shortcuts.no_springs {
                    self.torque_by_delta[(d, d)] -= link.stiffness;
                }
                if !model.shortcuts.no_dampers {
                    self.torque_by_qvel[(d, d)] -= link.damping;
                }
            }
        }
    }

    /// M⁻¹ = ℓ*ℓ column by column: ε = ℓ e_c by the inward pass of
    /// forces.rs, then θ̈ = ℓ*ε outward.
    fn mass_inverse(&mut self, model: &Model) {
        for c in 0..model.nv {
            self.unit[c] = 1.0;
            eps_of_torque(model, &mut self.ws, &self.unit, &mut self.unit_eps);
            self.unit[c] = 0.0;
            for (i, link) in model.links.iter().enumerate() {
                let a_plus =
                    link.parent.map_or(SpatialVec::zeros(), |p| self.ws.x_parent[i].apply_motion(&self.outward[p]));
                let column = self.mass_inverse.column_mut(c);
                self.outward[i] = match link.ndof {
                    1 => outward_link::<1>(model, &self.ws, i, &self.unit_eps, a_plus, column),
                    _ => outward_link::<3>(model, &self.ws, i, &self.unit_eps, a_plus, column),
                };
            }
        }
    }
}

/// ℓ* for one link with N dofs: θ̈_i = R_i⁻ᵀε_i − G_iᵀA⁺ into `out`; returns A_i = A⁺ + S θ̈_i.
fn outward_link<const N: usize>(
    model: &Model,
    ws: &Workspace,
    i: usize,
    eps: &[f64],
    a_plus: SpatialVec,
    mut out: nalgebra::DVectorViewMut<f64>,
) -> SpatialVec {
    let link = &model.links[i];
    let adr = link.dof_adr;
    let e = SVector::<f64, N>::from_column_slice(&eps[adr..adr + N]);
    let qacc = block::<_, N>(&ws.r_inv_joint[i]).transpose() * e - cols::<_, N>(&ws.gain[i]).transpose() * a_plus;
    out.rows_mut(adr, N).copy_from(&qacc);
    a_plus + cols::<_, N>(&link.motion_subspace) * qacc
}

/// 2B for inertia `y` at velocity `v` (`momentum` = Y v): the matrix of
/// w ↦ v ×* Y w − Y (v × w) + w ×* Y v, the change of f = Y a + v ×* Y v
/// with v along w when a changes by −v × w.
fn coriolis_matrix(y: &SpatialMat, v: &SpatialVec, momentum: &SpatialVec) -> SpatialMat {
    let mut out = -mul_cross_motion(y, v);
    for c in 0..6 {
        let column = cross_force(v, &y.column(c).into_owned());
        let mut slot = out.column_mut(c);
        slot += column;
    }
    // w ×* h = (w_ang × h_ang + w_lin × h_lin, w_ang × h_lin) = [−h_ang× −h_lin×; −h_lin× 0] w.
    let (h_ang, h_lin) = (skew(&angular(momentum)), skew(&linear(momentum)));
    let mut block_at = |row: usize, col: usize, m: &nalgebra::Matrix3<f64>| {
        let mut view = out.fixed_view_mut::<3, 3>(row, col);
        view -= m;
    };
    block_at(0, 0, &h_ang);
    block_at(0, 3, &h_lin);
    block_at(3, 0, &h_lin);
    out
}
