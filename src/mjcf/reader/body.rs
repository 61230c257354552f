//! The walk through the body tree: bodies, their frames and `<replicate>`s,
//! joints, geoms and sites in document order, read into a [`ReadTree`]
//! (their defaults resolved, the `<frame>`s around them kept) for the
//! compile stage (`compile/`).

use super::compile::{BodySpec, GeomSpec, MassSource, ReadTree, SiteSpec};
use super::geom::fromto_frame;
use super::joint::check_joint_values;
use super::replicate::{Named, Suffix};
use super::{
    IGNORED_IN_BODIES, JointSpec, MAX_REPLICATED_ELEMENTS, PendingBody, Placed, Pose, Reader, claim_name, no_children,
    unsupported_child,
};
use crate::math::{Quat, Vec3};
use crate::mjcf::attributes::names;
use crate::mjcf::bodies::{
    Align, BODY_ATTRIBUTES, BodySettings, FRAME_ATTRIBUTES, FREEJOINT_ATTRIBUTES, FrameSettings, FreeJointSettings,
    REPLICATE_ATTRIBUTES, ReplicateSettings, read_settings,
};
use crate::mjcf::defaults::{GEOM_ATTRIBUTES, JOINT_ATTRIBUTES, JointSettings, MAIN, SITE_ATTRIBUTES, SiteKind};
use crate::mjcf::element::{Element, Origin};
use crate::mjcf::error::MjcfError;
use crate::mjcf::inertia::BodyInertia;
use crate::mjcf::orientation::Orientation;
use crate::vehicle::{JointKind, Site};

