//! Noninteracting control in the ν-coordinates: the paper's Control 1,
//! with docs/DYNAMICS.md §1's erratum for 1(b):
//!
//!   (a) rate feedback          ε = −c₁ ν,
//!   (b) configuration control  ε = −c₁ ν + ℓ(θ) Jᵀ(θ) c₂ (Ŷ − Y(θ)),
//!
//! c₁ (nv) and c₂ (ny) non-negative diagonal gains, J = ∂Y/∂θ the Jacobian
//! of the controlled quantities Y (in qvel coordinates). ℓJᵀc₂ΔY is the ε of
//! a generalized force Jᵀc₂ΔY, computed in O(N) by the inward pass of
//! [`crate::dynamics::forces`] (docs/DYNAMICS.md §5): joint forces for joint
//! targets, a body wrench for a pose target. No T = m ε is ever formed.
//!
//! Why (b) works: with U(θ) = ½ ΔYᵀ c₂ ΔY and θ̇ = ℓ*ν,
//! dU/dt = −ΔYᵀc₂ J θ̇ = −νᵀ ℓ Jᵀ c₂ ΔY, and dK/dt = νᵀε (Lemma 3), so
//! V = K + U has dV/dt = −νᵀ c₁ ν ≤ 0: the Lyapunov function of the tests.
//! That needs J to be the true Jacobian of the Y whose error U measures,
//! which is why the orientation error carries its SO(3) Jacobian ([`pose`]).
//!
//! Two kinds of Y ([`Objective`]):
//! - [`Objective::Joints`]: the values of every hinge and slide joint
//!   (ball and free joints are left to the rate feedback);
//! - [`Objective::Pose`]: the pose of one body frame: position of its origin
//!   in world axes, and orientation as the rotation vector φ = log(R̂ᵀR)
//!   of the body's rotation R relative to the target R̂ (see [`pose`]).
//!
//! Model vs workspace: [`ControlLaw`] is immutable (it goes into the
//! controller FMU's resource with the [`Model`]); [`ControlWorkspace`]
//! holds every buffer, so [`ControlWorkspace::evaluate`] never allocates.

pub mod pose;

use nalgebra::DVector;
use serde::{Deserialize, Serialize};

use crate::dynamics::DynamicsError;
use crate::math::{Quat, SpatialVec, Transform, Vec3, angular, linear, spatial, unit_quat_from_wxyz};
use crate::model::{LinkJoint, Model};
use crate::vehicle::Vehicle;
use crate::workspace::Workspace;

/// Default rate gain c₁ (1/s) of every dof: ν decays as e^(−c₁t). At the
/// DefaultExperiment's communication step h = 0.01 s, c₁h = 0.05: well
/// inside the stability limit of the sampled loop (c₁h < 2 when ε is held
/// from the current sample, c₁h < 1 with one step of delay, as in a master
/// that steps all FMUs in parallel), and the Lyapunov function's increase
/// within a step is O((c₁h)²) of K (docs/control.md, "The sample-and-hold bound").
pub const DEFAULT_RATE_GAIN: f64 = 5.0;

/// Default configuration gain c₂: 0, pure rate feedback (detumbling) until
/// gains for the vehicle are chosen (their units are N/m or N·m/rad).
pub const DEFAULT_TARGET_GAIN: f64 = 0.0;

/// Why a control law cannot be built or evaluated.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ControlError {
    /// The body named for a pose target does not exist.
    #[error("no body named '{name}' (bodies: {known})")]
    UnknownBody {
        /// The name asked for.
        name: String,
        /// The vehicle's body names, comma-separated.
        known: String,
    },
    /// The body is welded to the world: nothing moves it.
    #[error("body '{0}' is welded to the world (no joint between it and the world): its pose cannot be controlled")]
    WeldedToWorld(String),
    /// Joint targets asked of a vehicle without hinge or slide joints.
    #[error("the vehicle has no hinge or slide joint to give a target to (use a pose target with --end-effector)")]
    NoJointTargets,
    /// A vector has the wrong length.
    #[error("{what} has {found} entries, expected {expected}")]
    Length {
        /// Which vector.
        what: &'static str,
        /// Its required length.
        expected: usize,
        /// Its actual length.
        found: usize,
    },
    /// An entry that must be finite is not.
    #[error("{what}[{index}] = {value} is not finite", index = index + 1)]
    NonFinite {
        /// Which vector.
        what: &'static str,
        /// 0-based index (printed 1-based, like the FMU's names).
        index: usize,
        /// The value.
        value: f64,
    },
    /// A gain that is negative: it would pump energy in.
    #[error("{what}[{index}] = {value} is negative: gains must be non-negative", index = index + 1)]
    NegativeGain {
        /// c1 or c2.
        what: &'static str,
        /// 0-based index (printed 1-based).
        index: usize,
        /// The value.
        value: f64,
    },
    /// The target quaternion has zero norm.
    #[error("the target quaternion is zero: it names no orientation")]
    ZeroTargetQuaternion,
    /// The dynamics passes refused the configuration.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
}

