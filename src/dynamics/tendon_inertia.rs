//! Tendon armature as MuJoCo 4.0 applies it (docs/DYNAMICS.md §9), on the
//! tree's factor: the mass matrix is M_a = M + U C Uᵀ (U the columns of the
//! model's [`InertiaTerm`]s, C their weights), and the bias gains
//! Σ a·J(J̇θ̇) = U C β, β each term's tendon's J̇θ̇.
//!
//! The tree's passes give θ̈₀ = M⁻¹(T − h). The armature's force on the tree,
//! −U f with f = C(Uᵀθ̈ + β), makes M θ̈ = M θ̈₀ − U f, so θ̈ = θ̈₀ − M⁻¹U f and
//!
//!   (I + C G) f = C (Uᵀθ̈₀ + β),   G = UᵀM⁻¹U = EᵀE,   E = m⁻¹U,
//!
//! with ε_a = −E f its ε. For the constraint rows (E_c = m⁻¹J_cᵀ) the solver
//! needs M_a⁻¹: by Woodbury, J_c M_a⁻¹ J_cᵀ = E_cᵀE_c − PᵀZ and the rows' ε
//! columns are E_c − E Z, with P = EᵀE_c and Z = (I + C G)⁻¹ C P.
//! I + C G is k × k (k terms) and invertible exactly when M_a is.

use super::DynamicsError;
use super::actuation::site_in_world;
use super::forces::eps_of_torque;
use crate::math::{Real, SpatialVec, Vec3, angular, dot, linear, sum};
use crate::model::{Model, Path, PathStop};
use crate::workspace::{Stage, Workspace};

/// MuJoCo's `mjMINVAL`: a shorter segment has no direction.
const MIN_VALUE: f64 = 1e-15;

/// Buffers of the tendons' armature (all empty when no tendon has any), in
/// the passes' scalar: with dual numbers the derivatives go through it.
#[derive(Clone, Debug)]
pub struct TendonInertiaState<S: Real = f64> {
    /// U: term k's moment arms are entries k·nv .. (k+1)·nv.
    columns: Vec<S>,
    /// E = m⁻¹U, laid out like `columns`.
    eps_columns: Vec<S>,
    /// The LU factors of I + C G (row-major, k × k, unit lower part below the diagonal).
    factors: Vec<S>,
    /// The LU factorization's row exchanges.
    pivots: Vec<usize>,
    /// Each tendon's J̇θ̇ (MuJoCo's `mj_tendonDot` with θ̇).
    jdot_qvel: Vec<S>,
    /// Per term: the right-hand side, then the armature's forces f.
    force: Vec<S>,
    /// Per term: scratch of `tendon_inertia_change`.
    scratch: Vec<S>,
    /// Per link: spatial accelerations at θ̈ = 0 (empty without spatial tendons with armature).
    bias_acceleration: Vec<SpatialVec<S>>,
    /// P = EᵀE_c, k × max_rows, row-major with stride max_rows.
    projection: Vec<S>,
    /// Z = (I + C G)⁻¹ C P, laid out like `projection`.
    projection_solved: Vec<S>,
    /// The armature's ε_a = −E f (nv).
    pub eps: Vec<S>,
}

impl<S: Real> Default for TendonInertiaState<S> {
    fn default() -> Self {
        TendonInertiaState {
            columns: Vec::new(),
            eps_columns: Vec::new(),
            factors: Vec::new(),
            pivots: Vec::new(),
            jdot_qvel: Vec::new(),
            force: Vec::new(),
            scratch: Vec::new(),
            bias_acceleration: Vec::new(),
            projection: Vec::new(),
            projection_solved: Vec::new(),
            eps: Vec::new(),
        }
    }
}

