//! Constraint forces as MuJoCo computes them (docs/DYNAMICS.md §8), put
//! on the diagonalized dynamics as ε_c = m⁻¹Jᵀf, so that
//! ν̇ + C(θ, ν) = ε + ε_c keeps its form.
//!
//! For a state whose pass 3 has just run with the applied ε:
//! 1. θ̈ without constraints (MuJoCo's qacc_smooth): that pass's outward pass;
//! 2. the active rows in MuJoCo's order (equality constraints, friction loss
//!    by dof, then limits by joint, a hinge's or slide's lower side first):
//!    J, distance, margin (equality.rs builds the equality rows);
//! 3. E = m⁻¹Jᵀ, one inward pass per row, and A = J M⁻¹ Jᵀ = EᵀE (as
//!    M⁻¹ = m⁻ᵀm⁻¹: no dense M, no factorization beyond the passes'); with
//!    tendon armature, both made those of M_a (`tendon_inertia`);
//! 4. impedance, regularizer R and reference acceleration aref from
//!    solref/solimp (MuJoCo's `mj_makeImpedance`, `mj_referenceConstraint`);
//! 5. f minimizing ½fᵀ(A + R)f + fᵀ(J·qacc_smooth − aref) in the box each
//!    row allows ([`super::box_qp`]): the dual of MuJoCo's problem, whose
//!    unique minimizer all its solvers approach;
//! 6. MuJoCo's no-slip pass on the friction-loss rows, when the model asks
//!    for it (`super::noslip`);
//! 7. ε_c = E f and MuJoCo's qfrc_constraint = Jᵀf; ε_c is added to the
//!    pass's ν̇ and θ̈'s joint term (ε enters ν̇ additively), and the outward
//!    pass gives θ̈.

use super::box_qp::{BoxQp, Held};
use super::noslip::NoSlipBuffers;
use super::{DynamicsError, forces, require};
use crate::math::{Real, SpatialVec};
use crate::model::Limit;
use crate::model::Model;
use crate::vehicle::{JointKind, SoftConstraint};
use crate::workspace::{Stage, Workspace};

/// MuJoCo's smallest denominator (mjMINVAL).
const MIN_VALUE: f64 = 1e-15;
/// MuJoCo's bounds on the impedance (mjMINIMP, mjMAXIMP).
const IMPEDANCE_BOUNDS: (f64, f64) = (0.0001, 0.9999);

/// What a row constrains (MuJoCo's `efc_type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RowKind {
    /// An equality constraint's row: f free.
    Equality,
    /// Friction loss of a dof: |f| ≤ frictionloss.
    Friction,
    /// A joint limit: f ≥ 0.
    Limit,
    /// Friction loss of a tendon: |f| ≤ frictionloss.
    #[serde(rename = "tendon_friction")]
    TendonFriction,
    /// A tendon limit: f ≥ 0.
    #[serde(rename = "tendon_limit")]
    TendonLimit,
}

impl RowKind {
    /// Whether the row is a friction loss (no stiffness in its reference).
    pub(super) fn is_friction(self) -> bool {
        matches!(self, RowKind::Friction | RowKind::TendonFriction)
    }
}

/// The rows active at the current state and their forces — filled by
/// [`Workspace::apply_constraint_forces`]; entries past `count` are stale.
/// What depends on the state is in the passes' scalar `S`.
#[derive(Clone, Debug)]
pub struct ConstraintRows<S: Real = f64> {
    /// Active rows.
    pub count: usize,
    /// Each row's kind.
    pub kind: Vec<RowKind>,
    /// Each row's constraint: its index into `Model::constraints`' friction
    /// or limit list.
    pub id: Vec<usize>,
    /// Jᵀ: row k of J is entries k·nv .. (k+1)·nv.
    pub jacobian: Vec<S>,
    /// E = m⁻¹Jᵀ, laid out like `jacobian`.
    pub eps_columns: Vec<S>,
    /// The dofs outside which each column of E is zero (a row moves its
    /// bodies' links and their ancestors only).
    pub eps_spans: Vec<(usize, usize)>,
    /// Distance to the limit, or an equality row's violation (MuJoCo's
    /// efc_pos; 0 for friction).
    pub distance: Vec<S>,
    /// What the impedance is a function of: the distance, or the norm of
    /// a connect's or weld's whole violation (MuJoCo's `getposdim`).
    pub violation: Vec<S>,
    /// MuJoCo's approximation of the row's diagonal of A (efc_diagApprox
    /// before the impedance adjusts it).
    pub diagonal_estimate: Vec<f64>,
    /// J̇θ̇ of a connect's or weld's row (0 for the others), which MuJoCo
    /// takes out of the reference acceleration.
    pub jdot_v: Vec<S>,
    /// MuJoCo's efc_margin.
    pub margin: Vec<f64>,
    /// J θ̇ (efc_vel).
    pub velocity: Vec<S>,
    /// Reference acceleration (efc_aref).
    pub aref: Vec<S>,
    /// Regularizer R (efc_R).
    pub regularizer: Vec<S>,
    /// The box of each force.
    pub lower: Vec<f64>,
    /// See `lower`.
    pub upper: Vec<f64>,
    /// The forces f (efc_force).
    pub force: Vec<S>,
    /// A + R, row-major with stride `max_rows`.
    pub hessian: Vec<S>,
    /// J·qacc_smooth − aref.
    pub gradient: Vec<S>,
    /// The solver's buffers; its working set is the last solve's.
    pub solver: BoxQp<S>,
    /// The rows of the last solve (kind and constraint), whose working set
    /// starts the next solve when the rows are the same.
    last_rows: Vec<(RowKind, usize)>,
    /// The most rows that can be active (fixed by the model).
    pub max_rows: usize,
    /// Which limit sides are active, when an integrator holds them over a
    /// step (`Workspace::hold_limit_sides`); else each is active where its
    /// distance is below its margin, as in MuJoCo.
    held_sides: Option<Vec<bool>>,
    /// The buffer of `held_sides` while nothing is held (one per limit side).
    side_buffer: Vec<bool>,
    /// With this many rows, the solver's working set is held
    /// (`Workspace::hold_working_set`): the forces are its minimizer's,
    /// smooth in the state, instead of the box's.
    held_working_set: Option<usize>,
    /// With this many rows, the next solve starts from the working set the
    /// solver holds, whatever rows the last solve had
    /// (`Workspace::start_solve_from`).
    given_start: Option<usize>,
    /// While limit sides are held: how far each row's force is from
    /// leaving its working set ([`BoxQp::working_set_margins`]).
    margins: Vec<f64>,
    /// The impedance piece of each row (held with the working set).
    pieces: Vec<ImpedancePiece>,
    /// While limit sides are held: how far each row is from leaving its piece.
    piece_margins: Vec<f64>,
    /// Per-link scratch: spatial accelerations at θ̈ = 0 (for J̇θ̇).
    pub bias_acceleration: Vec<SpatialVec<S>>,
    /// MuJoCo's qfrc_constraint = Jᵀf (nv).
    pub qfrc_constraint: Vec<S>,
    /// ε_c = m⁻¹Jᵀf (nv).
    pub eps_constraint: Vec<S>,
    /// The no-slip pass's buffers.
    pub(super) no_slip: NoSlipBuffers<S>,
}

