//! `polycal report --dcc` (docs/FORMAT.md §10.3): every DCC the tests write validates
//! against the vendored DCC 3.1.2 and D-SI 2.1.0 schemas (`docs/schema/`, xmllint, offline
//! through the catalog), and the validator is shown to reject a broken document; read
//! back with an XML parser, every β, φ, α, U and k is the `solve --format json` number
//! stated as GUM 7.2.6 says (checked from the rule's definition, docs/FORMAT.md §10.4),
//! the face numbers integers, a self-calibration's e and head errors are `selfcal`'s, the
//! En are `compare`'s, and the HTML report of the same inputs shows the same text;
//! missing metadata is refused naming every key missing, with nothing written; XML
//! specials survive the round trip and control characters are refused where they are
//! read.
//!
//! The schema validation needs `xmllint` (`tests/commands/dcc_schema` says how it is
//! found and when its absence fails).

use std::path::{Path, PathBuf};
use std::process::Command;

use roxmltree::{Document, Node};
use scraper::{Html, Selector};
use serde_json::Value;

const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const REFERENCE: &str = "examples/data/polygon24-shift-angle.result.csv";
const META: &str = "examples/report/meta.toml";
const SELFCAL: &str = "examples/data/selfa-168.csv";
const SELFCAL_BUDGET: &str = "examples/budgets/selfcal.toml";
const DCC: &str = "https://ptb.de/dcc";
const SI: &str = "https://ptb.de/si";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

use crate::document_support;

use crate::dcc_schema::{assert_valid, schema_valid};
use crate::document_support::{assert_gum_rounded, assert_k_rounded, json, polycal};

fn temp_dir(name: &str) -> PathBuf {
    document_support::temp_dir("dcc", name)
}

/// Runs `polycal report ARGS --dcc DIR/NAME`; returns the status and the document text
/// after asserting that it validates.
fn dcc(dir: &Path, name: &str, args: &[&str]) -> (Option<i32>, String) {
    let path = dir.join(name);
    let path_text = path.to_str().unwrap().to_string();
    let mut all = vec!["report"];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--dcc", &path_text]);
    let out = polycal(&all);
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_valid(&path);
    (out.status.code(), std::fs::read_to_string(&path).unwrap())
}

fn dcc_element<'a>(node: Node<'a, 'a>, name: &str) -> Option<Node<'a, 'a>> {
    node.children()
        .find(|c| c.tag_name().name() == name && c.tag_name().namespace() == Some(DCC))
}

/// The text of an element's `dcc:name/dcc:content`.
fn name_of(node: Node) -> String {
    dcc_element(node, "name")
        .and_then(|n| dcc_element(n, "content"))
        .and_then(|c| c.text())
        .unwrap_or_default()
        .to_string()
}

/// The D-SI list of the quantity named `quantity` in the result (or influence condition)
/// with refType containing `result_ref`: its values, and its U, k and p when given.
struct SiList {
    /// The texts of the values, U and k, as written.
    texts: [Vec<String>; 3],
    values: Vec<f64>,
    p: Vec<f64>,
    unit: String,
}

fn si_list(doc: &Document, result_ref: &str, quantity: &str) -> SiList {
    let result = doc
        .descendants()
        .find(|n| {
            matches!(n.tag_name().name(), "result" | "influenceCondition")
                && n.attribute("refType")
                    .is_some_and(|r| r.split(' ').any(|t| t == result_ref))
        })
        .unwrap_or_else(|| panic!("no result {result_ref}"));
    let q = result
        .descendants()
        .find(|n| n.tag_name().name() == "quantity" && name_of(*n) == quantity)
        .unwrap_or_else(|| panic!("{result_ref}: no quantity {quantity}"));
    let list = |name: &str| -> Vec<f64> {
        q.descendants()
            .find(|n| n.tag_name().name() == name && n.tag_name().namespace() == Some(SI))
            .and_then(|n| n.text())
            .map(|t| {
                t.split_whitespace()
                    .map(|v| v.parse().unwrap_or_else(|_| panic!("{name}: {v}")))
                    .collect()
            })
            .unwrap_or_default()
    };
    let texts = |name: &str| -> Vec<String> {
        q.descendants()
            .find(|n| n.tag_name().name() == name && n.tag_name().namespace() == Some(SI))
            .and_then(|n| n.text())
            .map(|t| t.split_whitespace().map(str::to_string).collect())
            .unwrap_or_default()
    };
    let unit = q
        .descendants()
        .find(|n| n.tag_name().name() == "unitXMLList")
        .and_then(|n| n.text())
        .unwrap_or_default()
        .to_string();
    SiList {
        texts: [
            texts("valueXMLList"),
            texts("uncertaintyXMLList"),
            texts("coverageFactorXMLList"),
        ],
        values: list("valueXMLList"),
        p: list("coverageProbabilityXMLList"),
        unit,
    }
}

