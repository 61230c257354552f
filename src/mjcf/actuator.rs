//! Actuator elements, in `<actuator>` and in `<default>`: `<general>` and the
//! shortcuts `<motor>`, `<position>`, `<velocity>`, `<damper>`,
//! `<intvelocity>` and `<cylinder>`, resolved into MuJoCo's one general
//! actuator as MuJoCo 4.0's parser does.
//!
//! MuJoCo 4.0's rules for defaults (its Modeling chapter, "Shortcuts"): a
//! default class has a single actuator default, written with `<general>` or
//! a shortcut. An actuator inherits its class's mechanical attributes
//! (`gear`, `ctrlrange`, ...) whatever the default was written with. A
//! shortcut sets its whole table of gain, bias and dynamics parameters; its
//! own parameters (`kp`, `kv`, ...) come from the element, else from the
//! nearest class (this one, then its ancestors) whose default was written
//! with the same shortcut, or with `<general>` of the shortcut's gain type
//! (whose raw parameters are read as the shortcut's), else from the
//! shortcut's documented defaults. `<general>` overwrites only the
//! attributes it gives.

use super::attributes::{Attribute, names, read_into, set};
use super::defaults::Limited;
use super::element::{Element, Origin};
use super::error::MjcfError;
use crate::vehicle::{ActivationKind, ActuatorKind, BiasType, GainType};

