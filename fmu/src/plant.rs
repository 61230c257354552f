//! The plant: the vehicle's dynamics as an FMU component. It holds the
//! compiled model from the FMU's resources, the state (θ, ν, act), the inputs ε
//! and the actuators' controls, and the parameters, and advances them with
//! the core integrator.
//!
//! Outputs beyond θ and ν are computed when first read after a change of
//! state, so outputs nobody reads cost nothing.

use nudyn::dynamics::derivatives::qpos_rate;
use nudyn::dynamics::mode::ConstraintMode;
use nudyn::dynamics::quantities::kinetic_energy;
use nudyn::integrate::{HeldJacobian, Input, MethodSetting, RunState, Settings, Simulation};
use nudyn::model::Model;
use nudyn_contract::capabilities::Capabilities;
use nudyn_contract::plant::{
    DEFAULT_MAX_STEP, DEFAULT_TOLERANCE, ENERGY_PROJECTION_VR, Layout, METHOD_VR, PlantResource, RealVariable,
    capabilities, method_of_value, method_value, serves_model_exchange,
};
use nudyn_contract::variable::Kind;

use crate::component::{CallError, Component, StepError, StepReport, Variable};
use crate::partials::{At, Partials};
use crate::snapshot::{PlantState, Sizes, Snapshot, SnapshotError};
use crate::state::Phase;

/// The parameters' defaults.
const DEFAULT_SETTINGS: Settings =
    Settings { tolerance: DEFAULT_TOLERANCE, max_step: DEFAULT_MAX_STEP, energy_projection: false };

/// How far the workspace holds the passes for the current (θ, ν, ε).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Evaluated {
    Nothing,
    /// θ̇ (qvel) and, if it is an output, the momentum.
    Velocity,
    /// ν̇ too.
    Acceleration,
    /// The sensors too.
    Sensors,
}

/// One plant instance.
pub struct Plant {
    model: Model,
    layout: Layout,
    /// The Real variables' slots and kinds in value-reference order from
    /// `METHOD_VR + 1`, looked up on every get and set (the layout's own
    /// lookup walks the table and is meant for writing the modelDescription).
    reals: Vec<(RealVariable, Kind)>,
    guid: String,
    /// Time, θ, ν, the settings and method, the integrator and workspace.
    sim: Simulation,
    /// Start time of the experiment (s).
    start_time: f64,
    /// Stop time, if the master declared one (s).
    stop_time: Option<f64>,
    /// K = ½|ν|² at initialization (J), for the energy residual.
    initial_energy: f64,
    /// The inputs ε (nv) as set at the current communication point.
    eps: Vec<f64>,
    /// dε/dt (nv) from fmi2SetRealInputDerivatives, for the next step only.
    eps_rate: Vec<f64>,
    /// The actuators' controls (nu, MuJoCo's `d.ctrl`) as set at the current communication point.
    ctrl: Vec<f64>,
    /// Their rates (nu), for the next step only.
    ctrl_rate: Vec<f64>,
    evaluated: Evaluated,
    /// Momentum at the current state, when `evaluated` ≥ Velocity and it is an output.
    momentum: [f64; 6],
    /// Set when a step failed on a non-finite state: the master should stop
    /// (fmi2GetBooleanStatus(fmi2Terminated)).
    failed_for_good: bool,
    /// The tolerance fmi2SetupExperiment passed, if it passed one: it
    /// replaces the `tolerance` parameter at initialization.
    experiment_tolerance: Option<f64>,
    /// The start values chosen at export (value reference, value), set at
    /// instantiation and at every reset.
    starts: (Vec<u32>, Vec<f64>),
    /// The start of `method` chosen at export.
    start_method: MethodSetting,
    /// Model exchange in FMI 2.0: the constraint mode held from one event
    /// to the next (its margins are the event indicators), once set.
    mode: ConstraintMode,
    mode_held: bool,
    /// The margins of `mode` (scratch), and θ to set it at (scratch).
    margins: Vec<f64>,
    /// The event indicators as the variable `constraint_switch` reads them,
    /// filled by the prepare of each read that asks for one.
    indicators: Vec<f64>,
    theta_scratch: Vec<f64>,
    /// The partial derivatives' dual workspace, or why there are none.
    partials: Partials,
    /// Where a restored state's velocities are checked (`check_velocities`),
    /// apart from the one the outputs are read from; made at the first
    /// restore and kept, as a master that rolls back may restore every step.
    restore_check: Option<Box<nudyn::workspace::Workspace>>,
}

