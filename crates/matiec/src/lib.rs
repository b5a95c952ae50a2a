//! MATIEC, the IEC 61131-3 compiler of OpenPLC and Beremiz, as an independent second
//! implementation of Structured Text: the tests run a batch of PROGRAMs through it and compare
//! their outputs, scan for scan, with what the project's own implementation computes.
//!
//! # A run
//!
//! [`Matiec::run`] appends to the caller's POUs one CONFIGURATION `Cetratus_Config` with one
//! RESOURCE `Cetratus_Res`, one TASK `Cetratus_Tick` whose interval is the tick, and one program
//! instance `Cetratus_Case<i>` per [`Case`] (so POU names starting with `Cetratus_` are
//! reserved). One `iec2c` and one build turn the whole batch into one executable, whose harness
//! reads the input values from a file and writes the output values to standard output; with
//! [`Matiec::compile`], a new input sequence for the same cases costs a run of the [`Batch`]
//! (milliseconds), not a compile. Scan `k` (0-based) of the batch:
//!
//! 1. writes the inputs of scan `k` into each case's program instance (`__SET_VAR` on the
//!    instance struct, as the generated code does), or, for an input named by its address
//!    (`%IX0.1`), into the located variable, as a PLC runtime's I/O does (outputs likewise);
//! 2. sets `__CURRENT_TIME` to `k × tick` (normalized: `tv_sec` and `tv_nsec` of one sign), so
//!    the first scan sees time 0, and a TON started in scan `j` with `PT = n × tick` has `Q`
//!    TRUE from scan `j + n` on (for a PT that is exact: MATIEC computes many TIME literals
//!    1 ns short, `T#1ms` for one): the implementation under test must give scan `k` the time
//!    `k × tick`, exactly;
//! 3. calls `config_run__(k)`, which runs every instance once, in case order;
//! 4. reads the outputs of each case.
//!
//! A case with fewer scans than the longest one keeps its last inputs and goes on running (the
//! task runs every instance), but its outputs are no longer read: its result has one entry per
//! scan it gave. Variables keep their values from scan to scan; `config_init__()` runs once.
//!
//! # Canonical value text
//!
//! Inputs and outputs are text, one value each, the same in both directions:
//!
//! | type | text |
//! |---|---|
//! | BOOL | `TRUE` or `FALSE` (a stored byte other than 0 or 1 comes out as `BOOL#<n>`) |
//! | SINT, INT, DINT, LINT | signed decimal, e.g. `-32768` |
//! | USINT … ULINT, BYTE … LWORD | unsigned decimal, e.g. `65535` |
//! | REAL | `r` + the 8 lowercase hex digits of the f32 bits, e.g. `r3fc00000` (1.5) |
//! | LREAL | `l` + the 16 lowercase hex digits of the f64 bits |
//! | TIME | `t` + the signed total of nanoseconds, e.g. `t-1500000000` (MATIEC's TIME is `tv_sec`/`tv_nsec`; beyond ±292 years it cannot be written) |
//! | STRING | `'` bytes `'`, where `$` is `$$`, `'` is `$'`, and a byte < 0x20 or ≥ 0x7f is `$XX` (two uppercase hex digits); at most 126 bytes (MATIEC's `STR_MAX_LEN`) |
//!
//! Input text is checked before anything is compiled, and must be exactly canonical (no `+5`,
//! no `007`, no `$41` for `A`), so that a generator's mistake is found where it is made.
//!
//! # Compiling
//!
//! `iec2c -f -O p` writes each POU to a file of its own, which the harness compiles in as many
//! translation units as the machine has cores, in parallel: `cc` is the slow part, and a batch
//! of 500 small programs is otherwise one 30 000-line C file that `cc -O2` needs 26 s for on
//! one core. (So beside `Cetratus_*`, a POU must not be named `POUS`; the harness's own files
//! are named `cetratus-…`, which no POU can be.) Every unit is compiled with
//! `cc -O2 -fwrapv -ffp-contract=off -Werror=implicit-function-declaration`:
//!
//! * `-fwrapv`: IEC integer arithmetic wraps at the type's width, and MATIEC emits plain C
//!   arithmetic (`a + b`), in which DINT and LINT overflow is undefined behaviour; with
//!   `-fwrapv` gcc wraps. (SINT and INT arithmetic happens in C `int` and wraps when stored.)
//! * `-ffp-contract=off`: gcc otherwise fuses `a * b + c` into one FMA where the target has one
//!   (aarch64), which rounds once instead of twice, unlike the interpreter.
//! * `-Werror=implicit-function-declaration`: a function C does not know (the accessor of a
//!   global a unit was not shown) would return a truncated `int`; it is an error instead.
//! * `-O2` unless [`Matiec::with_optimisation`] says otherwise: what the undefined behaviour
//!   that `-fwrapv` leaves yields (a shift by the width or more, a REAL out of an integer's
//!   range) depends on the level and on what gcc folds at compile time. A program free of it
//!   (every generated one is) computes the same at every level, so a differential test may
//!   trade `-O2` for a faster compile; a benchmark keeps `-O2`.
//!
//! The harness asserts at compile time that each input and output has the C type of its
//! [`IecType`] (so a mistyped case fails in `cc`, naming the case and the variable); types
//! that MATIEC stores alike (BOOL, BYTE and USINT are all `uint8_t`) cannot be told apart.
//!
//! # Cost
//!
//! Wall times of [`Matiec::run_timed`] on a quiet 2-core x86-64 machine (gcc 12), for programs
//! of some 30 lines each (three inputs, four outputs, an IF, a FOR loop, a TON), 10 scans:
//!
//! | programs | iec2c | cc | run |
//! |---|---|---|---|
//! | 1 | 0.6 s | 0.8 s | 2 ms |
//! | 50 | 1.1 s | 2.7 s | 6 ms |
//! | 200 | 3.1 s | 7.8 s | 9 ms |
//! | 500 | 6.8 s | 17.0 s | 33 ms |
//!
//! `iec2c` costs about 0.4 s plus 13 ms a program, on one core; `cc -O2` about 1.5 s plus
//! 48 ms of CPU a program, spread over the cores (as one unit, 500 programs take 26 s; at `-O1`
//! 14 s, at `-O0` 7 s). A run is milliseconds, so one compile should serve many input
//! sequences. On a machine busy with other builds the figures double or triple.
//!
//! # Errors
//!
//! Every stage that can fail has its variant of [`MatiecError`], with what the tool said: the
//! first error of `iec2c` with the offending source line, the first error of `cc` with the
//! offending C line, or how and in which scan the executable failed (an integer division by
//! zero kills it with SIGFPE). The temporary directory is removed in every case.

