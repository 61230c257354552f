//! Pass 3, tip to base: ν̇ = ε − C(θ,ν) + ε_passive (docs/DYNAMICS.md §4 pass 3).
//!
//! Velocity-product terms:
//!   p^A_i = V_i ×* I_i V_i + Σ_children Xᵀ p^a_c,   u_i = −Sᵀ p^A_i,
//!   p^a_i = p^A_i + I^a_i c_i + G_i u_i,
//!   İ^A_i = Σ_children Xᵀ [İ^a_c + v_J ×* I^a_c − I^a_c v_J ×] X,
//!   Ḋ = Sᵀ İ^A S,  Ġᵀ = D⁻¹(Sᵀ İ^A − Ḋ Gᵀ),  Ṙ = R Φ(R⁻¹ Ḋ R⁻ᵀ),
//!   İ^a_i = (1 − G Sᵀ) İ^A (1 − G Sᵀ)ᵀ,
//!   −C_i = R⁻¹ u_i + Ṙᵀ w_i + Rᵀ Ġᵀ V⁺_i.
//! Forces (springs, dampers, gravity, its compensation) run the same inward recursion without
//! velocities: u_i = τ_i − Sᵀ p_i, p^a = p + G u, ε_passive,i = R⁻¹ u_i;
//! a tendon's spring and damper enter τ as Jᵀf (`tendon`); a vehicle with
//! none of them (`Shortcuts::no_passive_forces`, no tendon spring or
//! damper) skips it.

use nalgebra::{SMatrix, SVector};

use super::subspace::{
    by_subspace, cross_s_times, mul_cross_s_times, s_transpose_times, s_transpose_times_columns, times_s,
};
use super::{accumulate, block, cols};
use crate::math::{
    Quat, Real, SpatialMat, SpatialVec, Vec3, cross_force, owned, quat_difference, real, spatial, times,
};
use crate::model::{LinkJoint, Model, MotionSubspace};
use crate::workspace::Workspace;

/// Springs −k(θ − θ_spring) and dampers −b θ̇, as MuJoCo applies them
/// (ball and free-joint rotations: −k times the rotation vector from the
/// spring pose, in the body frame), and the gravity compensation of the
/// joints without `actuatorgravcomp` (MuJoCo's qfrc_passive). Each term is
/// skipped when no joint has it.
pub(crate) fn passive_forces<S: Real>(model: &Model, ws: &mut Workspace<S>) {
    let shortcuts = model.shortcuts;
    for link in &model.links {
        let spring: Vec3<S> = if shortcuts.no_springs {
            Vec3::zeros()
        } else {
            let (q, qs) = (&ws.theta.as_slice()[link.qpos_adr..], &model.qpos_spring[link.qpos_adr..]);
            match link.joint {
                LinkJoint::Hinge | LinkJoint::Slide => Vec3::new(q[0] - qs[0], S::zero(), S::zero()),
                LinkJoint::Translation => Vec3::new(q[0] - qs[0], q[1] - qs[1], q[2] - qs[2]),
                LinkJoint::Ball => {
                    let spring_pose: [S; 4] = std::array::from_fn(|k| S::from(qs[k]));
                    let quat = |v: &[S]| Quat::from_quaternion(crate::math::quat_from_wxyz(v));
                    quat_difference(&quat(q), &quat(&spring_pose))
                }
            }
        };
        for k in 0..link.ndof {
            let dof = link.dof_adr + k;
            let damper = if shortcuts.no_dampers { S::zero() } else { ws.qvel[dof] * link.damping };
            ws.tau_passive[dof] = spring[k] * -link.stiffness - damper;
        }
    }
    if !model.flexible.is_empty() {
        super::flexible::passive_forces(model, ws);
    }
    if !model.gravity_compensation.is_empty() {
        let mut routed = model.gravity_compensation.actuator_dofs.iter().peekable();
        for dof in 0..model.nv {
            if routed.next_if_eq(&&dof).is_none() {
                ws.tau_passive[dof] += ws.qfrc_gravcomp[dof];
            }
        }
    }
}

/// Φ: the upper triangle with the diagonal halved (so Φ(X) + Φ(X)ᵀ = X for symmetric X).
pub(super) fn upper_half<S: Real, const N: usize>(x: &SMatrix<S, N, N>) -> SMatrix<S, N, N> {
    let mut out = x.upper_triangle();
    for k in 0..N {
        out[(k, k)] *= 0.5;
    }
    out
}

