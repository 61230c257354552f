//! `<tendon>`: fixed tendons (a linear combination of hinge and slide
//! joint values) and spatial tendons through sites, with MuJoCo 4.0's
//! attributes, defaults and compiler checks, wrapping around sphere and
//! cylinder geoms included (with a side site on the geom's body outside it;
//! one inside, through which MuJoCo passes the tendon, is refused).

use super::attributes::{Attribute, names, read_into, set};
use super::defaults::Limited;
use super::element::{Element, Origin};
use super::error::MjcfError;
use crate::vehicle::{JointKind, JointLimit, PathPoint, SoftConstraint, Tendon, TendonPath, WrapGeom};

/// `<fixed>` and `<spatial>` (MuJoCo 4.0 schema): their attributes and how
/// each is read; `<fixed>` takes all but [`SPATIAL_ONLY`], a `<default>`
/// class all but the name and class.
pub(crate) const TENDON_ATTRIBUTES: &[Attribute<TendonSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("class"),
    Attribute::no_effect("group"),
    Attribute::into("limited", |s, e, a| set(&mut s.limited, e.keyword(a, &LIMITED)?)),
    Attribute::into("actuatorfrclimited", |s, e, a| set(&mut s.actuator_force_limited, e.keyword(a, &LIMITED)?)),
    Attribute::into("range", |s, e, a| set(&mut s.range, e.numbers(a)?)),
    Attribute::into("actuatorfrcrange", |s, e, a| set(&mut s.actuator_force_range, e.numbers(a)?)),
    Attribute::into("solreflimit", |s, e, a| e.overwrite_numbers(a, &mut s.limit_soft.solref)),
    Attribute::into("solimplimit", |s, e, a| e.overwrite_numbers(a, &mut s.limit_soft.solimp)),
    Attribute::into("solreffriction", |s, e, a| e.overwrite_numbers(a, &mut s.friction_soft.solref)),
    Attribute::into("solimpfriction", |s, e, a| e.overwrite_numbers(a, &mut s.friction_soft.solimp)),
    Attribute::into("frictionloss", |s, e, a| set(&mut s.frictionloss, e.number(a)?)),
    Attribute::into("springlength", read_spring_length),
    Attribute::into("margin", |s, e, a| set(&mut s.margin, e.number(a)?)),
    Attribute::into("stiffness", |s, e, a| e.overwrite_numbers(a, &mut s.stiffness)),
    Attribute::into("damping", |s, e, a| e.overwrite_numbers(a, &mut s.damping)),
    Attribute::into("armature", |s, e, a| set(&mut s.armature, e.number(a)?)),
    Attribute::no_effect("user"),
    Attribute::into("springyield", |s, e, a| set(&mut s.springyield, e.number(a)?)),
    Attribute::no_effect("width"),
    Attribute::no_effect("material"),
    Attribute::no_effect("rgba"),
];

/// Attributes only `<spatial>` has: how it is drawn.
pub(crate) const SPATIAL_ONLY: &[&str] = &["width", "material", "rgba"];

/// The attributes of a `<fixed>` (`spatial` false) or `<spatial>` tendon.
pub(crate) fn tendon_attributes(spatial: bool) -> Vec<&'static str> {
    names(TENDON_ATTRIBUTES).into_iter().filter(|a| spatial || !SPATIAL_ONLY.contains(a)).collect()
}

/// The attributes a `<tendon>` default class may set.
pub(crate) fn default_attributes() -> Vec<&'static str> {
    names(TENDON_ATTRIBUTES).into_iter().filter(|a| !["name", "class"].contains(a)).collect()
}

/// The keywords of `limited` and `actuatorfrclimited`.
const LIMITED: [(&str, Limited); 3] = [("false", Limited::No), ("true", Limited::Yes), ("auto", Limited::Auto)];

/// `springlength`: one value is a point, which MuJoCo repeats.
fn read_spring_length(settings: &mut TendonSettings, element: &Element, attribute: &str) -> Result<(), MjcfError> {
    let mut spring_length = [f64::NAN; 2];
    element.overwrite_numbers(attribute, &mut spring_length)?;
    if spring_length[1].is_nan() {
        spring_length[1] = spring_length[0];
    }
    settings.spring_length = spring_length;
    Ok(())
}

