//! `polycal report --kc KC.json [--kc-lab NAME]` (docs/FORMAT.md §10.2, §10.3, §12): the
//! key comparison's section of the HTML report and its result in the DCC carry the
//! numbers of `polycal kc --format json` — exactly in the HTML's `data-value` cells, and in
//! the DCC's D-SI lists as GUM 7.2.6 states a value with its U (docs/FORMAT.md §10.4),
//! checked from the rule's definition against the JSON parsed here with serde_json alone
//! —, the exclusions with their reasons, the file by its name and its SHA-256
//! (computed here) and never by its directories; the DCC validates against the vendored
//! schema (xmllint, `tests/commands/dcc_schema`, as `tests/commands/certificate_dcc.rs`);
//! a malformed, foreign or inconsistent file and a `--kc-lab` not in the comparison are
//! refused with one `error:` line, status 2 and nothing written; read through the
//! library's `KeyComparison` and written again, the kc JSON is the command's to the byte.

use std::path::{Path, PathBuf};

use polycal::certificate::{CalibrationReport, ReportInputs};
use roxmltree::{Document, Node};
use scraper::{ElementRef, Html, Selector};
use serde_json::Value;
use sha2::{Digest, Sha256};

use crate::document_support;

use crate::document_support::polycal;

const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const META: &str = "examples/report/meta.toml";
const KC: &str = "examples/data/kc";
const LABS: [&str; 6] = ["A", "B", "C", "D", "E", "F"];
const SI: &str = "https://ptb.de/si";

/// `polycal kc` of the bundled comparison (with `extra` options; of the pitch deviations
/// unless they name `--quantity`) written to `dir/name`; returns its path and its JSON
/// parsed by serde_json alone.
fn kc_json(dir: &Path, name: &str, extra: &[&str]) -> (PathBuf, Value) {
    let labs: Vec<String> = LABS.iter().map(|l| format!("{l}={KC}/{l}.csv")).collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend_from_slice(extra);
    if !extra.contains(&"--quantity") {
        args.extend(["--quantity", "pitch_deviation"]);
    }
    args.extend_from_slice(&["--format", "json"]);
    let out = polycal(&args);
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let path = dir.join(name);
    std::fs::write(&path, &out.stdout).unwrap();
    (path, serde_json::from_slice(&out.stdout).unwrap())
}

/// The pilot's first two repeats, which agree: the artefact stable, F left out.
fn with_pilot() -> [&'static str; 4] {
    [
        "--pilot",
        "start=examples/data/kc/pilot-start.csv",
        "--pilot",
        "middle=examples/data/kc/pilot-middle.csv",
    ]
}

/// All three repeats: the last shows the artefact moved, so u_stab is in every u and
/// nobody is left out.
fn with_moving_pilot() -> [&'static str; 6] {
    [
        "--pilot",
        "start=examples/data/kc/pilot-start.csv",
        "--pilot",
        "middle=examples/data/kc/pilot-middle.csv",
        "--pilot",
        "end=examples/data/kc/pilot-end.csv",
    ]
}

/// The numbers of a JSON array.
fn numbers(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("not an array: {value}"))
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

fn sel(s: &str) -> Selector {
    Selector::parse(s).unwrap()
}

/// The `data-value` numbers of a row's cells, in order.
fn data_values(row: ElementRef) -> Vec<f64> {
    row.select(&sel("td[data-value]"))
        .map(|td| td.value().attr("data-value").unwrap().parse().unwrap())
        .collect()
}

/// The rows of the table `id`'s body.
/// The comparison's verdict as the library words it, from the JSON read back.
fn polycal_verdict(kc: &Value) -> String {
    let comparison: polycal::kc::KeyComparison = serde_json::from_value(kc.clone()).unwrap();
    comparison.verdict_statement()
}

fn super_rows<'a>(html: &'a Html, id: &str) -> Vec<ElementRef<'a>> {
    rows(html, id)
}

