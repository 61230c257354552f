//! Where the constraint forces switch, located as events inside an
//! adaptive run (docs/integration.md, "Constraint switches"; the mode and
//! its margins are [`crate::dynamics::mode`]'s).
//!
//! MuJoCo's constraint forces are smooth in the state except where
//! - a limit side switches on or off (its distance crosses its margin):
//!   a row appears or vanishes, and its reference acceleration's velocity
//!   term makes θ̈ jump;
//! - a force reaches or leaves a bound of its box (friction loss sticking
//!   or sliding, a limit's force falling to zero): the forces kink.
//!
//! An error control that steps across either sees an error that does not
//! fall with the step as it expects (per second: not at all across a jump,
//! as h across a kink), and creeps across with tiny steps, or stalls.
//! Instead each step holds the constraint mode of its start: the sides
//! active there, and the bounds the forces sit at there (the solver's
//! working set). Over the step the rates are then smooth (a side held past
//! its switch, a force held in its working set, extend smoothly). Each
//! switch has a margin, positive while the mode holds: a side's distance
//! past its margin (negated while active), a free force's distance to its
//! bounds, a bound force's multiplier. A step that ends with a margin
//! below zero is cut to end just past the earliest switch, found by a
//! safeguarded secant (Illinois), first on the step's interpolant and then
//! by attempts from there, and the next step starts in the mode its start
//! gives. The mode is always derived from the step's start, so nothing
//! beyond the state is carried between steps, and a restored run repeats
//! exactly.
//!
//! A switch undone within one step does not show at its end. The margins
//! are also read at each stage of an explicit step (the stage states lie
//! within the step's error of the solution, and their rates are evaluated
//! in the held mode anyway: [`StageWatch`]); a step whose end holds the
//! mode but one of whose stages left it is cut to end at that stage's
//! time, where location then finds the switch. A weld's impedance moving
//! between pieces and back within 10 ms was missed so by `dop853` at
//! loose tolerances, 4.7e-3 off (docs/integration.md, "Switches undone
//! within one step"). Where a method's stages leave a gap of more than a
//! fifth of the step (every explicit method), the margins are read at its
//! middle too, on the step's interpolant
//! ([`super::tableau::Method::gap_probe`]): with the damped errors
//! discounted (decay.rs) the steps grew long enough for a 5.5 ms
//! excursion of the same weld to fall between two of `tsit5`'s stages,
//! and a touch of a limit between two of `dop853`'s.

use super::reach::Reach;
use super::rkmk::{Integrator, retract};
use crate::dynamics::DynamicsError;
use crate::dynamics::mode::ConstraintMode;
use crate::model::Model;
use crate::workspace::Workspace;

/// At most this many attempts locate one switch: from the interpolant's
/// estimate they close the bracket in four or five on the docked servicer
/// (two where the estimate is within the resolution), and bisect where three
/// of the secant's have not halved it, so that 40 reach any resolution
/// down to round-off from a step of any length.
const MAX_ATTEMPTS: usize = 40;

/// At most this many readings on the interpolant give the attempts their
/// first aim (a reading costs one evaluation of the rates, an attempt a
/// whole step).
const MAX_READINGS: usize = 40;

/// The bracket a switch is located to, as a share of the tolerance times
/// the step: held past its switch by that much of the step, a mode
/// changes the state by a small part of what the step may err by.
const RESOLUTION_SHARE: f64 = 0.01;

/// How many times in a row a step may be cut to a stage that left the
/// mode: the stage states only approximate the solution, so near a margin
/// that touches zero without crossing, cuts could otherwise go on shrinking
/// the step.
pub(super) const MAX_STAGE_CUTS: usize = 4;

/// The margins at the stages of an explicit step, in the mode the step
/// holds (a copy of [`Switches`]' mode, set where it is established).
#[derive(Clone, Debug, Default)]
pub(super) struct StageWatch {
    mode: ConstraintMode,
    margins: Vec<f64>,
    /// The earliest stage time, as a share of the step, whose margins left
    /// the mode in the step attempted last.
    earliest: Option<f64>,
}

impl StageWatch {
    /// Forgets the last attempt's stages.
    pub(super) fn start_attempt(&mut self) {
        self.earliest = None;
    }

    /// Reads the margins of the stage just evaluated at `theta_stage`, at
    /// `share` of the step; nothing on a vehicle without switches.
    pub(super) fn check_stage(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        theta_stage: &[f64],
        share: f64,
    ) -> Result<(), DynamicsError> {
        // A stage at the step's end is the end, which is checked as such.
        if self.margins.is_empty() || share <= 0.0 || share >= 1.0 {
            return Ok(());
        }
        self.mode.margins(model, ws, theta_stage, &mut self.margins)?;
        if self.mode.left(&self.margins) && self.earliest.is_none_or(|earliest| share < earliest) {
            self.earliest = Some(share);
        }
        Ok(())
    }