/// The numbers a path element gives; the names it gives (joint, site,
/// geom, side site) the reader looks up itself.
#[derive(Clone, Debug, Default)]
pub(crate) struct PathSettings {
    /// `<joint coef>`.
    pub coef: Option<f64>,
    /// `<pulley divisor>`.
    pub divisor: Option<f64>,
}

/// `<fixed>/<joint>` (MuJoCo 4.0 schema).
pub(crate) const FIXED_JOINT_ATTRIBUTES: &[Attribute<PathSettings>] =
    &[Attribute::by_reader("joint"), Attribute::into("coef", |s, e, a| set(&mut s.coef, e.number(a)?.map(Some)))];

/// `<spatial>/<site>`.
pub(crate) const SPATIAL_SITE_ATTRIBUTES: &[Attribute<PathSettings>] = &[Attribute::by_reader("site")];

/// `<spatial>/<pulley>`.
pub(crate) const PULLEY_ATTRIBUTES: &[Attribute<PathSettings>] =
    &[Attribute::into("divisor", |s, e, a| set(&mut s.divisor, e.number(a)?.map(Some)))];

/// `<spatial>/<geom>`.
pub(crate) const SPATIAL_GEOM_ATTRIBUTES: &[Attribute<PathSettings>] =
    &[Attribute::by_reader("geom"), Attribute::by_reader("sidesite")];

/// The path elements of each tendon and their attribute tables.
pub(crate) const PATH_ELEMENTS: &[(&str, &[Attribute<PathSettings>])] = &[
    ("fixed/joint", FIXED_JOINT_ATTRIBUTES),
    ("spatial/site", SPATIAL_SITE_ATTRIBUTES),
    ("spatial/pulley", PULLEY_ATTRIBUTES),
    ("spatial/geom", SPATIAL_GEOM_ATTRIBUTES),
];

/// A path element's numbers, its attributes checked against `table`.
fn path_settings(element: &Element, table: &[Attribute<PathSettings>]) -> Result<PathSettings, MjcfError> {
    element.check_attributes(&names(table))?;
    let mut settings = PathSettings::default();
    read_into(table, &mut settings, element)?;
    Ok(settings)
}

/// A tendon's attributes, as a class or an element sets them.
#[derive(Clone, Debug)]
pub(crate) struct TendonSettings {
    /// `limited`.
    pub limited: Limited,
    /// `range`.
    pub range: [f64; 2],
    /// `margin`.
    pub margin: f64,
    /// `solreflimit`, `solimplimit`.
    pub limit_soft: SoftConstraint,
    /// `frictionloss`.
    pub frictionloss: f64,
    /// `solreffriction`, `solimpfriction`.
    pub friction_soft: SoftConstraint,
    /// `springlength` (MuJoCo's −1 −1: the length in the spring pose).
    pub spring_length: [f64; 2],
    /// `stiffness`: the linear coefficient, then MuJoCo's nonlinear ones.
    pub stiffness: [f64; 3],
    /// `damping`, like `stiffness`.
    pub damping: [f64; 3],
    /// `armature`.
    pub armature: f64,
    /// `springyield`.
    pub springyield: f64,
    /// `actuatorfrclimited`.
    pub actuator_force_limited: Limited,
    /// `actuatorfrcrange`.
    pub actuator_force_range: [f64; 2],
}

impl Default for TendonSettings {
    /// MuJoCo's built-in tendon defaults.
    fn default() -> Self {
        TendonSettings {
            limited: Limited::Auto,
            range: [0.0; 2],
            margin: 0.0,
            limit_soft: SoftConstraint::default(),
            frictionloss: 0.0,
            friction_soft: SoftConstraint::default(),
            spring_length: [-1.0, -1.0],
            stiffness: [0.0; 3],
            damping: [0.0; 3],
            armature: 0.0,
            springyield: 0.0,
            actuator_force_limited: Limited::Auto,
            actuator_force_range: [0.0; 2],
        }
    }
}

impl TendonSettings {
    /// Overwrites the settings the element gives.
    pub fn apply(&mut self, element: &Element) -> Result<(), MjcfError> {
        read_into(TENDON_ATTRIBUTES, self, element)
    }
}