fn rows<'a>(html: &'a Html, id: &str) -> Vec<ElementRef<'a>> {
    html.select(&sel(&format!("#{id} tbody tr"))).collect()
}

/// The text of the element `id`.
fn text(html: &Html, id: &str) -> String {
    html.select(&sel(&format!("#{id}")))
        .next()
        .unwrap_or_else(|| panic!("no #{id}"))
        .text()
        .collect()
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The report of the bundled run with `--kc kc` ([`document_support::report_with_kc`]).
fn report(dir: &Path, kc: &Path, extra: &[&str]) -> (Html, String) {
    document_support::report_with_kc(dir, kc, extra)
}

/// The key comparison's `dcc:result`.
fn kc_result<'a>(doc: &'a Document<'a>) -> Node<'a, 'a> {
    doc.descendants()
        .find(|n| {
            n.tag_name().name() == "result"
                && n.attribute("refType") == Some("polycal_keyComparison")
        })
        .expect("a polycal_keyComparison result")
}

/// The D-SI lists of the quantities of refType `refs` in the result, in order:
/// (name, values, U, k).
type SiList = (String, Vec<f64>, Vec<f64>, Vec<f64>);

fn si_lists(result: Node, refs: &str) -> Vec<SiList> {
    result
        .descendants()
        .filter(|n| n.tag_name().name() == "quantity" && n.attribute("refType") == Some(refs))
        .map(|q| {
            let list = |name: &str| -> Vec<f64> {
                q.descendants()
                    .find(|n| n.tag_name().name() == name && n.tag_name().namespace() == Some(SI))
                    .and_then(|n| n.text())
                    .map(|t| t.split_whitespace().map(|v| v.parse().unwrap()).collect())
                    .unwrap_or_default()
            };
            let name = q
                .descendants()
                .find(|n| n.tag_name().name() == "content")
                .and_then(|n| n.text())
                .unwrap_or_default()
                .to_string();
            (
                name,
                list("valueXMLList"),
                list("uncertaintyXMLList"),
                list("coverageFactorXMLList"),
            )
        })
        .collect()
}

/// The value, U and k texts of the D-SI lists of `refs` in a DCC result, as written.
fn si_texts(result: Node, refs: &str) -> Vec<(Vec<String>, Vec<String>, Vec<String>)> {
    result
        .descendants()
        .filter(|n| n.tag_name().name() == "quantity" && n.attribute("refType") == Some(refs))
        .map(|q| {
            let list = |name: &str| -> Vec<String> {
                q.descendants()
                    .find(|n| n.tag_name().name() == name && n.tag_name().namespace() == Some(SI))
                    .and_then(|n| n.text())
                    .map(|t| t.split_whitespace().map(str::to_string).collect())
                    .unwrap_or_default()
            };
            (
                list("valueXMLList"),
                list("uncertaintyXMLList"),
                list("coverageFactorXMLList"),
            )
        })
        .collect()
}

/// Every value and its U as the DCC states them: GUM 7.2.6 from its definition
/// (`document_support::assert_gum_rounded`), against the kc JSON's numbers; k = 2 with
/// three significant digits.
fn assert_stated(
    texts: &(Vec<String>, Vec<String>, Vec<String>),
    values: &[f64],
    us: &[f64],
    what: &str,
) {
    let (value_texts, u_texts, k_texts) = texts;
    assert_eq!(value_texts.len(), values.len(), "{what}");
    assert_eq!(u_texts.len(), us.len(), "{what}");
    assert_eq!(k_texts.len(), values.len(), "{what}");
    for k_text in k_texts {
        document_support::assert_k_rounded(k_text, 2.0, what);
    }
    for (k, ((vt, ut), (&v, &u))) in value_texts
        .iter()
        .zip(u_texts)
        .zip(values.iter().zip(us))
        .enumerate()
    {
        document_support::assert_gum_rounded(vt, ut, v, u, &format!("{what} {}", k + 1));
    }
}

