//! Every JSON field name polycal prints or writes is documented in `docs/FORMAT.md`.
//!
//! The test runs the binary on the commands whose JSON the contract describes — `solve`
//! (plain, with `--budget`, with `--monte-carlo`, several files, sub-pitch mountings, a
//! stated cross-talk), `diagnose` with a truth, with `--budget` and with a stated
//! cross-talk, `plan` (designs with a budget and a target, a lost harmonic, a file's design),
//! `budget`, `compare`, the truth files of
//! `simulate` (plain and sub-pitch) and `simulate --selfcal`, `selfcal` (plain and with
//! `--budget`), `diagnose` of a self-calibration (an outlier, a truth, a budget), and on Unix a whole `run`
//! against `sim-lab` (its device paths, `manifest.json` and every line of
//! `traffic.jsonl`) — collects every object key, at any depth, and checks that each
//! appears in the document as a code span (`` `name` ``). A field added to an output
//! without a word in the contract fails here, with every missing name listed at once.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");
const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";

/// A scratch directory unique to this process, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new() -> Scratch {
        let dir = std::env::temp_dir().join(format!("polycal-format-doc-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("the scratch directory can be created");
        Scratch(dir)
    }

    fn path(&self, name: &str) -> String {
        self.0.join(name).display().to_string()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Runs the binary in the repository root; a status other than 0 or 1 fails the test.
fn polycal(args: &[&str]) -> Output {
    let out = Command::new(BIN)
        .args(args)
        .current_dir(ROOT)
        .stdin(Stdio::null())
        .output()
        .expect("the binary runs");
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "polycal {}: status {:?}\n{}",
        args.join(" "),
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The JSON values of a command's standard output (one per line: JSON Lines).
fn json_lines(args: &[&str]) -> Vec<Value> {
    let out = polycal(args);
    let text = String::from_utf8(out.stdout).expect("UTF-8 output");
    let values: Vec<Value> = text
        .lines()
        .filter(|line| !line.trim().is_empty())
        .map(|line| {
            serde_json::from_str(line)
                .unwrap_or_else(|e| panic!("polycal {}: not JSON ({e}): {line}", args.join(" ")))
        })
        .collect();
    assert!(!values.is_empty(), "polycal {}: no output", args.join(" "));
    values
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: cannot read: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: not JSON: {e}", path.display()))
}

/// Every field name of the outputs, with where it was seen.
#[derive(Default)]
struct Fields(BTreeMap<String, BTreeSet<String>>);

impl Fields {
    /// Adds every object key of `value`, at any depth, as seen in `source`.
    fn add(&mut self, source: &str, value: &Value) {
        match value {
            Value::Object(map) => {
                for (key, inner) in map {
                    self.0
                        .entry(key.clone())
                        .or_default()
                        .insert(source.to_string());
                    self.add(source, inner);
                }
            }
            Value::Array(items) => items.iter().for_each(|v| self.add(source, v)),
            _ => {}
        }
    }

    fn has(&self, key: &str) -> bool {
        self.0.contains_key(key)
    }
}

/// Whether `name` appears in the document as a code span.
fn documented(doc: &str, name: &str) -> bool {
    doc.contains(&format!("`{name}`"))
}

/// The command outputs: solve, diagnose, budget, compare and the truth file.
fn command_fields(scratch: &Scratch, fields: &mut Fields) {
    let solve = |extra: &[&str]| {
        let mut args = vec!["solve", EXAMPLE, "--format", "json"];
        args.extend_from_slice(extra);
        json_lines(&args)
    };
    for v in solve(&[]) {
        fields.add("solve --format json", &v);
    }
    for v in solve(&["--budget", BUDGET]) {
        fields.add("solve --budget", &v);
    }
    for v in solve(&["--budget", BUDGET, "--monte-carlo", "2000"]) {
        fields.add("solve --budget --monte-carlo", &v);
    }

    // A run with a drift and an outlier, diagnosed against its truth.
    let (drift, truth) = (scratch.path("drift.csv"), scratch.path("drift.json"));
    polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "6",
        "--closing",
        "--drift",
        "2:2.0",
        "--outlier",
        "2:5:1:3",
        "--out",
        &drift,
        "--truth-out",
        &truth,
    ]);
    fields.add("truth file of simulate", &read_json(Path::new(&truth)));

    // The self-calibration truth of `simulate --selfcal`.
    let (selfcal, selfcal_truth) = (scratch.path("selfcal.csv"), scratch.path("selfcal.json"));
    polycal(&[
        "simulate",
        "--selfcal",
        "--positions",
        "12",
        "--heads",
        "0,90,180,270",
        "--out",
        &selfcal,
        "--truth-out",
        &selfcal_truth,
    ]);
    fields.add(
        "truth file of simulate --selfcal",
        &read_json(Path::new(&selfcal_truth)),
    );
    // Its diagnosis, with one bad reading (an effect with every field), a truth and a
    // budget.
    let text = std::fs::read_to_string(&selfcal).expect("the self-calibration file");
    let bad: Vec<String> = text
        .lines()
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            match f.as_slice() {
                ["2", "5", "3", angle, reading, rest @ ..] => {
                    let reading: f64 = reading.parse().expect("a reading");
                    let mut row = vec!["2".to_string(), "5".into(), "3".into(), angle.to_string()];
                    row.push((reading + 1.0).to_string());
                    row.extend(rest.iter().map(|s| s.to_string()));
                    row.join(",")
                }
                _ => line.to_string(),
            }
        })
        .collect();
    let selfcal_bad = scratch.path("selfcal-bad.csv");
    std::fs::write(&selfcal_bad, bad.join("\n") + "\n").expect("written");
    for v in json_lines(&[
        "diagnose",
        &selfcal_bad,
        "--truth",
        &selfcal_truth,
        "--budget",
        "examples/budgets/selfcal.toml",
        "--format",
        "json",
    ]) {
        assert!(v["effects"][0]["kind"] == "outlier", "{v}");
        fields.add("diagnose SELFCAL --truth --budget --format json", &v);
    }
    // The self-calibration itself: plain, with a bound and a gauge, and with a budget.
    for v in json_lines(&["selfcal", "examples/data/selfa-168.csv", "--format", "json"]) {
        fields.add("selfcal --format json", &v);
    }
    for v in json_lines(&[
        "selfcal",
        "examples/data/selfa-168.csv",
        "--lost-harmonic-bound",
        "0.01",
        "--gauge-positions",
        "24",
        "--head-angle-u",
        "0.5",
        "--budget",
        "examples/budgets/selfcal.toml",
        "--format",
        "json",
    ]) {
        fields.add("selfcal --budget --format json", &v);
    }
    // `plan`: a design with a budget and a target, one that loses harmonics, a file's
    for v in json_lines(&[
        "plan",
        "--sigma",
        "0.05",
        "--closing",
        "--budget",
        BUDGET,
        "--target-u",
        "0.03",
        "--design",
        "name=A",
        "--design",
        "name=lost;ac-faces=1,4",
        "--format",
        "json",
    ]) {
        fields.add("plan --format json", &v);
    }
    for v in json_lines(&["plan", EXAMPLE, "--sigma", "0.05", "--format", "json"]) {
        fields.add("plan FILE --format json", &v);
    }
    for v in json_lines(&["diagnose", &drift, "--truth", &truth, "--format", "json"]) {
        fields.add("diagnose --truth --format json", &v);
    }
    for v in json_lines(&["diagnose", &drift, "--budget", BUDGET, "--format", "json"]) {
        fields.add("diagnose --budget --format json", &v);
    }

    // Sub-pitch mountings: the truth's and solve's angles, and solve's notes.
    let (sub_pitch, sub_truth) = (scratch.path("subpitch.csv"), scratch.path("subpitch.json"));
    polycal(&[
        "simulate",
        "--faces",
        "12",
        "--setups",
        "2",
        "--shift-deg",
        "0,10",
        "--out",
        &sub_pitch,
        "--truth-out",
        &sub_truth,
    ]);
    fields.add(
        "truth file of simulate --shift-deg",
        &read_json(Path::new(&sub_truth)),
    );
    for v in json_lines(&["solve", &sub_pitch, "--format", "json"]) {
        fields.add("solve (sub-pitch) --format json", &v);
    }

    // Cross-talk stated from a calibration: `stated_cross_talk`, and its budget component.
    let xtalk = scratch.path("xtalk.csv");
    polycal(&[
        "simulate",
        "--faces",
        "12",
        "--cycles",
        "3",
        "--closing",
        "--elevation",
        "10:0:1:5:0.05",
        "--cross-talk",
        "1:0.01",
        "--out",
        &xtalk,
    ]);
    for v in json_lines(&[
        "solve",
        &xtalk,
        "--cross-talk",
        "1:0.01:0.001",
        "--budget",
        BUDGET,
        "--monte-carlo",
        "2000",
        "--format",
        "json",
    ]) {
        fields.add("solve --cross-talk --budget --monte-carlo", &v);
    }
    for v in json_lines(&[
        "diagnose",
        &xtalk,
        "--cross-talk",
        "1:0.01:0.001",
        "--budget",
        BUDGET,
        "--format",
        "json",
    ]) {
        fields.add("diagnose --cross-talk --budget", &v);
    }

    // Several files: JSON Lines with "file".
    for v in json_lines(&["solve", EXAMPLE, &drift, "--format", "json"]) {
        fields.add("solve FILE FILE --format json", &v);
    }

    for v in json_lines(&[
        "budget",
        "examples/budgets/paper-table1.toml",
        "--format",
        "json",
    ]) {
        fields.add("budget --format json", &v);
    }

    for v in json_lines(&["validate", "--format", "json"]) {
        fields.add("validate --format json", &v);
    }

    // Two results whose rows differ (two mountings against one), compared with a
    // correlation: every optional field of the comparison is present (the encoder errors
    // matched by angle, so with `index_b` and `angle_deg`).
    let mut results = Vec::new();
    for (name, design) in [
        ("a", &["--setups", "2", "--cycles", "2", "--seed", "11"][..]),
        ("b", &["--cycles", "3", "--seed", "12"][..]),
    ] {
        let run = scratch.path(&format!("{name}.csv"));
        let mut args = vec!["simulate", "--faces", "12", "--closing", "--out", &run];
        args.extend_from_slice(design);
        polycal(&args);
        let out = polycal(&["solve", &run, "--budget", BUDGET, "--format", "csv"]);
        let result = scratch.path(&format!("result-{name}.csv"));
        std::fs::write(&result, &out.stdout).expect("the result file can be written");
        results.push(result);
    }
    for v in json_lines(&[
        "compare",
        &results[0],
        &results[1],
        "--correlation",
        "0.3",
        "--format",
        "json",
    ]) {
        fields.add("compare --format json", &v);
    }
    // `kc` on the bundled example, with the pilot's repeats, and of encoder errors.
    let kc = |name: &str| format!("{name}=examples/data/kc/{name}.csv");
    let labs: Vec<String> = ["A", "B", "C", "D", "E", "F"]
        .iter()
        .map(|n| kc(n))
        .collect();
    let pilot: Vec<String> = ["pilot-start", "pilot-end"].iter().map(|n| kc(n)).collect();
    let mut args: Vec<&str> = vec!["kc", "--format", "json"];
    args.extend(labs.iter().map(String::as_str));
    for repeat in &pilot {
        args.extend(["--pilot", repeat.as_str()]);
    }
    for v in json_lines(&args) {
        fields.add("kc --format json", &v);
    }
    args.extend(["--quantity", "encoder_error"]);
    for v in json_lines(&args) {
        fields.add("kc --quantity encoder_error --format json", &v);
    }
}

