//! Walks an MJCF document and builds the [`Vehicle`].

use std::collections::HashMap;
use std::path::Path;

use roxmltree::Document;

use super::actuator;
use super::contacts::{self, BodyFilter, ContactGeom, Reach};
use super::defaults::{
    Defaults, GEOM_ATTRIBUTES, GeomKind, GeomSettings, JOINT_ATTRIBUTES, JointSettings, Limited, MAIN, SITE_ATTRIBUTES,
    SiteKind,
};
use super::element::{Element, LineStarts};
use super::equality::{self, EqualityTargets};
use super::error::MjcfError;
use super::include::{self, Sources};
use super::inertia::{self, BodyInertia, EPS, GeomMass, mul_quat, quat_array, quat_to_mat};
use super::mesh::{self, MESH_ATTRIBUTES, Meshes};
use super::orientation::{AngleConvention, ORIENTATION_ATTRIBUTES, Orientation, normalized, z_to_quaternion};
use super::sensor::{self, SensorTargets};
use super::tendon::{self, TendonFlags, TendonTargets};
use super::{Imported, MjcfWarning};
use crate::math::{Mat3, Quat, Vec3};
use crate::vehicle::{
    Actuation, Actuator, ActuatorKind, BiasType, Body, ConstraintOptions, Equality, EqualityObjects, FrameObject,
    GainType, Joint, JointConstraints, JointKind, JointLimit, MassProperties, PathPoint, Sensor, SensorKind,
    SensorTarget, Site, SpringDamper, Tendon, TendonPath, Transmission, Vehicle, WrapGeom,
};

/// MuJoCo's `mjMINVAL`: the least mass and principal moment of a moving body.
const MIN_VALUE: f64 = 1e-15;

/// Attributes of `<body>`.
#[rustfmt::skip]
pub(crate) const BODY_ATTRIBUTES: &[&str] = &[
    "name", "childclass", "pos", "quat", "axisangle", "xyaxes", "zaxis", "euler", "mocap", "gravcomp",
    "user", "sleep", "simple", "fuse",
];

/// Attributes of `<frame>`.
#[rustfmt::skip]
pub(crate) const FRAME_ATTRIBUTES: &[&str] = &["name", "childclass", "pos", "quat", "axisangle", "xyaxes", "zaxis", "euler"];

/// The most elements the `<replicate>`s of a file may produce: each
/// replicate's copies times the elements inside it (nested ones included),
/// summed over every replicate as it is expanded. Far beyond any vehicle;
/// a count past it would exhaust the memory before the import could fail.
pub(crate) const MAX_REPLICATED_ELEMENTS: usize = 100_000;

/// Attributes of `<replicate>`.
pub(crate) const REPLICATE_ATTRIBUTES: &[&str] = &["count", "sep", "offset", "euler", "childclass"];

/// Attributes of `<inertial>`.
#[rustfmt::skip]
pub(crate) const INERTIAL_ATTRIBUTES: &[&str] =
    &["pos", "mass", "diaginertia", "fullinertia", "quat", "axisangle", "xyaxes", "zaxis", "euler"];

/// Attributes of `<compiler>`.
#[rustfmt::skip]
pub(crate) const COMPILER_ATTRIBUTES: &[&str] = &[
    "alignfree", "angle", "assetdir", "autolimits", "balanceinertia", "boundinertia", "boundmass",
    "conflict", "coordinate", "discardvisual", "eulerseq", "fitaabb", "fusestatic", "inertiafromgeom",
    "inertiagrouprange", "meshdir", "passthrough", "savecanonical", "savecompiled", "saveinertial",
    "settotalmass", "strippath", "texturedir", "usethread",
];

/// Attributes of `<option>`.
#[rustfmt::skip]
pub(crate) const OPTION_ATTRIBUTES: &[&str] = &[
    "actuatorgroupdisable", "ccd_iterations", "ccd_tolerance", "cone", "density", "gravity", "impratio",
    "integrator", "iterations", "jacobian", "ls_iterations", "ls_tolerance", "magnetic",
    "noslip_iterations", "noslip_tolerance", "o_friction", "o_margin", "o_solimp", "o_solref",
    "sdf_initpoints", "sdf_iterations", "sleep_tolerance", "solver", "timestep", "tolerance",
    "viscosity", "wind",
];

/// Attributes of `<flag>`; all take "enable" or "disable".
#[rustfmt::skip]
pub(crate) const FLAG_ATTRIBUTES: &[&str] = &[
    "actuation", "autoreset", "clampctrl", "constraint", "contact", "damper", "diagexact", "energy",
    "equality", "eulerdamp", "filterparent", "frictionloss", "fwdinv", "gravity", "invdiscrete", "ipc",
    "island", "limit", "midphase", "multiccd", "nativeccd", "override", "refsafe", "sensor", "sleep",
    "speculative", "spring", "warmstart",
];

/// Top-level sections without effect on the dynamics.
#[rustfmt::skip]
pub(crate) const IGNORED_SECTIONS: &[&str] =
    &["size", "statistic", "visual", "contact", "keyframe", "custom", "extension"];

/// Actuator attributes naming a transmission nudyn refuses, and why.
#[rustfmt::skip]
pub(crate) const REFUSED_TRANSMISSIONS: &[(&str, &str)] = &[
    ("cranksite", "slider-crank transmissions"),
    ("slidersite", "slider-crank transmissions"),
    ("body", "body transmissions act through contacts, which nudyn does not model"),
];

/// Elements nudyn refuses where bodies or sections are expected, and why.
#[rustfmt::skip]
pub(crate) const UNSUPPORTED_CHILDREN: &[(&str, &str)] = &[
    ("attach", "attaching another model"),
    ("composite", "composite and flexible objects"),
    ("flexcomp", "composite and flexible objects"),
    ("plugin", "plugins"),
];

/// Children of bodies (and of the world body) without effect on the
/// dynamics; in the world body, geoms too (they belong to no moving body).
pub(crate) const IGNORED_IN_BODIES: &[&str] = &["camera", "light"];

/// MuJoCo's actuator groups that `actuatorgroupdisable` can disable: 0 to 30.
const ACTUATOR_GROUPS: std::ops::RangeInclusive<i32> = 0..=30;

/// Where `<compiler inertiafromgeom>` takes a body's mass properties from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum InertiaFromGeom {
    /// Always from `<inertial>` (massless without one).
    Never,
    /// Always from the geoms, overriding `<inertial>`.
    Always,
    /// From the geoms when the body has no `<inertial>`.
    Auto,
}

/// `<compiler>` settings that matter here.
struct Compiler {
    angles: AngleConvention,
    inertia_from_geom: InertiaFromGeom,
    inertia_groups: [i32; 2],
    bound_mass: f64,
    bound_inertia: f64,
    balance_inertia: bool,
    autolimits: bool,
    align_free: bool,
    /// `settotalmass` when positive, with the warning it earns.
    total_mass: Option<(f64, MjcfWarning)>,
    /// Where mesh files are: `meshdir`, else `assetdir`, relative to the model's directory.
    mesh_dir: String,
    /// `strippath`: asset file names lose their directories.
    strip_path: bool,
    /// `fusestatic`: bodies without joints merge into their parents.
    fuse_static: bool,
    /// `fitaabb`: primitives fitted to a mesh hold its bounding box rather
    /// than match its inertia box.
    fit_aabb: bool,
}

/// `<option>` settings that matter here.
struct Physics {
    gravity: Vec3,
    magnetic: Vec3,
    gravity_disabled: bool,
    spring_disabled: bool,
    damper_disabled: bool,
    actuation: Actuation,
    /// The actuator groups `actuatorgroupdisable` lists.
    disabled_actuator_groups: Vec<i32>,
    constraint_options: ConstraintOptions,
    /// `<flag constraint="disable">`: no constraint forces at all.
    constraint_disabled: bool,
    frictionloss_disabled: bool,
    limit_disabled: bool,
    equality_disabled: bool,
    /// `<flag sensor="disable">`: sensordata stays 0.
    sensor_disabled: bool,
}

/// What an actuator needs to know of a joint it may name.
struct JointTarget {
    kind: JointKind,
    /// `range` as MuJoCo's compiler leaves it: in radians for a limited hinge
    /// or ball joint when angles are in degrees, as written otherwise.
    range: [f64; 2],
    /// Whether the joint is limited (MuJoCo's jnt_limited, before any flag).
    limited: bool,
}

/// What the checks after the whole tree is read need to know of a body.
struct BodyRecord {
    line: u32,
    label: String,
    inertia: BodyInertia,
    has_joints: bool,
    children: Vec<usize>,
}

/// A body element waiting to be read, with what it inherits from its parent.
struct PendingBody<'a> {
    element: Element<'a, 'a>,
    /// Index of the parent in the vehicle's bodies; `None` below `<worldbody>`.
    parent: Option<usize>,
    /// The nearest ancestor's `childclass`.
    inherited_class: usize,
    /// Whether a joint lies between the parent and the world.
    parent_moving: bool,
    /// The pose of the `<frame>`s around the body, in its parent.
    frame: Option<Pose>,
    /// The suffix the `<replicate>`s around it give the names in it.
    suffix: String,
}

/// A pose in a parent frame: position, then orientation.
type Pose = (Vec3, Quat);

/// The pose `inner`, given in the frame `outer` places, in `outer`'s parent
/// (MuJoCo's `mjuu_frameaccumChild`).
fn compose(outer: &Pose, inner: &Pose) -> Pose {
    (outer.0 + outer.1 * inner.0, outer.1 * inner.1)
}

/// A child element of a body or of the world body, with what the `<frame>`s
/// around it give it: their composed pose (`None` outside any frame) and
/// the default class.
struct Placed<'a> {
    element: Element<'a, 'a>,
    frame: Option<Pose>,
    class: usize,
    /// The suffix of `<replicate>` copies for its name and those below it.
    suffix: String,
}

/// `align` of a free joint.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Align {
    No,
    Yes,
    Auto,
}

/// A joint element with its resolved settings.
struct JointElement<'a, 'input> {
    element: Element<'a, 'input>,
    settings: JointSettings,
    align: Align,
    /// The `<replicate>` suffix of its name.
    suffix: String,
}

/// What the walk through the document has gathered so far.
struct Reader {
    compiler: Compiler,
    physics: Physics,
    defaults: Defaults,
    warnings: Vec<MjcfWarning>,
    bodies: Vec<Body>,
    records: Vec<BodyRecord>,
    body_names: HashMap<String, u32>,
    joint_names: HashMap<String, u32>,
    joint_targets: HashMap<String, JointTarget>,
    sites: Vec<Site>,
    /// Whether each site is fitted to a mesh (which moves its frame).
    site_fitted_to_mesh: Vec<bool>,
    site_names: HashMap<String, u32>,
    actuators: Vec<Actuator>,
    actuator_names: HashMap<String, u32>,
    sensors: Vec<Sensor>,
    sensor_names: HashMap<String, u32>,
    equalities: Vec<Equality>,
    tendons: Vec<Tendon>,
    tendon_names: HashMap<String, u32>,
    /// Whether each tendon is limited (MuJoCo's tendon_limited, before any flag).
    tendon_limited: Vec<bool>,
    /// The named geoms, for tendons to wrap around: their type, and their
    /// frame when a sphere or cylinder.
    named_geoms: HashMap<String, (GeomKind, Option<WrapGeom>)>,
    /// The bodies the file leaves unnamed.
    unnamed_bodies: Vec<usize>,
    /// The files the model is read from, for the paths of its assets.
    sources: Sources,
    /// The `<mesh>` assets, processed.
    meshes: Meshes,
    /// The names of the mocap bodies, in MuJoCo's mocap order.
    mocap_bodies: Vec<String>,
    /// Bodies named by an ignored element (a camera's or light's `target`, a
    /// contact `<exclude>`), which `fusestatic` keeps.
    named_elsewhere: Vec<String>,
    /// The names given inside `<replicate>`s, each with its first copy's name.
    replicated: HashMap<String, String>,
    /// The elements the `<replicate>`s expanded so far produce (see
    /// [`MAX_REPLICATED_ELEMENTS`]).
    replicated_elements: std::cell::Cell<usize>,
    /// Each body's pose in the world at qpos0 (before `align_free` moves its frame).
    world_poses: Vec<Pose>,
    /// The geoms that may collide, for the warning on contacts.
    contact_geoms: Vec<ContactGeom>,
}

