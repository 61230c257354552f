//! Exact first derivatives of the dynamics, by forward mode: the passes,
//! generic over their scalar ([`Real`]), run in dual numbers
//! (num-dual's `Dual64`), each carrying its value and its derivative along
//! one direction of the inputs. One directional derivative costs one run
//! of the passes in duals; a Jacobian, one run per column (a column along
//! ε, ctrl or act alone at the inputs of the run before takes that run's
//! values and runs less, or nothing: `Passes::alone_along`). The result is
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
//! The passes made generic so far are the tree's (placements, the
//! factorization, velocities, springs, dampers, gravity and its
//! compensation, ν̇, C and θ̈), the tendons' (lengths, moment arms and
//! velocities of fixed and spatial paths with their wraps, springs and
//! dampers), the actuators' (transmissions,
//! gains and biases, the clamps of ctrl and force, which hold their piece:
//! a clamped input's derivative is 0; activation states, whose act the
//! direction may move, their rates MuJoCo's act_dot, an act read clamped to
//! its range with derivative 0 beyond it), the constraint forces' (equality
//! rows, friction loss, joint and tendon limits) and the sensors' (every
//! kind nudyn reads, after the passes: [`Output::Sensordata`]). The constraint
//! forces are taken at the mode of the point: the limit sides active
//! there, each row's impedance piece, the solver's working set and the
//! no-slip pass's decisions, each decided on the values, so that the duals
//! carry the derivative of that mode's forces, a smooth function of the
//! state (the integrators hold the same mode over a step). A point on a
//! switch of that mode, where the derivative is one-sided, is refused by
//! [`Derivatives::run`] with the switches named. The tendons' armature
//! (MuJoCo's M + its terms, and the rows' mass matrix with it) runs in the
//! duals too.

use nalgebra::{DMatrix, Quaternion};
use num_dual::Dual64;

use super::configuration_tangent::ConfigurationTangent;
use super::constraint::{ConstraintRows, KeptColumns, limit_switching_functions};
use super::sensors::{cutoff_switch, sensors_need_accelerations};
use super::velocity::{self, Given};
use super::{DynamicsError, bias, check_input, forces};
use crate::math::{Real, normalize_wxyz, quat_from_wxyz};
use crate::model::{LinkJoint, Model};
use crate::workspace::{Stage, Workspace};

/// Why derivatives could not be given.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum DerivativeError {
    /// The model has a part whose passes do not carry derivatives yet.
    #[error("derivatives do not cover {0} yet; this model has them")]
    Unsupported(&'static str),
    /// The point lies on a switch of the constraint forces (a limit side
    /// at its margin, a force at a bound of its box with no push left, a
    /// row's impedance where two pieces meet): their derivative there is
    /// one-sided. Names each switch.
    #[error("the constraint forces switch at this point ({0}); their derivative there is one-sided")]
    OnSwitch(String),
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
/// qfrc_applied; each nv), and the actuators' ctrl (nu, the wrench inputs'
/// values after the MJCF's actuators'). The ε applied is ε + ℓ(θ)(T + T_actuators).
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
    /// The actuators' controls.
    pub ctrl: &'a [f64],
    /// The activation states (MuJoCo's act, na; empty without them).
    pub act: &'a [f64],
    /// The time, which the clock sensors read (their derivative is 0).
    pub time: f64,
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
    /// Along ctrl.
    pub ctrl: &'a [f64],
    /// Along act.
    pub act: &'a [f64],
}

impl<'a> Direction<'a> {
    /// `values` along `input` (tangent space for θ), `zeros[other]` along
    /// every other input (each as long as that input: [`Input::len`]).
    pub fn along(input: Input, values: &'a [f64], zeros: &'a [Vec<f64>; 6]) -> Self {
        let along = |which: Input| if which == input { values } else { zeros[which as usize].as_slice() };
        Direction {
            theta: along(Input::Theta),
            theta_in: ThetaDirection::Tangent,
            velocity: along(Input::Velocity),
            eps: along(Input::Eps),
            torque: along(Input::Torque),
            ctrl: along(Input::Ctrl),
            act: along(Input::Act),
        }
    }
}

/// The outputs whose derivatives a run gives, each nv long but the sensors'.
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
    /// MuJoCo's sensordata (its nsensordata entries), with the point's
    /// inputs and constraint mode; a reading held at its `cutoff` has
    /// derivative 0.
    Sensordata,
    /// The activation states' rates (na): MuJoCo's act_dot.
    ActDot,
    /// The vehicle's spatial momentum (6: angular about the world origin,
    /// then linear, in world axes), [`Workspace::momentum`]'s.
    Momentum,
}

impl Output {
    /// How many entries the output has for `model`.
    pub fn len(self, model: &Model) -> usize {
        match self {
            Output::Sensordata => model.sensors.iter().map(|s| s.dim()).sum(),
            Output::ActDot => model.activation_count(),
            Output::Momentum => 6,
            _ => model.nv,
        }
    }
}

/// The inputs a Jacobian's columns run along.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// θ in the tangent space (nv columns).
    Theta,
    /// The given velocity (nv).
    Velocity,
    /// ε (nv).
    Eps,
    /// T (nv).
    Torque,
    /// ctrl (nu).
    Ctrl,
    /// act (na).
    Act,
}

