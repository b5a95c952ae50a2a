//! Building a package from its manifest (`*.package.toml`): load both programs, resolve the
//! transformation and the projection, sign.

use super::*;

/// The package manifest (`*.package.toml`).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    package: ManifestPackage,
    #[serde(default)]
    transform: TransformSpec,
    #[serde(default)]
    projection: Option<TransformSpec>,
    /// What the update changes on purpose.
    #[serde(default)]
    changes: Changes,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestPackage {
    name: Spanned<String>,
    version: Spanned<String>,
    #[serde(default)]
    author: String,
    #[serde(default)]
    description: String,
    program: Spanned<String>,
    /// The POU of a PLCopen `program`, when the file has several.
    pou: Option<Spanned<String>>,
    base: Spanned<String>,
    /// The POU of a PLCopen `base`.
    base_pou: Option<Spanned<String>>,
    #[serde(default)]
    changes_throughput: bool,
}

/// What [`build_package`] made, for printing.
#[derive(Clone, Debug)]
pub struct BuildReport {
    /// The metadata written.
    pub meta: PackageMeta,
    /// Name of the new program.
    pub program_name: String,
    /// Version of the new program.
    pub program_version: String,
    /// [`Program::hash_hex`] of the new program.
    pub program_hash: String,
    /// Name and version of the base program.
    pub base_program: String,
    /// `generated`, `dense` or `sparse`.
    pub transform_kind: &'static str,
    /// The transformation resolved against the base program (rows: new places; columns: old).
    pub transform: DenseMatrix,
    /// `generated` when the manifest declares none, else its kind.
    pub projection_kind: &'static str,
    /// The projection resolved against the base program (rows: old places; columns: new).
    pub projection: DenseMatrix,
    /// The key id that signed it, `None` when unsigned.
    pub signer: Option<String>,
    /// Things that do not stop the build but deserve a look.
    pub warnings: Vec<String>,
}

/// Turns a program file of another format into program TOML and PNML text, for a manifest whose
/// `program` or `base` names one: the caller that knows the format gives it (the `cetratus`
/// binary gives the PLCopen SFC importer). The text must be the same for the same file, since
/// the program hash is computed from it.
pub trait ProgramImporter {
    /// `None` when `path` is not in this importer's format; else the program TOML and PNML text
    /// of `pou` (or of the file's only program), or what is wrong with the file.
    fn import(&self, path: &Path, pou: Option<&str>) -> Option<Result<ProgramText, ImportError>>;
}

/// A program file of another format as a program: its TOML and its PNML text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ProgramText {
    /// The program TOML.
    pub toml: String,
    /// The net, as PNML.
    pub pnml: String,
}

/// What an importer found wrong with a file of its format, in its own words (with file:line
/// where it can).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ImportError(pub String);

/// Builds a package from a manifest, signed with `key` (unsigned when `None`), its `created`
/// stamp given in seconds since the Unix epoch: the caller reads the clock (or takes
/// `SOURCE_DATE_EPOCH`, for a reproducible build), so that nothing in this crate does.
pub fn build_package(
    manifest_path: &Path,
    key: Option<&KeyPair>,
    created_unix_secs: u64,
) -> Result<(Vec<u8>, BuildReport), PackageError> {
    build_package_with(manifest_path, key, created_unix_secs, None)
}

