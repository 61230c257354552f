//! FMU states (fmi2GetFMUstate) and their byte format
//! (fmi2SerializeFMUstate): a versioned header naming the FMU, the sizes,
//! the state machine's state, the values as little-endian f64 (with, for a
//! Rosenbrock method that holds one, its W: (nv + na)(2nv + na) more), and an FNV-1a
//! checksum, so that a truncated, corrupted or foreign blob is
//! rejected before anything is restored. A run whose last step reaches
//! past the communication point adds that step (its interpolant, its end,
//! and the input and settings it was taken with). The values are checked too
//! (finite, positive settings), so that even a blob crafted with a valid
//! checksum cannot put a NaN into the outputs.

use nudyn::dynamics::box_qp::Held;
use nudyn::integrate::{
    AutoChoice, Carry, DENSE_ROWS, HeldJacobian, MOVE_UP_WINDOW, MethodSetting, Reach, RunState, Scheme, Settings,
};
use nudyn_contract::plant::{method_of_value, method_value};

use crate::state::Phase;

/// Identifies a nudyn FMU state blob.
const MAGIC: &[u8; 8] = b"nudynFMS";
/// Version of the byte layout below, raised with every change to it; a blob
/// of another version is refused (what each version added is in git's
/// history).
const VERSION: u32 = 14;

/// The values that determine the plant's future: what an FMU state saves.
#[derive(Clone, Debug, PartialEq)]
pub struct PlantState {
    /// Time, θ (nq, qpos), ν (nv) and the integrator's carry.
    pub run: RunState,
    /// Parameters `tolerance`, `max_step` and `energy_projection`.
    pub settings: Settings,
    /// Parameter `method`; what `auto` chose is in `run`.
    pub method: MethodSetting,
    /// Start time of the experiment (s).
    pub start_time: f64,
    /// Stop time, if the master declared one (s).
    pub stop_time: Option<f64>,
    /// K = ½|ν|² at initialization (J), for the energy residual.
    pub initial_energy: f64,
    /// The inputs ε (nv) as set at the current communication point.
    pub eps: Vec<f64>,
    /// dε/dt (nv) from fmi2SetRealInputDerivatives, for the next step only.
    pub eps_rate: Vec<f64>,
    /// The actuators' controls (nu) as set at the current communication point.
    pub ctrl: Vec<f64>,
    /// Their rates (nu), for the next step only.
    pub ctrl_rate: Vec<f64>,
    /// The W a Rosenbrock method holds for its next step: restored with
    /// the rest, the run continues bit for bit.
    pub jacobian: HeldJacobian,
}

/// The sizes of a plant's state: a blob is restored only into a plant of the same.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sizes {
    /// Position coordinates (θ).
    pub nq: usize,
    /// Dofs (ν, ε).
    pub nv: usize,
    /// Actuators (ctrl).
    pub nu: usize,
    /// Activation states (act, after θ̇): the FMU's own, not in the header,
    /// so that the blobs of vehicles without them keep their bytes.
    pub na: usize,
}

impl std::fmt::Display for Sizes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "nq = {}, nv = {}, nu = {}", self.nq, self.nv, self.nu)?;
        if self.na > 0 {
            write!(f, ", na = {}", self.na)?;
        }
        Ok(())
    }
}

/// A saved state of one FMU (its GUID names the FMU it belongs to).
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// The state machine's state when it was saved: fmi2SetFMUstate returns to it.
    pub phase: Phase,
    /// GUID of the FMU that saved it.
    pub guid: String,
    /// The saved values.
    pub state: PlantState,
}

/// Why a blob cannot be deserialized.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SnapshotError {
    /// Shorter than its header says.
    #[error("serialized FMU state is truncated: {found} bytes, expected {expected}")]
    Truncated {
        /// Bytes needed.
        expected: usize,
        /// Bytes given.
        found: usize,
    },
    /// Longer than its header says.
    #[error("serialized FMU state has {found} bytes, expected {expected}")]
    TrailingBytes {
        /// Bytes the header accounts for.
        expected: usize,
        /// Bytes given.
        found: usize,
    },
    /// Not a nudyn FMU state.
    #[error("not a serialized nudyn FMU state (bad magic number)")]
    BadMagic,
    /// Written by another version of the format.
    #[error("serialized FMU state has format version {found}, expected {VERSION}")]
    Version {
        /// The blob's version.
        found: u32,
    },
    /// Saved by another FMU.
    #[error("serialized FMU state belongs to the FMU with GUID '{found}', not '{expected}'")]
    ForeignGuid {
        /// The blob's GUID.
        found: String,
        /// This FMU's GUID.
        expected: String,
    },
    /// Sizes that do not match this FMU.
    #[error("serialized FMU state has {found}, expected {expected}")]
    Sizes {
        /// The blob's.
        found: Sizes,
        /// This FMU's.
        expected: Sizes,
    },
    /// A `method` value that names no method.
    #[error("serialized FMU state names integration method value {0}, which does not exist")]
    UnknownMethod(u8),
    /// A choice of `auto` saved with a method named by the user, or naming a method `auto` never chooses.
    #[error("serialized FMU state holds a choice of method auto (value {chosen}) with method value {method}")]
    ChoiceWithoutAuto {
        /// The `method` value.
        method: u8,
        /// The chosen method's value.
        chosen: u8,
    },
    /// A W saved with a method that holds none.
    #[error("serialized FMU state holds a Jacobian W, which integration method '{0}' does not use")]
    JacobianWithoutRosenbrock(&'static str),
    /// A state machine state that a saved state cannot have.
    #[error("serialized FMU state has state machine state {0}, which is not one a state can be saved in")]
    Phase(u8),
    /// A value that a state of this FMU cannot hold.
    #[error("serialized FMU state has {what} = {value}, which must be {must}")]
    Value {
        /// Which value.
        what: &'static str,
        /// The value.
        value: f64,
        /// What it must be.
        must: &'static str,
    },
    /// The checksum does not match the contents.
    #[error("serialized FMU state is corrupted (checksum {found:#018x}, contents hash to {computed:#018x})")]
    Checksum {
        /// Stored checksum.
        found: u64,
        /// Checksum of the contents.
        computed: u64,
    },
}

