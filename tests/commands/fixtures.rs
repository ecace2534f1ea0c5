//! The fixture runs of `tests/fixtures/commands.txt`: every command of the binary on a set
//! of inputs, compared byte for byte with the outputs recorded before the architecture
//! change of issue 8 (standard output, standard error, exit status and the files written),
//! so that a reshaping of the code cannot change what a lab sees.
//!
//! The one difference allowed is the one issue 8 asks for: every JSON object gained the
//! software version (`"version"`), which is removed before comparing.
//!
//! `POLYCAL_BLESS=1 cargo test --test commands fixtures::` records the outputs anew; do
//! that only for a change of behaviour that is wanted, and say so in the commit.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_polycal");

struct Case {
    name: String,
    args: Vec<String>,
    stdin: Option<String>,
    files: Vec<String>,
}

fn cases(work: &str) -> Vec<Case> {
    let text = std::fs::read_to_string("tests/fixtures/commands.txt").expect("commands.txt");
    let mut cases = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut parts = line.split('|').map(str::trim);
        let name = parts.next().expect("a name").to_string();
        let args = parts
            .next()
            .expect("arguments")
            .split_whitespace()
            .map(|a| a.replace("$W", work))
            .collect();
        let (mut stdin, mut files) = (None, Vec::new());
        for extra in parts {
            if let Some(path) = extra.strip_prefix("stdin=") {
                stdin = Some(path.to_string());
            } else if let Some(list) = extra.strip_prefix("files=") {
                files = list.split(',').map(str::to_string).collect();
            } else {
                panic!("{name}: unknown field {extra:?}");
            }
        }
        cases.push(Case {
            name,
            args,
            stdin,
            files,
        });
    }
    cases
}

/// Removes every `"version":"…"` member from JSON text (the addition of issue 8).
fn without_version(text: &str) -> String {
    let key = "\"version\":\"";
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find(key) {
        let end = at + key.len() + rest[at + key.len()..].find('"').expect("a closed string") + 1;
        let (before, after) = (&rest[..at], &rest[end..]);
        if let Some(stripped) = after.strip_prefix(',') {
            out.push_str(before);
            rest = stripped;
        } else {
            out.push_str(before.strip_suffix(',').unwrap_or(before));
            rest = after;
        }
    }
    out.push_str(rest);
    out
}

fn compare_or_bless(expected: &Path, actual: &[u8], failures: &mut Vec<String>) {
    let actual = without_version(&String::from_utf8_lossy(actual));
    if std::env::var_os("POLYCAL_BLESS").is_some() {
        std::fs::write(expected, &actual).expect("write fixture");
        return;
    }
    let recorded =
        std::fs::read_to_string(expected).unwrap_or_else(|e| panic!("{}: {e}", expected.display()));
    if recorded != actual {
        let line = recorded
            .lines()
            .zip(actual.lines())
            .position(|(a, b)| a != b)
            .unwrap_or(recorded.lines().count().min(actual.lines().count()));
        failures.push(format!(
            "{} differs from line {}:\n  recorded: {:?}\n  now:      {:?}",
            expected.display(),
            line + 1,
            recorded.lines().nth(line).unwrap_or("<end>"),
            actual.lines().nth(line).unwrap_or("<end>"),
        ));
    }
}

