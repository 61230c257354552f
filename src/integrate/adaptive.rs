//! Advancing (θ, θ̇) over an interval [t₀, t₁]: equal fixed steps for RK4,
//! or adaptive steps of an embedded pair, explicit or Rosenbrock, under
//! error control (Hairer, Nørsett & Wanner I, §II.4: the scaled error norm,
//! the step-size controller, and the starting step).
//!
//! The error is measured on the step's Δ and ν increments (θ̇'s mapped by
//! m*), with the scale tol·(1 + |y|) per component (relative and absolute
//! tolerance both `tol`): y is ν, a hinge or slide coordinate or a free
//! joint's position; rotations (rotation vectors of ball and free joints)
//! are measured absolutely, in rad.
//! A step passes when its error is within tol·h/(1 s) (`TOLERANCE_TIME`;
//! at tight tolerances the part that adds up is held to a looser one where
//! the method's estimate is of a lower order than its solution,
//! [`order_gap_discount`]), or for a method held per step
//! ([`ErrorPer::Step`], ROS34PW2) within a share of tol.
//!
//! Round-off in the rates does not shrink with the step: on an
//! ill-conditioned vehicle (near-singular inertias, very long chains) it can
//! exceed tol per second at every step size. When the error estimate is
//! seen not to fall as the step is cut (`at_round_off_floor`), and it lies
//! within reach of what θ̈'s round-off, measured there, can make of it
//! (`ROUND_OFF_REACH`; a settling stiff vehicle also keeps the estimate
//! up when the step is cut once), the per-second tolerance is relaxed to ten times that level (`Carry::
//! relaxation`, reported by the caller), never beyond tol per step; a run
//! that cannot hold even that stops with `StepTooSmall`.
//!
//! With `energy_projection`, θ̇ (so ν = m*θ̇) is rescaled after each step so that
//! K = ½|ν|² equals K before the step plus the step's quadrature of the
//! power ν·ν̇ (= ν·(ε + passive forces), since ν·C = 0). With ε = 0 and no
//! passive forces that power is zero, so K is then kept to round-off for
//! any length of run; the rescaling is O(h^(p+1)), so orders are kept
//! (ROS34PW2's quadrature, the trapezoid rule, is O(h³)).

use super::reach::Reach;
use super::rkmk::{Integrator, retract};
use super::simulation::Simulation;
use super::switches::MAX_STAGE_CUTS;
use super::tableau::{ErrorEstimate, ErrorPer, Method, Scheme, StepControl};
use crate::dynamics::DynamicsError;
use crate::dynamics::quantities::kinetic_energy;
use crate::model::{LinkJoint, Model};
use crate::workspace::Workspace;

/// How to integrate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Relative (and absolute) local error tolerance of adaptive methods.
    pub tolerance: f64,
    /// Longest internal step (s); RK4 takes equal steps of at most this.
    /// 0 means the method's own bound ([`Settings::step_bound`]).
    pub max_step: f64,
    /// Rescale ν after each step to the energy balance (module docs).
    pub energy_projection: bool,
}

/// RK4's step when `max_step` is 0 (s).
pub const DEFAULT_FIXED_STEP: f64 = 0.01;

/// The most internal steps one advance may attempt (accepted and rejected),
/// whatever the method, as `nmax` in Hairer's codes: an interval that
/// `max_step` alone would cut into more is refused before any step, and an
/// error control that holds the step far below what the interval needs
/// stops there, so that a host is never stalled for long.
pub const MAX_STEPS: usize = 100_000;

impl Settings {
    /// The longest internal step of `method` (s): `max_step`, or if that is
    /// 0, none for an adaptive method (the error control and the interval
    /// decide) and [`DEFAULT_FIXED_STEP`] for RK4.
    pub fn step_bound(&self, method: Method) -> f64 {
        match (self.max_step > 0.0, method.is_adaptive()) {
            (true, _) => self.max_step,
            (false, true) => f64::INFINITY,
            (false, false) => DEFAULT_FIXED_STEP,
        }
    }

    /// Refuses an interval for which the step bound alone requires more than
    /// [`MAX_STEPS`] steps, before any is taken.
    pub fn check_interval(&self, method: Method, interval: f64) -> Result<(), IntervalTooLong> {
        let max_step = self.step_bound(method);
        let needed = interval / max_step;
        if needed > MAX_STEPS as f64 {
            return Err(IntervalTooLong { interval, max_step, needed });
        }
        Ok(())
    }
}

/// An interval that the step bound would cut into more than [`MAX_STEPS`] steps.
#[derive(Debug, thiserror::Error)]
#[error(
    "an interval of {interval} s with steps of at most {max_step} s needs {needed:e} internal steps, more than \
     the {MAX_STEPS:e} one advance may take: a larger max_step or a shorter interval lets it through"
)]
pub struct IntervalTooLong {
    /// The interval asked for (s).
    pub interval: f64,
    /// The longest step in effect (s).
    pub max_step: f64,
    /// interval / max_step.
    pub needed: f64,
}

/// What one interval hands to the next, beyond (θ, θ̇) and the time: part of
/// the integration's state, so that a saved and restored run repeats exactly.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Carry {
    /// The step size the controller proposes next (s); 0 before the first step.
    pub next_step: f64,
    /// ∫ν·ν̇ dt since the start (J): the work of all forces, for the energy
    /// residual K − K₀ − work.
    pub work: f64,
    /// How far round-off in the rates has put the tolerance out of reach:
    /// steps are accepted at tolerance × this (1 when it has not; 0 before
    /// the first step means 1).
    pub relaxation: f64,
    /// The largest |θ̈| of the run's first step that had any (0 before):
    /// the size the rates are measured against when the tolerance has to be
    /// relaxed ([`ToleranceRelaxed`]).
    pub start_rates: f64,
    /// After a refused interpolant, steps reaching past a communication
    /// point are no longer than `reach_cap` until this time (reach.rs).
    pub reach_from: f64,
    /// The longest step that may reach past a point until `reach_from`:
    /// the step last refused shortened as its stray asks (`interpolant_shrink`).
    pub reach_cap: f64,
    /// Interpolants refused so far in the run: each doubles how long the
    /// cap then holds.
    pub refusals: f64,
}