impl<S: Real> TendonInertiaState<S> {
    /// Tendon `tendon`'s J̇θ̇ as the last acceleration pass found it (0
    /// without armature).
    pub(super) fn jdot_qvel(&self, tendon: usize) -> S {
        self.jdot_qvel.get(tendon).copied().unwrap_or(S::zero())
    }

    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let k = model.tendon_inertia.len();
        if k == 0 {
            return Self::default();
        }
        let spatial = model.tendon_inertia.iter().any(|t| matches!(model.tendons[t.tendon].path, Path::Spatial { .. }));
        let rows = model.constraints.max_rows();
        let zero = S::zero();
        TendonInertiaState {
            columns: vec![zero; k * model.nv],
            eps_columns: vec![zero; k * model.nv],
            factors: vec![zero; k * k],
            pivots: vec![0; k],
            jdot_qvel: vec![zero; model.tendons.len()],
            force: vec![zero; k],
            scratch: vec![zero; k],
            bias_acceleration: vec![SpatialVec::zeros(); if spatial { model.links.len() } else { 0 }],
            projection: vec![zero; k * rows],
            projection_solved: vec![zero; k * rows],
            eps: vec![zero; model.nv],
        }
    }

    /// Solves (I + C G) x = C b in place, `b` one value per term.
    fn solve(&self, model: &Model, b: &mut [S]) {
        let k = b.len();
        for (value, term) in b.iter_mut().zip(&model.tendon_inertia) {
            *value *= term.weight;
        }
        for i in 0..k {
            b.swap(i, self.pivots[i]);
            for j in 0..i {
                let change = self.factors[i * k + j] * b[j];
                b[i] -= change;
            }
        }
        for i in (0..k).rev() {
            for j in i + 1..k {
                let change = self.factors[i * k + j] * b[j];
                b[i] -= change;
            }
            let diagonal = self.factors[i * k + i];
            b[i] /= diagonal;
        }
    }

    /// Term `k`'s ε column E_k.
    fn eps_column(&self, nv: usize, k: usize) -> &[S] {
        &self.eps_columns[k * nv..(k + 1) * nv]
    }
}

/// Factors the k × k matrix `a` (row-major) in place as P·A = L·U with
/// partial pivoting; false when a pivot vanishes (M_a singular).
fn lu_factor<S: Real>(a: &mut [S], pivots: &mut [usize]) -> bool {
    let k = pivots.len();
    for c in 0..k {
        let size = |i: usize| a[i * k + c].value().abs();
        let pivot = (c..k).max_by(|&i, &j| size(i).total_cmp(&size(j))).unwrap_or(c);
        pivots[c] = pivot;
        if pivot != c {
            for j in 0..k {
                a.swap(c * k + j, pivot * k + j);
            }
        }
        let diagonal = a[c * k + c];
        if diagonal.value() == 0.0 || !diagonal.value().is_finite() {
            return false;
        }
        for i in c + 1..k {
            let factor = a[i * k + c] / diagonal;
            a[i * k + c] = factor;
            for j in c + 1..k {
                let change = factor * a[c * k + j];
                a[i * k + j] -= change;
            }
        }
    }
    true
}

/// The tendons with armature, for the error that names them.
fn armature_tendons(model: &Model) -> String {
    let names: Vec<String> = (model.tendons.iter().enumerate())
        .filter(|(_, tendon)| tendon.armature != 0.0)
        .map(|(k, tendon)| match &tendon.name {
            Some(name) => format!("tendon '{name}'"),
            None => format!("tendon {k}"),
        })
        .collect();
    names.join(", ")
}

impl<S: Real> Workspace<S> {
    /// The armature's columns U and E = m⁻¹U and the factors of I + C G at
    /// the configuration of pass 1 (`set_configuration` runs it after the
    /// tendons' kinematics when some tendon has armature).
    pub(super) fn tendon_inertia_configuration(&mut self, model: &Model) -> Result<(), DynamicsError> {
        let nv = model.nv;
        let mut state = std::mem::take(&mut self.tendon_inertia);
        for (k, term) in model.tendon_inertia.iter().enumerate() {
            let column = &mut state.columns[k * nv..(k + 1) * nv];
            column.fill(S::zero());
            let arms = &self.tendon_moment[term.tendon * nv..(term.tendon + 1) * nv];
            // The term's dof, those before it in its joint, then every ancestor link's.
            let link = &model.links[term.link];
            column[link.dof_adr..=term.dof].copy_from_slice(&arms[link.dof_adr..=term.dof]);
            let mut parent = link.parent;
            while let Some(p) = parent {
                let link = &model.links[p];
                column[link.dof_adr..link.dof_adr + link.ndof]
                    .copy_from_slice(&arms[link.dof_adr..link.dof_adr + link.ndof]);
                parent = link.parent;
            }
            eps_of_torque(
                model,
                self,
                &state.columns[k * nv..(k + 1) * nv],
                &mut state.eps_columns[k * nv..(k + 1) * nv],
            );
        }
        let k = model.tendon_inertia.len();
        for i in 0..k {
            for j in 0..k {
                let g = dot(state.eps_column(nv, i), state.eps_column(nv, j));
                state.factors[i * k + j] = g * model.tendon_inertia[i].weight + f64::from(u8::from(i == j));
            }
        }
        let invertible = lu_factor(&mut state.factors, &mut state.pivots);
        self.tendon_inertia = state;
        if invertible { Ok(()) } else { Err(DynamicsError::TendonInertia { tendons: armature_tendons(model) }) }
    }

