//! `nudyn linearize`: the dynamics linearized at a state, A, B, C, D, from
//! the exact derivatives of [`crate::dynamics::derivatives`], or, where the
//! model allows and only θ and its rates are asked for, θ̈'s
//! in closed form ([`crate::dynamics::qacc_jacobian`]: the same numbers to
//! round-off, at a fraction of the cost).
//!
//! The state is MuJoCo's for linearization (that of `mjd_transitionFD`):
//! x = (δq, θ̇), δq the displacement from the point's θ in the tangent
//! space (q = q₀ ⊕ δq: a quaternion rotated by the rotation vector δq in
//! its body frame, every other coordinate moved by δq), θ̇ MuJoCo's qvel.
//! ẋ = (δq̇, θ̈) with δq̇ = θ̇ except for a ball or free joint's rotation,
//! whose rotation vector moves as δq̇ = J_r(δq)⁻¹ω = ω + ½ δq × ω + O(δq²),
//! so that ∂δq̇/∂δq = −½\[ω\]× at the point. The inputs u are ε, the
//! physical joint forces T (MuJoCo's qfrc_applied) or the actuators' ctrl,
//! added to the point's. With a step H, the pair of the zero-order hold:
//! A_d = e^{AH}, B_d = ∫₀ᴴ e^{As} ds B, from the exponential of [[A, B], [0, 0]]·H.

use nalgebra::DMatrix;

use crate::dynamics::derivatives::{DerivativeError, Derivatives, Input, Output, Point};
use crate::dynamics::qacc_jacobian::QaccJacobian;
use crate::dynamics::velocity::Given;
use crate::math::{Transform, angular, linear};
use crate::model::{LinkJoint, Model};

/// Which inputs the linearization's B and D are for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inputs {
    /// ε, the FMU's inputs.
    Eps,
    /// The physical joint forces T (MuJoCo's qfrc_applied).
    Torque,
    /// The actuators' ctrl (and the wrench inputs' values after them).
    Ctrl,
}

/// An output of the linearization, each nv rows but the sensors' and the
/// end effector's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LinearOutput {
    /// δq.
    Qpos,
    /// θ̇.
    Qvel,
    /// ν = m*(θ)θ̇.
    Nu,
    /// θ̈.
    Qacc,
    /// MuJoCo's sensordata (nsensordata rows), as mjd_transitionFD's C and D take it.
    Sensordata,
    /// The pose of a body frame (`offset` = ᵇX_ₗ on `link`, as
    /// [`crate::control::BodyFrame`] finds it), 6 rows: the frame's origin
    /// in world axes, then its turn φ in its own axes (R = R₀ exp(\[φ\]×),
    /// R₀ its orientation at the point), as MuJoCo's mj_jacBody gives them
    /// (jacp, and jacr in the body's axes). A function of δq alone.
    EndEffector {
        /// The link carrying the body.
        link: usize,
        /// The body frame relative to the link frame.
        offset: Transform,
    },
}

impl LinearOutput {
    /// The output's name on the command line and in the files.
    pub fn name(self) -> &'static str {
        match self {
            LinearOutput::Qpos => "qpos",
            LinearOutput::Qvel => "qvel",
            LinearOutput::Nu => "nu",
            LinearOutput::Qacc => "qacc",
            LinearOutput::Sensordata => "sensordata",
            LinearOutput::EndEffector { .. } => "end_effector",
        }
    }

    /// How many rows of C and D the output has for `model`.
    pub fn len(self, model: &Model) -> usize {
        match self {
            LinearOutput::Sensordata => Output::Sensordata.len(model),
            LinearOutput::EndEffector { .. } => 6,
            _ => model.nv,
        }
    }
}

/// The point of the linearization: θ (nq), θ̇ (nv), the activation states
/// act (na), the ε and T held (nv each) and the actuators' ctrl (nu).
#[derive(Clone, Debug)]
pub struct OperatingPoint {
    /// θ (qpos).
    pub qpos: Vec<f64>,
    /// θ̇ (qvel).
    pub qvel: Vec<f64>,
    /// act (na).
    pub act: Vec<f64>,
    /// ε held.
    pub eps: Vec<f64>,
    /// T held.
    pub torque: Vec<f64>,
    /// ctrl held.
    pub ctrl: Vec<f64>,
}

