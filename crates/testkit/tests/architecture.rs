//! The architecture, checked: which workspace crate may depend on which (read from
//! `cargo metadata`), and how long a source file may grow. ARCHITECTURE.md explains the rules;
//! the table below is their one machine-readable copy.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

/// Where a reader finds the dependency rules and their reasons.
const DEPENDENCY_RULES: &str = "ARCHITECTURE.md, section Dependency rules";
/// Where a reader finds the size rules and their reasons.
const SIZE_RULES: &str = "ARCHITECTURE.md, section Invariants, \"Files stay readable\"";

/// The workspace crates a crate may have as normal or build dependencies.
enum Allowed {
    /// These at most.
    Only(&'static [&'static str]),
    /// Any but these.
    AnyBut(&'static [&'static str]),
}

use Allowed::{AnyBut, Only};

/// One row per workspace crate. A new crate fails the test until it has a row here and a line
/// in ARCHITECTURE.md.
const RULES: &[(&str, Allowed)] = &[
    ("cetratus-vocab", Only(&[])),
    ("cetratus-net", Only(&["cetratus-vocab"])),
    ("cetratus-twin", Only(&[])),
    ("cetratus-slots", Only(&[])),
    ("cetratus-proto", Only(&["cetratus-vocab"])),
    ("cetratus-analysis", Only(&["cetratus-net"])),
    ("cetratus-st", Only(&[])),
    ("cetratus-matiec", Only(&[])),
    (
        "cetratus-program",
        Only(&[
            "cetratus-vocab",
            "cetratus-net",
            "cetratus-analysis",
            "cetratus-st",
        ]),
    ),
    (
        "cetratus-sfc",
        Only(&["cetratus-net", "cetratus-program", "cetratus-st"]),
    ),
    (
        "cetratus-export",
        Only(&[
            "cetratus-net",
            "cetratus-program",
            "cetratus-st",
            "cetratus-sfc",
        ]),
    ),
    (
        "cetratus-runtime",
        Only(&["cetratus-vocab", "cetratus-net", "cetratus-program"]),
    ),
    (
        "cetratus-persist",
        Only(&["cetratus-net", "cetratus-program", "cetratus-runtime"]),
    ),
    (
        "cetratus-io",
        Only(&[
            "cetratus-vocab",
            "cetratus-net",
            "cetratus-program",
            "cetratus-runtime",
            "cetratus-twin",
            "cetratus-slots",
        ]),
    ),
    (
        "cetratus-mct",
        Only(&["cetratus-vocab", "cetratus-proto", "cetratus-slots"]),
    ),
    (
        "cetratus-fleet",
        Only(&[
            "cetratus-vocab",
            "cetratus-program",
            "cetratus-proto",
            "cetratus-mct",
        ]),
    ),
    (
        "cetratus-dashboard",
        Only(&[
            "cetratus-vocab",
            "cetratus-proto",
            "cetratus-mct",
            "cetratus-fleet",
            "cetratus-net",
            "cetratus-slots",
        ]),
    ),
    (
        "cetratus-node",
        AnyBut(&[
            "cetratus-cli",
            "cetratus-dashboard",
            "cetratus-bench",
            "cetratus-testkit",
        ]),
    ),
    (
        "cetratus-bench",
        AnyBut(&["cetratus-cli", "cetratus-testkit"]),
    ),
    ("cetratus-testkit", AnyBut(&["cetratus-cli"])),
    ("cetratus-cli", AnyBut(&["cetratus-testkit"])),
];

/// Crates, of the workspace or not, that only the crates named beside them may have as normal
/// dependencies.
const RESTRICTED: &[(&str, &[&str])] = &[
    ("cetratus-dashboard", &["cetratus-cli"]),
    ("cetratus-bench", &["cetratus-cli"]),
    ("anyhow", &["cetratus-cli"]),
    // A tool that compiles C: the benches and the tests drive it, a PLC never does.
    ("cetratus-matiec", &["cetratus-bench", "cetratus-testkit"]),
];
/// Crates every other crate may have as dev-dependencies only.
const DEV_ONLY: &[&str] = &["cetratus-testkit"];

