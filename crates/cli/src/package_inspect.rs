//! `cetratus package inspect`: what a package holds, shown without trusting or loading it.

use anyhow::Context;
use cetratus_program::{package, DenseMatrix, TransformSpec};
use serde_json::json;

use crate::package::{load_program, read, InspectArgs};

/// Runs `cetratus package inspect`.
pub fn inspect(a: &InspectArgs) -> anyhow::Result<()> {
    let bytes = read(&a.package)?;
    let info =
        package::inspect(&bytes).with_context(|| format!("cannot read {}", a.package.display()))?;
    let resolved = match &a.base {
        None => None,
        Some(base) => {
            let old = load_program(base)?;
            let matches = old.hash_hex() == info.meta.base_program_hash;
            // Resolved as if forced, whoever signed it: inspect shows, it never loads anything.
            let up = info.resolve_for_display(&old).with_context(|| {
                format!(
                    "{} does not resolve against {}",
                    a.package.display(),
                    base.display()
                )
            })?;
            Some((old, matches, up))
        }
    };
    if a.json {
        let mut v = json!({
            "file_sha256": info.hash_hex,
            "meta": info.meta,
            "claimed_signer": info.claimed_signer,
            "signature_checked": false,
            "program": {
                "name": info.program.name(),
                "version": info.program.version(),
                "hash": info.program.hash_hex(),
                "places": info.program.net().num_places(),
                "transitions": info.program.net().num_transitions(),
            },
            "transform": info.transform,
            "projection": info.projection,
        });
        if let Some((old, matches, up)) = &resolved {
            v["resolved"] = json!({
                "base": { "name": old.name(), "version": old.version(), "hash": old.hash_hex(),
                          "is_the_packages_base": matches },
                "transform": up.0.to_dense(),
                "projection": up.1.to_dense(),
            });
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    let m = &info.meta;
    println!("package     {} {}", m.name, m.version);
    if !m.author.is_empty() {
        println!("author      {}", m.author);
    }
    if !m.description.is_empty() {
        println!("description {}", m.description);
    }
    println!("created     {}", m.created);
    println!("file sha256 {}", info.hash_hex);
    match &info.claimed_signer {
        Some(k) => println!(
            "signed by   {k}  (not checked here; `cetratus package verify --trust DIR` checks it)"
        ),
        None => println!("signed by   nobody (unsigned)"),
    }
    let p = &info.program;
    println!(
        "program     {} {}  {}  ({} places, {} transitions)",
        p.name(),
        p.version(),
        p.hash_hex(),
        p.net().num_places(),
        p.net().num_transitions()
    );
    println!("built for   program {}", m.base_program_hash);
    print_changes(m);
    println!();
    match &resolved {
        Some((old, matches, up)) => {
            if !matches {
                println!(
                    "note: {} is not the program this package was built against; shown as if forced",
                    old.name()
                );
            }
            println!(
                "state transform ({}), resolved against {} {}:",
                info.transform.kind(),
                old.name(),
                old.version()
            );
            print!("{}", up.0.to_dense());
            println!();
            let kind = info
                .projection
                .as_ref()
                .map_or("generated", TransformSpec::kind);
            println!("projection ({kind}):");
            print!("{}", up.1.to_dense());
        }
        None => {
            println!("state transform:");
            print_spec(&info.transform, "new", "old");
            println!("projection:");
            match &info.projection {
                Some(s) => print_spec(s, "old", "new"),
                None => println!("  generated: each place kept by id reads itself"),
            }
            println!("(add --base PROGRAM to see the matrices resolved against a program)");
        }
    }
    Ok(())
}

/// A declared transformation, as far as it can be shown without the running program.
/// What the package declares it changes on purpose (`[changes]`, signed with it).
fn print_changes(m: &cetratus_program::PackageMeta) {
    if !m.changes.outputs.is_empty() {
        println!("changes     outputs {}", m.changes.outputs.join(", "));
    }
    if let Some(share) = m.declared_share() {
        println!(
            "changes     production may drop to {:.0} % of the old program's",
            share * 100.0
        );
    }
}

fn print_spec(spec: &TransformSpec, rows: &str, cols: &str) {
    match spec {
        TransformSpec::Generated { removed } => {
            println!("  generated: places kept by id keep their tokens and timers, new places start at their initial marking");
            for (from, to) in removed {
                println!("  removed place {from}: its tokens go to {to}");
            }
        }
        TransformSpec::Dense {
            rows: r,
            cols: c,
            matrix,
            base,
        } => {
            println!("  dense (rows: {rows} places, columns: {cols} places)");
            let d = DenseMatrix {
                row_ids: r.clone(),
                col_ids: c.clone(),
                matrix: matrix.clone(),
                base: base.clone().unwrap_or_else(|| vec![0; r.len()]),
            };
            for line in d.to_string().lines() {
                println!("  {line}");
            }
        }
        TransformSpec::Sparse {
            entries,
            base,
            identity_on_kept,
        } => {
            println!("  sparse (to: {rows} place, from: {cols} place)");
            if *identity_on_kept {
                println!("  identity on every place both nets have");
            }
            for e in entries {
                println!("  {} <- {}·{}", e.to, e.coef, e.from);
            }
            for (p, b) in base {
                println!("  base {p} = {b}");
            }
        }
    }
}
