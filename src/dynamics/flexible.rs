//! The modal block of each flexible body inside the passes (docs/flexible.md,
//! "In the O(N) recursions"). A body's m modes are eliminated at the frame
//! R of the link that carries it, as a joint of m dofs whose "body" is the
//! set of nodes, each moving with V_j = ʲX_R V_R + Ψ_j η̇:
//!
//!   pass 1:  𝓘_RR = Σ X_jᵀ I_j X_j,  U = Σ X_jᵀ I_j Ψ_j,  D = Σ Ψ_jᵀ I_j Ψ_j = R Rᵀ,
//!            G = U D⁻¹,  I^a = 𝓘_RR − G Uᵀ  (added to the link's I^A);
//!   pass 2:  w = η̇ + Gᵀ V_R = R⁻ᵀ ν_η,  V_j;
//!   pass 3:  p_j = I_j c_j + V_j ×* I_j V_j,  c_j = Ψ̇_j η̇ + V_j × Ψ_j η̇,
//!            u = Q − Σ Ψ_jᵀ p_j,  ν̇_η = ε_η + R⁻¹u (+ Ṙᵀw + RᵀĠᵀV_R),
//!            p^a = Σ X_jᵀ p_j + G u  (added to the link's p^A);
//!   outward: η̈ = R⁻ᵀ(R⁻¹u) − Gᵀ A_R.
//!
//! Q holds the modal stiffness and damping (−ω²η − 2ζωη̇) and, in the force
//! recursion, gravity on the nodes. The factor's rates come from
//! 𝓘̇ = Σ Ḃ_jᵀ I_j B_j + B_jᵀ I_j Ḃ_j with Ḃ_j = [−(Ψ_jη̇)× X_j, Ψ̇_j]:
//!   U̇ = Σ X_jᵀ(Ψ_jη̇ ×* I_jΨ_j + I_jΨ̇_j),  Ḋ = Σ Ψ̇_jᵀI_jΨ_j + Ψ_jᵀI_jΨ̇_j,
//!   İ^a = Σ X_jᵀ(Ψ_jη̇ ×* I_j − I_j Ψ_jη̇ ×)X_j − U̇Gᵀ − GU̇ᵀ + GḊGᵀ.
//! With Ġᵀ = D⁻¹(U̇ − GḊ)ᵀ and RᵀD⁻¹ = R⁻¹, the rate term RᵀĠᵀV_R is
//! R⁻¹(U̇ − GḊ)ᵀV_R. Dense per body (m is small, nodes few): O(nodes · m²)
//! per evaluation, in buffers sized once ([`FlexState`]). A body of point
//! masses only has a constant D (the modal masses): its factor R, R⁻¹ and
//! D⁻¹ are made once, with the workspace, and Ḋ = Ṙ = 0. Each block's
//! arithmetic is instantiated for 1 to [`FIXED_MODES`] modes, where its
//! loops unroll (`by_modes!`), and for any count beyond.
//!
//! A child body at a node hangs from that node as from a parent link: its
//! I^a, p^a and İ^a (brought to the node's frame) join the node's, so that
//! for such a node I_j is its own inertia plus its children's articulated
//! inertias, p_j gains their p^a, and the rates gain Σ B_jᵀ İ_j B_j; its
//! parent velocity and acceleration are the node's, V_j and
//! A_j = X_j A_R + Ψ_j η̈ + c_j. A body welded at a node is part of the
//! node: its inertia about the node's origin (first moment included) joins
//! the node's own inertia, a constant, and gravity on both is I_node (0, g).

use nalgebra::{DMatrix, DVector, Dim, U1, U6};

use super::articulated::{upper_cholesky_into, upper_triangular_inverse_into};
use super::{DynamicsError, accumulate};
use crate::flex::nodes;
use crate::flex::point_masses;
use crate::math::{
    Real, SpatialMat, SpatialVec, Transform, Vec3, cross_force, cross_motion, leading, leading_mut, mul_cross_motion,
    real, spatial,
};
use crate::model::{FlexBody, Model};
use crate::workspace::{NodeParent, Workspace};

/// The largest mode count with its own fixed-size instance of the blocks' arithmetic.
pub const FIXED_MODES: usize = 6;

/// `f(modes, args)` with `modes` the dimension of `m` modes: `Const` up to
/// [`FIXED_MODES`], `Dyn` beyond, and always `Dyn` for a scalar `S` without
/// specialized instances ([`Real::SPECIALIZED`]).
macro_rules! by_modes {
    ($m:expr, $f:ident $(::<$($g:tt),*>)? ($($arg:expr),* $(,)?)) => {{
        use nalgebra::{Const, Dyn};
        match $m {
            m if !S::SPECIALIZED => $f $(::<$($g),*>)? (Dyn(m), $($arg),*),
            1 => $f $(::<$($g),*>)? (Const::<1>, $($arg),*),
            2 => $f $(::<$($g),*>)? (Const::<2>, $($arg),*),
            3 => $f $(::<$($g),*>)? (Const::<3>, $($arg),*),
            4 => $f $(::<$($g),*>)? (Const::<4>, $($arg),*),
            5 => $f $(::<$($g),*>)? (Const::<5>, $($arg),*),
            6 => $f $(::<$($g),*>)? (Const::<6>, $($arg),*),
            m => $f $(::<$($g),*>)? (Dyn(m), $($arg),*),
        }
    }};
}

