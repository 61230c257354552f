//! Sensor elements in `<sensor>`: what each measures, with MuJoCo 4.0's
//! compiler checks, and the refusal of the sensor types nudyn does not
//! compute (so that `sensordata` keeps MuJoCo's layout or the import stops).

use super::attributes::{Attribute, names, read_into, set};
use super::element::{Element, Origin};
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
/// the error that names the element (`at`) and attribute.
pub(crate) trait SensorTargets {
    /// The kind of the joint `name`.
    fn joint_kind(&self, at: &Origin, name: &str) -> Result<JointKind, MjcfError>;
    /// Whether the joint `name` is limited.
    fn joint_limited(&self, at: &Origin, name: &str) -> Result<bool, MjcfError>;
    /// The body `name`; `None` for "world".
    fn body(&self, at: &Origin, name: &str) -> Result<Option<usize>, MjcfError>;
    /// The site `name`, which the attribute gives.
    fn site(&self, at: &Origin, attribute: &str, name: &str) -> Result<usize, MjcfError>;
    /// The actuator `name`.
    fn actuator(&self, at: &Origin, name: &str) -> Result<usize, MjcfError>;
    /// The tendon `name`.
    fn tendon(&self, at: &Origin, name: &str) -> Result<usize, MjcfError>;
    /// Whether the tendon `name` is limited.
    fn tendon_limited(&self, at: &Origin, name: &str) -> Result<bool, MjcfError>;
    /// The name the attribute gives as `written` (in a `<replicate>` copy, the copy's).
    fn name(&self, attribute: &str, written: &str) -> String;
    /// The element's own name as `written` (in a `<replicate>` copy, the copy's).
    fn own_name(&self, written: Option<&str>) -> Option<String>;
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

/// The kinds of frame a frame sensor measures or measures in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum FrameType {
    /// `body`: the body's inertial frame (as MuJoCo names them).
    Body,
    /// `xbody`: the body's own frame.
    XBody,
    /// `site`.
    Site,
}