/// Attributes every actuator element reads into the general actuator, in
/// `<actuator>` and in `<default>` (MuJoCo 4.0 schema; `ctrllimited` is not
/// an attribute of `<damper>`, whose ctrl is always limited), and how each
/// is read. `nsample`, `interp`, `lengthrange` and `cranklength` are read
/// for their syntax: without a delay or a slider-crank (both refused) they
/// change nothing nudyn computes.
pub(crate) const COMMON_ATTRIBUTES: &[Attribute<ActuatorSettings>] = &[
    Attribute::into("group", |s, e, a| set(&mut s.group, e.integers(a)?.map(|[group]| group))),
    Attribute::checked("nsample", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::checked("interp", |e, a| e.keyword(a, &[("zoh", ()), ("linear", ()), ("cubic", ())]).map(drop)),
    Attribute::into("delay", |s, e, a| set(&mut s.delay, e.number(a)?)),
    Attribute::into("ctrllimited", |s, e, a| set(&mut s.ctrllimited, e.keyword(a, &LIMITED)?)),
    Attribute::into("ctrlrange", |s, e, a| set(&mut s.ctrlrange, e.numbers(a)?)),
    Attribute::into("forcelimited", |s, e, a| set(&mut s.forcelimited, e.keyword(a, &LIMITED)?)),
    Attribute::into("forcerange", |s, e, a| set(&mut s.forcerange, e.numbers(a)?)),
    Attribute::checked("lengthrange", |e, a| e.numbers::<2>(a).map(drop)),
    Attribute::into("gear", |s, e, a| e.overwrite_numbers(a, &mut s.gear)),
    Attribute::checked("cranklength", |e, a| e.number(a).map(drop)),
    Attribute::no_effect("user"),
    Attribute::into("damping", |s, e, a| e.overwrite_numbers(a, &mut s.damping)),
    Attribute::into("armature", |s, e, a| set(&mut s.armature, e.number(a)?)),
];

/// The keywords of `ctrllimited`, `forcelimited` and `actlimited`.
const LIMITED: [(&str, Limited); 3] = [("false", Limited::No), ("true", Limited::Yes), ("auto", Limited::Auto)];

/// Attributes that only `<general>` has, besides the common ones; it
/// overwrites only those it gives. `ffrange` and `velrange` are read for
/// their syntax.
pub(crate) const GENERAL_ATTRIBUTES: &[Attribute<ActuatorSettings>] = &[
    Attribute::into("actdim", |s, e, a| set(&mut s.actdim, e.integers(a)?.map(|[actdim]| actdim))),
    Attribute::into("actearly", |s, e, a| set(&mut s.actearly, e.boolean(a)?)),
    Attribute::into("actlimited", |s, e, a| set(&mut s.actlimited, e.keyword(a, &LIMITED)?)),
    Attribute::into("actrange", |s, e, a| set(&mut s.actrange, e.numbers(a)?)),
    Attribute::into("biasprm", |s, e, a| e.overwrite_numbers(a, &mut s.biasprm)),
    Attribute::into("biastype", |s, e, a| set(&mut s.biastype, e.keyword(a, &BIAS_TYPES)?)),
    Attribute::into("dynprm", |s, e, a| e.overwrite_numbers(a, &mut s.dynprm)),
    Attribute::into("dyntype", |s, e, a| set(&mut s.dyntype, e.keyword(a, &DYNAMICS_TYPES)?)),
    Attribute::checked("ffrange", |e, a| e.numbers::<2>(a).map(drop)),
    Attribute::into("gainprm", |s, e, a| e.overwrite_numbers(a, &mut s.gainprm)),
    Attribute::into("gaintype", |s, e, a| set(&mut s.gaintype, e.keyword(a, &GAIN_TYPES)?)),
    Attribute::into("inheritrange", |s, e, a| set(&mut s.inheritrange, e.number(a)?)),
    Attribute::no_effect("input"),
    Attribute::checked("velrange", |e, a| e.numbers::<2>(a).map(drop)),
];

/// `<position>`'s own attributes. Its gains and time constant are read by
/// [`ActuatorSettings::apply`] together: what one element does not give
/// comes from the class that lends it, and `kv` excludes `dampratio`.
const POSITION_ATTRIBUTES: &[Attribute<ActuatorSettings>] = &[
    Attribute::by_reader("kp"),
    Attribute::by_reader("kv"),
    Attribute::by_reader("dampratio"),
    Attribute::by_reader("timeconst"),
    Attribute::into("inheritrange", |s, e, a| set(&mut s.inheritrange, e.number(a)?)),
];

/// `<velocity>`'s and `<damper>`'s own attribute, read like `<position>`'s gains.
const KV_ATTRIBUTES: &[Attribute<ActuatorSettings>] = &[Attribute::by_reader("kv")];

/// `<intvelocity>`'s own attributes: `<position>`'s gains (no filter), and
/// the range of the integrated command, given or inherited from the target.
/// MuJoCo 4.0 sets `actlimited` itself (limited when the range is
/// increasing), whatever the element or its class writes.
const INTVELOCITY_ATTRIBUTES: &[Attribute<ActuatorSettings>] = &[
    Attribute::by_reader("kp"),
    Attribute::by_reader("kv"),
    Attribute::by_reader("dampratio"),
    Attribute::into("inheritrange", |s, e, a| set(&mut s.inheritrange, e.number(a)?)),
    Attribute::into("actrange", |s, e, a| set(&mut s.actrange, e.numbers(a)?)),
    Attribute::checked("actlimited", |e, a| e.keyword(a, &LIMITED).map(drop)),
];

/// `<cylinder>`'s own attributes, read by [`ActuatorSettings::apply`]
/// together: its time constant, its area (or diameter) as gain, its bias.
const CYLINDER_ATTRIBUTES: &[Attribute<ActuatorSettings>] = &[
    Attribute::by_reader("timeconst"),
    Attribute::by_reader("area"),
    Attribute::by_reader("diameter"),
    Attribute::by_reader("bias"),
];

/// Attributes that name the actuator, its class and its transmission target
/// (not allowed in `<default>`), read by the reader.
const TARGET_ATTRIBUTES: &[Attribute<ActuatorSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("class"),
    Attribute::by_reader("joint"),
    Attribute::by_reader("jointinparent"),
    Attribute::by_reader("site"),
    Attribute::by_reader("refsite"),
    Attribute::by_reader("tendon"),
    Attribute::by_reader("cranksite"),
    Attribute::by_reader("slidersite"),
    Attribute::by_reader("body"),
];

/// The attributes an element of `kind` has besides the common ones.
pub(crate) fn own_attributes(kind: ActuatorKind) -> &'static [Attribute<ActuatorSettings>] {
    match kind {
        ActuatorKind::General => GENERAL_ATTRIBUTES,
        ActuatorKind::Motor => &[],
        ActuatorKind::Position => POSITION_ATTRIBUTES,
        ActuatorKind::Velocity | ActuatorKind::Damper => KV_ATTRIBUTES,
        ActuatorKind::IntVelocity => INTVELOCITY_ATTRIBUTES,
        ActuatorKind::Cylinder => CYLINDER_ATTRIBUTES,
    }
}