/// FNV-1a, 64 bit: a checksum against accidental corruption, not an adversary.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| (hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3))
}

impl Snapshot {
    /// Number of scalars after the header: [`SCALAR_FIELDS`], then the
    /// vectors of [`VECTOR_FIELDS`].
    fn scalar_count(sizes: Sizes) -> usize {
        SCALAR_FIELDS.len() + VECTOR_FIELDS.iter().map(|field| (field.len)(sizes)).sum::<usize>()
    }

    /// The sizes of the saved state.
    fn sizes(&self) -> Sizes {
        let s = &self.state;
        let na = s.run.qvel.len().saturating_sub(s.run.nu.len());
        Sizes { nq: s.run.theta.len(), nv: s.run.nu.len(), nu: s.ctrl.len(), na }
    }

    /// The size of [`Snapshot::serialize`]'s output.
    pub fn serialized_size(&self) -> usize {
        let run = &self.state.run;
        let reach = if run.reach.held { reach_len(self.sizes()) + 1 + run.reach.working_set.len() } else { 0 };
        let scalars = Self::scalar_count(self.sizes()) + CHOICE_SCALARS + self.state.jacobian.derivatives.len() + reach;
        MAGIC.len() + 4 + 4 + self.guid.len() + 3 * 4 + FLAGS + 4 + 8 * scalars + 8
    }

