//! Reading one XML element: its attributes as typed values, and errors that
//! name the element and its line.

use roxmltree::Node;

use super::MjcfWarning;
use super::error::MjcfError;

/// Where each line of the document starts, for line numbers in O(log n).
/// roxmltree's `text_pos_at` counts lines from the start of the text on
/// every call, which made reading deeply nested files quadratic (a
/// 2000-link chain, 16 MB of indentation, took 4 s).
pub(crate) struct LineStarts(Vec<usize>);

impl LineStarts {
    /// Indexes `text`.
    pub fn new(text: &str) -> Self {
        Self(std::iter::once(0).chain(text.match_indices('\n').map(|(at, _)| at + 1)).collect())
    }

    /// The 1-based line holding byte `offset`.
    pub fn line_of(&self, offset: usize) -> u32 {
        u32::try_from(self.0.partition_point(|&start| start <= offset)).unwrap_or(u32::MAX)
    }
}

/// An element being read, with what error messages say about it.
#[derive(Clone, Copy)]
pub(crate) struct Element<'a, 'input> {
    /// The XML node.
    pub node: Node<'a, 'input>,
    /// 1-based line of the start tag.
    pub line: u32,
    /// The document's line index, for the children's lines.
    lines: &'a LineStarts,
}

impl<'a, 'input> Element<'a, 'input> {
    /// Wraps an element node of the document that `lines` indexes.
    pub fn new(node: Node<'a, 'input>, lines: &'a LineStarts) -> Self {
        Self { node, line: lines.line_of(node.range().start), lines }
    }

