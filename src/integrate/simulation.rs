//! One simulation object for every caller that integrates a vehicle over
//! time (the FMU, `nudyn simulate`, the benchmarks): the state that a run
//! carries from one interval to the next, the settings, the preallocated
//! integrator and workspace, and one input convention. Callers read and
//! set (θ, ν); the integrator advances (θ, θ̇) (rkmk.rs says why).

use super::adaptive::{
    AdvanceError, Carry, ScaledError, Settings, Stats, ToleranceRelaxed, per_second_error, step_factor,
    take_attempted_step, tested_error,
};
use super::auto::{AutoChoice, AutoMove, MethodSetting, MoveReason, PROBE_METHOD, held_input_move};
use super::reach::Reach;
use super::rkmk::{Integrator, nu_of_qvel, qvel_of_nu};
use super::rosenbrock::{HeldJacobian, JacobianSource};
use super::stiffness::{RETURN_SHARE, StabilityHeld, held_by_stability};
use super::switches::Switches;
use super::tableau::{Method, Scheme};
use crate::dynamics::DynamicsError;
use crate::model::Model;
use crate::workspace::Workspace;

/// What determines a run's future (what an FMU state saves of it).
#[derive(Clone, Debug, PartialEq)]
pub struct RunState {
    /// The time (s).
    pub time: f64,
    /// θ (nq, MuJoCo's qpos).
    pub theta: Vec<f64>,
    /// ν (nv).
    pub nu: Vec<f64>,
    /// θ̇ (nv, MuJoCo's qvel), which the integrator advances: ν = m*(θ)θ̇ up
    /// to round-off. Kept rather than formed from ν at each advance so that
    /// a run continues from bit for bit the θ̇ it reached, whether or not it
    /// was saved and restored in between; an advance forms it again if θ or
    /// ν were changed from outside. Then the actuators' activation states
    /// (na, MuJoCo's act), which the integrator advances with θ̇
    /// ([`Simulation::act`]): nv + na in all.
    pub qvel: Vec<f64>,
    /// The step the error control proposes next, and the work done.
    pub carry: Carry,
    /// What `auto` chose, once it has (the method it runs with from then on).
    pub auto_choice: Option<AutoChoice>,
    /// ε then the controls (nv + nu) over the last advance, when they were
    /// constant over it (`input_constant`): an advance with the same
    /// constant input goes on from the rates its last stage left ("first
    /// same as last") and from the step held past `time` (`reach`).
    pub input: Vec<f64>,
    /// Whether the last advance's input was constant over it.
    pub input_constant: bool,
    /// The last step, when it reached past `time`: (θ, ν, θ̇ and act) and the
    /// work above are then its interpolant's at `time`, and the
    /// integration goes on from its end while the inputs and settings
    /// stay as they were (reach.rs).
    pub reach: Reach,
}

impl RunState {
    /// The actuators' activation states (na, MuJoCo's act): `qvel` after θ̇.
    pub fn act(&self, model: &Model) -> &[f64] {
        self.qvel.get(model.nv..).unwrap_or_default()
    }
}

/// The applied input over one advance: ε(t) = eps + eps_rate·(t − t₀) and
/// ctrl(t) = ctrl + ctrl_rate·(t − t₀), t₀ the time the advance starts from
/// (a first-order hold, as FMI's input derivatives define it).
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    /// ε at the start of the advance (nv).
    pub eps: &'a [f64],
    /// dε/dt over the advance (nv).
    pub eps_rate: &'a [f64],
    /// The actuators' controls at the start of the advance (nu, MuJoCo's `d.ctrl`).
    pub ctrl: &'a [f64],
    /// Their rates over the advance (nu).
    pub ctrl_rate: &'a [f64],
}

/// The inputs as functions of time over one advance: [`Input`], the
/// convention of the FMU and `nudyn simulate`, or any function of time for
/// ε (a test's smooth signal), with the controls at 0.
pub trait InputSignal {
    /// Writes ε(t) into `out` (nv); `start` is the time the advance started from.
    fn eps_at(&mut self, t: f64, start: f64, out: &mut [f64]);