/// The actuator elements nudyn models, and the kind each stands for.
pub(crate) const ACTUATOR_KINDS: &[(&str, ActuatorKind)] = &[
    ("general", ActuatorKind::General),
    ("motor", ActuatorKind::Motor),
    ("position", ActuatorKind::Position),
    ("velocity", ActuatorKind::Velocity),
    ("damper", ActuatorKind::Damper),
    ("intvelocity", ActuatorKind::IntVelocity),
    ("cylinder", ActuatorKind::Cylinder),
];

/// The actuator kinds an element tag stands for, among those nudyn models.
pub(crate) fn kind_of(tag: &str) -> Option<ActuatorKind> {
    ACTUATOR_KINDS.iter().find(|(name, _)| *name == tag).map(|(_, kind)| *kind)
}

/// The actuator elements MuJoCo has that nudyn refuses, and why.
#[rustfmt::skip]
pub(crate) const REFUSED_ACTUATORS: &[(&str, &str)] = &[
    ("muscle", "muscle actuators (activation dynamics and muscle force curves)"),
    ("adhesion", "adhesion actuators act through contacts, which nudyn does not model"),
    ("pid", "pid actuators (their inputs and integral and slew states)"),
    ("orientation", "orientation servos (three outputs on a geodesic error)"),
    ("dcmotor", "dcmotor actuators (electrical and thermal states)"),
    ("plugin", "actuator plugins"),
];

/// Why nudyn refuses an actuator element MuJoCo has; `None` for a tag that
/// is no actuator element at all.
pub(crate) fn refusal(tag: &str) -> Option<&'static str> {
    REFUSED_ACTUATORS.iter().find(|(refused, _)| *refused == tag).map(|(_, reason)| *reason)
}

/// Why nudyn refuses an actuator's `dyntype` (all but none, integrator,
/// filter and filterexact).
pub(crate) fn dynamics_refusal(dyntype: &str) -> String {
    let reason = match dyntype {
        "muscle" => "muscle activation dynamics (time constants that depend on act and ctrl)",
        "pid" => "a pid controller's integral and slew states",
        "dcmotor" => "a dc motor's electrical and thermal states",
        _ => "user-defined activation dynamics (a callback MuJoCo calls, which an MJCF file does not carry)",
    };
    format!("dyntype \"{dyntype}\": {reason}")
}

/// The attributes an actuator element of `kind` may have.
pub(crate) fn attributes(kind: ActuatorKind, in_default: bool) -> Vec<&'static str> {
    let mut allowed = names(COMMON_ATTRIBUTES);
    if kind == ActuatorKind::Damper {
        allowed.retain(|a| *a != "ctrllimited");
    }
    allowed.extend(names(own_attributes(kind)));
    if !in_default {
        allowed.extend(names(TARGET_ATTRIBUTES));
    }
    allowed
}

/// MuJoCo's `gaintype` keywords.
const GAIN_TYPES: [(&str, &str); 7] = [
    ("fixed", "fixed"),
    ("affine", "affine"),
    ("muscle", "muscle"),
    ("dcmotor", "dcmotor"),
    ("pid", "pid"),
    ("so3", "so3"),
    ("user", "user"),
];

