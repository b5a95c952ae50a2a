//! The C harness around MATIEC's generated code: the configuration appended to a batch, the C
//! program that feeds each scan's inputs and prints its outputs, and the text between them.

use super::*;

pub(super) fn batch_source(source: &str, globals: &str, cases: &[Case], tick: Duration) -> String {
    let mut text = String::from(source);
    if !text.ends_with('\n') {
        text.push('\n');
    }
    text.push_str(&format!(
        "\nCONFIGURATION Cetratus_Config\n{globals}  RESOURCE Cetratus_Res ON PLC\n    \
         TASK Cetratus_Tick(INTERVAL := {}, PRIORITY := 0);\n",
        time_literal(tick)
    ));
    for (i, case) in cases.iter().enumerate() {
        text.push_str(&format!(
            "    PROGRAM Cetratus_Case{i} WITH Cetratus_Tick : {};\n",
            case.program
        ));
    }
    text.push_str("  END_RESOURCE\nEND_CONFIGURATION\n");
    text
}

/// `tick` as an IEC duration literal; milliseconds are its smallest unit, with a fraction.
pub(super) fn time_literal(tick: Duration) -> String {
    let ns = tick.as_nanos();
    let (ms, frac) = (ns / 1_000_000, ns % 1_000_000);
    if frac == 0 {
        format!("T#{ms}ms")
    } else {
        let frac = format!("{frac:06}");
        format!("T#{ms}.{}ms", frac.trim_end_matches('0'))
    }
}

/// The C name of the pointer MATIEC's code reads a located variable through (`%IX0.1` is
/// `__IX0_1`), when `name` is an address rather than a variable of the program.
pub(super) fn located(name: &str) -> Option<String> {
    let rest = name.strip_prefix('%')?;
    Some(format!("__{}", rest.to_uppercase().replace('.', "_")))
}

/// `LOCATED_VARIABLES.h` with only its `__LOCATED_VAR(…)` lines: iec2c also writes the names of
/// the configuration's global variables into it, run together on one line, which no C
/// compiler reads.
pub(super) fn located_only(text: &str) -> String {
    text.lines()
        .filter(|l| l.starts_with("__LOCATED_VAR(") && l.ends_with(')'))
        .map(|l| format!("{l}\n"))
        .collect()
}

/// The C name of case `i`'s program instance: MATIEC upper-cases identifiers and prefixes the
/// resource.
pub(super) fn instance(i: usize) -> String {
    format!("CETRATUS_RES__CETRATUS_CASE{i}")
}