/// The rows whose columns of E a problem kept for the next, for runs of
/// the derivatives' passes at one θ (a Jacobian's velocity, ε, T, ctrl and
/// act columns reuse the configuration passes of the column before): E
/// depends on θ alone, so it is taken again for the same rows.
#[derive(Clone, Debug)]
pub(crate) struct KeptColumns {
    /// Whether the next problem may take the columns.
    still: bool,
    /// How many rows' columns are kept (`None`: none), and their kinds and
    /// ids (the first that many entries).
    rows: Option<usize>,
    kind: Vec<RowKind>,
    id: Vec<usize>,
}

impl KeptColumns {
    /// Room for `model`'s rows.
    pub(crate) fn new(model: &Model) -> Self {
        let rows = model.constraints.max_rows();
        KeptColumns { still: false, rows: None, kind: vec![RowKind::Friction; rows], id: vec![0; rows] }
    }

    /// Whether the next run is at the θ of the run before, whose
    /// configuration passes it reuses; if not, the columns kept are
    /// forgotten, so that a run that stops before its problem leaves none
    /// of another θ's.
    pub(crate) fn still(&mut self, still: bool) {
        self.still = still;
        if !still {
            self.rows = None;
        }
    }

    /// Whether `rows`' columns of E are those kept: a still run with the
    /// same rows. Forgets them otherwise, as they are about to be replaced.
    fn hold_for<S: Real>(&mut self, rows: &ConstraintRows<S>) -> bool {
        let n = rows.count;
        let held = std::mem::take(&mut self.still)
            && self.rows == Some(n)
            && self.kind[..n] == rows.kind[..n]
            && self.id[..n] == rows.id[..n];
        if !held {
            self.rows = None;
        }
        held
    }

    /// Keeps `rows`' columns just formed.
    fn keep<S: Real>(&mut self, rows: &ConstraintRows<S>) {
        let n = rows.count;
        self.kind[..n].copy_from_slice(&rows.kind[..n]);
        self.id[..n].copy_from_slice(&rows.id[..n]);
        self.rows = Some(n);
    }
}

impl<S: Real> Default for ConstraintRows<S> {
    fn default() -> Self {
        ConstraintRows::sized(0, 0, 0, 0, NoSlipBuffers::default())
    }
}

impl<S: Real> ConstraintRows<S> {
    /// Buffers for `model`'s constraints.
    pub fn new(model: &Model) -> Self {
        let has_equalities = !model.constraints.equalities.is_empty();
        ConstraintRows::sized(
            model.constraints.max_rows(),
            model.nv,
            model.constraints.limit_sides(),
            if has_equalities { model.links.len() } else { 0 },
            NoSlipBuffers::new(model),
        )
    }

    /// Buffers for `rows` rows over `nv` dofs, `sides` limit sides and
    /// `links` links' bias accelerations.
    fn sized(rows: usize, nv: usize, sides: usize, links: usize, no_slip: NoSlipBuffers<S>) -> Self {
        let per_row = vec![S::zero(); rows];
        let constants = vec![0.0; rows];
        ConstraintRows {
            count: 0,
            kind: vec![RowKind::Friction; rows],
            id: vec![0; rows],
            jacobian: vec![S::zero(); rows * nv],
            eps_columns: vec![S::zero(); rows * nv],
            eps_spans: vec![(0, 0); rows],
            distance: per_row.clone(),
            violation: per_row.clone(),
            diagonal_estimate: constants.clone(),
            jdot_v: per_row.clone(),
            margin: constants.clone(),
            velocity: per_row.clone(),
            aref: per_row.clone(),
            regularizer: per_row.clone(),
            lower: constants.clone(),
            upper: constants,
            force: per_row.clone(),
            hessian: vec![S::zero(); rows * rows],
            gradient: per_row,
            solver: BoxQp::new(rows),
            last_rows: Vec::with_capacity(rows),
            max_rows: rows,
            held_sides: None,
            side_buffer: vec![false; sides],
            held_working_set: None,
            given_start: None,
            margins: vec![f64::INFINITY; rows],
            pieces: vec![ImpedancePiece::Constant; rows],
            piece_margins: vec![f64::INFINITY; rows],
            bias_acceleration: vec![SpatialVec::zeros(); links],
            qfrc_constraint: vec![S::zero(); if rows > 0 { nv } else { 0 }],
            eps_constraint: vec![S::zero(); if rows > 0 { nv } else { 0 }],
            no_slip,
        }
    }

    /// Opens row `count` with J = 0, free bounds and no J̇θ̇, and returns its index.
    pub(super) fn push(&mut self, nv: usize, kind: RowKind, id: usize, distance: S, margin: f64) -> usize {
        let k = self.count;
        self.count += 1;
        self.kind[k] = kind;
        self.id[k] = id;
        self.distance[k] = distance;
        self.violation[k] = distance;
        self.margin[k] = margin;
        self.jdot_v[k] = S::zero();
        (self.lower[k], self.upper[k]) = (f64::NEG_INFINITY, f64::INFINITY);
        self.jacobian[k * nv..(k + 1) * nv].fill(S::zero());
        k
    }