impl SiList {
    /// Asserts that the list states the evaluated values, U and k (the JSON's) rounded
    /// as GUM 7.2.6 says (docs/FORMAT.md §10.4), one per value.
    fn states(&self, values: &[f64], expanded_u: &[f64], k: &[f64], what: &str) {
        assert_eq!(self.texts[0].len(), values.len(), "{what}: values");
        assert_eq!(self.texts[1].len(), values.len(), "{what}: U");
        assert_eq!(self.texts[2].len(), values.len(), "{what}: k");
        for i in 0..values.len() {
            let at = format!("{what}[{i}]");
            assert_gum_rounded(
                &self.texts[0][i],
                &self.texts[1][i],
                values[i],
                expanded_u[i],
                &at,
            );
            assert_k_rounded(&self.texts[2][i], k[i], &at);
        }
    }
}

/// The numbers of a JSON array (nulls refused).
fn numbers(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("not an array: {value}"))
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

fn text_of<'a>(doc: &'a Document, element: &str) -> Vec<&'a str> {
    doc.descendants()
        .filter(|n| n.tag_name().name() == element && n.tag_name().namespace() == Some(DCC))
        .filter_map(|n| n.text())
        .collect()
}

#[test]
fn the_validator_rejects_a_broken_certificate() {
    let dir = temp_dir("broken");
    let (_, text) = dcc(&dir, "c.xml", &[DATA, "--budget", BUDGET, "--meta", META]);
    // the same document without its required end date, and with a β that is not a number
    for (what, broken) in [
        (
            "no endPerformanceDate",
            text.replace(
                &text[text.find("<dcc:endPerformanceDate>").unwrap()
                    ..text.find("</dcc:endPerformanceDate>").unwrap() + 25],
                "",
            ),
        ),
        (
            "a value NaN",
            text.replacen("<si:valueXMLList>1 ", "<si:valueXMLList>NaN ", 1),
        ),
        (
            "a negative uncertainty",
            text.replacen("<si:uncertaintyXMLList>", "<si:uncertaintyXMLList>-", 1),
        ),
    ] {
        assert_ne!(broken, text, "{what}: nothing changed");
        let path = dir.join("broken.xml");
        std::fs::write(&path, broken).unwrap();
        if let Some((valid, _)) = schema_valid(&path) {
            assert!(!valid, "{what}: a broken DCC validates");
        }
    }
}

