//! `<keyframe>`: each `<key>` checked as MuJoCo checks it (every vector
//! given has the model's size) and kept, so that a command can start from it
//! (`nudyn linearize --keyframe`).

use std::fmt;

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

/// The vectors a `<key>` may give, in the order MuJoCo checks their sizes.
const KEY_VECTORS: [&str; 6] = ["qpos", "qvel", "act", "mpos", "mquat", "ctrl"];

/// A `<key>` as read: its numbers parsed (an empty vector counts as not
/// given); their sizes are checked at compile, once the model's are known.
#[derive(Clone, Debug)]
pub(crate) struct KeySpec {
    /// The element, for messages.
    at: Origin,
    name: Option<String>,
    time: f64,
    /// The vectors of [`KEY_VECTORS`], each if given.
    vectors: [Option<Vec<f64>>; 6],
}

/// Reads one `<key>`.
pub(crate) fn parse(key: &Element) -> Result<KeySpec, MjcfError> {
    if key.tag() != "key" {
        return Err(key.unknown());
    }
    key.check_attributes(&["name", "time", "qpos", "qvel", "act", "mpos", "mquat", "ctrl"])?;
    if let Some(child) = key.children().next() {
        return Err(child.unknown());
    }
    let time = key.number("time")?.unwrap_or(0.0);
    let mut vectors: [Option<Vec<f64>>; 6] = Default::default();
    for (attribute, vector) in KEY_VECTORS.into_iter().zip(&mut vectors) {
        let Some(text) = key.text(attribute) else { continue };
        let values: Result<Vec<f64>, _> = text.split_ascii_whitespace().map(str::parse).collect();
        *vector = Some(values.map_err(|_| key.bad_value(attribute, "numbers"))?).filter(|v| !v.is_empty());
    }
    Ok(KeySpec { at: key.origin(), name: key.text("name").map(str::to_string), time, vectors })
}

/// The keyframe `spec` describes, with MuJoCo's check that each vector
/// given has the model's size (`sizes`: nq, nv, na, 3 nmocap, 4 nmocap, nu).
pub(crate) fn compile(spec: KeySpec, sizes: [usize; 6]) -> Result<Keyframe, MjcfError> {
    for ((attribute, vector), size) in KEY_VECTORS.iter().zip(&spec.vectors).zip(sizes) {
        if let Some(given) = vector.as_ref().map(Vec::len).filter(|&given| given != size) {
            return Err(spec.at.invalid(format!("invalid {attribute} size, expected {size}, got {given}")));
        }
    }
    let [qpos, qvel, act, mpos, mquat, ctrl] = spec.vectors;
    let places_mocap_bodies = mpos.is_some() || mquat.is_some();
    Ok(Keyframe { name: spec.name, time: spec.time, qpos, qvel, act, ctrl, places_mocap_bodies, line: spec.at.line })
}