use std::fmt;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The flags every translation unit is compiled with (the module doc says why), besides the
/// optimisation level ([`Matiec::with_optimisation`]).
const CFLAGS: [&str; 3] = [
    "-fwrapv",
    "-ffp-contract=off",
    "-Werror=implicit-function-declaration",
];

/// The first line of the harness's input, so that a stale executable refuses new input.
const INPUT_HEADER: &str = "cetratus-matiec-input 1";

/// The longest STRING MATIEC stores (`STR_MAX_LEN` in `iec_types.h`).
const STR_MAX_LEN: usize = 126;

/// How long a run may take before it is taken for an endless loop, unless
/// [`Matiec::with_run_timeout`] says otherwise.
const DEFAULT_RUN_TIMEOUT: Duration = Duration::from_secs(120);

/// IEC elementary types the harness can pass in and read out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum IecType {
    /// BOOL, stored by MATIEC as `uint8_t`.
    Bool,
    /// SINT, 8-bit signed.
    Sint,
    /// INT, 16-bit signed.
    Int,
    /// DINT, 32-bit signed.
    Dint,
    /// LINT, 64-bit signed.
    Lint,
    /// USINT, 8-bit unsigned.
    Usint,
    /// UINT, 16-bit unsigned.
    Uint,
    /// UDINT, 32-bit unsigned.
    Udint,
    /// ULINT, 64-bit unsigned.
    Ulint,
    /// BYTE, 8 bits.
    Byte,
    /// WORD, 16 bits.
    Word,
    /// DWORD, 32 bits.
    Dword,
    /// LWORD, 64 bits.
    Lword,
    /// REAL, an f32.
    Real,
    /// LREAL, an f64.
    Lreal,
    /// TIME, seconds and nanoseconds.
    Time,
    /// STRING of at most 126 bytes.
    String,
}