impl Plant {
    /// The plant of a loaded resource, of the FMU with `guid`.
    pub fn new(resource: PlantResource, guid: String) -> Plant {
        let layout = resource.layout();
        let starts = layout
            .elements()
            .filter_map(|element| resource.starts.get(&element.name()).map(|&value| (element.value_reference, value)))
            .unzip();
        let (model, start_method) = (resource.model, resource.method);
        let reals = layout.elements().map(|element| (element.variable(), element.kind())).collect();
        let partials = Partials::new(&layout);
        let mut plant = Plant {
            layout,
            reals,
            guid,
            sim: Simulation::new(&model, start_method, DEFAULT_SETTINGS),
            start_time: 0.0,
            stop_time: None,
            initial_energy: 0.0,
            eps: vec![0.0; model.nv],
            eps_rate: vec![0.0; model.nv],
            ctrl: vec![0.0; model.actuators.len()],
            ctrl_rate: vec![0.0; model.actuators.len()],
            evaluated: Evaluated::Nothing,
            momentum: [0.0; 6],
            failed_for_good: false,
            experiment_tolerance: None,
            starts,
            start_method,
            mode: ConstraintMode::new(&model),
            mode_held: false,
            margins: vec![0.0; model.switch_count()],
            indicators: vec![0.0; model.switch_count()],
            theta_scratch: vec![0.0; model.nq],
            partials,
            restore_check: None,
            model,
        };
        plant.set_starts();
        plant
    }

    /// Sets the start values chosen at export, as a master's set would.
    fn set_starts(&mut self) {
        let (vrs, values) = std::mem::take(&mut self.starts);
        self.set_reals(&vrs, &values);
        self.starts = (vrs, values);
    }

    /// The Real variable with value reference `vr`, if any.
    fn real(&self, vr: u32) -> Option<RealVariable> {
        self.real_with_kind(vr).map(|(variable, _)| variable)
    }

    /// The Real variable with value reference `vr` and its kind, if any.
    fn real_with_kind(&self, vr: u32) -> Option<(RealVariable, Kind)> {
        let index = vr.checked_sub(METHOD_VR + 1)?;
        self.reals.get(index as usize).copied()
    }

    /// Runs the passes needed for outputs beyond θ and ν, once per state.
    fn evaluate(&mut self, needed: Evaluated) -> Result<(), CallError> {
        if self.evaluated >= needed {
            return Ok(());
        }
        let model = &self.model;
        let time = self.sim.state.time;
        let ws = self.sim.evaluate_velocity(model).map_err(CallError::Evaluate)?;
        if self.layout.outputs.has("momentum") {
            let momentum = ws.momentum(model).map_err(CallError::Evaluate)?;
            self.momentum.iter_mut().zip(momentum.iter()).for_each(|(m, x)| *m = *x);
        }
        self.evaluated = Evaluated::Velocity;
        if needed >= Evaluated::Acceleration {
            ws.compute_nu_dot_actuated(model, &self.eps, &self.ctrl).map_err(CallError::Evaluate)?;
            self.evaluated = Evaluated::Acceleration;
        }
        if needed == Evaluated::Sensors {
            ws.compute_sensors(model, &self.eps, &self.ctrl, time).map_err(CallError::Evaluate)?;
            self.evaluated = Evaluated::Sensors;
        }
        Ok(())
    }

    /// The margins of the held constraint mode at the current state, into `margins`.
    fn held_margins(&mut self) -> Result<(), CallError> {
        self.evaluate(Evaluated::Acceleration)?;
        self.theta_scratch.copy_from_slice(&self.sim.state.theta);
        let ws = self.sim.workspace_mut();
        self.mode.margins(&self.model, ws, &self.theta_scratch, &mut self.margins).map_err(CallError::Evaluate)?;
        if !self.model.constraints.tendon_limits.is_empty() {
            // The tendons' lengths ran passes 0 and 1 again.
            self.evaluated = Evaluated::Nothing;
        }
        Ok(())
    }