/// The bundled example with budget, diagnosis, reference and metadata: a valid DCC whose
/// every number is solve's, compare's and the HTML report's.
#[test]
fn the_full_example_validates_and_carries_the_json_numbers() {
    let dir = temp_dir("full");
    let html_path = dir.join("r.html");
    let (status, text) = dcc(
        &dir,
        "c.xml",
        &[
            DATA,
            "--budget",
            BUDGET,
            "--diagnose",
            "--reference",
            REFERENCE,
            "--meta",
            META,
            "--out",
            html_path.to_str().unwrap(),
        ],
    );
    assert_eq!(status, Some(0));
    let doc = Document::parse(&text).unwrap();
    let top = doc.root_element();
    assert_eq!(top.tag_name().name(), "digitalCalibrationCertificate");
    assert_eq!(top.attribute("schemaVersion"), Some("3.1.2"));
    let solve = json(&["solve", DATA, "--budget", BUDGET, "--format", "json"]);
    let n = 24;
    // β: every value, U and k the JSON's, rounded as GUM 7.2.6 states them; p for each
    let beta = si_list(&doc, "polycal_pitchDeviations", "Pitch deviation β");
    assert_eq!(beta.unit, "\\arcsecond");
    beta.states(
        &numbers(&solve["pitch_deviation"]),
        &numbers(&solve["pitch_deviation_U"]),
        &numbers(&solve["pitch_deviation_k"]),
        "β",
    );
    assert_eq!(beta.p, vec![0.95; n]);
    // the face numbers are integers
    let faces = si_list(&doc, "polycal_pitchDeviations", "Face");
    assert_eq!(
        faces.texts[0],
        (1..=n).map(|f| f.to_string()).collect::<Vec<_>>()
    );
    // φ[1..N−1] (φ[N] = 0 by definition, not listed)
    let phi = si_list(&doc, "polycal_faceDeviations", "Face deviation φ");
    let phi_k: Vec<f64> = solve["face_deviation_k"].as_array().unwrap()[..n - 1]
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    phi.states(
        &numbers(&solve["face_deviation"])[..n - 1],
        &numbers(&solve["face_deviation_U"])[..n - 1],
        &phi_k,
        "φ",
    );
    // α with its table angles in degrees
    let alpha = si_list(&doc, "polycal_encoderErrors", "Encoder error α");
    alpha.states(
        &numbers(&solve["encoder_error"]),
        &numbers(&solve["encoder_error_U"]),
        &numbers(&solve["encoder_error_k"]),
        "α",
    );
    let angles = si_list(&doc, "polycal_encoderErrors", "Table angle");
    assert_eq!(angles.unit, "\\degree");
    assert_eq!(
        angles.values,
        (0..n).map(|p| p as f64 * 15.0).collect::<Vec<_>>()
    );
    // the setup errors: a result (estimated with β and α), not an influence condition,
    // and not named U
    assert!(
        !doc.descendants()
            .any(|n| n.tag_name().name() == "influenceCondition"
                && n.attribute("refType") == Some("polycal_setupErrors")),
        "setup errors under influenceConditions"
    );
    let setup = si_list(&doc, "polycal_setupErrors", "Setup error");
    let setup_json = solve["setup_error"].as_array().unwrap();
    let field = |key: &str| {
        setup_json
            .iter()
            .map(|s| s[key].as_f64().unwrap())
            .collect::<Vec<_>>()
    };
    setup.states(&field("value"), &field("U"), &field("k"), "setup error");
    // the fit
    let rms = doc
        .descendants()
        .find(|n| n.attribute("refType") == Some("polycal_residualRms"))
        .and_then(|r| r.descendants().find(|n| n.tag_name().name() == "value"))
        .and_then(|v| v.text())
        .unwrap();
    assert_eq!(
        rms.parse::<f64>().unwrap(),
        solve["residual_rms"].as_f64().unwrap()
    );
    // the comparison: compare's En, row by row
    let ours = dir.join("ours.csv");
    let rows = polycal(&["solve", DATA, "--budget", BUDGET, "--format", "csv"]);
    std::fs::write(&ours, &rows.stdout).unwrap();
    let compared = json(&[
        "compare",
        ours.to_str().unwrap(),
        REFERENCE,
        "--format",
        "json",
    ]);
    // En to two decimals, as the report shows it
    let en = si_list(&doc, "polycal_comparison", "En");
    let compared_en: Vec<f64> = compared["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["en"].as_f64().unwrap())
        .collect();
    assert_eq!(en.values.len(), compared_en.len());
    for (i, (shown, en)) in en.texts[0].iter().zip(&compared_en).enumerate() {
        assert_eq!(
            shown.split_once('.').map(|(_, d)| d.len()),
            Some(2),
            "En[{i}] {shown}"
        );
        let value: f64 = shown.parse().unwrap();
        assert!(
            (value - en).abs() <= 0.005 + 1e-12,
            "En[{i}]: {shown} is not {en}"
        );
    }
    // the comparison's verdict in the very words of compare's table (docs/FORMAT.md §5.4)
    let table =
        String::from_utf8(polycal(&["compare", ours.to_str().unwrap(), REFERENCE]).stdout).unwrap();
    let verdict_line = table
        .lines()
        .find(|l| l.starts_with("Verdict: "))
        .expect("the table states the verdict");
    let stated = doc
        .descendants()
        .filter(|n| n.tag_name().name() == "content")
        .filter_map(|n| n.text())
        .any(|t| t.starts_with(&format!("{verdict_line}. Largest |En| = ")));
    assert!(stated, "the DCC states {verdict_line:?}");
    // the diagnosis's verdict is diagnose's
    let diagnosed = json(&["diagnose", DATA, "--format", "json"]);
    let verdict = doc
        .descendants()
        .find(|n| n.attribute("refType") == Some("polycal_adequacy"))
        .map(|q| {
            q.descendants()
                .rfind(|n| n.tag_name().name() == "content")
                .and_then(|c| c.text())
                .unwrap()
                .to_string()
        })
        .unwrap();
    let adequate = diagnosed["adequate"].as_bool().unwrap();
    assert_eq!(verdict, if adequate { "adequate" } else { "not adequate" });
    // the administrative data from the metadata
    assert_eq!(text_of(&doc, "uniqueIdentifier"), ["EXAMPLE-2026-117"]);
    assert_eq!(text_of(&doc, "countryCodeISO3166_1"), ["DE"]);
    assert_eq!(text_of(&doc, "beginPerformanceDate"), ["2026-11-03"]);
    assert_eq!(text_of(&doc, "endPerformanceDate"), ["2026-11-03"]);
    assert_eq!(text_of(&doc, "performanceLocation"), ["laboratory"]);
    assert_eq!(text_of(&doc, "release"), [env!("CARGO_PKG_VERSION"); 2]);
    let serials: Vec<&str> = text_of(&doc, "value");
    for serial in ["P-24/7", "RT-300-0042", "EXAMPLE-AC1", "EXAMPLE-AC2"] {
        assert!(serials.contains(&serial), "{serial}: {serials:?}");
    }
    // the SHA-256 of every input, as sha256sum computes it
    for file in [DATA, BUDGET, REFERENCE, META] {
        let sum = Command::new("sha256sum")
            .arg(file)
            .current_dir(root())
            .output()
            .unwrap();
        let hex = String::from_utf8(sum.stdout).unwrap()[..64].to_string();
        // named by its file name alone, never the directories it was read from
        let name = Path::new(file).file_name().unwrap().to_str().unwrap();
        assert!(
            text.contains(&format!(">{name} (")) && text.contains(&hex),
            "{file}: {hex}"
        );
    }
    // the accreditation, the traceability statement and the customer's country
    assert_eq!(
        text_of(&doc, "calibrationLaboratoryCode"),
        ["EAB-K-99999-01"]
    );
    assert_eq!(text_of(&doc, "countryCode"), ["DE", "GB"]);
    assert_eq!(text_of(&doc, "traceable"), ["true"]);
    let statement = |kind: &str| {
        doc.descendants()
            .find(|n| n.tag_name().name() == "statement" && n.attribute("refType") == Some(kind))
            .and_then(|n| n.descendants().find(|c| c.tag_name().name() == "content"))
            .and_then(|c| c.text())
            .unwrap_or_else(|| panic!("no statement {kind}"))
            .to_string()
    };
    assert!(statement("polycal_traceability").starts_with("The angle is traced to the SI radian"));
    assert_eq!(
        statement("polycal_accreditation"),
        "Accredited by Example Accreditation Body (EAB), accreditation number EAB-K-99999-01."
    );
    // the HTML report of the same run shows the same numbers, rounded alike (its visible
    // text, with a true minus sign)
    let html = Html::parse_document(&std::fs::read_to_string(&html_path).unwrap());
    let cells = |id: &str, column: usize| -> Vec<String> {
        html.select(&Selector::parse(&format!("table#{id} > tbody > tr")).unwrap())
            .map(|row| {
                row.select(&Selector::parse("td").unwrap())
                    .nth(column)
                    .map(|c| c.text().collect::<String>().replace('−', "-"))
                    .unwrap_or_default()
            })
            .collect()
    };
    assert_eq!(cells("pitch-deviation", 1), beta.texts[0]);
    assert_eq!(cells("pitch-deviation", 3), beta.texts[1]);
    assert_eq!(cells("pitch-deviation", 4), beta.texts[2]);
    assert_eq!(cells("encoder-error", 2), alpha.texts[0]);
    assert_eq!(cells("encoder-error", 4), alpha.texts[1]);
    assert_eq!(cells("encoder-error", 5), alpha.texts[2]);
    assert_eq!(cells("face-deviation", 1)[..n - 1], phi.texts[0]);
    assert_eq!(cells("setup-error", 1), setup.texts[0]);
}

/// A self-calibration with its budget and diagnosis: a valid DCC with selfcal's e and
/// head errors; no polygon item.
#[test]
fn a_self_calibration_gives_a_valid_dcc_with_selfcals_numbers() {
    let dir = temp_dir("selfcal");
    let meta = dir.join("meta.toml");
    std::fs::write(
        &meta,
        "certificate = \"S-1\"\ncustomer = \"C\"\ncustomer_address = \"A\"\ncustomer_email = \"c@example.org\"\n\
         encoder_manufacturer = \"M\"\nencoder_serial = \"E-1\"\nlaboratory = \"L\"\nlaboratory_address = \"LA\"\n\
         laboratory_email = \"l@example.org\"\ncountry = \"GB\"\nperformance_location = \"customer\"\n\
         date_of_measurement = \"2024-02-29\"\napproved_by = \"B. Approver\"\n",
    )
    .unwrap();
    let (_, text) = dcc(
        &dir,
        "s.xml",
        &[
            SELFCAL,
            "--budget",
            SELFCAL_BUDGET,
            "--diagnose",
            "--meta",
            meta.to_str().unwrap(),
        ],
    );
    let doc = Document::parse(&text).unwrap();
    let selfcal = json(&[
        "selfcal",
        SELFCAL,
        "--budget",
        SELFCAL_BUDGET,
        "--format",
        "json",
    ]);
    let e = si_list(&doc, "polycal_encoderErrors", "Encoder error e");
    e.states(
        &numbers(&selfcal["encoder_error"]),
        &numbers(&selfcal["encoder_error_U"]),
        &numbers(&selfcal["encoder_error_k"]),
        "e",
    );
    let angles = si_list(&doc, "polycal_encoderErrors", "Table angle");
    assert_eq!(angles.values, numbers(&selfcal["encoder_angle_deg"]));
    let heads = si_list(&doc, "polycal_headErrors", "Head error");
    let head_json = selfcal["head_error"].as_array().unwrap();
    let field = |key: &str| {
        head_json
            .iter()
            .map(|h| h[key].as_f64().unwrap())
            .collect::<Vec<_>>()
    };
    heads.states(&field("value"), &field("U"), &field("k"), "head error");
    assert!(!text.contains("id=\"polygon\""));
    assert!(!text.contains("polycal_pitchDeviations"));
    assert_eq!(text_of(&doc, "performanceLocation"), ["customer"]);
}

/// A run directory: the dates of the run (start and end), the instruments' replies.
#[test]
fn a_run_directory_gives_the_performance_dates() {
    let dir = temp_dir("run");
    let run = dir.join("run1");
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(
        run.join("manifest.json"),
        r#"{"format": "polycal-run/1", "software": "polycal 0.1.0",
  "settings": {"faces": 24, "cycles": 6, "closing": true},
  "instruments": {"ac1": "ELCOMAT 3000 S/N 4711", "ac2": "ELCOMAT 3000 S/N 4712", "table": "SMC100CC 2.0.0"},
  "started": "2026-11-03T23:05:09.123Z", "ended": "2026-11-04T01:01:00.000Z",
  "outcome": "completed", "readings": 300, "expected_readings": 300, "sessions": []}"#,
    )
    .unwrap();
    // the metadata without its date: the run gives it
    let meta_text = std::fs::read_to_string(root().join(META))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with("date_of_measurement"))
        .collect::<Vec<_>>()
        .join("\n");
    let meta = dir.join("meta.toml");
    std::fs::write(&meta, meta_text).unwrap();
    let (_, text) = dcc(
        &dir,
        "c.xml",
        &[
            DATA,
            "--budget",
            BUDGET,
            "--meta",
            meta.to_str().unwrap(),
            "--run-dir",
            run.to_str().unwrap(),
        ],
    );
    let doc = Document::parse(&text).unwrap();
    assert_eq!(text_of(&doc, "beginPerformanceDate"), ["2026-11-03"]);
    assert_eq!(text_of(&doc, "endPerformanceDate"), ["2026-11-04"]);
    let equipment: Vec<String> = doc
        .descendants()
        .filter(|n| n.tag_name().name() == "measuringEquipment")
        .map(name_of)
        .collect();
    assert!(
        equipment.contains(&"ELCOMAT 3000 S/N 4711".to_string())
            && equipment.contains(&"SMC100CC 2.0.0".to_string()),
        "{equipment:?}"
    );
    assert!(text.contains("run manifest"));
}

