//! The compile stage of the body tree: what MuJoCo's compiler computes from
//! the bodies, joints, geoms, sites and `<inertial>`s as read (their
//! defaults resolved, the `<frame>`s around them kept): the frames
//! composed, each body placed in its parent and in the world at qpos0, its
//! joints built and checked; each geom's mass and frame, from its
//! primitive or its mesh (a mesh file is read here, and only for a geom
//! whose mass counts or a primitive a tendon wraps around); the wrap
//! frames of the sphere and cylinder geoms tendons wrap around; the geoms
//! that may collide, and a warning on those that touch; each body's mass properties (`inertiafromgeom`,
//! `boundmass`, `boundinertia`); and the free bodies aligned with their
//! inertial frames.

use super::{BodySpec, GeomSpec, MassSource, SiteSpec};
use crate::math::{Quat, Vec3};
use crate::mjcf::MjcfWarning;
use crate::mjcf::contacts::{self, BodyFilter};
use crate::mjcf::error::MjcfError;
use crate::mjcf::inertia::{BodyInertia, EPS, GeomMass};
use crate::mjcf::reader::body::compose;
use crate::mjcf::reader::geom::mass_not_computed;
use crate::mjcf::reader::{BodyRecord, InertiaFromGeom, Reader, WorldGeom};
use crate::vehicle::Body;

impl Reader {
    /// Compiles the bodies and geoms of `tree`: each body placed in its
    /// parent and in the world, the geoms in document order, then each
    /// body's mass properties, with which a free body may move its frame.
    pub(super) fn compile_bodies(
        &mut self,
        bodies: Vec<BodySpec>,
        geoms: Vec<GeomSpec>,
        sites: Vec<SiteSpec>,
    ) -> Result<(), MjcfError> {
        let sources = self.place_bodies(bodies)?;
        for SiteSpec { mut site, frame, fitted_to_mesh } in sites {
            if let Some(frame) = frame {
                (site.pos, site.quat) = compose(&frame, &(site.pos, site.quat));
            }
            self.sites.push(site);
            self.site_fitted_to_mesh.push(fitted_to_mesh);
        }
        let mut masses: Vec<Vec<GeomMass>> = sources.iter().map(|_| Vec::new()).collect();
        for geom in &geoms {
            self.register_wrap_geom(geom)?;
            match geom.body {
                None => self.compile_world_geom(geom)?,
                Some(index) => {
                    // MuJoCo leaves out geoms of mass up to mjEPS.
                    if let Some(mass) = self.compile_body_geom(geom, &sources[index])?
                        && mass.mass > EPS
                    {
                        masses[index].push(mass);
                    }
                }
            }
        }
        for (index, (body, selected)) in sources.into_iter().zip(masses).enumerate() {
            let explicit = body.explicit.map(|(mut inertia, frame)| {
                if let Some((pos, quat)) = frame {
                    inertia.place(&pos, &quat);
                }
                inertia
            });
            let inertia = match (selected.is_empty(), explicit) {
                (false, _) => BodyInertia::from_geoms(&selected).map_err(|r| body.at.invalid(r))?,
                (true, Some(explicit)) => explicit,
                // MuJoCo puts the inertial frame of a body without mass at the body's
                // own pose in its parent, before any <frame> around it; it matters
                // once boundmass gives it mass.
                (true, None) => BodyInertia::from_principal(0.0, body.own_pose.0, &body.own_pose.1, Vec3::zeros()),
            };
            let mut inertia = self.bound(&body.at, inertia)?;
            if body.aligned {
                inertia = self.align_free(index, inertia);
            }
            let has_joints = !self.bodies[index].joints.is_empty();
            let (line, label) = (body.at.line, body.at.label);
            self.records.push(BodyRecord { line, label, inertia, has_joints, children: Vec::new() });
        }
        for index in 0..self.bodies.len() {
            if let Some(parent) = self.bodies[index].parent {
                self.records[parent].children.push(index);
            }
        }
        Ok(())
    }

    /// The vehicle's bodies, each placed in its parent (the `<frame>`s
    /// around it and its joints composed) and in the world at qpos0, its
    /// joints built, with the names made up for unnamed ones set apart;
    /// what their masses come from.
    fn place_bodies(&mut self, bodies: Vec<BodySpec>) -> Result<Vec<MassSource>, MjcfError> {
        let mut sources = Vec::with_capacity(bodies.len());
        for BodySpec { name, parent, frame, mut joints, gravcomp, mass } in bodies {
            for joint in joints.iter_mut() {
                if let Some((at, turn)) = joint.frame {
                    joint.settings.pos = (at + turn * Vec3::from(joint.settings.pos)).into();
                    joint.settings.axis = (turn * Vec3::from(joint.settings.axis)).into();
                }
            }
            let joints = self.build_joints(&name, parent, joints)?;
            let (pos, quat) = frame.map_or(mass.own_pose, |frame| compose(&frame, &mass.own_pose));
            let world_pose = parent.map_or((pos, quat), |parent| compose(&self.world_poses[parent], &(pos, quat)));
            self.world_poses.push(world_pose);
            self.bodies.push(Body {
                name,
                parent,
                pos,
                quat,
                inertia: None,
                inertial_pos: Vec3::zeros(),
                inertial_quat: None,
                mass_unknown: false,
                joints,
                gravcomp,
                line: mass.at.line,
            });
            sources.push(mass);
        }
        self.set_apart_unnamed();
        Ok(sources)
    }

