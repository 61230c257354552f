//! Shared test harness: random vehicles, and an independent dense reference
//! for the dynamics.
//!
//! The reference works in world coordinates straight from the vehicle
//! description (not the compiled model): body poses by MuJoCo's kinematic
//! rules, per-dof world Jacobians, M = Σ Jᵀ diag(m, I) J + armature, and
//! the bias forces by Kane's method (h = Σ Jᵀ(m J̇θ̇ − m g, I J̇ωθ̇ + ω×Iω)),
//! which holds for the quaternion quasi-velocities of ball and free joints.
//! J̇θ̇ and ṁ are taken by 4th-order central differences along the exact
//! constant-velocity motion. A flexible body's nodes are rigid bodies placed
//! by its modal coordinates (docs/flexible.md), their angular Jacobian
//! columns taken by differences of the node's rotation (nalgebra's exp and
//! log). A child body at a node of a flexible body (its `pos` within 1 µm
//! of a node that some mode moves) hangs from that node's frame, and each
//! modal coordinate moves it as the node's twist per unit rate.
//! Nothing here uses the spatial-operator code under test.

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Unit, UnitQuaternion, Vector3};
use nudyn::flex::{ModalBody, Mode, Node};
use nudyn::vehicle::{
    Actuation, Actuator, ActuatorKind, BiasType, Body, GainType, Joint, JointKind, MassProperties, Transmission,
    Vehicle,
};

pub type V3 = Vector3<f64>;
pub type M3 = Matrix3<f64>;

/// One dof's effect on the world, at a configuration.
#[derive(Clone, Copy, Debug)]
enum DofMotion {
    /// Rotation about `axis` through `point` (world).
    Rotation { axis: V3, point: V3 },
    /// Translation along `axis` (world).
    Translation { axis: V3 },
}

/// World poses of all bodies and the world motion of every dof.
pub struct Kinematics {
    /// The configuration (the flexible bodies' nodes are placed from it).
    pub theta: Vec<f64>,
    pub body_rot: Vec<M3>,
    pub body_pos: Vec<V3>,
    dofs: Vec<DofMotion>,
    /// For each body, the dofs that move it (ancestors' and its own).
    pub body_dofs: Vec<Vec<usize>>,
    /// For each body, the modal coordinates of the flexible ancestors whose
    /// nodes carry it: (ν entry, angular velocity, velocity of `point`,
    /// `point`), world, per unit rate.
    pub node_twists: Vec<Vec<(usize, V3, V3, V3)>>,
}

pub fn nq_nv(vehicle: &Vehicle) -> (usize, usize) {
    let joints = vehicle.bodies.iter().flat_map(|b| b.joints.iter());
    let (nq, nv) = joints.fold((0, 0), |(q, v), j| (q + j.kind.nq(), v + j.kind.nv()));
    let modes = modal_count(vehicle);
    (nq + modes, nv + modes)
}

/// The modal coordinates, after the joints' in θ and ν.
pub fn modal_count(vehicle: &Vehicle) -> usize {
    vehicle.flexible.iter().map(|f| f.modes.len()).sum()
}

/// Each flexible body with modes: its body index and its first modal coordinate's
/// place in θ and in ν.
fn flexible_bodies(vehicle: &Vehicle) -> Vec<(usize, &ModalBody, usize, usize)> {
    let joints = vehicle.bodies.iter().flat_map(|b| b.joints.iter());
    let (mut qa, mut va) = joints.fold((0, 0), |(q, v), j| (q + j.kind.nq(), v + j.kind.nv()));
    let mut out = Vec::new();
    for modal in vehicle.flexible.iter().filter(|f| !f.modes.is_empty()) {
        let body = vehicle.bodies.iter().position(|b| b.name == modal.body).unwrap();
        out.push((body, modal, qa, va));
        qa += modal.modes.len();
        va += modal.modes.len();
    }
    out
}

fn quat_at(theta: &[f64], adr: usize) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        theta[adr],
        theta[adr + 1],
        theta[adr + 2],
        theta[adr + 3],
    ))
}