    /// Writes the state into `out`, which must be [`Snapshot::serialized_size`] bytes long.
    pub fn serialize(&self, out: &mut [u8]) {
        let s = &self.state;
        let mut bytes = Vec::with_capacity(self.serialized_size());
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&VERSION.to_le_bytes());
        bytes.extend_from_slice(&(self.guid.len() as u32).to_le_bytes());
        bytes.extend_from_slice(self.guid.as_bytes());
        bytes.extend_from_slice(&(s.run.theta.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&(s.run.nu.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&(s.ctrl.len() as u32).to_le_bytes());
        bytes.push(self.phase.code());
        bytes.push(u8::from(s.stop_time.is_some()));
        bytes.push(method_value(s.method) as u8);
        bytes.push(u8::from(s.settings.energy_projection));
        bytes.push(u8::from(!s.jacobian.derivatives.is_empty()));
        bytes.push(s.run.auto_choice.map_or(0, |choice| method_value(choice.method) as u8));
        bytes.push(u8::from(s.run.reach.held));
        bytes.push(u8::from(s.run.input_constant));
        bytes.extend_from_slice(&s.jacobian.age.to_le_bytes());
        let scalars = SCALAR_FIELDS.map(|field| (field.get)(s));
        let mut choice = [0.0; CHOICE_SCALARS];
        if let Some(c) = s.run.auto_choice {
            choice[..3].copy_from_slice(&[c.probe_step, c.error_per_second, c.tolerance]);
            for (slot, &attempts) in choice[3..].iter_mut().zip(&c.earlier_attempts) {
                *slot = attempts as f64;
            }
        }
        let vectors = VECTOR_FIELDS.iter().flat_map(|field| (field.get)(s));
        let reach = &s.run.reach;
        let reach_values: Vec<f64> =
            if reach.held { reach_values(reach).chain(working_set_values(reach)).collect() } else { Vec::new() };
        for x in scalars.iter().chain(&choice).chain(vectors).chain(&s.jacobian.derivatives).chain(&reach_values) {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
        let checksum = fnv1a(&bytes);
        bytes.extend_from_slice(&checksum.to_le_bytes());
        out.copy_from_slice(&bytes);
    }

    /// Reads a blob written by [`Snapshot::serialize`] for the FMU with
    /// `guid` and `sizes`; checks everything before returning.
    pub fn deserialize(bytes: &[u8], guid: &str, sizes: Sizes) -> Result<Snapshot, SnapshotError> {
        let mut reader = Reader { bytes, at: 0 };
        if reader.take(MAGIC.len())? != MAGIC {
            return Err(SnapshotError::BadMagic);
        }
        let version = reader.u32()?;
        if version != VERSION {
            return Err(SnapshotError::Version { found: version });
        }
        let guid_len = reader.u32()? as usize;
        let found_guid = String::from_utf8_lossy(reader.take(guid_len)?).into_owned();
        if found_guid != guid {
            return Err(SnapshotError::ForeignGuid { found: found_guid, expected: guid.to_string() });
        }
        let (nq, nv, nu) = (reader.u32()? as usize, reader.u32()? as usize, reader.u32()? as usize);
        let found = Sizes { nq, nv, nu, na: sizes.na };
        if found != sizes {
            return Err(SnapshotError::Sizes { found, expected: sizes });
        }
        let nv = sizes.nv;
        let flags = reader.take(FLAGS)?;
        let (phase_code, stop_time_defined, method_value_byte, energy_projection, holds_jacobian, chosen_byte) =
            (flags[0], flags[1] != 0, flags[2], flags[3] != 0, flags[4] != 0, flags[5]);
        let (holds_reach, input_constant) = (flags[6] != 0, flags[7] != 0);
        let jacobian_age = reader.u32()?;
        // ∂(θ̈, act's rate)/∂Δ and ∂(θ̈, act's rate)/∂(θ̇, act).
        let jacobian_len = if holds_jacobian { (nv + sizes.na) * (2 * nv + sizes.na) } else { 0 };
        let reach_len = if holds_reach { reach_len(sizes) } else { 0 };
        let scalars: Vec<f64> = (0..Self::scalar_count(sizes) + CHOICE_SCALARS + jacobian_len + reach_len)
            .map(|_| reader.f64())
            .collect::<Result<_, _>>()?;
        let working_set = if holds_reach { read_working_set(&mut reader)? } else { Vec::new() };
        let contents_len = reader.at;
        let found = u64::from_le_bytes(reader.take(8)?.try_into().expect("8 bytes"));
        if reader.at != bytes.len() {
            return Err(SnapshotError::TrailingBytes { expected: reader.at, found: bytes.len() });
        }
        let computed = fnv1a(&bytes[..contents_len]);
        if found != computed {
            return Err(SnapshotError::Checksum { found, computed });
        }
        // Fatal is never entered, so never saved.
        let phase =
            Phase::from_code(phase_code).filter(|&p| p != Phase::Fatal).ok_or(SnapshotError::Phase(phase_code))?;
        let method =
            method_of_value(i32::from(method_value_byte)).ok_or(SnapshotError::UnknownMethod(method_value_byte))?;
        let chosen = match (method, chosen_byte) {
            (_, 0) => None,
            (MethodSetting::Auto, value) => match method_of_value(i32::from(value)) {
                Some(MethodSetting::Fixed(chosen)) if chosen.is_adaptive() => Some(chosen),
                _ => return Err(SnapshotError::ChoiceWithoutAuto { method: method_value_byte, chosen: value }),
            },
            (MethodSetting::Fixed(_), value) => {
                return Err(SnapshotError::ChoiceWithoutAuto { method: method_value_byte, chosen: value });
            }
        };
        let in_effect = match method {
            MethodSetting::Fixed(method) => Some(method),
            MethodSetting::Auto => chosen,
        };
        if holds_jacobian && !in_effect.is_some_and(|m| matches!(m.scheme(), Scheme::Rosenbrock(_))) {
            return Err(SnapshotError::JacobianWithoutRosenbrock(in_effect.map_or("auto", |m| m.name())));
        }
        let (settings, rest) = scalars.split_at(SCALAR_FIELDS.len());
        let (choice, vectors) = rest.split_at(CHOICE_SCALARS);
        let (vectors, reach) = vectors.split_at(vectors.len() - reach_len);
        check_values(settings, vectors)?;
        if let Some(&value) = choice.iter().find(|x| x.is_nan() || **x < 0.0) {
            return Err(SnapshotError::Value { what: "a value auto measured", value, must: "non-negative" });
        }
        let mut earlier_attempts = [0; MOVE_UP_WINDOW - 1];
        let mut counted = false;
        for (slot, &value) in earlier_attempts.iter_mut().zip(&choice[3..]) {
            if value.fract() != 0.0 || value > u32::MAX as f64 {
                return Err(SnapshotError::Value { what: "a step count auto weighs", value, must: "a whole number" });
            }
            // Counts enter the window at the back, so its "not judged" zeros all come first.
            if counted && value == 0.0 {
                return Err(SnapshotError::Value {
                    what: "a step count auto weighs",
                    value,
                    must: "positive after a count",
                });
            }
            counted |= value > 0.0;
            *slot = value as usize;
        }
        let auto_choice = chosen.map(|method| AutoChoice {
            method,
            probe_step: choice[0],
            error_per_second: choice[1],
            tolerance: choice[2],
            earlier_attempts,
        });
        let mut state = PlantState {
            run: RunState {
                time: 0.0,
                theta: Vec::new(),
                nu: Vec::new(),
                qvel: Vec::new(),
                carry: Carry::default(),
                auto_choice,
                input: Vec::new(),
                input_constant,
                reach: Reach::default(),
            },
            settings: Settings { tolerance: 0.0, max_step: 0.0, energy_projection },
            method,
            start_time: 0.0,
            stop_time: None,
            initial_energy: 0.0,
            eps: Vec::new(),
            eps_rate: Vec::new(),
            ctrl: Vec::new(),
            ctrl_rate: Vec::new(),
            jacobian: HeldJacobian { derivatives: Vec::new(), age: jacobian_age },
        };
        for (field, &value) in SCALAR_FIELDS.iter().zip(settings) {
            (field.set)(&mut state, value);
        }
        // The writer stores 0 for a stop time not defined.
        state.stop_time = state.stop_time.filter(|_| stop_time_defined);
        let mut rest = vectors;
        for field in &VECTOR_FIELDS {
            let (values, after) = rest.split_at((field.len)(sizes));
            *(field.set)(&mut state) = values.to_vec();
            rest = after;
        }
        state.jacobian.derivatives = rest.to_vec();
        if holds_reach {
            state.run.reach = Reach { working_set, ..read_reach(reach, sizes, state.run.time)? };
        }
        Ok(Snapshot { phase, guid: found_guid, state })
    }
}

/// What a saved value must be, beyond finite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Bound {
    /// Any finite value.
    Finite,
    /// Greater than zero.
    Positive,
    /// Zero or more.
    NonNegative,
}

/// One f64 of the state saved after the header: its name in messages,
/// what it must be, and where it lives. Serialization writes and reads
/// [`SCALAR_FIELDS`] in its order, so the layout and the checks are this
/// one list.
struct ScalarField {
    name: &'static str,
    bound: Bound,
    get: fn(&PlantState) -> f64,
    set: fn(&mut PlantState, f64),
}

/// The scalars before the vectors: times, settings and integration values.
/// Appending a field changes the byte layout: raise [`VERSION`].
const SCALAR_FIELDS: [ScalarField; 13] = [
    ScalarField { name: "time", bound: Bound::Finite, get: |s| s.run.time, set: |s, x| s.run.time = x },
    ScalarField { name: "start_time", bound: Bound::Finite, get: |s| s.start_time, set: |s, x| s.start_time = x },
    // Checked even when not defined: the writer stores 0 then.
    ScalarField {
        name: "stop_time",
        bound: Bound::Finite,
        get: |s| s.stop_time.unwrap_or(0.0),
        set: |s, x| s.stop_time = Some(x),
    },
    ScalarField {
        name: "tolerance",
        bound: Bound::Positive,
        get: |s| s.settings.tolerance,
        set: |s, x| s.settings.tolerance = x,
    },
    ScalarField {
        name: "max_step",
        bound: Bound::NonNegative,
        get: |s| s.settings.max_step,
        set: |s, x| s.settings.max_step = x,
    },
    ScalarField {
        name: "next step",
        bound: Bound::NonNegative,
        get: |s| s.run.carry.next_step,
        set: |s, x| s.run.carry.next_step = x,
    },
    ScalarField { name: "work", bound: Bound::Finite, get: |s| s.run.carry.work, set: |s, x| s.run.carry.work = x },
    ScalarField {
        name: "initial energy",
        bound: Bound::NonNegative,
        get: |s| s.initial_energy,
        set: |s, x| s.initial_energy = x,
    },
    ScalarField {
        name: "relaxation",
        bound: Bound::NonNegative,
        get: |s| s.run.carry.relaxation,
        set: |s, x| s.run.carry.relaxation = x,
    },
    ScalarField {
        name: "start rates",
        bound: Bound::NonNegative,
        get: |s| s.run.carry.start_rates,
        set: |s, x| s.run.carry.start_rates = x,
    },
    ScalarField {
        name: "reach from",
        bound: Bound::Finite,
        get: |s| s.run.carry.reach_from,
        set: |s, x| s.run.carry.reach_from = x,
    },
    ScalarField {
        name: "reach cap",
        bound: Bound::NonNegative,
        get: |s| s.run.carry.reach_cap,
        set: |s, x| s.run.carry.reach_cap = x,
    },
    ScalarField {
        name: "refusals",
        bound: Bound::NonNegative,
        get: |s| s.run.carry.refusals,
        set: |s, x| s.run.carry.refusals = x,
    },
];

/// One vector of the state saved after the scalars: its length for the
/// FMU's sizes and where it lives (W, whose length a header flag gives,
/// follows them).
struct VectorField {
    len: fn(Sizes) -> usize,
    get: fn(&PlantState) -> &Vec<f64>,
    set: fn(&mut PlantState) -> &mut Vec<f64>,
}

/// θ, ν, θ̇ then act, ε and its rate, the controls and their rates, and
/// the last advance's input (ε then the controls), in this order.
const VECTOR_FIELDS: [VectorField; 8] = [
    VectorField { len: |n| n.nq, get: |s| &s.run.theta, set: |s| &mut s.run.theta },
    VectorField { len: |n| n.nv, get: |s| &s.run.nu, set: |s| &mut s.run.nu },
    VectorField { len: |n| n.nv + n.na, get: |s| &s.run.qvel, set: |s| &mut s.run.qvel },
    VectorField { len: |n| n.nv, get: |s| &s.eps, set: |s| &mut s.eps },
    VectorField { len: |n| n.nv, get: |s| &s.eps_rate, set: |s| &mut s.eps_rate },
    VectorField { len: |n| n.nu, get: |s| &s.ctrl, set: |s| &mut s.ctrl },
    VectorField { len: |n| n.nu, get: |s| &s.ctrl_rate, set: |s| &mut s.ctrl_rate },
    VectorField { len: |n| n.nv + n.nu, get: |s| &s.run.input, set: |s| &mut s.run.input },
];

/// Header bytes after the sizes: the state machine's state, whether a stop
/// time is defined, the method, energy projection, whether W is held, the
/// method `auto` chose (0: none yet), whether a step reaching past the
/// communication point is held, whether the last advance's input was
/// constant (then `input` holds it). W's age (steps accepted with it, a
/// u32) follows them.
const FLAGS: usize = 8;

/// The scalars of a step held past the communication point, after W: its
/// start, size and end, the work at its end, and the tolerance and
/// max_step it was taken with; then its vectors ([`reach_values`]).
const REACH_SCALARS: usize = 6;

/// The number of values of a step held past the communication point.
fn reach_len(n: Sizes) -> usize {
    let rates = n.nv + n.na;
    REACH_SCALARS + 2 * n.nq + (rates + 1) + DENSE_ROWS * (n.nv + rates + 1) + rates
}

/// A held step's values in the order saved: [`REACH_SCALARS`], then θ at
/// its start, its origin (θ̇, act, work), its interpolant's rows, θ and
/// (θ̇, act) at its end.
fn reach_values(reach: &Reach) -> impl Iterator<Item = f64> + '_ {
    let scalars = [reach.start, reach.step, reach.end, reach.work_end, reach.tolerance, reach.max_step];
    scalars.into_iter().chain(
        [&reach.theta_start, &reach.origin, &reach.rows, &reach.theta_end, &reach.qvel_end]
            .into_iter()
            .flat_map(|v| v.iter().copied()),
    )
}