impl Carry {
    /// The interpolant of the step of `refused` (s) past the communication
    /// point `t1`, which ends a communication step of `communication_step`,
    /// refused: steps reaching past a point are at most `shrink` times as
    /// long ([`interpolant_shrink`]) from `t1` on, for once the longer of the
    /// two steps, then twice, four times, … with each refusal of the run (at
    /// most [`MAX_REFUSAL_PAUSE`] times), then as long as the error control
    /// allows again. Ending the steps at the points instead (at most the
    /// communication step) left runs far more accurate than asked
    /// (noslip_trees' `dop853` at 1e-6: 1.4e-3 of the tolerance,
    /// docs/integration.md).
    fn refuse_interpolant(&mut self, t1: f64, refused: f64, shrink: f64, communication_step: f64) {
        self.refusals += 1.0;
        let pause = 2f64.powf(self.refusals - 1.0).min(MAX_REFUSAL_PAUSE);
        self.reach_from = t1 + pause * communication_step.max(refused);
        self.reach_cap = shrink * refused;
    }

    /// The tolerance the error control has actually held: `tolerance` unless
    /// round-off in the rates made it unattainable (`relaxation`).
    pub fn attained_tolerance(&self, tolerance: f64) -> f64 {
        tolerance * self.relaxation.max(1.0)
    }

    /// Whether the relaxation grew past `before` in the interval from `time`,
    /// and then what the caller must be told; `rates` gives the largest |θ̈|
    /// where the interval ended (asked for only then: a scan of every
    /// stage's rates, 1.3 % of an advance of bus_arm7).
    pub fn relaxed_since(
        &self,
        before: f64,
        time: f64,
        tolerance: f64,
        rates: impl FnOnce() -> f64,
    ) -> Option<ToleranceRelaxed> {
        (self.relaxation > before.max(1.0)).then(|| ToleranceRelaxed {
            time,
            tolerance,
            attained: self.attained_tolerance(tolerance),
            rates: rates(),
            start_rates: self.start_rates,
        })
    }
}

/// Rates this many times their size at the start of the run mean that the
/// motion itself runs away, not that round-off limits the vehicle: an error
/// estimate that does not fall as the step is cut is then truncation error
/// of a motion faster than any step (a sampled loop with a gain too high
/// for its communication step grows |ν| by a factor each step), which the
/// round-off test cannot tell from round-off.
pub const DIVERGING_GROWTH: f64 = 100.0;

/// A tolerance held for round-off at most this many times the one asked
/// still meets it: the error delivered lies within 20 times the tolerance
/// on every vehicle and method the tests run (docs/integration.md, "The
/// error delivered"), and a relaxation for round-off means the truncation
/// error already lies below what the rates' round-off lets the estimate see.
const HELD_AS_ASKED: f64 = 20.0;

/// An interval completed only by relaxing the tolerance (the FMU's
/// fmi2Warning, or a `logMethodChoice` note where it [`meets_asked`](Self::meets_asked)).
#[derive(Debug)]
pub struct ToleranceRelaxed {
    /// The start of the interval.
    pub time: f64,
    /// The tolerance asked for.
    pub tolerance: f64,
    /// The tolerance held.
    pub attained: f64,
    /// The largest |θ̈| where the interval ended.
    pub rates: f64,
    /// The largest |θ̈| of the run's first step ([`Carry::start_rates`]).
    pub start_rates: f64,
}

impl ToleranceRelaxed {
    /// How many times the rates have grown since the start (infinite from rest).
    pub fn growth(&self) -> f64 {
        self.rates / self.start_rates
    }

    /// Whether the motion runs away rather than round-off limiting the vehicle.
    pub fn diverges(&self) -> bool {
        self.growth() >= DIVERGING_GROWTH
    }

    /// Whether the tolerance held still meets the one asked: round-off (not
    /// a run-away motion) put it at most
    /// `HELD_AS_ASKED` times looser.
    pub fn meets_asked(&self) -> bool {
        !self.diverges() && self.attained <= HELD_AS_ASKED * self.tolerance
    }
}

impl std::fmt::Display for ToleranceRelaxed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ToleranceRelaxed { time, tolerance, attained, rates, start_rates } = *self;
        if self.diverges() {
            write!(
                f,
                "the motion diverges: the rates grew {:.1e}-fold since the start (largest |qacc| {start_rates:.2e}, \
                 now {rates:.2e}), as in an unstable loop around the FMU (a gain too high for the communication \
                 step); tolerance {tolerance:e} per second cannot be held in it",
                self.growth()
            )?;
        } else {
            write!(
                f,
                "tolerance {tolerance:e} per second is below what round-off in this vehicle's rates allows \
                 (largest |qacc| {rates:.2e}, {:.2}× its size at the start)",
                self.growth()
            )?;
        }
        write!(
            f,
            ": from the step at t = {time} s on, the error is held to {attained:e} per second, relative to \
             1 + |x| for each coordinate and velocity x"
        )?;
        if attained >= 1e-3 {
            write!(f, " ({:.3}% of a large x per second)", 100.0 * attained)?;
        }
        write!(f, ", and to {tolerance:e} per internal step")?;
        if self.meets_asked() {
            write!(f, "; within {HELD_AS_ASKED} times the tolerance asked, the error delivered still meets it")?;
        }
        Ok(())
    }
}

impl std::error::Error for ToleranceRelaxed {}

/// Counts of one call to `advance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Steps taken.
    pub accepted: usize,
    /// Steps rejected by the error control.
    pub rejected: usize,
    /// Evaluations of the rates θ̈, the integration's unit of cost.
    pub evaluations: usize,
    /// Times a Rosenbrock method formed its matrix W: from exact
    /// derivatives (2·nv runs of the passes in dual numbers, not counted in
    /// `evaluations`), or by forward differences (2·nv of the evaluations).
    pub jacobians: usize,
    /// Of those, the times from exact derivatives.
    pub exact_jacobians: usize,
    /// Steps attempted to locate a switch: of the constraint mode or a
    /// tendon's wrap (`switches`), or an activation clamp.
    pub locating: usize,
    /// Steps of an explicit method tested for stiffness (stiffness.rs:
    /// not `bs3`, nor a step cut to a switch).
    pub stiffness_tests: usize,
    /// Of those, the steps whose size stability held
    /// ([`crate::integrate::STABILITY_SHARE`] of the method's stability
    /// boundary or more).
    pub stability_held: usize,
    /// Steps past the communication point taken again to end there, as
    /// their interpolant strayed from the motion by more than
    /// 3 × the tolerance (`STRAY_ALLOWANCE`; reach.rs).
    pub refused_interpolants: usize,
}

