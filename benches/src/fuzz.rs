//! A mutation fuzzer on stable Rust for everything a PLC reads from outside: PNML files, guard
//! conditions (`substitute --when`), program files, update packages, `state.json` and MQTT
//! commands. `cetratus bench fuzz` runs it for a while; the test suite runs a short, seeded round
//! and every input kept in `benches/fuzz-corpus/<target>/` (inputs that once crashed a reader).
//!
//! Inputs start from real seeds (the Vernadat example, its packages, real commands) and are
//! mutated: bytes flipped, inserted, deleted and duplicated, tokens of each format spliced in,
//! and the shapes that once overflowed a stack (long operator chains, deep nesting) grown on
//! purpose. A reader passes when it returns, with a value or an error; a panic is a finding.

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use cetratus_mct::ControlPlane;
use cetratus_program::{Program, TrustStore, UpdatePackage};
use serde::Serialize;

use crate::embedded::examples_dir;
use crate::program::vernadat_program;

/// What each reader is fed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Target {
    /// `cetratus_net::pnml::read_str`.
    Pnml,
    /// `Program::compile_condition` on the Vernadat program.
    Guard,
    /// `Program::from_sources` with the Vernadat net.
    ProgramToml,
    /// `package::inspect` and `UpdatePackage::verify`.
    Package,
    /// `state.json` as the persistence reader parses it.
    StateJson,
    /// `ControlPlane::parse` of an MQTT command.
    Command,
}

impl Target {
    /// Every target.
    pub const ALL: [Target; 6] = [
        Target::Pnml,
        Target::Guard,
        Target::ProgramToml,
        Target::Package,
        Target::StateJson,
        Target::Command,
    ];

    /// The name of its corpus directory.
    pub fn name(self) -> &'static str {
        match self {
            Target::Pnml => "pnml",
            Target::Guard => "guard",
            Target::ProgramToml => "program_toml",
            Target::Package => "package",
            Target::StateJson => "state_json",
            Target::Command => "command",
        }
    }
}

/// What one target's round found.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Round {
    /// Inputs run.
    pub execs: u64,
    /// Inputs per second.
    pub execs_per_s: f64,
    /// Inputs that made the reader panic.
    pub panics: u64,
    /// The first few of them, for the report (the corpus keeps them whole).
    #[serde(skip)]
    pub found: Vec<Vec<u8>>,
}

/// The readers, built once.
pub struct Readers {
    program: Arc<Program>,
    toml: String,
    trust: TrustStore,
}

impl Readers {
    /// The Vernadat program and its files.
    pub fn new() -> Self {
        let toml = std::fs::read_to_string(examples_dir().join("vernadat/vernadat.toml"))
            .expect("the embedded example");
        Readers {
            program: vernadat_program(),
            toml,
            trust: TrustStore::empty(),
        }
    }

    /// Feeds one input to a reader; `false` when it panicked.
    pub fn run(&self, target: Target, input: &[u8]) -> bool {
        let text = || String::from_utf8_lossy(input);
        catch_unwind(AssertUnwindSafe(|| match target {
            Target::Pnml => drop(cetratus_net::pnml::read_str(&text(), "fuzz.pnml")),
            Target::Guard => drop(self.program.compile_condition(&text())),
            Target::ProgramToml => {
                let net = (**self.program.net()).clone();
                drop(Program::from_sources(&text(), "fuzz.toml", net));
            }
            Target::Package => {
                drop(cetratus_program::package::inspect(input));
                drop(UpdatePackage::verify(
                    input,
                    &self.trust,
                    cetratus_program::Unsigned::Allowed,
                ));
            }
            Target::StateJson => drop(serde_json::from_slice::<cetratus_persist::StateFile>(input)),
            Target::Command => {
                let mut cp = ControlPlane::new("fuzz", None).expect("a valid id");
                for verb in ["load", "substitute", "exec_info"] {
                    let topic = format!("cetratus/fuzz/cmd/{verb}");
                    drop(cp.parse(&topic, input, Some("cetratus/fuzz/reply/f"), None, 0));
                }
            }
        }))
        .is_ok()
    }