/// A held step from its values ([`reach_values`]), checked: finite, a
/// positive size and tolerance, a non-negative max_step, an end at its
/// start plus its size (to rounding: a step that reaches the limit ends on
/// it), spanning `time`, the time it is held at. The next advance would
/// otherwise go on from its end to that time, however far (a forged blob
/// with the time at 7e36 and the step at 0.01 s ran 100 000 steps).
fn read_reach(values: &[f64], n: Sizes, time: f64) -> Result<Reach, SnapshotError> {
    if let Some(&value) = values.iter().find(|x| !x.is_finite()) {
        return Err(SnapshotError::Value {
            what: "a value of the step held past the communication point",
            value,
            must: "finite",
        });
    }
    let (scalars, vectors) = values.split_at(REACH_SCALARS);
    let [start, step, end, work_end, tolerance, max_step] = scalars.try_into().expect("REACH_SCALARS values");
    for (what, value, positive) in
        [("the held step's size", step, true), ("its tolerance", tolerance, true), ("its max_step", max_step, false)]
    {
        if value < 0.0 || (positive && value == 0.0) {
            let must = if positive { "positive" } else { "non-negative" };
            return Err(SnapshotError::Value { what, value, must });
        }
    }
    if (start + step - end).abs() > 4.0 * f64::EPSILON * end.abs().max(1.0) {
        return Err(SnapshotError::Value { what: "the held step's end", value: end, must: "its start plus its size" });
    }
    if !(start <= time && time <= end) {
        return Err(SnapshotError::Value { what: "the time", value: time, must: "within the step held past it" });
    }
    let rates = n.nv + n.na;
    let mut rest = vectors;
    let mut take = |len: usize| {
        let (taken, after) = rest.split_at(len);
        rest = after;
        taken.to_vec()
    };
    Ok(Reach {
        held: true,
        start,
        step,
        theta_start: take(n.nq),
        origin: take(rates + 1),
        rows: take(DENSE_ROWS * (n.nv + rates + 1)),
        end,
        theta_end: take(n.nq),
        qvel_end: take(rates),
        work_end,
        tolerance,
        max_step,
        working_set: Vec::new(),
    })
}