    /// The earliest stage of the last attempt that left the mode, as a share of the step.
    pub(super) fn earliest(&self) -> Option<f64> {
        self.earliest
    }

    /// Takes the point at `share` of the step for one that left the mode
    /// (its rates could not be evaluated).
    pub(super) fn left_at(&mut self, share: f64) {
        self.earliest = Some(self.earliest.map_or(share, |earliest| earliest.min(share)));
    }
}

/// The mode a step holds, its margins at the points of the step being
/// located, and the end configuration.
#[derive(Clone, Debug, Default)]
pub struct Switches {
    mode: ConstraintMode,
    /// The margins at the step's start.
    start: Vec<f64>,
    /// At the end of the step attempted last.
    end: Vec<f64>,
    /// At the end of the longest step known not to switch (the bracket's start).
    before: Vec<f64>,
    /// At the end of the shortest step known to switch (the bracket's end).
    after: Vec<f64>,
    /// At the end of the step being located, while its interpolant is read.
    attempted: Vec<f64>,
    /// The configuration at the end of the attempted step.
    theta_end: Vec<f64>,
    /// Per margin, what the readings of the bracket being narrowed showed
    /// of a jump ([`NEAR_SIDE_STAYS`], [`FAR_SIDE_STAYS`]): a margin that
    /// shows both jumps rather than passes through zero, and is left out
    /// of the secant.
    jump_evidence: Vec<u8>,
}

/// A switch's bracket, in time into the step (s).
struct Bracket {
    /// The longest step known not to switch.
    before: f64,
    /// The shortest step known to switch.
    after: f64,
    /// Whether the last reading was that of `after`.
    holds_after: bool,
    /// Readings taken.
    readings: usize,
}

/// Where a located switch left the integrator.
pub(super) struct Located {
    /// The step, just past the switch, whose attempt the integrator holds.
    pub step: f64,
    /// Extra attempts it took.
    pub attempts: usize,
}

impl Switches {
    /// Buffers for `model`; empty (and not [`Switches::watched`]) without constraints.
    pub fn new(model: &Model) -> Self {
        let mode = ConstraintMode::new(model);
        let margins = vec![0.0; mode.len()];
        Switches {
            start: margins.clone(),
            end: margins.clone(),
            before: margins.clone(),
            after: margins.clone(),
            attempted: margins,
            theta_end: if mode.is_empty() { Vec::new() } else { vec![0.0; model.nq] },
            jump_evidence: vec![0; mode.len()],
            mode,
        }
    }

    /// Whether the model has constraints whose forces can switch.
    pub fn watched(&self) -> bool {
        !self.mode.is_empty()
    }

