//! Hardening (issue 13): numbers that are finite but absurd are refused at their file,
//! line and column; inputs too big for the machine are refused up front with the size and
//! the limit; every usage and OS error is one `error:` line; standard input is read where
//! `-` is given, and once. Each class is tried with its own bad input, through the binary
//! as a user meets it. The limits are docs/FORMAT.md §2.2; the positions and the
//! arithmetic below are derived by hand from the texts written here.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";
const EXAMPLE_TRUTH: &str = "examples/data/polygon24-2ac-6cycles.truth.json";
const SELFCAL: &str = "examples/data/selfa-168.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";

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
    let mut stdin = child.stdin.take().expect("a pipe");
    // the process may refuse before reading all of it
    let _ = stdin.write_all(input);
    drop(stdin);
    child.wait_with_output().expect("the binary ends")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-hard-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

/// Status 2 and exactly one line on standard error, which begins `error:`; returns it
/// without the prefix.
fn one_error_line(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "status; stderr:\n{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line on standard error, got:\n{stderr}");
    lines[0]
        .strip_prefix("error: ")
        .unwrap_or_else(|| panic!("an error: line, got {:?}", lines[0]))
        .to_string()
}

/// A valid measurement file of the paper's design with N = 3 and every optional numeric
/// column: autocollimator 1 reads face p+1, 2 reads face p+2 at step p.
const SMALL_HEADER: &str = "cycle,step,ac,face,reading,time,reading_y,temperature,encoder";
const SMALL_ROWS: [&str; 6] = [
    "1,0,1,1,0.5,0,1.5,20.1,0",
    "1,0,2,2,-0.25,0,1.25,20.1,0",
    "1,1,1,2,0.75,20,1.5,20.2,120",
    "1,1,2,3,0.5,20,1.75,20.2,120",
    "1,2,1,3,-1,40,1,20.3,240",
    "1,2,2,1,0.25,40,1.5,20.3,240",
];

/// The small file with the field `column` (0-based) of data row `row` (0-based) replaced;
/// returns the text and the 1-based line and character column of that field.
fn small_file_with(row: usize, column: usize, value: &str) -> (String, usize, usize) {
    let mut text = format!("{SMALL_HEADER}\n");
    let mut at = (0, 0);
    for (i, line) in SMALL_ROWS.iter().enumerate() {
        if i == row {
            let mut fields: Vec<&str> = line.split(',').collect();
            let before: usize = fields[..column].iter().map(|f| f.chars().count() + 1).sum();
            fields[column] = value;
            at = (i + 2, before + 1);
            text.push_str(&fields.join(","));
        } else {
            text.push_str(line);
        }
        text.push('\n');
    }
    (text, at.0, at.1)
}

