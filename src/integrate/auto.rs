//! `auto`: the run chooses its method, once, before its first step, from
//! the tolerance and how fast the vehicle moves for its communication step
//! (docs/integration.md, "The cost of each method per tolerance").
//!
//! The measure is one DOP853 step over the whole first interval from the
//! start, attempted and not taken: its error estimate per second, relative
//! to 1 + |x| (the tolerance's own scale), is E. DOP853 stays at one step
//! per communication step at tolerance τ exactly when its controller's
//! next step is not shorter, E ≤ SAFETY⁷·τ (adaptive.rs). The benchmark's
//! rule, in those terms:
//! - fast (more than one DOP853 step per interval even at 1e-4): `dop853`;
//! - slow (one DOP853 step per interval even at 1e-10): `bs3` at loose
//!   tolerances (around 1e-4), `tsit5` down to about 1e-9, `dop853` below;
//! - in between: `tsit5` down to about 1e-6, `dop853` below.
//!
//! The tolerance bounds lie halfway (in log) between the tolerances the
//! benchmark measured.
//!
//! The start can mislead: a motion that speeds up later (a long chain whose
//! swing grows) looks slower than it is. So a run that chose `bs3` or
//! `tsit5` moves up one order (to `tsit5`, then `dop853`) when its
//! attempted steps over the last [`MOVE_UP_WINDOW`] communication steps
//! cost more than one step of the next method in each of them: more than
//! two attempts per communication step on average (a step of `bs3` costs
//! 3 evaluations, of `tsit5` 6, of `dop853` 12). A lone communication step
//! of three attempts (one full-interval step rejected, then two) is the
//! controller probing the edge of one step per interval, and a few
//! communication steps of two or three a passing phase, not a faster
//! motion: a move is for the rest of the run, and judged on one or three
//! communication steps it took bus_arm7 at 1e-7 to `dop853` for its last
//! 2 s (758 evaluations, where `tsit5` throughout takes 632). The first
//! communication step is not judged: its first step is the starting
//! step's guess. The window grows from the second, judged alone (a start
//! that misled is caught at once), and starts afresh after a move.
//!
//! The rule above is for steps that end at every communication point, as
//! they do while the host changes the input at each (a closed loop). Once
//! the input stays as it was at the last point (an open-loop run, a slowly
//! sampled controller), steps may reach past the points and the state there
//! comes from the dense output (reach.rs). A run on BS3 then moves to
//! TSIT5, and a run on either to DOP853 below a tolerance that depends on
//! the pace ([`held_input_move`]): with steps no longer cut at each point,
//! the higher order pays at tighter tolerances than when they were, while
//! a step's stages count for more where a few steps span many points
//! (docs/integration.md, "When the input is held").
//!
//! A vehicle whose explicit steps stability holds (a fast, strongly damped
//! mode: stiffness.rs) moves to ROS34PW2 after a communication step in
//! which most of its tested steps were so held, and back to DOP853 when
//! ROS34PW2's steps lie well within DOP853's stability (simulation.rs,
//! `move_if_due`).

use super::tableau::{Method, Scheme};

/// How a run's method is set: named by the user (never overridden), or
/// chosen by the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodSetting {
    /// This method.
    Fixed(Method),
    /// The cheapest for the tolerance and the vehicle, chosen at the first advance.
    Auto,
}

impl MethodSetting {
    /// Every setting, in the order of the FMU's enumeration (values 1 to 7):
    /// `auto` comes after the methods, so that no value is renumbered.
    pub const ALL: [MethodSetting; 7] = [
        MethodSetting::Fixed(Method::Rk4),
        MethodSetting::Fixed(Method::Dopri5),
        MethodSetting::Fixed(Method::Dop853),
        MethodSetting::Fixed(Method::Ros34pw2),
        MethodSetting::Fixed(Method::Bs3),
        MethodSetting::Fixed(Method::Tsit5),
        MethodSetting::Auto,
    ];