    /// Sets the mode a step from (θ, θ̇) at `t` holds: the sides active at
    /// θ, and the working set the solver finds there; evaluates the rates
    /// there as the step's first stage. At the end of a step cut to a
    /// switch (`located`), the forces that crossed a bound of their working
    /// set start the solve on its far side, so that a solve a hair past the
    /// switch does not find the old working set again.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn establish(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        integrator: &mut Integrator,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        located: bool,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        if located {
            let sides = self.mode.sides();
            let forces =
                (sides..sides + model.constraints.max_rows()).filter(|&k| self.mode.distance(k, self.end[k]) < 0.0);
            for k in forces {
                ws.cross_working_set(k - sides);
            }
        }
        self.mode.hold_sides(model, ws, theta)?;
        integrator.evaluate_start(model, ws, (theta, qvel), t, inputs_at)?;
        self.mode.hold_working_set(ws, &mut self.start);
        let watch = &mut integrator.stage_watch;
        watch.mode.clone_from(&self.mode);
        watch.margins.resize(self.start.len(), 0.0);
        Ok(())
    }

    /// Whether the attempted step's end (θ ⊕ its Δ from `theta`, its θ̇)
    /// leaves the mode of its start. The rows' margins are those of the
    /// rates at the end: the last stage's for a "first same as last"
    /// method, else evaluated there (and kept for the next step's first
    /// stage).
    pub(super) fn switched(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        integrator: &mut Integrator,
        theta: &[f64],
        end_time: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<bool, DynamicsError> {
        if !integrator.last_stage_is_end() {
            integrator.evaluate_end(model, ws, theta, end_time, inputs_at)?;
        }
        self.theta_end.copy_from_slice(theta);
        retract(model, &mut self.theta_end, integrator.delta.as_slice());
        self.mode.margins(model, ws, &self.theta_end, &mut self.end)?;
        Ok(self.mode.left(&self.end))
    }

    /// Cuts the attempted step of `step`, which left the mode, to end just
    /// past the earliest switch: the integrator is left holding the attempt
    /// of the step returned, from (θ, θ̇) at `t` after work `work`.
    ///
    /// The switch is first found on the attempt's interpolant, formed in
    /// `reach` (free here: a step cut to a switch is formed again there if
    /// it reaches past the communication point), where a reading costs one
    /// evaluation of the rates; attempts, a whole step each, then confirm
    /// it from there.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn locate(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        integrator: &mut Integrator,
        (theta, qvel): (&[f64], &[f64]),
        (t, step, work): (f64, f64, f64),
        tolerance: f64,
        reach: &mut Reach,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<Located, DynamicsError> {
        let resolution = (RESOLUTION_SHARE * tolerance * step).max(4.0 * f64::EPSILON * t.abs().max(1.0));
        self.attempted.copy_from_slice(&self.end);
        // ROS34PW2 has no interpolant; where the rates cannot be evaluated on
        // one, the attempts find the switch alone too.
        let hint = integrator.method.dense().and_then(|_| {
            integrator
                .form_interpolant(model, ws, (theta, qvel), (t, step), work, inputs_at, reach)
                .and_then(|()| {
                    self.narrow((step, resolution), MAX_READINGS, None, |switches, aim| {
                        integrator.evaluate_on_interpolant(model, ws, reach, t + aim, inputs_at)?;
                        switches.mode.margins(model, ws, integrator.theta_stage.as_slice(), &mut switches.end)?;
                        Ok(switches.mode.left(&switches.end))
                    })
                })
                .ok()
                .map(|bracket| (bracket.before, bracket.after))
        });
        self.end.copy_from_slice(&self.attempted);
        let bracket = self.narrow((step, resolution), MAX_ATTEMPTS, hint, |switches, aim| {
            integrator.attempt(model, ws, (theta, qvel), (t, aim), inputs_at)?;
            switches.switched(model, ws, integrator, theta, t + aim, inputs_at)
        })?;
        let mut attempts = bracket.readings;
        if !bracket.holds_after {
            integrator.attempt(model, ws, (theta, qvel), (t, bracket.after), inputs_at)?;
            if !integrator.last_stage_is_end() {
                integrator.evaluate_end(model, ws, theta, t + bracket.after, inputs_at)?;
            }
            attempts += 1;
        }
        self.end.copy_from_slice(&self.after);
        Ok(Located { step: bracket.after, attempts })
    }

    /// Narrows the bracket (0, `step`) of the earliest switch, whose
    /// margins are `start` and `end`, to `resolution` or at most `limit`
    /// readings of `read` (which sets `end` at the share given and says
    /// whether it left the mode), then by the secant. A `hint` (a bracket
    /// found on the interpolant) is read first at its end and, where that
    /// switches, at its start: a switch that only a jumping margin shows
    /// (no secant to follow) is then bracketed in two readings.
    fn narrow(
        &mut self,
        (step, resolution): (f64, f64),
        limit: usize,
        hint: Option<(f64, f64)>,
        mut read: impl FnMut(&mut Self, f64) -> Result<bool, DynamicsError>,
    ) -> Result<Bracket, DynamicsError> {
        self.before.copy_from_slice(&self.start);
        self.after.copy_from_slice(&self.end);
        self.jump_evidence.fill(0);
        let mut bracket = Bracket { before: 0.0, after: step, holds_after: true, readings: 0 };
        // The Illinois rule: an end of the bracket that stays while the other
        // moves twice has its distances halved in the secant, so that the
        // estimates close in on the switch from both sides instead of from
        // one (plain regula falsi took 10 to 13 attempts per switch).
        let (mut weight_before, mut weight_after) = (1.0, 1.0);
        let mut last_moved: Option<bool> = None;
        // Aim just past the secant's estimate after the bracket's start
        // moved, just short of it after its end moved: an accurate
        // estimate then closes the bracket in two readings.
        let mut past = true;
        // How far past or short of the estimate a reading aims, and the least
        // it keeps from either end of the bracket.
        let nudge = 0.4 * resolution;
        let mut widths = [step; 3];
        while bracket.after - bracket.before > resolution && bracket.readings < limit {
            let (before, after) = (bracket.before, bracket.after);
            let width = after - before;
            let inset = nudge.max(1e-6 * width);
            let aim = match hint {
                // The hint is read as close to the bracket's ends as it lies: it
                // may bound the switch to within the resolution already.
                Some((_, end)) if bracket.readings == 0 => end.clamp(before + nudge, after - nudge),
                Some((start, end)) if bracket.readings == 1 && after == end && start > before => {
                    start.clamp(before + nudge, after - nudge)
                }
                // Bisect where the secant has not halved the bracket in its last three readings.
                _ if bracket.readings >= 3 && width > 0.5 * widths[bracket.readings % 3] => before + 0.5 * width,
                _ => match self.earliest_switch(weight_before, weight_after) {
                    Some(share) => {
                        let estimate = before + share * width;
                        let nudged = if past { estimate + nudge } else { estimate - nudge };
                        nudged.clamp(before + inset, after - inset)
                    }
                    // Only margins that jump switch in the bracket: no secant to follow.
                    None => before + 0.5 * width,
                },
            };
            widths[bracket.readings % 3] = width;
            bracket.readings += 1;
            let left = read(self, aim)?;
            self.note_jumps((aim - before) / width, left);
            if left {
                bracket.after = aim;
                self.after.copy_from_slice(&self.end);
                bracket.holds_after = true;
                past = false;
                weight_after = 1.0;
            } else {
                bracket.before = aim;
                self.before.copy_from_slice(&self.end);
                bracket.holds_after = false;
                past = true;
                weight_before = 1.0;
            }
            if last_moved == Some(left) {
                if left { weight_before *= 0.5 } else { weight_after *= 0.5 }
            }
            last_moved = Some(left);
        }
        Ok(bracket)
    }

    /// After a step is taken without leaving its mode: the margins at its
    /// end are those at the next step's start, in the same mode.
    pub(super) fn step_taken(&mut self) {
        std::mem::swap(&mut self.start, &mut self.end);
    }

    /// The earliest switch, as a share of the bracket, of the margins that
    /// switch between its ends, each taken as linear between them (the
    /// secant); `None` when only margins that jump switch there.
    fn earliest_switch(&self, weight_before: f64, weight_after: f64) -> Option<f64> {
        let continuous = || (0..self.before.len()).filter(|&k| !self.jumps(k));
        continuous().any(|k| self.switches_in_bracket(k)).then(|| {
            earliest_zero(continuous().map(|k| {
                let (before, after) = (self.mode.distance(k, self.before[k]), self.mode.distance(k, self.after[k]));
                (weight_before * before, weight_after * after)
            }))
        })
    }

    /// Whether margin `k` switches between the bracket's ends.
    fn switches_in_bracket(&self, k: usize) -> bool {
        self.mode.distance(k, self.before[k]) >= 0.0 && self.mode.distance(k, self.after[k]) < 0.0
    }

    /// Whether the readings showed margin `k` to jump.
    fn jumps(&self, k: usize) -> bool {
        self.jump_evidence[k] == NEAR_SIDE_STAYS | FAR_SIDE_STAYS
    }

    /// After a reading at `share` of the bracket (its margins in `end`,
    /// `left` whether it switched), before the bracket moves: of each
    /// margin switching in the bracket, whether the reading found it where
    /// the bracket's end on its side of the switch has it, although the
    /// line between the ends put it a share of the way across. A margin
    /// that a wrap's choice of tangents makes jump (by 10⁴ where they
    /// cross) shows this on both sides; a smooth one on one side at most
    /// (a margin that starts at zero and bends back reads as staying near
    /// its start), so only both make a jump.
    fn note_jumps(&mut self, share: f64, left: bool) {
        for k in 0..self.before.len() {
            if !self.switches_in_bracket(k) {
                continue;
            }
            let (before, after) = (self.mode.distance(k, self.before[k]), self.mode.distance(k, self.after[k]));
            let reading = self.mode.distance(k, self.end[k]);
            let across = after - before;
            let stays = if reading >= 0.0 {
                ((reading - before).abs() < 0.1 * share * across.abs()).then_some(NEAR_SIDE_STAYS)
            } else if left {
                ((reading - after).abs() < 0.1 * (1.0 - share) * across.abs()).then_some(FAR_SIDE_STAYS)
            } else {
                None
            };
            self.jump_evidence[k] |= stays.unwrap_or(0);
        }
    }
}

