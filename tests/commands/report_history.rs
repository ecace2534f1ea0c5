//! `polycal report --history` (docs/FORMAT.md §10.2, §13.2): the section "History of the
//! standard" holds the numbers `polycal history --format json` gives for the same
//! calibrations, the control chart inline; a run whose values lie on the earlier
//! calibrations' line agrees (χ² = 0, status 0), the same run against calibrations shifted
//! by many U does not (status 1); refusals are one `error:` line with status 2.

use std::path::PathBuf;
use std::process::{Command, Output};

use scraper::{Html, Selector};
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");
const H: &str = "examples/data/history";
const RUN: &str = "examples/data/history/run-2026-11-03.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const META: &str = "examples/report/meta.toml";
const TODAY: &str = "2026-11-03";
const DATES: [&str; 6] = [
    "2019-03-12",
    "2020-03-10",
    "2021-03-02",
    "2022-03-15",
    "2023-03-07",
    "2024-03-05",
];

fn polycal(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env("SOURCE_DATE_EPOCH", "1795000000")
        .output()
        .expect("polycal runs")
}

fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-report-history-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn earlier() -> Vec<String> {
    DATES
        .iter()
        .map(|d| format!("{H}/{}.csv@{d}", &d[..4]))
        .collect()
}

/// The report of `RUN` with `history` as its earlier calibrations: its status and HTML.
fn report(history: &[String], out: &str) -> (Option<i32>, Html, String) {
    let mut args = vec![
        "report", RUN, "--budget", BUDGET, "--meta", META, "--out", out,
    ];
    for h in history {
        args.extend(["--history", h.as_str()]);
    }
    let output = polycal(&args);
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    let html = std::fs::read_to_string(out).unwrap_or_else(|_| panic!("{stderr}"));
    (output.status.code(), Html::parse_document(&html), stderr)
}

fn json(args: &[&str]) -> Value {
    let out = polycal(args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

/// The `data-value` of the cells of the history table's column `column` (0 = drift).
fn column(html: &Html, column: usize) -> Vec<f64> {
    let rows = Selector::parse("#history-faces tbody tr").unwrap();
    let cells = Selector::parse("td.num").unwrap();
    html.select(&rows)
        .map(|row| {
            let cell = row.select(&cells).nth(column).expect("the cell");
            cell.value()
                .attr("data-value")
                .expect("data-value")
                .parse()
                .unwrap()
        })
        .collect()
}

fn text(html: &Html, selector: &str) -> String {
    let s = Selector::parse(selector).unwrap();
    html.select(&s)
        .next()
        .map(|e| e.text().collect())
        .unwrap_or_default()
}

fn close(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            (x - y).abs() <= 1e-9 * (1.0 + y.abs()),
            "{what} face {}: {x} vs {y}",
            k + 1
        );
    }
}