impl Input {
    /// Every input, in [`Jacobians`]' order (and in the order of the enum).
    pub const ALL: [Input; 6] = [Input::Theta, Input::Velocity, Input::Eps, Input::Torque, Input::Ctrl, Input::Act];

    /// How many columns the input has for `model`.
    pub fn len(self, model: &Model) -> usize {
        match self {
            Input::Ctrl => model.actuators.len(),
            Input::Act => model.activation_count(),
            _ => model.nv,
        }
    }
}

/// The Jacobians of one output at a point, one matrix per input: a row
/// per entry of the output, and nv columns for θ (tangent space), the
/// velocity, ε and T, nu for ctrl, na for act.
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
    /// ∂/∂ctrl.
    pub ctrl: DMatrix<f64>,
    /// ∂/∂act.
    pub act: DMatrix<f64>,
}

/// How a run along the inputs alone takes the values of the run before
/// ([`Passes::alone_along`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Alone {
    /// Along ε: no pass runs.
    Eps,
    /// Along ctrl or act (and ε): the velocities and the actuators run.
    Actuators,
}

/// The passes' workspace in dual numbers and the inputs' buffers.
#[derive(Clone, Debug)]
struct Passes {
    ws: Workspace<Dual64>,
    eps: Vec<Dual64>,
    torque: Vec<Dual64>,
    eps_of_torque: Vec<Dual64>,
    ctrl: Vec<Dual64>,
    /// The direction in θ's coordinates (nq).
    theta_rates: Vec<f64>,
    /// Whether the last run computed θ̈ (ν̇'s is the workspace's stage).
    qacc_current: bool,
    /// Whether the last run read the sensors.
    sensors_current: bool,
    /// The momentum, when the last run was asked for it.
    momentum: Option<[Dual64; 6]>,
    /// Whether the last run's direction had no θ part: the configuration
    /// passes' results in `ws` are then those of θ = `still_theta` with
    /// zero derivatives, and a run at the same θ along no θ direction (a
    /// Jacobian's velocity, ε, T, ctrl and act columns) reuses them.
    configuration_still: bool,
    still_theta: Vec<f64>,
    /// The constraint rows' columns of E the last run formed, which such a
    /// run takes again.
    kept_columns: KeptColumns,
    /// The configuration passes in `f64` at θ = `values_theta` (when
    /// `values_current`), from which [`ConfigurationTangent`] fills `ws`'s
    /// configuration for a run at that θ along any direction.
    values: Workspace,
    values_theta: Vec<f64>,
    values_current: bool,
    tangent: ConfigurationTangent,
    /// The inputs of the last run (θ, the velocity, ε, T, ctrl and act, one
    /// after the other, then the time) and its velocity's kind, if it
    /// completed (else None): a run along the inputs alone at the same
    /// inputs takes its values ([`Passes::alone_along`]).
    completed: Vec<f64>,
    completed_given: Option<Given>,
}

impl Passes {
    fn new(model: &Model) -> Self {
        let zeros = vec![Dual64::from(0.0); model.nv];
        Passes {
            ws: Workspace::in_scalar(model),
            eps: zeros.clone(),
            torque: zeros.clone(),
            eps_of_torque: zeros,
            ctrl: vec![Dual64::from(0.0); model.actuators.len()],
            theta_rates: vec![0.0; model.nq],
            qacc_current: false,
            sensors_current: false,
            momentum: None,
            configuration_still: false,
            still_theta: vec![0.0; model.nq],
            kept_columns: KeptColumns::new(model),
            values: model.workspace(),
            values_theta: vec![0.0; model.nq],
            values_current: false,
            tangent: ConfigurationTangent::new(model),
            completed: Vec::with_capacity(
                model.nq + 3 * model.nv + model.actuators.len() + model.activation_count() + 1,
            ),
            completed_given: None,
        }
    }

