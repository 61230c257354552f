//! What kind of variable each FMU variable is. The exporter writes these
//! values into the modelDescription (causality, variability, initial, min)
//! and the FMU refuses a set from the same values, so what an importer
//! reads and what the FMU enforces are one thing.

/// FMI's causality, of the values nudyn uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    /// A parameter: set by the user, not by connections.
    Parameter,
    /// An input, set by the master from other FMUs' outputs.
    Input,
    /// An output.
    Output,
    /// Neither input nor output: a state derivative of model exchange.
    Local,
}

/// FMI's variability, of the values nudyn uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    /// Set before initialization, then constant.
    Fixed,
    /// May change between steps.
    Tunable,
    /// Changes continuously in time.
    Continuous,
}

/// The values a variable accepts, beyond being finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Range {
    /// Any finite value.
    Any,
    /// Greater than zero.
    Positive,
    /// Zero or more (written as min="0").
    NonNegative,
}

/// The nature of one variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Kind {
    /// Causality.
    pub causality: Causality,
    /// Variability.
    pub variability: Variability,
    /// An output with initial="exact": the master chooses its value before
    /// initialization (the plant's θ and ν, its initial state).
    pub exact_start: bool,
    /// The values it accepts.
    pub range: Range,
    /// A model-exchange event indicator: FMI 3.0's `<ModelStructure>`
    /// lists it as an `<EventIndicator>`.
    pub event_indicator: bool,
}

impl Kind {
    /// A parameter constant after initialization.
    pub const fn fixed_parameter(range: Range) -> Kind {
        Kind {
            causality: Causality::Parameter,
            variability: Variability::Fixed,
            exact_start: true,
            range,
            event_indicator: false,
        }
    }

    /// A parameter that may change between steps.
    pub const fn tunable_parameter(range: Range) -> Kind {
        Kind {
            causality: Causality::Parameter,
            variability: Variability::Tunable,
            exact_start: true,
            range,
            event_indicator: false,
        }
    }

    /// A continuous input.
    pub const INPUT: Kind = Kind {
        causality: Causality::Input,
        variability: Variability::Continuous,
        exact_start: false,
        range: Range::Any,
        event_indicator: false,
    };

    /// A continuous output whose start value the master may choose before initialization.
    pub const STATE_OUTPUT: Kind = Kind {
        causality: Causality::Output,
        variability: Variability::Continuous,
        exact_start: true,
        range: Range::Any,
        event_indicator: false,
    };

    /// A continuous output the FMU calculates.
    pub const CALCULATED_OUTPUT: Kind = Kind {
        causality: Causality::Output,
        variability: Variability::Continuous,
        exact_start: false,
        range: Range::Any,
        event_indicator: false,
    };

    /// The time derivative of a continuous state (model exchange), calculated.
    pub const DERIVATIVE: Kind = Kind {
        causality: Causality::Local,
        variability: Variability::Continuous,
        exact_start: false,
        range: Range::Any,
        event_indicator: false,
    };

    /// An event indicator of model exchange: a local variable the FMU
    /// calculates, whose sign change the host locates.
    pub const EVENT_INDICATOR: Kind = Kind {
        causality: Causality::Local,
        variability: Variability::Continuous,
        exact_start: false,
        range: Range::Any,
        event_indicator: true,
    };

    /// What a local variable is, for messages.
    fn local_what(&self) -> &'static str {
        if self.event_indicator { "an event indicator" } else { "a state derivative" }
    }

    /// Why the variable cannot be set now, if it cannot: "after
    /// initialization" or "at all: it is a calculated output".
    /// `initialized`: after fmi2ExitInitializationMode.
    pub fn refuses_set(&self, initialized: bool) -> Option<&'static str> {
        let fixed_after_start =
            self.variability == Variability::Fixed || (self.causality == Causality::Output && self.exact_start);
        match self.causality {
            Causality::Output if !self.exact_start => Some("at all: it is a calculated output"),
            Causality::Local if self.event_indicator => Some("at all: it is an event indicator, calculated"),
            Causality::Local => Some("at all: it is a state derivative, calculated"),
            _ if fixed_after_start && initialized => Some("after initialization"),
            _ => None,
        }
    }

    /// Whether `value` is in the variable's range (finiteness is checked apart).
    pub fn accepts(&self, value: f64) -> bool {
        match self.range {
            Range::Any => true,
            Range::Positive => value > 0.0,
            Range::NonNegative => value >= 0.0,
        }
    }
}

/// Why a start value chosen before export cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StartError {
    /// No variable has this name.
    #[error("no variable is named {0}")]
    Unknown(String),
    /// The variable has no start value to choose (a calculated output).
    #[error("{name} has no start value: it is {what}")]
    NoStart {
        /// The variable.
        name: String,
        /// What it is.
        what: &'static str,
    },
    /// The value is outside the variable's range.
    #[error("{name} = {value} is refused: it must be {must}")]
    OutOfRange {
        /// The variable.
        name: String,
        /// The value refused.
        value: f64,
        /// What the value must be.
        must: &'static str,
    },
}

/// Checks a start value chosen for the variable `name` of kind `kind`
/// (`has_start`: whether it has a start value at all), as the FMU would
/// check the same value set before initialization.
pub fn check_start(name: &str, kind: Kind, has_start: bool, value: f64) -> Result<(), StartError> {
    if !has_start {
        let what = if kind.causality == Causality::Local { kind.local_what() } else { "a calculated output" };
        return Err(StartError::NoStart { name: name.to_string(), what });
    }
    let must = match kind.range {
        _ if !value.is_finite() => "finite",
        Range::Positive if value <= 0.0 => "positive",
        Range::NonNegative if value < 0.0 => "non-negative",
        _ => return Ok(()),
    };
    Err(StartError::OutOfRange { name: name.to_string(), value, must })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn when_each_kind_may_be_set() {
        let fixed = Kind::fixed_parameter(Range::Positive);
        assert_eq!(fixed.refuses_set(false), None);
        assert_eq!(fixed.refuses_set(true), Some("after initialization"));
        let tunable = Kind::tunable_parameter(Range::NonNegative);
        assert_eq!(tunable.refuses_set(true), None);
        assert_eq!(Kind::INPUT.refuses_set(true), None);
        assert_eq!(Kind::STATE_OUTPUT.refuses_set(false), None);
        assert_eq!(Kind::STATE_OUTPUT.refuses_set(true), Some("after initialization"));
        assert_eq!(Kind::CALCULATED_OUTPUT.refuses_set(false), Some("at all: it is a calculated output"));
        assert!(fixed.accepts(1e-9) && !fixed.accepts(0.0));
        assert!(tunable.accepts(0.0) && !tunable.accepts(-1.0));
        // The FMU calculates the locals: never set, and no start value to choose.
        assert_eq!(Kind::DERIVATIVE.refuses_set(false), Some("at all: it is a state derivative, calculated"));
        assert_eq!(Kind::EVENT_INDICATOR.refuses_set(false), Some("at all: it is an event indicator, calculated"));
        let chosen = check_start("constraint_switch[1]", Kind::EVENT_INDICATOR, false, 0.0).unwrap_err();
        assert_eq!(chosen.to_string(), "constraint_switch[1] has no start value: it is an event indicator");
    }
}
