//! Passes 0 and 1 in dual numbers from their `f64` values: the link
//! placements and the factor at θ, with their derivatives along a
//! direction δ in θ's tangent space, by one sweep tip to base in `f64`
//! (docs/linearization.md, "The configuration's derivatives from its values").
//!
//! A derivative along δ is a rate along the velocity θ̇ = δ, and pass 3
//! already forms the factor's rates along θ̇ (bias.rs); the same formulas
//! with δ in place of θ̇ give the configuration's derivatives, each from
//! the values the `f64` passes left:
//!
//!   Ẋ = −(v_J×) X with v_J = S δ (the placement, in child coordinates),
//!   δI^A_i = Σ_children Xᵀ [δI^a_c + v_J ×* I^a_c − I^a_c v_J ×] X,
//!   δD = Sᵀ δI^A S,  δG = (δI^A S − G δD) D⁻¹,
//!   δR = R Φ(R⁻¹ δD R⁻ᵀ),  δR⁻¹ = −Φ(R⁻¹ δD R⁻ᵀ) R⁻¹,
//!   δI^a = δI^A − G A′ᵀ − A′ Gᵀ with A′ = δI^A S − ½ G δD,
//!
//! and the world placements' rates from the links' velocities along δ,
//! V_i = X V_λ + S δ_i, outward. Run in dual numbers instead, passes 0 and 1
//! recompute every value and carry each product's derivative in three
//! products: this sweep costs about a third of theirs (the congruence is
//! the `f64` one, on the derivatives alone). Vehicles with flexible bodies
//! keep the dual passes (their modal blocks have no such sweep).

use nalgebra::{SMatrix, SVector};
use num_dual::Dual64;

use super::bias::upper_half;
use super::subspace::{GENERAL, Subspace, mul_cross_s_times, s_times, s_transpose_times_columns, times_s};
use super::{block, cols};
use crate::math::{SpatialMat, SpatialVec, Transform, angular, linear, skew};
use crate::model::{LinkJoint, Model};
use crate::workspace::Workspace;

/// The sweep's buffers: built once per model, so that a run allocates nothing.
#[derive(Clone, Debug)]
pub(crate) struct ConfigurationTangent {
    /// δ in the tangent space (nv).
    tangent: Vec<f64>,
    /// Each link's δI^A, gathered from its children.
    ia_rate: Vec<SpatialMat>,
    /// Each link's velocity along δ, for the world placements' rates.
    velocity: Vec<SpatialVec>,
}

impl ConfigurationTangent {
    pub(crate) fn new(model: &Model) -> Self {
        let links = model.links.len();
        ConfigurationTangent {
            tangent: vec![0.0; model.nv],
            ia_rate: vec![SpatialMat::zeros(); links],
            velocity: vec![SpatialVec::zeros(); links],
        }
    }

    /// Whether the sweep covers `model` (no flexible bodies).
    pub(crate) fn covers(model: &Model) -> bool {
        model.flexible.is_empty()
    }

    /// Fills `ws`'s θ, placements and factor (and world placements where
    /// `values` has them) with the values of `values`, whose configuration
    /// passes ran at `theta` (nq, as given: quaternions need not be of unit
    /// length), and their derivatives along `theta_rates` (θ's rate in its
    /// own coordinates, nq).
    pub(crate) fn fill(
        &mut self,
        model: &Model,
        values: &Workspace,
        theta: &[f64],
        theta_rates: &[f64],
        ws: &mut Workspace<Dual64>,
    ) {
        self.theta_and_tangent(model, values, theta, theta_rates, ws);
        for i in (0..model.links.len()).rev() {
            // The passes' instances per subspace shape (`by_subspace!`, whose
            // first parameter is the scalar, which here is always `f64`).
            match values.subspaces[i] {
                Subspace::AboutX => factor_link_rate::<1, 0>(model, values, self, ws, i),
                Subspace::AboutY => factor_link_rate::<1, 1>(model, values, self, ws, i),
                Subspace::AboutZ => factor_link_rate::<1, 2>(model, values, self, ws, i),
                Subspace::Rotation => factor_link_rate::<3, 0>(model, values, self, ws, i),
                Subspace::Translation => factor_link_rate::<3, 3>(model, values, self, ws, i),
                Subspace::General1 => factor_link_rate::<1, GENERAL>(model, values, self, ws, i),
                Subspace::General3 => factor_link_rate::<3, GENERAL>(model, values, self, ws, i),
            }
        }
        ws.world_transforms_current = values.world_transforms_current;
        if values.world_transforms_current {
            self.world_placement_rates(model, values, ws);
        }
    }