    /// `point`'s inputs but the time, in [`Passes::completed`]'s order.
    fn input_slices<'a>(point: &Point<'a>) -> [&'a [f64]; 6] {
        [point.theta, point.velocity, point.eps, point.torque, point.ctrl, point.act]
    }

    /// Whether a run along `direction` can take the values of the last
    /// run: it runs along the inputs ε, ctrl and act alone (no θ, velocity
    /// or T part), at the inputs of the last run, which completed and
    /// computed the outputs asked, on a vehicle where those inputs enter ν̇
    /// only by adding to ε (no constraint rows or tendon armature, whose
    /// solves take ε in); θ̈ and the sensors, which ε moves through the
    /// passes, are never taken this way. Along ε alone no pass runs
    /// ([`Passes::along_eps_alone`]); along ctrl or act the velocities and
    /// the actuators run, and pass 3 does not ([`Passes::run`]).
    fn alone_along(&self, model: &Model, point: &Point, direction: &Direction, outputs: &[Output]) -> Option<Alone> {
        let taken = |&output: &Output| !matches!(output, Output::Qacc | Output::Sensordata) && self.computed(output);
        let zero = |values: &[&[f64]]| values.iter().copied().flatten().all(|&d| d == 0.0);
        let inputs = Self::input_slices(point).into_iter().flatten().chain([&point.time]);
        let applies = self.completed_given == Some(point.given)
            && !model.couples_beyond_tree()
            && zero(&[direction.theta, direction.velocity, direction.torque])
            && outputs.iter().all(taken)
            && inputs.map(|v| v.to_bits()).eq(self.completed.iter().map(|v| v.to_bits()));
        match applies {
            false => None,
            true if zero(&[direction.ctrl, direction.act]) => Some(Alone::Eps),
            true => Some(Alone::Actuators),
        }
    }

    /// A run along ε alone where [`Passes::alone_along`]: the outputs'
    /// values are the last run's, ν̇'s derivative is ε's direction and
    /// every other output's (θ̇, ν, act_dot and the momentum's) is zero.
    /// Such runs are a Jacobian's ε columns and a host's ε seeds, which
    /// otherwise run passes 2 and 3 in dual numbers to find the identity.
    fn along_eps_alone(&mut self, direction: &Direction) {
        let ws = &mut self.ws;
        let unmoved = [&mut ws.theta, &mut ws.qvel, &mut ws.nu, &mut ws.act, &mut ws.act_dot];
        unmoved.into_iter().flat_map(|values| values.iter_mut()).for_each(|v| v.eps = 0.0);
        ws.nu_dot.iter_mut().zip(direction.eps).for_each(|(v, &d)| v.eps = d);
        if let Some(momentum) = &mut self.momentum {
            momentum.iter_mut().for_each(|v| v.eps = 0.0);
        }
        (self.qacc_current, self.sensors_current) = (false, false);
    }

    /// `ws`'s θ and configuration passes at `theta` along θ's rate
    /// `self.theta_rates`: from the `f64` passes' values and the derivatives'
    /// sweep where it covers the model (configuration_tangent.rs), else the
    /// passes in dual numbers. The values are `offered`'s where its
    /// configuration passes ran at `theta`, else those of the `f64` passes
    /// run here (kept for the next run at the same θ).
    fn configuration(
        &mut self,
        model: &Model,
        theta: &[f64],
        offered: Option<&Workspace>,
    ) -> Result<(), DerivativeError> {
        let ws = &mut self.ws;
        if !ConfigurationTangent::covers(model) {
            seed(ws.theta.as_mut_slice(), theta, &self.theta_rates);
            return Ok(ws.configuration_passes(model)?);
        }
        let offered = offered.filter(|values| configured_at(model, values, theta));
        if offered.is_none() && !(self.values_current && self.values_theta == theta) {
            self.values_current = false;
            self.values.theta.copy_from_slice(theta);
            self.values.configuration_passes(model)?;
            self.values_theta.copy_from_slice(theta);
            self.values_current = true;
        }
        let values = offered.unwrap_or(&self.values);
        self.tangent.fill(model, values, theta, &self.theta_rates, ws);
        if !model.gravity_compensation.is_empty() {
            super::gravity_compensation::gravity_compensation_pass(model, ws);
        }
        Ok(())
    }

    /// The passes `outputs` need at `point` along `direction` (checked),
    /// with `switches` refusing a point on a switch of the constraint forces.
    fn run(
        &mut self,
        model: &Model,
        point: &Point,
        direction: &Direction,
        outputs: &[Output],
        switches: &mut Switches,
        offered: Option<&Workspace>,
    ) -> Result<(), DerivativeError> {
        let alone = self.alone_along(model, point, direction, outputs);
        if alone == Some(Alone::Eps) {
            self.along_eps_alone(direction);
            return Ok(());
        }
        self.completed_given = None;
        (self.qacc_current, self.sensors_current, self.momentum) = (false, false, None);
        theta_rates(model, point.theta, direction, &mut self.theta_rates);
        let still = self.theta_rates.iter().all(|&rate| rate == 0.0);
        let reused = still && self.configuration_still && self.still_theta == point.theta;
        self.kept_columns.still(reused);
        if !reused {
            self.configuration_still = false;
            self.ws.stage = Stage::Empty;
            self.configuration(model, point.theta, offered)?;
            let ws = &mut self.ws;
            if !model.tendons.is_empty() {
                ws.tendon_kinematics(model);
            }
            if !model.tendon_inertia.is_empty() {
                ws.tendon_inertia_configuration(model)?;
            }
            if still {
                self.still_theta.copy_from_slice(point.theta);
                self.configuration_still = true;
            }
        }
        let ws = &mut self.ws;
        ws.stage = Stage::Configuration;
        let velocity = match point.given {
            Given::Nu => ws.nu.as_mut_slice(),
            Given::Qvel => ws.qvel.as_mut_slice(),
        };
        seed(velocity, point.velocity, direction.velocity);
        velocity::velocity_pass(model, ws, point.given);
        if !model.tendons.is_empty() {
            ws.tendon_velocities(model);
        }
        ws.stage = Stage::Velocity;
        if outputs.contains(&Output::Momentum) {
            self.momentum = Some(ws.momentum(model)?.into());
        }
        seed(&mut self.eps, point.eps, direction.eps);
        // The FMU's knowns hold no joint forces: no inward pass for a zero T.
        if point.torque.iter().chain(direction.torque).any(|&t| t != 0.0) {
            seed(&mut self.torque, point.torque, direction.torque);
            forces::eps_of_torque(model, ws, &self.torque, &mut self.eps_of_torque);
            self.eps.iter_mut().zip(&self.eps_of_torque).for_each(|(e, t)| *e += *t);
        }
        if !model.actuators.is_empty() {
            seed(&mut self.ctrl, point.ctrl, direction.ctrl);
            seed(ws.act.as_mut_slice(), point.act, direction.act);
            ws.actuation_pass(model, &self.ctrl)?;
            self.eps.iter_mut().zip(ws.eps_actuator.iter()).for_each(|(e, a)| *e += *a);
        }
        if alone == Some(Alone::Actuators) {
            // ν̇ = ε + ε_actuator + terms of θ and ν alone, at the values
            // of the last run: its derivative is the sum's.
            if outputs.contains(&Output::NuDot) {
                ws.nu_dot.iter_mut().zip(&self.eps).for_each(|(v, e)| v.eps = e.eps);
                ws.stage = Stage::Acceleration;
            }
            self.record_completed(point);
            return Ok(());
        }
        let passive = bias::all_passive_forces(model, ws);
        // ν̇ needs pass 3 with the factor's rates; θ̈ alone does without
        // them, and the outward pass only θ̈ needs.
        // The sensors read θ̈ and the constraint forces of the point's inputs where they need them.
        let sensors = outputs.contains(&Output::Sensordata);
        let nu_dot = outputs.contains(&Output::NuDot);
        let qacc = outputs.contains(&Output::Qacc) || (sensors && sensors_need_accelerations(model));
        if nu_dot {
            bias::link_sweep::<_, true>(model, ws, &self.eps, passive);
            ws.stage = Stage::Acceleration;
        } else if qacc {
            bias::link_sweep::<_, false>(model, ws, &self.eps, passive);
            ws.stage = Stage::JointRates;
        }
        if qacc {
            ws.compute_accelerations(model)?;
        }
        if model.couples_beyond_tree() {
            // The forces of the mode the point is in: its active sides,
            // impedance pieces and working set, decided on the values.
            // They need θ̈ without them (run above, or by this call with ν̇).
            // The tendons' armature first (MuJoCo's qacc_smooth), then the rows
            // with the mass matrix it makes, as the f64 passes take them.
            if !model.tendon_inertia.is_empty() {
                ws.apply_tendon_inertia(model, &mut self.eps)?;
            }
            ws.add_constraint_forces(model, &mut self.eps, Some(&mut self.kept_columns), |ws, model, rows| {
                if !model.tendon_inertia.is_empty() {
                    let (n, stride) = (rows.count, rows.max_rows);
                    ws.tendon_inertia_on_rows(model, n, &mut rows.eps_columns, &mut rows.hessian, stride);
                    rows.eps_spans[..n].fill((0, model.nv));
                }
                rows.solve_in_one_working_set()?;
                ws.no_slip_pass(model, rows)
            })?;
            // A held mode's forces are smooth on both sides of its switches.
            if !ws.constraint_rows.holds_mode() {
                switches.refuse_on_switch(model, ws)?;
            }
        }
        self.qacc_current = qacc;
        if sensors {
            let on_cutoff = ws.read_sensors(model, point.time);
            // A held mode holds the cutoffs' pieces too: a reading on its
            // cutoff then keeps the derivative of the unclamped side.
            if let Some(entry) = on_cutoff
                && !ws.constraint_rows.holds_mode()
            {
                return Err(DerivativeError::OnSwitch(cutoff_switch(model, entry)));
            }
            self.sensors_current = true;
        }
        self.record_completed(point);
        Ok(())
    }

    /// Notes that a run at `point` completed ([`Passes::alone_along`]).
    fn record_completed(&mut self, point: &Point) {
        self.completed.clear();
        for slice in Self::input_slices(point) {
            self.completed.extend_from_slice(slice);
        }
        self.completed.push(point.time);
        self.completed_given = Some(point.given);
    }

    /// Whether the last run computed `output`.
    fn computed(&self, output: Output) -> bool {
        match output {
            Output::Qvel | Output::Nu | Output::ActDot => true,
            Output::NuDot => self.ws.stage == Stage::Acceleration,
            Output::Qacc => self.qacc_current,
            Output::Sensordata => self.sensors_current,
            Output::Momentum => self.momentum.is_some(),
        }
    }

    /// `output` of the last run, which must have been asked for.
    fn output(&self, output: Output) -> &[Dual64] {
        assert!(self.computed(output), "{output:?} was not asked of the last run");
        match output {
            Output::Qvel => self.ws.qvel.as_slice(),
            Output::Nu => self.ws.nu.as_slice(),
            Output::NuDot => self.ws.nu_dot.as_slice(),
            Output::Qacc => self.ws.qacc.as_slice(),
            Output::Sensordata => self.ws.sensordata.as_slice(),
            Output::ActDot => self.ws.act_dot.as_slice(),
            Output::Momentum => self.momentum.as_ref().expect("checked above"),
        }
    }
}

