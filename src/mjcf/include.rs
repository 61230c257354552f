//! `<include file="...">`: the files a model includes, merged into one text
//! as MuJoCo merges them into one document before reading it, and the map
//! from a line of that text back to its file and line.
//!
//! MuJoCo 4.0's rules (XML reference, `include`; `IncludeXML` in its
//! `xml.cc`): an `<include>` has a `file` attribute and no children; the
//! file is looked for relative to the directory of the main model file,
//! and, for an include inside an included file that is not found there,
//! relative to that file's directory; its root element (of any name) is
//! dropped and the elements below it take the `<include>`'s place, wherever
//! it stands; at least one element must come in; a file is included at most
//! once in the whole model, so an include cycle is refused too.
//! Backslashes in the file name are separators, as MuJoCo reads them on
//! every system.
//!
//! The merged text places every included piece on lines of its own, so
//! that each line of it comes from one file: an error or warning found in
//! the merged text is then reported with the file and line it comes from.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use roxmltree::{Document, Node};

use super::MjcfWarning;
use super::element::{Element, LineStarts};
use super::error::MjcfError;

/// Lines of the merged text that come from one file, from `first` on.
#[derive(Clone, Debug)]
struct Piece {
    /// 1-based line of the merged text where the piece starts.
    first: u32,
    /// Index of the file in [`Sources::files`].
    file: usize,
    /// The line of `first` in that file.
    line: u32,
}

/// The files a model is read from and where each line of the merged text
/// comes from.
#[derive(Clone, Debug)]
pub(crate) struct Sources {
    /// The model's directory, where include and asset paths start.
    model_dir: PathBuf,
    /// The main file (`None` for a document given as text), then the
    /// included files in the order they are included.
    files: Vec<Option<PathBuf>>,
    /// Sorted by `first`.
    pieces: Vec<Piece>,
}

/// The model's text with every include merged in, and where its lines come from.
pub(crate) struct Assembled<'a> {
    /// The merged text (the document itself when it includes nothing).
    pub text: Cow<'a, str>,
    /// Where its lines come from.
    pub sources: Sources,
}

impl Sources {
    /// The file and the line in it of line `line` of the merged text.
    fn locate(&self, line: u32) -> (usize, u32) {
        let at = self.pieces.partition_point(|p| p.first <= line).saturating_sub(1);
        match self.pieces.get(at) {
            Some(piece) => (piece.file, piece.line + (line - piece.first.min(line))),
            None => (0, line),
        }
    }

    /// The line, in its own file, of line `line` of the merged text.
    pub fn line_in_file(&self, line: u32) -> u32 {
        self.locate(line).1
    }

    /// Where MuJoCo reads the asset file `file` named on line `line` of the
    /// merged text: `file` itself when absolute; else in `dir` (the
    /// compiler's `meshdir`, or its `assetdir`) below the model's directory
    /// when it is there; else, for an element of an included file, beside
    /// that file (MuJoCo 4.0's `ResolveFilePath`); backslashes are separators.
    pub fn asset_path(&self, dir: &str, file: &str, line: u32) -> PathBuf {
        let file = &with_slashes(file);
        let in_dir = self.model_dir.join(with_slashes(dir)).join(file);
        if Path::new(file).is_absolute() || in_dir.is_file() {
            return in_dir;
        }
        let included = match self.locate(line).0 {
            0 => None,
            index => self.files[index].as_deref().and_then(Path::parent),
        };
        included.map_or(in_dir, |beside| beside.join(file))
    }

    /// The path of file `file` when it is an included one; `None` for the
    /// main file.
    fn included_file(&self, file: usize) -> Option<PathBuf> {
        if file == 0 { None } else { self.files[file].clone() }
    }

    /// A warning found in the merged text, with its file and line.
    pub fn place_warning(&self, mut warning: MjcfWarning) -> MjcfWarning {
        let (file, line) = self.locate(warning.line);
        warning.line = line;
        warning.file = self.included_file(file);
        warning
    }

