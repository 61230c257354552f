//! A dense O(N³) route to the same ν̇, the way one would compute it from
//! the mass matrix — the scaling plot's other line, and a check of nudyn's
//! ν̇ at sizes the tests do not reach:
//!
//! 1. M by the composite-rigid-body algorithm (O(N·depth)),
//! 2. its upper factor m (M = m mᵀ) by a dense Cholesky of the flipped
//!    matrix (O(N³)), θ̇ = m⁻ᵀν,
//! 3. the bias forces h(θ, θ̇) by recursive Newton–Euler, θ̈ = −M⁻¹h,
//! 4. Ṁ by a central difference along the motion, ṁ = m Φ(m⁻¹ Ṁ m⁻ᵀ)
//!    (Φ: upper triangle, diagonal halved; O(N³)),
//! 5. ν̇ = mᵀθ̈ + ṁᵀθ̇.
//!
//! Applied forces: ε = 0; springs and dampers of hinges and slides, and
//! gravity. It allocates freely: it is a reference, not a hot path.

use anyhow::{Result, bail};
use nalgebra::{DMatrix, DVector};
use nudyn::math::{SpatialMat, SpatialVec, cross_force, cross_motion, spatial};
use nudyn::model::{LinkJoint, Model};
use nudyn::workspace::Workspace;

/// Checks that the dense path covers the model's forces.
pub fn check_supported(model: &Model) -> Result<()> {
    for link in &model.links {
        if matches!(link.joint, LinkJoint::Ball | LinkJoint::Translation)
            && (link.stiffness != 0.0 || link.damping != 0.0)
        {
            bail!("the dense path has no springs or dampers on ball and free joints (joint '{}')", link.joint_name);
        }
    }
    Ok(())
}

/// M(θ) by the composite-rigid-body algorithm, with `ws` at configuration θ.
fn mass_matrix(model: &Model, ws: &Workspace) -> DMatrix<f64> {
    let n = model.links.len();
    let mut composite: Vec<SpatialMat> = model.links.iter().map(|l| l.spatial_inertia()).collect();
    for i in (0..n).rev() {
        if let Some(p) = model.links[i].parent {
            // Parents precede their children in the link order (p < i).
            let (parents, children) = composite.split_at_mut(i);
            ws.x_parent[i].add_inertia_to_parent(&children[0], &mut parents[p], false);
        }
    }
    let mut m = DMatrix::zeros(model.nv, model.nv);
    for (i, link) in model.links.iter().enumerate() {
        for col in 0..link.ndof {
            let mut force: SpatialVec = composite[i] * link.motion_subspace.column(col);
            let mut j = i;
            loop {
                let lj = &model.links[j];
                for row in 0..lj.ndof {
                    let value = lj.motion_subspace.column(row).dot(&force);
                    m[(lj.dof_adr + row, link.dof_adr + col)] = value;
                    m[(link.dof_adr + col, lj.dof_adr + row)] = value;
                }
                match lj.parent {
                    Some(p) => {
                        force = ws.x_parent[j].apply_transpose_force(&force);
                        j = p;
                    }
                    None => break,
                }
            }
        }
        for k in 0..link.ndof {
            m[(link.dof_adr + k, link.dof_adr + k)] += link.armature;
        }
    }
    m
}

