//! `<default>` classes and the joint, geom, site and actuator settings they
//! carry.
//!
//! As in MuJoCo, a class starts as a copy of its parent class, its `<joint>`,
//! `<geom>` and `<site>` children overwrite the attributes they give, and an
//! element starts as a copy of its class and overwrites the attributes it
//! gives. Actuator defaults follow MuJoCo 4.0's own rules (`super::actuator`).

use std::collections::HashMap;

use super::MjcfWarning;
use super::actuator::{self, ActuatorSettings};
use super::attributes::{Attribute, names, read_into, set};
use super::element::Element;
use super::equality::{self, EqualitySettings};
use super::error::MjcfError;
use super::mesh::{MeshSettings, mesh_default_attributes};
use super::orientation::Orientation;
use super::tendon::{self, TendonSettings};
use crate::vehicle::{ActuatorKind, JointKind, SoftConstraint};

/// `<joint>` in a body (MuJoCo 4.0 schema): its attributes and how each is read.
pub(crate) const JOINT_ATTRIBUTES: &[Attribute<JointSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("class"),
    Attribute::into("type", |s, e, a| set(&mut s.kind, e.keyword(a, &JointKind::ALL.map(|kind| (kind.name(), kind)))?)),
    Attribute::no_effect("group"),
    Attribute::into("pos", |s, e, a| set(&mut s.pos, e.numbers(a)?)),
    Attribute::into("axis", |s, e, a| set(&mut s.axis, e.numbers(a)?)),
    Attribute::into("springdamper", |s, e, a| set(&mut s.springdamper, e.numbers(a)?)),
    Attribute::into("limited", |s, e, a| set(&mut s.limited, e.keyword(a, &LIMITED)?)),
    Attribute::into("actuatorfrclimited", |s, e, a| set(&mut s.actuator_force_limited, e.keyword(a, &LIMITED)?)),
    Attribute::into("solreflimit", |s, e, a| e.overwrite_numbers(a, &mut s.limit_soft.solref)),
    Attribute::into("solimplimit", |s, e, a| e.overwrite_numbers(a, &mut s.limit_soft.solimp)),
    Attribute::into("solreffriction", |s, e, a| e.overwrite_numbers(a, &mut s.friction_soft.solref)),
    Attribute::into("solimpfriction", |s, e, a| e.overwrite_numbers(a, &mut s.friction_soft.solimp)),
    Attribute::into("stiffness", |s, e, a| overwrite_coefficients(e, a, &mut s.stiffness)),
    Attribute::into("range", |s, e, a| set(&mut s.range, e.numbers(a)?)),
    Attribute::into("actuatorfrcrange", |s, e, a| set(&mut s.actuator_force_range, e.numbers(a)?)),
    Attribute::into("actuatorgravcomp", |s, e, a| set(&mut s.actuator_gravcomp, e.boolean(a)?)),
    Attribute::into("margin", |s, e, a| set(&mut s.margin, e.number(a)?)),
    Attribute::into("ref", |s, e, a| set(&mut s.reference, e.number(a)?)),
    Attribute::into("springref", |s, e, a| set(&mut s.springref, e.number(a)?)),
    Attribute::into("armature", |s, e, a| set(&mut s.armature, e.non_negative(a)?)),
    Attribute::into("damping", |s, e, a| overwrite_coefficients(e, a, &mut s.damping)),
    Attribute::into("frictionloss", |s, e, a| set(&mut s.frictionloss, e.non_negative(a)?)),
    Attribute::no_effect("user"),
    Attribute::into("springyield", |s, e, a| set(&mut s.springyield, e.number(a)?)),
];

/// The keywords of `limited` and `actuatorfrclimited`.
const LIMITED: [(&str, Limited); 3] = [("false", Limited::No), ("true", Limited::Yes), ("auto", Limited::Auto)];

