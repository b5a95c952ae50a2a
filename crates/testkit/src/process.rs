//! The programs a test runs beside itself: finding them, and stopping them when the test ends.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

/// A child process, killed and reaped when the guard drops, so that a failing test does not
/// leave a broker, a driver or a PLC running.
#[derive(Debug)]
pub struct ChildGuard(pub Child);

impl ChildGuard {
    /// Guards a process that is already running.
    pub fn new(child: Child) -> Self {
        ChildGuard(child)
    }

    /// The process id, to watch the process from outside (its memory in `/proc`).
    pub fn id(&self) -> u32 {
        self.0.id()
    }

    /// Starts `cmd` and guards it.
    ///
    /// # Panics
    ///
    /// When the program cannot be started, naming it.
    pub fn spawn(cmd: &mut Command) -> Self {
        match cmd.spawn() {
            Ok(child) => ChildGuard(child),
            Err(e) => panic!("cannot start {:?}: {e}", cmd.get_program()),
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

pub use cetratus_matiec::find_program;

/// The output of `cmd`, killed if it has not ended within `limit`: the bound on a reader whose
/// work must grow with its input's size, not faster (a quadratic one takes hours on the inputs
/// that such tests give it, a linear one seconds). Its output is read while it runs, so that a
/// full pipe never stops it.
pub fn output_within(cmd: &mut Command, limit: std::time::Duration) -> std::process::Output {
    let mut child = (cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn())
        .unwrap_or_else(|e| panic!("{cmd:?} does not start: {e}"));
    let drain = |pipe: Option<Box<dyn std::io::Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                std::io::Read::read_to_end(&mut pipe, &mut bytes).ok();
            }
            bytes
        })
    };
    let stdout = drain(child.stdout.take().map(|p| Box::new(p) as _));
    let stderr = drain(child.stderr.take().map(|p| Box::new(p) as _));
    let started = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        if started.elapsed() > limit {
            child.kill().ok();
            panic!("{cmd:?} was still running after {limit:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    std::process::Output {
        status,
        stdout: stdout.join().expect("stdout read"),
        stderr: stderr.join().expect("stderr read"),
    }
}

/// Where the program `name` is installed.
///
/// # Panics
///
/// When it is not, saying which Debian package installs it: the tests that talk to real
/// programs fail rather than skip, so that a green run means they ran.
pub fn require_program(name: &str, package: &str) -> PathBuf {
    find_program(name).unwrap_or_else(|| {
        panic!(
            "`{name}` is missing: install the Debian package `{package}` \
             (`apt-get install -y {package}`; ./scripts/test does)"
        )
    })
}

/// The lines a child writes to its piped standard error, as they come, read on a thread of their
/// own so that the child never blocks on a full pipe.
///
/// # Panics
///
/// When the child's standard error is not piped.
pub fn stderr_lines(child: &mut std::process::Child) -> std::sync::mpsc::Receiver<String> {
    lines_of(child.stderr.take().expect("a piped standard error"))
}

/// The lines of `pipe`, read on a thread of their own.
fn lines_of(pipe: impl std::io::Read + Send + 'static) -> std::sync::mpsc::Receiver<String> {
    use std::io::BufRead;
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(pipe).lines().map_while(Result::ok) {
            // Read on when nobody listens any more: a child whose pipe closed would fail on
            // its next line (and Rust's `println!` panics then).
            let _ = tx.send(line);
        }
    });
    rx
}

/// The lines a child writes to its piped standard output, as [`stderr_lines`] reads standard
/// error.
///
/// # Panics
///
/// When the child's standard output is not piped.
pub fn stdout_lines(child: &mut std::process::Child) -> std::sync::mpsc::Receiver<String> {
    lines_of(child.stdout.take().expect("a piped standard output"))
}

/// Waits up to `within` for a line of `lines` that holds a dashboard login link, and returns
/// the link; panics with the lines seen.
pub fn login_link(
    lines: &std::sync::mpsc::Receiver<String>,
    within: std::time::Duration,
) -> String {
    let end = std::time::Instant::now() + within;
    let mut seen = Vec::new();
    while let Some(left) = end.checked_duration_since(std::time::Instant::now()) {
        match lines.recv_timeout(left) {
            Ok(line) => match crate::http::login_link_in(&line) {
                Some(link) => return link,
                None => seen.push(line),
            },
            Err(_) => break,
        }
    }
    panic!(
        "no dashboard login link within {within:?}; the output was:\n{}",
        seen.join("\n")
    )
}

