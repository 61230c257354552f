//! The log categories every nudyn FMU declares. The modelDescription lists
//! [`LogCategory::ALL`] with their names and descriptions, and the FMU logs
//! and filters by the same values, so a category cannot be declared and
//! not served, or served and not declared.

/// One log category.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogCategory {
    /// Why a step was discarded (fmi2Discard).
    Discard,
    /// Why a call was refused or failed (fmi2Error).
    Error,
    /// Unrecoverable failures (fmi2Fatal).
    Fatal,
    /// Every call and its status: debug output, off unless loggingOn.
    Calls,
    /// A call that completed with fmi2Warning.
    Warning,
    /// The method `auto` chose, and why.
    MethodChoice,
    /// Each doStep's integration statistics as one JSON object, for
    /// programs: off unless loggingOn, like [`LogCategory::Calls`].
    StepStatistics,
}

impl LogCategory {
    /// Every category, in the order of the modelDescription's `<LogCategories>`.
    pub const ALL: [LogCategory; 7] = [
        LogCategory::Discard,
        LogCategory::Error,
        LogCategory::Fatal,
        LogCategory::Calls,
        LogCategory::Warning,
        LogCategory::MethodChoice,
        LogCategory::StepStatistics,
    ];

    /// The category's name, as in the modelDescription and fmi2SetDebugLogging.
    pub fn name(self) -> &'static str {
        match self {
            LogCategory::Discard => "logStatusDiscard",
            LogCategory::Error => "logStatusError",
            LogCategory::Fatal => "logStatusFatal",
            LogCategory::Calls => "logCalls",
            LogCategory::Warning => "logStatusWarning",
            LogCategory::MethodChoice => "logMethodChoice",
            LogCategory::StepStatistics => "logStepStatistics",
        }
    }

    /// What the category holds.
    pub fn description(self) -> &'static str {
        match self {
            LogCategory::Discard => "why a step was discarded",
            LogCategory::Error => "why a call was refused or failed",
            LogCategory::Fatal => "unrecoverable failures",
            LogCategory::Calls => "every call and its status (debug)",
            LogCategory::Warning => "a step that completed at a tolerance too loose to meet the one asked",
            LogCategory::MethodChoice => {
                "how the FMU integrates: the method that method = auto chose, and why, a tolerance the host set in \
                 place of the FMU's own, and a tolerance held within 20 times the one asked where round-off in the \
                 rates puts it out of reach"
            }
            LogCategory::StepStatistics => {
                "each doStep's internal steps as JSON: {\"accepted\", \"rejected\", \"jacobians\", \"evaluations\", \"locating\"} (debug)"
            }
        }
    }

    /// The category of `name`, if it is one.
    pub fn from_name(name: &str) -> Option<LogCategory> {
        LogCategory::ALL.into_iter().find(|c| c.name() == name)
    }

    /// Its position in [`LogCategory::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Whether the category is on when an instance starts: every status
    /// category and the method choice, and the debug categories only with loggingOn.
    pub fn on_at_start(self, logging_on: bool) -> bool {
        !matches!(self, LogCategory::Calls | LogCategory::StepStatistics) || logging_on
    }

    /// "logStatusDiscard, logStatusError, ...": the known names, for messages.
    pub fn known_names() -> String {
        LogCategory::ALL.map(LogCategory::name).join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_positions_round_trip() {
        for (k, category) in LogCategory::ALL.into_iter().enumerate() {
            assert_eq!(category.index(), k);
            assert_eq!(LogCategory::from_name(category.name()), Some(category));
        }
        assert_eq!(LogCategory::from_name("logAll"), None);
        assert!(LogCategory::known_names().contains("logStatusWarning"));
    }
}
