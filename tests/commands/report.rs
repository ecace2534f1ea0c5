//! `polycal report` (docs/FORMAT.md §10): the HTML parses without a single HTML5 parse
//! error; every number it shows is the number the JSON commands print (`solve`,
//! `diagnose`, `compare`, `selfcal`), shown rounded (a result as GUM 7.2.6 states it);
//! no document names a directory; printed, every page carries "Page i of n" and the
//! certificate number; each section is there exactly when
//! asked for; missing metadata is shown as missing; the SHA-256 of every input equals
//! an independent computation (coreutils' `sha256sum`); the status follows the verdicts.

use std::path::{Path, PathBuf};
use std::process::Command;

use scraper::{ElementRef, Html, Selector};
use serde_json::Value;

const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";
const TRUTH: &str = "examples/data/polygon24-2ac-6cycles.truth.json";
const BUDGET: &str = "examples/budgets/instrument.toml";
const REFERENCE: &str = "examples/data/polygon24-shift-angle.result.csv";
const META: &str = "examples/report/meta.toml";

use crate::document_support;
use crate::skip_support;

use crate::document_support::{assert_gum_rounded, assert_k_rounded, json, polycal};

fn temp_dir(name: &str) -> PathBuf {
    document_support::temp_dir("report", name)
}

/// Runs `polycal report … --out DIR/report.html`; returns the status and the parsed
/// document, after asserting it has no HTML5 parse error.
fn report(dir: &Path, args: &[&str]) -> (Option<i32>, Html, String) {
    let out_path = dir.join("report.html");
    let mut all: Vec<&str> = vec!["report"];
    all.extend_from_slice(args);
    let out_text = out_path.to_str().unwrap().to_string();
    all.extend_from_slice(&["--out", &out_text]);
    let out = polycal(&all);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{args:?}: {stderr}"
    );
    let text = std::fs::read_to_string(&out_path).unwrap();
    let html = Html::parse_document(&text);
    assert!(
        html.errors.is_empty(),
        "HTML parse errors: {:?}",
        html.errors
    );
    (out.status.code(), html, text)
}

fn select<'a>(html: &'a Html, css: &str) -> Vec<ElementRef<'a>> {
    let selector = Selector::parse(css).unwrap();
    html.select(&selector).collect()
}

/// The numeric cells of column `column` (0-based, among all cells) of table `id`'s body.
fn column(html: &Html, id: &str, column: usize) -> Vec<(Option<f64>, String)> {
    select(html, &format!("table#{id} > tbody > tr"))
        .into_iter()
        .map(|row| {
            let cell = row
                .select(&Selector::parse("td").unwrap())
                .nth(column)
                .unwrap_or_else(|| panic!("{id}: no column {column}"));
            let value = cell.value().attr("data-value").map(|v| v.parse().unwrap());
            (value, cell.text().collect::<String>())
        })
        .collect()
}

/// The text a report shows for `value` at `decimals`: rounded, with a true minus sign.
fn shown(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        return text.trim_start_matches('-').to_string();
    }
    text.replace('-', "−")
}

/// Every cell of the column equals the JSON array exactly, and shows it rounded.
fn assert_column(html: &Html, id: &str, col: usize, expected: &Value, decimals: usize) {
    let cells = column(html, id, col);
    let expected = expected
        .as_array()
        .unwrap_or_else(|| panic!("{id}: {expected}"));
    assert_eq!(cells.len(), expected.len(), "{id} column {col}");
    for (i, ((value, text), want)) in cells.iter().zip(expected).enumerate() {
        match want.as_f64() {
            Some(want) => {
                assert_eq!(*value, Some(want), "{id}[{i}] column {col}");
                assert_eq!(text, &shown(want, decimals), "{id}[{i}] column {col}");
            }
            None => assert_eq!(text, "—", "{id}[{i}] column {col}: null"),
        }
    }
}