/// One flexible body's share of the workspace.
#[derive(Clone, Debug)]
pub struct FlexState<S: Real = f64> {
    /// Whether this block sets its link's inward slots (no rigid child and
    /// no block before it on the link) rather than adding to them.
    pub opens_link: bool,
    /// Whether D is constant (point masses only): R, R⁻¹ and D⁻¹ are made
    /// with the workspace, and Ḋ = 0.
    constant_factor: bool,
    /// Each node's own inertia, with the bodies welded at it
    /// (`FlexBody::node_inertia`), per node taken one by one.
    node_inertia: Vec<SpatialMat<S>>,
    /// ʲX_R per node taken one by one (`FlexBody::rotating`; pass 1).
    pub node_x: Vec<Transform<S>>,
    /// Ψ_j per such node, 6 × m (pass 1).
    pub psi: Vec<DMatrix<S>>,
    /// V_j per such node (pass 2).
    pub v_node: Vec<SpatialVec<S>>,
    /// Ψ_j η̇ per such node, its velocity relative to R (pass 2; pass 3 reads it).
    v_relative: Vec<SpatialVec<S>>,
    /// The point-mass nodes' integrals and sums.
    points: point_masses::State<S>,
    /// 𝓘_RR, all nodes' inertia about R (pass 1).
    pub rigid: SpatialMat<S>,
    /// U = 𝓘_Rη, 6 × m (pass 1).
    pub coupling: DMatrix<S>,
    /// R, upper triangular with R Rᵀ = D (pass 1).
    pub r: DMatrix<S>,
    /// R⁻¹ (pass 1).
    pub r_inv: DMatrix<S>,
    /// G = U D⁻¹, 6 × m (pass 1).
    pub gain: DMatrix<S>,
    /// D, then D⁻¹ (m × m; D⁻¹ throughout with a constant factor).
    d: DMatrix<S>,
    /// Scratch: I_j Ψ_j (6 × m).
    inertia_psi: DMatrix<S>,
    /// Scratch: Ψ̇_j (6 × m).
    psi_rate: DMatrix<S>,
    /// Scratch: U̇ (6 × m).
    coupling_rate: DMatrix<S>,
    /// Scratch: Ḋ, then R⁻¹ḊR⁻ᵀ's upper triangle with its diagonal halved (m × m).
    d_rate: DMatrix<S>,
    /// Scratch: G Ḋ (6 × m).
    gain_d_rate: DMatrix<S>,
    /// Scratch: R⁻¹Ḋ (m × m).
    square: DMatrix<S>,
    /// Scratch: the velocity-product u, the force u, and one more m-vector.
    u_bias: DVector<S>,
    u_force: DVector<S>,
    scratch: DVector<S>,
    /// Per child at a node: its first link's placement relative to the
    /// node, ᶜX_j (pass 1).
    pub child_x: Vec<Transform<S>>,
    /// Per node of `rotating` (empty without children at nodes): the
    /// children's I^a in the node's frame (pass 1) ...
    child_inertia: Vec<SpatialMat<S>>,
    /// ... their p^a of the velocity products and of the forces, and İ^a (pass 3) ...
    child_bias: Vec<SpatialVec<S>>,
    child_force: Vec<SpatialVec<S>>,
    child_inertia_rate: Vec<SpatialMat<S>>,
    /// ... their wrenches in the force recursions (ε ↔ T, Jᵀf) ...
    pub(crate) child_scratch: Vec<SpatialVec<S>>,
    /// ... and the node's c_j (pass 3) and A_j (the outward pass).
    node_bias_acceleration: Vec<SpatialVec<S>>,
    pub(crate) a_node: Vec<SpatialVec<S>>,
}