impl Reader {
    /// Reads a `<worldbody>` section into `tree`, for the compile stage.
    pub(super) fn read_worldbody<'a>(
        &mut self,
        section: &Element<'a, 'a>,
        tree: &mut ReadTree,
    ) -> Result<(), MjcfError> {
        // MuJoCo: "World body cannot have attributes".
        section.check_attributes(&[])?;
        for Placed { element: child, frame, class, suffix } in
            self.placed_children(section, MAIN, &Suffix::default())?
        {
            match child.tag() {
                "body" => self.read_body_tree(child, frame, class, suffix, tree)?,
                "site" => {
                    let site = self.read_site(&child, class, None, frame, &suffix)?;
                    tree.sites.push(site);
                }
                "geom" => {
                    let geom = self.read_geom(child, class, frame, &suffix, None)?;
                    tree.geoms.push(geom);
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
        Ok(())
    }

    /// Gives the names made up for unnamed bodies and joints a suffix where
    /// they equal a name the file gives (or each other), so that no two
    /// bodies or joints share a name in descriptions and messages.
    pub(super) fn set_apart_unnamed(&mut self) {
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
    pub(super) fn read_body_tree<'a>(
        &mut self,
        top: Element<'a, 'a>,
        frame: Option<Pose>,
        class: usize,
        suffix: Suffix,
        tree: &mut ReadTree,
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
            let children = self.read_body(&body, tree)?;
            // Reversed so that the first child is read next.
            pending.extend(children.into_iter().rev());
        }
        Ok(())
    }

    /// Reads one body into `tree`, for the compile stage; returns its child
    /// bodies, still to be read.
    pub(super) fn read_body<'a>(
        &mut self,
        body: &PendingBody<'a>,
        tree: &mut ReadTree,
    ) -> Result<Vec<PendingBody<'a>>, MjcfError> {
        let &PendingBody { ref element, parent, inherited_class, parent_moving, frame, ref suffix } = body;
        let BodySettings { pos: own_pos, orientation, mocap, gravcomp, sleep_policy } =
            read_settings(BODY_ATTRIBUTES, element)?;
        let class = self.defaults.lookup(element, "childclass")?.unwrap_or(inherited_class);
        let own_pos = Vec3::from(own_pos);
        let own_quat = self.resolve(&element.origin(), &orientation)?;
        let index = tree.bodies.len();
        // An unnamed body gets a name for messages and descriptions, which
        // nothing can refer to (MuJoCo's unnamed elements have none).
        let name = match element.text("name") {
            Some(name) => {
                let copy = self.replicated_name(Named::Body, name, suffix);
                claim_name(&mut self.body_names, "body", &copy, &element.origin())?;
                copy
            }
            None => {
                self.unnamed_bodies.push(index);
                format!("body{index}")
            }
        };

        let BodyChildren { inertial, joints, geoms, sites, child_bodies } =
            self.read_body_children(element, index, class, suffix)?;
        tree.geoms.extend(geoms);
        tree.sites.extend(sites);

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
        // MuJoCo 4.0's rule for a sleep policy.
        let movable_root = has_joints && !parent_moving;
        if sleep_policy && !movable_root {
            return Err(element.invalid("sleep policy only allowed for movable root bodies"));
        }
        // MuJoCo's condition for moving the body frame to the inertial frame.
        let aligned = match joints.as_slice() {
            [only] if only.settings.kind == JointKind::Free && child_bodies.is_empty() => {
                only.align == Align::Yes || (only.align == Align::Auto && self.compiler.align_free)
            }
            _ => false,
        };
        let explicit = inertial.map(|(_, inertia, frame)| (inertia, frame));
        let mass = MassSource { at: element.origin(), explicit, moving, aligned, own_pose: (own_pos, own_quat) };
        tree.bodies.push(BodySpec { name, parent, frame, joints, gravcomp, mass });
        Ok(child_bodies.into_iter().map(|child| PendingBody { parent_moving: moving, ..child }).collect())
    }

    /// Reads the children of the body `element` (the `index`th body, of
    /// default class `class`): its `<inertial>`, joints, geoms and sites
    /// with their settings resolved, and its child bodies, still to be read.
    fn read_body_children<'a>(
        &mut self,
        element: &Element<'a, 'a>,
        index: usize,
        class: usize,
        suffix: &Suffix,
    ) -> Result<BodyChildren<'a>, MjcfError> {
        let mut children = BodyChildren {
            inertial: None,
            joints: Vec::new(),
            geoms: Vec::new(),
            sites: Vec::new(),
            child_bodies: Vec::new(),
        };
        let BodyChildren { inertial, joints, geoms, sites, child_bodies } = &mut children;
        for Placed { element: child, frame, class, suffix } in self.placed_children(element, class, suffix)? {
            match child.tag() {
                "inertial" => {
                    if let Some((first, ..)) = &inertial {
                        return Err(child.repeated(first));
                    }
                    let read = self.read_inertial(&child)?;
                    *inertial = Some((child, read, frame));
                }
                "joint" => {
                    child.check_attributes(&names(JOINT_ATTRIBUTES))?;
                    no_children(&child)?;
                    let mut settings = self.defaults.class(self.class_of(&child, class)?).joint.clone();
                    settings.apply(&child)?;
                    check_joint_values(&child, &settings)?;
                    let (at, name) = (child.origin(), child.text("name").map(str::to_string));
                    joints.push(JointSpec { at, name, settings, frame, align: Align::Auto, suffix });
                }
                "freejoint" => {
                    // MuJoCo's <freejoint> takes no defaults.
                    let FreeJointSettings { align } = read_settings(FREEJOINT_ATTRIBUTES, &child)?;
                    no_children(&child)?;
                    let settings = JointSettings { kind: JointKind::Free, ..JointSettings::default() };
                    let (at, name) = (child.origin(), child.text("name").map(str::to_string));
                    joints.push(JointSpec { at, name, settings, frame: None, align, suffix });
                }
                "geom" => geoms.push(self.read_geom(child, class, frame, &suffix, Some(index))?),
                "site" => sites.push(self.read_site(&child, class, Some(index), frame, &suffix)?),
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

        Ok(children)
    }

    /// The children of a body (or of the world body) of class `class`, with
    /// the elements inside its `<frame>`s and `<replicate>`s, nested or not,
    /// in their place in document order: MuJoCo's frames vanish when it
    /// compiles a model, their pose composed into their children's and their
    /// `childclass` handed on; a replicate is the same as its copies, each
    /// in a frame of its own, their names suffixed (`suffix`: that of the
    /// replicates around `parent`).
    pub(super) fn placed_children<'a>(
        &self,
        parent: &Element<'a, 'a>,
        class: usize,
        suffix: &Suffix,
    ) -> Result<Vec<Placed<'a>>, MjcfError> {
        let mut placed = Vec::new();
        // Reversed, so that the first child comes off the stack first.
        let mut pending: Vec<Placed<'a>> = parent
            .children()
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .map(|element| Placed { element, frame: None, class, suffix: suffix.clone() })
            .collect();
        while let Some(item) = pending.pop() {
            let replicate = item.element.tag() == "replicate";
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
                let suffix = match replicate {
                    true => item.suffix.within(container, copy_suffix),
                    false => item.suffix.clone(),
                };
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
    pub(super) fn frame_pose(&self, item: &Placed) -> Result<Vec<(Pose, String)>, MjcfError> {
        let frame = &item.element;
        let FrameSettings { pos, orientation } = read_settings(FRAME_ATTRIBUTES, frame)?;
        let quat = self.resolve(&frame.origin(), &orientation)?;
        Ok(vec![((Vec3::from(pos), quat), String::new())])
    }

    /// The poses and name suffixes of a `<replicate>`'s copies, as MuJoCo
    /// 4.0 makes them (`mjXReader::Body`): copy i turned by i·euler (the
    /// compiler's angle unit and sequence), at p_i with p_0 = 0 and
    /// p_{i+1} = p_i + q^i · offset (q: the turn of one copy), its suffix
    /// `sep` and i padded with zeros to the digits of `count`.
    pub(super) fn replicate_poses(&self, item: &Placed) -> Result<Vec<(Pose, String)>, MjcfError> {
        let replicate = &item.element;
        let ReplicateSettings { count, separator, offset, euler } = read_settings(REPLICATE_ATTRIBUTES, replicate)?;
        let count = count.ok_or_else(|| replicate.missing("count"))?;
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
        let offset = Vec3::from(offset);
        let at = replicate.origin();
        let step = self.resolve(&at, &Orientation::Euler(euler))?;
        let digits = count.to_string().len();
        let (mut pos, mut turned) = (Vec3::zeros(), Quat::identity());
        let mut copies = Vec::with_capacity(count as usize);
        for i in 0..count {
            // MuJoCo resolves i·euler afresh for each copy's orientation,
            // and accumulates the turn only for the positions.
            let quat = self.resolve(&at, &Orientation::Euler(euler.map(|angle| f64::from(i) * angle)))?;
            copies.push(((pos, quat), format!("{separator}{i:0digits$}")));
            pos += turned * offset;
            turned *= step;
        }
        Ok(copies)
    }

    /// The class of a joint, geom or site: its `class`, else its body's class.
    pub(super) fn class_of(&self, element: &Element, body_class: usize) -> Result<usize, MjcfError> {
        Ok(self.defaults.lookup(element, "class")?.unwrap_or(body_class))
    }

    /// A `<geom>` of `body` (`None`: the world body) as read: its class's
    /// defaults with its own attributes applied, after checking its
    /// attributes and that it has no children; its name claimed.
    fn read_geom<'a>(
        &mut self,
        element: Element<'a, 'a>,
        body_class: usize,
        frame: Option<Pose>,
        suffix: &Suffix,
        body: Option<usize>,
    ) -> Result<GeomSpec, MjcfError> {
        element.check_attributes(&names(GEOM_ATTRIBUTES))?;
        if let Some(child) = element.children().next() {
            return Err(unsupported_child(&child));
        }
        let mut settings = self.defaults.class(self.class_of(&element, body_class)?).geom.clone();
        settings.apply(&element)?;
        let name = element.text("name").map(|name| self.replicated_name(Named::Geom, name, suffix));
        Ok(GeomSpec { at: element.origin(), settings, frame, name, body })
    }

    /// Reads a `<site>` of body `body` (`None`: the world body), its name claimed.
    pub(super) fn read_site(
        &mut self,
        element: &Element,
        body_class: usize,
        body: Option<usize>,
        frame: Option<Pose>,
        suffix: &Suffix,
    ) -> Result<SiteSpec, MjcfError> {
        element.check_attributes(&names(SITE_ATTRIBUTES))?;
        no_children(element)?;
        let mut settings = self.defaults.class(self.class_of(element, body_class)?).site.clone();
        settings.apply(element)?;
        let (pos, quat) = match settings.fromto {
            Some(fromto) => {
                if settings.kind == SiteKind::Sphere {
                    return Err(element.invalid("'fromto' requires a capsule, cylinder, ellipsoid or box site"));
                }
                let (pos, quat, _) = fromto_frame(&element.origin(), &fromto, &settings.pos)?;
                (pos, quat)
            }
            None => (Vec3::from(settings.pos), self.resolve(&element.origin(), &settings.orientation)?),
        };
        let name = element.text("name").map(|name| self.replicated_name(Named::Site, name, suffix));
        if let Some(name) = &name {
            claim_name(&mut self.site_names, "site", name, &element.origin())?;
        }
        let site = Site { name, body, pos, quat, line: element.line };
        Ok(SiteSpec { site, frame, fitted_to_mesh: settings.mesh })
    }

    /// An orientation in MuJoCo's conventions as the `<compiler>` sets them.
    pub(super) fn resolve(&self, at: &Origin, orientation: &Orientation) -> Result<Quat, MjcfError> {
        orientation.resolve(&self.compiler.angles).map_err(|reason| at.invalid(reason))
    }
}

/// The pose `inner`, given in the frame `outer` places, in `outer`'s parent
/// (MuJoCo's `mjuu_frameaccumChild`).
pub(super) fn compose(outer: &Pose, inner: &Pose) -> Pose {
    (outer.0 + outer.1 * inner.0, outer.1 * inner.1)
}

/// What a body element holds, read.
struct BodyChildren<'a> {
    /// Its `<inertial>`, with the element for messages on a second one and
    /// the pose of the `<frame>`s around it.
    inertial: Option<(Element<'a, 'a>, BodyInertia, Option<Pose>)>,
    joints: Vec<JointSpec>,
    geoms: Vec<GeomSpec>,
    sites: Vec<SiteSpec>,
    child_bodies: Vec<PendingBody<'a>>,
}