    /// Whether the rows are those of the last solve (kind and constraint),
    /// noting them for the next.
    fn note_rows(&mut self) -> bool {
        let n = self.count;
        let same_rows = self.last_rows.len() == n && (0..n).all(|k| self.last_rows[k] == (self.kind[k], self.id[k]));
        if !same_rows {
            self.last_rows.clear();
            self.last_rows.extend((0..n).map(|k| (self.kind[k], self.id[k])));
        }
        same_rows
    }

    /// The forces of the problem set up in the rows: in the held working
    /// set, or by the active-set method (from the last solve's working set
    /// when the rows are the same); either way the minimizer of one working
    /// set, smooth in the data while that set holds. For derivatives, which
    /// refuse the tendons' armature and the no-slip pass.
    pub(crate) fn solve_in_one_working_set(&mut self) -> Result<(), DynamicsError> {
        let (n, stride) = (self.count, self.max_rows);
        let warm = self.note_rows();
        let (hessian, gradient, lower, upper) = (&self.hessian, &self.gradient, &self.lower, &self.upper);
        if self.held_working_set == Some(n) {
            self.solver.solve_in_working_set(n, hessian, stride, gradient, lower, upper, &mut self.force)
        } else {
            self.solver.solve(n, hessian, stride, gradient, lower, upper, &mut self.force, warm)
        }
    }

    /// Holds the constraint mode `held` holds (its limit sides, and its
    /// working set and impedance pieces when held), or lets the state
    /// decide again when it holds none: the mode an FMU holds between
    /// events, for its derivatives.
    pub fn hold_mode_of(&mut self, held: &ConstraintRows) {
        match &held.held_sides {
            Some(sides) => {
                let mut mine = self.held_sides.take().unwrap_or_else(|| std::mem::take(&mut self.side_buffer));
                mine.copy_from_slice(sides);
                self.held_sides = Some(mine);
            }
            None => {
                if let Some(mine) = self.held_sides.take() {
                    self.side_buffer = mine;
                }
            }
        }
        self.held_working_set = held.held_working_set;
        if let Some(n) = held.held_working_set {
            self.solver.held[..n].copy_from_slice(&held.solver.held[..n]);
            self.pieces[..n].copy_from_slice(&held.pieces[..n]);
        }
        self.no_slip.hold_those_of(&held.no_slip);
    }

    /// Whether a mode is held (its limit sides at least).
    pub fn holds_mode(&self) -> bool {
        self.held_sides.is_some()
    }

    /// How far each row is from a switch of its force, by row (for the
    /// first `count` entries of each): in `forces` from leaving the
    /// solver's working set (a free force's distance to its nearer bound, a
    /// held one's multiplier), in `pieces` from leaving its impedance's
    /// piece. Negative once switched; within round-off of 0 on a switch.
    pub(crate) fn mode_margins(&self, model: &Model, forces: &mut [f64], pieces: &mut [f64]) {
        let (n, stride) = (self.count, self.max_rows);
        let bounds = (self.lower.as_slice(), self.upper.as_slice());
        self.solver.working_set_margins(n, &self.hessian, stride, &self.gradient, bounds, &self.force, forces);
        for (k, margin) in pieces[..n].iter_mut().enumerate() {
            let soft = soft_of(model, self.kind[k], self.id[k]);
            let (piece, x) = impedance_piece(&soft.solimp, self.violation[k].value(), self.margin[k]);
            *margin = impedance_piece_margin(&soft.solimp, piece, x);
        }
    }

    /// Row `k` named for a message: its kind and the joint, tendon or
    /// equality it belongs to.
    pub fn row_name(&self, model: &Model, k: usize) -> String {
        let constraints = &model.constraints;
        let joint_of_dof = |dof: usize| {
            let joint = model.joints.iter().rev().find(|j| j.dof_adr <= dof);
            joint.map_or_else(|| format!("dof {dof}"), |j| format!("joint '{}'", j.name))
        };
        let tendon =
            |t: usize| model.tendons[t].name.clone().map_or_else(|| format!("tendon {t}"), |n| format!("tendon '{n}'"));
        let id = self.id[k];
        match self.kind[k] {
            RowKind::Equality => format!("row {k}, equality {}", constraints.equalities[id].label),
            RowKind::Friction => format!("row {k}, friction loss of {}", joint_of_dof(constraints.friction[id].dof)),
            RowKind::Limit => format!("row {k}, limit of {}", joint_of_dof(constraints.limits[id].dof)),
            RowKind::TendonFriction => {
                format!("row {k}, friction loss of {}", tendon(constraints.tendon_friction[id].tendon))
            }
            RowKind::TendonLimit => format!("row {k}, limit of {}", tendon(constraints.tendon_limits[id].tendon)),
        }
    }

    /// Whether the limit side in `slot` makes a row: as held, or where
    /// the state puts it (`inside`: its distance is below its margin).
    fn side_active(&self, slot: usize, inside: bool) -> bool {
        self.held_sides.as_ref().map_or(inside, |held| held[slot])
    }

    /// Removes each constraint whose rows' Jacobian is zero throughout (a
    /// weld of two world-fixed sites, a tendon limit whose path lies on one
    /// link), as MuJoCo's `mj_addConstraint` does: such rows cannot move the
    /// vehicle, and their regularizer alone would give them forces of 1e17.
    /// A constraint's rows are consecutive and share their kind and id.
    fn drop_empty_constraints(&mut self, nv: usize) {
        let mut kept = 0;
        let mut first = 0;
        while first < self.count {
            let group = (self.kind[first], self.id[first]);
            let mut end = first + 1;
            while end < self.count && (self.kind[end], self.id[end]) == group {
                end += 1;
            }
            if self.jacobian[first * nv..end * nv].iter().any(|entry| entry.value() != 0.0) {
                for k in first..end {
                    self.move_row(nv, k, kept);
                    kept += 1;
                }
            }
            first = end;
        }
        self.count = kept;
    }

