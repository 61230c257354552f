//! `<custom><text name="nudyn:modal:BODY" data="FILE"/>`: the modal data
//! file that makes BODY flexible (docs/flexible.md). MuJoCo keeps the text
//! and ignores it, so the same MJCF file is the rigid vehicle there.

use super::Reader;
use crate::flex::{ModalBody, modal_file};
use crate::mjcf::element::Element;
use crate::mjcf::error::MjcfError;

/// The prefix of a `<text>` name that makes the body after it flexible.
pub(crate) const MODAL_PREFIX: &str = "nudyn:modal:";

/// A `nudyn:modal:` text as read, resolved once the bodies are known.
#[derive(Debug)]
pub(super) struct ModalText {
    pub(super) body: String,
    data: String,
    line: u32,
    element: String,
}

impl Reader {
    /// A `<custom>` section: its `nudyn:modal:` texts are kept; a section
    /// with anything else, or nothing, is ignored with one warning, as before.
    pub(super) fn read_custom(&mut self, section: &Element) -> Result<(), MjcfError> {
        let mut ignored = section.children().next().is_none();
        for child in section.children() {
            let name = child.text("name").unwrap_or_default();
            match (child.tag(), name.strip_prefix(MODAL_PREFIX)) {
                ("text", Some(body)) => {
                    let data = child.text("data").ok_or_else(|| child.missing("data"))?;
                    // fusestatic must keep the body whole.
                    self.named_elsewhere.push(body.to_string());
                    let element = child.label();
                    self.modal_texts.push(ModalText {
                        body: body.to_string(),
                        data: data.to_string(),
                        line: child.line,
                        element,
                    });
                }
                _ => ignored = true,
            }
        }
        if ignored {
            self.warnings.push(section.ignored());
        }
        Ok(())
    }

    /// The modal bodies the texts name, each file read, checked and held
    /// to its body's inertial; in body order.
    pub(super) fn modal_bodies(&mut self) -> Result<Vec<ModalBody>, MjcfError> {
        let mut found: Vec<(usize, ModalBody)> = Vec::new();
        for text in std::mem::take(&mut self.modal_texts) {
            let invalid =
                |reason: String| MjcfError::Invalid { line: text.line, element: text.element.clone(), reason };
            let Some(index) = self.bodies.iter().position(|b| b.name == text.body) else {
                return Err(invalid(format!("there is no body named '{}' to make flexible", text.body)));
            };
            if found.iter().any(|(k, _)| *k == index) {
                return Err(invalid(format!("body '{}' is made flexible by an earlier text already", text.body)));
            }
            let path = self.sources.asset_path("", &text.data, text.line);
            let modal = modal_file::read(&path, &text.body).map_err(|e| invalid(e.to_string()))?;
            modal.check_mass_properties(self.bodies[index].inertia.as_ref()).map_err(|e| invalid(e.to_string()))?;
            found.push((index, modal));
        }
        found.sort_by_key(|(index, _)| *index);
        Ok(found.into_iter().map(|(_, modal)| modal).collect())
    }
}
