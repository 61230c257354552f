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

use std::ops::Range;

use super::actuation::site_in_world;
use super::constraint::RowKind;
use super::equality::polynomial_coupling;
use super::forces::add_joint_forces_of_wrenches;
use super::wrap::{self, WrapPath};
use crate::math::{Real, SpatialVec, Transform, Vec3, dot, spatial};
use crate::model::{ActuatorTransmission, EqualityRows, Model, Path, PathStop, Tendon, WRAP_SWITCHES};
use crate::workspace::Workspace;

/// A point of a spatial tendon's path in the world, and what carries it.
#[derive(Clone, Copy)]
pub(super) struct PathPoint<S: Real = f64> {
    /// The link moving it (`None`: the world).
    pub link: Option<usize>,
    /// The MJCF body carrying it.
    pub body: Option<usize>,
    /// Its world position.
    pub at: Vec3<S>,
}

/// MuJoCo's `mjMINVAL`: a shorter segment has no direction.
const MIN_VALUE: f64 = 1e-15;

impl<S: Real> Workspace<S> {
    /// Lengths and moment arms of every tendon at the configuration of
    /// passes 0 and 1 (`set_configuration` runs it when the model has
    /// tendons), and the wraps' switching functions.
    pub(crate) fn tendon_kinematics(&mut self, model: &Model) {
        let nv = model.nv;
        for ((k, tendon), wraps) in model.tendons.iter().enumerate().zip(model.tendon_wraps()) {
            let row = k * nv..(k + 1) * nv;
            self.tendon_moment[row.clone()].fill(S::zero());
            self.tendon_length[k] = match &tendon.path {
                Path::Fixed { terms } => {
                    let mut length = S::zero();
                    for term in terms {
                        length += self.theta[term.qpos] * term.coef;
                        self.tendon_moment[k * nv + term.dof] += term.coef;
                    }
                    length
                }
                Path::Spatial { stops } => {
                    self.world_transforms(model);
                    let mut moment = std::mem::take(&mut self.tendon_moment);
                    let length = self.spatial_tendon(model, stops, &mut moment[row], wraps);
                    self.tendon_moment = moment;
                    length
                }
            };
        }
    }

