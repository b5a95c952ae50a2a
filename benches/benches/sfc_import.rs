//! Criterion benches of the PLCopen SFC importer: reading every chart of each reference fixture,
//! importing the charts that import as programs (net, TOML and the loaded program), and the scan
//! of the SFC Vernadat cell (examples/vernadat-sfc) against the Petri-net one, in one run.

use std::hint::black_box;
use std::sync::Arc;

use cetratus_bench::program::{recorded_inputs, vernadat_program};
use cetratus_program::Program;
use cetratus_runtime::Container;
use cetratus_testkit::paths::fixture;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

const FILES: [&str; 6] = [
    "twincat-sfc-evolution-1.xml",
    "twincat-sfc-evolution-6.xml",
    "beremiz-first-steps.xml",
    "iec-checker-example.xml",
    "beremiz-svghmi-traffic-light.xml",
    "codesys-nested-sfc.xml",
];

fn read(name: &str) -> String {
    let path = fixture(&format!("plcopen/{name}"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

fn charts(c: &mut Criterion) {
    let mut g = c.benchmark_group("sfc_charts");
    for name in FILES {
        let text = read(name);
        g.throughput(Throughput::Bytes(text.len() as u64));
        g.bench_function(name, |b| {
            b.iter(|| cetratus_sfc::charts(&text, name).expect("reads"))
        });
    }
    g.finish();
}

fn import(c: &mut Criterion) {
    let mut g = c.benchmark_group("sfc_import");
    for (name, pou) in [
        ("twincat-sfc-evolution-1.xml", None),
        ("twincat-sfc-evolution-6.xml", None),
        ("beremiz-first-steps.xml", Some("CounterSFC")),
        ("codesys-nested-sfc.xml", None),
        ("beremiz-svghmi-traffic-light.xml", None),
    ] {
        let text = read(name);
        g.throughput(Throughput::Bytes(text.len() as u64));
        g.bench_function(name, |b| {
            b.iter(|| cetratus_sfc::import_str(&text, name, pou, "Main.pnml").expect("imports"))
        });
    }
    g.finish();
}

/// 30 000 scans (5 minutes of the cell at 10 ms) replayed on a fresh container, per program: the
/// inputs each program saw on the twin, so each does its own work.
fn vernadat_scan(c: &mut Criterion) {
    let xml = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../examples/vernadat-sfc/vernadat-sfc.xml");
    let text = std::fs::read_to_string(&xml).expect("the SFC example");
    let sfc: Arc<Program> = Arc::new(
        cetratus_sfc::import_program(&text, "vernadat-sfc.xml", Some("Cell"))
            .expect("imports")
            .program,
    );
    let mut g = c.benchmark_group("vernadat_scan");
    g.throughput(Throughput::Elements(30_000));
    for (name, program) in [("petri_net", vernadat_program()), ("sfc", sfc)] {
        let images = recorded_inputs(&program, 30_000);
        let period = program.scan_period().as_micros() as u64;
        let fresh = Container::new(program, 0);
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut c = fresh.clone();
                for (k, img) in images.iter().enumerate() {
                    black_box(c.scan(k as u64 * period, img).expect("replay runs"));
                }
            })
        });
    }
    g.finish();
}

/// The press of `examples/press-sfc`, a chart on the Structured Text compiler: its import, and
/// 30 000 scans with `start` pressed for 20 scans in every 100.
fn press(c: &mut Criterion) {
    let xml =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/press-sfc/press.xml");
    let text = std::fs::read_to_string(&xml).expect("the press example");
    let mut g = c.benchmark_group("press");
    g.bench_function("import", |b| {
        b.iter(|| {
            cetratus_sfc::import_str(&text, "press.xml", None, "Press.pnml").expect("imports")
        })
    });
    let program = Arc::new(
        cetratus_sfc::import_str(&text, "press.xml", None, "Press.pnml")
            .expect("imports")
            .program,
    );
    let images: Vec<Vec<cetratus_program::Value>> = (0..30_000)
        .map(|k| vec![cetratus_program::Value::Bool(k % 100 < 20)])
        .collect();
    let fresh = Container::new(program, 0);
    g.throughput(Throughput::Elements(30_000));
    g.bench_function("scan", |b| {
        b.iter(|| {
            let mut c = fresh.clone();
            for (k, img) in images.iter().enumerate() {
                black_box(c.scan(k as u64 * 10_000, img).expect("runs"));
            }
        })
    });
    g.finish();
}

criterion_group!(benches, charts, import, vernadat_scan, press);
criterion_main!(benches);