pub fn kinematics(vehicle: &Vehicle, theta: &[f64]) -> Kinematics {
    let n = vehicle.bodies.len();
    let mut k = Kinematics {
        theta: theta.to_vec(),
        body_rot: Vec::with_capacity(n),
        body_pos: Vec::with_capacity(n),
        dofs: Vec::new(),
        body_dofs: Vec::with_capacity(n),
        node_twists: Vec::with_capacity(n),
    };
    let (_, nv) = nq_nv(vehicle);
    let flexible = flexible_bodies(vehicle);
    let mut qadr = 0;
    for body in &vehicle.bodies {
        let (mut parent_rot, mut parent_pos, mut dofs) = match body.parent {
            Some(p) => (k.body_rot[p], k.body_pos[p], k.body_dofs[p].clone()),
            None => (M3::identity(), V3::zeros(), Vec::new()),
        };
        let mut twists = body.parent.map_or_else(Vec::new, |p| k.node_twists[p].clone());
        let mut offset = body.pos;
        let carrier = body.parent.and_then(|p| flexible.iter().find(|f| f.0 == p));
        if let Some(&(p, modal, qa, va)) = carrier {
            let moves =
                |j: usize| modal.modes.iter().any(|m| m.translation[j] != V3::zeros() || m.rotation[j] != V3::zeros());
            let at = (0..modal.nodes.len()).find(|&j| (modal.nodes[j].position - body.pos).norm() <= 1e-6 && moves(j));
            if let Some(j) = at {
                let node = node_motion(&k, p, modal, &theta[qa..qa + modal.modes.len()], va, nv, j);
                for c in 0..modal.modes.len() {
                    let (w, v): (V3, V3) = (
                        node.jw.fixed_view::<3, 1>(0, va + c).into_owned(),
                        node.jv.fixed_view::<3, 1>(0, va + c).into_owned(),
                    );
                    twists.push((va + c, w, v, node.pos));
                }
                (parent_rot, parent_pos, offset) = (node.rot, node.pos, body.pos - modal.nodes[j].position);
            }
        }
        let mut rot = parent_rot * body.quat.to_rotation_matrix().into_inner();
        let mut pos = parent_pos + parent_rot * offset;
        for joint in &body.joints {
            match joint.kind {
                JointKind::Hinge => {
                    let axis = rot * joint.axis;
                    let anchor = pos + rot * joint.pos;
                    let r = Rotation3::from_axis_angle(&Unit::new_normalize(joint.axis), theta[qadr] - joint.reference);
                    rot *= r.into_inner();
                    pos = anchor - rot * joint.pos;
                    dofs.push(k.dofs.len());
                    k.dofs.push(DofMotion::Rotation { axis, point: anchor });
                }
                JointKind::Slide => {
                    let axis = rot * joint.axis;
                    pos += axis * (theta[qadr] - joint.reference);
                    dofs.push(k.dofs.len());
                    k.dofs.push(DofMotion::Translation { axis });
                }
                JointKind::Ball => {
                    let anchor = pos + rot * joint.pos;
                    rot *= quat_at(theta, qadr).to_rotation_matrix().into_inner();
                    pos = anchor - rot * joint.pos;
                    for c in 0..3 {
                        dofs.push(k.dofs.len());
                        k.dofs.push(DofMotion::Rotation { axis: rot.column(c).into_owned(), point: anchor });
                    }
                }
                JointKind::Free => {
                    pos = V3::new(theta[qadr], theta[qadr + 1], theta[qadr + 2]);
                    rot = quat_at(theta, qadr + 3).to_rotation_matrix().into_inner();
                    for c in 0..3 {
                        dofs.push(k.dofs.len());
                        k.dofs.push(DofMotion::Translation { axis: M3::identity().column(c).into_owned() });
                    }
                    for c in 0..3 {
                        dofs.push(k.dofs.len());
                        k.dofs.push(DofMotion::Rotation { axis: rot.column(c).into_owned(), point: pos });
                    }
                }
            }
            qadr += joint.kind.nq();
        }
        k.body_rot.push(rot);
        k.body_pos.push(pos);
        k.body_dofs.push(dofs);
        k.node_twists.push(twists);
    }
    k
}

/// Angular and linear (of a world point) Jacobians of a body, 3×nv each.
pub fn point_jacobian(k: &Kinematics, body: usize, point: &V3, nv: usize) -> (DMatrix<f64>, DMatrix<f64>) {
    let mut jw = DMatrix::zeros(3, nv);
    let mut jv = DMatrix::zeros(3, nv);
    for &d in &k.body_dofs[body] {
        match k.dofs[d] {
            DofMotion::Rotation { axis, point: c } => {
                jw.fixed_view_mut::<3, 1>(0, d).copy_from(&axis);
                jv.fixed_view_mut::<3, 1>(0, d).copy_from(&axis.cross(&(point - c)));
            }
            DofMotion::Translation { axis } => jv.fixed_view_mut::<3, 1>(0, d).copy_from(&axis),
        }
    }
    for &(d, w, v, at) in &k.node_twists[body] {
        jw.fixed_view_mut::<3, 1>(0, d).copy_from(&w);
        jv.fixed_view_mut::<3, 1>(0, d).copy_from(&(v + w.cross(&(point - at))));
    }
    (jw, jv)
}

/// Per body: (mass, world centre of mass, world inertia about com, Jω, Jv_com).
pub struct BodyTerms {
    pub mass: f64,
    pub com: V3,
    pub inertia: M3,
    pub jw: DMatrix<f64>,
    pub jv: DMatrix<f64>,
}