/// What reading a geom gives: its mass when it counts, and how far it
/// reaches in its body when known.
struct GeomRead {
    mass: Option<GeomMass>,
    reach: Option<(Vec3, Quat, Reach)>,
}

/// Reads an MJCF document, from the file `path` if it comes from one (the
/// files it includes are looked for from there).
pub(crate) fn read(xml: &str, path: Option<&Path>) -> Result<Imported, MjcfError> {
    let assembled = include::assemble(xml, path)?;
    let sources = assembled.sources;
    let mut imported = read_merged(&assembled.text, &sources).map_err(|e| sources.place_error(e))?;
    // Lines of the merged text back to lines of their files.
    imported.warnings = imported.warnings.into_iter().map(|w| sources.place_warning(w)).collect();
    let vehicle = &mut imported.vehicle;
    let lines = vehicle
        .bodies
        .iter_mut()
        .flat_map(|b| std::iter::once(&mut b.line).chain(b.joints.iter_mut().map(|j| &mut j.line)));
    let lines = lines
        .chain(vehicle.sites.iter_mut().map(|s| &mut s.line))
        .chain(vehicle.actuators.iter_mut().map(|a| &mut a.line))
        .chain(vehicle.sensors.iter_mut().map(|s| &mut s.line))
        .chain(vehicle.tendons.iter_mut().map(|t| &mut t.line))
        .chain(vehicle.equalities.iter_mut().map(|e| &mut e.line));
    for line in lines {
        *line = sources.line_in_file(*line);
    }
    Ok(imported)
}

/// Reads the document with its includes merged in.
fn read_merged(xml: &str, sources: &Sources) -> Result<Imported, MjcfError> {
    let document = Document::parse(xml).map_err(|e| MjcfError::Xml {
        line: e.pos().row,
        column: e.pos().col,
        message: e.to_string(),
    })?;
    let lines = LineStarts::new(xml);
    let root = Element::new(document.root_element(), &lines);
    if root.tag() != "mujoco" {
        return Err(MjcfError::WrongRoot { line: root.line, element: root.label() });
    }
    root.check_attributes(&["model"])?;

    let mut reader = Reader::new(sources.clone());
    // MuJoCo applies these wherever they appear, even after <worldbody>.
    for section in root.children() {
        match section.tag() {
            "compiler" => reader.read_compiler(&section)?,
            "option" => reader.read_option(&section)?,
            "default" => reader.defaults.read(&section, &mut reader.warnings)?,
            _ => {}
        }
    }
    // Meshes once the compiler's directories and the default classes are known.
    for section in root.children().filter(|section| section.tag() == "asset") {
        reader.read_assets(&section)?;
    }
    for exclude in root.children().filter(|s| s.tag() == "contact").flat_map(|s| s.children()) {
        let bodies = ["body1", "body2"].iter().filter_map(|a| exclude.text(a).filter(|_| exclude.tag() == "exclude"));
        reader.named_elsewhere.extend(bodies.map(str::to_string));
    }

    let mut has_worldbody = false;
    let mut actuator_sections = Vec::new();
    let mut sensor_sections = Vec::new();
    let mut equality_sections = Vec::new();
    let mut tendon_sections = Vec::new();
    let mut keyframe_sections = Vec::new();
    for section in root.children() {
        match section.tag() {
            "compiler" | "option" | "default" | "asset" => {}
            "worldbody" => {
                has_worldbody = true;
                reader.read_worldbody(&section)?;
            }
            // Read once every joint and site is known, wherever the section stands.
            "actuator" => actuator_sections.push(section),
            "sensor" => sensor_sections.push(section),
            // Checked once the sizes are known, then ignored.
            "keyframe" => {
                keyframe_sections.push(section);
                reader.warnings.push(section.ignored());
            }
            tag if IGNORED_SECTIONS.contains(&tag) => reader.warnings.push(section.ignored()),
            // Read once every joint and site is known.
            "tendon" => tendon_sections.push(section),
            // Read once every body, site and joint is known.
            "equality" => equality_sections.push(section),
            "deformable" => reader.read_deformable(&section)?,
            _ => return Err(section.unknown()),
        }
    }
    if !has_worldbody {
        return Err(MjcfError::MissingWorldbody { line: root.line, element: root.label() });
    }
    // Before the equalities, actuators and sensors, which may name tendons.
    for section in &tendon_sections {
        reader.read_tendons(section)?;
    }
    for section in &equality_sections {
        reader.read_equalities(section)?;
    }
    for section in &actuator_sections {
        reader.read_actuators(section)?;
    }
    // After the actuators, which sensors may name.
    for section in &sensor_sections {
        reader.read_sensors(section)?;
    }
    for section in &keyframe_sections {
        reader.check_keyframes(section)?;
    }
    reader.warn_of_contacts(&root);

    let name = root.text("model").unwrap_or("vehicle").to_string();
    reader.finish(name)
}

impl Reader {
    fn new(sources: Sources) -> Self {
        Self {
            compiler: Compiler {
                angles: AngleConvention { degrees: true, euler_seq: *b"xyz" },
                inertia_from_geom: InertiaFromGeom::Auto,
                inertia_groups: [0, 5],
                bound_mass: 0.0,
                bound_inertia: 0.0,
                balance_inertia: false,
                autolimits: true,
                align_free: false,
                total_mass: None,
                mesh_dir: String::new(),
                strip_path: false,
                fuse_static: false,
                fit_aabb: false,
            },
            physics: Physics {
                gravity: Vec3::new(0.0, 0.0, -9.81),
                // MuJoCo's default field.
                magnetic: Vec3::new(0.0, -0.5, 0.0),
                gravity_disabled: false,
                spring_disabled: false,
                damper_disabled: false,
                actuation: Actuation::default(),
                disabled_actuator_groups: Vec::new(),
                constraint_options: ConstraintOptions::default(),
                constraint_disabled: false,
                frictionloss_disabled: false,
                limit_disabled: false,
                equality_disabled: false,
                sensor_disabled: false,
            },
            defaults: Defaults::new(),
            warnings: Vec::new(),
            bodies: Vec::new(),
            records: Vec::new(),
            body_names: HashMap::new(),
            joint_names: HashMap::new(),
            joint_targets: HashMap::new(),
            sites: Vec::new(),
            site_fitted_to_mesh: Vec::new(),
            site_names: HashMap::new(),
            actuators: Vec::new(),
            actuator_names: HashMap::new(),
            sensors: Vec::new(),
            sensor_names: HashMap::new(),
            equalities: Vec::new(),
            tendons: Vec::new(),
            tendon_names: HashMap::new(),
            tendon_limited: Vec::new(),
            named_geoms: HashMap::new(),
            unnamed_bodies: Vec::new(),
            sources,
            meshes: Meshes::new(),
            mocap_bodies: Vec::new(),
            named_elsewhere: Vec::new(),
            replicated: HashMap::new(),
            replicated_elements: std::cell::Cell::new(0),
            world_poses: Vec::new(),
            contact_geoms: Vec::new(),
        }
    }

    fn read_compiler(&mut self, element: &Element) -> Result<(), MjcfError> {
        element.check_attributes(COMPILER_ATTRIBUTES)?;
        let compiler = &mut self.compiler;
        match element.text("coordinate") {
            None | Some("local") => {}
            Some("global") => {
                return Err(element.unsupported("coordinate=\"global\" (removed from MuJoCo in version 2.3.3)"));
            }
            Some(_) => return Err(element.bad_value("coordinate", "\"local\"")),
        }
        if let Some(degrees) = element.keyword("angle", &[("degree", true), ("radian", false)])? {
            compiler.angles.degrees = degrees;
        }
        if let Some(sequence) = element.text("eulerseq") {
            compiler.angles.euler_seq = sequence
                .as_bytes()
                .try_into()
                .ok()
                .filter(|s: &[u8; 3]| s.iter().all(|c| b"xyzXYZ".contains(c)))
                .ok_or_else(|| element.bad_value("eulerseq", "3 letters from x, y, z, X, Y, Z"))?;
        }
        let sources =
            [("false", InertiaFromGeom::Never), ("true", InertiaFromGeom::Always), ("auto", InertiaFromGeom::Auto)];
        if let Some(source) = element.keyword("inertiafromgeom", &sources)? {
            compiler.inertia_from_geom = source;
        }
        if let Some(groups) = element.integers("inertiagrouprange")? {
            compiler.inertia_groups = groups;
        }
        if let Some(bound) = element.non_negative("boundmass")? {
            compiler.bound_mass = bound;
        }
        if let Some(bound) = element.non_negative("boundinertia")? {
            compiler.bound_inertia = bound;
        }
        if let Some(balance) = element.boolean("balanceinertia")? {
            compiler.balance_inertia = balance;
        }
        if let Some(fit_aabb) = element.boolean("fitaabb")? {
            compiler.fit_aabb = fit_aabb;
        }
        if let Some(autolimits) = element.boolean("autolimits")? {
            compiler.autolimits = autolimits;
        }
        if let Some(align) = element.boolean("alignfree")? {
            compiler.align_free = align;
        }
        if let Some(total) = element.number("settotalmass")? {
            let warning = element.warning(format!(
                "settotalmass is deprecated in MuJoCo; all masses and inertias are scaled so the total mass is {total}"
            ));
            compiler.total_mass = (total > 0.0).then_some((total, warning));
        }
        // MuJoCo reads assetdir first, so that meshdir wins.
        for attribute in ["assetdir", "meshdir"] {
            if let Some(dir) = element.text(attribute) {
                compiler.mesh_dir = dir.to_string();
            }
        }
        if let Some(strip) = element.boolean("strippath")? {
            compiler.strip_path = strip;
        }
        if let Some(fuse) = element.boolean("fusestatic")? {
            compiler.fuse_static = fuse;
        }
        for child in element.children() {
            match child.tag() {
                "lengthrange" => self.warnings.push(child.ignored()),
                _ => return Err(child.unknown()),
            }
        }
        Ok(())
    }

