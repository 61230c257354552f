//! Exact first derivatives of the dynamics, by forward mode: the passes,
//! generic over their scalar ([`Real`]), run in dual numbers
//! (num-dual's `Dual64`), each carrying its value and its derivative along
//! one direction of the inputs. One directional derivative costs one run
//! of the passes in duals; a Jacobian, one run per column. The result is
//! the derivative of the code itself, exact to round-off, with nothing to
//! tune (a finite difference trades truncation against cancellation).
//!
//! Directions in θ are given either in the tangent space (nv entries:
//! a ball joint's or free joint's rotation as a rotation vector in the
//! body frame, q ⊕ δ = q ⊗ exp(δ/2), as MuJoCo's `mj_integratePos`
//! moves it; a free joint's translation in world axes) or in θ's own
//! coordinates (nq entries, as an FMU's `theta[k]` variables are; a
//! quaternion's component along itself has no effect, the passes
//! normalizing it).
//!
//! The passes made generic so far are the tree's: placements, the
//! factorization, velocities, springs, dampers, gravity and its
//! compensation, ν̇, C and θ̈. A model whose dynamics need more
//! (actuators, tendons, constraint forces) is refused by
//! [`Derivatives::new`] with what is missing, rather than given a
//! derivative that leaves a term out.

use nalgebra::{DMatrix, Quaternion};
use num_dual::Dual64;

use super::velocity::{self, Given};
use super::{DynamicsError, bias, check_input, forces};
use crate::math::{Real, quat_from_wxyz};
use crate::model::{LinkJoint, Model};
use crate::workspace::{Stage, Workspace};

/// Why derivatives could not be given.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DerivativeError {
    /// The model has a part whose passes do not carry derivatives yet.
    #[error("derivatives do not cover {0} yet; this model has them")]
    Unsupported(&'static str),
    /// A direction has the wrong length.
    #[error("the direction of {what} has {found} entries, expected {expected}")]
    DirectionLength {
        /// Which input.
        what: &'static str,
        /// Its required length.
        expected: usize,
        /// Its actual length.
        found: usize,
    },
    /// The point is not a valid state.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
}

/// Where the derivatives are taken: θ (nq), the velocity (nv: ν or θ̇, as
/// `given` says), the applied ε and the physical joint forces T (MuJoCo's
/// qfrc_applied; each nv). The ε applied is ε + ℓ(θ)T.
#[derive(Clone, Copy, Debug)]
pub struct Point<'a> {
    /// θ (qpos).
    pub theta: &'a [f64],
    /// ν or θ̇.
    pub velocity: &'a [f64],
    /// Which of ν and θ̇ `velocity` is.
    pub given: Given,
    /// Applied ε.
    pub eps: &'a [f64],
    /// Physical joint forces T.
    pub torque: &'a [f64],
}

/// How a direction in θ is written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThetaDirection {
    /// nv entries in the tangent space (rotation vectors for quaternions).
    Tangent,
    /// nq entries along θ's coordinates.
    Coordinates,
}

/// A direction of the inputs of a [`Point`], entry for entry (θ's as
/// `theta_in` says).
#[derive(Clone, Copy, Debug)]
pub struct Direction<'a> {
    /// Along θ.
    pub theta: &'a [f64],
    /// How `theta` is written.
    pub theta_in: ThetaDirection,
    /// Along the given velocity (ν or θ̇).
    pub velocity: &'a [f64],
    /// Along ε.
    pub eps: &'a [f64],
    /// Along T.
    pub torque: &'a [f64],
}

/// The outputs whose derivatives a run gives, each nv long.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// θ̇ (MuJoCo's qvel; the given one's derivative is the direction's).
    Qvel,
    /// ν.
    Nu,
    /// ν̇.
    NuDot,
    /// θ̈ (MuJoCo's qacc).
    Qacc,
}

/// The Jacobians of one output at a point, one matrix per input: nv rows,
/// and nv columns for θ (tangent space), the velocity, ε and T.
#[derive(Clone, Debug, PartialEq)]
pub struct Jacobians {
    /// ∂/∂θ in the tangent space.
    pub theta: DMatrix<f64>,
    /// ∂/∂(the given velocity).
    pub velocity: DMatrix<f64>,
    /// ∂/∂ε.
    pub eps: DMatrix<f64>,
    /// ∂/∂T.
    pub torque: DMatrix<f64>,
}

