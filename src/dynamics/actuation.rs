//! Actuators (docs/DYNAMICS.md §5): MuJoCo's transmission (actuator length,
//! velocity and moment arms), force law and generalized force T (its
//! `qfrc_actuator`), and the ε = ℓT they produce, in O(N).
//!
//! A joint transmission puts its moment arms straight on the joint's dofs.
//! A site transmission is a wrench on the link carrying the site (and, with
//! a reference site, the opposite wrench on the reference's link); one
//! inward pass turns all wrenches into joint forces, T_i = S_iᵀ Σ_subtree f,
//! and another maps T to ε. A site at a node of a flexible body puts its
//! wrench f_j on the node: on the link as ʲX_Rᵀ f_j (the node's deformed
//! placement), and on the body's modes as Ψ_jᵀ f_j (docs/flexible.md).
//! Nothing forms a Jacobian or the mass matrix.
//! An actuator's velocity is its moment arms times θ̇, as in MuJoCo: for a
//! wrench f on a link moving with V, f·V.

use nalgebra::Rotation3;

use super::{DynamicsError, check_input, check_length, forces, require};
use crate::flex::nodes;
use crate::math::{Mat3, Quat, Real, SpatialVec, Transform, Vec3, quat_difference, quat_from_wxyz, real, spatial};
use crate::model::{Actuator, ActuatorTransmission, Model, NodeSite, SiteFrame};
use crate::vehicle::{BiasType, GainType};
use crate::workspace::{Stage, Workspace};

/// Where a unit force of one actuator goes.
enum Moment<S: Real> {
    /// Moment arms on `count` consecutive dofs from `dof`.
    Dofs { dof: usize, arms: [S; 6], count: usize },
    /// Wrenches on links, and at nodes.
    Wrenches(SiteWrenches<S>),
    /// A tendon's moment arms times `gear`.
    Tendon { tendon: usize, gear: f64 },
}

/// A site transmission's unit wrenches: on links (link coordinates, about
/// the link origin), and the same at the nodes that carry sites, for their
/// modal forces.
struct SiteWrenches<S: Real> {
    wrenches: [(usize, SpatialVec<S>); 3],
    count: usize,
    at_nodes: [Option<NodeWrench<S>>; 3],
}

/// One unit wrench of a site transmission: on `link` (link coordinates,
/// about its origin), and the same on the node it reaches the link through.
#[derive(Clone, Copy)]
struct OnLink<S: Real> {
    link: usize,
    wrench: SpatialVec<S>,
    at_node: Option<NodeWrench<S>>,
}

/// A wrench on a node of a flexible body (node coordinates, about its
/// origin): its modal forces are Ψ_jᵀ f (docs/flexible.md, "Sites at nodes").
#[derive(Clone, Copy)]
struct NodeWrench<S: Real> {
    at: NodeSite,
    wrench: SpatialVec<S>,
}

/// What carries a site: its link, and the node it rides with ʲX_R, the
/// node's placement on the link at the workspace's η.
struct Carrier<S: Real> {
    link: usize,
    node: Option<(NodeSite, Transform<S>)>,
}

impl<S: Real> Carrier<S> {
    /// The carrier of `site`, `None` for a site on the world.
    fn of(model: &Model, ws: &Workspace<S>, site: &SiteFrame) -> Option<Carrier<S>> {
        let link = site.link?;
        let node = site.node.map(|at| (at, ws.node_placement(model, at).1));
        Some(Carrier { link, node })
    }

    /// The carrier's placement in the world (the link's, or the node's on it).
    fn in_world(&self, x_world: &[Transform<S>]) -> Transform<S> {
        match &self.node {
            None => x_world[self.link],
            Some((_, x_node)) => x_node.compose(&x_world[self.link]),
        }
    }

    /// A wrench `f` in the carrier's coordinates on the link (about its
    /// origin), with the node's share when it rides one.
    fn wrench(&self, f: SpatialVec<S>) -> OnLink<S> {
        match &self.node {
            None => OnLink { link: self.link, wrench: f, at_node: None },
            Some((at, x_node)) => OnLink {
                link: self.link,
                wrench: x_node.apply_transpose_force(&f),
                at_node: Some(NodeWrench { at: *at, wrench: f }),
            },
        }
    }
}

