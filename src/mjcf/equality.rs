//! `<equality>`: connect, weld, joint and tendon constraints, with MuJoCo
//! 4.0's attributes, defaults and compiler checks. Flex equalities are
//! refused (nudyn models no flexes).

use super::attributes::{Attribute, Read, names, read_into, set};
use super::element::Element;
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
/// lookup gives the error that names the element and attribute.
pub(crate) trait EqualityTargets {
    /// The body the attribute names: `None` for "world".
    fn equality_body(&self, element: &Element, attribute: &str) -> Result<Option<usize>, MjcfError>;
    /// The site the attribute names.
    fn equality_site(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError>;
    /// The tendon the attribute names.
    fn equality_tendon(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError>;
    /// The kind of the joint the attribute names.
    fn equality_joint(&self, element: &Element, attribute: &str) -> Result<JointKind, MjcfError>;
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

/// Reads one element of `<equality>` whose class settings are `settings`.
pub(crate) fn read(
    element: &Element,
    mut settings: EqualitySettings,
    targets: &impl EqualityTargets,
) -> Result<Equality, MjcfError> {
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
    let kind = match element.tag() {
        "joint" => {
            let joint1 = element.text("joint1").ok_or_else(|| element.missing("joint1"))?;
            let scalar = |attribute: &str| match targets.equality_joint(element, attribute)? {
                JointKind::Hinge | JointKind::Slide => Ok(()),
                _ => Err(element.invalid(format!("{attribute} must be a hinge or slide joint in equality constraint"))),
            };
            scalar("joint1")?;
            let joint2 = element.text("joint2");
            if joint2.is_some() {
                scalar("joint2")?;
            }
            if joint2 == Some(joint1) {
                return Err(element.invalid("joint1 and joint2 name the same joint in equality constraint"));
            }
            EqualityKind::Joint { joint1: joint1.to_string(), joint2: joint2.map(str::to_string), polycoef }
        }
        "tendon" => {
            if !element.has("tendon1") {
                return Err(element.missing("tendon1"));
            }
            let tendon1 = targets.equality_tendon(element, "tendon1")?;
            let tendon2 = match element.has("tendon2") {
                true => Some(targets.equality_tendon(element, "tendon2")?),
                false => None,
            };
            if tendon2 == Some(tendon1) {
                return Err(element.invalid("tendon1 and tendon2 name the same tendon in equality constraint"));
            }
            EqualityKind::Tendon { tendon1, tendon2, polycoef }
        }
        tag => {
            let objects = objects(element, targets)?;
            if tag == "connect" {
                if matches!(objects, EqualityObjects::Bodies(..)) && !element.has("anchor") {
                    return Err(element.missing("anchor"));
                }
                EqualityKind::Connect { objects, anchor: Vec3::from(anchor) }
            } else {
                let quat = [relpose[3], relpose[4], relpose[5], relpose[6]];
                let relpose = (quat != [0.0; 4]).then(|| {
                    let q = Quat::from_quaternion(nalgebra::Quaternion::new(quat[0], quat[1], quat[2], quat[3]));
                    (Vec3::new(relpose[0], relpose[1], relpose[2]), q)
                });
                EqualityKind::Weld { objects, anchor: Vec3::from(anchor), relpose, torquescale }
            }
        }
    };
    Ok(Equality {
        name: element.text("name").map(str::to_string),
        kind,
        active: settings.active,
        soft: settings.soft,
        line: element.line,
    })
}

/// The frames a connect or weld holds: two bodies (body2 the world when
/// left out) or two sites, not a mix, not a body with itself; sites take no
/// `anchor` (nor `relpose`, for a weld).
fn objects(element: &Element, targets: &impl EqualityTargets) -> Result<EqualityObjects, MjcfError> {
    let with_bodies = element.has("body1") || element.has("body2");
    let with_sites = element.has("site1") || element.has("site2");
    let objects = match (with_bodies, with_sites) {
        (true, true) => return Err(element.invalid("body and site semantics cannot be mixed in equality constraint")),
        (false, false) => return Err(element.invalid("either body1 or site1 must be given in equality constraint")),
        (true, false) => {
            if !element.has("body1") {
                return Err(element.missing("body1"));
            }
            let body2 = if element.has("body2") { targets.equality_body(element, "body2")? } else { None };
            EqualityObjects::Bodies(targets.equality_body(element, "body1")?, body2)
        }
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
            for attribute in ["site1", "site2"] {
                if !element.has(attribute) {
                    return Err(element.missing(attribute));
                }
            }
            EqualityObjects::Sites(targets.equality_site(element, "site1")?, targets.equality_site(element, "site2")?)
        }
    };
    let same = match objects {
        EqualityObjects::Bodies(a, b) => a == b,
        EqualityObjects::Sites(a, b) => a == b,
    };
    if same {
        return Err(element.invalid("an equality constraint must join two different frames"));
    }
    Ok(objects)
}