/// ẋ = A x + B u, y = C x + D u at the point, x = (δθ, θ̇, act) (δθ in
/// the tangent space); `discrete` with a step.
#[derive(Clone, Debug)]
pub struct Linearization {
    /// (2nv + na) × (2nv + na).
    pub a: DMatrix<f64>,
    /// (2nv + na) × (nv, or nu for ctrl).
    pub b: DMatrix<f64>,
    /// The outputs' rows ([`LinearOutput::len`] each), in the order asked.
    pub c: DMatrix<f64>,
    /// See `c`.
    pub d: DMatrix<f64>,
    /// The eigenvalues of A (1/s), by modulus, then imaginary part.
    pub eigenvalues: Vec<nalgebra::Complex<f64>>,
    /// The zero-order hold's (H, A_d, B_d).
    pub discrete: Option<(f64, DMatrix<f64>, DMatrix<f64>)>,
}

/// Linearizes the model at `point` for `inputs` and `outputs`; with `step`
/// also the zero-order hold's pair.
pub fn linearize(
    model: &Model,
    point: &OperatingPoint,
    inputs: Inputs,
    outputs: &[LinearOutput],
    step: Option<f64>,
) -> Result<Linearization, DerivativeError> {
    let (nv, na) = (model.nv, model.activation_count());
    let n = 2 * nv + na;
    let input = match inputs {
        Inputs::Eps => Input::Eps,
        Inputs::Torque => Input::Torque,
        Inputs::Ctrl => Input::Ctrl,
    };
    let closed_form = outputs.iter().all(|o| !matches!(o, LinearOutput::Nu | LinearOutput::Sensordata))
        && QaccJacobian::check(model).is_ok();
    let (qacc_by, nu_by, act_dot_by, sensors_by) = if closed_form {
        let qacc_by = closed_form_blocks(model, point, input)?;
        let act_dot_by = qacc_by.iter().map(|by| DMatrix::zeros(0, by.ncols())).collect();
        (qacc_by, Vec::new(), act_dot_by, Vec::new())
    } else {
        dual_blocks(model, point, input, outputs)?
    };
    let inputs_count = qacc_by[2].ncols();
    // Rows of x's rates: θ̈ from nv, act's from 2nv; each over (δθ, θ̇, act).
    let mut a = DMatrix::zeros(n, n);
    a.view_mut((0, 0), (nv, nv)).copy_from(&rotation_vector_rates(model, &point.qvel));
    a.view_mut((0, nv), (nv, nv)).fill_with_identity();
    let mut b = DMatrix::zeros(n, inputs_count);
    for (row, by) in [(nv, &qacc_by), (2 * nv, &act_dot_by)] {
        let count = by[0].nrows();
        a.view_mut((row, 0), (count, nv)).copy_from(&by[0]);
        a.view_mut((row, nv), (count, nv)).copy_from(&by[1]);
        a.view_mut((row, 2 * nv), (count, na)).copy_from(&by[3]);
        b.view_mut((row, 0), (count, inputs_count)).copy_from(&by[2]);
    }

    let output_rows: usize = outputs.iter().map(|o| o.len(model)).sum();
    let mut c = DMatrix::zeros(output_rows, n);
    let mut d = DMatrix::zeros(output_rows, inputs_count);
    let mut rows = 0;
    for output in outputs {
        match output {
            LinearOutput::Qpos => c.view_mut((rows, 0), (nv, nv)).fill_with_identity(),
            LinearOutput::Qvel => c.view_mut((rows, nv), (nv, nv)).fill_with_identity(),
            LinearOutput::Nu => {
                c.view_mut((rows, 0), (nv, nv)).copy_from(&nu_by[0]);
                c.view_mut((rows, nv), (nv, nv)).copy_from(&nu_by[1]);
            }
            LinearOutput::Qacc => {
                c.view_mut((rows, 0), (nv, n)).copy_from(&a.rows(nv, nv));
                d.view_mut((rows, 0), (nv, inputs_count)).copy_from(&qacc_by[2]);
            }
            LinearOutput::Sensordata => {
                let count = sensors_by[0].nrows();
                c.view_mut((rows, 0), (count, nv)).copy_from(&sensors_by[0]);
                c.view_mut((rows, nv), (count, nv)).copy_from(&sensors_by[1]);
                c.view_mut((rows, 2 * nv), (count, na)).copy_from(&sensors_by[3]);
                d.view_mut((rows, 0), (count, inputs_count)).copy_from(&sensors_by[2]);
            }
            LinearOutput::EndEffector { link, offset } => {
                c.view_mut((rows, 0), (6, nv)).copy_from(&end_effector_rows(model, &point.qpos, *link, offset)?);
            }
        }
        rows += output.len(model);
    }
    // nalgebra's Schur iterates without end on a matrix with a NaN.
    if let Some(index) = a.iter().chain(b.iter()).position(|x| !x.is_finite()) {
        let value = a.iter().chain(b.iter()).nth(index).copied().unwrap_or(f64::NAN);
        return Err(DerivativeError::Dynamics(crate::dynamics::DynamicsError::NonFinite {
            what: "A, B",
            index,
            value,
        }));
    }
    let mut eigenvalues: Vec<_> = a.complex_eigenvalues().iter().copied().collect();
    eigenvalues.sort_by(|x, y| x.norm().total_cmp(&y.norm()).then(x.im.total_cmp(&y.im)));
    let discrete = step.map(|h| {
        let (ad, bd) = zero_order_hold(&a, &b, h);
        (h, ad, bd)
    });
    Ok(Linearization { a, b, c, d, eigenvalues, discrete })
}