impl IecType {
    /// The type's IEC name, which is also its C name in MATIEC's headers.
    pub fn name(self) -> &'static str {
        match self {
            IecType::Bool => "BOOL",
            IecType::Sint => "SINT",
            IecType::Int => "INT",
            IecType::Dint => "DINT",
            IecType::Lint => "LINT",
            IecType::Usint => "USINT",
            IecType::Uint => "UINT",
            IecType::Udint => "UDINT",
            IecType::Ulint => "ULINT",
            IecType::Byte => "BYTE",
            IecType::Word => "WORD",
            IecType::Dword => "DWORD",
            IecType::Lword => "LWORD",
            IecType::Real => "REAL",
            IecType::Lreal => "LREAL",
            IecType::Time => "TIME",
            IecType::String => "STRING",
        }
    }

    /// Whether `text` is a value of this type in canonical text; if not, what was expected.
    fn check(self, text: &str) -> Result<(), &'static str> {
        let ok = match self {
            IecType::Bool => text == "TRUE" || text == "FALSE",
            IecType::Sint => signed_in(text, i8::MIN.into(), i8::MAX.into()),
            IecType::Int => signed_in(text, i16::MIN.into(), i16::MAX.into()),
            IecType::Dint => signed_in(text, i32::MIN.into(), i32::MAX.into()),
            IecType::Lint => signed_in(text, i64::MIN, i64::MAX),
            IecType::Usint | IecType::Byte => unsigned_in(text, u8::MAX.into()),
            IecType::Uint | IecType::Word => unsigned_in(text, u16::MAX.into()),
            IecType::Udint | IecType::Dword => unsigned_in(text, u32::MAX.into()),
            IecType::Ulint | IecType::Lword => unsigned_in(text, u64::MAX),
            IecType::Real => bits(text, 'r', 8),
            IecType::Lreal => bits(text, 'l', 16),
            IecType::Time => text
                .strip_prefix('t')
                .is_some_and(|ns| signed_in(ns, i64::MIN, i64::MAX)),
            IecType::String => canonical_string(text),
        };
        if ok {
            return Ok(());
        }
        Err(match self {
            IecType::Bool => "TRUE or FALSE",
            IecType::Sint | IecType::Int | IecType::Dint | IecType::Lint => {
                "a signed decimal in the type's range, without `+` or leading zeros"
            }
            IecType::Real => "`r` and the 8 lowercase hex digits of the f32 bits",
            IecType::Lreal => "`l` and the 16 lowercase hex digits of the f64 bits",
            IecType::Time => "`t` and a signed decimal number of nanoseconds",
            IecType::String => {
                "`'…'` with `$$`, `$'` and `$XX` (uppercase) for bytes < 0x20 or >= 0x7f, \
                 and only there, at most 126 bytes"
            }
            _ => "an unsigned decimal in the type's range, without `+` or leading zeros",
        })
    }
}

impl fmt::Display for IecType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

fn signed_in(text: &str, min: i64, max: i64) -> bool {
    text.parse::<i64>()
        .is_ok_and(|v| (min..=max).contains(&v) && v.to_string() == text)
}

fn unsigned_in(text: &str, max: u64) -> bool {
    text.parse::<u64>()
        .is_ok_and(|v| v <= max && v.to_string() == text)
}

fn bits(text: &str, tag: char, digits: usize) -> bool {
    text.strip_prefix(tag).is_some_and(|hex| {
        hex.len() == digits && hex.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
    })
}