/// The most lines of a file of the binary, which only parses arguments and calls libraries.
const BINARY_FILE_LINES: usize = 400;
/// The most lines of any other source file, unless its header gives the reason.
const FILE_LINES: usize = 900;
/// How a file over [`FILE_LINES`] starts the line, within its first ten, that says why.
const SIZE_REASON: &str = "//! Over 900 lines because";

/// A workspace crate and its dependencies by package name.
struct Package {
    name: String,
    /// Normal and build dependencies: what the crate's code may use.
    deps: BTreeSet<String>,
    /// Dev-dependencies: what only its tests, examples and benches may use.
    dev_deps: BTreeSet<String>,
}

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The workspace's crates, from `cargo metadata --no-deps` (no resolution, no network).
fn packages() -> Vec<Package> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(&cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--manifest-path",
        ])
        .arg(workspace_root().join("Cargo.toml"))
        .output()
        .unwrap_or_else(|e| panic!("cannot run {cargo:?} metadata: {e}"));
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: Value = serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON");
    let packages = meta["packages"].as_array().expect("a list of packages");
    packages
        .iter()
        .map(|p| {
            let mut pkg = Package {
                name: p["name"].as_str().expect("a package name").to_string(),
                deps: BTreeSet::new(),
                dev_deps: BTreeSet::new(),
            };
            for d in p["dependencies"]
                .as_array()
                .expect("a list of dependencies")
            {
                let name = d["name"].as_str().expect("a dependency name").to_string();
                // `kind` is null for normal dependencies, "build" or "dev" otherwise.
                if d["kind"] == "dev" {
                    pkg.dev_deps.insert(name);
                } else {
                    pkg.deps.insert(name);
                }
            }
            pkg
        })
        .collect()
}

/// Every way the dependencies of `packages` break the rules, one sentence each.
fn dependency_violations(packages: &[Package]) -> Vec<String> {
    let members: BTreeSet<&str> = packages.iter().map(|p| p.name.as_str()).collect();
    let mut out = Vec::new();
    for (name, _) in RULES {
        if !members.contains(name) {
            out.push(format!(
                "the rules name {name}, which is not a workspace crate: remove its row"
            ));
        }
    }
    for p in packages {
        let name = p.name.as_str();
        let Some((_, allowed)) = RULES.iter().find(|(n, _)| *n == name) else {
            out.push(format!(
                "{name} has no dependency rule: add its row to the table of this test and its \
                 line to {DEPENDENCY_RULES}"
            ));
            continue;
        };
        for dep in p.deps.iter().filter(|d| members.contains(d.as_str())) {
            let ok = match allowed {
                Only(list) => list.contains(&dep.as_str()),
                AnyBut(list) => !list.contains(&dep.as_str()) && dep != name,
            };
            if !ok {
                out.push(format!(
                    "{name} depends on {dep}, which {DEPENDENCY_RULES} forbids ({name} may \
                     depend on {})",
                    describe(allowed)
                ));
            }
        }
        for dep in p.deps.iter().map(String::as_str) {
            if let Some((_, only)) = RESTRICTED
                .iter()
                .find(|(d, only)| *d == dep && !only.contains(&name))
            {
                out.push(format!(
                    "{name} depends on {dep}, which {DEPENDENCY_RULES} allows only to {}",
                    only.join(", ")
                ));
            }
            if DEV_ONLY.contains(&dep) {
                out.push(format!(
                    "{name} depends on {dep} outside [dev-dependencies]; {DEPENDENCY_RULES} \
                     allows it only there"
                ));
            }
        }
    }
    out
}

fn describe(allowed: &Allowed) -> String {
    match allowed {
        Only([]) => "no workspace crate".to_string(),
        Only(list) => format!("only {}", list.join(", ")),
        AnyBut(list) => format!("any workspace crate but {}", list.join(", ")),
    }
}

