//! Reads an MJCF document and builds the [`Vehicle`]: the settings
//! sections first, then every other section parsed into a spec tree (the
//! body tree by `body.rs`; tendons, equalities, actuators, sensors and
//! keyframes by `sections.rs`: defaults resolved, values checked, objects
//! named by name, each element's line and label kept in an `Origin`, no
//! XML node), compiled once the whole document is read (`compile/`:
//! frames, mass properties, free-body alignment, the names resolved,
//! `fusestatic`, `settotalmass`), and last the [`Vehicle`] (`finish.rs`).

mod body;
mod compile;
mod finish;
mod geom;
mod joint;
mod modal;
mod options;
mod replicate;
mod sections;
mod targets;

pub(crate) use options::{COMPILER_ATTRIBUTES, FLAG_ATTRIBUTES, OPTION_ATTRIBUTES};

use std::collections::HashMap;
use std::path::Path;

use roxmltree::Document;

use super::bodies::Align;
use super::contacts::{ContactGeom, Reach};
use super::defaults::{Defaults, GeomKind, JointSettings};
use super::element::{Element, LineStarts, Origin};
use super::error::MjcfError;
use super::include::{self, Sources};
use super::inertia::{BodyInertia, GeomMass};
use super::keyframe::Keyframe;
use super::mesh::Meshes;
use super::orientation::AngleConvention;
use super::{Imported, MjcfWarning};
use crate::math::{Quat, Vec3};
use crate::vehicle::{
    Actuation, Actuator, Body, ConstraintOptions, Equality, JointKind, Sensor, Site, Tendon, WrapGeom,
};
use compile::ReadTree;
use replicate::{ElementCopy, Named, ReplicatedName, Suffix};

/// MuJoCo's `mjMINVAL`: the least mass and principal moment of a moving body.
const MIN_VALUE: f64 = 1e-15;

/// The most elements the `<replicate>`s of a file may produce: each
/// replicate's copies times the elements inside it (nested ones included),
/// summed over every replicate as it is expanded. Far beyond any vehicle;
/// a count past it would exhaust the memory before the import could fail.
pub(crate) const MAX_REPLICATED_ELEMENTS: usize = 100_000;

/// Top-level sections without effect on the dynamics.
#[rustfmt::skip]
pub(crate) const IGNORED_SECTIONS: &[&str] =
    &["size", "statistic", "visual", "contact", "extension"];

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
pub(crate) enum InertiaFromGeom {
    /// Always from `<inertial>` (massless without one).
    Never,
    /// Always from the geoms, overriding `<inertial>`.
    Always,
    /// From the geoms when the body has no `<inertial>`.
    Auto,
}

/// `<compiler>` settings that matter here.
#[derive(Debug)]
pub(crate) struct Compiler {
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
#[derive(Debug)]
pub(crate) struct Physics {
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
    /// `<flag contact="disable">`: no contact warnings.
    contact_disabled: bool,
    /// `<flag filterparent="disable">`: a parent and child may touch.
    filterparent_disabled: bool,
}

/// MuJoCo's defaults.
impl Default for Compiler {
    fn default() -> Self {
        Compiler {
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
        }
    }
}

/// MuJoCo's defaults.
impl Default for Physics {
    fn default() -> Self {
        Physics {
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
            contact_disabled: false,
            filterparent_disabled: false,
        }
    }
}

/// What actuators, tendons, equalities and sensors need to know of a joint they may name.
struct JointTarget {
    kind: JointKind,
    /// `range` as MuJoCo's compiler leaves it: in radians for a limited hinge
    /// or ball joint when angles are in degrees, as written otherwise.
    range: [f64; 2],
    /// Whether the joint is limited (MuJoCo's jnt_limited, before any flag).
    limited: bool,
}

/// A body's mass properties as compiled, with what the mass check and
/// `fusestatic` need to know of it.
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
    suffix: Suffix,
}

/// A pose in a parent frame: position, then orientation.
type Pose = (Vec3, Quat);

/// A child element of a body or of the world body, with what the `<frame>`s
/// around it give it: their composed pose (`None` outside any frame) and
/// the default class.
struct Placed<'a> {
    element: Element<'a, 'a>,
    frame: Option<Pose>,
    class: usize,
    /// The suffix of `<replicate>` copies for its name and those below it.
    suffix: Suffix,
}

/// A `<joint>` or `<freejoint>` as read, its values checked.
struct JointSpec {
    /// The element, for messages.
    at: Origin,
    /// `name` as written.
    name: Option<String>,
    settings: JointSettings,
    /// The pose of the `<frame>`s around a `<joint>`, in its body.
    frame: Option<Pose>,
    align: Align,
    /// The `<replicate>` suffix of its name.
    suffix: Suffix,
}

