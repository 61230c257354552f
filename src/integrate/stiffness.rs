//! Whether an explicit method's steps are held by stability rather than by
//! accuracy: Hairer's stiffness test (Hairer & Wanner, Solving Ordinary
//! Differential Equations II, §IV.2, the test of their DOPRI5 and DOP853
//! codes), on the (Δ, θ̇) the methods integrate.
//!
//! A step's result y₁ and its last stage point at the step's end, Y_s (the
//! stage at c = 1 before f(y₁)), are two approximations of the same point
//! that differ by about the local error. Where a fast, damped mode holds
//! the steps, that error lies along the mode, so
//!     ρ̂ = ‖f(y₁) − f(Y_s)‖ / ‖y₁ − Y_s‖
//! estimates its rate |λ|, and h·ρ̂ near the method's stability boundary on
//! the negative real axis ([`Method::real_stability_bound`]) says the step
//! is as long as stability lets it be: no tolerance makes it longer, and
//! the error delivered lies below the one asked. `bs3` has no such pair
//! (its only stage at c = 1 is f(y₁)), as in Hairer's codes, and is not
//! tested.
//!
//! The rates' Δ part is θ̇ up to dexp⁻¹, taken about different points at
//! Y_s (Δ from the step's start) and at y₁ (Δ = 0): its difference is
//! taken as the θ̇ part of y₁ − Y_s, which it is on vector coordinates.

use nalgebra::DVector;

use super::adaptive::Stats;
use super::tableau::{Method, Scheme, Tableau};

/// A test counts a step as held by stability from h·ρ̂ at this share of
/// the stability boundary on: the controller keeps such steps at the
/// boundary, shortening one that grew past it after a rejection, so that
/// accepted steps lie around 0.7–1 of it, where accuracy-bound steps of a
/// smooth vehicle lie far below (docs/integration.md, "Stiff vehicles").
pub const STABILITY_SHARE: f64 = 0.5;

/// The fewest tests that judge a communication step (a step cut to a
/// switch goes untested, and so does DOP853's last step of an advance).
const JUDGED_TESTS: usize = 4;

/// Whether a communication step's steps (its `stats`) were held by
/// stability: most of at least [`JUDGED_TESTS`] tested.
pub(super) fn held_by_stability(stats: &Stats) -> bool {
    stats.stiffness_tests >= JUDGED_TESTS && 2 * stats.stability_held > stats.stiffness_tests
}

/// `auto`, on ROS34PW2 for stability, moves back to DOP853 when
/// ROS34PW2's mean step times the vehicle's fastest |λ| lies within this
/// share of DOP853's boundary: half of [`STABILITY_SHARE`], so that a
/// run at the edge does not go back and forth.
pub(super) const RETURN_SHARE: f64 = 0.5 * STABILITY_SHARE;

/// A method the user named whose steps stability held over a
/// communication step: said once per run (an FMU's `logMethodChoice`,
/// `nudyn simulate`'s standard error), not a warning: the steps are
/// right, only dearer than an L-stable method's may be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StabilityHeld {
    /// The method.
    pub method: Method,
    /// The start of the communication step (s).
    pub time: f64,
    /// The tolerance asked.
    pub tolerance: f64,
    /// Steps found held by stability there, of `tests` tested.
    pub held: usize,
    /// Steps tested there.
    pub tests: usize,
}

impl std::fmt::Display for StabilityHeld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let StabilityHeld { method, time, tolerance, held, tests } = *self;
        write!(
            f,
            "{} steps held by stability, not by tolerance {tolerance:e}: in the communication step from t = {time} s, \
             {held} of the {tests} steps tested lie at half its stability boundary or beyond on a fast damped mode, \
             so the error delivered lies below the one asked; ros34pw2 (L-stable) is not held so and may take \
             fewer steps (method auto moves to it)",
            method.name()
        )
    }
}

/// The stiffness test's buffers and counts (part of the integrator).
#[derive(Clone, Debug)]
pub(super) struct StiffnessTest {
    /// y₁ − Y_s of the step last taken: Δ (nv), then θ̇ and act (nv + na).
    delta: DVector<f64>,
    qvel: DVector<f64>,
    /// That step's size, while its f(y₁) (the next attempt's first stage)
    /// is awaited: DOP853 evaluates it only there.
    pending: Option<f64>,
    /// Tests made, and of them the steps found held by stability, ever
    /// (as the integrator's evaluations are counted).
    pub tests: usize,
    pub held: usize,
}

impl StiffnessTest {
    /// Buffers for `nv` velocities and `rates` integrated rates (nv + na).
    pub fn new(nv: usize, rates: usize) -> Self {
        StiffnessTest { delta: DVector::zeros(nv), qvel: DVector::zeros(rates), pending: None, tests: 0, held: 0 }
    }

    /// Forgets a test awaiting f(y₁): the next first stage is not f at the
    /// step's result (the inputs may change at a communication point, the
    /// mode at a switch, θ̇ by a projection, act by its clamp, the method).
    pub fn drop_pending(&mut self) {
        self.pending = None;
    }

