//! Where the constraint forces switch, located as events inside an
//! adaptive run (docs/integration.md, "Constraint switches").
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
//! safeguarded secant, and the next step starts in the mode its start
//! gives. The mode is always derived from the step's start, so nothing
//! beyond the state is carried between steps, and a restored run repeats
//! exactly.
//!
//! A switch undone within one step is not seen (the usual limit of event
//! location); steps under error control are short against the time a soft
//! constraint takes to act.

use super::rkmk::{Integrator, retract};
use crate::dynamics::DynamicsError;
use crate::dynamics::constraint::limit_switching_functions;
use crate::model::Model;
use crate::workspace::Workspace;

/// At most this many attempts locate one switch: the secant closes the
/// bracket in two or three, and every third attempt bisects, so that 40
/// reach any resolution down to round-off from a step of any length.
const MAX_ATTEMPTS: usize = 40;

/// The bracket a switch is located to, as a share of the tolerance times
/// the step: held past its switch by that much of the step, a mode
/// changes the state by a small part of what the step may err by.
const RESOLUTION_SHARE: f64 = 0.01;

/// The margins of the mode (limit sides first, then rows) at the points of
/// the step being located, and the buffers to compute them.
#[derive(Clone, Debug, Default)]
pub struct Switches {
    /// Which limit sides the step holds active.
    sides_active: Vec<bool>,
    /// The sides' switching functions at a configuration (scratch).
    side_values: Vec<f64>,
    /// The margins at the step's start: a margin switches where it falls
    /// below the lesser of 0 and this (a bound force's multiplier may start
    /// a hair below 0, within the solver's tolerance).
    start: Vec<f64>,
    /// At the end of the step attempted last.
    end: Vec<f64>,
    /// At the end of the longest step known not to switch (the bracket's start).
    before: Vec<f64>,
    /// At the end of the shortest step known to switch (the bracket's end).
    after: Vec<f64>,
    /// The configuration at the end of the attempted step.
    theta_end: Vec<f64>,
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
        let sides = model.constraints.limit_sides();
        let margins = if model.constraints.is_empty() { 0 } else { sides + 2 * model.constraints.max_rows() };
        Switches {
            sides_active: vec![false; sides],
            side_values: vec![0.0; sides],
            start: vec![0.0; margins],
            end: vec![0.0; margins],
            before: vec![0.0; margins],
            after: vec![0.0; margins],
            theta_end: if margins > 0 { vec![0.0; model.nq] } else { Vec::new() },
        }
    }

    /// Whether the model has constraints whose forces can switch.
    pub fn watched(&self) -> bool {
        !self.start.is_empty()
    }

    /// Sets the mode a step from (θ, θ̇) at `t` holds: the sides active at
    /// θ, and the working set the solver finds there; evaluates the rates
    /// there as the step's first stage.
    pub(super) fn establish(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        integrator: &mut Integrator,
        (theta, qvel): (&[f64], &[f64]),
        t: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<(), DynamicsError> {
        self.establish_after(model, ws, integrator, (theta, qvel), t, false, inputs_at)
    }

    /// [`Switches::establish`] at the end of a step cut to a switch
    /// (`located`): the forces that crossed a bound of their working set
    /// start the solve there on its far side.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn establish_after(
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
            let sides = self.sides_active.len();
            let rows = model.constraints.max_rows();
            let forces = (sides..sides + rows).filter(|&k| self.end[k] < threshold(self.start[k]));
            for k in forces {
                ws.cross_working_set(k - sides);
            }
        }
        side_switching_functions(model, ws, theta, &mut self.side_values)?;
        for (active, value) in self.sides_active.iter_mut().zip(&self.side_values) {
            *active = *value < 0.0;
        }
        ws.hold_limit_sides(&self.side_values);
        ws.release_working_set();
        integrator.evaluate_start(model, ws, (theta, qvel), t, inputs_at)?;
        ws.hold_working_set(model);
        let Switches { sides_active, side_values, start, .. } = self;
        margins(model, ws, sides_active, side_values, start);
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
        side_switching_functions(model, ws, &self.theta_end, &mut self.side_values)?;
        let Switches { sides_active, side_values, end, .. } = self;
        margins(model, ws, sides_active, side_values, end);
        Ok(leaves(&self.start, &self.end))
    }

    /// Cuts the attempted step of `step`, which left the mode, to end just
    /// past the earliest switch: the integrator is left holding the attempt
    /// of the step returned, from (θ, θ̇) at `t`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn locate(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        integrator: &mut Integrator,
        (theta, qvel): (&[f64], &[f64]),
        (t, step): (f64, f64),
        tolerance: f64,
        inputs_at: &mut impl FnMut(f64, &mut [f64], &mut [f64]),
    ) -> Result<Located, DynamicsError> {
        let resolution = (RESOLUTION_SHARE * tolerance * step).max(4.0 * f64::EPSILON * t.abs().max(1.0));
        self.before.copy_from_slice(&self.start);
        self.after.copy_from_slice(&self.end);
        let (mut before, mut after) = (0.0, step);
        // Whether the attempt the integrator holds is the one of `after`.
        let mut holds_after = true;
        // Aim just past the secant's estimate after the bracket's start
        // moved, just short of it after its end moved: an accurate
        // estimate then closes the bracket in two attempts.
        let mut past = true;
        let mut attempts = 0;
        while after - before > resolution && attempts < MAX_ATTEMPTS {
            let width = after - before;
            let aim = if attempts % 3 == 2 {
                before + 0.5 * width
            } else {
                let estimate = before + earliest_switch(&self.start, &self.before, &self.after) * width;
                let nudged = if past { estimate + 0.5 * resolution } else { estimate - 0.5 * resolution };
                nudged.clamp(before + 0.01 * width, after - 0.01 * width)
            };
            integrator.attempt(model, ws, (theta, qvel), (t, aim), inputs_at)?;
            attempts += 1;
            if self.switched(model, ws, integrator, theta, t + aim, inputs_at)? {
                after = aim;
                self.after.copy_from_slice(&self.end);
                holds_after = true;
                past = false;
            } else {
                before = aim;
                self.before.copy_from_slice(&self.end);
                holds_after = false;
                past = true;
            }
        }
        if !holds_after {
            integrator.attempt(model, ws, (theta, qvel), (t, after), inputs_at)?;
            if !integrator.last_stage_is_end() {
                integrator.evaluate_end(model, ws, theta, t + after, inputs_at)?;
            }
            attempts += 1;
        }
        self.end.copy_from_slice(&self.after);
        Ok(Located { step: after, attempts })
    }

    /// After a step is taken without leaving its mode: the margins at its
    /// end are those at the next step's start, in the same mode.
    pub(super) fn step_taken(&mut self) {
        std::mem::swap(&mut self.start, &mut self.end);
    }
}

