//! Attribute tables: for an element, every attribute it takes and how it
//! is read, in one table that is at once the reader, the allow-list
//! (an attribute not in it is refused as unknown) and the list
//! docs/mjcf-support.md renders, as MuJoCo's XML reader reads an element
//! from the table that is also its schema (`ReadAttrTable`).

use super::element::Element;
use super::error::MjcfError;

/// One attribute of an element whose settings are an `S`.
pub(crate) struct Attribute<S: 'static> {
    /// The attribute's name.
    pub name: &'static str,
    /// How it is read.
    pub read: Read<S>,
}

/// How an attribute is read.
pub(crate) enum Read<S: 'static> {
    /// Into the settings, by a function given the element and the name.
    Into(fn(&mut S, &Element, &'static str) -> Result<(), MjcfError>),
    /// For its syntax only, as MuJoCo checks it, without effect on what
    /// nudyn computes (contact and fluid parameters, colours).
    Checked(fn(&Element, &'static str) -> Result<(), MjcfError>),
    /// By the reader itself, not into the settings (a name, a class).
    ByReader,
    /// Accepted without effect on what nudyn computes (rendering, user data).
    NoEffect,
}

impl<S> Attribute<S> {
    /// An attribute read into the settings by `read`.
    pub const fn into(name: &'static str, read: fn(&mut S, &Element, &'static str) -> Result<(), MjcfError>) -> Self {
        Attribute { name, read: Read::Into(read) }
    }

    /// An attribute checked for its syntax only.
    pub const fn checked(name: &'static str, check: fn(&Element, &'static str) -> Result<(), MjcfError>) -> Self {
        Attribute { name, read: Read::Checked(check) }
    }

    /// An attribute the reader reads itself.
    pub const fn by_reader(name: &'static str) -> Self {
        Attribute { name, read: Read::ByReader }
    }

    /// An attribute accepted without effect.
    pub const fn no_effect(name: &'static str) -> Self {
        Attribute { name, read: Read::NoEffect }
    }
}

/// The names of a table's attributes, in its order.
pub(crate) fn names<S>(table: &[Attribute<S>]) -> Vec<&'static str> {
    table.iter().map(|attribute| attribute.name).collect()
}

/// Overwrites `settings` with the attributes of `table` that `element`
/// gives, in the table's order.
pub(crate) fn read_into<S>(table: &[Attribute<S>], settings: &mut S, element: &Element) -> Result<(), MjcfError> {
    for attribute in table.iter().filter(|attribute| element.has(attribute.name)) {
        match attribute.read {
            Read::Into(read) => read(settings, element, attribute.name)?,
            Read::Checked(check) => check(element, attribute.name)?,
            Read::ByReader | Read::NoEffect => {}
        }
    }
    Ok(())
}