    /// Writes the actuators' controls at t into `out` (nu); 0 unless the signal has them.
    fn ctrl_at(&mut self, _t: f64, _start: f64, out: &mut [f64]) {
        out.fill(0.0);
    }

    /// Whether ε and the controls are the same at every t of the advance.
    fn is_constant(&self) -> bool {
        false
    }
}

/// A first-order hold: `value + rate·elapsed` into `out`.
fn hold(out: &mut [f64], value: &[f64], rate: &[f64], elapsed: f64) {
    for ((o, v), r) in out.iter_mut().zip(value).zip(rate) {
        *o = v + r * elapsed;
    }
}

impl InputSignal for Input<'_> {
    fn eps_at(&mut self, t: f64, start: f64, out: &mut [f64]) {
        hold(out, self.eps, self.eps_rate, t - start);
    }

    fn ctrl_at(&mut self, t: f64, start: f64, out: &mut [f64]) {
        hold(out, self.ctrl, self.ctrl_rate, t - start);
    }

    fn is_constant(&self) -> bool {
        self.eps_rate.iter().chain(self.ctrl_rate).all(|&r| r == 0.0)
    }
}

impl<F: FnMut(f64, &mut [f64])> InputSignal for F {
    fn eps_at(&mut self, t: f64, _start: f64, out: &mut [f64]) {
        self(t, out)
    }
}

/// What one advance did.
#[derive(Debug)]
pub struct Advanced {
    /// The internal steps taken and rejected.
    pub stats: Stats,
    /// Set when the advance completed only by relaxing the tolerance.
    pub relaxed: Option<ToleranceRelaxed>,
    /// Set when `auto` chose the method at the start of this advance.
    pub chose: Option<AutoChoice>,
    /// Set when `auto` moved to another method after this advance.
    pub moved: Option<AutoMove>,
    /// Set the first time a method the user named was held by stability.
    pub held: Option<StabilityHeld>,
}

/// A vehicle's run: its state, settings and buffers. The model is passed
/// to each call, as to the passes.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// Time, θ, ν and the carry; θ and ν may be set directly before
    /// [`Simulation::initialize`].
    pub state: RunState,
    /// Tolerance, longest step, energy projection.
    pub settings: Settings,
    /// The method asked for: one named, or `auto`, which runs [`PROBE_METHOD`] until it has chosen.
    setting: MethodSetting,
    pub(super) integrator: Integrator,
    pub(super) ws: Workspace,
    /// θ and ν (nq + nv) when `state.qvel` was last formed or advanced,
    /// to tell whether a caller has changed them since.
    qvel_belongs_to: Vec<f64>,
    /// Where limit sides switch within an adaptive run.
    pub(super) switches: Switches,
    /// The end of the run (s), which no step passes ([`Simulation::set_horizon`]).
    horizon: f64,
    /// Whether the run has said that stability held a named method's steps.
    said_held: bool,
}

impl Simulation {
    /// A run of `model` at t = 0 from the pose drawn in the file (qpos0), at rest.
    pub fn new(model: &Model, setting: impl Into<MethodSetting>, settings: Settings) -> Self {
        let setting = setting.into();
        Simulation {
            state: RunState {
                time: 0.0,
                theta: model.qpos0.clone(),
                nu: vec![0.0; model.nv],
                // act starts at 0, as MuJoCo's.
                qvel: vec![0.0; model.nv + model.activation_count()],
                carry: Carry::default(),
                auto_choice: None,
                input: vec![0.0; model.nv + model.actuators.len()],
                input_constant: false,
                reach: Reach::new(model),
            },
            settings,
            setting,
            integrator: Integrator::new(model, method_before_choice(setting)),
            ws: model.workspace(),
            qvel_belongs_to: model.qpos0.iter().copied().chain(std::iter::repeat_n(0.0, model.nv)).collect(),
            switches: Switches::new(model),
            horizon: f64::INFINITY,
            said_held: false,
        }
    }

    /// Where the run ends, if it is known (an FMU's stop time): no step
    /// reaches past it. Without one, the last step may reach past the last
    /// communication point, and its work there is lost.
    pub fn set_horizon(&mut self, end: Option<f64>) {
        self.horizon = end.unwrap_or(f64::INFINITY);
    }