pub fn body_terms(vehicle: &Vehicle, k: &Kinematics, nv: usize) -> Vec<BodyTerms> {
    let mut out = Vec::new();
    let flexible = flexible_bodies(vehicle);
    for (b, body) in vehicle.bodies.iter().enumerate() {
        if let Some(&(_, modal, qa, va)) = flexible.iter().find(|f| f.0 == b) {
            out.extend(node_terms(k, b, modal, &k.theta[qa..qa + modal.modes.len()], va, nv));
            continue;
        }
        let Some(mp) = &body.inertia else { continue };
        let com = k.body_pos[b] + k.body_rot[b] * mp.com;
        let inertia = k.body_rot[b] * mp.inertia * k.body_rot[b].transpose();
        let (jw, jv) = point_jacobian(k, b, &com, nv);
        out.push(BodyTerms { mass: mp.mass, com, inertia, jw, jv });
    }
    out
}

/// The nodes of flexible body `b` as rigid bodies at the modal coordinates
/// `eta`, its modal rates at ν entry `va`.
fn node_terms(k: &Kinematics, b: usize, modal: &ModalBody, eta: &[f64], va: usize, nv: usize) -> Vec<BodyTerms> {
    (0..modal.nodes.len())
        .map(|j| {
            let node = node_motion(k, b, modal, eta, va, nv, j);
            let inertia = node.rot * modal.nodes[j].rotary_inertia * node.rot.transpose();
            BodyTerms { mass: modal.nodes[j].mass, com: node.pos, inertia, jw: node.jw, jv: node.jv }
        })
        .collect()
}

/// A node of a flexible body as a rigid body: its world rotation and
/// origin, and the angular and linear (of its origin) Jacobians, 3×nv.
pub struct NodeMotion {
    pub rot: M3,
    pub pos: V3,
    pub jw: DMatrix<f64>,
    pub jv: DMatrix<f64>,
}

/// Node `j` of flexible body `b` at the modal coordinates `eta` (its modal
/// rates at ν entry `va`).
fn node_motion(k: &Kinematics, b: usize, modal: &ModalBody, eta: &[f64], va: usize, nv: usize, j: usize) -> NodeMotion {
    let (rot, pos) = (k.body_rot[b], k.body_pos[b]);
    let rotation_vector =
        |j: usize, eta: &[f64]| -> V3 { modal.modes.iter().zip(eta).map(|(m, e)| m.rotation[j] * *e).sum() };
    let turn = |j: usize, eta: &[f64]| Rotation3::from_scaled_axis(rotation_vector(j, eta)).into_inner();
    let node = &modal.nodes[j];
    let displacement: V3 = modal.modes.iter().zip(eta).map(|(m, e)| m.translation[j] * *e).sum();
    let origin = pos + rot * (node.position + displacement);
    let (mut jw, mut jv) = point_jacobian(k, b, &origin, nv);
    for (c, mode) in modal.modes.iter().enumerate() {
        jv.fixed_view_mut::<3, 1>(0, va + c).copy_from(&(rot * mode.translation[j]));
        // The node's angular velocity per unit rate of mode c (body
        // axes), from E(η + hφ)E(η − hφ)ᵀ = exp(2h[ω]×) + O(h³), an
        // even series in h: two Richardson steps leave O(h⁶).
        let rate = |h: f64| {
            let (mut ahead, mut behind) = (eta.to_vec(), eta.to_vec());
            ahead[c] += h;
            behind[c] -= h;
            let step = nalgebra::Rotation3::from_matrix_unchecked(turn(j, &ahead) * turn(j, &behind).transpose());
            step.scaled_axis() / (2.0 * h)
        };
        let h = 8e-3;
        let (once, twice, thrice) = (rate(h), rate(h / 2.0), rate(h / 4.0));
        let (first, second) = ((4.0 * twice - once) / 3.0, (4.0 * thrice - twice) / 3.0);
        let omega = (16.0 * second - first) / 15.0;
        jw.fixed_view_mut::<3, 1>(0, va + c).copy_from(&(rot * omega));
    }
    NodeMotion { rot: rot * turn(j, eta), pos: origin, jw, jv }
}

/// Node `j` of the flexible body `body` (by index into `vehicle.bodies`) at θ.
pub fn node_at(vehicle: &Vehicle, theta: &[f64], body: usize, j: usize) -> NodeMotion {
    let (_, nv) = nq_nv(vehicle);
    let &(_, modal, qa, va) = flexible_bodies(vehicle).iter().find(|f| f.0 == body).expect("a flexible body");
    node_motion(&kinematics(vehicle, theta), body, modal, &theta[qa..qa + modal.modes.len()], va, nv, j)
}

pub fn armature(vehicle: &Vehicle) -> Vec<f64> {
    let joints = vehicle.bodies.iter().flat_map(|b| b.joints.iter());
    let rigid = joints.flat_map(|j| std::iter::repeat_n(j.armature, j.kind.nv()));
    rigid.chain(std::iter::repeat_n(0.0, modal_count(vehicle))).collect()
}