fn temp_dir(name: &str) -> PathBuf {
    document_support::temp_dir("report-kc", name)
}

#[test]
fn the_named_laboratorys_section_carries_the_kc_json_numbers() {
    let dir = temp_dir("lab");
    let (kc_path, kc) = kc_json(&dir, "kc.json", &with_pilot());
    let (html, dcc) = report(&dir, &kc_path, &["--kc-lab", "F"]);

    // the file by its name and its SHA-256, computed here
    assert_eq!(text(&html, "kc-file"), "kc.json");
    assert_eq!(
        text(&html, "kc-sha256"),
        sha256_hex(&std::fs::read(&kc_path).unwrap())
    );
    assert_eq!(text(&html, "kc-lab"), "F");
    // the figures of `kc` with its pilot, inlined in the figures section
    for name in [
        "kc-degrees-of-equivalence",
        "kc-reference",
        "kc-pairwise",
        "kc-pilot-stability",
    ] {
        assert_eq!(
            html.select(&sel(&format!("#figures #figure-{name} svg")))
                .count(),
            1,
            "{name}"
        );
    }

    // the reference per face: x_ref, u_ref, τ, χ², χ²_0.95 and ν as in the JSON
    let reference = rows(&html, "kc-reference");
    let faces = kc["index"].as_array().unwrap().len();
    assert_eq!(faces, 12);
    assert_eq!(reference.len(), faces);
    for (k, row) in reference.iter().enumerate() {
        assert_eq!(
            data_values(*row),
            vec![
                numbers(&kc["reference"])[k],
                numbers(&kc["reference_u"])[k],
                numbers(&kc["tau"])[k],
                numbers(&kc["chi2"])[k],
                numbers(&kc["chi2_critical"])[k],
            ],
            "face {}",
            k + 1
        );
        let cells: Vec<String> = row.select(&sel("td")).map(|c| c.text().collect()).collect();
        assert_eq!(cells[0], kc["index"][k].to_string());
        assert_eq!(cells[5], kc["chi2_dof"][k].to_string());
        assert_eq!(
            cells[7],
            if kc["consistent"][k].as_bool().unwrap() {
                "yes"
            } else {
                "NO"
            }
        );
    }

    // the closed vector's tests: every laboratory (the decision), then those in the reference
    let vector = rows(&html, "kc-vector");
    assert_eq!(vector.len(), 2);
    for (row, key) in vector.iter().zip(["vector_all", "vector"]) {
        assert_eq!(
            data_values(*row),
            vec![
                kc[key]["chi2"].as_f64().unwrap(),
                kc[key]["chi2_critical"].as_f64().unwrap()
            ]
        );
        let row_text: String = row.text().collect();
        assert!(row_text.contains(&kc[key]["dof"].to_string()), "{row_text}");
    }
    // the search's one step, with the subset that passed
    let search = rows(&html, "kc-search");
    assert_eq!(
        search.len(),
        kc["search"]["steps"].as_array().unwrap().len()
    );
    assert_eq!(
        data_values(search[0]),
        vec![
            kc["search"]["steps"][0]["chi2"].as_f64().unwrap(),
            kc["search"]["steps"][0]["chi2_critical"].as_f64().unwrap()
        ]
    );

    // the exclusion of F with its reason, in the introduction too
    let excluded = kc["excluded"].as_array().unwrap();
    assert_eq!(excluded.len(), 1);
    assert_eq!(excluded[0]["lab"], "F");
    let exclusions = rows(&html, "kc-exclusions");
    assert_eq!(exclusions.len(), 1);
    assert_eq!(exclusions[0].value().attr("data-lab"), Some("F"));
    let reason = excluded[0]["reason"].as_str().unwrap();
    let row_text: String = exclusions[0].text().collect();
    assert!(row_text.contains(reason), "{row_text}");
    let section: String = html
        .select(&sel("#key-comparison > p"))
        .next()
        .unwrap()
        .text()
        .collect();
    assert!(section.contains("left out of the reference"), "{section}");
    assert!(section.contains(reason), "{section}");

    // F's degrees of equivalence alone
    let f = kc["degrees_of_equivalence"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["lab"] == "F")
        .unwrap();
    assert_eq!(f["in_reference"], false);
    let headers: Vec<&str> = html
        .select(&sel("#kc-doe th[data-column='d']"))
        .map(|th| th.value().attr("data-lab").unwrap())
        .collect();
    assert_eq!(headers, ["F"]);
    let doe_rows = rows(&html, "kc-doe");
    assert_eq!(doe_rows.len(), faces);
    for (k, row) in doe_rows.iter().enumerate() {
        assert_eq!(
            data_values(*row),
            vec![numbers(&f["d"])[k], numbers(&f["U"])[k]]
        );
    }

    // the pilot's stability
    let pilot = &kc["pilot"];
    let pilot_rows = rows(&html, "kc-pilot");
    assert_eq!(pilot_rows.len(), faces);
    for (k, row) in pilot_rows.iter().enumerate() {
        assert_eq!(
            data_values(*row),
            vec![
                numbers(&pilot["mean"])[k],
                numbers(&pilot["spread"])[k],
                numbers(&pilot["chi2"])[k],
                numbers(&pilot["stability_u"])[k],
            ]
        );
    }
    assert_eq!(
        html.select(&sel("#kc-notes li")).count(),
        kc["notes"].as_array().unwrap().len()
    );
    assert!(text(&html, "kc-verdict").starts_with(
        if kc["comparison_consistent"].as_bool().unwrap() {
            "Consistent"
        } else {
            "NOT consistent"
        }
    ));

    // the DCC: the reference with U = 2·u_ref at k = 2, χ², F's d and U(d)
    let doc = Document::parse(&dcc).unwrap();
    let result = kc_result(&doc);
    let refs = si_lists(result, "polycal_kcReferenceValue");
    assert_eq!(refs.len(), 1);
    let twice_u: Vec<f64> = numbers(&kc["reference_u"])
        .iter()
        .map(|u| 2.0 * u)
        .collect();
    assert_stated(
        &si_texts(result, "polycal_kcReferenceValue")[0],
        &numbers(&kc["reference"]),
        &twice_u,
        "reference",
    );
    assert_eq!(refs[0].3, vec![2.0; faces]);
    assert_eq!(
        si_lists(result, "polycal_kcChi2")[0].1,
        numbers(&kc["chi2"])
    );
    assert_eq!(
        si_lists(result, "polycal_kcChi2Critical")[0].1,
        numbers(&kc["chi2_critical"])
    );
    let doe = si_lists(result, "polycal_kcDegreeOfEquivalence");
    assert_eq!(doe.len(), 1);
    assert!(doe[0].0.contains("laboratory F (left out"), "{}", doe[0].0);
    assert_stated(
        &si_texts(result, "polycal_kcDegreeOfEquivalence")[0],
        &numbers(&f["d"]),
        &numbers(&f["U"]),
        "d of F",
    );
    let statements: Vec<&str> = result
        .descendants()
        .filter(|n| n.tag_name().name() == "content")
        .filter_map(|n| n.text())
        .collect();
    assert!(
        statements
            .iter()
            .any(|s| s.contains("laboratory F left out") && s.contains(reason)),
        "{statements:?}"
    );
    // the closed vectors' χ² as the report states numbers without U: two decimals; every
    // laboratory's first (the decision), then those in the reference
    for (key, start) in [
        ("vector_all", "Every laboratory: Closed vector (GLS"),
        ("vector", "In the reference: Closed vector (GLS"),
    ] {
        let vector = &kc[key];
        let chi2 = format!("χ² = {:.2},", vector["chi2"].as_f64().unwrap());
        let dof = format!("= {},", vector["dof"].as_u64().unwrap());
        assert!(
            statements
                .iter()
                .any(|s| s.starts_with(start) && s.contains(&chi2) && s.contains(&dof)),
            "{chi2} {dof} in {statements:?}"
        );
    }
    // the verdict in the table's words
    let verdict = format!("Verdict: {}.", polycal_verdict(&kc));
    assert!(statements.contains(&verdict.as_str()), "{verdict}");
    // the KCDB graphs as an SVG file in the certificate: one graph per face, every
    // laboratory labelled (decoded here by a decoder of the test's own)
    let byte_data = result
        .descendants()
        .find(|n| n.tag_name().name() == "byteData")
        .expect("a dcc:byteData");
    let child = |name: &str| {
        byte_data
            .children()
            .find(|n| n.tag_name().name() == name)
            .and_then(|n| n.text())
            .unwrap_or_default()
            .to_string()
    };
    assert_eq!(child("fileName"), "kc-kcdb.svg");
    assert_eq!(child("mimeType"), "image/svg+xml");
    let svg = String::from_utf8(decode_base64(&child("dataBase64"))).unwrap();
    assert!(svg.starts_with("<svg"), "{}", &svg[..40.min(svg.len())]);
    assert_eq!(svg.matches("class=\"position\"").count(), faces);
    for lab in kc["labs"].as_array().unwrap() {
        let lab = lab.as_str().unwrap();
        assert!(svg.contains(&format!(">{lab}</text>")), "{lab}");
    }
}