    /// After a step of size `h` is taken with `method`, from its stages'
    /// rates: tests it at once where f(y₁) is a stage (first same as
    /// last), or awaits the next attempt's first stage.
    pub fn after_step(&mut self, method: Method, (k_delta, k_qvel): (&[DVector<f64>], &[DVector<f64>]), h: f64) {
        self.pending = None;
        let (Scheme::Explicit(tableau), Some(bound)) = (method.scheme(), method.real_stability_bound()) else {
            return;
        };
        let Some(s) = stage_at_end(tableau) else { return };
        // y₁ − Y_s = h Σ (bⱼ − a_sⱼ) kⱼ.
        self.delta.fill(0.0);
        self.qvel.fill(0.0);
        for (j, b) in tableau.b.iter().enumerate() {
            let w = h * (b - tableau.a[s].get(j).copied().unwrap_or(0.0));
            if w != 0.0 {
                self.delta.axpy(w, &k_delta[j], 1.0);
                self.qvel.axpy(w, &k_qvel[j], 1.0);
            }
        }
        if tableau.first_same_as_last {
            let last = tableau.b.len() - 1;
            self.record(h, bound, &k_qvel[last], &k_qvel[s]);
        } else {
            self.pending = Some(h);
        }
    }

    /// At an attempt's first stage (`k_qvel[0]`, f where the last step
    /// ended), the test that awaited it; `k_qvel` still holds that step's
    /// stage at its end.
    pub fn at_first_stage(&mut self, method: Method, k_qvel: &[DVector<f64>]) {
        let Some(h) = self.pending.take() else { return };
        if let (Scheme::Explicit(tableau), Some(bound)) = (method.scheme(), method.real_stability_bound())
            && let Some(s) = stage_at_end(tableau)
        {
            self.record(h, bound, &k_qvel[0], &k_qvel[s]);
        }
    }

    /// Counts a test with rates `at_result` (f(y₁)) and `at_stage` (f(Y_s)).
    fn record(&mut self, h: f64, bound: f64, at_result: &DVector<f64>, at_stage: &DVector<f64>) {
        let nv = self.delta.len();
        let distance = self.delta.norm_squared() + self.qvel.norm_squared();
        let change = self.qvel.as_slice()[..nv].iter().map(|x| x * x).sum::<f64>()
            + at_result.iter().zip(at_stage.iter()).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
        if !(distance > 0.0 && change.is_finite()) {
            return;
        }
        self.tests += 1;
        if h * (change / distance).sqrt() >= STABILITY_SHARE * bound {
            self.held += 1;
        }
    }
}

/// The last stage at the step's end (c = 1) other than f(y₁), if any.
fn stage_at_end(tableau: &Tableau) -> Option<usize> {
    let stages = tableau.b.len() - usize::from(tableau.first_same_as_last);
    (1..stages).rev().find(|&i| tableau.c[i] == 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stages_at_the_end_are_hairers() {
        let stage = |method: Method| match method.scheme() {
            Scheme::Explicit(tableau) => stage_at_end(tableau),
            Scheme::Rosenbrock(_) => None,
        };
        // DOPRI5 and Tsit5: stage 6 against the 7th, f(y₁); DOP853: stage 12 against f(y₁).
        assert_eq!(stage(Method::Dopri5), Some(5));
        assert_eq!(stage(Method::Tsit5), Some(5));
        assert_eq!(stage(Method::Dop853), Some(11));
        assert_eq!(stage(Method::Bs3), None);
    }

    /// On y' = λy (one hinge's θ̈ = λθ̇ is the same test in θ̇), the ratio
    /// is |λ| exactly, whatever the step.
    #[test]
    fn the_ratio_is_the_rate_of_a_linear_damped_mode() {
        for method in [Method::Dopri5, Method::Tsit5, Method::Dop853] {
            let Scheme::Explicit(tableau) = method.scheme() else { unreachable!() };
            let lambda = -480.0;
            let bound = method.real_stability_bound().unwrap();
            for (h, held) in [(0.9 * bound / 480.0, true), (0.1 * bound / 480.0, false)] {
                // Stages of y' = λy from y = 1 (a velocity whose position does not matter).
                let stages = tableau.b.len();
                let (k_delta, mut k_qvel) = (vec![DVector::zeros(0); 16], vec![DVector::zeros(1); 16]);
                for i in 0..stages {
                    let y = 1.0 + h * (0..i).map(|j| tableau.a[i][j] * k_qvel[j][0]).sum::<f64>();
                    k_qvel[i][0] = lambda * y;
                }
                let mut test = StiffnessTest::new(0, 1);
                test.after_step(method, (&k_delta, &k_qvel), h);
                if !tableau.first_same_as_last {
                    let y1 = 1.0 + h * (0..stages).map(|j| tableau.b[j] * k_qvel[j][0]).sum::<f64>();
                    k_qvel[0][0] = lambda * y1;
                    test.at_first_stage(method, &k_qvel);
                }
                assert_eq!((test.tests, test.held), (1, usize::from(held)), "{method:?} at h·|λ| = {}", h * 480.0);
            }
        }
    }
}
