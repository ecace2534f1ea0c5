//! What a document polycal writes depends on (docs/FORMAT.md §10.2): `SOURCE_DATE_EPOCH`
//! makes the report reproducible, and no document — the HTML report, the DCC, the `--plot`
//! figures — names a directory of the machine that wrote it.

use std::path::Path;
use std::process::Command;

use scraper::Html;

use crate::report_support::{BUDGET, DATA, META, REFERENCE, TRUTH, select, temp_dir};

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
