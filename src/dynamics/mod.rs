//! The O(N) passes of the diagonalized dynamics (docs/DYNAMICS.md §4–§5) and
//! the operators built from them.
//!
//! | pass | direction | input | fills |
//! |---|---|---|---|
//! | 0 [`kinematics`] | within pass 1; world placements base → tip | θ | link transforms |
//! | 1 [`articulated`] | tip → base | θ | I^a, R = D^½, G |
//! | 2 [`velocity`] | base → tip | ν or θ̇ | V, θ̇ = ℓ*ν or ν = m*θ̇ |
//! | 3 [`bias`] | tip → base | ε | ν̇, C(θ,ν), ε of passive forces and gravity (or without the factor's rates, only what θ̈ needs) |
//!
//! [`forces`] maps physical joint torques and body wrenches to ε and back;
//! `gravity_compensation` gives MuJoCo's `qfrc_gravcomp` with the configuration;
//! [`actuation`] computes the actuators' forces and their ε;
//! [`acceleration`] gives θ̈ and the links' accelerations after pass 3;
//! [`sensors`] evaluates MuJoCo's sensors, `interaction` the bodies'
//! interaction forces that its force and torque sensors read;
//! [`quantities`] gives kinetic energy, power and momentum; [`subspace`]
//! the shapes of the links' motion subspaces that the passes specialize on;
//! [`derivatives`] runs the passes in dual numbers for exact derivatives.

pub mod acceleration;
pub mod actuation;
pub mod articulated;
pub mod bias;
pub mod box_qp;
mod configuration_tangent;
pub mod constraint;
pub mod derivatives;
mod equality;
pub mod flexible;
pub mod forces;
mod gravity_compensation;
mod interaction;
pub mod kinematics;
pub mod mode;
mod noslip;
pub mod qacc_jacobian;
pub mod quantities;
pub mod sensors;
pub mod subspace;
pub mod tendon;
mod tendon_inertia;
pub mod velocity;
mod wrap;

pub use tendon_inertia::TendonInertiaState;
pub use wrap::WrapPath;

use nalgebra::SMatrix;

use crate::math::Real;
use crate::model::Model;
use crate::workspace::{Stage, Workspace};

/// Why a dynamics call could not be evaluated.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DynamicsError {
    /// A vector has the wrong length.
    #[error("{what} has {found} entries, expected {expected}")]
    Length {
        /// Which vector.
        what: &'static str,
        /// Its required length.
        expected: usize,
        /// Its actual length.
        found: usize,
    },
    /// An input entry is NaN or infinite. The message numbers entries from
    /// 1, as the FMU's variables are named (`nu[1]` is entry 0).
    #[error("{what}[{}] is not finite ({value})", index + 1)]
    NonFinite {
        /// Which vector.
        what: &'static str,
        /// 0-based index of the entry.
        index: usize,
        /// The entry.
        value: f64,
    },
    /// A quaternion in θ has zero norm (the message numbers from 1, as the FMU's variables).
    #[error("theta[{}] to theta[{}] are a zero quaternion (joint '{joint}')", qpos_adr + 1, qpos_adr + 4)]
    ZeroQuaternion {
        /// Joint name.
        joint: String,
        /// First qpos entry of the quaternion.
        qpos_adr: usize,
    },
    /// The articulated inertia seen by a link's joint is not positive definite.
    #[error("articulated inertia of link {link} is not positive definite")]
    Singular {
        /// Link index.
        link: usize,
    },
    /// A Rosenbrock step's linear system has no unique solution at this step size.
    #[error("the implicit step's linear system (I/(hγ) − J) is singular at step {step:e} s")]
    SingularStep {
        /// The step size (s).
        step: f64,
    },
    /// The constraint forces' problem could not be solved (its matrix lost
    /// positive definiteness to overflow, or the working sets cycled).
    #[error("the constraint forces of {rows} active rows could not be solved for")]
    ConstraintSolver {
        /// Active constraint rows.
        rows: usize,
    },
    /// The mass matrix with the tendons' armature is singular (MuJoCo adds
    /// that armature only within the tree's sparsity, which need not keep
    /// the matrix positive definite).
    #[error("the mass matrix with the armature of {tendons} is singular (MuJoCo adds it only where M has entries)")]
    TendonInertia {
        /// The tendons with armature, named as in the MJCF ("tendon 3"
        /// when unnamed, numbered from 0 as MuJoCo's ids).
        tendons: String,
    },
    /// A pass was called before the passes it depends on.
    #[error("{call} needs {needed:?} computed first")]
    OutOfOrder {
        /// The call.
        call: &'static str,
        /// The stage it needs.
        needed: Stage,
    },
}

