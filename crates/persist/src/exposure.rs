//! Whether a file or directory that the PLC trusts (its state directory, its configuration, its
//! keys) is closed to everyone but the PLC's user: the one test of it, which the state directory
//! and the local configuration each turn into an error of their own.

use std::os::unix::fs::MetadataExt;

/// What leaves a file or directory open to others.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exposure {
    /// Another user than the process's (root aside) owns it, and may change it.
    OwnedByOther {
        /// Its owner's uid.
        owner: u32,
        /// The process's effective uid.
        me: u32,
    },
    /// Its group or others may write it. A sticky directory (like `/tmp`) still lets others add
    /// files, so it is no exception.
    WritableByOthers {
        /// Its permission bits.
        mode: u32,
    },
}

/// How `meta` leaves its file open to others, if it does: owned by another user than the
/// process's (root aside), or writable by its group or others.
pub fn exposure(meta: &std::fs::Metadata) -> Option<Exposure> {
    let me = nix::unistd::geteuid().as_raw();
    if meta.uid() != me && meta.uid() != 0 {
        return Some(Exposure::OwnedByOther {
            owner: meta.uid(),
            me,
        });
    }
    let mode = meta.mode() & 0o7777;
    (mode & 0o022 != 0).then_some(Exposure::WritableByOthers { mode })
}