/// Base64 (RFC 4648) decoded: the test's own reading of `dcc:dataBase64`.
fn decode_base64(text: &str) -> Vec<u8> {
    let value = |c: u8| -> u32 {
        match c {
            b'A'..=b'Z' => u32::from(c - b'A'),
            b'a'..=b'z' => u32::from(c - b'a') + 26,
            b'0'..=b'9' => u32::from(c - b'0') + 52,
            b'+' => 62,
            b'/' => 63,
            other => panic!("not base64: {other}"),
        }
    };
    let bytes: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    let mut out = Vec::new();
    for chunk in bytes.chunks(4) {
        let pad = chunk.iter().filter(|&&c| c == b'=').count();
        let n = chunk
            .iter()
            .map(|&c| if c == b'=' { 0 } else { value(c) })
            .fold(0u32, |n, v| (n << 6) | v);
        let three = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
        out.extend_from_slice(&three[..3 - pad]);
    }
    out
}

#[test]
fn without_a_laboratory_every_degree_of_equivalence_is_shown() {
    let dir = temp_dir("all");
    let (kc_path, kc) = kc_json(&dir, "kc-encoder.json", &["--quantity", "encoder_error"]);
    let (html, dcc) = report(&dir, &kc_path, &[]);
    let does = kc["degrees_of_equivalence"].as_array().unwrap();
    let labs: Vec<&str> = html
        .select(&sel("#kc-doe th[data-column='d']"))
        .map(|th| th.value().attr("data-lab").unwrap())
        .collect();
    let expected: Vec<&str> = does.iter().map(|d| d["lab"].as_str().unwrap()).collect();
    assert_eq!(labs, expected);
    let angles = numbers(&kc["angle_deg"]);
    let rows = rows(&html, "kc-doe");
    assert_eq!(rows.len(), angles.len());
    for (k, row) in rows.iter().enumerate() {
        let mut want = vec![angles[k]];
        for d in does {
            want.push(numbers(&d["d"])[k]);
            want.push(numbers(&d["U"])[k]);
        }
        assert_eq!(data_values(*row), want, "angle {}", angles[k]);
    }
    assert_eq!(html.select(&sel("#figure-kc-reference svg")).count(), 1);
    assert_eq!(html.select(&sel("#figure-kc-pilot-stability")).count(), 0);
    // encoder errors: a closed vector too, each result less its mean
    assert!(html.html().contains("defined up to a constant"));
    let vector_rows = super_rows(&html, "kc-vector");
    assert_eq!(
        data_values(vector_rows[0])[0],
        kc["vector_all"]["chi2"].as_f64().unwrap()
    );
    let doc = Document::parse(&dcc).unwrap();
    let result = kc_result(&doc);
    assert_eq!(si_lists(result, "polycal_kcTableAngle")[0].1, angles);
    let lists = si_lists(result, "polycal_kcDegreeOfEquivalence");
    assert_eq!(lists.len(), does.len());
    for (list, d) in lists.iter().zip(does) {
        assert!(
            list.0
                .contains(&format!("laboratory {}", d["lab"].as_str().unwrap()))
        );
    }
    for (texts, d) in si_texts(result, "polycal_kcDegreeOfEquivalence")
        .iter()
        .zip(does)
    {
        assert_stated(texts, &numbers(&d["d"]), &numbers(&d["U"]), "d");
    }
}