    /// Its name, as in the FMU's enumeration and the CLI.
    pub fn name(self) -> &'static str {
        match self {
            MethodSetting::Fixed(method) => method.name(),
            MethodSetting::Auto => "auto",
        }
    }

    /// One line for people.
    pub fn description(self) -> &'static str {
        match self {
            MethodSetting::Fixed(method) => method.description(),
            MethodSetting::Auto => {
                "the cheapest of bs3, tsit5 and dop853 for the tolerance and for how fast the vehicle moves over \
                 the first communication step, one order up when later motion asks, tsit5 or dop853 once the input is \
                 held (steps past the communication points), and ros34pw2 while stability holds the explicit steps; each \
                 choice logged"
            }
        }
    }

    /// The setting of a name.
    pub fn from_name(name: &str) -> Option<MethodSetting> {
        MethodSetting::ALL.into_iter().find(|m| m.name() == name)
    }
}

/// Written by name, as `"auto"` or `"dop853"` (the FMU's resource file).
impl serde::Serialize for MethodSetting {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for MethodSetting {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        MethodSetting::from_name(&name).ok_or_else(|| {
            let names: Vec<&str> = MethodSetting::ALL.iter().map(|m| m.name()).collect();
            serde::de::Error::custom(format!("unknown method '{name}' (known: {})", names.join(", ")))
        })
    }
}

impl From<Method> for MethodSetting {
    fn from(method: Method) -> Self {
        MethodSetting::Fixed(method)
    }
}

/// The method `auto` measures the vehicle with, and runs until it has chosen.
pub const PROBE_METHOD: Method = Method::Dop853;

/// How fast the vehicle moves for its communication step, as DOP853 sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pace {
    /// DOP853 needs more than one step per communication step at 1e-4.
    Fast,
    /// DOP853 needs one step per communication step at 1e-4, more at 1e-10.
    Between,
    /// DOP853 needs one step per communication step at 1e-10.
    Slow,
}

/// The tolerances that bound the pace classes (the loosest and tightest
/// the rule was measured at).
const LOOSE: f64 = 1e-4;
const TIGHT: f64 = 1e-10;

/// DOP853's error per second E over one step of the interval stays within
/// τ·this exactly when its controller (safety 0.9, exponent 1/7) proposes
/// no shorter step next: the condition for one step per interval.
const ONE_STEP_SHARE: f64 = 0.478_296_9; // 0.9⁷

impl Pace {
    /// The pace of a vehicle whose probe step erred by `error_per_second`.
    pub fn of(error_per_second: f64) -> Pace {
        // A non-finite probe (a start too fast for the interval) is fast.
        if error_per_second.is_nan() || error_per_second > LOOSE * ONE_STEP_SHARE {
            Pace::Fast
        } else if error_per_second <= TIGHT * ONE_STEP_SHARE {
            Pace::Slow
        } else {
            Pace::Between
        }
    }

    /// The cheapest method at `tolerance` for a vehicle of this pace.
    pub fn method(self, tolerance: f64) -> Method {
        // Halfway in log between the measured tolerances 1e-4 and 1e-5, 1e-6 and 1e-7, 1e-9 and 1e-10.
        match self {
            Pace::Fast => Method::Dop853,
            Pace::Slow if tolerance >= 10f64.powf(-4.5) => Method::Bs3,
            Pace::Slow if tolerance >= 10f64.powf(-9.5) => Method::Tsit5,
            Pace::Between if tolerance >= 10f64.powf(-6.5) => Method::Tsit5,
            Pace::Slow | Pace::Between => Method::Dop853,
        }
    }

    /// How the log says it.
    fn words(self) -> &'static str {
        match self {
            Pace::Fast => {
                "fast for the communication step (DOP853 needs more than one step per communication step at 1e-4)"
            }
            Pace::Between => "between (DOP853 needs one step per communication step at 1e-4 and more at 1e-10)",
            Pace::Slow => "slow for the communication step (DOP853 needs one step per communication step at 1e-10)",
        }
    }
}

/// Communication steps over which `auto` weighs a run's attempted steps
/// (this one and the ones before it, back to the run's second or its last move).
pub const MOVE_UP_WINDOW: usize = 5;

/// Whether a run with `method` moves up after communication steps that
/// attempted `attempts` steps each (the window, judged ones only): when
/// their evaluations exceed one step of the next method per communication step.
pub fn moves_up(method: Method, attempts: &[usize]) -> Option<Method> {
    let to = order_up(method)?;
    let total: usize = attempts.iter().sum();
    (total * evaluations_per_step(method) > attempts.len() * evaluations_per_step(to)).then_some(to)
}

