//! What the tests of `polycal report` (`tests/commands/report_*.rs`) share: the bundled
//! files a report is made of, the report written and parsed (asserting that it has not a
//! single HTML5 parse error), its elements and a table's cells, a number as a report shows
//! it, and the result columns checked against a command's JSON.

use std::path::{Path, PathBuf};

use scraper::{ElementRef, Html, Selector};
use serde_json::Value;

use crate::document_support;

use crate::document_support::{assert_gum_rounded, assert_k_rounded, polycal};

pub const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";

pub const TRUTH: &str = "examples/data/polygon24-2ac-6cycles.truth.json";

pub const BUDGET: &str = "examples/budgets/instrument.toml";

pub const REFERENCE: &str = "examples/data/polygon24-shift-angle.result.csv";

pub const META: &str = "examples/report/meta.toml";

pub fn temp_dir(name: &str) -> PathBuf {
    document_support::temp_dir("report", name)
}

/// Runs `polycal report … --out DIR/report.html`; returns the status and the parsed
/// document, after asserting it has no HTML5 parse error.
pub fn report(dir: &Path, args: &[&str]) -> (Option<i32>, Html, String) {
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

pub fn select<'a>(html: &'a Html, css: &str) -> Vec<ElementRef<'a>> {
    let selector = Selector::parse(css).unwrap();
    html.select(&selector).collect()
}

/// The numeric cells of column `column` (0-based, among all cells) of table `id`'s body.
pub fn column(html: &Html, id: &str, column: usize) -> Vec<(Option<f64>, String)> {
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
pub fn shown(value: f64, decimals: usize) -> String {
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

/// Asserts that table `id`'s result columns from `col` — value, u, U, k — carry
/// `json`'s `key`, `key_u` (with a budget `uncertainty.key.u`, the u_c behind U), `key_U`
/// and `key_k`: each `data-value` the JSON's number, the
/// text as GUM 7.2.6 states it, checked from its definition (docs/FORMAT.md §10.4).
pub fn assert_results(html: &Html, id: &str, col: usize, json: &Value, key: &str) {
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
