//! MuJoCo's no-slip pass (docs/DYNAMICS.md §8): after the constraint
//! forces are solved for, projected Gauss-Seidel sweeps over the
//! friction-loss rows move each force to the minimizer of the cost *without*
//! its regularizer, clamped to ±frictionloss, the other forces held. MuJoCo
//! 4.0 runs it island by island: an island is a connected group of
//! kinematic trees (subtrees hanging from the world) joined by rows that
//! reach into several of them, and each island stops on its own once a
//! sweep's cost improvement, divided by the trace of its trees' M at the
//! state, falls below `noslip_tolerance`. With `<flag island="disable">`
//! all rows are one group and the trace is M's.
//!
//! The pass's decisions (each sweep's clamp of each row, each island's
//! number of sweeps) make its forces jump or kink where they change: the
//! stopping rule is a jump. So they belong to the constraint mode: an
//! integrator holds them over a step like the solver's working set
//! ([`Workspace::hold_working_set`]), the pass then follows them, and
//! their margins say where MuJoCo's pass would decide otherwise.

use super::constraint::{ConstraintRows, RowKind};
use super::forces::{Direction, inward_pass};
use super::{DynamicsError, require};
use crate::math::{Real, SpatialMat, Transform, dot};
use crate::model::Model;
use crate::vehicle::ConstraintOptions;
use crate::workspace::{Stage, Workspace};

/// MuJoCo's smallest denominator (mjMINVAL).
const MIN_VALUE: f64 = 1e-15;
/// A row whose Jacobian reaches no dof: in no island.
const NO_TREE: usize = usize::MAX;

/// Where a sweep put a friction row's force.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Clamp {
    /// At the row's own minimizer, within its box.
    #[default]
    Free,
    /// Clamped to the box's lower end.
    Lower,
    /// Clamped to its upper end.
    Upper,
}

/// What one pass decided.
#[derive(Clone, Debug, Default)]
struct Decisions {
    /// The rows of the pass.
    rows: usize,
    /// Each island's sweeps, at its first row (0 at the other rows).
    sweeps: Vec<usize>,
    /// Each sweep's clamp of each row: sweep j of row k at j·max_rows + k.
    clamps: Vec<Clamp>,
}

/// The pass's buffers (empty for a model that never runs it), in the
/// passes' scalar: with dual numbers the forces carry their derivatives
/// through the sweeps, each decision taken on the values.
#[derive(Clone, Debug)]
pub struct NoSlipBuffers<S: Real = f64> {
    /// Each dof's kinematic tree, named by the link at its root.
    dof_tree: Vec<usize>,
    /// Union-find parents over trees (indexed by link; only roots used).
    tree_parent: Vec<usize>,
    /// Each row's island (its representative tree), or [`NO_TREE`].
    row_island: Vec<usize>,
    /// diag(M) at the state (its values: it scales the stopping rule only).
    mass_diagonal: Vec<f64>,
    /// Each link's composite inertia (its subtree's, in its frame), for
    /// diag(M) of a rigid tree.
    composite: Vec<SpatialMat>,
    /// A unit ε and the torque m ε it gives: one column of m, for diag(M)
    /// of a flexible vehicle.
    unit: Vec<S>,
    column: Vec<S>,
    /// The solver's forces, before the pass moved the friction rows'.
    solved: Vec<S>,
    /// The last pass's decisions.
    decided: Decisions,
    /// The decisions held over an integrator's step, when `holding`.
    held: Decisions,
    holding: bool,
    /// Whether the last pass's last sweep over each row left its force
    /// free (the row sticks).
    free_at_end: Vec<bool>,
    /// How far each of the last pass's decisions is from changing
    /// ([`Constraints::no_slip_switches`](crate::model::Constraints::no_slip_switches)
    /// long): the clamps, then the stopping rules; +∞ where nothing switches.
    margins: Vec<f64>,
}

impl<S: Real> Default for NoSlipBuffers<S> {
    fn default() -> Self {
        NoSlipBuffers {
            dof_tree: Vec::new(),
            tree_parent: Vec::new(),
            row_island: Vec::new(),
            mass_diagonal: Vec::new(),
            composite: Vec::new(),
            unit: Vec::new(),
            column: Vec::new(),
            solved: Vec::new(),
            decided: Decisions::default(),
            held: Decisions::default(),
            holding: false,
            free_at_end: Vec::new(),
            margins: Vec::new(),
        }
    }
}