/// The refusals: status 2, one `error:` line naming the file (with serde's line and
/// column where it has them), nothing written.
#[test]
fn malformed_foreign_or_inconsistent_files_and_unknown_labs_are_refused() {
    let dir = temp_dir("refused");
    let (kc_path, kc) = kc_json(&dir, "kc.json", &[]);
    let text = std::fs::read_to_string(&kc_path).unwrap();
    let truncated = dir.join("truncated.json");
    std::fs::write(&truncated, &text[..text.len() / 2]).unwrap();
    let solve = dir.join("solve.json");
    let solve_json = document_support::json(&["solve", DATA, "--format", "json"]);
    std::fs::write(&solve, solve_json.to_string()).unwrap();
    let mut short = kc.clone();
    short["reference"].as_array_mut().unwrap().pop();
    let inconsistent = dir.join("inconsistent.json");
    std::fs::write(&inconsistent, serde_json::to_string(&short).unwrap()).unwrap();
    let html = dir.join("r.html");
    let cases: [(&Path, &[&str], String); 4] = [
        (&truncated, &[], format!("{}:1:", truncated.display())),
        (&solve, &[], format!("{}:1:", solve.display())),
        (
            &inconsistent,
            &[],
            format!(
                "{}: reference has 11 entries, but the comparison has 12",
                inconsistent.display()
            ),
        ),
        (
            &kc_path,
            &["--kc-lab", "Z"],
            "laboratory \"Z\" is not in this key comparison; its laboratories: A, B, C, D, E, F"
                .to_string(),
        ),
    ];
    for (file, extra, expected) in cases {
        let mut args = vec!["report", DATA, "--kc", file.to_str().unwrap()];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--out", html.to_str().unwrap()]);
        let out = polycal(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{stderr}");
        assert!(lines[0].starts_with("error: "), "{stderr}");
        assert!(lines[0].contains(&expected), "{expected:?} not in {stderr}");
        assert!(!html.exists(), "{args:?} wrote the report");
    }
    // the solve JSON: refused as not the kc JSON, serde's reason given
    let out = polycal(&[
        "report",
        DATA,
        "--kc",
        solve.to_str().unwrap(),
        "--out",
        html.to_str().unwrap(),
    ]);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("not the JSON of `polycal kc --format json`")
    );
}

