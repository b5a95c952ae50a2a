//! Structured fuzzing of the PNML reader on stable Rust: whatever the text or the bytes, reading
//! returns a net or an error, and never panics. Besides arbitrary text, the inputs are documents
//! built from the reader's own vocabulary (PNML and PIPE elements, their attributes, counts that
//! overflow, entities, character references, CDATA, nested pages, reference chains) and the
//! example net with pieces cut, repeated or spliced in. Bounded, so the suite stays fast.

use cetratus_net::pnml;
use cetratus_testkit::paths;
use proptest::collection::vec;
use proptest::prelude::*;

const ELEMENTS: &[&str] = &[
    "pnml",
    "net",
    "page",
    "place",
    "transition",
    "arc",
    "name",
    "text",
    "value",
    "initialMarking",
    "inscription",
    "toolspecific",
    "referencePlace",
    "referenceTransition",
    "graphics",
    "position",
    "offset",
    "capacity",
    "priority",
    "arcType",
    "type",
    "p:place",
];

const ATTRIBUTES: &[&str] = &[
    "id", "source", "target", "ref", "type", "tool", "version", "x", "y", "xmlns", "xmlns:p",
    "value",
];

const VALUES: &[&str] = &[
    "p1",
    "p2",
    "t1",
    "a1",
    "pg",
    "",
    "cetratus",
    "1",
    "-1",
    "0",
    "1e400",
    "NaN",
    "4294967296",
    "99999999999999999999",
    "http://www.pnml.org/version-2009/grammar/pnml",
    "http://www.pnml.org/version-2009/grammar/ptnet",
    "inhibitor",
    "x&amp;y",
    "&e;",
    "&#0;",
    "&#65;",
    "a\tb",
];

const TEXTS: &[&str] = &[
    "",
    "1",
    "7",
    "-5",
    "0",
    "4294967295",
    "4294967296",
    "18446744073709551616",
    "Default,3",
    "Default,",
    ",",
    "  7 ",
    "1.5",
    "abc",
    "normal",
    "inhibitor",
    "&e;",
    "&lt;",
    "&#x110000;",
    "&#65;",
    "<![CDATA[<x>]]>",
    "<!-- c -->",
    "<?pi x?>",
    "\r\n",
];

/// An element, its attributes and its children, as XML text.
fn element() -> impl Strategy<Value = String> {
    let leaf = (
        prop::sample::select(ELEMENTS),
        vec(
            (
                prop::sample::select(ATTRIBUTES),
                prop::sample::select(VALUES),
            ),
            0..3,
        ),
        prop::sample::select(TEXTS),
    )
        .prop_map(|(name, attrs, text)| format!("<{name}{}>{text}</{name}>", attributes(&attrs)));
    leaf.prop_recursive(5, 48, 6, |inner| {
        (
            prop::sample::select(ELEMENTS),
            vec(
                (
                    prop::sample::select(ATTRIBUTES),
                    prop::sample::select(VALUES),
                ),
                0..3,
            ),
            vec(inner, 0..6),
            0..20u8,
        )
            .prop_map(|(name, attrs, children, wrong)| {
                let body = children.concat();
                // Now and then the end tag is wrong.
                let end = if wrong == 0 { "x" } else { name };
                format!("<{name}{}>{body}</{end}>", attributes(&attrs))
            })
    })
}

fn attributes(attrs: &[(&str, &str)]) -> String {
    attrs.iter().map(|(k, v)| format!(" {k}=\"{v}\"")).collect()
}

/// What may come before the root: an XML declaration and a DOCTYPE with entities of every kind
/// the reader refuses or accepts.
fn prolog() -> impl Strategy<Value = String> {
    let decl = prop::sample::select(
        &[
            "",
            "",
            "<?xml version=\"1.0\"?>",
            "<?xml version=\"1.0\"?>",
            "<?xml version=\"1.0\" encoding=\"ISO-8859-1\"?>",
            "<?xml version=\"1.1\" encoding=\"UTF-16\"?>",
            " <?xml version=\"1.0\"?>",
        ][..],
    );
    let entity = prop::sample::select(
        &[
            "<!ENTITY e \"7\">",
            "<!ENTITY e \"p1\">",
            "<!ENTITY e \"3\">",
            "<!ENTITY e \"&e;\">",
            "<!ENTITY e \"<place id='p9'/>\">",
            "<!ENTITY e SYSTEM \"file:///etc/passwd\">",
            "<!ENTITY % pe \"x\">",
            "<!ENTITY e 'p1'>",
            "<!ENTITY e \"unclosed>",
            "<!ELEMENT net ANY>",
        ][..],
    );
    (decl, vec(entity, 0..3), any::<bool>()).prop_map(|(decl, entities, doctype)| {
        if doctype {
            format!("{decl}<!DOCTYPE pnml [{}]>", entities.concat())
        } else {
            decl.to_string()
        }
    })
}