/// Whether `text` is a STRING in canonical text (see the module doc).
fn canonical_string(text: &str) -> bool {
    let Some(body) = text.strip_prefix('\'').and_then(|t| t.strip_suffix('\'')) else {
        return false;
    };
    let body = body.as_bytes();
    let (mut i, mut len) = (0, 0);
    while i < body.len() {
        i += match body[i..] {
            [b'$', b'$' | b'\'', ..] => 2,
            [b'$', h, l, ..] => match (upper_hex(h), upper_hex(l)) {
                (Some(h), Some(l)) if !(0x20..0x7f).contains(&(h * 16 + l)) => 3,
                _ => return false,
            },
            [0x20..=0x7e, ..] if !matches!(body[i], b'$' | b'\'') => 1,
            _ => return false,
        };
        len += 1;
    }
    len <= STR_MAX_LEN
}

fn upper_hex(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'A'..=b'F' => Some(c - b'A' + 10),
        _ => None,
    }
}

/// One PROGRAM of a batch, its inputs (VAR_INPUT) and outputs (VAR_OUTPUT) by name and type,
/// and the input values of each scan, as canonical text (see the module doc).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Case {
    /// The name of the PROGRAM, declared in the batch's source.
    pub program: String,
    /// The variables written before each scan, in the order of each scan's values.
    pub inputs: Vec<(String, IecType)>,
    /// The variables read after each scan, in the order of each scan's results.
    pub outputs: Vec<(String, IecType)>,
    /// Per scan, one value per input.
    pub scans: Vec<Vec<String>>,
}

/// The outputs of a batch: per case, per scan of the case, one canonical value per output.
pub type Outputs = Vec<Vec<Vec<String>>>;

/// What each stage of [`Matiec::run_timed`] took.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Timings {
    /// Translating the ST to C.
    pub iec2c: Duration,
    /// Compiling and linking the C (wall time; the units compile in parallel).
    pub cc: Duration,
    /// Running every scan of every case.
    pub run: Duration,
}

/// A stage of a batch that failed, with what the tool said.
#[derive(Debug)]
pub enum MatiecError {
    /// MATIEC is not installed and cannot be built, or a tool it needs is missing.
    Build {
        /// What is missing, and how to get it.
        message: String,
    },
    /// The batch is malformed (a name that is no identifier, a value not in canonical text, a
    /// scan with the wrong number of values, a zero tick); nothing was compiled.
    Invalid {
        /// What is wrong, naming the case, the scan and the variable.
        message: String,
    },
    /// `iec2c` rejected the source.
    Iec2c {
        /// The line of the batch's source where the first error is, when `iec2c` says; the
        /// caller's source comes first, so its line numbers are the caller's.
        line: Option<usize>,
        /// That line of the source.
        source_line: Option<String>,
        /// The first error line `iec2c` printed.
        first_error: String,
        /// All that `iec2c` printed on standard error.
        output: String,
    },
    /// `cc` rejected the C that `iec2c` and the harness generated.
    Cc {
        /// The first error line `cc` printed.
        first_error: String,
        /// The C line it points at, when there is one.
        c_line: Option<String>,
        /// All that `cc` printed on standard error.
        output: String,
    },
    /// The compiled batch failed while running.
    Run {
        /// The scan that was running, when the failure came during one.
        scan: Option<usize>,
        /// How it failed: the exit status or signal, the timeout, or what was wrong with its
        /// output, and what it printed on standard error.
        message: String,
    },
    /// A file of the batch could not be written or read, or a tool could not be started.
    Io {
        /// What was being done.
        what: String,
        /// Why it failed.
        source: io::Error,
    },
}

