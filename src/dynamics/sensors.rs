//! MuJoCo's sensors (its Computation chapter and MJCF reference, "sensor"),
//! evaluated at the workspace's state into `sensordata`, in MuJoCo's order
//! and layout.
//!
//! Frames come from the links' world placements and velocities; the
//! acceleration sensors from the outward pass after pass 3 with the world
//! accelerating at −g, as MuJoCo's accelerometer reads (a body at rest on
//! the ground reads +g up, one in free fall reads 0). A body point's
//! classical acceleration is the spatial one at the point plus ω × v.
//! Quaternions are composed link by link as MuJoCo composes `xquat`, so
//! that a framequat has MuJoCo's sign.
//!
//! The readings are generic over the passes' scalar (`read_sensors`): in
//! dual numbers (`derivatives`) each carries its derivative, every branch
//! (a cutoff's clamp, which limit row is a sensor's) decided on the values.

use nalgebra::{Quaternion, Unit};

use super::constraint::RowKind;
use super::{DynamicsError, require};
use crate::flex::nodes;
use crate::math::{
    Mat3, Quat, Real, SpatialVec, Transform, Vec3, angular, cross_motion, linear, quat_from_rotation_vector,
    quat_from_wxyz, real, sum,
};
use crate::model::{LinkJoint, Model, SensorSource, SiteFrame};
use crate::vehicle::SensorKind;
use crate::workspace::{Stage, Workspace};

/// What the model's sensors need computed beyond the velocities.
struct Needs {
    /// θ̈ and the link accelerations (and so pass 3 with the actuators).
    acceleration: bool,
    /// The actuators' lengths, velocities and forces.
    actuation: bool,
    /// The links' world quaternions.
    quaternions: bool,
    /// The constraint rows and their forces.
    constraints: bool,
    /// The bodies' interaction forces (which need all of the above but the quaternions).
    interaction: bool,
}

impl Needs {
    fn of(model: &Model) -> Needs {
        use SensorKind::*;
        let any = |kinds: &[SensorKind]| model.sensors.iter().any(|s| kinds.contains(&s.kind));
        Needs {
            acceleration: any(&[FrameLinAcc, FrameAngAcc, Accelerometer]),
            actuation: any(&[ActuatorFrc, ActuatorPos, ActuatorVel, JointActuatorFrc, TendonActuatorFrc]),
            quaternions: any(&[FrameQuat]),
            constraints: any(&[
                JointLimitPos,
                JointLimitVel,
                JointLimitFrc,
                TendonLimitPos,
                TendonLimitVel,
                TendonLimitFrc,
            ]),
            interaction: any(&[Force, Torque]),
        }
    }
}

/// A frame's placement and motion in the world.
struct FrameMotion<S: Real> {
    /// Rotation frame → world (MuJoCo's xmat: the frame's axes as columns).
    rot: Mat3<S>,
    /// Origin.
    pos: Vec3<S>,
    /// Angular velocity.
    omega: Vec3<S>,
    /// Velocity of the origin.
    vel: Vec3<S>,
}

/// Whether the model's sensors read θ̈, the links' accelerations or the
/// constraint forces: the passes that give them must have run before
/// [`Workspace::read_sensors`].
pub(crate) fn sensors_need_accelerations(model: &Model) -> bool {
    let needs = Needs::of(model);
    needs.acceleration || needs.constraints || needs.interaction
}

/// A model quaternion in the passes' scalar.
fn real_quat<S: Real>(q: &Quat) -> Quat<S> {
    Quat::new_unchecked(Quaternion::new(S::from(q.w), S::from(q.i), S::from(q.j), S::from(q.k)))
}

/// MuJoCo's `cutoff` on one value: clamped to ±`cutoff`, decided on the
/// value, so that a clamped reading's derivative is 0 (the piece held, as
/// the clamps of ctrl hold theirs); `f64::clamp`'s numbers for `f64`.
fn cut_off<S: Real>(value: S, cutoff: f64) -> S {
    if value.value() < -cutoff {
        S::from(-cutoff)
    } else if value.value() > cutoff {
        S::from(cutoff)
    } else {
        value
    }
}

