//! Update packages seen from outside: the Vernadat U.1 and U.2 packages build, verify, resolve and
//! transform as the paper says, and every bad package or transform is refused with a clear error
//! and leaves the caller's state alone.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use cetratus_net::{NetBuilder, Place, Tokens};
use cetratus_program::package::PackageError;
use cetratus_program::{
    build_package, KeyPair, Program, StateTransform, TransformError, TrustStore, UpdatePackage,
};
use cetratus_testkit::{paths, programs};

const IDS: [&str; 13] = [
    "H", "B", "R", "P10", "P11", "P12", "P13", "P14", "P20", "P21", "P22", "P23", "P24",
];

fn ok<T, E: std::fmt::Display>(r: Result<T, E>) -> T {
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn ids() -> Vec<String> {
    IDS.iter().map(|s| s.to_string()).collect()
}

fn identity(n: usize) -> Vec<Vec<i64>> {
    (0..n)
        .map(|r| (0..n).map(|c| i64::from(r == c)).collect())
        .collect()
}

/// A fresh key saved in a temp dir whose `.pub` is the only trusted key.
struct Signer {
    dir: tempfile::TempDir,
    key: KeyPair,
}

impl Signer {
    fn new() -> Self {
        let dir = ok(tempfile::tempdir());
        let key = KeyPair::generate();
        ok(key.save(&dir.path().join("signer.key")));
        // Loaded back from disk, as the CLI does.
        let key = ok(KeyPair::load(&dir.path().join("signer.key")));
        Signer { dir, key }
    }
    fn trust(&self) -> TrustStore {
        ok(TrustStore::load_dir(self.dir.path()))
    }
    fn build(&self, manifest: &Path) -> (Vec<u8>, cetratus_program::BuildReport) {
        ok(build_package(manifest, Some(&self.key), 1_700_000_000))
    }
}

/// Writes a manifest for the U.1 program against the Vernadat base with this `[transform]`.
fn u1_manifest(dir: &Path, transform: &str) -> PathBuf {
    let text = format!(
        "[package]\nname = \"t\"\nversion = \"1\"\nprogram = {:?}\nbase = {:?}\n{transform}",
        paths::example("vernadat/u1.toml").display().to_string(),
        paths::example("vernadat/vernadat.toml")
            .display()
            .to_string(),
    );
    let path = dir.join("t.package.toml");
    ok(std::fs::write(&path, text));
    path
}

#[test]
fn u1_dense_transform_gives_h_plus_two_with_other_places_equal() {
    let s = Signer::new();
    let (bytes, report) = s.build(&paths::example("vernadat/u1.package.toml"));
    assert_eq!(report.transform_kind, "dense");
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    let pkg = ok(UpdatePackage::verify(
        &bytes,
        &s.trust(),
        cetratus_program::Unsigned::Refused,
    ));
    assert_eq!(pkg.signer(), Some(s.key.key_id().as_str()));
    let old = programs::example("vernadat/vernadat.toml");
    let up = ok(pkg.resolve(&old, cetratus_program::OtherBase::Refused));
    assert_eq!((up.transform.rows(), up.transform.cols()), (13, 13));

    let m_old = old.net().initial_marking();
    let mut m_new = [0; 13];
    ok(up
        .transform
        .apply(m_old.as_slice(), &up.program, &mut m_new));
    assert_eq!(m_new[0], m_old.as_slice()[0] + 2, "H grows by two");
    assert_eq!(m_new[1..], m_old.as_slice()[1..], "the other places keep");
    assert_eq!(
        up.projection.drift(&m_new, m_old.as_slice()),
        0,
        "H - 2 projects back"
    );

    // Any marking of the old invariants, not only M0: one part unloading M1 (P14) with H=3, B=3.
    let m = [3, 3, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0];
    ok(old.check_invariants(&m));
    ok(up.transform.apply(&m, &up.program, &mut m_new));
    assert_eq!(m_new, [5, 3, 0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 0]);
}

#[test]
fn u2_generated_transform_is_the_identity_over_a_zero_block() {
    let s = Signer::new();
    let (bytes, report) = s.build(&paths::example("vernadat/u2.package.toml"));
    assert_eq!(report.transform_kind, "generated");
    let mut expected = identity(13);
    expected.extend([vec![0; 13], vec![0; 13]]);
    assert_eq!(report.transform.matrix, expected, "[I13; 0(2x13)]");
    assert_eq!(report.transform.base, vec![0; 15]);
    assert_eq!(report.transform.col_ids, ids());
    let mut rows = ids();
    rows.extend(["P30".to_string(), "P31".to_string()]);
    assert_eq!(report.transform.row_ids, rows);

    let pkg = ok(UpdatePackage::verify(
        &bytes,
        &s.trust(),
        cetratus_program::Unsigned::Refused,
    ));
    let old = programs::example("vernadat/u1.toml");
    let up = ok(pkg.resolve(&old, cetratus_program::OtherBase::Refused));
    assert_eq!(up.transform.to_dense(), report.transform);
    assert_eq!((up.transform.rows(), up.transform.cols()), (15, 13));

    // The declared projection reads P30 as P13 and P31 as P23, and the kept places as themselves.
    let pi = up.projection.to_dense();
    assert_eq!((pi.row_ids.len(), pi.col_ids.len()), (13, 15));
    assert_eq!(pi.matrix[6][13], 1, "P13 <- P30");
    assert_eq!(pi.matrix[11][14], 1, "P23 <- P31");
    for (r, row) in pi.matrix.iter().enumerate() {
        assert_eq!(row[r], 1, "identity on kept place {}", IDS[r]);
    }
    // A candidate lubricating M1 (P30) while the primary's M1 part is ready (P13): no drift.
    let primary = [6, 3, 1, 0, 0, 0, 1, 0, 1, 0, 0, 0, 0];
    let candidate = [6, 3, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0];
    assert_eq!(up.projection.drift(&candidate, &primary), 0);
}

#[test]
fn a_package_file_says_who_signed_it_and_hashes_its_bytes() {
    let s = Signer::new();
    let (bytes, report) = s.build(&paths::example("vernadat/u2.package.toml"));
    let pkg = ok(UpdatePackage::verify(
        &bytes,
        &s.trust(),
        cetratus_program::Unsigned::Refused,
    ));
    assert_eq!(pkg.meta().name, "U.2 lubrication");
    assert_eq!(pkg.meta().created, "2023-11-14T22:13:20Z");
    assert_eq!(
        pkg.meta().base_program_hash,
        programs::example("vernadat/u1.toml").hash_hex()
    );
    assert_eq!(
        pkg.program().hash_hex(),
        programs::example("vernadat/u2.toml").hash_hex()
    );
    assert_eq!(pkg.program().hash_hex(), report.program_hash);
    assert_eq!(UpdatePackage::file_hash_hex(&bytes).len(), 64);
    let info = ok(cetratus_program::package::inspect(&bytes));
    assert_eq!(
        info.claimed_signer.as_deref(),
        Some(s.key.key_id().as_str())
    );
    assert_eq!(info.hash_hex, UpdatePackage::file_hash_hex(&bytes));
}

#[test]
fn a_tampered_package_is_refused() {
    let s = Signer::new();
    let (bytes, _) = s.build(&paths::example("vernadat/u1.package.toml"));
    let mut doc: serde_json::Value = ok(serde_json::from_slice(&bytes));
    let b64 = base64::engine::general_purpose::STANDARD;
    let mut payload = ok(b64.decode(doc["payload"].as_str().unwrap_or_default()));
    // Flip one bit inside the program text: still valid JSON, so only the signature catches it.
    let at = payload.len() / 2;
    payload[at] ^= 0x01;
    doc["payload"] = serde_json::Value::String(b64.encode(&payload));
    let tampered = ok(serde_json::to_vec(&doc));
    let err = UpdatePackage::verify(&tampered, &s.trust(), cetratus_program::Unsigned::Refused)
        .unwrap_err();
    assert!(matches!(err, PackageError::BadSignature { .. }), "{err}");
    assert!(err.to_string().contains("altered"), "{err}");

    // A flipped byte in the file itself is refused too, whatever it hits.
    let mut raw = bytes.clone();
    let at = raw.len() / 2;
    raw[at] ^= 0x01;
    assert!(UpdatePackage::verify(&raw, &s.trust(), cetratus_program::Unsigned::Refused).is_err());
}

#[test]
fn a_truncated_package_is_refused() {
    let s = Signer::new();
    let (bytes, _) = s.build(&paths::example("vernadat/u1.package.toml"));
    for len in [0, 1, bytes.len() / 2, bytes.len() - 3] {
        let err = UpdatePackage::verify(
            &bytes[..len],
            &s.trust(),
            cetratus_program::Unsigned::Refused,
        )
        .unwrap_err();
        assert!(matches!(err, PackageError::Malformed { .. }), "{err}");
        assert!(err.to_string().contains("truncated"), "{err}");
    }
}

#[test]
fn an_unsigned_package_is_refused_unless_allowed() {
    let (bytes, report) = ok(build_package(
        &paths::example("vernadat/u2.package.toml"),
        None,
        1_700_000_000,
    ));
    assert_eq!(report.signer, None);
    let err = UpdatePackage::verify(
        &bytes,
        &TrustStore::empty(),
        cetratus_program::Unsigned::Refused,
    )
    .unwrap_err();
    assert!(matches!(err, PackageError::Unsigned), "{err}");
    let pkg = ok(UpdatePackage::verify(
        &bytes,
        &TrustStore::empty(),
        cetratus_program::Unsigned::Allowed,
    ));
    assert_eq!(pkg.signer(), None);
}

#[test]
fn a_package_signed_by_an_unknown_key_is_refused() {
    let s = Signer::new();
    let (bytes, _) = s.build(&paths::example("vernadat/u1.package.toml"));
    let other = Signer::new();
    for trust in [TrustStore::empty(), other.trust()] {
        let err =
            UpdatePackage::verify(&bytes, &trust, cetratus_program::Unsigned::Allowed).unwrap_err();
        assert!(matches!(err, PackageError::UnknownSigner { .. }), "{err}");
        assert!(err.to_string().contains(&s.key.key_id()), "{err}");
    }
}

#[test]
fn a_package_built_against_another_program_is_refused_unless_forced() {
    let s = Signer::new();
    let (bytes, _) = s.build(&paths::example("vernadat/u2.package.toml"));
    let pkg = ok(UpdatePackage::verify(
        &bytes,
        &s.trust(),
        cetratus_program::Unsigned::Refused,
    ));
    // U.2 follows U.1; the cell still running the initial program is another program.
    let initial = programs::example("vernadat/vernadat.toml");
    let err = pkg
        .resolve(&initial, cetratus_program::OtherBase::Refused)
        .unwrap_err();
    assert!(matches!(err, PackageError::BaseMismatch { .. }), "{err}");
    assert!(err.to_string().contains(initial.hash_hex()), "{err}");
    let up = ok(pkg.resolve(&initial, cetratus_program::OtherBase::Forced));
    assert_eq!(up.transform.rows(), 15);
}

#[test]
fn wrong_dimensions_are_refused_naming_them() {
    let (old, new) = (
        programs::example("vernadat/vernadat.toml"),
        programs::example("vernadat/u1.toml"),
    );
    let (on, nn) = (old.net(), new.net());
    let short: Vec<String> = ids()[..12].to_vec();
    let err = StateTransform::dense(on, nn, &short, &ids(), &identity(12), &[0; 12]).unwrap_err();
    assert!(matches!(err, TransformError::Dimensions { .. }), "{err}");
    assert!(
        err.to_string().contains("12") && err.to_string().contains("13"),
        "{err}"
    );

    let mut ragged = identity(13);
    ragged[4].pop();
    let err = StateTransform::dense(on, nn, &ids(), &ids(), &ragged, &[0; 13]).unwrap_err();
    assert!(err.to_string().contains("row 5 (`P11`)"), "{err}");

    let err = StateTransform::dense(on, nn, &ids(), &ids(), &identity(13), &[0; 12]).unwrap_err();
    assert!(matches!(err, TransformError::BaseLength { .. }), "{err}");

    // The same mistake in a manifest is refused at build time, naming the manifest.
    let dir = ok(tempfile::tempdir());
    let m = u1_manifest(
        dir.path(),
        "[transform]\nkind = \"dense\"\nrows = [\"H\"]\ncols = [\"H\"]\nmatrix = [[1]]\n",
    );
    let err = build_package(&m, None, 1_700_000_000).unwrap_err();
    assert!(
        matches!(err, PackageError::ManifestTransform { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("t.package.toml"), "{err}");
}

#[test]
fn wrong_place_ids_are_refused_naming_them() {
    let (old, new) = (
        programs::example("vernadat/vernadat.toml"),
        programs::example("vernadat/u1.toml"),
    );
    let (on, nn) = (old.net(), new.net());
    let mut swapped = ids();
    swapped.swap(0, 1);
    let err = StateTransform::dense(on, nn, &swapped, &ids(), &identity(13), &[0; 13]).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("row 1") && text.contains("`B`") && text.contains("`H`"),
        "{text}"
    );
    let err = StateTransform::dense(on, nn, &ids(), &swapped, &identity(13), &[0; 13]).unwrap_err();
    assert!(err.to_string().contains("column 1"), "{err}");

    let u2 = programs::example("vernadat/u2.toml");
    let err =
        StateTransform::dense(on, u2.net(), &ids(), &ids(), &identity(13), &[0; 13]).unwrap_err();
    assert!(matches!(err, TransformError::Dimensions { .. }), "{err}");
}

#[test]
fn a_negative_result_is_refused_and_nothing_is_written() {
    let (old, new) = (
        programs::example("vernadat/vernadat.toml"),
        programs::example("vernadat/u1.toml"),
    );
    let mut base = [0i64; 13];
    base[1] = -5; // B has 3 parts
    let st = ok(StateTransform::dense(
        old.net(),
        new.net(),
        &ids(),
        &ids(),
        &identity(13),
        &base,
    ));
    let mut out = [77; 13];
    let err = st
        .apply(old.net().initial_marking().as_slice(), &new, &mut out)
        .unwrap_err();
    assert!(matches!(err, TransformError::Negative { .. }), "{err}");
    assert!(
        err.to_string().contains("`B`") && err.to_string().contains("-2"),
        "{err}"
    );
    assert_eq!(out, [77; 13], "nothing written");
}

#[test]
fn a_count_above_a_capacity_of_the_new_net_is_refused() {
    let net = |cap: Option<Tokens>| {
        let mut b = NetBuilder::new("c");
        let mut p = Place::new("A", 1);
        p.capacity = cap;
        ok(b.add_place(p));
        ok(b.build())
    };
    let src = "[program]\nname = \"c\"\nversion = \"1\"\n";
    let old = ok(Program::from_sources(src, "old.toml", net(None)));
    let new = ok(Program::from_sources(src, "new.toml", net(Some(3))));
    let st = ok(StateTransform::generated(&old, &new, &BTreeMap::new()));
    let mut out = [9];
    let err = st.apply(&[4], &new, &mut out).unwrap_err();
    assert!(matches!(err, TransformError::AboveCapacity { .. }), "{err}");
    assert!(err.to_string().contains("capacity 3"), "{err}");
    assert_eq!(out, [9], "nothing written");
    ok(st.apply(&[3], &new, &mut out));
    assert_eq!(out, [3]);
}

#[test]
fn a_broken_invariant_of_the_new_program_is_refused_naming_it() {
    let (old, new) = (
        programs::example("vernadat/vernadat.toml"),
        programs::example("vernadat/u1.toml"),
    );
    let mut base = [0i64; 13];
    base[0] = 1; // one slot instead of two: H + B + P14 = 8, U.1 declares 9
    let st = ok(StateTransform::dense(
        old.net(),
        new.net(),
        &ids(),
        &ids(),
        &identity(13),
        &base,
    ));
    let mut out = [0; 13];
    let err = st
        .apply(old.net().initial_marking().as_slice(), &new, &mut out)
        .unwrap_err();
    assert!(matches!(err, TransformError::Invariant { .. }), "{err}");
    assert!(err.to_string().contains("H + B + P14 = 9"), "{err}");
    assert_eq!(out, [0; 13], "nothing written");

    // The generated transform derives H + 2 from the invariants, so it keeps U.1's invariant
    // (transform/derive.rs), and a build against the base program has nothing to warn about.
    let st = ok(StateTransform::generated(&old, &new, &BTreeMap::new()));
    ok(st.apply(old.net().initial_marking().as_slice(), &new, &mut out));
    new.check_invariants(&out).expect("H + B + P14 = 9 holds");
    let dir = ok(tempfile::tempdir());
    let m = u1_manifest(dir.path(), "[transform]\nkind = \"generated\"\n");
    let (_, report) = ok(build_package(&m, None, 1_700_000_000));
    assert_eq!(report.warnings, Vec::<String>::new());
}

#[test]
fn a_sparse_transform_in_a_manifest_resolves_like_the_dense_one() {
    let dir = ok(tempfile::tempdir());
    let m = u1_manifest(
        dir.path(),
        "[transform]\nkind = \"sparse\"\nidentity_on_kept = true\nbase = { H = 2 }\n",
    );
    let (_, sparse) = ok(build_package(&m, None, 1_700_000_000));
    let (_, dense) = ok(build_package(
        &paths::example("vernadat/u1.package.toml"),
        None,
        1_700_000_000,
    ));
    assert_eq!(sparse.transform, dense.transform);
    assert_eq!(dense.projection_kind, "sparse");
    assert_eq!(dense.projection.base[0], -2);
    assert!(sparse.warnings.is_empty(), "{:?}", sparse.warnings);
}

#[test]
fn a_manifest_with_an_unknown_key_is_refused_at_its_position() {
    let dir = ok(tempfile::tempdir());
    let m = u1_manifest(dir.path(), "[transform]\nkind = \"dense\"\nrowz = []\n");
    let err = build_package(&m, None, 1_700_000_000).unwrap_err();
    let text = err.to_string();
    // Internally tagged tables are read whole, so the position is that of `[transform]`.
    assert!(
        text.contains("t.package.toml:6:") && text.contains("`rowz`"),
        "{text}"
    );
}

#[test]
fn a_missing_program_file_is_reported_at_the_manifest_line() {
    let dir = ok(tempfile::tempdir());
    let path = dir.path().join("m.toml");
    ok(std::fs::write(
        &path,
        "[package]\nname = \"x\"\nversion = \"1\"\nprogram = \"nope.toml\"\nbase = \"nope.toml\"\n",
    ));
    let err = build_package(&path, None, 1_700_000_000).unwrap_err();
    assert!(err.to_string().contains("m.toml:4:"), "{err}");
}

#[test]
fn declared_changes_are_signed_into_the_package_and_checked_when_it_is_built() {
    let dir = ok(tempfile::tempdir());
    let m = u1_manifest(
        dir.path(),
        "[changes]\noutputs = [\"DM1\"]\nthroughput_share = 0.8\n",
    );
    let s = Signer::new();
    let (bytes, _) = s.build(&m);
    let pkg = ok(UpdatePackage::verify(
        &bytes,
        &s.trust(),
        cetratus_program::Unsigned::Refused,
    ));
    assert_eq!(pkg.meta().changes.outputs, ["DM1"]);
    assert_eq!(pkg.meta().declared_share(), Some(0.8));
    // The older boolean reads as a share of 0, and is written as that.
    let m = u1_manifest(dir.path(), "");
    let text =
        ok(std::fs::read_to_string(&m)).replace("base = ", "changes_throughput = true\nbase = ");
    ok(std::fs::write(&m, text));
    let (_, report) = ok(build_package(&m, None, 1_700_000_000));
    assert!(!report.meta.changes_throughput);
    assert_eq!(report.meta.declared_share(), Some(0.0));
    for (changes, says) in [
        ("[changes]\noutputs = [\"NOPE\"]\n", "`NOPE`"),
        ("[changes]\nthroughput_share = 1.5\n", "between 0 and 1"),
        ("[changes]\ncolour = \"red\"\n", "colour"),
    ] {
        let m = u1_manifest(dir.path(), changes);
        let e = build_package(&m, None, 1_700_000_000)
            .err()
            .unwrap_or_else(|| panic!("{changes} is refused"));
        assert!(e.to_string().contains(says), "{changes}: {e}");
    }
}