    /// The event indicators into `indicators`, for a read of the variable
    /// `constraint_switch`. Read outside model exchange's events (in
    /// co-simulation, or before the first event) the mode set to compute
    /// them is let go again, so that the next step or event finds the
    /// state's own mode as it would have without the read.
    fn read_event_indicators(&mut self) -> Result<(), CallError> {
        let held = self.mode_held;
        let mut indicators = std::mem::take(&mut self.indicators);
        let read = self.event_indicators(&mut indicators);
        self.indicators = indicators;
        if !held {
            self.sim.workspace_mut().release_limit_sides();
            self.mode_held = false;
            self.evaluated = Evaluated::Nothing;
        }
        read
    }

    /// The sizes of the state an FMU state of this plant holds.
    fn sizes(&self) -> Sizes {
        Sizes {
            nq: self.model.nq,
            nv: self.model.nv,
            nu: self.model.actuators.len(),
            na: self.model.activation_count(),
        }
    }

    /// d(qpos[k])/dt from the workspace's θ̇ (passes 0–2 done).
    fn qpos_rate(&self, k: usize) -> f64 {
        let ws = self.sim.workspace();
        qpos_rate(&self.model, ws.theta.as_slice(), ws.qvel.as_slice(), k)
    }

    /// Whether θ̇ (the integrated velocity, which the next doStep goes on
    /// from) and ν of a saved run are one velocity, ν = m*(θ)θ̇, to
    /// round-off: a blob where they disagree (a forged θ̇ of 1e270 beside
    /// ν = 0 took 100 000 steps of 1e-9 s, 6 s, before its doStep failed) is
    /// refused. Checked in a workspace of its own, so that a refusal leaves
    /// the instance (and the outputs it reads) as it was.
    fn check_velocities(&mut self, run: &RunState) -> Result<(), CallError> {
        let model = &self.model;
        let ws = self.restore_check.get_or_insert_with(|| Box::new(model.workspace()));
        ws.set_configuration(model, &run.theta).map_err(CallError::Evaluate)?;
        ws.set_qvel(model, &run.qvel[..model.nv]).map_err(CallError::Evaluate)?;
        let scale = 1.0 + run.nu.iter().chain(ws.nu.iter()).fold(0.0f64, |m, x| m.max(x.abs()));
        match run.nu.iter().zip(ws.nu.iter()).find(|(saved, of_qvel)| (*saved - *of_qvel).abs() > 1e-9 * scale) {
            Some((&value, _)) => {
                let must = "m*(theta) qvel, the nu of the state's own theta and qvel, to round-off";
                Err(SnapshotError::Value { what: "a value of nu", value, must }.into())
            }
            None => Ok(()),
        }
    }
}

impl Component for Plant {
    fn capabilities(&self) -> Capabilities {
        capabilities(self.layout.outputs)
    }

    fn reset(&mut self) {
        self.sim = Simulation::new(&self.model, self.start_method, DEFAULT_SETTINGS);
        self.start_time = 0.0;
        self.stop_time = None;
        self.initial_energy = 0.0;
        self.eps.fill(0.0);
        self.eps_rate.fill(0.0);
        self.ctrl.fill(0.0);
        self.ctrl_rate.fill(0.0);
        self.evaluated = Evaluated::Nothing;
        self.failed_for_good = false;
        self.experiment_tolerance = None;
        self.mode_held = false;
        self.set_starts();
    }

    fn time(&self) -> f64 {
        self.sim.state.time
    }

    fn stop_time(&self) -> Option<f64> {
        self.stop_time
    }

    /// The start time becomes the current time.
    fn setup_experiment(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) {
        self.experiment_tolerance = tolerance;
        self.start_time = start_time;
        self.sim.state.time = start_time;
        self.stop_time = stop_time;
        // No internal step reaches past the stop time.
        self.sim.set_horizon(stop_time);
    }

