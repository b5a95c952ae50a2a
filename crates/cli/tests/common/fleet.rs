//! A fleet of real PLC processes (the Vernadat cell on its twin, fast) on a real Mosquitto, the
//! packages a rollout takes across it, and a record of every event the PLCs publish.

// Each test binary that includes this file uses a part of it.
#![allow(dead_code)]

use std::collections::BTreeMap;
use std::io::{BufRead as _, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cetratus_testkit::mqtt::{self, tool, Mosquitto};
use cetratus_testkit::paths::example;
use cetratus_testkit::process::{signed_package, ChildGuard};
use serde_json::Value;

pub const BIN: &str = env!("CARGO_BIN_EXE_cetratus");

/// The PLCs' speed: ten seconds of program time a second.
pub const SPEED: &str = "10";

/// One fleet: the broker, the PLCs by id, and where their files are.
pub struct Fleet {
    pub broker: Mosquitto,
    pub root: tempfile::TempDir,
    pub plcs: BTreeMap<String, ChildGuard>,
    pub trusted: PathBuf,
    pub events: Events,
    /// Brokers of other sites, bridged to `broker`.
    pub sites: Vec<Mosquitto>,
}

impl Fleet {
    /// A broker, with no PLC on it yet.
    pub fn new() -> Fleet {
        let broker = Mosquitto::start();
        let root = tempfile::tempdir().unwrap();
        let trusted = root.path().join("trusted");
        std::fs::create_dir_all(&trusted).unwrap();
        let events = Events::follow(broker.port());
        Fleet {
            broker,
            root,
            plcs: BTreeMap::new(),
            trusted,
            events,
            sites: Vec::new(),
        }
    }

    /// Starts the broker of another site, bridged to the fleet's own as two plants' brokers
    /// would be (every `cetratus/` topic both ways); its URL.
    pub fn site(&mut self) -> String {
        let bridge = format!(
            "allow_anonymous true\npersistence false\nconnection plant\n\
             address 127.0.0.1:{}\ntopic cetratus/# both 1\ncleansession true\n",
            self.broker.port()
        );
        let site = Mosquitto::start_with(&bridge);
        let url = format!("mqtt://127.0.0.1:{}", site.port());
        self.sites.push(site);
        url
    }

    /// Starts `n` PLCs `plc-00` … of line 1, each running `program` (an example path). The
    /// PLCs read their trusted keys at start: make the packages first.
    pub fn start(&mut self, n: usize, program: &str) {
        for k in 0..n {
            self.add(&format!("plc-{k:02}"), program, "line = \"1\"");
        }
    }

    /// Starts one more PLC, with `labels` and a probation window of 20 s.
    pub fn add(&mut self, id: &str, program: &str, labels: &str) {
        let url = self.url();
        self.add_at(id, program, labels, &url);
    }

    /// [`Fleet::add`] on the broker at `url`.
    pub fn add_at(&mut self, id: &str, program: &str, labels: &str, url: &str) {
        let config = self.root.path().join(format!("config-{id}"));
        std::fs::create_dir_all(&config).unwrap();
        std::fs::write(
            config.join("config.toml"),
            format!("[labels]\n{labels}\n\n[updates]\nprobation = \"20s\"\n"),
        )
        .unwrap();
        let child = ChildGuard::spawn(
            Command::new(BIN)
                .arg("run")
                .arg(example(program))
                .args(["--twin", "vernadat", "--speed", SPEED, "--period", "20ms"])
                .args(["--no-dashboard", "--plc", id, "--broker", url])
                .arg("--config")
                .arg(&config)
                .arg("--trust")
                .arg(&self.trusted)
                .arg("--state-dir")
                .arg(self.root.path().join(format!("state-{id}")))
                .stdout(Stdio::null())
                .stderr(Stdio::null()),
        );
        self.plcs.insert(id.to_string(), child);
    }

    pub fn url(&self) -> String {
        format!("mqtt://127.0.0.1:{}", self.broker.port())
    }

    /// Waits until every PLC has published an online state.
    pub fn wait_online(&self) {
        let end = Instant::now() + Duration::from_secs(60);
        for id in self.plcs.keys() {
            loop {
                let topic = format!("cetratus/{id}/state");
                let v = mqtt::sub_one(self.broker.port(), &topic, 2, true);
                if v.is_some_and(|v| v["online"] == true) {
                    break;
                }
                assert!(Instant::now() < end, "{id} never came online");
            }
        }
    }

    /// The signed package of `manifest` (a path), as `name.cpkg` in the fleet's directory,
    /// its key trusted by every PLC.
    pub fn package(&self, manifest: &Path, name: &str) -> PathBuf {
        signed_package(BIN, manifest, name, self.root.path(), &self.trusted)
    }

    /// Writes `rollout.toml` for `package` with the given stages and extra lines.
    pub fn plan(&self, package: &Path, select: &str, stages: &str, extra: &str) -> PathBuf {
        let path = self.root.path().join("rollout.toml");
        std::fs::write(
            &path,
            format!(
                "package = \"{}\"\nselect = \"{select}\"\nstages = {stages}\n\
                 quarantine = \"15s\"\nprobation = \"10s\"\nmax_parallel = 10\n{extra}",
                package.display()
            ),
        )
        .unwrap();
        path
    }

    /// `cetratus rollout ARGS… --broker … --state-dir DIR`.
    pub fn rollout(&self, args: &[&str], state: &Path) -> Command {
        let mut cmd = Command::new(BIN);
        cmd.arg("rollout")
            .args(args)
            .args(["--broker", &self.url()]);
        cmd.arg("--state-dir").arg(state);
        cmd
    }

    /// The retained state of `id`.
    pub fn state(&self, id: &str) -> Value {
        mqtt::sub_one(self.broker.port(), &format!("cetratus/{id}/state"), 5, true)
            .unwrap_or_else(|| panic!("no state of {id}"))
    }
}

/// Every event the PLCs publish, by PLC, as `mosquitto_sub -v` prints them.
pub struct Events {
    seen: Arc<Mutex<Vec<(String, Value)>>>,
    _sub: ChildGuard,
}

impl Events {
    fn follow(port: u16) -> Events {
        let mut child = Command::new(tool("mosquitto_sub"))
            .args(["-h", "127.0.0.1", "-p", &port.to_string()])
            .args(["-t", "cetratus/+/events", "-v"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("mosquitto_sub starts");
        let out = child.stdout.take().expect("its stdout");
        let seen = Arc::new(Mutex::new(Vec::new()));
        let into = seen.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines().map_while(Result::ok) {
                let Some((topic, payload)) = line.split_once(' ') else {
                    continue;
                };
                let plc = topic.split('/').nth(1).unwrap_or("").to_string();
                if let Ok(v) = serde_json::from_str::<Value>(payload) {
                    into.lock().unwrap().push((plc, v));
                }
            }
        });
        std::thread::sleep(Duration::from_millis(300));
        Events {
            seen,
            _sub: ChildGuard::new(child),
        }
    }

    /// How many events of `kind` each PLC published.
    pub fn count(&self, kind: &str) -> BTreeMap<String, usize> {
        let mut out = BTreeMap::new();
        for (plc, v) in self.seen.lock().unwrap().iter() {
            if v["kind"] == kind {
                *out.entry(plc.clone()).or_default() += 1;
            }
        }
        out
    }
}

/// What U.1 declares it changes on purpose for a rollout: with two more buffer slots, M1 no
/// longer waits for a free one, so the robot's moves and both machines' cycles shift in time.
const U1_CHANGES: &str =
    "\n[changes]\noutputs = [\"CM1\", \"PM1\", \"DM1\", \"CM2\", \"PM2\", \"DM2\"]\n";

/// A copy of the Vernadat example's U.1 in `dir` whose manifest declares the outputs it
/// changes ([`U1_CHANGES`]); the manifest's path.
pub fn u1_declared(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for f in ["vernadat.toml", "vernadat.pnml", "u1.toml", "u1.pnml"] {
        std::fs::copy(example(&format!("vernadat/{f}")), dir.join(f)).unwrap();
    }
    let manifest = std::fs::read_to_string(example("vernadat/u1.package.toml")).unwrap();
    let path = dir.join("u1.package.toml");
    std::fs::write(&path, manifest + U1_CHANGES).unwrap();
    path
}

/// [`u1_declared`] with U.1 broken: its outfeed action (DM2 at P24) is gone, so as primary it
/// never unloads M2. Its divergence on DM2 is among the declared ones, so its quarantine passes
/// and its probation catches it.
pub fn broken_u1(dir: &Path) -> PathBuf {
    let manifest = u1_declared(dir);
    let u1 = std::fs::read_to_string(dir.join("u1.toml")).unwrap();
    let action = "[[action]]\nplace = \"P24\"\nqualifier = \"N\"\ntarget = \"DM2\"\n";
    assert!(u1.contains(action), "U.1 unloads M2 at P24");
    std::fs::write(dir.join("u1.toml"), u1.replace(action, "")).unwrap();
    manifest
}

/// The rollout's report, from its `--json` output.
pub fn report(out: &std::process::Output) -> Value {
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.trim()).unwrap_or_else(|e| {
        panic!(
            "not a report ({e}): {text}\nstderr: {}",
            String::from_utf8_lossy(&out.stderr)
        )
    })
}
