//! `<keyframe>`: each `<key>` checked as MuJoCo checks it (every vector
//! given has the model's size) and kept, so that a command can start from it
//! (`nudyn linearize --keyframe`).

use std::fmt;

use super::attributes::{Attribute, names, read_into, set};
use super::element::{Element, Origin};
use super::error::MjcfError;

/// One `<key>`: a state of the vehicle and its inputs. A vector the key
/// does not give is MuJoCo's default: qpos0, and zeros for the others.
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframe {
    /// The key's `name`, if it has one.
    pub name: Option<String>,
    /// `time`.
    pub time: f64,
    /// `qpos` (nq values), if given.
    pub qpos: Option<Vec<f64>>,
    /// `qvel` (nv values), if given.
    pub qvel: Option<Vec<f64>>,
    /// `act` (one value per activation state), if given.
    pub act: Option<Vec<f64>>,
    /// `ctrl` (one value per actuator), if given.
    pub ctrl: Option<Vec<f64>>,
    /// Whether the key places mocap bodies (`mpos` or `mquat`), which nudyn
    /// holds at their modelled pose.
    pub places_mocap_bodies: bool,
    /// Line of the `<key>` element.
    pub line: u32,
}

/// Why a keyframe asked for cannot be found.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("the model has no keyframe {asked:?} (its keyframes: {available})")]
pub struct NoSuchKeyframe {
    /// What was asked: a name, or an index.
    pub asked: String,
    /// The keyframes there are, by name or index.
    pub available: Available,
}

/// The keyframes of a model, as a list for a message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Available(Vec<String>);

impl fmt::Display for Available {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() { f.write_str("none") } else { f.write_str(&self.0.join(", ")) }
    }
}

/// The keyframe named `asked`, or, as MuJoCo's `mj_resetDataKeyframe`
/// takes them, at index `asked` (0-based, in document order).
pub fn find<'a>(keyframes: &'a [Keyframe], asked: &str) -> Result<&'a Keyframe, NoSuchKeyframe> {
    let by_name = keyframes.iter().find(|k| k.name.as_deref() == Some(asked));
    let by_index = || asked.parse::<usize>().ok().and_then(|k| keyframes.get(k));
    by_name.or_else(by_index).ok_or_else(|| NoSuchKeyframe {
        asked: asked.to_string(),
        available: Available(
            keyframes
                .iter()
                .enumerate()
                .map(|(k, key)| key.name.as_ref().map_or_else(|| k.to_string(), |name| format!("{name:?}")))
                .collect(),
        ),
    })
}

/// `<key>` (MuJoCo 4.0 schema): its attributes and how each is read.
pub(crate) const KEY_ATTRIBUTES: &[Attribute<KeySettings>] = &[
    Attribute::by_reader("name"),
    Attribute::into("time", |s, e, a| set(&mut s.time, e.number(a)?)),
    Attribute::into("qpos", |s, e, a| set(&mut s.qpos, vector(e, a)?)),
    Attribute::into("qvel", |s, e, a| set(&mut s.qvel, vector(e, a)?)),
    Attribute::into("act", |s, e, a| set(&mut s.act, vector(e, a)?)),
    Attribute::into("mpos", |s, e, a| set(&mut s.mpos, vector(e, a)?)),
    Attribute::into("mquat", |s, e, a| set(&mut s.mquat, vector(e, a)?)),
    Attribute::into("ctrl", |s, e, a| set(&mut s.ctrl, vector(e, a)?)),
];

/// A vector of numbers; an empty one counts as not given (`Some(None)`).
fn vector(element: &Element, attribute: &str) -> Result<Option<Option<Vec<f64>>>, MjcfError> {
    let Some(text) = element.text(attribute) else { return Ok(None) };
    let values: Result<Vec<f64>, _> = text.split_ascii_whitespace().map(str::parse).collect();
    let values = values.map_err(|_| element.bad_value(attribute, "numbers"))?;
    Ok(Some(Some(values).filter(|values| !values.is_empty())))
}

/// What a `<key>` gives (MuJoCo's defaults: time 0, no vector).
#[derive(Clone, Debug, Default)]
pub(crate) struct KeySettings {
    time: f64,
    qpos: Option<Vec<f64>>,
    qvel: Option<Vec<f64>>,
    act: Option<Vec<f64>>,
    mpos: Option<Vec<f64>>,
    mquat: Option<Vec<f64>>,
    ctrl: Option<Vec<f64>>,
}

/// A `<key>` as read; the sizes of its vectors are checked at compile, once
/// the model's are known.
#[derive(Clone, Debug)]
pub(crate) struct KeySpec {
    /// The element, for messages.
    at: Origin,
    name: Option<String>,
    settings: KeySettings,
}

/// Reads one `<key>`.
pub(crate) fn parse(key: &Element) -> Result<KeySpec, MjcfError> {
    if key.tag() != "key" {
        return Err(key.unknown());
    }
    key.check_attributes(&names(KEY_ATTRIBUTES))?;
    if let Some(child) = key.children().next() {
        return Err(child.unknown());
    }
    let mut settings = KeySettings::default();
    read_into(KEY_ATTRIBUTES, &mut settings, key)?;
    Ok(KeySpec { at: key.origin(), name: key.text("name").map(str::to_string), settings })
}

/// The model's sizes a key's vectors must have.
pub(crate) struct KeySizes {
    /// Position coordinates.
    pub nq: usize,
    /// Degrees of freedom.
    pub nv: usize,
    /// Activation states.
    pub na: usize,
    /// Mocap bodies.
    pub nmocap: usize,
    /// Actuators.
    pub nu: usize,
}

/// The keyframe `spec` describes, with MuJoCo's check that each vector
/// given has the model's size.
pub(crate) fn compile(spec: KeySpec, sizes: &KeySizes) -> Result<Keyframe, MjcfError> {
    let KeySettings { time, qpos, qvel, act, mpos, mquat, ctrl } = spec.settings;
    let checked = [
        ("qpos", &qpos, sizes.nq),
        ("qvel", &qvel, sizes.nv),
        ("act", &act, sizes.na),
        ("mpos", &mpos, 3 * sizes.nmocap),
        ("mquat", &mquat, 4 * sizes.nmocap),
        ("ctrl", &ctrl, sizes.nu),
    ];
    for (attribute, vector, size) in checked {
        if let Some(given) = vector.as_ref().map(Vec::len).filter(|&given| given != size) {
            return Err(spec.at.invalid(format!("invalid {attribute} size, expected {size}, got {given}")));
        }
    }
    let places_mocap_bodies = mpos.is_some() || mquat.is_some();
    Ok(Keyframe { name: spec.name, time, qpos, qvel, act, ctrl, places_mocap_bodies, line: spec.at.line })
}