    /// An error found in the merged text, with the line in its own file, and
    /// wrapped in [`MjcfError::Included`] when that file is an included one.
    pub fn place_error(&self, mut error: MjcfError) -> MjcfError {
        let Some(line) = error.line_mut() else { return error };
        let (file, in_file) = self.locate(*line);
        *line = in_file;
        // A name used first in another file: say which.
        let first = match &mut error {
            MjcfError::DuplicateName { first_line, .. } | MjcfError::Repeated { first_line, .. } => Some(first_line),
            _ => None,
        };
        if let Some(first_line) = first {
            let (first_file, first_in_file) = self.locate(*first_line);
            *first_line = first_in_file;
            if first_file != file
                && let MjcfError::DuplicateName { line, element, kind, name, first_line } = &error
            {
                let place = match &self.files[first_file] {
                    Some(path) => format!("line {first_line} of {}", path.display()),
                    None => format!("line {first_line} of the main document"),
                };
                error = MjcfError::Invalid {
                    line: *line,
                    element: element.clone(),
                    reason: format!("{kind} name \"{name}\" is already used at {place}"),
                };
            }
        }
        match self.included_file(file) {
            Some(path) => MjcfError::Included { path, error: Box::new(error) },
            None => error,
        }
    }
}

/// Merges the files `xml` includes into it. `path` is the main file's path
/// (`None` for a document given as text: includes are then looked for
/// relative to the current directory).
pub(crate) fn assemble<'a>(xml: &'a str, path: Option<&Path>) -> Result<Assembled<'a>, MjcfError> {
    let model_dir = path.and_then(Path::parent).map(Path::to_path_buf).unwrap_or_default();
    let mut merger = Merger {
        sources: Sources {
            model_dir,
            files: vec![path.map(Path::to_path_buf)],
            pieces: vec![Piece { first: 1, file: 0, line: 1 }],
        },
        text: String::new(),
        lines: 1,
        chain: path.map(|p| vec![(identity(p), p.to_path_buf())]).unwrap_or_default(),
        included: Vec::new(),
    };
    // Most files include nothing: read them as they are.
    if !xml.contains("include") {
        return Ok(Assembled { text: Cow::Borrowed(xml), sources: merger.sources });
    }
    let document = parse(xml)?;
    let lines = LineStarts::new(xml);
    let includes = includes_in(&document, &lines)?;
    if includes.is_empty() {
        return Ok(Assembled { text: Cow::Borrowed(xml), sources: merger.sources });
    }
    let whole = 0..xml.len();
    merger.merge(0, xml, &lines, &includes, whole)?;
    Ok(Assembled { text: Cow::Owned(merger.text), sources: merger.sources })
}

/// The state of a merge.
struct Merger {
    sources: Sources,
    /// The merged text so far.
    text: String,
    /// Its number of lines (1 + its newlines).
    lines: u32,
    /// The files being included, outermost first (to name a cycle): each
    /// one's identity and its path as found.
    chain: Vec<(PathBuf, PathBuf)>,
    /// Each file included so far: its identity, and where it was included
    /// (the including file's index and the `<include>`'s line).
    included: Vec<(PathBuf, usize, u32)>,
}

/// An `<include>` element found in a file.
struct Include {
    /// Byte range of the element in its file.
    range: std::ops::Range<usize>,
    /// Line of the element.
    line: u32,
    /// The element as messages show it.
    label: String,
    /// The `file` attribute.
    file: String,
}

impl Merger {
    /// Appends `text[region]` of file `file` to the merged text, with the
    /// contents of the files its `includes` (those inside `region`) name in
    /// their place.
    fn merge(
        &mut self,
        file: usize,
        text: &str,
        lines: &LineStarts,
        includes: &[Include],
        region: std::ops::Range<usize>,
    ) -> Result<(), MjcfError> {
        let mut cursor = region.start;
        for include in includes.iter().filter(|i| region.contains(&i.range.start)) {
            self.append(file, lines, &text[cursor..include.range.start], cursor);
            self.include(file, include)?;
            cursor = include.range.end;
        }
        self.append(file, lines, &text[cursor..region.end], cursor);
        Ok(())
    }

    /// Appends `piece`, which starts at byte `start` of file `file`, on a line
    /// of its own.
    fn append(&mut self, file: usize, lines: &LineStarts, piece: &str, start: usize) {
        if !self.text.is_empty() {
            self.text.push('\n');
            self.lines += 1;
        }
        let line = lines.line_of(start);
        self.sources.pieces.push(Piece { first: self.lines, file, line });
        self.text.push_str(piece);
        self.lines += u32::try_from(piece.matches('\n').count()).unwrap_or(u32::MAX);
    }