/// A `polycal sim-lab` process; killed when dropped.
#[cfg(unix)]
struct Lab {
    child: std::process::Child,
    _stdin: std::process::ChildStdin,
    paths: Value,
}

#[cfg(unix)]
impl Lab {
    fn start() -> Lab {
        use std::io::{BufRead, BufReader};
        let mut child = Command::new(BIN)
            .args([
                "sim-lab",
                "--faces",
                "8",
                "--time-scale",
                "0",
                "--format",
                "json",
            ])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("sim-lab starts");
        let stdin = child.stdin.take().expect("sim-lab's standard input");
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("sim-lab's standard output"))
            .read_line(&mut line)
            .expect("sim-lab prints its device paths");
        let paths = serde_json::from_str(&line)
            .unwrap_or_else(|e| panic!("sim-lab --format json: not JSON ({e}): {line}"));
        Lab {
            child,
            _stdin: stdin,
            paths,
        }
    }

    fn path(&self, device: &str) -> String {
        self.paths[device]
            .as_str()
            .unwrap_or_else(|| panic!("sim-lab's {device} path in {}", self.paths))
            .to_string()
    }
}

#[cfg(unix)]
impl Drop for Lab {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The run directory of a whole run against the simulated lab: `manifest.json` and every
/// record of `traffic.jsonl`, and sim-lab's device paths.
#[cfg(unix)]
fn run_fields(scratch: &Scratch, fields: &mut Fields) {
    let lab = Lab::start();
    fields.add("sim-lab --format json", &lab.paths);
    let dir = scratch.0.join("run");
    let (ac1, ac2, table) = (lab.path("ac1"), lab.path("ac2"), lab.path("table"));
    let out_dir = dir.display().to_string();
    let out = polycal(&[
        "run",
        "--ac1",
        &ac1,
        "--ac2",
        &ac2,
        "--table",
        &table,
        "--faces",
        "8",
        "--cycles",
        "1",
        "--closing",
        "--settle",
        "0",
        "-q",
        "--out",
        &out_dir,
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "the run completes: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    drop(lab);
    fields.add("manifest.json", &read_json(&dir.join("manifest.json")));
    let traffic = std::fs::read_to_string(dir.join("traffic.jsonl")).expect("traffic.jsonl");
    for line in traffic.lines().filter(|l| !l.trim().is_empty()) {
        let record: Value = serde_json::from_str(line)
            .unwrap_or_else(|e| panic!("traffic.jsonl: not JSON ({e}): {line}"));
        fields.add("traffic.jsonl", &record);
    }
}

#[cfg(not(unix))]
fn run_fields(_scratch: &Scratch, _fields: &mut Fields) {}

#[test]
fn every_json_field_name_is_documented() {
    let doc_path = Path::new(ROOT).join("docs/FORMAT.md");
    let doc = std::fs::read_to_string(&doc_path)
        .unwrap_or_else(|e| panic!("{}: cannot read: {e}", doc_path.display()));
    assert!(
        !documented(&doc, "no_such_field_in_polycal"),
        "the check must be able to fail"
    );

    let scratch = Scratch::new();
    let mut fields = Fields::default();
    command_fields(&scratch, &mut fields);
    run_fields(&scratch, &mut fields);

    // The outputs were really collected, down to the nested objects.
    let mut expected = vec![
        "pitch_deviation_U",
        "dof_eff",
        "acts_on",
        "monte_carlo",
        "d_high",
        "checks",
        "p_adjusted",
        "encoder_rms",
        "index_percent",
        "U_a",
        "only_in_a",
        "only_in_b",
        "correlation",
        "in_verdict",
        "encoder_matched_by",
        "index_b",
        "angle_deg",
        "noise_arcsec",
        "file",
        "stated_cross_talk",
        "coefficient",
    ];
    if cfg!(unix) {
        expected.extend(["sessions", "readings_before", "started_unix", "event"]);
    }
    for key in expected {
        assert!(fields.has(key), "no output had the field {key:?}");
    }

    let missing: Vec<String> = fields
        .0
        .iter()
        .filter(|(key, _)| !documented(&doc, key))
        .map(|(key, sources)| {
            format!(
                "  `{key}` (in {})",
                sources.iter().cloned().collect::<Vec<_>>().join(", ")
            )
        })
        .collect();
    assert!(
        missing.is_empty(),
        "{} JSON field names are not documented in docs/FORMAT.md as code spans:\n{}",
        missing.len(),
        missing.join("\n")
    );
}
