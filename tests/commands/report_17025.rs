//! What a certificate states beside its numbers (issue 48; docs/FORMAT.md §10): the u
//! shown beside U and k is the combined standard uncertainty behind U — read back from
//! the HTML report and from the DCC, held to the result CSV's u_c of `solve --budget` and
//! to k·u formed here —; the ISO/IEC 17025 7.8 items (condition of the item, date of
//! receipt as the DCC's `receiptDate`, date of issue as a day, the statement that the
//! results relate only to the items calibrated) with the DCC still schema-valid, and a
//! malformed date refused at its file, line and column; a row whose difference rounds to
//! its U shows the digits that decide its mark; with no effect found the final model is
//! neither repeated in tables nor drawn as a second identical panel; the En figure's
//! legend keys only what it shows, one marker per series.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use roxmltree::Document;
use scraper::{ElementRef, Html, Selector};

const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const REFERENCE: &str = "examples/data/polygon24-shift-angle.result.csv";
const META: &str = "examples/report/meta.toml";

use crate::document_support;

use crate::dcc_schema::assert_valid;
use crate::document_support::{assert_gum_rounded, assert_k_rounded, polycal, shown_number};

fn temp_dir(name: &str) -> PathBuf {
    document_support::temp_dir("report-17025", name)
}

/// Runs `polycal report ARGS --out DIR/report.html [--dcc DIR/certificate.xml]` with the
/// environment `env`; returns the HTML text and the DCC text (validated) when asked.
fn documents(
    dir: &Path,
    args: &[&str],
    dcc: bool,
    env: &[(&str, &str)],
) -> (String, Option<String>) {
    let (html, xml) = (dir.join("report.html"), dir.join("certificate.xml"));
    let mut command = Command::new(env!("CARGO_BIN_EXE_polycal"));
    command
        .arg("report")
        .args(args)
        .arg("--out")
        .arg(&html)
        .current_dir(env!("CARGO_MANIFEST_DIR"));
    if dcc {
        command.arg("--dcc").arg(&xml);
    }
    for (key, value) in env {
        command.env(key, value);
    }
    let out = command.output().unwrap();
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let xml = dcc.then(|| {
        assert_valid(&xml);
        std::fs::read_to_string(&xml).unwrap()
    });
    (std::fs::read_to_string(&html).unwrap(), xml)
}

fn select<'a>(html: &'a Html, css: &str) -> Vec<ElementRef<'a>> {
    html.select(&Selector::parse(css).unwrap()).collect()
}

fn text(e: &ElementRef) -> String {
    e.text().collect::<String>()
}

/// One unit of the last digit of a number's text: 0.01 for `0.11`, 1 for `13`.
fn unit(text: &str) -> f64 {
    10f64.powi(-text.split_once('.').map_or(0, |(_, d)| d.len() as i32))
}

/// The result CSV of `solve --budget`: (quantity, index) → (U, u, k).
fn result_csv() -> BTreeMap<(String, u32), (f64, f64, f64)> {
    let out = polycal(&["solve", DATA, "--budget", BUDGET, "--format", "csv"]);
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("quantity,index,value,U,u,k,angle_deg"),
        "the result CSV's columns"
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let n = |i: usize| f[i].parse::<f64>().unwrap();
            (
                (f[0].to_string(), f[1].parse().unwrap()),
                (n(3), n(4), n(5)),
            )
        })
        .collect()
}