/// The metadata text with the line of `key` replaced (`None`: removed).
fn with_line(full: &str, key: &str, replacement: Option<&str>) -> String {
    let text: String = full
        .lines()
        .filter_map(|l| {
            if l.starts_with(&format!("{key} =")) {
                replacement
            } else {
                Some(l)
            }
        })
        .map(|l| format!("{l}\n"))
        .collect();
    assert_ne!(text, full, "{key} is in the example");
    text
}

/// `polycal report DATA ARGS --dcc DIR/refused.xml --out DIR/refused.html` is refused:
/// status 2, one `error:` line (returned), and neither document written.
fn refused(dir: &Path, data: &str, args: &[&str]) -> String {
    let path = dir.join("refused.xml");
    let html = dir.join("refused.html");
    let (path_text, html_text) = (path.to_str().unwrap(), html.to_str().unwrap());
    let mut all = vec!["report", data];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--dcc", path_text, "--out", html_text]);
    let out = polycal(&all);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(
        !path.exists() && !html.exists(),
        "{args:?}: a file was written"
    );
    stderr
}

/// Every key the schema needs, left out in turn: one `error:` line naming it, status 2,
/// no file; and a polygon run without a budget (no U) likewise.
#[test]
fn missing_metadata_is_refused_by_name_and_nothing_is_written() {
    let dir = temp_dir("missing");
    let full = std::fs::read_to_string(root().join(META)).unwrap();
    let meta = dir.join("meta.toml");
    let meta_text = meta.to_str().unwrap();
    for key in [
        "certificate",
        "customer",
        "customer_address",
        "customer_email",
        "laboratory",
        "laboratory_address",
        "laboratory_email",
        "country",
        "performance_location",
        "date_of_measurement",
        "artefact_manufacturer",
        "artefact_serial",
        "encoder_manufacturer",
        "encoder_serial",
    ] {
        std::fs::write(&meta, with_line(&full, key, None)).unwrap();
        let stderr = refused(&dir, DATA, &["--budget", BUDGET, "--meta", meta_text]);
        assert!(
            stderr.starts_with("error: cannot write the DCC: it needs `")
                && stderr.contains(&format!("`{key}`")),
            "{key}: {stderr}"
        );
    }
    // four keys missing: one refusal names all four, in the metadata file's order
    let four = ["customer_email", "country", "encoder_serial", "laboratory"];
    let text = four
        .iter()
        .fold(full.clone(), |t, key| with_line(&t, key, None));
    std::fs::write(&meta, text).unwrap();
    let stderr = refused(&dir, DATA, &["--budget", BUDGET, "--meta", meta_text]);
    let at: Vec<usize> = ["customer_email", "laboratory", "country", "encoder_serial"]
        .iter()
        .map(|key| {
            stderr
                .find(&format!("`{key}`"))
                .unwrap_or_else(|| panic!("{key} not named: {stderr}"))
        })
        .collect();
    assert!(at.windows(2).all(|w| w[0] < w[1]), "{stderr}");
    assert!(stderr.contains("add them"), "{stderr}");
    // no responsible person
    let text = with_line(&with_line(&full, "operator", None), "approved_by", None);
    std::fs::write(&meta, text).unwrap();
    let stderr = refused(&dir, DATA, &["--budget", BUDGET, "--meta", meta_text]);
    assert!(stderr.contains("`approved_by`"), "{stderr}");
    // a date the schema cannot take, named with its source
    let text = with_line(
        &full,
        "date_of_measurement",
        Some("date_of_measurement = \"3 Nov 2026\""),
    );
    let row = text
        .lines()
        .position(|l| l.starts_with("date_of_measurement"))
        .unwrap()
        + 1;
    std::fs::write(&meta, text).unwrap();
    let stderr = refused(&dir, DATA, &["--budget", BUDGET, "--meta", meta_text]);
    assert!(
        stderr.starts_with(&format!("error: {meta_text}:{row}:23: cannot write the DCC: date_of_measurement “3 Nov 2026” is not a date YYYY-MM-DD")),
        "{stderr}"
    );
    // from a comment line of the measurement file: its line and the value's column
    let data = dir.join("dated.csv");
    let original = std::fs::read_to_string(root().join(DATA)).unwrap();
    std::fs::write(
        &data,
        format!("# Date of measurement: 3.11.2026\n{original}"),
    )
    .unwrap();
    let without_date = with_line(&full, "date_of_measurement", None);
    std::fs::write(&meta, without_date).unwrap();
    let data_text = data.to_str().unwrap();
    let stderr = refused(&dir, data_text, &["--budget", BUDGET, "--meta", meta_text]);
    assert!(
        stderr.starts_with(&format!(
            "error: {data_text}:1:24: cannot write the DCC: date_of_measurement “3.11.2026”"
        )),
        "{stderr}"
    );
    // a polygon run without a budget has no U: refused, the flag named
    let stderr = refused(&dir, DATA, &["--meta", META]);
    assert!(
        stderr.contains("expanded uncertainty") && stderr.contains("--budget"),
        "{stderr}"
    );
    // the metadata's own checks: a country code and a place of the DCC's forms
    for (line, expected) in [
        ("country = \"Germany\"", "ISO 3166-1"),
        ("performance_location = \"lab\"", "laboratory, customer"),
    ] {
        let key = line.split(' ').next().unwrap();
        let text = with_line(&full, key, Some(line));
        std::fs::write(&meta, &text).unwrap();
        let row = text.lines().position(|l| l == line).unwrap() + 1;
        let column = line.find('"').unwrap() + 1;
        let stderr = refused(&dir, DATA, &["--budget", BUDGET, "--meta", meta_text]);
        assert!(
            stderr.starts_with(&format!("error: {meta_text}:{row}:{column}: "))
                && stderr.contains(expected),
            "{line}: {stderr}"
        );
    }
}