/// After a held step's values: the rows of the solver's working set where
/// the step was cut to end past a constraint switch (0 otherwise), then
/// each row's place in it ([`held_code`]).
fn working_set_values(reach: &Reach) -> impl Iterator<Item = f64> + '_ {
    let rows = reach.working_set.len() as f64;
    std::iter::once(rows).chain(reach.working_set.iter().map(|&held| f64::from(held_code(held))))
}

/// A working set's entry as saved.
fn held_code(held: Held) -> u8 {
    match held {
        Held::Free => 0,
        Held::Lower => 1,
        Held::Upper => 2,
    }
}

/// The working set [`working_set_values`] wrote.
fn read_working_set(reader: &mut Reader) -> Result<Vec<Held>, SnapshotError> {
    let rows = reader.f64()?;
    // No more rows than bytes left: a corrupt count is refused before it allocates.
    let most = (reader.bytes.len() - reader.at) / 8;
    if rows.fract() != 0.0 || !(0.0..=most as f64).contains(&rows) {
        let must = "a whole number, at most the values left";
        return Err(SnapshotError::Value { what: "the working set's rows", value: rows, must });
    }
    (0..rows as usize)
        .map(|_| match reader.f64()? {
            0.0 => Ok(Held::Free),
            1.0 => Ok(Held::Lower),
            2.0 => Ok(Held::Upper),
            value => Err(SnapshotError::Value { what: "a working set's entry", value, must: "0, 1 or 2" }),
        })
        .collect()
}

