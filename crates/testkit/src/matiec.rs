//! MATIEC as the second implementation the Structured Text tests compare against: the
//! `cetratus-matiec` crate, which `cetratus bench st` uses too.

pub use cetratus_matiec::*;
