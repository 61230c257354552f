//! Time integration of (θ, θ̇), read and set as (θ, ν): Runge–Kutta–Munthe-Kaas steps (`rkmk`) with
//! the methods of `tableau`, driven over an interval with fixed or adaptive
//! steps (`adaptive`) by one [`Simulation`] (`simulation`).

mod adaptive;
mod rkmk;
mod simulation;
mod tableau;

pub use adaptive::{
    AdvanceError, Carry, DEFAULT_FIXED_STEP, IntervalTooLong, MAX_STEPS, Overflow, Settings, Stats, ToleranceRelaxed,
};
pub use rkmk::{Integrator, retract};
pub use simulation::{Advanced, Input, InputSignal, RunState, Simulation};
pub use tableau::{DOP853, DOPRI5, ErrorEstimate, Method, RK4, Tableau};