#[test]
fn every_crate_depends_only_on_what_the_dependency_rules_allow() {
    let packages = packages();
    let violations = dependency_violations(&packages);
    assert!(
        violations.is_empty(),
        "{} dependency rule(s) broken:\n  {}",
        violations.len(),
        violations.join("\n  ")
    );
}

#[test]
fn dev_dependencies_are_read_apart_from_normal_ones() {
    // Guards the check above against reading the metadata wrongly: were dev-dependencies mixed
    // in with normal ones, or dropped, the rules would pass or fail for the wrong reason.
    let packages = packages();
    let io = packages
        .iter()
        .find(|p| p.name == "cetratus-io")
        .expect("cetratus-io is a workspace crate");
    assert!(
        io.dev_deps.contains("cetratus-testkit"),
        "{:?}",
        io.dev_deps
    );
    assert!(!io.deps.contains("cetratus-testkit"), "{:?}", io.deps);
    assert!(io.deps.contains("cetratus-runtime"), "{:?}", io.deps);
}

#[test]
fn a_forbidden_edge_is_reported_with_the_crate_the_edge_and_where_the_rule_is_written() {
    let package = |name: &str, deps: &[&str]| Package {
        name: name.to_string(),
        deps: deps.iter().map(|d| d.to_string()).collect(),
        dev_deps: BTreeSet::new(),
    };
    let all = [
        package("cetratus-dashboard", &["cetratus-runtime", "anyhow"]),
        package("cetratus-runtime", &["cetratus-net", "cetratus-testkit"]),
        package("cetratus-net", &[]),
        package("cetratus-testkit", &[]),
        package("cetratus-newcomer", &[]),
    ];
    let found: Vec<String> = dependency_violations(&all)
        .into_iter()
        .filter(|m| !m.contains("which is not a workspace crate"))
        .collect();
    let expected = [
        "cetratus-dashboard depends on cetratus-runtime, which",
        "cetratus-dashboard depends on anyhow, which",
        "cetratus-runtime depends on cetratus-testkit, which",
        "cetratus-runtime depends on cetratus-testkit outside [dev-dependencies]",
        "cetratus-newcomer has no dependency rule",
    ];
    assert_eq!(found.len(), expected.len(), "{found:#?}");
    for (message, start) in found.iter().zip(expected) {
        assert!(
            message.starts_with(start),
            "{message:?} should start {start:?}"
        );
        assert!(message.contains(DEPENDENCY_RULES), "{message:?}");
    }
}