fn numbers(v: &Value, key: &str) -> Vec<f64> {
    v[key]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// The bundled example: the section's drift is `polycal history`'s of the six files and
/// the run's result file (`solve --budget --format csv`, dated 2026-11-03), its prediction
/// that of the six alone at 2026-11-03, every file listed with its SHA-256, the chart
/// inline; the run agrees (status 0).
#[test]
fn report_history_numbers_are_those_of_polycal_history() {
    let dir = scratch();
    let out = dir.join("bundled.html");
    let (status, html, stderr) = report(&earlier(), out.to_str().unwrap());
    assert_eq!(status, Some(0), "{stderr}");
    let result = polycal(&["solve", RUN, "--budget", BUDGET, "--format", "csv"]);
    let today = dir.join("today.csv");
    std::fs::write(&today, &result.stdout).unwrap();
    let today_arg = format!("{}@{TODAY}", today.display());
    let mut all: Vec<String> = earlier();
    all.push(today_arg);
    let mut args: Vec<&str> = vec!["history"];
    args.extend(all.iter().map(String::as_str));
    args.extend(["--at", TODAY, "--format", "json"]);
    let full = json(&args);
    let mut args: Vec<&str> = vec!["history"];
    let six = earlier();
    args.extend(six.iter().map(String::as_str));
    args.extend(["--at", TODAY, "--format", "json"]);
    let prior = json(&args);
    close(&column(&html, 0), &numbers(&full, "drift"), "drift");
    close(&column(&html, 1), &numbers(&full, "drift_u"), "u(drift)");
    close(
        &column(&html, 2),
        &numbers(&prior, "predicted"),
        "predicted",
    );
    let expanded: Vec<f64> = numbers(&prior, "predicted_u")
        .iter()
        .map(|u| 2.0 * u)
        .collect();
    close(&column(&html, 3), &expanded, "U(predicted)");
    let model = Selector::parse("#history-model").unwrap();
    let model = html.select(&model).next().expect("the model statement");
    assert_eq!(model.value().attr("data-model"), full["model"].as_str());
    assert!(text(&html, "#history-model").contains(&format!(
        "χ² = {:.2}",
        full["vector"]["chi2"].as_f64().unwrap()
    )));
    // every calibration with its file's SHA-256
    let rows = Selector::parse("#history-calibrations tbody tr").unwrap();
    let listed: Vec<String> = html.select(&rows).map(|r| r.text().collect()).collect();
    assert_eq!(listed.len(), 7);
    for (row, date) in listed.iter().zip(DATES) {
        let bytes = std::fs::read(format!("{H}/{}.csv", &date[..4])).unwrap();
        assert!(
            row.contains(date) && row.contains(&polycal::certificate::sha256_hex(&bytes)),
            "{row}"
        );
    }
    assert!(listed[6].contains(TODAY) && listed[6].contains("this calibration"));
    let chart = Selector::parse("section#history figure svg g.position").unwrap();
    assert_eq!(html.select(&chart).count(), 24, "the control charts inline");
    assert!(text(&html, "#history-verdict").starts_with("This calibration agrees"));
}

/// Earlier calibrations written here on a straight line through the run's own values
/// (a closed drift pattern of 0.2″ a year, found by the drift test; u = 0.05″): the prediction is the run's value, every
/// difference 0, the run agrees (status 0). The same calibrations with +1″ on face 1 and
/// −1″ on face 2 (about 6 U(a − b)) predict a value the run does not agree with: the
/// failing statement, status 1.
#[test]
fn report_history_agreement_decides_the_status() {
    let dir = scratch();
    let result = polycal(&["solve", RUN, "--budget", BUDGET, "--format", "json"]);
    let solve: Value = serde_json::from_slice(&result.stdout).unwrap();
    let beta: Vec<f64> = solve["pitch_deviation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(beta.len(), 24);
    let write = |shift: f64| -> Vec<String> {
        // days before 2026-11-03, counted by hand (2024 a leap year)
        [
            ("2022-11-03", 1461.0),
            ("2023-11-03", 1096.0),
            ("2024-11-03", 730.0),
        ]
        .iter()
        .map(|(date, days)| {
            let years = days / 365.25;
            let mut csv = String::from("quantity,index,value,u\n");
            for (k, b) in beta.iter().enumerate() {
                let drift = 0.2 * (2.0 * std::f64::consts::PI * (k + 1) as f64 / 24.0).cos();
                let offset = match k {
                    0 => shift,
                    1 => -shift,
                    _ => 0.0,
                };
                csv.push_str(&format!(
                    "pitch_deviation,{},{},0.05\n",
                    k + 1,
                    b - drift * years + offset
                ));
            }
            let path = dir.join(format!("line-{shift}-{date}.csv"));
            std::fs::write(&path, csv).unwrap();
            format!("{}@{date}", path.display())
        })
        .collect()
    };
    let out = dir.join("agrees.html");
    let (status, html, stderr) = report(&write(0.0), out.to_str().unwrap());
    assert_eq!(status, Some(0), "{stderr}");
    assert!(
        text(&html, "#history-verdict").contains("χ² = 0.00 ≤"),
        "{}",
        text(&html, "#history-verdict")
    );
    for en in column(&html, 8) {
        assert!(en.abs() < 1e-6, "{en}");
    }
    let out = dir.join("disagrees.html");
    let (status, html, stderr) = report(&write(1.0), out.to_str().unwrap());
    assert_eq!(status, Some(1), "{stderr}");
    let verdict = text(&html, "#history-verdict");
    assert!(
        verdict.starts_with("This calibration does NOT agree"),
        "{verdict}"
    );
    assert!(text(&html, "#verdict").contains("history: This calibration does NOT agree"));
    assert!(
        stderr.contains("the history: This calibration does NOT agree"),
        "{stderr}"
    );
}

/// One `error:` line with status 2, and no report written.
fn refused(args: &[&str]) -> String {
    let out = polycal(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    lines[0].to_string()
}

/// A file that is not a result, a result without @DATE, a calibration not before the
/// run's day, no budget, no date_of_measurement: refused, naming the file.
#[test]
fn report_history_refusals() {
    let dir = scratch();
    let out = dir.join("refused.html");
    let out = out.to_str().unwrap();
    let bad = dir.join("bad.csv");
    std::fs::write(
        &bad,
        "quantity,index,value,u\npitch_deviation,1,zero,0.05\n",
    )
    .unwrap();
    let bad_arg = format!("{}@2020-01-01", bad.display());
    let base = [
        "report", RUN, "--budget", BUDGET, "--meta", META, "--out", out,
    ];
    let line = refused(
        &[
            &base[..],
            &["--history", &bad_arg, "--history", &earlier()[0]],
        ]
        .concat(),
    );
    assert!(line.contains("bad.csv:2:"), "{line}");
    let undated = format!("{H}/2019.csv");
    let line = refused(
        &[
            &base[..],
            &["--history", &undated, "--history", &earlier()[1]],
        ]
        .concat(),
    );
    assert!(
        line.contains("2019.csv") && line.contains("FILE@DATE"),
        "{line}"
    );
    let late = format!("{H}/2024.csv@2027-01-01");
    let line = refused(&[&base[..], &["--history", &late, "--history", &earlier()[1]]].concat());
    assert!(
        line.contains("2024.csv") && line.contains("not before"),
        "{line}"
    );
    let e = earlier();
    let line = refused(&[
        "report",
        RUN,
        "--meta",
        META,
        "--out",
        out,
        "--history",
        &e[0],
        "--history",
        &e[1],
    ]);
    assert!(line.contains("--budget"), "{line}");
    let line = refused(&[
        "report",
        "examples/data/polygon24-2ac-6cycles.csv",
        "--budget",
        BUDGET,
        "--out",
        out,
        "--history",
        &e[0],
        "--history",
        &e[1],
    ]);
    assert!(line.contains("date_of_measurement"), "{line}");
    assert!(!std::path::Path::new(out).exists());
}
