//! Time integration of (θ, θ̇), read and set as (θ, ν): Runge–Kutta–Munthe-Kaas steps (`rkmk`) with
//! the methods of `tableau`, explicit or Rosenbrock (`rosenbrock`), driven over an interval with fixed or adaptive
//! steps (`adaptive`) by one [`Simulation`] (`simulation`), with a method named or chosen by the run (`auto`).

mod adaptive;
mod auto;
mod decay;
mod reach;
mod rkmk;
mod rosenbrock;
mod simulation;
mod stiffness;
mod switches;
mod tableau;

pub use adaptive::{
    AdvanceError, Carry, DEFAULT_FIXED_STEP, IntervalTooLong, MAX_STEPS, Overflow, Settings, Stats, ToleranceRelaxed,
};
pub use auto::{
    AutoChoice, AutoMove, MOVE_UP_WINDOW, MethodSetting, MoveReason, PROBE_METHOD, Pace, moves_up, order_up,
};
pub use reach::Reach;
pub use rkmk::{Integrator, retract};
pub use rosenbrock::{HeldJacobian, JacobianSource, W_MAX_AGE};
pub use simulation::{Advanced, Input, InputSignal, RunState, Simulation};
pub use stiffness::{STABILITY_SHARE, StabilityHeld};
pub use tableau::{
    DENSE_ROWS, DOP853, DOPRI5, DenseOutput, ErrorEstimate, ErrorPer, Method, RK4, ROS34PW2, ROS34PW2_SHARE,
    ROSENBROCK_STAGES, Rosenbrock, RosenbrockStages, Scheme, StepControl, Tableau,
};
