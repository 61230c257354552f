//! `<keyframe>`: each `<key>` checked as MuJoCo checks it (every vector
//! given has the model's size) and kept, so that a command can start from it
//! (`nudyn linearize --keyframe`).

use std::fmt;

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
