//! `polycal report` (docs/FORMAT.md §10), its sections and metadata: each optional
//! section is there exactly when asked for; missing metadata is shown as missing; the
//! measurement file's comments are metadata, a conflict said; the SHA-256 of every input
//! equals an independent computation (coreutils' `sha256sum`); a run directory gives the
//! instruments and the run.

use std::path::Path;
use std::process::Command;

use scraper::Selector;

use crate::document_support::{json, polycal};
use crate::report_support::{BUDGET, DATA, META, assert_results, report, select, temp_dir};

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