/// How close to 0 a switching function may come before the point counts
/// as on the switch: round-off of the quantities it compares (lengths and
/// angles, the impedance's argument; forces and multipliers relative to
/// the problem's scale).
const SWITCH_TOLERANCE: f64 = 1e-12;

/// The buffers of the check for switches of the constraint forces.
#[derive(Clone, Debug)]
struct Switches {
    /// Each limit side's distance less its margin at the point.
    sides: Vec<f64>,
    /// θ's values (quaternions normalized by the passes).
    theta: Vec<f64>,
    /// The tendons' lengths.
    tendon_length: Vec<f64>,
    /// Each row's margins from its working set and its impedance's piece.
    forces: Vec<f64>,
    pieces: Vec<f64>,
}

impl Switches {
    fn new(model: &Model) -> Self {
        let rows = model.constraints.max_rows();
        Switches {
            sides: vec![0.0; model.constraints.limit_sides()],
            theta: vec![0.0; model.nq],
            tendon_length: vec![0.0; model.tendons.len()],
            forces: vec![0.0; rows],
            pieces: vec![0.0; rows],
        }
    }

    /// [`DerivativeError::OnSwitch`] when the point whose constraint
    /// forces `ws` holds lies on a switch, naming each.
    fn refuse_on_switch(&mut self, model: &Model, ws: &Workspace<Dual64>) -> Result<(), DerivativeError> {
        let constraints = &model.constraints;
        let mut on = Vec::new();
        self.theta.iter_mut().zip(ws.theta.iter()).for_each(|(slot, q)| *slot = q.re);
        self.tendon_length.iter_mut().zip(ws.tendon_length.iter()).for_each(|(slot, l)| *slot = l.re);
        limit_switching_functions(model, &self.theta, &self.tendon_length, &mut self.sides);
        let side_name = |side: usize| ["lower", "upper"][side];
        for (index, limit) in constraints.limits.iter().enumerate() {
            for side in 0..2 {
                if self.sides[constraints.joint_limit_slot(index, side)].abs() <= SWITCH_TOLERANCE {
                    on.push(format!(
                        "the {} limit of joint '{}' at its margin",
                        side_name(side),
                        model.joints[limit.joint].name
                    ));
                }
            }
        }
        for (index, limit) in constraints.tendon_limits.iter().enumerate() {
            for side in 0..2 {
                if self.sides[constraints.tendon_limit_slot(index, side)].abs() <= SWITCH_TOLERANCE {
                    let name = model.tendons[limit.tendon].name.clone().unwrap_or_else(|| limit.tendon.to_string());
                    on.push(format!("the {} limit of tendon '{name}' at its margin", side_name(side)));
                }
            }
        }
        let rows = &ws.constraint_rows;
        rows.mode_margins(model, &mut self.forces, &mut self.pieces);
        let n = rows.count;
        let scale = rows.gradient[..n].iter().chain(&rows.force[..n]).fold(1.0_f64, |s, x| s.max(x.re.abs()));
        for k in 0..n {
            if self.forces[k].abs() <= SWITCH_TOLERANCE * scale {
                on.push(format!("{}: its force at a bound of its box", rows.row_name(model, k)));
            }
            if self.pieces[k].abs() <= SWITCH_TOLERANCE {
                on.push(format!("{}: its impedance between two pieces", rows.row_name(model, k)));
            }
        }
        // The no-slip pass's: each sweep's clamp of each row, then each island's stop.
        let (clamps, stops) = rows
            .no_slip
            .margins()
            .split_at(rows.no_slip.margins().len().min(constraints.options.noslip_iterations as usize * rows.max_rows));
        for (slot, margin) in clamps.iter().enumerate() {
            if margin.abs() <= SWITCH_TOLERANCE * scale {
                let (sweep, k) = (slot / rows.max_rows, slot % rows.max_rows);
                on.push(format!(
                    "{}: the no-slip pass's sweep {} at a bound of its box",
                    rows.row_name(model, k),
                    sweep + 1
                ));
            }
        }
        if stops.iter().any(|margin| margin.abs() <= SWITCH_TOLERANCE) {
            on.push("the no-slip pass's improvement at noslip_tolerance".to_string());
        }
        match on.is_empty() {
            true => Ok(()),
            false => Err(DerivativeError::OnSwitch(on.join("; "))),
        }
    }
}