#[test]
fn absurd_numbers_in_a_measurement_file_are_refused_at_their_field() {
    let dir = temp_dir("measurement");
    // the file as written solves
    let (valid, _, _) = small_file_with(0, 4, "0.5");
    let path = write(&dir, "valid.csv", &valid);
    let out = polycal(&["solve", &path, "--sigma", "0.1"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    for (row, column, value, rule) in [
        (
            0,
            4,
            "1e300",
            "column \"reading\": \"1e300\" is beyond the limits of a reading, −1e6 … 1e6″",
        ),
        (
            3,
            4,
            "-1000000.5",
            "column \"reading\": \"-1000000.5\" is beyond the limits of a reading, −1e6 … 1e6″",
        ),
        (
            2,
            6,
            "-1e300",
            "column \"reading_y\": \"-1e300\" is beyond the limits of a reading, −1e6 … 1e6″",
        ),
        (
            5,
            5,
            "1e10",
            "column \"time\": \"1e10\" is beyond the limits of a time, −1e9 … 1e9 s",
        ),
        (
            1,
            7,
            "-300",
            "column \"temperature\": \"-300\" is beyond the limits of a temperature, −273.15 … 1000 °C",
        ),
        (
            4,
            8,
            "1.5e7",
            "column \"encoder\": \"1.5e7\" is beyond the limits of an encoder position, −1e6 … 1e6°",
        ),
    ] {
        let (text, line, col) = small_file_with(row, column, value);
        let path = write(&dir, "absurd.csv", &text);
        for command in ["solve", "diagnose"] {
            let message = one_error_line(&polycal(&[command, &path, "--sigma", "0.1"]));
            assert_eq!(
                message,
                format!("{path}:{line}:{col}: {rule} (docs/FORMAT.md §2.2)"),
                "{command} with {value}"
            );
        }
    }

    // the limits themselves are readings
    for value in ["1e6", "-1e6"] {
        let (text, _, _) = small_file_with(2, 4, value);
        let path = write(&dir, "edge.csv", &text);
        let out = polycal(&["solve", &path, "--sigma", "0.1", "--format", "json"]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{value}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert!(
            json["pitch_deviation_u"]
                .as_array()
                .unwrap()
                .iter()
                .all(|u| u.as_f64().is_some()),
            "{json}"
        );
    }
    // σ too is held to the limit of a reading
    let message = one_error_line(&polycal(&["solve", &path, "--sigma", "1e300"]));
    assert!(message.contains("1e300 is beyond the limits"), "{message}");
}

#[test]
fn absurd_numbers_in_other_files_are_refused_at_their_place() {
    let dir = temp_dir("other-files");
    // a self-calibration reading: line 3 of the bundled file, field 5
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(SELFCAL)).unwrap();
    let text = text.replacen("1,0,1,0,0.01322522954256664,0", "1,0,1,0,1e300,0", 1);
    let path = write(&dir, "selfcal.csv", &text);
    assert_eq!(
        one_error_line(&polycal(&["selfcal", &path])),
        format!(
            "{path}:3:9: column \"reading\": \"1e300\" is beyond the limits of a reading, −1e6 … 1e6″ \
             (docs/FORMAT.md §2.2)"
        )
    );

    // a result file: compare's En with −1e308 was `null`
    let reference = write(
        &dir,
        "a.csv",
        "quantity,index,value,U\npitch_deviation,1,0.5,0.1\n",
    );
    let absurd = write(
        &dir,
        "b.csv",
        "quantity,index,value,U\npitch_deviation,1,-1e308,0.1\n",
    );
    assert_eq!(
        one_error_line(&polycal(&[
            "compare", &reference, &absurd, "--format", "json"
        ])),
        format!(
            "{absurd}:2:19: column \"value\": \"-1e308\" is beyond the limits of a result's value, −1e12 … 1e12″ \
             (docs/FORMAT.md §2.2)"
        )
    );

    // a truth file
    let truth = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE_TRUTH))
        .unwrap()
        .replacen("-0.2040012791581015", "1e300", 1);
    let truth = write(&dir, "truth.json", &truth);
    let message = one_error_line(&polycal(&["diagnose", EXAMPLE, "--truth", &truth]));
    assert_eq!(
        message,
        format!(
            "{truth}: invalid truth: pitch_deviation[3]: 1e300 is beyond the limits of a truth \
             value, −1e6 … 1e6″ (docs/FORMAT.md §2.2)"
        )
    );
}

