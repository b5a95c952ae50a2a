//! Real-time scheduling on request: SCHED_FIFO for the scan thread, locked memory, and a CPU of
//! the scan thread's own.
//!
//! SCHED_FIFO and locked memory need privileges most machines do not grant by default. Where the
//! machine refuses, the caller gets the reason and goes on without them.
//!
//! SCHED_FIFO alone lets the scan thread preempt the process's other threads, but not the kernel
//! work they cause on its CPU: copying a 1 MiB MQTT payload out of a socket, or mapping and
//! unmapping its buffer, runs to its end before the scan thread gets the CPU back. With two or
//! more CPUs, [`request`] therefore gives the scan thread the last CPU the process may use, and
//! moves every other thread of the process to the others. A thread started later by the scan
//! thread inherits its CPU and priority: it calls [`normal`] first, which gives it back both.

use std::fmt;
#[cfg(target_os = "linux")]
use std::sync::OnceLock;

/// What `--rt` obtained.
#[derive(Clone, Debug, Default)]
pub struct RtStatus {
    /// SCHED_FIFO was granted to the calling thread.
    pub fifo: bool,
    /// All current and future pages are locked in memory.
    pub mlockall: bool,
    /// The CPU the scan thread has to itself, when the process may use two or more.
    pub cpu: Option<usize>,
    /// The CPUs are kept out of deep idle states (`/dev/cpu_dma_latency` held at 0 µs).
    pub idle_latency: bool,
    /// Why something was refused.
    pub warnings: Vec<String>,
}

impl fmt::Display for RtStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SCHED_FIFO {}, mlockall {}, ",
            if self.fifo { "on" } else { "off" },
            if self.mlockall { "on" } else { "off" }
        )?;
        match self.cpu {
            Some(cpu) => write!(f, "CPU {cpu} to itself")?,
            None => write!(f, "no CPU to itself")?,
        }
        if self.idle_latency {
            write!(f, ", no deep idle")?;
        }
        Ok(())
    }
}

/// The CPUs of every thread but the scan thread, once [`request`] gave the scan thread its own.
#[cfg(target_os = "linux")]
static OTHERS: OnceLock<nix::sched::CpuSet> = OnceLock::new();

/// Asks for SCHED_FIFO at `priority` (1..=99) on the calling thread and for mlockall, and gives
/// the calling thread a CPU of its own (see the module's doc).
pub fn request(priority: u8) -> RtStatus {
    let mut status = RtStatus::default();
    #[cfg(target_os = "linux")]
    {
        use thread_priority::{
            set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
            ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
        };
        let prio = ThreadPriorityValue::try_from(priority.clamp(1, 99))
            .map(ThreadPriority::Crossplatform)
            .unwrap_or(ThreadPriority::Max);
        match set_thread_priority_and_policy(
            thread_native_id(),
            prio,
            ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
        ) {
            Ok(()) => status.fifo = true,
            Err(e) => status.warnings.push(format!(
                "SCHED_FIFO refused ({e:?}); run as root or grant CAP_SYS_NICE / an rtprio limit"
            )),
        }
        use nix::sys::mman::{mlockall, MlockAllFlags};
        keep_heap();
        match mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
            Ok(()) => status.mlockall = true,
            Err(e) => status.warnings.push(format!(
                "mlockall refused ({e}); raise the memlock limit (ulimit -l) or grant CAP_IPC_LOCK"
            )),
        }
        match isolate() {
            Ok(cpu) => status.cpu = Some(cpu),
            Err(why) => status.warnings.push(why),
        }
        match hold_idle_latency() {
            Ok(()) => status.idle_latency = true,
            Err(why) => status.warnings.push(why),
        }
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = priority;
        status
            .warnings
            .push("real-time scheduling is only supported on Linux".to_string());
    }
    status
}