/// Pass 3 for one link with N dofs; `forces`: whether to run the recursion
/// of springs, dampers and gravity (else their ε is zero); `RATES`: whether
/// to add the factor's rates and so complete ν̇ and C (else only the joint
/// terms that θ̈ needs, without the İ^A recursion).
#[inline(always)]
fn bias_link<S: Real, const N: usize, const UNIT: usize, const RATES: bool, const FLEXIBLE: bool>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    eps: &[S],
    forces: bool,
) {
    let link = &model.links[i];
    let adr = link.dof_adr;
    let s = &link.motion_subspace;
    let gain = cols::<_, N>(&ws.gain[i]);
    let r = block::<_, N>(&ws.r_joint[i]);
    let r_inv = block::<_, N>(&ws.r_inv_joint[i]);
    let (v, v_plus) = (ws.v_body[i], ws.v_plus_body[i]);
    // v_J = S θ̇ and c = V × v_J = V⁺ × v_J, recomputed rather than stored
    // by pass 2: two fewer per-link arrays to stream on long chains; the
    // products with v_J take only its nonzero entries (subspace.rs).
    let qvel: SVector<S, N> = owned(ws.qvel.fixed_rows::<N>(adr));
    let has_children = ws.accumulation[i].gathers();
    // İ^A is zero for a link without children (its own inertia is constant in its frame).
    let ia_dot = (RATES && has_children).then(|| &ws.ia_dot_body[i]);

    // Velocity-product terms.
    let mut p_bias = cross_force(&v, &link.inertia_times(&v));
    if has_children {
        p_bias += ws.p_bias_body[i];
    }
    let u: SVector<S, N> = -s_transpose_times::<_, N, UNIT>(s, &p_bias);
    let joint_bias = times!(r_inv, u);
    // ν̇'s terms from the factor's rates, Ṙᵀw + RᵀĠᵀV⁺, which θ̈ does not need,
    // as products with vectors: Ṙᵀw = Φ(R⁻¹ḊR⁻ᵀ)ᵀ(Rᵀw), and RᵀD⁻¹ = R⁻¹ (D = RRᵀ),
    // so RᵀĠᵀV⁺ = R⁻¹((İ^A S)ᵀV⁺ − Ḋ(GᵀV⁺)).
    // Ṙ and Ġ themselves, N×N and N×6, are never formed: for a free base that
    // is four 6×6 products fewer.
    let rates = RATES.then(|| {
        let w: SVector<S, N> = owned(ws.w_joint.fixed_rows::<N>(adr));
        let ia_dot_s: SMatrix<S, 6, N> = ia_dot.map_or_else(SMatrix::zeros, |ia_dot| times_s::<_, N, UNIT>(ia_dot, s));
        let d_dot = s_transpose_times_columns::<_, N, UNIT>(s, &ia_dot_s);
        let turn = upper_half(&times!(times!(r_inv, d_dot), r_inv.transpose()));
        let gain_rate = times!(ia_dot_s.transpose(), v_plus) - times!(d_dot, times!(gain.transpose(), v_plus));
        (times!(turn.transpose(), times!(r.transpose(), w)) + times!(r_inv, gain_rate), ia_dot_s, d_dot)
    });

    // Springs, dampers and gravity.
    let p_force = if !forces {
        SpatialVec::zeros()
    } else {
        let mut p_force = if model.shortcuts.no_gravity {
            SpatialVec::zeros()
        } else {
            // Gravity is an external force m g at the centre of mass: p = −f_ext.
            let g_link = ws.x_world[i].rot * real::<S, 3, 1>(&model.gravity);
            -spatial(&real::<S, 3, 1>(&link.mass_moment).cross(&g_link), &(g_link * S::from(link.mass)))
        };
        if has_children {
            p_force += ws.p_force_body[i];
        }
        p_force
    };
    let u_force: SVector<S, N> = if forces {
        ws.tau_passive.fixed_rows::<N>(adr) - s_transpose_times::<_, N, UNIT>(s, &p_force)
    } else {
        SVector::zeros()
    };
    let eps_passive = times!(r_inv, u_force);

    for k in 0..N {
        ws.eps_passive[adr + k] = eps_passive[k];
        ws.nu_dot_joint[adr + k] = eps[adr + k] + eps_passive[k] + joint_bias[k];
    }
    if let Some((factor_rate, ..)) = &rates {
        for k in 0..N {
            let minus_c = joint_bias[k] + factor_rate[k];
            ws.coriolis[adr + k] = -minus_c;
            ws.nu_dot[adr + k] = eps[adr + k] + eps_passive[k] + minus_c;
        }
    }

    if let Some(p) = link.parent {
        let ia_reduced = &ws.ia_reduced[i];
        let opens_parent = ws.accumulation[i].opens_parent;
        let p_reduced = p_bias + times!(ia_reduced, cross_s_times::<_, N, UNIT>(&v_plus, s, &qvel)) + times!(gain, u);
        let node = if FLEXIBLE { ws.accumulation[i].node } else { None };
        if let Some(at) = node {
            // A child at a node hands its terms to the node (docs/flexible.md).
            let f_reduced = forces.then(|| p_force + times!(gain, u_force));
            let rate = rates.map(|(_, ia_dot_s, d_dot)| {
                child_inertia_rate::<_, N, UNIT>(ia_reduced, ia_dot, s, &qvel, &gain, &ia_dot_s, &d_dot)
            });
            super::flexible::child_bias(model, ws, at, opens_parent, p_reduced, f_reduced, rate.as_ref());
            return;
        }
        // The rigid path computes each term where it adds it (an Option of
        // the 6×6 child term, built and moved ahead of its use, cost bus_arm7's
        // ν̇ 8 % more instructions).
        let x = &ws.x_parent[i];
        accumulate(&mut ws.p_bias_body[p], x.apply_transpose_force(&p_reduced), opens_parent);
        if forces {
            accumulate(
                &mut ws.p_force_body[p],
                x.apply_transpose_force(&(p_force + times!(gain, u_force))),
                opens_parent,
            );
        }
        let Some((_, ia_dot_s, d_dot)) = rates else { return };
        let child_term = child_inertia_rate::<_, N, UNIT>(ia_reduced, ia_dot, s, &qvel, &gain, &ia_dot_s, &d_dot);
        x.add_inertia_to_parent(&child_term, &mut ws.ia_dot_body[p], opens_parent);
    }
}

