//! Structured fuzzing of the update package reader on stable Rust: `package::inspect` and
//! `UpdatePackage::verify` return a package or an error for any bytes, and never panic; a package
//! that verifies resolves against the running program, and its transform and projection apply to
//! any marking, each with a result or an error. The inputs are arbitrary bytes, and a real unsigned
//! U.1 package whose envelope, metadata, program, net, transform and projection are replaced by
//! hostile ones (matrices of any shape with extreme coefficients, unknown place ids, edited
//! program text, truncated nets).

use std::sync::OnceLock;

use base64::engine::general_purpose::STANDARD as B64;
use base64::Engine as _;
use cetratus_program::package::{build_package, inspect};
use cetratus_program::{Program, TrustStore, UpdatePackage};
use cetratus_testkit::{paths, programs};
use proptest::collection::vec;
use proptest::prelude::*;
use serde_json::{json, Value};

/// The running program the packages are resolved against.
fn vernadat() -> &'static Program {
    static P: OnceLock<Program> = OnceLock::new();
    P.get_or_init(|| programs::example("vernadat/vernadat.toml"))
}

/// The payload of a real unsigned U.1 package, as JSON.
fn u1_payload() -> &'static Value {
    static P: OnceLock<Value> = OnceLock::new();
    P.get_or_init(|| {
        let manifest = paths::example("vernadat/u1.package.toml");
        let (bytes, _) = build_package(&manifest, None, 1_700_000_000)
            .unwrap_or_else(|e| panic!("U.1 builds: {e}"));
        let envelope: Value = serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("{e}"));
        let b64 = envelope["payload"].as_str().unwrap_or_default();
        let payload = B64.decode(b64).unwrap_or_else(|e| panic!("{e}"));
        serde_json::from_slice(&payload).unwrap_or_else(|e| panic!("{e}"))
    })
}

const IDS: &[&str] = &[
    "H", "B", "R", "P10", "P11", "P12", "P13", "P14", "P20", "P21", "P22", "P23", "P24", "P99", "",
];

fn coefficient() -> impl Strategy<Value = i64> {
    prop_oneof![
        4 => -2..3i64,
        1 => Just(i64::MAX),
        1 => Just(i64::MIN),
        1 => any::<i64>(),
    ]
}

fn ids(max: usize) -> impl Strategy<Value = Vec<&'static str>> {
    prop_oneof![
        // The real ids in order, now and then with one changed.
        (any::<prop::sample::Index>(), prop::sample::select(IDS)).prop_map(|(i, id)| {
            let mut v: Vec<&str> = IDS[..13].to_vec();
            if id == "P99" {
                let at = i.index(v.len());
                v[at] = id;
            }
            v
        }),
        vec(prop::sample::select(IDS), 0..max),
    ]
}

/// A transform or projection spec of any kind and shape.
fn spec() -> impl Strategy<Value = Value> {
    let dense = (
        ids(16),
        ids(16),
        vec(vec(coefficient(), 0..15), 0..15),
        prop::option::of(vec(coefficient(), 0..15)),
    )
        .prop_map(|(rows, cols, matrix, base)| {
            let mut v = json!({"kind": "dense", "rows": rows, "cols": cols, "matrix": matrix});
            if let Some(b) = base {
                v["base"] = json!(b);
            }
            v
        });
    let identity_dense = (ids(16), coefficient(), vec(coefficient(), 13)).prop_map(|(ids, k, base)| {
        let n = ids.len();
        let matrix: Vec<Vec<i64>> = (0..n)
            .map(|r| (0..n).map(|c| if r == c { k } else { 0 }).collect())
            .collect();
        json!({"kind": "dense", "rows": ids, "cols": ids, "matrix": matrix, "base": base[..n.min(13)]})
    });
    let sparse = (
        vec((prop::sample::select(IDS), prop::sample::select(IDS), coefficient()), 0..8),
        vec((prop::sample::select(IDS), coefficient()), 0..4),
        any::<bool>(),
    )
        .prop_map(|(entries, base, identity)| {
            let entries: Vec<Value> = entries
                .into_iter()
                .map(|(to, from, coef)| json!({"to": to, "from": from, "coef": coef}))
                .collect();
            let base: serde_json::Map<String, Value> =
                base.into_iter().map(|(k, v)| (k.to_string(), json!(v))).collect();
            json!({"kind": "sparse", "entries": entries, "base": base, "identity_on_kept": identity})
        });
    let generated =
        vec((prop::sample::select(IDS), prop::sample::select(IDS)), 0..3).prop_map(|removed| {
            let removed: serde_json::Map<String, Value> = removed
                .into_iter()
                .map(|(k, v)| (k.to_string(), json!(v)))
                .collect();
            json!({"kind": "generated", "removed": removed})
        });
    prop_oneof![dense, identity_dense, sparse, generated, json_value()]
}

/// Any small JSON value.
fn json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(|i| json!(i)),
        any::<f64>().prop_map(|f| json!(f)),
        "\\PC{0,12}".prop_map(Value::String),
    ];
    leaf.prop_recursive(3, 16, 4, |inner| {
        prop_oneof![
            vec(inner.clone(), 0..4).prop_map(Value::Array),
            vec(("[a-z_]{1,8}", inner), 0..4)
                .prop_map(|kv| Value::Object(kv.into_iter().collect())),
        ]
    })
}