    /// Copies what instantiation wrote of row `from` into row `to` (`to` ≤ `from`).
    fn move_row(&mut self, nv: usize, from: usize, to: usize) {
        if from == to {
            return;
        }
        self.jacobian.copy_within(from * nv..(from + 1) * nv, to * nv);
        self.kind[to] = self.kind[from];
        self.id[to] = self.id[from];
        for field in [&mut self.distance, &mut self.violation, &mut self.jdot_v] {
            field[to] = field[from];
        }
        for field in [&mut self.diagonal_estimate, &mut self.margin, &mut self.lower, &mut self.upper] {
            field[to] = field[from];
        }
    }

    /// The friction and limit rows at configuration `theta` (quaternions
    /// normalized), after the equality rows: the dofs' friction, the
    /// tendons', the joints' limits, the tendons' (MuJoCo's order).
    fn instantiate_friction_and_limits(&mut self, model: &Model, theta: &[S], tendons: &TendonState<S>) {
        let nv = model.nv;
        let weights = &model.constraints.dof_invweight0;
        for (index, friction) in model.constraints.friction.iter().enumerate() {
            let k = self.push(nv, RowKind::Friction, index, S::zero(), 0.0);
            self.jacobian[k * nv + friction.dof] = S::one();
            (self.lower[k], self.upper[k]) = (-friction.frictionloss, friction.frictionloss);
            self.diagonal_estimate[k] = weights[friction.dof];
        }
        for (index, friction) in model.constraints.tendon_friction.iter().enumerate() {
            let k = self.push(nv, RowKind::TendonFriction, index, S::zero(), 0.0);
            self.jacobian[k * nv..(k + 1) * nv].copy_from_slice(tendons.moment(friction.tendon));
            (self.lower[k], self.upper[k]) = (-friction.frictionloss, friction.frictionloss);
            self.diagonal_estimate[k] = model.tendons[friction.tendon].invweight0;
        }
        let constraints = &model.constraints;
        for (index, limit) in constraints.limits.iter().enumerate() {
            match limit.kind {
                JointKind::Ball => {
                    let (distance, axis) = ball_limit_distance(limit, theta);
                    if self.side_active(constraints.joint_limit_slot(index, 0), distance.value() < limit.margin) {
                        let k = self.push(nv, RowKind::Limit, index, distance, limit.margin);
                        for (c, a) in axis.iter().enumerate() {
                            self.jacobian[k * nv + limit.dof + c] = -*a;
                        }
                    }
                }
                _ => {
                    for (side, sign) in SIDES {
                        let distance = (-theta[limit.qpos] + limit.range[side]) * sign;
                        if self.side_active(constraints.joint_limit_slot(index, side), distance.value() < limit.margin)
                        {
                            let k = self.push(nv, RowKind::Limit, index, distance, limit.margin);
                            self.jacobian[k * nv + limit.dof] = S::from(-sign);
                        }
                    }
                }
            }
        }
        for k in 0..self.count {
            if self.kind[k] == RowKind::Limit {
                (self.lower[k], self.upper[k]) = (0.0, f64::INFINITY);
                self.diagonal_estimate[k] = weights[model.constraints.limits[self.id[k]].dof];
            }
        }
        for (index, limit) in constraints.tendon_limits.iter().enumerate() {
            for (side, sign) in SIDES {
                let distance = (-tendons.length[limit.tendon] + limit.range[side]) * sign;
                if self.side_active(constraints.tendon_limit_slot(index, side), distance.value() < limit.margin) {
                    let k = self.push(nv, RowKind::TendonLimit, index, distance, limit.margin);
                    for (entry, arm) in self.jacobian[k * nv..(k + 1) * nv].iter_mut().zip(tendons.moment(limit.tendon))
                    {
                        *entry = *arm * -sign;
                    }
                    (self.lower[k], self.upper[k]) = (0.0, f64::INFINITY);
                    self.diagonal_estimate[k] = model.tendons[limit.tendon].invweight0;
                }
            }
        }
    }
}

/// A hinge's, slide's or tendon's limit sides: (index into `range`, the
/// sign that makes `sign · (range[side] − value)` the distance inside).
const SIDES: [(usize, f64); 2] = [(0, -1.0), (1, 1.0)];

/// A ball limit's distance (the larger range value less the rotation
/// angle) and the axis its row pushes about.
fn ball_limit_distance<S: Real>(limit: &Limit, theta: &[S]) -> (S, [S; 3]) {
    let (angle, axis) = rotation_angle_axis(&theta[limit.qpos..limit.qpos + 4]);
    (-angle + limit.range[0].max(limit.range[1]), axis)
}

/// Each limit side's distance less its margin at configuration `theta`
/// (quaternions normalized), with the tendons' lengths there, into `out`
/// by slot: negative where MuJoCo makes the side a row. A ball's unused
/// second slot reads +∞. These are the switching functions of the
/// dynamics: where one changes sign, a row appears or vanishes and the
/// reference acceleration's velocity term makes θ̈ jump.
pub fn limit_switching_functions(model: &Model, theta: &[f64], tendon_length: &[f64], out: &mut [f64]) {
    let constraints = &model.constraints;
    for (index, limit) in constraints.limits.iter().enumerate() {
        let slots = [constraints.joint_limit_slot(index, 0), constraints.joint_limit_slot(index, 1)];
        match limit.kind {
            JointKind::Ball => {
                out[slots[0]] = ball_limit_distance(limit, theta).0 - limit.margin;
                out[slots[1]] = f64::INFINITY;
            }
            _ => {
                for (side, sign) in SIDES {
                    out[slots[side]] = sign * (limit.range[side] - theta[limit.qpos]) - limit.margin;
                }
            }
        }
    }
    for (index, limit) in constraints.tendon_limits.iter().enumerate() {
        for (side, sign) in SIDES {
            let distance = sign * (limit.range[side] - tendon_length[limit.tendon]);
            out[constraints.tendon_limit_slot(index, side)] = distance - limit.margin;
        }
    }
}