/// The harness: the fixed part, then per case a type check of each variable, a function that
/// writes the inputs of a scan and one that prints the outputs, then their tables.
pub(super) fn harness_c(cases: &[Case]) -> String {
    let mut c = String::from(HARNESS_PRELUDE);
    for (i, case) in cases.iter().enumerate() {
        let inst = instance(i);
        let program = case.program.to_uppercase();
        c.push_str(&format!("\n/* case {i}: PROGRAM {} */\n", case.program));
        c.push_str(&format!("extern {program} {inst};\n"));
        for (name, ty) in case.inputs.iter().chain(&case.outputs) {
            let var = match located(name) {
                Some(c_name) => format!("*{c_name}"),
                None => format!("{inst}.{}.value", name.to_uppercase()),
            };
            c.push_str(&format!(
                "_Static_assert(__builtin_types_compatible_p(__typeof__({var}), {ty}), \
                 \"case {i} (PROGRAM {}): `{name}` is not declared {ty}\");\n",
                case.program
            ));
        }
        c.push_str(&format!("static void write_inputs_{i}(void) {{\n"));
        for (name, ty) in &case.inputs {
            c.push_str(&match located(name) {
                Some(c_name) => format!("  *{c_name} = rd_{ty}();\n"),
                None => format!(
                    "  __SET_VAR({inst}., {}, , rd_{ty}());\n",
                    name.to_uppercase()
                ),
            });
        }
        c.push_str(&format!("}}\nstatic void print_outputs_{i}(void) {{\n"));
        for (name, ty) in &case.outputs {
            c.push_str(&match located(name) {
                Some(c_name) => format!("  wr_{ty}(*{c_name});\n"),
                None => format!("  wr_{ty}(__GET_VAR({inst}.{}));\n", name.to_uppercase()),
            });
        }
        c.push_str("}\n");
    }
    let table = |prefix: &str| {
        (0..cases.len())
            .map(|i| format!("{prefix}_{i}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    c.push_str(&format!(
        "\n#define INPUT_HEADER \"{INPUT_HEADER}\"\n#define CASES {}\n\
         static void (*const write_inputs[CASES])(void) = {{{}}};\n\
         static void (*const print_outputs[CASES])(void) = {{{}}};\n",
        cases.len(),
        table("write_inputs"),
        table("print_outputs")
    ));
    c.push_str(HARNESS_MAIN);
    c
}

/// The C files to compile: the harness, the configuration, and the resource with the POUs,
/// the POUs split into as many units as there are cores when `POUS.c` is only the list of
/// their files that `-O p` makes (the resource then compiled without it).
pub(super) fn input_text(cases: &[Case], tick: Duration) -> String {
    let mut text = format!("{INPUT_HEADER}\n{}\n{}\n", cases.len(), tick.as_nanos());
    for case in cases {
        text.push_str(&format!("{}\n", case.scans.len()));
    }
    let scans = cases.iter().map(|c| c.scans.len()).max().unwrap_or(0);
    for k in 0..scans {
        for values in cases.iter().filter_map(|c| c.scans.get(k)) {
            for value in values {
                text.push_str(value);
                text.push('\n');
            }
        }
    }
    text
}

/// The outputs of each case in each of its scans, from the harness's output: per scan a line
/// `scan k`, then per case that has the scan one line per output value; then `end`.
pub(super) fn parse_output(output: &str, cases: &[Case]) -> Result<Outputs, MatiecError> {
    let mut lines = output.lines();
    let mut results: Outputs = cases
        .iter()
        .map(|c| Vec::with_capacity(c.scans.len()))
        .collect();
    let scans = cases.iter().map(|c| c.scans.len()).max().unwrap_or(0);
    let malformed = |scan: Option<usize>, what: String| MatiecError::Run {
        scan,
        message: format!("its output is malformed: {what}"),
    };
    for k in 0..scans {
        let marker = format!("scan {k}");
        match lines.next() {
            Some(line) if line == marker => {}
            other => {
                return Err(malformed(
                    Some(k),
                    format!("expected `{marker}`, found {other:?}"),
                ))
            }
        }
        for (i, case) in cases.iter().enumerate().filter(|(_, c)| k < c.scans.len()) {
            let mut values = Vec::with_capacity(case.outputs.len());
            for (name, _) in &case.outputs {
                let value = lines.next().ok_or_else(|| {
                    malformed(
                        Some(k),
                        format!("it ends before output `{name}` of case {i}"),
                    )
                })?;
                values.push(value.to_owned());
            }
            results[i].push(values);
        }
    }
    match lines.next() {
        Some("end") => Ok(results),
        other => Err(malformed(None, format!("expected `end`, found {other:?}"))),
    }
}

/// What the timed loop printed: `ns <total>`, then per case one line per output value, then
/// `end`.
pub(super) fn parse_timed(
    output: &str,
    cases: &[Case],
) -> Result<(Duration, Vec<Vec<String>>), MatiecError> {
    let malformed = |what: String| MatiecError::Run {
        scan: None,
        message: format!("its timed output is malformed: {what}"),
    };
    let mut lines = output.lines();
    let first = lines.next().unwrap_or_default();
    let ns: u64 = first
        .strip_prefix("ns ")
        .and_then(|n| n.parse().ok())
        .ok_or_else(|| malformed(format!("expected `ns <total>`, found {first:?}")))?;
    let mut last = Vec::with_capacity(cases.len());
    for (i, case) in cases.iter().enumerate() {
        let values = (0..case.outputs.len())
            .map(|_| lines.next().map(str::to_owned))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| malformed(format!("it ends before the outputs of case {i}")))?;
        last.push(values);
    }
    match lines.next() {
        Some("end") => Ok((Duration::from_nanos(ns), last)),
        other => Err(malformed(format!("expected `end`, found {other:?}"))),
    }
}

