//! `<replicate>` copies: the suffixes they give names, and the actuators and
//! sensors that name an element inside a replicate by its name as written
//! (without the copies' suffixes), which MuJoCo 4.0 copies with it.
//!
//! What MuJoCo 4.0 does, measured with its Python bindings: the replicates
//! are expanded innermost first, siblings in document order (each in the
//! order its end tag comes). Expanding one takes out of the list of
//! actuators (or sensors) every element that names something inside it by
//! the name it has there (the inner replicates' suffixes already on), and
//! appends the copies at the end of the list: copy 0 of each such element
//! in list order, then copy 1, and so on. A copy's own name and the names
//! it refers to inside the replicate get the copy's suffix. So `<motor
//! name="m" joint="j"/>` beside a `<replicate count="2" sep="_">` around
//! joint `j` becomes `m_0` on `j_0` and `m_1` on `j_1`, after the actuators
//! nothing copies. An actuator whose other references lie outside the
//! replicate is left out of MuJoCo's model without a word, and a sensor
//! naming objects of two replicates side by side is refused; nudyn refuses
//! both, saying so.

use std::collections::HashSet;

use super::Reader;
use crate::mjcf::element::{Element, Origin};
use crate::mjcf::error::MjcfError;

/// A `<replicate>` element: where it starts and ends in the text, its line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct ReplicateAt {
    start: usize,
    end: usize,
    line: u32,
}

impl ReplicateAt {
    /// Whether `inner` lies inside this replicate.
    fn contains(&self, inner: &ReplicateAt) -> bool {
        self.start < inner.start && inner.end < self.end
    }
}

/// One copy of a `<replicate>`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct ReplicateCopy {
    /// The replicate.
    pub replicate: ReplicateAt,
    /// The copy's suffix: `sep` and its number.
    pub suffix: String,
}

/// The `<replicate>` copies an element is in, innermost first, as MuJoCo
/// appends their suffixes to its name.
#[derive(Clone, Debug, Default)]
pub(super) struct Suffix(Vec<ReplicateCopy>);

impl Suffix {
    /// The suffixes, innermost first.
    pub fn text(&self) -> String {
        self.0.iter().map(|copy| copy.suffix.as_str()).collect()
    }

    /// This suffix inside copy `suffix` of the replicate `element`.
    pub fn within(&self, element: &Element, suffix: String) -> Suffix {
        let range = element.node.range();
        let replicate = ReplicateAt { start: range.start, end: range.end, line: element.line };
        let copy = ReplicateCopy { replicate, suffix };
        Suffix(std::iter::once(copy).chain(self.0.iter().cloned()).collect())
    }
}

/// The kinds of object an actuator or sensor names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) enum Named {
    Body,
    Joint,
    Geom,
    Site,
    Actuator,
}