/// Why an interval could not be completed. (θ, θ̇, ν) and the carry are left at
/// the last successful internal step, at time `reached`.
#[derive(Debug, thiserror::Error)]
pub enum AdvanceError {
    /// The error control shrank the step to round-off level.
    #[error(
        "cannot meet tolerance {tolerance:e}: the step size fell to {step:e} s at t = {reached} s{}",
        cause.as_ref().map(|c| format!(" (last attempt: {c})")).unwrap_or_default()
    )]
    StepTooSmall {
        /// Where the state stays.
        reached: f64,
        /// The step size at which it gave up.
        step: f64,
        /// The tolerance.
        tolerance: f64,
        /// What went wrong in the last attempt, if something overflowed rather than the error test failing.
        cause: Option<Overflow>,
    },
    /// The error control kept the steps so short that the interval needs
    /// more of them than one advance may take.
    #[error(
        "{MAX_STEPS} internal steps reached only t = {reached} s: the error control held the step to {step:e} s, \
         as the motion is too fast or stiff for tolerance {tolerance:e}; \
         a looser tolerance, or shorter intervals (each may take {MAX_STEPS} steps), lets it through"
    )]
    TooManySteps {
        /// Where the state stays.
        reached: f64,
        /// The last step size.
        step: f64,
        /// The tolerance.
        tolerance: f64,
    },
    /// The step bound alone asks for too many steps: refused before any is taken.
    #[error("{cause}")]
    TooLong {
        /// Where the state stays: the interval's start.
        reached: f64,
        /// How many steps the bound asks for.
        cause: IntervalTooLong,
    },
    /// A fixed step failed (a non-finite value).
    #[error("the step from t = {reached} s by {step:e} s failed: {cause}")]
    StepFailed {
        /// Where the state stays.
        reached: f64,
        /// The step size.
        step: f64,
        /// The cause.
        cause: DynamicsError,
    },
}

impl AdvanceError {
    /// Whether the dynamics produced a non-finite value, rather than the
    /// error test alone failing: going on from here is pointless.
    pub fn is_non_finite(&self) -> bool {
        matches!(self, AdvanceError::StepFailed { .. } | AdvanceError::StepTooSmall { cause: Some(_), .. })
    }

    /// The time of the last successful internal step, where (θ, θ̇, ν) are.
    pub fn reached(&self) -> f64 {
        match self {
            AdvanceError::StepTooSmall { reached, .. }
            | AdvanceError::TooManySteps { reached, .. }
            | AdvanceError::TooLong { reached, .. }
            | AdvanceError::StepFailed { reached, .. } => *reached,
        }
    }
}

/// Why an attempted step produced no usable error estimate.
#[derive(Debug, thiserror::Error)]
pub enum Overflow {
    /// The dynamics failed at a stage or the result is not finite.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// The result is finite but its error estimate is not.
    #[error("the error estimate is not finite: the rates reach |qacc| = {largest_rate:e}")]
    ErrorEstimate {
        /// The largest |θ̈| over the stages.
        largest_rate: f64,
    },
}

/// The tolerance is the error allowed per this much simulated time (s):
/// each step's local error is held to tol·h/(1 s) ("error per unit step"),
/// so that errors summed over a second stay near tol, whatever the number
/// of steps, rather than near tol per step.
pub const TOLERANCE_TIME: f64 = 1.0;

/// The factor on the part of a step's scaled error estimate that adds up
/// from step to step, at `tolerance`: (tol/anchor)^(1 − p̂/q) below the
/// method's [`StepControl::order_gap_anchor`], 1 at and above it, for an
/// estimate that is that of an embedded solution of order p̂ while the
/// method goes on with the solution of order q (docs/integration.md, "The
/// order gap").
///
/// Held per unit step, the estimate (local error O(h^(p̂+1))) sets the step
/// as h ∝ tol^(1/p̂), while the error delivered is the order-q solution's,
/// O(h^q) = O(tol^(q/p̂)): `bs3` (q = 3, p̂ = 2) delivered tol^1.5 (a tenth
/// of the tolerance at 1e-4, a thousandth at 1e-8), `dopri5` and `tsit5`
/// tol^1.25, on vehicles without constraint rows. Holding the estimate to
/// anchor·(tol/anchor)^(p̂/q) instead makes the error delivered
/// proportional to the tolerance below the anchor. The part along the
/// directions constraint rows damp out (decay.rs) is left as it is: it
/// does not add up, and its error was proportional to the tolerance already.
pub(super) fn order_gap_discount(control: &StepControl, tolerance: f64) -> f64 {
    match control.order_gap_anchor {
        Some(anchor) if tolerance < anchor => {
            // controller_exponent is 1/p̂ for a method held per unit step.
            let power = 1.0 - 1.0 / (control.controller_exponent * f64::from(control.order));
            (tolerance / anchor).powf(power)
        }
        _ => 1.0,
    }
}

/// Whether an attempted step's error estimate is round-off rather than
/// truncation error: since the first rejection at this t the step has been
/// at least halved, and the per-second error fell by less than that factor
/// to the power [`ROUND_OFF_POWER`] (truncation error falls faster,
/// round-off in the rates not at all), while the step
/// passes the classic per-step test. Round-off in the rates (ill-conditioned
/// inertias, long chains) does not shrink with the step, so per-second
/// control would shrink it to nothing.
fn at_round_off_floor(
    per_step: f64,
    (step, per_second): (f64, f64),
    (first_step, first_per_second): (f64, f64),
) -> bool {
    let shrink = step / first_step;
    per_step <= 1.0 && shrink <= 0.5 && per_second >= first_per_second * shrink.powf(ROUND_OFF_POWER)
}

/// The power of the step's shrink factor below which a per-second error
/// that fell is taken for round-off (`at_round_off_floor`). Round-off does
/// not fall per step, so per second it rises as the step is cut; the
/// truncation error of a smooth motion falls per second as h² at least (h⁴
/// for the 5th-order pairs), and across a kink in the rates (a constraint
/// force at a switch not located) as h. Half a power keeps the three apart.
const ROUND_OFF_POWER: f64 = 0.5;

/// How far above its round-off floor (θ̈'s measured round-off carried by
/// the estimator's weights over the step) an error estimate that does not
/// fall as the step is cut may lie and still be taken for round-off.
/// Measured (estimate / floor): 1e-4 to 0.02 on an ill-conditioned vehicle
/// (thin rods) and 0.4 to 2 on the docked servicer at 1e-12, where
/// round-off rules; 17 to 80 on the docked servicer settling at 1e-10,
/// where the estimate stalls when the step is cut once (its steps lie
/// within a quarter of dop853's stability boundary there: tests/all/stiffness.rs).
/// An estimate that stays up while the step is cut further is still taken
/// for the floor (`PERSISTENT_SHRINK`).
const ROUND_OFF_REACH: f64 = 4.0;

/// [`ROUND_OFF_REACH`] for a cut step that passes: the estimate must lie
/// well below the floor. Measured: 6e-5 on the thin rods (whose only sign
/// of round-off with dopri5 at 1e-9 is such a step; their error is then
/// 1e4 times the tolerance), 2.5 and 4.2 on the docked servicer settling.
const ROUND_OFF_REACH_PASSED: f64 = 0.1;

