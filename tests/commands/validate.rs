//! `polycal validate` (docs/FORMAT.md §13.1): the bundled cases pass, the record's JSON
//! and HTML carry what an assessor needs, a corrupted reference fails with its case
//! named, a case that cannot be read is refused, and the references are what their
//! generator writes.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use sha2::{Digest, Sha256};

use crate::cli_support::{assert_status, polycal, temp_dir};

const CASES: &str = "examples/validation";

/// The bundled case directories, in name order.
fn case_dirs() -> Vec<PathBuf> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(CASES)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.join("case.toml").is_file())
        .collect();
    dirs.sort();
    dirs
}

fn json(out: &std::process::Output) -> Value {
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Every bundled case passes; the record states the build, the platform, the date, and
/// each case's command, deviation, tolerance and the SHA-256 of every file, which are
/// those of the files in examples/validation/.
#[test]
fn every_bundled_case_passes_and_the_record_names_its_files() {
    let out = polycal(&["validate", "--format", "json"]);
    assert_status(&out, 0);
    let record = json(&out);
    assert_eq!(record["version"], env!("CARGO_PKG_VERSION"));
    for key in ["commit", "compiler", "target", "profile"] {
        assert!(
            record["build"][key].as_str().is_some_and(|s| !s.is_empty()),
            "{key}"
        );
    }
    assert!(
        record["build"]["compiler"]
            .as_str()
            .unwrap()
            .starts_with("rustc ")
    );
    assert!(
        record["build"]["features"]
            .as_array()
            .unwrap()
            .contains(&"cli".into())
    );
    assert_eq!(record["platform"]["os"], std::env::consts::OS);
    assert!(polycal::clock::is_date(
        &record["date"].as_str().unwrap()[..10]
    ));
    let cases = record["cases"].as_array().unwrap();
    let dirs = case_dirs();
    assert_eq!(cases.len(), dirs.len());
    assert_eq!(record["passed"], dirs.len());
    assert_eq!(record["failed"], 0);
    let mut evaluations = std::collections::BTreeSet::new();
    for (case, dir) in cases.iter().zip(&dirs) {
        let name = dir.file_name().unwrap().to_str().unwrap();
        assert_eq!(case["name"], name);
        assert_eq!(case["pass"], true, "{case}");
        assert!(case["command"].as_str().unwrap().starts_with("polycal "));
        let (d, t) = (
            case["deviation"].as_f64().unwrap(),
            case["tolerance"].as_f64().unwrap(),
        );
        assert!(d <= t && t > 0.0, "{name}: {d} > {t}");
        assert!(case["compared"].as_u64().unwrap() > 0, "{name}");
        evaluations.insert(case["evaluation"].as_str().unwrap().to_string());
        let mut files: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        let listed = case["files"].as_array().unwrap();
        assert_eq!(listed.len(), files.len(), "{name}");
        for (entry, file) in listed.iter().zip(&files) {
            assert_eq!(entry["name"], file.file_name().unwrap().to_str().unwrap());
            let digest: String = Sha256::digest(std::fs::read(file).unwrap())
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect();
            assert_eq!(entry["sha256"], digest.as_str(), "{}", file.display());
        }
    }
    let expected = [
        "budget",
        "compare",
        "diagnose",
        "kc",
        "monte-carlo",
        "selfcal",
        "solve",
    ];
    assert_eq!(
        evaluations,
        expected.iter().map(|s| s.to_string()).collect()
    );
}

/// Copies the bundled cases to `dir`.
fn copy_cases(dir: &Path) {
    for case in case_dirs() {
        let to = dir.join(case.file_name().unwrap());
        std::fs::create_dir_all(&to).unwrap();
        for file in std::fs::read_dir(&case).unwrap() {
            let file = file.unwrap().path();
            std::fs::copy(&file, to.join(file.file_name().unwrap())).unwrap();
        }
    }
}

/// One reference number moved by a part in 10⁹ (far above the 1e-12 tolerance, far
/// below anything a reader would see) fails that case, named, with status 1; the other
/// cases still pass.
#[test]
fn a_corrupted_reference_fails_its_case_by_name() {
    let dir = temp_dir("validate-corrupted");
    copy_cases(&dir);
    let path = dir.join("solve-3ac").join("reference.json");
    let mut reference: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let value = reference["values"]["encoder_error"][4].as_f64().unwrap();
    reference["values"]["encoder_error"][4] = (value * (1.0 + 1e-9)).into();
    std::fs::write(&path, serde_json::to_vec(&reference).unwrap()).unwrap();
    let cases = dir.to_str().unwrap();
    let out = polycal(&["validate", "--cases", cases, "--format", "json"]);
    assert_status(&out, 1);
    let record = json(&out);
    assert_eq!(record["failed"], 1);
    for case in record["cases"].as_array().unwrap() {
        let corrupted = case["name"] == "solve-3ac";
        assert_eq!(case["pass"], !corrupted, "{case}");
        if corrupted {
            assert_eq!(case["worst"], "encoder_error[4]");
            assert!(case["deviation"].as_f64().unwrap() > 1e-10);
        }
    }
    let table = polycal(&["validate", "--cases", cases]);
    assert_status(&table, 1);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(text.contains("FAIL solve-3ac: largest deviation"), "{text}");
    assert!(text.contains("at encoder_error[4]"), "{text}");
    // a reference that lacks a value polycal prints is no failure; one polycal lacks is
    let mut missing = reference.clone();
    missing["values"]["no_such_field"] = 1.0.into();
    std::fs::write(&path, serde_json::to_vec(&missing).unwrap()).unwrap();
    let out = polycal(&["validate", "--cases", cases, "--format", "json"]);
    assert_status(&out, 1);
    let case = json(&out)["cases"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "solve-3ac")
        .cloned()
        .unwrap();
    assert_eq!(
        case["problem"],
        "no_such_field: missing from polycal's output"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--out` writes the record as HTML: the build, each case with its command and the
/// SHA-256 of its files, the verdict, and how to reproduce it; the date from
/// SOURCE_DATE_EPOCH.
#[test]
fn the_html_record_states_every_case() {
    let dir = temp_dir("validate-html");
    let html_path = dir.join("validation.html");
    let out = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args([
            "validate",
            "--format",
            "json",
            "--out",
            html_path.to_str().unwrap(),
        ])
        .env("SOURCE_DATE_EPOCH", "1700000000")
        .output()
        .unwrap();
    assert_status(&out, 0);
    let record = json(&out);
    assert_eq!(record["date"], "2023-11-14T22:13:20.000Z");
    let html = std::fs::read_to_string(&html_path).unwrap();
    let total = record["cases"].as_array().unwrap().len();
    assert!(html.contains(&format!("All {total} cases passed.")));
    assert!(html.contains("2023-11-14T22:13:20.000Z"));
    assert!(html.contains(record["build"]["commit"].as_str().unwrap()));
    assert!(html.contains("python3 scripts/validation/reference.py"));
    for case in record["cases"].as_array().unwrap() {
        assert!(html.contains(&format!("id=\"{}\"", case["name"].as_str().unwrap())));
        assert!(html.contains(case["command"].as_str().unwrap()));
        for file in case["files"].as_array().unwrap() {
            assert!(html.contains(file["sha256"].as_str().unwrap()));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A directory without cases, and a case.toml that cannot be read, are refused with
/// status 2 and one `error:` line naming the file, line and column.
#[test]
fn cases_that_cannot_be_read_are_refused() {
    let dir = temp_dir("validate-refused");
    let out = polycal(&["validate", "--cases", dir.to_str().unwrap()]);
    assert_status(&out, 2);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("error: --cases: ") && stderr.contains("no case"),
        "{stderr}"
    );
    copy_cases(&dir);
    let toml = dir.join("solve-3ac").join("case.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    std::fs::write(
        &toml,
        text.replace("tolerance = 1e-12", "tolerance = \"small\""),
    )
    .unwrap();
    let out = polycal(&["validate", "--cases", dir.to_str().unwrap()]);
    assert_status(&out, 2);
    let stderr = String::from_utf8(out.stderr).unwrap();
    let line = text
        .lines()
        .position(|l| l.starts_with("tolerance ="))
        .unwrap()
        + 1;
    let at = format!("solve-3ac/case.toml:{line}:13: ");
    assert!(stderr.contains(&at), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The bundled references are exactly what their generator writes: rerun (about 3 s), it
/// would change no byte.
#[test]
fn the_generator_reproduces_the_bundled_references() {
    let run = Command::new("python3")
        .args(["scripts/validation/reference.py", "--check"])
        .output();
    match run {
        Ok(out) => assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => crate::skip_support::missing(
            "python3",
            "the bundled validation references are not recomputed",
            "any Python 3",
            "POLYCAL_REQUIRE_PYTHON",
            &e.to_string(),
        ),
    }
}
