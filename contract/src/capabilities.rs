//! The capability flags of each kind of nudyn FMU: the exporter writes them
//! into `<CoSimulation>` and `<ModelExchange>`, and the FMU refuses what
//! they deny from the same value.

/// What an FMU can do, beyond the calls every FMU serves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capabilities {
    /// canInterpolateInputs: fmi2SetRealInputDerivatives is served.
    pub can_interpolate_inputs: bool,
    /// maxOutputDerivativeOrder: fmi2GetRealOutputDerivatives serves orders up to this.
    pub max_output_derivative_order: u32,
    /// canGetAndSetFMUstate.
    pub can_get_and_set_fmu_state: bool,
    /// canSerializeFMUstate.
    pub can_serialize_fmu_state: bool,
    /// providesDirectionalDerivative (FMI 3.0: providesDirectionalDerivatives
    /// and providesAdjointDerivatives).
    pub provides_directional_derivative: bool,
    /// canHandleVariableCommunicationStepSize.
    pub can_handle_variable_communication_step_size: bool,
    /// Whether the FMU also serves model exchange (a `<ModelExchange>` element).
    pub model_exchange: bool,
}
