//! Sensor elements in `<sensor>`: what each measures, with MuJoCo 4.0's
//! compiler checks, and the refusal of the sensor types nudyn does not
//! compute (so that `sensordata` keeps MuJoCo's layout or the import stops).

use super::attributes::{Attribute, names, read_into, set};
use super::element::Element;
use super::error::MjcfError;
use crate::vehicle::{FrameObject, JointKind, Sensor, SensorKind, SensorTarget};

/// What a sensor element's attributes give besides the objects it names.
#[derive(Clone, Debug, Default)]
pub(crate) struct SensorSettings {
    /// `cutoff`: the bound on the sensor's value (0: none).
    pub cutoff: f64,
}

/// Attributes every sensor element has (MuJoCo 4.0 schema) and how each is
/// read; `nsample` and `interp` matter only with a delay, which is refused.
pub(crate) const COMMON_ATTRIBUTES: &[Attribute<SensorSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::checked("noise", |e, a| non_negative(e, a).map(drop)),
    Attribute::into("cutoff", |s, e, a| set(&mut s.cutoff, non_negative(e, a)?)),
    Attribute::no_effect("user"),
    Attribute::no_effect("nsample"),
    Attribute::no_effect("interp"),
    Attribute::checked("delay", refuse_history),
    Attribute::checked("interval", refuse_history),
];

/// A number MuJoCo's compiler refuses when negative.
fn non_negative(element: &Element, attribute: &str) -> Result<Option<f64>, MjcfError> {
    match element.number(attribute)? {
        Some(value) if value < 0.0 => Err(element.invalid(format!("negative {attribute} in sensor"))),
        value => Ok(value),
    }
}

/// Refuses a positive `delay` or `interval` (a period and an optional
/// phase: the period decides).
fn refuse_history(element: &Element, attribute: &str) -> Result<(), MjcfError> {
    let first = element.text(attribute).and_then(|text| text.split_whitespace().next());
    let value = match first.map(str::parse::<f64>) {
        None => 0.0,
        Some(Ok(value)) if value.is_finite() => value,
        Some(_) => return Err(element.bad_value(attribute, "a finite number")),
    };
    if value > 0.0 {
        return Err(element.unsupported(format!(
            "{attribute}: the sensor would report from a history of values, which nudyn does not keep"
        )));
    }
    Ok(())
}

