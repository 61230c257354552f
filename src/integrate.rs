//! Explicit Runge–Kutta–Munthe-Kaas integration of (θ, ν) (DYNAMICS.md §6).
//!
//! Each step writes the configuration as θ = θₙ ⊕ Δ, where Δ (nv) is a
//! displacement in the Lie algebra: Δθ for hinges and slides, Δp for the
//! translation of a free joint, and a body-frame rotation vector Θ for ball
//! and free-joint rotations (q = qₙ · exp(Θ)). Δ obeys an ordinary ODE,
//!     Δ̇ = dexp⁻¹₋Θ(θ̇) = θ̇ + ½ Θ×ω + c(|Θ|) Θ×(Θ×ω)   on rotations,
//! so any Runge–Kutta tableau applied to (Δ, ν) keeps its order on every
//! joint type. No crate offers this on a product of vector spaces and unit
//! quaternions, hence this module.

use nalgebra::DVector;

use crate::dynamics::DynamicsError;
use crate::math::{Quat, Vec3, quat_from_wxyz, quat_to_wxyz};
use crate::model::{LinkJoint, Model};
use crate::workspace::Workspace;

/// A Butcher tableau of an explicit Runge–Kutta method.
#[derive(Clone, Copy, Debug)]
pub struct Tableau {
    /// Strictly lower-triangular stage coefficients, row i has i entries.
    pub a: &'static [&'static [f64]],
    /// Weights.
    pub b: &'static [f64],
    /// Nodes.
    pub c: &'static [f64],
}

/// The classical 4th-order Runge–Kutta method.
pub const RK4: Tableau = Tableau {
    a: &[&[], &[0.5], &[0.0, 0.5], &[0.0, 0.0, 1.0]],
    b: &[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
    c: &[0.0, 0.5, 0.5, 1.0],
};

/// θₙ ⊕ Δ: moves `theta` (nq) by the algebra displacement `delta` (nv), in place.
pub fn retract(model: &Model, theta: &mut [f64], delta: &[f64]) {
    for link in &model.links {
        let (q, d) = (&mut theta[link.qpos_adr..], &delta[link.dof_adr..]);
        match link.joint {
            LinkJoint::Hinge | LinkJoint::Slide => q[0] += d[0],
            LinkJoint::Translation => (0..3).for_each(|k| q[k] += d[k]),
            LinkJoint::Ball => {
                let rotated = Quat::from_quaternion(quat_from_wxyz(q)) * Quat::from_scaled_axis(Vec3::new(d[0], d[1], d[2]));
                quat_to_wxyz(&rotated, q);
            }
        }
    }
}

/// dexp⁻¹₋Θ(ω): the rate of the body-frame rotation vector Θ of q = qₙ·exp(Θ)
/// when the body-frame angular velocity is ω.
fn dexp_inv(theta: &Vec3, omega: &Vec3) -> Vec3 {
    let angle2 = theta.norm_squared();
    // c = (1 − (a/2)cot(a/2))/a², by its series near 0 where the closed form cancels.
    let c = if angle2 < 1e-6 {
        1.0 / 12.0 + angle2 / 720.0
    } else {
        let a = angle2.sqrt();
        (1.0 - 0.5 * a / (0.5 * a).tan()) / angle2
    };
    let cross = theta.cross(omega);
    omega + 0.5 * cross + c * theta.cross(&cross)
}

/// Preallocated stage storage for one integrator instance.
#[derive(Clone, Debug)]
pub struct Integrator {
    tableau: Tableau,
    /// Δ-rates of the stages.
    k_delta: Vec<DVector<f64>>,
    /// ν-rates of the stages.
    k_nu: Vec<DVector<f64>>,
    delta: DVector<f64>,
    nu_stage: DVector<f64>,
    theta_stage: DVector<f64>,
    eps_stage: DVector<f64>,
}

impl Integrator {
    /// An integrator with `tableau`, sized for `model`.
    pub fn new(model: &Model, tableau: Tableau) -> Self {
        let stages = tableau.b.len();
        Integrator {
            tableau,
            k_delta: vec![DVector::zeros(model.nv); stages],
            k_nu: vec![DVector::zeros(model.nv); stages],
            delta: DVector::zeros(model.nv),
            nu_stage: DVector::zeros(model.nv),
            theta_stage: DVector::zeros(model.nq),
            eps_stage: DVector::zeros(model.nv),
        }
    }

    /// One step of size `h` from time `t`: advances `theta` (nq) and `nu`
    /// (nv) in place. `eps_at(t, out)` writes the applied ε at time t.
    /// On error, `theta` and `nu` are unchanged.
    pub fn step(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        theta: &mut [f64],
        nu: &mut [f64],
        t: f64,
        h: f64,
        mut eps_at: impl FnMut(f64, &mut [f64]),
    ) -> Result<(), DynamicsError> {
        let tableau = self.tableau;
        for (i, row) in tableau.a.iter().enumerate() {
            self.delta.fill(0.0);
            self.nu_stage.copy_from_slice(nu);
            for (j, a) in row.iter().enumerate() {
                if *a != 0.0 {
                    self.delta.axpy(h * a, &self.k_delta[j], 1.0);
                    self.nu_stage.axpy(h * a, &self.k_nu[j], 1.0);
                }
            }
            self.theta_stage.copy_from_slice(theta);
            retract(model, self.theta_stage.as_mut_slice(), self.delta.as_slice());
            eps_at(t + tableau.c[i] * h, self.eps_stage.as_mut_slice());
            ws.set_configuration(model, self.theta_stage.as_slice())?;
            ws.set_nu(model, self.nu_stage.as_slice())?;
            ws.compute_nu_dot(model, self.eps_stage.as_slice())?;
            self.k_nu[i].copy_from(&ws.nu_dot);
            self.k_delta[i].copy_from(&ws.qvel);
            for link in model.links.iter().filter(|l| l.joint == LinkJoint::Ball) {
                let a = link.dof_adr;
                let rotation = Vec3::new(self.delta[a], self.delta[a + 1], self.delta[a + 2]);
                let omega = Vec3::new(ws.qvel[a], ws.qvel[a + 1], ws.qvel[a + 2]);
                self.k_delta[i].fixed_rows_mut::<3>(a).copy_from(&dexp_inv(&rotation, &omega));
            }
        }
        self.delta.fill(0.0);
        self.nu_stage.copy_from_slice(nu);
        for (i, b) in tableau.b.iter().enumerate() {
            self.delta.axpy(h * b, &self.k_delta[i], 1.0);
            self.nu_stage.axpy(h * b, &self.k_nu[i], 1.0);
        }
        let update = self.nu_stage.iter().chain(self.delta.iter());
        if let Some((index, &value)) = update.enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(DynamicsError::NonFinite { what: "integrated state", index, value });
        }
        retract(model, theta, self.delta.as_slice());
        nu.copy_from_slice(self.nu_stage.as_slice());
        Ok(())
    }
}