impl fmt::Display for MatiecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MatiecError::Build { message } => write!(f, "MATIEC is not available: {message}"),
            MatiecError::Invalid { message } => write!(f, "malformed MATIEC batch: {message}"),
            MatiecError::Iec2c {
                line,
                source_line,
                first_error,
                output,
            } => {
                match line {
                    Some(line) => write!(f, "iec2c rejected the source at line {line}: ")?,
                    None => write!(f, "iec2c rejected the source: ")?,
                }
                write!(f, "{first_error}")?;
                if let (Some(line), Some(text)) = (line, source_line) {
                    write!(f, "\n  {line} | {text}")?;
                }
                write!(f, "\niec2c's output:\n{}", first_lines(output, 30))
            }
            MatiecError::Cc {
                first_error,
                c_line,
                output,
            } => {
                write!(f, "cc rejected the generated C: {first_error}")?;
                if let Some(text) = c_line {
                    write!(f, "\n  | {text}")?;
                }
                write!(f, "\ncc's output:\n{}", first_lines(output, 30))
            }
            MatiecError::Run {
                scan: Some(scan),
                message,
            } => write!(
                f,
                "the compiled MATIEC batch failed in scan {scan}: {message}"
            ),
            MatiecError::Run {
                scan: None,
                message,
            } => write!(f, "the compiled MATIEC batch failed: {message}"),
            MatiecError::Io { what, source } => write!(f, "{what}: {source}"),
        }
    }
}

impl std::error::Error for MatiecError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            MatiecError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// The first `n` lines of `text`, and how many more there were.
fn first_lines(text: &str, n: usize) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let mut shown = lines[..lines.len().min(n)].join("\n");
    if lines.len() > n {
        shown.push_str(&format!("\n… and {} more lines", lines.len() - n));
    }
    shown
}

fn io_error(what: impl Into<String>) -> impl FnOnce(io::Error) -> MatiecError {
    let what = what.into();
    move |source| MatiecError::Io { what, source }
}

/// An installed MATIEC: `DIR/bin/iec2c`, its ST library `DIR/lib` and its C headers
/// `DIR/lib/C`.
#[derive(Debug, Clone)]
pub struct Matiec {
    dir: PathBuf,
    run_timeout: Duration,
    /// `-O2` unless set.
    optimisation: &'static str,
    /// VAR_GLOBAL blocks of the configuration.
    globals: String,
}

impl Matiec {
    /// Builds MATIEC once with the shared `build.sh` (found at
    /// `../shared/tools/matiec/build.sh` beside the workspace of a source checkout; the environment variable
    /// `CETRATUS_MATIEC_DIR` overrides it with an install dir) and returns it; `Err` with a
    /// clear message naming what is missing otherwise.
    ///
    /// The build runs once per process however many tests ask at once, and under `flock`
    /// (when installed) so that two test processes never build at the same time.
    pub fn get() -> Result<Matiec, MatiecError> {
        if let Some(dir) = std::env::var_os("CETRATUS_MATIEC_DIR") {
            return Matiec::at(PathBuf::from(dir));
        }
        static BUILT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
        let dir = BUILT
            .get_or_init(build)
            .clone()
            .map_err(|message| MatiecError::Build { message })?;
        Matiec::at(dir)
    }

    /// The MATIEC installed in `dir`, once `iec2c`, its library and `cc` are found.
    pub fn at(dir: PathBuf) -> Result<Matiec, MatiecError> {
        for needed in ["bin/iec2c", "lib/ieclib.txt", "lib/C/iec_std_lib.h"] {
            if !dir.join(needed).is_file() {
                return Err(MatiecError::Build {
                    message: format!(
                        "{} is missing: {} is no MATIEC install dir (build one with \
                         ../shared/tools/matiec/build.sh DIR)",
                        dir.join(needed).display(),
                        dir.display()
                    ),
                });
            }
        }
        if find_program("cc").is_none() {
            return Err(MatiecError::Build {
                message: "`cc` is missing: install the Debian package `build-essential`".into(),
            });
        }
        Ok(Matiec {
            dir,
            run_timeout: DEFAULT_RUN_TIMEOUT,
            optimisation: "-O2",
            globals: String::new(),
        })
    }