    fn read_option(&mut self, element: &Element) -> Result<(), MjcfError> {
        element.check_attributes(OPTION_ATTRIBUTES)?;
        if let Some(gravity) = element.numbers::<3>("gravity")? {
            self.physics.gravity = Vec3::from(gravity);
        }
        if let Some(magnetic) = element.numbers::<3>("magnetic")? {
            self.physics.magnetic = Vec3::from(magnetic);
        }
        if let Some(timestep) = element.number("timestep")? {
            if timestep <= 0.0 {
                return Err(element.bad_value("timestep", "a positive time step"));
            }
            self.physics.constraint_options.timestep = timestep;
        }
        if let Some([iterations]) = element.integers::<1>("noslip_iterations")? {
            self.physics.constraint_options.noslip_iterations = u32::try_from(iterations)
                .map_err(|_| element.bad_value("noslip_iterations", "a non-negative number of iterations"))?;
        }
        if let Some(tolerance) = element.number("noslip_tolerance")? {
            self.physics.constraint_options.noslip_tolerance = tolerance;
        }
        if let Some(groups) = element.integer_list("actuatorgroupdisable")? {
            if groups.iter().any(|g| !ACTUATOR_GROUPS.contains(g)) {
                return Err(element.bad_value("actuatorgroupdisable", "actuator groups from 0 to 30"));
            }
            self.physics.disabled_actuator_groups = groups;
        }
        // Read for their syntax only: they set contacts, which nudyn does not
        // model, and MuJoCo's iterative solver, which nudyn does not use.
        // MuJoCo refuses more numbers than each holds.
        element.overwrite_numbers("o_solref", &mut [0.0; 2])?;
        element.overwrite_numbers("o_solimp", &mut [0.0; 5])?;
        element.overwrite_numbers("o_friction", &mut [0.0; 5])?;
        for attribute in ["o_margin", "impratio", "ls_tolerance", "ccd_tolerance", "sleep_tolerance"] {
            element.number(attribute)?;
        }
        for attribute in ["ls_iterations", "ccd_iterations", "sdf_iterations", "sdf_initpoints"] {
            element.integers::<1>(attribute)?;
        }
        // Fewer iterations or a looser tolerance than MuJoCo's defaults (100,
        // 1e-8) let MuJoCo stop short of the constraint forces nudyn computes.
        let iterations = element.integers::<1>("iterations")?.map(|[n]| n);
        let tolerance = element.number("tolerance")?;
        let loose = [
            iterations.filter(|&n| n < 100).map(|n| format!("iterations={n}")),
            tolerance.filter(|&t| t > 1e-8).map(|t| format!("tolerance={t}")),
        ];
        let loose: Vec<String> = loose.into_iter().flatten().collect();
        if !loose.is_empty() {
            self.warnings.push(element.warning(format!(
                "nudyn solves the constraint problem exactly; MuJoCo with {} will differ",
                loose.join(" and ")
            )));
        }
        if element.numbers::<3>("wind")?.is_some_and(|w| w != [0.0; 3]) {
            return Err(element.unsupported("wind acts through fluid forces, which nudyn does not model"));
        }
        for medium in ["density", "viscosity"] {
            if element.number(medium)?.is_some_and(|x| x != 0.0) {
                return Err(element
                    .unsupported(format!("a nonzero medium {medium} adds fluid forces, which nudyn does not model")));
            }
        }
        let mut flag_seen: Option<Element> = None;
        for child in element.children() {
            if child.tag() != "flag" {
                return Err(child.unknown());
            }
            if let Some(first) = &flag_seen {
                return Err(child.repeated(first));
            }
            flag_seen = Some(child);
            child.check_attributes(FLAG_ATTRIBUTES)?;
            let mut disabled = HashMap::new();
            for &flag in FLAG_ATTRIBUTES {
                if let Some(off) = child.keyword(flag, &[("enable", false), ("disable", true)])? {
                    disabled.insert(flag, off);
                }
            }
            if disabled.get("sleep") == Some(&false) {
                return Err(child.unsupported("sleeping bodies (flag sleep=\"enable\") freeze the dynamics"));
            }
            let physics = &mut self.physics;
            if let Some(&off) = disabled.get("island") {
                physics.constraint_options.islands = !off;
            }
            if let Some(&off) = disabled.get("refsafe") {
                physics.constraint_options.refsafe = !off;
            }
            for (flag, target) in [
                ("gravity", &mut physics.gravity_disabled),
                ("spring", &mut physics.spring_disabled),
                ("damper", &mut physics.damper_disabled),
                ("constraint", &mut physics.constraint_disabled),
                ("frictionloss", &mut physics.frictionloss_disabled),
                ("limit", &mut physics.limit_disabled),
                ("equality", &mut physics.equality_disabled),
                ("sensor", &mut physics.sensor_disabled),
            ] {
                if let Some(&off) = disabled.get(flag) {
                    *target = off;
                }
            }
            for (flag, target) in
                [("actuation", &mut physics.actuation.enabled), ("clampctrl", &mut physics.actuation.clamp_ctrl)]
            {
                if let Some(&off) = disabled.get(flag) {
                    *target = !off;
                }
            }
        }
        Ok(())
    }

    /// Reads an `<asset>` section: meshes are declared (their files read
    /// once a geom needs them), the other assets (textures, materials,
    /// height fields, skins) ignored with a warning.
    fn read_assets(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        if section.children().next().is_none() {
            self.warnings.push(section.ignored());
        }
        for child in section.children() {
            if child.tag() != "mesh" {
                self.warnings.push(child.ignored());
                continue;
            }
            child.check_attributes(MESH_ATTRIBUTES)?;
            let class = self.defaults.lookup(&child, "class")?.unwrap_or(MAIN);
            // Where MuJoCo reads the file: in meshdir, or beside the included file naming it.
            let path = child.text("file").map(|file| {
                let file = match self.compiler.strip_path {
                    true => file.rsplit(['/', '\\']).next().unwrap_or(file),
                    false => file,
                };
                self.sources.asset_path(&self.compiler.mesh_dir, file, child.line)
            });
            // MuJoCo names a mesh without a name after its file.
            let name = match (child.text("name"), child.text("file")) {
                (Some(name), _) => name.to_string(),
                (None, Some(file)) => {
                    let file = file.rsplit(['/', '\\']).next().unwrap_or(file);
                    file.rsplit_once('.').map_or(file, |(stem, _)| stem).to_string()
                }
                (None, None) => return Err(child.missing("name")),
            };
            if let Some(first) = self.meshes.get(&name) {
                return Err(MjcfError::DuplicateName {
                    line: child.line,
                    element: child.label(),
                    kind: "mesh",
                    name,
                    first_line: first.line,
                });
            }
            let declared = mesh::declare(&child, &self.defaults.class(class).mesh, path)?;
            self.meshes.insert(name, declared);
        }
        Ok(())
    }

    fn read_deformable(&mut self, section: &Element) -> Result<(), MjcfError> {
        if section.children().next().is_none() {
            self.warnings.push(section.ignored());
        }
        for child in section.children() {
            match child.tag() {
                "skin" => self.warnings.push(child.ignored()),
                "flex" => return Err(child.unsupported("flexible bodies")),
                _ => return Err(child.unknown()),
            }
        }
        Ok(())
    }

    fn read_worldbody(&mut self, section: &Element) -> Result<(), MjcfError> {
        // MuJoCo: "World body cannot have attributes".
        section.check_attributes(&[])?;
        for Placed { element: child, frame, class, suffix } in self.placed_children(section, MAIN, "")? {
            match child.tag() {
                "body" => self.read_body_tree(child, frame, class, suffix)?,
                "site" => self.read_site(&child, class, None, frame, &suffix)?,
                "geom" => {
                    child.check_attributes(GEOM_ATTRIBUTES)?;
                    if let Some(grandchild) = child.children().next() {
                        return Err(unsupported_child(&grandchild));
                    }
                    let mut settings = self.defaults.class(self.class_of(&child, class)?).geom.clone();
                    settings.apply(&child)?;
                    self.name_geom(&child, &settings, frame.as_ref(), None, &suffix)?;
                    let read = self.geom_mass(&child, &settings, frame.as_ref(), false, false)?;
                    self.add_contact_geom(&child, &settings, None, read.reach);
                    self.warnings.push(child.ignored());
                }
                tag if IGNORED_IN_BODIES.contains(&tag) => {
                    self.named_elsewhere.extend(child.text("target").map(str::to_string));
                    self.warnings.push(child.ignored());
                }
                "joint" | "freejoint" => {
                    return Err(child.invalid("the world body cannot have joints"));
                }
                "inertial" => return Err(child.invalid("the world body cannot have an <inertial>")),
                _ => return Err(unsupported_child(&child)),
            }
        }
        self.set_apart_unnamed();
        Ok(())
    }

    /// Gives the names made up for unnamed bodies and joints a suffix where
    /// they equal a name the file gives (or each other), so that no two
    /// bodies or joints share a name in descriptions and messages.
    fn set_apart_unnamed(&mut self) {
        let mut taken: std::collections::HashSet<String> = self.body_names.keys().cloned().collect();
        for &index in &self.unnamed_bodies {
            let name = &mut self.bodies[index].name;
            while !taken.insert(name.clone()) {
                name.push_str("_unnamed");
            }
        }
        let mut taken: std::collections::HashSet<String> = self.joint_names.keys().cloned().collect();
        for joint in self.bodies.iter_mut().flat_map(|b| &mut b.joints) {
            // A named joint is the one its name was claimed for, at its line.
            if self.joint_names.get(&joint.name) != Some(&joint.line) {
                while !taken.insert(joint.name.clone()) {
                    joint.name.push_str("_unnamed");
                }
            }
        }
    }

