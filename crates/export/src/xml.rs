//! A small XML element tree over `quick-xml`, shared by the writers and readers of this crate.
//!
//! Writers build an [`Element`] tree and serialise it with [`Element::to_document`] (quick-xml
//! escapes every attribute value; control characters, which XML 1.0 cannot carry even escaped,
//! become spaces). Readers parse a document into the same tree with [`parse`] and walk it with
//! [`Node`], which remembers the path from the root (`OpenSCENARIO/Storyboard/.../Vertex[3]`) so
//! every error names the element or attribute and says what was expected. The formats written
//! here carry everything in attributes, so text content is ignored.

use crate::error::ExportError;
use quick_xml::events::{BytesDecl, BytesEnd, BytesStart, Event};
use quick_xml::{Reader, Writer};

/// One element: its name, attributes in document order, child elements, and where it started
/// (byte offset in the parsed text; 0 for built trees).
#[derive(Clone, Debug, PartialEq)]
pub struct Element {
    pub name: String,
    pub attrs: Vec<(String, String)>,
    pub children: Vec<Element>,
    pub offset: u64,
}

impl Element {
    pub fn new(name: &str) -> Self {
        Element { name: name.to_string(), attrs: Vec::new(), children: Vec::new(), offset: 0 }
    }

    /// Adds an attribute (builder style).
    pub fn attr(mut self, key: &str, value: impl Into<String>) -> Self {
        self.attrs.push((key.to_string(), value.into()));
        self
    }

    /// Adds a child element (builder style).
    pub fn child(mut self, child: Element) -> Self {
        self.children.push(child);
        self
    }

    /// Adds child elements (builder style).
    pub fn children(mut self, children: impl IntoIterator<Item = Element>) -> Self {
        self.children.extend(children);
        self
    }

    /// The value of attribute `key`, if present.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// Serialises the tree as a UTF-8 document with an XML declaration, indented by two spaces.
    pub fn to_document(&self) -> Result<String, ExportError> {
        let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
        w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None))).map_err(ExportError::Write)?;
        write_element(&mut w, self).map_err(ExportError::Write)?;
        let mut bytes = w.into_inner();
        bytes.push(b'\n');
        // Only `&str` went in, so the output is UTF-8.
        String::from_utf8(bytes).map_err(|e| ExportError::Write(std::io::Error::other(e)))
    }
}

/// XML 1.0 cannot carry most control characters at all: write them as spaces.
fn clean(value: &str) -> std::borrow::Cow<'_, str> {
    if value.chars().any(|c| c.is_control()) {
        value.chars().map(|c| if c.is_control() { ' ' } else { c }).collect::<String>().into()
    } else {
        value.into()
    }
}

fn write_element(w: &mut Writer<Vec<u8>>, el: &Element) -> std::io::Result<()> {
    let mut start = BytesStart::new(el.name.as_str());
    for (k, v) in &el.attrs {
        start.push_attribute((k.as_str(), clean(v).as_ref()));
    }
    if el.children.is_empty() {
        return w.write_event(Event::Empty(start));
    }
    w.write_event(Event::Start(start))?;
    for c in &el.children {
        write_element(w, c)?;
    }
    w.write_event(Event::End(BytesEnd::new(el.name.as_str())))
}

/// Parses a whole document into its root element. A document cut short names the innermost
/// element still open, as is one cut inside a tag (quick-xml's syntax errors are all markup left
/// open at the end); another error names the element it happened in and the byte offset.
pub fn parse(text: &str) -> Result<Element, ExportError> {
    let mut reader = Reader::from_str(text);
    reader.config_mut().check_end_names = true;
    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    let path = |stack: &[Element]| -> String {
        if stack.is_empty() {
            "(document)".to_string()
        } else {
            stack.iter().map(|e| e.name.as_str()).collect::<Vec<_>>().join("/")
        }
    };
    loop {
        let offset = reader.buffer_position();
        let event = reader.read_event().map_err(|e| match e {
            // Every syntax error quick-xml reports is markup the input ended inside: a cut file.
            quick_xml::Error::Syntax(_) => ExportError::Truncated {
                path: path(&stack),
                offset: stack.last().map_or(reader.error_position(), |open| open.offset),
            },
            e => ExportError::Xml { path: path(&stack), offset: reader.error_position(), message: e.to_string() },
        })?;
        match event {
            Event::Start(s) | Event::Empty(s) if root.is_some() => {
                let name = String::from_utf8_lossy(s.name().as_ref()).into_owned();
                return Err(ExportError::Xml {
                    path: path(&stack),
                    offset,
                    message: format!("element <{name}> after the root element ended"),
                });
            }
            Event::Start(s) => stack.push(start_element(&s, offset, &path(&stack))?),
            Event::Empty(s) => {
                let el = start_element(&s, offset, &path(&stack))?;
                match stack.last_mut() {
                    Some(parent) => parent.children.push(el),
                    None => root = Some(el),
                }
            }
            Event::End(_) => {
                // check_end_names guarantees the match; an unmatched end tag is a reader error.
                let Some(el) = stack.pop() else {
                    return Err(ExportError::Xml { path: path(&stack), offset, message: "unmatched end tag".into() });
                };
                match stack.last_mut() {
                    Some(parent) => parent.children.push(el),
                    None => root = Some(el),
                }
            }
            Event::Eof => {
                if let Some(open) = stack.last() {
                    return Err(ExportError::Truncated { path: path(&stack), offset: open.offset });
                }
                return root.ok_or_else(|| ExportError::Xml {
                    path: "(document)".into(),
                    offset,
                    message: "no root element (empty document?)".into(),
                });
            }
            _ => {}
        }
    }
}