/// A model's workspace in dual numbers and the inputs' buffers: built
/// once, so that derivatives allocate nothing but their results.
#[derive(Clone, Debug)]
pub struct Derivatives {
    ws: Workspace<Dual64>,
    eps: Vec<Dual64>,
    torque: Vec<Dual64>,
    eps_of_torque: Vec<Dual64>,
}

impl Derivatives {
    /// The buffers for `model`, or what the model has that derivatives do
    /// not cover yet.
    pub fn new(model: &Model) -> Result<Self, DerivativeError> {
        Self::check(model)?;
        let zeros = vec![Dual64::from(0.0); model.nv];
        Ok(Derivatives {
            ws: Workspace::in_scalar(model),
            eps: zeros.clone(),
            torque: zeros.clone(),
            eps_of_torque: zeros,
        })
    }

    /// Whether derivatives cover `model`, without building the buffers
    /// (an exporter's question): what [`Derivatives::new`] refuses.
    pub fn check(model: &Model) -> Result<(), DerivativeError> {
        let unsupported = [
            (!model.actuators.is_empty(), "actuators"),
            (!model.tendons.is_empty(), "tendons"),
            (!model.constraints.is_empty(), "constraint forces (limits, friction loss, equalities)"),
        ];
        match unsupported.iter().find(|(has, _)| *has) {
            Some((_, what)) => Err(DerivativeError::Unsupported(what)),
            None => Ok(()),
        }
    }

    /// Runs the passes at `point` along `direction`; [`Derivatives::derivative`]
    /// and [`Derivatives::value`] then read the outputs.
    pub fn run(&mut self, model: &Model, point: &Point, direction: &Direction) -> Result<(), DerivativeError> {
        check_input("theta", point.theta, model.nq)?;
        check_input(velocity_name(point.given), point.velocity, model.nv)?;
        check_input("eps", point.eps, model.nv)?;
        check_input("torque", point.torque, model.nv)?;
        let theta_length = match direction.theta_in {
            ThetaDirection::Tangent => model.nv,
            ThetaDirection::Coordinates => model.nq,
        };
        for (what, values, expected) in [
            ("theta", direction.theta, theta_length),
            (velocity_name(point.given), direction.velocity, model.nv),
            ("eps", direction.eps, model.nv),
            ("torque", direction.torque, model.nv),
        ] {
            if values.len() != expected {
                return Err(DerivativeError::DirectionLength { what, expected, found: values.len() });
            }
        }
        let ws = &mut self.ws;
        seed_theta(model, point.theta, direction, ws.theta.as_mut_slice())?;
        ws.stage = Stage::Empty;
        ws.configuration_passes(model)?;
        ws.stage = Stage::Configuration;
        let velocity = match point.given {
            Given::Nu => ws.nu.as_mut_slice(),
            Given::Qvel => ws.qvel.as_mut_slice(),
        };
        seed(velocity, point.velocity, direction.velocity);
        velocity::velocity_pass(model, ws, point.given);
        ws.stage = Stage::Velocity;
        seed(&mut self.torque, point.torque, direction.torque);
        forces::eps_of_torque(model, ws, &self.torque, &mut self.eps_of_torque);
        seed(&mut self.eps, point.eps, direction.eps);
        self.eps.iter_mut().zip(&self.eps_of_torque).for_each(|(e, t)| *e += *t);
        let passive = !model.shortcuts.no_passive_forces();
        if passive {
            bias::passive_forces(model, ws);
        }
        bias::link_sweep::<_, true>(model, ws, &self.eps, passive);
        ws.stage = Stage::Acceleration;
        ws.compute_accelerations(model)?;
        Ok(())
    }

