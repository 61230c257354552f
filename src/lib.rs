//! nudyn: the diagonalized ν-dynamics of robotic space vehicles
//! (ν̇ + C(θ, ν) = ε, M(θ) = m m*), computed in O(N) with spatial operator
//! algebra, in MuJoCo's generalized coordinates.
//!
//! The pieces, in the order data flows through them:
//! - [`vehicle`]: a vehicle as its MJCF file describes it;
//! - [`model`]: the immutable compiled model (serializable; the FMU's resource);
//! - [`workspace`]: per-instance preallocated buffers, filled by the passes;
//! - [`dynamics`]: the O(N) passes and the operators built from them;
//! - [`control`]: the paper's noninteracting controllers, and their FMU.
#![warn(missing_docs)]

pub mod math;
pub mod mjcf;
pub mod vehicle;
pub mod dynamics;
pub mod control;
pub mod describe;
pub mod eval;
pub mod export;
pub mod integrate;
pub mod model;
pub mod workspace;
