//! A compiled batch: its executable, run on any input sequence of its cases, or timed.

use super::*;

/// A batch that `iec2c` and `cc` compiled: one executable for its cases, which runs any number
/// of input sequences, each in a process of its own (so each starts from the initial values).
/// The temporary directory goes when the batch is dropped.
#[derive(Debug)]
pub struct Batch {
    pub(super) dir: tempfile::TempDir,
    /// The cases compiled, without scans.
    pub(super) cases: Vec<Case>,
    pub(super) tick: Duration,
    pub(super) run_timeout: Duration,
}

impl Batch {
    /// Runs `cases`, which must be the cases the batch was compiled with (the same programs,
    /// inputs and outputs, in the same order) with any scans; returns per case, per scan, the
    /// output values in canonical text.
    pub fn run(&self, cases: &[Case]) -> Result<Outputs, MatiecError> {
        let output = self.start(cases, &[])?;
        parse_output(&output, cases)
    }

    /// Runs `scans` scans of every case, each case's inputs held at its first scan's values,
    /// with nothing else in the loop (no input, no output), and returns how long they took on
    /// the monotonic clock, and per case the output values after the last scan: what the
    /// compiled C costs a scan, measured as `cetratus bench st` measures the interpreter.
    pub fn time(
        &self,
        cases: &[Case],
        scans: u64,
    ) -> Result<(Duration, Vec<Vec<String>>), MatiecError> {
        if let Some((i, _)) = cases.iter().enumerate().find(|(_, c)| c.scans.is_empty()) {
            return Err(MatiecError::Invalid {
                message: format!("case {i} has no scan of inputs to hold"),
            });
        }
        let output = self.start(cases, &["--time".to_string(), scans.to_string()])?;
        parse_timed(&output, cases)
    }

    /// Checks `cases` against the compiled ones, writes their inputs and runs the executable
    /// with `args`; returns its standard output.
    fn start(&self, cases: &[Case], args: &[String]) -> Result<String, MatiecError> {
        check_batch(cases, self.tick)?;
        if cases.len() != self.cases.len() {
            return Err(MatiecError::Invalid {
                message: format!(
                    "{} cases given to a batch compiled for {}",
                    cases.len(),
                    self.cases.len()
                ),
            });
        }
        for (i, (given, compiled)) in cases.iter().zip(&self.cases).enumerate() {
            if (&given.program, &given.inputs, &given.outputs)
                != (&compiled.program, &compiled.inputs, &compiled.outputs)
            {
                return Err(MatiecError::Invalid {
                    message: format!(
                        "case {i} ({}) is not the case {i} the batch was compiled with ({})",
                        given.program, compiled.program
                    ),
                });
            }
        }
        // A directory per run, so that runs of one batch on several threads do not meet.
        let run = tempfile::Builder::new()
            .prefix("run-")
            .tempdir_in(self.dir.path())
            .map_err(io_error("cannot create a directory for the run"))?;
        write_file(
            &run.path().join("cetratus-input.txt"),
            &input_text(cases, self.tick),
        )?;
        self.execute(run.path(), args)
    }

    /// Runs the executable on the input file in `dir`; returns its standard output.
    fn execute(&self, dir: &Path, args: &[String]) -> Result<String, MatiecError> {
        let (out_path, err_path) = (
            dir.join("cetratus-output.txt"),
            dir.join("cetratus-stderr.txt"),
        );
        let input = fs::File::open(dir.join("cetratus-input.txt"))
            .map_err(io_error("cannot read input"))?;
        let mut child = Command::new(self.dir.path().join("cetratus-harness"))
            .args(args)
            .current_dir(dir)
            .stdin(input)
            .stdout(file(&out_path)?)
            .stderr(file(&err_path)?)
            .spawn()
            .map_err(io_error("cannot start the compiled batch"))?;
        let status = wait_with_timeout(&mut child, self.run_timeout)?;
        let output = fs::read_to_string(&out_path).map_err(io_error("cannot read the output"))?;
        let stderr = fs::read_to_string(&err_path).unwrap_or_default();
        let scan = last_scan(&output);
        match status {
            None => Err(MatiecError::Run {
                scan,
                message: format!(
                    "still running after {:?}, and killed (an endless loop?){}",
                    self.run_timeout,
                    stderr_note(&stderr)
                ),
            }),
            Some(status) if !status.success() => Err(MatiecError::Run {
                scan,
                message: format!("{}{}", describe(status), stderr_note(&stderr)),
            }),
            Some(_) => Ok(output),
        }
    }
}