fn start_element(s: &BytesStart, offset: u64, parent: &str) -> Result<Element, ExportError> {
    let name = String::from_utf8_lossy(s.name().as_ref()).into_owned();
    let mut el = Element { name, attrs: Vec::new(), children: Vec::new(), offset };
    for a in s.attributes() {
        let err = |message: String| ExportError::Xml { path: format!("{parent}/{}", el.name), offset, message };
        let a = a.map_err(|e| err(format!("bad attribute: {e}")))?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a.unescape_value().map_err(|e| err(format!("attribute `{key}`: {e}")))?.into_owned();
        el.attrs.push((key, value));
    }
    Ok(el)
}

/// An element with its path from the root (`OpenSCENARIO/Entities/ScenarioObject[1]`), for
/// reading with errors that say where.
#[derive(Clone, Debug)]
pub struct Node<'a> {
    pub el: &'a Element,
    pub path: String,
}

impl<'a> Node<'a> {
    pub fn root(el: &'a Element) -> Self {
        Node { el, path: el.name.clone() }
    }

    /// The first child named `name`, or an error naming this element and the missing child.
    pub fn child(&self, name: &str) -> Result<Node<'a>, ExportError> {
        self.opt_child(name).ok_or_else(|| self.error(format!("expected a child element <{name}>")))
    }

    /// The first child named `name`, if any.
    pub fn opt_child(&self, name: &str) -> Option<Node<'a>> {
        self.el.children.iter().find(|c| c.name == name).map(|c| Node { el: c, path: format!("{}/{name}", self.path) })
    }

    /// Every child named `name`, indexed in the path (`Vertex[0]`, `Vertex[1]`, ...).
    pub fn all(&self, name: &str) -> Vec<Node<'a>> {
        self.el
            .children
            .iter()
            .filter(|c| c.name == name)
            .enumerate()
            .map(|(i, c)| Node { el: c, path: format!("{}/{name}[{i}]", self.path) })
            .collect()
    }

    /// A required attribute.
    pub fn attr(&self, key: &str) -> Result<&'a str, ExportError> {
        self.el.get(key).ok_or_else(|| ExportError::Content {
            path: format!("{}@{key}", self.path),
            message: "expected this attribute, it is missing".into(),
        })
    }

    /// A required attribute holding a finite number.
    pub fn f64(&self, key: &str) -> Result<f64, ExportError> {
        self.opt_f64(key)?.ok_or_else(|| ExportError::Content {
            path: format!("{}@{key}", self.path),
            message: "expected a number, the attribute is missing".into(),
        })
    }

    /// An optional attribute holding a finite number (`None` when absent).
    pub fn opt_f64(&self, key: &str) -> Result<Option<f64>, ExportError> {
        let Some(raw) = self.el.get(key) else { return Ok(None) };
        parse_finite(raw)
            .map(Some)
            .map_err(|message| ExportError::Content { path: format!("{}@{key}", self.path), message })
    }

    /// An error located at this element.
    pub fn error(&self, message: String) -> ExportError {
        ExportError::Content { path: self.path.clone(), message }
    }
}

/// `v` with at most `decimals` decimals, trailing zeros (and a trailing `.`) trimmed, never
/// `-0`: the number format of every writer here.
pub fn num(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    let s = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { s.as_str() };
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// Parses a finite `xsd:double` (parameter references such as `$Speed` are not resolved).
pub fn parse_finite(raw: &str) -> Result<f64, String> {
    let s = raw.trim();
    if s.starts_with('$') {
        return Err(format!("expected a number, got `{s}` (parameter references are not resolved)"));
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("expected a finite number, got `{s}`")),
        Err(_) => Err(format!("expected a number, got `{s}`")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_and_parses_back() {
        let doc = Element::new("A")
            .attr("v", "x < y & \"z\"\u{1}")
            .child(Element::new("B").attr("n", "1.5"))
            .child(Element::new("B").attr("n", "two"));
        let text = doc.to_document().unwrap();
        assert!(text.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>"));
        let back = parse(&text).unwrap();
        assert_eq!(back.get("v"), Some("x < y & \"z\" "));
        let root = Node::root(&back);
        let bs = root.all("B");
        assert_eq!(bs[0].f64("n").unwrap(), 1.5);
        let e = bs[1].f64("n").unwrap_err().to_string();
        assert!(e.contains("A/B[1]@n") && e.contains("expected a number"), "{e}");
        let e = root.child("C").unwrap_err().to_string();
        assert!(e.contains("<C>"), "{e}");
    }

    #[test]
    fn truncation_names_the_open_element() {
        let e = parse("<A><B x=\"1\"><C/>").unwrap_err().to_string();
        assert!(e.contains("A/B"), "{e}");
        let e = parse("<A><B x=\"1").unwrap_err().to_string();
        assert!(e.contains("A"), "{e}");
        assert!(parse("").is_err());
        assert!(parse("<A></B>").is_err());
        assert!(parse("<A/><B/>").is_err());
    }
}