/// [`build_package`] with an importer for program files of another format.
pub fn build_package_with(
    manifest_path: &Path,
    key: Option<&KeyPair>,
    created_unix_secs: u64,
    importer: Option<&dyn ProgramImporter>,
) -> Result<(Vec<u8>, BuildReport), PackageError> {
    let label = manifest_path.display().to_string();
    let (text, m) = read_manifest(manifest_path, &label)?;
    let o = Origin::new(&text, &label);
    let at = |offset: usize, message: String| PackageError::Manifest {
        pos: o.pos(offset),
        message,
    };
    let dir = manifest_path.parent().unwrap_or_else(|| Path::new(""));
    let in_manifest = |e: PackageError, v: &Spanned<String>| match e {
        PackageError::Io { path, source } => at(
            v.span().start,
            format!("cannot read `{path}`: {source}; paths are relative to the manifest"),
        ),
        other => other,
    };
    fn pou(p: &Option<Spanned<String>>) -> Option<&str> {
        p.as_ref().map(|s| s.get_ref().as_str())
    }
    let import = |path: &Path, p: &Option<Spanned<String>>, field: &Spanned<String>| {
        importer.and_then(|i| i.import(path, pou(p))).map(|r| {
            r.map(|i| (i.toml, i.pnml))
                .map_err(|e| at(field.span().start, e.0))
        })
    };
    let program_path = dir.join(m.package.program.get_ref());
    let (program_toml, program_pnml) =
        match import(&program_path, &m.package.pou, &m.package.program) {
            Some(r) => r?,
            None => {
                if let Some(p) = &m.package.pou {
                    return Err(at(
                        p.span().start,
                        "`pou` is for a `program` in PLCopen XML; remove it".into(),
                    ));
                }
                program_sources(&program_path).map_err(|e| in_manifest(e, &m.package.program))?
            }
        };
    let base_path = dir.join(m.package.base.get_ref());
    if !base_path.is_file() {
        return Err(at(
            m.package.base.span().start,
            format!(
                "cannot read the base program `{}`; paths are relative to the manifest",
                base_path.display()
            ),
        ));
    }
    let base = match import(&base_path, &m.package.base_pou, &m.package.base) {
        Some(r) => {
            let (toml, pnml) = r?;
            let label = base_path.display().to_string();
            let net = cetratus_net::pnml::read_str(&pnml, &label).map_err(ProgramError::from)?;
            Program::from_sources(&toml, &label, net)?
        }
        None => Program::load(&base_path)?,
    };

    let meta = m
        .package
        .meta(created_unix_secs, &base, &m.changes, &label)?;
    let payload = Payload {
        format: PAYLOAD_FORMAT.to_string(),
        meta: meta.clone(),
        program_toml,
        program_pnml,
        transform: m.transform.clone(),
        projection: m.projection.clone(),
    };
    // The program is taken from the payload, as the PLC will load it, so that what is resolved
    // here is what runs there.
    let new = load_embedded(&payload)?;
    declared_outputs(&meta.changes, &base, &new, &label)?;
    // The PLC checks this again at load; the engineer hears of it at build.
    crate::st::carry_plan(base.st(), new.st(), &meta.changes.variables).map_err(|w| {
        PackageError::ManifestChanges {
            path: label.clone(),
            message: format!("Structured Text variable `{}`: {}", w.name, w.message),
        }
    })?;
    let manifest_err = |section, reason| PackageError::ManifestTransform {
        path: label.clone(),
        section,
        reason: Box::new(reason),
    };
    if let Some(e) = removed_reachable(&base, &new, &payload.transform) {
        return Err(manifest_err("transform", e));
    }
    let transform = resolve_transform(&payload.transform, &base, &new)
        .map_err(|e| manifest_err("transform", e))?;
    let projection = resolve_projection(payload.projection.as_ref(), &base, &new)
        .map_err(|e| manifest_err("projection", e))?;

    let warnings = initial_marking_warnings(&transform, &base, &new);
    let bytes = seal(&payload, key)?;

    let report = BuildReport {
        meta,
        program_name: new.name().to_string(),
        program_version: new.version().to_string(),
        program_hash: new.hash_hex().to_string(),
        base_program: format!("{} {}", base.name(), base.version()),
        transform_kind: payload.transform.kind(),
        transform: transform.to_dense(),
        projection_kind: payload
            .projection
            .as_ref()
            .map_or("generated", TransformSpec::kind),
        projection: projection.to_dense(),
        signer: key.map(KeyPair::key_id),
        warnings,
    };
    Ok((bytes, report))
}

/// What is worth a look before the package goes out: the transform refused on the base
/// program's initial marking (the marking at load time is the PLC's, so not an error).
fn initial_marking_warnings(
    transform: &StateTransform,
    base: &Program,
    new: &Program,
) -> Vec<String> {
    let m0 = base.net().initial_marking();
    let mut out = vec![0; transform.rows()];
    match transform.apply(m0.as_slice(), new, &mut out) {
        Ok(()) => Vec::new(),
        Err(e) => vec![format!(
            "applied to the initial marking of the base program, the transform is refused: {e}"
        )],
    }
}

impl ManifestPackage {
    /// The package's metadata, created at `created_unix_secs`, bound to `base`, with the
    /// changes it declares. `changes_throughput = true` is the older form of
    /// `[changes] throughput_share = 0`, and is written as that.
    fn meta(
        &self,
        created_unix_secs: u64,
        base: &Program,
        changes: &Changes,
        label: &str,
    ) -> Result<PackageMeta, PackageError> {
        let created = std::time::UNIX_EPOCH + std::time::Duration::from_secs(created_unix_secs);
        let mut changes = changes.clone();
        let bad = |message: String| PackageError::ManifestChanges {
            path: label.to_string(),
            message,
        };
        match (self.changes_throughput, changes.throughput_share) {
            (true, Some(_)) => return Err(bad("the manifest gives both `changes_throughput` and `throughput_share`; keep `throughput_share`, which says how far production may drop".into())),
            (true, None) => changes.throughput_share = Some(0.0),
            (false, Some(s)) if !(0.0..=1.0).contains(&s) => return Err(bad(format!("`throughput_share = {s}` is not a share; give one between 0 and 1, e.g. 0.7 for 70 % of the old program's production"))),
            _ => {}
        }
        Ok(PackageMeta {
            name: self.name.get_ref().clone(),
            version: self.version.get_ref().clone(),
            author: self.author.clone(),
            description: self.description.clone(),
            created: humantime::format_rfc3339_seconds(created).to_string(),
            base_program_hash: base.hash_hex().to_string(),
            changes_throughput: false,
            changes,
        })
    }
}