/// The switch of sensordata entry `entry`'s cutoff, named for a message.
pub(crate) fn cutoff_switch(model: &Model, entry: usize) -> String {
    let (index, sensor) =
        model.sensors.iter().enumerate().find(|(_, s)| (s.adr..s.adr + s.dim()).contains(&entry)).expect("an entry");
    format!("{}'s reading (sensordata[{}]) at its cutoff", sensor.label(index), entry + 1)
}

impl Workspace {
    /// MuJoCo's `sensordata` at the workspace's state, the inputs `eps` (nv)
    /// and `ctrl` (nu) held and the time `time`: acceleration and actuator
    /// sensors depend on the inputs, and their passes run here. Needs the
    /// velocities.
    pub fn compute_sensors(
        &mut self,
        model: &Model,
        eps: &[f64],
        ctrl: &[f64],
        time: f64,
    ) -> Result<(), DynamicsError> {
        require(self, Stage::Velocity, "compute_sensors")?;
        if model.sensors.is_empty() || model.sensors_disabled {
            // Nothing was ever written there: sensordata stays 0.
            return Ok(());
        }
        let needs = Needs::of(model);
        if needs.acceleration || needs.constraints || needs.interaction {
            if !self.nu_dot_is_for(eps, ctrl) {
                self.compute_nu_dot_actuated(model, eps, ctrl)?;
            }
            self.compute_accelerations(model)?;
        } else if needs.actuation {
            self.compute_actuation(model, ctrl)?;
        }
        self.read_sensors_with(model, &needs, time);
        Ok(())
    }
}

impl<S: Real> Workspace<S> {
    /// The sensors' readings into `sensordata` from the passes already run
    /// for the state and inputs: the velocities, the actuators', and
    /// where [`sensors_need_accelerations`] says so θ̈ with the constraint
    /// forces. In dual numbers each reading carries its derivative.
    /// Returns the first entry whose reading lies exactly on its cutoff,
    /// where the clamp switches (its derivative there is one-sided).
    pub(crate) fn read_sensors(&mut self, model: &Model, time: f64) -> Option<usize> {
        if model.sensors.is_empty() || model.sensors_disabled {
            return None;
        }
        self.read_sensors_with(model, &Needs::of(model), time)
    }

    /// [`Workspace::read_sensors`] with the model's `needs` found.
    fn read_sensors_with(&mut self, model: &Model, needs: &Needs, time: f64) -> Option<usize> {
        self.world_transforms(model);
        if needs.quaternions {
            self.link_quaternions(model);
        }
        if needs.interaction {
            self.body_interaction_wrenches(model);
        }
        let mut sensordata = std::mem::take(&mut self.sensordata);
        let mut on_cutoff = None;
        for sensor in &model.sensors {
            let values = &mut sensordata.as_mut_slice()[sensor.adr..sensor.adr + sensor.dim()];
            self.read_sensor(model, sensor.kind, &sensor.source, time, values);
            if sensor.cutoff > 0.0 {
                for (k, value) in values.iter_mut().enumerate() {
                    if value.value().abs() == sensor.cutoff {
                        on_cutoff.get_or_insert(sensor.adr + k);
                    }
                    *value = cut_off(*value, sensor.cutoff);
                }
            }
        }
        self.sensordata = sensordata;
        on_cutoff
    }