/// h(θ, θ̇): the joint forces that keep θ̈ = 0 against velocity products,
/// gravity, springs and dampers (recursive Newton–Euler).
fn bias_forces(model: &Model, ws: &Workspace, theta: &[f64], qvel: &[f64]) -> DVector<f64> {
    let n = model.links.len();
    let mut velocity = vec![SpatialVec::zeros(); n];
    let mut force = vec![SpatialVec::zeros(); n];
    let mut acceleration = vec![SpatialVec::zeros(); n];
    // Gravity as an upward acceleration of the world.
    let world = spatial(&nalgebra::Vector3::zeros(), &-model.gravity);
    for (i, link) in model.links.iter().enumerate() {
        let v_joint: SpatialVec = (0..link.ndof).map(|k| link.motion_subspace.column(k) * qvel[link.dof_adr + k]).sum();
        let (v_parent, a_parent) = match link.parent {
            Some(p) => (velocity[p], acceleration[p]),
            None => (SpatialVec::zeros(), world),
        };
        let x = &ws.x_parent[i];
        velocity[i] = x.apply_motion(&v_parent) + v_joint;
        acceleration[i] = x.apply_motion(&a_parent) + cross_motion(&velocity[i], &v_joint);
        force[i] = link.inertia_times(&acceleration[i]) + cross_force(&velocity[i], &link.inertia_times(&velocity[i]));
    }
    let mut h = DVector::zeros(model.nv);
    for i in (0..n).rev() {
        let link = &model.links[i];
        for k in 0..link.ndof {
            h[link.dof_adr + k] = link.motion_subspace.column(k).dot(&force[i]);
        }
        if matches!(link.joint, LinkJoint::Hinge | LinkJoint::Slide) {
            let spring = theta[link.qpos_adr] - model.qpos_spring[link.qpos_adr];
            h[link.dof_adr] += link.stiffness * spring + link.damping * qvel[link.dof_adr];
        }
        if let Some(p) = link.parent {
            let to_parent = ws.x_parent[i].apply_transpose_force(&force[i]);
            force[p] += to_parent;
        }
    }
    h
}

/// The upper-triangular m with m mᵀ = M and a positive diagonal: the lower
/// Cholesky factor of M with rows and columns reversed, reversed back.
fn upper_factor(m: &DMatrix<f64>) -> Result<DMatrix<f64>> {
    let n = m.nrows();
    let flipped = DMatrix::from_fn(n, n, |i, j| m[(n - 1 - i, n - 1 - j)]);
    let Some(cholesky) = flipped.cholesky() else { bail!("M is not positive definite") };
    let lower = cholesky.l();
    Ok(DMatrix::from_fn(n, n, |i, j| lower[(n - 1 - i, n - 1 - j)]))
}

/// ν̇ at (θ, ν) with ε = 0, by the dense route of the module docs.
pub fn nu_dot(model: &Model, ws: &mut Workspace, theta: &[f64], nu: &[f64]) -> Result<DVector<f64>> {
    ws.set_configuration(model, theta)?;
    let theta = ws.theta.as_slice().to_vec();
    let mass = mass_matrix(model, ws);
    let m = upper_factor(&mass)?;
    let Some(qvel) = m.transpose().solve_lower_triangular(&DVector::from_column_slice(nu)) else {
        bail!("m is singular")
    };
    let h = bias_forces(model, ws, &theta, qvel.as_slice());
    // θ̈ = −M⁻¹h = −m⁻ᵀ m⁻¹ h.
    let Some(qacc) = m.solve_upper_triangular(&-h).and_then(|y| m.transpose().solve_lower_triangular(&y)) else {
        bail!("m is singular")
    };

    // Ṁ by a central difference along θ(s) = θ ⊕ s θ̇; the step makes
    // s|θ̇| about 1e-5, where truncation (s²) and rounding (ε/s) balance.
    let step = 1e-5 / qvel.amax().max(1e-300);
    let mass_at = |ws: &mut Workspace, s: f64| -> Result<DMatrix<f64>> {
        let mut moved = theta.clone();
        let delta: Vec<f64> = qvel.iter().map(|v| s * v).collect();
        nudyn::integrate::retract(model, &mut moved, &delta);
        ws.set_configuration(model, &moved)?;
        Ok(mass_matrix(model, ws))
    };
    let mass_dot = (mass_at(ws, step)? - mass_at(ws, -step)?) / (2.0 * step);
    // m⁻¹ Ṁ m⁻ᵀ, then Φ, then ṁ = m Φ(·).
    let Some(left) = m.solve_upper_triangular(&mass_dot) else { bail!("m is singular") };
    let Some(both) = m.solve_upper_triangular(&left.transpose()) else { bail!("m is singular") };
    let mut phi = both.upper_triangle();
    phi.set_diagonal(&(both.diagonal() * 0.5));
    let m_dot = &m * phi;
    Ok(m.transpose() * qacc + m_dot.transpose() * qvel)
}