/// An actuator's transmission at the current state.
struct Transmitted<S: Real> {
    length: S,
    velocity: S,
    moment: Moment<S>,
}

impl<S: Real> SiteWrenches<S> {
    /// Wrenches collected on the links that exist (a site on the world
    /// moves nothing), with the node shares of those at nodes.
    fn of(candidates: [Option<OnLink<S>>; 3]) -> SiteWrenches<S> {
        let mut out = SiteWrenches { wrenches: [(0, SpatialVec::zeros()); 3], count: 0, at_nodes: [None; 3] };
        let mut node_count = 0;
        for OnLink { link, wrench, at_node } in candidates.into_iter().flatten() {
            out.wrenches[out.count] = (link, wrench);
            out.count += 1;
            if at_node.is_some() {
                out.at_nodes[node_count] = at_node;
                node_count += 1;
            }
        }
        out
    }

    /// Their power at the workspace's velocities: Σ f·V over the links,
    /// plus Σ f_j·Ψ_jη̇ over the nodes (as MuJoCo, moment arms times θ̇).
    fn power(&self, model: &Model, ws: &Workspace<S>) -> S {
        let on_links =
            self.wrenches[..self.count].iter().fold(S::from(-0.0), |sum, (link, w)| sum + w.dot(&ws.v_body[*link]));
        self.at_nodes.iter().flatten().fold(on_links, |sum, node| {
            let flexible = &model.flexible[node.at.flexible];
            let (v, m) = (flexible.dof_adr, flexible.mode_count());
            let (eta, rate) = (flexible.eta(ws.theta.as_slice()), &ws.qvel.as_slice()[v..v + m]);
            sum + node.wrench.dot(&nodes::subspace_times(&flexible.modal, node.at.node, eta, rate))
        })
    }

    /// Transmitted with this moment, its velocity its power.
    fn transmitted(self, model: &Model, ws: &Workspace<S>, length: S) -> Transmitted<S> {
        Transmitted { length, velocity: self.power(model, ws), moment: Moment::Wrenches(self) }
    }
}

/// The rotation vector of a unit quaternion, its angle in [−π, π] (MuJoCo's
/// `mju_quat2Vel` with unit time).
fn rotation_vector<S: Real>(q: &Quat<S>) -> Vec3<S> {
    quat_difference(q, &Quat::identity())
}

/// The rotation of a unit (w, x, y, z) quaternion in θ (set_configuration normalized it).
fn rotation_at<S: Real>(theta: &[S], qpos: usize) -> Quat<S> {
    Quat::new_unchecked(quat_from_wxyz(&theta[qpos..qpos + 4]))
}

/// A site's placement in the world, ˢX₀, from its link's.
pub(super) fn site_in_world<S: Real>(site: &SiteFrame, x_world: &[Transform<S>]) -> Transform<S> {
    match site.link {
        Some(link) => site.frame.real().compose(&x_world[link]),
        None => site.frame.real(),
    }
}

/// A site's placement in the world, ˢX₀, with its carrier (`None` on the world).
fn site_placement<S: Real>(site: &SiteFrame, carrier: &Option<Carrier<S>>, x_world: &[Transform<S>]) -> Transform<S> {
    match carrier {
        Some(carrier) => site.frame.real().compose(&carrier.in_world(x_world)),
        None => site.frame.real(),
    }
}

/// The wrench of force `f` through the site's origin and torque `n` (both in
/// world axes) on the site's carrier, in link coordinates about the link
/// origin, with the node's share when the site rides one.
fn wrench_at_site<S: Real>(
    site: &SiteFrame,
    carrier: &Option<Carrier<S>>,
    x_world: &[Transform<S>],
    n: &Vec3<S>,
    f: &Vec3<S>,
) -> Option<OnLink<S>> {
    let carrier = carrier.as_ref()?;
    let to_carrier = carrier.in_world(x_world).rot;
    let (n, f) = (to_carrier * n, to_carrier * f);
    // The site's origin in the carrier's coordinates.
    let r = real::<S, 3, 1>(&site.frame.trans);
    Some(carrier.wrench(spatial(&(n + r.cross(&f)), &f)))
}

