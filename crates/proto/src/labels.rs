//! A PLC's labels (`[labels]` of its local configuration, published in its retained `state`)
//! and the selectors that pick PLCs by id or by label (docs/fleet.md).
//!
//! A selector is one or more terms separated by commas, every one of which must hold:
//! `line=2` (the label `line` is `2`), `cell=press-*` (a glob: `*` any run of characters, `?`
//! one), `plc-3` or `plc-*` (the PLC's id, a glob too), `*` (every PLC). Matching is
//! iterative and linear in the pattern times the text, whatever either holds.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use crate::ProtoError;

/// A PLC's labels, by key.
pub type Labels = BTreeMap<String, String>;

/// Most labels a PLC may have.
pub const MAX_LABELS: usize = 32;
/// Most bytes of a label's key.
pub const MAX_LABEL_KEY: usize = 64;
/// Most bytes of a label's value, and of a selector's pattern.
pub const MAX_LABEL_VALUE: usize = 128;
/// Most terms of a selector.
pub const MAX_TERMS: usize = 16;

/// Checks a label: a key of letters, digits, `_`, `-` and `.` that starts with a letter (and is
/// not `id`, which a selector reads as the PLC's id), and a value of printable text. The error
/// says what is wrong and what to do.
pub fn check_label(key: &str, value: &str) -> Result<(), ProtoError> {
    label_rule(key, value).map_err(ProtoError::Label)
}

fn label_rule(key: &str, value: &str) -> Result<(), String> {
    key_rule(key)?;
    if value.len() > MAX_LABEL_VALUE || value.is_empty() || value.chars().any(char::is_control) {
        return Err(format!(
            "the label `{key}`'s value must be 1 to {MAX_LABEL_VALUE} bytes of printable text"
        ));
    }
    Ok(())
}

/// A label key's rule, which a selector's keys follow too.
fn key_rule(key: &str) -> Result<(), String> {
    let key_ok = key.len() <= MAX_LABEL_KEY
        && key.starts_with(|c: char| c.is_ascii_alphabetic())
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c));
    if !key_ok {
        return Err(format!(
            "the label key `{}` must start with a letter and hold letters, digits, `_`, `-` and `.` only, at most {MAX_LABEL_KEY} bytes",
            key.escape_debug()
        ));
    }
    if key.eq_ignore_ascii_case("id") {
        return Err(
            "the label key `id` is the PLC's id in a selector; name the label otherwise".into(),
        );
    }
    Ok(())
}

/// Checks a PLC's labels: at most [`MAX_LABELS`] of them, each by [`check_label`].
pub fn check_labels(labels: &Labels) -> Result<(), ProtoError> {
    if labels.len() > MAX_LABELS {
        return Err(ProtoError::Label(format!(
            "{} labels, more than the {MAX_LABELS} a PLC may have",
            labels.len()
        )));
    }
    labels.iter().try_for_each(|(k, v)| check_label(k, v))
}

/// One term of a selector.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Term {
    /// The PLC's id matches the glob.
    Id(String),
    /// The label is present and its value matches the glob.
    Label(String, String),
}

/// Picks PLCs by id or by label; see the module's documentation for the syntax.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Selector {
    terms: Vec<Term>,
    text: String,
}

impl Selector {
    /// Whether the PLC `id` with `labels` is selected.
    pub fn matches(&self, id: &str, labels: &Labels) -> bool {
        self.terms.iter().all(|t| match t {
            Term::Id(glob) => matches(glob, id),
            Term::Label(key, glob) => labels.get(key).is_some_and(|v| matches(glob, v)),
        })
    }
}

impl fmt::Display for Selector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text)
    }
}

impl FromStr for Selector {
    type Err = ProtoError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse(s).map_err(|reason| ProtoError::Selector {
            selector: s.escape_debug().to_string(),
            reason,
        })
    }
}