/// Of a margin that jumps: a reading short of the switch found it where
/// the bracket's start has it.
const NEAR_SIDE_STAYS: u8 = 1;

/// A reading past the switch found it where the bracket's end has it.
const FAR_SIDE_STAYS: u8 = 2;

/// The earliest zero, as a share of the bracket, of the (before, after)
/// distances that change from non-negative to negative across it.
fn earliest_zero(distances: impl Iterator<Item = (f64, f64)>) -> f64 {
    distances
        .filter(|(before, after)| *after < 0.0 && *before >= 0.0)
        .map(|(before, after)| if before.is_finite() && after.is_finite() { before / (before - after) } else { 0.5 })
        .fold(1.0, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_secant_takes_the_earliest_switch() {
        // Distance 0 stays, 1 crosses at 3/4, 2 at 1/4 of the bracket, 3 was past already.
        let distances = [(1.0, 2.0), (3.0, -1.0), (1.0, -3.0), (-1.0, -2.0)];
        assert_eq!(earliest_zero(distances.into_iter()), 0.25);
        assert_eq!(earliest_zero([(1.0, 2.0)].into_iter()), 1.0);
    }

    /// Switches over margins given as functions of the time into a step of 1 s.
    fn switches_of(margins: &[fn(f64) -> f64]) -> Switches {
        let start: Vec<f64> = margins.iter().map(|m| m(0.0)).collect();
        let end: Vec<f64> = margins.iter().map(|m| m(1.0)).collect();
        Switches {
            mode: ConstraintMode::of_margins(margins.len()),
            before: start.clone(),
            after: end.clone(),
            attempted: end.clone(),
            jump_evidence: vec![0; margins.len()],
            theta_end: Vec::new(),
            start,
            end,
        }
    }

    /// Narrows (0, 1 s) to `RESOLUTION` from `hint` on `margins`.
    fn narrowed(margins: &[fn(f64) -> f64], hint: Option<(f64, f64)>) -> (Bracket, Switches) {
        let mut switches = switches_of(margins);
        let bracket = switches
            .narrow((1.0, RESOLUTION), MAX_ATTEMPTS, hint, |switches, aim| {
                for (value, margin) in switches.end.iter_mut().zip(margins) {
                    *value = margin(aim);
                }
                Ok(switches.mode.left(&switches.end))
            })
            .expect("the readings cannot fail");
        assert!(bracket.after - bracket.before <= RESOLUTION, "not narrowed: {:?}", (bracket.before, bracket.after));
        (bracket, switches)
    }

    const RESOLUTION: f64 = 1e-9;

    /// A wrap's choice of tangents where they cross, by 10⁴, at 0.37 s.
    fn jumping(t: f64) -> f64 {
        if t < 0.37 { 1e-3 } else { -1e4 }
    }

    #[test]
    fn a_margin_that_jumps_is_left_out_of_the_secant() {
        // A continuous margin crossing just before it: the secant follows that one.
        let (bracket, switches) = narrowed(&[jumping, |t| 0.37 - 1e-10 - t], None);
        assert!((bracket.after - 0.37).abs() < 1e-9 && bracket.readings <= 10, "{} readings", bracket.readings);
        assert!(switches.jumps(0) && !switches.jumps(1));
        // Just after it: the secant brings the bracket near, halving closes it.
        let (bracket, _) = narrowed(&[jumping, |t| 0.37 + 1e-10 - t], None);
        assert!((bracket.after - 0.37).abs() < 1e-9 && bracket.readings <= 16, "{} readings", bracket.readings);
        // Alone, it is halved (30 halvings of 1 s to 1e-9 s).
        let (bracket, _) = narrowed(&[jumping], None);
        assert!((bracket.after - 0.37).abs() < 1e-9 && bracket.readings <= 34, "{} readings", bracket.readings);
    }

    #[test]
    fn a_margin_that_starts_at_zero_and_bends_back_is_no_jump() {
        // Just past an earlier switch, it rises and falls through zero at 0.4 s.
        let (bracket, switches) = narrowed(&[|t| 1e-9 + 0.4 * t - t * t], None);
        assert!(!switches.jumps(0));
        // The secant's own pace here (Illinois), 17 readings; halving took 30.
        assert!((bracket.after - 0.4).abs() < 1e-8 && bracket.readings <= 20, "{} readings", bracket.readings);
    }

    #[test]
    fn a_hint_within_the_resolution_closes_the_bracket_at_once() {
        // A jump a hair after the start, bracketed on the interpolant already.
        let (bracket, _) = narrowed(&[|t| if t < 1e-12 { 1e4 } else { -1e-3 }], Some((0.0, 6.6e-10)));
        assert_eq!(bracket.readings, 1);
        // A hint whose end switches and whose start does not: two readings.
        let (bracket, _) = narrowed(&[jumping], Some((0.37 - 0.5e-9, 0.37 + 0.4e-9)));
        assert_eq!(bracket.readings, 2);
    }
}