    /// Reads a child of `<worldbody>` and its descendants in document order
    /// (parent before child). A work stack instead of recursion: a vehicle
    /// file may nest bodies thousands deep, and the importer must not
    /// overflow the thread's stack, which is small in a host's FMU thread.
    fn read_body_tree<'a>(
        &mut self,
        top: Element<'a, 'a>,
        frame: Option<Pose>,
        class: usize,
        suffix: String,
    ) -> Result<(), MjcfError> {
        let mut pending = vec![PendingBody {
            element: top,
            parent: None,
            inherited_class: class,
            parent_moving: false,
            frame,
            suffix,
        }];
        while let Some(body) = pending.pop() {
            let children = self.read_body(&body)?;
            // Reversed so that the first child is read next.
            pending.extend(children.into_iter().rev());
        }
        Ok(())
    }

    /// Reads one body; returns its child bodies, still to be read.
    fn read_body<'a>(&mut self, body: &PendingBody<'a>) -> Result<Vec<PendingBody<'a>>, MjcfError> {
        let &PendingBody { ref element, parent, inherited_class, parent_moving, frame, ref suffix } = body;
        element.check_attributes(BODY_ATTRIBUTES)?;
        let mocap = element.boolean("mocap")? == Some(true);
        let gravcomp = element.number("gravcomp")?.unwrap_or(0.0);
        let class = self.defaults.lookup(element, "childclass")?.unwrap_or(inherited_class);
        let own_pos = Vec3::from(element.numbers::<3>("pos")?.unwrap_or_default());
        let own_quat = self.resolve(element, &Orientation::read(element)?.unwrap_or_default())?;
        let (pos, quat) = frame.map_or((own_pos, own_quat), |frame| compose(&frame, &(own_pos, own_quat)));
        let index = self.bodies.len();
        let world_pose = parent.map_or((pos, quat), |parent| compose(&self.world_poses[parent], &(pos, quat)));
        self.world_poses.push(world_pose);
        // An unnamed body gets a name for messages and descriptions, which
        // nothing can refer to (MuJoCo's unnamed elements have none).
        let name = match element.text("name") {
            Some(name) => {
                let copy = self.replicated_name(name, suffix);
                claim_name(&mut self.body_names, "body", &copy, element)?;
                copy
            }
            None => {
                self.unnamed_bodies.push(index);
                format!("body{index}")
            }
        };

        let mut inertial: Option<(Element, BodyInertia)> = None;
        let mut joints = Vec::new();
        let mut geoms = Vec::new();
        let mut child_bodies = Vec::new();
        for Placed { element: child, frame, class, suffix } in self.placed_children(element, class, suffix)? {
            match child.tag() {
                "inertial" => {
                    if let Some((first, _)) = &inertial {
                        return Err(child.repeated(first));
                    }
                    let mut read = self.read_inertial(&child)?;
                    if let Some(frame) = frame {
                        read.place(&frame.0, &frame.1);
                    }
                    inertial = Some((child, read));
                }
                "joint" => {
                    child.check_attributes(JOINT_ATTRIBUTES)?;
                    no_children(&child)?;
                    let mut settings = self.defaults.class(self.class_of(&child, class)?).joint.clone();
                    settings.apply(&child)?;
                    if let Some((at, turn)) = frame {
                        settings.pos = (at + turn * Vec3::from(settings.pos)).into();
                        settings.axis = (turn * Vec3::from(settings.axis)).into();
                    }
                    joints.push(JointElement { element: child, settings, align: Align::Auto, suffix });
                }
                "freejoint" => {
                    // MuJoCo's <freejoint> takes no defaults.
                    child.check_attributes(&["name", "group", "align"])?;
                    no_children(&child)?;
                    let aligns = [("false", Align::No), ("true", Align::Yes), ("auto", Align::Auto)];
                    let align = child.keyword("align", &aligns)?.unwrap_or(Align::Auto);
                    let settings = JointSettings { kind: JointKind::Free, ..JointSettings::default() };
                    joints.push(JointElement { element: child, settings, align, suffix });
                }
                "geom" => {
                    child.check_attributes(GEOM_ATTRIBUTES)?;
                    if let Some(grandchild) = child.children().next() {
                        return Err(unsupported_child(&grandchild));
                    }
                    let mut settings = self.defaults.class(self.class_of(&child, class)?).geom.clone();
                    settings.apply(&child)?;
                    geoms.push((child, settings, frame, suffix));
                }
                "site" => self.read_site(&child, class, Some(index), frame, &suffix)?,
                tag if IGNORED_IN_BODIES.contains(&tag) => {
                    self.named_elsewhere.extend(child.text("target").map(str::to_string));
                    self.warnings.push(child.ignored());
                }
                "body" => child_bodies.push(PendingBody {
                    element: child,
                    parent: Some(index),
                    inherited_class: class,
                    parent_moving: false,
                    frame,
                    suffix,
                }),
                _ => return Err(unsupported_child(&child)),
            }
        }

        let has_joints = !joints.is_empty();
        // A mocap body stays where the file puts it, since nudyn takes no
        // mocap poses: a body welded to the world, as MuJoCo's is until its
        // mocap_pos or mocap_quat is changed.
        if mocap {
            if has_joints || parent.is_some() {
                return Err(element.invalid(format!("mocap body '{name}' is not a fixed child of world")));
            }
            self.mocap_bodies.push(name.clone());
        }
        let moving = parent_moving || has_joints;
        // MuJoCo 4.0's keywords, and its rule for a sleep policy.
        element.keyword("fuse", &[("auto", ()), ("false", ())])?;
        let policies = [("auto", false), ("never", true), ("allowed", true), ("init", true)];
        let movable_root = has_joints && !parent_moving;
        if element.keyword("sleep", &policies)? == Some(true) && !movable_root {
            return Err(element.invalid("sleep policy only allowed for movable root bodies"));
        }
        // MuJoCo's condition for moving the body frame to the inertial frame.
        let aligned = match joints.as_slice() {
            [only] if only.settings.kind == JointKind::Free && child_bodies.is_empty() => {
                only.align == Align::Yes || (only.align == Align::Auto && self.compiler.align_free)
            }
            _ => false,
        };
        let joints = self.build_joints(&name, parent, joints)?;

        let explicit = inertial.map(|(_, inertia)| inertia);
        let from_geoms = match self.compiler.inertia_from_geom {
            InertiaFromGeom::Never => false,
            InertiaFromGeom::Always => true,
            InertiaFromGeom::Auto => explicit.is_none(),
        };
        let mut selected = Vec::new();
        let mut mass_unknown = false;
        for (geom, settings, frame, suffix) in &geoms {
            self.name_geom(geom, settings, frame.as_ref(), Some(index), suffix)?;
            let [low, high] = self.compiler.inertia_groups;
            let contributes = from_geoms && (low..=high).contains(&settings.group);
            if contributes && mass_not_computed(settings) && !moving {
                mass_unknown = true;
                self.warnings.push(geom.warning(
                    "its mass is not computed: the body is fixed to the world, so it moves nothing \
                     (a subtree sensor that would count it is refused)",
                ));
            }
            let read = self.geom_mass(geom, settings, frame.as_ref(), moving, contributes)?;
            self.add_contact_geom(geom, settings, Some(index), read.reach);
            // MuJoCo leaves out geoms of mass up to mjEPS.
            if let Some(mass) = read.mass
                && mass.mass > EPS
            {
                selected.push(mass);
            }
        }
        let inertia = if !selected.is_empty() {
            BodyInertia::from_geoms(&selected).map_err(|r| element.invalid(r))?
        } else if let Some(explicit) = explicit {
            explicit
        } else {
            // MuJoCo puts the inertial frame of a body without mass at the body's
            // own pose in its parent, before any <frame> around it; it matters
            // once boundmass gives it mass.
            BodyInertia::from_principal(0.0, own_pos, &own_quat, Vec3::zeros())
        };
        let inertia = self.bound(element, inertia)?;
        let ((pos, quat), inertia) = match aligned {
            true => self.align_free(index, (pos, quat), inertia),
            false => ((pos, quat), inertia),
        };

        self.bodies.push(Body {
            name,
            parent,
            pos,
            quat,
            inertia: None,
            inertial_pos: Vec3::zeros(),
            inertial_quat: None,
            mass_unknown,
            joints,
            gravcomp,
            line: element.line,
        });
        self.records.push(BodyRecord {
            line: element.line,
            label: element.label(),
            inertia,
            has_joints,
            children: Vec::new(),
        });
        if let Some(parent) = parent {
            self.records[parent].children.push(index);
        }
        Ok(child_bodies.into_iter().map(|child| PendingBody { parent_moving: moving, ..child }).collect())
    }

    /// A warning on each pair of geoms MuJoCo would collide at qpos0
    /// (`super::contacts` says what is checked), unless `<flag contact>` or
    /// `<flag constraint>` turns contacts off.
    fn warn_of_contacts(&mut self, root: &Element) {
        let flags: Vec<Element> =
            root.children().filter(|s| s.tag() == "option").flat_map(|option| option.children()).collect();
        let disabled = |flag: &str| flags.iter().any(|f| f.text(flag) == Some("disable"));
        if disabled("contact") || disabled("constraint") {
            return;
        }
        let body = |name: &str| match name {
            "world" => Some(None),
            name => self.bodies.iter().position(|b| b.name == name && self.body_names.contains_key(name)).map(Some),
        };
        let exclusions = root.children().filter(|s| s.tag() == "contact").flat_map(|s| s.children());
        let excluded: Vec<_> = exclusions
            .filter(|e| e.tag() == "exclude")
            .filter_map(|e| Some((body(e.text("body1")?)?, body(e.text("body2")?)?)))
            .collect();
        let parents: Vec<Option<usize>> = self.bodies.iter().map(|b| b.parent).collect();
        let roots: Vec<bool> =
            self.bodies.iter().map(|b| !b.joints.is_empty() || self.mocap_bodies.contains(&b.name)).collect();
        let filter = BodyFilter {
            parents: &parents,
            poses: &self.world_poses,
            roots: &roots,
            filter_parent: !disabled("filterparent"),
            excluded: &excluded,
        };
        for (a, b) in contacts::touching(&self.contact_geoms, &filter) {
            let (first, second) = (&self.contact_geoms[a], &self.contact_geoms[b]);
            let warning = MjcfWarning {
                file: None,
                line: first.line,
                element: first.label.clone(),
                message: format!(
                    "touches <{}> (line {}) at the initial pose: MuJoCo would make contacts between them, \
                     nudyn models no contacts",
                    second.label,
                    self.sources.line_in_file(second.line)
                ),
            };
            self.warnings.push(warning);
        }
    }

    /// A free body without children aligned with its inertial frame
    /// (`<freejoint align>`, `<compiler alignfree>`): MuJoCo moves the body
    /// frame there, so that the free joint's qpos is the inertial frame's
    /// pose, and re-expresses the body's sites in it. Returns the body's new
    /// pose in its parent and its mass properties in the new frame.
    fn align_free(&mut self, index: usize, pose: Pose, inertia: BodyInertia) -> (Pose, BodyInertia) {
        let (principal, axes) = (inertia.principal, inertia.quat);
        let inverse = (-(axes.inverse() * inertia.com), axes.inverse());
        for site in self.sites.iter_mut().filter(|s| s.body == Some(index)) {
            (site.pos, site.quat) = compose(&inverse, &(site.pos, site.quat));
        }
        let aligned = BodyInertia::from_principal(inertia.mass, Vec3::zeros(), &Quat::identity(), principal);
        (compose(&pose, &(inertia.com, axes)), aligned)
    }

    /// The children of a body (or of the world body) of class `class`, with
    /// the elements inside its `<frame>`s and `<replicate>`s, nested or not,
    /// in their place in document order: MuJoCo's frames vanish when it
    /// compiles a model, their pose composed into their children's and their
    /// `childclass` handed on; a replicate is the same as its copies, each
    /// in a frame of its own, their names suffixed (`suffix`: that of the
    /// replicates around `parent`).
    fn placed_children<'a>(
        &self,
        parent: &Element<'a, 'a>,
        class: usize,
        suffix: &str,
    ) -> Result<Vec<Placed<'a>>, MjcfError> {
        let mut placed = Vec::new();
        // Reversed, so that the first child comes off the stack first.
        let mut pending: Vec<Placed<'a>> = parent
            .children()
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .map(|element| Placed { element, frame: None, class, suffix: suffix.to_string() })
            .collect();
        while let Some(item) = pending.pop() {
            let copies = match item.element.tag() {
                "frame" => self.frame_pose(&item)?,
                "replicate" => self.replicate_poses(&item)?,
                _ => {
                    placed.push(item);
                    continue;
                }
            };
            let container = &item.element;
            let class = self.defaults.lookup(container, "childclass")?.unwrap_or(item.class);
            let children: Vec<_> = container.children().collect();
            for (pose, copy_suffix) in copies.into_iter().rev() {
                let pose = item.frame.map_or(pose, |outer| compose(&outer, &pose));
                // MuJoCo appends an inner replicate's suffix first.
                let suffix = format!("{copy_suffix}{}", item.suffix);
                pending.extend(children.iter().rev().map(|&element| Placed {
                    element,
                    frame: Some(pose),
                    class,
                    suffix: suffix.clone(),
                }));
            }
        }
        Ok(placed)
    }

    /// A `<frame>`'s pose in its parent, as one copy without a suffix.
    fn frame_pose(&self, item: &Placed) -> Result<Vec<(Pose, String)>, MjcfError> {
        let frame = &item.element;
        frame.check_attributes(FRAME_ATTRIBUTES)?;
        let pos = Vec3::from(frame.numbers::<3>("pos")?.unwrap_or_default());
        let quat = self.resolve(frame, &Orientation::read(frame)?.unwrap_or_default())?;
        Ok(vec![((pos, quat), String::new())])
    }

    /// The poses and name suffixes of a `<replicate>`'s copies, as MuJoCo
    /// 4.0 makes them (`mjXReader::Body`): copy i turned by i·euler (the
    /// compiler's angle unit and sequence), at p_i with p_0 = 0 and
    /// p_{i+1} = p_i + q^i · offset (q: the turn of one copy), its suffix
    /// `sep` and i padded with zeros to the digits of `count`.
    fn replicate_poses(&self, item: &Placed) -> Result<Vec<(Pose, String)>, MjcfError> {
        let replicate = &item.element;
        replicate.check_attributes(REPLICATE_ATTRIBUTES)?;
        let [count] = replicate.integers::<1>("count")?.ok_or_else(|| replicate.missing("count"))?;
        if count <= 0 {
            return Err(replicate.bad_value("count", "a positive number of copies"));
        }
        // Counted before any copy is made.
        let inside = replicate.node.descendants().filter(|node| node.is_element()).count() - 1;
        let produced = (count as usize).saturating_mul(inside).saturating_add(self.replicated_elements.get());
        if produced > MAX_REPLICATED_ELEMENTS {
            return Err(replicate.invalid(format!(
                "{count} copies of the {inside} elements inside it would take the file's replicates past \
                 {MAX_REPLICATED_ELEMENTS} elements, the most nudyn reads"
            )));
        }
        self.replicated_elements.set(produced);
        let offset = Vec3::from(replicate.numbers::<3>("offset")?.unwrap_or_default());
        let euler = replicate.numbers::<3>("euler")?.unwrap_or_default();
        let separator = replicate.text("sep").unwrap_or_default();
        let step = self.resolve(replicate, &Orientation::Euler(euler))?;
        let digits = count.to_string().len();
        let (mut pos, mut turned) = (Vec3::zeros(), Quat::identity());
        let mut copies = Vec::with_capacity(count as usize);
        for i in 0..count {
            // MuJoCo resolves i·euler afresh for each copy's orientation,
            // and accumulates the turn only for the positions.
            let quat = self.resolve(replicate, &Orientation::Euler(euler.map(|angle| f64::from(i) * angle)))?;
            copies.push(((pos, quat), format!("{separator}{i:0digits$}")));
            pos += turned * offset;
            turned *= step;
        }
        Ok(copies)
    }

    /// The class of a joint, geom or site: its `class`, else its body's class.
    fn class_of(&self, element: &Element, body_class: usize) -> Result<usize, MjcfError> {
        Ok(self.defaults.lookup(element, "class")?.unwrap_or(body_class))
    }

    /// Reads a `<site>` of body `body` (`None`: the world body).
    fn read_site(
        &mut self,
        element: &Element,
        body_class: usize,
        body: Option<usize>,
        frame: Option<Pose>,
        suffix: &str,
    ) -> Result<(), MjcfError> {
        element.check_attributes(SITE_ATTRIBUTES)?;
        no_children(element)?;
        let mut settings = self.defaults.class(self.class_of(element, body_class)?).site.clone();
        settings.apply(element)?;
        let (pos, quat) = match settings.fromto {
            Some(fromto) => {
                if settings.kind == SiteKind::Sphere {
                    return Err(element.invalid("'fromto' requires a capsule, cylinder, ellipsoid or box site"));
                }
                let (pos, quat, _) = fromto_frame(element, &fromto, &settings.pos)?;
                (pos, quat)
            }
            None => (Vec3::from(settings.pos), self.resolve(element, &settings.orientation)?),
        };
        let (pos, quat) = frame.map_or((pos, quat), |frame| compose(&frame, &(pos, quat)));
        let name = element.text("name").map(|name| self.replicated_name(name, suffix));
        if let Some(name) = &name {
            claim_name(&mut self.site_names, "site", name, element)?;
        }
        self.sites.push(Site { name, body, pos, quat, line: element.line });
        self.site_fitted_to_mesh.push(settings.mesh);
        Ok(())
    }

    fn resolve(&self, element: &Element, orientation: &Orientation) -> Result<Quat, MjcfError> {
        orientation.resolve(&self.compiler.angles).map_err(|reason| element.invalid(reason))
    }

    fn read_inertial(&self, element: &Element) -> Result<BodyInertia, MjcfError> {
        element.check_attributes(INERTIAL_ATTRIBUTES)?;
        no_children(element)?;
        let com = Vec3::from(element.numbers::<3>("pos")?.ok_or_else(|| element.missing("pos"))?);
        let mass = element.non_negative("mass")?.ok_or_else(|| element.missing("mass"))?;
        let orientation = Orientation::read(element)?;
        let Some([xx, yy, zz, xy, xz, yz]) = element.numbers::<6>("fullinertia")? else {
            let principal = element.non_negative_numbers::<3>("diaginertia")?.unwrap_or_default();
            let quat = self.resolve(element, &orientation.unwrap_or_default())?;
            return Ok(BodyInertia::from_principal(mass, com, &quat, Vec3::from(principal)));
        };
        if let Some(attribute) = ORIENTATION_ATTRIBUTES.iter().find(|a| element.has(a)) {
            return Err(element.conflict("fullinertia", attribute));
        }
        if element.has("diaginertia") {
            return Err(element.conflict("fullinertia", "diaginertia"));
        }
        let tensor = Mat3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
        BodyInertia::from_tensor(mass, com, tensor).map_err(|r| element.invalid(format!("fullinertia: {r}")))
    }

    /// Applies `boundmass`, `boundinertia` and MuJoCo's triangle inequality.
    fn bound(&self, element: &Element, mut inertia: BodyInertia) -> Result<BodyInertia, MjcfError> {
        let compiler = &self.compiler;
        inertia.mass = inertia.mass.max(compiler.bound_mass);
        let bounded = inertia.principal.map(|p| p.max(compiler.bound_inertia));
        if bounded != inertia.principal {
            inertia.set_principal(bounded);
        }
        let p = inertia.principal;
        if p.x + p.y < p.z || p.x + p.z < p.y || p.y + p.z < p.x {
            if !compiler.balance_inertia {
                return Err(element.invalid(format!(
                    "principal moments of inertia {} {} {} violate A + B >= C; \
                     fix them or set <compiler balanceinertia=\"true\">",
                    p.x, p.y, p.z
                )));
            }
            inertia.set_principal(Vec3::repeat(p.sum() / 3.0));
        }
        Ok(inertia)
    }

    /// A primitive's size and frame once fitted to its mesh: MuJoCo's
    /// compiler sizes and places it by the mesh, then forgets the mesh.
    fn fit_to_mesh(
        &self,
        element: &Element,
        settings: &GeomSettings,
        mesh: &mesh::Mesh,
        size: [f64; 3],
        pos: Vec3,
        quat: Quat,
    ) -> Result<([f64; 3], Vec3, Quat), MjcfError> {
        let kind = settings.kind;
        let (fitted, center) = mesh
            .fit(kind, size, self.compiler.fit_aabb, settings.fit_scale)
            .ok_or_else(|| element.invalid(format!("a {kind:?} geom cannot be fitted to a mesh")))?;
        let (pos, quat) = absorb_frame(pos, quat, &mesh.frame_point(&center), &mesh.quat);
        Ok((fitted, pos, quat))
    }

    /// Registers a named geom of `body` (`None`: the world) for tendons to
    /// wrap around: its type, and a sphere's or cylinder's frame in the body.
    fn name_geom(
        &mut self,
        element: &Element,
        settings: &GeomSettings,
        frame: Option<&Pose>,
        body: Option<usize>,
        suffix: &str,
    ) -> Result<(), MjcfError> {
        let Some(name) = element.text("name") else { return Ok(()) };
        let name = self.replicated_name(name, suffix);
        let wrap = match settings.kind {
            GeomKind::Sphere | GeomKind::Cylinder => {
                let (pos, quat) = match settings.fromto {
                    Some(_) if settings.mesh.is_some() => {
                        return Err(element.invalid("fromto cannot be used with a mesh"));
                    }
                    Some(fromto) if settings.kind == GeomKind::Cylinder => {
                        let (pos, quat, _) = fromto_frame(element, &fromto, &settings.pos)?;
                        (pos, quat)
                    }
                    _ => (Vec3::from(settings.pos), self.resolve(element, &settings.orientation)?),
                };
                let (pos, quat) = frame.map_or((pos, quat), |frame| compose(frame, &(pos, quat)));
                let (size, pos, quat) = match &settings.mesh {
                    Some(name) => {
                        let mesh = self.mesh_named(element, name)?.mesh()?;
                        self.fit_to_mesh(element, settings, mesh, settings.size, pos, quat)?
                    }
                    None => (settings.size, pos, quat),
                };
                if size[0] <= 0.0 {
                    return Err(element.invalid(format!("size[0] must be positive, found {}", size[0])));
                }
                let cylinder = settings.kind == GeomKind::Cylinder;
                Some(WrapGeom { body, pos, quat, radius: size[0], cylinder })
            }
            _ => None,
        };
        self.named_geoms.insert(name, (settings.kind, wrap));
        Ok(())
    }

    /// The mesh asset a geom names (not read yet).
    fn mesh_named(&self, element: &Element, name: &str) -> Result<&mesh::MeshAsset, MjcfError> {
        self.meshes.get(name).ok_or_else(|| element.invalid(format!("unknown mesh '{name}'")))
    }

    /// The geom's mass, frame and principal moments when it contributes to its
    /// body's inertia; checks it as MuJoCo does either way, but for what
    /// needs its mesh, which is read only when it contributes.
    fn geom_mass(
        &self,
        element: &Element,
        settings: &GeomSettings,
        frame: Option<&Pose>,
        moving: bool,
        contributes: bool,
    ) -> Result<GeomRead, MjcfError> {
        if matches!(settings.kind, GeomKind::Mesh | GeomKind::Sdf) && settings.mesh.is_none() {
            return Err(element.missing("mesh"));
        }
        if settings.kind == GeomKind::Hfield && !settings.hfield {
            return Err(element.missing("hfield"));
        }
        if settings.kind == GeomKind::Plane && moving {
            return Err(element.invalid("a plane geom is only allowed in a body that cannot move"));
        }
        let mut size = settings.size;
        let (pos, quat) = match settings.fromto {
            Some(fromto) => {
                if !matches!(
                    settings.kind,
                    GeomKind::Capsule | GeomKind::Cylinder | GeomKind::Ellipsoid | GeomKind::Box
                ) {
                    return Err(element.invalid("'fromto' requires a capsule, cylinder, ellipsoid or box geom"));
                }
                let (pos, quat, half_length) = fromto_frame(element, &fromto, &settings.pos)?;
                if matches!(settings.kind, GeomKind::Ellipsoid | GeomKind::Box) {
                    size = [size[0], size[0], half_length];
                } else {
                    size[1] = half_length;
                }
                (pos, quat)
            }
            None => (Vec3::from(settings.pos), self.resolve(element, &settings.orientation)?),
        };
        let (pos, quat) = frame.map_or((pos, quat), |frame| compose(frame, &(pos, quat)));
        let mesh = match &settings.mesh {
            Some(name) => {
                if settings.fromto.is_some() {
                    return Err(element.invalid("fromto cannot be used with a mesh"));
                }
                let asset = self.mesh_named(element, name)?;
                if settings.kind == GeomKind::Mesh && settings.shell_inertia {
                    return Err(element.invalid("for mesh geoms, inertia should be specified in the mesh asset"));
                }
                // A mesh is read only for a mass nudyn needs: one that only
                // shapes contacts is never opened (nor a primitive's size fitted to it).
                if !contributes {
                    return Ok(GeomRead { mass: None, reach: None });
                }
                Some(asset.mesh()?)
            }
            None => None,
        };
        let (pos, quat) = match (settings.kind, mesh) {
            (GeomKind::Mesh | GeomKind::Sdf, _) | (_, None) => (pos, quat),
            (_, Some(mesh)) => {
                let (fitted, pos, quat) = self.fit_to_mesh(element, settings, mesh, size, pos, quat)?;
                size = fitted;
                (pos, quat)
            }
        };
        check_size(element, settings.kind, &size)?;
        let mesh = match (settings.kind, mesh) {
            (GeomKind::Mesh, Some(mesh)) => {
                if settings.contype != [0, 0]
                    && let Some(reason) = &mesh.hull_error
                {
                    return Err(element.invalid(format!(
                        "mesh '{}' (line {}): {reason}; MuJoCo needs the hull of a colliding geom's mesh \
                         (contype or conaffinity not 0)",
                        settings.mesh.as_deref().unwrap_or_default(),
                        mesh.line
                    )));
                }
                Some(mesh)
            }
            _ => None,
        };
        let reach = contacts::reach(settings.kind, &size).map(|reach| (pos, quat, reach));
        if !contributes {
            return Ok(GeomRead { mass: None, reach });
        }
        // A body that cannot move needs no mass: its sdf or height field is never read.
        if mass_not_computed(settings) && !moving {
            return Ok(GeomRead { mass: None, reach });
        }
        if mass_not_computed(settings) {
            return Err(element.unsupported(
                "the mass properties of sdf and height-field geoms are not computed; give the body an \
                 <inertial>, or put the geom in a group outside inertiagrouprange",
            ));
        }
        let (pos, quat, volume) = match mesh {
            // The geom's frame absorbs the mesh frame (MuJoCo's mjuu_frameaccum).
            Some(mesh) => {
                let (pos, quat) = absorb_frame(pos, quat, &mesh.pos, &mesh.quat);
                (pos, quat, mesh.volume)
            }
            None => (pos, quat, inertia::volume(settings.kind, &size, settings.shell_inertia)),
        };
        let mass = match settings.mass {
            Some(mass) if volume > EPS => mass,
            // MuJoCo ignores a given mass when the volume is zero.
            Some(_) => 0.0,
            None => settings.density * volume,
        };
        let principal = match mesh {
            Some(mesh) => Vec3::from(mesh.principal_moments(mass)),
            None => inertia::principal_moments(settings.kind, &size, mass, settings.shell_inertia),
        };
        Ok(GeomRead { mass: Some(GeomMass { mass, pos, quat, principal }), reach })
    }

    /// Keeps a geom that may collide for the warning on contacts.
    fn add_contact_geom(
        &mut self,
        element: &Element,
        settings: &GeomSettings,
        body: Option<usize>,
        reach: Option<(Vec3, Quat, Reach)>,
    ) {
        let [contype, conaffinity] = settings.contype;
        if let Some((pos, quat, reach)) = reach
            && (contype != 0 || conaffinity != 0)
        {
            self.contact_geoms.push(ContactGeom {
                body,
                pos,
                quat,
                reach,
                contype,
                conaffinity,
                margin: settings.margin,
                label: element.label(),
                line: element.line,
            });
        }
    }

    /// Checks a body's joints and turns them into [`Joint`]s.
    fn build_joints(
        &mut self,
        body_name: &str,
        parent: Option<usize>,
        elements: Vec<JointElement>,
    ) -> Result<Vec<Joint>, MjcfError> {
        let count = elements.len();
        let mut joints = Vec::with_capacity(count);
        let mut after_ball = false;
        let mut dofs = 0;
        for (k, joint) in elements.into_iter().enumerate() {
            let JointElement { element, settings: s, suffix, .. } = joint;
            let origin = |attribute: &str| {
                if element.has(attribute) { "" } else { " (from its default class)" }
            };
            if s.springdamper != [0.0; 2] && !(s.springdamper[0] > 0.0 && s.springdamper[1] > 0.0) {
                return Err(element.bad_value("springdamper", "two positive values (time constant, damping ratio)"));
            }
            if s.springyield != 0.0 {
                return Err(element.unsupported(format!("springyield{}: yielding springs", origin("springyield"))));
            }
            for (attribute, coefficients) in [("stiffness", &s.stiffness), ("damping", &s.damping)] {
                if coefficients[1..] != [0.0; 2] {
                    return Err(element.unsupported(format!(
                        "nonlinear {attribute}{} (more than one coefficient)",
                        origin(attribute)
                    )));
                }
            }

            let rotational = matches!(s.kind, JointKind::Hinge | JointKind::Ball);
            if rotational && after_ball {
                return Err(element.unsupported(
                    "a hinge or ball joint after a ball joint in the same body (MuJoCo allows no rotation after a ball joint)",
                ));
            }
            after_ball |= s.kind == JointKind::Ball;

            if s.kind == JointKind::Free {
                if count > 1 {
                    return Err(element.invalid("a free joint must be the only joint of its body"));
                }
                if parent.is_some() {
                    return Err(element.invalid("a free joint must belong to a body directly inside <worldbody>"));
                }
            } else {
                self.check_limits(&element, &s)?;
            }
            dofs += s.kind.nv();
            if dofs > 6 {
                return Err(element.invalid("more than 6 degrees of freedom in one body"));
            }

            let axis = match s.kind {
                JointKind::Hinge | JointKind::Slide => normalized(Vec3::from(s.axis))
                    .ok_or_else(|| element.bad_value("axis", "a vector that is not zero"))?,
                JointKind::Ball | JointKind::Free => Vec3::z(),
            };
            let (reference, springref) = match s.kind {
                JointKind::Hinge => {
                    let angles = &self.compiler.angles;
                    (angles.radians(s.reference), angles.radians(s.springref))
                }
                JointKind::Slide => (s.reference, s.springref),
                JointKind::Ball | JointKind::Free => (0.0, 0.0),
            };
            let actuator_force_range = self.actuator_force_range(&element, &s)?;
            let named = element.text("name");
            let name =
                named.map_or_else(|| format!("{body_name}_joint{k}"), |name| self.replicated_name(name, &suffix));
            if named.is_some() {
                claim_name(&mut self.joint_names, "joint", &name, &element)?;
            }
            let range = match s.kind {
                JointKind::Hinge | JointKind::Ball if self.joint_limited(&s) => {
                    s.range.map(|x| self.compiler.angles.radians(x))
                }
                _ => s.range,
            };
            let limited = s.kind != JointKind::Free && self.joint_limited(&s);
            if named.is_some() {
                self.joint_targets.insert(name.clone(), JointTarget { kind: s.kind, range, limited });
            }
            joints.push(Joint {
                name,
                kind: s.kind,
                pos: if s.kind == JointKind::Free { Vec3::zeros() } else { Vec3::from(s.pos) },
                axis,
                reference,
                springref,
                stiffness: if self.physics.spring_disabled { 0.0 } else { s.stiffness[0] },
                damping: if self.physics.damper_disabled { 0.0 } else { s.damping[0] },
                armature: s.armature,
                actuator_force_range,
                actuator_gravcomp: s.actuator_gravcomp,
                springdamper: (s.springdamper != [0.0; 2]).then_some(SpringDamper {
                    time_constant: s.springdamper[0],
                    damping_ratio: s.springdamper[1],
                    spring: !self.physics.spring_disabled,
                    damper: !self.physics.damper_disabled,
                }),
                constraints: self.joint_constraints(&s, range),
                line: element.line,
            });
        }
        Ok(joints)
    }

    /// The joint's friction loss and limits as constraints, less what the
    /// `<flag>`s turn off (`range` in radians for hinges).
    fn joint_constraints(&self, settings: &JointSettings, range: [f64; 2]) -> JointConstraints {
        let physics = &self.physics;
        let on = |disabled: bool| !physics.constraint_disabled && !disabled;
        let limited = settings.kind != JointKind::Free && self.joint_limited(settings);
        JointConstraints {
            frictionloss: if on(physics.frictionloss_disabled) { settings.frictionloss } else { 0.0 },
            friction: settings.friction_soft,
            limit: (limited && on(physics.limit_disabled)).then_some(JointLimit {
                range,
                margin: settings.margin,
                soft: settings.limit_soft,
            }),
        }
    }

    /// Whether a joint other than a free one has limits (MuJoCo's rule).
    fn joint_limited(&self, settings: &JointSettings) -> bool {
        let [low, high] = settings.range;
        settings.limited == Limited::Yes || (settings.limited == Limited::Auto && low < high)
    }

    /// MuJoCo's checks of joint limits.
    fn check_limits(&mut self, element: &Element, settings: &JointSettings) -> Result<(), MjcfError> {
        let [low, high] = settings.range;
        if settings.limited == Limited::Auto && settings.range != [0.0; 2] && !self.compiler.autolimits {
            return Err(element.invalid(
                "'range' without 'limited' while <compiler autolimits=\"false\">; give 'limited' or remove 'range'",
            ));
        }
        if !self.joint_limited(settings) {
            return Ok(());
        }
        if settings.kind == JointKind::Ball {
            if low != 0.0 {
                return Err(element.invalid("the first 'range' value of a ball joint must be 0"));
            }
        } else if low >= high {
            return Err(element.invalid("the first 'range' value must be smaller than the second"));
        }
        Ok(())
    }

    /// A hinge or slide joint's limits on the total actuator force
    /// (`actuatorfrclimited`, `actuatorfrcrange`); ball and free joints have none.
    fn actuator_force_range(&self, element: &Element, settings: &JointSettings) -> Result<Option<[f64; 2]>, MjcfError> {
        if matches!(settings.kind, JointKind::Ball | JointKind::Free) {
            return Ok(None);
        }
        self.limits(element, "actuatorfrc", settings.actuator_force_limited, settings.actuator_force_range)
    }

    /// MuJoCo's rule for an `<prefix>limited` and `<prefix>range` pair: with
    /// "auto", limited when the range is not empty (a range given without the
    /// flag is an error under `autolimits="false"`); a limited range must be
    /// increasing.
    fn limits(
        &self,
        element: &Element,
        prefix: &str,
        limited: Limited,
        range: [f64; 2],
    ) -> Result<Option<[f64; 2]>, MjcfError> {
        if limited == Limited::Auto && range != [0.0; 2] && !self.compiler.autolimits {
            return Err(element.invalid(format!(
                "'{prefix}range' without '{prefix}limited' while <compiler autolimits=\"false\">; \
                 give '{prefix}limited' or remove '{prefix}range'"
            )));
        }
        let on = limited == Limited::Yes || (limited == Limited::Auto && range[0] < range[1]);
        if on && range[0] >= range[1] {
            return Err(element.invalid(format!(
                "invalid '{prefix}range' {} {}: the first value must be smaller than the second",
                range[0], range[1]
            )));
        }
        Ok(on.then_some(range))
    }

    /// Why an element of `<equality>` is refused.
    /// An equality constraint to a mocap body, refused: its pose is an
    /// input MuJoCo's users set, which an FMU does not take.
    fn mocap_equality_refusal(&self, element: &Element) -> Option<MjcfError> {
        let tag = element.tag();
        let site_body = |name: &str| {
            let site = self.sites.iter().find(|s| s.name.as_deref() == Some(name))?;
            site.body.map(|b| self.bodies[b].name.as_str())
        };
        let bodies = ["body1", "body2"].iter().filter_map(|a| element.text(a));
        let bodies = bodies.chain(["site1", "site2"].iter().filter_map(|a| element.text(a).and_then(site_body)));
        let body = bodies.into_iter().find(|body| self.mocap_bodies.iter().any(|m| m == body))?;
        Some(element.unsupported(format!(
            "<equality>/<{tag}> to mocap body '{body}': nudyn takes no mocap poses for the constraint to follow"
        )))
    }

    /// MuJoCo's checks of the `<key>`s of a `<keyframe>` section: each
    /// vector given has the model's size. nudyn does not use keyframes.
    fn check_keyframes(&self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        let joints = self.bodies.iter().flat_map(|b| &b.joints);
        let (nq, nv) = joints.fold((0, 0), |(nq, nv), j| (nq + j.kind.nq(), nv + j.kind.nv()));
        let nmocap = self.mocap_bodies.len();
        // Activation states are refused, so na is 0.
        let sizes = [
            ("qpos", nq),
            ("qvel", nv),
            ("act", 0),
            ("mpos", 3 * nmocap),
            ("mquat", 4 * nmocap),
            ("ctrl", self.actuators.len()),
        ];
        for key in section.children() {
            if key.tag() != "key" {
                return Err(key.unknown());
            }
            key.check_attributes(&["name", "time", "qpos", "qvel", "act", "mpos", "mquat", "ctrl"])?;
            no_children(&key)?;
            key.number("time")?;
            for (attribute, size) in sizes {
                let Some(text) = key.text(attribute) else { continue };
                let values: Result<Vec<f64>, _> = text.split_ascii_whitespace().map(str::parse).collect();
                let given = values.map_err(|_| key.bad_value(attribute, "numbers"))?.len();
                // An empty list counts as not given.
                if given != 0 && given != size {
                    return Err(key.invalid(format!("invalid {attribute} size, expected {size}, got {given}")));
                }
            }
        }
        Ok(())
    }

    /// Reads an `<actuator>` section.
    /// The `<equality>` section: each element read as MuJoCo reads it; the
    /// constraints kept unless a `<flag>` turns them off.
    fn read_equalities(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        for element in section.children() {
            if let Some(refusal) = self.mocap_equality_refusal(&element) {
                return Err(refusal);
            }
            let settings = self.defaults.class(self.class_of(&element, MAIN)?).equality.clone();
            let equality = equality::read(&element, settings, self)?;
            if !(self.physics.constraint_disabled || self.physics.equality_disabled) {
                self.equalities.push(equality);
            }
        }
        Ok(())
    }

    /// The `<tendon>` section: each `<fixed>` or `<spatial>` read as MuJoCo
    /// reads it, less what the `<flag>`s turn off.
    fn read_tendons(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        let physics = &self.physics;
        let flags = TendonFlags {
            autolimits: self.compiler.autolimits,
            spring_disabled: physics.spring_disabled,
            damper_disabled: physics.damper_disabled,
            frictionloss_disabled: physics.constraint_disabled || physics.frictionloss_disabled,
            limit_disabled: physics.constraint_disabled || physics.limit_disabled,
        };
        for element in section.children() {
            let settings = self.defaults.class(self.class_of(&element, MAIN)?).tendon.clone();
            let (read, limited) = tendon::read(&element, settings, self, flags)?;
            if let Some(name) = &read.name {
                claim_name(&mut self.tendon_names, "tendon", name, &element)?;
            }
            self.tendons.push(read);
            self.tendon_limited.push(limited);
        }
        Ok(())
    }

    /// The index of the tendon the attribute names.
    fn tendon_named(&self, element: &Element, attribute: &str, user: &str) -> Result<usize, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        self.tendons
            .iter()
            .position(|t| t.name.as_deref() == Some(name))
            .ok_or_else(|| element.invalid(format!("unknown tendon '{name}' in {user}")))
    }

    fn read_sensors(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        for child in section.children() {
            let Some(kind) = SensorKind::from_name(child.tag()) else {
                return Err(match sensor::refusal(child.tag()) {
                    Some(reason) => child.unsupported(reason),
                    None => child.unknown(),
                });
            };
            let read = sensor::read(&child, kind, self)?;
            if let Some(name) = &read.name {
                claim_name(&mut self.sensor_names, "sensor", name, &child)?;
            }
            self.sensors.push(read);
        }
        Ok(())
    }

    fn read_actuators(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        for child in section.children() {
            match actuator::kind_of(child.tag()) {
                Some(kind) => self.read_actuator(&child, kind)?,
                None => match actuator::refusal(child.tag()) {
                    Some(reason) => return Err(child.unsupported(reason)),
                    None => return Err(child.unknown()),
                },
            }
        }
        Ok(())
    }

    /// Reads one actuator element into MuJoCo's general actuator, with
    /// MuJoCo's compiler checks, refusing what nudyn does not model.
    fn read_actuator(&mut self, element: &Element, kind: ActuatorKind) -> Result<(), MjcfError> {
        element.check_attributes(&actuator::attributes(kind, false))?;
        no_children(element)?;
        let class = self.defaults.lookup(element, "class")?.unwrap_or(MAIN);
        let mut settings = self.defaults.class(class).actuator.clone();
        settings.apply(kind, element, self.defaults.lender(class, kind))?;
        let transmission = self.transmission(element)?;

        if settings.dyntype != "none" {
            return Err(element.unsupported(format!(
                "dyntype \"{}\": the actuator has an activation state, which nudyn does not integrate",
                settings.dyntype
            )));
        }
        let gain_type = match settings.gaintype {
            "fixed" => GainType::Fixed,
            "affine" => GainType::Affine,
            other => {
                return Err(element.unsupported(format!("gaintype \"{other}\" (nudyn models fixed and affine gains)")));
            }
        };
        let bias_type = match settings.biastype {
            "none" => BiasType::None,
            "affine" => BiasType::Affine,
            other => {
                return Err(element.unsupported(format!("biastype \"{other}\" (nudyn models none and affine biases)")));
            }
        };
        if settings.delay > 0.0 {
            return Err(element.unsupported("delay: the force would follow a ctrl history, which nudyn does not keep"));
        }
        if settings.armature != 0.0 || settings.damping != [0.0; 3] {
            return Err(element.unsupported(
                "actuator armature and damping; give the joint armature·gear² and damping·gear² instead",
            ));
        }
        match settings.actdim {
            2.. => return Err(element.invalid("actdim > 1 is only allowed for dyntype \"user\" and \"dcmotor\"")),
            1 => return Err(element.invalid("invalid actdim 1 in stateless actuator")),
            _ => {}
        }

        // A position servo may take its ctrlrange from its joint's range.
        let position_like = gain_type == GainType::Fixed
            && bias_type == BiasType::Affine
            && settings.gainprm[0] == -settings.biasprm[1];
        if position_like && settings.inheritrange > 0.0 {
            let (name, [low, high]) = match &transmission {
                Transmission::Joint { joint, .. } => {
                    let target = &self.joint_targets[joint];
                    if !matches!(target.kind, JointKind::Hinge | JointKind::Slide) {
                        return Err(element.invalid("inheritrange can only be used with hinge and slide joints"));
                    }
                    (joint.as_str(), target.range)
                }
                Transmission::Tendon { tendon } => {
                    let tendon = &self.tendons[*tendon];
                    (tendon.name.as_deref().unwrap_or_default(), tendon.range)
                }
                Transmission::Site { .. } => {
                    return Err(element.invalid("inheritrange can only be used with joint and tendon transmission"));
                }
            };
            if low == high {
                return Err(element.invalid(format!("inheritrange used but target '{name}' has no range defined")));
            }
            let (mean, radius) = (0.5 * (high + low), 0.5 * (high - low) * settings.inheritrange);
            settings.ctrlrange = [mean - radius, mean + radius];
        }
        let force_range = self.limits(element, "force", settings.forcelimited, settings.forcerange)?;
        let ctrl_range = self.limits(element, "ctrl", settings.ctrllimited, settings.ctrlrange)?;
        if self.limits(element, "act", settings.actlimited, settings.actrange)?.is_some() {
            return Err(element.invalid("actrange specified but dyntype is 'none'"));
        }

        let name = element.text("name").map(str::to_string);
        if let Some(name) = &name {
            claim_name(&mut self.actuator_names, "actuator", name, element)?;
        }
        let group = settings.group;
        self.actuators.push(Actuator {
            name,
            kind,
            transmission,
            gear: settings.gear,
            gain_type,
            gain: [settings.gainprm[0], settings.gainprm[1], settings.gainprm[2]],
            bias_type,
            bias: [settings.biasprm[0], settings.biasprm[1], settings.biasprm[2]],
            ctrl_range,
            force_range,
            group_disabled: ACTUATOR_GROUPS.contains(&group) && self.physics.disabled_actuator_groups.contains(&group),
            line: element.line,
        });
        Ok(())
    }

    /// The transmission an actuator element names: a joint, or a site with
    /// an optional reference site. Tendon, slider-crank and body
    /// transmissions are refused.
    fn transmission(&self, element: &Element) -> Result<Transmission, MjcfError> {
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
        let name = element.text(target).unwrap_or_default();
        if target == "tendon" {
            return Ok(Transmission::Tendon { tendon: self.tendon_named(element, "tendon", "actuator")? });
        }
        if target != "site" {
            if !self.joint_targets.contains_key(name) {
                return Err(self.unknown(element, &format!("transmission target '{name}' for actuator"), name));
            }
            return Ok(Transmission::Joint { joint: name.to_string(), in_parent: target == "jointinparent" });
        }
        let site = self.site_named(element, "site", "actuator")?;
        let refsite = match element.has("refsite") {
            true => Some(self.site_named(element, "refsite", "actuator")?),
            false => None,
        };
        Ok(Transmission::Site { site, refsite })
    }

    /// The name of an element in a `<replicate>` copy (`suffix` empty
    /// outside replicates), remembered for [`Reader::unknown`].
    fn replicated_name(&mut self, name: &str, suffix: &str) -> String {
        let copy = format!("{name}{suffix}");
        if !suffix.is_empty() {
            self.replicated.entry(name.to_string()).or_insert_with(|| copy.clone());
        }
        copy
    }

    /// The error for a reference to `name`, which names nothing of its kind
    /// (`described`: the kind, the name and where it stands). MuJoCo copies
    /// an element naming something inside a `<replicate>` for each copy;
    /// nudyn does not, and says so.
    fn unknown(&self, element: &Element, described: &str, name: &str) -> MjcfError {
        let hint = match self.replicated.get(name) {
            Some(copy) => format!(
                ": it is inside a <replicate>, whose copies are named '{copy}' and so on; nudyn does not copy \
                 the elements that name it (MuJoCo does): name a copy instead"
            ),
            None => String::new(),
        };
        element.invalid(format!("unknown {described}{hint}"))
    }

    /// The index of the site the attribute names; a site fitted to a mesh is
    /// refused (the mesh would move its frame).
    fn site_named(&self, element: &Element, attribute: &str, user: &str) -> Result<usize, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        let Some(index) = self.sites.iter().position(|s| s.name.as_deref() == Some(name)) else {
            return Err(self.unknown(element, &format!("{attribute} '{name}' for {user}"), name));
        };
        if self.site_fitted_to_mesh[index] {
            return Err(element.unsupported(format!(
                "{attribute} '{name}' (line {}) is fitted to a mesh, which would move its frame",
                self.sites[index].line
            )));
        }
        Ok(index)
    }

    /// The checks that need the whole tree, `settotalmass`, and the vehicle.
    /// The joint a sensor's attribute names.
    fn sensed_joint(&self, element: &Element, attribute: &str) -> Result<&JointTarget, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        self.joint_targets.get(name).ok_or_else(|| self.unknown(element, &format!("joint '{name}' in sensor"), name))
    }

    fn finish(mut self, name: String) -> Result<Imported, MjcfError> {
        let valid = |r: &BodyRecord| r.inertia.mass >= MIN_VALUE && r.inertia.principal.min() >= MIN_VALUE;
        for record in self.records.iter().filter(|r| r.has_joints && !valid(r)) {
            // MuJoCo accepts it when a body welded below it carries the mass.
            let mut welded: Vec<usize> = record.children.clone();
            let mut carried = false;
            while let Some(index) = welded.pop() {
                let child = &self.records[index];
                if child.has_joints {
                    continue;
                }
                carried |= valid(child);
                welded.extend(&child.children);
            }
            if !carried {
                return Err(MjcfError::Invalid {
                    line: record.line,
                    element: record.label.clone(),
                    reason: "a moving body needs mass and principal moments of inertia of at least 1e-15 \
                             (MuJoCo's mjMINVAL), or a body welded to it that has them"
                        .to_string(),
                });
            }
        }

        if self.compiler.fuse_static {
            self.fuse_static()?;
        }

        if let Some((total, warning)) = self.compiler.total_mass.take() {
            let sum: f64 = self.records.iter().map(|r| r.inertia.mass).sum();
            if sum < MIN_VALUE {
                return Err(MjcfError::Invalid {
                    line: warning.line,
                    element: warning.element,
                    reason: "settotalmass cannot scale a model without mass".to_string(),
                });
            }
            for record in &mut self.records {
                record.inertia.scale(total / sum);
            }
            self.warnings.push(warning);
        }

        for (body, record) in self.bodies.iter_mut().zip(&self.records) {
            let inertia = &record.inertia;
            let massless = inertia.mass == 0.0 && inertia.tensor == Mat3::zeros();
            body.inertia =
                (!massless).then_some(MassProperties { mass: inertia.mass, com: inertia.com, inertia: inertia.tensor });
            body.inertial_pos = inertia.com;
            body.inertial_quat = Some(inertia.quat);
        }
        // MuJoCo's passive stage, which computes the gravity compensation,
        // stops before it when springs and dampers are both disabled (the
        // compensation still decided what fusestatic fused).
        if self.physics.spring_disabled && self.physics.damper_disabled {
            self.bodies.iter_mut().for_each(|body| body.gravcomp = 0.0);
        }
        self.warnings.sort_by_key(|w| w.line);
        let gravity = if self.physics.gravity_disabled { Vec3::zeros() } else { self.physics.gravity };
        let vehicle = Vehicle {
            name,
            gravity,
            magnetic: self.physics.magnetic,
            bodies: self.bodies,
            sites: self.sites,
            actuators: self.actuators,
            sensors: self.sensors,
            actuation: self.physics.actuation,
            constraint_options: self.physics.constraint_options,
            equalities: std::mem::take(&mut self.equalities),
            sensors_disabled: self.physics.sensor_disabled,
            tendons: std::mem::take(&mut self.tendons),
        };
        Ok(Imported { vehicle, warnings: self.warnings })
    }
}