/// Every `.rs` file under `dir`, recursively, in path order.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries =
            std::fs::read_dir(&d).unwrap_or_else(|e| panic!("cannot list {}: {e}", d.display()));
        for entry in entries {
            let path = entry.expect("a directory entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// The `src/` directory of every crate, and of the benches.
fn source_dirs() -> Vec<PathBuf> {
    let root = workspace_root();
    let crates = std::fs::read_dir(root.join("crates")).expect("crates/ lists");
    let mut dirs: Vec<PathBuf> = crates
        .map(|e| e.expect("a directory entry").path().join("src"))
        .filter(|p| p.is_dir())
        .collect();
    dirs.push(root.join("benches/src"));
    dirs.sort();
    dirs
}

/// `path` relative to the workspace, for messages.
fn shown(path: &Path) -> String {
    let root = workspace_root();
    path.strip_prefix(&root)
        .unwrap_or(path)
        .display()
        .to_string()
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

#[test]
fn no_file_of_the_binary_is_over_400_lines() {
    let offenders: Vec<String> = rust_files(&workspace_root().join("crates/cli/src"))
        .iter()
        .map(|p| (shown(p), read(p).lines().count()))
        .filter(|(_, n)| *n > BINARY_FILE_LINES)
        .map(|(p, n)| format!("{p}: {n} lines"))
        .collect();
    assert!(
        offenders.is_empty(),
        "files of the binary over {BINARY_FILE_LINES} lines ({SIZE_RULES}: move the logic \
         into a library crate):\n  {}",
        offenders.join("\n  ")
    );
}

#[test]
fn no_source_file_is_over_900_lines_unless_its_header_says_why() {
    let offenders: Vec<String> = source_dirs()
        .iter()
        .flat_map(|d| rust_files(d))
        .filter_map(|p| {
            let text = read(&p);
            let lines = text.lines().count();
            let reasoned = text.lines().take(10).any(|l| l.starts_with(SIZE_REASON));
            (lines > FILE_LINES && !reasoned).then(|| format!("{}: {lines} lines", shown(&p)))
        })
        .collect();
    assert!(
        offenders.is_empty(),
        "source files over {FILE_LINES} lines without a `{SIZE_REASON} …` line in their first \
         ten ({SIZE_RULES}: split them, or say why they must stay whole):\n  {}",
        offenders.join("\n  ")
    );
}

/// Where a reader finds the vocabulary rule and its reason.
const VOCABULARY_RULE: &str = "ARCHITECTURE.md, section Invariants, \"One vocabulary\"";

/// An enum read from source: its name, its variants, and whether every variant is a bare name
/// (no fields): only such an enum is a set of names that could repeat the vocabulary.
type EnumItem = (String, Vec<String>, bool);

/// The name an item starts with on `line`: `enum X` (with `pub` or `pub(crate)`), or `X` on the
/// first line of a `names!` invocation (`pending`).
fn enum_name(line: &str, pending: bool) -> Option<String> {
    let word = |t: &str| -> String {
        t.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    let t = line.trim();
    let t = t
        .strip_prefix("pub(crate) ")
        .or_else(|| t.strip_prefix("pub "))
        .unwrap_or(t);
    if let Some(rest) = t.strip_prefix("enum ") {
        return Some(word(rest)).filter(|w| !w.is_empty());
    }
    (pending && (t.ends_with(',') || t.contains(", \"")))
        .then(|| word(t))
        .filter(|w| !w.is_empty())
}

/// The enums defined in `source` (Rust): `enum X` items and `names!` invocations. A line-based
/// reading, enough for rustfmt's layout: a variant is a capitalised word that starts a line one
/// brace deep in the enum's body.
fn enums_in(source: &str) -> Vec<EnumItem> {
    let lines: Vec<&str> = source.lines().collect();
    let (mut out, mut pending, mut k) = (Vec::new(), false, 0);
    while k < lines.len() {
        let t = lines[k].trim();
        if t == "names! {" {
            pending = true;
        }
        let Some(name) = enum_name(lines[k], pending && t != "names! {") else {
            k += 1;
            continue;
        };
        pending = false;
        let (mut depth, mut variants, mut unit) = (0i32, Vec::new(), true);
        for body in &lines[k..] {
            k += 1;
            let t = body.trim();
            if depth == 1 && !t.starts_with('#') && !t.starts_with("//") {
                let word: String = t
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if word.starts_with(|c: char| c.is_ascii_uppercase()) {
                    let after = t[word.len()..].trim_start();
                    unit &= !(after.starts_with('(') || after.starts_with('{'));
                    variants.push(word);
                }
            }
            depth += body.matches('{').count() as i32 - body.matches('}').count() as i32;
            if depth <= 0 && body.contains('}') {
                break;
            }
        }
        out.push((name, variants, unit));
    }
    out
}

/// Every enum outside `vocab` (file path, enum) with the same variants as an enum of `vocab`.
fn vocabulary_violations(vocab: &str, others: &[(String, String)]) -> Vec<String> {
    let words = enums_in(vocab);
    let mut found = Vec::new();
    for (path, source) in others {
        for (name, variants, unit) in enums_in(source) {
            if !unit {
                continue;
            }
            let mut mine = variants.clone();
            mine.sort();
            for (word, theirs, _) in &words {
                let mut theirs = theirs.clone();
                theirs.sort();
                if !mine.is_empty() && mine == theirs {
                    found.push(format!(
                        "{path}: enum {name} has the variants of cetratus_vocab::{word}; use that one \
                         instead ({VOCABULARY_RULE})"
                    ));
                }
            }
        }
    }
    found
}

#[test]
fn no_crate_defines_again_an_enum_of_the_vocabulary() {
    let root = workspace_root();
    let vocab_dir = root.join("crates/vocab/src");
    let vocab: String = rust_files(&vocab_dir).iter().map(|p| read(p)).collect();
    assert!(
        enums_in(&vocab).len() >= 9,
        "the vocabulary is read: {:?}",
        enums_in(&vocab)
    );
    let others: Vec<(String, String)> = source_dirs()
        .into_iter()
        .filter(|d| *d != vocab_dir)
        .flat_map(|d| rust_files(&d))
        .map(|p| (shown(&p), read(&p)))
        .collect();
    let found = vocabulary_violations(&vocab, &others);
    assert!(found.is_empty(), "{found:#?}");
}

#[test]
fn an_enum_that_repeats_the_vocabulary_is_named_with_its_file_and_the_rule() {
    let vocab = "names! {\n    /// A container.\n    Slot, \"container\", \"A or B\" {\n        /// A.\n        A = \"A\",\n        /// B.\n        B = \"B\",\n    }\n}\n";
    let other = "/// Mine.\n#[derive(Clone)]\npub enum Container {\n    /// B.\n    B,\n    /// A.\n    #[default]\n    A,\n}\n\nenum Other {\n    A,\n    B(u32),\n    C { x: u8 },\n}\n";
    let slot = (
        "Slot".to_string(),
        vec!["A".to_string(), "B".to_string()],
        true,
    );
    assert_eq!(enums_in(vocab), [slot]);
    let read = enums_in(other);
    assert_eq!(
        (read[1].1.as_slice(), read[1].2),
        (&["A", "B", "C"].map(String::from)[..], false)
    );
    let found = vocabulary_violations(vocab, &[("crates/x/src/lib.rs".into(), other.into())]);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with(
        "crates/x/src/lib.rs: enum Container has the variants of cetratus_vocab::Slot"
    ));
    assert!(found[0].contains(VOCABULARY_RULE));
}

/// Where a reader finds the rule on function length and its reason.
const FUNCTION_RULE: &str = "ARCHITECTURE.md, section Invariants, \"Functions stay short\"";

/// The most physical lines of a function, from `fn` to its closing brace, outside tests.
const FUNCTION_LINES: usize = 120;

/// `source` with every comment, string and character literal blanked to spaces (line breaks
/// kept), so that the braces left are the code's own.
fn code_only(source: &str) -> String {
    #[derive(PartialEq)]
    enum At {
        Code,
        Line,
        Block(usize),
        Str,
        Raw(usize),
    }
    let b: Vec<char> = source.chars().collect();
    let (mut out, mut at, mut k) = (String::with_capacity(b.len()), At::Code, 0);
    let blank = |c: char| if c == '\n' { '\n' } else { ' ' };
    while k < b.len() {
        let (c, next) = (b[k], b.get(k + 1).copied().unwrap_or(' '));
        match at {
            At::Code if c == '/' && next == '/' => at = At::Line,
            At::Code if c == '/' && next == '*' => at = At::Block(0),
            At::Code if c == '"' => at = At::Str,
            At::Code
                if c == 'r'
                    && (next == '"' || next == '#')
                    && !b
                        .get(k.wrapping_sub(1))
                        .is_some_and(|p| p.is_alphanumeric() || *p == '_') =>
            {
                let hashes = b[k + 1..].iter().take_while(|h| **h == '#').count();
                if b.get(k + 1 + hashes) == Some(&'"') {
                    out.extend(std::iter::repeat_n(' ', hashes + 2));
                    k += hashes + 2;
                    at = At::Raw(hashes);
                    continue;
                }
            }
            At::Code if c == '\'' && (b.get(k + 2) == Some(&'\'') || next == '\\') => {
                // A character literal ('{', '\n', '\u{7b}'); a lifetime has no closing quote.
                let end = b[k + 1..]
                    .iter()
                    .position(|q| *q == '\'')
                    .map_or(k, |p| k + 1 + p);
                out.extend(std::iter::repeat_n(' ', end - k + 1));
                k = end + 1;
                continue;
            }
            At::Line if c == '\n' => at = At::Code,
            At::Block(d) if c == '*' && next == '/' => {
                out.push_str("  ");
                k += 2;
                at = if d == 0 { At::Code } else { At::Block(d - 1) };
                continue;
            }
            At::Block(d) if c == '/' && next == '*' => at = At::Block(d + 1),
            At::Str if c == '\\' => {
                out.push(' ');
                out.push(blank(next));
                k += 2;
                continue;
            }
            At::Str if c == '"' => {
                out.push(' ');
                k += 1;
                at = At::Code;
                continue;
            }
            At::Raw(h)
                if c == '"' && b[k + 1..].iter().take(h).filter(|x| **x == '#').count() == h =>
            {
                out.extend(std::iter::repeat_n(' ', h + 1));
                k += h + 1;
                at = At::Code;
                continue;
            }
            _ => {}
        }
        out.push(if at == At::Code { c } else { blank(c) });
        k += 1;
    }
    out
}

/// The functions of `source` outside `#[cfg(test)]` items: name, first line (1-based) and
/// length in physical lines, from `fn` to the closing brace.
fn functions_in(source: &str) -> Vec<(String, usize, usize)> {
    let code = code_only(source);
    let lines: Vec<&str> = code.lines().collect();
    let (mut out, mut k) = (Vec::new(), 0);
    while k < lines.len() {
        let t = lines[k].trim_start();
        if t.starts_with("#[cfg(test)]") {
            // Skip the test item that follows: up to its closing brace.
            k = end_of_item(&lines, k + 1).map_or(lines.len(), |e| e + 1);
            continue;
        }
        let Some(at) = t.find("fn ").filter(|at| {
            let before = &t[..*at];
            before.split_whitespace().all(|w| {
                [
                    "pub",
                    "pub(crate)",
                    "pub(super)",
                    "const",
                    "async",
                    "unsafe",
                    "extern",
                ]
                .contains(&w)
            })
        }) else {
            k += 1;
            continue;
        };
        let name: String = t[at + 3..]
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        match end_of_item(&lines, k) {
            Some(end) => {
                out.push((name, k + 1, end - k + 1));
                k += 1;
            }
            None => k += 1,
        }
    }
    out
}

/// The line of the brace that closes the item starting at line `start`, or `None` when the item
/// ends with `;` before any brace (a declaration without a body).
fn end_of_item(lines: &[&str], start: usize) -> Option<usize> {
    let mut depth = 0i64;
    let mut opened = false;
    // Brackets and parentheses of the signature: a `;` inside them (`[u64; W]`) ends nothing.
    let mut nested = 0i64;
    for (k, line) in lines.iter().enumerate().skip(start) {
        for c in line.chars() {
            match c {
                '{' => {
                    depth += 1;
                    opened = true;
                }
                '}' => depth -= 1,
                '(' | '[' if !opened => nested += 1,
                ')' | ']' if !opened => nested -= 1,
                ';' if !opened && depth == 0 && nested == 0 => return None,
                _ => {}
            }
            if opened && depth == 0 {
                return Some(k);
            }
        }
    }
    None
}

/// Functions allowed over [`FUNCTION_LINES`]: file, function, the most lines it may keep, and
/// why. A function here may shrink, never grow; once under the limit, its row goes.
const LONG_FUNCTIONS: &[(&str, &str, usize, &str)] = &[
    (
        "crates/program/src/guard/eval.rs",
        "run",
        190,
        "the interpreter of compiled guards and bodies: one loop over the instructions, each arm of its match an instruction; split, every instruction would pay a call on the scan's hot path",
    ),
    (
        "crates/st/src/vm.rs",
        "exec",
        123,
        "the register machine of Structured Text: one match over the instructions, an arm per instruction, which the interpreter's loop and the machine code's call back share; split, every instruction would pay a second dispatch on the scan's hot path",
    ),
];

/// Every function of `files` (path, source) over [`FUNCTION_LINES`] lines that `allowed` does
/// not allow at its length.
fn function_violations(
    files: &[(String, String)],
    allowed: &[(&str, &str, usize, &str)],
) -> Vec<String> {
    let mut found = Vec::new();
    let mut still_long = BTreeSet::new();
    for (path, source) in files {
        for (name, line, len) in functions_in(source) {
            if len <= FUNCTION_LINES {
                continue;
            }
            still_long.insert((path.clone(), name.clone()));
            let row = allowed.iter().find(|(p, f, _, _)| p == path && *f == name);
            match row {
                Some((_, _, most, _)) if len <= *most => {}
                Some((_, _, most, _)) => found.push(format!(
                    "{path}:{line}: fn {name} has {len} lines, more than the {most} it is allowed \
                     ({FUNCTION_RULE})"
                )),
                None => found.push(format!(
                    "{path}:{line}: fn {name} has {len} lines, more than {FUNCTION_LINES}; split \
                     it, or give the reason it cannot be ({FUNCTION_RULE})"
                )),
            }
        }
    }
    for (path, name, _, _) in allowed {
        if !still_long.contains(&(path.to_string(), name.to_string())) {
            found.push(format!(
                "{path}: fn {name} is listed as long but is not over {FUNCTION_LINES} lines any \
                 more (or is gone); remove its row ({FUNCTION_RULE})"
            ));
        }
    }
    found
}

/// Every non-test source file: under `src/` of a crate or of the benches, not a `tests.rs`.
fn non_test_sources() -> Vec<(String, String)> {
    source_dirs()
        .into_iter()
        .flat_map(|d| rust_files(&d))
        .filter(|p| p.file_name().is_some_and(|n| n != "tests.rs"))
        .filter(|p| !p.components().any(|c| c.as_os_str() == "tests"))
        .map(|p| (shown(&p), read(&p)))
        .collect()
}

#[test]
fn no_function_outside_the_tests_is_over_120_lines_unless_listed_with_its_reason() {
    let found = function_violations(&non_test_sources(), LONG_FUNCTIONS);
    assert!(found.is_empty(), "{found:#?}");
}

#[test]
fn a_long_function_is_found_with_its_length_and_braces_in_text_do_not_count() {
    let body = "    let s = \"}}}\"; let c = '{'; // }\n".repeat(FUNCTION_LINES);
    let in_test = format!("fn in_test() {{\n{body}}}\n");
    let source = format!(
        "pub(crate) fn long(x: u8) -> u8\nwhere u8: Copy,\n{{\n{body}    r#\"{{\"#;\n}}\n\
         fn short() {{}}\nfn sized(a: [u64; 4]) -> u64 {{ a[0] }}\ntrait T {{ fn declared(&self); }}\n#[cfg(test)]\nmod tests {{\n{in_test}}}\n"
    );
    let fns = functions_in(&source);
    let names: Vec<&str> = fns.iter().map(|(n, _, _)| n.as_str()).collect();
    assert_eq!(names, ["long", "short", "sized"], "{fns:?}");
    assert_eq!(fns[0], ("long".to_string(), 1, FUNCTION_LINES + 5));
    let files = [("crates/x/src/lib.rs".to_string(), source)];
    let found = function_violations(&files, &[]);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("crates/x/src/lib.rs:1: fn long has 125 lines"));
    assert!(found[0].contains(FUNCTION_RULE));
    let allowed = [("crates/x/src/lib.rs", "long", 125, "a lexer")];
    assert!(function_violations(&files, &allowed).is_empty());
    let shrunk = [("crates/x/src/lib.rs", "long", 124, "a lexer")];
    assert!(function_violations(&files, &shrunk)[0].contains("more than the 124 it is allowed"));
    let stale = [("crates/x/src/lib.rs", "short", 200, "once long")];
    assert!(function_violations(&files, &stale)
        .iter()
        .any(|m| m.contains("fn short is listed as long but is not")));
}