    /// The integration method in effect: the one named, or the one `auto`
    /// chose ([`PROBE_METHOD`] until it has).
    pub fn method(&self) -> Method {
        self.integrator.method()
    }

    /// The method asked for.
    pub fn method_setting(&self) -> MethodSetting {
        self.setting
    }

    /// Where a Rosenbrock method's W comes from: exact derivatives where
    /// they cover the model and the point (the default), or forward
    /// differences always (to compare with the runs before them). W held
    /// is kept; the next one formed comes from `source`.
    pub fn set_jacobian_source(&mut self, source: JacobianSource) {
        self.integrator.jacobian_source = source;
    }

    /// Changes the method asked for; `auto` chooses again at the next advance.
    pub fn set_method(&mut self, model: &Model, setting: impl Into<MethodSetting>) {
        self.setting = setting.into();
        self.state.auto_choice = None;
        self.state.reach.held = false;
        self.integrator.set_method(model, method_before_choice(self.setting));
    }

    /// Checks θ, ν and act (sizes, finite, no zero quaternion), normalizes
    /// θ's quaternions in place, as MuJoCo does, and starts the carry afresh.
    pub fn initialize(&mut self, model: &Model) -> Result<(), DynamicsError> {
        self.ws.set_configuration(model, &self.state.theta)?;
        self.ws.set_nu(model, &self.state.nu)?;
        self.ws.set_act(model, self.state.act(model))?;
        self.state.theta.copy_from_slice(self.ws.theta.as_slice());
        self.state.carry = Carry::default();
        self.said_held = false;
        if self.state.auto_choice.take().is_some() {
            self.integrator.set_method(model, PROBE_METHOD);
        }
        self.integrator.first.valid = false;
        self.integrator.release_jacobian();
        self.state.reach.held = false;
        self.state.qvel[..model.nv].copy_from_slice(self.ws.qvel.as_slice());
        self.record_qvel_owner();
        Ok(())
    }

    /// The actuators' activation states (na, MuJoCo's act).
    pub fn act(&self, model: &Model) -> &[f64] {
        self.state.act(model)
    }

    /// The same, to set (before [`Simulation::initialize`], or between
    /// advances: the rates cached at the state are dropped, and the
    /// integration restarts from the state).
    pub fn act_mut(&mut self, model: &Model) -> &mut [f64] {
        self.integrator.first.valid = false;
        self.state.reach.held = false;
        self.state.qvel.get_mut(model.nv..).unwrap_or_default()
    }

    fn record_qvel_owner(&mut self) {
        let (theta, nu) = self.qvel_belongs_to.split_at_mut(self.state.theta.len());
        theta.copy_from_slice(&self.state.theta);
        nu.copy_from_slice(&self.state.nu);
    }

    /// Whether θ or ν were changed since θ̇ was formed or advanced (bitwise),
    /// or replaced by vectors of other lengths (which forming θ̇ refuses).
    fn qvel_is_stale(&self) -> bool {
        if self.state.theta.len() + self.state.nu.len() != self.qvel_belongs_to.len() {
            return true;
        }
        let (theta, nu) = self.qvel_belongs_to.split_at(self.state.theta.len());
        let differs = |a: &[f64], b: &[f64]| a.iter().zip(b).any(|(x, y)| x.to_bits() != y.to_bits());
        differs(theta, &self.state.theta) || differs(nu, &self.state.nu)
    }

