//! Criterion benches of the PLCopen SFC importer: reading every chart of each reference fixture,
//! and importing the charts that import as programs (net, TOML and the loaded program).

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
    for name in ["twincat-sfc-evolution-1.xml", "twincat-sfc-evolution-6.xml"] {
        let text = read(name);
        g.throughput(Throughput::Bytes(text.len() as u64));
        g.bench_function(name, |b| {
            b.iter(|| cetratus_sfc::import_str(&text, name, None, "Main.pnml").expect("imports"))
        });
    }
    g.finish();
}

criterion_group!(benches, charts, import);
criterion_main!(benches);
