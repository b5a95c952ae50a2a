//! Real-time scheduling on request: SCHED_FIFO for the scan thread and locked memory.
//!
//! Both need privileges most machines do not grant by default. Where the machine refuses, the
//! caller gets the reason and goes on without them.

use std::fmt;

/// What `--rt` obtained.
#[derive(Clone, Debug, Default)]
pub struct RtStatus {
    /// SCHED_FIFO was granted to the calling thread.
    pub fifo: bool,
    /// All current and future pages are locked in memory.
    pub mlockall: bool,
    /// Why something was refused.
    pub warnings: Vec<String>,
}

impl fmt::Display for RtStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SCHED_FIFO {}, mlockall {}",
            if self.fifo { "on" } else { "off" },
            if self.mlockall { "on" } else { "off" }
        )
    }
}

/// Asks for SCHED_FIFO at `priority` (1..=99) on the calling thread and for mlockall.
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
        match mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
            Ok(()) => status.mlockall = true,
            Err(e) => status.warnings.push(format!(
                "mlockall refused ({e}); raise the memlock limit (ulimit -l) or grant CAP_IPC_LOCK"
            )),
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

/// Gives up real-time scheduling on the calling thread: a thread inherits its creator's policy,
/// so a helper started by a SCHED_FIFO scan thread would otherwise compete with it at its
/// priority. Does nothing where real-time scheduling was never granted.
pub fn normal() {
    #[cfg(target_os = "linux")]
    {
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