/// Dense mass matrix.
pub fn mass_matrix(vehicle: &Vehicle, theta: &[f64]) -> DMatrix<f64> {
    let (_, nv) = nq_nv(vehicle);
    let k = kinematics(vehicle, theta);
    let mut m = DMatrix::from_diagonal(&DVector::from_vec(armature(vehicle)));
    for t in body_terms(vehicle, &k, nv) {
        m += t.mass * t.jv.transpose() * &t.jv + t.jw.transpose() * t.inertia * &t.jw;
    }
    m
}

/// θ ⊕ s·u: MuJoCo's position integration (exact for constant u).
pub fn integrate_pos(vehicle: &Vehicle, theta: &[f64], u: &[f64], s: f64) -> Vec<f64> {
    let mut out = theta.to_vec();
    let (mut qa, mut va) = (0, 0);
    let rotate = |out: &mut Vec<f64>, qa: usize, w: V3| {
        let q = quat_at(out, qa) * UnitQuaternion::from_scaled_axis(w * s);
        out[qa..qa + 4].copy_from_slice(&[q.w, q.i, q.j, q.k]);
    };
    for joint in vehicle.bodies.iter().flat_map(|b| b.joints.iter()) {
        match joint.kind {
            JointKind::Hinge | JointKind::Slide => out[qa] += s * u[va],
            JointKind::Ball => rotate(&mut out, qa, V3::new(u[va], u[va + 1], u[va + 2])),
            JointKind::Free => {
                for c in 0..3 {
                    out[qa + c] += s * u[va + c];
                }
                rotate(&mut out, qa + 3, V3::new(u[va + 3], u[va + 4], u[va + 5]));
            }
        }
        qa += joint.kind.nq();
        va += joint.kind.nv();
    }
    for c in 0..modal_count(vehicle) {
        out[qa + c] += s * u[va + c];
    }
    out
}

/// Passive joint forces (springs about qpos_spring, dampers), as MuJoCo.
pub fn passive(vehicle: &Vehicle, theta: &[f64], qvel: &[f64]) -> DVector<f64> {
    let mut tau = DVector::zeros(qvel.len());
    let (mut qa, mut va) = (0, 0);
    for body in &vehicle.bodies {
        for joint in &body.joints {
            let (k, b) = (joint.stiffness, joint.damping);
            match joint.kind {
                JointKind::Hinge | JointKind::Slide => tau[va] = -k * (theta[qa] - joint.springref),
                JointKind::Ball => {
                    let r = quat_at(theta, qa).scaled_axis();
                    for c in 0..3 {
                        tau[va + c] = -k * r[c];
                    }
                }
                JointKind::Free => {
                    let rest = body.quat;
                    let d = rest.rotation_to(&quat_at(theta, qa + 3));
                    let r = rest.inverse() * d.scaled_axis();
                    for c in 0..3 {
                        tau[va + c] = -k * (theta[qa + c] - body.pos[c]);
                        tau[va + 3 + c] = -k * r[c];
                    }
                }
            }
            for c in 0..joint.kind.nv() {
                tau[va + c] -= b * qvel[va + c];
            }
            qa += joint.kind.nq();
            va += joint.kind.nv();
        }
    }
    for (_, modal, qa, va) in flexible_bodies(vehicle) {
        for (c, mode) in modal.modes.iter().enumerate() {
            let omega = mode.angular_frequency;
            tau[va + c] = -omega * omega * theta[qa + c] - 2.0 * mode.damping_ratio * omega * qvel[va + c];
        }
    }
    tau
}

/// Step of the finite differences along the motion (state scale ~1).
const FD_STEP: f64 = 1e-3;

/// f'(0) to O(h⁴) from f(±h), f(±2h).
fn central_difference(
    p1: &DMatrix<f64>,
    m1: &DMatrix<f64>,
    p2: &DMatrix<f64>,
    m2: &DMatrix<f64>,
    h: f64,
) -> DMatrix<f64> {
    (8.0 * (p1 - m1) - (p2 - m2)) / (12.0 * h)
}