/// One joint given a target: a hinge or slide, with its qpos and dof.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TargetJoint {
    /// The MJCF joint name.
    pub name: String,
    /// Its qpos entry (θ).
    pub qpos_adr: usize,
    /// Its dof (ν, ε).
    pub dof_adr: usize,
}

/// A body frame as the passes see it: the link that carries it and the
/// body frame relative to that link frame (identity for a body with joints,
/// whose frame is its last link's; a welded body sits at a fixed offset).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BodyFrame {
    /// The MJCF body name.
    pub body: String,
    /// The link carrying it.
    pub link: usize,
    /// ᵇX_ₗ: the body frame relative to the link frame.
    pub offset: Transform,
}

impl BodyFrame {
    /// The frame of body `name`: the link it moves with and its offset,
    /// following MuJoCo's body tree from the body to its nearest ancestor
    /// with a joint (whose frame is its last link's frame).
    pub fn find(vehicle: &Vehicle, model: &Model, name: &str) -> Result<BodyFrame, ControlError> {
        let Some(mut b) = vehicle.bodies.iter().position(|body| body.name == name) else {
            let known: Vec<&str> = vehicle.bodies.iter().map(|body| body.name.as_str()).collect();
            return Err(ControlError::UnknownBody { name: name.to_string(), known: known.join(", ") });
        };
        let mut offset = Transform::identity();
        loop {
            let body = &vehicle.bodies[b];
            if !body.joints.is_empty() {
                let link =
                    model.links.iter().rposition(|l| l.body_name == body.name).expect("a body with joints has links");
                return Ok(BodyFrame { body: name.to_string(), link, offset });
            }
            // A welded body: its frame relative to its parent's, then on up.
            let in_parent = Transform::from_pose(&body.quat.to_rotation_matrix().into_inner(), &body.pos);
            offset = offset.compose(&in_parent);
            match body.parent {
                Some(parent) => b = parent,
                None => return Err(ControlError::WeldedToWorld(name.to_string())),
            }
        }
    }
}

/// What the configuration term of the law controls.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Objective {
    /// Y = the values of these hinge and slide joints (qpos), ΔY = Ŷ − θ.
    Joints(Vec<TargetJoint>),
    /// Y = the pose of a body frame: ΔY = (p̂ − p, −φ), p the frame origin
    /// in world axes, φ = log(R̂ᵀR) (about the target frame's axes).
    Pose(BodyFrame),
}

/// The control law of one vehicle: immutable, serializable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControlLaw {
    /// What c₂ acts on.
    pub objective: Objective,
}

impl ControlLaw {
    /// Joint targets on every hinge and slide joint of `model`.
    pub fn joints(model: &Model) -> Result<ControlLaw, ControlError> {
        let joints: Vec<TargetJoint> = model
            .links
            .iter()
            .filter(|l| matches!(l.joint, LinkJoint::Hinge | LinkJoint::Slide))
            .map(|l| TargetJoint { name: l.joint_name.clone(), qpos_adr: l.qpos_adr, dof_adr: l.dof_adr })
            .collect();
        if joints.is_empty() {
            return Err(ControlError::NoJointTargets);
        }
        Ok(ControlLaw { objective: Objective::Joints(joints) })
    }

    /// A pose target on body `name`.
    pub fn pose(vehicle: &Vehicle, model: &Model, name: &str) -> Result<ControlLaw, ControlError> {
        Ok(ControlLaw { objective: Objective::Pose(BodyFrame::find(vehicle, model, name)?) })
    }

    /// ny: the number of controlled quantities (entries of c₂ and ΔY).
    pub fn ny(&self) -> usize {
        match &self.objective {
            Objective::Joints(joints) => joints.len(),
            Objective::Pose(_) => 6,
        }
    }

    /// The number of target values: ny for joints; 7 for a pose (position,
    /// then the quaternion w, x, y, z).
    pub fn target_len(&self) -> usize {
        match &self.objective {
            Objective::Joints(joints) => joints.len(),
            Objective::Pose(_) => 7,
        }
    }