/// An edit of a text: a range cut out, or the text cut short.
fn text_edit() -> impl Strategy<Value = (prop::sample::Index, usize, bool)> {
    (any::<prop::sample::Index>(), 0..200usize, any::<bool>())
}

fn edit_text(text: &str, (at, len, truncate): &(prop::sample::Index, usize, bool)) -> String {
    let mut at = at.index(text.len() + 1);
    while !text.is_char_boundary(at) {
        at -= 1;
    }
    if *truncate {
        return text[..at].to_string();
    }
    let mut end = (at + len).min(text.len());
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}{}", &text[..at], &text[end..])
}

/// What to change in the U.1 payload.
#[derive(Clone, Debug)]
struct Mutation {
    transform: Option<Value>,
    projection: Option<Option<Value>>,
    meta_field: Option<(prop::sample::Index, Value)>,
    toml_edit: Option<(prop::sample::Index, usize, bool)>,
    pnml_edit: Option<(prop::sample::Index, usize, bool)>,
    format: Option<Value>,
    extra_field: Option<Value>,
}

fn mutation() -> impl Strategy<Value = Mutation> {
    (
        prop::option::of(spec()),
        prop::option::of(prop::option::of(spec())),
        prop::option::weighted(0.2, (any::<prop::sample::Index>(), json_value())),
        prop::option::weighted(0.2, text_edit()),
        prop::option::weighted(0.2, text_edit()),
        prop::option::weighted(0.05, json_value()),
        prop::option::weighted(0.05, json_value()),
    )
        .prop_map(
            |(transform, projection, meta_field, toml_edit, pnml_edit, format, extra_field)| {
                Mutation {
                    transform,
                    projection,
                    meta_field,
                    toml_edit,
                    pnml_edit,
                    format,
                    extra_field,
                }
            },
        )
}

fn mutated_package(m: &Mutation, signature: Option<Value>) -> Vec<u8> {
    let mut p = u1_payload().clone();
    if let Some(t) = &m.transform {
        p["transform"] = t.clone();
    }
    match &m.projection {
        None => {}
        Some(None) => p["projection"] = Value::Null,
        Some(Some(s)) => p["projection"] = s.clone(),
    }
    if let (Some((i, v)), Some(meta)) = (&m.meta_field, p["meta"].as_object_mut()) {
        let keys: Vec<String> = meta.keys().cloned().collect();
        meta.insert(keys[i.index(keys.len())].clone(), v.clone());
    }
    for (field, edit) in [
        ("program_toml", &m.toml_edit),
        ("program_pnml", &m.pnml_edit),
    ] {
        if let Some(e) = edit {
            let text = p[field].as_str().unwrap_or_default().to_string();
            p[field] = Value::String(edit_text(&text, e));
        }
    }
    if let Some(f) = &m.format {
        p["format"] = f.clone();
    }
    if let Some(x) = &m.extra_field {
        p["extra"] = x.clone();
    }
    let mut envelope = json!({
        "format": "cetratus-package/1",
        "payload": B64.encode(p.to_string()),
    });
    if let Some(s) = signature {
        envelope["signature"] = s;
    }
    envelope.to_string().into_bytes()
}

/// Reads a package every way a PLC and the CLI do; any of it may fail, none of it may panic.
fn read_every_way(bytes: &[u8], markings: &[Vec<u32>]) {
    let _ = inspect(bytes);
    let _ = UpdatePackage::verify(
        bytes,
        &TrustStore::empty(),
        cetratus_program::Unsigned::Refused,
    );
    let Ok(pkg) = UpdatePackage::verify(
        bytes,
        &TrustStore::empty(),
        cetratus_program::Unsigned::Allowed,
    ) else {
        return;
    };
    for force in [false, true] {
        let Ok(up) = pkg.resolve(vernadat(), cetratus_program::OtherBase::forced_if(force)) else {
            continue;
        };
        let mut out = vec![0; up.program.net().num_places()];
        let mut since = vec![None; out.len()];
        for m in markings {
            if up.transform.apply(m, &up.program, &mut out).is_ok() {
                let old_since: Vec<Option<u64>> = m.iter().map(|_| Some(u64::MAX)).collect();
                up.transform.apply_timers(&old_since, &out, 7, &mut since);
            }
            let _ = up.projection.drift(m, m);
        }
    }
}

fn markings() -> impl Strategy<Value = Vec<Vec<u32>>> {
    let initial = vernadat().net().initial_marking().as_slice().to_vec();
    vec(
        prop_oneof![
            Just(initial),
            vec(
                prop_oneof![Just(0u32), Just(1), Just(u32::MAX), any::<u32>()],
                0..16
            ),
        ],
        1..3,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_are_read_or_refused(bytes in vec(any::<u8>(), 0..400)) {
        read_every_way(&bytes, &[]);
    }

    #[test]
    fn arbitrary_json_is_read_or_refused(v in json_value()) {
        read_every_way(v.to_string().as_bytes(), &[]);
    }

    #[test]
    fn a_real_package_made_hostile_is_read_or_refused(
        m in mutation(),
        signature in prop::option::weighted(0.1, json_value()),
        cut in prop::option::weighted(0.05, any::<prop::sample::Index>()),
        markings in markings(),
    ) {
        let mut bytes = mutated_package(&m, signature);
        if let Some(at) = cut {
            bytes.truncate(at.index(bytes.len()));
        }
        read_every_way(&bytes, &markings);
    }
}
