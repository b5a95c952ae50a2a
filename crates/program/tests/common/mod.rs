//! A small program for the behaviour tests.

#![allow(dead_code)]

use cetratus_program::Program;

/// A program over `cetratus_testkit::nets::small` with inputs `x: bool`, `n: int`, `r: real`,
/// variable `v: int`, and whatever `rest` adds.
pub fn program(rest: &str) -> Program {
    let src = format!(
        "[program]\nname = \"small\"\nversion = \"1\"\n\
         [[input]]\nname = \"x\"\ntype = \"bool\"\n\
         [[input]]\nname = \"n\"\ntype = \"int\"\n\
         [[input]]\nname = \"r\"\ntype = \"real\"\n\
         [[variable]]\nname = \"v\"\ntype = \"int\"\ninitial = 5\n{rest}"
    );
    Program::from_sources(&src, "small.toml", cetratus_testkit::nets::small())
        .unwrap_or_else(|e| panic!("{e}"))
}