/// The scan the harness last started, from the markers it flushes before each.
pub(super) fn last_scan(output: &str) -> Option<usize> {
    output
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("scan ")?.parse().ok())
}

/// Waits for `child` at most `timeout`; kills it and returns `None` when it is still running.
/// The fixed first part of the harness: MATIEC's runtime symbols, and one reader and one
/// printer of canonical text per type.
pub(super) const HARNESS_PRELUDE: &str = r#"/* The harness of cetratus-matiec: reads each scan's inputs from standard input,
 * runs one cycle, prints the outputs on standard output, all in canonical text. */
#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "iec_std_lib.h"
#include "POUS.h"

TIME __CURRENT_TIME;
BOOL __DEBUG;

/* Located variables, should a program declare some: plain variables, as in MATIEC's plc.c. */
#define __LOCATED_VAR(type, name, ...) type __##name;
#include "LOCATED_VARIABLES.h"
#undef __LOCATED_VAR
#define __LOCATED_VAR(type, name, ...) type *name = &__##name;
#include "LOCATED_VARIABLES.h"
#undef __LOCATED_VAR

void config_init__(void);
void config_run__(unsigned long tick);

static char line[1024];
static long line_no;

static void bad_input(const char *expected) {
  fprintf(stderr, "input line %ld: expected %s, found \"%s\"\n", line_no, expected, line);
  exit(2);
}

static const char *next_line(void) {
  size_t n;
  line_no++;
  if (fgets(line, sizeof line, stdin) == NULL) {
    line[0] = 0;
    bad_input("one more line");
  }
  n = strlen(line);
  if (n > 0 && line[n - 1] == '\n') line[--n] = 0;
  return line;
}

static long long rd_signed(long long lo, long long hi) {
  const char *s = next_line();
  char *end;
  long long v;
  errno = 0;
  v = strtoll(s, &end, 10);
  if (errno != 0 || end == s || *end != 0 || v < lo || v > hi) bad_input("a signed integer in range");
  return v;
}

static unsigned long long rd_unsigned(unsigned long long hi) {
  const char *s = next_line();
  char *end;
  unsigned long long v;
  errno = 0;
  v = strtoull(s, &end, 10);
  if (errno != 0 || s[0] < '0' || s[0] > '9' || *end != 0 || v > hi) bad_input("an unsigned integer in range");
  return v;
}

static unsigned long long rd_bits(char tag, size_t digits) {
  const char *s = next_line();
  char *end;
  unsigned long long v;
  if (s[0] != tag || strlen(s) != digits + 1) bad_input("a tag and hex digits");
  errno = 0;
  v = strtoull(s + 1, &end, 16);
  if (errno != 0 || *end != 0) bad_input("a tag and hex digits");
  return v;
}

static int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

