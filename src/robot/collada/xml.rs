//! The XML underneath a COLLADA document: elements by `id` for its `#id` references, children by
//! tag, an element's numbers, and where an element is (tag, id, line) for every message the
//! reader gives. No geometry here.

use std::collections::BTreeMap;

pub(super) type Node<'a, 'i> = roxmltree::Node<'a, 'i>;

/// Every element with an `id`, for the document's `#id` references.
pub(super) struct Ids<'a, 'i>(BTreeMap<&'a str, Node<'a, 'i>>);

impl<'a, 'i> Ids<'a, 'i> {
    pub(super) fn new(doc: &'a roxmltree::Document<'i>) -> Self {
        Self(
            doc.descendants()
                .filter(|n| n.is_element())
                .filter_map(|n| n.attribute("id").map(|id| (id, n)))
                .collect(),
        )
    }

    /// The element with `id`.
    pub(super) fn get(&self, id: &str) -> Option<Node<'a, 'i>> {
        self.0.get(id).copied()
    }

    /// The element an attribute's `#id` reference names, which must have tag `tag`.
    pub(super) fn target(
        &self,
        n: Node<'a, 'i>,
        attr: &str,
        tag: &str,
    ) -> Result<Node<'a, 'i>, String> {
        let url = n
            .attribute(attr)
            .ok_or_else(|| format!("{}: no {attr} attribute", at(n)))?;
        let id = url
            .strip_prefix('#')
            .ok_or_else(|| format!("{}: {attr}=\"{url}\" is not a local #id", at(n)))?;
        match self.0.get(id) {
            Some(t) if t.has_tag_name(tag) => Ok(*t),
            Some(t) => Err(format!(
                "{}: {attr}=\"{url}\" names {}, not a <{tag}>",
                at(n),
                at(*t)
            )),
            None => Err(format!("{}: {attr}=\"{url}\" names nothing", at(n))),
        }
    }
}

pub(super) fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.has_tag_name(name))
}

pub(super) fn children<'a, 'i: 'a>(
    n: Node<'a, 'i>,
    name: &'a str,
) -> impl Iterator<Item = Node<'a, 'i>> {
    n.children().filter(move |c| c.has_tag_name(name))
}

/// Where an element is, for messages: `<tag id="…">` or `<tag>` at line L.
pub(super) fn at(n: Node) -> String {
    let pos = n.document().text_pos_at(n.range().start);
    match n.attribute("id") {
        Some(id) => format!("<{} id=\"{id}\"> (line {})", n.tag_name().name(), pos.row),
        None => format!("<{}> (line {})", n.tag_name().name(), pos.row),
    }
}

/// The numbers of an element's text, refused when one is not a finite number.
pub(super) fn numbers<T: std::str::FromStr>(n: Node) -> Result<Vec<T>, String> {
    n.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .map(|w| {
            w.parse::<T>()
                .map_err(|_| format!("{}: '{w}' is not a number", at(n)))
        })
        .collect()
}

pub(super) fn floats(n: Node, expected: usize) -> Result<Vec<f64>, String> {
    let v: Vec<f64> = numbers(n)?;
    if v.len() != expected || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "{}: expected {expected} finite numbers, found {:?}",
            at(n),
            v
        ));
    }
    Ok(v)
}