/// Length, velocity and unit moment of `actuator` at the workspace's state
/// (world placements must be current for a reference site).
fn transmit<S: Real>(model: &Model, ws: &Workspace<S>, actuator: &Actuator) -> Transmitted<S> {
    let theta = ws.theta.as_slice();
    let qvel = ws.qvel.as_slice();
    let gear = &actuator.gear;
    let zero = S::zero();
    // From −0, as f64's `sum` starts.
    let dot = |arms: &[S], dof: usize| arms.iter().zip(&qvel[dof..]).fold(S::from(-0.0), |sum, (a, v)| sum + *a * *v);
    match actuator.transmission {
        ActuatorTransmission::Scalar { dof, qpos } => {
            let arms = [S::from(gear[0]), zero, zero, zero, zero, zero];
            Transmitted {
                length: theta[qpos] * gear[0],
                velocity: qvel[dof] * gear[0],
                moment: Moment::Dofs { dof, arms, count: 1 },
            }
        }
        ActuatorTransmission::Ball { dof, qpos, in_parent } => {
            let rotation = rotation_at(theta, qpos);
            let gear = real::<S, 3, 1>(&actuator.gear_translation());
            // The child-frame axis: a parent-frame gear turns with the joint.
            let axis = if in_parent { rotation.inverse_transform_vector(&gear) } else { gear };
            let arms = [axis.x, axis.y, axis.z, zero, zero, zero];
            Transmitted {
                length: rotation_vector(&rotation).dot(&axis),
                velocity: dot(&arms[..3], dof),
                moment: Moment::Dofs { dof, arms, count: 3 },
            }
        }
        ActuatorTransmission::Free { dof, qpos, in_parent } => {
            let torque_axis = real::<S, 3, 1>(&actuator.gear_rotation());
            let axis =
                if in_parent { rotation_at(theta, qpos).inverse_transform_vector(&torque_axis) } else { torque_axis };
            let arms = [S::from(gear[0]), S::from(gear[1]), S::from(gear[2]), axis.x, axis.y, axis.z];
            Transmitted { length: zero, velocity: dot(&arms, dof), moment: Moment::Dofs { dof, arms, count: 6 } }
        }
        ActuatorTransmission::Site { site } => {
            let Some(carrier) = Carrier::of(model, ws, &site) else {
                return SiteWrenches::of([None; 3]).transmitted(model, ws, zero);
            };
            // The gear in site coordinates, moved to the carrier's origin.
            let in_site = spatial(&actuator.gear_rotation(), &actuator.gear_translation());
            let wrench: SpatialVec<S> = real(&site.frame.apply_transpose_force(&in_site));
            SiteWrenches::of([Some(carrier.wrench(wrench)), None, None]).transmitted(model, ws, zero)
        }
        ActuatorTransmission::RelativeSite { site, reference, common_link, common_node } => {
            relative_site(model, ws, actuator, &site, &reference, common_link, common_node)
        }
        ActuatorTransmission::Tendon { tendon } => Transmitted {
            length: ws.tendon_length[tendon] * gear[0],
            velocity: ws.tendon_velocity[tendon] * gear[0],
            moment: Moment::Tendon { tendon, gear: gear[0] },
        },
    }
}