static BOOL rd_BOOL(void) {
  const char *s = next_line();
  if (strcmp(s, "TRUE") == 0) return 1;
  if (strcmp(s, "FALSE") != 0) bad_input("TRUE or FALSE");
  return 0;
}
static SINT rd_SINT(void) { return (SINT)rd_signed(INT8_MIN, INT8_MAX); }
static INT rd_INT(void) { return (INT)rd_signed(INT16_MIN, INT16_MAX); }
static DINT rd_DINT(void) { return (DINT)rd_signed(INT32_MIN, INT32_MAX); }
static LINT rd_LINT(void) { return (LINT)rd_signed(INT64_MIN, INT64_MAX); }
static USINT rd_USINT(void) { return (USINT)rd_unsigned(UINT8_MAX); }
static UINT rd_UINT(void) { return (UINT)rd_unsigned(UINT16_MAX); }
static UDINT rd_UDINT(void) { return (UDINT)rd_unsigned(UINT32_MAX); }
static ULINT rd_ULINT(void) { return (ULINT)rd_unsigned(UINT64_MAX); }
static BYTE rd_BYTE(void) { return (BYTE)rd_unsigned(UINT8_MAX); }
static WORD rd_WORD(void) { return (WORD)rd_unsigned(UINT16_MAX); }
static DWORD rd_DWORD(void) { return (DWORD)rd_unsigned(UINT32_MAX); }
static LWORD rd_LWORD(void) { return (LWORD)rd_unsigned(UINT64_MAX); }

static REAL rd_REAL(void) {
  uint32_t b = (uint32_t)rd_bits('r', 8);
  REAL v;
  memcpy(&v, &b, sizeof v);
  return v;
}

static LREAL rd_LREAL(void) {
  uint64_t b = (uint64_t)rd_bits('l', 16);
  LREAL v;
  memcpy(&v, &b, sizeof v);
  return v;
}

/* Normalized as MATIEC normalizes: tv_sec and tv_nsec of one sign. */
static TIME rd_TIME(void) {
  const char *s = next_line();
  char *end;
  long long ns;
  TIME t;
  if (s[0] != 't') bad_input("t and nanoseconds");
  errno = 0;
  ns = strtoll(s + 1, &end, 10);
  if (errno != 0 || end == s + 1 || *end != 0) bad_input("t and nanoseconds");
  t.tv_sec = (long)(ns / 1000000000LL);
  t.tv_nsec = (long)(ns % 1000000000LL);
  return t;
}

static STRING rd_STRING(void) {
  const char *s = next_line();
  size_t n = strlen(s), i;
  STRING v;
  /* Zeroed beyond the length, as MATIEC's own strings are: STRING_TO_REAL reads past it. */
  memset(&v, 0, sizeof v);
  if (n < 2 || s[0] != '\'' || s[n - 1] != '\'') bad_input("a quoted string");
  for (i = 1; i < n - 1; i++) {
    int c = (unsigned char)s[i];
    if (c == '$') {
      if (i + 1 < n - 1 && (s[i + 1] == '$' || s[i + 1] == '\'')) {
        c = s[++i];
      } else {
        int h = i + 2 < n - 1 ? hex_digit(s[i + 1]) : -1;
        int l = h < 0 ? -1 : hex_digit(s[i + 2]);
        if (l < 0) bad_input("$$, $' or $ and two hex digits");
        c = h * 16 + l;
        i += 2;
      }
    } else if (c == '\'') {
      bad_input("$' for a quote");
    }
    if (v.len >= STR_MAX_LEN) bad_input("at most STR_MAX_LEN bytes");
    v.body[v.len++] = (uint8_t)c;
  }
  return v;
}

static void wr_signed(long long v) { printf("%lld\n", v); }
static void wr_unsigned(unsigned long long v) { printf("%llu\n", v); }

static void wr_BOOL(BOOL v) {
  if (v == 0) puts("FALSE");
  else if (v == 1) puts("TRUE");
  else printf("BOOL#%u\n", (unsigned)v);
}
static void wr_SINT(SINT v) { wr_signed(v); }
static void wr_INT(INT v) { wr_signed(v); }
static void wr_DINT(DINT v) { wr_signed(v); }
static void wr_LINT(LINT v) { wr_signed(v); }
static void wr_USINT(USINT v) { wr_unsigned(v); }
static void wr_UINT(UINT v) { wr_unsigned(v); }
static void wr_UDINT(UDINT v) { wr_unsigned(v); }
static void wr_ULINT(ULINT v) { wr_unsigned(v); }
static void wr_BYTE(BYTE v) { wr_unsigned(v); }
static void wr_WORD(WORD v) { wr_unsigned(v); }
static void wr_DWORD(DWORD v) { wr_unsigned(v); }
static void wr_LWORD(LWORD v) { wr_unsigned(v); }