/// `target` = the attribute's value when the element gives one (`value`
/// reads it), for the tables' entries.
pub(crate) fn set<T>(target: &mut T, value: Option<T>) -> Result<(), MjcfError> {
    if let Some(value) = value {
        *target = value;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mjcf::bodies::{
        BODY_ATTRIBUTES, FRAME_ATTRIBUTES, FREEJOINT_ATTRIBUTES, INERTIAL_ATTRIBUTES, REPLICATE_ATTRIBUTES,
    };
    use crate::mjcf::defaults::{GEOM_ATTRIBUTES, JOINT_ATTRIBUTES, SITE_ATTRIBUTES};
    use crate::mjcf::element::LineStarts;
    use crate::mjcf::equality::COMMON_ATTRIBUTES as EQUALITY_ATTRIBUTES;
    use crate::mjcf::mesh::MESH_ATTRIBUTES;
    use crate::mjcf::reader::{COMPILER_ATTRIBUTES, FLAG_ATTRIBUTES, OPTION_ATTRIBUTES};
    use crate::mjcf::tendon::{PATH_ELEMENTS, TENDON_ATTRIBUTES};

    /// The settings an element `<tag attribute="value"/>` reads with `table`, or its error.
    fn read<S: Default>(table: &[Attribute<S>], attribute: &str, value: &str) -> Result<S, MjcfError> {
        let xml = format!("<element {attribute}=\"{value}\"/>");
        let document = roxmltree::Document::parse(&xml).unwrap();
        let lines = LineStarts::new(&xml);
        let mut settings = S::default();
        read_into(table, &mut settings, &Element::new(document.root_element(), &lines))?;
        Ok(settings)
    }

    /// Each attribute a table reads into the settings changes them for some
    /// valid value: no entry reads into nothing.
    fn every_entry_changes_the_settings<S: Default + std::fmt::Debug>(tag: &str, table: &[Attribute<S>]) {
        let default = format!("{:?}", S::default());
        let values = [
            "0.5",
            "3",
            "5",
            "convex",
            "0.5 0.5",
            "0.5 0.5 0.5",
            "0.5 0.5 0.5 0.5",
            "0 0 0 0 0 1",
            "slide",
            "box",
            "true",
            "false",
            "radian",
            "zyx",
            "enable",
            "disable",
            "1 2",
            "never",
            "affine",
            "integrator",
        ];
        for attribute in table.iter().filter(|a| matches!(a.read, Read::Into(_))) {
            let changes = values.iter().any(|value| {
                read(table, attribute.name, value).is_ok_and(|settings| format!("{settings:?}") != default)
            });
            assert!(changes, "<{tag} {}>: no value changes the settings", attribute.name);
        }
    }

    #[test]
    fn every_attribute_read_into_the_settings_changes_them() {
        every_entry_changes_the_settings("body", BODY_ATTRIBUTES);
        every_entry_changes_the_settings("frame", FRAME_ATTRIBUTES);
        every_entry_changes_the_settings("replicate", REPLICATE_ATTRIBUTES);
        every_entry_changes_the_settings("inertial", INERTIAL_ATTRIBUTES);
        every_entry_changes_the_settings("freejoint", FREEJOINT_ATTRIBUTES);
        every_entry_changes_the_settings("joint", JOINT_ATTRIBUTES);
        every_entry_changes_the_settings("geom", GEOM_ATTRIBUTES);
        every_entry_changes_the_settings("site", SITE_ATTRIBUTES);
        every_entry_changes_the_settings("mesh", MESH_ATTRIBUTES);
        every_entry_changes_the_settings("tendon", TENDON_ATTRIBUTES);
        every_entry_changes_the_settings("equality", EQUALITY_ATTRIBUTES);
        for (tag, table) in crate::mjcf::equality::EQUALITY_ATTRIBUTES {
            every_entry_changes_the_settings(tag, table);
        }
        every_entry_changes_the_settings("sensor", crate::mjcf::sensor::COMMON_ATTRIBUTES);
        every_entry_changes_the_settings("actuator", crate::mjcf::actuator::COMMON_ATTRIBUTES);
        for (tag, kind) in crate::mjcf::actuator::ACTUATOR_KINDS {
            every_entry_changes_the_settings(tag, crate::mjcf::actuator::own_attributes(*kind));
        }
        every_entry_changes_the_settings("compiler", COMPILER_ATTRIBUTES);
        every_entry_changes_the_settings("option", OPTION_ATTRIBUTES);
        every_entry_changes_the_settings("flag", FLAG_ATTRIBUTES);
        for (path, table) in PATH_ELEMENTS {
            every_entry_changes_the_settings(path, table);
        }
    }

    /// What a table only checks is still checked: a malformed value is refused.
    fn checked_entries_refuse_malformed_values<S: Default>(tag: &str, table: &[Attribute<S>]) {
        let checked = table.iter().filter(|a| matches!(a.read, Read::Checked(_)));
        for attribute in checked {
            assert!(read(table, attribute.name, "x").is_err(), "<{tag} {}=\"x\"> was accepted", attribute.name);
        }
    }

    #[test]
    fn attributes_checked_for_their_syntax_refuse_malformed_values() {
        checked_entries_refuse_malformed_values("body", BODY_ATTRIBUTES);
        checked_entries_refuse_malformed_values("geom", GEOM_ATTRIBUTES);
        checked_entries_refuse_malformed_values("site", SITE_ATTRIBUTES);
        checked_entries_refuse_malformed_values("option", OPTION_ATTRIBUTES);
        checked_entries_refuse_malformed_values("sensor", crate::mjcf::sensor::COMMON_ATTRIBUTES);
        checked_entries_refuse_malformed_values("actuator", crate::mjcf::actuator::COMMON_ATTRIBUTES);
        checked_entries_refuse_malformed_values("general", crate::mjcf::actuator::GENERAL_ATTRIBUTES);
        checked_entries_refuse_malformed_values("flag", FLAG_ATTRIBUTES);
    }

    #[test]
    fn joint_attributes_are_checked_as_read() {
        let error = read(JOINT_ATTRIBUTES, "stiffness", "-1").unwrap_err().to_string();
        assert!(error.contains("stiffness") && error.contains("non-negative first coefficient"), "{error}");
        let error = read(JOINT_ATTRIBUTES, "armature", "-1").unwrap_err().to_string();
        assert!(error.contains("armature") && error.contains("non-negative"), "{error}");
        let error = read(JOINT_ATTRIBUTES, "limited", "maybe").unwrap_err().to_string();
        assert!(error.contains("limited"), "{error}");
    }
}