/// Overwrites the leading coefficients of `stiffness` or `damping` with
/// those the attribute gives; the linear one must not be negative.
fn overwrite_coefficients(element: &Element, attribute: &str, coefficients: &mut [f64; 3]) -> Result<(), MjcfError> {
    element.overwrite_numbers(attribute, coefficients)?;
    if coefficients[0] < 0.0 {
        return Err(element.bad_value(attribute, "a non-negative first coefficient"));
    }
    Ok(())
}

/// `<geom>` in a body (MuJoCo 4.0 schema): its attributes and how each is
/// read. Those for contacts and fluid forces are read for their syntax
/// only (nudyn models neither); MuJoCo refuses more numbers than each holds.
pub(crate) const GEOM_ATTRIBUTES: &[Attribute<GeomSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("class"),
    Attribute::into("type", |s, e, a| set(&mut s.kind, e.keyword(a, &GEOM_KINDS)?)),
    Attribute::into("contype", |s, e, a| set(&mut s.contype[0], e.integers(a)?.map(|[bits]| bits))),
    Attribute::into("conaffinity", |s, e, a| set(&mut s.contype[1], e.integers(a)?.map(|[bits]| bits))),
    Attribute::checked("condim", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::into("group", |s, e, a| set(&mut s.group, e.integers(a)?.map(|[group]| group))),
    Attribute::checked("priority", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::into("size", |s, e, a| e.overwrite_numbers(a, &mut s.size)),
    Attribute::no_effect("material"),
    Attribute::checked("friction", |e, a| e.overwrite_numbers(a, &mut [0.0; 3])),
    Attribute::into("mass", |s, e, a| set(&mut s.mass, e.non_negative(a)?.map(Some))),
    Attribute::into("density", |s, e, a| set(&mut s.density, e.non_negative(a)?)),
    Attribute::into("shellinertia", |s, e, a| set(&mut s.shell_inertia, e.boolean(a)?)),
    Attribute::checked("solmix", |e, a| e.number(a).map(drop)),
    Attribute::checked("solref", |e, a| e.overwrite_numbers(a, &mut [0.0; 2])),
    Attribute::checked("solimp", |e, a| e.overwrite_numbers(a, &mut [0.0; 5])),
    Attribute::into("margin", |s, e, a| set(&mut s.margin, e.number(a)?)),
    Attribute::checked("gap", |e, a| e.number(a).map(drop)),
    Attribute::no_effect("surfacevel"),
    Attribute::no_effect("adhesion"),
    Attribute::into("fromto", |s, e, a| set(&mut s.fromto, e.numbers(a)?.map(Some))),
    Attribute::into("pos", |s, e, a| set(&mut s.pos, e.numbers(a)?)),
    // An orientation written on the element replaces the class's, whichever form each uses.
    Attribute::into("quat", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("axisangle", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("xyaxes", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("zaxis", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("euler", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("hfield", |s, _, _| set(&mut s.hfield, Some(true))),
    Attribute::into("mesh", |s, e, a| set(&mut s.mesh, e.text(a).map(|mesh| Some(mesh.to_string())))),
    Attribute::into("fitscale", |s, e, a| set(&mut s.fit_scale, e.number(a)?)),
    Attribute::checked("rgba", |e, a| e.numbers::<4>(a).map(drop)),
    Attribute::no_effect("fluidshape"),
    Attribute::checked("fluidcoef", |e, a| e.overwrite_numbers(a, &mut [0.0; 5])),
    Attribute::no_effect("user"),
    Attribute::no_effect("castshadow"),
];

/// The keywords of a geom's `type`.
const GEOM_KINDS: [(&str, GeomKind); 9] = [
    ("plane", GeomKind::Plane),
    ("hfield", GeomKind::Hfield),
    ("sphere", GeomKind::Sphere),
    ("capsule", GeomKind::Capsule),
    ("ellipsoid", GeomKind::Ellipsoid),
    ("cylinder", GeomKind::Cylinder),
    ("box", GeomKind::Box),
    ("mesh", GeomKind::Mesh),
    ("sdf", GeomKind::Sdf),
];

/// `<site>` in a body (MuJoCo 4.0 schema): its attributes and how each is
/// read. `group`, `size` and `rgba` are read for their syntax; they do not
/// move the site.
pub(crate) const SITE_ATTRIBUTES: &[Attribute<SiteSettings>] = &[
    Attribute::by_reader("name"),
    Attribute::by_reader("class"),
    Attribute::into("type", |s, e, a| set(&mut s.kind, e.keyword(a, &SITE_KINDS)?)),
    Attribute::checked("group", |e, a| e.integers::<1>(a).map(drop)),
    Attribute::into("pos", |s, e, a| set(&mut s.pos, e.numbers(a)?)),
    Attribute::into("quat", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("axisangle", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("xyaxes", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("zaxis", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::into("euler", |s, e, _| set(&mut s.orientation, Orientation::read(e)?)),
    Attribute::checked("size", |e, a| e.overwrite_numbers(a, &mut [0.0; 3])),
    Attribute::no_effect("material"),
    Attribute::into("mesh", |s, _, _| set(&mut s.mesh, Some(true))),
    Attribute::checked("rgba", |e, a| e.numbers::<4>(a).map(drop)),
    Attribute::into("fromto", |s, e, a| set(&mut s.fromto, e.numbers(a)?.map(Some))),
    Attribute::no_effect("user"),
];

/// The keywords of a site's `type`.
const SITE_KINDS: [(&str, SiteKind); 5] = [
    ("sphere", SiteKind::Sphere),
    ("capsule", SiteKind::Capsule),
    ("ellipsoid", SiteKind::Ellipsoid),
    ("cylinder", SiteKind::Cylinder),
    ("box", SiteKind::Box),
];

/// `<joint>`, `<geom>` and `<site>` inside `<default>` take everything but these.
const NOT_IN_DEFAULTS: [&str; 2] = ["name", "class"];

/// Children of `<default>` that configure elements without effect on the
/// dynamics.
#[rustfmt::skip]
pub(crate) const IGNORED_DEFAULTS: &[&str] =
    &["camera", "light", "material", "texture", "pair"];

/// Whether a joint or tendon has limits (`limited`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Limited {
    /// `limited="false"`.
    No,
    /// `limited="true"`.
    Yes,
    /// `limited="auto"`: limited when `range` is given and `autolimits` is on.
    Auto,
}

/// A joint's attributes, as a class or an element sets them.
#[derive(Clone, Debug)]
pub(crate) struct JointSettings {
    /// `type`.
    pub kind: JointKind,
    /// `pos`.
    pub pos: [f64; 3],
    /// `axis`, not normalized.
    pub axis: [f64; 3],
    /// `ref`, in the compiler's angle unit for hinges.
    pub reference: f64,
    /// `springref`, like `ref`.
    pub springref: f64,
    /// `stiffness`: the linear coefficient, then MuJoCo's nonlinear ones.
    pub stiffness: [f64; 3],
    /// `damping`, like `stiffness`.
    pub damping: [f64; 3],
    /// `armature`.
    pub armature: f64,
    /// `frictionloss`.
    pub frictionloss: f64,
    /// `springdamper` (time constant, damping ratio).
    pub springdamper: [f64; 2],
    /// `springyield`.
    pub springyield: f64,
    /// `limited`.
    pub limited: Limited,
    /// `range`.
    pub range: [f64; 2],
    /// `actuatorfrclimited`.
    pub actuator_force_limited: Limited,
    /// `actuatorfrcrange`.
    pub actuator_force_range: [f64; 2],
    /// `actuatorgravcomp`.
    pub actuator_gravcomp: bool,
    /// `margin`.
    pub margin: f64,
    /// `solreflimit`, `solimplimit`.
    pub limit_soft: SoftConstraint,
    /// `solreffriction`, `solimpfriction`.
    pub friction_soft: SoftConstraint,
}

impl Default for JointSettings {
    /// MuJoCo's built-in joint defaults.
    fn default() -> Self {
        Self {
            kind: JointKind::Hinge,
            pos: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            reference: 0.0,
            springref: 0.0,
            stiffness: [0.0; 3],
            damping: [0.0; 3],
            armature: 0.0,
            frictionloss: 0.0,
            springdamper: [0.0; 2],
            springyield: 0.0,
            limited: Limited::Auto,
            range: [0.0; 2],
            actuator_force_limited: Limited::Auto,
            actuator_force_range: [0.0; 2],
            actuator_gravcomp: false,
            margin: 0.0,
            limit_soft: SoftConstraint::default(),
            friction_soft: SoftConstraint::default(),
        }
    }
}

impl JointSettings {
    /// Overwrites the settings the element gives.
    pub fn apply(&mut self, element: &Element) -> Result<(), MjcfError> {
        read_into(JOINT_ATTRIBUTES, self, element)
    }
}

/// MuJoCo's geom types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum GeomKind {
    /// `plane`.
    Plane,
    /// `hfield` (height field asset).
    Hfield,
    /// `sphere`, MuJoCo's default.
    Sphere,
    /// `capsule`.
    Capsule,
    /// `ellipsoid`.
    Ellipsoid,
    /// `cylinder`.
    Cylinder,
    /// `box`.
    Box,
    /// `mesh` (mesh asset).
    Mesh,
    /// `sdf` (signed distance field plugin).
    Sdf,
}

/// A geom's attributes, as a class or an element sets them.
#[derive(Clone, Debug)]
pub(crate) struct GeomSettings {
    /// `type`.
    pub kind: GeomKind,
    /// `size` (its meaning depends on `type`).
    pub size: [f64; 3],
    /// `pos`.
    pub pos: [f64; 3],
    /// `quat` or one of its alternatives.
    pub orientation: Orientation,
    /// `fromto`.
    pub fromto: Option<[f64; 6]>,
    /// `mass`, which overrides `density` when given.
    pub mass: Option<f64>,
    /// `density`.
    pub density: f64,
    /// `shellinertia`.
    pub shell_inertia: bool,
    /// `group`.
    pub group: i32,
    /// The mesh asset `mesh` names (the geom's shape, or the shape a
    /// primitive is fitted to).
    pub mesh: Option<String>,
    /// `fitscale`: the factor on a fitted primitive's size.
    pub fit_scale: f64,
    /// `contype` and `conaffinity`: a geom with either not 0 collides, and
    /// MuJoCo builds its mesh's convex hull.
    pub contype: [i32; 2],
    /// Whether `hfield` names a height-field asset.
    pub hfield: bool,
    /// `margin`: the distance at which MuJoCo starts its contacts.
    pub margin: f64,
}

impl Default for GeomSettings {
    /// MuJoCo's built-in geom defaults.
    fn default() -> Self {
        Self {
            kind: GeomKind::Sphere,
            size: [0.0; 3],
            pos: [0.0; 3],
            orientation: Orientation::default(),
            fromto: None,
            mass: None,
            density: 1000.0,
            shell_inertia: false,
            group: 0,
            mesh: None,
            fit_scale: 1.0,
            contype: [1, 1],
            hfield: false,
            margin: 0.0,
        }
    }
}

impl GeomSettings {
    /// Overwrites the settings the element gives.
    pub fn apply(&mut self, element: &Element) -> Result<(), MjcfError> {
        read_into(GEOM_ATTRIBUTES, self, element)
    }
}

/// MuJoCo's site types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum SiteKind {
    /// `sphere`, MuJoCo's default.
    Sphere,
    /// `capsule`.
    Capsule,
    /// `ellipsoid`.
    Ellipsoid,
    /// `cylinder`.
    Cylinder,
    /// `box`.
    Box,
}

/// A site's attributes that place it, as a class or an element sets them.
#[derive(Clone, Debug)]
pub(crate) struct SiteSettings {
    /// `type`.
    pub kind: SiteKind,
    /// `pos`.
    pub pos: [f64; 3],
    /// `quat` or one of its alternatives.
    pub orientation: Orientation,
    /// `fromto`.
    pub fromto: Option<[f64; 6]>,
    /// Whether `mesh` fits the site to a mesh asset (which moves its frame).
    pub mesh: bool,
}

impl Default for SiteSettings {
    /// MuJoCo's built-in site defaults.
    fn default() -> Self {
        Self { kind: SiteKind::Sphere, pos: [0.0; 3], orientation: Orientation::default(), fromto: None, mesh: false }
    }
}

impl SiteSettings {
    /// Overwrites the settings the element gives.
    pub fn apply(&mut self, element: &Element) -> Result<(), MjcfError> {
        read_into(SITE_ATTRIBUTES, self, element)
    }
}

/// One `<default>` class.
#[derive(Clone, Debug)]
pub(crate) struct DefaultClass {
    /// Settings a `<joint>` of this class starts from.
    pub joint: JointSettings,
    /// Settings a `<geom>` of this class starts from.
    pub geom: GeomSettings,
    /// Settings a `<site>` of this class starts from.
    pub site: SiteSettings,
    /// The class's actuator default, which every actuator element of the
    /// class starts from.
    pub actuator: ActuatorSettings,
    /// Settings a `<mesh>` asset of this class starts from.
    pub mesh: MeshSettings,
    /// Settings an `<equality>` element of this class starts from.
    pub equality: EqualitySettings,
    /// Settings a `<fixed>` or `<spatial>` tendon of this class starts from.
    pub tendon: TendonSettings,
}

/// All default classes; index 0 is "main".
pub(crate) struct Defaults {
    classes: Vec<DefaultClass>,
    /// Each class's parent class (`None` for "main").
    parents: Vec<Option<usize>>,
    /// Class name → (index, line of its `<default>`).
    by_name: HashMap<String, (usize, u32)>,
}

/// The top-level class.
pub(crate) const MAIN: usize = 0;

impl Defaults {
    /// Only the "main" class, with MuJoCo's built-in settings.
    pub fn new() -> Self {
        let main = DefaultClass {
            joint: JointSettings::default(),
            geom: GeomSettings::default(),
            site: SiteSettings::default(),
            actuator: ActuatorSettings::default(),
            mesh: MeshSettings::default(),
            equality: EqualitySettings::default(),
            tendon: TendonSettings::default(),
        };
        Self { classes: vec![main], parents: vec![None], by_name: HashMap::from([("main".to_string(), (MAIN, 0))]) }
    }

    /// The class with this index.
    pub fn class(&self, index: usize) -> &DefaultClass {
        &self.classes[index]
    }

    /// Where a shortcut of `kind` in class `index` takes the parameters its
    /// element does not give: the nearest of the class and its ancestors
    /// whose actuator default lends them (MuJoCo 4.0), if any.
    pub fn lender(&self, index: usize, kind: ActuatorKind) -> Option<&ActuatorSettings> {
        let mut class = Some(index);
        while let Some(k) = class {
            if self.classes[k].actuator.lends_parameters_to(kind) {
                return Some(&self.classes[k].actuator);
            }
            class = self.parents[k];
        }
        None
    }

    /// The index of the class named by the element's attribute (`class` or
    /// `childclass`), if it has that attribute.
    pub fn lookup(&self, element: &Element, attribute: &str) -> Result<Option<usize>, MjcfError> {
        match element.text(attribute) {
            None => Ok(None),
            Some(name) => match self.by_name.get(name) {
                Some(&(index, _)) => Ok(Some(index)),
                None => Err(element.unknown_class(name)),
            },
        }
    }

    /// Reads a top-level `<default>` element (it adds to "main") and the
    /// classes nested in it. As MuJoCo does, a class's own settings are read
    /// before its nested classes copy them, wherever the nested `<default>`
    /// stands among its siblings. A work stack instead of recursion: nesting
    /// may be deep, and the importer must not overflow the thread's stack.
    pub fn read(&mut self, top: &Element, warnings: &mut Vec<MjcfWarning>) -> Result<(), MjcfError> {
        let mut pending = vec![(*top, None)];
        while let Some((element, parent)) = pending.pop() {
            let index = self.read_class(&element, parent, warnings)?;
            let nested = element.children().filter(|child| child.tag() == "default");
            let nested: Vec<_> = nested.map(|child| (child, Some(index))).collect();
            // Reversed so that the first nested class is read next.
            pending.extend(nested.into_iter().rev());
        }
        Ok(())
    }

    /// Reads one `<default>` element without its nested classes; returns the
    /// class it defines (or "main" for a top-level one, `parent` `None`).
    fn read_class(
        &mut self,
        element: &Element,
        parent: Option<usize>,
        warnings: &mut Vec<MjcfWarning>,
    ) -> Result<usize, MjcfError> {
        element.check_attributes(&["class"])?;
        let index = match parent {
            None => {
                if element.text("class").is_some_and(|name| name != "main") {
                    return Err(element.invalid("the top-level default class is \"main\" and cannot be renamed"));
                }
                MAIN
            }
            Some(parent) => {
                let name = element.text("class").ok_or_else(|| element.missing("class"))?;
                if name == "main" {
                    return Err(element.invalid("\"main\" is the name of the top-level default class"));
                }
                if let Some(&(_, first_line)) = self.by_name.get(name) {
                    return Err(MjcfError::DuplicateName {
                        line: element.line,
                        element: element.label(),
                        kind: "default class",
                        name: name.to_string(),
                        first_line,
                    });
                }
                self.classes.push(self.classes[parent].clone());
                self.parents.push(Some(parent));
                let index = self.classes.len() - 1;
                self.by_name.insert(name.to_string(), (index, element.line));
                index
            }
        };

        // MuJoCo's schema allows each of these children once per class.
        let mut seen: Vec<Element> = Vec::new();
        for child in element.children() {
            if let Some(first) = seen.iter().find(|e| e.tag() == child.tag()) {
                return Err(child.repeated(first));
            }
            match child.tag() {
                "joint" | "geom" | "site" => {
                    let allowed = match child.tag() {
                        "joint" => names(JOINT_ATTRIBUTES),
                        "geom" => names(GEOM_ATTRIBUTES),
                        _ => names(SITE_ATTRIBUTES),
                    };
                    let allowed: Vec<&str> = allowed.into_iter().filter(|a| !NOT_IN_DEFAULTS.contains(a)).collect();
                    child.check_attributes(&allowed)?;
                    let class = &mut self.classes[index];
                    match child.tag() {
                        "joint" => class.joint.apply(&child)?,
                        "geom" => class.geom.apply(&child)?,
                        _ => class.site.apply(&child)?,
                    }
                }
                "mesh" => {
                    child.check_attributes(&mesh_default_attributes())?;
                    if let Some(grandchild) = child.children().next() {
                        return Err(grandchild.unknown());
                    }
                    self.classes[index].mesh.apply(&child)?;
                }
                "equality" => {
                    child.check_attributes(&equality::default_attributes())?;
                    self.classes[index].equality.apply(&child)?;
                }
                "tendon" => {
                    child.check_attributes(&tendon::default_attributes())?;
                    self.classes[index].tendon.apply(&child)?;
                }
                "default" => {}
                tag if IGNORED_DEFAULTS.contains(&tag) => warnings.push(child.ignored()),
                tag => match actuator::kind_of(tag) {
                    Some(kind) => {
                        child.check_attributes(&actuator::attributes(kind, true))?;
                        let lender = self.lender(index, kind).cloned();
                        self.classes[index].actuator.apply(kind, &child, lender.as_ref())?;
                    }
                    None => match actuator::refusal(tag) {
                        Some(reason) => return Err(child.unsupported(reason)),
                        None => return Err(child.unknown()),
                    },
                },
            }
            if child.tag() != "default" {
                seen.push(child);
            }
        }
        Ok(index)
    }
}