/// The limit sides' switching functions at `theta`: the joints' limits
/// read it directly, the tendons' need their lengths there (passes 0 and 1).
fn side_switching_functions(
    model: &Model,
    ws: &mut Workspace,
    theta: &[f64],
    out: &mut [f64],
) -> Result<(), DynamicsError> {
    if model.constraints.tendon_limits.is_empty() {
        limit_switching_functions(model, theta, &[], out);
    } else {
        ws.set_configuration(model, theta)?;
        limit_switching_functions(model, theta, ws.tendon_length.as_slice(), out);
    }
    Ok(())
}

/// The mode's margins into `out`: the sides' (their switching function,
/// negated where held active), then the rows' of the workspace's last
/// evaluation.
fn margins(model: &Model, ws: &Workspace, sides_active: &[bool], side_values: &[f64], out: &mut [f64]) {
    let (sides, rows) = out.split_at_mut(sides_active.len());
    for ((margin, &active), &value) in sides.iter_mut().zip(sides_active).zip(side_values) {
        *margin = if active { -value } else { value };
    }
    ws.switching_margins(model, rows);
}

/// The level below which a margin that started at `start` has switched.
fn threshold(start: f64) -> f64 {
    start.min(0.0)
}

/// Whether some margin fell below its threshold.
fn leaves(start: &[f64], end: &[f64]) -> bool {
    start.iter().zip(end).any(|(s, e)| *e < threshold(*s))
}

/// The earliest switch, as a share of the bracket, of the margins that
/// cross their threshold between its ends, each taken as linear between
/// them (the secant).
fn earliest_switch(start: &[f64], before: &[f64], after: &[f64]) -> f64 {
    start
        .iter()
        .zip(before.iter().zip(after))
        .filter(|(s, (b, a))| **a < threshold(**s) && **b >= threshold(**s))
        .map(|(s, (b, a))| {
            let (b, a) = (b - threshold(*s), a - threshold(*s));
            if b.is_finite() && a.is_finite() { b / (b - a) } else { 0.5 }
        })
        .fold(1.0, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_secant_takes_the_earliest_switch() {
        // Margin 0 stays, margin 1 crosses at 3/4, margin 2 at 1/4 of the bracket.
        let start = [1.0, 3.0, 1.0];
        let before = [1.0, 3.0, 1.0];
        let after = [2.0, -1.0, -3.0];
        assert_eq!(earliest_switch(&start, &before, &after), 0.25);
        assert!(leaves(&start, &after));
        assert!(!leaves(&start, &[5.0, 0.0, 2.0]));
        // A margin that starts a hair below zero switches only below that.
        assert!(!leaves(&[-1e-16], &[-1e-16]));
        assert!(leaves(&[-1e-16], &[-1e-15]));
    }
}
