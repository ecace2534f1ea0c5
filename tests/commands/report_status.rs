//! `polycal report` (docs/FORMAT.md §10), its exit status: the status follows the
//! verdicts (a failing comparison and an inadequate model give 1), and bad input is one
//! `error:` line with status 2.

use crate::document_support::polycal;
use crate::report_support::{BUDGET, DATA, REFERENCE, report, select, temp_dir};

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

    // structure no effect explains (as tests/commands/cli_diagnose.rs: a slow wave on
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
