//! The compile stage of the sections that name the body tree's objects:
//! tendons, equalities, actuators and sensors, their names looked up in
//! the compiled tree (`targets.rs`), the `<replicate>` copies of actuators
//! and sensors made (`replicate.rs`), the `<flag>`s applied; and the
//! keyframes, whose sizes are the compiled model's.

use crate::mjcf::actuator::{ActuatorSpec, TransmissionSpec};
use crate::mjcf::element::Origin;
use crate::mjcf::equality::{EqualitySpec, ObjectsSpec};
use crate::mjcf::error::MjcfError;
use crate::mjcf::keyframe::{self, KeySizes, KeySpec};
use crate::mjcf::reader::replicate::{Named, Reference};
use crate::mjcf::reader::{ACTUATOR_GROUPS, Reader, claim_name};
use crate::mjcf::sensor::SensorSpec;
use crate::mjcf::tendon::{TendonFlags, TendonSpec};
use crate::mjcf::{equality, sensor, tendon};
use crate::vehicle::{Activation, ActivationKind, Actuator, BiasType, GainType, JointKind, Transmission};

impl Reader {
    /// Notes the geoms the tendons wrap around, each with the first such
    /// tendon, before the body tree is compiled: only their wrap frames are
    /// needed (and, for a primitive fitted to a mesh, the mesh).
    pub(super) fn note_wrap_obstacles(&mut self, tendons: &[TendonSpec]) {
        for spec in tendons {
            for geom in spec.wrap_geoms() {
                self.wrap_obstacles.entry(geom.to_string()).or_insert_with(|| spec.at.label.clone());
            }
        }
    }

    /// The tendons, less what the `<flag>`s turn off, their names claimed.
    pub(super) fn compile_tendons(&mut self, specs: &[TendonSpec]) -> Result<(), MjcfError> {
        let physics = &self.physics;
        let flags = TendonFlags {
            spring_disabled: physics.spring_disabled,
            damper_disabled: physics.damper_disabled,
            frictionloss_disabled: physics.constraint_disabled || physics.frictionloss_disabled,
            limit_disabled: physics.constraint_disabled || physics.limit_disabled,
        };
        for spec in specs {
            let compiled = tendon::compile(spec, self, flags)?;
            if let Some(name) = &spec.name {
                claim_name(&mut self.tendon_names, "tendon", name, &spec.at)?;
            }
            self.tendons.push(compiled);
            self.tendon_limited.push(spec.limited);
        }
        Ok(())
    }

    /// The equality constraints, kept unless a `<flag>` turns them off.
    pub(super) fn compile_equalities(&mut self, specs: &[EqualitySpec]) -> Result<(), MjcfError> {
        for spec in specs {
            if let Some(refusal) = self.mocap_equality_refusal(spec) {
                return Err(refusal);
            }
            let compiled = equality::compile(spec, self)?;
            if !(self.physics.constraint_disabled || self.physics.equality_disabled) {
                self.equalities.push(compiled);
            }
        }
        Ok(())
    }

    /// An equality constraint to a mocap body, refused: its pose is an
    /// input MuJoCo's users set, which an FMU does not take.
    fn mocap_equality_refusal(&self, spec: &EqualitySpec) -> Option<MjcfError> {
        let site_body = |name: &str| {
            let site = self.sites.iter().find(|s| s.name.as_deref() == Some(name))?;
            site.body.map(|b| self.bodies[b].name.as_str())
        };
        let bodies: Vec<&str> = match spec.frames()? {
            ObjectsSpec::Bodies(body1, body2) => std::iter::once(body1.as_str()).chain(body2.as_deref()).collect(),
            ObjectsSpec::Sites(site1, site2) => [site1, site2].into_iter().filter_map(|s| site_body(s)).collect(),
        };
        let body = bodies.into_iter().find(|body| self.mocap_bodies.iter().any(|m| m == body))?;
        let tag = &spec.at.tag;
        Some(spec.at.unsupported(format!(
            "<equality>/<{tag}> to mocap body '{body}': nudyn takes no mocap poses for the constraint to follow"
        )))
    }

