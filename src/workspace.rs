//! Per-instance buffers for the passes, sized once from the model so that
//! no pass allocates. Each field says which pass fills it; per-link arrays
//! are indexed like [`Model::links`](crate::model::Model::links), dof-length
//! vectors like qvel.

use nalgebra::{DVector, SMatrix};

use crate::dynamics::TendonInertiaState;
use crate::dynamics::WrapPath;
use crate::dynamics::constraint::ConstraintRows;
use crate::dynamics::flexible::FlexState;
use crate::dynamics::subspace::Subspace;
use crate::flex::nodes;
use crate::math::{Mat3, Quat, Real, SpatialMat, SpatialVec, Transform, Vec3};
use crate::model::{Model, NodeSite, SensorSource};

/// 6×3 storage for per-link 6×ndof quantities (first `ndof` columns used).
pub type LinkCols<S = f64> = SMatrix<S, 6, 3>;

/// How far the passes have got for the current state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    /// Nothing computed yet.
    Empty,
    /// Passes 0 and 1 done for `theta`.
    Configuration,
    /// Pass 2 done: velocities known.
    Velocity,
    /// Pass 3 without the factor's rates: enough for θ̈
    /// (`compute_accelerations`), not for ν̇ or C.
    JointRates,
    /// Pass 3 done: ν̇ and C known.
    Acceleration,
}

/// Where a link stands in the inward passes' sums (from the model's parent
/// array): the passes keep in each link's slot only what its children add,
/// so no sweep has to clear or seed the slots first.
#[derive(Clone, Copy, Debug, Default)]
pub struct Accumulation {
    /// Some child adds into this link's slots.
    pub has_children: bool,
    /// This link is the first of its parent's children that the inward
    /// passes reach (the highest index): it sets the parent's slots rather
    /// than adding to them.
    pub opens_parent: bool,
    /// A flexible body's modal block adds into this link's slots (`dynamics::flexible`).
    pub has_modes: bool,
    /// This link's parent frame is a node of a flexible body: it adds into
    /// that node's slots instead of its parent link's, and `opens_parent`
    /// says whether it sets them (the first child of that node the inward
    /// passes reach).
    pub node: Option<NodeParent>,
}

/// Where a child body at a node hangs: its flexible body and its entry in
/// `FlexBody::node_children`.
#[derive(Clone, Copy, Debug)]
pub struct NodeParent {
    /// Index into `Model::flexible` (and `Workspace::flex`).
    pub flexible: u32,
    /// Index into that body's `node_children`.
    pub child: u32,
}

impl Accumulation {
    /// Whether the passes that carry modal blocks find anything in this link's slots.
    #[inline(always)]
    pub fn gathers(&self) -> bool {
        self.has_children || self.has_modes
    }
}

/// Preallocated buffers and results of the passes.
#[derive(Clone, Debug)]
pub struct Workspace<S: Real = f64> {
    /// How far the passes have got.
    pub stage: Stage,
    /// Each link's place in the inward sums (fixed by the model).
    pub accumulation: Vec<Accumulation>,
    /// Each flexible body's modal block (model order).
    pub flex: Vec<FlexState<S>>,
    /// The shape of each link's motion subspace (fixed by the model).
    pub subspaces: Vec<Subspace>,
    /// The configuration θ (qpos, quaternions normalized) — set_configuration.
    pub theta: DVector<S>,

    /// ⁱX_λ: link relative to parent link (or world) — pass 0.
    pub x_parent: Vec<Transform<S>>,
    /// ⁱX₀: link relative to world — pass 0 when the model has gravity,
    /// else on demand (momentum).
    pub x_world: Vec<Transform<S>>,
    /// Whether `x_world` belongs to the current configuration.
    pub world_transforms_current: bool,

    /// I^a = I^A − U D⁻¹ Uᵀ: what the parent sees through the joint — pass 1.
    /// Pass 1 accumulates the children's share of the articulated-body
    /// inertia I^A (the paper's P) in the same slot and replaces it once the
    /// link's joint is factored: one 6×6 array fewer to stream through the
    /// cache on long chains.
    pub ia_reduced: Vec<SpatialMat<S>>,
    /// G = U D⁻¹ (the paper's Kalman gain) — pass 1.
    pub gain: Vec<LinkCols<S>>,
    /// R, upper triangular with R Rᵀ = D (D^½ of docs/DYNAMICS.md §3) — pass 1.
    pub r_joint: Vec<Mat3<S>>,
    /// R⁻¹ — pass 1.
    pub r_inv_joint: Vec<Mat3<S>>,