/// What `auto` measured, after the scalars (0 before it has chosen): the
/// probe's step, its error per second, the tolerance, and the steps
/// attempted in the communication steps it weighs with the next.
const CHOICE_SCALARS: usize = 3 + MOVE_UP_WINDOW - 1;

/// Checks what fmi2SetupExperiment and fmi2SetReal would have refused:
/// every value finite, and each scalar what [`SCALAR_FIELDS`] says it must be.
fn check_values(scalars: &[f64], vectors: &[f64]) -> Result<(), SnapshotError> {
    for (field, &value) in SCALAR_FIELDS.iter().zip(scalars) {
        if !value.is_finite() {
            return Err(SnapshotError::Value { what: field.name, value, must: "finite" });
        }
    }
    for (field, &value) in SCALAR_FIELDS.iter().zip(scalars) {
        let must = match field.bound {
            Bound::Positive if value <= 0.0 => "positive",
            Bound::NonNegative if value < 0.0 => "non-negative",
            _ => continue,
        };
        return Err(SnapshotError::Value { what: field.name, value, must });
    }
    match vectors.iter().find(|x| !x.is_finite()) {
        Some(&value) => Err(SnapshotError::Value {
            what: "a value of theta, nu, eps, ctrl, their rates or W",
            value,
            must: "finite",
        }),
        None => Ok(()),
    }
}

/// A cursor over a blob that fails with `Truncated` instead of panicking.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], SnapshotError> {
        let end = self.at.checked_add(n).filter(|&end| end <= self.bytes.len());
        let end =
            end.ok_or(SnapshotError::Truncated { expected: self.at.saturating_add(n), found: self.bytes.len() })?;
        let slice = &self.bytes[self.at..end];
        self.at = end;
        Ok(slice)
    }

    fn u32(&mut self) -> Result<u32, SnapshotError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }

    fn f64(&mut self) -> Result<f64, SnapshotError> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
}

#[cfg(test)]
mod tests {
    use nudyn::integrate::Method;

    use super::*;

    const GUID: &str = "{01234567-89ab-cdef-0123-456789abcdef}";
    const SIZES: Sizes = Sizes { nq: 5, nv: 4, nu: 2, na: 0 };

    fn sample() -> Snapshot {
        Snapshot {
            phase: Phase::StepComplete,
            guid: GUID.to_string(),
            state: PlantState {
                run: RunState {
                    time: 0.1 + 0.2,
                    theta: vec![1.0, 0.0, 0.0, 0.0, std::f64::consts::PI],
                    nu: vec![1e-300, -0.0, 3.5, 7.25],
                    qvel: vec![2e-300, -0.0, 1.75, -0.5],
                    carry: Carry {
                        next_step: 2.5e-3,
                        work: -0.75,
                        relaxation: 3.0,
                        start_rates: 42.5,
                        reach_from: 1.25,
                        reach_cap: 0.0625,
                        refusals: 2.0,
                    },
                    auto_choice: None,
                    input: vec![0.5, 0.25, -1.0, 2.0, -2.5, 0.125],
                    input_constant: true,
                    reach: Reach::default(),
                },
                settings: Settings { tolerance: 1e-6, max_step: 1e-3, energy_projection: true },
                method: Method::Dopri5.into(),
                start_time: -1.5,
                stop_time: Some(10.0),
                initial_energy: 1.25,
                eps: vec![0.5, 0.25, -1.0, 2.0],
                eps_rate: vec![0.0, 1.0, 0.0, -3.0],
                ctrl: vec![-2.5, 0.125],
                ctrl_rate: vec![4.0, 0.0],
                jacobian: HeldJacobian::default(),
            },
        }
    }

    /// The sample as a Rosenbrock run holding W.
    fn sample_holding_w() -> Snapshot {
        let mut snapshot = sample();
        snapshot.state.method = Method::Ros34pw2.into();
        let nv = snapshot.state.run.nu.len();
        snapshot.state.jacobian =
            HeldJacobian { derivatives: (0..2 * nv * nv).map(|k| (k as f64 - 7.5) * 0.125).collect(), age: 17 };
        snapshot
    }

    /// The sample as a run whose method `auto` has chosen.
    fn sample_with_choice() -> Snapshot {
        let mut snapshot = sample();
        snapshot.state.method = MethodSetting::Auto;
        snapshot.state.run.auto_choice = Some(AutoChoice {
            method: Method::Bs3,
            probe_step: 0.1,
            error_per_second: 3.5e-14,
            tolerance: 1e-6,
            earlier_attempts: [0, 1, 3, 2],
        });
        snapshot
    }