/// Asserts that the shown u, U and k say U = k·u to rounding, and that this u is the
/// CSV's u_c: U shown is k·u_c (formed here) rounded up to two significant digits, u shown
/// is u_c rounded up, and u_shown·k_shown lies within the rounding of U_shown.
fn assert_u_behind(
    u_text: Option<&str>,
    big_u_text: &str,
    k_text: &str,
    csv: (f64, f64, f64),
    at: &str,
) {
    let (_, u_c, k) = csv;
    let expanded = k * u_c; // independent: U = k·u_c formed here
    let shown_big_u = shown_number(big_u_text);
    assert!(
        shown_big_u >= expanded * (1.0 - 1e-12)
            && shown_big_u - expanded < unit(big_u_text) * (1.0 + 1e-9),
        "{at}: U {big_u_text} is not k·u_c = {k}·{u_c} rounded up"
    );
    assert_k_rounded(k_text, k, at);
    let shown_k = shown_number(k_text);
    // the u behind the shown U and k: U/k within the rounding of both
    let slack = unit(big_u_text) + u_c * unit(k_text);
    assert!(
        (shown_big_u - shown_k * u_c).abs() <= slack,
        "{at}: U {big_u_text} / k {k_text} is not u_c {u_c}"
    );
    if let Some(u_text) = u_text {
        let shown_u = shown_number(u_text);
        assert!(
            shown_u >= u_c * (1.0 - 1e-12) && shown_u - u_c < unit(u_text) * (1.0 + 1e-9),
            "{at}: u {u_text} is not u_c {u_c} rounded up"
        );
        assert!(
            (shown_u * shown_k - shown_big_u).abs() <= unit(big_u_text) + shown_k * unit(u_text),
            "{at}: u {u_text} × k {k_text} is not U {big_u_text} to rounding"
        );
    }
}

#[test]
fn the_u_beside_u_and_k_is_the_u_behind_u_in_the_html_and_the_dcc() {
    let dir = temp_dir("u");
    let (html_text, xml) = documents(&dir, &[DATA, "--budget", BUDGET, "--meta", META], true, &[]);
    let csv = result_csv();
    let html = Html::parse_document(&html_text);
    let td = Selector::parse("td").unwrap();
    let mut checked = 0;
    // (table id, CSV quantity, column of the value)
    for (id, quantity, col) in [
        ("pitch-deviation", "pitch_deviation", 1),
        ("face-deviation", "face_deviation", 1),
        ("encoder-error", "encoder_error", 2),
        ("setup-error", "setup_error", 1),
    ] {
        let headings: Vec<String> = select(&html, &format!("table#{id} thead th"))
            .iter()
            .map(text)
            .collect();
        // the coverage factor is the one column headed k; the index is not "face k"
        assert_eq!(
            headings.iter().filter(|h| h.contains('k')).count(),
            1,
            "{id}: {headings:?}"
        );
        assert!(
            headings.contains(&"u / ″".to_string()),
            "{id}: {headings:?}"
        );
        for row in select(&html, &format!("table#{id} > tbody > tr")) {
            let cells: Vec<ElementRef> = row.select(&td).collect();
            let index_text = text(&cells[0]);
            // the setup error of mounting 1, autocollimator A is the CSV's index A
            let index: u32 = index_text.rsplit(" / ").next().unwrap().parse().unwrap();
            let Some(&row_csv) = csv.get(&(quantity.to_string(), index)) else {
                // φ[N] = 0 by definition: not in the CSV, no uncertainty
                assert_eq!((quantity, index), ("face_deviation", 24));
                continue;
            };
            let at = format!("HTML {id}[{index}]");
            let u_cell = &cells[col + 1];
            let u_value: f64 = u_cell.value().attr("data-value").unwrap().parse().unwrap();
            assert_eq!(u_value, row_csv.1, "{at}: u is the CSV's u_c");
            assert_u_behind(
                Some(&text(u_cell)),
                &text(&cells[col + 2]),
                &text(&cells[col + 3]),
                row_csv,
                &at,
            );
            checked += 1;
        }
    }
    // 24 β, 23 φ, 24 α, 2 setup errors
    assert_eq!(checked, 24 + 23 + 24 + 2);

    // the DCC: every U and k read back, the u behind them the CSV's u_c
    let xml = xml.unwrap();
    let doc = Document::parse(&xml).unwrap();
    let mut checked = 0;
    for (ref_type, name, quantity, first) in [
        (
            "polycal_pitchDeviations",
            "Pitch deviation β",
            "pitch_deviation",
            1,
        ),
        (
            "polycal_faceDeviations",
            "Face deviation φ",
            "face_deviation",
            1,
        ),
        (
            "polycal_encoderErrors",
            "Encoder error α",
            "encoder_error",
            0,
        ),
        ("polycal_setupErrors", "Setup error", "setup_error", 1),
    ] {
        let result = doc
            .descendants()
            .find(|n| n.tag_name().name() == "result" && n.attribute("refType") == Some(ref_type))
            .unwrap_or_else(|| panic!("no result {ref_type}"));
        let quantity_node = result
            .descendants()
            .find(|n| {
                n.tag_name().name() == "quantity"
                    && n.descendants()
                        .any(|c| c.tag_name().name() == "content" && c.text() == Some(name))
            })
            .unwrap_or_else(|| panic!("{ref_type}: no {name}"));
        let list = |element: &str| -> Vec<String> {
            quantity_node
                .descendants()
                .find(|n| n.tag_name().name() == element)
                .and_then(|n| n.text())
                .unwrap_or_else(|| panic!("{ref_type}: no {element}"))
                .split_whitespace()
                .map(str::to_string)
                .collect()
        };
        let (big_u, k) = (list("uncertaintyXMLList"), list("coverageFactorXMLList"));
        assert_eq!(big_u.len(), k.len(), "{ref_type}");
        for (i, (big_u, k)) in big_u.iter().zip(&k).enumerate() {
            let index = first + i as u32;
            let row_csv = csv[&(quantity.to_string(), index)];
            assert_u_behind(None, big_u, k, row_csv, &format!("DCC {ref_type}[{index}]"));
            checked += 1;
        }
    }
    assert_eq!(checked, 24 + 23 + 24 + 2);
}