    /// θ in `ws` (the values' normalized quaternions, with the normalized
    /// quaternion's rate (ṙ − q̂ (q̂·ṙ)) / |q| as the dual passes have it),
    /// and δ: a ball's rotation vector 2 vec(q̂* ⊗ dq̂) in the body frame.
    fn theta_and_tangent(
        &mut self,
        model: &Model,
        values: &Workspace,
        theta: &[f64],
        theta_rates: &[f64],
        ws: &mut Workspace<Dual64>,
    ) {
        for link in &model.links {
            let (q, d) = (link.qpos_adr, link.dof_adr);
            match link.joint {
                LinkJoint::Hinge | LinkJoint::Slide | LinkJoint::Translation => {
                    for k in 0..link.ndof {
                        ws.theta[q + k] = Dual64::new(values.theta[q + k], theta_rates[q + k]);
                        self.tangent[d + k] = theta_rates[q + k];
                    }
                }
                LinkJoint::Ball => {
                    let unit: [f64; 4] = std::array::from_fn(|k| values.theta[q + k]);
                    let rate: [f64; 4] = std::array::from_fn(|k| theta_rates[q + k]);
                    let norm = theta[q..q + 4].iter().map(|c| c * c).sum::<f64>().sqrt();
                    let along = (0..4).map(|k| unit[k] * rate[k]).sum::<f64>();
                    let unit_rate: [f64; 4] = std::array::from_fn(|k| (rate[k] - unit[k] * along) / norm);
                    for k in 0..4 {
                        ws.theta[q + k] = Dual64::new(unit[k], unit_rate[k]);
                    }
                    // vec(q̂* ⊗ dq̂) for q̂ = (w, v), dq̂ = (ẇ, v̇): w v̇ − ẇ v − v × v̇.
                    let ([w, x, y, z], [dw, dx, dy, dz]) = (unit, unit_rate);
                    self.tangent[d] = 2.0 * (w * dx - dw * x - (y * dz - z * dy));
                    self.tangent[d + 1] = 2.0 * (w * dy - dw * y - (z * dx - x * dz));
                    self.tangent[d + 2] = 2.0 * (w * dz - dw * z - (x * dy - y * dx));
                }
            }
        }
    }

    /// ⁱX₀'s rates, −(V_i×) ⁱX₀, from the links' velocities along δ, base to tip.
    fn world_placement_rates(&mut self, model: &Model, values: &Workspace, ws: &mut Workspace<Dual64>) {
        for (i, link) in model.links.iter().enumerate() {
            let joint = joint_velocity(&link.motion_subspace, &self.tangent[link.dof_adr..], link.ndof);
            let velocity = match link.parent {
                Some(p) => values.x_parent[i].apply_motion(&self.velocity[p]) + joint,
                None => joint,
            };
            self.velocity[i] = velocity;
            ws.x_world[i] = moving(&values.x_world[i], &velocity);
        }
    }
}

/// S δ for a link of `ndof` dofs.
fn joint_velocity(s: &crate::model::MotionSubspace, tangent: &[f64], ndof: usize) -> SpatialVec {
    (0..ndof).fold(SpatialVec::zeros(), |v, k| v + s.column(k) * tangent[k])
}

/// The transform `x` with its rate −(v×) X for a child-frame velocity v:
/// Ė = −ω× E and ṙ = Eᵀ l for v = (ω, l).
fn moving(x: &Transform, v: &SpatialVec) -> Transform<Dual64> {
    let rot_rate = -(skew(&angular(v)) * x.rot);
    let trans_rate = x.rot.transpose() * linear(v);
    Transform { rot: x.rot.zip_map(&rot_rate, Dual64::new), trans: x.trans.zip_map(&trans_rate, Dual64::new) }
}

