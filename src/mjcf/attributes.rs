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
    for attribute in table {
        if let Read::Into(read) = attribute.read
            && element.has(attribute.name)
        {
            read(settings, element, attribute.name)?;
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
    use crate::mjcf::defaults::{JOINT_ATTRIBUTES, JointSettings};
    use crate::mjcf::element::LineStarts;

    /// The settings a `<joint>` with `attribute="value"` reads, or its error.
    fn joint_with(attribute: &str, value: &str) -> Result<JointSettings, MjcfError> {
        let xml = format!("<joint {attribute}=\"{value}\"/>");
        let document = roxmltree::Document::parse(&xml).unwrap();
        let lines = LineStarts::new(&xml);
        let mut settings = JointSettings::default();
        settings.apply(&Element::new(document.root_element(), &lines))?;
        Ok(settings)
    }

    /// Each attribute the joint table reads into the settings changes them
    /// for some valid value: no entry reads into nothing.
    #[test]
    fn every_joint_attribute_read_into_the_settings_changes_them() {
        let default = format!("{:?}", JointSettings::default());
        let values = ["0.5", "0.5 0.5", "0.5 0.5 0.5", "slide", "true", "false"];
        for attribute in JOINT_ATTRIBUTES.iter().filter(|a| matches!(a.read, Read::Into(_))) {
            let changes = values.iter().any(|value| {
                joint_with(attribute.name, value).is_ok_and(|settings| format!("{settings:?}") != default)
            });
            assert!(changes, "<joint {}>: no value changes the settings", attribute.name);
        }
    }

    #[test]
    fn joint_attributes_are_checked_as_read() {
        let error = joint_with("stiffness", "-1").unwrap_err().to_string();
        assert!(error.contains("stiffness") && error.contains("non-negative first coefficient"), "{error}");
        let error = joint_with("armature", "-1").unwrap_err().to_string();
        assert!(error.contains("armature") && error.contains("non-negative"), "{error}");
        let error = joint_with("limited", "maybe").unwrap_err().to_string();
        assert!(error.contains("limited"), "{error}");
    }
}