/// A site transmission measured in a reference site's frame (MuJoCo's
/// `refsite`): length = gear · (the site's position in the reference frame,
/// and the rotation vector from the reference to the site's orientation);
/// force and torque along the reference frame's axes, at the site and
/// opposite at the reference site, and on their common link (or the node
/// on it that both hang from) the torque that cancels the pair's couple
/// there (MuJoCo clears those moment arms).
fn relative_site<S: Real>(
    model: &Model,
    ws: &Workspace<S>,
    actuator: &Actuator,
    site: &SiteFrame,
    reference: &SiteFrame,
    common_link: Option<usize>,
    common_node: Option<NodeSite>,
) -> Transmitted<S> {
    let x_world = ws.x_world.as_slice();
    let (site_carrier, reference_carrier) = (Carrier::of(model, ws, site), Carrier::of(model, ws, reference));
    let (at_site, at_reference) =
        (site_placement(site, &site_carrier, x_world), site_placement(reference, &reference_carrier, x_world));
    // Rotations site → world (columns: the site's axes in world).
    let (site_axes, reference_axes): (Mat3<S>, Mat3<S>) = (at_site.rot.transpose(), at_reference.rot.transpose());
    let (gear_translation, gear_rotation) = (actuator.gear_translation(), actuator.gear_rotation());
    let (gear_translation, gear_rotation, nonzero) = (
        real::<S, 3, 1>(&gear_translation),
        real::<S, 3, 1>(&gear_rotation),
        (gear_translation != Vec3::zeros(), gear_rotation != Vec3::zeros()),
    );
    let offset = at_site.trans - at_reference.trans;
    let mut length = S::zero();
    if nonzero.0 {
        length += (reference_axes.transpose() * offset).dot(&gear_translation);
    }
    if nonzero.1 {
        let orientation = |axes: &Mat3<S>| Quat::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*axes));
        length += quat_difference(&orientation(&site_axes), &orientation(&reference_axes)).dot(&gear_rotation);
    }
    let force = reference_axes * gear_translation;
    let torque = reference_axes * gear_rotation;
    let on_site = wrench_at_site(site, &site_carrier, x_world, &torque, &force);
    let on_reference = wrench_at_site(reference, &reference_carrier, x_world, &(-torque), &(-force));
    let couple = offset.cross(&force);
    let correction = common_link.map(|link| {
        let carrier =
            Carrier::of(model, ws, &SiteFrame { link: Some(link), frame: Transform::identity(), node: common_node })
                .expect("a common link");
        carrier.wrench(spatial(&(carrier.in_world(x_world).rot * -couple), &Vec3::zeros()))
    });
    SiteWrenches::of([on_site, on_reference, correction]).transmitted(model, ws, length)
}

/// Each actuator's activation state (its index in act: they are numbered
/// in actuator order), or `None` for a stateless one.
fn activation_slots(model: &Model) -> impl Iterator<Item = Option<usize>> + '_ {
    let mut next = 0;
    model.actuators.iter().map(move |actuator| {
        actuator.activation.map(|_| {
            next += 1;
            next - 1
        })
    })
}

/// ctrl clamped to the actuator's range, unless `<flag clampctrl="disable"/>`.
pub(crate) fn clamped_ctrl<S: Real>(actuator: &Actuator, clamp_ctrl: bool, ctrl: S) -> S {
    match actuator.ctrl_range {
        Some([low, high]) if clamp_ctrl => clip(ctrl, low, high),
        _ => ctrl,
    }
}

/// MuJoCo's force of an actuator before its force range: gain · input plus
/// bias (the setpoint of a rotation servo taken nearest the length), the
/// input being the clamped ctrl, or the activation the force reads
/// ([`Workspace::actuator_input`]); a disabled group gives 0
/// ([`clamp_force`] still clamps it).
pub(super) fn unclamped_force<S: Real>(actuator: &Actuator, input: S, length: S, velocity: S) -> S {
    let mut force = S::zero();
    if actuator.enabled {
        let [g0, g1, g2] = actuator.gain;
        let gain = match actuator.gain_type {
            GainType::Fixed => S::from(g0),
            GainType::Affine => length * g1 + g0 + velocity * g2,
        };
        let [b0, b1, b2] = actuator.bias;
        let bias = match actuator.bias_type {
            BiasType::None => S::zero(),
            BiasType::Affine => length * b1 + b0 + velocity * b2,
        };
        let period = actuator.setpoint_period;
        // The turns taken off are a whole number: piecewise constant in the state.
        let turns = || ((input - length) / period).value().round();
        let input = if period > 0.0 { input - S::from(period * turns()) } else { input };
        force = gain * input + bias;
    }
    force
}