/// Values with their rates, entry by entry.
fn paired<const R: usize, const C: usize>(
    values: &SMatrix<f64, R, C>,
    rates: &SMatrix<f64, R, C>,
) -> SMatrix<Dual64, R, C> {
    values.zip_map(rates, Dual64::new)
}

/// An N×N block's rates padded to the 3×3 buffer the workspace keeps it in.
fn padded<const N: usize>(rates: &SMatrix<f64, N, N>) -> SMatrix<f64, 3, 3> {
    let mut out = SMatrix::<f64, 3, 3>::zeros();
    out.fixed_view_mut::<N, N>(0, 0).copy_from(rates);
    out
}

/// Pass 1's derivatives for link `i` of N dofs: its placement, R, R⁻¹, G
/// and I^a into `ws`, and its term of the parent's δI^A.
#[inline(always)]
fn factor_link_rate<const N: usize, const UNIT: usize>(
    model: &Model,
    values: &Workspace,
    sweep: &mut ConfigurationTangent,
    ws: &mut Workspace<Dual64>,
    i: usize,
) {
    let link = &model.links[i];
    let s = &link.motion_subspace;
    let delta: SVector<f64, N> = SVector::from_fn(|k, _| sweep.tangent[link.dof_adr + k]);
    let x = &values.x_parent[i];
    ws.x_parent[i] = moving(x, &s_times::<f64, N, UNIT>(s, &delta));

    // A link without children: its own inertia is constant in its frame.
    let ia_rate = if values.accumulation[i].gathers() { sweep.ia_rate[i] } else { SpatialMat::zeros() };
    let u_rate = times_s::<f64, N, UNIT>(&ia_rate, s);
    let d_rate = s_transpose_times_columns::<f64, N, UNIT>(s, &u_rate);
    let gain = cols::<f64, N>(&values.gain[i]);
    let (r, r_inv) = (block::<f64, N>(&values.r_joint[i]), block::<f64, N>(&values.r_inv_joint[i]));
    let turn = upper_half(&(r_inv * d_rate * r_inv.transpose()));
    let gain_rate = (u_rate - gain * d_rate) * (r_inv.transpose() * r_inv);
    let mut gain_rates = SMatrix::<f64, 6, 3>::zeros();
    gain_rates.fixed_columns_mut::<N>(0).copy_from(&gain_rate);
    ws.gain[i] = paired(&values.gain[i], &gain_rates);
    ws.r_joint[i] = paired(&values.r_joint[i], &padded(&(r * turn)));
    ws.r_inv_joint[i] = paired(&values.r_inv_joint[i], &padded(&-(turn * r_inv)));

    if let Some(p) = link.parent {
        let ia_reduced = &values.ia_reduced[i];
        let shifted = u_rate - gain * (d_rate * 0.5);
        let update = gain * shifted.transpose();
        let reduced_rate = ia_rate - update - update.transpose();
        ws.ia_reduced[i] = paired(ia_reduced, &reduced_rate);
        let turning = mul_cross_s_times::<f64, N, UNIT>(ia_reduced, s, &delta);
        let term = reduced_rate - turning - turning.transpose();
        x.add_inertia_to_parent(&term, &mut sweep.ia_rate[p], values.accumulation[i].opens_parent);
    }
}

#[cfg(test)]
mod tests {
    use num_dual::Dual64;

    use super::ConfigurationTangent;
    use crate::model::{LinkJoint, Model};
    use crate::workspace::Workspace;