/// θ̈ evaluations of one step of an explicit method (its last stage reused
/// as the next step's first where it is "first same as last").
fn evaluations_per_step(method: Method) -> usize {
    match method.scheme() {
        Scheme::Explicit(t) => t.b.len() - usize::from(t.first_same_as_last),
        Scheme::Rosenbrock(_) => unreachable!("auto chooses explicit methods"),
    }
}

/// The method `auto` moves a run on `method` to once the input is held
/// (steps may then reach past the points), at `tolerance`, for a vehicle
/// of `pace`, if any: `bs3` to `tsit5`, and either to `dop853` below the
/// tolerance down to which `tsit5`, with steps reaching past the points,
/// took the fewest evaluations and the least time to the accuracy it
/// delivered: 1e-5 on the slow vehicles (bus_arm7 and the slow station; at
/// 1e-6 it took fewer evaluations but delivered 3.2 times the tolerance on
/// bus_arm7, which MuJoCo's RK4 reaches at twice the step), 1e-4 on the
/// others (the random trees), where with steps ending at the points it
/// keeps to 1e-9 and 1e-6 ([`Pace::method`]) (docs/integration.md, "When
/// the input is held"). `bs3` never took the fewest. The bounds lie halfway
/// in log between the tolerances measured.
pub fn held_input_move(method: Method, tolerance: f64, pace: Pace) -> Option<Method> {
    let tsit5_down_to = match pace {
        Pace::Slow => 10f64.powf(-5.5),
        Pace::Between | Pace::Fast => 10f64.powf(-4.5),
    };
    let tight = tolerance < tsit5_down_to;
    match method {
        Method::Bs3 if tight => Some(Method::Dop853),
        Method::Bs3 => Some(Method::Tsit5),
        Method::Tsit5 if tight => Some(Method::Dop853),
        _ => None,
    }
}

/// The method one order up that `auto` moves to from `method`, if any.
pub fn order_up(method: Method) -> Option<Method> {
    match method {
        Method::Bs3 => Some(Method::Tsit5),
        Method::Tsit5 => Some(Method::Dop853),
        _ => None,
    }
}

/// `auto` moving a run to another method (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoMove {
    /// The method it ran with.
    pub from: Method,
    /// The method it runs with from now on.
    pub to: Method,
    /// The start of the communication step that asked for it (s).
    pub time: f64,
    /// Why.
    pub why: MoveReason,
}

/// Why `auto` moved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MoveReason {
    /// Up one order: the window's steps cost more than the next method's.
    Cost {
        /// The steps attempted in the window's communication steps, oldest
        /// first; the last `judged` of them were judged (the others are 0).
        attempts: [usize; MOVE_UP_WINDOW],
        /// How many communication steps the window held.
        judged: usize,
    },
    /// To ROS34PW2: most of the communication step's explicit steps were
    /// held by stability (stiffness.rs).
    Stability {
        /// Steps found held by stability.
        held: usize,
        /// Steps tested.
        tests: usize,
    },
    /// To DOP853: the host holds the input, so steps may reach past the
    /// communication points, where DOP853 takes the fewest evaluations.
    HeldInput,
    /// Back to DOP853: ROS34PW2's steps lie well within DOP853's stability
    /// boundary on the vehicle's fastest mode, where DOP853's order pays.
    Accuracy {
        /// ROS34PW2's mean step over the communication step (s).
        step: f64,
        /// The largest |λ| of its W (/s).
        rate: f64,
    },
}

impl std::fmt::Display for AutoMove {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let AutoMove { from, to, time, why } = *self;
        let (from, to) = (from.name(), to.name());
        match why {
            MoveReason::HeldInput => write!(f, "method auto moved from {from} to {to} at t = {time} s: ")?,
            _ => write!(f, "method auto moved from {from} to {to} after the communication step from t = {time} s: ")?,
        }
        match why {
            MoveReason::Cost { attempts, judged } => write!(
                f,
                "{from} attempted {:?} steps in the last {judged} communication steps, costing more than one step \
                 of {to} in each",
                &attempts[MOVE_UP_WINDOW - judged..],
            ),
            MoveReason::Stability { held, tests } => write!(
                f,
                "{held} of the {tests} steps {from} took there were held by its stability on a fast damped mode, not \
                 by the tolerance, and {to} (L-stable) is not held so"
            ),
            MoveReason::HeldInput => write!(
                f,
                "the input has stayed as it was at the last communication point, so the steps may reach past the \
                 communication points (the state there from the dense output), where {to}'s order takes the fewest \
                 evaluations"
            ),
            MoveReason::Accuracy { step, rate } => write!(
                f,
                "{from}'s steps ({step:.1e} s on average) are short for the vehicle's fastest mode (|λ| ≈ {rate:.1e} /s), \
                 well within {to}'s stability, where its higher order takes fewer evaluations"
            ),
        }
    }
}