    /// Checks the initial state set by the master and normalizes its
    /// quaternions, as MuJoCo does. A tolerance from fmi2SetupExperiment
    /// takes the place of the `tolerance` parameter, which then reads back
    /// the tolerance in effect; a different one is noted, since hosts pass
    /// their own default (OMSimulator and PyFMI: 1e-4) without saying so.
    fn initialize(&mut self) -> Result<Option<String>, CallError> {
        self.sim.initialize(&self.model).map_err(CallError::InitialState)?;
        let own = self.sim.settings.tolerance;
        let note = self.experiment_tolerance.filter(|&tolerance| tolerance != own).map(|tolerance| {
            format!(
                "the tolerance {tolerance:e} the host passed (fmi2SetupExperiment, fmi3EnterInitializationMode) \
                 replaces the FMU's tolerance parameter {own:e}: the error is held to {tolerance:e} per second"
            )
        });
        if let Some(tolerance) = self.experiment_tolerance {
            self.sim.settings.tolerance = tolerance;
        }
        self.initial_energy = kinetic_energy(&self.sim.state.nu);
        self.evaluated = Evaluated::Nothing;
        Ok(note)
    }

    fn dependencies(&self, vr: u32) -> Option<Vec<u32>> {
        self.layout.dependency_vrs(vr)
    }

    fn real_variable(&self, vr: u32) -> Option<Variable> {
        let (variable, kind) = self.real_with_kind(vr)?;
        Some(Variable { name: self.layout.name(variable)?, kind })
    }

    fn real_kind(&self, vr: u32) -> Option<Kind> {
        self.real_with_kind(vr).map(|(_, kind)| kind)
    }

    fn set_reals(&mut self, vrs: &[u32], values: &[f64]) {
        for (&vr, &value) in vrs.iter().zip(values) {
            let variable = self.real(vr).expect("checked by the caller");
            let (run, settings) = (&mut self.sim.state, &mut self.sim.settings);
            match variable {
                RealVariable::Tolerance => settings.tolerance = value,
                RealVariable::MaxStep => settings.max_step = value,
                RealVariable::Eps(k) => self.eps[k] = value,
                RealVariable::Ctrl(k) => self.ctrl[k] = value,
                RealVariable::XfrcApplied(k) => self.ctrl[self.layout.nu + k] = value,
                RealVariable::Theta(k) => run.theta[k] = value,
                RealVariable::Nu(k) => run.nu[k] = value,
                RealVariable::Act(k) => self.sim.act_mut(&self.model)[k] = value,
                variable => unreachable!("{variable:?} is a calculated output: the caller refuses it"),
            }
        }
        self.evaluated = Evaluated::Nothing;
    }

    fn prepare_reals(&mut self, vrs: &[u32]) -> Result<Option<String>, CallError> {
        // One pass over the references: a host reads θ and ν after every step.
        let needed = vrs.iter().filter_map(|&vr| self.real(vr)).fold(Evaluated::Nothing, |needed, v| {
            needed.max(match v {
                RealVariable::Sensordata(_) => Evaluated::Sensors,
                RealVariable::QfrcConstraint(_) => Evaluated::Acceleration,
                v if v.is_derivative() => Evaluated::Acceleration,
                RealVariable::Qvel(_) | RealVariable::Momentum(_) => Evaluated::Velocity,
                _ => Evaluated::Nothing,
            })
        });
        if needed > Evaluated::Nothing {
            self.evaluate(needed)?;
        }
        if vrs.iter().any(|&vr| matches!(self.real(vr), Some(RealVariable::ConstraintSwitch(_)))) {
            self.read_event_indicators()?;
        }
        Ok(None)
    }