/// A cut this deep (since the first rejection at this t) that still
/// leaves the error estimate up is taken for the floor whatever the probe
/// measured (it samples one direction at one point); the settling docked
/// servicer's estimate falls after one or two cuts.
const PERSISTENT_SHRINK: f64 = 1.0 / 16.0;

/// How far above the round-off level found the error control then sets its
/// tolerance: close to the floor the estimate is all noise, which does not
/// shrink with the step, so the controller could not grow the step again.
const ROUND_OFF_MARGIN: f64 = 10.0;

/// A step's scaled error estimate (≤ 1 passes the per-step test).
#[derive(Clone, Copy, Debug)]
pub(super) struct ScaledError {
    /// The estimate's norm.
    pub(super) per_step: f64,
    /// The norm of what of it adds up from step to step: `per_step`'s
    /// estimate with its part along the directions that free constraint
    /// rows damp out discounted, and the rest by [`order_gap_discount`]
    /// ([`Integrator::error_norm`]).
    pub(super) accumulating: f64,
}

impl ScaledError {
    /// A step whose rates or estimate could not be evaluated: it fails.
    pub(super) const FAILED: ScaledError = ScaledError { per_step: f64::INFINITY, accumulating: f64::INFINITY };
}

/// A step's error per second from its scaled error `error` over `step`,
/// and whether the method is held per unit step; a method held per step
/// has no per-second error (its share of the tolerance stands for it), and
/// so no round-off floor below it.
pub(super) fn per_second_error(control: &StepControl, error: ScaledError, step: f64) -> (f64, bool) {
    match control.error_per {
        ErrorPer::UnitStep => (error.accumulating / (step / TOLERANCE_TIME).min(1.0), true),
        ErrorPer::Step { share } => (error.per_step / share, false),
    }
}

/// The error the control tests (≤ 1 passes): the per-second one, relaxed
/// by `relaxation` where round-off rules the tolerance out, but never
/// looser than the classic per-step test.
pub(super) fn tested_error(per_second: f64, per_step: f64, relaxation: f64) -> f64 {
    (per_second / relaxation.max(1.0)).max(per_step)
}

/// Takes the step `integrator` attempted, of size `step`: (θ, θ̇) move to
/// its end, and `carry` adds its work (and its rates, on a run's first step).
pub(super) fn take_attempted_step(
    integrator: &mut Integrator,
    model: &Model,
    ws: &mut Workspace,
    (theta, qvel): (&mut [f64], &mut [f64]),
    step: f64,
    settings: &Settings,
    carry: &mut Carry,
) -> Result<(), DynamicsError> {
    integrator.accept_with_energy(model, ws, (theta, qvel), step, settings, carry)?;
    if carry.start_rates == 0.0 {
        carry.start_rates = integrator.largest_rate();
    }
    Ok(())
}

/// Holds the step just taken, which ended at `end` with (θ, θ̇) =
/// (`theta`, `qvel`) and the work `work` done, in `reach` (whose
/// interpolant is formed): its end, and the settings it was taken with
/// (the input is the run's, `RunState::input`).
fn hold_reach(reach: &mut Reach, (theta, qvel, work): (&[f64], &[f64], f64), end: f64, settings: &Settings) {
    reach.end = end;
    reach.theta_end.copy_from_slice(theta);
    reach.qvel_end.copy_from_slice(qvel);
    reach.work_end = work;
    reach.tolerance = settings.tolerance;
    reach.max_step = settings.max_step;
}

/// How far an interpolant may stray, by [`Integrator::interpolant_strays`], in units
/// of the tolerance: the estimate is rough (it reads the error of a fast
/// damped mode through its rate, and misses a smooth error's slope, nil at
/// the middle), so a margin below the band's 20 × tolerance. Measured
/// (docs/integration.md, "Steps past the communication point"): at 1 the
/// smooth bus_arm7 had dopri5's and tsit5's interpolants refused, costing
/// up to 2.3 times the evaluations for the same errors; at 10
/// flexible_boom stayed at 21 × tolerance.
const STRAY_ALLOWANCE: f64 = 3.0;

/// The factor by which the steps after one whose interpolant strayed
/// `strays` times what is allowed (> 1) are shortened: as the step-size
/// controller's, from the interpolant's order p (its stray, the defect
/// carried over a quarter step, falls as h^(p+1)), but never below half,
/// the factor before 2026-12-02, which held the runs that refused most
/// in the band. Half alone held tendon_limits' `dop853` at 1e-4 to 0.0078
/// of the tolerance: its interpolant over a 0.118 s step strayed 8.6
/// times the allowance and over 0.059 s 0.0021 times (a fast damped mode,
/// whose stray fell as h^11.5 there).
pub(super) fn interpolant_shrink(strays: f64, interpolant_order: u32) -> f64 {
    (SAFETY * strays.recip().powf(1.0 / f64::from(interpolant_order + 1))).max(0.5)
}

/// The most lengths (communication or refused steps) a refused
/// interpolant pauses reaching past the points for
/// ([`Carry::refuse_interpolant`]).
const MAX_REFUSAL_PAUSE: f64 = 64.0;

/// Safety factor of the step-size controller.
const SAFETY: f64 = 0.9;

/// The factor the next step is the last attempted one times, from its
/// scaled error (≤ 1 passed): the classic (error)^(−1/(q+1)) rule with a
/// safety factor, within the tableau's bounds; it never grows the step right
/// after a rejection (`after_rejection`, which a rejected step itself is),
/// and a non-finite error shrinks it as far as allowed.
pub(super) fn step_factor(error: f64, control: &StepControl, after_rejection: bool) -> f64 {
    let (shrink_limit, grow_limit) = control.factor_bounds;
    if !error.is_finite() {
        return shrink_limit;
    }
    let factor = (SAFETY * error.powf(-control.controller_exponent)).clamp(shrink_limit, grow_limit);
    if after_rejection { factor.min(1.0) } else { factor }
}

