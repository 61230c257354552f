//! The constraints MuJoCo builds for what nudyn's trees hold, compiled:
//! equality constraints (connect, weld, joint and tendon couplings), the
//! friction loss of each dof and tendon, and the joints' and tendons' limits (docs/DYNAMICS.md §8). Which rows are active at a state, and their
//! forces, are [`crate::dynamics::constraint`]'s.

use serde::{Deserialize, Serialize};

use super::{Attachment, InvalidModel, JointInfo, Model, ModelError, SiteFrame};
use crate::dynamics::DynamicsError;
use crate::math::{Mat3, Quat, SpatialVec, Transform, Vec3, spatial};
use crate::vehicle::{ConstraintOptions, Equality, EqualityKind, EqualityObjects, JointKind, SoftConstraint, Vehicle};
use crate::workspace::Workspace;

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
        /// Tendon 1 (index into [`Model::tendons`]).
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
    /// The tendon (index into [`Model::tendons`]).
    pub tendon: usize,
    /// Its `frictionloss`: the largest force the row can apply.
    pub frictionloss: f64,
    /// `solreffriction`, `solimpfriction`.
    pub soft: SoftConstraint,
}

/// A limited tendon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TendonLimit {
    /// The tendon (index into [`Model::tendons`]).
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
    /// per row: its force's working set and its impedance piece), the
    /// margins of [`crate::dynamics::mode::ConstraintMode`]; 0 without
    /// constraints.
    pub fn switch_count(&self) -> usize {
        if self.is_empty() { 0 } else { self.limit_sides() + 2 * self.max_rows() }
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

impl Model {
    /// Compiles the active equality constraints of `vehicle` (its bodies on
    /// `attachments`, its sites at `sites`) and fills what MuJoCo computes
    /// in qpos0: `dof_invweight0`, the bodies' invweights and the
    /// equalities' anchors and relative poses. Nothing without constraints.
    pub(super) fn compile_constraints_in_qpos0(
        &mut self,
        vehicle: &Vehicle,
        attachments: &[Attachment],
        sites: &[SiteFrame],
    ) -> Result<(), ModelError> {
        let active: Vec<(usize, &Equality)> = vehicle.equalities.iter().enumerate().filter(|(_, e)| e.active).collect();
        if self.constraints.is_empty() && active.is_empty() {
            return Ok(());
        }
        let singular = |e| self.singular(e);
        let mut ws = self.workspace();
        ws.set_configuration(self, &self.qpos0).map_err(singular)?;
        ws.world_transforms(self);
        self.constraints.dof_invweight0 = self.mujoco_dof_invweight0(vehicle, &mut ws).map_err(singular)?;
        let mut equalities = Vec::with_capacity(active.len());
        for (index, equality) in active {
            let rows = self.equality_rows(vehicle, attachments, sites, &mut ws, equality).map_err(|reason| {
                ModelError::Equality { equality: equality_label(equality, index), line: equality.line, reason }
            })?;
            equalities.push(CompiledEquality { label: equality_label(equality, index), rows, soft: equality.soft });
        }
        self.constraints.equalities = equalities;
        super::validate::validate_constraints(self).map_err(|e| ModelError::Invalid(InvalidModel::Constraint(e)))
    }

    /// MuJoCo's `dof_invweight0` at the configuration `ws` holds (qpos0):
    /// [`Model::dof_invweight0`], but 1/mass for the dofs of a body moved
    /// by slides alone ([`slider_body_mass`]).
    pub(super) fn mujoco_dof_invweight0(
        &self,
        vehicle: &Vehicle,
        ws: &mut Workspace,
    ) -> Result<Vec<f64>, DynamicsError> {
        let mut invweight = self.dof_invweight0(ws)?;
        let mut joint_infos = self.joints.iter();
        for (b, body) in vehicle.bodies.iter().enumerate() {
            // Taken whether used or not: the next body's joints follow.
            let infos: Vec<&JointInfo> = joint_infos.by_ref().take(body.joints.len()).collect();
            if let Some(mass) = slider_body_mass(vehicle, b) {
                for info in infos {
                    invweight[info.dof_adr] = 1.0 / mass;
                }
            }
        }
        Ok(invweight)
    }

    /// MuJoCo's `dof_invweight0`: the mean diagonal of M⁻¹ over each
    /// joint's dofs (a free joint's translation and rotation apart), with
    /// diag(M⁻¹)_d = |m⁻¹ e_d|² since M⁻¹ = m⁻ᵀ m⁻¹ (less the tendons'
    /// armature's share: MuJoCo's M includes it).
    fn dof_invweight0(&self, ws: &mut Workspace) -> Result<Vec<f64>, DynamicsError> {
        let (mut unit, mut eps) = (vec![0.0; self.nv], vec![0.0; self.nv]);
        let mut diagonal = vec![0.0; self.nv];
        for (d, entry) in diagonal.iter_mut().enumerate() {
            unit[d] = 1.0;
            ws.eps_from_forces(self, &unit, None, &mut eps)?;
            unit[d] = 0.0;
            *entry = ws.inverse_mass_quadratic(self, &eps);
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
        Ok(invweight)
    }

    /// MuJoCo's `body_invweight0` of `body` (translation, rotation): the mean
    /// diagonal of J M⁻¹ Jᵀ for the Jacobian of its centre of mass and its
    /// rotation, in world axes; (0, 0) for a body fixed to the world.
    fn body_invweight0(
        &self,
        vehicle: &Vehicle,
        attachments: &[Attachment],
        ws: &mut Workspace,
        body: Option<usize>,
    ) -> [f64; 2] {
        let Some(b) = body else { return [0.0; 2] };
        let Some(link) = attachments[b].link else { return [0.0; 2] };
        if let Some(mass) = slider_body_mass(vehicle, b) {
            return [1.0 / mass, 0.0];
        }
        let offset = &attachments[b].offset;
        let com = offset.trans + offset.rot.transpose() * vehicle.bodies[b].inertial_pos;
        let to_link = ws.x_world[link].rot;
        let mut wrenches = vec![SpatialVec::zeros(); self.links.len()];
        let (zero, mut eps) = (vec![0.0; self.nv], vec![0.0; self.nv]);
        let mut means = [0.0; 2];
        for (part, mean) in means.iter_mut().enumerate() {
            for axis in 0..3 {
                let direction = to_link * Vec3::ith(axis, 1.0);
                wrenches[link] = match part {
                    0 => spatial(&com.cross(&direction), &direction),
                    _ => spatial(&direction, &Vec3::zeros()),
                };
                // Cannot fail: the configuration is set and the lengths are the model's.
                if ws.eps_from_forces(self, &zero, Some(&wrenches), &mut eps).is_ok() {
                    *mean += ws.inverse_mass_quadratic(self, &eps) / 3.0;
                }
            }
        }
        means
    }

    /// One equality's rows, with MuJoCo's qpos0 data: a connect's second
    /// anchor, a weld's first anchor and relative pose when `relpose` leaves
    /// them to qpos0, and the invweights of the rows' regularizer.
    fn equality_rows(
        &self,
        vehicle: &Vehicle,
        attachments: &[Attachment],
        sites: &[SiteFrame],
        ws: &mut Workspace,
        equality: &Equality,
    ) -> Result<EqualityRows, String> {
        let frame_of_body = |body: Option<usize>| match body {
            Some(b) => SiteFrame { link: attachments[b].link, frame: attachments[b].offset },
            None => SiteFrame { link: None, frame: Transform::identity() },
        };
        let resolve = |objects: &EqualityObjects| match *objects {
            EqualityObjects::Bodies(a, b) => ([frame_of_body(a), frame_of_body(b)], [a, b], true),
            EqualityObjects::Sites(a, b) => {
                ([sites[a], sites[b]], [vehicle.sites[a].body, vehicle.sites[b].body], false)
            }
        };
        let in_world = |ws: &Workspace, frame: &SiteFrame| match frame.link {
            Some(link) => frame.frame.compose(&ws.x_world[link]),
            None => frame.frame,
        };
        let rows = match &equality.kind {
            EqualityKind::Connect { objects, anchor } => {
                let (frames, bodies, body_semantics) = resolve(objects);
                let anchors = if body_semantics {
                    let (first, second) = (in_world(ws, &frames[0]), in_world(ws, &frames[1]));
                    let point = first.trans + first.rot.transpose() * anchor;
                    [*anchor, second.rot * (point - second.trans)]
                } else {
                    [Vec3::zeros(); 2]
                };
                let weights = bodies.map(|b| self.body_invweight0(vehicle, attachments, ws, b));
                EqualityRows::Connect { frames, anchors, invweight: weights[0][0] + weights[1][0] }
            }
            EqualityKind::Weld { objects, anchor, relpose, torquescale } => {
                let (frames, bodies, body_semantics) = resolve(objects);
                let (anchors, relative) = match (body_semantics, relpose) {
                    (false, _) => ([Vec3::zeros(); 2], Quat::identity()),
                    (true, Some((position, quat))) => ([*position, *anchor], *quat),
                    (true, None) => {
                        let (first, second) = (in_world(ws, &frames[0]), in_world(ws, &frames[1]));
                        let point = second.trans + second.rot.transpose() * anchor;
                        let rotation = |t: &Transform| rotation_quat(&t.rot.transpose());
                        ([first.rot * (point - first.trans), *anchor], rotation(&first).inverse() * rotation(&second))
                    }
                };
                let weights = bodies.map(|b| self.body_invweight0(vehicle, attachments, ws, b));
                EqualityRows::Weld {
                    frames,
                    anchors,
                    relative,
                    torquescale: *torquescale,
                    invweight: [weights[0][0] + weights[1][0], weights[0][1] + weights[1][1]],
                }
            }
            EqualityKind::Joint { joint1, joint2, polycoef } => {
                let find = |name: &str| {
                    self.joints
                        .iter()
                        .find(|j| j.name == name)
                        .map(|j| [j.dof_adr, j.qpos_adr])
                        .ok_or(format!("no joint '{name}'"))
                };
                let first = find(joint1)?;
                let second = joint2.as_deref().map(find).transpose()?;
                let weights = &self.constraints.dof_invweight0;
                let invweight = weights[first[0]] + second.map_or(0.0, |s| weights[s[0]]);
                EqualityRows::Joint { first, second, polycoef: *polycoef, invweight }
            }
            EqualityKind::Tendon { tendon1, tendon2, polycoef } => {
                let weight = |k: usize| self.tendons[k].invweight0;
                let invweight = weight(*tendon1) + tendon2.map_or(0.0, weight);
                EqualityRows::Tendon { first: *tendon1, second: *tendon2, polycoef: *polycoef, invweight }
            }
        };
        Ok(rows)
    }
}

/// The rotation matrix `frame_to_world` as a unit quaternion.
/// MuJoCo's smallest component of an axis that counts as nonzero (mjEPS).
const AXIS_EPSILON: f64 = 1e-14;

/// The mass of `body` when MuJoCo's compiler marks it `body_simple == 2`,
/// for which its `mj_setConst` takes the invweights as 1/mass (the joints'
/// armature left out) instead of the diagonal of M⁻¹: a leaf body on the
/// world or on a jointless child of the world, its inertial frame its body
/// frame, moved by slides alone, anchored at the origin and along
/// coordinate axes.
fn slider_body_mass(vehicle: &Vehicle, body: usize) -> Option<f64> {
    let bodies = &vehicle.bodies;
    let this = &bodies[body];
    let on_world = match this.parent {
        None => true,
        Some(p) => bodies[p].parent.is_none() && bodies[p].joints.is_empty(),
    };
    let leaf = !bodies.iter().any(|other| other.parent == Some(body));
    let same_frame = this.inertial_pos.amax() <= AXIS_EPSILON
        && this.inertial_quat.is_some_and(|q| (q.w - 1.0).abs() <= AXIS_EPSILON && q.imag().amax() <= AXIS_EPSILON);
    let sliders = !this.joints.is_empty()
        && this.joints.iter().all(|joint| {
            joint.kind == JointKind::Slide
                && joint.pos == Vec3::zeros()
                && joint.axis.iter().filter(|c| c.abs() > AXIS_EPSILON).count() == 1
        });
    let mass = this.inertia.as_ref().map(|inertia| inertia.mass).filter(|&m| m > 0.0)?;
    (on_world && leaf && same_frame && sliders).then_some(mass)
}

fn rotation_quat(frame_to_world: &Mat3) -> Quat {
    Quat::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(*frame_to_world))
}

/// How messages name an equality: its element and name, or its index.
fn equality_label(equality: &Equality, index: usize) -> String {
    let tag = match equality.kind {
        EqualityKind::Connect { .. } => "connect",
        EqualityKind::Weld { .. } => "weld",
        EqualityKind::Joint { .. } => "joint",
        EqualityKind::Tendon { .. } => "tendon",
    };
    match &equality.name {
        Some(name) => format!("<{tag}> '{name}'"),
        None => format!("<{tag}> {index}"),
    }
}
