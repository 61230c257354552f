//! The names tendons, equalities, actuators and sensors refer to, looked up
//! in the compiled body tree and what the compile stage has compiled.

use super::{JointTarget, Reader};
use crate::mjcf::element::Origin;
use crate::mjcf::equality::EqualityTargets;
use crate::mjcf::error::MjcfError;
use crate::mjcf::sensor::SensorTargets;
use crate::mjcf::tendon::TendonTargets;
use crate::vehicle::{JointKind, WrapGeom};

impl Reader {
    /// The error for a reference to `name`, which names nothing of its kind
    /// (`described`: the kind, the name and where it stands). MuJoCo copies
    /// an element naming something inside a `<replicate>` for each copy;
    /// nudyn copies actuators and sensors, and says so for the others.
    pub(super) fn unknown(&self, at: &Origin, described: &str, name: &str) -> MjcfError {
        let hint = match self.replicated.get(name) {
            Some(copy) => match at.parent.as_str() {
                "actuator" | "sensor" => {
                    format!(": it is inside a <replicate>, whose copies are named '{copy}' and so on: name a copy")
                }
                _ => format!(
                    ": it is inside a <replicate>, whose copies are named '{copy}' and so on; nudyn copies the \
                     actuators and sensors that name it as written, not tendons and equalities (MuJoCo does): \
                     name a copy instead"
                ),
            },
            None => String::new(),
        };
        at.invalid(format!("unknown {described}{hint}"))
    }

    /// The index of the site `name` (which `attribute` gives); a site fitted
    /// to a mesh is refused (the mesh would move its frame).
    pub(super) fn site_named(&self, at: &Origin, attribute: &str, name: &str, user: &str) -> Result<usize, MjcfError> {
        let Some(index) = self.sites.iter().position(|s| s.name.as_deref() == Some(name)) else {
            return Err(self.unknown(at, &format!("{attribute} '{name}' for {user}"), name));
        };
        if self.site_fitted_to_mesh[index] {
            return Err(at.unsupported(format!(
                "{attribute} '{name}' (line {}) is fitted to a mesh, which would move its frame",
                self.sites[index].line
            )));
        }
        Ok(index)
    }

    /// The joint `name` a sensor names.
    fn sensed_joint(&self, at: &Origin, name: &str) -> Result<&JointTarget, MjcfError> {
        self.joint_targets.get(name).ok_or_else(|| self.unknown(at, &format!("joint '{name}' in sensor"), name))
    }
}

impl EqualityTargets for Reader {
    fn equality_body(&self, at: &Origin, name: &str) -> Result<Option<usize>, MjcfError> {
        if name == "world" {
            return Ok(None);
        }
        match self.bodies.iter().position(|b| b.name == name) {
            Some(index) if self.body_names.contains_key(name) => Ok(Some(index)),
            _ => Err(self.unknown(at, &format!("body '{name}' in equality constraint"), name)),
        }
    }

    fn equality_site(&self, at: &Origin, attribute: &str, name: &str) -> Result<usize, MjcfError> {
        self.site_named(at, attribute, name, "equality constraint")
    }

    fn equality_tendon(&self, at: &Origin, name: &str) -> Result<usize, MjcfError> {
        self.tendon_named(at, name, "equality constraint")
    }

    fn equality_joint(&self, at: &Origin, name: &str) -> Result<JointKind, MjcfError> {
        self.joint_targets
            .get(name)
            .map(|joint| joint.kind)
            .ok_or_else(|| self.unknown(at, &format!("joint '{name}' in equality constraint"), name))
    }
}

impl TendonTargets for Reader {
    fn tendon_joint(&self, at: &Origin, name: &str) -> Result<JointKind, MjcfError> {
        self.joint_targets
            .get(name)
            .map(|joint| joint.kind)
            .ok_or_else(|| at.invalid(format!("unknown joint '{name}' in tendon")))
    }

    fn tendon_site(&self, at: &Origin, attribute: &str, name: &str) -> Result<usize, MjcfError> {
        self.site_named(at, attribute, name, "tendon")
    }

    fn tendon_side_site(&self, at: &Origin, attribute: &str, name: &str, geom: &WrapGeom) -> Result<usize, MjcfError> {
        self.side_site(at, attribute, name, geom)
    }

    fn tendon_geom(&self, at: &Origin, name: &str) -> Result<WrapGeom, MjcfError> {
        match self.named_geoms.get(name) {
            None => Err(at.invalid(format!("unknown geom '{name}' in tendon"))),
            Some((_, Some(geom))) => Ok(*geom),
            Some((kind, None)) => {
                Err(at.invalid(format!("geom '{name}' in tendon is not sphere or cylinder (it is {kind:?})")))
            }
        }
    }
}

impl Reader {
    /// A wrap's side site, refused where nudyn does not follow MuJoCo: on
    /// another body than the geom's (it could move into the geom), or inside
    /// the geom (MuJoCo then passes the tendon through it).
    fn side_site(&self, at: &Origin, attribute: &str, name: &str, geom: &WrapGeom) -> Result<usize, MjcfError> {
        let index = self.site_named(at, attribute, name, "tendon")?;
        let site = &self.sites[index];
        if site.body != geom.body {
            return Err(at.unsupported(format!(
                "{attribute} on another body than the geom's: nudyn takes side sites on the geom's body, which \
                 cannot move into it"
            )));
        }
        let local = geom.quat.inverse() * (site.pos - geom.pos);
        let off_axis = if geom.cylinder { local.xy().norm() } else { local.norm() };
        if off_axis < geom.radius {
            return Err(at.unsupported(format!(
                "{attribute} inside the geom: MuJoCo 4.0 then makes the tendon pass through the geom, which nudyn \
                 does not model"
            )));
        }
        Ok(index)
    }
}

impl SensorTargets for Reader {
    fn tendon(&self, at: &Origin, name: &str) -> Result<usize, MjcfError> {
        self.tendon_named(at, name, "sensor")
    }

    fn tendon_limited(&self, at: &Origin, name: &str) -> Result<bool, MjcfError> {
        Ok(self.tendon_limited[self.tendon_named(at, name, "sensor")?])
    }

    fn joint_kind(&self, at: &Origin, name: &str) -> Result<JointKind, MjcfError> {
        Ok(self.sensed_joint(at, name)?.kind)
    }

    fn joint_limited(&self, at: &Origin, name: &str) -> Result<bool, MjcfError> {
        Ok(self.sensed_joint(at, name)?.limited)
    }

    fn body(&self, at: &Origin, name: &str) -> Result<Option<usize>, MjcfError> {
        if name == "world" {
            return Ok(None);
        }
        match self.body_names.contains_key(name) {
            true => Ok(self.bodies.iter().position(|b| b.name == name)),
            false => Err(self.unknown(at, &format!("body '{name}' in sensor"), name)),
        }
    }

    fn site(&self, at: &Origin, attribute: &str, name: &str) -> Result<usize, MjcfError> {
        self.site_named(at, attribute, name, "sensor")
    }

    fn actuator(&self, at: &Origin, name: &str) -> Result<usize, MjcfError> {
        match self.actuators.iter().position(|a| a.name.as_deref() == Some(name)) {
            Some(index) => Ok(index),
            None => Err(self.unknown(at, &format!("actuator '{name}' in sensor"), name)),
        }
    }

    fn name(&self, attribute: &str, written: &str) -> String {
        self.reference(attribute, written)
    }

    fn own_name(&self, written: Option<&str>) -> Option<String> {
        Reader::own_name(self, written)
    }
}
