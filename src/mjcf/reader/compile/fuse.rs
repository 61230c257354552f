//! The compile stage of what needs the whole model: the check that every
//! moving body has mass, `<compiler fusestatic>` (which needs the sensors
//! and equalities that name bodies), `settotalmass`, and the bodies' mass
//! properties as the vehicle holds them.

use crate::math::Mat3;
use crate::mjcf::error::MjcfError;
use crate::mjcf::reader::body::compose;
use crate::mjcf::reader::{BodyRecord, MIN_VALUE, Reader};
use crate::vehicle::{
    EqualityObjects, FrameObject, MassProperties, PathPoint, SensorKind, SensorTarget, Tendon, TendonPath, WrapGeom,
};

impl Reader {
    /// The bodies' mass properties, once every body is compiled and every
    /// name resolved: checked, fused (`fusestatic`), scaled
    /// (`settotalmass`), and set on the vehicle's bodies.
    pub(super) fn compile_masses(&mut self) -> Result<(), MjcfError> {
        self.check_moving_masses()?;
        if self.compiler.fuse_static {
            self.fuse_static()?;
        }
        self.scale_total_mass()?;
        for (body, record) in self.bodies.iter_mut().zip(&self.records) {
            let inertia = &record.inertia;
            let massless = inertia.mass == 0.0 && inertia.tensor == Mat3::zeros();
            body.inertia =
                (!massless).then_some(MassProperties { mass: inertia.mass, com: inertia.com, inertia: inertia.tensor });
            body.inertial_pos = inertia.com;
            body.inertial_quat = Some(inertia.quat);
        }
        Ok(())
    }

    /// A moving body needs mass and principal moments (MuJoCo's mjMINVAL),
    /// its own or a body's welded below it.
    fn check_moving_masses(&self) -> Result<(), MjcfError> {
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

        Ok(())
    }

    /// `<compiler settotalmass>`: every body's mass properties scaled alike
    /// to the total, with the warning it earns.
    fn scale_total_mass(&mut self) -> Result<(), MjcfError> {
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

        Ok(())
    }

    /// `<compiler fusestatic="true">` as MuJoCo 4.0 applies it
    /// (`mjCModel::FuseStatic`), in body order: a body without joints, not
    /// mocap, not named by anything that refers to bodies (a sensor, a
    /// camera's or light's target, a contact exclusion), carrying no site a
    /// force or torque sensor reads, and not with a mass under another
    /// gravcomp than its parent's (unless that is the world), and not a
    /// child of a flexible body (whose inertial its nodes must reproduce),
    /// disappears into its parent. Its mass properties join the parent's (unless the parent is
    /// the world, or its mass is below mjMINVAL), its child bodies and sites
    /// become the parent's, placed where they were. The parent's inertial
    /// frame moves: sensors of objtype "body" on it measure the merged one.
    fn fuse_static(&mut self) -> Result<(), MjcfError> {
        let referenced = self.referenced_bodies();
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
            // A flexible body's inertial is its nodes': a body welded to it
            // stays a body (at a node it joins that node, docs/flexible.md).
            let on_flexible =
                body.parent.is_some_and(|p| self.modal_texts.iter().any(|t| t.body == self.bodies[p].name));
            let keep = referenced[index] || named || !body.joints.is_empty() || compensated_otherwise || on_flexible;
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

    /// The bodies fusestatic keeps because a sensor or an equality names them.
    fn referenced_bodies(&self) -> Vec<bool> {
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
        referenced
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