/// The tendons' lengths and moment arms at the state, as the rows read them.
struct TendonState<'a, S: Real> {
    length: &'a [S],
    moments: &'a [S],
    nv: usize,
}

impl<S: Real> TendonState<'_, S> {
    /// Tendon `k`'s moment arms.
    fn moment(&self, k: usize) -> &[S] {
        &self.moments[k * self.nv..(k + 1) * self.nv]
    }
}

/// A unit quaternion's rotation angle in [0, π] and the unit axis it turns
/// about, as MuJoCo's `mju_quat2Vel` and `mju_normalize3` give them (the
/// axis is x when the angle vanishes).
fn rotation_angle_axis<S: Real>(q: &[S]) -> (S, [S; 3]) {
    let sine_norm = (q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let x_axis = [S::one(), S::zero(), S::zero()];
    let mut axis = if sine_norm.value() < MIN_VALUE { x_axis } else { [q[1], q[2], q[3]].map(|x| x / sine_norm) };
    let mut angle = sine_norm.atan2(q[0]) * 2.0;
    if angle.value() > std::f64::consts::PI {
        angle -= 2.0 * std::f64::consts::PI;
    }
    if angle.value().abs() < MIN_VALUE {
        return (angle.abs(), x_axis);
    }
    if angle.value() < 0.0 {
        axis = axis.map(|x| -x);
    }
    (angle.abs(), axis)
}

/// Which polynomial of MuJoCo's impedance curve a row is on: the curve
/// (`getimpedance`) rises from dmin to dmax over the width, by one
/// polynomial up to the midpoint and another beyond, and stays at dmax past
/// the width; it is only once differentiable where the pieces meet, so an
/// integrator holds a row's piece over a step and locates the change.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImpedancePiece {
    /// dmin = dmax or no width: the impedance is constant.
    #[default]
    Constant,
    /// Up to the midpoint.
    Rising,
    /// From the midpoint to the width.
    Leveling,
    /// Past the width: dmax.
    Level,
}

/// MuJoCo's `getsolparam` clamps of a solimp: (dmin, dmax, width, midpoint, power).
fn impedance_parameters(solimp: &[f64; 5]) -> (f64, f64, f64, f64, f64) {
    let (low, high) = IMPEDANCE_BOUNDS;
    (
        solimp[0].clamp(low, high),
        solimp[1].clamp(low, high),
        solimp[2].max(0.0),
        solimp[3].clamp(low, high),
        solimp[4].max(1.0),
    )
}

/// Where on the impedance curve of `solimp` a row at `distance` from its
/// `margin` is: the piece MuJoCo's `getimpedance` takes there, and the
/// curve's argument x = |distance − margin| / width.
fn impedance_piece<S: Real>(solimp: &[f64; 5], distance: S, margin: f64) -> (ImpedancePiece, S) {
    let (dmin, dmax, width, midpoint, _) = impedance_parameters(solimp);
    if dmin == dmax || width <= MIN_VALUE {
        return (ImpedancePiece::Constant, S::zero());
    }
    let x = ((distance - margin) / width).abs();
    let piece = if x.value() >= 1.0 {
        ImpedancePiece::Level
    } else if x.value() <= midpoint {
        ImpedancePiece::Rising
    } else {
        ImpedancePiece::Leveling
    };
    (piece, x)
}

/// The impedance on `piece` at x (MuJoCo's `getimpedance` where x is on
/// that piece; beyond it, the piece's polynomial continued).
fn impedance_on<S: Real>(solimp: &[f64; 5], piece: ImpedancePiece, x: S) -> S {
    let (dmin, dmax, _, midpoint, power) = impedance_parameters(solimp);
    let y = match piece {
        ImpedancePiece::Constant => return S::from(0.5 * (dmin + dmax)),
        ImpedancePiece::Level => return S::from(dmax),
        ImpedancePiece::Rising if x.value() <= 0.0 => return S::from(dmin),
        _ if power == 1.0 => x,
        ImpedancePiece::Rising => raise(x, power) / raise(S::from(midpoint), power - 1.0),
        ImpedancePiece::Leveling => -(raise(-x + 1.0, power) / raise(S::from(1.0 - midpoint), power - 1.0)) + 1.0,
    };
    y * (dmax - dmin) + dmin
}

/// How far x is from leaving `piece` (positive while on it).
fn impedance_piece_margin(solimp: &[f64; 5], piece: ImpedancePiece, x: f64) -> f64 {
    let midpoint = impedance_parameters(solimp).3;
    match piece {
        ImpedancePiece::Constant => f64::INFINITY,
        ImpedancePiece::Rising => midpoint - x,
        ImpedancePiece::Leveling => (x - midpoint).min(1.0 - x),
        ImpedancePiece::Level => x - 1.0,
    }
}

/// aᵇ, exact for the common powers 1 and 2 as MuJoCo computes them.
fn raise<S: Real>(a: S, b: f64) -> S {
    match b {
        1.0 => a,
        2.0 => a * a,
        _ => a.powf(S::from(b)),
    }
}

/// The reference's stiffness K and damping B (MuJoCo's `mj_makeImpedance`):
/// from a time constant and damping ratio (solref positive, the time
/// constant at least two time steps with refsafe), or given directly
/// (negative). A friction row has no stiffness.
fn stiffness_damping(model: &Model, soft: &SoftConstraint, friction: bool) -> (f64, f64) {
    let options = &model.constraints.options;
    let mut solref = soft.solref;
    // MuJoCo replaces a mixed-sign solref with its default, with a warning.
    if (solref[0] > 0.0) != (solref[1] > 0.0) {
        solref = SoftConstraint::default().solref;
    }
    if options.refsafe && solref[0] > 0.0 {
        solref[0] = solref[0].max(2.0 * options.timestep);
    }
    let dmax = soft.solimp[1].clamp(IMPEDANCE_BOUNDS.0, IMPEDANCE_BOUNDS.1);
    let stiffness = if friction {
        0.0
    } else if solref[0] > 0.0 {
        1.0 / (dmax * dmax * solref[0] * solref[0] * solref[1] * solref[1]).max(MIN_VALUE)
    } else {
        -solref[0] / (dmax * dmax).max(MIN_VALUE)
    };
    let damping =
        if solref[1] > 0.0 { 2.0 / (dmax * solref[0]).max(MIN_VALUE) } else { -solref[1] / dmax.max(MIN_VALUE) };
    (stiffness, damping)
}