/// A model's passes in dual numbers and the inputs' buffers: built once,
/// so that derivatives allocate nothing but their results.
#[derive(Clone, Debug)]
pub struct Derivatives {
    passes: Passes,
    switches: Switches,
}

impl Derivatives {
    /// The buffers for `model`.
    pub fn new(model: &Model) -> Self {
        Derivatives { passes: Passes::new(model), switches: Switches::new(model) }
    }

    /// Runs the passes `outputs` need at `point` along `direction`;
    /// [`Derivatives::derivative`] and [`Derivatives::value`] then read
    /// those outputs (θ̇, ν and act_dot are always computed; ν̇ and θ̈ when
    /// asked).
    pub fn run(
        &mut self,
        model: &Model,
        point: &Point,
        direction: &Direction,
        outputs: &[Output],
    ) -> Result<(), DerivativeError> {
        self.checked_run(model, point, direction, outputs, None)
    }

    /// [`Derivatives::run`], taking the configuration's values from
    /// `evaluated` (an `f64` workspace, as an FMU's or an integrator's
    /// evaluations leave it) where its configuration passes ran at the
    /// point's θ: a direction then reruns none of them. Where they did not
    /// (another θ, or not run), the same as [`Derivatives::run`].
    pub fn run_after(
        &mut self,
        model: &Model,
        evaluated: &Workspace,
        point: &Point,
        direction: &Direction,
        outputs: &[Output],
    ) -> Result<(), DerivativeError> {
        self.checked_run(model, point, direction, outputs, Some(evaluated))
    }