    /// Merges in the file one `<include>` of file `from` names.
    fn include(&mut self, from: usize, include: &Include) -> Result<(), MjcfError> {
        let including = self.sources.included_file(from);
        let at = |reason: String| {
            let error = MjcfError::Invalid { line: include.line, element: include.label.clone(), reason };
            match &including {
                Some(path) => MjcfError::Included { path: path.clone(), error: Box::new(error) },
                None => error,
            }
        };
        let path = self.find(from, &include.file).map_err(at)?;
        let id = identity(&path);
        if let Some(start) = self.chain.iter().position(|(p, _)| *p == id) {
            let mut cycle: Vec<String> = self.chain[start..].iter().map(|(_, p)| p.display().to_string()).collect();
            cycle.push(path.display().to_string());
            return Err(at(format!("include cycle: {}", cycle.join(" includes "))));
        }
        if let Some((_, file, line)) = self.included.iter().find(|(p, ..)| *p == id) {
            let place = match &self.sources.files[*file] {
                Some(including) if *file != 0 => format!("line {line} of {}", including.display()),
                _ => format!("line {line}"),
            };
            return Err(at(format!(
                "file '{}' is already included at {place} (MuJoCo includes a file at most once)",
                include.file
            )));
        }
        let text = super::read_regular_file(&path)
            .and_then(|bytes| {
                String::from_utf8(bytes).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))
            })
            .map_err(|e| at(format!("cannot read {}: {e}", path.display())))?;
        self.included.push((id.clone(), from, include.line));
        self.sources.files.push(Some(path.clone()));
        let file = self.sources.files.len() - 1;
        let in_file = |error: MjcfError| MjcfError::Included { path: path.clone(), error: Box::new(error) };

        let document = parse(&text).map_err(in_file)?;
        let lines = LineStarts::new(&text);
        let root = document.root_element();
        let mut elements = root.children().filter(Node::is_element);
        let (Some(first), last) = (elements.next(), elements.next_back()) else {
            return Err(at(format!("'{}' has no element below its root <{}>", include.file, root.tag_name().name())));
        };
        let region = first.range().start..last.unwrap_or(first).range().end;
        let includes = includes_in(&document, &lines).map_err(in_file)?;
        self.chain.push((id, path.clone()));
        self.merge(file, &text, &lines, &includes, region)?;
        self.chain.pop();
        Ok(())
    }

    /// Where MuJoCo finds the file an include of file `from` names: relative
    /// to the model's directory, else to the including file's.
    fn find(&self, from: usize, name: &str) -> Result<PathBuf, String> {
        let name = &with_slashes(name);
        let mut looked = vec![self.sources.model_dir.join(name)];
        if let Some(dir) = self.sources.files[from].as_deref().and_then(Path::parent).filter(|_| from != 0) {
            let beside = dir.join(name);
            if identity(&beside) != identity(&looked[0]) {
                looked.push(beside);
            }
        }
        // Whatever is there but a directory, so that a named pipe is refused as such.
        match looked.iter().find(|p| p.metadata().is_ok_and(|m| !m.is_dir())) {
            Some(found) => Ok(found.clone()),
            None => {
                let places: Vec<String> = looked.iter().map(|p| p.display().to_string()).collect();
                Err(format!("cannot open '{name}': no file {}", places.join(" nor ")))
            }
        }
    }
}

/// A file name as MuJoCo opens it: every '\\' a '/', on any system (MuJoCo
/// 4.0 on Linux opens `sub/meshes/box.stl` for `sub\\meshes\\box.stl`, even
/// when a file of that literal name exists).
fn with_slashes(file: &str) -> String {
    file.replace('\\', "/")
}

/// What tells two paths to the same file apart from two files.
fn identity(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

/// Parses one file's text.
fn parse(text: &str) -> Result<Document<'_>, MjcfError> {
    Document::parse(text).map_err(|e| MjcfError::Xml { line: e.pos().row, column: e.pos().col, message: e.to_string() })
}

/// The `<include>` elements of a document, in document order, checked.
fn includes_in(document: &Document, lines: &LineStarts) -> Result<Vec<Include>, MjcfError> {
    let mut includes = Vec::new();
    for node in document.descendants().filter(|n| n.is_element() && n.tag_name().name() == "include") {
        let element = Element::new(node, lines);
        element.check_attributes(&["file"])?;
        let has_content = node.children().any(|c| c.is_element() || c.text().is_some_and(|t| !t.trim().is_empty()));
        if has_content {
            return Err(element.invalid("an <include> element cannot have children"));
        }
        let file = element.text("file").ok_or_else(|| element.missing("file"))?;
        includes.push(Include {
            range: node.range(),
            line: element.line,
            label: element.label(),
            file: file.to_string(),
        });
    }
    Ok(includes)
}