    fn real_value(&self, vr: u32) -> f64 {
        let (run, settings) = (&self.sim.state, &self.sim.settings);
        match self.real(vr).expect("checked by the caller") {
            RealVariable::Tolerance => settings.tolerance,
            RealVariable::MaxStep => settings.max_step,
            RealVariable::Eps(k) => self.eps[k],
            RealVariable::Ctrl(k) => self.ctrl[k],
            RealVariable::XfrcApplied(k) => self.ctrl[self.layout.nu + k],
            RealVariable::Theta(k) => run.theta[k],
            RealVariable::Nu(k) => run.nu[k],
            RealVariable::Sensordata(k) => self.sim.workspace().sensordata[k],
            RealVariable::Qvel(k) => self.sim.workspace().qvel[k],
            RealVariable::KineticEnergy => kinetic_energy(&run.nu),
            RealVariable::Power => run.nu.iter().zip(&self.eps).map(|(n, e)| n * e).sum(),
            RealVariable::Momentum(k) => self.momentum[k],
            RealVariable::EnergyResidual => kinetic_energy(&run.nu) - self.initial_energy - run.carry.work,
            RealVariable::ModalStrainEnergy => self.model.strain_energy(&run.theta),
            // A vehicle without constraints keeps no rows: its constraint forces are 0.
            RealVariable::QfrcConstraint(k) => {
                self.sim.workspace().constraint_rows.qfrc_constraint.get(k).copied().unwrap_or(0.0)
            }
            RealVariable::ConstraintSwitch(k) => self.indicators[k],
            RealVariable::DerTheta(k) => self.qpos_rate(k),
            RealVariable::DerNu(k) => self.sim.workspace().nu_dot[k],
            RealVariable::Act(k) => self.sim.act(&self.model)[k],
            RealVariable::DerAct(k) => self.sim.workspace().act_rate_within_range(&self.model, k),
        }
    }

    /// The enumeration parameter `method`.
    fn get_integer(&self, vrs: &[u32], values: &mut [i32]) -> Result<(), CallError> {
        if let Some(&vr) = vrs.iter().find(|&&vr| vr != METHOD_VR) {
            return Err(CallError::UnknownValueReference { vr, kind: "Integer" });
        }
        values.fill(method_value(self.sim.method_setting()));
        Ok(())
    }

    /// `method`, before initialization, to an item of its enumeration.
    fn set_integer(&mut self, vrs: &[u32], values: &[i32], initialized: bool) -> Result<(), CallError> {
        for (&vr, &value) in vrs.iter().zip(values) {
            if vr != METHOD_VR {
                return Err(CallError::UnknownValueReference { vr, kind: "Integer" });
            }
            if initialized {
                return Err(CallError::NotSettable { name: "method".into(), vr, when: "after initialization" });
            }
            if method_of_value(value).is_none() {
                return Err(CallError::UnknownMethod(value));
            }
        }
        if let Some(method) = values.last().and_then(|&v| method_of_value(v)) {
            self.sim.set_method(&self.model, method);
        }
        Ok(())
    }

    /// The only Boolean variable, the parameter `energy_projection`.
    fn get_boolean(&self, vrs: &[u32], values: &mut [bool]) -> Result<(), CallError> {
        if let Some(&vr) = vrs.iter().find(|&&vr| vr != ENERGY_PROJECTION_VR) {
            return Err(CallError::UnknownValueReference { vr, kind: "Boolean" });
        }
        values.fill(self.sim.settings.energy_projection);
        Ok(())
    }

    /// `energy_projection`, before initialization.
    fn set_boolean(&mut self, vrs: &[u32], values: &[bool], initialized: bool) -> Result<(), CallError> {
        for &vr in vrs {
            if vr != ENERGY_PROJECTION_VR {
                return Err(CallError::UnknownValueReference { vr, kind: "Boolean" });
            }
            if initialized {
                return Err(CallError::NotSettable {
                    name: "energy_projection".into(),
                    vr,
                    when: "after initialization",
                });
            }
        }
        if let Some(&value) = values.last() {
            self.sim.settings.energy_projection = value;
        }
        Ok(())
    }

    /// dε/dt and the controls' rates for the next step.
    fn set_input_derivatives(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), CallError> {
        for (&vr, &value) in vrs.iter().zip(values) {
            match self.real(vr) {
                Some(RealVariable::Eps(k)) => self.eps_rate[k] = value,
                Some(RealVariable::Ctrl(k)) => self.ctrl_rate[k] = value,
                Some(RealVariable::XfrcApplied(k)) => self.ctrl_rate[self.layout.nu + k] = value,
                _ => {}
            }
        }
        Ok(())
    }