    /// Integrates from the state's time to `t_end` with `input`. On
    /// failure the state stays at the last successful internal step, and
    /// its time says where.
    pub fn advance_to(
        &mut self,
        model: &Model,
        t_end: f64,
        mut input: impl InputSignal,
    ) -> Result<Advanced, AdvanceError> {
        // Where the state stood: ν is formed again wherever the advance leaves it.
        let called_at = self.state.time;
        let stale = self.qvel_is_stale();
        if stale {
            let (t0, state) = (self.state.time, &mut self.state);
            if let Err(cause) = qvel_of_nu(model, &mut self.ws, &state.theta, &state.nu, &mut state.qvel) {
                return Err(AdvanceError::StepFailed { reached: t0, step: 0.0, cause });
            }
            self.record_qvel_owner();
            self.integrator.first.valid = false;
        }
        // The cached first stage holds only if the input is the same constant as over the last advance.
        let input_held = self.keeps_held_input(&mut input, self.state.time);
        if !input_held {
            self.integrator.first.valid = false;
        }
        if self.state.reach.held {
            if stale || !input_held || !self.settings_held() {
                // An input, a setting or the state changed at the communication point: the
                // integration restarts there, from the interpolated state.
                self.state.reach.held = false;
                self.integrator.first.valid = false;
            } else if t_end < self.state.reach.end {
                return self.interpolate_in_reach(model, t_end);
            } else {
                self.go_to_reach_end();
            }
        }
        let t0 = self.state.time;
        let mut inputs_at = |t: f64, eps: &mut [f64], ctrl: &mut [f64]| {
            input.eps_at(t, t0, eps);
            input.ctrl_at(t, t0, ctrl);
        };
        let relaxation_before = self.state.carry.relaxation;
        let evaluations_before = self.integrator.evaluations;
        let mut chose = None;
        let mut held_move = None;
        let mut starts = false;
        let result = if let Err(cause) = self.settings.check_interval(self.method(), t_end - t0) {
            Err(AdvanceError::TooLong { reached: t0, cause })
        } else {
            let mut probe = Ok(0);
            if self.setting == MethodSetting::Auto && self.state.auto_choice.is_none() && t_end > t0 {
                let (choice, taken) = self.choose_method(model, t_end, &mut inputs_at);
                self.state.auto_choice = Some(choice);
                chose = Some(choice);
                probe = taken.map(usize::from);
            }
            if chose.is_none() && input_held {
                held_move = self.reach_with_dense_output(model, t0);
            }
            let probe_evaluations = self.integrator.evaluations - evaluations_before;
            // A method that starts here (its first step from the starting
            // heuristic, after a probe that took the interval) is not judged on it.
            starts = self.state.carry.next_step == 0.0;
            match probe {
                Err(cause) => {
                    let step = (t_end - t0).min(self.settings.step_bound(PROBE_METHOD));
                    Err(AdvanceError::StepFailed { reached: t0, step, cause })
                }
                Ok(probe_steps) => {
                    // Steps may reach past t_end where the method can interpolate and the host
                    // holds the input (the same constant as over the last advance: a closed
                    // loop, which changes it at every point, ends its steps there); not with
                    // energy projection, which holds K at a step's end only.
                    let reaches = input_held && self.method().dense().is_some() && !self.settings.energy_projection;
                    let limit = if reaches { self.horizon.max(t_end) } else { t_end };
                    let result = if self.method().is_adaptive() {
                        self.advance_adaptive(model, (t_end, limit), t_end - called_at, &mut inputs_at)
                    } else {
                        self.advance_fixed(model, t_end, &mut inputs_at)
                    };
                    result.map(|stats| Stats {
                        accepted: stats.accepted + probe_steps,
                        evaluations: stats.evaluations + probe_evaluations,
                        ..stats
                    })
                }
            }
        };
        // Outside a step the state decides the active limit sides again.
        self.ws.release_limit_sides();
        // ν where the run stands, whether it reached t_end or not; a run
        // that took no step keeps its ν bit for bit (m*ℓ* is the identity
        // only to round-off).
        let reached = result.as_ref().map_or_else(AdvanceError::reached, |_| t_end);
        let state = &mut self.state;
        let formed = if reached <= called_at {
            Ok(())
        } else if self.integrator.first.valid && !state.reach.held {
            // The cached first stage was evaluated at the state reached (a
            // "first same as last" step's last stage, or the start of a
            // failed attempt): its ν is m*θ̇ there, bit for bit. (A step
            // reaching past t_end leaves it at its end, not at t_end.)
            state.nu.copy_from_slice(self.integrator.first.nu.as_slice());
            Ok(())
        } else {
            nu_of_qvel(model, &mut self.ws, &state.theta, &state.qvel, &mut state.nu)
        };
        self.record_qvel_owner();
        let result = match (result, formed) {
            (Ok(_), Err(cause)) => Err(AdvanceError::StepFailed { reached: t_end, step: 0.0, cause }),
            (result, _) => result,
        };
        match result {
            Ok(stats) => {
                self.state.time = t_end;
                let rates = || self.integrator.largest_rate();
                let relaxed =
                    self.state.carry.relaxed_since(relaxation_before, called_at, self.settings.tolerance, rates);
                let judged = chose.is_none() && held_move.is_none() && !starts;
                let moved =
                    if judged { self.move_if_due(model, (called_at, t_end), &stats, input_held) } else { held_move };
                let held = self.held_once(called_at, &stats);
                Ok(Advanced { stats, relaxed, chose, moved, held })
            }
            Err(error) => {
                self.state.time = error.reached();
                Err(error)
            }
        }
    }