#[test]
fn every_command_gives_the_recorded_output() {
    let work = "target/fixture-work";
    let _ = std::fs::remove_dir_all(work);
    std::fs::create_dir_all(work).unwrap();
    let expected = PathBuf::from("tests/fixtures/expected");
    let mut failures = Vec::new();
    for case in cases(work) {
        let mut command = Command::new(BIN);
        command
            .args(&case.args)
            .env_remove("NO_COLOR")
            .env_remove("CLICOLOR_FORCE")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        match &case.stdin {
            Some(path) => command.stdin(std::fs::File::open(path).expect("stdin file")),
            None => command.stdin(Stdio::null()),
        };
        let output = command.output().expect("polycal runs");
        let dir = |suffix: &str| expected.join(format!("{}.{suffix}", case.name));
        compare_or_bless(&dir("stdout"), &output.stdout, &mut failures);
        compare_or_bless(&dir("stderr"), &output.stderr, &mut failures);
        let status = format!("{}\n", output.status.code().unwrap_or(-1));
        compare_or_bless(&dir("status"), status.as_bytes(), &mut failures);
        for file in &case.files {
            let written = std::fs::read(Path::new(work).join(file)).expect("written file");
            compare_or_bless(&dir(&format!("file.{file}")), &written, &mut failures);
        }
    }
    assert!(
        failures.is_empty(),
        "{} fixture outputs changed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn the_version_filter_removes_only_the_version() {
    assert_eq!(
        without_version(r#"{"version":"0.2.0","faces":24}"#),
        r#"{"faces":24}"#
    );
    assert_eq!(
        without_version(r#"{"faces":24,"version":"0.2.0"}"#),
        r#"{"faces":24}"#
    );
    assert_eq!(
        without_version(r#"{"a":1,"version":"x","b":2}"#),
        r#"{"a":1,"b":2}"#
    );
    assert_eq!(without_version("no json"), "no json");
}

/// Keeps what a run writes that does not depend on the clock or the pseudo-terminals'
/// names: the measurement file without its `time` column and its dated comment, the
/// manifest's settings, instruments, outcome and counts, and the solved result.
#[cfg(unix)]
#[test]
fn a_run_against_the_simulated_lab_gives_the_recorded_readings() {
    use std::io::{BufRead, BufReader};
    let work = Path::new("target/fixture-work-lab");
    let _ = std::fs::remove_dir_all(work);
    std::fs::create_dir_all(work).unwrap();
    let truth = work.join("truth.json");
    let mut lab = Command::new(BIN)
        .args([
            "sim-lab",
            "--faces",
            "8",
            "--seed",
            "11",
            "--time-scale",
            "0",
        ])
        .arg("--truth-out")
        .arg(&truth)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("sim-lab starts");
    let mut lines = BufReader::new(lab.stdout.take().unwrap()).lines();
    let mut ports = Vec::new();
    for _ in 0..3 {
        let line = lines.next().expect("a device line").unwrap();
        ports.push(line.split_whitespace().nth(1).unwrap().to_string());
    }
    let out = work.join("run1");
    let run = Command::new(BIN)
        .args([
            "run", "--ac1", &ports[0], "--ac2", &ports[1], "--table", &ports[2],
        ])
        .args([
            "--faces",
            "8",
            "--cycles",
            "2",
            "--bidirectional",
            "--settle",
            "0",
        ])
        .arg("--out")
        .arg(&out)
        .stdin(Stdio::null())
        .output()
        .expect("run runs");
    let _ = lab.kill();
    let _ = lab.wait();
    let mut failures = Vec::new();
    let expected = PathBuf::from("tests/fixtures/expected");
    compare_or_bless(&expected.join("lab-run.stdout"), &run.stdout, &mut failures);
    compare_or_bless(&expected.join("lab-run.stderr"), &run.stderr, &mut failures);
    let csv = std::fs::read_to_string(out.join("measurements.csv")).unwrap();
    let mut kept = String::new();
    let mut time_column = None;
    for line in csv.lines().filter(|l| !l.starts_with('#')) {
        let fields: Vec<&str> = line.split(',').collect();
        let time = *time_column.get_or_insert_with(|| fields.iter().position(|f| *f == "time"));
        let fields: Vec<&str> = fields
            .iter()
            .enumerate()
            .filter(|(i, _)| Some(*i) != time)
            .map(|(_, f)| *f)
            .collect();
        kept.push_str(&fields.join(","));
        kept.push('\n');
    }
    compare_or_bless(
        &expected.join("lab-run.readings"),
        kept.as_bytes(),
        &mut failures,
    );
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let mut summary = String::new();
    for key in [
        "format",
        "software",
        "settings",
        "instruments",
        "outcome",
        "readings",
        "expected_readings",
    ] {
        summary.push_str(&format!("{key}: {}\n", manifest[key]));
    }
    compare_or_bless(
        &expected.join("lab-run.manifest"),
        summary.as_bytes(),
        &mut failures,
    );
    let solved = Command::new(BIN)
        .args(["solve", "--format", "json"])
        .arg(out.join("measurements.csv"))
        .output()
        .expect("solve runs");
    compare_or_bless(
        &expected.join("lab-run.solve"),
        &solved.stdout,
        &mut failures,
    );
    let truth_json = std::fs::read(&truth).expect("the lab wrote its truth");
    compare_or_bless(&expected.join("lab-run.truth"), &truth_json, &mut failures);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