/// The objects tendon elements name, as the importer knows them; each
/// lookup gives the error that names the element (`at`) and attribute.
pub(crate) trait TendonTargets {
    /// The kind of the joint `name`.
    fn tendon_joint(&self, at: &Origin, name: &str) -> Result<JointKind, MjcfError>;
    /// The site `name`, which the attribute gives.
    fn tendon_site(&self, at: &Origin, attribute: &str, name: &str) -> Result<usize, MjcfError>;
    /// The sphere or cylinder geom `name`.
    fn tendon_geom(&self, at: &Origin, name: &str) -> Result<WrapGeom, MjcfError>;
    /// The side site `name`, which the attribute gives, for wrapping around `geom`.
    fn tendon_side_site(&self, at: &Origin, attribute: &str, name: &str, geom: &WrapGeom) -> Result<usize, MjcfError>;
}

/// What the `<flag>`s leave of a tendon's terms.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TendonFlags {
    /// `<flag spring="disable">`.
    pub spring_disabled: bool,
    /// `<flag damper="disable">`.
    pub damper_disabled: bool,
    /// `<flag frictionloss="disable">` or `constraint="disable"`.
    pub frictionloss_disabled: bool,
    /// `<flag limit="disable">` or `constraint="disable"`.
    pub limit_disabled: bool,
}

/// A `<fixed>` or `<spatial>` element as read: its settings resolved and
/// checked, the objects of its path by name, for the compile stage.
#[derive(Clone, Debug)]
pub(crate) struct TendonSpec {
    /// The element, for messages.
    pub at: Origin,
    /// `name`.
    pub name: Option<String>,
    /// Its class's settings with its own attributes applied.
    pub settings: TendonSettings,
    /// Whether it is limited (MuJoCo's tendon_limited, before any flag).
    pub limited: bool,
    /// Whether `actuatorfrcrange` applies.
    pub force_limited: bool,
    /// Whether `armature` comes from its default class (for messages).
    pub armature_from_class: bool,
    /// Its path, the objects by name.
    pub path: PathSpec,
}

/// A tendon's path as read.
#[derive(Clone, Debug)]
pub(crate) enum PathSpec {
    /// `<fixed>`: each `<joint>`, its name and `coef`.
    Fixed(Vec<(Origin, String, f64)>),
    /// `<spatial>`: its `<site>`, `<pulley>` and `<geom>` children.
    Spatial(Vec<PointSpec>),
}

/// A child of a `<spatial>` tendon as read.
#[derive(Clone, Debug)]
pub(crate) enum PointSpec {
    /// `<site site>`.
    Site(Origin, String),
    /// `<pulley divisor>`.
    Pulley(f64),
    /// `<geom geom sidesite>`.
    Geom(Origin, String, Option<String>),
}

impl TendonSpec {
    /// The geoms its path wraps around, by name.
    pub fn wrap_geoms(&self) -> impl Iterator<Item = &str> {
        let points = match &self.path {
            PathSpec::Spatial(points) => points.as_slice(),
            PathSpec::Fixed(_) => &[],
        };
        points.iter().filter_map(|point| match point {
            PointSpec::Geom(_, geom, _) => Some(geom.as_str()),
            _ => None,
        })
    }
}

/// Reads one `<fixed>` or `<spatial>` element whose class settings are
/// `settings`, with MuJoCo's checks of its values (`autolimits`: the
/// `<compiler>`'s); the objects it names are looked up by [`compile`].
pub(crate) fn parse(
    element: &Element,
    mut settings: TendonSettings,
    autolimits: bool,
) -> Result<TendonSpec, MjcfError> {
    let spatial = match element.tag() {
        "fixed" => false,
        "spatial" => true,
        _ => return Err(element.unknown()),
    };
    element.check_attributes(&tendon_attributes(spatial))?;
    settings.apply(element)?;
    let origin = |attribute: &str| if element.has(attribute) { "" } else { " (from its default class)" };
    if settings.springyield != 0.0 {
        return Err(element.unsupported(format!("springyield{}: yielding springs", origin("springyield"))));
    }
    for (attribute, coefficients) in [("stiffness", &settings.stiffness), ("damping", &settings.damping)] {
        if coefficients[1..] != [0.0; 2] {
            return Err(
                element.unsupported(format!("nonlinear {attribute}{} (more than one coefficient)", origin(attribute)))
            );
        }
    }
    let [low, high] = settings.actuator_force_range;
    let force_limited = match settings.actuator_force_limited {
        Limited::Yes => true,
        Limited::No => false,
        Limited::Auto if !autolimits && (low, high) != (0.0, 0.0) => {
            return Err(element.invalid(format!(
                "tendon has actuatorfrcrange{} but not actuatorfrclimited while <compiler autolimits=\"false\">; \
                 give actuatorfrclimited or remove actuatorfrcrange",
                origin("actuatorfrcrange")
            )));
        }
        Limited::Auto => low < high,
    };
    // MuJoCo's: the sum is scaled into the range, which must hold zero.
    if force_limited && (low >= high || low > 0.0 || high < 0.0) {
        return Err(element.invalid(format!(
            "invalid actuatorfrcrange in tendon{}: ({low}, {high}) must have lower < upper and hold 0",
            origin("actuatorfrcrange")
        )));
    }
    let [low, high] = settings.spring_length;
    if !(low == -1.0 && high == -1.0) && low > high {
        return Err(element.invalid(format!("invalid springlength in tendon: {low} > {high}")));
    }
    let [range_low, range_high] = settings.range;
    let limited = match settings.limited {
        Limited::Yes => true,
        Limited::No => false,
        Limited::Auto => autolimits && range_low < range_high,
    };
    if limited && range_low >= range_high {
        return Err(element
            .invalid(format!("invalid limits in tendon: range ({range_low}, {range_high}) must have lower < upper")));
    }
    if settings.armature < 0.0 {
        return Err(element.invalid(format!("tendon armature cannot be negative{}", origin("armature"))));
    }
    let path = if spatial { parse_spatial_path(element)? } else { parse_fixed_path(element)? };
    Ok(TendonSpec {
        at: element.origin(),
        name: element.text("name").map(str::to_string),
        settings,
        limited,
        force_limited,
        armature_from_class: !element.has("armature"),
        path,
    })
}