/// The documents name the key comparison's file by its file name only: given by its
/// absolute path, neither the HTML nor the DCC holds its directory.
#[test]
fn the_documents_hold_no_absolute_path_of_the_kc_file() {
    let dir = temp_dir("absolute");
    let (kc_path, _) = kc_json(&dir, "kc.json", &[]);
    assert!(kc_path.is_absolute());
    let inputs = ReportInputs::new(DATA)
        .with_budget(BUDGET)
        .with_meta(META)
        .with_key_comparison(&kc_path, Some("A".to_string()))
        .with_generated_utc("2026-11-27T12:00:00.000Z");
    let report = CalibrationReport::build(&inputs).unwrap();
    let directory = dir.to_str().unwrap();
    let html = report.to_html();
    let dcc = report.to_dcc().unwrap();
    assert!(html.contains("kc.json"));
    assert!(dcc.contains("kc.json"));
    assert!(!html.contains(directory), "the HTML names {directory}");
    assert!(!dcc.contains(directory), "the DCC names {directory}");
}

/// The report reads the kc JSON through the library's own `KeyComparison`: read back and
/// written again, the JSON is the command's to the byte, with and without a pilot and
/// angles, so no member is dropped or changed on the way into the documents.
#[test]
fn the_kc_json_reads_back_to_the_same_bytes() {
    let dir = temp_dir("round-trip");
    let cases: [(&str, &[&str]); 4] = [
        ("pilot.json", &with_pilot()),
        ("moving.json", &with_moving_pilot()),
        ("encoder.json", &["--quantity", "encoder_error"]),
        ("dl.json", &["--method", "dersimonian-laird"]),
    ];
    for (name, extra) in cases {
        let (path, _) = kc_json(&dir, name, extra);
        let text = std::fs::read_to_string(&path).unwrap();
        let kc: polycal::kc::KeyComparison = serde_json::from_str(&text).unwrap();
        assert_eq!(
            polycal::output::to_json(&kc).unwrap(),
            text.trim_end(),
            "{name}"
        );
    }
}