impl<S: Real> FlexState<S> {
    /// Buffers for `flexible`; `opens_link` as the workspace places it.
    pub(crate) fn new(flexible: &FlexBody, opens_link: bool) -> Self {
        let (m, nodes) = (flexible.mode_count(), flexible.rotating.len());
        let carrying = if flexible.node_children.is_empty() { 0 } else { nodes };
        let points = point_masses::State::new(&flexible.points, m);
        let (mut r, mut r_inv, mut d) = (DMatrix::zeros(m, m), DMatrix::zeros(m, m), DMatrix::zeros(m, m));
        // Point masses only: the factor of the constant D, once (if D is
        // not positive definite, pass 1 factors it and reports it).
        let constant_factor = nodes == 0 && upper_cholesky_into(&points.modal_mass, &mut r);
        if constant_factor {
            upper_triangular_inverse_into(&r, &mut r_inv);
            inverse_from_factor(nalgebra::Dyn(m), &r_inv, &mut d);
        }
        FlexState {
            opens_link,
            constant_factor,
            node_inertia: (0..nodes).map(|r| real(&flexible.node_inertia(r))).collect(),
            node_x: vec![Transform::identity(); nodes],
            psi: vec![DMatrix::zeros(6, m); nodes],
            v_node: vec![SpatialVec::zeros(); nodes],
            v_relative: vec![SpatialVec::zeros(); nodes],
            points,
            rigid: SpatialMat::zeros(),
            coupling: DMatrix::zeros(6, m),
            r,
            r_inv,
            gain: DMatrix::zeros(6, m),
            d,
            inertia_psi: DMatrix::zeros(6, m),
            psi_rate: DMatrix::zeros(6, m),
            coupling_rate: DMatrix::zeros(6, m),
            d_rate: DMatrix::zeros(m, m),
            gain_d_rate: DMatrix::zeros(6, m),
            square: DMatrix::zeros(m, m),
            u_bias: DVector::zeros(m),
            u_force: DVector::zeros(m),
            scratch: DVector::zeros(m),
            child_x: vec![Transform::identity(); flexible.node_children.len()],
            child_inertia: vec![SpatialMat::zeros(); carrying],
            child_bias: vec![SpatialVec::zeros(); carrying],
            child_force: vec![SpatialVec::zeros(); carrying],
            child_inertia_rate: vec![SpatialMat::zeros(); carrying],
            child_scratch: vec![SpatialVec::zeros(); carrying],
            node_bias_acceleration: vec![SpatialVec::zeros(); carrying],
            a_node: vec![SpatialVec::zeros(); carrying],
        }
    }

    /// Σ X_jᵀ I^a_j V_j over the nodes that carry children, I^a_j their
    /// children's articulated inertias: the share of 𝓘_RR V_R + U η̇ that is
    /// not the nodes' momentum (after pass 2).
    pub(crate) fn carried_momentum(&self, flexible: &FlexBody) -> SpatialVec<S> {
        (0..flexible.rotating.len())
            .filter(|&r| flexible.carries(r))
            .map(|r| self.node_x[r].apply_transpose_force(&(self.child_inertia[r] * self.v_node[r])))
            .fold(SpatialVec::zeros(), |a, b| a + b)
    }
}

/// D⁻¹ = R⁻ᵀR⁻¹ into `d_inv` (both m × m; R⁻¹ upper triangular).
fn inverse_from_factor<S: Real, M: Dim>(modes: M, r_inv: &DMatrix<S>, d_inv: &mut DMatrix<S>) {
    let r_inv = leading(r_inv, modes, modes);
    let mut d_inv = leading_mut(d_inv, modes, modes);
    for a in 0..modes.value() {
        for b in a..modes.value() {
            let mut s = S::zero();
            for l in 0..=a {
                s += r_inv[(l, a)] * r_inv[(l, b)];
            }
            d_inv[(a, b)] = s;
            d_inv[(b, a)] = s;
        }
    }
}

/// Column `k` of a 6-row block.
fn column<S: Real, M: Dim>(m: &nalgebra::MatrixView<'_, S, U6, M, U1, nalgebra::Dyn>, k: usize) -> SpatialVec<S> {
    SpatialVec::from_fn(|row, _| m[(row, k)])
}

/// The flexible bodies on link `i`, by index into the model's and workspace's lists.
pub(crate) fn on_link(model: &Model, i: usize) -> impl Iterator<Item = usize> + '_ {
    model.flexible.iter().enumerate().filter(move |(_, f)| f.link == i).map(|(f, _)| f)
}

/// Node slot `r`'s inertia I_j: its own, plus its children's I^a when it carries any.
fn slot_inertia<S: Real>(flexible: &FlexBody, state: &FlexState<S>, r: usize) -> SpatialMat<S> {
    let own = state.node_inertia[r];
    if flexible.carries(r) { own + state.child_inertia[r] } else { own }
}

/// The flexible body and node slot that link `i` (a child at a node) hangs from.
#[inline]
pub(crate) fn node_of(model: &Model, at: NodeParent) -> (usize, usize, usize) {
    let (f, c) = (at.flexible as usize, at.child as usize);
    (f, c, model.flexible[f].node_children[c].slot)
}