/// The actuator's force clamped to its `forcerange`.
pub(super) fn clamp_force<S: Real>(actuator: &Actuator, force: S) -> S {
    match actuator.force_range {
        Some([low, high]) => clip(force, low, high),
        None => force,
    }
}

/// What MuJoCo multiplies each force of a tendon's actuators by when their
/// sum `total` lies outside the tendon's `actuatorfrcrange`: the near end
/// of the range over the sum, so that the scaled forces sum to it.
fn tendon_force_scale<S: Real>(range: Option<[f64; 2]>, total: f64) -> S {
    S::from(match range {
        Some([low, _]) if total != 0.0 && total < low => low / total,
        Some([_, high]) if total != 0.0 && total > high => high / total,
        _ => 1.0,
    })
}

/// MuJoCo's `mju_clip`.
fn clip<S: Real>(x: S, low: f64, high: f64) -> S {
    if x.value() < low {
        S::from(low)
    } else if x.value() > high {
        S::from(high)
    } else {
        x
    }
}

/// Adds `force` times the unit moment to the dof forces or link wrenches
/// (`tendon_moment`: the tendons' moment arms, nv per tendon; `theta` the
/// configuration, for the modal forces of wrenches at nodes).
fn apply<S: Real>(
    model: &Model,
    theta: &[S],
    moment: &Moment<S>,
    force: S,
    qfrc: &mut [S],
    link_wrench: &mut [SpatialVec<S>],
    tendon_moment: &[S],
) {
    match moment {
        Moment::Dofs { dof, arms, count } => {
            for (slot, arm) in qfrc[*dof..*dof + count].iter_mut().zip(arms) {
                *slot += *arm * force;
            }
        }
        Moment::Wrenches(unit) => {
            for (link, wrench) in &unit.wrenches[..unit.count] {
                link_wrench[*link] += wrench * force;
            }
            for node in unit.at_nodes.iter().flatten() {
                let flexible = &model.flexible[node.at.flexible];
                let (v, m) = (flexible.dof_adr, flexible.mode_count());
                let (eta, modal) = (flexible.eta(theta), &mut qfrc[v..v + m]);
                nodes::add_subspace_transpose_times(&flexible.modal, node.at.node, eta, &node.wrench, force, modal);
            }
        }
        Moment::Tendon { tendon, gear } => {
            let nv = qfrc.len();
            let arms = &tendon_moment[tendon * nv..(tendon + 1) * nv];
            for (slot, arm) in qfrc.iter_mut().zip(arms) {
                *slot += force * (*arm * *gear);
            }
        }
    }
}

impl Workspace {
    /// The actuators at `ctrl` (MuJoCo's `d.ctrl`, then the wrench inputs'
    /// six values per body, MuJoCo's `xfrc_applied`): fills
    /// `actuator_length`, `actuator_velocity`, `actuator_force`,
    /// `qfrc_actuator` (T of the MJCF's actuators, with the gravity
    /// compensation of `actuatorgravcomp` joints) and `eps_actuator`
    /// (ℓ(T + Jᵀ xfrc)); with `<flag actuation="disable"/>` the MJCF's
    /// actuators have lengths only, as in MuJoCo. Needs the velocities.
    pub fn compute_actuation(&mut self, model: &Model, ctrl: &[f64]) -> Result<(), DynamicsError> {
        require(self, Stage::Velocity, "compute_actuation")?;
        check_input("ctrl", ctrl, model.actuators.len())?;
        self.actuation_pass(model, ctrl)
    }
    /// Pass 3 with the actuators: ν̇ for the applied `eps` (nv) plus the ε of
    /// the actuators at `ctrl` (nu, MuJoCo's `d.ctrl`), as the FMU and the
    /// integrators apply them. A vehicle without actuators goes straight to
    /// pass 3, so it costs what it did before actuators existed.
    pub fn compute_nu_dot_actuated(&mut self, model: &Model, eps: &[f64], ctrl: &[f64]) -> Result<(), DynamicsError> {
        self.with_actuators(model, eps, ctrl, Self::compute_nu_dot)
    }

