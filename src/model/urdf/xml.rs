//! The XML layer of the URDF reader: the text before parsing (a declaration after leading
//! whitespace, bytes that are not UTF-8), the nesting-depth limit, and typed access to elements
//! and attributes that turns every problem into an error or a note with the file and line.

use super::version::UrdfVersion;
use crate::model::error::ModelError;
use roxmltree::{Document, Node};

/// Deepest element nesting ribbon reads (the `<robot>` element is depth 1).
///
/// A URDF nests about five levels (`robot/link/visual/geometry/mesh`); Gazebo plugin blocks add a
/// few more. The XML parser (roxmltree) descends recursively, one stack frame per level, so a
/// hostile file of 100 000 nested elements would overflow the stack: the depth is measured by a
/// linear scan of the text *before* parsing. 256 leaves ample room for real files
/// and keeps the parser's recursion shallow: a file nested to the limit parses on a test thread's
/// 2 MiB stack (`src/model/urdf/tests.rs`).
pub const MAX_XML_DEPTH: usize = 256;

/// Reads the file's bytes as text. Bytes that are not UTF-8 (a Latin-1 comment, say) become
/// U+FFFD with a note naming the first such line: tinyxml2, which Pinocchio uses, reads such files.
pub(super) fn decode(bytes: &[u8], path: &str, notes: &mut Vec<String>) -> String {
    match std::str::from_utf8(bytes) {
        Ok(text) => text.to_string(),
        Err(e) => {
            let line = 1 + bytes[..e.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            notes.push(format!(
                "{path}:{line}: the file has bytes that are not UTF-8 (first on this line); they are read as U+FFFD — save the file as UTF-8 if names or numbers are affected"
            ));
            String::from_utf8_lossy(bytes).into_owned()
        }
    }
}

/// Blanks out an XML declaration that follows leading whitespace (XML requires it to be the very
/// first thing in the file; tinyxml2, and so Pinocchio, accept it after blank lines). Replaced by
/// spaces, so that every line number stays valid. Returns the text to parse.
pub(super) fn blank_late_declaration(text: String, path: &str, notes: &mut Vec<String>) -> String {
    let body = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let bom = text.len() - body.len();
    let leading = body.len() - body.trim_start().len();
    if leading == 0 || !body[leading..].starts_with("<?xml") {
        return text;
    }
    let start = bom + leading;
    let Some(end) = text[start..].find("?>").map(|i| start + i + 2) else {
        return text; // unterminated: the XML parser reports it with its position
    };
    let line = 1 + text[..start].matches('\n').count();
    notes.push(format!(
        "{path}:{line}: whitespace before the XML declaration <?xml …?> (XML wants the declaration first; read anyway, as Pinocchio does)"
    ));
    let mut bytes = text.into_bytes();
    for byte in &mut bytes[start..end] {
        if *byte != b'\n' {
            *byte = b' ';
        }
    }
    // Only bytes of the ASCII-delimited declaration were replaced, each by an ASCII space.
    String::from_utf8(bytes).unwrap_or_default()
}

/// Cuts NUL bytes (and whitespace between them) at the very end of the text, with a note: a C
/// string terminator saved into the file by some exporters. tinyxml2, and so Pinocchio, stops
/// reading at the first NUL; a NUL anywhere else is left for the XML parser to report.
pub(super) fn cut_trailing_nul(mut text: String, path: &str, notes: &mut Vec<String>) -> String {
    let Some(first) = text.find('\0') else {
        return text;
    };
    if text[first..]
        .chars()
        .all(|c| c == '\0' || c.is_ascii_whitespace())
    {
        let line = 1 + text[..first].matches('\n').count();
        notes.push(format!(
            "{path}:{line}: NUL bytes after the end of the document (ignored, as Pinocchio ignores them)"
        ));
        text.truncate(first);
    }
    text
}

/// Most distinct undeclared namespace prefixes [`declare_undeclared_prefixes`] declares; a file
/// with more is left for the XML parser to refuse. (Real files use one or two: `sensor:`,
/// `controller:`, `interface:` in the Gazebo blocks of older ROS descriptions.)
const MAX_UNDECLARED_PREFIXES: usize = 32;

/// The namespace given to a prefix the file uses without declaring it: not the URDF's, so the
/// reader treats its elements as foreign markup and skips them, as it skips `<xacro:…>`.
const UNDECLARED_NAMESPACE: &str = "urn:ribbon:undeclared-prefix:";

/// Declares, on the root element, every namespace prefix the text uses without an `xmlns:`
/// declaration (`<sensor:camera>` inside the `<gazebo>` blocks of older ROS descriptions). XML
/// namespaces make such a file an error, but tinyxml2 does not process namespaces, so Pinocchio
/// and ROS load it. Each prefix is bound to a placeholder namespace, which makes its elements and
/// attributes foreign markup that the reader ignores; one note per prefix names where it is first
/// used. The declarations are inserted inside the root's start tag, on its line, so every line
/// number stays valid. Called only after [`parse`] refused the text, so a well-formed file is
/// parsed once. `None` when no prefix was declared (the text is broken in another way, or nested
/// beyond [`MAX_XML_DEPTH`], which must not reach the parser): the first error stands.
pub(super) fn declare_undeclared_prefixes(
    text: &str,
    path: &str,
    notes: &mut Vec<String>,
) -> Option<String> {
    check_depth(text, path).ok()?;
    let mut declared: Option<String> = None;
    for _ in 0..MAX_UNDECLARED_PREFIXES {
        let current = declared.as_deref().unwrap_or(text);
        let (prefix, pos) = match Document::parse_with_options(current, parsing_options()) {
            Err(roxmltree::Error::UnknownNamespace(prefix, pos)) => (prefix, pos),
            _ => break,
        };
        let at = root_name_end(current.as_bytes())?;
        notes.push(format!(
            "{path}:{}: namespace prefix '{prefix}' is used without an xmlns:{prefix} declaration (first here, column {}); its elements and attributes are read as foreign markup and ignored, as Pinocchio (tinyxml2, which does not check namespaces) ignores them",
            pos.row, pos.col
        ));
        let mut next = current.to_string();
        next.insert_str(
            at,
            &format!(" xmlns:{prefix}=\"{UNDECLARED_NAMESPACE}{prefix}\""),
        );
        declared = Some(next);
    }
    declared
}

/// The byte offset just after the root element's name in its start tag, skipping the XML
/// declaration, processing instructions, comments and a DOCTYPE; `None` if the text has no root
/// start tag this scan can find.
fn root_name_end(bytes: &[u8]) -> Option<usize> {
    let find = |from: usize, pattern: &[u8]| {
        bytes
            .get(from..)?
            .windows(pattern.len())
            .position(|w| w == pattern)
            .map(|p| from + p + pattern.len())
    };
    let mut at = 0;
    loop {
        let open = at + bytes.get(at..)?.iter().position(|&b| b == b'<')?;
        at = match *bytes.get(open + 1)? {
            b'?' => find(open + 2, b"?>")?,
            b'!' if bytes[open..].starts_with(b"<!--") => find(open + 4, b"-->")?,
            b'!' => declaration_end(bytes, open).0?,
            _ => {
                let name = bytes[open + 1..]
                    .iter()
                    .position(|b| b.is_ascii_whitespace() || *b == b'/' || *b == b'>')?;
                return Some(open + 1 + name);
            }
        };
    }
}

/// The parser's options: a DTD is allowed (roxmltree bounds entity expansion).
fn parsing_options() -> roxmltree::ParsingOptions {
    roxmltree::ParsingOptions {
        allow_dtd: true,
        ..roxmltree::ParsingOptions::default()
    }
}

/// Parses the text (a DTD is allowed: roxmltree bounds entity expansion) after checking the
/// nesting depth with [`check_depth`].
pub(super) fn parse<'input>(text: &'input str, path: &str) -> Result<Document<'input>, ModelError> {
    check_depth(text, path)?;
    Document::parse_with_options(text, parsing_options()).map_err(|e| {
        let pos = e.pos();
        ModelError::Xml {
            path: path.to_string(),
            line: pos.row,
            column: pos.col,
            message: e.to_string(),
        }
    })
}