    /// ν — pass 2 (given, or computed from θ̇).
    pub nu: DVector<S>,
    /// θ̇ in dof space (MuJoCo's qvel) — pass 2.
    pub qvel: DVector<S>,
    /// w = R⁻ᵀ ν = θ̇ + GᵀV⁺, stored in dof layout — pass 2.
    pub w_joint: DVector<S>,
    /// V⁺ = X V_λ: parent velocity in link coordinates — pass 2.
    pub v_plus_body: Vec<SpatialVec<S>>,
    /// V: link spatial velocity in link coordinates — pass 2.
    pub v_body: Vec<SpatialVec<S>>,

    /// Children's share of the velocity-product bias p^A — pass 3.
    pub p_bias_body: Vec<SpatialVec<S>>,
    /// Children's share of the force bias (gravity, springs, dampers) — pass 3.
    pub p_force_body: Vec<SpatialVec<S>>,
    /// Children's share of the force-only recursions' p (ε ↔ T).
    pub p_scratch_body: Vec<SpatialVec<S>>,
    /// Whether some link below each link carries torque, in a pass over
    /// torques on few links (`forces::eps_of_sparse_torque`); set, like the
    /// slots, by the first child the pass reaches.
    pub subtree_carries: Vec<bool>,
    /// Children's share of İ^A — pass 3.
    pub ia_dot_body: Vec<SpatialMat<S>>,
    /// Gravity compensation on each link (link coordinates), nonzero on the
    /// compensated links only; empty without compensation — set_configuration.
    pub gravcomp_wrench: Vec<SpatialVec<S>>,
    /// MuJoCo's qfrc_gravcomp (nv), zero without compensation — set_configuration.
    pub qfrc_gravcomp: DVector<S>,
    /// Passive joint forces: springs, dampers and the gravity compensation
    /// not routed to the actuators — pass 3.
    pub tau_passive: DVector<S>,
    /// ε of the passive forces and gravity, ℓ(θ)(τ_passive + Jᵀf_gravity) — pass 3.
    pub eps_passive: DVector<S>,
    /// C(θ, ν): velocity-product terms — pass 3.
    pub coriolis: DVector<S>,
    /// ν̇ = ε − C + eps_passive — pass 3.
    pub nu_dot: DVector<S>,
    /// ν̇ less its terms from the factor's rates (Ṙᵀw + RᵀĠᵀV⁺):
    /// ε + ε_passive + R⁻¹u, what θ̈ needs — pass 3, with or without the rates.
    pub nu_dot_joint: DVector<S>,
    /// θ̈ in dof space (MuJoCo's qacc) — compute_accelerations.
    pub qacc: DVector<S>,
    /// A: link spatial acceleration in link coordinates, the world at rest
    /// (gravity not included) — compute_accelerations.
    pub a_body: Vec<SpatialVec<S>>,

    /// Whether some actuator applies wrenches to links (fixed by the model).
    pub actuators_apply_wrenches: bool,
    /// MuJoCo's actuator_length (nu) — compute_actuation.
    pub actuator_length: DVector<S>,
    /// MuJoCo's actuator_velocity (nu) — compute_actuation.
    pub actuator_velocity: DVector<S>,
    /// MuJoCo's act (na), the activation states the actuators' forces read — set_act.
    pub act: DVector<S>,
    /// MuJoCo's act_dot (na), their rates — compute_actuation.
    pub act_dot: DVector<S>,
    /// MuJoCo's actuator_force (nu) — compute_actuation.
    pub actuator_force: DVector<S>,
    /// Wrenches of site actuators on each link (link coordinates) — compute_actuation.
    pub link_wrench: Vec<SpatialVec<S>>,
    /// T of the actuators, MuJoCo's qfrc_actuator (nv) — compute_actuation.
    pub qfrc_actuator: DVector<S>,
    /// T of the actuators and the wrench inputs together (nv) — compute_actuation.
    pub qfrc_total: DVector<S>,
    /// ε = ℓT of the actuators and the wrench inputs (nv) — compute_actuation.
    pub eps_actuator: DVector<S>,
    /// The ε pass 3 applied: the input's plus the actuators' and the
    /// constraints' (nv) — compute_nu_dot_actuated.
    pub eps_applied: DVector<f64>,
    /// The inputs of the last compute_nu_dot_actuated: ε (nv) and ctrl.
    pub eps_input: DVector<f64>,
    /// See `eps_input`.
    pub ctrl_input: DVector<f64>,
    /// Whether pass 3 is that of `eps_input` and `ctrl_input` (cleared by
    /// every other pass 3), so that the sensors need not run it again.
    pub inputs_applied: bool,