/// The example metadata with `key`'s line replaced by `line` (or removed), written into
/// `dir`.
fn meta_with(dir: &Path, replace: &[(&str, Option<&str>)]) -> PathBuf {
    let mut text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(META)).unwrap();
    for (key, line) in replace {
        let old = text
            .lines()
            .find(|l| l.starts_with(&format!("{key} = ")))
            .unwrap_or_else(|| panic!("no {key} in {META}"))
            .to_string();
        text = text.replace(
            &format!("{old}\n"),
            &line.map_or(String::new(), |l| format!("{l}\n")),
        );
    }
    let path = dir.join("meta.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn the_17025_items_are_stated_and_the_dcc_stays_valid() {
    let dir = temp_dir("items");
    let meta = meta_with(
        &dir,
        &[
            (
                "item_condition",
                Some("item_condition = \"Face 7 scratched at its edge, usable\""),
            ),
            ("date_of_receipt", Some("date_of_receipt = \"2026-10-29\"")),
            ("date_of_issue", Some("date_of_issue = \"2026-11-05\"")),
        ],
    );
    let meta_text = meta.to_str().unwrap();
    let (html_text, xml) = documents(
        &dir,
        &[DATA, "--budget", BUDGET, "--meta", meta_text],
        true,
        &[],
    );
    let html = Html::parse_document(&html_text);
    assert_eq!(text(&select(&html, "#date-of-issue")[0]), "2026-11-05");
    let value = |key: &str| text(&select(&html, &format!("tr[data-key={key}] td"))[0]);
    assert_eq!(
        value("item_condition"),
        "Face 7 scratched at its edge, usable"
    );
    assert_eq!(value("date_of_receipt"), "2026-10-29");
    assert_eq!(value("date_of_issue"), "2026-11-05");
    let relate = text(&select(&html, "#results-relate")[0]);
    assert!(
        relate.starts_with("The results relate only to the items calibrated: "),
        "{relate}"
    );
    assert!(
        relate.contains("P-24/7") && relate.contains("RT-300-0042"),
        "{relate}"
    );
    // the DCC (valid, checked above): receiptDate in coreData between the identifier
    // and the performance dates, and the statements
    let xml = xml.unwrap();
    let doc = Document::parse(&xml).unwrap();
    let core: Vec<(String, String)> = doc
        .descendants()
        .find(|n| n.tag_name().name() == "coreData")
        .unwrap()
        .children()
        .filter(|n| n.is_element())
        .map(|n| {
            (
                n.tag_name().name().to_string(),
                n.text().unwrap_or_default().to_string(),
            )
        })
        .collect();
    let at = |name: &str| {
        core.iter()
            .position(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("no {name}"))
    };
    assert_eq!(core[at("receiptDate")].1, "2026-10-29");
    assert!(
        at("uniqueIdentifier") < at("receiptDate")
            && at("receiptDate") < at("beginPerformanceDate")
    );
    let statement = |ref_type: &str| {
        doc.descendants()
            .find(|n| {
                n.tag_name().name() == "statement" && n.attribute("refType") == Some(ref_type)
            })
            .unwrap_or_else(|| panic!("no statement {ref_type}"))
    };
    let issue = statement("polycal_dateOfIssue");
    let date = issue
        .descendants()
        .find(|n| n.tag_name().name() == "date")
        .unwrap();
    assert_eq!(date.text(), Some("2026-11-05"));
    let content = |ref_type: &str| -> String {
        statement(ref_type)
            .descendants()
            .filter(|n| n.tag_name().name() == "content")
            .filter_map(|n| n.text())
            .collect()
    };
    assert!(content("polycal_itemCondition").contains("Face 7 scratched at its edge, usable"));
    assert_eq!(content("polycal_resultsRelateToItem"), relate);

    // no date of issue given: the day the report is written (UTC); SOURCE_DATE_EPOCH
    // 1 700 000 000 s is 2023-11-14T22:13:20Z (19 675 days and 80 000 s, by hand)
    let dir = temp_dir("issue-default");
    let meta = meta_with(&dir, &[("date_of_issue", None)]);
    let args = [DATA, "--budget", BUDGET, "--meta", meta.to_str().unwrap()];
    let (html_text, xml) = documents(&dir, &args, true, &[("SOURCE_DATE_EPOCH", "1700000000")]);
    let html = Html::parse_document(&html_text);
    assert_eq!(text(&select(&html, "#date-of-issue")[0]), "2023-11-14");
    assert!(xml.unwrap().contains("<dcc:date>2023-11-14</dcc:date>"));
    // and without it, today: the day coreutils' `date -u` gives (before and after, in
    // case the test runs across midnight)
    let today = || {
        String::from_utf8(
            Command::new("date")
                .args(["-u", "+%Y-%m-%d"])
                .output()
                .unwrap()
                .stdout,
        )
        .unwrap()
        .trim()
        .to_string()
    };
    let before = today();
    let (html_text, _) = documents(&dir, &args, false, &[]);
    let shown = text(&select(&Html::parse_document(&html_text), "#date-of-issue")[0]);
    assert!(
        shown == before || shown == today(),
        "{shown}, not today {before}"
    );
}