/// A linked comparison in the report and the DCC: the link's laboratories and test, Δ with
/// u(Δ) and the named laboratory's d and U against the linked reference, every number the
/// JSON's (`data-value`), and in the DCC the correction (U = 2·u(Δ)) and the laboratory's
/// linked degree of equivalence.
#[test]
fn a_linked_comparison_states_its_link() {
    let dir = temp_dir("linked");
    let run = |labs: &[&str], extra: &[&str]| -> Vec<u8> {
        let named: Vec<String> = labs.iter().map(|l| format!("{l}={KC}/{l}.csv")).collect();
        let mut args: Vec<&str> = vec!["kc"];
        args.extend(named.iter().map(String::as_str));
        args.extend_from_slice(extra);
        args.extend(["--quantity", "pitch_deviation", "--format", "json"]);
        let out = polycal(&args);
        assert!(out.status.code().is_some_and(|c| c <= 1));
        out.stdout
    };
    let cipm = dir.join("cipm.json");
    std::fs::write(&cipm, run(&["A", "B", "C", "D"], &[])).unwrap();
    let rmo_bytes = run(&["B", "C", "E", "F"], &["--link", cipm.to_str().unwrap()]);
    let rmo = dir.join("rmo.json");
    std::fs::write(&rmo, &rmo_bytes).unwrap();
    let kc: Value = serde_json::from_slice(&rmo_bytes).unwrap();
    let (html, dcc) = report(&dir, &rmo, &["--kc-lab", "E"]);
    let link_text = text(&html, "kc-link");
    assert!(link_text.contains("through B, C"), "{link_text}");
    let e = kc["degrees_of_equivalence"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["lab"] == "E")
        .unwrap();
    let rows = rows(&html, "kc-linked");
    let faces = kc["index"].as_array().unwrap().len();
    assert_eq!(rows.len(), faces);
    let (correction, correction_u) = (
        numbers(&kc["link"]["correction"]),
        numbers(&kc["link"]["correction_u"]),
    );
    let (d_linked, u_linked) = (numbers(&e["d_linked"]), numbers(&e["U_linked"]));
    for (k, row) in rows.iter().enumerate() {
        let values = data_values(*row);
        // (the face's cell has no number) Δ, u(Δ), E's d and U against the linked reference
        assert_eq!(
            values,
            [correction[k], correction_u[k], d_linked[k], u_linked[k]],
            "face {}",
            k + 1
        );
    }
    let doc = Document::parse(&dcc).unwrap();
    let result = kc_result(&doc);
    let delta = si_lists(result, "polycal_kcLinkCorrection");
    assert_eq!(delta.len(), 1);
    assert!(delta[0].0.contains("through B, C"), "{}", delta[0].0);
    let twice_u: Vec<f64> = correction_u.iter().map(|u| 2.0 * u).collect();
    assert_stated(
        &si_texts(result, "polycal_kcLinkCorrection")[0],
        &correction,
        &twice_u,
        "Δ",
    );
    let linked = si_lists(result, "polycal_kcDegreeOfEquivalenceLinked");
    assert_eq!(linked.len(), 1, "the named laboratory's only");
    assert_stated(
        &si_texts(result, "polycal_kcDegreeOfEquivalenceLinked")[0],
        &d_linked,
        &u_linked,
        "E linked",
    );
}

