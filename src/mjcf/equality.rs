//! `<equality>`: connect, weld, joint and tendon constraints, with MuJoCo
//! 4.0's attributes, defaults and compiler checks. Flex equalities are
//! refused (nudyn models no flexes).

use super::attributes::{Attribute, Read, names, read_into, set};
use super::element::{Element, Origin};
use super::error::MjcfError;
use crate::math::{Quat, Vec3};
use crate::vehicle::{Equality, EqualityKind, EqualityObjects, JointKind, SoftConstraint};

/// Attributes every equality element has (MuJoCo 4.0 schema) and how each
/// is read; a `<default>` class may set those read into the settings.
pub(crate) const COMMON_ATTRIBUTES: &[Attribute<EqualitySettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("class"),
    Attribute::into("active", |s, e, a| set(&mut s.active, e.boolean(a)?)),
    Attribute::into("solref", |s, e, a| e.overwrite_numbers(a, &mut s.soft.solref)),
    Attribute::into("solimp", |s, e, a| e.overwrite_numbers(a, &mut s.soft.solimp)),
];

/// The attributes an `<equality>` default class may set.
pub(crate) fn default_attributes() -> Vec<&'static str> {
    COMMON_ATTRIBUTES.iter().filter(|a| matches!(a.read, Read::Into(_))).map(|a| a.name).collect()
}

/// What an equality element starts from: its class's settings.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct EqualitySettings {
    /// `active`.
    pub active: bool,
    /// `solref`, `solimp`.
    pub soft: SoftConstraint,
}

impl Default for EqualitySettings {
    /// MuJoCo's defaults: active, solref (0.02, 1), solimp (0.9, 0.95, 0.001, 0.5, 2).
    fn default() -> Self {
        EqualitySettings { active: true, soft: SoftConstraint::default() }
    }
}

impl EqualitySettings {
    /// Overwrites the settings the element gives.
    pub fn apply(&mut self, element: &Element) -> Result<(), MjcfError> {
        read_into(COMMON_ATTRIBUTES, self, element)
    }
}

/// The objects equality elements name, as the importer knows them; each
/// lookup gives the error that names the element (`at`) and attribute.
pub(crate) trait EqualityTargets {
    /// The body `name`: `None` for "world".
    fn equality_body(&self, at: &Origin, name: &str) -> Result<Option<usize>, MjcfError>;
    /// The site `name`, which the attribute gives.
    fn equality_site(&self, at: &Origin, attribute: &str, name: &str) -> Result<usize, MjcfError>;
    /// The tendon `name`.
    fn equality_tendon(&self, at: &Origin, name: &str) -> Result<usize, MjcfError>;
    /// The kind of the joint `name`.
    fn equality_joint(&self, at: &Origin, name: &str) -> Result<JointKind, MjcfError>;
}

/// What an equality element's own attributes give besides the objects it
/// names (a `<default>` class sets none of them).
#[derive(Clone, Debug)]
pub(crate) struct OwnSettings {
    /// `anchor`: a connect's or weld's point in body1's frame.
    pub anchor: [f64; 3],
    /// `relpose`: a weld's pose of body2 in body1 (position, then a
    /// quaternion; all zeros: the pose at qpos0).
    pub relpose: [f64; 7],
    /// `torquescale`.
    pub torquescale: f64,
    /// `polycoef`: a joint or tendon coupling's polynomial.
    pub polycoef: [f64; 5],
}

impl Default for OwnSettings {
    /// MuJoCo's defaults.
    fn default() -> Self {
        OwnSettings {
            anchor: [0.0; 3],
            relpose: [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            torquescale: 1.0,
            polycoef: [0.0, 1.0, 0.0, 0.0, 0.0],
        }
    }
}

/// `<connect>`'s own attributes (MuJoCo 4.0 schema); the reader looks up
/// the bodies and sites.
const CONNECT_ATTRIBUTES: &[Attribute<OwnSettings>] = &[
    Attribute::by_reader("body1"),
    Attribute::by_reader("body2"),
    Attribute::by_reader("site1"),
    Attribute::by_reader("site2"),
    Attribute::into("anchor", |s, e, a| e.overwrite_numbers(a, &mut s.anchor)),
];

/// `<weld>`'s own attributes.
const WELD_ATTRIBUTES: &[Attribute<OwnSettings>] = &[
    Attribute::by_reader("body1"),
    Attribute::by_reader("body2"),
    Attribute::by_reader("site1"),
    Attribute::by_reader("site2"),
    Attribute::into("anchor", |s, e, a| e.overwrite_numbers(a, &mut s.anchor)),
    Attribute::into("relpose", |s, e, a| e.overwrite_numbers(a, &mut s.relpose)),
    Attribute::into("torquescale", |s, e, a| set(&mut s.torquescale, e.number(a)?)),
];

/// `<joint>`'s own attributes in `<equality>`.
const JOINT_ATTRIBUTES: &[Attribute<OwnSettings>] = &[
    Attribute::by_reader("joint1"),
    Attribute::by_reader("joint2"),
    Attribute::into("polycoef", |s, e, a| e.overwrite_numbers(a, &mut s.polycoef)),
];

/// `<tendon>`'s own attributes in `<equality>`.
const TENDON_ATTRIBUTES: &[Attribute<OwnSettings>] = &[
    Attribute::by_reader("tendon1"),
    Attribute::by_reader("tendon2"),
    Attribute::into("polycoef", |s, e, a| e.overwrite_numbers(a, &mut s.polycoef)),
];

/// The equality elements nudyn models, with their own attributes.
pub(crate) const EQUALITY_ATTRIBUTES: &[(&str, &[Attribute<OwnSettings>])] = &[
    ("connect", CONNECT_ATTRIBUTES),
    ("weld", WELD_ATTRIBUTES),
    ("joint", JOINT_ATTRIBUTES),
    ("tendon", TENDON_ATTRIBUTES),
];

/// The attributes of an equality element whose own ones are `own`.
pub(crate) fn attributes(own: &[Attribute<OwnSettings>]) -> Vec<&'static str> {
    names(COMMON_ATTRIBUTES).into_iter().chain(names(own)).collect()
}