/// Runs a report expected to be refused; returns its standard error.
fn refused(dir: &Path, data: &str, meta: &Path) -> String {
    let out = polycal(&[
        "report",
        data,
        "--meta",
        meta.to_str().unwrap(),
        "--out",
        dir.join("r.html").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        !dir.join("r.html").exists(),
        "a refused report is not written"
    );
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    stderr
}

#[test]
fn a_malformed_date_is_one_error_line_at_its_file_line_and_column() {
    let dir = temp_dir("bad-date");
    // line 2, the value's opening quote at column 19 (`date_of_receipt = ` is 18 wide)
    let meta = dir.join("m.toml");
    std::fs::write(
        &meta,
        "customer = \"A\"\ndate_of_receipt = \"2026-02-30\"\n",
    )
    .unwrap();
    let stderr = refused(&dir, DATA, &meta);
    let want = format!(
        "error: {}:2:19: date_of_receipt “2026-02-30” is not a date YYYY-MM-DD",
        meta.display()
    );
    assert!(stderr.starts_with(&want), "{stderr}");
    std::fs::write(&meta, "date_of_issue = \"5 Nov 2026\"\n").unwrap();
    let stderr = refused(&dir, DATA, &meta);
    assert!(
        stderr.starts_with(&format!("error: {}:1:17: date_of_issue", meta.display())),
        "{stderr}"
    );
    // a comment line of the measurement file: `# date of issue: ` is 17 wide
    let data = dir.join("m.csv");
    let original =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(DATA)).unwrap();
    std::fs::write(&data, format!("# date of issue: 2026-11-31\n{original}")).unwrap();
    std::fs::write(&meta, "customer = \"A\"\n").unwrap();
    let stderr = refused(&dir, data.to_str().unwrap(), &meta);
    assert!(
        stderr.starts_with(&format!(
            "error: {}:1:18: date_of_issue “2026-11-31”",
            data.display()
        )),
        "{stderr}"
    );
}