/// A sensor element as read: its settings checked, the objects it names by
/// name, for the compile stage.
#[derive(Clone, Debug)]
pub(crate) struct SensorSpec {
    /// The element, for messages.
    pub at: Origin,
    /// `name` as written.
    pub name: Option<String>,
    /// Its type.
    pub kind: SensorKind,
    /// `cutoff`.
    pub cutoff: f64,
    /// The objects it names: each attribute given and its name as written.
    pub names: Vec<(&'static str, String)>,
    /// A frame sensor's `objtype` and `reftype` (when given).
    pub frame: Option<(FrameType, Option<FrameType>)>,
}

impl SensorSpec {
    /// The name the attribute gives as written ("" when not given).
    fn written(&self, attribute: &str) -> &str {
        self.names.iter().find(|(a, _)| *a == attribute).map_or("", |(_, name)| name.as_str())
    }
}

/// Reads one sensor element of a type nudyn computes, with MuJoCo's checks
/// of what it gives; the objects it names are looked up by [`compile`].
pub(crate) fn parse(element: &Element, kind: SensorKind) -> Result<SensorSpec, MjcfError> {
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
    // A frame sensor names its frame by type and name (its reference frame
    // likewise, or not at all); any other but the clock names one object.
    let mut frame = None;
    if names(own_attributes(kind)).contains(&"objtype") {
        let object = frame_type(element, "objtype", "objname")?;
        let reference = match (element.has("reftype"), element.has("refname")) {
            (false, false) => None,
            (true, true) => Some(frame_type(element, "reftype", "refname")?),
            _ => return Err(element.invalid("attributes 'reftype', 'refname' must be specified together")),
        };
        frame = Some((object, reference));
    } else if let Some(attribute) = own_attributes(kind).first().map(|a| a.name)
        && !element.has(attribute)
    {
        return Err(element.missing(attribute));
    }
    let own = names(own_attributes(kind)).into_iter().filter(|a| !["objtype", "reftype"].contains(a));
    let names = own.filter_map(|a| element.text(a).map(|name| (a, name.to_string()))).collect();
    let name = element.text("name").map(str::to_string);
    Ok(SensorSpec { at: element.origin(), name, kind, cutoff, names, frame })
}

/// The type of frame `type_attribute` gives, `name_attribute` naming it.
fn frame_type(element: &Element, type_attribute: &str, name_attribute: &str) -> Result<FrameType, MjcfError> {
    let objtype = element.text(type_attribute).ok_or_else(|| element.missing(type_attribute))?;
    if !element.has(name_attribute) {
        return Err(element.missing(name_attribute));
    }
    Ok(match objtype {
        "body" => FrameType::Body,
        "xbody" => FrameType::XBody,
        "site" => FrameType::Site,
        "geom" | "camera" => {
            return Err(element.unsupported(format!(
                "{type_attribute} \"{objtype}\": nudyn keeps no {objtype} frames; put a site where the {objtype} is"
            )));
        }
        _ => return Err(element.bad_value(type_attribute, "body, xbody, geom, site or camera")),
    })
}

/// The sensor `spec` describes, the objects it names looked up in
/// `targets` and checked as MuJoCo's compiler checks them.
pub(crate) fn compile(spec: &SensorSpec, targets: &impl SensorTargets) -> Result<Sensor, MjcfError> {
    use SensorKind::*;
    let at = &spec.at;
    let name = |attribute: &str| targets.name(attribute, spec.written(attribute));
    let target = match spec.kind {
        JointPos | JointVel | JointActuatorFrc | BallQuat | BallAngVel => {
            let joint = name("joint");
            let ball = matches!(spec.kind, BallQuat | BallAngVel);
            match (ball, targets.joint_kind(at, &joint)?) {
                (true, JointKind::Ball) | (false, JointKind::Hinge | JointKind::Slide) => {}
                (true, _) => return Err(at.invalid("joint must be ball in sensor")),
                (false, _) => return Err(at.invalid("joint must be slide or hinge in sensor")),
            }
            SensorTarget::Joint(joint)
        }
        JointLimitPos | JointLimitVel | JointLimitFrc => {
            let joint = name("joint");
            if !targets.joint_limited(at, &joint)? {
                return Err(at.invalid("joint must be limited in sensor"));
            }
            SensorTarget::Joint(joint)
        }
        ActuatorPos | ActuatorVel | ActuatorFrc => SensorTarget::Actuator(targets.actuator(at, &name("actuator"))?),
        TendonPos | TendonVel | TendonActuatorFrc => SensorTarget::Tendon(targets.tendon(at, &name("tendon"))?),
        TendonLimitPos | TendonLimitVel | TendonLimitFrc => {
            let tendon = name("tendon");
            if !targets.tendon_limited(at, &tendon)? {
                return Err(at.invalid("tendon must be limited in sensor"));
            }
            SensorTarget::Tendon(targets.tendon(at, &tendon)?)
        }
        Gyro | Velocimeter | Accelerometer | Force | Torque | Magnetometer => {
            let site = targets.site(at, "site", &name("site"))?;
            SensorTarget::Frame { object: FrameObject::Site(site), reference: None }
        }
        SubtreeCom | SubtreeLinVel | SubtreeAngMom => SensorTarget::Subtree(targets.body(at, &name("body"))?),
        // The frame sensors, and the clock (which names no frame).
        _ => match spec.frame {
            Some((object_type, reference_type)) => {
                let object = frame_object(at, object_type, "objname", &name("objname"), targets)?;
                let reference = reference_type
                    .map(|reference_type| frame_object(at, reference_type, "refname", &name("refname"), targets))
                    .transpose()?;
                SensorTarget::Frame { object, reference }
            }
            None => SensorTarget::None,
        },
    };
    Ok(Sensor {
        name: targets.own_name(spec.name.as_deref()),
        kind: spec.kind,
        target,
        cutoff: spec.cutoff,
        line: at.line,
    })
}

/// The frame of type `frame_type` named `name` (which `attribute` gives).
fn frame_object(
    at: &Origin,
    frame_type: FrameType,
    attribute: &str,
    name: &str,
    targets: &impl SensorTargets,
) -> Result<FrameObject, MjcfError> {
    Ok(match frame_type {
        FrameType::Body => FrameObject::Body(targets.body(at, name)?),
        FrameType::XBody => FrameObject::XBody(targets.body(at, name)?),
        FrameType::Site => FrameObject::Site(targets.site(at, attribute, name)?),
    })
}
