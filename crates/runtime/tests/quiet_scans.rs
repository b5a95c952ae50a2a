//! A quiet scan (nothing can fire, so nothing is evaluated) is exactly a full scan that fires
//! nothing: two containers, one that never takes the quiet path, stay identical scan by scan on
//! random input sequences, for a program with plain guards and one with timer guards.

use std::sync::Arc;

use cetratus_program::{Program, Value};
use cetratus_runtime::Container;
use proptest::prelude::*;

fn program(name: &str) -> Arc<Program> {
    Arc::new(cetratus_testkit::programs::example(&format!(
        "vernadat/{name}"
    )))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn quiet_scans_change_nothing_a_full_scan_would(
        u2 in any::<bool>(),
        // Runs of (input bits, how many scans they hold, time step in ms).
        runs in prop::collection::vec((any::<u8>(), 1usize..40, 1u64..500), 1..60),
    ) {
        let p = program(if u2 { "u2.toml" } else { "vernadat.toml" });
        let mut quick = Container::new(p.clone(), 0);
        let mut full = Container::new(p.clone(), 0);
        full.set_always_full(true);
        let n = p.inputs().len();
        let mut now = 0u64;
        let mut last: Option<Vec<Value>> = None;
        for (bits, hold, step_ms) in runs {
            let image: Vec<Value> = (0..n).map(|i| Value::Bool(bits >> (i % 8) & 1 == 1)).collect();
            for _ in 0..hold {
                now += step_ms * 1000;
                // The hint the Message Router gives: the image is the previous scan's.
                let unchanged = last.as_ref() == Some(&image);
                let a = quick.scan_hinted(now, &image, unchanged).expect("scans");
                last = Some(image.clone());
                let b = full.scan(now, &image).expect("scans");
                prop_assert_eq!(a, b);
                prop_assert_eq!(quick.marking(), full.marking());
                prop_assert_eq!(quick.outputs(), full.outputs());
                prop_assert_eq!(quick.fired(), full.fired());
                prop_assert_eq!(quick.place_since_us(), full.place_since_us());
            }
        }
        prop_assert_eq!(quick.firings(), full.firings());
    }
}

/// A program whose body writes a variable in every scan while A is marked, and whose guard
/// reads it: a quiet scan that skipped the body's effect would fire T1 late or never.
fn counting() -> Arc<Program> {
    let src = "[program]\nname = \"count\"\nversion = \"1\"\n\
        [[input]]\nname = \"x\"\ntype = \"bool\"\n\
        [[output]]\nname = \"level\"\ntype = \"int\"\n\
        [[variable]]\nname = \"v\"\ntype = \"int\"\n\
        [guards]\nT1 = \"v >= 3 && x\"\nT2 = \"!x && B.t >= 20ms\"\nT3 = \"false\"\n\
        [bodies]\nUp = 'v := v + 1'\nShow = 'level := v'\nZero = 'v := 0'\n\
        [[action]]\nplace = \"A\"\nqualifier = \"N\"\nbody = \"Up\"\n\
        [[action]]\nplace = \"B\"\nqualifier = \"P1\"\nbody = \"Zero\"\n\
        [[action]]\nplace = \"B\"\nqualifier = \"L\"\nduration = \"50ms\"\nbody = \"Show\"\n";
    Arc::new(
        Program::from_sources(src, "count.toml", cetratus_testkit::nets::small())
            .unwrap_or_else(|e| panic!("{e}")),
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn a_body_that_writes_a_variable_in_every_scan_keeps_the_quiet_path_honest(
        runs in prop::collection::vec((any::<bool>(), 1usize..30, 1u64..40), 1..60),
    ) {
        let p = counting();
        let mut quick = Container::new(p.clone(), 0);
        let mut full = Container::new(p.clone(), 0);
        full.set_always_full(true);
        let mut now = 0u64;
        let mut last: Option<Vec<Value>> = None;
        for (x, hold, step_ms) in runs {
            let image = vec![Value::Bool(x)];
            for _ in 0..hold {
                now += step_ms * 1000;
                let unchanged = last.as_ref() == Some(&image);
                let a = quick.scan_hinted(now, &image, unchanged).expect("scans");
                last = Some(image.clone());
                let b = full.scan(now, &image).expect("scans");
                prop_assert_eq!(a, b);
                prop_assert_eq!(quick.marking(), full.marking());
                prop_assert_eq!(quick.variables(), full.variables());
                prop_assert_eq!(quick.outputs(), full.outputs());
                prop_assert_eq!(quick.fired(), full.fired());
            }
        }
        prop_assert_eq!(quick.firings(), full.firings());
    }
}
