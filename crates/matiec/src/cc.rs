//! Compiling the generated C (in parallel, one translation unit per core) and running it.

use super::*;

pub(super) fn translation_units(dir: &Path) -> Result<Vec<String>, MatiecError> {
    let read = |name: &str| {
        fs::read_to_string(dir.join(name)).map_err(io_error(format!("cannot read iec2c's {name}")))
    };
    let mut units = vec![
        "cetratus-harness.c".to_owned(),
        "Cetratus_Config.c".to_owned(),
    ];
    let resource = read("Cetratus_Res.c")?;
    let pous = read("POUS.c")?;
    let files: Option<Vec<&str>> = pous
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            l.strip_prefix("#include \"")
                .and_then(|l| l.strip_suffix(".c\""))
        })
        .collect();
    let include = "#include \"POUS.c\"";
    let (Some(files), 1) = (files, resource.matches(include).count()) else {
        units.push("Cetratus_Res.c".to_owned());
        return Ok(units);
    };
    for name in &files {
        guard_array_types(&dir.join(format!("{name}.h")))?;
    }
    write_file(
        &dir.join("cetratus-resource.c"),
        &resource.replace(include, ""),
    )?;
    units.push("cetratus-resource.c".to_owned());
    let parallel = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunks = parallel.min(files.len()).max(1);
    for (j, chunk) in balance(dir, &files, chunks).into_iter().enumerate() {
        // The configuration's header declares the accessors of its globals, which a POU's
        // VAR_EXTERNAL calls.
        let mut text = String::from(
            "#include \"iec_std_lib.h\"\n#include \"accessor.h\"\n#include \"POUS.h\"\n\
             #include \"Cetratus_Config.h\"\n",
        );
        for name in chunk {
            text.push_str(&format!("#include \"{name}.c\"\n"));
        }
        let unit = format!("cetratus-pous-{j}.c");
        write_file(&dir.join(&unit), &text)?;
        units.push(unit);
    }
    Ok(units)
}

/// Puts each anonymous array type of a POU's header under an include guard of its own: iec2c's
/// one-file-per-POU mode (`-f`) declares `ARRAY [1..3] OF DINT` as `__ARRAY_OF_DINT_3` in every
/// header that uses it, and the harness includes them all in one translation unit.
pub(super) fn guard_array_types(header: &Path) -> Result<(), MatiecError> {
    let Ok(text) = fs::read_to_string(header) else {
        return Ok(());
    };
    let mut out = String::with_capacity(text.len());
    for line in text.lines() {
        let name = line
            .strip_prefix("__DECLARE_ARRAY_TYPE(")
            .and_then(|rest| rest.split(',').next());
        match name {
            Some(name) => {
                let guard = format!("CETRATUS_DECLARED{name}");
                out.push_str(&format!(
                    "#ifndef {guard}\n#define {guard}\n{line}\n#endif\n"
                ));
            }
            None => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    write_file(header, &out)
}

/// `files` in `n` groups of about equal size, the largest placed first.
pub(super) fn balance<'a>(dir: &Path, files: &[&'a str], n: usize) -> Vec<Vec<&'a str>> {
    let size = |f: &str| fs::metadata(dir.join(format!("{f}.c"))).map_or(0, |m| m.len());
    let mut sized: Vec<(u64, &str)> = files.iter().map(|f| (size(f), *f)).collect();
    sized.sort_by(|a, b| b.cmp(a));
    let mut groups: Vec<(u64, Vec<&str>)> = vec![(0, Vec::new()); n];
    for (bytes, file) in sized {
        let lightest = groups
            .iter_mut()
            .min_by_key(|(total, _)| *total)
            .expect("at least one group");
        lightest.0 += bytes;
        lightest.1.push(file);
    }
    groups.into_iter().map(|(_, g)| g).collect()
}

/// The error of a failed `cc`: its first error line, and the C line it points at.
pub(super) fn cc_error(dir: &Path, output: &str) -> MatiecError {
    let first_error = output
        .lines()
        .find(|l| l.contains("error") || l.contains("undefined reference"))
        .unwrap_or_else(|| output.lines().next().unwrap_or("cc failed without output"))
        .to_owned();
    // `FILE:LINE:COLUMN: error: …`
    let mut parts = first_error.splitn(3, ':');
    let c_line = match (
        parts.next(),
        parts.next().and_then(|l| l.parse::<usize>().ok()),
    ) {
        (Some(file), Some(line)) => fs::read_to_string(dir.join(file))
            .ok()
            .and_then(|text| text.lines().nth(line.checked_sub(1)?).map(str::to_owned)),
        _ => None,
    };
    MatiecError::Cc {
        first_error,
        c_line,
        output: output.to_owned(),
    }
}

/// The harness's input: the header, the number of cases, the tick in nanoseconds, each case's
/// number of scans, then per scan, per case that has it, one line per input value.
pub(super) fn wait_with_timeout(
    child: &mut Child,
    timeout: Duration,
) -> Result<Option<ExitStatus>, MatiecError> {
    let deadline = Instant::now() + timeout;
    let mut pause = Duration::from_millis(1);
    loop {
        if let Some(status) = child
            .try_wait()
            .map_err(io_error("cannot wait for the batch"))?
        {
            return Ok(Some(status));
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Ok(None);
        }
        std::thread::sleep(pause);
        pause = (pause * 2).min(Duration::from_millis(50));
    }
}

/// How a process ended, naming the signal, and what SIGFPE means in generated code.
pub(super) fn describe(status: ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match status.signal() {
        Some(8) => {
            "killed by SIGFPE: an integer division by zero, or MIN / -1 or MIN MOD -1 in DINT \
             or LINT"
                .into()
        }
        Some(11) => "killed by SIGSEGV (an array index out of its bounds?)".into(),
        Some(signal) => format!("killed by signal {signal}"),
        None => format!("it exited with {status}"),
    }
}

pub(super) fn stderr_note(stderr: &str) -> String {
    if stderr.trim().is_empty() {
        String::new()
    } else {
        format!(
            "; its standard error:\n{}",
            first_lines(stderr.trim_end(), 20)
        )
    }
}

pub(super) fn write_file(path: &Path, text: &str) -> Result<(), MatiecError> {
    fs::write(path, text).map_err(io_error(format!("cannot write {}", path.display())))
}

pub(super) fn file(path: &Path) -> Result<fs::File, MatiecError> {
    fs::File::create(path).map_err(io_error(format!("cannot create {}", path.display())))
}
