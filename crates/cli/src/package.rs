//! `cetratus package`: make signing keys, build signed update packages, inspect and verify them.
//!
//! The formats (manifest, package file, key files) are in `docs/package-format.md`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use cetratus_program::package::{build_package_with, BuildReport};
use cetratus_program::PackageError;
use cetratus_program::{KeyPair, Program, TrustStore, UpdatePackage};

/// Arguments of `cetratus package`.
#[derive(clap::Args, Debug)]
pub struct PackageArgs {
    /// What to do.
    #[command(subcommand)]
    pub command: PackageCommand,
}

/// The `cetratus package` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum PackageCommand {
    /// Make a signing key: FILE holds the secret (mode 0600), FILE.pub the public key to copy into
    /// each PLC's trust directory.
    Keygen(KeygenArgs),
    /// Build an update package from a manifest (`*.package.toml`) and print its transformation.
    Build(BuildArgs),
    /// Show what a package contains (without checking its signature).
    Inspect(InspectArgs),
    /// Check a package's signature against trusted keys and, with --base, that it fits a program;
    /// exits non-zero with the reason when it does not.
    Verify(VerifyArgs),
}

/// Arguments of `cetratus package keygen`.
#[derive(clap::Args, Debug)]
pub struct KeygenArgs {
    /// The secret key file to write; the public key goes to FILE.pub. Neither may exist.
    #[arg(long, short, value_name = "FILE")]
    pub out: PathBuf,
}

/// Arguments of `cetratus package build`.
#[derive(clap::Args, Debug)]
pub struct BuildArgs {
    /// The package manifest (TOML).
    pub manifest: PathBuf,
    /// The secret key to sign with (from `cetratus package keygen`).
    #[arg(long, value_name = "FILE", required_unless_present = "unsigned")]
    pub key: Option<PathBuf>,
    /// Where to write the package.
    #[arg(long, short, value_name = "OUT")]
    pub out: PathBuf,
    /// Build without a signature (a PLC accepts it only with --allow-unsigned).
    #[arg(long, conflicts_with = "key")]
    pub unsigned: bool,
}

/// Arguments of `cetratus package inspect`.
#[derive(clap::Args, Debug)]
pub struct InspectArgs {
    /// The package file.
    pub package: PathBuf,
    /// Also resolve the transformation against this program and print the matrices.
    #[arg(long, value_name = "PROGRAM")]
    pub base: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Arguments of `cetratus package verify`.
#[derive(clap::Args, Debug)]
pub struct VerifyArgs {
    /// The package file.
    pub package: PathBuf,
    /// Directory of trusted public keys (`*.pub`).
    #[arg(long, value_name = "DIR")]
    pub trust: Option<PathBuf>,
    /// Also check that the package resolves against this program (the one it will replace).
    #[arg(long, value_name = "PROGRAM")]
    pub base: Option<PathBuf>,
    /// Accept a package without a signature.
    #[arg(long)]
    pub allow_unsigned: bool,
    /// With --base: accept a package built against another program.
    #[arg(long, requires = "base")]
    pub force: bool,
}

/// Runs `cetratus package`.
pub fn run(args: &PackageArgs) -> anyhow::Result<()> {
    match &args.command {
        PackageCommand::Keygen(a) => keygen(a),
        PackageCommand::Build(a) => build(a),
        PackageCommand::Inspect(a) => crate::package_inspect::inspect(a),
        PackageCommand::Verify(a) => verify(a),
    }
}

fn keygen(a: &KeygenArgs) -> anyhow::Result<()> {
    let key = KeyPair::try_generate()?;
    key.save(&a.out)?;
    println!("key id      {}", key.key_id());
    println!("secret key  {}  (keep it private)", a.out.display());
    println!(
        "public key  {}  (copy it into each PLC's trust directory)",
        KeyPair::public_path(&a.out).display()
    );
    Ok(())
}

fn build(a: &BuildArgs) -> anyhow::Result<()> {
    let key = match &a.key {
        Some(path) => Some(
            KeyPair::load(path)
                .with_context(|| format!("cannot load the key {}", path.display()))?,
        ),
        None => None,
    };
    // SOURCE_DATE_EPOCH makes `created`, and so the package, reproducible.
    let secs = match std::env::var("SOURCE_DATE_EPOCH") {
        Ok(s) => s
            .trim()
            .parse()
            .with_context(|| format!("SOURCE_DATE_EPOCH `{s}` is not a number of seconds"))?,
        Err(_) => std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs()),
    };
    // A manifest may name PLCopen XML files, imported as `cetratus import plcopen` does.
    let importer = cetratus_sfc::IecImporter;
    let (bytes, report) = build_package_with(&a.manifest, key.as_ref(), secs, Some(&importer))?;
    write_file(&a.out, &bytes)?;
    print_report(&report);
    println!("wrote {} ({} bytes)", a.out.display(), bytes.len());
    Ok(())
}