/// Checks a vector's length.
/// Unit tests' vehicle: `file` (relative to the crate's root) compiled, and
/// a workspace configured at θ_k = qpos0_k + `spread`·sin k, away from the
/// file pose.
#[cfg(test)]
pub(crate) fn test_vehicle(file: &str, spread: f64) -> (Model, Workspace) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
    let model = Model::compile(&crate::mjcf::load_mjcf(&path).unwrap().vehicle).unwrap();
    let mut ws = model.workspace();
    let theta: Vec<f64> = model.qpos0.iter().enumerate().map(|(k, q)| q + spread * (k as f64).sin()).collect();
    ws.set_configuration(&model, &theta).unwrap();
    (model, ws)
}

pub(crate) fn check_length(what: &'static str, values: &[f64], expected: usize) -> Result<(), DynamicsError> {
    if values.len() != expected {
        return Err(DynamicsError::Length { what, expected, found: values.len() });
    }
    Ok(())
}

/// Checks a vector's length and that all its entries are finite.
pub(crate) fn check_input(what: &'static str, values: &[f64], expected: usize) -> Result<(), DynamicsError> {
    check_length(what, values, expected)?;
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(DynamicsError::NonFinite { what, index, value: values[index] }),
        None => Ok(()),
    }
}

/// Checks that the workspace has reached `needed`.
pub(crate) fn require<S: Real>(ws: &Workspace<S>, needed: Stage, call: &'static str) -> Result<(), DynamicsError> {
    if ws.stage < needed {
        return Err(DynamicsError::OutOfOrder { call, needed });
    }
    Ok(())
}

/// Adds a child's term to its parent's slot in an inward pass, or sets the
/// slot if this child is the first the pass reaches (`Accumulation::opens_parent`).
#[inline(always)]
pub(crate) fn accumulate<T: std::ops::AddAssign>(slot: &mut T, value: T, opens_parent: bool) {
    if opens_parent {
        *slot = value;
    } else {
        *slot += value;
    }
}

/// An N×N block of a padded 3×3 matrix.
#[inline(always)]
pub(crate) fn block<S: Real, const N: usize>(m: &nalgebra::Matrix3<S>) -> SMatrix<S, N, N> {
    crate::math::owned(m.fixed_view::<N, N>(0, 0))
}

/// The first N columns of a padded 6×3 matrix.
#[inline(always)]
pub(crate) fn cols<S: Real, const N: usize>(m: &SMatrix<S, 6, 3>) -> SMatrix<S, 6, N> {
    crate::math::owned(m.fixed_columns::<N>(0))
}

/// All passes for one state: ν̇ = ε − C(θ,ν) + ε_passive, in O(N),
/// without actuators or constraint forces (`Workspace::compute_nu_dot_actuated`
/// applies both).
///
/// After it returns, the workspace holds θ̇ (`qvel`), `nu_dot`, `coriolis`
/// and `eps_passive`.
pub fn forward(model: &Model, ws: &mut Workspace, theta: &[f64], nu: &[f64], eps: &[f64]) -> Result<(), DynamicsError> {
    ws.set_configuration(model, theta)?;
    ws.set_nu(model, nu)?;
    ws.compute_nu_dot(model, eps)
}