/// Gives the calling thread the last CPU the process may use, and moves every other thread of
/// the process to the rest; returns that CPU, or why not.
#[cfg(target_os = "linux")]
fn isolate() -> Result<usize, String> {
    use nix::sched::{sched_getaffinity, sched_setaffinity, CpuSet};
    use nix::unistd::{gettid, Pid};
    let me = gettid();
    let allowed =
        sched_getaffinity(me).map_err(|e| format!("cannot read the CPU affinity ({e})"))?;
    let cpus: Vec<usize> = (0..CpuSet::count())
        .filter(|&c| allowed.is_set(c).unwrap_or(false))
        .collect();
    let [_, .., scan] = cpus[..] else {
        return Err(
            "the process may use one CPU only: the scan thread shares it with the others"
                .to_string(),
        );
    };
    let mut own = CpuSet::new();
    let mut others = allowed;
    own.set(scan)
        .and_then(|()| others.unset(scan))
        .map_err(|e| format!("CPU {scan}: {e}"))?;
    sched_setaffinity(me, &own)
        .map_err(|e| format!("cannot pin the scan thread to CPU {scan} ({e})"))?;
    let _ = OTHERS.set(others);
    // Twice: a thread that another one started while the first pass ran has its creator's old
    // CPUs.
    for _ in 0..2 {
        let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
            break;
        };
        for tid in tasks
            .flatten()
            .filter_map(|t| t.file_name().to_str()?.parse::<i32>().ok())
        {
            if tid != me.as_raw() {
                // A thread that ended meanwhile is no error.
                let _ = sched_setaffinity(Pid::from_raw(tid), &others);
            }
        }
    }
    Ok(scan)
}

/// Keeps the allocator from returning memory to the kernel and from mapping large blocks of
/// their own. Every mapping change takes the process's memory-map lock, and under
/// `mlockall(MCL_FUTURE)` a new mapping is also faulted in and locked while the lock is held: a
/// thread receiving 1 MiB MQTT payloads would map and unmap one per message, and the scan thread,
/// whenever its own heap grows or shrinks, would wait for it. With this, the heap grows to the
/// process's peak and stays there (the usual recipe for real-time programs with locked memory).
#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
fn keep_heap() {
    #[cfg(target_env = "gnu")]
    // SAFETY: mallopt only changes the allocator's tunables; it is called before the scan
    // thread starts its cycles, and glibc serialises it against allocations.
    unsafe {
        nix::libc::mallopt(nix::libc::M_TRIM_THRESHOLD, i32::MAX);
        nix::libc::mallopt(nix::libc::M_MMAP_MAX, 0);
    }
}

/// The open `/dev/cpu_dma_latency`: the kernel keeps the request while it stays open.
#[cfg(target_os = "linux")]
static IDLE_LATENCY: OnceLock<std::fs::File> = OnceLock::new();

/// Asks the kernel to keep every CPU out of idle states whose wake-up takes longer than 0 µs,
/// for as long as the process lives, as `cyclictest` does. An idle CPU otherwise halts, and on a
/// virtual machine a halted CPU gives its physical one back to the host: the scan thread's timer
/// then wakes it with a latency of tens to hundreds of microseconds (docs/performance.md).
#[cfg(target_os = "linux")]
fn hold_idle_latency() -> Result<(), String> {
    use std::io::Write;
    if IDLE_LATENCY.get().is_some() {
        return Ok(());
    }
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/cpu_dma_latency")
        .map_err(|e| {
            format!(
                "cannot open /dev/cpu_dma_latency ({e}): idle CPUs may enter deep sleep states \
                 and wake the scan thread late; run as root or make the device writable"
            )
        })?;
    f.write_all(&0i32.to_ne_bytes())
        .map_err(|e| format!("cannot write /dev/cpu_dma_latency ({e})"))?;
    let _ = IDLE_LATENCY.set(f);
    Ok(())
}

/// Gives up real-time scheduling on the calling thread: a thread inherits its creator's policy
/// and CPU, so a helper started by a SCHED_FIFO scan thread would otherwise compete with it at its
/// priority, on its CPU. Does nothing where real-time scheduling was never granted.
pub fn normal() {
    #[cfg(target_os = "linux")]
    {
        if let Some(others) = OTHERS.get() {
            let _ = nix::sched::sched_setaffinity(nix::unistd::gettid(), others);
        }
        use thread_priority::{
            set_thread_priority_and_policy, thread_native_id, NormalThreadSchedulePolicy,
            ThreadPriority, ThreadSchedulePolicy,
        };
        // Nice 0, as a thread gets by default.
        let _ = set_thread_priority_and_policy(
            thread_native_id(),
            ThreadPriority::Os(thread_priority::ThreadPriorityOsValue::default()),
            ThreadSchedulePolicy::Normal(NormalThreadSchedulePolicy::Other),
        );
    }
}
