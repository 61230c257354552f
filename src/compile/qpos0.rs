//! The qpos0 stage: one workspace, the dynamics evaluated once at qpos0,
//! and from that evaluation every constant MuJoCo's compiler computes
//! there (`mj_setConst`): the check that every joint moves some inertia,
//! the joints' invweights and the stiffness and damping of their
//! `springdamper`s, the tendons' lengths and invweights, the dampings of
//! actuators given a damping ratio, and the equality constraints' anchors,
//! poses and invweights. Then the kinematics of the spring pose give the
//! tendons' spring lengths the file leaves to MuJoCo.

use super::{equality, invweight};
use crate::dynamics::DynamicsError;
use crate::model::{
    Actuator, InvalidModel, LinkSpringDamper, MIN_VALUE, Model, ModelError, Qpos0Constants, TendonConstants, Tree,
};
use crate::vehicle::{Equality, Vehicle};
use crate::workspace::Workspace;

/// The constants of `tree` (compiled from `vehicle`) at its qpos0.
pub(super) fn evaluate(tree: &Tree, vehicle: &Vehicle) -> Result<Qpos0Constants, ModelError> {
    let model = &tree.model;
    let singular = |e| singular(model, e);
    let mut ws = model.workspace();
    // Fails when a joint's articulated inertia is singular: MuJoCo's check
    // that every dof moves some inertia.
    ws.set_configuration(model, &model.qpos0).map_err(singular)?;
    let active: Vec<(usize, &Equality)> = vehicle.equalities.iter().enumerate().filter(|(_, e)| e.active).collect();
    let has_constraints = !tree.constraints.is_empty() || !active.is_empty();
    let has_spring_dampers = vehicle.bodies.iter().flat_map(|b| &b.joints).any(|j| j.springdamper.is_some());
    let dof_invweight0 = match has_constraints || has_spring_dampers {
        true => invweight::mujoco_dof_invweight0(model, vehicle, &mut ws).map_err(singular)?,
        false => Vec::new(),
    };
    let spring_dampers = if has_spring_dampers { spring_dampers(model, vehicle, &dof_invweight0) } else { Vec::new() };
    let mut tendons = tendons_in_qpos0(model, &mut ws)?;
    let actuator_dampings = actuator_dampings(model, &mut ws)?;
    let equalities = match has_constraints {
        true => {
            ws.world_transforms(model);
            let invweights = equality::Invweights { dofs: &dof_invweight0, tendons: &tendons };
            active
                .into_iter()
                .map(|(index, e)| equality::compile(tree, vehicle, &mut ws, &invweights, index, e))
                .collect::<Result<_, _>>()?
        }
        false => Vec::new(),
    };
    if !tendons.is_empty() {
        ws.set_configuration(model, &model.qpos_spring).map_err(singular)?;
        for (k, tendon) in tendons.iter_mut().enumerate() {
            if vehicle.tendons[k].spring_length.is_none() {
                tendon.spring_length = [ws.tendon_length[k]; 2];
            }
        }
    }
    Ok(Qpos0Constants {
        spring_dampers,
        tendons,
        actuator_dampings,
        dof_invweight0: if has_constraints { dof_invweight0 } else { Vec::new() },
        equalities,
    })
}

/// A failed evaluation at qpos0: only a singular articulated inertia can
/// fail there, once the model is valid.
fn singular(model: &Model, error: DynamicsError) -> ModelError {
    match error {
        DynamicsError::Singular { link } => ModelError::Singular { joint: model.links[link].joint_name.clone() },
        other => ModelError::Invalid(InvalidModel::Evaluation(other.to_string())),
    }
}