    /// Whether the step held past the communication point was taken with
    /// the settings now in effect (compared bit for bit).
    fn settings_held(&self) -> bool {
        let reach = &self.state.reach;
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits();
        same(self.settings.tolerance, reach.tolerance) && same(self.settings.max_step, reach.max_step)
    }

    /// An advance to `t_end` within the step held: the state there is the
    /// step's interpolant, and no step is taken.
    fn interpolate_in_reach(&mut self, model: &Model, t_end: f64) -> Result<Advanced, AdvanceError> {
        let t0 = self.state.time;
        let Simulation { state, integrator, ws, .. } = self;
        let delta = integrator.dense_delta.as_mut_slice();
        state.carry.work = state.reach.interpolate(model, t_end, &mut state.theta, &mut state.qvel, delta);
        let formed = nu_of_qvel(model, ws, &state.theta, &state.qvel, &mut state.nu);
        self.record_qvel_owner();
        formed.map_err(|cause| AdvanceError::StepFailed { reached: t0, step: 0.0, cause })?;
        self.state.time = t_end;
        let stats = Stats::default();
        let moved = self.move_if_due(model, (t0, t_end), &stats, true);
        Ok(Advanced { stats, relaxed: None, chose: None, moved, held: None })
    }

    /// Moves the state to the end of the step held, where the integration
    /// goes on. The rates cached there are dropped: evaluated at θₙ ⊕ Δ, they
    /// can differ in the last bit from rates evaluated at the stored θ (a
    /// quaternion is normalized again), which is what a run restored from
    /// an FMU state has; evaluated afresh in both, the runs agree bit for bit.
    /// A step that ended past a switch has the solver start there from the
    /// working set it found then, for the same reason.
    fn go_to_reach_end(&mut self) {
        self.integrator.first.valid = false;
        let state = &mut self.state;
        let reach = &mut state.reach;
        state.time = reach.end;
        state.theta.copy_from_slice(&reach.theta_end);
        state.qvel.copy_from_slice(&reach.qvel_end);
        state.carry.work = reach.work_end;
        reach.held = false;
        if !reach.working_set.is_empty() {
            self.ws.start_solve_from(&reach.working_set);
        }
    }

    /// Whether `input` is constant and equal to the last advance's constant
    /// input; records it as the held input (in place: no allocation).
    fn keeps_held_input(&mut self, input: &mut impl InputSignal, t0: f64) -> bool {
        let state = &mut self.state;
        let was_constant = std::mem::replace(&mut state.input_constant, input.is_constant());
        if !state.input_constant {
            return false;
        }
        let (eps, ctrl) = (self.integrator.eps_stage.as_mut_slice(), self.integrator.ctrl_stage.as_mut_slice());
        input.eps_at(t0, t0, eps);
        input.ctrl_at(t0, t0, ctrl);
        let mut same = was_constant;
        for (held, &now) in state.input.iter_mut().zip(eps.iter().chain(ctrl.iter())) {
            same &= held.to_bits() == now.to_bits();
            *held = now;
        }
        same
    }

    /// The W a Rosenbrock method holds for its next advance, into `out`
    /// (its buffer reused). Save it with the state: a run restored with it
    /// forms W again exactly when the saved run would have, and so
    /// continues bit for bit.
    pub fn save_jacobian(&self, out: &mut HeldJacobian) {
        self.integrator.save_jacobian(out);
    }