/// Writes next to the target and renames, so a reader never sees half a package.
fn write_file(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".part");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

fn print_report(r: &BuildReport) {
    println!("package     {} {}", r.meta.name, r.meta.version);
    if !r.meta.author.is_empty() {
        println!("author      {}", r.meta.author);
    }
    println!("created     {}", r.meta.created);
    println!(
        "program     {} {}  {}",
        r.program_name, r.program_version, r.program_hash
    );
    println!(
        "base        {}  {}",
        r.base_program, r.meta.base_program_hash
    );
    match &r.signer {
        Some(k) => println!("signed by   {k}"),
        None => println!("signed by   nobody (unsigned)"),
    }
    println!();
    println!(
        "state transform ({}): M_new = ST·M_old + ST_base  (rows: new places, columns: old places)",
        r.transform_kind
    );
    print!("{}", r.transform);
    println!();
    println!(
        "projection ({}): Π·M_cand + Π_base  (rows: old places, columns: new places)",
        r.projection_kind
    );
    print!("{}", r.projection);
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
}

pub(crate) fn read(path: &Path) -> anyhow::Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))
}

pub(crate) fn load_program(path: &Path) -> anyhow::Result<Program> {
    Program::load(path).with_context(|| format!("cannot load the program {}", path.display()))
}

fn verify(a: &VerifyArgs) -> anyhow::Result<()> {
    let bytes = read(&a.package)?;
    let trust = match &a.trust {
        Some(dir) => TrustStore::load_dir(dir)
            .with_context(|| format!("cannot load the trust directory {}", dir.display()))?,
        None => TrustStore::empty(),
    };
    let pkg = match UpdatePackage::verify(
        &bytes,
        &trust,
        cetratus_program::Unsigned::allowed_if(a.allow_unsigned),
    ) {
        Ok(p) => p,
        Err(e @ PackageError::UnknownSigner { .. }) if a.trust.is_none() => {
            bail!(
                "{} refused: {e} (no --trust DIR was given, so no key is trusted)",
                a.package.display()
            )
        }
        Err(e) => return Err(e).with_context(|| format!("{} refused", a.package.display())),
    };
    let m = pkg.meta();
    match pkg.signer() {
        Some(k) => println!("signature   good, by trusted key {k}"),
        None => println!("signature   none (unsigned, allowed by --allow-unsigned)"),
    }
    println!(
        "package     {} {}  sha256 {}",
        m.name,
        m.version,
        UpdatePackage::file_hash_hex(&bytes)
    );
    println!(
        "program     {} {}  {}",
        pkg.program().name(),
        pkg.program().version(),
        pkg.program().hash_hex()
    );
    if let Some(base) = &a.base {
        let old = load_program(base)?;
        let up = pkg
            .resolve(&old, cetratus_program::OtherBase::forced_if(a.force))
            .with_context(|| format!("{} does not fit {}", a.package.display(), base.display()))?;
        println!(
            "resolves    against {} {}: transform {}×{}, projection {}×{}",
            old.name(),
            old.version(),
            up.transform.rows(),
            up.transform.cols(),
            up.projection.rows(),
            up.projection.cols()
        );
        // The marking at load time is the PLC's, not M0; M0 is only a hint, so this is a note.
        let m0 = old.net().initial_marking();
        let mut out = vec![0; up.transform.rows()];
        if let Err(e) = up.transform.apply(m0.as_slice(), &up.program, &mut out) {
            eprintln!(
                "note: at the initial marking of {}, the transform is refused: {e}",
                base.display()
            );
        }
    }
    println!("ok");
    Ok(())
}