    /// θ̈ for the same inputs as [`Workspace::compute_nu_dot_actuated`],
    /// without ν̇ ([`Workspace::compute_qacc`]).
    pub fn compute_qacc_actuated(&mut self, model: &Model, eps: &[f64], ctrl: &[f64]) -> Result<(), DynamicsError> {
        self.with_actuators(model, eps, ctrl, Self::compute_qacc)
    }

    /// Runs `pass` with ε = `eps` plus the actuators' at `ctrl` and the
    /// constraint forces' ε_c, leaving that total in `eps_applied`.
    fn with_actuators(
        &mut self,
        model: &Model,
        eps: &[f64],
        ctrl: &[f64],
        pass: fn(&mut Self, &Model, &[f64]) -> Result<(), DynamicsError>,
    ) -> Result<(), DynamicsError> {
        check_length("ctrl", ctrl, model.actuators.len())?;
        check_input("eps", eps, model.nv)?;
        let mut applied = std::mem::take(&mut self.eps_applied);
        if model.actuators.is_empty() {
            applied.copy_from_slice(eps);
        } else {
            self.compute_actuation(model, ctrl)?;
            for ((total, input), actuator) in applied.iter_mut().zip(eps).zip(self.eps_actuator.iter()) {
                *total = input + actuator;
            }
        }
        let mut result = pass(self, model, applied.as_slice());
        if result.is_ok() && model.couples_beyond_tree() {
            result = self.apply_constraint_forces(model, applied.as_mut_slice());
        }
        self.eps_applied = applied;
        result?;
        self.eps_input.copy_from_slice(eps);
        self.ctrl_input.copy_from_slice(ctrl);
        self.inputs_applied = true;
        Ok(())
    }

    /// Whether pass 3 is done for exactly these inputs, with the actuators
    /// (by [`Workspace::compute_nu_dot_actuated`]).
    pub(crate) fn nu_dot_is_for(&self, eps: &[f64], ctrl: &[f64]) -> bool {
        self.stage == Stage::Acceleration
            && self.inputs_applied
            && self.eps_input.as_slice() == eps
            && self.ctrl_input.as_slice() == ctrl
    }

    /// The generalized force of a unit force of actuator `k` (its moment
    /// arms, MuJoCo's `actuator_moment` row) into `moment` (nv). Needs the
    /// velocities; leaves `qfrc_actuator` holding the same.
    pub fn actuator_moment(&mut self, model: &Model, k: usize, moment: &mut [f64]) -> Result<(), DynamicsError> {
        require(self, Stage::Velocity, "actuator_moment")?;
        check_length("output", moment, model.nv)?;
        if k >= model.actuators.len() {
            return Err(DynamicsError::Length { what: "actuator index", expected: model.actuators.len(), found: k });
        }
        self.prepare_transmissions(model);
        let transmitted = transmit(model, self, &model.actuators[k]);
        let mut qfrc = std::mem::take(&mut self.qfrc_actuator);
        apply(
            model,
            self.theta.as_slice(),
            &transmitted.moment,
            1.0,
            qfrc.as_mut_slice(),
            &mut self.link_wrench,
            &self.tendon_moment,
        );
        self.collect_wrenches(model, qfrc.as_mut_slice());
        moment.copy_from_slice(qfrc.as_slice());
        self.qfrc_actuator = qfrc;
        Ok(())
    }
}

impl<S: Real> Workspace<S> {
    /// Activation state k's rate as a host's solver integrates it (model
    /// exchange): MuJoCo's act_dot, but 0 where act is at or past a bound of
    /// its range and would leave it, where MuJoCo's step clamps act (and so
    /// its derivative 0 there, in dual numbers). Needs
    /// [`Workspace::compute_actuation`].
    pub fn act_rate_within_range(&self, model: &Model, k: usize) -> S {
        let range = model.actuators.iter().filter_map(|a| a.activation).nth(k).and_then(|a| a.range);
        let (act, rate) = (self.act[k].value(), self.act_dot[k]);
        match range {
            Some([low, _]) if act <= low && rate.value() < 0.0 => S::zero(),
            Some([_, high]) if act >= high && rate.value() > 0.0 => S::zero(),
            _ => rate,
        }
    }