impl<S: Real> NoSlipBuffers<S> {
    /// Buffers for `model` when it runs the pass (iterations > 0 and
    /// friction-loss rows), else none.
    pub fn new(model: &Model) -> Self {
        let constraints = &model.constraints;
        if !constraints.runs_no_slip_pass() {
            return NoSlipBuffers::default();
        }
        let mut dof_tree = vec![0; model.nv];
        for (i, link) in model.links.iter().enumerate() {
            let mut root = i;
            while let Some(parent) = model.links[root].parent {
                root = parent;
            }
            dof_tree[link.dof_adr..link.dof_adr + link.ndof].fill(root);
        }
        let nv = model.nv;
        let max_rows = constraints.max_rows();
        let sweeps = constraints.options.noslip_iterations as usize;
        let decisions = Decisions { rows: 0, sweeps: vec![0; max_rows], clamps: vec![Clamp::Free; sweeps * max_rows] };
        NoSlipBuffers {
            dof_tree,
            tree_parent: (0..model.links.len()).collect(),
            row_island: vec![NO_TREE; max_rows],
            mass_diagonal: vec![0.0; nv],
            composite: vec![SpatialMat::zeros(); model.links.len()],
            unit: vec![S::zero(); nv],
            column: vec![S::zero(); nv],
            solved: vec![S::zero(); max_rows],
            decided: decisions.clone(),
            held: decisions,
            holding: false,
            free_at_end: vec![false; max_rows],
            margins: vec![f64::INFINITY; constraints.no_slip_switches()],
        }
    }

    /// Holds the last pass's decisions for the passes that follow.
    pub(super) fn hold(&mut self) {
        self.held.clone_from(&self.decided);
        self.holding = !self.margins.is_empty();
    }

    /// Holds the decisions `other` holds (an f64 workspace's), or none.
    pub(super) fn hold_those_of<T: Real>(&mut self, other: &NoSlipBuffers<T>) {
        self.held.clone_from(&other.held);
        self.holding = other.holding && !self.margins.is_empty();
    }

    /// Lets the passes decide again.
    pub(super) fn release(&mut self) {
        self.holding = false;
    }

    /// The last pass's margins (empty without the pass).
    pub(super) fn margins(&self) -> &[f64] {
        &self.margins
    }

    /// Whether the last pass left row `k`'s force free of its box (a friction
    /// row that sticks): its acceleration is then taken to its reference.
    pub(super) fn sticks(&self, k: usize) -> bool {
        k < self.decided.rows && self.free_at_end[k]
    }

    /// Row `k`'s force as the solver gave it, when the pass ran on the rows.
    pub(super) fn solved_force(&self, k: usize) -> Option<f64> {
        (k < self.decided.rows).then(|| self.solved[k].value())
    }

    /// The representative of `tree`'s group, halving paths on the way.
    fn find(&mut self, mut tree: usize) -> usize {
        while self.tree_parent[tree] != tree {
            self.tree_parent[tree] = self.tree_parent[self.tree_parent[tree]];
            tree = self.tree_parent[tree];
        }
        tree
    }

    fn union(&mut self, one: usize, two: usize) {
        let (one, two) = (self.find(one), self.find(two));
        self.tree_parent[one.max(two)] = one.min(two);
    }

    /// Each row's island: trees a row reaches into are joined, and so are
    /// those of an equality constraint's rows together (MuJoCo joins the
    /// two bodies' trees even where one row's Jacobian vanishes in one).
    fn assign_islands(&mut self, rows: &ConstraintRows<S>, nv: usize, islands: bool) {
        for (t, parent) in self.tree_parent.iter_mut().enumerate() {
            *parent = t;
        }
        for k in 0..rows.count {
            let jacobian = &rows.jacobian[k * nv..(k + 1) * nv];
            let mut first = NO_TREE;
            for d in (0..nv).filter(|&d| jacobian[d].value() != 0.0) {
                let tree = self.dof_tree[d];
                if first == NO_TREE {
                    first = tree;
                } else {
                    self.union(first, tree);
                }
            }
            let same_equality = k > 0 && rows.kind[k] == RowKind::Equality && rows.kind[k - 1] == RowKind::Equality;
            if same_equality && rows.id[k] == rows.id[k - 1] && first != NO_TREE {
                match self.row_island[k - 1] {
                    NO_TREE => {}
                    previous => self.union(previous, first),
                }
            }
            self.row_island[k] = first;
        }
        for k in 0..rows.count {
            self.row_island[k] = match (self.row_island[k], islands) {
                (NO_TREE, _) => NO_TREE,
                (_, false) => 0,
                (tree, true) => self.find(tree),
            };
        }
    }