/// Velocity-dependent and gravity bias h(θ, θ̇) by Kane's method, split
/// into (velocity products, gravity).
pub fn bias(vehicle: &Vehicle, theta: &[f64], qvel: &[f64]) -> (DVector<f64>, DVector<f64>) {
    let (_, nv) = nq_nv(vehicle);
    let u = DVector::from_column_slice(qvel);
    let terms = |s: f64| {
        let th = integrate_pos(vehicle, theta, qvel, s);
        body_terms(vehicle, &kinematics(vehicle, &th), nv)
    };
    let h = FD_STEP;
    let (now, p1, m1, p2, m2) = (terms(0.0), terms(h), terms(-h), terms(2.0 * h), terms(-2.0 * h));
    let mut h_vel = DVector::zeros(nv);
    let mut h_grav = DVector::zeros(nv);
    for (b, t) in now.iter().enumerate() {
        let jv_dot_u = central_difference(&p1[b].jv, &m1[b].jv, &p2[b].jv, &m2[b].jv, h) * &u;
        let jw_dot_u = central_difference(&p1[b].jw, &m1[b].jw, &p2[b].jw, &m2[b].jw, h) * &u;
        let w: V3 = (&t.jw * &u).fixed_rows::<3>(0).into_owned();
        let moment: V3 = t.inertia * jw_dot_u.fixed_rows::<3>(0) + w.cross(&(t.inertia * w));
        h_vel +=
            t.mass * t.jv.transpose() * jv_dot_u + t.jw.transpose() * DVector::from_column_slice(moment.as_slice());
        h_grav -= t.mass * t.jv.transpose() * DVector::from_column_slice(vehicle.gravity.as_slice());
    }
    (h_vel, h_grav)
}

/// Upper-triangular m with m mᵀ = M and a positive diagonal.
pub fn upper_factor(m: &DMatrix<f64>) -> DMatrix<f64> {
    let n = m.nrows();
    let flip = |a: &DMatrix<f64>| DMatrix::from_fn(n, n, |i, j| a[(n - 1 - i, n - 1 - j)]);
    let l = nalgebra::Cholesky::new(flip(m)).expect("M positive definite").l();
    flip(&l)
}

/// The ν entries in an order where every dof follows those that carry it:
/// bodies in order, each body's joints' and then its modes' (which carry
/// the children at its nodes, ahead in ν).
pub fn tree_order(vehicle: &Vehicle) -> Vec<usize> {
    let flexible = flexible_bodies(vehicle);
    let mut order = Vec::new();
    let mut va = 0;
    for (b, body) in vehicle.bodies.iter().enumerate() {
        let nv: usize = body.joints.iter().map(|j| j.kind.nv()).sum();
        order.extend(va..va + nv);
        va += nv;
        if let Some(&(_, modal, _, modes)) = flexible.iter().find(|f| f.0 == b) {
            order.extend(modes..modes + modal.modes.len());
        }
    }
    order
}

/// The factor m of M (m mᵀ = M) upper triangular with a positive diagonal
/// in [`tree_order`], given in ν's order.
pub fn tree_factor(vehicle: &Vehicle, m: &DMatrix<f64>) -> DMatrix<f64> {
    let order = tree_order(vehicle);
    let n = m.nrows();
    let factor = upper_factor(&DMatrix::from_fn(n, n, |r, c| m[(order[r], order[c])]));
    let mut out = DMatrix::zeros(n, n);
    for r in 0..n {
        for c in 0..n {
            out[(order[r], order[c])] = factor[(r, c)];
        }
    }
    out
}

/// θ̈ from the dense equations: M θ̈ = T + τ_passive − h.
pub fn forward_dynamics(vehicle: &Vehicle, theta: &[f64], qvel: &[f64], torque: &[f64]) -> DVector<f64> {
    let m = mass_matrix(vehicle, theta);
    let (h_vel, h_grav) = bias(vehicle, theta, qvel);
    let rhs = DVector::from_column_slice(torque) + passive(vehicle, theta, qvel) - h_vel - h_grav;
    m.cholesky().expect("M positive definite").solve(&rhs)
}

/// ν̇ = m*θ̈ + (d/dt m*) θ̇, the derivative of m* by central differences
/// along the motion.
pub fn nu_dot_reference(vehicle: &Vehicle, theta: &[f64], qvel: &[f64], torque: &[f64]) -> DVector<f64> {
    let u = DVector::from_column_slice(qvel);
    let qacc = forward_dynamics(vehicle, theta, qvel, torque);
    let m_at = |s: f64| tree_factor(vehicle, &mass_matrix(vehicle, &integrate_pos(vehicle, theta, qvel, s)));
    let difference = |h: f64| central_difference(&m_at(h), &m_at(-h), &m_at(2.0 * h), &m_at(-2.0 * h), h);
    // Richardson's step on the O(h⁴) differences: the factor's square roots
    // make its higher derivatives large on badly conditioned trees, where
    // the h⁴ term alone reached 2e-7.
    let m_dot = (16.0 * difference(FD_STEP / 2.0) - difference(FD_STEP)) / 15.0;
    m_at(0.0).transpose() * qacc + m_dot.transpose() * u
}

