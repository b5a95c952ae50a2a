//! Workloads of the state-space benches.