    /// d(theta)/dt, the qpos rate, and d(nu)/dt = ν̇ at the current inputs.
    fn prepare_output_derivatives(&mut self) -> Result<(), CallError> {
        self.evaluate(Evaluated::Acceleration)
    }

    fn output_derivative(&self, vr: u32) -> f64 {
        match self.real(vr) {
            Some(RealVariable::Theta(k)) => self.qpos_rate(k),
            Some(RealVariable::Nu(k)) => self.sim.workspace().nu_dot[k],
            variable => unreachable!("{variable:?} is not a state output: the caller refuses it"),
        }
    }

    /// Refuses a step that `max_step` alone would cut into more internal
    /// steps than one advance may take (`nudyn::integrate::MAX_STEPS`).
    fn check_step_size(&self, step: f64) -> Result<(), CallError> {
        self.sim.settings.check_interval(self.sim.method(), step).map_err(CallError::TooLong)
    }

    /// Integrates from `time` to `time + step` with the chosen method
    /// (internal steps independent of the communication step), with
    /// ε(t) = ε + dε/dt·(t − time), and the controls likewise; the ramps
    /// apply to this step only. With the inputs as at the last step and
    /// no ramp, an adaptive method with a dense output goes on from where
    /// its last step ended, past `time`, and the state at `time + step`
    /// is its interpolant (docs/integration.md, "Steps past the
    /// communication point").
    /// If the integration stops inside the step, the state stays at the
    /// last successful internal step and the time says where. A step that
    /// completed only by relaxing the tolerance says so.
    fn do_step(&mut self, time: f64, step: f64) -> Result<Option<StepReport>, StepError> {
        // The master's communication point, within round-off of the plant's time, is where the step starts.
        self.sim.state.time = time;
        let input = Input { eps: &self.eps, eps_rate: &self.eps_rate, ctrl: &self.ctrl, ctrl_rate: &self.ctrl_rate };
        let result = self.sim.advance_to(&self.model, time + step, input);
        self.evaluated = Evaluated::Nothing;
        match result {
            Ok(advanced) => {
                self.eps_rate.fill(0.0);
                self.ctrl_rate.fill(0.0);
                Ok(Some(StepReport {
                    stats: advanced.stats,
                    relaxed: advanced.relaxed,
                    chose: advanced.chose,
                    moved: advanced.moved,
                    held: advanced.held,
                }))
            }
            Err(source) => {
                self.failed_for_good = source.is_non_finite();
                Err(StepError { time, step, source })
            }
        }
    }

    fn failed_for_good(&self) -> bool {
        self.failed_for_good
    }

    /// x = (θ, ν, act): nq + nv + na states.
    fn continuous_state_count(&self) -> Option<usize> {
        let count = self.model.nq + self.model.nv + self.model.activation_count();
        serves_model_exchange(self.layout.outputs).then_some(count)
    }

    fn set_time(&mut self, time: f64) {
        self.sim.state.time = time;
        // The clock sensors read the time.
        self.evaluated = self.evaluated.min(Evaluated::Acceleration);
    }

    fn continuous_states(&self, x: &mut [f64]) {
        let (theta, rest) = x.split_at_mut(self.model.nq);
        let (nu, act) = rest.split_at_mut(self.model.nv);
        theta.copy_from_slice(&self.sim.state.theta);
        nu.copy_from_slice(&self.sim.state.nu);
        act.copy_from_slice(self.sim.act(&self.model));
    }

    /// Takes the host's states as they are: a quaternion the host's
    /// integration moved off unit length stays so in x, and the passes use
    /// it normalized, so the drift never changes the motion.
    fn set_continuous_states(&mut self, x: &[f64]) {
        let (theta, rest) = x.split_at(self.model.nq);
        let (nu, act) = rest.split_at(self.model.nv);
        self.sim.state.theta.copy_from_slice(theta);
        self.sim.state.nu.copy_from_slice(nu);
        self.sim.act_mut(&self.model).copy_from_slice(act);
        self.evaluated = Evaluated::Nothing;
    }

    fn prepare_derivatives(&mut self) -> Result<(), CallError> {
        self.evaluate(Evaluated::Acceleration)
    }