    /// The sample as a run whose last step reaches past the communication point.
    fn sample_with_reach() -> Snapshot {
        let mut snapshot = sample();
        let Sizes { nq, nv, na, .. } = SIZES;
        let values = |len: usize, scale: f64| (0..len).map(|k| scale * (k as f64 - 2.5)).collect::<Vec<f64>>();
        snapshot.state.run.reach = Reach {
            held: true,
            start: 0.25,
            step: 0.5,
            theta_start: values(nq, 0.5),
            origin: values(nv + na + 1, -0.25),
            rows: values(DENSE_ROWS * (2 * nv + na + 1), 1e-3),
            end: 0.75,
            theta_end: values(nq, 0.125),
            qvel_end: values(nv + na, 2.0),
            work_end: -0.5,
            tolerance: 1e-4,
            max_step: 0.0,
            working_set: Vec::new(),
        };
        snapshot
    }

    /// The sample as a run whose last step, cut to end past a constraint
    /// switch, reaches past the communication point.
    fn sample_past_switch() -> Snapshot {
        let mut snapshot = sample_with_reach();
        snapshot.state.run.reach.working_set = vec![Held::Free, Held::Upper, Held::Lower, Held::Free];
        snapshot
    }

    fn serialized(snapshot: &Snapshot) -> Vec<u8> {
        let mut bytes = vec![0; snapshot.serialized_size()];
        snapshot.serialize(&mut bytes);
        bytes
    }

    #[test]
    fn round_trips_bit_exactly() {
        let bases = [
            (Some(10.0), sample()),
            (None, sample()),
            (Some(10.0), sample_holding_w()),
            (None, sample_with_choice()),
            (Some(10.0), sample_with_reach()),
            (None, sample_past_switch()),
        ];
        for (stop_time, base) in bases {
            let mut original = base;
            original.state.stop_time = stop_time;
            let bytes = serialized(&original);
            let back = Snapshot::deserialize(&bytes, GUID, SIZES).unwrap();
            assert_eq!(back, original);
            assert!(back.state.run.nu[1].is_sign_negative(), "-0.0 keeps its sign");
            assert_eq!(serialized(&back), bytes);
        }
    }

    /// A run with two activation states after θ̇, holding a W with their
    /// rows and columns, round-trips; a blob is read with the FMU's na.
    #[test]
    fn activation_states_round_trip_with_their_w() {
        let mut original = sample_holding_w();
        let (nv, na) = (original.state.run.nu.len(), 2);
        original.state.run.qvel.extend([0.25, -0.75]);
        let w_len = (nv + na) * (2 * nv + na);
        original.state.jacobian.derivatives = (0..w_len).map(|k| k as f64 * 0.5).collect();
        let bytes = serialized(&original);
        let sizes = Sizes { na, ..SIZES };
        assert_eq!(Snapshot::deserialize(&bytes, GUID, sizes).unwrap(), original);
        assert!(Snapshot::deserialize(&bytes, GUID, SIZES).is_err(), "read without act, the blob does not fit");
    }