    /// [`Workspace::compute_actuation`] after its checks.
    pub(crate) fn actuation_pass(&mut self, model: &Model, ctrl: &[S]) -> Result<(), DynamicsError> {
        let actuation = model.actuation;
        let mjcf_count = model.mjcf_actuator_count();
        self.prepare_transmissions(model);
        if !self.act.is_empty() {
            self.compute_activation_rates(model, ctrl);
        }
        if actuation.enabled && !self.tendon_actuator_total.is_empty() {
            self.sum_tendon_actuator_forces(model, ctrl);
        }
        let actuators = model.actuators[..mjcf_count].iter().zip(activation_slots(model));
        for (k, (actuator, slot)) in actuators.enumerate() {
            let transmitted = transmit(model, self, actuator);
            self.actuator_length[k] = transmitted.length;
            if !actuation.enabled {
                // MuJoCo then computes the lengths only.
                (self.actuator_velocity[k], self.actuator_force[k]) = (S::zero(), S::zero());
                continue;
            }
            self.actuator_velocity[k] = transmitted.velocity;
            let input = self.actuator_input(model, actuator, slot, ctrl[k]);
            let mut force = unclamped_force(actuator, input, transmitted.length, transmitted.velocity);
            if let ActuatorTransmission::Tendon { tendon } = actuator.transmission
                && !self.tendon_actuator_total.is_empty()
            {
                force *= tendon_force_scale::<S>(
                    model.tendons[tendon].actuator_force_range,
                    self.tendon_actuator_total[tendon],
                );
            }
            let force = clamp_force(actuator, force);
            self.actuator_force[k] = force;
            apply(
                model,
                self.theta.as_slice(),
                &transmitted.moment,
                force,
                self.qfrc_actuator.as_mut_slice(),
                &mut self.link_wrench,
                &self.tendon_moment,
            );
        }
        let mut qfrc = std::mem::take(&mut self.qfrc_actuator);
        self.collect_wrenches(model, qfrc.as_mut_slice());
        // MuJoCo's actuation stage returns before these when no MJCF
        // actuator acts: the compensation of `actuatorgravcomp` joints,
        // then the joints' limits (a range without 0 would move a 0).
        if actuation.enabled && mjcf_count > 0 {
            for &dof in &model.gravity_compensation.actuator_dofs {
                qfrc[dof] += self.qfrc_gravcomp[dof];
            }
            for limit in &model.actuator_force_limits {
                let [low, high] = limit.range;
                qfrc[limit.dof] = clip(qfrc[limit.dof], low, high);
            }
        }
        self.qfrc_actuator = qfrc;
        let mut total = std::mem::take(&mut self.qfrc_total);
        total.copy_from(&self.qfrc_actuator);
        if mjcf_count < model.actuators.len() {
            self.add_wrench_inputs(model, &ctrl[mjcf_count..], total.as_mut_slice());
        }
        let mut eps = std::mem::take(&mut self.eps_actuator);
        // eps_from_forces's check of its input, which ctrl could make overflow.
        let result = match total.iter().position(|t| !t.value().is_finite()) {
            Some(index) => Err(DynamicsError::NonFinite { what: "torque", index, value: total[index].value() }),
            None => {
                forces::eps_of_torque(model, self, total.as_slice(), eps.as_mut_slice());
                Ok(())
            }
        };
        (self.qfrc_total, self.eps_actuator) = (total, eps);
        result
    }