/// What `auto` measured and chose: part of the run's state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoChoice {
    /// The method chosen, or moved up to since.
    pub method: Method,
    /// The probe's step (s): the first interval, or `max_step` if shorter.
    pub probe_step: f64,
    /// DOP853's error estimate per second over that step, relative to 1 + |x|.
    pub error_per_second: f64,
    /// The tolerance it was chosen for.
    pub tolerance: f64,
    /// Steps attempted in the judged communication steps before the last
    /// one, since the second or the last move, newest last (0: none).
    pub earlier_attempts: [usize; MOVE_UP_WINDOW - 1],
}

impl AutoChoice {
    /// The choice for a probe step of `probe_step` that erred by `error_per_second`, at `tolerance`.
    pub fn new(probe_step: f64, error_per_second: f64, tolerance: f64) -> Self {
        let method = Pace::of(error_per_second).method(tolerance);
        AutoChoice { method, probe_step, error_per_second, tolerance, earlier_attempts: [0; MOVE_UP_WINDOW - 1] }
    }

    /// Judges a communication step from `time` that attempted `attempts`
    /// steps: moves up one order (and starts the window afresh) when the
    /// window asks for it, else remembers the count. An advance of no
    /// length attempts nothing and is not judged: a count of 0 in the window
    /// means "not judged", which keeps the judged counts the last ones.
    pub fn judge(&mut self, time: f64, attempts: usize) -> Option<AutoMove> {
        if attempts == 0 {
            return None;
        }
        // Counts enter at the back, so the ones held are the last nonzero ones.
        let mut window = [0; MOVE_UP_WINDOW];
        window[..MOVE_UP_WINDOW - 1].copy_from_slice(&self.earlier_attempts);
        window[MOVE_UP_WINDOW - 1] = attempts;
        let judged = 1 + self.earlier_attempts.iter().filter(|&&n| n > 0).count();
        match moves_up(self.method, &window[MOVE_UP_WINDOW - judged..]) {
            Some(to) => Some(self.move_to(to, time, MoveReason::Cost { attempts: window, judged })),
            None => {
                self.earlier_attempts.rotate_left(1);
                self.earlier_attempts[MOVE_UP_WINDOW - 2] = attempts;
                None
            }
        }
    }

    /// Moves to `to` after the communication step from `time`, for `why`,
    /// and starts the window afresh.
    pub fn move_to(&mut self, to: Method, time: f64, why: MoveReason) -> AutoMove {
        let moved = AutoMove { from: self.method, to, time, why };
        self.method = to;
        self.earlier_attempts = [0; MOVE_UP_WINDOW - 1];
        moved
    }

    /// The vehicle's pace as measured.
    pub fn pace(&self) -> Pace {
        Pace::of(self.error_per_second)
    }
}

