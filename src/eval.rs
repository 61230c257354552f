//! `nudyn eval`: one evaluation of the diagonalized dynamics per JSON
//! request. The field names are a contract with users' scripts.

use serde::{Deserialize, Serialize};

use crate::dynamics::DynamicsError;
use crate::dynamics::constraint::{ConstraintRows, RowKind};
use crate::model::Model;
use crate::workspace::Workspace;

/// One state to evaluate.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalRequest {
    /// Configuration θ (nq, MuJoCo's qpos).
    pub theta: Vec<f64>,
    /// ν (nv); give this or `qvel`.
    pub nu: Option<Vec<f64>>,
    /// θ̇ (nv, MuJoCo's qvel); give this or `nu`.
    pub qvel: Option<Vec<f64>>,
    /// Applied ε (nv); default 0.
    pub eps: Option<Vec<f64>>,
    /// Physical joint torques and forces (nv, MuJoCo's qfrc_applied); default 0.
    pub torque: Option<Vec<f64>>,
    /// The actuators' controls (nu, MuJoCo's ctrl); without it the actuators
    /// apply no force (and the sensors read them at ctrl = 0, MuJoCo's default).
    pub ctrl: Option<Vec<f64>>,
    /// The actuators' activation states (na, MuJoCo's act); default 0.
    pub act: Option<Vec<f64>>,
    /// The time the `clock` sensors read (s); default 0.
    pub time: Option<f64>,
}

/// The dynamics at one state.
#[derive(Clone, Debug, Serialize)]
pub struct EvalResponse {
    /// θ with quaternions normalized.
    pub theta: Vec<f64>,
    /// θ̇ = ℓ*ν (MuJoCo's qvel).
    pub qvel: Vec<f64>,
    /// ν = m*θ̇.
    pub nu: Vec<f64>,
    /// ν̇ = ε + eps_actuator + eps_tendon_inertia + eps_constraint − C(θ,ν) + eps_passive.
    pub nu_dot: Vec<f64>,
    /// C(θ,ν): the velocity-product terms.
    pub coriolis: Vec<f64>,
    /// θ̈ (MuJoCo's qacc).
    pub qacc: Vec<f64>,
    /// Total applied ε: the request's `eps` plus ℓ·torque.
    pub eps: Vec<f64>,
    /// ε of springs, dampers, gravity and the gravity compensation not
    /// routed to the actuators.
    pub eps_passive: Vec<f64>,
    /// MuJoCo's qfrc_gravcomp (nv), when the model has gravity compensation:
    /// its share on `actuatorgravcomp` joints is inside `qfrc_actuator`
    /// (given `ctrl`), the rest a passive force.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub qfrc_gravcomp: Option<Vec<f64>>,
    /// K = ½|ν|².
    pub kinetic_energy: f64,
    /// Power of the applied ε, ν·ε.
    pub power: f64,
    /// Spatial momentum of the vehicle: angular (about the world origin) then linear, world frame.
    pub momentum: [f64; 6],
    /// What the actuators do, when the request gives `ctrl`.
    #[serde(flatten)]
    pub actuators: Option<ActuatorResponse>,
    /// ε_a of the tendons' armature, when a tendon has armature: the ε of
    /// the force −Jᵀ·a·L̈ the tendons' own inertia puts on the joints.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub eps_tendon_inertia: Option<Vec<f64>>,
    /// The constraint forces, when the model has friction loss or limits.
    #[serde(flatten)]
    pub constraints: Option<ConstraintResponse>,
    /// MuJoCo's sensordata, when the model has sensors.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensordata: Option<Vec<f64>>,
}

/// The actuators at the request's ctrl (MuJoCo's names).
#[derive(Clone, Debug, Serialize)]
pub struct ActuatorResponse {
    /// MuJoCo's actuator_length (nu).
    pub actuator_length: Vec<f64>,
    /// MuJoCo's actuator_velocity (nu).
    pub actuator_velocity: Vec<f64>,
    /// MuJoCo's actuator_force (nu): gain · ctrl + bias, clamped.
    pub actuator_force: Vec<f64>,
    /// T, MuJoCo's qfrc_actuator (nv).
    pub qfrc_actuator: Vec<f64>,
    /// ε = ℓT of the actuators (nv).
    pub eps_actuator: Vec<f64>,
    /// MuJoCo's act_dot (na), when some actuator has an activation state.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub act_dot: Vec<f64>,
}

/// The constraint forces at the request's state (MuJoCo's names).
#[derive(Clone, Debug, Serialize)]
pub struct ConstraintResponse {
    /// Jᵀf, MuJoCo's qfrc_constraint (nv).
    pub qfrc_constraint: Vec<f64>,
    /// ε_c = m⁻¹Jᵀf = ℓ·qfrc_constraint (nv).
    pub eps_constraint: Vec<f64>,
    /// The active rows in MuJoCo's order (that of efc_force).
    pub constraint_rows: Vec<ConstraintRowReport>,
}

/// One active constraint row.
#[derive(Clone, Debug, Serialize)]
pub struct ConstraintRowReport {
    /// "equality", "friction" (friction loss) or "limit".
    pub kind: RowKind,
    /// The equality constraint it belongs to (its element and name or index).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub equality: Option<String>,
    /// The tendon it acts on (tendon friction loss and limits).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tendon: Option<String>,
    /// The joint it acts on (friction loss and limits).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint: Option<String>,
    /// Its dof (friction loss), or the joint's first dof (limit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dof: Option<usize>,
    /// Distance to the limit, negative past it, or the equality's violation
    /// along this row (MuJoCo's efc_pos; 0 for friction loss).
    pub distance: f64,
    /// Its velocity J θ̇ (efc_vel).
    pub velocity: f64,
    /// Its force (efc_force).
    pub force: f64,
}