/// Refuses text whose elements nest deeper than [`MAX_XML_DEPTH`], by one iterative pass over the
/// bytes: start tags (quotes honoured, `/>` closes at once) deepen, end tags return; comments,
/// CDATA and processing instructions are skipped. Markup inside the quoted values of a DOCTYPE
/// (entities, which roxmltree expands in place) counts on top of the document's own depth, summed
/// over all values — a bound on any chain of entity references. Malformed text that this pass
/// cannot follow is left to the parser, which reports it with its position.
pub(super) fn check_depth(text: &str, path: &str) -> Result<(), ModelError> {
    let bytes = text.as_bytes();
    let (depth, at) = nesting(bytes, true);
    if depth > MAX_XML_DEPTH {
        let name_end = bytes[at + 1..]
            .iter()
            .position(|b| b.is_ascii_whitespace() || *b == b'/' || *b == b'>')
            .map_or(bytes.len(), |p| at + 1 + p);
        return Err(ModelError::TooDeep {
            path: path.to_string(),
            line: 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count() as u32,
            element: String::from_utf8_lossy(&bytes[(at + 1).min(name_end)..name_end]).into_owned(),
            depth,
            limit: MAX_XML_DEPTH,
            entities: entity_depth(bytes),
        });
    }
    Ok(())
}

