//! Equality constraints' rows as MuJoCo instantiates them
//! (`mj_instantiateEquality`, `mj_Jdotv`; docs/DYNAMICS.md §8): a
//! connect's three rows, a weld's six, a joint or tendon coupling's one, each with
//! its violation, its Jacobian row and, for connect and weld, J̇θ̇.
//!
//! A connect's or weld's Jacobian rows come from a walk up each frame's
//! ancestors, each dof's motion subspace column moving the point. J̇θ̇ is
//! the points' acceleration with θ̈ = 0, from one outward pass of the
//! velocity-product accelerations.

use nalgebra::Quaternion;

use super::constraint::{ConstraintRows, RowKind};
use crate::math::{Quat, Real, SpatialVec, Transform, Vec3, angular, cross_motion, linear, real};
use crate::model::{EqualityRows, Model, SiteFrame};
use crate::workspace::Workspace;

/// A frame of an equality at the current state, in the world.
struct FramePoint<S: Real> {
    /// The link carrying it (`None`: the world).
    link: Option<usize>,
    /// The anchor point in the world.
    position: Vec3<S>,
    /// The frame's orientation (frame → world).
    orientation: Quat<S>,
    /// The link's angular velocity, world axes.
    omega: Vec3<S>,
    /// The point's acceleration with θ̈ = 0, world axes.
    bias_acceleration: Vec3<S>,
    /// The link's angular acceleration with θ̈ = 0, world axes.
    bias_angular_acceleration: Vec3<S>,
}

impl<S: Real> Workspace<S> {
    /// Appends the active equality rows in MuJoCo's order (before the
    /// friction and limit rows). Needs the velocities.
    pub(super) fn instantiate_equalities(&mut self, model: &Model, rows: &mut ConstraintRows<S>) {
        let equalities = &model.constraints.equalities;
        if equalities.is_empty() {
            return;
        }
        self.world_transforms(model);
        if equalities.iter().any(|e| !matches!(e.rows, EqualityRows::Joint { .. } | EqualityRows::Tendon { .. })) {
            self.bias_accelerations(model, &mut rows.bias_acceleration);
        }
        let nv = model.nv;
        for (index, equality) in equalities.iter().enumerate() {
            match &equality.rows {
                EqualityRows::Joint { first, second, polycoef: c, invweight } => {
                    let offset = |[_, qpos]: [usize; 2]| self.theta[qpos] - model.qpos0[qpos];
                    let (violation, slope) = polynomial_coupling(c, offset(*first), second.map(offset));
                    let k = rows.push(nv, RowKind::Equality, index, violation, 0.0);
                    rows.jacobian[k * nv + first[0]] = S::one();
                    if let Some([dof, _]) = second {
                        rows.jacobian[k * nv + dof] -= slope;
                    }
                    rows.diagonal_estimate[k] = *invweight;
                }
                EqualityRows::Tendon { first, second, polycoef: c, invweight } => {
                    let offset = |k: usize| self.tendon_length[k] - model.tendons[k].length0;
                    let (violation, slope) = polynomial_coupling(c, offset(*first), second.map(offset));
                    let k = rows.push(nv, RowKind::Equality, index, violation, 0.0);
                    let row = &mut rows.jacobian[k * nv..(k + 1) * nv];
                    row.copy_from_slice(self.tendon_moment_row(model, *first));
                    if let Some(second) = second {
                        for (entry, arm) in row.iter_mut().zip(self.tendon_moment_row(model, *second)) {
                            *entry += -slope * *arm;
                        }
                    }
                    rows.diagonal_estimate[k] = *invweight;
                }
                EqualityRows::Connect { frames, anchors, invweight } => {
                    let [one, two] = [0, 1].map(|i| self.frame_point(&frames[i], &anchors[i], &rows.bias_acceleration));
                    let offset = one.position - two.position;
                    let first = rows.count;
                    for axis in 0..3 {
                        let k = rows.push(nv, RowKind::Equality, index, offset[axis], 0.0);
                        rows.violation[k] = offset.norm();
                        rows.diagonal_estimate[k] = *invweight;
                        rows.jdot_v[k] = one.bias_acceleration[axis] - two.bias_acceleration[axis];
                    }
                    self.jacobian_rows(model, rows, first, [&one, &two], false);
                }
                EqualityRows::Weld { frames, anchors, relative, torquescale, invweight } => {
                    let [one, two] = [0, 1].map(|i| self.frame_point(&frames[i], &anchors[i], &rows.bias_acceleration));
                    let target = one.orientation.into_inner() * quaternion_in(relative);
                    let inverse_two = two.orientation.into_inner().conjugate();
                    let rotation_error = (inverse_two * target).imag() * S::from(*torquescale);
                    let offset = one.position - two.position;
                    let violation = (offset.norm_squared() + rotation_error.norm_squared()).sqrt();
                    let first = rows.count;
                    for axis in 0..6 {
                        let value = if axis < 3 { offset[axis] } else { rotation_error[axis - 3] };
                        let k = rows.push(nv, RowKind::Equality, index, value, 0.0);
                        rows.violation[k] = violation;
                        rows.diagonal_estimate[k] = invweight[axis / 3];
                    }
                    self.jacobian_rows(model, rows, first, [&one, &two], true);
                    for axis in 0..3 {
                        rows.jdot_v[first + axis] = one.bias_acceleration[axis] - two.bias_acceleration[axis];
                    }
                    let columns = weld_rotation_map(&one.orientation, &two.orientation, relative, *torquescale);
                    let half_scaled = S::from(0.5 * torquescale);
                    for d in 0..nv {
                        let u = Vec3::from_fn(|c, _| rows.jacobian[(first + 3 + c) * nv + d]);
                        let mapped = columns[0] * u[0] + columns[1] * u[1] + columns[2] * u[2];
                        for r in 0..3 {
                            rows.jacobian[(first + 3 + r) * nv + d] = mapped[r];
                        }
                    }
                    // MuJoCo's J̇θ̇ of those rows: the product rule on that
                    // expression, with q̇ = ½ (0, ω) q for the world ω.
                    let relative_rate = |q: &Quaternion<S>, omega: &Vec3<S>| pure(omega) * q * S::from(0.5);
                    let omega_difference = one.omega - two.omega;
                    let target_rate =
                        relative_rate(&one.orientation.into_inner(), &one.omega) * quaternion_in(relative);
                    let inverse_two_rate = relative_rate(&two.orientation.into_inner(), &two.omega).conjugate();
                    let angular_difference = one.bias_angular_acceleration - two.bias_angular_acceleration;
                    let sum = inverse_two_rate * pure(&omega_difference) * target
                        + inverse_two * pure(&angular_difference) * target
                        + inverse_two * pure(&omega_difference) * target_rate;
                    let rotational = sum.imag() * half_scaled;
                    for r in 0..3 {
                        rows.jdot_v[first + 3 + r] = rotational[r];
                    }
                }
            }
        }
    }