    /// The install dir.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The same MATIEC, compiling the generated C at `level` (`-O0` … `-O2`) instead of `-O2`:
    /// a differential test of many programs spends most of its time in `cc -O2`, and the
    /// flags that fix the semantics (`-fwrapv`, `-ffp-contract=off`) stay.
    pub fn with_optimisation(self, level: &'static str) -> Matiec {
        Matiec {
            optimisation: level,
            ..self
        }
    }

    /// The same MATIEC, whose configuration declares `globals` (whole `VAR_GLOBAL … END_VAR`
    /// blocks) for the programs of its batches to read as `VAR_EXTERNAL`.
    pub fn with_globals(self, globals: impl Into<String>) -> Matiec {
        Matiec {
            globals: globals.into(),
            ..self
        }
    }

    /// The same MATIEC, whose runs are killed after `timeout` (two minutes unless set): a
    /// generated program may loop for ever.
    pub fn with_run_timeout(self, timeout: Duration) -> Matiec {
        Matiec {
            run_timeout: timeout,
            ..self
        }
    }

    /// Compiles `source` (ST text holding all the POUs, e.g. many PROGRAMs) with iec2c and cc in
    /// ONE compile, as one CONFIGURATION/RESOURCE with one TASK of interval `tick` and one
    /// instance per case, runs every case for its scans, and returns, per case, per scan, the
    /// output values in canonical text.
    pub fn run(
        &self,
        source: &str,
        cases: &[Case],
        tick: Duration,
    ) -> Result<Outputs, MatiecError> {
        self.run_timed(source, cases, tick)
            .map(|(outputs, _)| outputs)
    }

    /// [`Matiec::run`], and what each stage took.
    pub fn run_timed(
        &self,
        source: &str,
        cases: &[Case],
        tick: Duration,
    ) -> Result<(Outputs, Timings), MatiecError> {
        let (batch, iec2c, cc) = self.compile_timed(source, cases, tick)?;
        let start = Instant::now();
        let outputs = batch.run(cases)?;
        let run = start.elapsed();
        Ok((outputs, Timings { iec2c, cc, run }))
    }

    /// Compiles `source` for `cases` as [`Matiec::run`] does, without running it: the
    /// [`Batch`] runs any number of input sequences for the same cases, a process each.
    pub fn compile(
        &self,
        source: &str,
        cases: &[Case],
        tick: Duration,
    ) -> Result<Batch, MatiecError> {
        self.compile_timed(source, cases, tick)
            .map(|(batch, _, _)| batch)
    }

    /// [`Matiec::compile`], and what `iec2c` and `cc` took.
    fn compile_timed(
        &self,
        source: &str,
        cases: &[Case],
        tick: Duration,
    ) -> Result<(Batch, Duration, Duration), MatiecError> {
        check_batch(cases, tick)?;
        let tmp = tempfile::Builder::new()
            .prefix("cetratus-matiec-")
            .tempdir()
            .map_err(io_error("cannot create a temporary directory"))?;
        let dir = tmp.path();

        let start = Instant::now();
        self.iec2c(dir, &batch_source(source, &self.globals, cases, tick))?;
        let iec2c = start.elapsed();

        let start = Instant::now();
        write_file(&dir.join("cetratus-harness.c"), &harness_c(cases))?;
        self.cc(dir)?;
        let cc = start.elapsed();

        let schema = cases
            .iter()
            .map(|c| Case {
                scans: Vec::new(),
                ..c.clone()
            })
            .collect();
        let batch = Batch {
            dir: tmp,
            cases: schema,
            tick,
            run_timeout: self.run_timeout,
        };
        Ok((batch, iec2c, cc))
    }