/// Spatial momentum about the world origin (angular, linear), world axes.
pub fn momentum(vehicle: &Vehicle, theta: &[f64], qvel: &[f64]) -> [f64; 6] {
    let (_, nv) = nq_nv(vehicle);
    let u = DVector::from_column_slice(qvel);
    let mut out = [0.0; 6];
    for t in body_terms(vehicle, &kinematics(vehicle, theta), nv) {
        let v: V3 = (&t.jv * &u).fixed_rows::<3>(0).into_owned();
        let w: V3 = (&t.jw * &u).fixed_rows::<3>(0).into_owned();
        let lin = t.mass * v;
        let ang = t.com.cross(&lin) + t.inertia * w;
        for c in 0..3 {
            out[c] += ang[c];
            out[3 + c] += lin[c];
        }
    }
    out
}

// ---------------------------------------------------------------------------
// Vehicles for tests.

/// A small deterministic generator (tests must be reproducible without a crate).
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E3779B97F4A7C15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        // xorshift64*
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545F4914F6CDD1D)
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    pub fn vec3(&mut self, scale: f64) -> V3 {
        V3::new(self.uniform(-scale, scale), self.uniform(-scale, scale), self.uniform(-scale, scale))
    }
    pub fn unit_quat(&mut self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            self.uniform(-1.0, 1.0),
            self.uniform(-1.0, 1.0),
            self.uniform(-1.0, 1.0),
            self.uniform(-1.0, 1.0),
        ))
    }
    pub fn unit_vec(&mut self) -> V3 {
        loop {
            let v = self.vec3(1.0);
            if v.norm() > 0.2 {
                return v.normalize();
            }
        }
    }
    pub fn vec(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| self.uniform(-scale, scale)).collect()
    }
}

/// A body at `pos` in its parent with `joints`, turned and weighted at
/// random (its orientation, then its mass properties, drawn in that order).
fn random_body(rng: &mut Rng, name: String, parent: Option<usize>, pos: V3, joints: Vec<Joint>) -> Body {
    Body {
        name,
        parent,
        pos,
        quat: rng.unit_quat(),
        inertia: Some(random_mass(rng)),
        inertial_pos: V3::zeros(),
        inertial_quat: None,
        mass_unknown: false,
        joints,
        gravcomp: 0.0,
        line: 0,
    }
}

/// Full, off-centre mass properties: principal moments that satisfy the
/// triangle inequality, rotated to random axes.
pub fn random_mass(rng: &mut Rng) -> MassProperties {
    let mass = rng.uniform(0.2, 5.0);
    let a = rng.uniform(0.02, 0.3);
    let b = rng.uniform(0.02, 0.3);
    let c = rng.uniform(0.02, 0.3);
    // Moments of a solid box with half sizes a, b, c.
    let diag = M3::from_diagonal(&V3::new(b * b + c * c, a * a + c * c, a * a + b * b)) * (mass / 3.0);
    let r = rng.unit_quat().to_rotation_matrix().into_inner();
    MassProperties { mass, com: rng.vec3(0.3), inertia: r * diag * r.transpose() }
}

pub fn joint(rng: &mut Rng, name: String, kind: JointKind) -> Joint {
    Joint {
        name,
        kind,
        pos: if kind == JointKind::Free { V3::zeros() } else { rng.vec3(0.2) },
        axis: rng.unit_vec(),
        reference: if matches!(kind, JointKind::Hinge | JointKind::Slide) { rng.uniform(-0.5, 0.5) } else { 0.0 },
        springref: rng.uniform(-0.5, 0.5),
        stiffness: 0.0,
        damping: 0.0,
        armature: if rng.below(2) == 0 { rng.uniform(0.0, 0.5) } else { 0.0 },
        actuator_force_range: None,
        actuator_gravcomp: false,
        springdamper: None,
        constraints: Default::default(),
        line: 0,
    }
}

/// Options for [`random_vehicle`].
#[derive(Clone, Copy)]
pub struct TreeOptions {
    pub bodies: usize,
    /// Root is a free-floating base.
    pub free_base: bool,
    /// Allow gravity, springs and dampers.
    pub passive: bool,
    /// Attach each body to the previous one (a chain) instead of a random parent.
    pub chain: bool,
}