/// MuJoCo's `biastype` keywords.
const BIAS_TYPES: [(&str, &str); 6] = [
    ("none", "none"),
    ("affine", "affine"),
    ("muscle", "muscle"),
    ("dcmotor", "dcmotor"),
    ("so3", "so3"),
    ("user", "user"),
];

/// MuJoCo's `dyntype` keywords.
const DYNAMICS_TYPES: [(&str, &str); 8] = [
    ("none", "none"),
    ("integrator", "integrator"),
    ("filter", "filter"),
    ("filterexact", "filterexact"),
    ("pid", "pid"),
    ("dcmotor", "dcmotor"),
    ("muscle", "muscle"),
    ("user", "user"),
];

/// MuJoCo's general actuator as a class or an element sets it (the fields
/// of `mjsActuator` that matter here, and the element it was written with).
#[derive(Clone, Debug)]
pub(crate) struct ActuatorSettings {
    /// The element that last wrote the gain, bias and dynamics parameters.
    pub written_with: ActuatorKind,
    /// `gaintype` keyword.
    pub gaintype: &'static str,
    /// `gainprm`.
    pub gainprm: [f64; 10],
    /// `biastype` keyword.
    pub biastype: &'static str,
    /// `biasprm`.
    pub biasprm: [f64; 10],
    /// `dyntype` keyword.
    pub dyntype: &'static str,
    /// `dynprm`.
    pub dynprm: [f64; 10],
    /// `actdim` (−1: from `dyntype`).
    pub actdim: i32,
    /// `actearly`.
    pub actearly: bool,
    /// `gear`.
    pub gear: [f64; 6],
    /// `ctrllimited`.
    pub ctrllimited: Limited,
    /// `ctrlrange`.
    pub ctrlrange: [f64; 2],
    /// `forcelimited`.
    pub forcelimited: Limited,
    /// `forcerange`.
    pub forcerange: [f64; 2],
    /// `actlimited`.
    pub actlimited: Limited,
    /// `actrange`.
    pub actrange: [f64; 2],
    /// `inheritrange`.
    pub inheritrange: f64,
    /// `damping` (reflected damping on the target).
    pub damping: [f64; 3],
    /// `armature` (reflected inertia on the target).
    pub armature: f64,
    /// `group`.
    pub group: i32,
    /// `delay`.
    pub delay: f64,
}

impl Default for ActuatorSettings {
    /// MuJoCo's built-in general actuator: a unit-gain motor.
    fn default() -> Self {
        let mut gainprm = [0.0; 10];
        gainprm[0] = 1.0;
        let mut dynprm = [0.0; 10];
        dynprm[0] = 1.0;
        Self {
            written_with: ActuatorKind::General,
            gaintype: "fixed",
            gainprm,
            biastype: "none",
            biasprm: [0.0; 10],
            dyntype: "none",
            dynprm,
            actdim: -1,
            actearly: false,
            gear: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ctrllimited: Limited::Auto,
            ctrlrange: [0.0; 2],
            forcelimited: Limited::Auto,
            forcerange: [0.0; 2],
            actlimited: Limited::Auto,
            actrange: [0.0; 2],
            inheritrange: 0.0,
            damping: [0.0; 3],
            armature: 0.0,
            group: 0,
            delay: 0.0,
        }
    }
}

/// The gain type of a shortcut's table: a `<general>` default of this gain
/// type lends the shortcut its parameters.
fn shortcut_gain_type(kind: ActuatorKind) -> &'static str {
    match kind {
        ActuatorKind::Damper => "affine",
        _ => "fixed",
    }
}

/// A shortcut's table without activation dynamics (MuJoCo's dynprm[0] stays 1).
const NO_DYNAMICS: (&str, f64) = ("none", 1.0);