    /// Translates the batch `text` into C in `dir`, one file per POU (`-O p`).
    fn iec2c(&self, dir: &Path, text: &str) -> Result<(), MatiecError> {
        write_file(&dir.join("cetratus-batch.st"), text)?;
        let out = Command::new(self.dir.join("bin/iec2c"))
            .args(["-f", "-O", "p", "-I"])
            .arg(self.dir.join("lib"))
            .arg("-T")
            .arg(dir)
            .arg("cetratus-batch.st")
            .current_dir(dir)
            .output()
            .map_err(io_error("cannot start iec2c"))?;
        if out.status.success() {
            let header = dir.join("LOCATED_VARIABLES.h");
            let text = fs::read_to_string(&header)
                .map_err(io_error("cannot read iec2c's LOCATED_VARIABLES.h"))?;
            return write_file(&header, &located_only(&text));
        }
        let output = String::from_utf8_lossy(&out.stderr).into_owned();
        let first_error = output
            .lines()
            .find(|l| l.contains("error"))
            .map(str::to_owned)
            .unwrap_or_else(|| format!("iec2c failed ({}) without an error line", out.status));
        let line = first_error
            .strip_prefix("cetratus-batch.st:")
            .and_then(|rest| {
                let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
                rest[..digits].parse::<usize>().ok()
            });
        let source_line = line
            .and_then(|n| text.lines().nth(n.checked_sub(1)?))
            .map(str::to_owned);
        Err(MatiecError::Iec2c {
            line,
            source_line,
            first_error,
            output,
        })
    }

    /// Compiles the translation units of `dir` in parallel and links them into
    /// `dir/cetratus-harness`.
    fn cc(&self, dir: &Path) -> Result<(), MatiecError> {
        let units = translation_units(dir)?;
        let mut jobs = Vec::new();
        let mut error = None;
        for (i, unit) in units.iter().enumerate() {
            match self.spawn_cc(dir, unit, i) {
                Ok(job) => jobs.push(job),
                Err(e) => {
                    error = Some(e);
                    break;
                }
            }
        }
        // Every job started is waited for, even after a failure, so that none writes into the
        // temporary directory while it is removed.
        let (mut failed, mut messages) = (false, String::new());
        for (mut child, log) in jobs {
            match child.wait() {
                Ok(status) if status.success() => {}
                Ok(_) => {
                    failed = true;
                    messages.push_str(&fs::read_to_string(&log).unwrap_or_default());
                }
                Err(e) => error = error.or(Some(io_error("cannot wait for cc")(e))),
            }
        }
        if let Some(e) = error {
            return Err(e);
        }
        if failed {
            return Err(cc_error(dir, &messages));
        }
        let out = Command::new("cc")
            .args((0..units.len()).map(|i| format!("cetratus-unit-{i}.o")))
            .args(["-lm", "-o", "cetratus-harness"])
            .current_dir(dir)
            .output()
            .map_err(io_error("cannot start cc to link"))?;
        if !out.status.success() {
            return Err(cc_error(dir, &String::from_utf8_lossy(&out.stderr)));
        }
        Ok(())
    }

    /// Starts `cc -c` on `unit`, its messages going to a log file; returns it and the log.
    fn spawn_cc(&self, dir: &Path, unit: &str, i: usize) -> Result<(Child, PathBuf), MatiecError> {
        let log = dir.join(format!("cetratus-cc-{i}.log"));
        let child = Command::new("cc")
            .arg(self.optimisation)
            .args(CFLAGS)
            .arg("-I")
            .arg(self.dir.join("lib/C"))
            .args(["-I", ".", "-c", unit, "-o"])
            .arg(format!("cetratus-unit-{i}.o"))
            .current_dir(dir)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(file(&log)?)
            .spawn()
            .map_err(io_error("cannot start cc"))?;
        Ok((child, log))
    }
}

/// Runs `build.sh` (under `flock` when there is one) and returns the dir it printed.
fn build() -> Result<PathBuf, String> {
    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/tools/matiec/build.sh");
    if !script.is_file() {
        return Err(format!(
            "{} is missing (it builds MATIEC from the archive beside it); or set \
             CETRATUS_MATIEC_DIR to a MATIEC install dir",
            script.display()
        ));
    }
    let mut cmd = match find_program("flock") {
        Some(flock) => {
            let mut cmd = Command::new(flock);
            cmd.arg(std::env::temp_dir().join("cetratus-matiec-build.lock"))
                .arg("bash");
            cmd
        }
        None => Command::new("bash"),
    };
    let out = cmd
        .arg(&script)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("cannot start {}: {e}", script.display()))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return Err(format!(
            "{} failed ({}):\n{}",
            script.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim_end()
        ));
    }
    stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .map(|l| PathBuf::from(l.trim()))
        .ok_or_else(|| format!("{} printed no install dir", script.display()))
}

