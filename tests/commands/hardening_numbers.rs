//! Hardening (issue 13), numbers: numbers that are finite but absurd are refused at their
//! file, line and column — in a measurement file, a self-calibration file, a result file, a
//! truth file, a budget, an option — and the extreme ones that are not are computed and
//! written right, never `inf` (budgets of u = 1e90, an infinite F). Each class is tried
//! with its own bad input, through the binary as a user meets it. The limits are
//! docs/FORMAT.md §2.2; the positions and the arithmetic below are derived by hand from
//! the texts written here.

use std::path::Path;

use crate::hardening_support::{
    EXAMPLE, EXAMPLE_TRUTH, SELFCAL, one_error_line, polycal, temp_dir, write,
};

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