    /// Rows `first..first + 3` of J (and with `rotation` the next three):
    /// the world velocity of frame one's point (and its angular velocity)
    /// that a unit rate of each dof gives, less frame two's: for each dof on
    /// a frame's way to the world, its motion subspace column (ω, v) moves
    /// the point at v + ω × p in that link's coordinates.
    fn jacobian_rows(
        &self,
        model: &Model,
        rows: &mut ConstraintRows<S>,
        first: usize,
        points: [&FramePoint<S>; 2],
        rotation: bool,
    ) {
        let nv = model.nv;
        for (point, sign) in points.into_iter().zip([S::one(), -S::one()]) {
            let mut next = point.link;
            while let Some(a) = next {
                let link = &model.links[a];
                let placement = &self.x_world[a];
                let to_world = placement.rot.transpose();
                let in_link = placement.rot * (point.position - placement.trans);
                for c in 0..link.ndof {
                    let column = link.motion_subspace.column(c);
                    let omega = Vec3::new(column[0], column[1], column[2]).map(S::from);
                    let velocity = Vec3::new(column[3], column[4], column[5]).map(S::from);
                    let translation = to_world * (velocity + omega.cross(&in_link)) * sign;
                    let turn = to_world * omega * sign;
                    let dof = link.dof_adr + c;
                    for r in 0..3 {
                        rows.jacobian[(first + r) * nv + dof] += translation[r];
                        if rotation {
                            rows.jacobian[(first + 3 + r) * nv + dof] += turn[r];
                        }
                    }
                }
                next = link.parent;
            }
        }
    }