    /// The largest differences of the entries' values and of their
    /// derivatives, each relative to the largest of its kind.
    fn differences<'a>(a: impl Iterator<Item = &'a Dual64>, b: impl Iterator<Item = &'a Dual64>) -> [f64; 2] {
        let (mut difference, mut scale) = ([0.0_f64; 2], [1e-300_f64; 2]);
        for (x, y) in a.zip(b) {
            for (k, (p, q)) in [(x.re, y.re), (x.eps, y.eps)].into_iter().enumerate() {
                difference[k] = difference[k].max((p - q).abs());
                scale[k] = scale[k].max(p.abs());
            }
        }
        [difference[0] / scale[0], difference[1] / scale[1]]
    }

    /// [`differences`] of the entries `entries` gives of each item of `a` and `b`.
    fn compare<'a, T, I: Iterator<Item = &'a Dual64>>(
        a: &'a [T],
        b: &'a [T],
        entries: impl Fn(&'a T) -> I + Copy,
    ) -> [f64; 2] {
        differences(a.iter().flat_map(entries), b.iter().flat_map(entries))
    }

    /// Every quantity of passes 0 and 1, filled from the `f64` values and
    /// the sweep, against the passes run in dual numbers, at a θ with
    /// quaternions off unit length, along directions in θ's coordinates
    /// (a quaternion's component along itself included) and in the tangent
    /// space as the derivatives turn them into coordinates.
    #[test]
    fn the_sweep_gives_the_dual_passes_derivatives() {
        for file in [
            "examples/bus_arm7.xml",
            "examples/servicer.xml",
            "examples/chain60.xml",
            "tests/fixtures/mjcf/joints.xml",
            "tests/fixtures/constraints/docked_servicer.xml",
            "tests/fixtures/gravcomp/arm_on_bus.xml",
            "tests/fixtures/sensors/every_sensor.xml",
        ] {
            let (model, _) = crate::dynamics::test_vehicle(file, 0.0);
            assert!(ConfigurationTangent::covers(&model), "{file}");
            let mut theta: Vec<f64> =
                model.qpos0.iter().enumerate().map(|(k, q)| q + 0.3 * (1.3 * k as f64).sin()).collect();
            for link in model.links.iter().filter(|l| l.joint == LinkJoint::Ball) {
                theta[link.qpos_adr..link.qpos_adr + 4].iter_mut().for_each(|c| *c *= 1.7);
            }
            let rates: Vec<f64> = (0..model.nq).map(|k| (0.37 * k as f64 + 0.2).cos()).collect();
            let (mut dual, mut filled) =
                (Workspace::<Dual64>::in_scalar(&model), Workspace::<Dual64>::in_scalar(&model));
            for (slot, (&q, &rate)) in dual.theta.iter_mut().zip(theta.iter().zip(&rates)) {
                *slot = Dual64::new(q, rate);
            }
            dual.configuration_passes(&model).unwrap();
            dual.world_transforms(&model);
            let mut values: Workspace = model.workspace();
            values.theta.copy_from_slice(&theta);
            values.configuration_passes(&model).unwrap();
            values.world_transforms(&model);
            let mut sweep = ConfigurationTangent::new(&model);
            sweep.fill(&model, &values, &theta, &rates, &mut filled);
            assert!(filled.world_transforms_current);
            let with_parent = |m: &Model, i: usize| m.links[i].parent.is_some();
            let differences = [
                ("theta", differences(dual.theta.iter(), filled.theta.iter())),
                ("x_parent rot", compare(&dual.x_parent, &filled.x_parent, |x| x.rot.iter())),
                ("x_parent trans", compare(&dual.x_parent, &filled.x_parent, |x| x.trans.iter())),
                ("x_world rot", compare(&dual.x_world, &filled.x_world, |x| x.rot.iter())),
                ("x_world trans", compare(&dual.x_world, &filled.x_world, |x| x.trans.iter())),
                (
                    "ia_reduced",
                    differences(
                        (0..model.links.len())
                            .filter(|&i| with_parent(&model, i))
                            .flat_map(|i| dual.ia_reduced[i].iter()),
                        (0..model.links.len())
                            .filter(|&i| with_parent(&model, i))
                            .flat_map(|i| filled.ia_reduced[i].iter()),
                    ),
                ),
                ("gain", compare(&dual.gain, &filled.gain, |g| g.iter())),
                ("r_joint", compare(&dual.r_joint, &filled.r_joint, |r| r.iter())),
                ("r_inv_joint", compare(&dual.r_inv_joint, &filled.r_inv_joint, |r| r.iter())),
            ];
            for (what, [value, rate]) in differences {
                assert!(value < 1e-13, "{file}: {what}'s values differ by {value:e} of the largest");
                assert!(rate < 1e-13, "{file}: {what}'s derivatives differ by {rate:e} of the largest");
            }
        }
    }
}
