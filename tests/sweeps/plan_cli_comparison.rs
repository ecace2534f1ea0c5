//! `polycal plan` (docs/FORMAT.md §5.6) on several designs, as a user runs it, end to end
//! through the binary: the designs planned in order and compared, `--target-u`'s fewest
//! cycles, and the comparison's cycles the target needs and the time they take. Every
//! expected number comes from outside the command: the paper's closed form, the duration
//! of a run by hand, or other runs of `plan` itself with other cycles (for `--target-u`)
//! — never from the output of the run under test recorded as "expected".

use std::path::Path;

use crate::plan_cli_support::{f64s, json_lines, json_one, polycal, stderr, stdout};

const DESIGNS: &str = "examples/designs.toml";

/// 4. Several designs: one JSON line each, in order, with the changes of each `--design`
///    applied; the table prints one line per design; a designs file gives its designs.
#[test]
fn several_designs_are_planned_in_order_and_compared() {
    let args = [
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "name=A",
        "--design",
        "name=B;ac-faces=1,2,5;cycles=3",
        "--closing",
        "--format",
        "json",
    ];
    let lines = json_lines(&args, 0);
    assert_eq!(lines.len(), 2, "two JSON lines");
    assert_eq!(lines[0]["name"], "A");
    assert_eq!(lines[1]["name"], "B");
    // A is the design of the options; B changes its autocollimators and cycles
    assert_eq!(lines[0]["design"]["ac_faces"], serde_json::json!([1, 2]));
    assert_eq!(lines[0]["design"]["cycles"], 6);
    assert_eq!(lines[1]["design"]["ac_faces"], serde_json::json!([1, 2, 5]));
    assert_eq!(lines[1]["design"]["cycles"], 3);
    for line in &lines {
        assert_eq!(line["design"]["closing"], true);
        assert!(line["version"].is_string());
    }
    // readings by hand: autocollimators × (24 stops + the closing one) × cycles
    assert_eq!(lines[0]["readings"], 2 * 25 * 6);
    assert_eq!(lines[1]["readings"], 3 * 25 * 3);

    let out = polycal(&args[..args.len() - 2]);
    assert_eq!(out.status.code(), Some(0), "table: {}", stderr(&out));
    let table = stdout(&out);
    for name in ["A", "B"] {
        let rows: Vec<&str> = table.lines().filter(|l| l.starts_with(name)).collect();
        assert_eq!(rows.len(), 1, "one line for design {name}:\n{table}");
    }

    // the designs file: its names, in its order
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(DESIGNS))
        .expect("the example designs file");
    let file: toml::Table = text.parse().expect("the example designs file is TOML");
    let tables = file["design"].as_array().expect("[[design]] tables");
    let names: Vec<&str> = tables
        .iter()
        .map(|d| d["name"].as_str().expect("a name"))
        .collect();
    assert_eq!(names.len(), 4);
    let lines = json_lines(
        &[
            "plan",
            "--sigma",
            "0.05",
            "--designs",
            DESIGNS,
            "--format",
            "json",
        ],
        0,
    );
    assert_eq!(lines.len(), 4, "four JSON lines");
    for ((line, name), table) in lines.iter().zip(&names).zip(tables) {
        assert_eq!(line["name"], *name);
        let cycles = table
            .get("cycles")
            .and_then(toml::Value::as_integer)
            .unwrap_or(6);
        assert_eq!(line["design"]["cycles"], cycles, "{name}: cycles");
    }
    let out = polycal(&["plan", "--sigma", "0.05", "--designs", DESIGNS]);
    assert_eq!(out.status.code(), Some(0), "table: {}", stderr(&out));
    let table = stdout(&out);
    for name in &names {
        let rows = table.lines().filter(|l| l.starts_with(name)).count();
        assert_eq!(rows, 1, "one line for design {name:?}:\n{table}");
    }
}

/// The largest u(α) of the paper's design with closing readings and `cycles` cycles.
fn largest_u_alpha(cycles: u64) -> f64 {
    let cycles = cycles.to_string();
    let json = json_one(
        &[
            "plan",
            "--sigma",
            "0.05",
            "--closing",
            "--cycles",
            &cycles,
            "--format",
            "json",
        ],
        0,
    );
    f64s(&json["encoder_error_u"], "encoder_error_u")
        .into_iter()
        .fold(f64::NEG_INFINITY, f64::max)
}

/// 5. `--target-u`: the cycles found are the fewest, checked by planning them and one
///    fewer.
#[test]
fn target_u_finds_the_fewest_cycles() {
    let json = json_one(
        &[
            "plan",
            "--sigma",
            "0.05",
            "--target-u",
            "0.02",
            "--closing",
            "--format",
            "json",
        ],
        0,
    );
    let target = &json["target"];
    assert_eq!(target["encoder_error_u"], 0.02);
    let c = target["cycles"].as_u64().expect("the target is reached");
    assert!(c >= 2, "more than one cycle is needed here: {c}");
    let with_c = largest_u_alpha(c);
    let with_fewer = largest_u_alpha(c - 1);
    assert!(with_c <= 0.02, "{c} cycles: largest u(α) {with_c}");
    assert!(
        with_fewer > 0.02,
        "{} cycles: largest u(α) {with_fewer}",
        c - 1
    );
    let reached = target["reached_u"].as_f64().expect("reached_u");
    assert!(
        (reached - with_c).abs() <= 1e-12 * with_c,
        "reached_u {reached}, the largest u(α) with {c} cycles {with_c}"
    );
}