/// The objects sensors name, as the importer knows them; each lookup gives
/// the error that names the element and attribute.
pub(crate) trait SensorTargets {
    /// The kind of the joint the attribute names.
    fn joint_kind(&self, element: &Element, attribute: &str) -> Result<JointKind, MjcfError>;
    /// Whether the joint the attribute names is limited.
    fn joint_limited(&self, element: &Element, attribute: &str) -> Result<bool, MjcfError>;
    /// The body the attribute names; `None` for "world".
    fn body(&self, element: &Element, attribute: &str) -> Result<Option<usize>, MjcfError>;
    /// The site the attribute names.
    fn site(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError>;
    /// The actuator the attribute names.
    fn actuator(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError>;
    /// The tendon the attribute names.
    fn tendon(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError>;
    /// Whether the tendon the attribute names is limited.
    fn tendon_limited(&self, element: &Element, attribute: &str) -> Result<bool, MjcfError>;
    /// The name the attribute gives (in a `<replicate>` copy, the copy's).
    fn name(&self, element: &Element, attribute: &str) -> String;
    /// The element's own name (in a `<replicate>` copy, the copy's).
    fn own_name(&self, element: &Element) -> Option<String>;
}

/// The sensor elements MuJoCo has that nudyn refuses, and why.
#[rustfmt::skip]
pub(crate) const REFUSED_SENSORS: &[(&[&str], &str)] = &[
    (&["touch", "rangefinder", "contact", "tactile", "insidesite", "geomdist", "geomnormal", "geomfromto"],
     "the sensor measures contacts or geometry, which nudyn does not model"),
    (&["camprojection"], "the sensor type is not computed by nudyn"),
    (&["e_potential", "e_kinetic"], "energy sensors are not computed by nudyn (the FMU has kinetic_energy)"),
    (&["user", "plugin"], "user and plugin sensors are computed by code nudyn does not have"),
];

/// Why nudyn refuses a sensor element MuJoCo has; `None` for a tag that is
/// no sensor element at all.
pub(crate) fn refusal(tag: &str) -> Option<&'static str> {
    REFUSED_SENSORS.iter().find(|(tags, _)| tags.contains(&tag)).map(|(_, reason)| *reason)
}

/// A sensor's own attributes: the objects it names, which the reader looks up.
type Targets = &'static [Attribute<SensorSettings>];
const SITE: Targets = &[Attribute::by_reader("site")];
const JOINT: Targets = &[Attribute::by_reader("joint")];
const ACTUATOR: Targets = &[Attribute::by_reader("actuator")];
const TENDON: Targets = &[Attribute::by_reader("tendon")];
const BODY: Targets = &[Attribute::by_reader("body")];
const OBJECT: Targets = &[Attribute::by_reader("objtype"), Attribute::by_reader("objname")];
const OBJECT_IN_REFERENCE: Targets = &[
    Attribute::by_reader("objtype"),
    Attribute::by_reader("objname"),
    Attribute::by_reader("reftype"),
    Attribute::by_reader("refname"),
];

/// The attributes of a sensor type besides the common ones.
fn own_attributes(kind: SensorKind) -> Targets {
    use SensorKind::*;
    match kind {
        Gyro | Velocimeter | Accelerometer | Force | Torque | Magnetometer => SITE,
        JointPos | JointVel | BallQuat | BallAngVel | JointActuatorFrc => JOINT,
        JointLimitPos | JointLimitVel | JointLimitFrc => JOINT,
        ActuatorPos | ActuatorVel | ActuatorFrc => ACTUATOR,
        TendonPos | TendonVel | TendonActuatorFrc | TendonLimitPos | TendonLimitVel | TendonLimitFrc => TENDON,
        FrameLinAcc | FrameAngAcc => OBJECT,
        FramePos | FrameQuat | FrameXAxis | FrameYAxis | FrameZAxis | FrameLinVel | FrameAngVel => OBJECT_IN_REFERENCE,
        SubtreeCom | SubtreeLinVel | SubtreeAngMom => BODY,
        Clock => &[],
    }
}

/// The attributes a sensor element of `kind` may have, in their tables' order.
pub(crate) fn attributes(kind: SensorKind) -> Vec<&'static str> {
    names(COMMON_ATTRIBUTES).into_iter().chain(names(own_attributes(kind))).collect()
}

/// Reads one sensor element of a type nudyn computes.
pub(crate) fn read(element: &Element, kind: SensorKind, targets: &impl SensorTargets) -> Result<Sensor, MjcfError> {
    element.check_attributes(&attributes(kind))?;
    if let Some(child) = element.children().next() {
        return Err(child.unknown());
    }
    let mut settings = SensorSettings::default();
    read_into(COMMON_ATTRIBUTES, &mut settings, element)?;
    let SensorSettings { cutoff } = settings;
    if cutoff > 0.0 && kind.is_direction() {
        return Err(element.invalid("cutoff applied to axis or quaternion datatype in sensor"));
    }
    let target = target(element, kind, targets)?;
    Ok(Sensor { name: targets.own_name(element), kind, target, cutoff, line: element.line })
}

/// What the sensor measures, checked as MuJoCo's compiler does.
fn target(element: &Element, kind: SensorKind, targets: &impl SensorTargets) -> Result<SensorTarget, MjcfError> {
    use SensorKind::*;
    let required = |attribute: &str| match element.has(attribute) {
        true => Ok(()),
        false => Err(element.missing(attribute)),
    };
    Ok(match kind {
        JointPos | JointVel | JointActuatorFrc | BallQuat | BallAngVel => {
            required("joint")?;
            let joint_kind = targets.joint_kind(element, "joint")?;
            let ball = matches!(kind, BallQuat | BallAngVel);
            match (ball, joint_kind) {
                (true, JointKind::Ball) | (false, JointKind::Hinge | JointKind::Slide) => {}
                (true, _) => return Err(element.invalid("joint must be ball in sensor")),
                (false, _) => return Err(element.invalid("joint must be slide or hinge in sensor")),
            }
            SensorTarget::Joint(targets.name(element, "joint"))
        }
        JointLimitPos | JointLimitVel | JointLimitFrc => {
            required("joint")?;
            if !targets.joint_limited(element, "joint")? {
                return Err(element.invalid("joint must be limited in sensor"));
            }
            SensorTarget::Joint(targets.name(element, "joint"))
        }
        ActuatorPos | ActuatorVel | ActuatorFrc => {
            required("actuator")?;
            SensorTarget::Actuator(targets.actuator(element, "actuator")?)
        }
        TendonPos | TendonVel | TendonActuatorFrc => {
            required("tendon")?;
            SensorTarget::Tendon(targets.tendon(element, "tendon")?)
        }
        TendonLimitPos | TendonLimitVel | TendonLimitFrc => {
            required("tendon")?;
            if !targets.tendon_limited(element, "tendon")? {
                return Err(element.invalid("tendon must be limited in sensor"));
            }
            SensorTarget::Tendon(targets.tendon(element, "tendon")?)
        }
        Gyro | Velocimeter | Accelerometer | Force | Torque | Magnetometer => {
            required("site")?;
            SensorTarget::Frame { object: FrameObject::Site(targets.site(element, "site")?), reference: None }
        }
        SubtreeCom | SubtreeLinVel | SubtreeAngMom => {
            required("body")?;
            SensorTarget::Subtree(targets.body(element, "body")?)
        }
        Clock => SensorTarget::None,
        _ => {
            let object = frame_object(element, "objtype", "objname", targets)?;
            let reference = match (element.has("reftype"), element.has("refname")) {
                (false, false) => None,
                (true, true) => Some(frame_object(element, "reftype", "refname", targets)?),
                _ => {
                    return Err(element.invalid("attributes 'reftype', 'refname' must be specified together"));
                }
            };
            SensorTarget::Frame { object, reference }
        }
    })
}

/// The frame `type_attribute` and `name_attribute` name.
fn frame_object(
    element: &Element,
    type_attribute: &str,
    name_attribute: &str,
    targets: &impl SensorTargets,
) -> Result<FrameObject, MjcfError> {
    let objtype = element.text(type_attribute).ok_or_else(|| element.missing(type_attribute))?;
    if !element.has(name_attribute) {
        return Err(element.missing(name_attribute));
    }
    Ok(match objtype {
        "body" => FrameObject::Body(targets.body(element, name_attribute)?),
        "xbody" => FrameObject::XBody(targets.body(element, name_attribute)?),
        "site" => FrameObject::Site(targets.site(element, name_attribute)?),
        "geom" | "camera" => {
            return Err(element.unsupported(format!(
                "{type_attribute} \"{objtype}\": nudyn keeps no {objtype} frames; put a site where the {objtype} is"
            )));
        }
        _ => return Err(element.bad_value(type_attribute, "body, xbody, geom, site or camera")),
    })
}
