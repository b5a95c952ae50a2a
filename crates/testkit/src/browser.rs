//! Headless Chromium driven over WebDriver (ChromeDriver), and reading the dashboard's page in it.
//!
//! Needs Debian's `chromium` and `chromium-driver`; the browser tests fail, never skip, when they
//! are missing. Every function here runs inside a tokio runtime (`#[tokio::test]`).

use std::ops::Deref;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::wd::TimeoutConfiguration;
use fantoccini::{Client, ClientBuilder};
use serde_json::{json, Value};

use crate::ports::{free_port, wait_for_port};
use crate::process::ChildGuard;

pub use fantoccini::Locator;

/// Where Debian's `chromium` package installs the browser.
pub const CHROMIUM: &str = "/usr/bin/chromium";
/// Where Debian's `chromium-driver` package installs ChromeDriver.
pub const CHROMEDRIVER: &str = "/usr/bin/chromedriver";

/// How long ChromeDriver may take to listen; a loaded test machine needs seconds.
const DRIVER_START: Duration = Duration::from_secs(30);

/// How long a script or a page load may run before WebDriver interrupts it.
const SCRIPT_TIMEOUT: Duration = Duration::from_secs(120);

/// Fails, saying what to install, when Chromium or ChromeDriver is missing.
pub fn require_chromium() {
    for (path, package) in [(CHROMIUM, "chromium"), (CHROMEDRIVER, "chromium-driver")] {
        assert!(
            Path::new(path).is_file(),
            "{path} is missing: install the Debian package `{package}` (`apt-get install -y \
             chromium chromium-driver`; ./scripts/test does); the browser tests do not skip"
        );
    }
}

/// A headless Chromium session with a ChromeDriver of its own and a fresh profile. Dereferences
/// to the WebDriver client; call [`Browser::close`] at the end of the test.
pub struct Browser {
    client: Client,
    // Declared after the client and before the profile: the driver stops once the session is
    // gone, and the profile is removed once nothing uses it.
    _driver: ChildGuard,
    _profile: tempfile::TempDir,
}

impl Browser {
    /// Starts ChromeDriver on a free port and opens a headless Chromium in a new, empty profile.
    ///
    /// # Panics
    ///
    /// When Chromium or ChromeDriver is missing or does not start.
    pub async fn start() -> Self {
        require_chromium();
        let port = free_port();
        let driver = ChildGuard::spawn(
            Command::new(CHROMEDRIVER)
                .arg(format!("--port={port}"))
                .stdout(Stdio::null())
                .stderr(Stdio::null()),
        );
        wait_for_port(port, "chromedriver", DRIVER_START);
        let profile = tempfile::tempdir().expect("a temporary Chromium profile");
        let args = [
            "--headless".to_string(),
            // Test machines and containers run as root or without user namespaces.
            "--no-sandbox".into(),
            "--disable-gpu".into(),
            // A container's /dev/shm is often too small for Chromium's renderer.
            "--disable-dev-shm-usage".into(),
            // Nothing but the page under test may use the network.
            "--disable-quic".into(),
            "--no-first-run".into(),
            "--disable-background-networking".into(),
            "--disable-component-update".into(),
            "--disable-sync".into(),
            "--window-size=1400,1800".into(),
            format!("--user-data-dir={}", profile.path().display()),
        ];
        let mut caps = serde_json::Map::new();
        caps.insert(
            "goog:chromeOptions".into(),
            json!({"binary": CHROMIUM, "args": args}),
        );
        // ChromeDriver's port opens before it always answers: on a busy machine the first
        // session request can meet a reset connection, so a few are tried before giving up.
        let mut tries = 0;
        let client = loop {
            let connector = hyper_util::client::legacy::connect::HttpConnector::new();
            let session = ClientBuilder::new(connector)
                .capabilities(caps.clone())
                .connect(&format!("http://127.0.0.1:{port}"))
                .await;
            match session {
                Ok(client) => break client,
                Err(e) if tries >= 4 => panic!("chromedriver starts a Chromium session: {e:?}"),
                Err(_) => {
                    tries += 1;
                    tokio::time::sleep(std::time::Duration::from_millis(300)).await;
                }
            }
        };
        // A page that draws a wide net on a machine whose both cores are busy can hold a
        // script past the WebDriver default of 30 s; a test's own waits bound the time instead.
        client
            .update_timeouts(TimeoutConfiguration::new(
                Some(SCRIPT_TIMEOUT),
                Some(SCRIPT_TIMEOUT),
                None,
            ))
            .await
            .expect("the session takes its timeouts");
        Browser {
            client,
            _driver: driver,
            _profile: profile,
        }
    }