    /// Puts the tendons' armature on a pass 3 just run for `applied`: the
    /// force f of (I + C G) f = C(Uᵀθ̈₀ + β) with that pass's θ̈₀, its
    /// ε_a = −E f added to `applied`, to ν̇ (when the pass had the factor's
    /// rates) and to ν̇'s joint part, and the outward pass run again for θ̈.
    pub(crate) fn apply_tendon_inertia(&mut self, model: &Model, applied: &mut [S]) -> Result<(), DynamicsError> {
        let nv = model.nv;
        if self.stage == Stage::Acceleration {
            self.compute_accelerations(model)?;
        }
        self.tendon_jdot_qvel(model);
        let mut state = std::mem::take(&mut self.tendon_inertia);
        let mut force = std::mem::take(&mut state.force);
        for (k, term) in model.tendon_inertia.iter().enumerate() {
            force[k] = dot(&state.columns[k * nv..(k + 1) * nv], self.qacc.as_slice()) + state.jdot_qvel[term.tendon];
        }
        state.solve(model, &mut force);
        state.eps.fill(S::zero());
        for (k, f) in force.iter().enumerate() {
            for (e, column) in state.eps.iter_mut().zip(&state.eps_columns[k * nv..(k + 1) * nv]) {
                *e -= *column * *f;
            }
        }
        state.force = force;
        let with_rates = self.stage == Stage::Acceleration;
        for (d, e) in state.eps.iter().enumerate() {
            applied[d] += *e;
            self.nu_dot_joint[d] += *e;
            if with_rates {
                self.nu_dot[d] += *e;
            }
        }
        self.tendon_inertia = state;
        self.compute_accelerations(model)
    }

    /// Turns the tree's A = E_cᵀE_c of `count` rows (`hessian`, stride
    /// `stride`, lower triangle mirrored) and the rows' ε columns
    /// `eps_columns` (nv each) into those of M_a: A − PᵀZ and E_c − E Z.
    pub(crate) fn tendon_inertia_on_rows(
        &mut self,
        model: &Model,
        count: usize,
        eps_columns: &mut [S],
        hessian: &mut [S],
        stride: usize,
    ) {
        let nv = model.nv;
        let k = model.tendon_inertia.len();
        let mut state = std::mem::take(&mut self.tendon_inertia);
        let mut b = std::mem::take(&mut state.force);
        for r in 0..count {
            let row = &eps_columns[r * nv..(r + 1) * nv];
            for (t, value) in b.iter_mut().enumerate() {
                *value = dot(state.eps_column(nv, t), row);
                state.projection[t * stride + r] = *value;
            }
            state.solve(model, &mut b);
            for (t, value) in b.iter().enumerate() {
                state.projection_solved[t * stride + r] = *value;
            }
        }
        state.force = b;
        for i in 0..count {
            for j in 0..=i {
                let change =
                    sum((0..k).map(|t| state.projection[t * stride + i] * state.projection_solved[t * stride + j]));
                hessian[i * stride + j] -= change;
                if j != i {
                    hessian[j * stride + i] -= change;
                }
            }
        }
        for r in 0..count {
            for t in 0..k {
                let z = state.projection_solved[t * stride + r];
                for (e, column) in eps_columns[r * nv..(r + 1) * nv].iter_mut().zip(state.eps_column(nv, t)) {
                    *e -= *column * z;
                }
            }
        }
        self.tendon_inertia = state;
    }