    /// The point and direction checked, then the passes, with the `f64`
    /// configuration `offered` where it was evaluated at the point's θ.
    fn checked_run(
        &mut self,
        model: &Model,
        point: &Point,
        direction: &Direction,
        outputs: &[Output],
        offered: Option<&Workspace>,
    ) -> Result<(), DerivativeError> {
        check_point(model, point)?;
        check_direction(model, point, direction)?;
        self.passes.run(model, point, direction, outputs, &mut self.switches, offered)
    }

    /// The derivative of `output` along the last run's direction; panics
    /// unless the run was asked for it.
    pub fn derivative(&self, output: Output) -> impl Iterator<Item = f64> + '_ {
        self.passes.output(output).iter().map(|d| d.eps)
    }

    /// The value of `output` at the last run's point; panics unless the
    /// run was asked for it.
    pub fn value(&self, output: Output) -> impl Iterator<Item = f64> + '_ {
        self.passes.output(output).iter().map(|d| d.re)
    }

    /// The derivative of d(θ\[k\])/dt ([`qpos_rate`]) along the last run's
    /// direction: θ's rate as the state derivative of model exchange.
    pub fn qpos_rate_derivative(&self, model: &Model, k: usize) -> f64 {
        let ws = &self.passes.ws;
        qpos_rate(model, ws.theta.as_slice(), ws.qvel.as_slice(), k).eps
    }

    /// Holds the constraint mode that `held` (an f64 workspace's rows)
    /// holds, or none: the runs then give the derivatives of that mode's
    /// forces (an FMU's between events, an integrator's over a step),
    /// smooth on both sides of its switches, so a point on one is not
    /// refused. Without a held mode each run takes its point's own.
    pub fn hold_constraint_mode_of(&mut self, held: &ConstraintRows) {
        self.passes.ws.constraint_rows.hold_mode_of(held);
    }

    /// The derivative of activation state k's rate as model exchange's
    /// host integrates it ([`Workspace::act_rate_within_range`]: 0 at a
    /// bound act would leave) along the last run's direction.
    pub fn act_rate_within_range_derivative(&self, model: &Model, k: usize) -> f64 {
        self.passes.ws.act_rate_within_range(model, k).eps
    }

    /// The derivative of MuJoCo's qfrc_constraint = Jᵀf (entry `k`) along
    /// the last run's direction: 0 where no constraint row acts.
    pub fn qfrc_constraint_derivative(&self, k: usize) -> f64 {
        self.passes.ws.constraint_rows.qfrc_constraint.get(k).map_or(0.0, |d| d.eps)
    }

    /// The Jacobians of `output` at `point`, for every input.
    pub fn jacobians(&mut self, model: &Model, point: &Point, output: Output) -> Result<Jacobians, DerivativeError> {
        let [mut by_input] = self.jacobians_of(model, point, [output], &Input::ALL)?;
        let mut take = || by_input.remove(0);
        Ok(Jacobians { theta: take(), velocity: take(), eps: take(), torque: take(), ctrl: take(), act: take() })
    }

    /// The Jacobians of each of `outputs` at `point` with respect to each
    /// of `inputs`, `[output][input]` in the orders given: one run per
    /// input column, every output read from it. (Vector dual numbers,
    /// several columns per run, measured slower: num-dual's `DualSVec64<8>`
    /// cost 10–16 ν̇ per column where `Dual64` costs 4–5.)
    pub fn jacobians_of<const N: usize>(
        &mut self,
        model: &Model,
        point: &Point,
        outputs: [Output; N],
        inputs: &[Input],
    ) -> Result<[Vec<DMatrix<f64>>; N], DerivativeError> {
        check_point(model, point)?;
        let zeros = Input::ALL.map(|input| vec![0.0; input.len(model)]);
        let mut out: [Vec<DMatrix<f64>>; N] = std::array::from_fn(|_| Vec::with_capacity(inputs.len()));
        for &input in inputs {
            let count = input.len(model);
            let mut unit = vec![0.0; count];
            let mut jacobians: [DMatrix<f64>; N] =
                std::array::from_fn(|k| DMatrix::zeros(outputs[k].len(model), count));
            for column in 0..count {
                unit[column] = 1.0;
                let direction = Direction::along(input, &unit, &zeros);
                let run = self.passes.run(model, point, &direction, &outputs, &mut self.switches, None);
                unit[column] = 0.0;
                run?;
                for (jacobian, output) in jacobians.iter_mut().zip(outputs) {
                    for (row, d) in self.passes.output(output).iter().enumerate() {
                        jacobian[(row, column)] = d.eps;
                    }
                }
            }
            for (by_input, jacobian) in out.iter_mut().zip(jacobians) {
                by_input.push(jacobian);
            }
        }
        Ok(out)
    }
}