impl std::fmt::Display for AutoChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let AutoChoice { method, probe_step, error_per_second, tolerance, .. } = *self;
        write!(
            f,
            "method auto chose {} for tolerance {tolerance:e}: one DOP853 step of {probe_step} s from the start errs by \
             {error_per_second:.1e} per second, so the motion is {}",
            method.name(),
            self.pace().words()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rule as measured on the examples (docs/integration.md).
    #[test]
    fn the_rule_by_pace_and_tolerance() {
        let tolerances = [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10];
        let picks = |pace: Pace| tolerances.map(|tol| pace.method(tol));
        use Method::{Bs3, Dop853, Tsit5};
        assert_eq!(picks(Pace::Fast), [Dop853; 7]);
        assert_eq!(picks(Pace::Slow), [Bs3, Tsit5, Tsit5, Tsit5, Tsit5, Tsit5, Dop853]);
        assert_eq!(picks(Pace::Between), [Tsit5, Tsit5, Tsit5, Dop853, Dop853, Dop853, Dop853]);
    }

    /// One DOP853 step per interval at τ exactly when 0.9·(τ/E)^(1/7) ≥ 1.
    #[test]
    fn pace_bounds_are_the_one_step_condition() {
        assert!((ONE_STEP_SHARE - 0.9f64.powi(7)).abs() < 1e-7);
        assert_eq!(Pace::of(0.47e-4), Pace::Between);
        assert_eq!(Pace::of(0.49e-4), Pace::Fast);
        assert_eq!(Pace::of(0.47e-10), Pace::Slow);
        assert_eq!(Pace::of(0.49e-10), Pace::Between);
        assert_eq!(Pace::of(f64::NAN), Pace::Fast);
        assert_eq!(Pace::of(f64::INFINITY), Pace::Fast);
    }

    #[test]
    fn moves_up_one_order_to_dop853() {
        assert_eq!(order_up(Method::Bs3), Some(Method::Tsit5));
        assert_eq!(order_up(Method::Tsit5), Some(Method::Dop853));
        assert_eq!(order_up(Method::Dop853), None);
        // Each step of the next method costs twice one of the method before.
        assert_eq!([Method::Bs3, Method::Tsit5, Method::Dop853].map(evaluations_per_step), [3, 6, 12]);
        for (from, to) in [(Method::Bs3, Method::Tsit5), (Method::Tsit5, Method::Dop853)] {
            assert_eq!(moves_up(from, &[3]), Some(to), "three attempts judged alone");
            assert_eq!(moves_up(from, &[2]), None);
            assert_eq!(moves_up(from, &[1, 1, 3]), None, "one probe of the edge among single steps");
            assert_eq!(moves_up(from, &[1, 3, 3]), Some(to));
            assert_eq!(moves_up(from, &[3, 1, 3]), Some(to), "7 attempts in 3 communication steps");
            assert_eq!(moves_up(from, &[2, 2, 2]), None, "as dear as one step of the next");
        }
        assert_eq!(moves_up(Method::Dop853, &[9, 9, 9]), None);
    }

    /// The window as the FMU carries it from one communication step to the next.
    #[test]
    fn judging_keeps_a_window_and_restarts_it_after_a_move() {
        let mut choice = AutoChoice::new(0.1, 1e-12, 1e-7);
        assert_eq!(choice.method, Method::Tsit5);
        for (k, attempts) in [1, 1, 3, 2, 2].into_iter().enumerate() {
            assert_eq!(choice.judge(0.1 * (k + 1) as f64, attempts), None, "9 attempts in 5 communication steps");
        }
        assert_eq!(choice.earlier_attempts, [1, 3, 2, 2]);
        assert_eq!(choice.judge(0.5, 0), None);
        assert_eq!(choice.earlier_attempts, [1, 3, 2, 2], "an advance of no length is not judged");
        let moved = choice.judge(0.6, 4).expect("3, 2, 2, 4 after a 1: 12 attempts in 5");
        assert_eq!(
            (moved.from, moved.to, moved.why),
            (Method::Tsit5, Method::Dop853, MoveReason::Cost { attempts: [1, 3, 2, 2, 4], judged: 5 })
        );
        assert_eq!(choice.method, Method::Dop853);
        assert_eq!(choice.earlier_attempts, [0; MOVE_UP_WINDOW - 1]);
        assert!(
            moved.to_string().contains("attempted [1, 3, 2, 2, 4] steps in the last 5 communication steps"),
            "{moved}"
        );
        let mut fresh = AutoChoice::new(0.1, 1e-12, 1e-4);
        assert_eq!(fresh.method, Method::Bs3);
        assert_eq!(fresh.judge(0.1, 2), None);
        let moved = fresh.judge(0.2, 5).expect("7 attempts in 2 communication steps");
        assert_eq!(moved.why, MoveReason::Cost { attempts: [0, 0, 0, 2, 5], judged: 2 });
        assert_eq!(fresh.judge(0.3, 3).map(|m| m.to), Some(Method::Dop853), "the window restarted at the move");
    }

    #[test]
    fn names_round_trip() {
        for setting in MethodSetting::ALL {
            assert_eq!(MethodSetting::from_name(setting.name()), Some(setting));
        }
        assert_eq!(MethodSetting::from_name("fastest"), None);
    }
}