/// The nesting the DOCTYPE's entity values add (0 without entities with markup), for messages.
fn entity_depth(bytes: &[u8]) -> usize {
    let Some(start) = bytes.windows(2).position(|w| w == b"<!") else {
        return 0;
    };
    let (_, values) = declaration_end(bytes, start);
    values
        .iter()
        .map(|&(s, e)| nesting(&bytes[s..e], false).0)
        .sum()
}

/// The deepest nesting in `bytes` and the byte offset of the first `<` that reaches
/// `MAX_XML_DEPTH + 1` (or of the deepest one). With `in_document`, a DOCTYPE's quoted values are
/// measured too (once, not recursively) and their depths added.
fn nesting(bytes: &[u8], in_document: bool) -> (usize, usize) {
    let find = |from: usize, pattern: &[u8]| {
        bytes
            .get(from..)
            .and_then(|rest| rest.windows(pattern.len()).position(|w| w == pattern))
            .map(|p| from + p)
    };
    let (mut depth, mut deepest, mut deepest_at, mut entity_depth) =
        (0usize, 0usize, 0usize, 0usize);
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] != b'<' {
            i += 1;
            continue;
        }
        let rest = &bytes[i..];
        let skip_to = |pattern: &[u8], len: usize| find(i + 1, pattern).map(|e| e + len);
        let next = if rest.starts_with(b"<!--") {
            skip_to(b"-->", 3)
        } else if rest.starts_with(b"<![CDATA[") {
            skip_to(b"]]>", 3)
        } else if rest.starts_with(b"<?") {
            skip_to(b"?>", 2)
        } else if rest.starts_with(b"<!") {
            // DOCTYPE: up to its '>' outside quotes and outside the [ … ] internal subset.
            let (end, values) = declaration_end(bytes, i);
            if in_document {
                entity_depth += values
                    .iter()
                    .map(|&(s, e)| nesting(&bytes[s..e], false).0)
                    .sum::<usize>();
            }
            end
        } else {
            let end = tag_end(bytes, i);
            if rest.starts_with(b"</") {
                depth = depth.saturating_sub(1);
            } else {
                let self_closing = end.is_some_and(|e| e >= 2 && bytes[e - 2] == b'/');
                let reached = depth + 1 + entity_depth;
                if reached > deepest {
                    deepest = reached;
                    deepest_at = i;
                    if deepest > MAX_XML_DEPTH {
                        return (deepest, deepest_at);
                    }
                }
                if !self_closing {
                    depth += 1;
                }
            }
            end
        };
        match next {
            Some(n) => i = n,
            None => break, // unterminated: the parser reports it
        }
    }
    (deepest, deepest_at)
}

/// One past the `>` that ends the tag starting at `start`, honouring quoted attribute values.
fn tag_end(bytes: &[u8], start: usize) -> Option<usize> {
    let mut quote = None;
    for (k, &b) in bytes.iter().enumerate().skip(start + 1) {
        match (quote, b) {
            (None, b'"' | b'\'') => quote = Some(b),
            (Some(q), _) if b == q => quote = None,
            (None, b'>') => return Some(k + 1),
            _ => {}
        }
    }
    None
}