#[test]
fn a_difference_that_rounds_to_its_u_shows_the_digits_that_decide() {
    let dir = temp_dir("rounding");
    // the reference: this calibration's own result file with β[1] moved by 0.1452″, so
    // that a − b = 0.1452 against U(a − b) = √2·U_a = √2 · 0.10218… = 0.144504 (U_b = U_a):
    // |En| = 1.0048 > 1, while GUM 7.2.6 alone states both as 0.15 (U rounded up, the
    // difference to nearest) and En as 1.00
    let csv = result_csv();
    let (big_u_a, _, _) = csv[&("pitch_deviation".to_string(), 1)];
    let out = polycal(&["solve", DATA, "--budget", BUDGET, "--format", "csv"]);
    let mut reference = String::new();
    for line in String::from_utf8(out.stdout).unwrap().lines() {
        if let Some(rest) = line.strip_prefix("pitch_deviation,1,") {
            let (value, tail) = rest.split_once(',').unwrap();
            let a: f64 = value.parse().unwrap();
            reference.push_str(&format!("pitch_deviation,1,{},{tail}\n", a - 0.1452));
        } else {
            reference.push_str(line);
            reference.push('\n');
        }
    }
    let reference_path = dir.join("reference.csv");
    std::fs::write(&reference_path, reference).unwrap();
    let (html_text, _) = documents(
        &dir,
        &[
            DATA,
            "--budget",
            BUDGET,
            "--reference",
            reference_path.to_str().unwrap(),
        ],
        false,
        &[],
    );
    let html = Html::parse_document(&html_text);
    let td = Selector::parse("td").unwrap();
    let headings: Vec<String> = select(&html, "table#comparison-rows thead th")
        .iter()
        .map(text)
        .collect();
    assert_eq!(
        headings,
        [
            "Quantity",
            "Index",
            "angle / °",
            "a / ″",
            "Ua / ″",
            "b / ″",
            "Ub / ″",
            "a − b / ″",
            "U(a − b) / ″",
            "En"
        ]
    );
    let rows = select(&html, "table#comparison-rows > tbody > tr");
    let row = rows
        .iter()
        .find(|r| {
            let cells: Vec<String> = r.select(&td).map(|c| text(&c)).collect();
            cells[0] == "pitch_deviation" && cells[1] == "1"
        })
        .unwrap();
    assert_eq!(
        row.value().attr("class"),
        Some("fail"),
        "|En| > 1 is marked"
    );
    let cells: Vec<String> = row.select(&td).map(|c| text(&c)).collect();
    // by hand: 0.144504 rounded up at 10⁻⁴ is 0.1446; 0.1452 stays 0.1452; En 1.0048 is
    // 1.005 at three decimals
    let u_d = big_u_a.hypot(big_u_a);
    assert!((u_d - 0.144504).abs() < 1e-6, "{u_d}");
    assert_eq!(
        (cells[7].as_str(), cells[8].as_str(), cells[9].as_str()),
        ("0.1452", "0.1446", "1.005")
    );
    assert!(shown_number(&cells[7]) > shown_number(&cells[8]));
    // every other row: the shown difference and U(a − b) say what its mark says, and
    // each value is stated at its U's decimal place, as a result is
    for row in &rows {
        let cells: Vec<String> = row.select(&td).map(|c| text(&c)).collect();
        let en: f64 = row
            .select(&td)
            .nth(9)
            .unwrap()
            .value()
            .attr("data-value")
            .unwrap()
            .parse()
            .unwrap();
        let (d, u) = (shown_number(&cells[7]).abs(), shown_number(&cells[8]));
        assert_eq!(d > u, en.abs() > 1.0, "{cells:?}");
        assert_eq!(
            shown_number(&cells[9]).abs() > 1.0,
            en.abs() > 1.0,
            "{cells:?}"
        );
        // a with U_a as GUM 7.2.6 states a result
        let data = |c: usize| -> f64 {
            row.select(&td)
                .nth(c)
                .unwrap()
                .value()
                .attr("data-value")
                .unwrap()
                .parse()
                .unwrap()
        };
        assert_gum_rounded(
            &cells[3],
            &cells[4],
            data(3),
            data(4),
            &format!("{cells:?}"),
        );
    }
    // the figure's legend keys what it shows: a row beyond ±1 and rows within
    let legend = figure_legend(&html, "figure-compare-pitch-deviation-difference");
    assert!(legend.contains(&"En, |En| > 1".to_string()), "{legend:?}");
    assert!(legend.contains(&"En, |En| ≤ 1".to_string()), "{legend:?}");
}