/// The importer's state: the settings and name tables the parse fills,
/// and the vehicle's parts the compile stage builds from the spec tree.
struct Reader {
    compiler: Compiler,
    physics: Physics,
    defaults: Defaults,
    warnings: Vec<MjcfWarning>,
    /// The `<key>`s compiled so far.
    keyframes: Vec<Keyframe>,
    /// The `nudyn:modal:` texts of `<custom>`, resolved at the end.
    modal_texts: Vec<modal::ModalText>,
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
    /// The geoms tendons wrap around: their type, and their frame when a
    /// sphere or cylinder.
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
    /// The names given inside `<replicate>`s, with the copies they are in.
    replicated_names: Vec<ReplicatedName>,
    /// The copy of an actuator or sensor being compiled.
    copy: Option<ElementCopy>,
    /// The elements the `<replicate>`s expanded so far produce (see
    /// [`MAX_REPLICATED_ELEMENTS`]).
    replicated_elements: std::cell::Cell<usize>,
    /// The geoms of the world body, whose warnings wait for the tendons
    /// that may wrap around them.
    world_geoms: Vec<WorldGeom>,
    /// The geoms spatial tendons wrap around, each with the first such tendon.
    wrap_obstacles: HashMap<String, String>,
    /// Each body's pose in the world at qpos0 (before `align_free` moves its frame).
    world_poses: Vec<Pose>,
    /// The geoms that may collide, for the warning on contacts.
    contact_geoms: Vec<ContactGeom>,
    /// The body pairs of the `<contact>` sections' `<exclude>`s, by name.
    contact_exclusions: Vec<(String, String)>,
}

/// A geom of the world body: it moves no mass, so it has an effect only as
/// a tendon's wrap obstacle.
struct WorldGeom {
    /// Its name, when it has one.
    name: Option<String>,
    /// Whether MuJoCo may make contacts with it (`contype` or `conaffinity` not 0).
    collides: bool,
    /// The warning that it is ignored, for when no tendon wraps around it.
    warning: MjcfWarning,
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
    // The document is gone once parsed: the compile stage reads the spec only.
    let (mut reader, tree, name) = parse(xml, sources)?;
    reader.compile(tree)?;
    reader.finish(name)
}

/// Parses the document with its includes merged in: the settings read, every
/// other section into the spec tree; gives the model's name too.
fn parse(xml: &str, sources: &Sources) -> Result<(Reader, ReadTree, String), MjcfError> {
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
        let [body1, body2] = ["body1", "body2"].map(|a| exclude.text(a).filter(|_| exclude.tag() == "exclude"));
        reader.named_elsewhere.extend([body1, body2].into_iter().flatten().map(str::to_string));
        if let (Some(body1), Some(body2)) = (body1, body2) {
            reader.contact_exclusions.push((body1.to_string(), body2.to_string()));
        }
    }

    let mut tree = ReadTree::default();
    let mut has_worldbody = false;
    for section in root.children() {
        match section.tag() {
            "compiler" | "option" | "default" | "asset" => {}
            "worldbody" => {
                has_worldbody = true;
                reader.read_worldbody(&section, &mut tree)?;
            }
            "actuator" => tree.actuator_sections.push(reader.parse_actuators(&section)?),
            "sensor" => tree.sensor_sections.push(reader.parse_sensors(&section)?),
            "keyframe" => reader.parse_keyframes(&section, &mut tree.keyframes)?,
            "custom" => reader.read_custom(&section)?,
            tag if IGNORED_SECTIONS.contains(&tag) => reader.warnings.push(section.ignored()),
            "tendon" => reader.parse_tendons(&section, &mut tree.tendons)?,
            "equality" => reader.parse_equalities(&section, &mut tree.equalities)?,
            "deformable" => reader.read_deformable(&section)?,
            _ => return Err(section.unknown()),
        }
    }
    if !has_worldbody {
        return Err(MjcfError::MissingWorldbody { line: root.line, element: root.label() });
    }
    let name = root.text("model").unwrap_or("vehicle").to_string();
    Ok((reader, tree, name))
}

impl Reader {
    fn new(sources: Sources) -> Self {
        Self {
            compiler: Compiler::default(),
            physics: Physics::default(),
            defaults: Defaults::new(),
            warnings: Vec::new(),
            keyframes: Vec::new(),
            modal_texts: Vec::new(),
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
            replicated_names: Vec::new(),
            copy: None,
            replicated_elements: std::cell::Cell::new(0),
            world_geoms: Vec::new(),
            wrap_obstacles: HashMap::new(),
            world_poses: Vec::new(),
            contact_geoms: Vec::new(),
            contact_exclusions: Vec::new(),
        }
    }

    /// The name of an element of `kind` in a `<replicate>` copy (`suffix`
    /// empty outside replicates), remembered for [`Reader::unknown`] and
    /// for the actuators and sensors that name it as written.
    fn replicated_name(&mut self, kind: Named, name: &str, suffix: &Suffix) -> String {
        let text = suffix.text();
        let copy = format!("{name}{text}");
        if !text.is_empty() {
            self.replicated.entry(name.to_string()).or_insert_with(|| copy.clone());
            self.replicated_names.push(ReplicatedName { kind, name: name.to_string(), suffix: suffix.clone() });
        }
        copy
    }
}

/// Registers the name of an element of `kind`, rejecting a repetition.
fn claim_name(names: &mut HashMap<String, u32>, kind: &'static str, name: &str, at: &Origin) -> Result<(), MjcfError> {
    if let Some(&first_line) = names.get(name) {
        return Err(MjcfError::DuplicateName {
            line: at.line,
            element: at.label.clone(),
            kind,
            name: name.to_string(),
            first_line,
        });
    }
    names.insert(name.to_string(), at.line);
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