/// Passes 0 and 1 for a child's first link `i` at a node, after its own:
/// `x_parent` (its placement on the parent link through the deformed node,
/// ᶜX_j ʲX_R), ᶜX_j kept, and its I^a into the node's slot.
pub(crate) fn place_child<S: Real>(model: &Model, ws: &mut Workspace<S>, i: usize, at: NodeParent) {
    let (f, c, slot) = node_of(model, at);
    let flexible = &model.flexible[f];
    let eta = flexible.eta(ws.theta.as_slice());
    let to_node = ws.x_parent[i];
    ws.x_parent[i] = to_node.compose(&nodes::transform(&flexible.modal, flexible.rotating[slot], eta));
    let state = &mut ws.flex[f];
    state.child_x[c] = to_node;
    to_node.add_inertia_to_parent(&ws.ia_reduced[i], &mut state.child_inertia[slot], ws.accumulation[i].opens_parent);
}

/// V⁺ of a child's first link at a node: ᶜX_j V_j (pass 2, after its body's block).
#[inline]
pub(crate) fn child_velocity<S: Real>(model: &Model, ws: &Workspace<S>, at: NodeParent) -> SpatialVec<S> {
    let (f, c, slot) = node_of(model, at);
    let state = &ws.flex[f];
    state.child_x[c].apply_motion(&state.v_node[slot])
}

/// A⁺ (before its own joint's terms) of a child's first link at a node:
/// ᶜX_j A_j (the outward pass, after its body's block).
#[inline]
pub(crate) fn child_acceleration<S: Real>(model: &Model, ws: &Workspace<S>, at: NodeParent) -> SpatialVec<S> {
    let (f, c, slot) = node_of(model, at);
    let state = &ws.flex[f];
    state.child_x[c].apply_motion(&state.a_node[slot])
}

/// Pass 3's hand-over of a child's first link at a node: its p^a of the
/// velocity products and of the forces (`force`, when the recursion of
/// forces runs) and, with the rates, its İ^a term, brought to the node's
/// frame by ᶜX_j into the node's slots.
pub(crate) fn child_bias<S: Real>(
    model: &Model,
    ws: &mut Workspace<S>,
    at: NodeParent,
    opens: bool,
    bias: SpatialVec<S>,
    force: Option<SpatialVec<S>>,
    inertia_rate: Option<&SpatialMat<S>>,
) {
    let (f, c, slot) = node_of(model, at);
    let state = &mut ws.flex[f];
    let x = state.child_x[c];
    accumulate(&mut state.child_bias[slot], x.apply_transpose_force(&bias), opens);
    if let Some(force) = force {
        accumulate(&mut state.child_force[slot], x.apply_transpose_force(&force), opens);
    }
    if let Some(rate) = inertia_rate {
        x.add_inertia_to_parent(rate, &mut state.child_inertia_rate[slot], opens);
    }
}

/// Pass 1 for the modal blocks on link `i`: their factors, and I^a added to the link's I^A.
pub(crate) fn factor_modes<S: Real>(model: &Model, ws: &mut Workspace<S>, i: usize) -> Result<(), DynamicsError> {
    for f in on_link(model, i) {
        let flexible = &model.flexible[f];
        let state = &mut ws.flex[f];
        let eta = flexible.eta(ws.theta.as_slice());
        let reduced = by_modes!(flexible.mode_count(), factor_block(flexible, state, eta))
            .ok_or(DynamicsError::Singular { link: i })?;
        accumulate(&mut ws.ia_reduced[i], reduced, state.opens_link);
    }
    Ok(())
}

/// Pass 1 for one block: its factor, and I^a (None if D is not positive definite).
fn factor_block<S: Real, M: Dim>(
    modes: M,
    flexible: &FlexBody,
    state: &mut FlexState<S>,
    eta: &[S],
) -> Option<SpatialMat<S>> {
    let m = modes.value();
    let mut rigid = SpatialMat::zeros();
    state.coupling.as_mut_slice().fill(S::zero());
    if !state.constant_factor {
        state.d.copy_from(&state.points.modal_mass);
    }
    for (r, &j) in flexible.rotating.iter().enumerate() {
        let x = nodes::transform(&flexible.modal, j, eta);
        nodes::subspace(&flexible.modal, j, eta, &mut state.psi[r]);
        let inertia = slot_inertia(flexible, state, r);
        x.add_inertia_to_parent(&inertia, &mut rigid, false);
        let psi = leading(&state.psi[r], U6, modes);
        let mut inertia_psi = leading_mut(&mut state.inertia_psi, U6, modes);
        let mut coupling = leading_mut(&mut state.coupling, U6, modes);
        for k in 0..m {
            let i_psi = inertia * column(&psi, k);
            inertia_psi.column_mut(k).copy_from(&i_psi);
            let mut slot = coupling.column_mut(k);
            slot += x.apply_transpose_force(&i_psi);
        }
        let mut d = leading_mut(&mut state.d, modes, modes);
        for k in 0..m {
            for l in 0..=k {
                let mut s = S::zero();
                for row in 0..6 {
                    s += psi[(row, l)] * inertia_psi[(row, k)];
                }
                d[(l, k)] += s;
            }
        }
        state.node_x[r] = x;
    }
    state.points.configure(modes, eta);
    state.points.add_inertia(modes, &mut rigid, &mut state.coupling);
    state.rigid = rigid;
    if !state.constant_factor {
        if !upper_cholesky_into(&leading(&state.d, modes, modes), &mut leading_mut(&mut state.r, modes, modes)) {
            return None;
        }
        upper_triangular_inverse_into(
            &leading(&state.r, modes, modes),
            &mut leading_mut(&mut state.r_inv, modes, modes),
        );
        inverse_from_factor(modes, &state.r_inv, &mut state.d);
    }
    // G = U D⁻¹, and I^a = 𝓘_RR − G Uᵀ (symmetric: the upper triangle, mirrored).
    let (coupling, d_inv) = (leading(&state.coupling, U6, modes), leading(&state.d, modes, modes));
    let mut gain = leading_mut(&mut state.gain, U6, modes);
    for k in 0..m {
        for row in 0..6 {
            let mut s = S::zero();
            for l in 0..m {
                s += coupling[(row, l)] * d_inv[(l, k)];
            }
            gain[(row, k)] = s;
        }
    }
    let mut reduced = rigid;
    for col in 0..6 {
        for row in 0..=col {
            let mut s = S::zero();
            for k in 0..m {
                s += gain[(row, k)] * coupling[(col, k)];
            }
            reduced[(row, col)] -= s;
            reduced[(col, row)] = reduced[(row, col)];
        }
    }
    Some(reduced)
}