    /// One sensor's values into `out` (its dim entries).
    fn read_sensor(&self, model: &Model, kind: SensorKind, source: &SensorSource, time: f64, out: &mut [S]) {
        use SensorKind::*;
        match *source {
            SensorSource::Joint { dof, qpos } => match kind {
                JointPos => out[0] = self.theta[qpos],
                BallQuat => out.copy_from_slice(&self.theta.as_slice()[qpos..qpos + 4]),
                JointVel => out[0] = self.qvel[dof],
                BallAngVel => out.copy_from_slice(&self.qvel.as_slice()[dof..dof + 3]),
                JointLimitPos | JointLimitVel | JointLimitFrc => out[0] = self.limit_row_reading(model, kind, dof),
                _ => out[0] = self.qfrc_actuator[dof],
            },
            SensorSource::Actuator { actuator } => {
                out[0] = match kind {
                    ActuatorPos => self.actuator_length[actuator],
                    ActuatorVel => self.actuator_velocity[actuator],
                    _ => self.actuator_force[actuator],
                }
            }
            SensorSource::Frame { object, reference, quats } => {
                self.read_frame(model, kind, &object, reference.as_ref(), &quats, out)
            }
            SensorSource::Subtree { first, end } => write3(out, &self.subtree(model, kind, first, end)),
            SensorSource::Interaction { site, first, end } => {
                write3(out, &self.interaction_reading(kind, &site, first, end))
            }
            SensorSource::Tendon { tendon } => {
                out[0] = match kind {
                    TendonPos => self.tendon_length[tendon],
                    TendonVel => self.tendon_velocity[tendon],
                    TendonActuatorFrc => {
                        let on_tendon = |a: &&crate::model::Actuator| {
                            a.transmission == crate::model::ActuatorTransmission::Tendon { tendon }
                        };
                        let actuators = model.actuators.iter().enumerate().filter(|(_, a)| on_tendon(a));
                        sum(actuators.map(|(k, _)| self.actuator_force[k]))
                    }
                    _ => self.tendon_limit_row_reading(model, kind, tendon),
                }
            }
            SensorSource::Clock => out[0] = S::from(time),
        }
    }

    /// MuJoCo's tendon limit sensors, as [`Workspace::limit_row_reading`] for joints.
    fn tendon_limit_row_reading(&self, model: &Model, kind: SensorKind, tendon: usize) -> S {
        let rows = &self.constraint_rows;
        let limits = &model.constraints.tendon_limits;
        let row =
            (0..rows.count).find(|&k| rows.kind[k] == RowKind::TendonLimit && limits[rows.id[k]].tendon == tendon);
        match (row, kind) {
            (None, _) => S::zero(),
            (Some(k), SensorKind::TendonLimitPos) => rows.distance[k] - rows.margin[k],
            (Some(k), SensorKind::TendonLimitVel) => rows.velocity[k],
            (Some(k), _) => rows.force[k],
        }
    }

    /// MuJoCo's joint limit sensors: the distance less the margin, the
    /// velocity or the force of the joint's first active limit row, 0 when
    /// none is active.
    fn limit_row_reading(&self, model: &Model, kind: SensorKind, dof: usize) -> S {
        let rows = &self.constraint_rows;
        let limits = &model.constraints.limits;
        let row = (0..rows.count).find(|&k| rows.kind[k] == RowKind::Limit && limits[rows.id[k]].dof == dof);
        match (row, kind) {
            (None, _) => S::zero(),
            (Some(k), SensorKind::JointLimitPos) => rows.distance[k] - rows.margin[k],
            (Some(k), SensorKind::JointLimitVel) => rows.velocity[k],
            (Some(k), _) => rows.force[k],
        }
    }

    /// A frame sensor's values.
    fn read_frame(
        &self,
        model: &Model,
        kind: SensorKind,
        object: &SiteFrame,
        reference_frame: Option<&SiteFrame>,
        quats: &[Quat; 2],
        out: &mut [S],
    ) {
        use SensorKind::*;
        if kind == FrameQuat {
            let mut quat = self.world_quaternion(model, object, &quats[0]);
            if let Some(reference) = reference_frame {
                quat = self.world_quaternion(model, reference, &quats[1]).conjugate() * quat;
            }
            out.copy_from_slice(&[quat.w, quat.i, quat.j, quat.k]);
            return;
        }
        let frame = self.frame_motion(model, object);
        let reference = reference_frame.map(|r| self.frame_motion(model, r));
        // A world vector in the reference frame's axes, if any.
        let in_reference = |v: Vec3<S>| match &reference {
            Some(r) => r.rot.transpose() * v,
            None => v,
        };
        let value = match kind {
            FramePos => match &reference {
                Some(r) => r.rot.transpose() * (frame.pos - r.pos),
                None => frame.pos,
            },
            FrameXAxis => in_reference(frame.rot.column(0).into_owned()),
            FrameYAxis => in_reference(frame.rot.column(1).into_owned()),
            FrameZAxis => in_reference(frame.rot.column(2).into_owned()),
            // As an observer moving with the reference frame sees it.
            FrameLinVel => match &reference {
                Some(r) => r.rot.transpose() * (frame.vel - r.vel - r.omega.cross(&(frame.pos - r.pos))),
                None => frame.vel,
            },
            FrameAngVel => in_reference(frame.omega - reference.as_ref().map_or(Vec3::zeros(), |r| r.omega)),
            Gyro => frame.rot.transpose() * frame.omega,
            Velocimeter => frame.rot.transpose() * frame.vel,
            Magnetometer => frame.rot.transpose() * real::<S, 3, 1>(&model.magnetic),
            FrameAngAcc => self.frame_acceleration(model, object, &frame).0,
            FrameLinAcc => self.frame_acceleration(model, object, &frame).1,
            _ => frame.rot.transpose() * self.frame_acceleration(model, object, &frame).1,
        };
        write3(out, &value);
    }

