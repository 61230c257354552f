//! The sections after `<worldbody>`: assets, tendons, equalities,
//! actuators, sensors and keyframes.

use super::replicate::Named;
use super::{ACTUATOR_GROUPS, REFUSED_TRANSMISSIONS, Reader, claim_name, no_children};
use crate::mjcf::attributes::names;
use crate::mjcf::defaults::MAIN;
use crate::mjcf::element::Element;
use crate::mjcf::error::MjcfError;
use crate::mjcf::keyframe::Keyframe;
use crate::mjcf::mesh::MESH_ATTRIBUTES;
use crate::mjcf::tendon::TendonFlags;
use crate::mjcf::{actuator, equality, mesh, sensor, tendon};
use crate::vehicle::{
    Activation, ActivationKind, Actuator, ActuatorKind, BiasType, GainType, JointKind, SensorKind, Transmission,
};

impl Reader {
    /// Reads an `<asset>` section: meshes are declared (their files read
    /// once a geom needs them), the other assets (textures, materials,
    /// height fields, skins) ignored with a warning.
    pub(super) fn read_assets(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        if section.children().next().is_none() {
            self.warnings.push(section.ignored());
        }
        for child in section.children() {
            if child.tag() != "mesh" {
                self.warnings.push(child.ignored());
                continue;
            }
            child.check_attributes(&names(MESH_ATTRIBUTES))?;
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

    pub(super) fn read_deformable(&mut self, section: &Element) -> Result<(), MjcfError> {
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

    /// The `<key>`s of a `<keyframe>` section, with MuJoCo's checks: each
    /// vector given has the model's size (an empty one counts as not given).
    pub(super) fn read_keyframes(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        let joints = self.bodies.iter().flat_map(|b| &b.joints);
        let (nq, nv) = joints.fold((0, 0), |(nq, nv), j| (nq + j.kind.nq(), nv + j.kind.nv()));
        let nmocap = self.mocap_bodies.len();
        // Each activation state nudyn models has one act.
        let na = self.actuators.iter().filter(|a| a.activation.is_some()).count();
        let nu = self.actuators.len();
        for key in section.children() {
            if key.tag() != "key" {
                return Err(key.unknown());
            }
            key.check_attributes(&["name", "time", "qpos", "qvel", "act", "mpos", "mquat", "ctrl"])?;
            no_children(&key)?;
            let vector = |attribute: &str, size: usize| -> Result<Option<Vec<f64>>, MjcfError> {
                let Some(text) = key.text(attribute) else { return Ok(None) };
                let values: Result<Vec<f64>, _> = text.split_ascii_whitespace().map(str::parse).collect();
                let values = values.map_err(|_| key.bad_value(attribute, "numbers"))?;
                match values.len() {
                    0 => Ok(None),
                    given if given == size => Ok(Some(values)),
                    given => Err(key.invalid(format!("invalid {attribute} size, expected {size}, got {given}"))),
                }
            };
            let time = key.number("time")?.unwrap_or(0.0);
            let (qpos, qvel, act) = (vector("qpos", nq)?, vector("qvel", nv)?, vector("act", na)?);
            let places_mocap_bodies = vector("mpos", 3 * nmocap)?.is_some() | vector("mquat", 4 * nmocap)?.is_some();
            let ctrl = vector("ctrl", nu)?;
            let name = key.text("name").map(str::to_string);
            self.keyframes.push(Keyframe { name, time, qpos, qvel, act, ctrl, places_mocap_bodies, line: key.line });
        }
        Ok(())
    }

    /// Reads an `<actuator>` section.
    /// The `<equality>` section: each element read as MuJoCo reads it; the
    /// constraints kept unless a `<flag>` turns them off.
    pub(super) fn read_equalities(&mut self, section: &Element) -> Result<(), MjcfError> {
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
    pub(super) fn read_tendons(&mut self, section: &Element) -> Result<(), MjcfError> {
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

    /// Notes the geoms the tendons of `sections` wrap around, each with the
    /// first such tendon, before the body tree is compiled: only their wrap
    /// frames are needed (and, for a primitive fitted to a mesh, the mesh).
    pub(super) fn note_wrap_obstacles(&mut self, sections: &[Element]) {
        for element in sections.iter().flat_map(|section| section.children()) {
            for obstacle in element.children().filter(|child| child.tag() == "geom") {
                let geom = obstacle.text("geom").unwrap_or_default().to_string();
                self.wrap_obstacles.entry(geom).or_insert_with(|| element.label());
            }
        }
    }

    /// The index of the tendon the attribute names.
    pub(super) fn tendon_named(&self, element: &Element, attribute: &str, user: &str) -> Result<usize, MjcfError> {
        let name = element.text(attribute).unwrap_or_default();
        self.tendons
            .iter()
            .position(|t| t.name.as_deref() == Some(name))
            .ok_or_else(|| element.invalid(format!("unknown tendon '{name}' in {user}")))
    }

    /// The `<sensor>` section, with the copies of the sensors that name
    /// objects inside `<replicate>`s as they are written there.
    pub(super) fn read_sensors(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        let children: Vec<Element> = section.children().collect();
        let mut kinds = Vec::with_capacity(children.len());
        for child in &children {
            let Some(kind) = SensorKind::from_name(child.tag()) else {
                return Err(match sensor::refusal(child.tag()) {
                    Some(reason) => child.unsupported(reason),
                    None => child.unknown(),
                });
            };
            kinds.push(kind);
        }
        for copy in self.copies(&children, false, sensor_references)? {
            let (child, kind) = (&children[copy.index], kinds[copy.index]);
            self.copy = Some(copy);
            let read = sensor::read(child, kind, self);
            self.copy = None;
            let read = read?;
            if let Some(name) = &read.name {
                claim_name(&mut self.sensor_names, "sensor", name, child)?;
            }
            self.sensors.push(read);
        }
        Ok(())
    }

    /// The `<actuator>` section, with the copies of the actuators that name
    /// objects inside `<replicate>`s as they are written there.
    pub(super) fn read_actuators(&mut self, section: &Element) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        let children: Vec<Element> = section.children().collect();
        let mut kinds = Vec::with_capacity(children.len());
        for child in &children {
            match actuator::kind_of(child.tag()) {
                Some(kind) => kinds.push(kind),
                None => match actuator::refusal(child.tag()) {
                    Some(reason) => return Err(child.unsupported(reason)),
                    None => return Err(child.unknown()),
                },
            }
        }
        for copy in self.copies(&children, true, actuator_references)? {
            let (child, kind) = (&children[copy.index], kinds[copy.index]);
            let suffix = copy.suffix.clone();
            self.copy = Some(copy);
            let read = self.read_actuator(child, kind);
            self.copy = None;
            read?;
            // Sensors may name the copies as the actuator is written.
            if let Some(name) = child.text("name") {
                self.replicated_name(Named::Actuator, name, &suffix);
            }
        }
        Ok(())
    }

    /// Reads one actuator element into MuJoCo's general actuator, with
    /// MuJoCo's compiler checks, refusing what nudyn does not model.
    pub(super) fn read_actuator(&mut self, element: &Element, kind: ActuatorKind) -> Result<(), MjcfError> {
        element.check_attributes(&actuator::attributes(kind, false))?;
        no_children(element)?;
        let class = self.defaults.lookup(element, "class")?.unwrap_or(MAIN);
        let mut settings = self.defaults.class(class).actuator.clone();
        settings.apply(kind, element, self.defaults.lender(class, kind))?;
        let transmission = self.transmission(element)?;

        let activation_kind = match settings.dyntype {
            "none" => None,
            "integrator" => Some(ActivationKind::Integrator),
            "filter" => Some(ActivationKind::Filter),
            "filterexact" => Some(ActivationKind::FilterExact),
            other => return Err(element.unsupported(actuator::dynamics_refusal(other))),
        };
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
        match (settings.actdim, activation_kind) {
            (2.., _) => return Err(element.invalid("actdim > 1 is only allowed for dyntype \"user\" and \"dcmotor\"")),
            (1, None) => return Err(element.invalid("invalid actdim 1 in stateless actuator")),
            (0, Some(_)) => return Err(element.invalid("invalid actdim 0 in stateful actuator")),
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
        let act_range = self.limits(element, "act", settings.actlimited, settings.actrange)?;
        let activation = match activation_kind {
            Some(kind) => {
                Some(Activation { kind, time_constant: settings.dynprm[0], range: act_range, early: settings.actearly })
            }
            None if act_range.is_some() => return Err(element.invalid("actrange specified but dyntype is 'none'")),
            None => None,
        };

        let name = self.own_name(element);
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
            activation,
            group_disabled: ACTUATOR_GROUPS.contains(&group) && self.physics.disabled_actuator_groups.contains(&group),
            line: element.line,
        });
        Ok(())
    }

    /// The transmission an actuator element names: a joint, or a site with
    /// an optional reference site. Tendon, slider-crank and body
    /// transmissions are refused.
    pub(super) fn transmission(&self, element: &Element) -> Result<Transmission, MjcfError> {
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
        let name = self.reference(element, target);
        if target == "tendon" {
            return Ok(Transmission::Tendon { tendon: self.tendon_named(element, "tendon", "actuator")? });
        }
        if target != "site" {
            if !self.joint_targets.contains_key(&name) {
                return Err(self.unknown(element, &format!("transmission target '{name}' for actuator"), &name));
            }
            return Ok(Transmission::Joint { joint: name, in_parent: target == "jointinparent" });
        }
        let site = self.site_named(element, "site", "actuator")?;
        let refsite = match element.has("refsite") {
            true => Some(self.site_named(element, "refsite", "actuator")?),
            false => None,
        };
        Ok(Transmission::Site { site, refsite })
    }

    /// Why an element of `<equality>` is refused.
    /// An equality constraint to a mocap body, refused: its pose is an
    /// input MuJoCo's users set, which an FMU does not take.
    pub(super) fn mocap_equality_refusal(&self, element: &Element) -> Option<MjcfError> {
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
}

/// The attributes of an actuator element that name objects a `<replicate>` may hold.
fn actuator_references(_: &Element) -> Vec<(&'static str, Named)> {
    vec![("joint", Named::Joint), ("jointinparent", Named::Joint), ("site", Named::Site), ("refsite", Named::Site)]
}

/// The attributes of a sensor element that name objects a `<replicate>` may hold.
fn sensor_references(element: &Element) -> Vec<(&'static str, Named)> {
    let framed = |type_attribute: &str| match element.text(type_attribute) {
        Some("body" | "xbody") => Some(Named::Body),
        Some("site") => Some(Named::Site),
        _ => None,
    };
    let mut references = vec![("joint", Named::Joint), ("site", Named::Site), ("body", Named::Body)];
    references.push(("actuator", Named::Actuator));
    references.extend(framed("objtype").map(|kind| ("objname", kind)));
    references.extend(framed("reftype").map(|kind| ("refname", kind)));
    references
}