/// XML specials in every text come back as written; control characters are refused
/// where they are read, with their position; nothing is written.
#[test]
fn xml_specials_survive_and_control_characters_are_refused() {
    let dir = temp_dir("specials");
    let full = std::fs::read_to_string(root().join(META)).unwrap();
    let tricky = "Smith & Sons <Optics> \"Ltd\" 'GmbH' ]]> &amp; <!-- -- --> \u{feff}≤ ″ \u{202e}";
    let toml_value = tricky.replace('\\', "\\\\").replace('"', "\\\"");
    let customer_line = format!("customer = \"{toml_value}\"");
    let notes_line = format!("notes = \"{toml_value}\"");
    let text = with_line(
        &with_line(&full, "customer", Some(&customer_line)),
        "notes",
        Some(&notes_line),
    );
    let meta = dir.join("meta.toml");
    let meta_text = meta.to_str().unwrap();
    std::fs::write(&meta, &text).unwrap();
    let (_, xml) = dcc(
        &dir,
        "c.xml",
        &[DATA, "--budget", BUDGET, "--meta", meta_text],
    );
    let doc = Document::parse(&xml).unwrap();
    let customer = doc
        .descendants()
        .find(|n| n.tag_name().name() == "customer")
        .map(name_of)
        .unwrap();
    assert_eq!(customer, tricky);
    assert!(
        doc.descendants()
            .filter(|n| n.tag_name().name() == "content")
            .any(|n| n.text() == Some(tricky)),
        "the notes"
    );
    // a control character: refused at the metadata file's value
    let bad = with_line(&full, "customer", Some("customer = \"Acme\\u0001 Ltd\""));
    std::fs::write(&meta, &bad).unwrap();
    let row = bad
        .lines()
        .position(|l| l.starts_with("customer ="))
        .unwrap()
        + 1;
    let stderr = refused(&dir, DATA, &["--budget", BUDGET, "--meta", meta_text]);
    assert!(
        stderr.starts_with(&format!("error: {meta_text}:{row}:12: ")) && stderr.contains("U+0001"),
        "{stderr}"
    );
    // in a comment line of the measurement file: refused at its line and column
    let data = dir.join("data.csv");
    let original = std::fs::read_to_string(root().join(DATA)).unwrap();
    std::fs::write(&data, format!("# customer: Acme\u{1b}[31m\n{original}")).unwrap();
    let data_text = data.to_str().unwrap();
    let stderr = refused(&dir, data_text, &["--budget", BUDGET]);
    assert!(
        stderr.starts_with(&format!("error: {data_text}:1:17: ")) && stderr.contains("U+001B"),
        "{stderr}"
    );
}