    /// Why the law does not fit `model`, if it does not: a law read from a
    /// corrupted or hand-edited FMU resource must be refused when it is
    /// loaded, not crash later.
    pub fn mismatch(&self, model: &Model) -> Option<String> {
        match &self.objective {
            Objective::Joints(joints) if joints.is_empty() => Some("no joint has a target".into()),
            Objective::Joints(joints) => joints.iter().find_map(|joint| {
                let fits = model.links.iter().any(|l| {
                    l.qpos_adr == joint.qpos_adr
                        && l.dof_adr == joint.dof_adr
                        && matches!(l.joint, LinkJoint::Hinge | LinkJoint::Slide)
                });
                (!fits).then(|| format!("joint '{}' is not a hinge or slide of the model", joint.name))
            }),
            Objective::Pose(frame) if frame.link >= model.links.len() => {
                Some(format!("body '{}' is on link {}, the model has {}", frame.body, frame.link, model.links.len()))
            }
            Objective::Pose(frame) => {
                let mut numbers = frame.offset.rot.iter().chain(frame.offset.trans.iter());
                numbers.any(|x| !x.is_finite()).then(|| format!("body '{}' has a non-finite offset", frame.body))
            }
        }
    }

    /// The parameters with their defaults: c₁ = [`DEFAULT_RATE_GAIN`],
    /// c₂ = [`DEFAULT_TARGET_GAIN`], and the target Y(qpos0), the pose drawn
    /// in the MJCF file.
    pub fn default_parameters(&self, model: &Model) -> Result<ControlParameters, ControlError> {
        let target = match &self.objective {
            Objective::Joints(joints) => joints.iter().map(|j| model.qpos0[j.qpos_adr]).collect(),
            Objective::Pose(frame) => {
                let mut ws = model.workspace();
                ws.set_configuration(model, &model.qpos0)?;
                let (position, orientation) = body_pose(model, &mut ws, frame);
                let q = orientation.quaternion();
                vec![position.x, position.y, position.z, q.w, q.i, q.j, q.k]
            }
        };
        // A flexible body's modes have no actuator of their own: no rate
        // feedback on their ν entries unless the user sets one.
        let mut c1 = vec![DEFAULT_RATE_GAIN; model.nv];
        for flexible in &model.flexible {
            c1[flexible.dof_adr..flexible.dof_adr + flexible.mode_count()].fill(0.0);
        }
        Ok(ControlParameters { c1, c2: vec![DEFAULT_TARGET_GAIN; self.ny()], target })
    }
}

/// The law's parameters: gains and the target Ŷ.
#[derive(Clone, Debug, PartialEq)]
pub struct ControlParameters {
    /// c₁ (nv), 1/s.
    pub c1: Vec<f64>,
    /// c₂ (ny): N/m for positions and slides, N·m/rad for angles.
    pub c2: Vec<f64>,
    /// Ŷ ([`ControlLaw::target_len`]): joint values, or position then quaternion (w, x, y, z).
    pub target: Vec<f64>,
}

impl ControlParameters {
    /// Checks lengths, finiteness, non-negative gains and a non-zero target quaternion.
    pub fn check(&self, model: &Model, law: &ControlLaw) -> Result<(), ControlError> {
        for (what, values, expected) in
            [("c1", &self.c1, model.nv), ("c2", &self.c2, law.ny()), ("target", &self.target, law.target_len())]
        {
            if values.len() != expected {
                return Err(ControlError::Length { what, expected, found: values.len() });
            }
            if let Some(index) = values.iter().position(|v| !v.is_finite()) {
                return Err(ControlError::NonFinite { what, index, value: values[index] });
            }
        }
        for (what, gains) in [("c1", &self.c1), ("c2", &self.c2)] {
            if let Some(index) = gains.iter().position(|&g| g < 0.0) {
                return Err(ControlError::NegativeGain { what, index, value: gains[index] });
            }
        }
        if matches!(law.objective, Objective::Pose(_)) && unit_quat_from_wxyz(&self.target[3..7]).is_none() {
            return Err(ControlError::ZeroTargetQuaternion);
        }
        Ok(())
    }
}

/// Position (world) and orientation (body → world) of a body frame, from
/// the workspace's pass 0.
pub fn body_pose(model: &Model, ws: &mut Workspace, frame: &BodyFrame) -> (Vec3, Quat) {
    // ᵇX₀: rot maps world to body coordinates, trans is the body origin in world.
    let body_from_world = frame.offset.compose(&ws.world_transforms(model)[frame.link]);
    let rotation = nalgebra::Rotation3::from_matrix_unchecked(body_from_world.rot.transpose());
    (body_from_world.trans, Quat::from_rotation_matrix(&rotation))
}

/// Buffers and results of the control law for one model.
#[derive(Clone, Debug)]
pub struct ControlWorkspace {
    /// The dynamics passes (0 and 1 for θ; the inward force pass).
    pub ws: Workspace,
    /// ε = −c₁ν + ℓJᵀc₂ΔY (nv) — [`ControlWorkspace::evaluate`].
    pub eps: DVector<f64>,
    /// ΔY = Ŷ − Y(θ) (ny) — [`ControlWorkspace::evaluate`].
    pub error: DVector<f64>,
    /// U = ½ ΔYᵀ c₂ ΔY (J) — [`ControlWorkspace::evaluate`].
    pub potential: f64,
    /// Jᵀc₂ΔY as joint forces (joint targets), else zero.
    torque: DVector<f64>,
    /// Per-link wrenches for the inward pass (pose targets: one non-zero).
    body_forces: Vec<SpatialVec>,
}