    /// Where an equality's frame and point are, and how they move.
    fn frame_point(&self, frame: &SiteFrame, anchor: &Vec3, bias: &[SpatialVec<S>]) -> FramePoint<S> {
        let in_frame = (frame.frame.trans + frame.frame.rot.transpose() * anchor).map(S::from);
        let Some(link) = frame.link else {
            return FramePoint {
                link: None,
                position: in_frame,
                orientation: orientation(&frame.frame.real()),
                omega: Vec3::zeros(),
                bias_acceleration: Vec3::zeros(),
                bias_angular_acceleration: Vec3::zeros(),
            };
        };
        let world = &self.x_world[link];
        let to_world = world.rot.transpose();
        let velocity = &self.v_body[link];
        let (omega, linear_velocity) = (angular(velocity), linear(velocity));
        let a = &bias[link];
        // A body point's classical acceleration: the spatial one at the point plus ω × v.
        let point_acceleration =
            linear(a) + angular(a).cross(&in_frame) + omega.cross(&(linear_velocity + omega.cross(&in_frame)));
        FramePoint {
            link: Some(link),
            position: world.trans + to_world * in_frame,
            orientation: orientation(&frame.frame.real().compose(world)),
            omega: to_world * omega,
            bias_acceleration: to_world * point_acceleration,
            bias_angular_acceleration: to_world * angular(a),
        }
    }

    /// The links' spatial accelerations with θ̈ = 0 and the world at rest,
    /// base to tip: A⁰_i = X A⁰_λ + V⁺_i × S_i θ̇_i.
    pub(super) fn bias_accelerations(&self, model: &Model, out: &mut [SpatialVec<S>]) {
        for (i, link) in model.links.iter().enumerate() {
            let mut joint_velocity = SpatialVec::zeros();
            for c in 0..link.ndof {
                joint_velocity +=
                    real::<S, 6, 1>(&link.motion_subspace.column(c).into_owned()) * self.qvel[link.dof_adr + c];
            }
            let passed = match link.parent {
                Some(p) => self.x_parent[i].apply_motion(&out[p]),
                None => SpatialVec::zeros(),
            };
            out[i] = passed + cross_motion(&self.v_plus_body[i], &joint_velocity);
        }
    }
}

/// The columns of M, a weld's rotation rows being M(J_ω1 − J_ω2) with
/// M·a = ½ vec(q₂⁻¹ (0, a) q₁ q_rel)·torquescale for the frames'
/// orientations q₁, q₂ (frame → world) and the relative pose q_rel.
pub(super) fn weld_rotation_map<S: Real>(
    one: &Quat<S>,
    two: &Quat<S>,
    relative: &Quat,
    torquescale: f64,
) -> [Vec3<S>; 3] {
    let target = one.into_inner() * quaternion_in(relative);
    let inverse_two = two.into_inner().conjugate();
    [0, 1, 2].map(|c| (inverse_two * pure(&Vec3::ith(c, S::one())) * target).imag() * S::from(0.5 * torquescale))
}

/// The quaternion (0, v).
fn pure<S: Real>(v: &Vec3<S>) -> Quaternion<S> {
    Quaternion::new(S::zero(), v.x, v.y, v.z)
}

/// A model's unit quaternion in the passes' scalar.
fn quaternion_in<S: Real>(q: &Quat) -> Quaternion<S> {
    Quaternion::from_vector(q.coords.map(S::from))
}

/// A placement's orientation (frame → world) as a unit quaternion.
pub(super) fn orientation<S: Real>(placement: &Transform<S>) -> Quat<S> {
    Quat::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(placement.rot.transpose()))
}

/// A joint or tendon coupling's violation y₁ − p(y₂), p the polynomial of
/// `polycoef` c (p(y₂) = c₀ + c₁y₂ + … + c₄y₂⁴; c₀ alone without a second
/// object), and the slope p′(y₂) its Jacobian row takes; y are offsets
/// from qpos0.
pub(super) fn polynomial_coupling<S: Real>(c: &[f64; 5], first: S, second: Option<S>) -> (S, S) {
    match second {
        Some(x) => {
            // c₁x + c₂x² + …, each product in f64's order (c₂·x·x, …).
            let value = x * c[1] + x * c[2] * x + x * c[3] * x * x + x * c[4] * x * x * x;
            let slope = S::from(c[1]) + x * (2.0 * c[2]) + x * (3.0 * c[3]) * x + x * (4.0 * c[4]) * x * x;
            (first - c[0] - value, slope)
        }
        None => (first - c[0], S::zero()),
    }
}