    /// What carries a site on `link`: the link, or the node the site sits
    /// at (at the workspace's η): its placement in the world, velocity and
    /// acceleration (its own coordinates). A node moves with
    /// V_j = ʲX_R V_R + Ψ_jη̇ and A_j = ʲX_R A_R + Ψ_jη̈ + Ψ̇_jη̇ + V_j × Ψ_jη̇.
    fn carrier(&self, model: &Model, frame: &SiteFrame, link: usize) -> (Transform<S>, SpatialVec<S>, SpatialVec<S>) {
        let (x_r, v_r, a_r) = (self.x_world[link], self.v_body[link], self.a_body[link]);
        let Some(at) = frame.node else { return (x_r, v_r, a_r) };
        let flexible = &model.flexible[at.flexible];
        let (adr, m) = (flexible.dof_adr, flexible.mode_count());
        let (eta, x_node) = self.node_placement(model, at);
        let (rate, acceleration) = (&self.qvel.as_slice()[adr..adr + m], &self.qacc.as_slice()[adr..adr + m]);
        let relative = nodes::subspace_times(&flexible.modal, at.node, eta, rate);
        let v = x_node.apply_motion(&v_r) + relative;
        let a = x_node.apply_motion(&a_r)
            + nodes::subspace_times(&flexible.modal, at.node, eta, acceleration)
            + nodes::subspace_rate_times(&flexible.modal, at.node, eta, rate)
            + cross_motion(&v, &relative);
        (x_node.compose(&x_r), v, a)
    }

    /// A frame's placement and velocity in the world.
    fn frame_motion(&self, model: &Model, frame: &SiteFrame) -> FrameMotion<S> {
        let site = frame.frame.real::<S>();
        let Some(link) = frame.link else {
            return FrameMotion {
                rot: site.rot.transpose(),
                pos: site.trans,
                omega: Vec3::zeros(),
                vel: Vec3::zeros(),
            };
        };
        let (x_carrier, v, _) = self.carrier(model, frame, link);
        let in_world = site.compose(&x_carrier);
        let to_world = x_carrier.rot.transpose();
        let omega = angular(&v);
        // The frame origin's velocity, in the carrier's coordinates.
        let vel = linear(&v) + omega.cross(&site.trans);
        FrameMotion { rot: in_world.rot.transpose(), pos: in_world.trans, omega: to_world * omega, vel: to_world * vel }
    }

    /// A frame's angular acceleration and its origin's linear acceleration,
    /// in the world, the world accelerating at −g.
    fn frame_acceleration(&self, model: &Model, frame: &SiteFrame, motion: &FrameMotion<S>) -> (Vec3<S>, Vec3<S>) {
        let gravity = real::<S, 3, 1>(&model.gravity);
        let Some(link) = frame.link else {
            return (Vec3::zeros(), -gravity);
        };
        let (x_carrier, _, a) = self.carrier(model, frame, link);
        let to_world = x_carrier.rot.transpose();
        let r = real::<S, 3, 1>(&frame.frame.trans);
        let angular_acc = angular(&a);
        // The spatial acceleration at the frame origin, then the classical one.
        let at_origin = linear(&a) + angular_acc.cross(&r);
        let linear_acc = to_world * at_origin + motion.omega.cross(&motion.vel) - gravity;
        (to_world * angular_acc, linear_acc)
    }