impl Workspace {
    /// Holds the limit sides whose switching function (`switching`, by
    /// slot, from [`limit_switching_functions`]) is negative active, and
    /// the others inactive, whatever the states evaluated until
    /// [`Workspace::release_limit_sides`]: over an integrator's step the
    /// rates are then smooth, and it locates where a side switches.
    pub fn hold_limit_sides(&mut self, switching: &[f64]) {
        let rows = &mut self.constraint_rows;
        let mut held = rows.held_sides.take().unwrap_or_else(|| std::mem::take(&mut rows.side_buffer));
        for (active, value) in held.iter_mut().zip(switching) {
            *active = *value < 0.0;
        }
        rows.held_sides = Some(held);
    }

    /// Lets the state decide the active limit sides and the solver's
    /// working set again, as MuJoCo does.
    pub fn release_limit_sides(&mut self) {
        let rows = &mut self.constraint_rows;
        if let Some(held) = rows.held_sides.take() {
            rows.side_buffer = held;
        }
        self.release_working_set();
    }

    /// Holds the working set of the last solve and the rows' impedance
    /// pieces (at the state an
    /// integrator's step starts from, its sides held) for the evaluations
    /// until [`Workspace::release_working_set`]: each then gives the
    /// minimizer with the same bounds reached, and [`Workspace::
    /// switching_margins`] tells where that stops being the answer. The
    /// no-slip pass's decisions and the spatial tendons' wrap paths are
    /// held with it.
    pub fn hold_working_set(&mut self) {
        let rows = &mut self.constraint_rows;
        rows.held_working_set = Some(rows.count);
        rows.no_slip.hold();
        self.wrap_paths_held.copy_from_slice(&self.wrap_paths);
        self.wraps_held = !self.wrap_paths.is_empty();
    }

    /// Moves row `row` across the bound it crossed in the held working set
    /// (a free force past a bound is held there, a held one freed), so that
    /// the solve after a located switch starts on its far side: found from
    /// scratch a hair past the switch, the working set could be the old one
    /// again, within the solver's tolerance.
    pub fn cross_working_set(&mut self, row: usize) {
        let rows = &mut self.constraint_rows;
        // The solver's force: the no-slip pass clamps a friction row's own.
        let force = rows.no_slip.solved_force(row).unwrap_or(rows.force[row]);
        let held = &mut rows.solver.held[row];
        *held = match *held {
            Held::Free if force < rows.lower[row] => Held::Lower,
            Held::Free if force > rows.upper[row] => Held::Upper,
            Held::Free => Held::Free,
            Held::Lower | Held::Upper => Held::Free,
        };
    }

    /// The working set of the last solve, one entry per row.
    pub fn working_set(&self) -> &[Held] {
        let rows = &self.constraint_rows;
        &rows.solver.held[..rows.count]
    }

    /// Starts the next solve from the working set `set` (one entry per row,
    /// as [`Workspace::working_set`] gave it), where it has that many rows:
    /// so that a run continued from the end of a step cut to a switch
    /// finds the working set it found there, whatever was solved between
    /// (found from scratch a hair past the switch, it could be the old one).
    /// A set longer than the rows can be (not one this model's solver gave)
    /// is not started from.
    pub fn start_solve_from(&mut self, set: &[Held]) {
        let rows = &mut self.constraint_rows;
        if let Some(held) = rows.solver.held.get_mut(..set.len()) {
            held.copy_from_slice(set);
            rows.given_start = Some(set.len());
        }
    }

    /// Lets the solver find the working set again (the sides stay held).
    pub fn release_working_set(&mut self) {
        self.constraint_rows.held_working_set = None;
        self.constraint_rows.no_slip.release();
        self.wraps_held = false;
    }

    /// The rows' margins of the last evaluation (sides held) into `out`
    /// (2 × `max_rows` long, then the no-slip pass's: the forces' working
    /// set, the impedance pieces, the pass's decisions): +∞ past the rows.
    pub fn switching_margins(&self, out: &mut [f64]) {
        let rows = &self.constraint_rows;
        out.fill(f64::INFINITY);
        let (forces, rest) = out.split_at_mut(rows.max_rows);
        let (pieces, no_slip) = rest.split_at_mut(rows.max_rows);
        forces[..rows.count].copy_from_slice(&rows.margins[..rows.count]);
        pieces[..rows.count].copy_from_slice(&rows.piece_margins[..rows.count]);
        no_slip.copy_from_slice(rows.no_slip.margins());
    }

    /// Puts the forces beyond the tree's on a pass 3 just run for `applied`
    /// (the applied ε, actuators included): first the tendons' armature
    /// (`tendon_inertia`), which makes MuJoCo's qacc_smooth, then the
    /// constraint forces solved for with that θ̈ and the mass matrix with
    /// the armature. Each one's ε is added to `applied`, to ν̇ (when the
    /// pass had the factor's rates) and to ν̇'s joint part, and the outward
    /// pass runs again for θ̈. ε enters ν̇ additively, so pass 3 need not
    /// run again. The rows and forces stay in `constraint_rows`.
    pub fn apply_constraint_forces(&mut self, model: &Model, applied: &mut [f64]) -> Result<(), DynamicsError> {
        require(self, Stage::JointRates, "apply_constraint_forces")?;
        if !model.tendon_inertia.is_empty() {
            self.apply_tendon_inertia(model, applied)?;
        }
        self.add_constraint_forces(model, applied, None, Self::solve_for_forces)
    }