/// A PNML document: a prolog, then a root holding a net of generated elements.
fn hostile_document() -> impl Strategy<Value = String> {
    (
        prolog(),
        vec(element(), 0..8),
        any::<bool>(),
        prop::sample::select(VALUES),
    )
        .prop_map(|(prolog, body, iso, net_type)| {
            let ns = if iso {
                " xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\""
            } else {
                ""
            };
            format!(
                "{prolog}<pnml{ns}><net id=\"n\" type=\"{net_type}\">{}</net></pnml>",
                body.concat()
            )
        })
}

/// An edit of the example net, line by line (it has about one element per line, so most edits
/// keep it well-formed and reach the reader's checks): cut lines, repeat them, splice an
/// element in, or replace a quoted value or a text with a hostile one.
#[derive(Clone, Debug)]
enum Edit {
    Cut(usize, usize),
    Repeat(usize, usize, usize),
    Splice(usize, String),
    Value(usize, &'static str),
    Text(usize, &'static str),
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    vec(
        prop_oneof![
            (any::<usize>(), 1..8usize).prop_map(|(a, n)| Edit::Cut(a, n)),
            (any::<usize>(), 1..8usize, 1..4usize).prop_map(|(a, n, k)| Edit::Repeat(a, n, k)),
            (any::<usize>(), element()).prop_map(|(a, e)| Edit::Splice(a, e)),
            (any::<usize>(), prop::sample::select(VALUES)).prop_map(|(a, v)| Edit::Value(a, v)),
            (any::<usize>(), prop::sample::select(TEXTS)).prop_map(|(a, t)| Edit::Text(a, t)),
        ],
        1..6,
    )
}

/// Applies edits; positions are taken modulo the number of lines or of candidates.
fn apply(text: &str, edits: &[Edit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    for e in edits {
        let n = lines.len().max(1);
        match e {
            Edit::Cut(a, k) => {
                let a = a % n;
                lines.drain(a..(a + k).min(lines.len()));
            }
            Edit::Repeat(a, k, times) => {
                let a = a % n;
                let piece: Vec<String> =
                    lines[a.min(lines.len())..(a + k).min(lines.len())].to_vec();
                for _ in 0..*times {
                    lines.splice(a..a, piece.iter().cloned());
                }
            }
            Edit::Splice(a, element) => lines.insert(a % (lines.len() + 1), element.clone()),
            Edit::Value(a, v) => {
                // The a-th quoted value of the text.
                let quotes: Vec<(usize, usize)> = lines
                    .iter()
                    .enumerate()
                    .flat_map(|(i, l)| {
                        let q: Vec<usize> = l.match_indices('"').map(|(j, _)| j).collect();
                        q.chunks_exact(2).map(|c| (i, c[0])).collect::<Vec<_>>()
                    })
                    .collect();
                if let Some(&(i, open)) = quotes.get(a % quotes.len().max(1)) {
                    let l = &mut lines[i];
                    if let Some(len) = l[open + 1..].find('"') {
                        l.replace_range(open + 1..open + 1 + len, v);
                    }
                }
            }
            Edit::Text(a, t) => {
                // The a-th text between `>` and `<` on one line.
                let texts: Vec<(usize, usize, usize)> = lines
                    .iter()
                    .enumerate()
                    .filter_map(|(i, l)| {
                        let start = l.find('>')? + 1;
                        let len = l[start..].find('<')?;
                        Some((i, start, start + len))
                    })
                    .collect();
                if let Some(&(i, start, end)) = texts.get(a % texts.len().max(1)) {
                    lines[i].replace_range(start..end, t);
                }
            }
        }
    }
    lines.join("\n")
}

fn example_net() -> String {
    let path = paths::example("vernadat/vernadat.pnml");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_text_is_read_or_refused(text in "\\PC{0,300}") {
        let _ = pnml::read_str(&text, "fuzz.pnml");
    }

    #[test]
    fn arbitrary_bytes_are_read_or_refused(bytes in vec(any::<u8>(), 0..300)) {
        let _ = pnml::read_bytes(&bytes, "fuzz.pnml");
    }

    #[test]
    fn documents_of_pnml_vocabulary_are_read_or_refused(doc in hostile_document()) {
        let _ = pnml::read_str(&doc, "fuzz.pnml");
    }

    #[test]
    fn the_example_net_edited_is_read_or_refused(edits in edits()) {
        let text = apply(&example_net(), &edits);
        if let Ok(net) = pnml::read_str(&text, "fuzz.pnml") {
            // What was read writes back and reads again.
            let again = pnml::read_str(&pnml::write_string(&net), "again.pnml");
            prop_assert!(again.is_ok(), "{:?}", again.err());
        }
    }
}