impl Reader {
    /// `<compiler fusestatic="true">` as MuJoCo 4.0 applies it
    /// (`mjCModel::FuseStatic`), in body order: a body without joints, not
    /// mocap, not named by anything that refers to bodies (a sensor, a
    /// camera's or light's target, a contact exclusion), carrying no site a
    /// force or torque sensor reads, and not with a mass under another
    /// gravcomp than its parent's (unless that is the world) disappears
    /// into its parent. Its mass properties join the parent's (unless the parent is
    /// the world, or its mass is below mjMINVAL), its child bodies and sites
    /// become the parent's, placed where they were. The parent's inertial
    /// frame moves: sensors of objtype "body" on it measure the merged one.
    fn fuse_static(&mut self) -> Result<(), MjcfError> {
        let mut referenced = vec![false; self.bodies.len()];
        for sensor in &self.sensors {
            match &sensor.target {
                // MuJoCo 4.0 keeps the body a force or torque sensor's site is
                // on, named or not: the sensor reads that body's interaction force.
                SensorTarget::Frame { object: FrameObject::Site(site), .. }
                    if matches!(sensor.kind, SensorKind::Force | SensorKind::Torque) =>
                {
                    if let Some(body) = self.sites[*site].body {
                        referenced[body] = true;
                    }
                }
                SensorTarget::Frame { object, reference } => {
                    for object in std::iter::once(object).chain(reference) {
                        if let FrameObject::Body(Some(body)) | FrameObject::XBody(Some(body)) = object {
                            referenced[*body] = true;
                        }
                    }
                }
                SensorTarget::Subtree(Some(body)) => referenced[*body] = true,
                _ => {}
            }
        }
        // MuJoCo keeps a body an equality constraint names.
        for equality in &self.equalities {
            if let Some(EqualityObjects::Bodies(first, second)) = equality.kind.objects() {
                for body in [first, second].into_iter().flatten() {
                    referenced[body] = true;
                }
            }
        }
        // Bodies in document order; `host`: the body each one's mass ends
        // up in once fused (itself if kept, None for the world).
        let mut kept = Vec::with_capacity(self.bodies.len());
        let mut host: Vec<Option<usize>> = Vec::with_capacity(self.bodies.len());
        for (index, body) in self.bodies.iter().enumerate() {
            let parent_host = body.parent.and_then(|p| host[p]);
            let named = self.named_elsewhere.contains(&body.name) || self.mocap_bodies.contains(&body.name);
            // MuJoCo 4.0 keeps a body whose mass its host would compensate
            // otherwise (found by trying it: its published source does not
            // have this yet).
            let compensated_otherwise = parent_host.is_some_and(|p| self.bodies[p].gravcomp != body.gravcomp)
                && self.records[index].inertia.mass >= MIN_VALUE;
            let keep = referenced[index] || named || !body.joints.is_empty() || compensated_otherwise;
            kept.push(keep);
            host.push(if keep { Some(index) } else { parent_host });
        }

        for index in kept.iter().enumerate().filter(|(_, kept)| !**kept).map(|(index, _)| index) {
            let pose = (self.bodies[index].pos, self.bodies[index].quat);
            let parent = self.bodies[index].parent;
            if let Some(parent) = parent {
                let fused = &self.records[index];
                if fused.inertia.mass >= MIN_VALUE {
                    let merged = self.records[parent].inertia.merged(&fused.inertia, &pose.0, &pose.1);
                    self.records[parent].inertia = merged.map_err(|reason| MjcfError::Invalid {
                        line: fused.line,
                        element: fused.label.clone(),
                        reason: format!("error '{reason}' in fusing static body inertias"),
                    })?;
                }
                self.bodies[parent].mass_unknown |= self.bodies[index].mass_unknown;
            }
            for child in self.bodies.iter_mut().filter(|b| b.parent == Some(index)) {
                child.parent = parent;
                (child.pos, child.quat) = compose(&pose, &(child.pos, child.quat));
            }
            for site in self.sites.iter_mut().filter(|s| s.body == Some(index)) {
                site.body = parent;
                (site.pos, site.quat) = compose(&pose, &(site.pos, site.quat));
            }
            for geom in wrap_geoms_mut(&mut self.tendons).filter(|g| g.body == Some(index)) {
                geom.body = parent;
                (geom.pos, geom.quat) = compose(&pose, &(geom.pos, geom.quat));
            }
        }

        // Renumber the bodies left.
        let mut new_index = Vec::with_capacity(kept.len());
        let mut next = 0;
        for &keep in &kept {
            new_index.push(keep.then_some(next));
            next += usize::from(keep);
        }
        let renumber = |body: &mut Option<usize>| *body = body.and_then(|b| new_index[b]);
        let mut keep = kept.iter().copied();
        self.bodies.retain(|_| keep.next().unwrap_or(true));
        let mut keep = kept.iter().copied();
        self.records.retain(|_| keep.next().unwrap_or(true));
        self.bodies.iter_mut().for_each(|b| renumber(&mut b.parent));
        self.sites.iter_mut().for_each(|s| renumber(&mut s.body));
        wrap_geoms_mut(&mut self.tendons).for_each(|g| renumber(&mut g.body));
        for sensor in &mut self.sensors {
            match &mut sensor.target {
                SensorTarget::Frame { object, reference } => {
                    for object in std::iter::once(object).chain(reference.as_mut()) {
                        if let FrameObject::Body(body) | FrameObject::XBody(body) = object {
                            renumber(body);
                        }
                    }
                }
                SensorTarget::Subtree(body) => renumber(body),
                _ => {}
            }
        }
        for equality in &mut self.equalities {
            if let Some(EqualityObjects::Bodies(first, second)) = equality.kind.objects_mut() {
                renumber(first);
                renumber(second);
            }
        }
        Ok(())
    }
}

