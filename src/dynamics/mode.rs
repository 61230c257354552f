//! The constraint mode: what makes MuJoCo's constraint forces switch, held
//! while the state moves, and how far each switch is (docs/integration.md,
//! "Constraint switches"); and the spatial tendons' wraps, whose paths
//! switch too and are held with it (wrap.rs).
//!
//! The forces are smooth in the state except where a limit side switches
//! on or off, a force reaches or leaves a bound of its box, or a row's
//! impedance changes piece (and, with MuJoCo's no-slip pass, where its
//! sweeps decide otherwise). A mode fixes all of these (the sides active,
//! the solver's working set, the pieces, the pass's decisions, the wraps'
//! paths) on a [`Workspace`]; its margins, one
//! per switch and positive while the mode holds, tell where it stops being
//! MuJoCo's. The adaptive integrators hold a step's start mode over the
//! step and locate where a margin crosses zero; a model-exchange FMU holds
//! it between events and gives the margins as event indicators.

use super::DynamicsError;
use super::constraint::limit_switching_functions;
use crate::model::Model;
use crate::workspace::Workspace;

/// A mode held on a workspace, and the buffers of its margins.
#[derive(Clone, Debug, Default)]
pub struct ConstraintMode {
    /// Which limit sides the mode holds active.
    sides_active: Vec<bool>,
    /// The sides' switching functions at a configuration (scratch).
    side_values: Vec<f64>,
    /// Each margin's level of switching: the lesser of 0 and its value
    /// where the mode was set (a bound force's multiplier may start a hair
    /// below 0, within the solver's tolerance).
    thresholds: Vec<f64>,
    /// How many of the margins are the constraint rows' (after the sides).
    rows: usize,
    /// The sign of each wrap's switching function where the mode was set:
    /// its margin is the function times that.
    wrap_signs: Vec<f64>,
}

impl ConstraintMode {
    /// Buffers for `model`: [`Model::switch_count`] margins.
    pub fn new(model: &Model) -> Self {
        let sides = model.constraints.limit_sides();
        ConstraintMode {
            sides_active: vec![false; sides],
            side_values: vec![0.0; sides],
            thresholds: vec![0.0; model.switch_count()],
            rows: model.constraints.switch_count().saturating_sub(sides),
            wrap_signs: vec![1.0; model.wrap_switches()],
        }
    }

    /// A mode of `count` margins alone, each switching at zero: for
    /// testing what reads margins.
    #[cfg(test)]
    pub(crate) fn of_margins(count: usize) -> Self {
        ConstraintMode { thresholds: vec![0.0; count], ..ConstraintMode::default() }
    }

    /// How many margins the mode has (0 without constraints).
    pub fn len(&self) -> usize {
        self.thresholds.len()
    }

    /// Whether the mode has no margin (no constraints).
    pub fn is_empty(&self) -> bool {
        self.thresholds.is_empty()
    }

    /// First half of setting the mode at configuration `theta`: holds the
    /// sides active there and frees the working set. Evaluate the rates at
    /// the state (the solver then finds its working set there), then call
    /// [`ConstraintMode::hold_working_set`].
    pub fn hold_sides(&mut self, model: &Model, ws: &mut Workspace, theta: &[f64]) -> Result<(), DynamicsError> {
        side_switching_functions(model, ws, theta, &mut self.side_values)?;
        for (active, value) in self.sides_active.iter_mut().zip(&self.side_values) {
            *active = *value < 0.0;
        }
        ws.hold_limit_sides(&self.side_values);
        ws.release_working_set();
        Ok(())
    }

    /// Second half: holds the working set and impedance pieces of the
    /// evaluation just made, and writes the margins there into `start`
    /// (whose levels of switching they set).
    pub fn hold_working_set(&mut self, ws: &mut Workspace, start: &mut [f64]) {
        ws.hold_working_set();
        for (sign, value) in self.wrap_signs.iter_mut().zip(&ws.wrap_switching) {
            *sign = if *value < 0.0 { -1.0 } else { 1.0 };
        }
        self.write_margins(ws, start);
        for (threshold, margin) in self.thresholds.iter_mut().zip(start.iter()) {
            *threshold = margin.min(0.0);
        }
    }

    /// The margins at configuration `theta`, the rows' from the workspace's
    /// last evaluation (at that state, the mode held), into `out`.
    pub fn margins(
        &mut self,
        model: &Model,
        ws: &mut Workspace,
        theta: &[f64],
        out: &mut [f64],
    ) -> Result<(), DynamicsError> {
        side_switching_functions(model, ws, theta, &mut self.side_values)?;
        self.write_margins(ws, out);
        Ok(())
    }

    /// Whether some margin in `margins` has switched.
    pub fn left(&self, margins: &[f64]) -> bool {
        self.thresholds.iter().zip(margins).any(|(threshold, margin)| margin < threshold)
    }

    /// How far `margin` number `k` is from switching (negative once it has).
    pub fn distance(&self, k: usize, margin: f64) -> f64 {
        margin - self.thresholds[k]
    }

    /// The number of limit sides (the margins before the rows').
    pub fn sides(&self) -> usize {
        self.sides_active.len()
    }

    fn write_margins(&self, ws: &Workspace, out: &mut [f64]) {
        let (sides, rest) = out.split_at_mut(self.sides_active.len());
        let (rows, wraps) = rest.split_at_mut(self.rows);
        for ((margin, &active), &value) in sides.iter_mut().zip(&self.sides_active).zip(&self.side_values) {
            *margin = if active { -value } else { value };
        }
        if !rows.is_empty() {
            ws.switching_margins(rows);
        }
        for ((margin, sign), value) in wraps.iter_mut().zip(&self.wrap_signs).zip(&ws.wrap_switching) {
            *margin = sign * value;
        }
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