/// Which of ν and θ̇ pass 2 is given (as `velocity::Given`).
pub(crate) fn velocities<S: Real>(model: &Model, ws: &mut Workspace<S>, i: usize, nu_given: bool) {
    for f in on_link(model, i) {
        by_modes!(model.flexible[f].mode_count(), velocities_of_block(model, ws, i, f, nu_given));
    }
}

/// Pass 2 for block `f` on link `i`.
fn velocities_of_block<S: Real, M: Dim>(
    modes: M,
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    f: usize,
    nu_given: bool,
) {
    let flexible = &model.flexible[f];
    let (m, adr) = (modes.value(), flexible.dof_adr);
    let v_r = ws.v_body[i];
    let state = &mut ws.flex[f];
    let (gain, r, r_inv) =
        (leading(&state.gain, U6, modes), leading(&state.r, modes, modes), leading(&state.r_inv, modes, modes));
    let nu = &mut ws.nu.as_mut_slice()[adr..adr + m];
    let w = &mut ws.w_joint.as_mut_slice()[adr..adr + m];
    let qvel = &mut ws.qvel.as_mut_slice()[adr..adr + m];
    for k in 0..m {
        let gv = column(&gain, k).dot(&v_r);
        if nu_given {
            let mut w_k = S::zero();
            for l in 0..=k {
                w_k += r_inv[(l, k)] * nu[l];
            }
            w[k] = w_k;
            qvel[k] = w_k - gv;
        } else {
            w[k] = qvel[k] + gv;
        }
    }
    if !nu_given {
        for k in 0..m {
            let mut nu_k = S::zero();
            for l in 0..=k {
                nu_k += r[(l, k)] * w[l];
            }
            nu[k] = nu_k;
        }
    }
    for r in 0..flexible.rotating.len() {
        let psi = leading(&state.psi[r], U6, modes);
        let mut relative = SpatialVec::zeros();
        for (k, rate) in qvel.iter().enumerate() {
            relative += column(&psi, k) * *rate;
        }
        state.v_relative[r] = relative;
        state.v_node[r] = state.node_x[r].apply_motion(&v_r) + relative;
    }
}

/// The modal forces −ω²η − 2ζωη̇ into `tau_passive`'s modal entries.
pub(crate) fn passive_forces<S: Real>(model: &Model, ws: &mut Workspace<S>) {
    for flexible in &model.flexible {
        for k in 0..flexible.mode_count() {
            let (q, v) = (ws.theta[flexible.qpos_adr + k], ws.qvel[flexible.dof_adr + k]);
            ws.tau_passive[flexible.dof_adr + k] = q * -flexible.stiffness(k) - v * flexible.damping(k);
        }
    }
}

/// Pass 3 for the modal blocks on link `i`, before the link's own: their
/// ν̇ terms, and p^a (and with `rates`, İ^a) added to the link's slots.
pub(crate) fn bias<S: Real, const RATES: bool>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    eps: &[S],
    forces: bool,
) {
    for f in on_link(model, i) {
        by_modes!(model.flexible[f].mode_count(), bias_of_block::<RATES, _, _>(model, ws, i, f, eps, forces));
    }
}

