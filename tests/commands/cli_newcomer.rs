//! What a newcomer meets first (issue 48): refusals that say what the file is and what to
//! do, a warning for a cycle with fewer steps than the others, standard output closed by
//! its reader ending quietly, and the sim-lab banner's lines.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

fn polycal_stdin(args: &[&str], input: &[u8]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    child.stdin.take().unwrap().write_all(input).unwrap();
    child.wait_with_output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-newcomer-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn path_str(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Spawns polycal with standard output a pipe, reads one line of it, closes the pipe and
/// waits: (the line, standard error, the exit status).
fn read_one_line_then_close(args: &[&str]) -> (String, String, Option<i32>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let mut first = String::new();
    {
        let mut reader = BufReader::new(child.stdout.take().unwrap());
        reader.read_line(&mut first).unwrap();
        // the reader dropped here: the pipe's read end is closed
    }
    let out = child.wait_with_output().unwrap();
    (first, stderr(&out), out.status.code())
}

/// `simulate --faces 720` writes 8 640 readings (about 300 kB, far more than a pipe's
/// 64 kB buffer), so its writes after the reader is gone really fail with a broken pipe.
#[test]
fn standard_output_closed_by_its_reader_ends_quietly() {
    let (first, err, status) = read_one_line_then_close(&["simulate", "--faces", "720"]);
    assert!(first.starts_with("# polycal"), "{first}");
    assert_eq!(err, "", "nothing on standard error");
    assert_eq!(status, Some(141));

    // The same for a solve whose CSV is far larger than the pipe's buffer.
    let dir = temp_dir("pipe");
    let big = dir.join("big.csv");
    let made = polycal(&["simulate", "--faces", "720", "--out", path_str(&big)]);
    assert!(made.status.success(), "{}", stderr(&made));
    let (first, err, status) =
        read_one_line_then_close(&["solve", path_str(&big), "--format", "csv"]);
    assert_eq!(first, "quantity,index,value,U,u,k,angle_deg\n");
    assert_eq!(err, "", "nothing on standard error");
    assert_eq!(status, Some(141));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Standard output that is read to its end is no different: status 0, the whole table.
#[test]
fn standard_output_read_to_the_end_is_whole() {
    let out = polycal(&["simulate", "--faces", "720"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    // a comment line, the header, 720 steps × 2 autocollimators × 6 cycles
    assert_eq!(text.lines().count(), 2 + 720 * 2 * 6);
}

/// The sim-lab banner is lines, not one line with a literal `\n` in it.
#[test]
fn the_sim_lab_banner_is_lines() {
    // Standard input closed at once: the lab prints its paths and banner, then ends.
    let out = polycal_stdin(&["sim-lab", "--faces", "8"], b"");
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(!err.contains("\\n"), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines.first(),
        Some(&"polycal sim-lab: serving; try"),
        "{err}"
    );
    assert!(
        lines
            .get(1)
            .is_some_and(|l| l.starts_with("  polycal run --ac1 ")),
        "{err}"
    );
    assert!(
        lines.iter().any(|l| l.starts_with("stop with Ctrl-C")),
        "{err}"
    );
}

/// A negative count is a value out of range, not an unknown option `-5`.
#[test]
fn a_negative_count_is_out_of_range() {
    for (args, option) in [
        (&["simulate", "--faces", "-5"][..], "--faces -5"),
        (&["simulate", "--faces=-5"][..], "--faces -5"),
        (&["simulate", "--cycles", "-1"][..], "--cycles -1"),
        (
            &[
                "solve",
                "examples/data/polygon24-2ac-6cycles.csv",
                "--faces",
                "-24",
            ][..],
            "--faces -24",
        ),
    ] {
        let out = polycal(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = stderr(&out);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.starts_with(&format!("error: {option}: out of range")),
            "{err}"
        );
        assert!(!err.contains("unexpected argument"), "{err}");
    }
    // A parser with a message of its own keeps it.
    let out = polycal(&["solve", "-", "--sigma", "-1"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("must be a positive, finite number"),
        "{}",
        stderr(&out)
    );
}

const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const RESULT: &str = "examples/data/polygon24-shift-angle.result.csv";
const SELFCAL: &str = "examples/data/selfa-168.csv";

/// One refusal: status 2, one `error:` line beginning with `at` (file:line:column),
/// holding every one of `says`.
fn assert_refused(out: &Output, at: &str, says: &[&str]) -> String {
    assert_eq!(out.status.code(), Some(2), "{}", stderr(out));
    assert!(out.stdout.is_empty());
    let err = stderr(out);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.starts_with(&format!("error: {at}: ")), "{err}");
    for word in says {
        assert!(err.contains(word), "{word:?} in {err}");
    }
    err
}

/// The example measurement file rewritten as a spreadsheet in a comma-decimal locale
/// writes it: `;` or a tab between fields, and `,` for the decimal point when asked.
fn rewritten(dir: &Path, name: &str, separator: &str, decimal_comma: bool) -> PathBuf {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE)).unwrap();
    let mut out = String::new();
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let mut line = line.replace(',', separator);
        if decimal_comma {
            line = line.replace('.', ",");
        }
        out.push_str(&line);
        out.push('\n');
    }
    let path = dir.join(name);
    std::fs::write(&path, out).unwrap();
    path
}

/// A table separated by semicolons or tabs, or with decimal commas, is named so, with the
/// fix, at the header (line 1 once the comments are left out, column 1).
#[test]
fn separators_and_decimal_commas_are_named_with_the_fix() {
    let dir = temp_dir("separators");
    let semi = rewritten(&dir, "semi.csv", ";", false);
    let err = assert_refused(
        &polycal(&["solve", path_str(&semi)]),
        &format!("{}:1:1", semi.display()),
        &["separated by semicolons", "`,` between fields"],
    );
    assert!(!err.contains("decimal commas"), "{err}");
    assert!(!err.contains("missing required"), "{err}");

    let tab = rewritten(&dir, "tab.csv", "\t", false);
    assert_refused(
        &polycal(&["solve", path_str(&tab)]),
        &format!("{}:1:1", tab.display()),
        &["separated by tabs", "`,` between fields"],
    );

    let european = rewritten(&dir, "european.csv", ";", true);
    assert_refused(
        &polycal(&["diagnose", path_str(&european)]),
        &format!("{}:1:1", european.display()),
        &[
            "separated by semicolons",
            "decimal commas",
            "`.` in numbers",
        ],
    );

    // Decimal commas in a comma-separated file: the first row has more fields than the
    // header; line 2, at the first extra field. The example's first row is
    // `1,0,1,1,1.6009...,cw,1,0,0` (9 fields); with a decimal comma the fraction is field 6.
    let commas = rewritten(&dir, "commas.csv", ",", true);
    let first_row = std::fs::read_to_string(&commas).unwrap();
    let first_row = first_row.lines().nth(1).unwrap();
    let fields: Vec<&str> = first_row.split(',').collect();
    // the column of the 10th field: the characters of the nine before it and their commas
    let column = fields[..9]
        .iter()
        .map(|f| f.chars().count() + 1)
        .sum::<usize>()
        + 1;
    assert_refused(
        &polycal(&["solve", path_str(&commas)]),
        &format!("{}:2:{column}", commas.display()),
        &[
            "row has 10 fields but the header has 9",
            "decimal commas",
            "points",
        ],
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A file of another kind says what it is and what to do, at the line that tells.
#[test]
fn a_file_of_another_kind_says_what_it_is_and_what_to_do() {
    // The budget's first line that is not a comment: its `p = 0.95`.
    let budget_text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(BUDGET)).unwrap();
    let p_line = budget_text
        .lines()
        .position(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .unwrap()
        + 1;
    assert!(
        budget_text
            .lines()
            .nth(p_line - 1)
            .unwrap()
            .starts_with("p = ")
    );
    let err = assert_refused(
        &polycal(&["solve", BUDGET]),
        &format!("{BUDGET}:{p_line}:1"),
        &[
            "this is a budget (TOML",
            "not a measurement file",
            "with --budget",
        ],
    );
    assert!(!err.contains("missing required"), "{err}");

    // A measurement file given to `budget`, and as `--budget`: not TOML's "key with no value".
    for (args, what_to_do) in [
        (&["budget", EXAMPLE][..], "polycal solve FILE --budget"),
        (
            &["solve", EXAMPLE, "--budget", EXAMPLE][..],
            "--budget takes a budget",
        ),
    ] {
        let err = assert_refused(
            &polycal(args),
            &format!("{EXAMPLE}:2:1"),
            &["this is a measurement file", "not a budget", what_to_do],
        );
        assert!(!err.contains("key with no value"), "{err}");
    }

    // A measurement file where a result file is expected: solve it first.
    for args in [
        &["compare", EXAMPLE, RESULT][..],
        &["kc", &format!("A={EXAMPLE}"), &format!("B={RESULT}")][..],
    ] {
        assert_refused(
            &polycal(args),
            &format!("{EXAMPLE}:2:1"),
            &[
                "this is a measurement file",
                "not a result file",
                "polycal solve FILE --format csv",
            ],
        );
    }

    // A result file and a self-calibration file given to solve, a measurement file to selfcal.
    let result_header = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(RESULT))
        .unwrap()
        .lines()
        .position(|l| l.starts_with("quantity"))
        .unwrap()
        + 1;
    assert_refused(
        &polycal(&["solve", RESULT]),
        &format!("{RESULT}:{result_header}:1"),
        &[
            "this is a result file",
            "not a measurement file",
            "polycal compare",
        ],
    );
    assert_refused(
        &polycal(&["solve", SELFCAL]),
        &format!("{SELFCAL}:2:1"),
        &[
            "this is a self-calibration file",
            "not a measurement file",
            "polycal selfcal FILE",
        ],
    );
    assert_refused(
        &polycal(&["selfcal", EXAMPLE]),
        &format!("{EXAMPLE}:2:1"),
        &[
            "this is a measurement file",
            "not a self-calibration file",
            "polycal solve FILE",
        ],
    );
}

const EXAMPLE_TRUTH: &str = "examples/data/polygon24-2ac-6cycles.truth.json";

fn numbers(value: &serde_json::Value) -> Vec<f64> {
    value
        .as_array()
        .expect("an array")
        .iter()
        .map(|v| v.as_f64().expect("a number"))
        .collect()
}

/// The example run (24 faces, 6 cycles of 25 stops, the closing one included, 2
/// autocollimators) with its last cycle cut after step 9, as a run interrupted there
/// would leave it: one `warning:` naming cycle 6 and its missing steps 10–24, the same
/// in the JSON, and the result still agreeing with the truth the data were simulated
/// from within the uncertainties it states.
#[test]
fn an_incomplete_last_cycle_is_named_and_the_result_still_holds() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join(EXAMPLE)).unwrap();
    let mut kept = String::new();
    let mut dropped = 0;
    for line in text.lines() {
        let fields: Vec<&str> = line.split(',').collect();
        if fields[0] == "6" && fields[1].parse::<usize>().is_ok_and(|step| step >= 10) {
            dropped += 1;
            continue;
        }
        kept.push_str(line);
        kept.push('\n');
    }
    assert_eq!(
        dropped,
        15 * 2,
        "steps 10 … 24 of cycle 6, both autocollimators"
    );
    let dir = temp_dir("incomplete");
    let cut = dir.join("cut.csv");
    std::fs::write(&cut, kept).unwrap();

    // The whole file has no incomplete cycle.
    let whole = polycal(&["solve", EXAMPLE]);
    assert_eq!(whole.status.code(), Some(0));
    assert_eq!(stderr(&whole), "");

    let out = polycal(&["solve", path_str(&cut), "--format", "json"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(
        stderr(&out),
        format!(
            "warning: {}: cycle 6 is incomplete: it read 10 of the 25 steps of a whole cycle \
             (steps 10–24 missing); it is evaluated with the readings it has\n",
            cut.display()
        )
    );
    // -q silences the warning, not the JSON's record of it
    let quiet = polycal(&["-q", "solve", path_str(&cut), "--format", "json"]);
    assert_eq!(stderr(&quiet), "");
    assert_eq!(quiet.stdout, out.stdout);

    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        json["incomplete_cycles"],
        serde_json::json!([{
            "setup": 1, "cycle": 6, "steps": 10, "expected_steps": 25,
            "missing_steps": (10..25).collect::<Vec<usize>>(),
        }])
    );
    assert!(
        json["warnings"][0]
            .as_str()
            .unwrap()
            .starts_with("cycle 6 is incomplete")
    );
    // 300 readings less 30; 2N − 2 + K = 48 parameters (K = 2 setup errors)
    assert_eq!(json["readings"], 270);
    assert_eq!(json["dof"], 270 - 48);

    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join(EXAMPLE_TRUTH)).unwrap()).unwrap();
    for (estimate, u, truth) in [
        (
            "pitch_deviation",
            "pitch_deviation_u",
            &truth["pitch_deviation"],
        ),
        ("encoder_error", "encoder_error_u", &truth["encoder_error"]),
    ] {
        let estimate = numbers(&json[estimate]);
        let u = numbers(&json[u]);
        let truth = numbers(truth);
        assert_eq!(estimate.len(), 24);
        for k in 0..24 {
            let z = (estimate[k] - truth[k]) / u[k];
            assert!(
                z.abs() < 4.5,
                "index {k}: {} vs truth {} (u {})",
                estimate[k],
                truth[k],
                u[k]
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `diagnose` names an incomplete cycle as `solve` does: the example run without its
/// last four rows (steps 23 and 24 of cycle 6, both autocollimators), on standard input.
#[test]
fn diagnose_names_an_incomplete_cycle_too() {
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE)).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert!(
        lines[lines.len() - 4..]
            .iter()
            .all(|l| l.starts_with("6,23,") || l.starts_with("6,24,"))
    );
    let cut = lines[..lines.len() - 4].join("\n") + "\n";
    let out = polycal_stdin(&["diagnose", "-", "--format", "json"], cut.as_bytes());
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(
        stderr(&out),
        "warning: <stdin>: cycle 6 is incomplete: it read 23 of the 25 steps of a whole \
         cycle (steps 23–24 missing); it is evaluated with the readings it has\n"
    );
}
