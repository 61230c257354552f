//! The plant's partial derivatives (fmi2GetDirectionalDerivative,
//! fmi3GetDirectionalDerivative, fmi3GetAdjointDerivative): exact, by the
//! passes run in dual numbers (`nudyn::dynamics::derivatives`), one run
//! per direction.
//!
//! The knowns are the states θ, ν and act and the inputs ε, ctrl and the
//! wrench inputs (FMI 2.0 §2.2.8 and FMI 3.0 §2.4.8 list the continuous
//! states and the inputs as the knowns of `<Outputs>` and `<Derivatives>`,
//! at communication points too);
//! directions in θ are along θ's coordinates, the FMU's variables, a
//! quaternion's component along itself having no effect (the passes
//! normalize it). The unknowns are the continuous outputs (sensordata
//! among them) and the state derivatives. The adjoint Jᵀv is taken column by column of the forward
//! mode: one run per known.

use nudyn::dynamics::DynamicsError;
use nudyn::dynamics::constraint::ConstraintRows;
use nudyn::dynamics::derivatives::{DerivativeError, Derivatives, Direction, Output, Point, ThetaDirection};
use nudyn::dynamics::velocity::Given;
use nudyn::model::Model;
use nudyn::workspace::Workspace;
use nudyn_contract::plant::{Layout, RealVariable, derivatives_cover};

use crate::component::CallError;

/// The point the derivatives are taken at: the plant's model, its FMU's
/// variables, its state and inputs.
pub struct At<'a> {
    /// The model.
    pub model: &'a Model,
    /// The FMU's variables.
    pub layout: &'a Layout,
    /// θ.
    pub theta: &'a [f64],
    /// ν.
    pub nu: &'a [f64],
    /// ε.
    pub eps: &'a [f64],
    /// The actuators' controls and the wrench inputs' values (MuJoCo's
    /// ctrl, then xfrc_applied), as the plant applies them.
    pub ctrl: &'a [f64],
    /// The activation states (MuJoCo's act).
    pub act: &'a [f64],
    /// The constraint rows of the plant's evaluations, whose held mode
    /// (between events in model exchange) the derivatives hold.
    pub rows: &'a ConstraintRows,
    /// The time, which the clock sensors read.
    pub time: f64,
    /// The plant's evaluations' workspace, whose configuration the
    /// derivatives take where it was evaluated at θ.
    pub evaluated: &'a Workspace,
}

/// The dual workspace, or why the FMU has no derivatives, and the buffers
/// of one direction and its results, made at the first call (an instance
/// nobody asks for derivatives holds none).
pub struct Partials {
    /// The dual workspace once made (`Ok(None)` before the first call), or
    /// why the FMU has none (logged on every call).
    derivatives: Result<Option<Derivatives>, String>,
    /// The direction along θ, ν, ε, the controls (ctrl, then the
    /// wrench inputs) and act.
    theta: Vec<f64>,
    nu: Vec<f64>,
    eps: Vec<f64>,
    ctrl: Vec<f64>,
    act: Vec<f64>,
    /// The physical joint forces' direction: always 0 (T is no variable of the FMU).
    torque: Vec<f64>,
    /// The derivatives of θ̇ and ν̇ along the last direction.
    qvel: Vec<f64>,
    nu_dot: Vec<f64>,
    /// The sensors' derivatives along the last direction, when an unknown is one.
    sensordata: Vec<f64>,
    /// The momentum's derivative along the last direction, when an unknown is one of it.
    momentum: [f64; 6],
}

impl Partials {
    /// The partials of a plant whose FMU has the variables of `layout`.
    pub fn new(layout: &Layout) -> Self {
        let derivatives = derivatives_cover(layout.outputs).map(|()| None).map_err(|why| why.to_string());
        Partials {
            derivatives,
            theta: Vec::new(),
            nu: Vec::new(),
            eps: Vec::new(),
            ctrl: Vec::new(),
            act: Vec::new(),
            torque: Vec::new(),
            qvel: Vec::new(),
            nu_dot: Vec::new(),
            sensordata: Vec::new(),
            momentum: [0.0; 6],
        }
    }