/// A servo's (`<position>`'s, `<intvelocity>`'s) kp and biasprm[2]: −kv, or
/// a positive damping ratio (resolved by the compiler); each from the
/// element, else from the class that lends them.
fn servo_gains(element: &Element, lender: Option<&ActuatorSettings>) -> Result<(f64, f64), MjcfError> {
    let kp = match element.number("kp")? {
        Some(kp) => kp,
        None => lender.map_or(1.0, |l| l.gainprm[0]),
    };
    let damping = match (element.number("kv")?, element.number("dampratio")?) {
        (Some(_), Some(_)) => return Err(element.invalid("kv and dampratio cannot both be defined")),
        (Some(kv), None) if kv < 0.0 => return Err(element.invalid("kv cannot be negative")),
        (Some(kv), None) => -kv,
        (None, Some(ratio)) if ratio < 0.0 => return Err(element.invalid("dampratio cannot be negative")),
        (None, Some(ratio)) => ratio,
        (None, None) => lender.map_or(0.0, |l| l.biasprm[2]),
    };
    Ok((kp, damping))
}

impl ActuatorSettings {
    /// Whether a shortcut of `kind` takes its parameters from these settings.
    pub fn lends_parameters_to(&self, kind: ActuatorKind) -> bool {
        self.written_with == kind
            || (self.written_with == ActuatorKind::General && self.gaintype == shortcut_gain_type(kind))
    }

    /// Overwrites the settings with what an element of `kind` gives. `lender`
    /// is where a shortcut's parameters come from when the element does not
    /// give them (see [`ActuatorSettings::lends_parameters_to`]).
    pub fn apply(
        &mut self,
        kind: ActuatorKind,
        element: &Element,
        lender: Option<&ActuatorSettings>,
    ) -> Result<(), MjcfError> {
        read_into(COMMON_ATTRIBUTES, self, element)?;
        read_into(own_attributes(kind), self, element)?;
        match kind {
            ActuatorKind::General => {}
            ActuatorKind::Motor => self.set_table("fixed", &[1.0], "none", &[], NO_DYNAMICS),
            ActuatorKind::Position => {
                self.settle_inherited_range(element, "ctrlrange")?;
                let (kp, damping) = servo_gains(element, lender)?;
                let timeconst = match element.number("timeconst")? {
                    Some(t) if t < 0.0 => return Err(element.invalid("timeconst cannot be negative")),
                    Some(t) => t,
                    None => lender.filter(|l| l.dyntype == "filterexact").map_or(0.0, |l| l.dynprm[0]),
                };
                let dynamics = if timeconst > 0.0 { ("filterexact", timeconst) } else { NO_DYNAMICS };
                self.set_table("fixed", &[kp], "affine", &[0.0, -kp, damping], dynamics);
            }
            ActuatorKind::IntVelocity => {
                self.settle_inherited_range(element, "actrange")?;
                let (kp, damping) = servo_gains(element, lender)?;
                self.set_table("fixed", &[kp], "affine", &[0.0, -kp, damping], ("integrator", 1.0));
                self.actlimited = Limited::Auto;
            }
            ActuatorKind::Cylinder => self.apply_cylinder(element, lender)?,
            ActuatorKind::Velocity => {
                let kv = match element.number("kv")? {
                    Some(kv) => kv,
                    None => lender.map_or(1.0, |l| l.gainprm[0]),
                };
                self.set_table("fixed", &[kv], "affine", &[0.0, 0.0, -kv], NO_DYNAMICS);
            }
            ActuatorKind::Damper => {
                let kv = match element.number("kv")? {
                    Some(kv) => kv,
                    None => lender.map_or(0.0, |l| -l.gainprm[2]),
                };
                if kv < 0.0 {
                    return Err(element.invalid("damping coefficient cannot be negative"));
                }
                self.set_table("affine", &[0.0, 0.0, -kv], "none", &[], NO_DYNAMICS);
                self.ctrllimited = Limited::Yes;
                if self.ctrlrange.iter().any(|&x| x < 0.0) {
                    return Err(element.invalid("damper control range cannot be negative"));
                }
            }
        }
        self.written_with = kind;
        Ok(())
    }