    /// Ends the session and closes Chromium.
    pub async fn close(self) {
        self.client.close().await.expect("the browser closes");
    }

    /// The value `script` returns in the page.
    ///
    /// # Panics
    ///
    /// When the script throws, showing it.
    pub async fn js(&self, script: &str) -> Value {
        self.client
            .execute(script, Vec::new())
            .await
            .unwrap_or_else(|e| panic!("script failed: {e}\n{script}"))
    }

    /// The trimmed text of the element with id `id`; empty when there is none.
    pub async fn text_of(&self, id: &str) -> String {
        let v = self
            .js(&format!(
                "const e = document.getElementById('{id}'); return e ? e.textContent : null;"
            ))
            .await;
        v.as_str().unwrap_or("").trim().to_string()
    }

    /// The text of the exec-info table's row `label` in container `slot`'s column ("A" or
    /// "B"); empty when there is no such row.
    pub async fn exec_info_cell(&self, label: &str, slot: &str) -> String {
        let column = if slot == "A" { 1 } else { 2 };
        self.js(&format!(
            "for (const tr of document.querySelectorAll('#exec-info tbody tr')) {{
               if (tr.cells[0].textContent === {label:?}) return tr.cells[{column}].textContent;
             }}
             return '';"
        ))
        .await
        .as_str()
        .unwrap_or("")
        .to_string()
    }

    /// Waits until the exec-info table's row `label` in container `slot`'s column holds
    /// `want`, and returns it.
    ///
    /// # Panics
    ///
    /// After `within`, with what it read instead.
    pub async fn wait_exec_info(
        &self,
        label: &str,
        slot: &str,
        want: &str,
        within: Duration,
    ) -> String {
        let end = Instant::now() + within;
        let mut seen = String::new();
        while Instant::now() < end {
            seen = self.exec_info_cell(label, slot).await;
            if seen.contains(want) {
                return seen;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        panic!("exec-info `{label}` of {slot} is {seen:?}, without {want:?}, after {within:?}");
    }

    /// Waits until the element with id `id` reads `want`.
    ///
    /// # Panics
    ///
    /// After `within`, with what it read instead and the dashboard's `#reply`.
    pub async fn wait_text(&self, id: &str, want: &str, within: Duration) {
        let end = Instant::now() + within;
        let mut seen = String::new();
        while Instant::now() < end {
            seen = self.text_of(id).await;
            if seen == want {
                return;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let reply = self.text_of("reply").await;
        panic!("#{id} is {seen:?}, not {want:?}, after {within:?} (#reply: {reply:?})");
    }

    /// Clicks the dashboard's button `button`, then `confirm-yes` in its in-page confirmation.
    pub async fn click_and_confirm(&self, button: &str) {
        self.client
            .find(Locator::Id(button))
            .await
            .unwrap_or_else(|e| panic!("no button #{button}: {e}"))
            .click()
            .await
            .expect("click");
        self.client
            .wait()
            .at_most(Duration::from_secs(5))
            .for_element(Locator::Css("#confirm:not([hidden]) #confirm-yes"))
            .await
            .expect("the confirmation dialog opens")
            .click()
            .await
            .expect("confirm");
    }

    /// Chooses `package` in the dashboard's file input, then clicks Load and confirms.
    pub async fn load_package(&self, package: &Path) {
        self.client
            .find(Locator::Id("package-file"))
            .await
            .expect("the page has the package file input")
            .send_keys(&package.display().to_string())
            .await
            .expect("choose the package");
        self.click_and_confirm("load").await;
    }

    /// Whether the dashboard draws a net in container `slot`.
    async fn net_drawn(&self, slot: &str) -> bool {
        self.js(&format!(
            "return !!document.querySelector('#net-{slot} svg .place');"
        ))
        .await
            == Value::Bool(true)
    }

    /// Waits until container `slot` holds a drawn net: the drawing follows the status that
    /// announced it by one round trip for the net's layout.
    ///
    /// # Panics
    ///
    /// After `within`, with the dashboard's `#reply`.
    pub async fn wait_net_drawn(&self, slot: &str, within: Duration) {
        let end = Instant::now() + within;
        while Instant::now() < end {
            if self.net_drawn(slot).await {
                return;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        let reply = self.text_of("reply").await;
        panic!("no net is drawn in container {slot} after {within:?} (#reply: {reply:?})");
    }

    /// The places of container `slot`'s net as the dashboard draws them: `id=tokens:dots` per
    /// place, the token count of its attribute and the number of token dots drawn.
    pub async fn tokens(&self, slot: &str) -> String {
        self.js(&format!(
            "return [...document.querySelectorAll('#net-{slot} .place')]
               .map(p => p.id + '=' + p.getAttribute('data-tokens') + ':' + p.querySelector('.tokens').childElementCount)
               .join(',');"
        ))
        .await
        .as_str()
        .unwrap_or("")
        .to_string()
    }

    /// Waits until the tokens of container `slot`'s net move, and returns how they were drawn
    /// before.
    ///
    /// # Panics
    ///
    /// When they have not moved after `within`.
    pub async fn wait_tokens_move(&self, slot: &str, within: Duration) -> String {
        let before = self.tokens(slot).await;
        let end = Instant::now() + within;
        while Instant::now() < end {
            tokio::time::sleep(Duration::from_millis(100)).await;
            if self.tokens(slot).await != before {
                return before;
            }
        }
        panic!("the tokens of net {slot} never moved in {within:?}: {before}");
    }

    /// The level at the right edge of `signal`'s lane in `group` (`inputs`, `A`, `B` or
    /// `dispatched`) of the dashboard's timing diagram; `None` while that lane is not drawn.
    pub async fn lane_level(&self, group: &str, signal: &str) -> Option<bool> {
        self.js(&format!(
            "const p = document.querySelector('#timing .g-{group} path[data-signal=\"{signal}\"]');
             return p ? p.dataset.level === '1' : null;"
        ))
        .await
        .as_bool()
    }

    /// Waits until `signal`'s lane in `group` of the timing diagram is at `level`.
    ///
    /// # Panics
    ///
    /// After `within`, with the level it read last.
    pub async fn wait_lane_level(&self, group: &str, signal: &str, level: bool, within: Duration) {
        let end = Instant::now() + within;
        let mut seen = None;
        while Instant::now() < end {
            seen = self.lane_level(group, signal).await;
            if seen == Some(level) {
                return;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        panic!("{signal} in the {group} lanes is {seen:?}, not {level}, after {within:?}");
    }

    /// The dashboard's timing diagram as it is now.
    pub async fn timing(&self) -> Timing {
        let v = self
            .js("const t = document.getElementById('timing');
                 return [Number(t.dataset.samples || 0), t.dataset.lastTime || '', t.innerHTML];")
            .await;
        Timing {
            samples: v[0].as_u64().unwrap_or(0),
            last_time: v[1].as_str().unwrap_or("").to_string(),
            svg: v[2].as_str().unwrap_or("").to_string(),
        }
    }
}

impl Deref for Browser {
    type Target = Client;

    fn deref(&self) -> &Client {
        &self.client
    }
}

/// What the dashboard's timing diagram shows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Timing {
    /// How many samples it holds.
    pub samples: u64,
    /// The PLC time of its newest sample.
    pub last_time: String,
    /// Its drawing.
    pub svg: String,
}

impl Timing {
    /// Fails unless the diagram has a newer sample than `earlier` had, and has been redrawn. (Its
    /// number of samples is no measure: once the window is full, old samples leave it as new
    /// ones come.)
    pub fn assert_scrolled_since(&self, earlier: &Timing) {
        let t = |s: &str| s.parse::<f64>().ok();
        assert!(
            self.samples > 0
                && match (t(&earlier.last_time), t(&self.last_time)) {
                    (Some(a), Some(b)) => b > a,
                    (None, Some(_)) => true,
                    _ => false,
                },
            "the timing diagram gained no samples (newest sample at {:?}, then at {:?}; {} -> {} samples)",
            earlier.last_time,
            self.last_time,
            earlier.samples,
            self.samples
        );
        assert_ne!(earlier.svg, self.svg, "the timing diagram was not redrawn");
    }
}