/// The Jacobians of θ̈, ν, act's rates and the sensors (each as
/// [`Derivatives::jacobians_of`] gives them) over δθ, θ̇, `input` and act,
/// from the passes in dual numbers.
type Blocks = (Vec<DMatrix<f64>>, Vec<DMatrix<f64>>, Vec<DMatrix<f64>>, Vec<DMatrix<f64>>);

fn dual_blocks(
    model: &Model,
    point: &OperatingPoint,
    input: Input,
    outputs: &[LinearOutput],
) -> Result<Blocks, DerivativeError> {
    let mut derivatives = Derivatives::new(model);
    let at = Point {
        theta: &point.qpos,
        velocity: &point.qvel,
        given: Given::Qvel,
        eps: &point.eps,
        torque: &point.torque,
        ctrl: &point.ctrl,
        act: &point.act,
        time: 0.0,
    };
    // ν's, act's rates and the sensors' Jacobians come from the same runs
    // as θ̈'s (ν and act_dot are computed by every run; the sensors only
    // when asked). Columns: δθ, θ̇, the input, then act's (none without).
    let columns = [Input::Theta, Input::Velocity, input, Input::Act];
    Ok(if outputs.contains(&LinearOutput::Sensordata) {
        let [qacc_by, nu_by, act_dot_by, sensors_by] = derivatives.jacobians_of(
            model,
            &at,
            [Output::Qacc, Output::Nu, Output::ActDot, Output::Sensordata],
            &columns,
        )?;
        (qacc_by, nu_by, act_dot_by, sensors_by)
    } else {
        let [qacc_by, nu_by, act_dot_by] =
            derivatives.jacobians_of(model, &at, [Output::Qacc, Output::Nu, Output::ActDot], &columns)?;
        (qacc_by, nu_by, act_dot_by, Vec::new())
    })
}