/// Pass 3 for block `f` on link `i`.
fn bias_of_block<const RATES: bool, S: Real, M: Dim>(
    modes: M,
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    f: usize,
    eps: &[S],
    forces: bool,
) {
    let flexible = &model.flexible[f];
    let (m, adr) = (modes.value(), flexible.dof_adr);
    let eta = flexible.eta(ws.theta.as_slice());
    let rate = &ws.qvel.as_slice()[adr..adr + m];
    let gravity = (forces && !model.shortcuts.no_gravity).then(|| ws.x_world[i].rot * real::<S, 3, 1>(&model.gravity));
    let state = &mut ws.flex[f];
    let (mut p_bias, mut p_force) = (SpatialVec::zeros(), SpatialVec::zeros());
    let u_bias = &mut state.u_bias.as_mut_slice()[..m];
    let u_force = &mut state.u_force.as_mut_slice()[..m];
    u_bias.fill(S::zero());
    if forces {
        u_force.copy_from_slice(&ws.tau_passive.as_slice()[adr..adr + m]);
    } else {
        u_force.fill(S::zero());
    }
    for (r, &j) in flexible.rotating.iter().enumerate() {
        let (x, v, relative) = (&state.node_x[r], state.v_node[r], state.v_relative[r]);
        let psi = leading(&state.psi[r], U6, modes);
        let inertia = state.node_inertia[r];
        let c = nodes::subspace_rate_times(&flexible.modal, j, eta, rate) + cross_motion(&v, &relative);
        let mut p = inertia * c + cross_force(&v, &(inertia * v));
        let carries = flexible.carries(r);
        if carries {
            // The children's articulated inertias see the node's c_j, and their p^a join.
            p += state.child_inertia[r] * c + state.child_bias[r];
            state.node_bias_acceleration[r] = c;
        }
        p_bias += x.apply_transpose_force(&p);
        for (k, u) in u_bias.iter_mut().enumerate() {
            *u -= column(&psi, k).dot(&p);
        }
        if gravity.is_some() || (forces && carries) {
            // Gravity on the node and the bodies welded at it, I_node (0, g)
            // in its axes (p = −f_ext), and the children's p^a of forces.
            let mut p = match &gravity {
                Some(g) => -(inertia * spatial(&Vec3::zeros(), &(x.rot * g))),
                None => SpatialVec::zeros(),
            };
            if forces && carries {
                p += state.child_force[r];
            }
            p_force += x.apply_transpose_force(&p);
            for (k, u) in u_force.iter_mut().enumerate() {
                *u -= column(&psi, k).dot(&p);
            }
        }
    }
    state.points.add_bias(modes, rate, &ws.v_body[i], &mut p_bias, u_bias);
    if let Some(g) = &gravity {
        state.points.add_gravity(modes, g, &mut p_force, u_force);
    }
    // R⁻¹u for both u (R⁻¹ upper triangular).
    let (r_inv, gain) = (leading(&state.r_inv, modes, modes), leading(&state.gain, U6, modes));
    for k in 0..m {
        let (mut joint_bias, mut eps_passive) = (S::zero(), S::zero());
        for l in k..m {
            joint_bias += r_inv[(k, l)] * u_bias[l];
            eps_passive += r_inv[(k, l)] * u_force[l];
        }
        ws.eps_passive[adr + k] = eps_passive;
        ws.nu_dot_joint[adr + k] = eps[adr + k] + eps_passive + joint_bias;
        if RATES {
            ws.nu_dot[adr + k] = ws.nu_dot_joint[adr + k];
            ws.coriolis[adr + k] = -joint_bias;
        }
    }
    for k in 0..m {
        let g = column(&gain, k);
        p_bias += g * u_bias[k];
        p_force += g * u_force[k];
    }
    accumulate(&mut ws.p_bias_body[i], p_bias, state.opens_link);
    if forces {
        accumulate(&mut ws.p_force_body[i], p_force, state.opens_link);
    }
    if RATES {
        let w = &ws.w_joint.as_slice()[adr..adr + m];
        let nu_dot = &mut ws.nu_dot.as_mut_slice()[adr..adr + m];
        let coriolis = &mut ws.coriolis.as_mut_slice()[adr..adr + m];
        rates(modes, flexible, state, ws.v_body[i], &mut ws.ia_dot_body[i], nu_dot, coriolis, w, eta, rate);
    }
}