/// One past the `>` that ends the declaration starting at `start` (`<!DOCTYPE … [ … ]>`), and the
/// byte ranges of the quoted values inside it.
fn declaration_end(bytes: &[u8], start: usize) -> (Option<usize>, Vec<(usize, usize)>) {
    let mut values = Vec::new();
    let (mut quote, mut quote_start, mut bracket) = (None, 0, 0usize);
    for (k, &b) in bytes.iter().enumerate().skip(start + 2) {
        match (quote, b) {
            (None, b'"' | b'\'') => {
                quote = Some(b);
                quote_start = k + 1;
            }
            (Some(q), _) if b == q => {
                quote = None;
                values.push((quote_start, k));
            }
            (Some(_), _) => {}
            (None, b'[') => bracket += 1,
            (None, b']') => bracket = bracket.saturating_sub(1),
            (None, b'>') if bracket == 0 => return (Some(k + 1), values),
            _ => {}
        }
    }
    (None, values)
}

/// Typed access to the elements of one document, collecting notes.
pub(super) struct Reader<'a, 'input> {
    /// The file, for messages.
    pub path: &'a str,
    /// The document the nodes read belong to.
    document: std::marker::PhantomData<&'a Document<'input>>,
    /// Byte offsets of the document's line feeds, in order: a node's line is found by a binary
    /// search (roxmltree's `text_pos_at` counts from the start of the text, which made reading a
    /// file with one line per element quadratic in its length).
    line_feeds: Vec<usize>,
    namespace: Option<&'a str>,
    /// Non-fatal findings, each naming file, line and element.
    pub notes: Vec<String>,
    /// The file's URDF version (`<robot version>`; 1.0 until the root has been read).
    pub version: UrdfVersion,
}

/// A child element read once, with the line it was read from.
pub(super) struct Read<T> {
    /// The value.
    pub value: T,
    /// Line of the element it came from.
    pub line: u32,
}

impl<'a, 'input> Reader<'a, 'input> {
    /// A reader of `doc`, whose URDF elements are those in the namespace of `root` (prefixed
    /// elements such as `<xacro:property>` are other vocabularies and are skipped).
    pub fn new(doc: &'a Document<'input>, root: Node<'a, 'input>, path: &'a str) -> Self {
        let line_feeds = doc
            .input_text()
            .bytes()
            .enumerate()
            .filter_map(|(at, b)| (b == b'\n').then_some(at))
            .collect();
        Self {
            path,
            document: std::marker::PhantomData,
            line_feeds,
            namespace: root.tag_name().namespace(),
            notes: Vec::new(),
            version: UrdfVersion::V1_0,
        }
    }

    /// 1-based line where `node` starts: one more than the line feeds before it (as roxmltree's
    /// `text_pos_at` counts).
    pub fn line(&self, node: Node) -> u32 {
        let start = node.range().start;
        let before = self.line_feeds.partition_point(|&at| at < start);
        u32::try_from(before + 1).unwrap_or(u32::MAX)
    }

    /// Whether `node` is the URDF element `name`.
    pub fn is(&self, node: Node, name: &str) -> bool {
        node.is_element()
            && node.tag_name().name() == name
            && node.tag_name().namespace() == self.namespace
    }