/// The child's term İ^a + v_J ×* I^a − I^a v_J × of its parent's İ^A, as
/// İ^A − Q − Qᵀ: İ^a = (1 − G Sᵀ) İ^A (1 − G Sᵀ)ᵀ = İ^A − G A′ᵀ − A′ Gᵀ with
/// A′ = İ^A S − ½ G Ḋ (rank-N updates instead of two 6×6 products), and
/// v_J ×* I^a − I^a v_J × = −(B + Bᵀ) with B = I^a (v_J ×), I^a symmetric;
/// so Q = B + G A′ᵀ; v_J = S θ̇ with `qvel` the link's θ̇.
#[inline(always)]
fn child_inertia_rate<S: Real, const N: usize, const UNIT: usize>(
    ia_reduced: &SpatialMat<S>,
    ia_dot: Option<&SpatialMat<S>>,
    s: &MotionSubspace,
    qvel: &SVector<S, N>,
    gain: &SMatrix<S, 6, N>,
    ia_dot_s: &SMatrix<S, 6, N>,
    d_dot: &SMatrix<S, N, N>,
) -> SpatialMat<S> {
    let a_shifted = ia_dot_s - times!(gain, d_dot * S::from(0.5));
    let q = mul_cross_s_times::<_, N, UNIT>(ia_reduced, s, qvel) + times!(gain, a_shifted.transpose());
    match ia_dot {
        Some(ia_dot) => ia_dot - q - q.transpose(),
        None => -(q + q.transpose()),
    }
}

/// Pass 3 over all links; `eps` is the applied ε (nv). With `RATES` it
/// gives ν̇ and C; without, only the joint terms of ν̇ (`nu_dot_joint`),
/// from which the outward pass of acceleration.rs gives θ̈ (the
/// articulated-body algorithm's cost, without the İ^A recursion).
pub(crate) fn bias_pass<const RATES: bool>(model: &Model, ws: &mut Workspace, eps: &[f64]) {
    let forces = all_passive_forces(model, ws);
    link_sweep::<_, RATES>(model, ws, eps, forces);
}

/// The passive joint forces into `tau_passive`, the tendons' springs and
/// dampers with the joints': whether there are any.
pub(crate) fn all_passive_forces<S: Real>(model: &Model, ws: &mut Workspace<S>) -> bool {
    let tendon_forces = model.tendons.iter().any(|t| t.has_passive_force());
    let forces = model.has_passive_forces() || tendon_forces;
    if forces {
        passive_forces(model, ws);
        if tendon_forces {
            super::tendon::add_passive_forces(model, ws);
        }
    }
    forces
}

/// Pass 3's sweep over the links, with the passive joint forces already
/// in `tau_passive` when `forces` (else their ε is zero).
pub(crate) fn link_sweep<S: Real, const RATES: bool>(model: &Model, ws: &mut Workspace<S>, eps: &[S], forces: bool) {
    if S::SPECIALIZED && model.flexible.is_empty() {
        sweep::<_, RATES, false>(model, ws, eps, forces);
    } else {
        sweep::<_, RATES, true>(model, ws, eps, forces);
    }
}

/// [`link_sweep`]; without `FLEXIBLE` (a vehicle without flexible bodies)
/// it has no modal blocks and no children at nodes to look for.
fn sweep<S: Real, const RATES: bool, const FLEXIBLE: bool>(
    model: &Model,
    ws: &mut Workspace<S>,
    eps: &[S],
    forces: bool,
) {
    for i in (0..model.links.len()).rev() {
        if FLEXIBLE {
            super::flexible::bias::<_, RATES>(model, ws, i, eps, forces);
        }
        by_subspace!(ws.subspaces[i], bias_link::<RATES, FLEXIBLE>(model, ws, i, eps, forces));
    }
}
