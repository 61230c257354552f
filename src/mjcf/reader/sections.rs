//! The sections besides `<worldbody>` and the settings: assets read;
//! tendons, equalities, actuators, sensors and keyframes parsed into specs
//! for the compile stage (`compile/sections.rs`).

use super::{Reader, no_children};
use crate::mjcf::actuator::ActuatorSpec;
use crate::mjcf::attributes::names;
use crate::mjcf::defaults::MAIN;
use crate::mjcf::element::Element;
use crate::mjcf::equality::EqualitySpec;
use crate::mjcf::error::MjcfError;
use crate::mjcf::keyframe::{self, KeySpec};
use crate::mjcf::mesh::MESH_ATTRIBUTES;
use crate::mjcf::sensor::SensorSpec;
use crate::mjcf::tendon::TendonSpec;
use crate::mjcf::{actuator, equality, mesh, sensor, tendon};
use crate::vehicle::SensorKind;

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

    /// The `<key>`s of a `<keyframe>` section, into specs.
    pub(super) fn parse_keyframes(&self, section: &Element, specs: &mut Vec<KeySpec>) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        for key in section.children() {
            specs.push(keyframe::parse(&key)?);
        }
        Ok(())
    }

    /// The `<equality>` section into specs.
    pub(super) fn parse_equalities(&self, section: &Element, specs: &mut Vec<EqualitySpec>) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        for element in section.children() {
            let settings = self.defaults.class(self.class_of(&element, MAIN)?).equality.clone();
            specs.push(equality::parse(&element, settings)?);
        }
        Ok(())
    }

    /// The `<tendon>` section into specs: each `<fixed>` or `<spatial>`.
    pub(super) fn parse_tendons(&self, section: &Element, specs: &mut Vec<TendonSpec>) -> Result<(), MjcfError> {
        section.check_attributes(&[])?;
        for element in section.children() {
            let settings = self.defaults.class(self.class_of(&element, MAIN)?).tendon.clone();
            specs.push(tendon::parse(&element, settings, self.compiler.autolimits)?);
        }
        Ok(())
    }

    /// The `<sensor>` section into specs, refusing the types nudyn does not compute.
    pub(super) fn parse_sensors(&self, section: &Element) -> Result<Vec<SensorSpec>, MjcfError> {
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
        children.iter().zip(kinds).map(|(child, kind)| sensor::parse(child, kind)).collect()
    }

    /// The `<actuator>` section into specs, refusing what nudyn does not model.
    pub(super) fn parse_actuators(&self, section: &Element) -> Result<Vec<ActuatorSpec>, MjcfError> {
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
        let mut specs = Vec::with_capacity(children.len());
        for (child, kind) in children.iter().zip(kinds) {
            child.check_attributes(&actuator::attributes(kind, false))?;
            no_children(child)?;
            let class = self.defaults.lookup(child, "class")?.unwrap_or(MAIN);
            let mut settings = self.defaults.class(class).actuator.clone();
            settings.apply(kind, child, self.defaults.lender(class, kind))?;
            specs.push(actuator::parse(child, kind, settings)?);
        }
        Ok(specs)
    }
}