    /// The tag name.
    pub fn tag(&self) -> &'a str {
        self.node.tag_name().name()
    }

    /// The element as messages show it: the tag, plus the name when given.
    pub fn label(&self) -> String {
        match self.node.attribute("name") {
            Some(name) => format!("{} name=\"{name}\"", self.tag()),
            None => self.tag().to_string(),
        }
    }

    /// The child elements, skipping text and comments.
    pub fn children(&self) -> impl Iterator<Item = Element<'a, 'input>> + use<'a, 'input> {
        let lines = self.lines;
        self.node.children().filter(Node::is_element).map(move |node| Element::new(node, lines))
    }

    /// Rejects any attribute not in `allowed`.
    pub fn check_attributes(&self, allowed: &[&str]) -> Result<(), MjcfError> {
        match self.node.attributes().find(|a| !allowed.contains(&a.name())) {
            Some(unknown) => Err(MjcfError::UnknownAttribute {
                line: self.line,
                element: self.label(),
                attribute: unknown.name().to_string(),
            }),
            None => Ok(()),
        }
    }

    /// Whether the attribute is present.
    pub fn has(&self, attribute: &str) -> bool {
        self.node.has_attribute(attribute)
    }

    /// The attribute's raw text.
    pub fn text(&self, attribute: &str) -> Option<&'a str> {
        self.node.attribute(attribute)
    }

    /// Exactly `N` finite numbers.
    pub fn numbers<const N: usize>(&self, attribute: &str) -> Result<Option<[f64; N]>, MjcfError> {
        let Some(values) = self.number_list(attribute, N, N)? else {
            return Ok(None);
        };
        let mut out = [0.0; N];
        out.copy_from_slice(&values);
        Ok(Some(out))
    }

    /// Between 1 and `N` finite numbers, written over the first entries of
    /// `target` (MuJoCo's rule for `size`, `stiffness` and `damping`: the
    /// entries not given keep their value from the default class).
    pub fn overwrite_numbers<const N: usize>(&self, attribute: &str, target: &mut [f64; N]) -> Result<(), MjcfError> {
        if let Some(values) = self.number_list(attribute, 1, N)? {
            target[..values.len()].copy_from_slice(&values);
        }
        Ok(())
    }

    /// One finite number.
    pub fn number(&self, attribute: &str) -> Result<Option<f64>, MjcfError> {
        Ok(self.numbers::<1>(attribute)?.map(|[x]| x))
    }

    /// One finite number that is not negative.
    pub fn non_negative(&self, attribute: &str) -> Result<Option<f64>, MjcfError> {
        match self.number(attribute)? {
            Some(x) if x < 0.0 => Err(self.bad_value(attribute, "a non-negative number")),
            x => Ok(x),
        }
    }

    /// `N` finite numbers, none negative.
    pub fn non_negative_numbers<const N: usize>(&self, attribute: &str) -> Result<Option<[f64; N]>, MjcfError> {
        match self.numbers::<N>(attribute)? {
            Some(values) if values.iter().any(|&x| x < 0.0) => {
                Err(self.bad_value(attribute, &format!("{N} non-negative numbers")))
            }
            values => Ok(values),
        }
    }

    /// `N` integers.
    pub fn integers<const N: usize>(&self, attribute: &str) -> Result<Option<[i32; N]>, MjcfError> {
        let Some(text) = self.text(attribute) else {
            return Ok(None);
        };
        let expected = if N == 1 { "an integer".to_string() } else { format!("{N} integers") };
        let values: Vec<i32> = text
            .split_ascii_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| self.bad_value(attribute, &expected))?;
        let values: [i32; N] = values.try_into().map_err(|_| self.bad_value(attribute, &expected))?;
        Ok(Some(values))
    }

    /// Any number of integers.
    pub fn integer_list(&self, attribute: &str) -> Result<Option<Vec<i32>>, MjcfError> {
        let Some(text) = self.text(attribute) else {
            return Ok(None);
        };
        let values = text.split_ascii_whitespace().map(str::parse).collect::<Result<_, _>>();
        values.map(Some).map_err(|_| self.bad_value(attribute, "integers"))
    }

    /// One of the keywords in `choices`.
    pub fn keyword<T: Copy>(&self, attribute: &str, choices: &[(&str, T)]) -> Result<Option<T>, MjcfError> {
        let Some(text) = self.text(attribute) else {
            return Ok(None);
        };
        match choices.iter().find(|(word, _)| *word == text) {
            Some(&(_, value)) => Ok(Some(value)),
            None => {
                let words: Vec<&str> = choices.iter().map(|(word, _)| *word).collect();
                Err(self.bad_value(attribute, &format!("one of {}", words.join(", "))))
            }
        }
    }

    /// "true" or "false".
    pub fn boolean(&self, attribute: &str) -> Result<Option<bool>, MjcfError> {
        self.keyword(attribute, &[("false", false), ("true", true)])
    }

    /// Reads `min..=max` finite numbers.
    fn number_list(&self, attribute: &str, min: usize, max: usize) -> Result<Option<Vec<f64>>, MjcfError> {
        let Some(text) = self.text(attribute) else {
            return Ok(None);
        };
        let count = match (min, max) {
            (1, 1) => "a number".to_string(),
            (min, max) if min == max => format!("{max} numbers"),
            (min, max) => format!("{min} to {max} numbers"),
        };
        let values: Vec<f64> = text
            .split_ascii_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| self.bad_value(attribute, &count))?;
        if values.len() < min || values.len() > max {
            return Err(self.bad_value(attribute, &count));
        }
        if values.iter().any(|x| !x.is_finite()) {
            let finite = if max == 1 { "a finite number" } else { "finite numbers" };
            return Err(self.bad_value(attribute, finite));
        }
        Ok(Some(values))
    }

    /// The attribute's value is not what `expected` describes.
    pub fn bad_value(&self, attribute: &str, expected: &str) -> MjcfError {
        MjcfError::BadValue {
            line: self.line,
            element: self.label(),
            attribute: attribute.to_string(),
            expected: expected.to_string(),
            found: self.text(attribute).unwrap_or_default().to_string(),
        }
    }

    /// Where the element stands, for messages once the document is gone.
    pub fn origin(&self) -> Origin {
        let parent = self.node.parent_element().map_or("", |p| p.tag_name().name());
        Origin { line: self.line, tag: self.tag().to_string(), label: self.label(), parent: parent.to_string() }
    }

    /// A required attribute is absent.
    pub fn missing(&self, attribute: &str) -> MjcfError {
        self.origin().missing(attribute)
    }

    /// Two attributes given together that exclude each other.
    pub fn conflict(&self, first: &str, second: &str) -> MjcfError {
        self.origin().conflict(first, second)
    }

    /// A construct whose effect on the dynamics nudyn does not model.
    pub fn unsupported(&self, reason: impl Into<String>) -> MjcfError {
        self.origin().unsupported(reason)
    }

    /// A rule of MuJoCo's compiler is broken.
    pub fn invalid(&self, reason: impl Into<String>) -> MjcfError {
        self.origin().invalid(reason)
    }

    /// This element has no meaning inside its parent.
    pub fn unknown(&self) -> MjcfError {
        self.origin().unknown()
    }

    /// This element appears a second time where it may appear once.
    pub fn repeated(&self, first: &Element) -> MjcfError {
        let parent = self.node.parent_element().map_or("", |p| p.tag_name().name());
        MjcfError::Repeated {
            line: self.line,
            element: self.label(),
            parent: parent.to_string(),
            first_line: first.line,
        }
    }

    /// A `class` or `childclass` naming no default class.
    pub fn unknown_class(&self, class: &str) -> MjcfError {
        MjcfError::UnknownClass { line: self.line, element: self.label(), class: class.to_string() }
    }

    /// The warning that this element is ignored (see [`Origin::ignored`]).
    pub fn ignored(&self) -> MjcfWarning {
        self.origin().ignored()
    }

    /// A warning about this element.
    pub fn warning(&self, message: impl Into<String>) -> MjcfWarning {
        self.origin().warning(message)
    }
}