/// θ̈'s Jacobians over δθ, θ̇, `input` and act (none: the closed form
/// covers no activation states) in closed form (dynamics/qacc_jacobian.rs):
/// ∂θ̈/∂T = M⁻¹, ∂θ̈/∂ε = ℓ*, ∂θ̈/∂ctrl = M⁻¹ times the joint actuators' slopes.
fn closed_form_blocks(
    model: &Model,
    point: &OperatingPoint,
    input: Input,
) -> Result<Vec<DMatrix<f64>>, DerivativeError> {
    let nv = model.nv;
    let mut closed_form = QaccJacobian::new(model)?;
    let (mut by_delta, mut by_qvel) = (DMatrix::zeros(nv, nv), DMatrix::zeros(nv, nv));
    let state = (point.qpos.as_slice(), point.qvel.as_slice());
    closed_form.compute(model, state, (&point.eps, &point.torque, &point.ctrl), (&mut by_delta, &mut by_qvel))?;
    let by_input = match input {
        Input::Torque => closed_form.mass_inverse(model).clone(),
        Input::Eps => closed_form.factor_inverse_adjoint(model).clone(),
        _ => closed_form.by_ctrl(model, &point.ctrl),
    };
    Ok(vec![by_delta, by_qvel, by_input, DMatrix::zeros(nv, 0)])
}

/// [`LinearOutput::EndEffector`]'s rows over δq at θ = `qpos`: column k is
/// the frame's motion when θ̇ = e_k (pass 2), since δq moves θ as θ̇ does
/// at the point (q ⊕ δq, mj_integratePos's step); its twist in its own
/// axes (ω, v) gives (R v, ω), R the frame's orientation (body → world).
fn end_effector_rows(
    model: &Model,
    qpos: &[f64],
    link: usize,
    offset: &Transform,
) -> Result<DMatrix<f64>, DerivativeError> {
    let nv = model.nv;
    let mut ws = model.workspace();
    ws.set_configuration(model, qpos)?;
    let body_to_world = offset.compose(&ws.world_transforms(model)[link]).rot.transpose();
    let mut rows = DMatrix::zeros(6, nv);
    let mut unit = vec![0.0; nv];
    for k in 0..nv {
        unit[k] = 1.0;
        ws.set_qvel(model, &unit)?;
        unit[k] = 0.0;
        let twist = offset.apply_motion(&ws.v_body[link]);
        rows.fixed_view_mut::<3, 1>(0, k).copy_from(&(body_to_world * linear(&twist)));
        rows.fixed_view_mut::<3, 1>(3, k).copy_from(&angular(&twist));
    }
    Ok(rows)
}

/// ∂δq̇/∂δq at the point: −½[ω]× on each ball or free joint's rotation
/// (ω its qvel, body frame), zero elsewhere.
fn rotation_vector_rates(model: &Model, qvel: &[f64]) -> DMatrix<f64> {
    let mut rates = DMatrix::zeros(model.nv, model.nv);
    for link in model.links.iter().filter(|l| l.joint == LinkJoint::Ball) {
        let w = nalgebra::Vector3::from_column_slice(&qvel[link.dof_adr..link.dof_adr + 3]);
        let skew = crate::math::skew(&w) * -0.5;
        rates.view_mut((link.dof_adr, link.dof_adr), (3, 3)).copy_from(&skew);
    }
    rates
}

/// The zero-order hold of ẋ = Ax + Bu over `h`: the top blocks of
/// exp([[A, B], [0, 0]]·h).
fn zero_order_hold(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (a.nrows(), b.ncols());
    let mut augmented = DMatrix::zeros(n + m, n + m);
    augmented.view_mut((0, 0), (n, n)).copy_from(&(a * h));
    augmented.view_mut((0, n), (n, m)).copy_from(&(b * h));
    let exponential = augmented.exp();
    (exponential.view((0, 0), (n, n)).into_owned(), exponential.view((0, n), (n, m)).into_owned())
}

/// Frequency (Hz) and damping ratio of an eigenvalue: |λ|/2π and −Re λ/|λ|
/// (1 for a real negative λ, −1 for a real positive one; NaN for λ = 0).
pub fn frequency_and_damping(lambda: nalgebra::Complex<f64>) -> (f64, f64) {
    let modulus = lambda.norm();
    (modulus / (2.0 * std::f64::consts::PI), -lambda.re / modulus)
}