/// A `<fixed>` tendon's `<joint joint coef>` children.
fn parse_fixed_path(element: &Element) -> Result<PathSpec, MjcfError> {
    let mut terms = Vec::new();
    for child in element.children() {
        if child.tag() != "joint" {
            return Err(child.unknown());
        }
        let settings = path_settings(&child, FIXED_JOINT_ATTRIBUTES)?;
        let name = child.text("joint").ok_or_else(|| child.missing("joint"))?;
        let coef = settings.coef.ok_or_else(|| child.missing("coef"))?;
        terms.push((child.origin(), name.to_string(), coef));
    }
    Ok(PathSpec::Fixed(terms))
}

/// A `<spatial>` tendon's `<site>`, `<geom>` and `<pulley>` children.
fn parse_spatial_path(element: &Element) -> Result<PathSpec, MjcfError> {
    let mut points = Vec::new();
    for child in element.children() {
        let required =
            |attribute: &str| child.text(attribute).map(str::to_string).ok_or_else(|| child.missing(attribute));
        points.push(match child.tag() {
            "site" => {
                path_settings(&child, SPATIAL_SITE_ATTRIBUTES)?;
                PointSpec::Site(child.origin(), required("site")?)
            }
            "pulley" => {
                let divisor = path_settings(&child, PULLEY_ATTRIBUTES)?.divisor;
                let divisor = divisor.ok_or_else(|| child.missing("divisor"))?;
                if divisor <= 0.0 {
                    return Err(child.bad_value("divisor", "a positive number"));
                }
                PointSpec::Pulley(divisor)
            }
            "geom" => {
                path_settings(&child, SPATIAL_GEOM_ATTRIBUTES)?;
                PointSpec::Geom(child.origin(), required("geom")?, child.text("sidesite").map(str::to_string))
            }
            _ => return Err(child.unknown()),
        });
    }
    Ok(PathSpec::Spatial(points))
}

/// The tendon `spec` describes: the objects of its path looked up in
/// `targets` and the path checked as MuJoCo checks it, less what the
/// `<flag>`s turn off.
pub(crate) fn compile(
    spec: &TendonSpec,
    targets: &impl TendonTargets,
    flags: TendonFlags,
) -> Result<Tendon, MjcfError> {
    let TendonSpec { at, settings, limited, force_limited, .. } = spec;
    let path = match &spec.path {
        PathSpec::Fixed(terms) => fixed_path(at, terms, targets)?,
        PathSpec::Spatial(points) => spatial_path(at, points, targets)?,
    };
    let wraps = matches!(&path, TendonPath::Spatial(points) if points.iter().any(|p| matches!(p, PathPoint::Geom(_))));
    if settings.armature > 0.0 && wraps {
        // MuJoCo 4.0 refuses the file: its J̇θ̇ of a wrapped path is not written.
        let origin = if spec.armature_from_class { " (from its default class)" } else { "" };
        return Err(at.invalid(format!("geom wrapping not supported by tendon armature{origin}")));
    }
    let unset = settings.spring_length == [-1.0, -1.0];
    Ok(Tendon {
        name: spec.name.clone(),
        path,
        stiffness: if flags.spring_disabled { 0.0 } else { settings.stiffness[0] },
        damping: if flags.damper_disabled { 0.0 } else { settings.damping[0] },
        armature: settings.armature,
        actuator_force_range: force_limited.then_some(settings.actuator_force_range),
        spring_length: (!unset).then_some(settings.spring_length),
        frictionloss: if flags.frictionloss_disabled { 0.0 } else { settings.frictionloss },
        friction: settings.friction_soft,
        limit: (*limited && !flags.limit_disabled).then_some(JointLimit {
            range: settings.range,
            margin: settings.margin,
            soft: settings.limit_soft,
        }),
        range: settings.range,
        line: at.line,
    })
}