    /// `sensitivity` = J `seed`: the derivatives of `unknowns` along the
    /// direction `seed` of `knowns` (FMI 2.0 value references).
    pub fn directional(
        &mut self,
        at: &At,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Result<(), CallError> {
        let (unknowns, knowns) = classify_both(at.layout, unknowns, knowns)?;
        let reads = Reads::of(&unknowns);
        self.run(at, knowns.iter().copied().zip(seed.iter().copied()), reads)?;
        for (out, &variable) in sensitivity.iter_mut().zip(&unknowns) {
            *out = self.derivative(at, variable);
        }
        Ok(())
    }

    /// `sensitivity` = Jᵀ `seed`: `seed` along `unknowns`, `sensitivity`
    /// along `knowns`; one forward run per known.
    pub fn adjoint(
        &mut self,
        at: &At,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Result<(), CallError> {
        let (unknowns, knowns) = classify_both(at.layout, unknowns, knowns)?;
        let reads = Reads::of(&unknowns);
        for (out, &variable) in sensitivity.iter_mut().zip(&knowns) {
            self.run(at, [(variable, 1.0)].into_iter(), reads)?;
            *out = unknowns.iter().zip(seed).map(|(&u, s)| s * self.derivative(at, u)).sum();
        }
        Ok(())
    }

    /// Refuses the call if the FMU has no derivatives, with why.
    pub fn covered(&self) -> Result<(), CallError> {
        self.derivatives.as_ref().map(|_| ()).map_err(|why| CallError::NoPartials(why.clone()))
    }

    /// Runs the passes at `at` along the direction of the (known, seed)
    /// pairs, and the sensors and the momentum too where `reads` says.
    fn run(
        &mut self,
        at: &At,
        direction: impl Iterator<Item = (RealVariable, f64)>,
        reads: Reads,
    ) -> Result<(), CallError> {
        let derivatives = self.derivatives.as_mut().map_err(|why| CallError::NoPartials(why.clone()))?;
        let model = at.model;
        if derivatives.is_none() {
            let made = Derivatives::new(model);
            *derivatives = Some(made);
            let controls = model.actuators.len();
            for (buffer, n) in [
                (&mut self.theta, model.nq),
                (&mut self.nu, model.nv),
                (&mut self.eps, model.nv),
                (&mut self.ctrl, controls),
                (&mut self.act, model.activation_count()),
            ] {
                buffer.resize(n, 0.0);
            }
            for buffer in [&mut self.torque, &mut self.qvel, &mut self.nu_dot] {
                buffer.resize(model.nv, 0.0);
            }
            self.sensordata.resize(Output::Sensordata.len(model), 0.0);
        }
        let derivatives = derivatives.as_mut().expect("made above");
        derivatives.hold_constraint_mode_of(at.rows);
        for buffer in [&mut self.theta, &mut self.nu, &mut self.eps, &mut self.ctrl, &mut self.act] {
            buffer.fill(0.0);
        }
        let wrench_inputs = model.mjcf_actuator_count();
        for (variable, seed) in direction {
            match variable {
                RealVariable::Theta(k) => self.theta[k] += seed,
                RealVariable::Nu(k) => self.nu[k] += seed,
                RealVariable::Eps(k) => self.eps[k] += seed,
                RealVariable::Ctrl(k) => self.ctrl[k] += seed,
                RealVariable::XfrcApplied(k) => self.ctrl[wrench_inputs + k] += seed,
                RealVariable::Act(k) => self.act[k] += seed,
                other => unreachable!("{other:?} is not a known: classified before"),
            }
        }
        let point = Point {
            theta: at.theta,
            velocity: at.nu,
            given: Given::Nu,
            eps: at.eps,
            torque: &self.torque,
            ctrl: at.ctrl,
            act: at.act,
            time: at.time,
        };
        let direction = Direction {
            theta: &self.theta,
            theta_in: ThetaDirection::Coordinates,
            velocity: &self.nu,
            eps: &self.eps,
            torque: &self.torque,
            ctrl: &self.ctrl,
            act: &self.act,
        };
        let mut outputs = [Output::NuDot; 3];
        let mut count = 1;
        for (read, output) in [(reads.sensors, Output::Sensordata), (reads.momentum, Output::Momentum)] {
            if read {
                outputs[count] = output;
                count += 1;
            }
        }
        derivatives.run_after(at.model, at.evaluated, &point, &direction, &outputs[..count]).map_err(|error| {
            match error {
                DerivativeError::Dynamics(error) => CallError::Evaluate(error),
                DerivativeError::OnSwitch(switches) => CallError::OneSided(switches),
                other => unreachable!("the directions are sized by the model: {other}"),
            }
        })?;
        for (out, d) in self.qvel.iter_mut().zip(derivatives.derivative(Output::Qvel)) {
            *out = d;
        }
        for (out, d) in self.nu_dot.iter_mut().zip(derivatives.derivative(Output::NuDot)) {
            *out = d;
        }
        // A derivative that is not a number is a status, not a result.
        let rates = self.qvel.iter().chain(&self.nu_dot);
        if let Some((index, &value)) = rates.enumerate().find(|(_, d)| !d.is_finite()) {
            return Err(CallError::Evaluate(DynamicsError::NonFinite {
                what: "the derivative of (qvel, der(nu))",
                index,
                value,
            }));
        }
        if reads.momentum {
            copy_finite(&mut self.momentum, derivatives.derivative(Output::Momentum), "the derivative of momentum")?;
        }
        if reads.sensors {
            let derivative = derivatives.derivative(Output::Sensordata);
            copy_finite(&mut self.sensordata, derivative, "the derivative of sensordata")?;
        }
        Ok(())
    }

    /// The derivative of the unknown `variable` along the last run's direction.
    fn derivative(&self, at: &At, variable: RealVariable) -> f64 {
        let Ok(Some(derivatives)) = &self.derivatives else { unreachable!("a run made the workspace") };
        match variable {
            RealVariable::Theta(k) => self.theta[k],
            RealVariable::Nu(k) => self.nu[k],
            RealVariable::Act(k) => self.act[k],
            RealVariable::DerAct(k) => derivatives.act_rate_within_range_derivative(at.model, k),
            RealVariable::Qvel(k) => self.qvel[k],
            RealVariable::DerTheta(k) => derivatives.qpos_rate_derivative(at.model, k),
            RealVariable::DerNu(k) => self.nu_dot[k],
            // K = ½|ν|²; P = ν·ε.
            RealVariable::KineticEnergy => at.nu.iter().zip(&self.nu).map(|(n, d)| n * d).sum(),
            RealVariable::Power => {
                at.nu.iter().zip(&self.eps).map(|(n, d)| n * d).sum::<f64>()
                    + self.nu.iter().zip(at.eps).map(|(d, e)| d * e).sum::<f64>()
            }
            RealVariable::QfrcConstraint(k) => derivatives.qfrc_constraint_derivative(k),
            RealVariable::Sensordata(k) => self.sensordata[k],
            RealVariable::Momentum(k) => self.momentum[k],
            RealVariable::ModalStrainEnergy => at.model.strain_energy_derivative(at.theta, &self.theta),
            other => unreachable!("{other:?} is not an unknown: classified before"),
        }
    }
}

/// Copies `derivative` into `out`; a derivative that is not a number is a
/// status naming `what`, not a result.
fn copy_finite(out: &mut [f64], derivative: impl Iterator<Item = f64>, what: &'static str) -> Result<(), CallError> {
    for (out, d) in out.iter_mut().zip(derivative) {
        *out = d;
    }
    match out.iter().enumerate().find(|(_, d)| !d.is_finite()) {
        Some((index, &value)) => Err(CallError::Evaluate(DynamicsError::NonFinite { what, index, value })),
        None => Ok(()),
    }
}

/// Which outputs beyond θ̇ and ν̇ a run computes: those some unknown is an entry of.
#[derive(Clone, Copy)]
struct Reads {
    sensors: bool,
    momentum: bool,
}

impl Reads {
    fn of(unknowns: &[RealVariable]) -> Self {
        Reads {
            sensors: unknowns.iter().any(|u| matches!(u, RealVariable::Sensordata(_))),
            momentum: unknowns.iter().any(|u| matches!(u, RealVariable::Momentum(_))),
        }
    }
}

/// The unknowns' and the knowns' variables, each checked for its role.
fn classify_both(
    layout: &Layout,
    unknowns: &[u32],
    knowns: &[u32],
) -> Result<(Vec<RealVariable>, Vec<RealVariable>), CallError> {
    Ok((classify(layout, unknowns, Role::Unknown)?, classify(layout, knowns, Role::Known)?))
}

fn classify(layout: &Layout, vrs: &[u32], role: Role) -> Result<Vec<RealVariable>, CallError> {
    vrs.iter()
        .map(|&vr| {
            let variable = layout.real_variable(vr).ok_or(CallError::UnknownValueReference { vr, kind: "Real" })?;
            if role.admits(variable) {
                Ok(variable)
            } else {
                let name = layout.name(variable).expect("the layout's own variable");
                Err(CallError::NotPartial { name, vr, role: role.describe() })
            }
        })
        .collect()
}

/// Which side of a partial derivative a variable is passed as.
#[derive(Clone, Copy)]
enum Role {
    Known,
    Unknown,
}

impl Role {
    /// Whether `variable` can be one: a known is a continuous state or
    /// input; an unknown a continuous output or a state derivative.
    fn admits(self, variable: RealVariable) -> bool {
        use RealVariable::*;
        match self {
            Role::Known => matches!(variable, Theta(_) | Nu(_) | Act(_) | Eps(_) | Ctrl(_) | XfrcApplied(_)),
            Role::Unknown => matches!(
                variable,
                Theta(_)
                    | Nu(_)
                    | Act(_)
                    | DerAct(_)
                    | Sensordata(_)
                    | Qvel(_)
                    | DerTheta(_)
                    | DerNu(_)
                    | KineticEnergy
                    | Power
                    | Momentum(_)
                    | ModalStrainEnergy
                    | QfrcConstraint(_)
            ),
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Role::Known => {
                "a known of the partial derivatives (the states theta, nu and act, the inputs eps, ctrl and xfrc_applied)"
            }
            Role::Unknown => {
                "an unknown of the partial derivatives (the outputs theta, nu, act, sensordata, qvel, \
                 kinetic_energy, power, momentum, modal_strain_energy, qfrc_constraint and the state derivatives)"
            }
        }
    }
}