    /// Each tendon's length (MuJoCo's ten_length) — set_configuration.
    pub tendon_length: DVector<S>,
    /// Each tendon's moment arms, row k the entries k·nv .. (k+1)·nv
    /// (MuJoCo's ten_J, dense) — set_configuration.
    pub tendon_moment: Vec<S>,
    /// Each tendon's velocity J θ̇ (MuJoCo's ten_velocity) — pass 2.
    pub tendon_velocity: DVector<S>,
    /// Per-link scratch of the spatial tendons' unit forces (empty without
    /// spatial tendons) — set_configuration.
    pub tendon_wrench: Vec<SpatialVec<S>>,
    /// The spatial tendons' wraps' switching functions (`WRAP_SWITCHES`
    /// per wrap: whether it meets its geom, both sites outside it, which
    /// way round; +∞ where not reached) — set_configuration.
    pub wrap_switching: Vec<f64>,
    /// The path each wrap took — set_configuration.
    pub wrap_paths: Vec<WrapPath>,
    /// The wraps' paths an integrator holds over a step
    /// (`Workspace::hold_working_set`), when `wraps_held`.
    pub wrap_paths_held: Vec<WrapPath>,
    /// Whether set_configuration takes `wrap_paths_held` rather than
    /// deciding the paths on the state.
    pub wraps_held: bool,
    /// Each tendon's sum of its actuators' forces before their force range
    /// (empty when no tendon has an `actuatorfrcrange`) — compute_actuation.
    pub tendon_actuator_total: Vec<f64>,

    /// The tendons' armature: its columns and factors — set_configuration;
    /// its forces and ε — apply_constraint_forces.
    pub tendon_inertia: TendonInertiaState<S>,
    /// The active constraint rows and their forces — apply_constraint_forces.
    pub constraint_rows: ConstraintRows<S>,

    /// MuJoCo's sensordata — compute_sensors.
    pub sensordata: DVector<S>,
    /// Each link's orientation in the world as MuJoCo composes `xquat`,
    /// when a framequat sensor needs it — compute_sensors.
    pub link_quats: Vec<Quat<S>>,
    /// Each body's inertial force less the external forces on it (world
    /// axes, torque about its centre of mass), when a force or torque
    /// sensor needs it — compute_sensors.
    pub body_wrench: Vec<SpatialVec<S>>,
    /// Each body's centre of mass in the world, with `body_wrench`.
    pub body_com: Vec<Vec3<S>>,
}

impl Workspace {
    /// Buffers sized for `model`.
    pub fn new(model: &Model) -> Self {
        Self::in_scalar(model)
    }
}