/// A `<fixed>` tendon's terms: hinge and slide joints, each once.
fn fixed_path(
    at: &Origin,
    terms: &[(Origin, String, f64)],
    targets: &impl TendonTargets,
) -> Result<TendonPath, MjcfError> {
    let mut path: Vec<(String, f64)> = Vec::with_capacity(terms.len());
    for (child, name, coef) in terms {
        if !matches!(targets.tendon_joint(child, name)?, JointKind::Hinge | JointKind::Slide) {
            return Err(child.invalid(format!("joint '{name}' in a fixed tendon must be slide or hinge")));
        }
        if path.iter().any(|(known, _)| known == name) {
            return Err(child.invalid(format!("joint '{name}' is repeated in the tendon")));
        }
        path.push((name.clone(), *coef));
    }
    if path.is_empty() {
        return Err(at.invalid("the tendon's path cannot be empty"));
    }
    Ok(TendonPath::Fixed(path))
}

/// A `<spatial>` tendon's path, its objects looked up and checked as
/// MuJoCo checks the path.
fn spatial_path(at: &Origin, spec: &[PointSpec], targets: &impl TendonTargets) -> Result<TendonPath, MjcfError> {
    let mut points = Vec::with_capacity(spec.len());
    for point in spec {
        points.push(match point {
            PointSpec::Site(child, site) => PathPoint::Site(targets.tendon_site(child, "site", site)?),
            PointSpec::Pulley(divisor) => PathPoint::Pulley(*divisor),
            PointSpec::Geom(child, geom, side_site) => {
                let mut geom = targets.tendon_geom(child, geom)?;
                if let Some(side_site) = side_site {
                    geom.side = Some(targets.tendon_side_site(child, "sidesite", side_site, &geom)?);
                }
                PathPoint::Geom(geom)
            }
        });
    }
    if points.len() < 2 {
        return Err(at.invalid("a spatial tendon's path must contain at least two objects"));
    }
    // MuJoCo's checks: no pulley after a pulley or at the end, every site
    // beside a site, no site twice in a row, a geom between two sites.
    let is_pulley = |k: usize| matches!(points[k], PathPoint::Pulley(_));
    let is_site = |k: usize| matches!(points[k], PathPoint::Site(_));
    let last = points.len() - 1;
    for k in 0..=last {
        match points[k] {
            PathPoint::Pulley(_) if k > 0 && is_pulley(k - 1) => {
                return Err(at.invalid(format!("consecutive pulleys in the tendon's path (position {k})")));
            }
            PathPoint::Pulley(_) if k == last => {
                return Err(at.invalid("a spatial tendon's path cannot end with a pulley"));
            }
            PathPoint::Site(site) => {
                if (k == 0 || is_pulley(k - 1)) && (k == last || is_pulley(k + 1)) {
                    return Err(
                        at.invalid(format!("site {k} of the tendon's path needs a neighbour that is not a pulley"))
                    );
                }
                if k < last && points[k + 1] == PathPoint::Site(site) {
                    return Err(at.invalid(format!("site {k} is repeated in the tendon's path")));
                }
            }
            PathPoint::Geom { .. } if k == 0 || k == last || !is_site(k - 1) || !is_site(k + 1) => {
                return Err(at.invalid(format!("geom {k} of the tendon's path is not between two sites")));
            }
            PathPoint::Pulley(_) | PathPoint::Geom { .. } => {}
        }
    }
    Ok(TendonPath::Spatial(points))
}