/// A random tree with every joint type, several joints per body, welded
/// bodies, off-centre full inertias and armature.
pub fn random_vehicle(rng: &mut Rng, opts: TreeOptions) -> Vehicle {
    let mut bodies: Vec<Body> = Vec::new();
    for b in 0..opts.bodies {
        let parent = if b == 0 {
            None
        } else if opts.chain {
            Some(b - 1)
        } else {
            Some(rng.below(b))
        };
        let mut joints = Vec::new();
        if b == 0 && opts.free_base {
            joints.push(joint(rng, format!("j{b}_free"), JointKind::Free));
        } else {
            // 0 (welded) to 3 joints; a ball only last, as MuJoCo requires.
            let count = [0, 1, 1, 1, 2, 3][rng.below(6)];
            let count = if b == 0 && count == 0 { 1 } else { count };
            for k in 0..count {
                let kind = match rng.below(5) {
                    0 | 1 => JointKind::Hinge,
                    2 => JointKind::Slide,
                    _ if k + 1 == count => JointKind::Ball,
                    _ => JointKind::Hinge,
                };
                let mut j = joint(rng, format!("j{b}_{k}"), kind);
                if opts.passive {
                    j.stiffness = rng.uniform(0.0, 5.0);
                    j.damping = rng.uniform(0.0, 1.0);
                }
                joints.push(j);
            }
        }
        let pos = rng.vec3(0.5);
        let mut body = random_body(rng, format!("b{b}"), parent, pos, joints);
        if b == 0 && opts.free_base {
            if opts.passive {
                body.joints[0].stiffness = rng.uniform(0.0, 5.0);
                body.joints[0].damping = rng.uniform(0.0, 1.0);
            }
            body.joints[0].armature = 0.0;
        }
        bodies.push(body);
    }
    let gravity = if opts.passive { V3::new(0.3, -0.2, -9.81) } else { V3::zeros() };
    Vehicle {
        name: "random".into(),
        gravity,
        magnetic: V3::zeros(),
        bodies,
        sites: Vec::new(),
        actuators: Vec::new(),
        sensors: Vec::new(),
        actuation: Actuation::default(),
        constraint_options: Default::default(),
        equalities: Vec::new(),
        sensors_disabled: false,
        tendons: Vec::new(),
        flexible: Vec::new(),
    }
}

/// A random configuration (unit quaternions) for a vehicle.
pub fn random_theta(rng: &mut Rng, vehicle: &Vehicle) -> Vec<f64> {
    let mut theta = Vec::new();
    for joint in vehicle.bodies.iter().flat_map(|b| b.joints.iter()) {
        match joint.kind {
            JointKind::Hinge | JointKind::Slide => theta.push(rng.uniform(-2.0, 2.0)),
            JointKind::Ball => {
                let q = rng.unit_quat();
                theta.extend([q.w, q.i, q.j, q.k]);
            }
            JointKind::Free => {
                let p = rng.vec3(2.0);
                let q = rng.unit_quat();
                theta.extend([p.x, p.y, p.z, q.w, q.i, q.j, q.k]);
            }
        }
    }
    theta.extend(rng.vec(modal_count(vehicle), 0.5));
    theta
}

/// Makes 1–2 random bodies of `vehicle` flexible: 2–4 nodes with rotary
/// inertia and 1–3 modes whose shapes use every component (not orthogonal:
/// the dynamics do not need it); each body's inertia becomes its nodes'.
pub fn make_flexible(rng: &mut Rng, vehicle: &mut Vehicle, damped: bool) {
    let count = 1 + rng.below(2.min(vehicle.bodies.len()));
    let mut chosen: Vec<usize> = Vec::new();
    while chosen.len() < count {
        let b = rng.below(vehicle.bodies.len());
        if !chosen.contains(&b) {
            chosen.push(b);
        }
    }
    chosen.sort();
    for b in chosen {
        let count = 2 + rng.below(3);
        // About half the nodes point masses (no rotary inertia, no rotation
        // in any mode: the passes sum those in closed form); a body keeps
        // one rotating node unless three points span its inertia.
        let mut point: Vec<bool> = (0..count).map(|_| rng.below(2) == 0).collect();
        if count < 3 {
            point[0] = false;
        }
        let nodes: Vec<Node> = (0..count)
            .map(|j| Node {
                name: format!("n{j}"),
                position: rng.vec3(0.5),
                mass: rng.uniform(0.2, 2.0),
                rotary_inertia: if point[j] { Matrix3::zeros() } else { random_mass(rng).inertia * 0.3 },
            })
            .collect();
        let modes = (0..1 + rng.below(3))
            .map(|c| Mode {
                angular_frequency: rng.uniform(1.0, 10.0) * (c + 1) as f64,
                damping_ratio: if damped { rng.uniform(0.0, 0.1) } else { 0.0 },
                translation: (0..nodes.len()).map(|_| rng.vec3(0.4)).collect(),
                rotation: (0..nodes.len()).map(|j| if point[j] { Vector3::zeros() } else { rng.vec3(0.6) }).collect(),
            })
            .collect();
        let modal = ModalBody { body: vehicle.bodies[b].name.clone(), nodes, modes };
        vehicle.bodies[b].inertia = Some(modal.mass_properties());
        vehicle.flexible.push(modal);
    }
}