    /// A frame's orientation in the world as MuJoCo composes it (a node's
    /// turn exp(ρ×), ρ = Φʳη, between the link's and the site's).
    fn world_quaternion(&self, model: &Model, frame: &SiteFrame, in_link: &Quat) -> Quat<S> {
        let in_link = real_quat::<S>(in_link);
        let Some(link) = frame.link else { return in_link };
        match frame.node {
            None => self.link_quats[link] * in_link,
            Some(at) => {
                let flexible = &model.flexible[at.flexible];
                let eta = flexible.eta(self.theta.as_slice());
                let (_, rho) = nodes::displacement(&flexible.modal, at.node, eta);
                self.link_quats[link] * quat_from_rotation_vector(rho) * in_link
            }
        }
    }

    /// The links' world quaternions, base to tip: parent, tree offset, joint.
    fn link_quaternions(&mut self, model: &Model) {
        for (i, link) in model.links.iter().enumerate() {
            let joint = match link.joint {
                LinkJoint::Hinge => Quat::from_axis_angle(
                    &Unit::new_unchecked(real::<S, 3, 1>(&link.axis)),
                    self.theta[link.qpos_adr] - link.reference,
                ),
                LinkJoint::Ball => {
                    Quat::new_unchecked(quat_from_wxyz(&self.theta.as_slice()[link.qpos_adr..link.qpos_adr + 4]))
                }
                LinkJoint::Slide | LinkJoint::Translation => Quat::identity(),
            };
            let mut parent = link.parent.map_or(Quat::identity(), |p| self.link_quats[p]);
            if let Some(at) = self.accumulation[i].node {
                // A child at a node: the node's turn exp([Φʳ_j η]×) on its parent link.
                let (f, _, slot) = crate::dynamics::flexible::node_of(model, at);
                let flexible = &model.flexible[f];
                let eta = flexible.eta(self.theta.as_slice());
                let (_, rho) = nodes::displacement(&flexible.modal, flexible.rotating[slot], eta);
                parent *= quat_from_rotation_vector(rho);
            }
            let tree = real_quat::<S>(&model.link_tree_quats[i]);
            self.link_quats[i] = Quat::new_normalize((parent * tree * joint).into_inner());
        }
    }

    /// A subtree's centre of mass, the velocity of its centre of mass, or
    /// its angular momentum about its centre of mass (world axes).
    fn subtree(&self, model: &Model, kind: SensorKind, first: usize, end: usize) -> Vec3<S> {
        let bodies = &model.body_masses[first..end];
        // Each body's centre of mass and its velocity, in the world.
        let state = |body: &crate::model::BodyMass| {
            let com = real::<S, 3, 1>(&body.com);
            match body.link {
                Some(link) => {
                    let x = &self.x_world[link];
                    let v = &self.v_body[link];
                    let to_world = x.rot.transpose();
                    let velocity = to_world * (linear(v) + angular(v).cross(&com));
                    (x.trans + to_world * com, velocity, to_world * angular(v), to_world)
                }
                None => (com, Vec3::zeros(), Vec3::zeros(), Mat3::identity()),
            }
        };
        let mass: f64 = bodies.iter().map(|b| b.mass).sum();
        let weighted = |pick: &dyn Fn(&crate::model::BodyMass) -> Vec3<S>| -> Vec3<S> {
            bodies.iter().map(|b| pick(b) * S::from(b.mass)).sum::<Vec3<S>>() / S::from(mass)
        };
        let com = if mass > 0.0 { weighted(&|b| state(b).0) } else { Vec3::zeros() };
        match kind {
            SensorKind::SubtreeCom => com,
            SensorKind::SubtreeLinVel if mass > 0.0 => weighted(&|b| state(b).1),
            SensorKind::SubtreeLinVel => Vec3::zeros(),
            _ => bodies
                .iter()
                .map(|b| {
                    let (pos, vel, omega, to_world) = state(b);
                    to_world * real::<S, 3, 3>(&b.inertia) * to_world.transpose() * omega
                        + (pos - com).cross(&vel) * S::from(b.mass)
                })
                .sum(),
        }
    }
}

/// Writes a 3-vector.
fn write3<S: Real>(out: &mut [S], v: &Vec3<S>) {
    out.copy_from_slice(v.as_slice());
}