    /// The forces of the problem set up in `rows`: in the held working set,
    /// or by the active-set method from the last one; the held working
    /// set's margins; MuJoCo's no-slip pass.
    fn solve_for_forces(&mut self, model: &Model, rows: &mut ConstraintRows) -> Result<(), DynamicsError> {
        let n = rows.count;
        let stride = rows.max_rows;
        if !model.tendon_inertia.is_empty() {
            self.tendon_inertia_on_rows(model, n, &mut rows.eps_columns, &mut rows.hessian, stride);
            // The tendons' armature spreads each column of E over their dofs.
            rows.eps_spans[..n].fill((0, model.nv));
        }
        let warm = rows.note_rows() | (rows.given_start.take() == Some(n));
        let (gradient, lower, upper) = (&rows.gradient, &rows.lower, &rows.upper);
        if rows.held_working_set == Some(n) {
            rows.solver.solve_in_working_set(n, &rows.hessian, stride, gradient, lower, upper, &mut rows.force)?;
        } else {
            rows.solver.solve(n, &rows.hessian, stride, gradient, lower, upper, &mut rows.force, warm)?;
        }
        if rows.held_sides.is_some() {
            let bounds = (lower.as_slice(), upper.as_slice());
            rows.solver.working_set_margins(n, &rows.hessian, stride, gradient, bounds, &rows.force, &mut rows.margins);
        }
        self.no_slip_pass(model, rows)
    }
}

impl<S: Real> Workspace<S> {
    /// The constraint forces on a pass 3 just run for `applied`, their ε
    /// added to `applied`, ν̇ (with the factor's rates) and ν̇'s joint part,
    /// and θ̈ after them: [`Workspace::apply_constraint_forces`] after the
    /// tendons' armature, with `solve` finding the forces of the problem
    /// the rows set up (A + R in `hessian`, J·qacc_smooth − aref in
    /// `gradient`). The rows' decisions (which sides act, the impedance's
    /// piece, the solver's working set) are taken on the values, so that in
    /// dual numbers the forces carry their derivative at that mode.
    pub(crate) fn add_constraint_forces(
        &mut self,
        model: &Model,
        applied: &mut [S],
        kept: Option<&mut KeptColumns>,
        solve: impl FnOnce(&mut Self, &Model, &mut ConstraintRows<S>) -> Result<(), DynamicsError>,
    ) -> Result<(), DynamicsError> {
        let mut rows = std::mem::take(&mut self.constraint_rows);
        rows.count = 0;
        self.instantiate_equalities(model, &mut rows);
        let tendons = TendonState { length: self.tendon_length.as_slice(), moments: &self.tendon_moment, nv: model.nv };
        rows.instantiate_friction_and_limits(model, self.theta.as_slice(), &tendons);
        rows.drop_empty_constraints(model.nv);
        if rows.count == 0 {
            // No row active (limits away, no friction loss or equality):
            // the pass already run is the answer.
            rows.eps_constraint.fill(S::zero());
            rows.qfrc_constraint.fill(S::zero());
            self.constraint_rows = rows;
            return Ok(());
        }
        // compute_qacc (stage JointRates) and the armature have run the outward pass already.
        let mut result = Ok(());
        if self.stage == Stage::Acceleration && model.tendon_inertia.is_empty() {
            result = self.compute_accelerations(model);
        }
        let result = result
            .and_then(|()| self.constraint_problem(model, &mut rows, kept))
            .and_then(|()| solve(self, model, &mut rows))
            .map(|()| constraint_eps(model.nv, &mut rows));
        if result.is_ok() {
            let with_rates = self.stage == Stage::Acceleration;
            for (d, constraint) in rows.eps_constraint.iter().enumerate() {
                applied[d] += *constraint;
                self.nu_dot_joint[d] += *constraint;
                if with_rates {
                    self.nu_dot[d] += *constraint;
                }
            }
        }
        self.constraint_rows = rows;
        result?;
        self.compute_accelerations(model)
    }

    /// The problem of the instantiated rows, with the outward pass's θ̈ as
    /// qacc_smooth: E = m⁻¹Jᵀ, the impedance on each row's piece (held with
    /// the working set), R, aref, the gradient and A + R = EᵀE + R.
    /// E's columns are taken from the last problem where `kept` says they
    /// still hold, and kept for the next where it is given.
    fn constraint_problem(
        &mut self,
        model: &Model,
        rows: &mut ConstraintRows<S>,
        mut kept: Option<&mut KeptColumns>,
    ) -> Result<(), DynamicsError> {
        let nv = model.nv;
        let n = rows.count;
        // Only the derivatives' runs keep columns: f64's hot path stays as it was.
        if S::SPECIALIZED || !kept.as_deref_mut().is_some_and(|kept| kept.hold_for(rows)) {
            for k in 0..n {
                let column = k * nv..(k + 1) * nv;
                let jacobian = &rows.jacobian[column.clone()];
                // eps_from_forces's check of its input.
                if let Some(index) = jacobian.iter().position(|j| !j.value().is_finite()) {
                    return Err(DynamicsError::NonFinite { what: "torque", index, value: jacobian[index].value() });
                }
                rows.eps_spans[k] = forces::eps_of_sparse_torque(model, self, jacobian, &mut rows.eps_columns[column]);
            }
            // The tendons' armature changes the columns in place, after this.
            if let Some(kept) = kept.filter(|_| !S::SPECIALIZED && model.tendon_inertia.is_empty()) {
                kept.keep(rows);
            }
        }
        for k in 0..n {
            let jacobian = &rows.jacobian[k * nv..(k + 1) * nv];
            let (velocity, jacobian_qacc) = two_dots(jacobian, self.qvel.as_slice(), self.qacc.as_slice());
            rows.velocity[k] = velocity;
            let soft = soft_of(model, rows.kind[k], rows.id[k]);
            let (natural, x) = impedance_piece(&soft.solimp, rows.violation[k], rows.margin[k]);
            let piece = if rows.held_working_set == Some(n) { rows.pieces[k] } else { natural };
            rows.pieces[k] = piece;
            let imp = impedance_on(&soft.solimp, piece, x);
            if rows.held_sides.is_some() {
                rows.piece_margins[k] = impedance_piece_margin(&soft.solimp, piece, x.value());
            }
            let (stiffness, damping) = stiffness_damping(model, &soft, rows.kind[k].is_friction());
            rows.regularizer[k] = ((-imp + 1.0) * rows.diagonal_estimate[k] / imp).max(S::from(MIN_VALUE));
            rows.aref[k] = rows.velocity[k] * -damping - imp * stiffness * (rows.distance[k] - rows.margin[k]);
            rows.aref[k] -= rows.jdot_v[k];
            rows.gradient[k] = jacobian_qacc - rows.aref[k];
        }
        // A + R: A = EᵀE, each product over the dofs where both columns may be nonzero
        // (the terms left out are zeros, so the sums are the same). Up to four
        // entries of a row at a time, over the union of their dofs: four
        // running sums the processor overlaps, each added in the order
        // `dot` adds it, so the numbers are `dot`'s.
        let stride = rows.max_rows;
        for i in 0..n {
            let e_i = &rows.eps_columns[i * nv..(i + 1) * nv];
            let span_i = rows.eps_spans[i];
            for j in (0..=i).step_by(4) {
                let count = (i + 1 - j).min(4);
                let spans = &rows.eps_spans[j..j + count];
                let first = spans.iter().map(|span| span.0).min().unwrap_or(0).max(span_i.0);
                let end = spans.iter().map(|span| span.1).max().unwrap_or(0).min(span_i.1);
                let e: [&[S]; 4] = std::array::from_fn(|q| &rows.eps_columns[(j + q.min(count - 1)) * nv..][..nv]);
                let mut sums = [S::from(-0.0); 4];
                for k in first..end.max(first) {
                    for (sum, e_q) in sums.iter_mut().zip(&e).take(count) {
                        *sum += e_i[k] * e_q[k];
                    }
                }
                for (q, a) in sums.into_iter().enumerate().take(count) {
                    rows.hessian[i * stride + j + q] = a;
                    rows.hessian[(j + q) * stride + i] = a;
                }
            }
            rows.hessian[i * stride + i] += rows.regularizer[i];
        }
        Ok(())
    }
}

