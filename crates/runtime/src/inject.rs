//! Faults on purpose, for tests (feature `fault-injection`, off by default and in release builds).
//!
//! A test arms a fault for the program of a given name and version; the next scans of the
//! container running that program fail that way, on the real scan path.

use std::sync::Mutex;

use crate::RuntimeError;

/// How an armed scan fails.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Fault {
    /// The scan panics, as a faulty guard function would.
    Panic,
    /// The scan returns an evaluation error.
    Error,
    /// The scan takes this many microseconds longer.
    Slow(u64),
}

static ARMED: Mutex<Vec<(String, String, Fault)>> = Mutex::new(Vec::new());

/// Makes every scan of `name` `version` fail with `fault` until [`disarm`].
pub fn arm(name: &str, version: &str, fault: Fault) {
    if let Ok(mut v) = ARMED.lock() {
        v.push((name.to_string(), version.to_string(), fault));
    }
}

/// Removes every armed fault.
pub fn disarm() {
    if let Ok(mut v) = ARMED.lock() {
        v.clear();
    }
}

pub(crate) fn before_scan(name: &str, version: &str) -> Result<(), RuntimeError> {
    let fault = ARMED.lock().ok().and_then(|v| {
        v.iter()
            .find(|(n, ver, _)| n == name && ver == version)
            .map(|(_, _, f)| f.clone())
    });
    match fault {
        Some(Fault::Panic) => panic!("injected panic in {name} {version}"),
        Some(Fault::Error) => Err(RuntimeError::Injected(format!(
            "guard error in {name} {version}"
        ))),
        Some(Fault::Slow(us)) => {
            std::thread::sleep(std::time::Duration::from_micros(us));
            Ok(())
        }
        None => Ok(()),
    }
}