/// Checks the batch before anything is compiled or run.
fn check_batch(cases: &[Case], tick: Duration) -> Result<(), MatiecError> {
    let invalid = |message: String| Err(MatiecError::Invalid { message });
    if tick.is_zero() {
        return invalid("the tick is zero; a TASK needs a positive interval".into());
    }
    if cases.is_empty() {
        return invalid("no cases; a batch runs at least one PROGRAM instance".into());
    }
    for (i, case) in cases.iter().enumerate() {
        if !is_identifier(&case.program) {
            return invalid(format!(
                "case {i}: `{}` is not an IEC identifier",
                case.program
            ));
        }
        let signals =
            (case.inputs.iter().map(|(n, _)| n)).chain(case.outputs.iter().map(|(n, _)| n));
        for name in signals {
            if !name.split('.').all(is_identifier) && !is_address(name) {
                return invalid(format!(
                    "case {i}: `{name}` is neither an IEC identifier (or a member path such as \
                     LOGIC.COUNT) nor a direct address such as %IX0.1"
                ));
            }
        }
        for (k, values) in case.scans.iter().enumerate() {
            if values.len() != case.inputs.len() {
                return invalid(format!(
                    "case {i} ({}), scan {k}: {} values for {} inputs",
                    case.program,
                    values.len(),
                    case.inputs.len()
                ));
            }
            for ((name, ty), value) in case.inputs.iter().zip(values) {
                if let Err(expected) = ty.check(value) {
                    return invalid(format!(
                        "case {i} ({}), scan {k}, input `{name}` ({ty}): `{value}` is not \
                         canonical text; expected {expected}",
                        case.program
                    ));
                }
            }
        }
    }
    Ok(())
}

/// `%IX0.1`, `%QW3`, `%MD2`: an area, a size and a number, with a bit for `X`.
fn is_address(name: &str) -> bool {
    let b = name.as_bytes();
    let digits = |t: &[u8]| !t.is_empty() && t.iter().all(u8::is_ascii_digit);
    match b {
        [b'%', area, size, rest @ ..] if b"IQM".contains(area) => match size {
            b'X' => match rest.iter().position(|&c| c == b'.') {
                Some(dot) => digits(&rest[..dot]) && digits(&rest[dot + 1..]),
                None => false,
            },
            b'B' | b'W' | b'D' | b'L' => digits(rest),
            _ => false,
        },
        _ => false,
    }
}

fn is_identifier(name: &str) -> bool {
    let mut bytes = name.bytes();
    bytes
        .next()
        .is_some_and(|b| b.is_ascii_alphabetic() || b == b'_')
        && bytes.all(|b| b.is_ascii_alphanumeric() || b == b'_')
}

/// The caller's source, then the configuration that instantiates each case.
mod batch;
mod cc;
mod harness;

pub use batch::Batch;
use cc::*;
use harness::*;

/// Where the program `name` is installed: on `PATH`, or in an `sbin` directory, which Debian
/// keeps off an ordinary user's `PATH` although it installs Mosquitto there.
pub fn find_program(name: &str) -> Option<PathBuf> {
    let on_path = std::env::var_os("PATH")
        .map(|paths| std::env::split_paths(&paths).collect::<Vec<_>>())
        .unwrap_or_default();
    on_path
        .into_iter()
        .chain(["/usr/local/sbin", "/usr/sbin", "/sbin"].map(PathBuf::from))
        .map(|dir| dir.join(name))
        .find(|p| p.is_file())
}