    #[test]
    fn rejects_every_truncation_and_extension() {
        let bytes = serialized(&sample_holding_w());
        for len in 0..bytes.len() {
            assert!(Snapshot::deserialize(&bytes[..len], GUID, SIZES).is_err(), "truncated to {len}");
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(matches!(Snapshot::deserialize(&longer, GUID, SIZES), Err(SnapshotError::TrailingBytes { .. })));
    }

    #[test]
    fn rejects_every_single_bit_flip() {
        let bytes = serialized(&sample_with_reach());
        for byte in 0..bytes.len() {
            for bit in 0..8 {
                let mut corrupt = bytes.clone();
                corrupt[byte] ^= 1 << bit;
                assert!(Snapshot::deserialize(&corrupt, GUID, SIZES).is_err(), "byte {byte} bit {bit}");
            }
        }
    }

    #[test]
    fn rejects_foreign_blobs() {
        let bytes = serialized(&sample());
        assert!(matches!(Snapshot::deserialize(&bytes, "{other}", SIZES), Err(SnapshotError::ForeignGuid { .. })));
        for other in [Sizes { nq: 7, nv: 6, nu: 2, na: 0 }, Sizes { nu: 0, ..SIZES }] {
            assert!(matches!(Snapshot::deserialize(&bytes, GUID, other), Err(SnapshotError::Sizes { .. })));
        }
        assert_eq!(Snapshot::deserialize(b"PK\x03\x04 not a state", GUID, SIZES), Err(SnapshotError::BadMagic));
        let mut other_version = bytes.clone();
        other_version[8..12].copy_from_slice(&(VERSION + 1).to_le_bytes());
        let found = VERSION + 1;
        assert_eq!(Snapshot::deserialize(&other_version, GUID, SIZES), Err(SnapshotError::Version { found }));
    }

    /// A blob whose checksum is made to match, as a deliberate forgery would.
    fn with_valid_checksum(mut bytes: Vec<u8>) -> Vec<u8> {
        let contents = bytes.len() - 8;
        let checksum = fnv1a(&bytes[..contents]);
        bytes[contents..].copy_from_slice(&checksum.to_le_bytes());
        bytes
    }

    #[test]
    fn rejects_values_a_state_cannot_hold_even_with_a_valid_checksum() {
        let mut nan_theta = sample();
        nan_theta.state.run.theta[2] = f64::NAN;
        let mut negative_step = sample();
        negative_step.state.settings.max_step = -1e-3;
        let mut infinite_time = sample();
        infinite_time.state.run.time = f64::INFINITY;
        let mut nan_ctrl = sample();
        nan_ctrl.state.ctrl_rate[1] = f64::NAN;
        let mut infinite_w = sample_holding_w();
        infinite_w.state.jacobian.derivatives[5] = f64::NEG_INFINITY;
        let mut nan_reach = sample_with_reach();
        nan_reach.state.run.reach.rows[7] = f64::NAN;
        let mut empty_reach = sample_with_reach();
        empty_reach.state.run.reach.step = 0.0;
        let mut time_past_reach = sample_with_reach();
        time_past_reach.state.run.time = 6.8e36;
        let mut time_before_reach = sample_with_reach();
        time_before_reach.state.run.reach.start = 0.5;
        time_before_reach.state.run.reach.step = 0.25;
        let mut end_off_reach = sample_with_reach();
        end_off_reach.state.run.reach.end = 0.75 + 1e-9;
        for (snapshot, what) in [
            (nan_reach, "the step held past the communication point"),
            (empty_reach, "the held step's size"),
            (
                time_past_reach,
                "the time = 6800000000000000000000000000000000000, which must be within the step held past it",
            ),
            (time_before_reach, "the time = 0.30000000000000004, which must be within the step"),
            (end_off_reach, "the held step's end"),
            (nan_theta, "a value of theta"),
            (negative_step, "max_step"),
            (infinite_time, "time"),
            (nan_ctrl, "ctrl"),
            (infinite_w, "W"),
        ] {
            let error = Snapshot::deserialize(&serialized(&snapshot), GUID, SIZES).unwrap_err();
            assert!(matches!(error, SnapshotError::Value { .. }) && error.to_string().contains(what), "{error}");
        }
        let mut bytes = serialized(&sample());
        let phase_at = MAGIC.len() + 8 + GUID.len() + 12;
        for code in [Phase::Fatal.code(), 9, 255] {
            bytes[phase_at] = code;
            bytes = with_valid_checksum(bytes);
            assert_eq!(Snapshot::deserialize(&bytes, GUID, SIZES), Err(SnapshotError::Phase(code)));
        }
        let mut explicit_with_w = sample_holding_w();
        explicit_with_w.state.method = Method::Dop853.into();
        assert_eq!(
            Snapshot::deserialize(&serialized(&explicit_with_w), GUID, SIZES),
            Err(SnapshotError::JacobianWithoutRosenbrock("dop853"))
        );
        let mut bytes = serialized(&sample_with_choice());
        let newer_attempts_at =
            MAGIC.len() + 8 + GUID.len() + 12 + FLAGS + 4 + (SCALAR_FIELDS.len() + CHOICE_SCALARS - 1) * 8;
        assert_eq!(bytes[newer_attempts_at..newer_attempts_at + 8], 2.0f64.to_le_bytes());
        for (value, must) in [(1.5, "a whole number"), (0.0, "positive after a count")] {
            bytes[newer_attempts_at..newer_attempts_at + 8].copy_from_slice(&f64::to_le_bytes(value));
            bytes = with_valid_checksum(bytes);
            let error = Snapshot::deserialize(&bytes, GUID, SIZES).unwrap_err();
            assert!(
                error.to_string().contains("a step count auto weighs") && error.to_string().contains(must),
                "{error}"
            );
        }
        // The last value before the checksum: the working set's count of
        // rows without rows, its last entry with them.
        let (without_rows, with_rows) = (serialized(&sample_with_reach()), serialized(&sample_past_switch()));
        let rows_at = without_rows.len() - 16;
        let entry_at = with_rows.len() - 16;
        for (mut bytes, at, value, what) in [
            (without_rows.clone(), rows_at, 0.5, "the working set's rows"),
            (without_rows, rows_at, 1e9, "the working set's rows"),
            (with_rows, entry_at, 3.0, "a working set's entry"),
        ] {
            bytes[at..at + 8].copy_from_slice(&f64::to_le_bytes(value));
            let error = Snapshot::deserialize(&with_valid_checksum(bytes), GUID, SIZES).unwrap_err();
            assert!(error.to_string().contains(what), "{error}");
        }
        let mut choice_without_auto = sample_with_choice();
        choice_without_auto.state.method = Method::Tsit5.into();
        assert_eq!(
            Snapshot::deserialize(&serialized(&choice_without_auto), GUID, SIZES),
            Err(SnapshotError::ChoiceWithoutAuto { method: 6, chosen: 5 })
        );
    }
}