/// Laboratories that state the degrees of freedom of their u (`dof`): each U(d_i) in the
/// DCC carries its own k = t_95.45(ν_eff), the kc JSON's `k` (not k = 2), and the DCC's
/// description and the report's formulas say so.
#[test]
fn stated_degrees_of_freedom_give_each_u_its_own_coverage_factor_in_the_dcc() {
    let dir = temp_dir("dof");
    let write = |name: &str, values: [f64; 6], u: f64, dof: Option<u32>| -> String {
        let mut text = String::from("quantity,index,value,u,dof\n");
        for (face, value) in values.iter().enumerate() {
            let dof = dof.map_or(String::new(), |d| d.to_string());
            text.push_str(&format!("pitch_deviation,{},{value},{u},{dof}\n", face + 1));
        }
        let path = dir.join(format!("{name}.csv"));
        std::fs::write(&path, text).unwrap();
        format!("{name}={}", path.display())
    };
    let labs = [
        write("A", [0.10, -0.20, 0.05, 0.00, 0.10, -0.05], 0.05, Some(4)),
        write("B", [0.12, -0.18, 0.02, 0.01, 0.08, -0.05], 0.06, Some(6)),
        write("C", [0.08, -0.22, 0.06, -0.02, 0.12, -0.02], 0.05, None),
        write("D", [0.11, -0.19, 0.04, 0.02, 0.09, -0.07], 0.07, Some(9)),
    ];
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend(["--format", "json"]);
    let out = polycal(&args);
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let kc_path = dir.join("kc.json");
    std::fs::write(&kc_path, &out.stdout).unwrap();
    let kc: Value = serde_json::from_slice(&out.stdout).unwrap();
    let (html, dcc) = report(&dir, &kc_path, &[]);
    // the report says so where it gives the formulas
    let method = text(&html, "kc-method");
    assert!(
        method.contains("k = t95.45(νeff) of each value"),
        "{method}"
    );
    assert!(!method.contains("k = 2;"), "{method}");
    let doc = Document::parse(&dcc).unwrap();
    let result = kc_result(&doc);
    let texts = si_texts(result, "polycal_kcDegreeOfEquivalence");
    let does = kc["degrees_of_equivalence"].as_array().unwrap();
    assert_eq!(texts.len(), does.len());
    let mut above_two = 0;
    for (doe, (_, _, k_texts)) in does.iter().zip(&texts) {
        let k = numbers(&doe["k"]);
        assert_eq!(k_texts.len(), k.len(), "{}", doe["lab"]);
        for (text, &k) in k_texts.iter().zip(&k) {
            document_support::assert_k_rounded(text, k, &format!("k of {}", doe["lab"]));
            above_two += usize::from(k > 2.05);
        }
    }
    assert!(above_two >= 12, "{above_two} coverage factors above 2");
    let description = result
        .descendants()
        .find(|n| n.tag_name().name() == "description")
        .and_then(|n| n.descendants().find(|c| c.tag_name().name() == "content"))
        .and_then(|n| n.text())
        .unwrap_or_default();
    assert!(
        description.contains("k = t_95.45(ν_eff) of each value"),
        "{description}"
    );
}
