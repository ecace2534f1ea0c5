//! `polycal report` (docs/FORMAT.md §10), its numbers: the HTML parses without a single
//! HTML5 parse error; every number it shows is the number the JSON commands print
//! (`solve`, `diagnose`, `compare`, `selfcal`), shown rounded (a result as GUM 7.2.6
//! states it), and every section asked for is there — for a polygon run with every option,
//! a self-calibration, sub-pitch mountings, and an exactly determined run with a stated σ.

use scraper::{Html, Selector};
use serde_json::Value;

use crate::document_support::{assert_gum_rounded, json, polycal};
use crate::report_support::{
    BUDGET, DATA, META, REFERENCE, TRUTH, assert_results, column, report, select, shown, temp_dir,
};

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
