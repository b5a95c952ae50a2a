//! Workloads and baselines shared by the criterion benches and `cetratus bench`.
//!
//! Every figure the project reports is measured on a workload defined here, so that `cargo bench`
//! and `cetratus bench --quick --json` measure the same thing.

pub mod analysis;
pub mod cyclictest;
pub mod dense;
pub mod embedded;
pub mod export;
pub mod flood;
pub mod fuzz;
pub mod harness;
pub mod io;
pub mod measure;
pub mod program;
pub mod rollout;
pub mod st;
pub mod update;
pub mod workloads;
