//! Tendons at a state (docs/DYNAMICS.md §9): lengths L, moment arms J
//! (∂L/∂θ̇ as a row over the dofs, MuJoCo's `ten_J`), velocities J θ̇, and
//! the passive force −(k·(L − L_spring) + b·L̇) they put on the dofs as Jᵀf.
//!
//! A fixed tendon's arms are its coefficients. A spatial tendon's are those
//! of a unit tension: along each straight segment p₀ → p₁ (between sites of
//! different bodies), the unit force u = (p₁ − p₀)/|p₁ − p₀| pulls the
//! point p₁ and −u the point p₀, dL/dt = u·(ṗ₁ − ṗ₀); one inward pass turns
//! these point forces into joint forces, T_i = S_iᵀ Σ_subtree f. O(N) per tendon.

use super::actuation::{site_in_world, wrench_at_site};
use super::forces::add_joint_forces_of_wrenches;
use crate::math::{SpatialVec, Vec3};
use crate::model::{Model, Path, PathStop};
use crate::workspace::Workspace;

/// MuJoCo's `mjMINVAL`: a shorter segment has no direction.
const MIN_VALUE: f64 = 1e-15;

impl Workspace {
    /// Lengths and moment arms of every tendon at the configuration of
    /// passes 0 and 1 (`set_configuration` runs it when the model has tendons).
    pub(crate) fn tendon_kinematics(&mut self, model: &Model) {
        let nv = model.nv;
        for (k, tendon) in model.tendons.iter().enumerate() {
            let row = k * nv..(k + 1) * nv;
            self.tendon_moment[row.clone()].fill(0.0);
            self.tendon_length[k] = match &tendon.path {
                Path::Fixed { terms } => {
                    let mut length = 0.0;
                    for term in terms {
                        length += term.coef * self.theta[term.qpos];
                        self.tendon_moment[k * nv + term.dof] += term.coef;
                    }
                    length
                }
                Path::Spatial { stops } => {
                    self.world_transforms(model);
                    let mut moment = std::mem::take(&mut self.tendon_moment);
                    let length = self.spatial_tendon(model, stops, &mut moment[row]);
                    self.tendon_moment = moment;
                    length
                }
            };
        }
    }

    /// A spatial tendon's length, and its moment arms into `moment` (nv),
    /// as MuJoCo's `mj_tendon` walks the path: a pulley sets the divisor of
    /// the segments after it and starts a new branch.
    fn spatial_tendon(&mut self, model: &Model, stops: &[PathStop], moment: &mut [f64]) -> f64 {
        self.tendon_wrench.fill(SpatialVec::zeros());
        let mut divisor = 1.0;
        let mut length = 0.0;
        let mut pulls = false;
        for pair in stops.windows(2) {
            let (from, to) = match pair {
                [PathStop::Pulley { divisor: d }, _] => {
                    divisor = *d;
                    continue;
                }
                [PathStop::Site { frame: from, body: b0 }, PathStop::Site { frame: to, body: b1 }] => {
                    ((from, b0), (to, b1))
                }
                // A site before a pulley ends its branch.
                _ => continue,
            };
            let p0 = site_in_world(from.0, &self.x_world).trans;
            let p1 = site_in_world(to.0, &self.x_world).trans;
            let difference = p1 - p0;
            let distance = difference.norm();
            length += distance / divisor;
            if from.1 == to.1 {
                continue;
            }
            // MuJoCo's mju_normalize3: a vanishing segment points along x.
            let direction = if distance < MIN_VALUE { Vec3::x() } else { difference / distance };
            let force = direction / divisor;
            for (site, f) in [(from.0, -force), (to.0, force)] {
                if let (Some(link), wrench) = wrench_at_site(site, &self.x_world, &Vec3::zeros(), &f) {
                    self.tendon_wrench[link] += wrench;
                    pulls = true;
                }
            }
        }
        if pulls {
            add_joint_forces_of_wrenches(
                model,
                &self.x_parent,
                &self.accumulation,
                &mut self.p_scratch_body,
                &self.tendon_wrench,
                moment,
            );
        }
        length
    }

    /// Every tendon's velocity J θ̇ (`set_nu` and `set_qvel` run it when the
    /// model has tendons).
    pub(crate) fn tendon_velocities(&mut self, model: &Model) {
        let nv = model.nv;
        for k in 0..model.tendons.len() {
            let row = &self.tendon_moment[k * nv..(k + 1) * nv];
            self.tendon_velocity[k] = row.iter().zip(self.qvel.iter()).map(|(j, v)| j * v).sum();
        }
    }

    /// The moment arms of tendon `k` (nv).
    pub fn tendon_moment_row(&self, model: &Model, k: usize) -> &[f64] {
        &self.tendon_moment[k * model.nv..(k + 1) * model.nv]
    }
}

/// Adds the tendons' springs and dampers to the passive joint forces,
/// τ += Jᵀ(−k·x − b·L̇), x the length's distance beyond the spring's
/// deadband (MuJoCo's `mj_springdamper`).
pub(crate) fn add_passive_forces(model: &Model, ws: &mut Workspace) {
    let nv = model.nv;
    for (k, tendon) in model.tendons.iter().enumerate() {
        if !tendon.has_passive_force() {
            continue;
        }
        let length = ws.tendon_length[k];
        let [lower, upper] = tendon.spring_length;
        let stretch = if length > upper {
            length - upper
        } else if length < lower {
            length - lower
        } else {
            0.0
        };
        let force = -stretch * tendon.stiffness - ws.tendon_velocity[k] * tendon.damping;
        if force != 0.0 {
            for d in 0..nv {
                ws.tau_passive[d] += ws.tendon_moment[k * nv + d] * force;
            }
        }
    }
}
