//! `--rt` gives the scan thread a CPU of its own: every other thread of the process, those
//! running before and those the scan thread starts later, runs on the other CPUs. (A process of
//! its own, so that moving threads and locking memory touch no other test.)

use cetratus_node::rt;
use nix::sched::{sched_getaffinity, CpuSet};
use nix::unistd::{gettid, Pid};

fn cpus_of(tid: Pid) -> Vec<usize> {
    let set = sched_getaffinity(tid).expect("the affinity of a thread of this process");
    (0..CpuSet::count())
        .filter(|&c| set.is_set(c).unwrap_or(false))
        .collect()
}

#[test]
fn the_scan_thread_gets_the_last_cpu_and_every_other_thread_the_rest() {
    let allowed = cpus_of(gettid());
    let (tid_tx, tid_rx) = std::sync::mpsc::channel();
    let (stop_tx, stop_rx) = std::sync::mpsc::channel::<()>();
    let before = std::thread::spawn(move || {
        tid_tx.send(gettid()).expect("send");
        let _ = stop_rx.recv();
    });
    let helper = tid_rx.recv().expect("the helper's id");

    let status = rt::request(1);

    if allowed.len() < 2 {
        assert_eq!(status.cpu, None);
        assert!(
            status.warnings.iter().any(|w| w.contains("one CPU")),
            "{:?}",
            status.warnings
        );
        return;
    }
    let last = *allowed.last().expect("a CPU");
    let rest: Vec<usize> = allowed[..allowed.len() - 1].to_vec();
    assert_eq!(status.cpu, Some(last), "{status}");
    assert!(status
        .to_string()
        .contains(&format!("CPU {last} to itself")));
    assert_eq!(cpus_of(gettid()), [last]);
    assert_eq!(cpus_of(helper), rest, "a thread that ran before");
    let later = std::thread::spawn(|| {
        rt::normal();
        cpus_of(gettid())
    })
    .join()
    .expect("the later thread");
    assert_eq!(later, rest, "a thread the scan thread started later");
    stop_tx.send(()).expect("stop");
    before.join().expect("the helper");
}