/// Every output `[changes] outputs` names is an output of the new program or of the base.
fn declared_outputs(
    changes: &Changes,
    base: &Program,
    new: &Program,
    label: &str,
) -> Result<(), PackageError> {
    let known = |n: &str| {
        [base, new]
            .iter()
            .any(|p| p.outputs().iter().any(|s| s.name == n))
    };
    match changes.outputs.iter().find(|n| !known(n)) {
        None => Ok(()),
        Some(n) => Err(PackageError::ManifestChanges {
            path: label.to_string(),
            message: format!("`outputs` names `{n}`, which neither the new program nor the base declares as an output; name outputs by their signal names"),
        }),
    }
}

/// The manifest's text and its sections, with a name and a version.
fn read_manifest(path: &Path, label: &str) -> Result<(String, Manifest), PackageError> {
    let bytes = std::fs::read(path).map_err(|source| PackageError::Io {
        path: label.to_string(),
        source,
    })?;
    let text = crate::toml_text(bytes, label).map_err(|e| PackageError::Manifest {
        message: e.message(),
        pos: e.pos,
    })?;
    let o = Origin::new(&text, label);
    let at = |offset: usize, message: String| PackageError::Manifest {
        pos: o.pos(offset),
        message,
    };
    let m: Manifest = toml::from_str(&text).map_err(|e| {
        at(
            e.span().map_or(0, |s| s.start),
            e.message().trim_end().to_string(),
        )
    })?;
    for (field, v) in [("name", &m.package.name), ("version", &m.package.version)] {
        if v.get_ref().trim().is_empty() {
            return Err(at(
                v.span().start,
                format!("the package {field} is empty; give one"),
            ));
        }
    }
    Ok((text, m))
}

/// A step of the old chart that the new one removes, that the old chart can reach, and that a
/// generated transform does not map: a chart whose step vanishes while active would lose its
/// place in the sequence, so the build refuses it.
fn removed_reachable(
    base: &Program,
    new: &Program,
    spec: &TransformSpec,
) -> Option<TransformError> {
    let TransformSpec::Generated { removed } = spec else {
        return None;
    };
    if !base.is_sfc() {
        return None;
    }
    let markable = crate::transform::markable_places(base.net());
    base.net()
        .places()
        .iter()
        .zip(markable)
        .find(|(p, can)| {
            *can && new.net().place_by_id(&p.id).is_none() && !removed.contains_key(&p.id)
        })
        .map(|(p, _)| TransformError::RemovedReachable { id: p.id.clone() })
}

/// The package file: the payload, signed with `key` when there is one, in its envelope.
fn seal(payload: &Payload, key: Option<&KeyPair>) -> Result<Vec<u8>, PackageError> {
    let payload_bytes = serde_json::to_vec(payload).map_err(|e| PackageError::Malformed {
        reason: format!("cannot serialize the payload ({e})"),
    })?;
    let signature = key.map(|k| SignatureBlock {
        key_id: k.key_id(),
        ed25519: B64.encode(k.sign(&payload_bytes).to_bytes()),
    });
    let envelope = Envelope {
        format: PACKAGE_FORMAT.to_string(),
        payload: B64.encode(&payload_bytes),
        signature,
    };
    let mut bytes = serde_json::to_vec_pretty(&envelope).map_err(|e| PackageError::Malformed {
        reason: format!("cannot serialize the package ({e})"),
    })?;
    bytes.push(b'\n');
    Ok(bytes)
}

/// The program TOML text and PNML text of a program file: a `.toml` naming its net, or a
/// `.pnml` carrying the program.
fn program_sources(path: &Path) -> Result<(String, String), PackageError> {
    let label = path.display().to_string();
    let read = |p: &Path| {
        std::fs::read_to_string(p).map_err(|source| PackageError::Io {
            path: p.display().to_string(),
            source,
        })
    };
    let is_pnml = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("pnml") || e.eq_ignore_ascii_case("xml"));
    if is_pnml {
        let text = read(path)?;
        let program = Program::from_pnml_text(&text, &label)?;
        return Ok((program.source().to_string(), text));
    }
    let bytes = std::fs::read(path).map_err(|source| PackageError::Io {
        path: label.clone(),
        source,
    })?;
    let text = crate::toml_text(bytes, &label).map_err(ProgramError::from)?;
    // Loading first reports any problem of the program with its own file positions.
    Program::load(path)?;
    let head: NetOnly = toml::from_str(&text).map_err(|e| ProgramError::File {
        path: label.clone(),
        message: e.message().to_string(),
    })?;
    let Some(net) = head.program.net else {
        return Err(ProgramError::File {
            path: label,
            message: "`[program]` has no `net = \"….pnml\"`".into(),
        }
        .into());
    };
    let net_path = path
        .parent()
        .unwrap_or_else(|| Path::new(""))
        .join(net.get_ref());
    Ok((text, read(&net_path)?))
}

#[cfg(test)]
mod tests {

    #[test]
    fn created_is_rfc3339_utc_to_the_second() {
        let t = |s| {
            humantime::format_rfc3339_seconds(
                std::time::UNIX_EPOCH + std::time::Duration::from_secs(s),
            )
            .to_string()
        };
        assert_eq!(t(0), "1970-01-01T00:00:00Z");
        assert_eq!(t(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(t(1_700_000_000), "2023-11-14T22:13:20Z");
    }
}