/// Places child bodies at nodes of `vehicle`'s flexible bodies: each child
/// with joints of a flexible body moves onto one of its nodes (point masses
/// and rotating nodes alike) with probability ¾, and when none did, a new
/// child with a hinge, a ball or two joints hangs from a random node of the
/// first flexible body. Returns how many children sit at nodes.
pub fn attach_children_to_nodes(rng: &mut Rng, vehicle: &mut Vehicle) -> usize {
    let mut attached = 0;
    for modal in vehicle.flexible.iter().filter(|f| !f.modes.is_empty()) {
        let b = vehicle.bodies.iter().position(|body| body.name == modal.body).unwrap();
        for child in vehicle.bodies.iter_mut().filter(|c| c.parent == Some(b) && !c.joints.is_empty()) {
            if rng.below(4) != 0 {
                child.pos = modal.nodes[rng.below(modal.nodes.len())].position;
                attached += 1;
            }
        }
    }
    if attached == 0 {
        let Some(modal) = vehicle.flexible.iter().find(|f| !f.modes.is_empty()) else { return 0 };
        let b = vehicle.bodies.iter().position(|body| body.name == modal.body).unwrap();
        let n = vehicle.bodies.len();
        let kinds: &[JointKind] = match rng.below(3) {
            0 => &[JointKind::Hinge],
            1 => &[JointKind::Ball],
            _ => &[JointKind::Slide, JointKind::Hinge],
        };
        let joints = kinds.iter().enumerate().map(|(k, &kind)| joint(rng, format!("j{n}_{k}"), kind)).collect();
        let pos = modal.nodes[rng.below(modal.nodes.len())].position;
        vehicle.bodies.push(random_body(rng, format!("b{n}"), Some(b), pos, joints));
        attached = 1;
    }
    attached
}

/// Welds bodies at nodes of `vehicle`'s flexible bodies (docs/flexible.md,
/// "Bodies welded at nodes"): at a random node of each, a body without
/// joints, turned and off-centre at random; under it, each with
/// probability ½, a child with a hinge or a ball and a second welded body
/// (which may carry a child with a joint of its own). Returns the welded
/// bodies' indices.
pub fn weld_bodies_to_nodes(rng: &mut Rng, vehicle: &mut Vehicle) -> Vec<usize> {
    let mut welded = Vec::new();
    let flexible: Vec<(usize, Vec<V3>)> = vehicle
        .flexible
        .iter()
        .filter(|f| !f.modes.is_empty())
        .map(|f| {
            let b = vehicle.bodies.iter().position(|body| body.name == f.body).unwrap();
            (b, f.nodes.iter().map(|n| n.position).collect())
        })
        .collect();
    for (b, nodes) in flexible {
        let pos = nodes[rng.below(nodes.len())];
        let add = |rng: &mut Rng, vehicle: &mut Vehicle, parent: usize, pos: V3, joints: Vec<Joint>| {
            let n = vehicle.bodies.len();
            vehicle.bodies.push(random_body(rng, format!("b{n}"), Some(parent), pos, joints));
            n
        };
        let on_node = add(rng, vehicle, b, pos, Vec::new());
        welded.push(on_node);
        let mut carriers = vec![on_node];
        if rng.below(2) == 0 {
            let pos = rng.vec3(0.3);
            let second = add(rng, vehicle, on_node, pos, Vec::new());
            welded.push(second);
            carriers.push(second);
        }
        for carrier in carriers {
            if rng.below(2) == 0 {
                let n = vehicle.bodies.len();
                let kind = if rng.below(2) == 0 { JointKind::Hinge } else { JointKind::Ball };
                let joints = vec![joint(rng, format!("j{n}"), kind)];
                let pos = rng.vec3(0.3);
                add(rng, vehicle, carrier, pos, joints);
            }
        }
    }
    welded
}

/// A motor (gain 1, no bias, no ranges) on `transmission` with `gear`.
pub fn motor(transmission: Transmission, gear: [f64; 6]) -> Actuator {
    Actuator {
        name: None,
        kind: ActuatorKind::Motor,
        transmission,
        gear,
        gain_type: GainType::Fixed,
        gain: [1.0, 0.0, 0.0],
        bias_type: BiasType::None,
        bias: [0.0; 3],
        ctrl_range: None,
        force_range: None,
        activation: None,
        group_disabled: false,
        line: 0,
    }
}

/// max |a − b| / max(1, max |b|); NaN where an entry of either is NaN.
pub fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    max_abs_difference(a, b) / b.iter().fold(1.0f64, |m, x| m.max(x.abs()))
}

/// The largest |x − r| / (1 + |r|) over the pairs (x, r) (an end state
/// against its reference); NaN where an entry of either is NaN, as
/// [`max_abs_difference`].
pub fn largest_relative_error<'a>(pairs: impl IntoIterator<Item = (&'a f64, &'a f64)>) -> f64 {
    pairs.into_iter().fold(0.0f64, |m, (x, r)| {
        let error = (x - r).abs() / (1.0 + r.abs());
        if m.is_nan() || error.is_nan() { f64::NAN } else { m.max(error) }
    })
}

/// max |a − b|; NaN where an entry of either is NaN (`f64::max` would pass
/// over it, and a NaN is no agreement).
pub fn max_abs_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len(), "length mismatch");
    if a.iter().chain(b).any(|x| x.is_nan()) {
        return f64::NAN;
    }
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}