/// An object an actuator or sensor names: the attribute, the kind of
/// object, its name.
pub(super) type Reference = (&'static str, Named, String);

/// A name given inside `<replicate>`s: as written, and the copies it is in.
pub(super) struct ReplicatedName {
    pub kind: Named,
    pub name: String,
    pub suffix: Suffix,
}

/// One copy of an actuator or sensor element to read.
#[derive(Clone, Debug)]
pub(super) struct ElementCopy {
    /// The element's place among its section's children.
    pub index: usize,
    /// The names its attributes refer to in this copy: attribute, kind, name.
    pub references: Vec<Reference>,
    /// The replicate copies it was made for, innermost first.
    pub suffix: Suffix,
}

impl Reader {
    /// The copies of a section's actuator or sensor `elements` in MuJoCo's
    /// order, each element given with the objects it names (attribute,
    /// kind, name as written). `actuators`: an element some of whose
    /// references lie outside a replicate it is copied with is refused
    /// (MuJoCo drops the actuator).
    pub(super) fn copies(
        &self,
        elements: &[(&Origin, Vec<Reference>)],
        actuators: bool,
    ) -> Result<Vec<ElementCopy>, MjcfError> {
        let mut list: Vec<ElementCopy> = elements
            .iter()
            .enumerate()
            .map(|(index, (_, references))| ElementCopy {
                index,
                references: references.clone(),
                suffix: Suffix::default(),
            })
            .collect();
        for replicate in self.replicates() {
            let (scope, copies) = self.replicate_contents(replicate);
            let in_scope = |kind: Named, name: &str| scope.contains(&(kind, name.to_string()));
            let (copied, kept): (Vec<ElementCopy>, Vec<ElementCopy>) =
                list.into_iter().partition(|copy| copy.references.iter().any(|(_, kind, name)| in_scope(*kind, name)));
            for copy in &copied {
                let element = elements[copy.index].0;
                let outside = copy.references.iter().find(|(_, kind, name)| !in_scope(*kind, name));
                if let (true, Some((attribute, _, name))) = (actuators, outside) {
                    return Err(element.unsupported(format!(
                        "{attribute} '{name}' lies outside the <replicate> (line {}) whose copies the actuator's \
                         other targets are in: MuJoCo 4.0 leaves such an actuator out of the model; name the \
                         copies instead",
                        replicate.line
                    )));
                }
                if let Some(previous) = copy.suffix.0.last().filter(|previous| !replicate.contains(&previous.replicate))
                {
                    return Err(element.invalid(format!(
                        "it names objects inside two <replicate>s side by side (lines {} and {}), which MuJoCo \
                         4.0 refuses; name the copies instead",
                        previous.replicate.line, replicate.line
                    )));
                }
            }
            list = kept;
            for suffix in &copies {
                for copy in &copied {
                    let mut copy = copy.clone();
                    for (_, kind, name) in &mut copy.references {
                        if in_scope(*kind, name) {
                            name.push_str(suffix);
                        }
                    }
                    copy.suffix.0.push(ReplicateCopy { replicate, suffix: suffix.clone() });
                    list.push(copy);
                }
            }
        }
        Ok(list)
    }

    /// The replicates that have named elements, innermost first, siblings in
    /// document order: ordered by where they end.
    fn replicates(&self) -> Vec<ReplicateAt> {
        let mut replicates: Vec<ReplicateAt> =
            self.replicated_names.iter().flat_map(|name| name.suffix.0.iter().map(|copy| copy.replicate)).collect();
        replicates.sort_by_key(|replicate| replicate.end);
        replicates.dedup();
        replicates
    }

    /// The names inside `replicate` as they are there (the suffixes of the
    /// replicates inside it on), and its copies' suffixes in order.
    fn replicate_contents(&self, replicate: ReplicateAt) -> (HashSet<(Named, String)>, Vec<String>) {
        let mut scope = HashSet::new();
        let mut copies: Vec<String> = Vec::new();
        for named in &self.replicated_names {
            let Some(level) = named.suffix.0.iter().position(|copy| copy.replicate == replicate) else { continue };
            let inner: String = named.suffix.0[..level].iter().map(|copy| copy.suffix.as_str()).collect();
            scope.insert((named.kind, format!("{}{inner}", named.name)));
            let suffix = &named.suffix.0[level].suffix;
            if !copies.contains(suffix) {
                copies.push(suffix.clone());
            }
        }
        (scope, copies)
    }

    /// The name an attribute gives as `written`, in the copy being compiled.
    pub(super) fn reference(&self, attribute: &str, written: &str) -> String {
        let copied = self.copy.as_ref().and_then(|copy| copy.references.iter().find(|(a, _, _)| *a == attribute));
        match copied {
            Some((_, _, name)) => name.clone(),
            None => written.to_string(),
        }
    }

    /// An element's own name as `written`, with the suffix of the copy being compiled.
    pub(super) fn own_name(&self, written: Option<&str>) -> Option<String> {
        let suffix = self.copy.as_ref().map(|copy| copy.suffix.text()).unwrap_or_default();
        written.map(|name| format!("{name}{suffix}"))
    }
}