    /// Real inputs of each format, to mutate.
    pub fn seeds(&self, target: Target) -> Vec<Vec<u8>> {
        let file = |name: &str| {
            std::fs::read(examples_dir().join("vernadat").join(name)).unwrap_or_default()
        };
        match target {
            Target::Pnml => vec![file("vernadat.pnml"), file("u2.pnml")],
            Target::Guard => ["PE", "P10 == 1 && P20 == 1", "P30.t >= 3s", "rise(FPM1) || !EB"]
                .map(|s| s.as_bytes().to_vec())
                .to_vec(),
            Target::ProgramToml => vec![self.toml.clone().into_bytes()],
            Target::Package => {
                let p = crate::update::packages();
                vec![p.u1, p.u2]
            }
            Target::StateJson => vec![br#"{"format":"cetratus-state/1","seq":3,"written_utc":"2026-01-01T00:00:00.000Z","snapshot":{"cycle":5,"time_us":50000,"primary":"A","status":"idle","containers":[{"program_hash":"ab","marking":[4,3,1],"place_since_us":[0,null,0],"variables":[],"latches":[]},null],"update":null}}"#.to_vec()],
            Target::Command => [
                &br#"{"package_b64":"aGVsbG8=","reply_to":"cetratus/fuzz/reply/x"}"#[..],
                br#"{"mode":"keep","when":"P10 == 1","within_ms":5000,"force":false}"#,
                br#"{"envelope":{"v":2,"key_id":"k","payload_b64":"e30=","timestamp":1,"nonce":"nonce-123","signature":"AA=="}}"#,
                b"{}",
            ]
            .map(<[u8]>::to_vec)
            .to_vec(),
        }
    }
}

impl Default for Readers {
    fn default() -> Self {
        Self::new()
    }
}

/// Tokens of each format that mutations splice in.
fn dictionary(target: Target) -> &'static [&'static str] {
    match target {
        Target::Pnml => &[
            "<place id=\"p\">",
            "</place>",
            "<page id=\"q\">",
            "</page>",
            "<!DOCTYPE a [<!ENTITY e \"xxxxxxxx\">]>",
            "&e;",
            "<![CDATA[",
            "&#x0;",
            "<arc source=\"p\" target=\"t\"/>",
        ],
        Target::Guard => &[
            "&&",
            "||",
            "(",
            ")",
            "!",
            "rise(",
            "fall(",
            ".t",
            ">=",
            "1s",
            "99999999999999999999",
            "P10",
        ],
        Target::ProgramToml => &[
            "[[input]]",
            "[[action]]",
            "[guards]",
            "qualifier = \"L\"",
            "duration = \"1h\"",
            "\"",
            "=",
            "\n[program]\n",
        ],
        Target::Package => &["{", "}", "\"payload\":", "\"signature\":null", "=="],
        Target::StateJson => &[
            "{",
            "}",
            "[",
            "]",
            "18446744073709551615",
            "-1",
            "null",
            "\"B\"",
        ],
        Target::Command => &[
            "{",
            "}",
            "\"envelope\":",
            "\"reply_to\":",
            "\"within_ms\":18446744073709551615",
            "[",
            "\"when\":\"",
        ],
    }
}

/// A seeded xorshift generator: every round is reproducible from its seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// One mutation of `seed`.
fn mutate(rng: &mut Rng, target: Target, seed: &[u8]) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let at = rng.below(v.len() + 1);
        match rng.below(7) {
            0 if !v.is_empty() => {
                let i = rng.below(v.len());
                v[i] ^= 1 << rng.below(8);
            }
            1 => v.insert(at, rng.next() as u8),
            2 if !v.is_empty() => {
                let end = (at + 1 + rng.below(16)).min(v.len());
                v.drain(at.min(end)..end);
            }
            3 => {
                let d = dictionary(target);
                let tok = d[rng.below(d.len())].as_bytes();
                v.splice(at..at, tok.iter().copied());
            }
            4 if !v.is_empty() => {
                let start = rng.below(v.len());
                let end = (start + 1 + rng.below(64)).min(v.len());
                let chunk = v[start..end].to_vec();
                v.splice(at..at, chunk);
            }
            // The shapes that once overflowed a stack: long chains and deep nesting.
            5 => {
                let unit: &[u8] = match target {
                    Target::Guard => b"PE && ",
                    Target::Pnml => b"<page id=\"x\">",
                    _ => b"[",
                };
                let n = 1 + rng.below(20_000);
                let grown: Vec<u8> = unit.iter().copied().cycle().take(unit.len() * n).collect();
                v.splice(at..at, grown);
            }
            _ => {
                let n = 1 + rng.below(5_000);
                v.splice(at..at, std::iter::repeat_n(b'(', n));
            }
        }
    }
    v
}

/// Fuzzes `target` for `budget`, from `seed`; panicking inputs go to `corpus/<target>/` when a
/// corpus directory is given.
pub fn round(
    readers: &Readers,
    target: Target,
    budget: Duration,
    seed: u64,
    corpus: Option<&Path>,
) -> Round {
    let seeds = readers.seeds(target);
    let mut rng = Rng(seed | 1);
    let mut r = Round::default();
    let start = Instant::now();
    // The panic hook would print every finding; the round reports them instead.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    while start.elapsed() < budget {
        let base = &seeds[rng.below(seeds.len())];
        let input = mutate(&mut rng, target, base);
        r.execs += 1;
        if !readers.run(target, &input) {
            r.panics += 1;
            if let Some(dir) = corpus {
                let d = dir.join(target.name());
                let _ = std::fs::create_dir_all(&d);
                let _ = std::fs::write(d.join(format!("crash-{seed:x}-{}", r.execs)), &input);
            }
            if r.found.len() < 4 {
                r.found.push(input);
            }
        }
    }
    std::panic::set_hook(hook);
    r.execs_per_s = r.execs as f64 / start.elapsed().as_secs_f64().max(1e-9);
    r
}

/// Every target for `budget` each.
pub fn all(budget: Duration, seed: u64, corpus: Option<&Path>) -> BTreeMap<Target, Round> {
    let readers = Readers::new();
    Target::ALL
        .into_iter()
        .map(|t| (t, round(&readers, t, budget, seed, corpus)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A short seeded round of every reader, and every input kept in the corpus: none panics.
    #[test]
    fn no_reader_panics_on_a_seeded_round_or_on_the_kept_corpus() {
        let readers = Readers::new();
        for t in Target::ALL {
            let r = round(&readers, t, Duration::from_millis(300), 0x5eed, None);
            assert_eq!(
                r.panics,
                0,
                "{t:?} panicked on {:?}",
                r.found.first().map(|f| String::from_utf8_lossy(f)
                    .chars()
                    .take(200)
                    .collect::<String>())
            );
            assert!(r.execs > 0);
            let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("fuzz-corpus")
                .join(t.name());
            for entry in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
                let input = std::fs::read(entry.path()).expect("a corpus file");
                assert!(readers.run(t, &input), "{}", entry.path().display());
            }
        }
    }
}