/// Stops a `cetratus run --json` as an operator would (SIGTERM), waits up to 30 s for it to end,
/// checks that it ended well and parses its closing summary.
pub fn stop_with_sigterm(mut plc: ChildGuard) -> serde_json::Value {
    use std::time::{Duration, Instant};
    let kill = Command::new("kill")
        .args(["-TERM", &plc.id().to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    let end = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(s) = plc.0.try_wait().expect("wait") {
            break s;
        }
        assert!(Instant::now() < end, "the PLC did not stop on SIGTERM");
        std::thread::sleep(Duration::from_millis(50));
    };
    let (mut out, mut err) = (String::new(), String::new());
    if let Some(mut o) = plc.0.stdout.take() {
        std::io::Read::read_to_string(&mut o, &mut out).expect("stdout");
    }
    if let Some(mut e) = plc.0.stderr.take() {
        std::io::Read::read_to_string(&mut e, &mut err).expect("stderr");
    }
    assert!(status.success(), "the PLC failed:\n{err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("not JSON ({e}): {out}\n{err}"))
}

/// Waits for a guarded process and parses the JSON it printed.
pub fn json_of(mut child: ChildGuard) -> serde_json::Value {
    let mut text = String::new();
    if let Some(mut out) = child.0.stdout.take() {
        std::io::Read::read_to_string(&mut out, &mut text).expect("read stdout");
    }
    let _ = child.0.wait();
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

/// The demo's files as `cetratus demo --scripted` (the binary `bin`) writes them: the program,
/// U.1 and U.2 signed, the key that signed them, and an empty configuration directory
/// (`config/`), so that the machine's own configuration plays no part.
pub fn demo_files(bin: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a temporary directory");
    std::fs::create_dir(dir.path().join("config")).expect("a configuration directory");
    let out = Command::new(bin)
        .args(["demo", "--scripted", "--json", "--dir"])
        .arg(dir.path())
        .output()
        .expect("cetratus demo runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}

/// `bin run` of the Vernadat example as PLC `cell`, cold, with the I/O map `io`, a JSON summary,
/// and its state and configuration under `dir` (`state/`, `config/`); the caller adds the rest
/// (broker, twin, output).
pub fn run_vernadat(bin: &str, io: &std::path::Path, dir: &std::path::Path) -> Command {
    let mut cmd = Command::new(bin);
    cmd.arg("run")
        .arg(crate::paths::example("vernadat/vernadat.toml"))
        .arg("--io")
        .arg(io)
        .args(["--json", "--cold", "--plc", "cell"])
        .arg("--state-dir")
        .arg(dir.join("state"))
        .arg("--config")
        .arg(dir.join("config"));
    cmd
}

/// `bin package keygen` into `dir/<name>.key`, that key trusted in `trusted` (made if missing),
/// and `bin package build` of `manifest` signed with it into `dir/<name>.cpkg`; the package's
/// path. Fails with the binary's stderr.
pub fn signed_package(
    bin: &str,
    manifest: &std::path::Path,
    name: &str,
    dir: &std::path::Path,
    trusted: &std::path::Path,
) -> PathBuf {
    let run = |args: &[&std::ffi::OsStr]| {
        let out = Command::new(bin).args(args).output().expect("run cetratus");
        assert!(
            out.status.success(),
            "cetratus {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let key = dir.join(format!("{name}.key"));
    let package = dir.join(format!("{name}.cpkg"));
    run(&[
        "package".as_ref(),
        "keygen".as_ref(),
        "--out".as_ref(),
        key.as_os_str(),
    ]);
    std::fs::create_dir_all(trusted).expect("the trusted keys' directory");
    std::fs::copy(
        dir.join(format!("{name}.key.pub")),
        trusted.join(format!("{name}.pub")),
    )
    .expect("trust the key");
    run(&[
        "package".as_ref(),
        "build".as_ref(),
        manifest.as_os_str(),
        "--key".as_ref(),
        key.as_os_str(),
        "-o".as_ref(),
        package.as_os_str(),
    ]);
    package
}