/// The equality elements MuJoCo has that nudyn refuses: on flexes.
pub(crate) const REFUSED_EQUALITIES: &[&str] = &["flex", "flexvert", "flexstrain"];

/// An element of `<equality>` as read: its settings resolved and checked,
/// the objects it names by name, for the compile stage.
#[derive(Clone, Debug)]
pub(crate) struct EqualitySpec {
    /// The element, for messages.
    pub at: Origin,
    /// `name`.
    pub name: Option<String>,
    /// Its class's settings with its own attributes applied.
    pub settings: EqualitySettings,
    /// What it holds together, by name.
    pub kind: KindSpec,
}

/// What an equality element holds together, the objects by name.
#[derive(Clone, Debug)]
pub(crate) enum KindSpec {
    /// `<connect>`.
    Connect { objects: ObjectsSpec, anchor: Vec3 },
    /// `<weld>`.
    Weld { objects: ObjectsSpec, anchor: Vec3, relpose: Option<(Vec3, Quat)>, torquescale: f64 },
    /// `<joint>`.
    Joint { joint1: String, joint2: Option<String>, polycoef: [f64; 5] },
    /// `<tendon>`.
    Tendon { tendon1: String, tendon2: Option<String>, polycoef: [f64; 5] },
}

/// The frames a connect or weld names: bodies (body2 absent: the world) or sites.
#[derive(Clone, Debug)]
pub(crate) enum ObjectsSpec {
    /// `body1`, `body2`.
    Bodies(String, Option<String>),
    /// `site1`, `site2`.
    Sites(String, String),
}

impl EqualitySpec {
    /// The bodies and sites it names, by name, for the refusal of mocap bodies.
    pub fn frames(&self) -> Option<&ObjectsSpec> {
        match &self.kind {
            KindSpec::Connect { objects, .. } | KindSpec::Weld { objects, .. } => Some(objects),
            KindSpec::Joint { .. } | KindSpec::Tendon { .. } => None,
        }
    }
}

/// Reads one element of `<equality>` whose class settings are `settings`,
/// with MuJoCo's checks of what it gives; the objects it names are looked
/// up by [`compile`].
pub(crate) fn parse(element: &Element, mut settings: EqualitySettings) -> Result<EqualitySpec, MjcfError> {
    let own = match EQUALITY_ATTRIBUTES.iter().find(|(tag, _)| *tag == element.tag()) {
        Some((_, own)) => *own,
        None if REFUSED_EQUALITIES.contains(&element.tag()) => {
            return Err(element.unsupported(format!(
                "<equality>/<{}>: an equality constraint on a flex (nudyn models no flexes)",
                element.tag()
            )));
        }
        None => return Err(element.unknown()),
    };
    element.check_attributes(&attributes(own))?;
    if let Some(child) = element.children().next() {
        return Err(child.unknown());
    }
    settings.apply(element)?;
    let mut own_settings = OwnSettings::default();
    read_into(own, &mut own_settings, element)?;
    let OwnSettings { anchor, relpose, torquescale, polycoef } = own_settings;
    let text = |attribute: &str| element.text(attribute).map(str::to_string);
    let required = |attribute: &str| text(attribute).ok_or_else(|| element.missing(attribute));
    let kind = match element.tag() {
        "joint" => KindSpec::Joint { joint1: required("joint1")?, joint2: text("joint2"), polycoef },
        "tendon" => KindSpec::Tendon { tendon1: required("tendon1")?, tendon2: text("tendon2"), polycoef },
        tag => {
            let objects = objects(element)?;
            if tag == "connect" {
                if matches!(objects, ObjectsSpec::Bodies(..)) && !element.has("anchor") {
                    return Err(element.missing("anchor"));
                }
                KindSpec::Connect { objects, anchor: Vec3::from(anchor) }
            } else {
                let quat = [relpose[3], relpose[4], relpose[5], relpose[6]];
                let relpose = (quat != [0.0; 4]).then(|| {
                    let q = Quat::from_quaternion(nalgebra::Quaternion::new(quat[0], quat[1], quat[2], quat[3]));
                    (Vec3::new(relpose[0], relpose[1], relpose[2]), q)
                });
                KindSpec::Weld { objects, anchor: Vec3::from(anchor), relpose, torquescale }
            }
        }
    };
    Ok(EqualitySpec { at: element.origin(), name: text("name"), settings, kind })
}