impl ConstraintResponse {
    fn of(model: &Model, rows: &ConstraintRows) -> Self {
        let joint_of_dof = |dof: usize| model.joints.iter().rev().find(|j| j.dof_adr <= dof).map(|j| j.name.clone());
        let constraint_rows = (0..rows.count)
            .map(|k| {
                let constraints = &model.constraints;
                let (equality, dof) = match rows.kind[k] {
                    RowKind::Equality => (Some(constraints.equalities[rows.id[k]].label.clone()), None),
                    RowKind::Friction => (None, Some(constraints.friction[rows.id[k]].dof)),
                    RowKind::Limit => (None, Some(constraints.limits[rows.id[k]].dof)),
                    RowKind::TendonFriction | RowKind::TendonLimit => (None, None),
                };
                let tendon = match rows.kind[k] {
                    RowKind::TendonFriction => Some(constraints.tendon_friction[rows.id[k]].tendon),
                    RowKind::TendonLimit => Some(constraints.tendon_limits[rows.id[k]].tendon),
                    _ => None,
                };
                let tendon = tendon.map(|t| model.tendons[t].label(t));
                ConstraintRowReport {
                    kind: rows.kind[k],
                    equality,
                    tendon,
                    joint: dof.and_then(joint_of_dof),
                    dof,
                    distance: rows.distance[k],
                    velocity: rows.velocity[k],
                    force: rows.force[k],
                }
            })
            .collect();
        ConstraintResponse {
            qfrc_constraint: rows.qfrc_constraint.clone(),
            eps_constraint: rows.eps_constraint.clone(),
            constraint_rows,
        }
    }
}

/// Why a request could not be evaluated.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// The request gives both or neither of `nu` and `qvel`.
    #[error("give exactly one of \"nu\" and \"qvel\"")]
    Velocity,
    /// The state is not valid for the model.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
}

/// Evaluates one request.
pub fn evaluate(model: &Model, ws: &mut Workspace, request: &EvalRequest) -> Result<EvalResponse, EvalError> {
    let zeros = vec![0.0; model.nv];
    ws.set_configuration(model, &request.theta)?;
    match (&request.nu, &request.qvel) {
        (Some(nu), None) => ws.set_nu(model, nu)?,
        (None, Some(qvel)) => ws.set_qvel(model, qvel)?,
        _ => return Err(EvalError::Velocity),
    }
    if let Some(act) = &request.act {
        ws.set_act(model, act)?;
    } else {
        ws.act.fill(0.0);
    }
    let mut eps = request.eps.clone().unwrap_or_else(|| zeros.clone());
    crate::dynamics::check_input("eps", &eps, model.nv)?;
    if let Some(torque) = &request.torque {
        let mut eps_torque = zeros.clone();
        ws.eps_from_forces(model, torque, None, &mut eps_torque)?;
        eps.iter_mut().zip(&eps_torque).for_each(|(e, t)| *e += t);
    }
    let actuators = match &request.ctrl {
        Some(ctrl) => {
            ws.compute_actuation(model, ctrl)?;
            Some(ActuatorResponse {
                actuator_length: ws.actuator_length.as_slice().to_vec(),
                actuator_velocity: ws.actuator_velocity.as_slice().to_vec(),
                actuator_force: ws.actuator_force.as_slice().to_vec(),
                qfrc_actuator: ws.qfrc_actuator.as_slice().to_vec(),
                eps_actuator: ws.eps_actuator.as_slice().to_vec(),
                act_dot: ws.act_dot.as_slice().to_vec(),
            })
        }
        None => None,
    };
    let mut applied: Vec<f64> = match &actuators {
        Some(a) => eps.iter().zip(&a.eps_actuator).map(|(e, a)| e + a).collect(),
        None => eps.clone(),
    };
    ws.compute_nu_dot(model, &applied)?;
    if model.couples_beyond_tree() {
        ws.apply_constraint_forces(model, &mut applied)?;
    }
    let constraints = (!model.constraints.is_empty()).then(|| ConstraintResponse::of(model, &ws.constraint_rows));
    let eps_tendon_inertia = (!model.tendon_inertia.is_empty()).then(|| ws.tendon_inertia.eps.clone());
    ws.compute_accelerations(model)?;
    let momentum = ws.momentum(model)?;
    let mut response = EvalResponse {
        theta: ws.theta.as_slice().to_vec(),
        qvel: ws.qvel.as_slice().to_vec(),
        nu: ws.nu.as_slice().to_vec(),
        nu_dot: ws.nu_dot.as_slice().to_vec(),
        coriolis: ws.coriolis.as_slice().to_vec(),
        qacc: ws.qacc.as_slice().to_vec(),
        power: ws.power(&eps),
        eps_passive: ws.eps_passive.as_slice().to_vec(),
        qfrc_gravcomp: (!model.gravity_compensation.is_empty()).then(|| ws.qfrc_gravcomp.as_slice().to_vec()),
        kinetic_energy: ws.kinetic_energy(),
        momentum: std::array::from_fn(|k| momentum[k]),
        actuators,
        eps_tendon_inertia,
        constraints,
        sensordata: None,
        eps,
    };
    if !model.sensors.is_empty() {
        let ctrl = request.ctrl.clone().unwrap_or_else(|| vec![0.0; model.actuators.len()]);
        ws.compute_sensors(model, &response.eps, &ctrl, request.time.unwrap_or(0.0))?;
        response.sensordata = Some(ws.sensordata.as_slice().to_vec());
    }
    Ok(response)
}