impl<S: Real> Workspace<S> {
    /// Buffers sized for `model`, the passes' quantities in `S`
    /// (a dual number for derivatives; [`Workspace::new`] for `f64`).
    pub fn in_scalar(model: &Model) -> Self {
        let n = model.links.len();
        let dof = || DVector::zeros(model.nv);
        let mut accumulation = vec![Accumulation::default(); n];
        let mut opened_nodes = Vec::new();
        for (f, flexible) in model.flexible.iter().enumerate() {
            for (c, child) in flexible.node_children.iter().enumerate() {
                accumulation[child.link].node = Some(NodeParent { flexible: f as u32, child: c as u32 });
            }
        }
        for (i, link) in model.links.iter().enumerate().rev() {
            if let Some(at) = accumulation[i].node {
                let slot = (at.flexible, model.flexible[at.flexible as usize].node_children[at.child as usize].slot);
                accumulation[i].opens_parent = !opened_nodes.contains(&slot);
                opened_nodes.push(slot);
            } else if let Some(p) = link.parent
                && !accumulation[p].has_children
            {
                accumulation[p].has_children = true;
                accumulation[i].opens_parent = true;
            }
        }
        let flex = model
            .flexible
            .iter()
            .map(|flexible| {
                let slots = &mut accumulation[flexible.link];
                let opens_link = !slots.gathers();
                slots.has_modes = true;
                FlexState::new(flexible, opens_link)
            })
            .collect();
        let nu = model.actuators.len();
        let actuators_apply_wrenches = model.actuators.iter().any(|a| a.transmission.applies_wrenches());
        let interaction_bodies = if model.sensors.iter().any(|s| matches!(s.source, SensorSource::Interaction { .. })) {
            model.body_masses.len()
        } else {
            0
        };
        let spatial_tendons = model.tendons.iter().any(|t| matches!(t.path, crate::model::Path::Spatial { .. }));
        Workspace {
            stage: Stage::Empty,
            accumulation,
            flex,
            subspaces: model.links.iter().map(|link| Subspace::of(&link.motion_subspace, link.ndof)).collect(),
            theta: DVector::from_iterator(model.nq, model.qpos0.iter().map(|&q| S::from(q))),
            x_parent: vec![Transform::identity(); n],
            x_world: vec![Transform::identity(); n],
            world_transforms_current: false,
            ia_reduced: vec![SpatialMat::zeros(); n],
            gain: vec![LinkCols::zeros(); n],
            r_joint: vec![Mat3::zeros(); n],
            r_inv_joint: vec![Mat3::zeros(); n],
            nu: dof(),
            qvel: dof(),
            w_joint: dof(),
            v_plus_body: vec![SpatialVec::zeros(); n],
            v_body: vec![SpatialVec::zeros(); n],
            p_bias_body: vec![SpatialVec::zeros(); n],
            p_force_body: vec![SpatialVec::zeros(); n],
            p_scratch_body: vec![SpatialVec::zeros(); n],
            subtree_carries: vec![false; n],
            ia_dot_body: vec![SpatialMat::zeros(); n],
            gravcomp_wrench: vec![SpatialVec::zeros(); if model.gravity_compensation.is_empty() { 0 } else { n }],
            qfrc_gravcomp: dof(),
            tau_passive: dof(),
            eps_passive: dof(),
            coriolis: dof(),
            nu_dot: dof(),
            nu_dot_joint: dof(),
            qacc: dof(),
            a_body: vec![SpatialVec::zeros(); n],
            actuators_apply_wrenches,
            actuator_length: DVector::zeros(nu),
            actuator_velocity: DVector::zeros(nu),
            act: DVector::zeros(model.activation_count()),
            act_dot: DVector::zeros(model.activation_count()),
            actuator_force: DVector::zeros(nu),
            link_wrench: vec![SpatialVec::zeros(); if actuators_apply_wrenches { n } else { 0 }],
            qfrc_actuator: dof(),
            qfrc_total: dof(),
            eps_actuator: dof(),
            eps_applied: DVector::zeros(model.nv),
            eps_input: DVector::zeros(model.nv),
            ctrl_input: DVector::zeros(nu),
            inputs_applied: false,
            tendon_length: DVector::zeros(model.tendons.len()),
            tendon_moment: vec![S::zero(); model.tendons.len() * model.nv],
            tendon_velocity: DVector::zeros(model.tendons.len()),
            tendon_wrench: vec![SpatialVec::zeros(); if spatial_tendons { n } else { 0 }],
            wrap_switching: vec![f64::INFINITY; model.wrap_switches()],
            wrap_paths: vec![WrapPath::Straight; model.wrap_count()],
            wrap_paths_held: vec![WrapPath::Straight; model.wrap_count()],
            wraps_held: false,
            tendon_actuator_total: vec![
                0.0;
                if model.tendons.iter().any(|t| t.actuator_force_range.is_some()) {
                    model.tendons.len()
                } else {
                    0
                }
            ],
            tendon_inertia: TendonInertiaState::new(model),
            constraint_rows: ConstraintRows::new(model),
            sensordata: DVector::zeros(model.sensors.iter().map(|s| s.dim()).sum()),
            link_quats: vec![Quat::identity(); model.link_tree_quats.len()],
            body_wrench: vec![SpatialVec::zeros(); interaction_bodies],
            body_com: vec![Vec3::zeros(); interaction_bodies],
        }
    }

    /// The modal coordinates η of the flexible body `at` names, and its
    /// node's placement ʲX_R on the body at that η: where a site, a sensor's
    /// frame or an actuator's point riding the node is carried.
    pub(crate) fn node_placement(&self, model: &Model, at: NodeSite) -> (&[S], Transform<S>) {
        let flexible = &model.flexible[at.flexible];
        let eta = flexible.eta(self.theta.as_slice());
        (eta, nodes::transform(&flexible.modal, at.node, eta))
    }
}

impl Model {
    /// A fresh workspace for this model.
    pub fn workspace(&self) -> Workspace {
        Workspace::new(self)
    }
}