    /// A geom of the world body: it moves no mass, so its mesh is never
    /// read; it may still collide, or be a tendon's wrap obstacle.
    fn compile_world_geom(&mut self, geom: &GeomSpec) -> Result<(), MjcfError> {
        let GeomSpec { at, settings, frame, name, .. } = geom;
        let read = self.geom_mass(at, settings, frame.as_ref(), false, false)?;
        self.add_contact_geom(at, settings, None, read.reach);
        let collides = settings.contype != [0, 0];
        self.world_geoms.push(WorldGeom { name: name.clone(), collides, warning: at.ignored() });
        Ok(())
    }

    /// A geom of `body`: its mass when it counts towards the body's (as
    /// `inertiafromgeom` and `inertiagrouprange` say).
    fn compile_body_geom(&mut self, geom: &GeomSpec, body: &MassSource) -> Result<Option<GeomMass>, MjcfError> {
        let GeomSpec { at, settings, frame, body: index, .. } = geom;
        let from_geoms = match self.compiler.inertia_from_geom {
            InertiaFromGeom::Never => false,
            InertiaFromGeom::Always => true,
            InertiaFromGeom::Auto => body.explicit.is_none(),
        };
        let [low, high] = self.compiler.inertia_groups;
        let contributes = from_geoms && (low..=high).contains(&settings.group);
        if contributes && mass_not_computed(settings) && !body.moving {
            if let Some(index) = index {
                self.bodies[*index].mass_unknown = true;
            }
            self.warnings.push(at.warning(
                "its mass is not computed: the body is fixed to the world, so it moves nothing \
                 (a subtree sensor that would count it is refused)",
            ));
        }
        let read = self.geom_mass(at, settings, frame.as_ref(), body.moving, contributes)?;
        self.add_contact_geom(at, settings, *index, read.reach);
        Ok(read.mass)
    }

    /// A free body without children aligned with its inertial frame
    /// (`<freejoint align>`, `<compiler alignfree>`): MuJoCo moves the body
    /// frame there, so that the free joint's qpos is the inertial frame's
    /// pose, and re-expresses the body's sites in it. Moves the `index`th
    /// body and its sites; returns its mass properties in the new frame.
    fn align_free(&mut self, index: usize, inertia: BodyInertia) -> BodyInertia {
        let (principal, axes) = (inertia.principal, inertia.quat);
        let inverse = (-(axes.inverse() * inertia.com), axes.inverse());
        for site in self.sites.iter_mut().filter(|s| s.body == Some(index)) {
            (site.pos, site.quat) = compose(&inverse, &(site.pos, site.quat));
        }
        let body = &mut self.bodies[index];
        (body.pos, body.quat) = compose(&(body.pos, body.quat), &(inertia.com, axes));
        BodyInertia::from_principal(inertia.mass, Vec3::zeros(), &Quat::identity(), principal)
    }

    /// A warning on each pair of geoms MuJoCo would collide at qpos0
    /// (`super::contacts` says what is checked), unless `<flag contact>` or
    /// `<flag constraint>` turns contacts off.
    pub(super) fn warn_of_contacts(&mut self) {
        if self.physics.contact_disabled || self.physics.constraint_disabled {
            return;
        }
        let body = |name: &str| match name {
            "world" => Some(None),
            name => self.bodies.iter().position(|b| b.name == name && self.body_names.contains_key(name)).map(Some),
        };
        let excluded: Vec<_> =
            self.contact_exclusions.iter().filter_map(|(body1, body2)| Some((body(body1)?, body(body2)?))).collect();
        let parents: Vec<Option<usize>> = self.bodies.iter().map(|b| b.parent).collect();
        let roots: Vec<bool> =
            self.bodies.iter().map(|b| !b.joints.is_empty() || self.mocap_bodies.contains(&b.name)).collect();
        let filter = BodyFilter {
            parents: &parents,
            poses: &self.world_poses,
            roots: &roots,
            filter_parent: !self.physics.filterparent_disabled,
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
}
