//! The constraints MuJoCo builds for what nudyn's trees hold, compiled:
//! equality constraints (connect, weld, joint and tendon couplings), the
//! friction loss of each dof and tendon, and the joints' and tendons' limits (docs/DYNAMICS.md §8). Which rows are active at a state, and their
//! forces, are [`crate::dynamics::constraint`]'s.

use serde::{Deserialize, Serialize};

use super::{JointInfo, ModelError, SiteFrame};
use crate::math::{Quat, Vec3};
use crate::vehicle::{ConstraintOptions, JointKind, SoftConstraint, Vehicle};

/// The compiled constraints; empty for a vehicle without any, which then
/// pays nothing for them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Constraints {
    /// Active equality constraints in MuJoCo's order (its `mjCNSTR_EQUALITY` rows).
    #[serde(default)]
    pub equalities: Vec<CompiledEquality>,
    /// Friction loss, one row per dof that has it, in dof order (MuJoCo's
    /// `mjCNSTR_FRICTION_DOF` rows).
    pub friction: Vec<DofFriction>,
    /// Limited joints in joint order (`mjCNSTR_LIMIT_JOINT` rows: up to two
    /// for a hinge or slide, one for a ball).
    pub limits: Vec<Limit>,
    /// Friction loss of tendons, in tendon order (`mjCNSTR_FRICTION_TENDON`
    /// rows, after the dofs').
    #[serde(default)]
    pub tendon_friction: Vec<TendonFriction>,
    /// Limited tendons in tendon order (`mjCNSTR_LIMIT_TENDON` rows, up to
    /// two each, after the joints').
    #[serde(default)]
    pub tendon_limits: Vec<TendonLimit>,
    /// The `<option>` settings their forces depend on.
    pub options: ConstraintOptions,
    /// MuJoCo's `dof_invweight0` (nv; empty without constraints): the mean
    /// diagonal of M⁻¹ over each joint's dofs in qpos0 (a free joint's
    /// translation and rotation apart). MuJoCo's constraint regularizer
    /// takes its scale from it, not from the current M.
    pub dof_invweight0: Vec<f64>,
}

/// One equality constraint, its frames on links and its qpos0 data
/// resolved (MuJoCo's `eq_data` after `mj_setConst`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompiledEquality {
    /// The element and its name or index, for reports.
    pub label: String,
    /// Its rows.
    pub rows: EqualityRows,
    /// `solref`, `solimp`.
    pub soft: SoftConstraint,
}

/// What an equality constraint's rows measure.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "type")]
pub enum EqualityRows {
    /// Three rows: the world offset between a point of each frame.
    Connect {
        /// The two frames (body or site frames on their links).
        frames: [SiteFrame; 2],
        /// The point in each frame's coordinates.
        anchors: [Vec3; 2],
        /// MuJoCo's translational `body_invweight0` of the two bodies, summed.
        invweight: f64,
    },
    /// Six rows: the points' offset, then the relative rotation's vector
    /// part scaled by `torquescale`.
    Weld {
        /// The two frames.
        frames: [SiteFrame; 2],
        /// The point in each frame's coordinates.
        anchors: [Vec3; 2],
        /// Frame 2's orientation in frame 1 when the constraint holds (relpose's quaternion).
        relative: Quat,
        /// `torquescale`.
        torquescale: f64,
        /// MuJoCo's `body_invweight0` of the two bodies, summed: translation, rotation.
        invweight: [f64; 2],
    },
    /// One row: θ₁ − θ₁⁰ − p(θ₂ − θ₂⁰), p the quartic `polycoef`.
    Joint {
        /// Joint 1's dof and qpos entry.
        first: [usize; 2],
        /// Joint 2's, if any.
        second: Option<[usize; 2]>,
        /// `polycoef`.
        polycoef: [f64; 5],
        /// MuJoCo's `dof_invweight0` of the two joints, summed (set with the invweights).
        invweight: f64,
    },
    /// One row: L₁ − L₁⁰ − p(L₂ − L₂⁰) of two tendons' lengths, L⁰ in qpos0.
    Tendon {
        /// Tendon 1 (index into [`Model::tendons`](super::Model::tendons)).
        first: usize,
        /// Tendon 2, if any.
        second: Option<usize>,
        /// `polycoef`.
        polycoef: [f64; 5],
        /// MuJoCo's `tendon_invweight0` of the two tendons, summed.
        invweight: f64,
    },
}

impl EqualityRows {
    /// How many rows it has.
    pub fn count(&self) -> usize {
        match self {
            EqualityRows::Connect { .. } => 3,
            EqualityRows::Weld { .. } => 6,
            EqualityRows::Joint { .. } | EqualityRows::Tendon { .. } => 1,
        }
    }
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

/// Friction loss on one tendon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TendonFriction {
    /// The tendon (index into [`Model::tendons`](super::Model::tendons)).
    pub tendon: usize,
    /// Its `frictionloss`: the largest force the row can apply.
    pub frictionloss: f64,
    /// `solreffriction`, `solimpfriction`.
    pub soft: SoftConstraint,
}