impl Workspace {
    /// Passes 0 and 1 for configuration `theta` (nq; quaternions are
    /// normalized, as MuJoCo does).
    pub fn set_configuration(&mut self, model: &Model, theta: &[f64]) -> Result<(), DynamicsError> {
        check_input("theta", theta, model.nq)?;
        self.stage = Stage::Empty;
        self.theta.copy_from_slice(theta);
        self.configuration_passes(model)?;
        if !model.tendons.is_empty() {
            self.tendon_kinematics(model);
        }
        if !model.tendon_inertia.is_empty() {
            self.tendon_inertia_configuration(model)?;
        }
        self.stage = Stage::Configuration;
        Ok(())
    }

    /// Pass 2 from ν (nv): velocities and θ̇ = ℓ*(θ) ν.
    pub fn set_nu(&mut self, model: &Model, nu: &[f64]) -> Result<(), DynamicsError> {
        require(self, Stage::Configuration, "set_nu")?;
        check_input("nu", nu, model.nv)?;
        self.nu.copy_from_slice(nu);
        velocity::velocity_pass(model, self, velocity::Given::Nu);
        if !model.tendons.is_empty() {
            self.tendon_velocities(model);
        }
        self.stage = Stage::Velocity;
        Ok(())
    }

    /// Pass 2 from θ̇ (nv, MuJoCo's qvel): velocities and ν = m*(θ) θ̇.
    pub fn set_qvel(&mut self, model: &Model, qvel: &[f64]) -> Result<(), DynamicsError> {
        require(self, Stage::Configuration, "set_qvel")?;
        check_input("qvel", qvel, model.nv)?;
        self.qvel.copy_from_slice(qvel);
        velocity::velocity_pass(model, self, velocity::Given::Qvel);
        if !model.tendons.is_empty() {
            self.tendon_velocities(model);
        }
        self.stage = Stage::Velocity;
        Ok(())
    }

    /// The actuators' activation states (na, MuJoCo's act), which their
    /// forces read; they stay until set again. Keeps the passes up to the
    /// velocities.
    pub fn set_act(&mut self, model: &Model, act: &[f64]) -> Result<(), DynamicsError> {
        check_input("act", act, model.activation_count())?;
        self.act.copy_from_slice(act);
        if self.stage > Stage::Velocity {
            self.stage = Stage::Velocity;
        }
        self.inputs_applied = false;
        Ok(())
    }

    /// Pass 3: ν̇ = ε − C(θ,ν) + ε_passive for applied `eps` (nv).
    pub fn compute_nu_dot(&mut self, model: &Model, eps: &[f64]) -> Result<(), DynamicsError> {
        require(self, Stage::Velocity, "compute_nu_dot")?;
        check_input("eps", eps, model.nv)?;
        bias::bias_pass::<true>(model, self, eps);
        self.stage = Stage::Acceleration;
        self.inputs_applied = false;
        Ok(())
    }

    /// θ̈ (`qacc`) for applied `eps` (nv) without ν̇: pass 3 without the
    /// factor's rates, then the outward pass of [`acceleration`]. The
    /// articulated-body algorithm's cost; ν̇ and C stay unset.
    pub fn compute_qacc(&mut self, model: &Model, eps: &[f64]) -> Result<(), DynamicsError> {
        require(self, Stage::Velocity, "compute_qacc")?;
        check_input("eps", eps, model.nv)?;
        bias::bias_pass::<false>(model, self, eps);
        self.stage = Stage::JointRates;
        self.inputs_applied = false;
        self.compute_accelerations(model)
    }
}

impl<S: Real> Workspace<S> {
    /// Passes 0 and 1, and what the configuration alone gives of the tree
    /// (world placements, gravity compensation), for `self.theta`; the
    /// tendons' kinematics are the caller's.
    pub(crate) fn configuration_passes(&mut self, model: &Model) -> Result<(), DynamicsError> {
        self.world_transforms_current = false;
        articulated::articulated_pass(model, self)?;
        if !model.shortcuts.no_gravity {
            kinematics::world_transforms_pass(model, self);
        }
        if !model.gravity_compensation.is_empty() {
            gravity_compensation::gravity_compensation_pass(model, self);
        }
        Ok(())
    }
}
