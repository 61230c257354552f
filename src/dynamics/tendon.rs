//! Tendons at a state (docs/DYNAMICS.md §9): lengths L, moment arms J
//! (∂L/∂θ̇ as a row over the dofs, MuJoCo's `ten_J`), velocities J θ̇, and
//! the passive force −(k·(L − L_spring) + b·L̇) they put on the dofs as Jᵀf.
//!
//! A fixed tendon's arms are its coefficients. A spatial tendon's are those
//! of a unit tension: along each straight segment p₀ → p₁ (between sites of
//! different bodies), the unit force u = (p₁ − p₀)/|p₁ − p₀| pulls the
//! point p₁ and −u the point p₀, dL/dt = u·(ṗ₁ − ṗ₀); one inward pass turns
//! these point forces into joint forces, T_i = S_iᵀ Σ_subtree f. O(N) per
//! tendon. A segment wrapped around a geom (`wrap`) pulls the points where
//! it meets the geom, which move with the geom's link.

use super::actuation::site_in_world;
use super::forces::add_joint_forces_of_wrenches;
use super::wrap;
use crate::math::{SpatialVec, Transform, Vec3, spatial};
use crate::model::{Model, Path, PathStop};
use crate::workspace::Workspace;

/// A point of a spatial tendon's path in the world, and what carries it.
#[derive(Clone, Copy)]
struct PathPoint {
    /// The link moving it (`None`: the world).
    link: Option<usize>,
    /// The MJCF body carrying it.
    body: Option<usize>,
    /// Its world position.
    at: Vec3,
}

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
    /// the segments after it and starts a new branch; a site, geom, site
    /// triple wraps (two straight segments to the geom's surface and the arc
    /// between, the arc's points moving with the geom), or runs straight
    /// when the segment misses the geom.
    fn spatial_tendon(&mut self, model: &Model, stops: &[PathStop], moment: &mut [f64]) -> f64 {
        self.tendon_wrench.fill(SpatialVec::zeros());
        let mut divisor = 1.0;
        let mut length = 0.0;
        let mut pulls = false;
        let mut j = 0;
        while j + 1 < stops.len() {
            let (from, next) = match (&stops[j], &stops[j + 1]) {
                (PathStop::Pulley { divisor: d }, _) => {
                    divisor = *d;
                    j += 1;
                    continue;
                }
                // A site before a pulley ends its branch.
                (_, PathStop::Pulley { .. }) => {
                    j += 1;
                    continue;
                }
                (PathStop::Site { frame, body }, next) => ((frame, *body), next),
                // The importer puts a geom between two sites only.
                (PathStop::Geom { .. }, _) => unreachable!("a geom follows a site"),
            };
            let start = PathPoint { link: from.0.link, body: from.1, at: site_in_world(from.0, &self.x_world).trans };
            let site_point = |stop: &PathStop, x_world: &[Transform]| match stop {
                PathStop::Site { frame, body } => {
                    PathPoint { link: frame.link, body: *body, at: site_in_world(frame, x_world).trans }
                }
                _ => unreachable!("the importer ends a wrap at a site"),
            };
            match next {
                PathStop::Geom { frame, body, radius, cylinder } => {
                    let end = site_point(&stops[j + 2], &self.x_world);
                    let geom = site_in_world(frame, &self.x_world);
                    match wrap::wrap(&start.at, &end.at, &geom, *radius, *cylinder) {
                        Some((arc, first, second)) => {
                            let on_geom = |at: Vec3| PathPoint { link: frame.link, body: *body, at };
                            let points = [start, on_geom(first), on_geom(second), end];
                            length += ((first - start.at).norm() + arc + (end.at - second).norm()) / divisor;
                            for pair in points.windows(2) {
                                pulls |= self.pull_segment(&pair[0], &pair[1], divisor);
                            }
                        }
                        None => {
                            length += (end.at - start.at).norm() / divisor;
                            pulls |= self.pull_segment(&start, &end, divisor);
                        }
                    }
                    j += 2;
                }
                _ => {
                    let end = site_point(next, &self.x_world);
                    length += (end.at - start.at).norm() / divisor;
                    pulls |= self.pull_segment(&start, &end, divisor);
                    j += 1;
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

    /// Adds the unit tension's point forces of the straight segment
    /// `from → to` (its direction over `divisor` at `to`, the opposite at
    /// `from`) to the links' wrenches; MuJoCo leaves out a segment within one
    /// body. A segment between two bodies welded to one link (or both to the
    /// world) is left out too: its two forces cancel exactly, while summed
    /// as wrenches they leave round-off arms of 1e-17 that a tendon limit's
    /// row would multiply into forces of 1e17. Whether some link took a force.
    fn pull_segment(&mut self, from: &PathPoint, to: &PathPoint, divisor: f64) -> bool {
        if from.body == to.body || from.link == to.link {
            return false;
        }
        let difference = to.at - from.at;
        let distance = difference.norm();
        // MuJoCo's mju_normalize3: a vanishing segment points along x.
        let direction = if distance < MIN_VALUE { Vec3::x() } else { difference * (1.0 / distance) };
        let force = direction / divisor;
        let mut pulls = false;
        for (point, f) in [(from, -force), (to, force)] {
            if let Some(link) = point.link {
                // The point force in link coordinates, about the link origin.
                let x = &self.x_world[link];
                let (r, f) = (x.rot * (point.at - x.trans), x.rot * f);
                self.tendon_wrench[link] += spatial(&r.cross(&f), &f);
                pulls = true;
            }
        }
        pulls
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