/// The selector `s`, or what is wrong with it.
fn parse(s: &str) -> Result<Selector, String> {
    let text = s.trim();
    if text.is_empty() {
        return Err(
            "an empty selector; write `line=2`, `cell=press-*`, a PLC id, or `*` for every PLC"
                .into(),
        );
    }
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() > MAX_TERMS {
        return Err(format!(
            "{} terms, more than the {MAX_TERMS} a selector may have",
            parts.len()
        ));
    }
    let terms = parts
        .into_iter()
        .map(|part| {
            let (key, glob) = match part.split_once('=') {
                Some((k, g)) => (Some(k.trim()), g.trim()),
                None => (None, part),
            };
            if glob.is_empty() || glob.len() > MAX_LABEL_VALUE {
                return Err(format!(
                    "the term `{part}` needs a pattern of 1 to {MAX_LABEL_VALUE} bytes"
                ));
            }
            match key {
                None => Ok(Term::Id(glob.to_string())),
                Some(k) if k.eq_ignore_ascii_case("id") => Ok(Term::Id(glob.to_string())),
                Some(k) => {
                    key_rule(k).map_err(|e| format!("in `{part}`: {e}"))?;
                    Ok(Term::Label(k.to_string(), glob.to_string()))
                }
            }
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok(Selector {
        terms,
        text: text.to_string(),
    })
}

/// Whether `text` matches the glob `pattern` (`*` any run, `?` one character): the classic
/// two-pointer walk that remembers the last `*`, linear in both lengths for each restart and
/// never recursive.
fn matches(pattern: &str, text: &str) -> bool {
    let (p, t): (Vec<char>, Vec<char>) = (pattern.chars().collect(), text.chars().collect());
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < t.len() {
        if i < p.len() && (p[i] == '?' || p[i] == t[j]) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labels(pairs: &[(&str, &str)]) -> Labels {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    #[test]
    fn a_selector_picks_by_label_by_id_and_by_glob_and_every_term_must_hold() {
        let press4 = labels(&[("line", "2"), ("cell", "press-4")]);
        let weld = labels(&[("line", "1"), ("cell", "weld-1")]);
        let sel = |s: &str| s.parse::<Selector>().unwrap();
        assert!(sel("line=2").matches("a", &press4));
        assert!(!sel("line=2").matches("b", &weld));
        assert!(sel("cell=press-*").matches("a", &press4));
        assert!(sel("cell = ?ress-4").matches("a", &press4));
        assert!(sel("plc-*").matches("plc-7", &weld));
        assert!(sel("id=plc-7").matches("plc-7", &weld));
        assert!(!sel("plc-*").matches("cell7", &weld));
        assert!(sel("*").matches("anything", &Labels::new()));
        assert!(sel("line=1, cell=weld-*").matches("b", &weld));
        assert!(!sel("line=1,cell=press-*").matches("b", &weld));
        // A label the PLC does not have does not match, not even `*`.
        assert!(!sel("site=*").matches("a", &press4));
        assert_eq!(sel(" line=2 ").to_string(), "line=2");
    }

    #[test]
    fn globs_match_without_backtracking_blowup() {
        assert!(matches("a*b*c", "axxbyyc"));
        assert!(!matches("a*b*c", "axxbyy"));
        assert!(matches("*", ""));
        assert!(!matches("?", ""));
        // The pattern that makes a naive recursive matcher exponential.
        let text = "a".repeat(100);
        assert!(!matches(&format!("{}b", "a*".repeat(60)), &text));
    }

    #[test]
    fn bad_selectors_and_labels_are_refused_saying_what_to_write() {
        for (bad, says) in [
            ("", "an empty selector"),
            ("line=", "needs a pattern"),
            ("=2", "must start with a letter"),
            ("li ne=2", "must start with a letter"),
            (&"a,".repeat(20), "more than the 16"),
            (&format!("line={}", "x".repeat(200)), "needs a pattern"),
        ] {
            let e = bad.parse::<Selector>().unwrap_err().to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
        assert!(check_label("line", "2").is_ok());
        let refused = |r: Result<(), ProtoError>| r.unwrap_err().to_string();
        assert!(refused(check_label("id", "x")).contains("PLC's id"));
        assert!(refused(check_label("cell", "a\nb")).contains("printable"));
        assert!(refused(check_label("cell", "")).contains("1 to 128"));
        let many: Labels = (0..40).map(|i| (format!("k{i}"), "v".into())).collect();
        assert!(refused(check_labels(&many)).contains("more than the 32"));
    }
}
