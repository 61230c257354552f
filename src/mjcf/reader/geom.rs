//! Geoms and `<inertial>`: the mass properties a body takes from them
//! (MuJoCo's geom and mesh inertia, `boundmass`, `boundinertia`).

use super::body::compose;
use super::compile::GeomSpec;
use super::{GeomRead, Pose, Reader, no_children};
use crate::math::{Mat3, Quat, Vec3};
use crate::mjcf::bodies::{INERTIAL_ATTRIBUTES, InertialSettings, read_settings};
use crate::mjcf::contacts::{ContactGeom, Reach};
use crate::mjcf::defaults::{GeomKind, GeomSettings};
use crate::mjcf::element::{Element, Origin};
use crate::mjcf::error::MjcfError;
use crate::mjcf::inertia::{BodyInertia, EPS, GeomMass, mul_quat, quat_array, quat_to_mat};
use crate::mjcf::orientation::{ORIENTATION_ATTRIBUTES, normalized, z_to_quaternion};
use crate::mjcf::{contacts, inertia, mesh};
use crate::vehicle::WrapGeom;

impl Reader {
    pub(super) fn read_inertial(&self, element: &Element) -> Result<BodyInertia, MjcfError> {
        let InertialSettings { pos, mass, diaginertia, fullinertia, orientation } =
            read_settings(INERTIAL_ATTRIBUTES, element)?;
        no_children(element)?;
        let com = Vec3::from(pos.ok_or_else(|| element.missing("pos"))?);
        let mass = mass.ok_or_else(|| element.missing("mass"))?;
        let Some([xx, yy, zz, xy, xz, yz]) = fullinertia else {
            let quat = self.resolve(&element.origin(), &orientation.unwrap_or_default())?;
            return Ok(BodyInertia::from_principal(mass, com, &quat, Vec3::from(diaginertia)));
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
    pub(super) fn bound(&self, at: &Origin, mut inertia: BodyInertia) -> Result<BodyInertia, MjcfError> {
        let compiler = &self.compiler;
        inertia.mass = inertia.mass.max(compiler.bound_mass);
        let bounded = inertia.principal.map(|p| p.max(compiler.bound_inertia));
        if bounded != inertia.principal {
            inertia.set_principal(bounded);
        }
        let p = inertia.principal;
        if p.x + p.y < p.z || p.x + p.z < p.y || p.y + p.z < p.x {
            if !compiler.balance_inertia {
                return Err(at.invalid(format!(
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
    pub(super) fn fit_to_mesh(
        &self,
        at: &Origin,
        settings: &GeomSettings,
        mesh: &mesh::Mesh,
        size: [f64; 3],
        pos: Vec3,
        quat: Quat,
    ) -> Result<([f64; 3], Vec3, Quat), MjcfError> {
        let kind = settings.kind;
        let (fitted, center) = mesh
            .fit(kind, size, self.compiler.fit_aabb, settings.fit_scale)
            .ok_or_else(|| at.invalid(format!("a {kind:?} geom cannot be fitted to a mesh")))?;
        let (pos, quat) = absorb_frame(pos, quat, &mesh.frame_point(&center), &mesh.quat);
        Ok((fitted, pos, quat))
    }

    /// Registers a geom a tendon wraps around: its type, and a sphere's or
    /// cylinder's frame in its body (a primitive fitted to a mesh reads the
    /// mesh here, so only for a tendon).
    pub(super) fn register_wrap_geom(&mut self, geom: &GeomSpec) -> Result<(), MjcfError> {
        let GeomSpec { at, settings, frame, name, body } = geom;
        let Some(name) = name.as_ref().filter(|name| self.wrap_obstacles.contains_key(*name)) else {
            return Ok(());
        };
        let (body, frame) = (*body, frame.as_ref());
        let wrap = match settings.kind {
            GeomKind::Sphere | GeomKind::Cylinder => {
                let (pos, quat) = match settings.fromto {
                    Some(_) if settings.mesh.is_some() => {
                        return Err(at.invalid("fromto cannot be used with a mesh"));
                    }
                    Some(fromto) if settings.kind == GeomKind::Cylinder => {
                        let (pos, quat, _) = fromto_frame(at, &fromto, &settings.pos)?;
                        (pos, quat)
                    }
                    _ => (Vec3::from(settings.pos), self.resolve(at, &settings.orientation)?),
                };
                let (pos, quat) = frame.map_or((pos, quat), |frame| compose(frame, &(pos, quat)));
                let (size, pos, quat) = match &settings.mesh {
                    Some(name) => {
                        let mesh = self.mesh_named(at, name)?.mesh()?;
                        self.fit_to_mesh(at, settings, mesh, settings.size, pos, quat)?
                    }
                    None => (settings.size, pos, quat),
                };
                if size[0] <= 0.0 {
                    return Err(at.invalid(format!("size[0] must be positive, found {}", size[0])));
                }
                let cylinder = settings.kind == GeomKind::Cylinder;
                Some(WrapGeom { body, pos, quat, radius: size[0], cylinder, side: None })
            }
            _ => None,
        };
        self.named_geoms.insert(name.clone(), (settings.kind, wrap));
        Ok(())
    }

    /// The mesh asset a geom names (not read yet).
    pub(super) fn mesh_named(&self, at: &Origin, name: &str) -> Result<&mesh::MeshAsset, MjcfError> {
        self.meshes.get(name).ok_or_else(|| at.invalid(format!("unknown mesh '{name}'")))
    }

    /// The geom's mass, frame and principal moments when it contributes to its
    /// body's inertia; checks it as MuJoCo does either way, but for what
    /// needs its mesh, which is read only when it contributes.
    pub(super) fn geom_mass(
        &self,
        at: &Origin,
        settings: &GeomSettings,
        frame: Option<&Pose>,
        moving: bool,
        contributes: bool,
    ) -> Result<GeomRead, MjcfError> {
        if matches!(settings.kind, GeomKind::Mesh | GeomKind::Sdf) && settings.mesh.is_none() {
            return Err(at.missing("mesh"));
        }
        if settings.kind == GeomKind::Hfield && !settings.hfield {
            return Err(at.missing("hfield"));
        }
        if settings.kind == GeomKind::Plane && moving {
            return Err(at.invalid("a plane geom is only allowed in a body that cannot move"));
        }
        let mut size = settings.size;
        let (pos, quat) = match settings.fromto {
            Some(fromto) => {
                if !matches!(
                    settings.kind,
                    GeomKind::Capsule | GeomKind::Cylinder | GeomKind::Ellipsoid | GeomKind::Box
                ) {
                    return Err(at.invalid("'fromto' requires a capsule, cylinder, ellipsoid or box geom"));
                }
                let (pos, quat, half_length) = fromto_frame(at, &fromto, &settings.pos)?;
                if matches!(settings.kind, GeomKind::Ellipsoid | GeomKind::Box) {
                    size = [size[0], size[0], half_length];
                } else {
                    size[1] = half_length;
                }
                (pos, quat)
            }
            None => (Vec3::from(settings.pos), self.resolve(at, &settings.orientation)?),
        };
        let (pos, quat) = frame.map_or((pos, quat), |frame| compose(frame, &(pos, quat)));
        let mesh = match &settings.mesh {
            Some(name) => {
                if settings.fromto.is_some() {
                    return Err(at.invalid("fromto cannot be used with a mesh"));
                }
                let asset = self.mesh_named(at, name)?;
                if settings.kind == GeomKind::Mesh && settings.shell_inertia {
                    return Err(at.invalid("for mesh geoms, inertia should be specified in the mesh asset"));
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
                let (fitted, pos, quat) = self.fit_to_mesh(at, settings, mesh, size, pos, quat)?;
                size = fitted;
                (pos, quat)
            }
        };
        check_size(at, settings.kind, &size)?;
        let mesh = match (settings.kind, mesh) {
            (GeomKind::Mesh, Some(mesh)) => {
                if settings.contype != [0, 0]
                    && let Some(reason) = &mesh.hull_error
                {
                    return Err(at.invalid(format!(
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
            return Err(at.unsupported(
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
    pub(super) fn add_contact_geom(
        &mut self,
        at: &Origin,
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
                label: at.label.clone(),
                line: at.line,
            });
        }
    }
}

/// The frame MuJoCo gives a geom or site with `fromto`: centred between the
/// two points, its z axis pointing from the second towards the first; and
/// the half distance between the points. A `pos` beside it is refused.
pub(super) fn fromto_frame(at: &Origin, fromto: &[f64; 6], pos: &[f64; 3]) -> Result<(Vec3, Quat, f64), MjcfError> {
    if *pos != [0.0; 3] {
        return Err(at.conflict("pos", "fromto"));
    }
    let from = Vec3::new(fromto[0], fromto[1], fromto[2]);
    let to = Vec3::new(fromto[3], fromto[4], fromto[5]);
    let direction = normalized(from - to).ok_or_else(|| at.invalid("the 'fromto' points coincide"))?;
    let half_length = (from - to).norm() / 2.0;
    Ok(((from + to) / 2.0, Quat::new_normalize(z_to_quaternion(&direction)), half_length))
}

/// Whether a geom's mass would come from an asset nudyn does not read: an
/// sdf or a height field.
pub(super) fn mass_not_computed(settings: &GeomSettings) -> bool {
    matches!(settings.kind, GeomKind::Sdf | GeomKind::Hfield)
}

/// A geom frame (`pos`, `quat`) that takes in a frame given inside it
/// (MuJoCo's `mjuu_frameaccum`).
pub(super) fn absorb_frame(pos: Vec3, quat: Quat, inner_pos: &[f64; 3], inner_quat: &[f64; 4]) -> (Vec3, Quat) {
    let geom_quat = quat_array(&quat);
    let rotation = quat_to_mat(&geom_quat);
    let p = inner_pos;
    let offset: [f64; 3] =
        std::array::from_fn(|r| rotation[3 * r] * p[0] + rotation[3 * r + 1] * p[1] + rotation[3 * r + 2] * p[2]);
    let [w, x, y, z] = mul_quat(&geom_quat, inner_quat);
    (pos + Vec3::from(offset), Quat::new_unchecked(nalgebra::Quaternion::new(w, x, y, z)))
}

/// MuJoCo's size check: the sizes a primitive uses must be positive.
pub(super) fn check_size(at: &Origin, kind: GeomKind, size: &[f64; 3]) -> Result<(), MjcfError> {
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
        Some(i) => Err(at.invalid(format!("size[{i}] of a {name} geom must be positive, found {}", size[i]))),
        None => Ok(()),
    }
}