    /// A section's sensors, with the copies of those that name objects
    /// inside `<replicate>`s as they are written there.
    pub(super) fn compile_sensors(&mut self, specs: &[SensorSpec]) -> Result<(), MjcfError> {
        let elements: Vec<_> = specs.iter().map(|spec| (&spec.at, sensor_references(spec))).collect();
        for copy in self.copies(&elements, false)? {
            let spec = &specs[copy.index];
            self.copy = Some(copy);
            let compiled = sensor::compile(spec, self);
            self.copy = None;
            let compiled = compiled?;
            if let Some(name) = &compiled.name {
                claim_name(&mut self.sensor_names, "sensor", name, &spec.at)?;
            }
            self.sensors.push(compiled);
        }
        Ok(())
    }

    /// A section's actuators, with the copies of those that name objects
    /// inside `<replicate>`s as they are written there.
    pub(super) fn compile_actuators(&mut self, specs: &[ActuatorSpec]) -> Result<(), MjcfError> {
        let elements: Vec<_> = specs.iter().map(|spec| (&spec.at, actuator_references(spec))).collect();
        for copy in self.copies(&elements, true)? {
            let spec = &specs[copy.index];
            let suffix = copy.suffix.clone();
            self.copy = Some(copy);
            let compiled = self.compile_actuator(spec);
            self.copy = None;
            compiled?;
            // Sensors may name the copies as the actuator is written.
            if let Some(name) = &spec.name {
                self.replicated_name(Named::Actuator, name, &suffix);
            }
        }
        Ok(())
    }

    /// One actuator (or copy) into MuJoCo's general actuator: its target
    /// looked up, its ranges resolved with MuJoCo's compiler checks.
    fn compile_actuator(&mut self, spec: &ActuatorSpec) -> Result<(), MjcfError> {
        let ActuatorSpec { at, kind, gain_type, bias_type, .. } = spec;
        let mut settings = spec.settings.clone();
        let transmission = self.transmission(at, &spec.transmission)?;
        // A servo may take its range from its target's: a position servo
        // (no activation, or a filtered setpoint) its ctrlrange, an
        // integrated-velocity servo its actrange.
        let position_like = *gain_type == GainType::Fixed
            && *bias_type == BiasType::Affine
            && settings.gainprm[0] == -settings.biasprm[1];
        if position_like && settings.inheritrange > 0.0 {
            let [low, high] = self.inherited_range(at, &transmission)?;
            let (mean, radius) = (0.5 * (high + low), 0.5 * (high - low) * settings.inheritrange);
            match spec.activation {
                None | Some(ActivationKind::FilterExact) => settings.ctrlrange = [mean - radius, mean + radius],
                Some(ActivationKind::Integrator) => settings.actrange = [mean - radius, mean + radius],
                Some(ActivationKind::Filter) => {
                    return Err(at.invalid("inheritrange only available for position and intvelocity actuators"));
                }
            }
        }
        let force_range = self.limits(at, "force", settings.forcelimited, settings.forcerange)?;
        let ctrl_range = self.limits(at, "ctrl", settings.ctrllimited, settings.ctrlrange)?;
        let act_range = self.limits(at, "act", settings.actlimited, settings.actrange)?;
        let activation = match spec.activation {
            Some(kind) => {
                Some(Activation { kind, time_constant: settings.dynprm[0], range: act_range, early: settings.actearly })
            }
            None if act_range.is_some() => return Err(at.invalid("actrange specified but dyntype is 'none'")),
            None => None,
        };

        let name = self.own_name(spec.name.as_deref());
        if let Some(name) = &name {
            claim_name(&mut self.actuator_names, "actuator", name, at)?;
        }
        let group = settings.group;
        self.actuators.push(Actuator {
            name,
            kind: *kind,
            transmission,
            gear: settings.gear,
            gain_type: *gain_type,
            gain: [settings.gainprm[0], settings.gainprm[1], settings.gainprm[2]],
            bias_type: *bias_type,
            bias: [settings.biasprm[0], settings.biasprm[1], settings.biasprm[2]],
            ctrl_range,
            force_range,
            activation,
            group_disabled: ACTUATOR_GROUPS.contains(&group) && self.physics.disabled_actuator_groups.contains(&group),
            line: at.line,
        });
        Ok(())
    }

    /// The range an `inheritrange` servo takes its ctrlrange from: its
    /// hinge or slide joint's, or its tendon's.
    fn inherited_range(&self, at: &Origin, transmission: &Transmission) -> Result<[f64; 2], MjcfError> {
        let (name, range) = match transmission {
            Transmission::Joint { joint, .. } => {
                let target = &self.joint_targets[joint];
                if !matches!(target.kind, JointKind::Hinge | JointKind::Slide) {
                    return Err(at.invalid("inheritrange can only be used with hinge and slide joints"));
                }
                (joint.as_str(), target.range)
            }
            Transmission::Tendon { tendon } => {
                let tendon = &self.tendons[*tendon];
                (tendon.name.as_deref().unwrap_or_default(), tendon.range)
            }
            Transmission::Site { .. } => {
                return Err(at.invalid("inheritrange can only be used with joint and tendon transmission"));
            }
        };
        if range[0] == range[1] {
            return Err(at.invalid(format!("inheritrange used but target '{name}' has no range defined")));
        }
        Ok(range)
    }