/// The factor's rates of one block: its ν̇ and C gain Ṙᵀw + RᵀĠᵀV_R, and
/// İ^a goes into the link's İ^A slot (`ia_dot`, opened by this block if it
/// opens the link). `nu_dot`, `coriolis` and `w` are the block's entries.
#[allow(clippy::too_many_arguments)]
fn rates<S: Real, M: Dim>(
    modes: M,
    flexible: &FlexBody,
    state: &mut FlexState<S>,
    v_r: SpatialVec<S>,
    ia_dot: &mut SpatialMat<S>,
    nu_dot: &mut [S],
    coriolis: &mut [S],
    w: &[S],
    eta: &[S],
    rate: &[S],
) {
    let m = modes.value();
    let mut rigid_rate = SpatialMat::zeros();
    // Ḋ is zero for point masses only.
    let varying = !flexible.rotating.is_empty();
    state.coupling_rate.as_mut_slice().fill(S::zero());
    if varying {
        state.d_rate.as_mut_slice().fill(S::zero());
    }
    for (r, &j) in flexible.rotating.iter().enumerate() {
        let x = &state.node_x[r];
        let (inertia, relative) = (slot_inertia(flexible, state, r), state.v_relative[r]);
        // Ψη̇ ×* I − I Ψη̇ × = −(B + Bᵀ), B = I (Ψη̇ ×); a node carrying
        // children adds their İ_j: Bᵀ İ_j B to 𝓘̇ (B = [X_j, Ψ_j]).
        let b = mul_cross_motion(&inertia, &relative);
        let carried_rate = flexible.carries(r).then(|| state.child_inertia_rate[r]);
        let own_rate = match &carried_rate {
            Some(rate) => rate - (b + b.transpose()),
            None => -(b + b.transpose()),
        };
        x.add_inertia_to_parent(&own_rate, &mut rigid_rate, false);
        nodes::subspace_rate(&flexible.modal, j, eta, rate, &mut state.psi_rate);
        let (psi, psi_rate) = (leading(&state.psi[r], U6, modes), leading(&state.psi_rate, U6, modes));
        let mut coupling_rate = leading_mut(&mut state.coupling_rate, U6, modes);
        let mut d_rate = leading_mut(&mut state.d_rate, modes, modes);
        for k in 0..m {
            let i_psi = inertia * column(&psi, k);
            let mut i_psi_rate = inertia * column(&psi_rate, k);
            if let Some(rate) = &carried_rate {
                i_psi_rate += rate * column(&psi, k);
            }
            let term = cross_force(&relative, &i_psi) + i_psi_rate;
            let mut slot = coupling_rate.column_mut(k);
            slot += x.apply_transpose_force(&term);
            for l in 0..m {
                d_rate[(l, k)] += column(&psi_rate, l).dot(&i_psi) + column(&psi, l).dot(&i_psi_rate);
            }
        }
    }
    state.points.add_inertia_rates(modes, &mut rigid_rate, &mut state.coupling_rate);
    let (gain, d_rate) = (leading(&state.gain, U6, modes), leading(&state.d_rate, modes, modes));
    let mut gain_d_rate = leading_mut(&mut state.gain_d_rate, U6, modes);
    if varying {
        for k in 0..m {
            for row in 0..6 {
                let mut s = S::zero();
                for l in 0..m {
                    s += gain[(row, l)] * d_rate[(l, k)];
                }
                gain_d_rate[(row, k)] = s;
            }
        }
    }
    // İ^a = 𝓘̇_RR − U̇Gᵀ − GU̇ᵀ + (GḊ)Gᵀ (symmetric: the upper triangle, mirrored).
    let coupling_rate = leading(&state.coupling_rate, U6, modes);
    let mut reduced_rate = rigid_rate;
    for col in 0..6 {
        for row in 0..=col {
            let mut s = S::zero();
            for k in 0..m {
                s += coupling_rate[(row, k)] * gain[(col, k)] + gain[(row, k)] * coupling_rate[(col, k)];
                if varying {
                    s -= gain_d_rate[(row, k)] * gain[(col, k)];
                }
            }
            reduced_rate[(row, col)] -= s;
            reduced_rate[(col, row)] = reduced_rate[(row, col)];
        }
    }
    accumulate(ia_dot, reduced_rate, state.opens_link);
    // RᵀĠᵀV_R = R⁻¹(U̇ − GḊ)ᵀV_R.
    let (r, r_inv) = (leading(&state.r, modes, modes), leading(&state.r_inv, modes, modes));
    let scratch = &mut state.scratch.as_mut_slice()[..m];
    for k in 0..m {
        let mut s = S::zero();
        for row in 0..6 {
            let y = if varying { coupling_rate[(row, k)] - gain_d_rate[(row, k)] } else { coupling_rate[(row, k)] };
            s += y * v_r[row];
        }
        scratch[k] = s;
    }
    for k in 0..m {
        let mut term = S::zero();
        for l in k..m {
            term += r_inv[(k, l)] * scratch[l];
        }
        nu_dot[k] += term;
        coriolis[k] -= term;
    }
    if varying {
        // Ṙᵀw with Ṙ = RΦ, Φ = R⁻¹ḊR⁻ᵀ's upper triangle with the diagonal halved.
        let mut square = leading_mut(&mut state.square, modes, modes);
        for a in 0..m {
            for b in 0..m {
                let mut s = S::zero();
                for l in 0..m {
                    s += r_inv[(a, l)] * d_rate[(l, b)];
                }
                square[(a, b)] = s;
            }
        }
        let mut phi = leading_mut(&mut state.d_rate, modes, modes);
        for a in 0..m {
            for b in 0..m {
                let mut scaled = S::zero();
                for l in b..m {
                    scaled += square[(a, l)] * r_inv[(b, l)];
                }
                phi[(a, b)] = match a.cmp(&b) {
                    std::cmp::Ordering::Less => scaled,
                    std::cmp::Ordering::Equal => scaled * 0.5,
                    std::cmp::Ordering::Greater => S::zero(),
                };
            }
        }
        for k in 0..m {
            let mut term = S::zero();
            for l in 0..m {
                let mut r_rate = S::zero();
                for c in 0..m {
                    r_rate += r[(l, c)] * phi[(c, k)];
                }
                term += r_rate * w[l];
            }
            nu_dot[k] += term;
            coriolis[k] -= term;
        }
    }
}