    /// Replaces the state and the W saved with it (an FMU state being
    /// restored; no derivatives, or derivatives that do not fit the method,
    /// hold none). Set the saved method first: changing the method drops W.
    pub fn restore(&mut self, model: &Model, state: &RunState, jacobian: &HeldJacobian) {
        let own_reach = std::mem::take(&mut self.state.reach);
        self.state.clone_from(state);
        if !state.reach.held {
            // A state saved without a step held may carry no buffers: keep these.
            self.state.reach = own_reach;
            self.state.reach.held = false;
        }
        if self.setting == MethodSetting::Auto {
            let method = state.auto_choice.map_or(PROBE_METHOD, |choice| choice.method);
            self.integrator.set_method(model, method);
        }
        self.integrator.hold_jacobian(jacobian);
        // The cached first stage belongs to the state replaced.
        self.integrator.first.valid = false;
        self.record_qvel_owner();
    }

    /// `auto`'s choice for an advance to `t_end` from the state: one
    /// DOP853 step over the interval (or `max_step`) measures how fast the
    /// vehicle moves for it (auto.rs). A probe that passes the run's error
    /// test is the run's first step (then `Ok(true)`), and the chosen method
    /// goes on from its end; one that fails is not taken, and the start's
    /// rates it evaluated serve the chosen method's first step. `Err` when
    /// the probe passed and could not be taken (the energy projection's
    /// passes failed at its end).
    fn choose_method(
        &mut self,
        model: &Model,
        t_end: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> (AutoChoice, Result<bool, DynamicsError>) {
        let Simulation { state, settings, integrator, ws, switches, .. } = self;
        let t0 = state.time;
        let step = (t_end - t0).min(settings.step_bound(PROBE_METHOD));
        // The probe holds the constraint mode of its start, as every adaptive step does.
        let attempted = if switches.watched() {
            switches.establish(model, ws, integrator, (&state.theta, &state.qvel), t0, false, inputs_at)
        } else {
            Ok(())
        }
        .and_then(|()| integrator.attempt(model, ws, (&state.theta, &state.qvel), (t0, step), inputs_at));
        // The error relative to 1 + |x| itself (the norm with tolerance 1),
        // and the run's error test, as `advance_adaptive` applies it to a first step.
        let scaled_at = |integrator: &mut Integrator, ws: &mut Workspace, tolerance: f64| match attempted {
            Ok(()) => integrator.error_norm(model, ws, &state.theta, tolerance, step),
            Err(_) => ScaledError::FAILED,
        };
        let control = PROBE_METHOD.control();
        let (error_per_second, _) = per_second_error(control, scaled_at(integrator, ws, 1.0), step);
        let choice = AutoChoice::new(step, error_per_second, settings.tolerance);
        let scaled = scaled_at(integrator, ws, settings.tolerance);
        let error = tested_error(per_second_error(control, scaled, step).0, scaled.per_step, state.carry.relaxation);
        // A probe across a switch is not taken: the run's method locates it.
        let passes = error <= 1.0
            && integrator.non_finite_result().is_none()
            && !(switches.watched()
                && switches.switched(model, ws, integrator, &state.theta, t0 + step, inputs_at).unwrap_or(true));
        if passes {
            let taken = take_attempted_step(
                integrator,
                model,
                ws,
                (&mut state.theta, &mut state.qvel),
                step,
                settings,
                &mut state.carry,
            );
            if let Err(cause) = taken {
                return (choice, Err(cause));
            }
            state.time = if step == t_end - t0 { t_end } else { t0 + step };
            // DOP853 kept goes on as its controller would; another method
            // starts as a run does (the probe's error says little of its steps).
            if choice.method == PROBE_METHOD {
                state.carry.next_step = step * step_factor(error, control, false);
            }
        }
        let start_evaluated = integrator.first.valid;
        integrator.set_method(model, choice.method);
        integrator.first.valid = start_evaluated && !passes;
        (choice, Ok(passes))
    }

    /// `auto` at an advance from `t0` whose input is held, so that the steps
    /// reach past the communication points: a run on BS3 moves to TSIT5, and
    /// below [`held_input_move`]'s tolerance a run on either to DOP853
    /// (auto.rs). Not with energy projection, which ends every step at a point.
    fn reach_with_dense_output(&mut self, model: &Model, t0: f64) -> Option<AutoMove> {
        if self.settings.energy_projection {
            return None;
        }
        let choice = self.state.auto_choice?;
        let to = held_input_move(choice.method, self.settings.tolerance, choice.pace())?;
        let moved = self.state.auto_choice.as_mut()?.move_to(to, t0, MoveReason::HeldInput);
        self.integrator.set_method(model, moved.to);
        Some(moved)
    }

    /// After an advance from `t0` to `t1` that `auto` did not choose in:
    /// moves a run to ROS34PW2 when stability held most of its explicit
    /// steps, back to DOP853 when ROS34PW2's steps lie well within DOP853's
    /// stability, and up one order when its last communication steps'
    /// attempts ask for it (auto.rs). Each is a function of the advance's
    /// steps and the W held after it, so a restored run judges as the saved one.
    /// Not back from ROS34PW2 while the input is held (`input_held`) and its
    /// steps span half the interval or more: they end at every point and
    /// look short for the fastest mode only because of that, and DOP853's,
    /// reaching past the points, would be held by stability again.
    fn move_if_due(
        &mut self,
        model: &Model,
        (t0, t1): (f64, f64),
        stats: &Stats,
        input_held: bool,
    ) -> Option<AutoMove> {
        let method = self.state.auto_choice?.method;
        let moved = match method.scheme() {
            Scheme::Explicit(_) if held_by_stability(stats) => {
                let (held, tests) = (stats.stability_held, stats.stiffness_tests);
                let choice = self.state.auto_choice.as_mut()?;
                choice.move_to(Method::Ros34pw2, t0, MoveReason::Stability { held, tests })
            }
            Scheme::Explicit(_) => self.state.auto_choice.as_mut()?.judge(t0, stats.accepted + stats.rejected)?,
            Scheme::Rosenbrock(_) => {
                if stats.accepted == 0 {
                    return None;
                }
                let rate = self.integrator.held_largest_rate()?;
                let step = (t1 - t0) / stats.accepted as f64;
                if input_held && 2.0 * step >= t1 - t0 {
                    return None;
                }
                if step * rate >= RETURN_SHARE * PROBE_METHOD.real_stability_bound()? {
                    return None;
                }
                let choice = self.state.auto_choice.as_mut()?;
                choice.move_to(PROBE_METHOD, t0, MoveReason::Accuracy { step, rate })
            }
        };
        self.integrator.set_method(model, moved.to);
        Some(moved)
    }

    /// What to say the first time stability held the steps of a method
    /// the user named (`auto` moves instead).
    fn held_once(&mut self, time: f64, stats: &Stats) -> Option<StabilityHeld> {
        let MethodSetting::Fixed(method) = self.setting else { return None };
        if self.said_held || !held_by_stability(stats) {
            return None;
        }
        self.said_held = true;
        let (held, tests, tolerance) = (stats.stability_held, stats.stiffness_tests, self.settings.tolerance);
        Some(StabilityHeld { method, time, tolerance, held, tests })
    }

    /// The workspace, holding the passes of the last evaluation.
    pub fn workspace(&self) -> &Workspace {
        &self.ws
    }

    /// The workspace, to hold a constraint mode on it between a host's
    /// events (model exchange); an advance sets and releases its own.
    pub fn workspace_mut(&mut self) -> &mut Workspace {
        &mut self.ws
    }

    /// Runs the passes up to θ̇ at the current state and hands out the
    /// workspace, for outputs that need more (momentum, ν̇).
    pub fn evaluate_velocity(&mut self, model: &Model) -> Result<&mut Workspace, DynamicsError> {
        self.ws.set_configuration(model, &self.state.theta)?;
        self.ws.set_nu(model, &self.state.nu)?;
        self.ws.set_act(model, self.state.act(model))?;
        Ok(&mut self.ws)
    }
}

/// The method a run with `setting` integrates with before `auto` has chosen.
fn method_before_choice(setting: MethodSetting) -> Method {
    match setting {
        MethodSetting::Fixed(method) => method,
        MethodSetting::Auto => PROBE_METHOD,
    }
}