impl Simulation {
    /// Equal steps of at most `max_step` from the state's time to `t1`.
    pub(super) fn advance_fixed(
        &mut self,
        model: &Model,
        t1: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<Stats, AdvanceError> {
        let Simulation { state, settings, integrator, ws, .. } = self;
        let (t0, theta, qvel, carry) = (state.time, &mut state.theta[..], &mut state.qvel[..], &mut state.carry);
        let max_step = settings.step_bound(integrator.method);
        // The tolerance keeps an interval of exactly k·max_step (up to round-off) at k steps.
        let steps = ((t1 - t0) / max_step * (1.0 - 1e-12)).ceil().max(1.0) as usize;
        let h = (t1 - t0) / steps as f64;
        let evaluations_before = integrator.evaluations;
        for n in 0..steps {
            let t = t0 + n as f64 * h;
            let failed = |cause| AdvanceError::StepFailed { reached: t, step: h, cause };
            integrator.attempt(model, ws, (theta, qvel), (t, h), inputs_at).map_err(failed)?;
            if let Some(cause) = integrator.non_finite_result() {
                return Err(failed(cause));
            }
            integrator.accept_with_energy(model, ws, (theta, qvel), h, settings, carry).map_err(failed)?;
        }
        carry.next_step = h;
        Ok(Stats {
            accepted: steps,
            rejected: 0,
            evaluations: integrator.evaluations - evaluations_before,
            ..Stats::default()
        })
    }

    /// Steps of an embedded pair under error control from the state's time
    /// to `t1`. Where `limit` lies beyond `t1`, the last step may end past
    /// `t1`, up to `limit`: the state at `t1` is then its interpolant, and
    /// the step is held in `state.reach` (reach.rs). `communication_step`
    /// is the host's interval that ends at `t1`.
    pub(super) fn advance_adaptive(
        &mut self,
        model: &Model,
        (t1, limit): (f64, f64),
        communication_step: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<Stats, AdvanceError> {
        let t0 = self.state.time;
        // Within this of t1 the interval is done: a step that small is only
        // round-off, and the smallest step allowed below could not take it.
        let end_slack = 16.0 * f64::EPSILON * t1.abs().max(1.0);
        if t1 - t0 <= end_slack {
            // Nothing left (`auto`'s probe took the interval): the starting
            // step is left for the advance that takes one.
            return Ok(Stats::default());
        }
        let (evaluations_before, jacobians_before, exact_before) =
            (self.integrator.evaluations, self.integrator.jacobians, self.integrator.exact_jacobians);
        // The inputs may have changed at t0: the first stage is no test of the last step.
        self.integrator.stiffness.drop_pending();
        let stiffness_before = (self.integrator.stiffness.tests, self.integrator.stiffness.held);
        if self.switches.watched() {
            let Simulation { state, integrator, ws, switches, .. } = self;
            switches
                .establish(model, ws, integrator, (&state.theta, &state.qvel), t0, false, inputs_at)
                .map_err(|cause| AdvanceError::StepFailed { reached: t0, step: 0.0, cause })?;
        }
        let h = if self.state.carry.next_step > 0.0 {
            self.state.carry.next_step
        } else {
            self.initial_step(model, inputs_at).map_err(|cause| AdvanceError::StepFailed {
                reached: t0,
                step: 0.0,
                cause,
            })?
        };
        let Simulation { state, settings, integrator, ws, switches, .. } = self;
        let (theta, qvel, carry, reach) =
            (&mut state.theta[..], &mut state.qvel[..], &mut state.carry, &mut state.reach);
        let watch = switches.watched();
        let control = integrator.method.control();
        let tolerance = settings.tolerance;
        let mut stats = Stats::default();
        let mut t = t0;
        let mut h = h;
        // (step, per-second error) of the first of the rejections at this t,
        // and the least per-second error among them.
        let mut first_rejection: Option<(f64, f64)> = None;
        let mut least_rejected = f64::INFINITY;
        // θ̈'s round-off at this t, measured when a rejection looks like it.
        let mut round_off_level: Option<f64> = None;
        let mut last_cause = None;
        let max_step = settings.step_bound(integrator.method);
        // Cuts to a stage that left the mode since the last step taken.
        let mut stage_cuts = 0;
        while t1 - t > end_slack {
            let planned = h.min(max_step);
            // A step capped since a refusal reaches past t1 by no more than the cap allows.
            let limit = if carry.refusals > 0.0 && t < carry.reach_from {
                limit.min(t1.max(t + carry.reach_cap))
            } else {
                limit
            };
            let remaining = limit - t;
            // Two even steps rather than a full one and a sliver: a step cut
            // to a sliver to land on t1 costs as much as a full one.
            let step = if planned + end_slack >= remaining {
                remaining
            } else if 2.0 * planned > remaining {
                0.5 * remaining
            } else {
                planned
            };
            if step < 16.0 * f64::EPSILON * t.abs().max(1.0) {
                return Err(AdvanceError::StepTooSmall { reached: t, step, tolerance, cause: last_cause });
            }
            if stats.accepted + stats.rejected >= MAX_STEPS {
                return Err(AdvanceError::TooManySteps { reached: t, step, tolerance });
            }
            let mut step = step;
            let mut attempted = integrator.attempt(model, ws, (theta, qvel), (t, step), inputs_at);
            if attempted.is_ok()
                && let Some(share) = integrator.activation_crossing(model, qvel, (t, step), inputs_at)
            {
                // A clamp of act (or of actearly's look-ahead) starts within the step, where the
                // force kinks: the step is cut to end just past it (two secant steps), so that no
                // step straddles the kink, before its error is judged.
                let mut share = share;
                for _ in 0..ACTIVATION_CROSSING_ATTEMPTS {
                    step *= share + ACTIVATION_CROSSING_MARGIN * (1.0 - share);
                    attempted = integrator.attempt(model, ws, (theta, qvel), (t, step), inputs_at);
                    stats.locating += 1;
                    match attempted.is_ok().then(|| integrator.activation_crossing(model, qvel, (t, step), inputs_at)) {
                        // Still well short of the cut's end: closer.
                        Some(Some(next)) if next < 1.0 - 2.0 * ACTIVATION_CROSSING_MARGIN => share = next,
                        _ => break,
                    }
                }
            }
            let scaled = match attempted {
                Ok(()) => integrator.error_norm(model, ws, theta, tolerance, step),
                Err(cause) => {
                    last_cause = Some(Overflow::Dynamics(cause));
                    ScaledError::FAILED
                }
            };
            let per_step = scaled.per_step;
            let (per_second, per_unit_step) = per_second_error(control, scaled, step);
            if let Some(first_rejected) = first_rejection
                && per_unit_step
                && at_round_off_floor(per_step, (step, per_second), first_rejected)
            {
                // A run-away motion also keeps the estimate up; the
                // relaxation then goes on and says so (`DIVERGING_GROWTH`).
                let diverging =
                    carry.start_rates > 0.0 && integrator.largest_rate() > DIVERGING_GROWTH * carry.start_rates;
                let persistent = step <= PERSISTENT_SHRINK * first_rejected.0;
                let within_round_off = diverging || persistent || {
                    let level = match round_off_level {
                        Some(level) => level,
                        None => {
                            let level = integrator
                                .rate_round_off(model, ws, (theta, qvel), t, inputs_at)
                                .map_err(|cause| AdvanceError::StepFailed { reached: t, step, cause })?;
                            *round_off_level.insert(level)
                        }
                    };
                    // A step that passes as asked needs nothing now: only round-off
                    // beyond doubt makes it the reason to relax for the next.
                    let reach =
                        if per_second > carry.relaxation.max(1.0) { ROUND_OFF_REACH } else { ROUND_OFF_REACH_PASSED };
                    per_step <= reach * step * integrator.estimator_weight() * level / tolerance
                };
                if within_round_off {
                    // The least error seen is the one least mixed with truncation error.
                    carry.relaxation = carry.relaxation.max(ROUND_OFF_MARGIN * per_second.min(least_rejected));
                }
            }
            let error = tested_error(per_second, per_step, carry.relaxation);
            let failed = |cause| AdvanceError::StepFailed { reached: t, step, cause };
            let crossed = error <= 1.0
                && watch
                && switches.switched(model, ws, integrator, theta, t + step, inputs_at).map_err(failed)?;
            // Whether `reach` holds this attempt's interpolant. Nothing is held in
            // `reach` before the advance's last step (one that reaches past t1), so
            // the probe may form it there.
            let mut probed = false;
            if error <= 1.0
                && !crossed
                && watch
                && integrator.stage_watch.earliest().is_none()
                && let Some(share) = integrator.method.gap_probe()
            {
                // The widest gap between stages read at its middle, on the interpolant.
                let start = (&theta[..], &qvel[..]);
                integrator
                    .form_interpolant(model, ws, start, (t, step), carry.work, inputs_at, reach)
                    .map_err(failed)?;
                integrator.probe_margins(model, ws, reach, share, inputs_at);
                probed = true;
            }
            if error <= 1.0
                && !crossed
                && stage_cuts < MAX_STAGE_CUTS
                && let Some(share) = integrator.stage_watch.earliest()
            {
                // A stage left the mode and the end is back in it: a switch undone
                // within the step. Cut to that stage's time, whose end shows it.
                stage_cuts += 1;
                stats.locating += 1;
                h = step * share;
                continue;
            }
            // The step to take: the one attempted, or one cut to end just past a switch.
            let mut taken = (step, per_second, error);
            if crossed {
                let located = switches
                    .locate(model, ws, integrator, (theta, qvel), (t, step, carry.work), tolerance, reach, inputs_at)
                    .map_err(failed)?;
                stats.locating += located.attempts;
                let scaled = integrator.error_norm(model, ws, theta, tolerance, located.step);
                let per_second = per_second_error(control, scaled, located.step).0;
                taken = (located.step, per_second, tested_error(per_second, scaled.per_step, carry.relaxation));
            }
            if taken.2 <= 1.0 {
                // The step size goes on from the step attempted: a cut to a switch says nothing of the error.
                let factor = step_factor(error, control, first_rejection.is_some());
                h = if step < planned { (step * factor).max(planned) } else { step * factor };
                let step = taken.0;
                let failed = |cause| AdvanceError::StepFailed { reached: t, step, cause };
                let end = if step == remaining { limit } else { t + step };
                let reaches = end - t1 > end_slack;
                if reaches {
                    // Formed already for the probe (dop853's takes three evaluations).
                    if !probed {
                        let (start, work) = ((&theta[..], &qvel[..]), carry.work);
                        integrator
                            .form_interpolant(model, ws, start, (t, step), work, inputs_at, reach)
                            .map_err(failed)?;
                    }
                    // An interpolated state where the rates cannot be evaluated (or are not
                    // finite) is not trusted either. A step cut to a switch is checked too:
                    // its interpolant serves every point up to its end.
                    let strays = integrator
                        .interpolant_strays(model, ws, reach, inputs_at)
                        .ok()
                        .filter(|strays| strays.is_finite())
                        .map_or(f64::INFINITY, |strays| strays / (STRAY_ALLOWANCE * tolerance));
                    if strays > 1.0 {
                        // Its end is right, its inside is not (a fast damped mode, which
                        // the interpolant follows far less closely than the end):
                        // taken again shorter, the next ones too for a while.
                        let order = integrator.method.dense().map_or(1, |dense| dense.order);
                        let shrink = interpolant_shrink(strays, order);
                        carry.refuse_interpolant(t1, step, shrink, communication_step);
                        stats.refused_interpolants += 1;
                        continue;
                    }
                }
                if !crossed {
                    // Before the step is taken, which drops a test awaiting f(y₁) where it moves y₁
                    // (act clamped, θ̇ projected).
                    let stages = (&integrator.k_delta[..], &integrator.k_qvel[..]);
                    integrator.stiffness.after_step(integrator.method, stages, step);
                }
                take_attempted_step(integrator, model, ws, (theta, qvel), step, settings, carry).map_err(failed)?;
                t = end;
                if crossed {
                    // Past the switch: the mode of the new start, and its rates as the first stage.
                    switches
                        .establish(model, ws, integrator, (theta, qvel), t, true, inputs_at)
                        .map_err(|cause| AdvanceError::StepFailed { reached: t, step: 0.0, cause })?;
                } else if watch {
                    switches.step_taken();
                }
                stats.accepted += 1;
                stage_cuts = 0;
                if reaches {
                    hold_reach(reach, (theta, qvel, carry.work), t, settings);
                    carry.work = reach.interpolate(model, t1, theta, qvel, integrator.dense_delta.as_mut_slice());
                    reach.held = true;
                    // A step cut to a switch located: the next advance goes on from its end
                    // in the mode past the switch. Of that mode, only the solver's working
                    // set does not follow from the state alone, so it is kept with the step.
                    reach.working_set.clear();
                    if crossed {
                        reach.working_set.extend_from_slice(ws.working_set());
                    }
                }
                first_rejection = None;
                least_rejected = f64::INFINITY;
                round_off_level = None;
                last_cause = None;
            } else {
                // A step cut to a switch that fails (rarely: it is shorter) is rejected as itself.
                let (step, per_second, error) = taken;
                if error.is_finite() {
                    last_cause = None;
                } else if last_cause.is_none() {
                    last_cause = Some(match integrator.non_finite_result() {
                        Some(cause) => Overflow::Dynamics(cause),
                        None => Overflow::ErrorEstimate { largest_rate: integrator.largest_rate() },
                    });
                }
                let factor = step_factor(error, control, true);
                h = step * factor;
                stats.rejected += 1;
                first_rejection.get_or_insert((step, per_second));
                least_rejected = least_rejected.min(per_second);
            }
        }
        carry.next_step = h;
        stats.evaluations = integrator.evaluations - evaluations_before;
        stats.jacobians = integrator.jacobians - jacobians_before;
        stats.exact_jacobians = integrator.exact_jacobians - exact_before;
        stats.stiffness_tests = integrator.stiffness.tests - stiffness_before.0;
        stats.stability_held = integrator.stiffness.held - stiffness_before.1;
        Ok(stats)
    }

    /// A starting step from the size of the solution, its rate and an Euler
    /// probe of its second derivative (Hairer's starting-step heuristic);
    /// leaves the start's rates as the first stage.
    fn initial_step(
        &mut self,
        model: &Model,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<f64, DynamicsError> {
        let Simulation { state, settings, integrator, ws, .. } = self;
        let (t0, theta, qvel) = (state.time, &state.theta[..], &state.qvel[..]);
        let tolerance = settings.tolerance;
        integrator.evaluate_start(model, ws, (theta, qvel), t0, inputs_at)?;
        let first = &integrator.first;
        let size = start_norm(model, theta, qvel, tolerance, |dof, position| (position, qvel[dof]));
        let rate = start_norm(model, theta, qvel, tolerance, |dof, _| (first.qvel[dof], first.qacc[dof]));
        // Overflowing norms (huge rates) make the heuristic meaningless: start
        // small and let the error control decide.
        let h0 = 0.01 * size / rate;
        let h0 = if size < 1e-5 || rate < 1e-5 || !(h0 > 0.0 && h0.is_finite()) { 1e-6 } else { h0 };
        let max_step = settings.step_bound(integrator.method);
        let h0 = h0.min(max_step);
        // Explicit Euler probe to h0.
        integrator.delta.copy_from(&integrator.first.qvel);
        integrator.delta *= h0;
        retract(model, integrator.theta_stage.as_mut_slice(), integrator.delta.as_slice());
        integrator.qvel_stage.axpy(h0, &integrator.first.qacc, 1.0);
        integrator.evaluate_stage(model, ws, t0 + h0, inputs_at)?;
        let first = &integrator.first;
        let change = |dof, _| (ws.qvel[dof] - first.qvel[dof], ws.qacc[dof] - first.qacc[dof]);
        let curvature = start_norm(model, theta, qvel, tolerance, change) / h0;
        let largest = rate.max(curvature);
        let order = integrator.method.control().order as f64;
        let h1 = if largest <= 1e-15 { (h0 * 1e-3).max(1e-6) } else { (0.01 / largest).powf(1.0 / order) };
        let h = (100.0 * h0).min(h1).min(max_step);
        Ok(if h > 0.0 { h } else { h0 })
    }
}

impl Integrator {
    /// The largest |θ̈| over the attempted step's stages.
    pub(super) fn largest_rate(&self) -> f64 {
        self.k_qvel[..self.method.stages()].iter().flat_map(|k| k.iter()).fold(0.0, |m: f64, x| m.max(x.abs()))
    }

    /// Takes the attempted step, adds its work to `carry`, and projects θ̇
    /// onto the energy balance if asked (K = ½|m*θ̇|², so scaling θ̇ scales ν).
    fn accept_with_energy(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        (theta, qvel): (&mut [f64], &mut [f64]),
        h: f64,
        settings: &Settings,
        carry: &mut Carry,
    ) -> Result<(), DynamicsError> {
        let work = self.step_work(h);
        if !settings.energy_projection {
            self.accept(model, theta, qvel);
            carry.work += work;
            return Ok(());
        }
        let energy_before = kinetic_energy(self.first.nu.as_slice());
        // ν at the step's end comes from its configuration, placed in scratch
        // first: if the passes fail there, (θ, θ̇) stay at the step's start,
        // where the time is.
        self.theta_stage.as_mut_slice().copy_from_slice(theta);
        retract(model, self.theta_stage.as_mut_slice(), self.delta.as_slice());
        ws.set_configuration(model, self.theta_stage.as_slice())?;
        ws.set_qvel(model, &self.qvel_next.as_slice()[..model.nv])?;
        let energy = kinetic_energy(ws.nu.as_slice());
        self.accept(model, theta, qvel);
        carry.work += work;
        let target = energy_before + work;
        if target > 0.0 && energy > 0.0 {
            self.stiffness.drop_pending();
            let scale = (target / energy).sqrt();
            qvel[..model.nv].iter_mut().for_each(|x| *x *= scale);
            // The cached last stage was evaluated at the unprojected θ̇.
            self.first.valid = false;
        }
        Ok(())
    }

    /// The scaled max norm of the attempted step's error estimate: ≤ 1
    /// passes. The largest component rather than Hairer's RMS: users compare
    /// errors coordinate by coordinate, and an RMS over 2·nv components lets
    /// one coordinate's error be up to √(2nv) times the tolerance (on a
    /// 60-link chain the error delivered was 60–270 times the tolerance).
    /// The velocity part is measured on ν, as users read it: θ̇'s error
    /// estimate mapped by m* at the last stage's configuration (pass 2 on
    /// the estimate, which overwrites the workspace's velocities). act's
    /// error is scaled by tol·(1 + |act|) at the step's end.
    ///
    /// With constraint rows whose forces are free, the ν and Δ errors along
    /// the directions they move, which they damp out at a rate σ instead of
    /// letting them add up, count towards the error per second
    /// ([`ScaledError::accumulating`]) only by max(`step`, 1/σ)/(1 s) of
    /// them (decay.rs), and the rest by [`order_gap_discount`].
    pub(super) fn error_norm(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        theta: &[f64],
        tolerance: f64,
        step: f64,
    ) -> ScaledError {
        let two_estimates =
            matches!(self.method.scheme(), Scheme::Explicit(t) if matches!(t.error, ErrorEstimate::Dop853 { .. }));
        let undamped_share = order_gap_discount(self.method.control(), tolerance);
        let estimates = if two_estimates { 2 } else { 1 };
        let nv = model.nv;
        // A step of a second or more counts all of its error either way.
        let splits =
            step < TOLERANCE_TIME && ws.constraint_rows.count > 0 && self.damped.form(model, &ws.constraint_rows);
        let mut norms = [0.0_f64; 2];
        let mut accumulating = [0.0_f64; 2];
        for (k, (norm, accumulating)) in norms.iter_mut().zip(&mut accumulating).enumerate().take(estimates) {
            let (error_delta, error_qvel) = if k == 0 {
                (&self.error_delta, &self.error_qvel)
            } else {
                (&self.error_delta_low, &self.error_qvel_low)
            };
            let (error_qvel, error_act) = error_qvel.as_slice().split_at(nv);
            if ws.set_qvel(model, error_qvel).is_err() {
                return ScaledError::FAILED;
            }
            let act_next = &self.qvel_next.as_slice()[nv..];
            for (error, act) in error_act.iter().zip(act_next) {
                *norm = norm.max((error / (tolerance * (1.0 + act.abs()))).abs());
            }
            // Slices: nalgebra's indexing is checked against both dimensions.
            let error_delta = error_delta.as_slice();
            let damped = &mut self.damped;
            if splits {
                damped.error_nu.copy_from_slice(ws.nu.as_slice());
                damped.split_nu(nv, step);
                if damped.holds_positions() {
                    // Δ's parts along the rows: m*Δ's, mapped back by m*⁻¹ (pass 2 forward and back).
                    if ws.set_qvel(model, error_delta).is_err() {
                        return ScaledError::FAILED;
                    }
                    damped.split_delta(nv, step, ws.nu.as_slice());
                    for (part, back) in [
                        (&damped.damped_delta_nu, &mut damped.damped_delta),
                        (&damped.weighted_delta_nu, &mut damped.weighted_delta),
                    ] {
                        if ws.set_nu(model, part).is_err() {
                            return ScaledError::FAILED;
                        }
                        back.copy_from_slice(ws.qvel.as_slice());
                    }
                } else {
                    damped.damped_delta.fill(0.0);
                    damped.weighted_delta.fill(0.0);
                }
            }
            let error_nu = if splits { &damped.error_nu[..] } else { ws.nu.as_slice() };
            let (delta, nu_size) = (self.delta.as_slice(), self.nu_size.as_slice());
            // act's part, which no row damps.
            *accumulating = *norm * undamped_share;
            for (dof, position) in positions(model, theta) {
                let position = position.map_or(0.0, |y| y.abs().max((y + delta[dof]).abs()));
                let scale_delta = tolerance * (1.0 + position);
                let scale_nu = tolerance * (1.0 + nu_size[dof]);
                let (error_delta, error_nu) = (error_delta[dof], error_nu[dof]);
                *norm = norm.max((error_delta / scale_delta).abs()).max((error_nu / scale_nu).abs());
                if splits {
                    let parts = [
                        undamped_share * (error_delta - damped.damped_delta[dof]) / scale_delta,
                        damped.weighted_delta[dof] / scale_delta,
                        undamped_share * (error_nu - damped.damped_nu[dof]) / scale_nu,
                        damped.weighted_nu[dof] / scale_nu,
                    ];
                    *accumulating = parts.iter().fold(*accumulating, |largest, part| largest.max(part.abs()));
                }
            }
            if !splits {
                *accumulating = *norm * undamped_share;
            }
        }
        // The 5th-order estimate, damped where the 3rd-order one is much larger (Hairer's DOP853).
        let combined = |[high, low]: [f64; 2]| {
            if !two_estimates {
                return high;
            }
            let denominator = high * high + 0.01 * low * low;
            if denominator > 0.0 { high * high / denominator.sqrt() } else { 0.0 }
        };
        ScaledError { per_step: combined(norms), accumulating: combined(accumulating) }
    }
}

/// Secant attempts that cut a step to end just past where an act reaches
/// a bound, and how far past it (a share of the rest of the step): act is
/// all but linear over a step, so two attempts place the end within a tiny
/// part of the step past the bound.
const ACTIVATION_CROSSING_ATTEMPTS: usize = 2;
const ACTIVATION_CROSSING_MARGIN: f64 = 1e-3;

/// The RMS over the dofs of `value(dof, |coordinate|)`, a (Δ, θ̇) pair
/// scaled by tol·(1 + |θ|) and tol·(1 + |θ̇|) at the step's start: the
/// norm of the starting-step heuristic.
fn start_norm(
    model: &Model,
    theta: &[f64],
    qvel: &[f64],
    tolerance: f64,
    value: impl Fn(usize, f64) -> (f64, f64),
) -> f64 {
    let sum: f64 = positions(model, theta)
        .map(|(dof, position)| {
            let position = position.map_or(0.0, f64::abs);
            let (delta, rate) = value(dof, position);
            (delta / (tolerance * (1.0 + position))).powi(2) + (rate / (tolerance * (1.0 + qvel[dof].abs()))).powi(2)
        })
        .sum();
    (sum / (2.0 * model.nv as f64)).sqrt()
}

/// Each dof with the coordinate it moves, if that is a vector coordinate
/// (hinge, slide, free-joint position, modal coordinate); rotations have none.
pub(super) fn positions<'a>(model: &'a Model, theta: &'a [f64]) -> impl Iterator<Item = (usize, Option<f64>)> + 'a {
    let rigid = model.links.iter().flat_map(move |link| {
        (0..link.ndof).map(move |k| {
            let position = (link.joint != LinkJoint::Ball).then(|| theta[link.qpos_adr + k]);
            (link.dof_adr + k, position)
        })
    });
    let modal = model.flexible.iter().flat_map(move |flexible| {
        (0..flexible.mode_count()).map(move |k| (flexible.dof_adr + k, Some(theta[flexible.qpos_adr + k])))
    });
    rigid.chain(modal)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A step whose end the passes refuse (here a non-finite Δ, as a
    /// singular articulated inertia there would be refused) fails before
    /// (θ, θ̇) or the work move: the time stays at the step's start, so must
    /// they.
    #[test]
    fn a_projection_that_fails_leaves_the_state_at_the_steps_start() {
        let mjcf = r#"<mujoco><worldbody><body name="base"><freejoint/>
            <inertial pos="0 0 0" mass="3" diaginertia="0.4 0.3 0.2"/>
            <body name="arm" pos="0.3 0 0"><joint name="hinge" axis="0 0 1"/>
              <inertial pos="0.2 0 0" mass="1" diaginertia="0.01 0.02 0.02"/>
            </body></body></worldbody></mujoco>"#;
        let model = Model::compile(&crate::mjcf::parse_mjcf(mjcf).unwrap().vehicle).unwrap();
        let mut ws = model.workspace();
        let settings = Settings { tolerance: 1e-6, max_step: 1.0, energy_projection: true };
        let mut integrator = Integrator::new(&model, Method::Dop853);
        let mut theta = vec![0.1, -0.2, 0.3, 1.0, 0.0, 0.0, 0.0, 0.4];
        let mut qvel = vec![0.1, 0.2, -0.1, 0.3, -0.2, 0.5, 1.5];
        let mut no_inputs = |_: f64, eps: &mut [f64], ctrl: &mut [f64]| {
            eps.fill(0.0);
            ctrl.fill(0.0);
        };
        integrator.attempt(&model, &mut ws, (&theta, &qvel), (0.0, 0.01), &mut no_inputs).unwrap();
        let mut carry = Carry { work: 0.25, ..Carry::default() };
        let (theta_before, qvel_before) = (theta.clone(), qvel.clone());
        integrator.delta[6] = f64::NAN;
        let taken =
            take_attempted_step(&mut integrator, &model, &mut ws, (&mut theta, &mut qvel), 0.01, &settings, &mut carry);
        assert!(matches!(taken, Err(DynamicsError::NonFinite { .. })), "{taken:?}");
        assert_eq!((theta, qvel, carry.work), (theta_before, qvel_before, 0.25));
    }
}