/// d(θ\[k\])/dt from the passes' θ (quaternions normalized) and θ̇: θ̇'s
/// entry for a hinge, slide, translation or modal coordinate; q̇ = ½ q ⊗ (0, ω) for a
/// quaternion's entries (ω in the body frame), orthogonal to q. Generic,
/// so that run in dual numbers it carries its own derivative.
pub fn qpos_rate<S: Real>(model: &Model, theta: &[S], qvel: &[S], k: usize) -> S {
    // A flexible body's modal coordinate: its rate.
    if let Some(flexible) = model.flexible.iter().find(|f| (f.qpos_adr..f.qpos_adr + f.mode_count()).contains(&k)) {
        return qvel[flexible.dof_adr + k - flexible.qpos_adr];
    }
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

/// Whether `values`' configuration passes ran at `theta`: they did (their
/// stage says so) at a θ whose quaternions normalize to the bits of
/// `values.theta`, which the passes normalized in place, and whose other
/// entries are `values.theta`'s.
fn configured_at(model: &Model, values: &Workspace, theta: &[f64]) -> bool {
    if values.stage < Stage::Configuration {
        return false;
    }
    model.links.iter().all(|link| {
        let (q, held) = (&theta[link.qpos_adr..], &values.theta.as_slice()[link.qpos_adr..]);
        match link.joint {
            LinkJoint::Ball => {
                let mut unit = [q[0], q[1], q[2], q[3]];
                normalize_wxyz(&mut unit).is_some() && unit.iter().zip(held).all(|(a, b)| a.to_bits() == b.to_bits())
            }
            _ => q[..link.ndof].iter().zip(held).all(|(a, b)| a.to_bits() == b.to_bits()),
        }
    })
}

/// The point's entries: their lengths, and finite.
fn check_point(model: &Model, point: &Point) -> Result<(), DerivativeError> {
    check_input("theta", point.theta, model.nq)?;
    check_input(velocity_name(point.given), point.velocity, model.nv)?;
    check_input("eps", point.eps, model.nv)?;
    check_input("torque", point.torque, model.nv)?;
    check_input("ctrl", point.ctrl, model.actuators.len())?;
    check_input("act", point.act, model.activation_count())?;
    Ok(())
}

/// The direction's lengths.
fn check_direction(model: &Model, point: &Point, direction: &Direction) -> Result<(), DerivativeError> {
    let theta_length = match direction.theta_in {
        ThetaDirection::Tangent => model.nv,
        ThetaDirection::Coordinates => model.nq,
    };
    for (what, values, expected) in [
        ("theta", direction.theta, theta_length),
        (velocity_name(point.given), direction.velocity, model.nv),
        ("eps", direction.eps, model.nv),
        ("torque", direction.torque, model.nv),
        ("ctrl", direction.ctrl, model.actuators.len()),
        ("act", direction.act, model.activation_count()),
    ] {
        if values.len() != expected {
            return Err(DerivativeError::DirectionLength { what, expected, found: values.len() });
        }
    }
    Ok(())
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

/// θ's rate along the direction, in θ's coordinates (nq). A tangent
/// direction moves a quaternion q by q ⊗ (0, δ/2), its derivative along
/// q ⊗ exp(δ/2); for q not of unit length the passes' normalization
/// divides that by |q|, so that q̂ ⊗ exp(δ/2) is what they see.
fn theta_rates(model: &Model, theta: &[f64], direction: &Direction, out: &mut [f64]) {
    if direction.theta_in == ThetaDirection::Coordinates {
        out.copy_from_slice(direction.theta);
        return;
    }
    for link in &model.links {
        let (q, d) = (link.qpos_adr, link.dof_adr);
        match link.joint {
            LinkJoint::Hinge | LinkJoint::Slide => out[q] = direction.theta[d],
            LinkJoint::Translation => out[q..q + 3].copy_from_slice(&direction.theta[d..d + 3]),
            LinkJoint::Ball => {
                let rotation = direction.theta[d..d + 3].iter().map(|r| 0.5 * r);
                let half = Quaternion::from_parts(0.0, nalgebra::Vector3::from_iterator(rotation));
                let moved = quat_from_wxyz(&theta[q..q + 4]) * half;
                out[q..q + 4].copy_from_slice(&[moved.w, moved.i, moved.j, moved.k]);
            }
        }
    }
    for flexible in &model.flexible {
        let (q, d, m) = (flexible.qpos_adr, flexible.dof_adr, flexible.mode_count());
        out[q..q + m].copy_from_slice(&direction.theta[d..d + m]);
    }
}

#[cfg(test)]
mod tests {
    use super::{Alone, Derivatives, Direction, Output, Point, ThetaDirection};
    use crate::dynamics::test_vehicle;
    use crate::dynamics::velocity::Given;
    use crate::model::Model;

    /// Every derivative and value a run gives of `outputs`, and the
    /// accessors' (θ's rate, act's rate, qfrc_constraint), as bits.
    fn everything(derivatives: &Derivatives, model: &Model, outputs: &[Output]) -> Vec<u64> {
        let mut out: Vec<f64> = Vec::new();
        for &output in outputs {
            out.extend(derivatives.derivative(output));
            out.extend(derivatives.value(output));
        }
        out.extend((0..model.nq).map(|k| derivatives.qpos_rate_derivative(model, k)));
        out.extend((0..model.activation_count()).map(|k| derivatives.act_rate_within_range_derivative(model, k)));
        out.extend((0..model.nv).map(|k| derivatives.qfrc_constraint_derivative(k)));
        out.into_iter().map(f64::to_bits).collect()
    }

    fn wave(n: usize, a: f64, b: f64) -> Vec<f64> {
        (0..n).map(|k| (a * k as f64 + b).sin()).collect()
    }

    /// A direction along θ (its coordinates), the velocity, ε, ctrl and
    /// act, and zeros (`zeros`: nv long) along T.
    fn direction<'a>(
        theta: &'a [f64],
        velocity: &'a [f64],
        eps: &'a [f64],
        (ctrl, act): (&'a [f64], &'a [f64]),
        zeros: &'a [f64],
    ) -> Direction<'a> {
        Direction { theta, theta_in: ThetaDirection::Coordinates, velocity, eps, torque: zeros, ctrl, act }
    }

    /// A run along the inputs alone (ε; ctrl and act) after runs at the
    /// same inputs takes their values where those inputs only add to ν̇'s ε
    /// (bus_arm7, the servicer's thrusters and servos, actuators with
    /// activation states, a flexible boom, actuators on tendons with and
    /// without force ranges), and every output and accessor
    /// then gives the bits of a fresh run's; with constraint rows or the
    /// tendons' armature, with θ̈ or the sensors asked, at other inputs or
    /// along the velocity too, the passes run.
    #[test]
    fn a_run_along_the_inputs_alone_gives_a_fresh_runs_bits_and_is_taken_where_they_only_add() {
        let plain = [Output::Qvel, Output::Nu, Output::NuDot, Output::ActDot, Output::Momentum];
        for (file, takes) in [
            ("examples/bus_arm7.xml", true),
            ("examples/servicer.xml", true),
            ("tests/fixtures/activation/shortcut_servos.xml", true),
            ("examples/flexible_boom.xml", true),
            ("tests/fixtures/tendons/tendon_wrap.xml", true),
            ("tests/fixtures/tendons/tendon_force_range.xml", true),
            ("tests/fixtures/constraints/docked_servicer.xml", false),
            ("tests/fixtures/tendons/tendon_armature.xml", false),
        ] {
            let (model, ws) = test_vehicle(file, 0.3);
            let (nq, nv, nu, na) = (model.nq, model.nv, model.actuators.len(), model.activation_count());
            let theta = ws.theta.as_slice().to_vec();
            let (velocity, mut eps) = (wave(nv, 0.7, 0.2), wave(nv, 1.1, 0.5));
            let (torque, ctrl, act) = (vec![0.0; nv], wave(nu, 0.3, 0.1), wave(na, 0.9, 0.4));
            let (no_theta, no_velocity) = (vec![0.0; nq], vec![0.0; nv]);
            let (no_ctrl, no_act) = (vec![0.0; nu], vec![0.0; na]);
            let still = (&no_ctrl[..], &no_act[..]);
            let (along_theta, along_velocity, along_eps) =
                (wave(nq, 0.37, 0.1), wave(nv, 0.61, 0.2), wave(nv, 0.53, 0.3));
            let (along_ctrl, along_act) = (wave(nu, 0.41, 0.6), wave(na, 0.23, 0.7));
            let point_eps = eps.clone();
            let point = Point {
                theta: &theta,
                velocity: &velocity,
                given: Given::Nu,
                eps: &point_eps,
                torque: &torque,
                ctrl: &ctrl,
                act: &act,
                time: 0.0,
            };
            let eps_alone = direction(&no_theta, &no_velocity, &along_eps, still, &no_velocity);
            let mut alone = vec![(eps_alone, Alone::Eps)];
            if nu > 0 {
                let along = (&along_ctrl[..], &no_act[..]);
                alone.push((direction(&no_theta, &no_velocity, &no_velocity, along, &no_velocity), Alone::Actuators));
                let along = (&along_ctrl[..], &along_act[..]);
                alone.push((direction(&no_theta, &no_velocity, &along_eps, along, &no_velocity), Alone::Actuators));
            }
            for (along, kind) in &alone {
                let mut fresh = Derivatives::new(&model);
                fresh.run(&model, &point, along, &plain).unwrap();
                let expected = everything(&fresh, &model, &plain);
                for before in [
                    direction(&along_theta, &no_velocity, &no_velocity, still, &no_velocity),
                    direction(&no_theta, &along_velocity, &no_velocity, still, &no_velocity),
                ] {
                    let mut derivatives = Derivatives::new(&model);
                    derivatives.run(&model, &point, &before, &plain).unwrap();
                    let taken = takes.then_some(*kind);
                    assert_eq!(derivatives.passes.alone_along(&model, &point, along, &plain), taken, "{file}");
                    derivatives.run(&model, &point, along, &plain).unwrap();
                    assert!(everything(&derivatives, &model, &plain) == expected, "{file}, {kind:?}");
                    // Taken again after itself.
                    assert_eq!(derivatives.passes.alone_along(&model, &point, along, &plain), taken, "{file}");
                    // Not along the velocity too, nor for θ̈ or the sensors.
                    let mixed = Direction { velocity: &along_velocity, ..*along };
                    assert_eq!(derivatives.passes.alone_along(&model, &point, &mixed, &plain), None, "{file}");
                    for asked in [[Output::NuDot, Output::Qacc], [Output::NuDot, Output::Sensordata]] {
                        assert_eq!(derivatives.passes.alone_along(&model, &point, along, &asked), None, "{file}");
                    }
                }
            }
            // Not at other inputs.
            let mut derivatives = Derivatives::new(&model);
            derivatives.run(&model, &point, &eps_alone, &plain).unwrap();
            eps[0] += 1e-9;
            let moved = Point { eps: &eps, ..point };
            assert_eq!(derivatives.passes.alone_along(&model, &moved, &eps_alone, &plain), None, "{file}");
        }
    }
}