/// The outward pass for the modal blocks on link `i`, after the link's:
/// η̈ = R⁻ᵀ(R⁻¹u) − Gᵀ A_R.
pub(crate) fn accelerations<S: Real>(model: &Model, ws: &mut Workspace<S>, i: usize) {
    for f in on_link(model, i) {
        by_modes!(model.flexible[f].mode_count(), accelerations_of_block(model, ws, i, f));
    }
}

/// The outward pass for block `f` on link `i`.
fn accelerations_of_block<S: Real, M: Dim>(modes: M, model: &Model, ws: &mut Workspace<S>, i: usize, f: usize) {
    let flexible = &model.flexible[f];
    let (m, adr) = (modes.value(), flexible.dof_adr);
    let (state, a_r) = (&mut ws.flex[f], ws.a_body[i]);
    let (r_inv, gain) = (leading(&state.r_inv, modes, modes), leading(&state.gain, U6, modes));
    let nu_dot_joint = &ws.nu_dot_joint.as_slice()[adr..adr + m];
    let qacc = &mut ws.qacc.as_mut_slice()[adr..adr + m];
    for k in 0..m {
        let mut joint = S::zero();
        for l in 0..=k {
            joint += r_inv[(l, k)] * nu_dot_joint[l];
        }
        qacc[k] = joint - column(&gain, k).dot(&a_r);
    }
    // The nodes that carry children: A_j = X_j A_R + Ψ_j η̈ + c_j, their children's parent acceleration.
    for r in (0..flexible.rotating.len()).filter(|&r| flexible.carries(r)) {
        let psi = leading(&state.psi[r], U6, modes);
        let modal = (0..m).fold(SpatialVec::zeros(), |a, k| a + column(&psi, k) * qacc[k]);
        state.a_node[r] = state.node_x[r].apply_motion(&a_r) + modal + state.node_bias_acceleration[r];
    }
}

/// ε ↔ T for the modal blocks on link `i`, with p_j the wrenches that the
/// children at node j hand over (`child_scratch`; no other force acts on
/// nodes): u = T_η − Σ Ψ_jᵀp_j, ε_η = R⁻¹u, or u = R ε_η, T_η = u + Σ Ψ_jᵀp_j;
/// Σ X_jᵀp_j + G u added to the link's slot.
pub(crate) fn inward<S: Real>(
    model: &Model,
    ws: &mut Workspace<S>,
    i: usize,
    torque_from_eps: bool,
    input: &[S],
    out: &mut [S],
) {
    for f in on_link(model, i) {
        let flexible = &model.flexible[f];
        let (m, adr) = (flexible.mode_count(), flexible.dof_adr);
        let state = &mut ws.flex[f];
        // The children's wrenches at their nodes: Σ Ψ_jᵀ p_j on the modes, Σ X_jᵀ p_j on the link.
        state.u_force.fill(S::zero());
        let mut p = SpatialVec::zeros();
        for r in (0..flexible.rotating.len()).filter(|&r| flexible.carries(r)) {
            let p_node = state.child_scratch[r];
            p += state.node_x[r].apply_transpose_force(&p_node);
            for k in 0..m {
                state.u_force[k] += SpatialVec::from_fn(|row, _| state.psi[r][(row, k)]).dot(&p_node);
            }
        }
        for k in 0..m {
            state.scratch[k] = if torque_from_eps {
                (k..m).map(|l| state.r[(k, l)] * input[adr + l]).fold(S::zero(), |a, b| a + b)
            } else {
                input[adr + k] - state.u_force[k]
            };
        }
        for k in 0..m {
            out[adr + k] = if torque_from_eps {
                state.scratch[k] + state.u_force[k]
            } else {
                (k..m).map(|l| state.r_inv[(k, l)] * state.scratch[l]).fold(S::zero(), |a, b| a + b)
            };
        }
        let p = (0..m).fold(p, |p, k| p + SpatialVec::from_fn(|row, _| state.gain[(row, k)]) * state.scratch[k]);
        accumulate(&mut ws.p_scratch_body[i], p, state.opens_link);
    }
}