/// Asserts that table `id`'s result columns from `col` — value, u, U, k — carry
/// `json`'s `key`, `key_u` (with a budget `uncertainty.key.u`, the u_c behind U), `key_U`
/// and `key_k`: each `data-value` the JSON's number, the
/// text as GUM 7.2.6 states it, checked from its definition (docs/FORMAT.md §10.4).
fn assert_results(html: &Html, id: &str, col: usize, json: &Value, key: &str) {
    let values_of = |suffix: &str| json[format!("{key}{suffix}")].as_array().cloned();
    let field = |suffix: &str| {
        values_of(suffix)
            .unwrap_or_else(|| panic!("{key}{suffix}"))
            .iter()
            .map(Value::as_f64)
            .collect::<Vec<_>>()
    };
    let cells: Vec<Vec<(Option<f64>, String)>> =
        (col..col + 4).map(|c| column(html, id, c)).collect();
    let (values, u) = (field(""), field("_u"));
    assert_eq!(cells[0].len(), values.len(), "{id}");
    if values_of("_U").is_none() {
        // without a budget: value and u (type A) as GUM 7.2.6 states a result with its
        // standard uncertainty; no U, no k
        for i in 0..values.len() {
            let at = format!("{id}[{i}]");
            assert_eq!(cells[0][i].0, values[i], "{at}: data-value");
            assert_eq!(cells[1][i].0, u[i], "{at}: data-value of u");
            match (values[i], u[i]) {
                (Some(value), Some(u)) if u > 0.0 => {
                    assert_gum_rounded(&cells[0][i].1, &cells[1][i].1, value, u, &at);
                }
                _ => assert_eq!(values[i], Some(0.0), "{at}"),
            }
            assert_eq!((cells[2][i].1.as_str(), cells[3][i].1.as_str()), ("—", "—"));
        }
        return;
    }
    // with a budget, the u beside U and k is the budget's combined u_c (U = k·u_c,
    // docs/FORMAT.md §10), not the fit's own `key_u`; without one (a self-calibration's
    // U = k·u) the u U is formed from
    let u: Vec<Option<f64>> = json["uncertainty"][key]["u"]
        .as_array()
        .map_or(u, |c| c.iter().map(Value::as_f64).collect());
    let (expanded, k) = (field("_U"), field("_k"));
    for i in 0..values.len() {
        let at = format!("{id}[{i}]");
        for (c, want) in [values[i], u[i], expanded[i], k[i]].iter().enumerate() {
            assert_eq!(cells[c][i].0, *want, "{at} column {}: data-value", col + c);
        }
        let (Some(value), Some(u), Some(expanded), Some(k)) = (values[i], u[i], expanded[i], k[i])
        else {
            // φ[N] = 0 by definition: no uncertainty
            assert_eq!(values[i], Some(0.0), "{at}: a number missing");
            continue;
        };
        if expanded == 0.0 {
            assert_eq!((cells[0][i].1.as_str(), cells[2][i].1.as_str()), ("0", "0"));
            continue;
        }
        assert_gum_rounded(&cells[0][i].1, &cells[2][i].1, value, expanded, &at);
        assert_k_rounded(&cells[3][i].1, k, &at);
        // u: two significant digits, rounded up
        let shown_u = document_support::shown_number(&cells[1][i].1);
        let places = cells[1][i]
            .1
            .split_once('.')
            .map_or(0, |(_, d)| d.len() as i32);
        assert!(
            shown_u >= u * (1.0 - 1e-12) && shown_u - u < 10f64.powi(-places) * (1.0 + 1e-9),
            "{at}: u {} of {u}",
            cells[1][i].1
        );
    }
}

/// The largest number of a JSON array.
fn largest(values: &Value) -> f64 {
    values
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .fold(0.0, f64::max)
}