    /// The transmission an actuator names, its target looked up (in the
    /// copy being compiled).
    fn transmission(&self, at: &Origin, spec: &TransmissionSpec) -> Result<Transmission, MjcfError> {
        Ok(match spec {
            TransmissionSpec::Tendon(name) => Transmission::Tendon { tendon: self.tendon_named(at, name, "actuator")? },
            &TransmissionSpec::Joint { ref name, in_parent } => {
                let attribute = if in_parent { "jointinparent" } else { "joint" };
                let name = self.reference(attribute, name);
                if !self.joint_targets.contains_key(&name) {
                    return Err(self.unknown(at, &format!("transmission target '{name}' for actuator"), &name));
                }
                Transmission::Joint { joint: name, in_parent }
            }
            TransmissionSpec::Site { site, refsite } => {
                let site = self.site_named(at, "site", &self.reference("site", site), "actuator")?;
                let refsite = match refsite {
                    Some(refsite) => {
                        Some(self.site_named(at, "refsite", &self.reference("refsite", refsite), "actuator")?)
                    }
                    None => None,
                };
                Transmission::Site { site, refsite }
            }
        })
    }

    /// The index of the tendon `name`.
    pub(in crate::mjcf::reader) fn tendon_named(
        &self,
        at: &Origin,
        name: &str,
        user: &str,
    ) -> Result<usize, MjcfError> {
        self.tendons
            .iter()
            .position(|t| t.name.as_deref() == Some(name))
            .ok_or_else(|| at.invalid(format!("unknown tendon '{name}' in {user}")))
    }

    /// The keyframes, each vector checked against the model's size.
    pub(super) fn compile_keyframes(&mut self, specs: Vec<KeySpec>) -> Result<(), MjcfError> {
        let joints = self.bodies.iter().flat_map(|b| &b.joints);
        let (nq, nv) = joints.fold((0, 0), |(nq, nv), j| (nq + j.kind.nq(), nv + j.kind.nv()));
        // Each activation state nudyn models has one act.
        let na = self.actuators.iter().filter(|a| a.activation.is_some()).count();
        let sizes = KeySizes { nq, nv, na, nmocap: self.mocap_bodies.len(), nu: self.actuators.len() };
        for spec in specs {
            self.keyframes.push(keyframe::compile(spec, &sizes)?);
        }
        Ok(())
    }
}

/// The objects an actuator names that a `<replicate>` may hold.
fn actuator_references(spec: &ActuatorSpec) -> Vec<Reference> {
    match &spec.transmission {
        TransmissionSpec::Joint { name, in_parent } => {
            let attribute = if *in_parent { "jointinparent" } else { "joint" };
            vec![(attribute, Named::Joint, name.clone())]
        }
        TransmissionSpec::Site { site, refsite } => std::iter::once(("site", Named::Site, site.clone()))
            .chain(refsite.iter().map(|refsite| ("refsite", Named::Site, refsite.clone())))
            .collect(),
        TransmissionSpec::Tendon(_) => Vec::new(),
    }
}

/// The objects a sensor names that a `<replicate>` may hold.
fn sensor_references(spec: &SensorSpec) -> Vec<Reference> {
    let framed = |frame_type| match frame_type {
        sensor::FrameType::Body | sensor::FrameType::XBody => Named::Body,
        sensor::FrameType::Site => Named::Site,
    };
    let (object_type, reference_type) = match spec.frame {
        Some((object, reference)) => (Some(object), reference),
        None => (None, None),
    };
    let kind = |attribute: &str| match attribute {
        "joint" => Some(Named::Joint),
        "site" => Some(Named::Site),
        "body" => Some(Named::Body),
        "actuator" => Some(Named::Actuator),
        "objname" => object_type.map(framed),
        "refname" => reference_type.map(framed),
        _ => None,
    };
    let named = spec.names.iter().filter_map(|(attribute, name)| Some((*attribute, kind(attribute)?, name.clone())));
    named.collect()
}