/// The frame MuJoCo gives a geom or site with `fromto`: centred between the
/// two points, its z axis pointing from the second towards the first; and
/// the half distance between the points. A `pos` beside it is refused.
fn fromto_frame(element: &Element, fromto: &[f64; 6], pos: &[f64; 3]) -> Result<(Vec3, Quat, f64), MjcfError> {
    if *pos != [0.0; 3] {
        return Err(element.conflict("pos", "fromto"));
    }
    let from = Vec3::new(fromto[0], fromto[1], fromto[2]);
    let to = Vec3::new(fromto[3], fromto[4], fromto[5]);
    let direction = normalized(from - to).ok_or_else(|| element.invalid("the 'fromto' points coincide"))?;
    let half_length = (from - to).norm() / 2.0;
    Ok(((from + to) / 2.0, Quat::new_normalize(z_to_quaternion(&direction)), half_length))
}

/// The geoms the tendons wrap around.
fn wrap_geoms_mut(tendons: &mut [Tendon]) -> impl Iterator<Item = &mut WrapGeom> {
    tendons
        .iter_mut()
        .flat_map(|tendon| match &mut tendon.path {
            TendonPath::Spatial(points) => points.as_mut_slice(),
            TendonPath::Fixed(_) => &mut [],
        })
        .filter_map(|point| match point {
            PathPoint::Geom(geom) => Some(geom),
            _ => None,
        })
}