static void wr_REAL(REAL v) {
  uint32_t b;
  memcpy(&b, &v, sizeof b);
  printf("r%08lx\n", (unsigned long)b);
}

static void wr_LREAL(LREAL v) {
  uint64_t b;
  memcpy(&b, &v, sizeof b);
  printf("l%016llx\n", (unsigned long long)b);
}

static void wr_TIME(TIME v) { printf("t%lld\n", (long long)v.tv_sec * 1000000000LL + (long long)v.tv_nsec); }

static void wr_STRING(STRING v) {
  size_t i, n = v.len > STR_MAX_LEN ? STR_MAX_LEN : v.len;
  putchar('\'');
  for (i = 0; i < n; i++) {
    unsigned c = v.body[i];
    if (c == '$') fputs("$$", stdout);
    else if (c == '\'') fputs("$'", stdout);
    else if (c < 0x20 || c >= 0x7f) printf("$%02X", c);
    else putchar((int)c);
  }
  puts("'");
}
"#;

/// The fixed last part of the harness: the scan loop (the module doc's steps 1 to 4), and the
/// timed loop (`--time N`: the inputs of the first scan, then N scans with nothing else in
/// the loop, timed with the monotonic clock; then the outputs of the last).
pub(super) const HARNESS_MAIN: &str = r#"
static int time_scans(long n, long long tick_ns) {
  struct timespec a, b;
  long k, i;
  for (i = 0; i < CASES; i++) write_inputs[i]();
  clock_gettime(CLOCK_MONOTONIC, &a);
  for (k = 0; k < n; k++) {
    long long now = (long long)k * tick_ns;
    __CURRENT_TIME.tv_sec = (long)(now / 1000000000LL);
    __CURRENT_TIME.tv_nsec = (long)(now % 1000000000LL);
    config_run__((unsigned long)k);
  }
  clock_gettime(CLOCK_MONOTONIC, &b);
  printf("ns %lld\n", (long long)(b.tv_sec - a.tv_sec) * 1000000000LL + (b.tv_nsec - a.tv_nsec));
  for (i = 0; i < CASES; i++) print_outputs[i]();
  puts("end");
  return fflush(stdout) == 0 ? 0 : 1;
}

int main(int argc, char **argv) {
  static long scans[CASES];
  long cases, k, i, max_scans = 0;
  long long tick_ns;
  if (strcmp(next_line(), INPUT_HEADER) != 0) bad_input("the header " INPUT_HEADER);
  cases = (long)rd_signed(0, LONG_MAX);
  if (cases != CASES) bad_input("the number of cases compiled in");
  tick_ns = rd_signed(1, LLONG_MAX);
  for (i = 0; i < CASES; i++) {
    scans[i] = (long)rd_signed(0, LONG_MAX);
    if (scans[i] > max_scans) max_scans = scans[i];
  }
  config_init__();
  if (argc == 3 && strcmp(argv[1], "--time") == 0) return time_scans(atol(argv[2]), tick_ns);
  for (k = 0; k < max_scans; k++) {
    long long now = (long long)k * tick_ns;
    for (i = 0; i < CASES; i++)
      if (k < scans[i]) write_inputs[i]();
    __CURRENT_TIME.tv_sec = (long)(now / 1000000000LL);
    __CURRENT_TIME.tv_nsec = (long)(now % 1000000000LL);
    /* Flushed, so that a crash in this scan can be told. */
    printf("scan %ld\n", k);
    fflush(stdout);
    config_run__((unsigned long)k);
    for (i = 0; i < CASES; i++)
      if (k < scans[i]) print_outputs[i]();
  }
  puts("end");
  return fflush(stdout) == 0 ? 0 : 1;
}
"#;