/// The U a budget table ends with (its footer's last number).
fn budget_u(html: &Html, id: &str) -> f64 {
    select(html, &format!("table#{id} tfoot td[data-value]"))
        .last()
        .unwrap()
        .value()
        .attr("data-value")
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn every_number_is_the_jsons_and_every_section_is_there() {
    let dir = temp_dir("full");
    let (status, html, _) = report(
        &dir,
        &[
            DATA,
            "--budget",
            BUDGET,
            "--diagnose",
            "--truth",
            TRUTH,
            "--reference",
            REFERENCE,
            "--meta",
            META,
        ],
    );
    assert_eq!(status, Some(0));
    for id in [
        "details",
        "method",
        "results",
        "budget",
        "figures",
        "diagnosis",
        "comparison",
        "provenance",
        "signatures",
    ] {
        assert_eq!(select(&html, &format!("section#{id}")).len(), 1, "{id}");
    }
    // results: solve --budget's JSON
    let solve = json(&["solve", DATA, "--budget", BUDGET, "--format", "json"]);
    for (id, key) in [
        ("pitch-deviation", "pitch_deviation"),
        ("face-deviation", "face_deviation"),
    ] {
        assert_results(&html, id, 1, &solve, key);
    }
    // α has its angle in the second column
    let angles: Vec<Value> = (0..24).map(|p| Value::from(f64::from(p) * 15.0)).collect();
    assert_column(&html, "encoder-error", 1, &Value::Array(angles), 3);
    assert_results(&html, "encoder-error", 2, &solve, "encoder_error");
    let setup = solve["setup_error"].as_array().unwrap();
    let setup_field = |key: &str| Value::Array(setup.iter().map(|s| s[key].clone()).collect());
    let setup_json = serde_json::json!({
        "setup_error": setup_field("value"),
        "setup_error_u": setup_field("u"),
        "setup_error_U": setup_field("U"),
        "setup_error_k": setup_field("k"),
        "uncertainty": {"setup_error": {"u": solve["uncertainty"]["setup_error"]["u"].clone()}},
    });
    assert_results(&html, "setup-error", 1, &setup_json, "setup_error");
    let fit = column(&html, "fit", 1);
    assert_eq!(fit[1].0, solve["residual_rms"].as_f64());
    // the diagnosis: diagnose --budget --truth's JSON
    let diagnose = json(&[
        "diagnose", DATA, "--budget", BUDGET, "--truth", TRUTH, "--format", "json",
    ]);
    // no effect found in the example run: the final model is the base model, its
    // results not repeated (tests/commands/report_17025.rs)
    assert_eq!(diagnose["effects"].as_array().map(Vec::len), Some(0));
    assert_eq!(select(&html, "#final-model-same").len(), 1);
    let adequacy = select(&html, "#adequacy")[0].text().collect::<String>();
    assert_eq!(
        diagnose["adequate"].as_bool().unwrap(),
        !adequacy.contains("NOT"),
        "{adequacy}"
    );
    let fit = column(&html, "diagnosis-fit", 0);
    assert_eq!(fit[0].0, diagnose["before"]["residual_rms"].as_f64());
    let after_rms = column(&html, "diagnosis-fit", 1);
    assert_eq!(after_rms[0].0, diagnose["after"]["residual_rms"].as_f64());
    // error against the truth, before and after
    assert_eq!(
        column(&html, "diagnosis-fit", 0)[2].0,
        diagnose["error"]["before"]["pitch_rms"].as_f64()
    );
    // the comparison: compare's JSON on solve's result file against the reference
    let result = dir.join("result.csv");
    let out = polycal(&["solve", DATA, "--budget", BUDGET, "--format", "csv"]);
    std::fs::write(&result, &out.stdout).unwrap();
    let compare = json(&[
        "compare",
        result.to_str().unwrap(),
        REFERENCE,
        "--format",
        "json",
    ]);
    let rows = compare["rows"].as_array().unwrap();
    // a and b each with its U as GUM 7.2.6 states a result, a − b beside U(a − b), the
    // En denominator (docs/FORMAT.md §10.2); every data-value compare's number
    for (col, key) in [
        (3, "a"),
        (4, "U_a"),
        (5, "b"),
        (6, "U_b"),
        (7, "difference"),
        (9, "en"),
    ] {
        let cells = column(&html, "comparison-rows", col);
        assert_eq!(cells.len(), rows.len());
        for (i, (value, _)) in cells.iter().enumerate() {
            assert_eq!(*value, rows[i][key].as_f64(), "comparison row {i} {key}");
        }
    }
    for side in [3, 5] {
        let (values, us) = (
            column(&html, "comparison-rows", side),
            column(&html, "comparison-rows", side + 1),
        );
        for ((v, v_text), (u, u_text)) in values.iter().zip(&us) {
            assert_gum_rounded(v_text, u_text, v.unwrap(), u.unwrap(), "comparison");
        }
    }
    for (i, (_, text)) in column(&html, "comparison-rows", 9).iter().enumerate() {
        // |En| ≤ 1 everywhere here: two decimals
        assert_eq!(text, &shown(rows[i]["en"].as_f64().unwrap(), 2), "En {i}");
    }
    let max = compare["max_abs_en"].as_f64().unwrap();
    let verdict = select(&html, "#comparison-verdict")[0]
        .text()
        .collect::<String>();
    assert!(verdict.contains(&shown(max, 2)), "{verdict}");
    // the verdict in the very words of compare's table (docs/FORMAT.md §5.4)
    let table =
        String::from_utf8(polycal(&["compare", result.to_str().unwrap(), REFERENCE]).stdout)
            .unwrap();
    let verdict_line = table
        .lines()
        .find(|l| l.starts_with("Verdict: "))
        .expect("the table states the verdict");
    assert!(
        verdict.starts_with(&format!("{verdict_line}. Largest |En| = ")),
        "{verdict} vs {verdict_line}"
    );
    // the budget: its U is the largest U of the family
    assert_eq!(
        budget_u(&html, "budget-encoder-error"),
        largest(&solve["encoder_error_U"])
    );
    // the figures are the ones --plot writes, inlined
    let plots = dir.join("plots");
    let _ = polycal(&[
        "solve",
        DATA,
        "--budget",
        BUDGET,
        "--plot",
        plots.to_str().unwrap(),
    ]);
    for entry in std::fs::read_dir(&plots).unwrap() {
        let name = entry.unwrap().file_name();
        let stem = name.to_str().unwrap().trim_end_matches(".svg");
        assert_eq!(
            select(&html, &format!("figure#figure-{stem} svg")).len(),
            1,
            "{stem}"
        );
    }
    // metadata from the meta file, with its source by its file name
    assert_eq!(
        select(&html, "#customer")[0].text().collect::<String>(),
        "Example Precision Ltd."
    );
    let operator = select(&html, "tr[data-key=operator] td");
    assert_eq!(operator[0].text().collect::<String>(), "A. Operator");
    assert_eq!(operator[1].text().collect::<String>(), "meta.toml");
    // the new keys, shown: accreditation in the title block, traceability in the method
    assert_eq!(
        select(&html, "#accreditation")[0]
            .text()
            .collect::<String>(),
        "Accredited by Example Accreditation Body (EAB), accreditation number EAB-K-99999-01."
    );
    assert!(
        select(&html, "#traceability")[0]
            .text()
            .collect::<String>()
            .contains("traced to the SI radian")
    );
    let country = select(&html, "tr[data-key=customer_country] td");
    assert_eq!(country[0].text().collect::<String>(), "GB");
    // the environment's quantities are given: no "not given" environment
    assert!(select(&html, "tr[data-key=environment]").is_empty());
    // numeric headings right-aligned over their numbers
    let headings = select(&html, "table#pitch-deviation thead th.num");
    assert_eq!(headings.len(), 4);
}

#[test]
fn without_options_the_optional_sections_are_absent_and_metadata_is_missing() {
    let dir = temp_dir("bare");
    let (status, html, text) = report(&dir, &[DATA]);
    assert_eq!(status, Some(0));
    for id in ["budget", "diagnosis", "comparison"] {
        assert!(select(&html, &format!("section#{id}")).is_empty(), "{id}");
    }
    for id in ["details", "method", "results", "figures", "provenance"] {
        assert_eq!(select(&html, &format!("section#{id}")).len(), 1, "{id}");
    }
    // nothing invented: every field but the ones the file's comments give is missing
    for key in ["operator", "artefact", "approved_by", "traceability"] {
        let cells = select(&html, &format!("tr[data-key={key}] td"));
        assert_eq!(cells[0].text().collect::<String>(), "not given", "{key}");
        assert_eq!(cells[1].text().collect::<String>(), "", "{key}");
    }
    // the certificate number and the customer once, in the title block
    for id in ["certificate", "customer"] {
        assert_eq!(
            select(&html, &format!("#{id}"))[0]
                .text()
                .collect::<String>(),
            "not given"
        );
        assert!(
            select(&html, &format!("tr[data-key={id}]")).is_empty(),
            "{id} twice"
        );
    }
    assert_eq!(
        select(&html, "#instruments")[0].text().collect::<String>(),
        "not given"
    );
    // without a budget: u from the fit, no U, no k
    let solve = json(&["solve", DATA, "--format", "json"]);
    assert_results(&html, "pitch-deviation", 1, &solve, "pitch_deviation");
    // self-contained: nothing fetched, no script
    for needle in ["<script", "<link", "@import", " src=", "href=", "url("] {
        assert!(!text.contains(needle), "{needle}");
    }
}

#[test]
fn comments_of_the_file_are_metadata_and_a_conflict_is_said() {
    let dir = temp_dir("comments");
    let data = dir.join("run.csv");
    let body = std::fs::read_to_string(DATA).unwrap();
    std::fs::write(
        &data,
        format!("# Customer: Other Customer <b>&co</b>\n# Operator: C. Comment\n{body}"),
    )
    .unwrap();
    let (_, html, _) = report(&dir, &[data.to_str().unwrap()]);
    assert_eq!(
        select(&html, "#customer")[0].text().collect::<String>(),
        "Other Customer <b>&co</b>",
        "escaped, shown as text"
    );
    // its source by file name and line (no directory)
    let operator = select(&html, "tr[data-key=operator] td");
    assert_eq!(operator[0].text().collect::<String>(), "C. Comment");
    assert_eq!(operator[1].text().collect::<String>(), "run.csv:2");
    let (_, html, _) = report(&dir, &[data.to_str().unwrap(), "--meta", META]);
    assert_eq!(
        select(&html, "#customer")[0].text().collect::<String>(),
        "Example Precision Ltd."
    );
    let notes: String = select(&html, "#details p.note")
        .iter()
        .map(|n| n.text().collect::<String>())
        .collect();
    assert!(notes.contains("Other Customer"), "{notes}");
    // the operator the meta file also gives: the meta file's, the conflict said
    assert!(notes.contains("C. Comment"), "{notes}");
}

#[test]
fn the_sha256_of_every_input_is_its_own() {
    let dir = temp_dir("sha");
    let (_, html, _) = report(&dir, &[DATA, "--budget", BUDGET, "--meta", META]);
    let rows = select(&html, "table#inputs > tbody > tr");
    assert_eq!(rows.len(), 3);
    for row in rows {
        let cells: Vec<String> = row
            .select(&Selector::parse("td").unwrap())
            .map(|c| c.text().collect())
            .collect();
        // named by its file name alone
        let path = [DATA, BUDGET, META]
            .into_iter()
            .find(|p| Path::new(p).file_name().unwrap().to_str() == Some(cells[1].as_str()))
            .unwrap_or_else(|| panic!("{} is not an input's file name", cells[1]));
        let out = Command::new("sha256sum")
            .arg(path)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("coreutils sha256sum");
        let independent = String::from_utf8(out.stdout).unwrap();
        assert_eq!(cells[3], independent.split_whitespace().next().unwrap());
        let bytes = std::fs::metadata(Path::new(env!("CARGO_MANIFEST_DIR")).join(path))
            .unwrap()
            .len();
        assert_eq!(cells[2], bytes.to_string());
    }
}

#[test]
fn a_failing_comparison_and_an_inadequate_model_give_status_1() {
    let dir = temp_dir("verdicts");
    // the reference with every value 5″ off, +5″ and −5″ in turn (a constant offset alone
    // would be taken out with the mean difference of the closed families, docs/FORMAT.md
    // §5.4)
    let text = std::fs::read_to_string(REFERENCE).unwrap();
    let mut shifted = String::new();
    let mut value_column = None;
    let mut sign = 1.0;
    for line in text.lines() {
        if line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        match value_column {
            None => {
                value_column = fields.iter().position(|f| *f == "value");
                shifted.push_str(line);
            }
            Some(c) => {
                let mut fields: Vec<String> = fields.iter().map(|f| f.to_string()).collect();
                let v: f64 = fields[c].parse().unwrap();
                fields[c] = (v + sign * 5.0).to_string();
                sign = -sign;
                shifted.push_str(&fields.join(","));
            }
        }
        shifted.push('\n');
    }
    let off = dir.join("off.csv");
    std::fs::write(&off, shifted).unwrap();
    let (status, html, _) = report(
        &dir,
        &[
            DATA,
            "--budget",
            BUDGET,
            "--reference",
            off.to_str().unwrap(),
        ],
    );
    assert_eq!(status, Some(1));
    assert!(!select(&html, "table#comparison-rows tr.fail").is_empty());
    assert!(
        select(&html, "#verdict")[0]
            .value()
            .classes()
            .any(|c| c == "fail")
    );

    // structure no effect explains (as tests/commands/cli.rs: a slow wave on
    // autocollimator 2)
    let clean = dir.join("clean.csv");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "6",
        "--closing",
        "--seed",
        "9",
        "--out",
        clean.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let mut set = polycal::measurement::MeasurementSet::read_path(&clean, None).unwrap();
    for r in &mut set.readings {
        if r.ac == 2 {
            r.reading_arcsec +=
                0.8 * (2.0 * std::f64::consts::PI * r.time_seconds.unwrap() / 1500.0).sin();
        }
    }
    let wavy = dir.join("wavy.csv");
    set.write_path(&wavy, &[]).unwrap();
    let (status, html, _) = report(&dir, &[wavy.to_str().unwrap(), "--diagnose"]);
    assert_eq!(status, Some(1));
    let adequacy = select(&html, "#adequacy")[0].text().collect::<String>();
    assert!(adequacy.contains("NOT adequate"), "{adequacy}");
    // and the clean run is adequate: status 0
    let (status, _, _) = report(&dir, &[clean.to_str().unwrap(), "--diagnose"]);
    assert_eq!(status, Some(0));
}

#[test]
fn a_self_calibration_report_shows_the_selfcal_numbers() {
    let dir = temp_dir("selfcal");
    let file = "examples/data/selfa-168.csv";
    let (status, html, _) = report(&dir, &[file, "--budget", "examples/budgets/selfcal.toml"]);
    assert_eq!(status, Some(0));
    let selfcal = json(&[
        "selfcal",
        file,
        "--budget",
        "examples/budgets/selfcal.toml",
        "--format",
        "json",
    ]);
    assert_column(&html, "encoder-error", 1, &selfcal["encoder_angle_deg"], 3);
    assert_results(&html, "encoder-error", 2, &selfcal, "encoder_error");
    // the budget: the largest U(e), its components and the fit's type A
    let largest = largest(&selfcal["encoder_error_U"]);
    assert_eq!(budget_u(&html, "budget-encoder-error"), largest);
    let components = selfcal["uncertainty"]["components"].as_array().unwrap();
    let rows = select(&html, "table#budget-encoder-error > tbody > tr");
    assert_eq!(rows.len(), components.len() + 1);
    let j = selfcal["encoder_error_U"]
        .as_array()
        .unwrap()
        .iter()
        .position(|v| v.as_f64() == Some(largest))
        .unwrap();
    for (row, c) in rows[1..].iter().zip(components) {
        let cell = row.select(&Selector::parse("td").unwrap()).nth(7).unwrap();
        let value: f64 = cell.value().attr("data-value").unwrap().parse().unwrap();
        assert_eq!(value, c["encoder_error"][j].as_f64().unwrap());
    }
    assert_eq!(select(&html, "table#budget-head-error").len(), 1);
    let lost = select(&html, "#lost-harmonics")[0]
        .text()
        .collect::<String>();
    let want: Vec<String> = selfcal["lost_harmonics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|h| h.to_string())
        .collect();
    assert_eq!(lost, want.join(", "));
}

#[test]
fn bad_input_is_one_error_line_with_status_2() {
    let dir = temp_dir("bad");
    let meta = dir.join("meta.toml");
    std::fs::write(&meta, "customer = \"A\"\ncolour = \"red\"\n").unwrap();
    let out_path = dir.join("r.html");
    let out = polycal(&[
        "report",
        DATA,
        "--meta",
        meta.to_str().unwrap(),
        "--out",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with(&format!("error: {}:2:1: ", meta.display())),
        "{stderr}"
    );
    assert!(!out_path.exists(), "no report is written");
    // a comparison without U
    let out = polycal(&[
        "report",
        DATA,
        "--reference",
        REFERENCE,
        "--out",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("--budget"), "{stderr}");
    // a reference with U alone (no u, no k): the comparison's verdict needs u, named by
    // the reference's line (docs/FORMAT.md §5.4)
    let u_alone = dir.join("u-alone.csv");
    std::fs::write(
        &u_alone,
        "quantity,index,value,U\npitch_deviation,1,0.8,0.1\npitch_deviation,2,-0.3,0.1\n",
    )
    .unwrap();
    let out = polycal(&[
        "report",
        DATA,
        "--budget",
        BUDGET,
        "--reference",
        u_alone.to_str().unwrap(),
        "--out",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("u-alone.csv:2: pitch_deviation 1 has U but no standard uncertainty"),
        "{stderr}"
    );
    // an endless stream is read to the limit (256 MiB) and refused, never to the end
    let out = polycal(&["report", "/dev/zero", "--out", out_path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with(
            "error: /dev/zero: at least 268435457 bytes, more than polycal reads from one input"
        ),
        "{stderr}"
    );
    // --out a directory
    let out = polycal(&["report", DATA, "--out", dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(String::from_utf8(out.stderr).unwrap().lines().count(), 1);
}

#[test]
fn source_date_epoch_makes_the_report_reproducible() {
    let dir = temp_dir("epoch");
    let mut texts = Vec::new();
    // twice to the same file (the command line, shown in the report, names it)
    for _ in 0..2 {
        let path = dir.join("a.html");
        let out = Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(["report", DATA, "--budget", BUDGET, "--out"])
            .arg(&path)
            .env("SOURCE_DATE_EPOCH", "1700000000")
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(0));
        texts.push(std::fs::read(&path).unwrap());
    }
    assert!(texts[0] == texts[1], "the same inputs, the same bytes");
    let html = Html::parse_document(std::str::from_utf8(&texts[0]).unwrap());
    // 1 700 000 000 s after 1970-01-01T00:00:00Z (by hand: 19 675 days and 80 000 s)
    assert_eq!(
        select(&html, "#generated")[0].text().collect::<String>(),
        "2023-11-14T22:13:20.000Z"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(["report", DATA, "--out"])
        .arg(dir.join("c.html"))
        .env("SOURCE_DATE_EPOCH", "yesterday")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1);
    assert!(stderr.starts_with("error: SOURCE_DATE_EPOCH"), "{stderr}");
}

/// A run directory's manifest as docs/FORMAT.md §7.3 describes it, written here by hand.
#[test]
fn a_run_directory_gives_the_instruments_and_the_run() {
    let dir = temp_dir("run");
    let run = dir.join("run1");
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(
        run.join("manifest.json"),
        r#"{
  "format": "polycal-run/1",
  "software": "polycal 0.1.0",
  "settings": {"faces": 24, "cycles": 6, "closing": true, "bidirectional": false, "settle_seconds": 2.0},
  "instruments": {"ac1": "ELCOMAT 3000 S/N 4711", "ac2": "ELCOMAT 3000 S/N 4712", "table": "SMC100CC 2.0.0"},
  "ports": {"ac1": "/dev/ttyUSB0", "ac2": "/dev/ttyUSB1", "table": "/dev/ttyUSB2"},
  "started": "2026-11-03T14:05:09.123Z",
  "started_unix": 1793714709.123,
  "ended": "2026-11-03T15:01:00.000Z",
  "outcome": "completed",
  "readings": 300,
  "expected_readings": 300,
  "sessions": []
}"#,
    )
    .unwrap();
    let (_, html, _) = report(&dir, &[DATA, "--run-dir", run.to_str().unwrap()]);
    let instruments: Vec<String> = select(&html, "table#instruments > tbody > tr")
        .iter()
        .map(|r| r.text().collect::<String>())
        .collect();
    assert_eq!(instruments.len(), 3);
    assert!(instruments[0].starts_with("autocollimator 1ELCOMAT 3000 S/N 4711"));
    assert!(instruments[2].contains("SMC100CC 2.0.0"));
    let facts: String = select(&html, "table#run")[0].text().collect();
    for fact in [
        "2026-11-03T14:05:09.123Z",
        "2026-11-03T15:01:00.000Z",
        "completed",
        "cycles = 6",
    ] {
        assert!(facts.contains(fact), "{fact}: {facts}");
    }
    // the run's start date is the date of measurement, its source named
    let date = select(&html, "tr[data-key=date_of_measurement] td");
    assert_eq!(date[0].text().collect::<String>(), "2026-11-03");
    assert_eq!(
        date[1].text().collect::<String>(),
        // by its file name alone (docs/FORMAT.md §10.2)
        "manifest.json (run started)"
    );
    // the manifest is an input: its SHA-256 is listed
    let inputs: String = select(&html, "table#inputs")[0].text().collect();
    assert!(inputs.contains("run manifest"), "{inputs}");
    // a broken manifest: one error line with its position
    std::fs::write(run.join("manifest.json"), "{\n  \"format\": \n").unwrap();
    let out = polycal(&[
        "report",
        DATA,
        "--run-dir",
        run.to_str().unwrap(),
        "--out",
        dir.join("r.html").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with(&format!(
            "error: {}:3:",
            run.join("manifest.json").display()
        )),
        "{stderr}"
    );
}

/// Sub-pitch mountings (docs/FORMAT.md §9.1): α at every table angle of both cosets, as
/// `solve` reports them, and the note on each coset's constant.
#[test]
fn sub_pitch_mountings_give_every_table_angle() {
    let dir = temp_dir("subpitch");
    let data = dir.join("sub.csv");
    let out = polycal(&[
        "simulate",
        "--setups",
        "2",
        "--shift-deg",
        "0,10",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let (status, html, _) = report(&dir, &[data.to_str().unwrap()]);
    assert_eq!(status, Some(0));
    let solve = json(&["solve", data.to_str().unwrap(), "--format", "json"]);
    assert_eq!(solve["encoder_error"].as_array().unwrap().len(), 48);
    assert_column(&html, "encoder-error", 1, &solve["encoder_angle_deg"], 3);
    assert_results(&html, "encoder-error", 2, &solve, "encoder_error");
    let design: String = select(&html, "#design")[0].text().collect();
    let note = solve["notes"][0].as_str().unwrap();
    assert!(design.contains(note), "{design}");
}

/// The paper's bare design (one cycle, no closing reading) is exactly determined: u and U
/// need a stated σ, as for `solve --sigma`.
#[test]
fn an_exactly_determined_run_takes_a_stated_sigma() {
    let dir = temp_dir("sigma");
    let data = dir.join("bare.csv");
    let out = polycal(&["simulate", "--cycles", "1", "--out", data.to_str().unwrap()]);
    assert!(out.status.success());
    let out_path = dir.join("r.html");
    let out = polycal(&[
        "report",
        data.to_str().unwrap(),
        "--budget",
        BUDGET,
        "--out",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("--sigma"), "{stderr}");
    let (status, html, _) = report(
        &dir,
        &[
            data.to_str().unwrap(),
            "--budget",
            BUDGET,
            "--sigma",
            "0.05",
        ],
    );
    assert_eq!(status, Some(0));
    let solve = json(&[
        "solve",
        data.to_str().unwrap(),
        "--budget",
        BUDGET,
        "--sigma",
        "0.05",
        "--format",
        "json",
    ]);
    assert_eq!(solve["dof"], 0);
    assert_results(&html, "pitch-deviation", 1, &solve, "pitch_deviation");
    assert_results(&html, "encoder-error", 2, &solve, "encoder_error");
}

/// No document polycal writes names a directory of the machine that wrote it: run from a
/// temporary directory with absolute paths to every input and output, the HTML report,
/// the DCC (a polygon run with every option, and a self-calibration), and the `--plot`
/// figures of `solve`, `diagnose`, `compare`, `selfcal` and `kc` hold neither the repository's
/// path nor the temporary directory's (docs/FORMAT.md §10.2).
#[test]
fn no_document_holds_an_absolute_path() {
    let dir = temp_dir("absolute");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let abs = |p: &str| root.join(p).to_str().unwrap().to_string();
    let out = |p: &str| dir.join(p).to_str().unwrap().to_string();
    let run = dir.join("run1");
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(
        run.join("manifest.json"),
        r#"{"software": "polycal 0.1.0", "instruments": {"ac1": "AC 1"}, "started": "2026-11-03T14:05:09.123Z", "ended": "2026-11-03T15:01:00.000Z", "outcome": "completed"}"#,
    )
    .unwrap();
    let reference = abs(REFERENCE);
    let ours = out("ours.csv");
    let solved = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args([
            "solve",
            &abs(DATA),
            "--budget",
            &abs(BUDGET),
            "--format",
            "csv",
        ])
        .current_dir(&dir)
        .output()
        .unwrap();
    std::fs::write(&ours, &solved.stdout).unwrap();
    let runs: Vec<Vec<String>> = vec![
        vec![
            "report".into(),
            abs(DATA),
            "--budget".into(),
            abs(BUDGET),
            "--diagnose".into(),
            "--truth".into(),
            abs(TRUTH),
            "--reference".into(),
            reference.clone(),
            "--meta".into(),
            abs(META),
            format!("--run-dir={}", run.display()),
            "--out".into(),
            out("report.html"),
            format!("--dcc={}", out("certificate.xml")),
        ],
        vec![
            "report".into(),
            abs("examples/data/selfa-168.csv"),
            "--budget".into(),
            abs("examples/budgets/selfcal.toml"),
            "--diagnose".into(),
            "--meta".into(),
            abs(META),
            "--out".into(),
            out("selfcal.html"),
            "--dcc".into(),
            out("selfcal.xml"),
        ],
        vec![
            "solve".into(),
            abs(DATA),
            "--budget".into(),
            abs(BUDGET),
            "--plot".into(),
            out("solve-figures"),
        ],
        vec![
            "diagnose".into(),
            abs(DATA),
            "--plot".into(),
            out("diagnose-figures"),
        ],
        vec![
            "compare".into(),
            ours.clone(),
            reference,
            "--plot".into(),
            out("compare-figures"),
        ],
        vec![
            "selfcal".into(),
            abs("examples/data/selfa-168.csv"),
            "--plot".into(),
            out("selfcal-figures"),
        ],
        {
            let mut kc: Vec<String> = vec!["kc".into()];
            for lab in ["A", "B", "C", "D", "E", "F"] {
                kc.push(format!(
                    "{lab}={}",
                    abs(&format!("examples/data/kc/{lab}.csv"))
                ));
            }
            for when in ["start", "middle", "end"] {
                kc.push("--pilot".into());
                kc.push(format!(
                    "{when}={}",
                    abs(&format!("examples/data/kc/pilot-{when}.csv"))
                ));
            }
            kc.extend(["--plot".into(), out("kc-figures")]);
            kc
        },
    ];
    for args in &runs {
        let done = Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(
            done.status.code().is_some_and(|c| c <= 1),
            "{args:?}: {}",
            String::from_utf8_lossy(&done.stderr)
        );
    }
    // every file written, the figures' directories walked
    let mut documents = Vec::new();
    let mut pending = vec![dir.clone()];
    while let Some(d) = pending.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                if path != run {
                    pending.push(path);
                }
            } else if path != Path::new(&ours) {
                documents.push(path);
            }
        }
    }
    let kinds = |ext: &str| {
        documents
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e == ext))
            .count()
    };
    assert_eq!(kinds("html"), 2, "{documents:?}");
    assert_eq!(kinds("xml"), 2, "{documents:?}");
    assert!(kinds("svg") >= 11, "{documents:?}");
    let prefixes = [root.to_str().unwrap(), dir.to_str().unwrap()];
    for document in &documents {
        let text = std::fs::read_to_string(document).unwrap();
        for prefix in prefixes {
            assert!(
                !text.contains(prefix),
                "{} holds {prefix}: …{}…",
                document.display(),
                text.find(prefix)
                    .map(|i| &text[i.saturating_sub(80)..(i + 120).min(text.len())])
                    .unwrap_or_default()
            );
        }
    }
    // the files are named all the same: by name and SHA-256
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    for name in [
        "polygon24-2ac-6cycles.csv",
        "instrument.toml",
        "meta.toml",
        "manifest.json",
    ] {
        assert!(html.contains(name), "{name} not named");
    }
}

/// A program the printing test needs, or `None` (skipped, saying so) when it is not
/// installed and `POLYCAL_REQUIRE_BROWSER` is not set (a `SKIPPED:` line on standard
/// error, `tests/commands/skip_support`); `.ci/run` sets it, so that CI fails.
fn print_tool(program: &str, version: &str) -> Option<()> {
    match Command::new(program).arg(version).output() {
        Ok(out) if out.status.success() => Some(()),
        other => {
            skip_support::missing(
                program,
                "the printed report (every page's \"Page i of n\" and certificate number)",
                "Debian: apt-get install chromium poppler-utils",
                "POLYCAL_REQUIRE_BROWSER",
                &format!("{other:?}"),
            );
            None
        }
    }
}

/// The report `report …` writes into `dir`, printed to PDF by a headless browser
/// (Chromium, with its own header and footer off); `None` (skipped, saying so) without
/// the tools ([`print_tool`]).
fn printed(dir: &Path, args: &[&str]) -> Option<PathBuf> {
    // (poppler's tools take `-v`, not `--version`)
    print_tool("chromium", "--version")?;
    print_tool("pdftotext", "-v")?;
    report(dir, args);
    let pdf = dir.join("report.pdf");
    let out = Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-pdf-header-footer",
        ])
        .arg(format!("--user-data-dir={}", dir.join("profile").display()))
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(format!("file://{}", dir.join("report.html").display()))
        .output()
        .unwrap();
    assert!(
        pdf.exists(),
        "chromium printed nothing: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(pdf)
}

/// Page `i` of a PDF as text (`pdftotext`, with `extra` options), or `None` past its end.
fn pdf_page(pdf: &Path, i: usize, extra: &[&str]) -> Option<String> {
    let out = Command::new("pdftotext")
        .args(["-f", &i.to_string(), "-l", &i.to_string()])
        .args(extra)
        .arg(pdf)
        .arg("-")
        .output()
        .unwrap();
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The number of pages of a printed report: its first page's "Page 1 of n".
fn printed_pages(pdf: &Path) -> usize {
    let first = pdf_page(pdf, 1, &["-layout"]).unwrap();
    first
        .split("Page 1 of ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no \"Page 1 of n\" on page 1:\n{first}"))
}

/// The report printed to PDF: every page carries "Page i of n" and the certificate
/// number, in the `@page` margin boxes; the text of each page read back by poppler's
/// `pdftotext`.
#[test]
fn every_printed_page_carries_page_i_of_n_and_the_certificate_number() {
    let dir = temp_dir("print");
    let args = [
        DATA,
        "--budget",
        BUDGET,
        "--diagnose",
        "--reference",
        REFERENCE,
        "--meta",
        META,
    ];
    let Some(pdf) = printed(&dir, &args) else {
        return;
    };
    let n = printed_pages(&pdf);
    assert!(n >= 3, "the report has {n} pages");
    for i in 1..=n {
        let text = pdf_page(&pdf, i, &["-layout"]).unwrap_or_else(|| panic!("no page {i}"));
        assert!(
            text.contains(&format!("Page {i} of {n}")),
            "page {i}: no \"Page {i} of {n}\":\n{text}"
        );
        assert!(
            text.contains("Certificate EXAMPLE-2026-117"),
            "page {i}: no certificate number:\n{text}"
        );
    }
    // and no page beyond n
    assert!(pdf_page(&pdf, n + 1, &["-layout"]).is_none_or(|t| t.trim().is_empty()));
}

/// A self-calibration report printed on A4 at its own size, every line on the page: its
/// file's comment line (one unbroken run of 12 head angles, 250 characters) once made
/// Chromium lay the page out wider than A4 and print it shrunk to about 70 %, the line
/// cut at the right edge. Read back word by word (`pdftotext -bbox`, points): the title
/// set in 18 pt is 18 pt high (its box, ascent to descent, 1.0–1.3 times the size;
/// 12.6 pt shrunk), every word lies between the page's margins (15 mm = 42.5 pt each side
/// of 595 pt), and the comment's last words are printed.
#[test]
fn a_printed_self_calibration_report_keeps_every_line_on_the_page() {
    let dir = temp_dir("print-selfcal");
    let meta = dir.join("meta.toml");
    std::fs::write(
        &meta,
        "certificate = \"SC-7\"\nencoder = \"Rotary table RT-300\"\nencoder_serial = \"RT-1\"\n",
    )
    .unwrap();
    let args = [
        "examples/data/selfa-168.csv",
        "--budget",
        "examples/budgets/selfcal.toml",
        "--meta",
        meta.to_str().unwrap(),
    ];
    let Some(pdf) = printed(&dir, &args) else {
        return;
    };
    let number = |text: &str, key: &str| -> f64 {
        text.split(&format!("{key}=\""))
            .nth(1)
            .and_then(|t| t.split('"').next())
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("no {key} in {text}"))
    };
    let n = printed_pages(&pdf);
    let mut text = String::new();
    for i in 1..=n {
        let boxes = pdf_page(&pdf, i, &["-bbox"]).unwrap();
        let width = number(boxes.split("<page ").nth(1).unwrap(), "width");
        assert!(
            (width - 595.0).abs() < 1.0,
            "page {i}: A4 is 595 pt wide, not {width}"
        );
        for word in boxes
            .lines()
            .filter(|l| l.trim_start().starts_with("<word "))
        {
            let (x_min, x_max) = (number(word, "xMin"), number(word, "xMax"));
            assert!(
                x_min >= 42.5 - 2.0 && x_max <= width - 42.5 + 2.0,
                "page {i}: a word outside the margins: {word}"
            );
            if i == 1 && word.contains(">Self-calibration<") && text.is_empty() {
                let height = number(word, "yMax") - number(word, "yMin");
                assert!(
                    (18.0..=23.4).contains(&height),
                    "the 18 pt title is {height} pt high: the page is printed shrunk"
                );
                text.push_str("title ");
            }
        }
        text.push_str(&pdf_page(&pdf, i, &[]).unwrap());
    }
    assert!(text.starts_with("title "), "no title on page 1");
    let words: Vec<&str> = text.split_whitespace().collect();
    for end in ["308.57142857142856", "seed"] {
        assert!(
            words.iter().any(|w| w.ends_with(end)),
            "the comment's {end} is not printed"
        );
    }
    // a self-calibration calibrates an encoder: no polygon named anywhere
    assert!(!text.to_lowercase().contains("polygon"), "{text}");
}