/// Whether a geom's mass would come from an asset nudyn does not read: an
/// sdf or a height field.
fn mass_not_computed(settings: &GeomSettings) -> bool {
    matches!(settings.kind, GeomKind::Sdf | GeomKind::Hfield)
}

/// A geom frame (`pos`, `quat`) that takes in a frame given inside it
/// (MuJoCo's `mjuu_frameaccum`).
fn absorb_frame(pos: Vec3, quat: Quat, inner_pos: &[f64; 3], inner_quat: &[f64; 4]) -> (Vec3, Quat) {
    let geom_quat = quat_array(&quat);
    let rotation = quat_to_mat(&geom_quat);
    let p = inner_pos;
    let offset: [f64; 3] =
        std::array::from_fn(|r| rotation[3 * r] * p[0] + rotation[3 * r + 1] * p[1] + rotation[3 * r + 2] * p[2]);
    let [w, x, y, z] = mul_quat(&geom_quat, inner_quat);
    (pos + Vec3::from(offset), Quat::new_unchecked(nalgebra::Quaternion::new(w, x, y, z)))
}

/// MuJoCo's size check: the sizes a primitive uses must be positive.
fn check_size(element: &Element, kind: GeomKind, size: &[f64; 3]) -> Result<(), MjcfError> {
    let (used, name) = match kind {
        GeomKind::Sphere => (0..1, "sphere"),
        GeomKind::Capsule => (0..2, "capsule"),
        GeomKind::Cylinder => (0..2, "cylinder"),
        GeomKind::Ellipsoid => (0..3, "ellipsoid"),
        GeomKind::Box => (0..3, "box"),
        GeomKind::Plane => (2..3, "plane"),
        GeomKind::Hfield | GeomKind::Mesh | GeomKind::Sdf => return Ok(()),
    };
    match used.into_iter().find(|&i| size[i] <= 0.0) {
        Some(i) => Err(element.invalid(format!("size[{i}] of a {name} geom must be positive, found {}", size[i]))),
        None => Ok(()),
    }
}