/// The stiffness and damping of joints with a `springdamper`, as MuJoCo's
/// `AutoSpringDamper` derives them from the joint's inertia in qpos0,
/// I = ndof / Σ `dof_invweight0` over its dofs: k = I/(τζ)², b = 2I/τ (the
/// solref rule for a time constant τ and damping ratio ζ).
fn spring_dampers(model: &Model, vehicle: &Vehicle, dof_invweight0: &[f64]) -> Vec<LinkSpringDamper> {
    let mut derived = Vec::new();
    for (joint, info) in vehicle.bodies.iter().flat_map(|body| &body.joints).zip(&model.joints) {
        let Some(sd) = joint.springdamper else { continue };
        let dofs = info.dof_adr..info.dof_adr + joint.kind.nv();
        let inertia = dofs.len() as f64 / dof_invweight0[dofs.clone()].iter().sum::<f64>().max(MIN_VALUE);
        let stiffness = inertia / (sd.time_constant * sd.damping_ratio).powi(2).max(MIN_VALUE);
        let damping = 2.0 * inertia / sd.time_constant.max(MIN_VALUE);
        derived.extend(model.links.iter().enumerate().filter(|(_, link)| dofs.contains(&link.dof_adr)).map(
            |(link, _)| LinkSpringDamper {
                link,
                stiffness: if sd.spring { stiffness } else { 0.0 },
                damping: if sd.damper { damping } else { 0.0 },
            },
        ));
    }
    derived
}

/// Each tendon's length and J M⁻¹ Jᵀ at the configuration `ws` holds
/// (|m⁻¹Jᵀ|², less the tendons' armature's share: MuJoCo's M includes
/// it), with the spring length the compiled tendon has (the file's).
fn tendons_in_qpos0(model: &Model, ws: &mut Workspace) -> Result<Vec<TendonConstants>, ModelError> {
    let mut eps = vec![0.0; model.nv];
    let mut tendons = Vec::with_capacity(model.tendons.len());
    for (k, tendon) in model.tendons.iter().enumerate() {
        let moment = ws.tendon_moment[k * model.nv..(k + 1) * model.nv].to_vec();
        ws.eps_from_forces(model, &moment, None, &mut eps).map_err(|e| singular(model, e))?;
        tendons.push(TendonConstants {
            length0: ws.tendon_length[k],
            invweight0: ws.inverse_mass_quadratic(model, &eps),
            spring_length: tendon.spring_length,
        });
    }
    Ok(tendons)
}

/// Damping ratios turned into dampings (biasprm[2]) as MuJoCo's compiler
/// does: kv = ratio · 2√(kp·m), with m = (J M⁻¹ Jᵀ)⁻¹ the mass the
/// actuator moves at qpos0, J its moment arms. With M = m m*,
/// J M⁻¹ Jᵀ = |ℓJᵀ|²: the ε of a unit force, from the passes (less the
/// tendons' armature's share: MuJoCo's M includes it).
fn actuator_dampings(model: &Model, ws: &mut Workspace) -> Result<Vec<(usize, f64)>, ModelError> {
    let pending: Vec<usize> = (0..model.actuators.len()).filter(|&k| model.actuators[k].has_damping_ratio()).collect();
    let Some(&first) = pending.first() else { return Ok(Vec::new()) };
    let failed = |actuator: &Actuator, k: usize, reason: String| ModelError::Actuator {
        actuator: actuator.label(k),
        line: actuator.line,
        reason,
    };
    let (mut moment, mut eps) = (vec![0.0; model.nv], vec![0.0; model.nv]);
    ws.set_qvel(model, &eps).map_err(|e| failed(&model.actuators[first], first, e.to_string()))?;
    let mut dampings = Vec::with_capacity(pending.len());
    for k in pending {
        let actuator = &model.actuators[k];
        ws.actuator_moment(model, k, &mut moment)
            .and_then(|()| ws.eps_from_forces(model, &moment, None, &mut eps))
            .map_err(|e| failed(actuator, k, e.to_string()))?;
        let inverse_mass = ws.inverse_mass_quadratic(model, &eps);
        let mass = if inverse_mass > MIN_VALUE { 1.0 / inverse_mass } else { 0.0 };
        let kp = actuator.gain[0];
        if kp < 0.0 {
            return Err(failed(actuator, k, format!("dampratio needs kp >= 0, found kp = {kp}")));
        }
        dampings.push((k, -(actuator.bias[2] * 2.0 * (kp * mass).sqrt())));
    }
    Ok(dampings)
}