    /// diag(M) of a rigid tree on the values, from each link's composite
    /// inertia I^C (its subtree's, gathered tip to base by the congruence of
    /// pass 1): Mⱼⱼ = sⱼᵀ I^C sⱼ + armature. One congruence per link, where
    /// the columns of m take one inward pass per dof.
    fn mass_diagonal_of_tree(&mut self, model: &Model, ws: &Workspace<S>) {
        for (composite, link) in self.composite.iter_mut().zip(&model.links) {
            *composite = SpatialMat::zeros();
            link.add_spatial_inertia_to(composite);
        }
        // Parents precede their children, so a link's subtree is gathered when the sweep reaches it.
        for i in (0..model.links.len()).rev() {
            let link = &model.links[i];
            let (parents, rest) = self.composite.split_at_mut(i);
            let composite = &rest[0];
            for k in 0..link.ndof {
                let s = link.motion_subspace.column(k);
                self.mass_diagonal[link.dof_adr + k] = s.dot(&(composite * s)) + link.armature;
            }
            if let Some(p) = link.parent {
                let x = &ws.x_parent[i];
                let x = Transform { rot: x.rot.map(|e| e.value()), trans: x.trans.map(|e| e.value()) };
                x.add_inertia_to_parent(composite, &mut parents[p], false);
            }
        }
    }

    /// diag(M) = Σⱼ (m eⱼ)², as M = m mᵀ: one inward pass per dof, which
    /// also gathers a flexible body's modes and the links at its nodes.
    fn mass_diagonal_by_columns(&mut self, model: &Model, ws: &mut Workspace<S>) {
        self.mass_diagonal.fill(0.0);
        for j in 0..model.nv {
            self.unit[j] = S::one();
            inward_pass(model, ws, Direction::TorqueFromEps, &self.unit, None, &mut self.column);
            self.unit[j] = S::zero();
            for (entry, m) in self.mass_diagonal.iter_mut().zip(&self.column) {
                *entry += m.value() * m.value();
            }
        }
    }

    /// The trace of M over `island`'s trees (over every dof without islands).
    fn island_inertia(&mut self, island: usize, islands: bool) -> f64 {
        let mut trace = 0.0;
        for d in 0..self.dof_tree.len() {
            if !islands || self.find(self.dof_tree[d]) == island {
                trace += self.mass_diagonal[d];
            }
        }
        trace
    }
}

impl<S: Real> Workspace<S> {
    /// Runs MuJoCo's no-slip pass on the solved forces in `rows` when the
    /// model asks for it and a friction-loss row is active; while decisions
    /// are held over as many rows, it follows them.
    pub(crate) fn no_slip_pass(&mut self, model: &Model, rows: &mut ConstraintRows<S>) -> Result<(), DynamicsError> {
        let options = &model.constraints.options;
        let n = rows.count;
        let mut pass = std::mem::take(&mut rows.no_slip);
        if pass.margins.is_empty() {
            rows.no_slip = pass;
            return Ok(());
        }
        pass.margins.fill(f64::INFINITY);
        pass.decided.sweeps.fill(0);
        pass.decided.rows = n;
        pass.solved[..n].copy_from_slice(&rows.force[..n]);
        pass.free_at_end.fill(false);
        if !(0..n).any(|k| rows.kind[k].is_friction()) {
            rows.no_slip = pass;
            return Ok(());
        }
        let nv = model.nv;
        let result = require(self, Stage::Configuration, "no_slip_pass");
        if result.is_ok() {
            if model.flexible.is_empty() {
                pass.mass_diagonal_of_tree(model, self);
            } else {
                pass.mass_diagonal_by_columns(model, self);
            }
            pass.assign_islands(rows, nv, options.islands);
            let holding = pass.holding && pass.held.rows == n;
            for first in 0..n {
                let island = pass.row_island[first];
                if island == NO_TREE || (0..first).any(|k| pass.row_island[k] == island) {
                    continue;
                }
                let scale = 1.0 / pass.island_inertia(island, options.islands);
                // An island the held pass did not have (its rows' trees joined otherwise) decides anew.
                let held = (holding && pass.held.sweeps[first] > 0).then_some(&pass.held);
                let decided = (&mut pass.decided.clamps[..], &mut pass.free_at_end[..]);
                let sweeps = sweep_island(
                    rows,
                    (&pass.row_island, island, first),
                    scale,
                    options,
                    held,
                    decided,
                    &mut pass.margins,
                );
                pass.decided.sweeps[first] = sweeps;
            }
        }
        rows.no_slip = pass;
        result
    }
}

