//! The constraints MuJoCo builds for what nudyn's trees hold, compiled:
//! the friction loss of each dof and the joints' limits
//! (docs/DYNAMICS.md §8). Which rows are active at a state, and their
//! forces, are [`crate::dynamics::constraint`]'s.

use serde::{Deserialize, Serialize};

use super::{InvalidModel, JointInfo, Model, ModelError};
use crate::vehicle::{ConstraintOptions, JointKind, SoftConstraint, Vehicle};

/// The compiled constraints; empty for a vehicle without any, which then
/// pays nothing for them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Constraints {
    /// Friction loss, one row per dof that has it, in dof order (MuJoCo's
    /// `mjCNSTR_FRICTION_DOF` rows).
    pub friction: Vec<DofFriction>,
    /// Limited joints in joint order (`mjCNSTR_LIMIT_JOINT` rows: up to two
    /// for a hinge or slide, one for a ball).
    pub limits: Vec<Limit>,
    /// The `<option>` settings their forces depend on.
    pub options: ConstraintOptions,
    /// MuJoCo's `dof_invweight0` (nv; empty without constraints): the mean
    /// diagonal of M⁻¹ over each joint's dofs in qpos0 (a free joint's
    /// translation and rotation apart). MuJoCo's constraint regularizer
    /// takes its scale from it, not from the current M.
    pub dof_invweight0: Vec<f64>,
}

/// Friction loss on one dof.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DofFriction {
    /// The dof (qvel index).
    pub dof: usize,
    /// The joint's `frictionloss`: the largest force the row can apply.
    pub frictionloss: f64,
    /// `solreffriction`, `solimpfriction`.
    pub soft: SoftConstraint,
}

/// A limited joint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Limit {
    /// The joint (index into [`Model::joints`]).
    pub joint: usize,
    /// Hinge, slide or ball.
    pub kind: JointKind,
    /// Its first qpos entry.
    pub qpos: usize,
    /// Its first dof.
    pub dof: usize,
    /// `range` (rad or m); a ball joint limits its angle by the larger value.
    pub range: [f64; 2],
    /// `margin`.
    pub margin: f64,
    /// `solreflimit`, `solimplimit`.
    pub soft: SoftConstraint,
}

impl Constraints {
    /// Whether the vehicle has no constraint at all.
    pub fn is_empty(&self) -> bool {
        self.friction.is_empty() && self.limits.is_empty()
    }

    /// The most rows that can be active at once: one per friction dof, two
    /// per hinge or slide limit (both sides within a wide margin), one per ball.
    pub fn max_rows(&self) -> usize {
        let limit_rows: usize = self.limits.iter().map(|l| if l.kind == JointKind::Ball { 1 } else { 2 }).sum();
        self.friction.len() + limit_rows
    }

    /// What the constraints are, in words, for an FMU's descriptions:
    /// `None` without any.
    pub fn summary(&self) -> Option<String> {
        if self.is_empty() {
            return None;
        }
        let mut kinds = Vec::new();
        if !self.friction.is_empty() {
            kinds.push(format!("joint friction loss on {} dofs", self.friction.len()));
        }
        if !self.limits.is_empty() {
            kinds.push(format!("limits on {} joints", self.limits.len()));
        }
        Some(format!("constraint forces as MuJoCo's soft constraints: {}", kinds.join(", ")))
    }

    /// The constraints of `vehicle`'s joints, whose compiled `joints` are
    /// in the same order.
    pub(super) fn of(vehicle: &Vehicle, joints: &[JointInfo]) -> Result<Constraints, ModelError> {
        let mut constraints = Constraints { options: vehicle.constraint_options, ..Constraints::default() };
        let mjcf_joints = vehicle.bodies.iter().flat_map(|body| &body.joints);
        for (index, (joint, info)) in mjcf_joints.zip(joints).enumerate() {
            let c = &joint.constraints;
            let bad =
                |what: &'static str, value: f64| ModelError::BadParameter { joint: joint.name.clone(), what, value };
            if !(c.frictionloss.is_finite() && c.frictionloss >= 0.0) {
                return Err(bad("frictionloss", c.frictionloss));
            }
            if c.frictionloss > 0.0 {
                constraints.friction.extend((0..joint.kind.nv()).map(|k| DofFriction {
                    dof: info.dof_adr + k,
                    frictionloss: c.frictionloss,
                    soft: c.friction,
                }));
            }
            if let Some(limit) = &c.limit {
                if !limit.margin.is_finite() {
                    return Err(bad("margin", limit.margin));
                }
                constraints.limits.push(Limit {
                    joint: index,
                    kind: joint.kind,
                    qpos: info.qpos_adr,
                    dof: info.dof_adr,
                    range: limit.range,
                    margin: limit.margin,
                    soft: limit.soft,
                });
            }
        }
        // MuJoCo orders friction rows by dof: joints come in dof order already.
        Ok(constraints)
    }
}

impl Model {
    /// Fills `constraints.dof_invweight0` in qpos0, when there are constraints.
    pub(super) fn compute_invweights(&mut self) -> Result<(), ModelError> {
        if self.constraints.is_empty() {
            return Ok(());
        }
        let singular = |e| self.singular(e);
        let mut ws = self.workspace();
        ws.set_configuration(self, &self.qpos0).map_err(singular)?;
        let (mut unit, mut eps) = (vec![0.0; self.nv], vec![0.0; self.nv]);
        // diag(M⁻¹)_d = |m⁻¹ e_d|², since M⁻¹ = m⁻ᵀ m⁻¹.
        let mut diagonal = vec![0.0; self.nv];
        for (d, entry) in diagonal.iter_mut().enumerate() {
            unit[d] = 1.0;
            ws.eps_from_forces(self, &unit, None, &mut eps).map_err(singular)?;
            unit[d] = 0.0;
            *entry = eps.iter().map(|e| e * e).sum();
        }
        let mut invweight = vec![0.0; self.nv];
        for joint in &self.joints {
            // (first dof, count) of each group MuJoCo averages over.
            let groups: &[(usize, usize)] = match joint.kind {
                JointKind::Free => &[(0, 3), (3, 3)],
                JointKind::Ball => &[(0, 3)],
                JointKind::Hinge | JointKind::Slide => &[(0, 1)],
            };
            for &(first, count) in groups {
                let dofs = joint.dof_adr + first..joint.dof_adr + first + count;
                let mean = diagonal[dofs.clone()].iter().sum::<f64>() / count as f64;
                invweight[dofs].fill(mean);
            }
        }
        self.constraints.dof_invweight0 = invweight;
        super::validate::validate_constraints(self).map_err(|e| ModelError::Invalid(InvalidModel::Constraint(e)))
    }
}