    /// The derivative of `output` along the last run's direction.
    pub fn derivative(&self, output: Output) -> impl Iterator<Item = f64> + '_ {
        self.output(output).iter().map(|d| d.eps)
    }

    /// The value of `output` at the last run's point.
    pub fn value(&self, output: Output) -> impl Iterator<Item = f64> + '_ {
        self.output(output).iter().map(|d| d.re)
    }

    /// The derivative of d(θ[k])/dt ([`qpos_rate`]) along the last run's
    /// direction: θ's rate as the state derivative of model exchange.
    pub fn qpos_rate_derivative(&self, model: &Model, k: usize) -> f64 {
        qpos_rate(model, self.ws.theta.as_slice(), self.ws.qvel.as_slice(), k).eps
    }

    fn output(&self, output: Output) -> &[Dual64] {
        match output {
            Output::Qvel => self.ws.qvel.as_slice(),
            Output::Nu => self.ws.nu.as_slice(),
            Output::NuDot => self.ws.nu_dot.as_slice(),
            Output::Qacc => self.ws.qacc.as_slice(),
        }
    }

    /// The Jacobians of `output` at `point`: one run per column.
    pub fn jacobians(&mut self, model: &Model, point: &Point, output: Output) -> Result<Jacobians, DerivativeError> {
        let nv = model.nv;
        let zeros = vec![0.0; nv];
        let mut unit = vec![0.0; nv];
        let mut columns = |which: usize| -> Result<DMatrix<f64>, DerivativeError> {
            let mut jacobian = DMatrix::zeros(nv, nv);
            for column in 0..nv {
                unit[column] = 1.0;
                let along = |k: usize| if k == which { unit.as_slice() } else { zeros.as_slice() };
                let direction = Direction {
                    theta: along(0),
                    theta_in: ThetaDirection::Tangent,
                    velocity: along(1),
                    eps: along(2),
                    torque: along(3),
                };
                let run = self.run(model, point, &direction);
                unit[column] = 0.0;
                run?;
                for (row, d) in self.derivative(output).enumerate() {
                    jacobian[(row, column)] = d;
                }
            }
            Ok(jacobian)
        };
        Ok(Jacobians { theta: columns(0)?, velocity: columns(1)?, eps: columns(2)?, torque: columns(3)? })
    }
}

/// d(θ[k])/dt from the passes' θ (quaternions normalized) and θ̇: θ̇'s
/// entry for a hinge, slide or translation; q̇ = ½ q ⊗ (0, ω) for a
/// quaternion's entries (ω in the body frame), orthogonal to q. Generic,
/// so that run in dual numbers it carries its own derivative.
pub fn qpos_rate<S: Real>(model: &Model, theta: &[S], qvel: &[S], k: usize) -> S {
    let link = model.links.iter().rev().find(|l| l.qpos_adr <= k).expect("every coordinate belongs to a link");
    let (q, w) = (&theta[link.qpos_adr..], &qvel[link.dof_adr..]);
    let half = |x: S| x * 0.5;
    match (link.joint, k - link.qpos_adr) {
        (LinkJoint::Ball, 0) => -half(q[1] * w[0] + q[2] * w[1] + q[3] * w[2]),
        (LinkJoint::Ball, 1) => half(q[0] * w[0] + q[2] * w[2] - q[3] * w[1]),
        (LinkJoint::Ball, 2) => half(q[0] * w[1] + q[3] * w[0] - q[1] * w[2]),
        (LinkJoint::Ball, _) => half(q[0] * w[2] + q[1] * w[1] - q[2] * w[0]),
        (_, i) => w[i],
    }
}

fn velocity_name(given: Given) -> &'static str {
    match given {
        Given::Nu => "nu",
        Given::Qvel => "qvel",
    }
}

/// Values with their derivatives.
fn seed(out: &mut [Dual64], values: &[f64], derivatives: &[f64]) {
    for ((o, &v), &d) in out.iter_mut().zip(values).zip(derivatives) {
        *o = Dual64::new(v, d);
    }
}

/// θ with its derivative along the direction. A tangent direction moves
/// a quaternion q by q ⊗ (0, δ/2), its derivative along q ⊗ exp(δ/2); for
/// q not of unit length the passes' normalization divides that by |q|,
/// so that q̂ ⊗ exp(δ/2) is what they see.
fn seed_theta(model: &Model, theta: &[f64], direction: &Direction, out: &mut [Dual64]) -> Result<(), DynamicsError> {
    if direction.theta_in == ThetaDirection::Coordinates {
        seed(out, theta, direction.theta);
        return Ok(());
    }
    for link in &model.links {
        let (q, d) = (link.qpos_adr, link.dof_adr);
        match link.joint {
            LinkJoint::Hinge | LinkJoint::Slide => out[q] = Dual64::new(theta[q], direction.theta[d]),
            LinkJoint::Translation => seed(&mut out[q..q + 3], &theta[q..q + 3], &direction.theta[d..d + 3]),
            LinkJoint::Ball => {
                let rotation = direction.theta[d..d + 3].iter().map(|r| 0.5 * r);
                let half = Quaternion::from_parts(0.0, nalgebra::Vector3::from_iterator(rotation));
                let moved = quat_from_wxyz(&theta[q..q + 4]) * half;
                seed(&mut out[q..q + 4], &theta[q..q + 4], &[moved.w, moved.i, moved.j, moved.k]);
            }
        }
    }
    Ok(())
}