    /// A servo's range taken from its target (`inheritrange`: `range` is
    /// `<position>`'s ctrlrange, `<intvelocity>`'s actrange) excludes one
    /// written beside it, as MuJoCo 4.0 has it: both on one element are
    /// refused, and a range written on the element replaces the class's
    /// inheritrange (an inheritrange written on it replaces the class's
    /// range at compile).
    fn settle_inherited_range(&mut self, element: &Element, range: &str) -> Result<(), MjcfError> {
        if element.has(range) {
            if element.number("inheritrange")?.is_some_and(|r| r > 0.0) {
                return Err(element.invalid(format!("{range} and inheritrange cannot both be defined")));
            }
            self.inheritrange = 0.0;
        }
        Ok(())
    }

    /// `<cylinder>`: a filter with time constant `timeconst` on ctrl, gain
    /// `area` (π/4 `diameter`² when a diameter of at least 0 is given),
    /// affine bias `bias`; each from the element, else from the class that
    /// lends them, else MuJoCo's defaults (1, 1, 0).
    fn apply_cylinder(&mut self, element: &Element, lender: Option<&ActuatorSettings>) -> Result<(), MjcfError> {
        let timeconst = match element.number("timeconst")? {
            Some(t) => t,
            None => lender.map_or(1.0, |l| l.dynprm[0]),
        };
        let area = match (element.number("diameter")?.filter(|d| *d >= 0.0), element.number("area")?) {
            (Some(diameter), _) => std::f64::consts::FRAC_PI_4 * diameter * diameter,
            (None, Some(area)) => area,
            (None, None) => lender.map_or(1.0, |l| l.gainprm[0]),
        };
        let bias = match element.numbers::<3>("bias")? {
            Some(bias) => bias,
            None => lender.map_or([0.0; 3], |l| [l.biasprm[0], l.biasprm[1], l.biasprm[2]]),
        };
        self.set_table("fixed", &[area], "affine", &bias, ("filter", timeconst));
        Ok(())
    }

