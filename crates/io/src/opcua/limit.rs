//! The rate limits of the OPC UA server (docs/security.md, *OPC UA*): password checks for all
//! clients together, and new connections per address, on the token buckets that the dashboard's
//! login limiter and the broker's use.

use cetratus_slots::rate::Rate;

/// Password checks a second for all clients together, and the burst allowed above it: as the
/// dashboard's logins.
pub(crate) const LOGINS: Rate = Rate {
    per_s: 4.0,
    burst: 8.0,
};

/// New connections a second from one address, and the burst allowed above it.
pub(crate) const CONNECTIONS_PER_ADDRESS: Rate = Rate {
    per_s: 4.0,
    burst: 16.0,
};