/// Gauss-Seidel sweeps over the friction rows of `island` (whose first row
/// is `first`) until its scaled improvement falls below `noslip_tolerance`
/// or `noslip_iterations` sweeps have run, or as `held` decided; writes
/// each sweep's clamps into `clamps` (and whether the last left each row
/// free into `free_at_end`) and the margins of the decisions into
/// `margins`, and returns the sweeps run.
fn sweep_island<S: Real>(
    rows: &mut ConstraintRows<S>,
    (row_island, island, first): (&[usize], usize, usize),
    scale: f64,
    options: &ConstraintOptions,
    held: Option<&Decisions>,
    (clamps, free_at_end): (&mut [Clamp], &mut [bool]),
    margins: &mut [f64],
) -> usize {
    let n = rows.count;
    let stride = rows.max_rows;
    let iterations = options.noslip_iterations as usize;
    let (clamp_margins, stop_margins) = margins.split_at_mut(iterations * stride);
    let in_island = |k: usize| row_island[k] == island;
    for iteration in 0..iterations {
        let mut improvement = S::zero();
        if iteration == 0 {
            // The main solver's cost counts ½ f R f, which this pass's does not.
            for k in (0..n).filter(|&k| in_island(k)) {
                improvement += S::from(0.5) * rows.force[k] * rows.force[k] * rows.regularizer[k];
            }
        }
        for i in 0..n {
            if !in_island(i) || !rows.kind[i].is_friction() {
                continue;
            }
            let hessian = &rows.hessian[i * stride..i * stride + n];
            let coupled = dot(hessian, &rows.force[..n]);
            let residual = coupled + rows.gradient[i] - rows.regularizer[i] * rows.force[i];
            let diagonal = hessian[i] - rows.regularizer[i];
            let inverse_diagonal = S::one() / if diagonal.value() < MIN_VALUE { S::from(MIN_VALUE) } else { diagonal };
            let old = rows.force[i];
            let minimizer = old - residual * inverse_diagonal;
            let (lower, upper) = (rows.lower[i], rows.upper[i]);
            let slot = iteration * stride + i;
            clamps[slot] = match held {
                Some(held) => held.clamps[slot],
                None if minimizer.value() < lower => Clamp::Lower,
                None if minimizer.value() > upper => Clamp::Upper,
                None => Clamp::Free,
            };
            let (force, margin) = match clamps[slot] {
                Clamp::Free => (minimizer, (minimizer.value() - lower).min(upper - minimizer.value())),
                Clamp::Lower => (S::from(lower), lower - minimizer.value()),
                Clamp::Upper => (S::from(upper), minimizer.value() - upper),
            };
            clamp_margins[slot] = margin;
            free_at_end[i] = clamps[slot] == Clamp::Free;
            rows.force[i] = force;
            let delta = force - old;
            improvement -= S::from(0.5) * delta * delta / inverse_diagonal + delta * residual;
        }
        let improvement = improvement.value() * scale;
        let stops = match held {
            Some(held) => iteration + 1 == held.sweeps[first],
            None => improvement < options.noslip_tolerance,
        };
        // After the last sweep, stopping or not is the same.
        if iteration + 1 < iterations {
            let to_tolerance = improvement - options.noslip_tolerance;
            stop_margins[iteration * stride + first] = if stops { -to_tolerance } else { to_tolerance };
        }
        if stops {
            return iteration + 1;
        }
    }
    iterations
}

#[cfg(test)]
mod tests {
    use super::*;

    /// diag(M) from the composite inertias agrees with the columns of m (one
    /// inward pass per dof, the route flexible vehicles take) on trees with
    /// free, ball, hinge and slide joints, several trees and armature, away
    /// from the file pose.
    #[test]
    fn the_composite_inertias_give_the_columns_diagonal() {
        let files = [
            "tests/fixtures/constraints/noslip_trees.xml",
            "tests/fixtures/constraints/docked_servicer.xml",
            "examples/bus_arm7.xml",
        ];
        for file in files {
            let (model, mut ws) = crate::dynamics::test_vehicle(file, 0.3);
            let nv = model.nv;
            let mut pass = NoSlipBuffers::<f64> {
                mass_diagonal: vec![f64::NAN; nv],
                composite: vec![SpatialMat::zeros(); model.links.len()],
                unit: vec![0.0; nv],
                column: vec![0.0; nv],
                ..NoSlipBuffers::default()
            };
            pass.mass_diagonal_by_columns(&model, &mut ws);
            let by_columns = pass.mass_diagonal.clone();
            pass.mass_diagonal.fill(f64::NAN);
            pass.mass_diagonal_of_tree(&model, &ws);
            for (d, (tree, columns)) in pass.mass_diagonal.iter().zip(&by_columns).enumerate() {
                assert!((tree - columns).abs() <= 1e-12 * columns, "{file}, dof {d}: {tree} against {columns}");
            }
        }
    }
}