/// The frames a connect or weld names: two bodies (body2 the world when
/// left out) or two sites, not a mix; sites take no `anchor` (nor
/// `relpose`, for a weld).
fn objects(element: &Element) -> Result<ObjectsSpec, MjcfError> {
    let with_bodies = element.has("body1") || element.has("body2");
    let with_sites = element.has("site1") || element.has("site2");
    let required =
        |attribute: &str| element.text(attribute).map(str::to_string).ok_or_else(|| element.missing(attribute));
    match (with_bodies, with_sites) {
        (true, true) => Err(element.invalid("body and site semantics cannot be mixed in equality constraint")),
        (false, false) => Err(element.invalid("either body1 or site1 must be given in equality constraint")),
        (true, false) => Ok(ObjectsSpec::Bodies(required("body1")?, element.text("body2").map(str::to_string))),
        (false, true) => {
            // MuJoCo's schema: a frame given by sites has no anchor or relative pose.
            let body_only: &[&str] = if element.tag() == "weld" { &["anchor", "relpose"] } else { &["anchor"] };
            if let Some(attribute) = body_only.iter().find(|a| element.has(a)) {
                let body_attributes: Vec<String> =
                    ["body1", "body2"].iter().chain(body_only).map(|a| format!("'{a}'")).collect();
                return Err(element.invalid(format!(
                    "'{attribute}' cannot be given with sites: at most one of ('site1', 'site2'), ({}) can be specified",
                    body_attributes.join(", ")
                )));
            }
            Ok(ObjectsSpec::Sites(required("site1")?, required("site2")?))
        }
    }
}

/// The equality constraint `spec` describes, the objects it names looked
/// up in `targets` and checked as MuJoCo's compiler checks them.
pub(crate) fn compile(spec: &EqualitySpec, targets: &impl EqualityTargets) -> Result<Equality, MjcfError> {
    let at = &spec.at;
    let kind = match &spec.kind {
        KindSpec::Joint { joint1, joint2, polycoef } => {
            let scalar = |attribute: &str, name: &str| match targets.equality_joint(at, name)? {
                JointKind::Hinge | JointKind::Slide => Ok(()),
                _ => Err(at.invalid(format!("{attribute} must be a hinge or slide joint in equality constraint"))),
            };
            scalar("joint1", joint1)?;
            if let Some(joint2) = joint2 {
                scalar("joint2", joint2)?;
            }
            if joint2.as_ref() == Some(joint1) {
                return Err(at.invalid("joint1 and joint2 name the same joint in equality constraint"));
            }
            EqualityKind::Joint { joint1: joint1.clone(), joint2: joint2.clone(), polycoef: *polycoef }
        }
        KindSpec::Tendon { tendon1, tendon2, polycoef } => {
            let tendon1 = targets.equality_tendon(at, tendon1)?;
            let tendon2 = tendon2.as_deref().map(|name| targets.equality_tendon(at, name)).transpose()?;
            if tendon2 == Some(tendon1) {
                return Err(at.invalid("tendon1 and tendon2 name the same tendon in equality constraint"));
            }
            EqualityKind::Tendon { tendon1, tendon2, polycoef: *polycoef }
        }
        KindSpec::Connect { objects: names, anchor } => {
            EqualityKind::Connect { objects: compile_objects(at, names, targets)?, anchor: *anchor }
        }
        &KindSpec::Weld { objects: ref names, anchor, relpose, torquescale } => {
            EqualityKind::Weld { objects: compile_objects(at, names, targets)?, anchor, relpose, torquescale }
        }
    };
    Ok(Equality {
        name: spec.name.clone(),
        kind,
        active: spec.settings.active,
        soft: spec.settings.soft,
        line: at.line,
    })
}

/// The frames a connect or weld holds, looked up; not a body with itself.
fn compile_objects(
    at: &Origin,
    names: &ObjectsSpec,
    targets: &impl EqualityTargets,
) -> Result<EqualityObjects, MjcfError> {
    let objects = match names {
        ObjectsSpec::Bodies(body1, body2) => {
            let body2 = body2.as_deref().map(|name| targets.equality_body(at, name)).transpose()?.flatten();
            EqualityObjects::Bodies(targets.equality_body(at, body1)?, body2)
        }
        ObjectsSpec::Sites(site1, site2) => EqualityObjects::Sites(
            targets.equality_site(at, "site1", site1)?,
            targets.equality_site(at, "site2", site2)?,
        ),
    };
    let same = match objects {
        EqualityObjects::Bodies(a, b) => a == b,
        EqualityObjects::Sites(a, b) => a == b,
    };
    if same {
        return Err(at.invalid("an equality constraint must join two different frames"));
    }
    Ok(objects)
}