    /// The sum of the forces (before their `forcerange`) of each tendon's
    /// actuators, for the tendons with an `actuatorfrcrange`.
    fn sum_tendon_actuator_forces(&mut self, model: &Model, ctrl: &[S]) {
        self.tendon_actuator_total.fill(0.0);
        let actuators = model.actuators[..model.mjcf_actuator_count()].iter().zip(activation_slots(model));
        for (k, (actuator, slot)) in actuators.enumerate() {
            if let ActuatorTransmission::Tendon { tendon } = actuator.transmission
                && model.tendons[tendon].actuator_force_range.is_some()
            {
                let transmitted = transmit(model, self, actuator);
                let input = self.actuator_input(model, actuator, slot, ctrl[k]);
                self.tendon_actuator_total[tendon] +=
                    unclamped_force(actuator, input, transmitted.length, transmitted.velocity).value();
            }
        }
    }

    /// MuJoCo's act_dot of every activation state at `ctrl` (clamped to
    /// each actuator's range), from `act`; 0 with `<flag actuation="disable"/>`,
    /// as in MuJoCo.
    fn compute_activation_rates(&mut self, model: &Model, ctrl: &[S]) {
        let actuation = model.actuation;
        let mut index = 0;
        for (actuator, &ctrl) in model.actuators.iter().zip(ctrl) {
            if actuator.activation.is_some() {
                self.act_dot[index] = if actuation.enabled {
                    actuator.activation_rate(clamped_ctrl(actuator, actuation.clamp_ctrl, ctrl), self.act[index])
                } else {
                    S::zero()
                };
                index += 1;
            }
        }
    }

    /// What `actuator`'s force multiplies its gain by: its ctrl, clamped
    /// to its range, or for an actuator with activation state `slot` the
    /// activation it reads (act, or with `actearly` the next; needs
    /// `act_dot`).
    fn actuator_input(&self, model: &Model, actuator: &Actuator, slot: Option<usize>, ctrl: S) -> S {
        match slot {
            None => clamped_ctrl(actuator, model.actuation.clamp_ctrl, ctrl),
            Some(slot) => {
                actuator.activation_input(self.act[slot], self.act_dot[slot], model.constraints.options.timestep)
            }
        }
    }

    /// Adds the generalized force of the wrench inputs (`values`: six per
    /// body, MuJoCo's `xfrc_applied`) to `qfrc`. They are not actuators to
    /// MuJoCo: outside `qfrc_actuator`, its joint limits and its
    /// `actuation="disable"` flag.
    fn add_wrench_inputs(&mut self, model: &Model, values: &[S], qfrc: &mut [S]) {
        self.link_wrench.fill(SpatialVec::zeros());
        let first = model.mjcf_actuator_count();
        for (k, actuator) in model.actuators[first..].iter().enumerate() {
            let transmitted = transmit(model, self, actuator);
            let index = first + k;
            self.actuator_length[index] = transmitted.length;
            self.actuator_velocity[index] = transmitted.velocity;
            self.actuator_force[index] = values[k];
            apply(
                model,
                self.theta.as_slice(),
                &transmitted.moment,
                values[k],
                qfrc,
                &mut self.link_wrench,
                &self.tendon_moment,
            );
        }
        self.collect_wrenches(model, qfrc);
    }

    /// Clears T and the link wrenches, and brings the world placements up
    /// to date when a reference site needs them.
    fn prepare_transmissions(&mut self, model: &Model) {
        self.qfrc_actuator.fill(S::zero());
        if self.actuators_apply_wrenches {
            self.link_wrench.fill(SpatialVec::zeros());
        }
        let relative = |a: &Actuator| matches!(a.transmission, ActuatorTransmission::RelativeSite { .. });
        if model.actuators.iter().any(relative) {
            self.world_transforms(model);
        }
    }

    /// `qfrc` += Σ Jᵀf of the link wrenches, when any actuator applies wrenches.
    fn collect_wrenches(&mut self, model: &Model, qfrc: &mut [S]) {
        if self.actuators_apply_wrenches {
            forces::add_joint_forces_of_wrenches(
                model,
                &self.x_parent,
                &self.accumulation,
                &mut self.flex,
                &mut self.p_scratch_body,
                &self.link_wrench,
                qfrc,
            );
        }
    }
}