impl ControlWorkspace {
    /// Buffers sized for `model` and `law`.
    pub fn new(model: &Model, law: &ControlLaw) -> Self {
        ControlWorkspace {
            ws: model.workspace(),
            eps: DVector::zeros(model.nv),
            error: DVector::zeros(law.ny()),
            potential: 0.0,
            torque: DVector::zeros(model.nv),
            body_forces: vec![SpatialVec::zeros(); model.links.len()],
        }
    }

    /// ε = ℓ(θ)Jᵀ(θ)f for a wrench f on `frame` (world axes, (moment about
    /// the frame origin, force)): one inward pass, O(N). Needs passes 0 and 1
    /// for θ (`self.ws.set_configuration`).
    pub fn eps_of_wrench(
        &mut self,
        model: &Model,
        frame: &BodyFrame,
        wrench_world: &SpatialVec,
        eps: &mut [f64],
    ) -> Result<(), ControlError> {
        self.load_wrench(model, frame, wrench_world);
        self.ws.eps_from_forces(model, self.torque.as_slice(), Some(&self.body_forces), eps)?;
        Ok(())
    }

    /// Puts the wrench (world axes, moment about the frame origin) on its
    /// link, in link coordinates about the link origin, and zeroes the joint forces.
    fn load_wrench(&mut self, model: &Model, frame: &BodyFrame, wrench_world: &SpatialVec) {
        let body_from_world = frame.offset.compose(&self.ws.world_transforms(model)[frame.link]);
        let in_body =
            spatial(&(body_from_world.rot * angular(wrench_world)), &(body_from_world.rot * linear(wrench_world)));
        self.body_forces.fill(SpatialVec::zeros());
        // ᵇX_ₗᵀ f: from body coordinates to link coordinates about the link origin.
        self.body_forces[frame.link] = frame.offset.apply_transpose_force(&in_body);
        self.torque.fill(0.0);
    }

    /// The law at (θ, ν): fills `eps`, `error` and `potential`. Parameters
    /// are assumed checked ([`ControlParameters::check`]); θ and ν are checked here.
    pub fn evaluate(
        &mut self,
        model: &Model,
        law: &ControlLaw,
        parameters: &ControlParameters,
        theta: &[f64],
        nu: &[f64],
    ) -> Result<(), ControlError> {
        self.ws.set_configuration(model, theta)?;
        crate::dynamics::check_input("nu", nu, model.nv)?;
        let c2 = &parameters.c2;
        match &law.objective {
            Objective::Joints(joints) => {
                self.torque.fill(0.0);
                for (k, joint) in joints.iter().enumerate() {
                    self.error[k] = parameters.target[k] - self.ws.theta[joint.qpos_adr];
                    self.torque[joint.dof_adr] = c2[k] * self.error[k];
                }
                self.ws.eps_from_forces(model, self.torque.as_slice(), None, self.eps.as_mut_slice())?;
            }
            Objective::Pose(frame) => {
                let (position, orientation) = body_pose(model, &mut self.ws, frame);
                let target = &parameters.target;
                // validate() refused a zero target quaternion.
                let target_orientation = unit_quat_from_wxyz(&target[3..7]).unwrap_or_else(Quat::identity);
                let position_error = Vec3::new(target[0], target[1], target[2]) - position;
                let phi = pose::rotation_error(&orientation, &target_orientation);
                let force = Vec3::new(c2[0], c2[1], c2[2]).component_mul(&position_error);
                // −∂U/∂θ for U = ½ φᵀKφ is the body-frame moment −J_r⁻ᵀ(φ) K φ.
                let gain = Vec3::new(c2[3], c2[4], c2[5]);
                let moment_body = -pose::right_jacobian_inverse_transpose(&phi) * gain.component_mul(&phi);
                for c in 0..3 {
                    self.error[c] = position_error[c];
                    self.error[3 + c] = -phi[c];
                }
                self.load_wrench(model, frame, &spatial(&(orientation * moment_body), &force));
                self.ws.eps_from_forces(
                    model,
                    self.torque.as_slice(),
                    Some(&self.body_forces),
                    self.eps.as_mut_slice(),
                )?;
            }
        }
        for ((eps, c1), nu) in self.eps.iter_mut().zip(&parameters.c1).zip(nu) {
            *eps -= c1 * nu;
        }
        self.potential = 0.5 * self.error.iter().zip(c2).map(|(e, c)| c * e * e).sum::<f64>();
        Ok(())
    }
}