/// A limited tendon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TendonLimit {
    /// The tendon (index into [`Model::tendons`](super::Model::tendons)).
    pub tendon: usize,
    /// `range` of its length.
    pub range: [f64; 2],
    /// `margin`.
    pub margin: f64,
    /// `solreflimit`, `solimplimit`.
    pub soft: SoftConstraint,
}

/// A limited joint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Limit {
    /// The joint (index into [`Model::joints`](super::Model::joints)).
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
        self.equalities.is_empty()
            && self.friction.is_empty()
            && self.limits.is_empty()
            && self.tendon_friction.is_empty()
            && self.tendon_limits.is_empty()
    }

    /// Whether MuJoCo's no-slip pass runs after the solver: iterations are
    /// asked for and there are friction-loss rows for it to move.
    pub fn runs_no_slip_pass(&self) -> bool {
        self.options.noslip_iterations > 0 && !(self.friction.is_empty() && self.tendon_friction.is_empty())
    }

    /// The most rows that can be active at once: one per friction dof or
    /// tendon, two per hinge, slide or tendon limit (both sides within a wide
    /// margin), one per ball.
    pub fn max_rows(&self) -> usize {
        let limit_rows: usize = self.limits.iter().map(|l| if l.kind == JointKind::Ball { 1 } else { 2 }).sum();
        let equality_rows: usize = self.equalities.iter().map(|e| e.rows.count()).sum();
        equality_rows + self.friction.len() + limit_rows + self.tendon_friction.len() + 2 * self.tendon_limits.len()
    }

    /// How many limit sides can switch on and off: two per hinge, slide
    /// and tendon limit (lower, upper), one per ball limit. Each has a slot
    /// ([`Constraints::joint_limit_slot`], [`Constraints::tendon_limit_slot`]).
    pub fn limit_sides(&self) -> usize {
        2 * (self.limits.len() + self.tendon_limits.len())
    }

    /// How many switches the constraint forces have (limit sides, then two
    /// per row: its force's working set and its impedance piece, then the
    /// no-slip pass's [`Constraints::no_slip_switches`]), the margins of
    /// [`crate::dynamics::mode::ConstraintMode`]; 0 without constraints.
    pub fn switch_count(&self) -> usize {
        if self.is_empty() { 0 } else { self.limit_sides() + 2 * self.max_rows() + self.no_slip_switches() }
    }

    /// The no-slip pass's switches: each sweep's clamp of each row, then
    /// each sweep's stopping rule of each island (named by its first row);
    /// 0 without the pass.
    pub fn no_slip_switches(&self) -> usize {
        if self.runs_no_slip_pass() { 2 * self.options.noslip_iterations as usize * self.max_rows() } else { 0 }
    }

    /// The slot of side `side` (0 lower, 1 upper; a ball's is 0) of joint limit `index`.
    pub fn joint_limit_slot(&self, index: usize, side: usize) -> usize {
        2 * index + side
    }

    /// The slot of side `side` of tendon limit `index`.
    pub fn tendon_limit_slot(&self, index: usize, side: usize) -> usize {
        2 * (self.limits.len() + index) + side
    }

    /// What the constraints are, in words, for an FMU's descriptions:
    /// `None` without any.
    pub fn summary(&self) -> Option<String> {
        if self.is_empty() {
            return None;
        }
        let mut kinds = Vec::new();
        if !self.equalities.is_empty() {
            let labels: Vec<&str> = self.equalities.iter().map(|e| e.label.as_str()).collect();
            kinds.push(format!("equality constraints {}", labels.join(", ")));
        }
        if !self.friction.is_empty() {
            kinds.push(format!("joint friction loss on {} dofs", self.friction.len()));
        }
        if !self.limits.is_empty() {
            kinds.push(format!("limits on {} joints", self.limits.len()));
        }
        if !self.tendon_friction.is_empty() {
            kinds.push(format!("tendon friction loss on {} tendons", self.tendon_friction.len()));
        }
        if !self.tendon_limits.is_empty() {
            kinds.push(format!("limits on {} tendons", self.tendon_limits.len()));
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
        for (index, tendon) in vehicle.tendons.iter().enumerate() {
            let bad = |what: &'static str, value: f64| ModelError::BadParameter {
                joint: format!("tendon {}", tendon.name.as_deref().unwrap_or(&index.to_string())),
                what,
                value,
            };
            if !tendon.frictionloss.is_finite() {
                return Err(bad("frictionloss", tendon.frictionloss));
            }
            // MuJoCo makes a row of a positive friction loss only.
            if tendon.frictionloss > 0.0 {
                constraints.tendon_friction.push(TendonFriction {
                    tendon: index,
                    frictionloss: tendon.frictionloss,
                    soft: tendon.friction,
                });
            }
            if let Some(limit) = &tendon.limit {
                if !limit.margin.is_finite() {
                    return Err(bad("margin", limit.margin));
                }
                constraints.tendon_limits.push(TendonLimit {
                    tendon: index,
                    range: limit.range,
                    margin: limit.margin,
                    soft: limit.soft,
                });
            }
        }
        Ok(constraints)
    }
}