    /// The URDF child elements of `node` named `name`, in file order.
    pub fn children<'n>(&self, node: Node<'n, 'input>, name: &str) -> Vec<Node<'n, 'input>> {
        node.children().filter(|c| self.is(*c, name)).collect()
    }

    /// Records a note about the element at `line`.
    pub fn note(&mut self, line: u32, message: String) {
        self.notes.push(format!("{}:{line}: {message}", self.path));
    }

    /// A required attribute.
    pub fn required<'n>(
        &self,
        node: Node<'n, 'input>,
        element: &str,
        attribute: &'static str,
        hint: &'static str,
    ) -> Result<&'n str, ModelError> {
        node.attribute(attribute)
            .ok_or_else(|| ModelError::MissingAttribute {
                path: self.path.to_string(),
                line: self.line(node),
                element: element.to_string(),
                attribute,
                hint,
            })
    }

    /// An optional numeric attribute. `owner` is `link 'a'` or `joint 'j'`; `field` names the value
    /// in a non-finite error (`<mass value>`). Whitespace around the number is allowed (urdfdom,
    /// and so Pinocchio, reads `value=" 2.5"`).
    pub fn number(
        &self,
        node: Node,
        owner: &str,
        attribute: &'static str,
        field: &str,
    ) -> Result<Option<f64>, ModelError> {
        let Some(text) = node.attribute(attribute) else {
            return Ok(None);
        };
        let value = text
            .trim_ascii()
            .parse::<f64>()
            .map_err(|_| self.bad_number(node, owner, attribute, text, "a number"))?;
        self.finite(node, owner, field, &[value])?;
        Ok(Some(value))
    }

    /// An optional attribute of three numbers separated by whitespace.
    pub fn vector3(
        &self,
        node: Node,
        owner: &str,
        attribute: &'static str,
        field: &str,
    ) -> Result<Option<[f64; 3]>, ModelError> {
        self.vector(
            node,
            owner,
            attribute,
            field,
            "three numbers separated by spaces",
        )
    }

    /// An optional attribute of `N` finite numbers separated by whitespace; `expected` says what
    /// a bad value should have been (`"four numbers x y z w separated by spaces"`).
    pub fn vector<const N: usize>(
        &self,
        node: Node,
        owner: &str,
        attribute: &'static str,
        field: &str,
        expected: &'static str,
    ) -> Result<Option<[f64; N]>, ModelError> {
        let Some(text) = node.attribute(attribute) else {
            return Ok(None);
        };
        let values = parse_vector::<N>(text)
            .ok_or_else(|| self.bad_number(node, owner, attribute, text, expected))?;
        self.finite(node, owner, field, &values)?;
        Ok(Some(values))
    }

    /// A [`ModelError::BadNumber`] for `attribute="text"` of `node`, which should have been
    /// `expected`.
    pub fn bad_number(
        &self,
        node: Node,
        owner: &str,
        attribute: &'static str,
        text: &str,
        expected: &'static str,
    ) -> ModelError {
        ModelError::BadNumber {
            path: self.path.to_string(),
            line: self.line(node),
            element: format!("{owner} <{}>", node.tag_name().name()),
            attribute,
            text: text.to_string(),
            expected,
        }
    }

    fn finite(
        &self,
        node: Node,
        owner: &str,
        field: &str,
        values: &[f64],
    ) -> Result<(), ModelError> {
        match values.iter().find(|v| !v.is_finite()) {
            None => Ok(()),
            Some(&value) => Err(ModelError::NonFinite {
                path: self.path.to_string(),
                line: self.line(node),
                element: owner.to_string(),
                field: field.to_string(),
                value,
            }),
        }
    }

    /// The child element `name` of `parent`, read by `read`, when there is one. A repeat that
    /// reads to the same value is ignored with a note (Pinocchio reads the first); a repeat that
    /// differs is a [`ModelError::ConflictingDuplicate`] naming both lines. `owner` is
    /// `link 'a'` or `joint 'j'` (or `link 'a' <inertial>`).
    pub fn single<'n, T: PartialEq>(
        &mut self,
        parent: Node<'n, 'input>,
        name: &'static str,
        owner: &str,
        mut read: impl FnMut(&mut Self, Node<'n, 'input>) -> Result<T, ModelError>,
    ) -> Result<Option<Read<T>>, ModelError> {
        let nodes = self.children(parent, name);
        let Some((&first, rest)) = nodes.split_first() else {
            return Ok(None);
        };
        let value = read(self, first)?;
        let first_line = self.line(first);
        for &repeat in rest {
            let line = self.line(repeat);
            if read(self, repeat)? != value {
                return Err(ModelError::ConflictingDuplicate {
                    path: self.path.to_string(),
                    line,
                    first_line,
                    element: owner.to_string(),
                    child: name,
                });
            }
            self.note(
                line,
                format!("{owner} repeats <{name}> identically (first at line {first_line}); the repeat is ignored, as Pinocchio does"),
            );
        }
        Ok(Some(Read {
            value,
            line: first_line,
        }))
    }
}

/// Three numbers separated by ASCII whitespace, or `None`.
pub(super) fn parse_vector3(text: &str) -> Option<[f64; 3]> {
    parse_vector::<3>(text)
}

/// Exactly `N` numbers separated by ASCII whitespace, or `None`.
fn parse_vector<const N: usize>(text: &str) -> Option<[f64; N]> {
    let mut parts = text.split_ascii_whitespace().map(str::parse::<f64>);
    let mut values = [0.0; N];
    for value in &mut values {
        *value = parts.next()?.ok()?;
    }
    parts.next().is_none().then_some(values)
}