/// The stops of a run of the paper's design without closing readings, by hand: every
/// cycle stops at the N steps, one stop every `step_seconds` (20 s by default), the
/// first at time 0; so a run of R cycles lasts (R·N − 1)·20 s from the first stop to the
/// last.
fn hand_duration_seconds(faces: u64, cycles: u64) -> f64 {
    (cycles * faces - 1) as f64 * 20.0
}

/// The fewest cycles of the paper's design (two adjacent autocollimators, no closing
/// readings) with u(α) ≤ u: u(α) = σ·√((N² − 1)/(6·N·R)) for every position, so
/// R = ⌈(N² − 1)/(6·N)·(σ/u)²⌉.
fn hand_cycles(faces: u64, sigma: f64, u: f64) -> u64 {
    let n = faces as f64;
    ((n * n - 1.0) / (6.0 * n) * (sigma / u).powi(2)).ceil() as u64
}

/// 9. The comparison names the cycles planned and the cycles the target needs, with the
///    time each takes, all by hand: 72 faces need 75 cycles for u(α) ≤ 0.02″ at
///    σ = 0.05″ ((72² − 1)/(6·72)·2.5² = 74.99), a run of (75·72 − 1)·20 s = 29.99 h;
///    24 faces need 25 cycles (24.96), 3.33 h. Every column has its legend line.
#[test]
fn the_comparison_shows_the_cycles_the_target_needs_and_their_time() {
    assert_eq!(hand_cycles(72, 0.05, 0.02), 75);
    assert_eq!(hand_cycles(24, 0.05, 0.02), 25);
    let args = [
        "plan",
        "--sigma",
        "0.05",
        "--faces",
        "72",
        "--design",
        "name=N72",
        "--design",
        "name=N24;faces=24",
        "--target-u",
        "0.02",
    ];
    let mut json_args = args.to_vec();
    json_args.extend(["--format", "json"]);
    let lines = json_lines(&json_args, 0);
    for (line, faces) in lines.iter().zip([72u64, 24]) {
        let cycles = hand_cycles(faces, 0.05, 0.02);
        let target = &line["target"];
        assert_eq!(target["cycles"], cycles, "{faces} faces");
        assert_eq!(target["readings"], 2 * faces * cycles, "{faces} faces");
        let seconds = target["duration_seconds"].as_f64().expect("a duration");
        assert!(
            (seconds - hand_duration_seconds(faces, cycles)).abs() < 1e-6,
            "{faces} faces: {seconds} s"
        );
        // the planned run is the 6 cycles of the options
        assert_eq!(line["design"]["cycles"], 6);
        let planned = line["duration_seconds"].as_f64().expect("a duration");
        assert!((planned - hand_duration_seconds(faces, 6)).abs() < 1e-6);
    }
    assert!((hand_duration_seconds(72, 75) / 3600.0 - 29.994).abs() < 1e-3);

    let out = polycal(&args);
    assert_eq!(out.status.code(), Some(0), "table: {}", stderr(&out));
    let table = stdout(&out);
    let header: Vec<&str> = table
        .lines()
        .find(|l| l.starts_with("design"))
        .unwrap_or_else(|| panic!("a header line:\n{table}"))
        .split_whitespace()
        .collect();
    assert_eq!(
        header,
        [
            "design",
            "cycles",
            "readings",
            "time",
            "u(β)max",
            "u(α)max",
            "drift″/h",
            "step″",
            "target",
            "cycles",
            "target",
            "time"
        ],
        "{table}"
    );
    for (name, faces) in [("N72", 72u64), ("N24", 24)] {
        let row: Vec<&str> = table
            .lines()
            .find(|l| l.starts_with(name))
            .unwrap_or_else(|| panic!("a row for {name}:\n{table}"))
            .split_whitespace()
            .collect();
        let cycles = hand_cycles(faces, 0.05, 0.02);
        let hours = |s: f64| format!("{:.2}", s / 3600.0);
        assert_eq!(
            (row[1], row[2], row[3], row[4]),
            (
                "6",
                (2 * faces * 6).to_string().as_str(),
                hours(hand_duration_seconds(faces, 6)).as_str(),
                "h"
            ),
            "{name}: {row:?}"
        );
        assert_eq!(
            (row[9], row[10], row[11]),
            (
                cycles.to_string().as_str(),
                hours(hand_duration_seconds(faces, cycles)).as_str(),
                "h"
            ),
            "{name}: {row:?}"
        );
    }
    // a legend line for every column
    for (column, words) in [
        ("cycles:", "planned per mounting"),
        ("u(β)max, u(α)max:", "k = 1"),
        ("drift″/h:", "90 % of runs"),
        ("step″:", "offset step"),
        ("target cycles:", "0.02″"),
        ("target time:", "how long"),
    ] {
        assert!(
            table
                .lines()
                .any(|l| l.contains(column) && l.contains(words)),
            "a legend line with {column:?} and {words:?}:\n{table}"
        );
    }
    assert!(table.contains("0.5 % false alarms per family"), "{table}");
}