    /// J̇θ̇ of every tendon with armature, as MuJoCo's `mj_tendonDot`: zero
    /// for a fixed tendon; along each straight segment of a spatial one
    /// (between sites of different bodies, over the pulley's divisor),
    /// u·(a₁ − a₀) + |Δv − u(u·Δv)|²/|Δp| with a the sites' accelerations at
    /// θ̈ = 0, Δv their velocities' difference, u the segment's direction.
    fn tendon_jdot_qvel(&mut self, model: &Model) {
        let mut state = std::mem::take(&mut self.tendon_inertia);
        if !state.bias_acceleration.is_empty() {
            self.world_transforms(model);
            self.bias_accelerations(model, &mut state.bias_acceleration);
        }
        for term in &model.tendon_inertia {
            let Path::Spatial { stops } = &model.tendons[term.tendon].path else {
                state.jdot_qvel[term.tendon] = S::zero();
                continue;
            };
            let mut total = S::zero();
            let mut divisor = 1.0;
            for pair in stops.windows(2) {
                match pair {
                    [PathStop::Pulley { divisor: d }, _] => divisor = *d,
                    [PathStop::Site { frame: f0, body: b0 }, PathStop::Site { frame: f1, body: b1 }] if b0 != b1 => {
                        let [(p0, v0, a0), (p1, v1, a1)] =
                            [f0, f1].map(|f| self.site_motion(f, &state.bias_acceleration));
                        let difference = p1 - p0;
                        let distance = difference.norm();
                        let (velocity, acceleration) = (v1 - v0, a1 - a0);
                        total += if distance.value() < MIN_VALUE {
                            acceleration.x
                        } else {
                            let u = difference / distance;
                            let along = u.dot(&velocity);
                            u.dot(&acceleration) + (velocity.norm_squared() - along * along) / distance
                        } / divisor;
                    }
                    // A pulley's neighbours, a segment within one body; geoms
                    // are refused with armature.
                    _ => {}
                }
            }
            state.jdot_qvel[term.tendon] = total;
        }
        self.tendon_inertia = state;
    }

    /// A site's world position, velocity and acceleration at θ̈ = 0.
    fn site_motion(&self, site: &crate::model::SiteFrame, bias: &[SpatialVec<S>]) -> (Vec3<S>, Vec3<S>, Vec3<S>) {
        let at = site_in_world(site, &self.x_world).trans;
        let Some(link) = site.link else { return (at, Vec3::zeros(), Vec3::zeros()) };
        let r: Vec3<S> = site.frame.trans.map(S::from);
        let to_world = self.x_world[link].rot.transpose();
        let velocity = &self.v_body[link];
        let (omega, v) = (angular(velocity), linear(velocity));
        let point_velocity = v + omega.cross(&r);
        let a = &bias[link];
        // A body point's classical acceleration: the spatial one at the point plus ω × v.
        let acceleration = linear(a) + angular(a).cross(&r) + omega.cross(&point_velocity);
        (at, to_world * point_velocity, to_world * acceleration)
    }
}

impl Workspace {
    /// xᵀM_a⁻¹x less xᵀM⁻¹x for the ε = m⁻¹x of a generalized force x at
    /// the configuration: −pᵀ(I + C G)⁻¹C p with p = Eᵀε. Zero without armature.
    pub fn tendon_inertia_change(&mut self, model: &Model, eps: &[f64]) -> f64 {
        let k = model.tendon_inertia.len();
        if k == 0 {
            return 0.0;
        }
        let state = &mut self.tendon_inertia;
        let mut z = std::mem::take(&mut state.scratch);
        let mut change = 0.0;
        for (i, value) in z.iter_mut().enumerate() {
            *value = dot(state.eps_column(model.nv, i), eps);
        }
        state.force.copy_from_slice(&z);
        state.solve(model, &mut z);
        change -= dot(&state.force, &z);
        state.scratch = z;
        change
    }

    /// xᵀM_a⁻¹x for the ε = m⁻¹x of a generalized force x: |ε|², less what
    /// the tendons' armature takes off (M_a = M + its terms).
    pub fn inverse_mass_quadratic(&mut self, model: &Model, eps: &[f64]) -> f64 {
        dot(eps, eps) + self.tendon_inertia_change(model, eps)
    }
}
