//! MuJoCo's interaction force of a body with its parent (`cfrc_int`, from
//! `mj_rnePostConstraint`), which the force and torque sensors read
//! (docs/DYNAMICS.md §8, "Force and torque sensors").
//!
//! The force a body's subtree takes through the body's joint is what moves
//! the subtree less what else pushes on it:
//!
//! ```text
//! f_int(b) = Σ_{c ∈ subtree(b)} (I_c a_c + v_c ×* I_c v_c − f_ext,c),
//! ```
//!
//! with the accelerations a of the constrained motion (θ̈ after the
//! constraint forces) and the world accelerating at −g, so that weight
//! counts as a force the joint carries. f_ext is MuJoCo's `cfrc_ext`: the
//! wrench inputs (`xfrc_applied`) at the body's centre of mass and the
//! forces of connect and weld rows at their anchor points, and the forces
//! spatial tendons pull with at their path points (MuJoCo 4.0's change
//! 263c638c0); the other actuator, spring, damper, friction-loss and limit
//! forces act through joints and stay inside f_int. A link may carry several MuJoCo bodies (welded
//! bodies, fusestatic): each body's share is taken on its own, from the
//! link's motion and the body's own mass, so that a sensor on a welded
//! body reads its own subtree.

use super::constraint::RowKind;
use super::equality::{orientation, weld_rotation_map};
use super::tendon::{direction, walk_path};
use crate::math::{Mat3, Real, Transform, Vec3, angular, linear, real, spatial};
use crate::model::{ActuatorTransmission, EqualityRows, Model, Path, SiteFrame};
use crate::vehicle::SensorKind;
use crate::workspace::Workspace;

impl<S: Real> Workspace<S> {
    /// Each body's inertial force less the external forces on it, in world
    /// axes about its centre of mass, into `body_wrench` and `body_com`.
    /// Needs the link accelerations, the actuators' forces and the
    /// constraint rows of the current inputs, and current world placements.
    pub(super) fn body_interaction_wrenches(&mut self, model: &Model) {
        let gravity = real::<S, 3, 1>(&model.gravity);
        for (b, body) in model.body_masses.iter().enumerate() {
            let c = real::<S, 3, 1>(&body.com);
            let (com, wrench) = match body.link {
                // Fixed to the world: it accelerates at −g and bears its weight.
                None => (c, spatial(&Vec3::zeros(), &(gravity * S::from(-body.mass)))),
                Some(link) => {
                    let placement = &self.x_world[link];
                    let to_world = placement.rot.transpose();
                    let (v, a) = (&self.v_body[link], &self.a_body[link]);
                    let omega = angular(v);
                    let alpha = angular(a);
                    let inertia = real::<S, 3, 3>(&body.inertia);
                    // Newton–Euler about the centre of mass, link axes: the
                    // spatial acceleration at c plus ω × v_c, and −g.
                    let velocity = linear(v) + omega.cross(&c);
                    let acceleration = linear(a) + alpha.cross(&c) + omega.cross(&velocity) - placement.rot * gravity;
                    let torque = inertia * alpha + omega.cross(&(inertia * omega));
                    let com = placement.trans + to_world * c;
                    (com, spatial(&(to_world * torque), &(to_world * (acceleration * S::from(body.mass)))))
                }
            };
            self.body_com[b] = com;
            self.body_wrench[b] = wrench;
        }
        self.subtract_wrench_inputs(model);
        self.subtract_equality_forces(model);
        self.subtract_tendon_forces(model);
    }

    /// The spatial tendons' forces, which MuJoCo 4.0 counts as external
    /// forces at their path points: the force F the tendon carries (see
    /// [`Workspace::tendon_force`]) along each straight segment p₀ → p₁ over
    /// its divisor, F·u at p₁ and −F·u at p₀ (u = (p₁ − p₀)/|p₁ − p₀|), as a
    /// unit tension's moment arms take it; a segment within one body pulls
    /// on it with two opposite forces on one line, which cancel.
    fn subtract_tendon_forces(&mut self, model: &Model) {
        for ((k, tendon), wraps) in model.tendons.iter().enumerate().zip(model.tendon_wraps()) {
            let Path::Spatial { stops } = &tendon.path else { continue };
            let force = self.tendon_force(model, k);
            if force.is_still_zero() {
                continue;
            }
            let (body_wrench, body_com) = (&mut self.body_wrench, &self.body_com);
            // The paths the tendons' kinematics took at this configuration.
            walk_path(stops, &self.x_world, Some(&self.wrap_paths[wraps]), None, |from, to, divisor| {
                if from.body == to.body {
                    return;
                }
                let f = direction(from, to) * (force / divisor);
                for (point, f) in [(from, -f), (to, f)] {
                    if let Some(b) = point.body {
                        body_wrench[b] -= spatial(&(point.at - body_com[b]).cross(&f), &f);
                    }
                }
            });
        }
    }