/// The texts of a figure's legend, in order, with the shape each key draws
/// (`circle`, `rect`, `polygon`, `line`) before its text.
fn figure_legend(html: &Html, figure_id: &str) -> Vec<String> {
    legend_keys(html, figure_id)
        .into_iter()
        .map(|(_, t)| t)
        .collect()
}

fn legend_keys(html: &Html, figure_id: &str) -> Vec<(String, String)> {
    let legend = select(html, &format!("figure#{figure_id} g.legend"));
    assert_eq!(legend.len(), 1, "{figure_id}: one legend");
    let mut keys = Vec::new();
    let mut shape = String::new();
    for child in legend[0].children().filter_map(ElementRef::wrap) {
        match child.value().name() {
            "text" => keys.push((std::mem::take(&mut shape), text(&child))),
            "g" => {
                shape = child
                    .children()
                    .filter_map(ElementRef::wrap)
                    .map(|c| {
                        format!(
                            "{}{}",
                            c.value().name(),
                            c.value().attr("fill").map_or("", |f| if f == "none" {
                                "-open"
                            } else {
                                "-filled"
                            })
                        )
                    })
                    .collect::<Vec<_>>()
                    .join("+");
            }
            other => shape = other.to_string(),
        }
    }
    keys
}

#[test]
fn with_no_effect_found_the_final_model_is_said_once() {
    let dir = temp_dir("no-effect");
    let (html_text, _) = documents(
        &dir,
        &[
            DATA,
            "--budget",
            BUDGET,
            "--diagnose",
            "--reference",
            REFERENCE,
        ],
        false,
        &[],
    );
    let html = Html::parse_document(&html_text);
    // the example run: no effect found (diagnose's JSON)
    let diagnosed = document_support::json(&["diagnose", DATA, "--format", "json"]);
    assert_eq!(diagnosed["effects"].as_array().map(Vec::len), Some(0));
    assert!(
        select(&html, "table[id^=final-]").is_empty(),
        "the final model's tables repeated"
    );
    assert!(text(&select(&html, "#final-model-same")[0]).contains("final model is the base model"));
    // one panel per residual figure, every reading of its autocollimator in it
    let residuals = &diagnosed["residuals"]["ac"];
    for ac in [1u64, 2] {
        let id = format!("figure-diagnose-residuals-ac{ac}");
        assert!(
            select(&html, &format!("figure#{id} [data-panel=after]")).is_empty(),
            "ac {ac}: a second panel"
        );
        let readings = residuals
            .as_array()
            .unwrap()
            .iter()
            .filter(|a| a.as_u64() == Some(ac))
            .count();
        assert_eq!(
            select(&html, &format!("figure#{id} g.point[data-series=before]")).len(),
            readings
        );
        let legend = figure_legend(&html, &id);
        assert_eq!(legend, ["residual (base model = final model)"]);
    }
    // the comparison agrees everywhere (|En| ≤ 1): its En figure keys no |En| > 1, and
    // no two of its series share a marker
    let keys = legend_keys(&html, "figure-compare-pitch-deviation-difference");
    let texts: Vec<&str> = keys.iter().map(|(_, t)| t.as_str()).collect();
    assert!(!texts.iter().any(|t| t.contains("|En| > 1")), "{texts:?}");
    let markers: Vec<&str> = keys
        .iter()
        .filter(|(_, t)| t == "a − b" || t.starts_with("En, "))
        .map(|(shape, _)| shape.as_str())
        .collect();
    assert_eq!(markers.len(), 2, "{keys:?}");
    assert_ne!(markers[0], markers[1], "{keys:?}");
    // the budget's combination: each number on a labelled line, none under "Index / %"
    let foot: Vec<String> = select(&html, "table#budget-pitch-deviation tfoot tr")
        .iter()
        .map(text)
        .collect();
    assert_eq!(foot.len(), 4, "{foot:?}");
    assert!(
        foot[3].starts_with("Expanded uncertainty U = k·uc / ″"),
        "{foot:?}"
    );
    assert!(
        !foot.iter().any(|l| l.contains("U = 0.")),
        "a U without its unit: {foot:?}"
    );
}

