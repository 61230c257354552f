//! The names tendons, equalities, actuators and sensors refer to, looked up
//! in what the reader has read.

use super::{JointTarget, Reader};
use crate::mjcf::element::Element;
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
    pub(super) fn unknown(&self, element: &Element, described: &str, name: &str) -> MjcfError {
        let hint = match self.replicated.get(name) {
            Some(copy) => match element.node.parent_element().map(|parent| parent.tag_name().name()) {
                Some("actuator" | "sensor") => {
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
        element.invalid(format!("unknown {described}{hint}"))
    }

    /// The index of the site the attribute names; a site fitted to a mesh is
    /// refused (the mesh would move its frame).
    pub(super) fn site_named(&self, element: &Element, attribute: &str, user: &str) -> Result<usize, MjcfError> {
        let name = self.reference(element, attribute);
        let Some(index) = self.sites.iter().position(|s| s.name.as_deref() == Some(&name)) else {
            return Err(self.unknown(element, &format!("{attribute} '{name}' for {user}"), &name));
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
    pub(super) fn sensed_joint(&self, element: &Element, attribute: &str) -> Result<&JointTarget, MjcfError> {
        let name = self.reference(element, attribute);
        self.joint_targets.get(&name).ok_or_else(|| self.unknown(element, &format!("joint '{name}' in sensor"), &name))
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

    fn tendon_side_site(&self, element: &Element, attribute: &str, geom: &WrapGeom) -> Result<usize, MjcfError> {
        self.side_site(element, attribute, geom)
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

impl Reader {
    /// A wrap's side site, refused where nudyn does not follow MuJoCo: on
    /// another body than the geom's (it could move into the geom), or inside
    /// the geom (MuJoCo then passes the tendon through it).
    fn side_site(&self, element: &Element, attribute: &str, geom: &WrapGeom) -> Result<usize, MjcfError> {
        let index = self.site_named(element, attribute, "tendon")?;
        let site = &self.sites[index];
        if site.body != geom.body {
            return Err(element.unsupported(format!(
                "{attribute} on another body than the geom's: nudyn takes side sites on the geom's body, which \
                 cannot move into it"
            )));
        }
        let local = geom.quat.inverse() * (site.pos - geom.pos);
        let off_axis = if geom.cylinder { local.xy().norm() } else { local.norm() };
        if off_axis < geom.radius {
            return Err(element.unsupported(format!(
                "{attribute} inside the geom: MuJoCo 4.0 then makes the tendon pass through the geom, which nudyn \
                 does not model"
            )));
        }
        Ok(index)
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
        let name = self.reference(element, attribute);
        if name == "world" {
            return Ok(None);
        }
        match self.body_names.contains_key(&name) {
            true => Ok(self.bodies.iter().position(|b| b.name == name)),
            false => Err(self.unknown(element, &format!("body '{name}' in sensor"), &name)),
        }
    }

    fn site(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        self.site_named(element, attribute, "sensor")
    }

    fn actuator(&self, element: &Element, attribute: &str) -> Result<usize, MjcfError> {
        let name = self.reference(element, attribute);
        match self.actuators.iter().position(|a| a.name.as_deref() == Some(&name)) {
            Some(index) => Ok(index),
            None => Err(self.unknown(element, &format!("actuator '{name}' in sensor"), &name)),
        }
    }

    fn name(&self, element: &Element, attribute: &str) -> String {
        self.reference(element, attribute)
    }

    fn own_name(&self, element: &Element) -> Option<String> {
        Reader::own_name(self, element)
    }
}