    /// The wrench inputs: MuJoCo's `xfrc_applied`, a world force and torque
    /// at the body's centre of mass (`xipos`), where their six actuators
    /// after the MJCF's put them.
    fn subtract_wrench_inputs(&mut self, model: &Model) {
        let first = model.mjcf_actuator_count();
        for (w, &b) in model.interaction_bodies.wrench_inputs.iter().enumerate() {
            let adr = first + 6 * w;
            let input = &self.actuator_force.as_slice()[adr..adr + 6];
            let (force, torque) = (Vec3::new(input[0], input[1], input[2]), Vec3::new(input[3], input[4], input[5]));
            let point = match &model.actuators[adr].transmission {
                ActuatorTransmission::RelativeSite { site, .. } => self.in_world(site).trans,
                _ => self.body_com[b],
            };
            let about_com = torque + (point - self.body_com[b]).cross(&force);
            self.body_wrench[b] -= spatial(&about_com, &force);
        }
    }

    /// The forces of the active connect and weld rows: +f at frame one's
    /// point on its body, −f at frame two's on its body. A weld's torque is
    /// what its rotation rows apply, Mᵀf for rows M(J_ω1 − J_ω2) (MuJoCo
    /// 4.0 takes it so too), which is the same whichever sign the rows'
    /// quaternions have.
    fn subtract_equality_forces(&mut self, model: &Model) {
        let rows = &self.constraint_rows;
        let mut k = 0;
        while k < rows.count && rows.kind[k] == RowKind::Equality {
            let equality = &model.constraints.equalities[rows.id[k]];
            let bodies = model.interaction_bodies.equalities[rows.id[k]];
            let force = |r: usize| Vec3::new(rows.force[r], rows.force[r + 1], rows.force[r + 2]);
            let (frames, anchors, torque) = match &equality.rows {
                EqualityRows::Connect { frames, anchors, .. } => (frames, anchors, Vec3::zeros()),
                EqualityRows::Weld { frames, anchors, relative, torquescale, .. } => {
                    let [one, two] = frames.map(|f| orientation(&self.in_world(&f)));
                    let map = weld_rotation_map(&one, &two, relative, *torquescale);
                    let f = force(k + 3);
                    (frames, anchors, Vec3::new(map[0].dot(&f), map[1].dot(&f), map[2].dot(&f)))
                }
                // Joint couplings and tendon equalities act through joints: inside the sum.
                EqualityRows::Joint { .. } | EqualityRows::Tendon { .. } => {
                    k += 1;
                    continue;
                }
            };
            let f = force(k);
            for (i, sign) in [(0, 1.0), (1, -1.0)] {
                let Some(b) = bodies[i] else { continue };
                let placement = self.in_world(&frames[i]);
                let point = placement.trans + placement.rot.transpose() * real::<S, 3, 1>(&anchors[i]);
                let about_com = torque + (point - self.body_com[b]).cross(&f);
                self.body_wrench[b] -= spatial(&about_com, &f) * S::from(sign);
            }
            k += equality.rows.count();
        }
    }

    /// A frame's placement in the world, ᶠX₀.
    fn in_world(&self, frame: &SiteFrame) -> Transform<S> {
        match frame.link {
            Some(link) => frame.frame.real().compose(&self.x_world[link]),
            None => frame.frame.real(),
        }
    }

    /// A force or torque sensor's reading: the interaction force of the
    /// bodies `first..end` (a subtree) in the site frame, the torque about
    /// the site. Needs [`Workspace::body_interaction_wrenches`].
    pub(super) fn interaction_reading(&self, kind: SensorKind, site: &SiteFrame, first: usize, end: usize) -> Vec3<S> {
        let placement = self.in_world(site);
        let (mut force, mut torque) = (Vec3::zeros(), Vec3::zeros());
        for b in first..end {
            let f = linear(&self.body_wrench[b]);
            force += f;
            torque += angular(&self.body_wrench[b]) + (self.body_com[b] - placement.trans).cross(&f);
        }
        // ᶠX₀'s rotation takes world axes to the site's.
        let to_site: Mat3<S> = placement.rot;
        match kind {
            SensorKind::Force => to_site * force,
            _ => to_site * torque,
        }
    }
}