/// A run with a drift: the diagnosis adds it, and the DCC carries the final model's β, α,
/// U and k (`polycal_finalModel…`) as `diagnose --budget` prints them, beside the
/// evaluation's, which stay `solve`'s.
#[test]
fn a_diagnosis_that_adds_effects_gives_the_final_models_results() {
    let dir = temp_dir("final");
    let data = dir.join("drift.csv");
    let out = polycal(&[
        "simulate",
        "--drift",
        "2:2.0",
        "--seed",
        "7",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0));
    let data_text = data.to_str().unwrap();
    let (_, text) = dcc(
        &dir,
        "c.xml",
        &[data_text, "--budget", BUDGET, "--diagnose", "--meta", META],
    );
    let doc = Document::parse(&text).unwrap();
    let diagnosed = json(&[
        "diagnose", data_text, "--budget", BUDGET, "--format", "json",
    ]);
    assert!(
        !diagnosed["effects"].as_array().unwrap().is_empty(),
        "the drift is found"
    );
    let after = &diagnosed["after"];
    let beta = si_list(
        &doc,
        "polycal_finalModelPitchDeviations",
        "Pitch deviation β",
    );
    beta.states(
        &numbers(&after["pitch_deviation"]),
        &numbers(&after["pitch_deviation_U"]),
        &numbers(&after["pitch_deviation_k"]),
        "final β",
    );
    let alpha = si_list(&doc, "polycal_finalModelEncoderErrors", "Encoder error α");
    alpha.states(
        &numbers(&after["encoder_error"]),
        &numbers(&after["encoder_error_U"]),
        &numbers(&after["encoder_error_k"]),
        "final α",
    );
    // the evaluation's results stay solve's (without the drift)
    let solve = json(&["solve", data_text, "--budget", BUDGET, "--format", "json"]);
    let evaluated = si_list(&doc, "polycal_pitchDeviations", "Pitch deviation β");
    evaluated.states(
        &numbers(&solve["pitch_deviation"]),
        &numbers(&solve["pitch_deviation_U"]),
        &numbers(&solve["pitch_deviation_k"]),
        "evaluated β",
    );
    assert_ne!(evaluated.values, beta.values);
    // the effect is named in the diagnosis
    assert!(text.contains("Effect found: drift"), "the drift in words");
}