    /// (θ̇, ν̇, act's rate); a quaternion's rate is ½ q ⊗ (0, ω) of the
    /// normalized q, orthogonal to q, so the host's integration does not
    /// grow the drift; act's rate is 0 where act is at a bound it would
    /// leave, so that the host keeps act within its range as MuJoCo does.
    fn derivative(&self, i: usize) -> f64 {
        let (nq, nv) = (self.model.nq, self.model.nv);
        let ws = self.sim.workspace();
        if i < nq {
            self.qpos_rate(i)
        } else if i < nq + nv {
            ws.nu_dot[i - nq]
        } else {
            ws.act_rate_within_range(&self.model, i - nq - nv)
        }
    }

    fn snapshot(&self, phase: Phase) -> Result<Snapshot, CallError> {
        let state = PlantState {
            run: self.sim.state.clone(),
            settings: self.sim.settings,
            method: self.sim.method_setting(),
            start_time: self.start_time,
            stop_time: self.stop_time,
            initial_energy: self.initial_energy,
            eps: self.eps.clone(),
            eps_rate: self.eps_rate.clone(),
            ctrl: self.ctrl.clone(),
            ctrl_rate: self.ctrl_rate.clone(),
            jacobian: HeldJacobian::default(),
        };
        let mut snapshot = Snapshot { phase, guid: self.guid.clone(), state };
        self.sim.save_jacobian(&mut snapshot.state.jacobian);
        Ok(snapshot)
    }

    /// Saves into `snapshot`, reusing its buffers.
    fn save(&self, phase: Phase, snapshot: &mut Snapshot) -> Result<(), CallError> {
        snapshot.phase = phase;
        snapshot.guid.clone_from(&self.guid);
        let state = &mut snapshot.state;
        state.run.clone_from(&self.sim.state);
        state.settings = self.sim.settings;
        state.method = self.sim.method_setting();
        state.start_time = self.start_time;
        state.stop_time = self.stop_time;
        state.initial_energy = self.initial_energy;
        state.eps.clone_from(&self.eps);
        state.eps_rate.clone_from(&self.eps_rate);
        state.ctrl.clone_from(&self.ctrl);
        state.ctrl_rate.clone_from(&self.ctrl_rate);
        self.sim.save_jacobian(&mut state.jacobian);
        Ok(())
    }

    /// A state of another FMU is refused.
    fn restore(&mut self, snapshot: &Snapshot) -> Result<(), CallError> {
        let state = &snapshot.state;
        let (nv, nu) = (state.run.nu.len(), state.ctrl.len());
        let na = state.run.qvel.len().saturating_sub(nv);
        let sizes = Sizes { nq: state.run.theta.len(), nv, nu, na };
        if snapshot.guid != self.guid {
            return Err(SnapshotError::ForeignGuid { found: snapshot.guid.clone(), expected: self.guid.clone() }.into());
        }
        let expected = self.sizes();
        if sizes != expected {
            return Err(SnapshotError::Sizes { found: sizes, expected }.into());
        }
        let rows = state.run.reach.working_set.len();
        if rows > self.model.constraints.max_rows() {
            let (what, must) = ("the rows of a working set", "at most the vehicle's constraint rows");
            return Err(SnapshotError::Value { what, value: rows as f64, must }.into());
        }
        // Where a doStep may follow: before it, θ̇ is formed from ν at the
        // initialization, and model exchange forms it from the states it is given.
        if matches!(snapshot.phase, Phase::StepComplete | Phase::StepFailed) {
            self.check_velocities(&state.run)?;
        }
        self.sim.settings = state.settings;
        // The method first: changing it drops W, which the restore then holds.
        self.sim.set_method(&self.model, state.method);
        self.sim.restore(&self.model, &state.run, &state.jacobian);
        self.start_time = state.start_time;
        self.stop_time = state.stop_time;
        self.sim.set_horizon(state.stop_time);
        self.initial_energy = state.initial_energy;
        self.eps.clone_from(&state.eps);
        self.eps_rate.clone_from(&state.eps_rate);
        self.ctrl.clone_from(&state.ctrl);
        self.ctrl_rate.clone_from(&state.ctrl_rate);
        self.evaluated = Evaluated::Nothing;
        self.failed_for_good = false;
        // The mode held belongs to the state replaced: the next event sets it anew.
        self.sim.workspace_mut().release_limit_sides();
        self.mode_held = false;
        Ok(())
    }

