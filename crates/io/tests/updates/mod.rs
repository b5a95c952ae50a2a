//! A workshop for update tests: a temporary copy of an example (the Vernadat cell unless told
//! otherwise) with a trusted signing key, and a cell (PLC + twin) that checks the Message Router's
//! law on every cycle.

// Each test crate uses a different part of this module.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::Arc;

use cetratus_io::TwinDriver;
use cetratus_program::{build_package, KeyPair, Program, TrustStore};
use cetratus_runtime::{Command, EventKind, Plc, Slot, Status, SubstituteMode, SubstituteRequest};
use cetratus_twin::{Twin, TwinKind};

pub const PERIOD: u64 = 10_000;
pub const EXAMPLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/vernadat");
pub const FESTO_EXAMPLES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/festo");

/// A temporary copy of the Vernadat example, a signing key that the trust store trusts, and the
/// packages built from manifests in it.
pub struct Workshop {
    dir: tempfile::TempDir,
    key: KeyPair,
    pub trust: TrustStore,
}

impl Workshop {
    pub fn new() -> Self {
        Self::of(EXAMPLES)
    }

    /// A workshop with the programs and manifests of the example directory `examples`.
    pub fn of(examples: &str) -> Self {
        let dir = tempfile::tempdir().expect("temp dir");
        for entry in std::fs::read_dir(examples).expect("examples dir") {
            let path = entry.expect("entry").path();
            if path.extension().is_some_and(|e| e == "toml" || e == "pnml") {
                std::fs::copy(&path, dir.path().join(path.file_name().expect("name")))
                    .expect("copy");
            }
        }
        let key = KeyPair::generate();
        let key_path = dir.path().join("test.key");
        key.save(&key_path).expect("save key");
        let trusted = dir.path().join("trusted");
        std::fs::create_dir_all(&trusted).expect("trusted dir");
        std::fs::copy(KeyPair::public_path(&key_path), trusted.join("test.pub")).expect("copy pub");
        let trust = TrustStore::load_dir(&trusted).expect("trust store");
        Workshop { dir, key, trust }
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    pub fn package(&self, manifest: &str) -> Vec<u8> {
        build_package(&self.path(manifest), Some(&self.key), 1_700_000_000)
            .unwrap_or_else(|e| panic!("{manifest} builds: {e}"))
            .0
    }

    /// U.1 with another ST_base, for refusals at install.
    pub fn u1_with_base(&self, base: &str) -> Vec<u8> {
        let text = std::fs::read_to_string(self.path("u1.package.toml")).expect("u1 manifest");
        let text = text.replace("base = [2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]", base);
        std::fs::write(self.path("u1-bad.package.toml"), text).expect("write");
        self.package("u1-bad.package.toml")
    }

    /// U.1 declaring a wrong invariant: H + B = 9 breaks when a part leaves M1 for the buffer
    /// (T13 takes a free slot and P14 holds the part). Its manifest is `u1-wrong.package.toml`.
    pub fn u1_breaking_an_invariant(&self) -> Vec<u8> {
        let text = std::fs::read_to_string(self.path("u1.toml")).expect("u1.toml");
        std::fs::write(
            self.path("u1-wrong.toml"),
            format!("{text}\n[[invariant]]\nexpr = \"H + B = 9\"\n"),
        )
        .expect("write");
        let manifest = std::fs::read_to_string(self.path("u1.package.toml")).expect("manifest");
        std::fs::write(
            self.path("u1-wrong.package.toml"),
            manifest.replace("program = \"u1.toml\"", "program = \"u1-wrong.toml\""),
        )
        .expect("write");
        self.package("u1-wrong.package.toml")
    }

    pub fn program(&self, name: &str) -> Arc<Program> {
        Arc::new(Program::load(&self.path(name)).expect("program loads"))
    }
}

pub struct Cell {
    pub plc: Plc,
    pub io: TwinDriver<Twin>,
    pub now: u64,
    pub events: Vec<cetratus_runtime::Event>,
}

impl Cell {
    pub fn new(program: Arc<Program>) -> Self {
        Self::with_twin(program, TwinKind::Vernadat.build(1))
    }

    /// A cell whose plant is `twin`.
    pub fn with_twin(program: Arc<Program>, twin: Twin) -> Self {
        let io = TwinDriver::new(twin, program.inputs(), program.outputs())
            .expect("signals match the twin");
        let mut plc = Plc::new(program, 0, cetratus_testkit::stopwatch());
        // Virtual time: a machine busy with other tests must not turn a preemption into a fault.
        plc.use_virtual_time(PERIOD);
        Cell {
            plc,
            io,
            now: 0,
            events: Vec::new(),
        }
    }

    /// One cycle, checking the Message Router's law: what is dispatched is the primary's output.
    pub fn step(&mut self) {
        self.plc.cycle(self.now, &mut self.io);
        if self.plc.status() != Status::Fault {
            let primary = self
                .plc
                .outputs_of(self.plc.primary())
                .expect("primary present");
            assert_eq!(
                self.plc.dispatched(),
                primary,
                "dispatched = primary's outputs at {} µs",
                self.now
            );
        }
        self.events.extend(self.plc.drain_events());
        drop(self.plc.take_retired());
        self.now += PERIOD;
    }

    pub fn run_for(&mut self, us: u64) {
        let end = self.now + us;
        while self.now < end {
            self.step();
        }
    }

    pub fn load(&mut self, bytes: &[u8], trust: &TrustStore) -> Result<(), String> {
        let p = self
            .plc
            .update_context()
            .prepare_package(
                bytes,
                trust,
                cetratus_program::Unsigned::Refused,
                cetratus_program::OtherBase::Refused,
            )
            .map_err(|e| e.to_string())?;
        self.plc
            .command(Command::Load(Box::new(p)))
            .map_err(|e| e.to_string())
    }

    pub fn substitute(&mut self, mode: SubstituteMode, force: bool) -> Result<(), String> {
        self.plc
            .command(Command::Substitute(SubstituteRequest {
                mode,
                when: None,
                within_us: None,
                force,
            }))
            .map_err(|e| e.to_string())
    }

    pub fn tokens(&self, slot: Slot, ids: &[&str]) -> u32 {
        let c = self.plc.container(slot).expect("container present");
        let net = c.program().net();
        ids.iter()
            .map(|id| c.marking()[net.place_by_id(id).expect("place").index()])
            .sum()
    }

    /// The parts the Vernadat twin finished so far.
    pub fn parts(&self) -> u64 {
        use cetratus_twin::Plant;
        self.io
            .plant()
            .counters()
            .get("parts_finished")
            .expect("the Vernadat twin counts finished parts")
    }

    pub fn has_event(&self, kind: EventKind) -> bool {
        self.events.iter().any(|e| e.kind == kind)
    }
}

/// A reference run with no update, to compare the primary against.
pub fn reference_marking(w: &Workshop, cycles: usize) -> Vec<u32> {
    let mut cell = Cell::new(w.program("vernadat.toml"));
    for _ in 0..cycles {
        cell.step();
    }
    cell.plc.primary_container().marking().to_vec()
}