    /// A shortcut's table: the gain and bias types and parameters (the
    /// parameters not listed are 0), the activation's `dyntype` and
    /// `dynprm[0]`, never read early (MuJoCo 4.0 clears `actearly`; the
    /// activation's range stays the class's).
    fn set_table(
        &mut self,
        gaintype: &'static str,
        gain: &[f64],
        biastype: &'static str,
        bias: &[f64],
        (dyntype, dynprm): (&'static str, f64),
    ) {
        self.gaintype = gaintype;
        self.gainprm = [0.0; 10];
        self.gainprm[..gain.len()].copy_from_slice(gain);
        self.biastype = biastype;
        self.biasprm = [0.0; 10];
        self.biasprm[..bias.len()].copy_from_slice(bias);
        self.dynprm = [0.0; 10];
        (self.dyntype, self.dynprm[0]) = (dyntype, dynprm);
        self.actdim = -1;
        self.actearly = false;
    }
}

/// An actuator element as read: MuJoCo's general actuator with its
/// defaults resolved and its types checked, its transmission target by
/// name, for the compile stage.
#[derive(Clone, Debug)]
pub(crate) struct ActuatorSpec {
    /// The element, for messages.
    pub at: Origin,
    /// `name` as written.
    pub name: Option<String>,
    /// The element it was written with.
    pub kind: ActuatorKind,
    /// Its class's settings with its own attributes applied.
    pub settings: ActuatorSettings,
    /// `dyntype`, when it has an activation state.
    pub activation: Option<ActivationKind>,
    /// `gaintype`.
    pub gain_type: GainType,
    /// `biastype`.
    pub bias_type: BiasType,
    /// Where its force goes, by name.
    pub transmission: TransmissionSpec,
}

/// An actuator's transmission target, by name as written.
#[derive(Clone, Debug)]
pub(crate) enum TransmissionSpec {
    /// `joint` (or `jointinparent`: `in_parent`).
    Joint { name: String, in_parent: bool },
    /// `tendon`.
    Tendon(String),
    /// `site`, with `refsite` when given.
    Site { site: String, refsite: Option<String> },
}

/// Reads an actuator element of `kind` whose class's settings, with the
/// element's own applied, are `settings`, with MuJoCo's checks of what it
/// gives, refusing what nudyn does not model; its target is looked up at
/// compile.
pub(crate) fn parse(
    element: &Element,
    kind: ActuatorKind,
    settings: ActuatorSettings,
) -> Result<ActuatorSpec, MjcfError> {
    let transmission = transmission(element)?;
    let activation = match settings.dyntype {
        "none" => None,
        "integrator" => Some(ActivationKind::Integrator),
        "filter" => Some(ActivationKind::Filter),
        "filterexact" => Some(ActivationKind::FilterExact),
        other => return Err(element.unsupported(dynamics_refusal(other))),
    };
    let gain_type = match settings.gaintype {
        "fixed" => GainType::Fixed,
        "affine" => GainType::Affine,
        other => return Err(element.unsupported(format!("gaintype \"{other}\" (nudyn models fixed and affine gains)"))),
    };
    let bias_type = match settings.biastype {
        "none" => BiasType::None,
        "affine" => BiasType::Affine,
        other => return Err(element.unsupported(format!("biastype \"{other}\" (nudyn models none and affine biases)"))),
    };
    if settings.delay > 0.0 {
        return Err(element.unsupported("delay: the force would follow a ctrl history, which nudyn does not keep"));
    }
    if settings.armature != 0.0 || settings.damping != [0.0; 3] {
        return Err(element
            .unsupported("actuator armature and damping; give the joint armature·gear² and damping·gear² instead"));
    }
    match (settings.actdim, activation) {
        (2.., _) => return Err(element.invalid("actdim > 1 is only allowed for dyntype \"user\" and \"dcmotor\"")),
        (1, None) => return Err(element.invalid("invalid actdim 1 in stateless actuator")),
        (0, Some(_)) => return Err(element.invalid("invalid actdim 0 in stateful actuator")),
        _ => {}
    }
    let name = element.text("name").map(str::to_string);
    Ok(ActuatorSpec { at: element.origin(), name, kind, settings, activation, gain_type, bias_type, transmission })
}

/// Actuator attributes naming a transmission nudyn refuses, and why.
#[rustfmt::skip]
pub(crate) const REFUSED_TRANSMISSIONS: &[(&str, &str)] = &[
    ("cranksite", "slider-crank transmissions"),
    ("slidersite", "slider-crank transmissions"),
    ("body", "body transmissions act through contacts, which nudyn does not model"),
];

/// The transmission an actuator element names: a joint, a tendon, or a
/// site with an optional reference site. Slider-crank and body
/// transmissions are refused.
fn transmission(element: &Element) -> Result<TransmissionSpec, MjcfError> {
    for (attribute, reason) in REFUSED_TRANSMISSIONS {
        if element.has(attribute) {
            return Err(element.unsupported(*reason));
        }
    }
    let mut targets = ["joint", "jointinparent", "tendon", "site"].into_iter().filter(|a| element.has(a));
    let target = targets.next();
    if let (Some(first), Some(second)) = (target, targets.next()) {
        return Err(element.conflict(first, second));
    }
    if element.has("cranklength") && target.is_some() {
        return Err(element.invalid("cranklength and slidersite can only be used in slidercrank transmission"));
    }
    if element.has("refsite") && target != Some("site") {
        return Err(element.invalid("refsite can only be used with site transmission"));
    }
    let Some(target) = target else {
        return Err(element.invalid("missing transmission target for actuator"));
    };
    let name = element.text(target).unwrap_or_default().to_string();
    Ok(match target {
        "tendon" => TransmissionSpec::Tendon(name),
        "site" => TransmissionSpec::Site { site: name, refsite: element.text("refsite").map(str::to_string) },
        _ => TransmissionSpec::Joint { name, in_parent: target == "jointinparent" },
    })
}