    /// The elements of `constraint_switch` (none without model exchange).
    fn event_indicator_count(&self) -> usize {
        self.layout.event_indicator_count()
    }

    /// The margins of the constraint mode held since the last event, each
    /// less its level of switching: negative once the constraint forces
    /// are no longer MuJoCo's (a limit side, a force's bound or an
    /// impedance piece crossed), when the host must locate the crossing
    /// and call fmi2NewDiscreteStates there.
    fn event_indicators(&mut self, out: &mut [f64]) -> Result<(), CallError> {
        if !self.mode_held {
            self.update_discrete_states()?;
        }
        self.held_margins()?;
        for (k, (indicator, &margin)) in out.iter_mut().zip(&self.margins).enumerate() {
            let distance = self.mode.distance(k, margin);
            // A row that is not there has no switch: any positive value says so.
            *indicator = if distance.is_finite() { distance } else { 1.0 };
        }
        Ok(())
    }

    /// Sets the constraint mode the state gives (MuJoCo's own forces here),
    /// held until the next event. At an event the host located, a force
    /// whose margin has crossed starts the solve on the far side of its
    /// bound: found from scratch a hair past the switch, the working set
    /// could be the old one again, and its indicator would then stay below
    /// zero, where the host sees no further crossing.
    fn update_discrete_states(&mut self) -> Result<bool, CallError> {
        if self.mode.is_empty() {
            return Ok(false);
        }
        if self.mode_held {
            self.held_margins()?;
            let sides = self.mode.sides();
            let ws = self.sim.workspace_mut();
            for k in sides..sides + self.model.constraints.max_rows() {
                if self.mode.distance(k, self.margins[k]) < 0.0 {
                    ws.cross_working_set(k - sides);
                }
            }
        }
        let model = &self.model;
        self.theta_scratch.copy_from_slice(&self.sim.state.theta);
        self.mode.hold_sides(model, self.sim.workspace_mut(), &self.theta_scratch).map_err(CallError::Evaluate)?;
        let ws = self.sim.evaluate_velocity(model).map_err(CallError::Evaluate)?;
        ws.compute_nu_dot_actuated(model, &self.eps, &self.ctrl).map_err(CallError::Evaluate)?;
        self.mode.hold_working_set(ws, &mut self.margins);
        self.mode_held = true;
        // The evaluation just made is the held mode's at this state.
        self.evaluated = Evaluated::Acceleration;
        Ok(true)
    }

    fn partials(&self) -> Result<(), CallError> {
        self.partials.covered()
    }

    /// At the current state and inputs ε, exact (crate::partials).
    fn directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Result<(), CallError> {
        let (model, layout, state) = (&self.model, &self.layout, &self.sim.state);
        let evaluated = self.sim.workspace();
        let rows = &evaluated.constraint_rows;
        let (theta, nu, act, time) = (&state.theta, &state.nu, self.sim.act(model), state.time);
        let at = At { model, layout, theta, nu, eps: &self.eps, ctrl: &self.ctrl, act, rows, time, evaluated };
        self.partials.directional(&at, unknowns, knowns, seed, sensitivity)
    }

    fn adjoint_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Result<(), CallError> {
        let (model, layout, state) = (&self.model, &self.layout, &self.sim.state);
        let evaluated = self.sim.workspace();
        let rows = &evaluated.constraint_rows;
        let (theta, nu, act, time) = (&state.theta, &state.nu, self.sim.act(model), state.time);
        let at = At { model, layout, theta, nu, eps: &self.eps, ctrl: &self.ctrl, act, rows, time, evaluated };
        self.partials.adjoint(&at, unknowns, knowns, seed, sensitivity)
    }

    fn deserialize(&self, bytes: &[u8]) -> Result<Snapshot, CallError> {
        Ok(Snapshot::deserialize(bytes, &self.guid, self.sizes())?)
    }
}