impl EqualityTargets for Reader {
    fn equality_body(&self, element: &Element, attribute: &str) -> Result<Option<usize>, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        if name == "world" {
            return Ok(None);
        }
        match self.bodies.iter().position(|b| b.name == name) {
            Some(index) if self.body_names.contains_key(name) => Ok(Some(index)),
            _ => Err(self.unknown(element, &format!("body '{name}' in equality constraint"), name)),
        }
    }

    fn equality_site(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        self.site_named(element, attribute, "equality constraint")
    }

    fn equality_tendon(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        self.tendon_named(element, attribute, "equality constraint")
    }

    fn equality_joint(&self, element: &Element, attribute: &str) -> Result<JointKind, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        self.joint_targets
            .get(name)
            .map(|joint| joint.kind)
            .ok_or_else(|| self.unknown(element, &format!("joint '{name}' in equality constraint"), name))
    }
}

impl TendonTargets for Reader {
    fn tendon_joint(&self, element: &Element, attribute: &str) -> Result<JointKind, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        self.joint_targets
            .get(name)
            .map(|joint| joint.kind)
            .ok_or_else(|| element.invalid(format!("unknown joint '{name}' in tendon")))
    }

    fn tendon_site(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        self.site_named(element, attribute, "tendon")
    }

    fn tendon_geom(&self, element: &Element, attribute: &str) -> Result<WrapGeom, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        match self.named_geoms.get(name) {
            None => Err(element.invalid(format!("unknown geom '{name}' in tendon"))),
            Some((_, Some(geom))) => Ok(*geom),
            Some((kind, None)) => {
                Err(element.invalid(format!("geom '{name}' in tendon is not sphere or cylinder (it is {kind:?})")))
            }
        }
    }
}

impl SensorTargets for Reader {
    fn tendon(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        self.tendon_named(element, attribute, "sensor")
    }

    fn tendon_limited(&self, element: &Element, attribute: &str) -> Result<bool, MjcfError> {
        Ok(self.tendon_limited[self.tendon_named(element, attribute, "sensor")?])
    }

    fn joint_kind(&self, element: &Element, attribute: &str) -> Result<JointKind, MjcfError> {
        Ok(self.sensed_joint(element, attribute)?.kind)
    }

    fn joint_limited(&self, element: &Element, attribute: &str) -> Result<bool, MjcfError> {
        Ok(self.sensed_joint(element, attribute)?.limited)
    }

    fn body(&self, element: &Element, attribute: &str) -> Result<Option<usize>, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        if name == "world" {
            return Ok(None);
        }
        match self.body_names.contains_key(name) {
            true => Ok(self.bodies.iter().position(|b| b.name == name)),
            false => Err(self.unknown(element, &format!("body '{name}' in sensor"), name)),
        }
    }

    fn site(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        self.site_named(element, attribute, "sensor")
    }

    fn actuator(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        match self.actuators.iter().position(|a| a.name.as_deref() == Some(name)) {
            Some(index) => Ok(index),
            None => Err(element.invalid(format!("unknown actuator '{name}' in sensor"))),
        }
    }
}

/// Registers a body or joint name, rejecting a repetition.
fn claim_name(
    names: &mut HashMap<String, u32>,
    kind: &'static str,
    name: &str,
    element: &Element,
) -> Result<(), MjcfError> {
    if let Some(&first_line) = names.get(name) {
        return Err(MjcfError::DuplicateName {
            line: element.line,
            element: element.label(),
            kind,
            name: name.to_string(),
            first_line,
        });
    }
    names.insert(name.to_string(), element.line);
    Ok(())
}

/// Rejects child elements of an element that takes none.
fn no_children(element: &Element) -> Result<(), MjcfError> {
    match element.children().next() {
        Some(child) => Err(child.unknown()),
        None => Ok(()),
    }
}

/// The error for an element that nudyn does not read where bodies or
/// sections are expected.
fn unsupported_child(element: &Element) -> MjcfError {
    match UNSUPPORTED_CHILDREN.iter().find(|(tag, _)| *tag == element.tag()) {
        Some((_, reason)) => element.unsupported(*reason),
        None => element.unknown(),
    }
}
