//! nudyn: the diagonalized ν-dynamics of robotic space vehicles
//! (ν̇ + C(θ, ν) = ε, M(θ) = m m*), computed in O(N) with spatial operator
//! algebra, in MuJoCo's generalized coordinates.
//!
//! The pieces, in the order data flows through them:
//! - [`vehicle`]: a vehicle as its MJCF file describes it;
//! - [`mjcf`]: the MJCF importer;
//! - [`flex`]: flexible bodies' modal data files;
//! - [`model`]: the immutable compiled model (serializable; the FMU's
//!   resource), and [`model::Model::validate`]; `compile`: [`model::Model::compile`],
//!   the model's structure, then one evaluation at qpos0 for its constants;
//! - [`workspace`]: per-instance preallocated buffers, filled by the passes;
//! - [`dynamics`]: the O(N) passes and the operators built from them;
//! - [`integrate`]: Runge–Kutta–Munthe-Kaas steps, error control;
//! - [`control`]: the paper's noninteracting control law;
//! - [`eval`], [`describe`], [`linearize`]: `nudyn eval`'s, `nudyn describe`'s
//!   and `nudyn linearize`'s data.
//!
//! This crate has no FMI, command-line or archive code: the FMI contract is
//! the `nudyn-contract` crate, the FMU binary `nudyn-fmu`, and the `nudyn`
//! command and its exporter `nudyn-cli`.
#![warn(missing_docs)]

mod compile;
pub mod control;
pub mod describe;
pub mod dynamics;
pub mod eval;
pub mod flex;
pub mod integrate;
pub mod linearize;
pub mod math;
pub mod mjcf;
pub mod model;
pub mod vehicle;
pub mod workspace;