/// (a · b, a · c) in one sweep over a, each summed as [`crate::math::dot`] sums it:
/// two running sums that overlap where two `dot`s would wait on each
/// addition in turn.
fn two_dots<S: Real>(a: &[S], b: &[S], c: &[S]) -> (S, S) {
    let (mut ab, mut ac) = (S::from(-0.0), S::from(-0.0));
    for ((a, b), c) in a.iter().zip(b).zip(c) {
        ab += *a * *b;
        ac += *a * *c;
    }
    (ab, ac)
}

impl ConstraintRows {
    /// How fast row `k` returns to its reference while its force is free
    /// (between its bounds), in 1/s, and whether its reference has a
    /// stiffness (so that its position returns too, not only its velocity);
    /// `None` when the force is held at a bound, where the row moves as the
    /// rest of the vehicle does. The row's acceleration is then
    /// (1 − d)·a₀ + d·aref with d = A/(A + R) and aref = −b·v − k·d·r, so
    /// v and r follow s² + d·b·s + d²·k = 0: the rate is that of its slower
    /// root's envelope, d·b/2 for a critically or under-damped row, and
    /// d·b/2 too for a friction row's velocity (k = 0), which decays at
    /// twice that. A friction row that MuJoCo's no-slip pass moves is the
    /// pass's: where its sweeps leave the force free (the row sticks),
    /// they take the row's acceleration to aref = −b·v with no regularizer,
    /// so its velocity decays at b; else `None`.
    pub(crate) fn free_row_decay(&self, model: &Model, k: usize) -> Option<(f64, bool)> {
        if self.kind[k].is_friction() && model.constraints.runs_no_slip_pass() {
            let (_, damping) = stiffness_damping(model, &soft_of(model, self.kind[k], self.id[k]), true);
            return (self.no_slip.sticks(k) && damping > 0.0).then_some((damping, false));
        }
        if self.solver.held[k] != Held::Free {
            return None;
        }
        let diagonal = self.hessian[k * self.max_rows + k];
        let regularizer = self.regularizer[k];
        if !(diagonal > regularizer && diagonal.is_finite()) {
            return None;
        }
        let impedance = (diagonal - regularizer) / diagonal;
        let soft = soft_of(model, self.kind[k], self.id[k]);
        let (stiffness, damping) = stiffness_damping(model, &soft, self.kind[k].is_friction());
        let (linear, constant) = (impedance * damping, impedance * impedance * stiffness);
        let discriminant = linear * linear - 4.0 * constant;
        let rate =
            if discriminant > 0.0 && constant > 0.0 { 0.5 * (linear - discriminant.sqrt()) } else { 0.5 * linear };
        (rate > 0.0).then_some((rate, stiffness > 0.0))
    }
}

/// The solref and solimp of a row of `kind` for constraint `id`.
fn soft_of(model: &Model, kind: RowKind, id: usize) -> SoftConstraint {
    let constraints = &model.constraints;
    match kind {
        RowKind::Equality => constraints.equalities[id].soft,
        RowKind::Friction => constraints.friction[id].soft,
        RowKind::Limit => constraints.limits[id].soft,
        RowKind::TendonFriction => constraints.tendon_friction[id].soft,
        RowKind::TendonLimit => constraints.tendon_limits[id].soft,
    }
}

/// ε_c = E f and MuJoCo's qfrc_constraint = Jᵀf of the solved rows.
fn constraint_eps<S: Real>(nv: usize, rows: &mut ConstraintRows<S>) {
    rows.eps_constraint.fill(S::zero());
    rows.qfrc_constraint.fill(S::zero());
    for k in 0..rows.count {
        let force = rows.force[k];
        // J is zero where E is (a row's dofs are its bodies' and their ancestors').
        let (first, end) = rows.eps_spans[k];
        for d in first..end {
            rows.eps_constraint[d] += rows.eps_columns[k * nv + d] * force;
            rows.qfrc_constraint[d] += rows.jacobian[k * nv + d] * force;
        }
    }
}