#[test]
fn with_effects_found_the_final_model_is_shown_with_its_u_behind_u() {
    let dir = temp_dir("effects");
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
    let (html_text, _) = documents(
        &dir,
        &[data_text, "--budget", BUDGET, "--diagnose"],
        false,
        &[],
    );
    let html = Html::parse_document(&html_text);
    let diagnosed = document_support::json(&[
        "diagnose", data_text, "--budget", BUDGET, "--format", "json",
    ]);
    let effects = diagnosed["effects"].as_array().unwrap();
    assert!(!effects.is_empty(), "the drift is found");
    assert!(select(&html, "#final-model-same").is_empty());
    // the final model's β: u is the budget's u_c of the final model (diagnose --budget's
    // after.uncertainty), u·k is U to rounding
    let after = &diagnosed["after"];
    let floats = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (u_c, k, big_u) = (
        floats(&after["uncertainty"]["pitch_deviation"]["u"]),
        floats(&after["pitch_deviation_k"]),
        floats(&after["pitch_deviation_U"]),
    );
    let td = Selector::parse("td").unwrap();
    let rows = select(&html, "table#final-pitch-deviation > tbody > tr");
    assert_eq!(rows.len(), u_c.len());
    for (i, row) in rows.iter().enumerate() {
        let cells: Vec<ElementRef> = row.select(&td).collect();
        let u_value: f64 = cells[2]
            .value()
            .attr("data-value")
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(u_value, u_c[i], "final β[{}]: u", i + 1);
        assert!((k[i] * u_c[i] - big_u[i]).abs() <= 1e-12 * big_u[i]);
        assert_u_behind(
            Some(&text(&cells[2])),
            &text(&cells[3]),
            &text(&cells[4]),
            (big_u[i], u_c[i], k[i]),
            &format!("final β[{}]", i + 1),
        );
    }
    // an effect's u is the fit's own, labelled so, its value stated with it (GUM 7.2.6)
    let headings: Vec<String> = select(&html, "table#effects thead th")
        .iter()
        .map(text)
        .collect();
    assert_eq!(headings[3], "u of the fit (type A)");
    let effect_row = &select(&html, "table#effects > tbody > tr")[0];
    let cells: Vec<ElementRef> = effect_row.select(&td).collect();
    let (value, u) = (
        effects[0]["value"].as_f64().unwrap(),
        effects[0]["u"].as_f64().unwrap(),
    );
    document_support::assert_gum_rounded(&text(&cells[2]), &text(&cells[3]), value, u, "effect");
    // the residual figures: before and after, two panels
    for ac in [1, 2] {
        let id = format!("figure-diagnose-residuals-ac{ac}");
        assert!(
            !select(&html, &format!("figure#{id} g.point[data-series=after]")).is_empty(),
            "ac {ac}"
        );
    }
}