/// Where an element stands in the document: what the messages of the
/// compile stage say of it, kept in the spec instead of the XML node so
/// that the spec outlives the document.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Origin {
    /// 1-based line of the start tag (in the merged text).
    pub line: u32,
    /// The tag name.
    pub tag: String,
    /// The element as messages show it: the tag, plus the name when given.
    pub label: String,
    /// The parent element's tag.
    pub parent: String,
}

impl Origin {
    /// A required attribute is absent.
    pub fn missing(&self, attribute: &str) -> MjcfError {
        MjcfError::MissingAttribute { line: self.line, element: self.label.clone(), attribute: attribute.to_string() }
    }

    /// A construct whose effect on the dynamics nudyn does not model.
    pub fn unsupported(&self, reason: impl Into<String>) -> MjcfError {
        MjcfError::Unsupported { line: self.line, element: self.label.clone(), reason: reason.into() }
    }

    /// A rule of MuJoCo's compiler is broken.
    pub fn invalid(&self, reason: impl Into<String>) -> MjcfError {
        MjcfError::Invalid { line: self.line, element: self.label.clone(), reason: reason.into() }
    }

    /// This element has no meaning inside its parent.
    pub fn unknown(&self) -> MjcfError {
        MjcfError::UnknownElement { line: self.line, element: self.label.clone(), parent: self.parent.clone() }
    }

    /// Two attributes given together that exclude each other.
    pub fn conflict(&self, first: &str, second: &str) -> MjcfError {
        MjcfError::ConflictingAttributes {
            line: self.line,
            element: self.label.clone(),
            first: first.to_string(),
            second: second.to_string(),
        }
    }

    /// The warning that this element is ignored. Sections that do change
    /// MuJoCo's dynamics say how nudyn's differ.
    pub fn ignored(&self) -> MjcfWarning {
        match self.tag.as_str() {
            "contact" => self.warning("ignored: nudyn models no contacts"),
            // Only geoms fixed to the world are ignored (a moving body's give its mass).
            "geom" => self.warning(
                "ignored: fixed to the world, it moves no mass, and nudyn models no contacts \
                 (MuJoCo would make contacts with it)",
            ),
            _ => self.warning("ignored (no effect on the dynamics)"),
        }
    }

    /// A warning about this element.
    pub fn warning(&self, message: impl Into<String>) -> MjcfWarning {
        MjcfWarning { file: None, line: self.line, element: self.label.clone(), message: message.into() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every element's line agrees with roxmltree's own (slow) count,
    /// with blank lines, CRLF endings, several tags on one line and a
    /// tag at the very start.
    #[test]
    fn line_starts_agree_with_roxmltree() {
        let xml = "<mujoco>\r\n\r\n  <worldbody><body name=\"a\">\n\n\n    <body/>\n  </body></worldbody>\n<!-- end -->\n<option/></mujoco>";
        let document = roxmltree::Document::parse(xml).unwrap();
        let lines = LineStarts::new(xml);
        let mut checked = 0;
        for node in document.descendants().filter(Node::is_element) {
            assert_eq!(
                Element::new(node, &lines).line,
                document.text_pos_at(node.range().start).row,
                "{:?}",
                node.tag_name()
            );
            checked += 1;
        }
        assert_eq!(checked, 5);
    }
}
