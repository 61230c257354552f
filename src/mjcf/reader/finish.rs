//! Once the whole document is read: `fusestatic`, the body names set
//! apart, and the [`Vehicle`] with its flags applied.

use super::body::compose;
use super::{BodyRecord, MIN_VALUE, Reader};
use crate::math::{Mat3, Vec3};
use crate::mjcf::error::MjcfError;
use crate::mjcf::{Imported, MjcfWarning};
use crate::vehicle::{
    EqualityObjects, FrameObject, MassProperties, PathPoint, SensorKind, SensorTarget, Tendon, TendonPath, Vehicle,
    WrapGeom,
};

impl Reader {
    pub(super) fn finish(mut self, name: String) -> Result<Imported, MjcfError> {
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
        self.warn_of_world_geoms();
        self.warnings.sort_by_key(|w| w.line);
        let gravity = if self.physics.gravity_disabled { Vec3::zeros() } else { self.physics.gravity };
        let flexible = self.modal_bodies()?;
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
            flexible,
        };
        Ok(Imported { vehicle, warnings: self.warnings, keyframes: self.keyframes })
    }

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
    /// The world body's geoms: one a tendon wraps around is used, and only
    /// its contacts are left out; any other is ignored. Their warnings come
    /// first, as when they were read.
    fn warn_of_world_geoms(&mut self) {
        let mut warnings = Vec::new();
        for geom in std::mem::take(&mut self.world_geoms) {
            let tendon = geom.name.as_ref().and_then(|name| self.wrap_obstacles.get(name));
            match tendon {
                None => warnings.push(geom.warning),
                Some(tendon) if geom.collides => warnings.push(MjcfWarning {
                    message: format!(
                        "used as the wrap obstacle of <{tendon}>; fixed to the world, it moves no mass, and its \
                         contacts are left out: nudyn models no contacts (MuJoCo would make contacts with it)"
                    ),
                    ..geom.warning
                }),
                Some(_) => {}
            }
        }
        self.warnings.splice(0..0, warnings);
    }

    pub(super) fn fuse_static(&mut self) -> Result<(), MjcfError> {
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

/// The geoms the tendons wrap around.
pub(super) fn wrap_geoms_mut(tendons: &mut [Tendon]) -> impl Iterator<Item = &mut WrapGeom> {
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