    /// A spatial tendon's length, and its moment arms into `moment` (nv):
    /// the unit tension's point forces on each segment, summed per link and
    /// taken inward to the joints. Its wraps, the model's `wraps`, take
    /// the paths held, if any, else decide them, and note their paths and
    /// switching functions.
    fn spatial_tendon(&mut self, model: &Model, stops: &[PathStop], moment: &mut [S], wraps: Range<usize>) -> S {
        self.tendon_wrench.fill(SpatialVec::zeros());
        let (x_world, wrench) = (&self.x_world, &mut self.tendon_wrench);
        let held = self.wraps_held.then(|| &self.wrap_paths_held[wraps.clone()]);
        let functions = wraps.start * WRAP_SWITCHES..wraps.end * WRAP_SWITCHES;
        let decided = (&mut self.wrap_paths[wraps], &mut self.wrap_switching[functions]);
        let mut pulls = false;
        let length = walk_path(stops, x_world, held, Some(decided), |from, to, divisor| {
            pulls |= pull_segment(x_world, wrench, from, to, divisor);
        });
        if pulls {
            add_joint_forces_of_wrenches(
                model,
                &self.x_parent,
                &self.accumulation,
                &mut self.flex,
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
            self.tendon_velocity[k] = row.iter().zip(self.qvel.iter()).fold(S::zero(), |sum, (j, v)| sum + *j * *v);
        }
    }

    /// The moment arms of tendon `k` (nv).
    pub fn tendon_moment_row(&self, model: &Model, k: usize) -> &[S] {
        &self.tendon_moment[k * model.nv..(k + 1) * model.nv]
    }
}

impl<S: Real> Workspace<S> {
    /// The force tendon `k` carries, F, whose generalized force is JᵀF (F > 0
    /// pushes its ends apart): its spring and damper, its armature's
    /// −a·L̈ (L̈ = J θ̈ + J̇θ̇), its actuators' forces times their gear, and
    /// its friction-loss, limit and equality rows' forces times the
    /// tendon's share of the row (a limit row's side decided on the values).
    pub(super) fn tendon_force(&self, model: &Model, k: usize) -> S {
        let tendon = &model.tendons[k];
        let mut force = S::zero();
        if tendon.armature != 0.0 {
            let along = dot(self.tendon_moment_row(model, k), self.qacc.as_slice());
            force -= (along + self.tendon_inertia.jdot_qvel(k)) * tendon.armature;
        }
        if tendon.has_passive_force() {
            force += passive_force(tendon, self.tendon_length[k], self.tendon_velocity[k]);
        }
        for (a, actuator) in model.actuators.iter().enumerate() {
            if matches!(actuator.transmission, ActuatorTransmission::Tendon { tendon } if tendon == k) {
                force += self.actuator_force[a] * actuator.gear[0];
            }
        }
        let rows = &self.constraint_rows;
        let constraints = &model.constraints;
        for r in 0..rows.count {
            let share = match rows.kind[r] {
                RowKind::TendonFriction if constraints.tendon_friction[rows.id[r]].tendon == k => S::one(),
                // The row is ∓J on the lower and upper side.
                RowKind::TendonLimit if constraints.tendon_limits[rows.id[r]].tendon == k => {
                    let row = &rows.jacobian[r * model.nv..(r + 1) * model.nv];
                    let arms = self.tendon_moment_row(model, k);
                    let along: f64 = row.iter().zip(arms).map(|(a, b)| a.value() * b.value()).sum();
                    S::from(along.signum())
                }
                RowKind::Equality => match &constraints.equalities[rows.id[r]].rows {
                    EqualityRows::Tendon { first, second, polycoef, .. } if *first == k || *second == Some(k) => {
                        let offset = |t: usize| self.tendon_length[t] - model.tendons[t].length0;
                        let (_, slope) = polynomial_coupling(polycoef, offset(*first), second.map(offset));
                        if *first == k { S::one() } else { -slope }
                    }
                    _ => S::zero(),
                },
                _ => S::zero(),
            };
            force += share * rows.force[r];
        }
        force
    }
}

/// Adds the unit tension's point forces of the straight segment `from →
/// to` (its direction over `divisor` at `to`, the opposite at `from`) to the
/// links' `wrench`es; MuJoCo leaves out a segment within one body. A segment
/// between two bodies welded to one link (or both to the world) is left out
/// too: its two forces cancel exactly, while summed as wrenches they leave
/// round-off arms of 1e-17 that a tendon limit's row would multiply into
/// forces of 1e17. Whether some link took a force.
fn pull_segment<S: Real>(
    x_world: &[Transform<S>],
    wrench: &mut [SpatialVec<S>],
    from: &PathPoint<S>,
    to: &PathPoint<S>,
    divisor: f64,
) -> bool {
    if from.body == to.body || from.link == to.link {
        return false;
    }
    let force = direction(from, to) / S::from(divisor);
    let mut pulls = false;
    for (point, f) in [(from, -force), (to, force)] {
        if let Some(link) = point.link {
            // The point force in link coordinates, about the link origin.
            let x = &x_world[link];
            let (r, f) = (x.rot * (point.at - x.trans), x.rot * f);
            wrench[link] += spatial(&r.cross(&f), &f);
            pulls = true;
        }
    }
    pulls
}

/// The unit vector from `from` to `to`; MuJoCo's mju_normalize3: a
/// vanishing segment points along x.
pub(super) fn direction<S: Real>(from: &PathPoint<S>, to: &PathPoint<S>) -> Vec3<S> {
    let difference = to.at - from.at;
    let distance = difference.norm();
    if distance.value() < MIN_VALUE { Vec3::x() } else { difference * (S::one() / distance) }
}

/// Walks a spatial tendon's path as MuJoCo's `mj_tendon` does, calling
/// `segment(from, to, divisor)` for each straight segment; its length. A
/// pulley sets the divisor of the segments after it and starts a new
/// branch; a site, geom, site triple wraps (two straight segments to the
/// geom's surface and the arc between, the arc's points moving with the
/// geom), or runs straight when the segment misses the geom: each wrap
/// as `held` says (one per geom in the path's order), or as the state
/// decides. With `decided`, each wrap's path goes to its first slice and
/// its switching functions to its second ([`WRAP_SWITCHES`] per geom).
pub(super) fn walk_path<S: Real>(
    stops: &[PathStop],
    x_world: &[Transform<S>],
    held: Option<&[WrapPath]>,
    mut decided: Option<(&mut [WrapPath], &mut [f64])>,
    mut segment: impl FnMut(&PathPoint<S>, &PathPoint<S>, f64),
) -> S {
    let site_point = |stop: &PathStop| match stop {
        PathStop::Site { frame, body } => {
            PathPoint { link: frame.link, body: *body, at: site_in_world(frame, x_world).trans }
        }
        _ => unreachable!("the importer ends a wrap at a site"),
    };
    let mut divisor = 1.0;
    let mut length = S::zero();
    let mut wraps = 0;
    let mut j = 0;
    while j + 1 < stops.len() {
        let start = match (&stops[j], &stops[j + 1]) {
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
            (site @ PathStop::Site { .. }, _) => site_point(site),
            // The importer puts a geom between two sites only.
            (PathStop::Geom { .. }, _) => unreachable!("a geom follows a site"),
        };
        match &stops[j + 1] {
            PathStop::Geom { frame, body, radius, cylinder, side } => {
                let end = site_point(&stops[j + 2]);
                let geom = site_in_world(frame, x_world);
                let side = side.map(|side| site_in_world(&side, x_world).trans);
                let mut functions = [0.0; WRAP_SWITCHES];
                let path = held.map(|held| held[wraps]);
                let (path, wrapped) =
                    wrap::wrap(&start.at, &end.at, &geom, *radius, *cylinder, side.as_ref(), path, &mut functions);
                if let Some((paths, switching)) = decided.as_mut() {
                    paths[wraps] = path;
                    switching[wraps * WRAP_SWITCHES..(wraps + 1) * WRAP_SWITCHES].copy_from_slice(&functions);
                }
                wraps += 1;
                match wrapped {
                    Some((arc, first, second)) => {
                        let on_geom = |at: Vec3<S>| PathPoint { link: frame.link, body: *body, at };
                        let points = [start, on_geom(first), on_geom(second), end];
                        length += ((first - start.at).norm() + arc + (end.at - second).norm()) / divisor;
                        for pair in points.windows(2) {
                            segment(&pair[0], &pair[1], divisor);
                        }
                    }
                    None => {
                        length += (end.at - start.at).norm() / divisor;
                        segment(&start, &end, divisor);
                    }
                }
                j += 2;
            }
            next => {
                let end = site_point(next);
                length += (end.at - start.at).norm() / divisor;
                segment(&start, &end, divisor);
                j += 1;
            }
        }
    }
    length
}

/// Adds the tendons' springs and dampers to the passive joint forces,
/// τ += Jᵀ(−k·x − b·L̇), x the length's distance beyond the spring's
/// deadband (MuJoCo's `mj_springdamper`).
pub(crate) fn add_passive_forces<S: Real>(model: &Model, ws: &mut Workspace<S>) {
    let nv = model.nv;
    for (k, tendon) in model.tendons.iter().enumerate() {
        if !tendon.has_passive_force() {
            continue;
        }
        let force = passive_force(tendon, ws.tendon_length[k], ws.tendon_velocity[k]);
        if !force.is_still_zero() {
            for d in 0..nv {
                ws.tau_passive[d] += ws.tendon_moment[k * nv + d] * force;
            }
        }
    }
}

/// A tendon's spring and damper force −(k·x + b·L̇), x the length's
/// distance beyond the spring's deadband.
fn passive_force<S: Real>(tendon: &Tendon, length: S, velocity: S) -> S {
    let [lower, upper] = tendon.spring_length;
    let stretch = if length.value() > upper {
        length - upper
    } else if length.value() < lower {
        length - lower
    } else {
        S::zero()
    };
    -stretch * tendon.stiffness - velocity * tendon.damping
}