#[test]
fn budget_values_are_refused_for_what_they_are_and_large_ones_combine() {
    let dir = temp_dir("budget");
    // u = 1e200 was refused as "every contribution is zero", with the file named twice
    let path = write(
        &dir,
        "u.toml",
        "p = 0.95\n[[component]]\nname = \"a\"\ntype = \"B\"\nu = 1e200\n",
    );
    assert_eq!(
        one_error_line(&polycal(&["budget", &path])),
        format!(
            "{path}:5:5: u: 1e200 is beyond the limits of a budget's u, −1e100 … 1e100 (docs/FORMAT.md §2.2)"
        )
    );
    let path = write(
        &dir,
        "w.toml",
        "[[component]]\nname = \"a\"\ntype = \"B\"\ndistribution = \"rectangular\"\nfull_width = 1e-200\n",
    );
    assert_eq!(
        one_error_line(&polycal(&["budget", &path])),
        format!(
            "{path}:5:14: full_width: 1e-200 is too small for a budget's full_width: a magnitude \
             other than 0 must be at least 1e-100 (docs/FORMAT.md §2.2)"
        )
    );
    // a whole-budget error names the file once
    let path = write(
        &dir,
        "zero.toml",
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 0\n",
    );
    let message = one_error_line(&polycal(&["budget", &path]));
    assert!(
        message.starts_with(&format!("{path}: the combined standard uncertainty is 0")),
        "{message}"
    );
    assert_eq!(message.matches(&path).count(), 1, "{message}");
    // invalid UTF-8 at its line and column
    let latin1 = dir.join("latin1.toml");
    std::fs::write(&latin1, b"[[component]]\nname = \"caf\xe9\"\n").unwrap();
    assert_eq!(
        one_error_line(&polycal(&["budget", &latin1.display().to_string()])),
        format!(
            "{}:2:12: not valid UTF-8 (byte 0xe9); the file must be UTF-8 text",
            latin1.display()
        )
    );

    // Two components of u = 1e90 with 10 degrees of freedom each: their fourth powers
    // (1e360) overflow, yet u_c = √2·1e90 and ν_eff = (2u²)² / (2u⁴/10) = 20 (GUM G.2b).
    let path = write(
        &dir,
        "large.toml",
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 1e90\ndof = 10\n\
         [[component]]\nname = \"b\"\ntype = \"B\"\nu = 1e90\ndof = 10\n",
    );
    let out = polycal(&["budget", &path, "--format", "json"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let u_c = json["combined_u"].as_f64().unwrap();
    assert!((u_c / (2f64.sqrt() * 1e90) - 1.0).abs() < 1e-14, "{u_c}");
    let nu = json["dof_eff"].as_f64().unwrap();
    assert!((nu - 20.0).abs() < 1e-12, "{nu}");
}

/// `n` type-B components `c0` … of u = 0.01 each, as budget TOML.
fn components(n: usize) -> String {
    (0..n)
        .map(|i| format!("[[component]]\nname = \"c{i}\"\ntype = \"B\"\nu = 0.01\n"))
        .collect()
}

#[test]
fn a_budget_of_sixty_thousand_components_combines_and_too_many_correlations_are_refused() {
    let dir = temp_dir("big-budget");
    let n = 60_000;
    let text = format!("p = 0.95\n{}", components(n));
    let path = write(&dir, "sixty.toml", &text);
    let out = polycal(&["budget", &path, "--format", "json"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // u_c = 0.01·√60000, k = 1.96 (ν infinite)
    let u_c = json["combined_u"].as_f64().unwrap();
    assert!((u_c - 0.01 * (n as f64).sqrt()).abs() < 1e-12, "{u_c}");
    assert_eq!(json["components"].as_array().unwrap().len(), n);

    // correlations need a matrix of the correlated components: more than 1000 refused
    let mut text = components(2004);
    for i in 0..1001 {
        text.push_str(&format!(
            "[[correlation]]\nbetween = [\"c{}\", \"c{}\"]\nr = 0.1\n",
            2 * i,
            2 * i + 1
        ));
    }
    let path = write(&dir, "correlated.toml", &text);
    assert_eq!(
        one_error_line(&polycal(&["budget", &path])),
        format!(
            "{path}: the budget gives 1001 correlation coefficients; at most 1000 are evaluated \
             (their consistency is checked on a matrix of the correlated components)"
        )
    );
}

#[test]
fn a_monte_carlo_too_big_for_the_machine_is_refused_up_front() {
    // The trials are not stored: the values kept grow like √M per output, so 10¹² trials
    // of the example's 71 outputs fit in about 17 GiB. Of 1440 positions' 4319 outputs
    // they need about 990 GiB: refused before the first trial.
    let dir = temp_dir("mc-too-big");
    let path = dir.join("p1440.csv").display().to_string();
    let out = polycal(&[
        "simulate",
        "--faces",
        "1440",
        "--cycles",
        "1",
        "--closing",
        "--out",
        &path,
    ]);
    assert!(out.status.success());
    let message = one_error_line(&polycal(&[
        "solve",
        &path,
        "--budget",
        BUDGET,
        "--monte-carlo",
        "1e12",
    ]));
    assert!(
        message.starts_with(&format!(
            "{path}: Monte Carlo failed: 1000000000000 trials of 4319 outputs need about "
        )) && message.contains(" GiB of memory; "),
        "{message}"
    );
    assert!(
        message.ends_with("are available on this machine: ask for fewer trials"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_design_too_big_for_the_machine_is_refused_up_front() {
    let dir = temp_dir("design");
    let path = dir.join("sub-pitch.csv").display().to_string();
    // 40 000 faces in two mountings 0.01° apart, the second mounting's second
    // autocollimator read at every third step only: too irregular for the coset engine
    // (that stream reads most positions zero times), so the cosets' differences are
    // effect columns, 39 999 of them of 266 668 readings, 8 bytes each, about 79.5 GiB
    // before the engine allocates anything.
    let out = polycal(&[
        "simulate",
        "--faces",
        "40000",
        "--cycles",
        "2",
        "--setups",
        "2",
        "--shift-deg",
        "0,0.01",
        "--out",
        &path,
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&path).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|line| {
            // cycle,step,ac,face,reading,direction,setup,…
            let fields: Vec<&str> = line.split(',').collect();
            let number = |i: usize| fields.get(i).and_then(|f| f.parse::<usize>().ok());
            !(number(6) == Some(2) && number(2) == Some(2) && number(1).is_some_and(|s| s % 3 != 0))
        })
        .collect();
    std::fs::write(&path, kept.join("\n") + "\n").unwrap();
    let message = one_error_line(&polycal(&["solve", &path]));
    assert!(
        message.starts_with(&format!(
            "{path}: cannot solve: the design (40000 positions, 4 autocollimator streams, 39999 \
             effect terms, 266668 readings) needs about 79.5 GiB of memory for the sub-pitch solver; "
        )),
        "{message}"
    );
    assert!(
        message.ends_with("are available on this machine"),
        "{message}"
    );
}

#[test]
fn inputs_beyond_the_read_limit_are_refused_not_read_to_the_end() {
    let limit = 256u64 << 20;
    // a stream is read to the limit and no further
    for args in [
        vec!["solve", "/dev/zero"],
        vec!["selfcal", "/dev/zero"],
        vec!["budget", "/dev/zero"],
        vec!["compare", "/dev/zero", EXAMPLE],
        vec!["diagnose", EXAMPLE, "--truth", "/dev/zero"],
    ] {
        assert_eq!(
            one_error_line(&polycal(&args)),
            format!(
                "/dev/zero: at least {} bytes, more than polycal reads from one input ({limit} bytes at most)",
                limit + 1
            ),
            "{args:?}"
        );
    }
    // a regular file is refused by its size, before it is read (a sparse file)
    let dir = temp_dir("large-file");
    let path = dir.join("large.csv");
    std::fs::File::create(&path)
        .unwrap()
        .set_len(300 << 20)
        .unwrap();
    let name = path.display().to_string();
    assert_eq!(
        one_error_line(&polycal(&["solve", &name])),
        format!(
            "{name}: 314572800 bytes, more than polycal reads from one input ({limit} bytes at most)"
        )
    );
    std::fs::remove_file(&path).unwrap();
}

#[test]
fn usage_errors_are_one_line() {
    for args in [
        vec![],
        vec!["solve"],
        vec!["solve", "--bogus", EXAMPLE],
        vec!["frobnicate"],
        vec!["solve", EXAMPLE, "--format", "yaml"],
        vec!["budget", BUDGET, "--format", "csv"],
        vec!["compare", EXAMPLE],
        vec!["run"],
        vec!["simulate", "--faces", "x", "--cycles", "1"],
    ] {
        let message = one_error_line(&polycal(&args));
        assert!(message.ends_with("(see --help)"), "{args:?}: {message}");
    }
    assert_eq!(
        one_error_line(&polycal(&[])),
        "no command given; the commands are solve, diagnose, budget, compare, kc, selfcal, plan, report, \
         simulate, run, sim-lab, completions, man (see --help)"
    );
}

#[test]
fn os_errors_are_named_once() {
    let missing = "no/such/file.csv";
    for args in [
        vec!["solve", missing],
        vec!["diagnose", missing],
        vec!["selfcal", missing],
        vec!["budget", missing],
        vec!["compare", missing, EXAMPLE],
        vec!["solve", EXAMPLE, "--budget", missing],
        vec!["diagnose", EXAMPLE, "--truth", missing],
        vec![
            "report",
            EXAMPLE,
            "--meta",
            missing,
            "--out",
            "/tmp/polycal-never.html",
        ],
    ] {
        let message = one_error_line(&polycal(&args));
        assert_eq!(
            message,
            format!("{missing}: No such file or directory (os error 2)"),
            "{args:?}"
        );
    }
    // a directory where a file is read
    assert_eq!(
        one_error_line(&polycal(&["solve", "examples"])),
        "examples: Is a directory (os error 21)"
    );
    // --plot on a file
    let dir = temp_dir("plot-file");
    let file = write(&dir, "not-a-dir", "");
    assert_eq!(
        one_error_line(&polycal(&["solve", EXAMPLE, "--plot", &file])),
        format!("--plot {file}: is a file, not a directory; the figures need a directory")
    );
}

#[test]
fn several_bad_files_give_one_error_line_each() {
    let out = polycal(&[
        "solve",
        "a/missing.csv",
        EXAMPLE,
        "b/missing.csv",
        "--format",
        "json",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(
        errors,
        [
            "error: a/missing.csv: No such file or directory (os error 2)",
            "error: b/missing.csv: No such file or directory (os error 2)",
        ],
        "{stderr}"
    );
    assert!(
        stderr.contains("\n2 of 3 files could not be solved\n"),
        "{stderr}"
    );
    // the good file is still solved, one JSON line
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1);
    // with -q the summary goes, the errors stay
    let out = polycal(&["-q", "solve", "a/missing.csv", "b/missing.csv"]);
    assert_eq!(String::from_utf8_lossy(&out.stderr).lines().count(), 2);
}

#[test]
fn truth_from_standard_input_and_standard_input_only_once() {
    let from_file = polycal(&[
        "diagnose",
        EXAMPLE,
        "--truth",
        EXAMPLE_TRUTH,
        "--format",
        "json",
    ]);
    assert_eq!(from_file.status.code(), Some(0));
    let truth = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE_TRUTH)).unwrap();
    let from_stdin = polycal_stdin(
        &["diagnose", EXAMPLE, "--truth", "-", "--format", "json"],
        &truth,
    );
    assert_eq!(
        from_stdin.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&from_stdin.stderr)
    );
    let a: serde_json::Value = serde_json::from_slice(&from_file.stdout).unwrap();
    let b: serde_json::Value = serde_json::from_slice(&from_stdin.stdout).unwrap();
    assert!(a["error"].is_object());
    assert_eq!(a["error"], b["error"]);
    // bad JSON on standard input is named <stdin> with its line and column
    assert_eq!(
        one_error_line(&polycal_stdin(
            &["diagnose", EXAMPLE, "--truth", "-"],
            b"{\n  \"faces\": x"
        )),
        "<stdin>:2:12: not a valid truth file: expected value"
    );
    // two inputs cannot both be standard input
    let csv = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE)).unwrap();
    assert_eq!(
        one_error_line(&polycal_stdin(&["diagnose", "-", "--truth", "-"], &csv)),
        "standard input (`-`) is given for a measurement file and --truth: it can be read only \
         once; give the others as files"
    );
}

/// A term that explains the rest exactly has an infinite F: `null` in the JSON (as
/// docs/FORMAT.md §5.2 says), `∞` for people, never `inf`. Three faces, two cycles, every
/// reading 0 but one of 0.5″: an outlier column leaves no residual.
#[test]
fn an_infinite_f_is_written_for_people_and_null_in_json() {
    let mut text = String::from("cycle,step,ac,face,reading\n");
    for cycle in 1..=2 {
        for step in 0..3 {
            for ac in 1..=2 {
                let face = (step + ac - 1) % 3 + 1;
                let value = if (cycle, step, ac) == (1, 0, 1) {
                    "0.5"
                } else {
                    "0"
                };
                text.push_str(&format!("{cycle},{step},{ac},{face},{value}\n"));
            }
        }
    }
    let dir = temp_dir("exact-fit");
    let path = write(&dir, "outlier.csv", &text);
    let table = polycal(&["diagnose", &path]);
    let stdout = String::from_utf8_lossy(&table.stdout);
    assert!(stdout.contains("F = ∞ (no residual left)"), "{stdout}");
    assert!(!stdout.contains("inf"), "{stdout}");
    let json = polycal(&["diagnose", &path, "--format", "json"]);
    let json: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let infinite: Vec<&serde_json::Value> = json["tried"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t["kind"] == "outlier")
        .collect();
    assert!(
        !infinite.is_empty() && infinite.iter().all(|t| t["F"].is_null()),
        "{json}"
    );
}

/// A file argument that is not UTF-8 (a Latin-1 `café.csv`) is a file like any other:
/// `report` records the command line without panicking (it did, status 101), and `solve`,
/// `diagnose` and `plan` read the same file (issue 34).
#[cfg(unix)]
#[test]
fn a_file_name_that_is_not_utf8_is_read_without_a_panic() {
    use std::ffi::OsStr;
    use std::os::unix::ffi::OsStrExt;
    let dir = temp_dir("latin1-name");
    let name = dir.join(OsStr::from_bytes(b"caf\xe9.csv"));
    std::fs::copy(EXAMPLE, &name).unwrap();
    let html = dir.join("r.html");
    let run = |args: &[&OsStr]| {
        Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("the binary runs")
    };
    let report = run(&[
        OsStr::new("report"),
        name.as_os_str(),
        OsStr::new("--out"),
        html.as_os_str(),
    ]);
    assert_eq!(
        report.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&report.stderr)
    );
    let text = std::fs::read_to_string(&html).unwrap();
    assert!(
        text.contains("caf\u{fffd}.csv"),
        "the name as it could be shown"
    );
    for command in ["solve", "diagnose"] {
        let out = run(&[OsStr::new(command), name.as_os_str()]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{command}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let plan = run(&[
        OsStr::new("plan"),
        name.as_os_str(),
        OsStr::new("--sigma"),
        OsStr::new("0.05"),
    ]);
    assert_eq!(
        plan.status.code(),
        Some(0),
        "plan: {}",
        String::from_utf8_lossy(&plan.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs polycal with `args` under `ulimit -v KB` (the address-space limit).
fn polycal_under_ulimit_v(kilobytes: u64, args: &[&str]) -> Output {
    let quoted: Vec<String> = args
        .iter()
        .map(|a| format!("'{}'", a.replace('\'', "'\\''")))
        .collect();
    Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {kilobytes} && exec '{}' {}",
            env!("CARGO_BIN_EXE_polycal"),
            quoted.join(" ")
        ))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("sh runs")
}

#[test]
fn work_beyond_the_address_space_limit_is_refused_up_front() {
    // The machine may have gigabytes available while `ulimit -v` leaves 1.43 GiB: the
    // guard takes the tightest. The dense solver of 6000 positions needs (2·6000)² · 8
    // bytes and more, about 7.5 GiB; a plan of 4 000 000 faces about 11.4 GiB.
    let dir = temp_dir("ulimit");
    let path = dir.join("d6000.csv").display().to_string();
    let out = polycal(&[
        "simulate", "--faces", "6000", "--cycles", "1", "--out", &path,
    ]);
    assert_eq!(out.status.code(), Some(0));
    let limited = "are left under this process's address-space limit (ulimit -v)";
    let message = one_error_line(&polycal_under_ulimit_v(
        1_500_000,
        &["solve", &path, "--method", "dense"],
    ));
    assert!(
        message.starts_with(&format!("{path}: cannot solve: the design (6000 positions")),
        "{message}"
    );
    // what is left is the limit less the process's own address space at the check (its
    // threads' malloc arenas included, which vary with the machine's load): 1.2–1.43 GiB
    let left: f64 = message
        .split("GiB of memory for the dense solver; ")
        .nth(1)
        .and_then(|rest| rest.split(" GiB ").next())
        .and_then(|number| number.parse().ok())
        .unwrap_or_else(|| panic!("{message}"));
    assert!((1.2..=1.43).contains(&left), "{message}");
    assert!(message.ends_with(limited), "{message}");
    let message = one_error_line(&polycal_under_ulimit_v(
        4_000_000,
        &["plan", "--sigma", "0.05", "--faces", "4000000"],
    ));
    assert!(
        message.contains("need about 11.4 GiB of memory; 3."),
        "{message}"
    );
    assert!(message.ends_with(limited), "{message}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The one error line of `solve EXAMPLE --budget BUDGET --monte-carlo TRIALS [extra]`.
fn monte_carlo_refusal(trials: &str, extra: &[&str]) -> String {
    let mut args = vec![
        "solve",
        EXAMPLE,
        "--budget",
        BUDGET,
        "--monte-carlo",
        trials,
    ];
    args.extend_from_slice(extra);
    one_error_line(&polycal(&args))
}

#[test]
fn trial_counts_at_their_edges_are_refused_or_bounded() {
    // 0, 1 and 2 trials are too few for a 95 % interval (at least 20); 2⁶³ and 2⁶⁴ − 1
    // trials are planned and refused on their memory (a doubling counter once wrapped to
    // 0 and aborted); 1e13 is read as the number it is; a negative count is named as
    // such, not taken for an option.
    for (trials, expected) in [
        (
            "0",
            "0 trials are too few for a 0.95 coverage interval: use at least 20",
        ),
        ("1", "1 trials are too few"),
        ("2", "2 trials are too few"),
        (
            "9223372036854775808",
            "9223372036854775808 trials of 71 outputs need about ",
        ),
        (
            "18446744073709551615",
            "18446744073709551615 trials of 71 outputs need about ",
        ),
        ("1e13", "10000000000000 trials of 71 outputs need about "),
    ] {
        let message = monte_carlo_refusal(trials, &[]);
        assert!(
            message.starts_with(&format!("{EXAMPLE}: Monte Carlo failed: {expected}")),
            "{trials}: {message}"
        );
    }
    for (trials, why) in [
        ("-1", "\"-1\": a number of trials is not negative"),
        ("1e20", "\"1e20\": more than 18446744073709551615 trials"),
    ] {
        let message = monte_carlo_refusal(trials, &[]);
        assert!(message.contains(why), "{trials}: {message}");
    }
    // the adaptive procedure needs room for two sequences of 10 000 trials at p = 0.95
    for (max, expected) in [
        (
            "0",
            "the adaptive procedure may run at most 0 trials, fewer than the 20000 of two sequences",
        ),
        (
            "19999",
            "the adaptive procedure may run at most 19999 trials, fewer than the 20000 of two sequences",
        ),
        (
            "18446744073709551615",
            "18446744073709551615 trials of 71 outputs need about ",
        ),
    ] {
        let message = monte_carlo_refusal("adaptive", &["--mc-max-trials", max]);
        assert!(
            message.starts_with(&format!("{EXAMPLE}: Monte Carlo failed: {expected}")),
            "{max}: {message}"
        );
    }
}

#[test]
fn a_selfcal_bound_beyond_a_reading_is_refused_not_printed_as_inf() {
    // 1e160 once gave every u and U as inf with status 0: a bound on the lost harmonics
    // or on the heads' angles is an angle, within a reading's range (0 … 1e6″).
    for (option, value, shown) in [
        ("--lost-harmonic-bound", "1e160", "1e160"),
        ("--lost-harmonic-bound", "1000001", "1.000001e6"),
        ("--head-angle-u", "1e300", "1e300"),
        ("--head-angle-u", "-0.5", "−0.5"),
    ] {
        let message = one_error_line(&polycal(&["selfcal", SELFCAL, option, value]));
        assert!(
            message.starts_with(&format!("{option}: ")),
            "{option} {value}: {message}"
        );
        assert!(
            message.ends_with(&format!(
                "must be a number from 0 to 1e6 arcsec (the range of a reading), not {shown}"
            )),
            "{option} {value}: {message}"
        );
    }
    let out = polycal(&["selfcal", SELFCAL, "--lost-harmonic-bound", "1e6"]);
    assert_eq!(out.status.code(), Some(0));
    assert!(!String::from_utf8_lossy(&out.stdout).contains("inf"));
}

#[test]
fn a_line_of_commas_is_refused_within_a_small_memory() {
    // 20 million commas in a header or a row took about 64 bytes of memory per byte
    // (1.3 GB: an abort under a 1 GB limit); refused at the 1024th comma now (the 1025th
    // field), with the file held once: under a 200 MB address-space limit. Columns by
    // hand: the header's 1024th comma is character 1024; the row `1,0,1,1,0.5` has 11
    // characters and 4 commas, so its 1024th is character 11 + 1020 = 1031; the
    // self-calibration header has 34 characters and 4 commas: 34 + 1020 = 1054.
    let dir = temp_dir("commas");
    let commas = ",".repeat(20_000_000);
    let cases = [
        (
            "header.csv",
            "solve",
            format!("# a comment, with, commas\n{commas}\n"),
            "2:1024",
        ),
        (
            "row.csv",
            "solve",
            format!("cycle,step,ac,face,reading\n1,0,1,1,0.5{commas}\n"),
            "2:1031",
        ),
        (
            "selfcal-header.csv",
            "selfcal",
            format!("cycle,step,head,head_angle,reading{commas}\n"),
            "1:1054",
        ),
    ];
    for (name, command, text, at) in cases {
        let path = write(&dir, name, &text);
        let message = one_error_line(&polycal_under_ulimit_v(200_000, &[command, &path]));
        assert_eq!(
            message,
            format!(
                "{path}:{at}: a line of more than 1024 fields; polycal's CSV files have a few \
                 columns (docs/FORMAT.md §2.2)"
            )
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

mod not_utf8_arguments {
    //! Every command's path arguments, given names that are not UTF-8 (bytes 0x80 … 0xFF
    //! of Latin-1 and others, drawn by proptest): no command may panic (status 101); it
    //! reads, writes or refuses the file with its usual statuses.
    use std::ffi::{OsStr, OsString};
    use std::os::unix::ffi::{OsStrExt, OsStringExt};
    use std::path::{Path, PathBuf};
    use std::process::Command;

    use proptest::prelude::*;

    use super::{BUDGET, EXAMPLE, EXAMPLE_TRUTH, SELFCAL};

    /// A command line with `@` where the drawn path goes, and the repository file copied
    /// to that path first, or `text:` and the text written there (`None`: the path is an
    /// output, or names nothing). The designs planned are of one bare cycle (dof 0), which
    /// are planned in milliseconds.
    const LINES: &[(&[&str], Option<&str>)] = &[
        (&["solve", "@"], Some(EXAMPLE)),
        (&["solve", EXAMPLE, "--budget", "@"], Some(BUDGET)),
        (&["solve", EXAMPLE, "--plot", "@"], None),
        (&["diagnose", "@"], Some(EXAMPLE)),
        (&["diagnose", EXAMPLE, "--truth", "@"], Some(EXAMPLE_TRUTH)),
        (
            &["diagnose", EXAMPLE, "--budget", "@", "--format", "csv"],
            Some(BUDGET),
        ),
        (&["diagnose", EXAMPLE, "--plot", "@"], None),
        (&["selfcal", "@"], Some(SELFCAL)),
        (&["selfcal", SELFCAL, "--plot", "@"], None),
        (
            &[
                "compare",
                "@",
                "examples/data/polygon24-shift-angle.result.csv",
            ],
            Some("examples/data/polygon24-shift-angle.result.csv"),
        ),
        (
            &["budget", "@"],
            Some("examples/budgets/gum-h1-end-gauge.toml"),
        ),
        (
            &["plan", "@", "--sigma", "0.05"],
            Some("tests/fixtures/expected/sim-bare.file.bare.csv"),
        ),
        (
            &["plan", "--sigma", "0.05", "--designs", "@"],
            Some("text:[[design]]\nfaces = 8\n"),
        ),
        (
            &[
                "plan", "--sigma", "0.05", "--faces", "8", "--cycles", "1", "--plot", "@",
            ],
            None,
        ),
        (&["report", "@", "--out", "@.html"], Some(EXAMPLE)),
        (&["report", EXAMPLE, "--out", "@"], None),
        (
            &[
                "report", EXAMPLE, "--budget", BUDGET, "--meta", "@", "--dcc", "@.xml",
            ],
            Some("examples/report/meta.toml"),
        ),
        (
            &["report", EXAMPLE, "--run-dir", "@", "--out", "@.html"],
            None,
        ),
        (&["simulate", "--out", "@", "--truth-out", "@.json"], None),
        (&["simulate", "--selfcal", "--out", "@"], None),
        (
            &[
                "run",
                "--ac1",
                "@",
                "--ac2",
                "@",
                "--table",
                "@",
                "--out",
                "@.run",
                "--timeout",
                "0.1",
            ],
            None,
        ),
        (&["sim-lab", "--truth-out", "@"], None),
        (&["completions", "bash"], None),
    ];

    fn not_utf8_name() -> impl Strategy<Value = Vec<u8>> {
        // a name of 1 … 12 bytes, one of them at least not UTF-8, never `/` or NUL
        (
            proptest::collection::vec(1u8..=255, 0..8),
            0x80u8..=0xff,
            proptest::collection::vec(1u8..=255, 0..4),
        )
            .prop_map(|(head, bad, tail)| {
                let mut name: Vec<u8> = head.into_iter().chain([bad]).chain(tail).collect();
                name.retain(|&b| b != b'/');
                if std::str::from_utf8(&name).is_ok() {
                    name.push(0xff);
                }
                name
            })
    }

    fn run(dir: &Path, name: &[u8], line: &[&str], copy: Option<&str>) -> std::process::Output {
        let path = dir.join(OsStr::from_bytes(name));
        let _ = std::fs::remove_dir_all(&path);
        let _ = std::fs::remove_file(&path);
        match copy.map(|c| (c, c.strip_prefix("text:"))) {
            Some((_, Some(text))) => std::fs::write(&path, text).expect("write"),
            Some((from, None)) => {
                std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join(from), &path)
                    .map(|_| ())
                    .expect("copy")
            }
            None => {}
        }
        let args: Vec<OsString> = line
            .iter()
            .map(|a| match a.strip_prefix('@') {
                Some(suffix) => {
                    let mut bytes = path.as_os_str().as_bytes().to_vec();
                    bytes.extend_from_slice(suffix.as_bytes());
                    OsString::from_vec(bytes)
                }
                None => OsString::from(a),
            })
            .collect();
        // standard input a pipe closed at once: `sim-lab` then ends (with /dev/null it
        // serves until killed)
        let child = Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("the binary runs");
        child.wait_with_output().expect("the binary ends")
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 6, failure_persistence: None, ..ProptestConfig::default() })]
        #[test]
        fn no_command_panics_on_a_path_that_is_not_utf8(name in not_utf8_name()) {
            let dir: PathBuf = super::temp_dir("not-utf8-args");
            for (line, copy) in LINES {
                let out = run(&dir, &name, line, *copy);
                let stderr = String::from_utf8_lossy(&out.stderr);
                prop_assert!(
                    matches!(out.status.code(), Some(0..=2)) && !stderr.contains("panicked"),
                    "{line:?} with {name:?}: {:?}\n{stderr}",
                    out.status
                );
            }
        }
    }
}

#[test]
fn a_long_monte_carlo_shows_its_progress_and_ends_within_a_second_of_ctrl_c() {
    // 10⁹ trials take hours: on a pseudo-terminal (util-linux `script`) the bar shows the
    // trials and the time left after a second; Ctrl-C (SIGINT from `timeout` after 3 s)
    // ends the process within a second of it.
    let started = std::time::Instant::now();
    let out = Command::new("script")
        .args([
            "-qec",
            &format!(
                "timeout -s INT 3 {} solve {EXAMPLE} --budget {BUDGET} --monte-carlo 1e9",
                env!("CARGO_BIN_EXE_polycal")
            ),
            "/dev/null",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::null())
        .output()
        .expect("script (util-linux) runs");
    let elapsed = started.elapsed();
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(
        shown.contains("Monte Carlo [") && shown.contains("/1000000000 trials · "),
        "no progress bar:\n{shown}"
    );
    assert!(
        shown.contains(" left"),
        "no estimate of the time left:\n{shown}"
    );
    assert!(
        elapsed < std::time::Duration::from_secs(4),
        "ended {elapsed:?} after its start, 3 s of it before Ctrl-C"
    );
}
