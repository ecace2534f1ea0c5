//! A pilot's Draft A with `polycal kc --anonymise KEY.csv` (docs/FORMAT.md §12): no
//! laboratory's name nor its file's path in any output — table, JSON, CSV, figures, and
//! the report and DCC made from the JSON —, the key in KEY.csv alone and read back for
//! the next draft, the letters drawn at random; the refusals; `--help` naming every kc
//! figure; a huge χ² written readably in the table and the report.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

use serde_json::Value;

use crate::document_support::{polycal, temp_dir};

const KC: &str = "examples/data/kc";
const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";

/// The bundled laboratories A … F under names and file names of their own (F is left
/// out of the reference; one name needs quoting in a CSV).
const NAMES: [(&str, &str, &str); 6] = [
    ("A", "Orionlab", "orion-result"),
    ("B", "Vegalab", "vega-result"),
    ("C", "Rigel Institute", "rigel-result"),
    ("D", "Deneb-NMI", "deneb-result"),
    ("E", "Altairmetrology", "altair-result"),
    ("F", "Sirius, Inc.", "sirius-result"),
];

fn stdout_of(out: &Output) -> String {
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "status {:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout.clone()).unwrap()
}

/// The one `error:` line of a refused run: status 2, nothing on standard output.
fn refused(args: &[&str]) -> String {
    let out = polycal(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(out.stdout.is_empty(), "{args:?}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    stderr.trim_end().to_string()
}

/// The laboratories' result files copied into `dir/in` under their own names; returns
/// the `NAME=PATH` arguments and the paths.
fn laboratories(dir: &Path) -> (Vec<String>, Vec<PathBuf>) {
    let inputs = dir.join("in");
    std::fs::create_dir_all(&inputs).unwrap();
    let mut args = Vec::new();
    let mut paths = Vec::new();
    for (bundled, name, file) in NAMES {
        let path = inputs.join(format!("{file}.csv"));
        std::fs::copy(format!("{KC}/{bundled}.csv"), &path).unwrap();
        args.push(format!("{name}={}", path.display()));
        paths.push(path);
    }
    (args, paths)
}

/// The key file: code → laboratory, read with the csv crate.
fn key_of(path: &Path) -> BTreeMap<String, String> {
    let mut reader = csv::Reader::from_path(path).unwrap();
    assert_eq!(reader.headers().unwrap(), vec!["code", "lab"]);
    reader
        .records()
        .map(|r| {
            let r = r.unwrap();
            (r[0].to_string(), r[1].to_string())
        })
        .collect()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn kc_anonymise_leaves_no_name_nor_path_in_any_output() {
    let dir = temp_dir("kc-draft", "leak");
    let (labs, paths) = laboratories(&dir);
    let key = dir.join("key.csv");
    let plot = dir.join("plot");
    let (k, p) = (key.to_str().unwrap(), plot.to_str().unwrap());
    let mut base: Vec<&str> = vec!["kc"];
    base.extend(labs.iter().map(String::as_str));
    // the pitch deviations (several quantities: tests/commands/kc_shared.rs)
    base.extend(["--quantity", "pitch_deviation"]);

    // the truth: the comparison under the real names
    let mut plain_args = base.clone();
    plain_args.extend(["--format", "json"]);
    let plain: Value = serde_json::from_str(&stdout_of(&polycal(&plain_args))).unwrap();
    let plain_d: BTreeMap<String, Vec<f64>> = plain["degrees_of_equivalence"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| (d["lab"].as_str().unwrap().to_string(), floats(&d["d"])))
        .collect();

    let mut json_args = base.clone();
    json_args.extend(["--anonymise", k, "--plot", p, "--format", "json"]);
    let json_text = stdout_of(&polycal(&json_args));
    let json: Value = serde_json::from_str(&json_text).unwrap();
    let written = std::fs::read(&key).unwrap();
    let codes = key_of(&key);
    let letters: Vec<&str> = codes.keys().map(String::as_str).collect();
    assert_eq!(letters, ["A", "B", "C", "D", "E", "F"]);
    let mut named: Vec<&str> = codes.values().map(String::as_str).collect();
    named.sort_unstable();
    let mut expected: Vec<&str> = NAMES.iter().map(|n| n.1).collect();
    expected.sort_unstable();
    assert_eq!(named, expected, "every laboratory once in the key");
    // the outputs list the codes in their order, and code c is the laboratory the key
    // says: its d are that laboratory's in the run under real names
    assert_eq!(
        json["labs"],
        serde_json::json!(["A", "B", "C", "D", "E", "F"])
    );
    for doe in json["degrees_of_equivalence"].as_array().unwrap() {
        let code = doe["lab"].as_str().unwrap();
        let truth = &plain_d[&codes[code]];
        for (got, want) in floats(&doe["d"]).iter().zip(truth) {
            assert!((got - want).abs() < 1e-12, "{code}: {got} vs {want}");
        }
    }
    let sirius = codes.iter().find(|(_, l)| *l == "Sirius, Inc.").unwrap().0;
    assert_eq!(json["excluded"][0]["lab"].as_str(), Some(sirius.as_str()));
    assert!(json["notes"].to_string().contains("code letters"));
    // the pilot's repeats keep their names (and the artefact's motion keeps F in)
    let (start, end) = (
        format!("start={KC}/pilot-start.csv"),
        format!("end={KC}/pilot-end.csv"),
    );
    let pilot_plot = dir.join("pilot-plot");
    let mut pilot_args = base.clone();
    pilot_args.extend(["--pilot", &start, "--pilot", &end, "--anonymise", k]);
    pilot_args.extend(["--plot", pilot_plot.to_str().unwrap(), "--format", "json"]);
    let pilot_text = stdout_of(&polycal(&pilot_args));
    let pilot: Value = serde_json::from_str(&pilot_text).unwrap();
    assert_eq!(
        pilot["pilot"]["repeats"],
        serde_json::json!(["start", "end"])
    );
    assert_eq!(pilot["labs"], json["labs"]);

    // Draft B: the key is read back, not written again, and gives the same letters
    let mut table_args = base.clone();
    table_args.extend(["--anonymise", k]);
    let table = stdout_of(&polycal(&table_args));
    let mut csv_args = base.clone();
    csv_args.extend(["--anonymise", k, "--format", "csv"]);
    let csv = stdout_of(&polycal(&csv_args));
    assert_eq!(
        std::fs::read(&key).unwrap(),
        written,
        "the key is not rewritten"
    );
    assert!(table.contains(&format!("{sirius}: left out of the whole comparison")));
    assert!(
        csv.lines().any(
            |l| l.starts_with(&format!("{sirius},4,")) && l.ends_with(",false,pitch_deviation")
        )
    );
    // --keep and --not-in-reference take the real names
    let deneb = codes.iter().find(|(_, l)| *l == "Deneb-NMI").unwrap().0;
    let mut keep_args = base.clone();
    keep_args.extend(["--anonymise", k, "--keep", "Sirius, Inc."]);
    keep_args.extend(["--not-in-reference", "Deneb-NMI", "--format", "json"]);
    let kept_text = stdout_of(&polycal(&keep_args));
    let kept: Value = serde_json::from_str(&kept_text).unwrap();
    assert_eq!(kept["kept"], serde_json::json!([sirius]));
    assert_eq!(kept["not_in_reference"], serde_json::json!([deneb]));

    // the report and the DCC made from the anonymised JSON
    let kc_json = dir.join("kc.json");
    std::fs::write(&kc_json, &json_text).unwrap();
    let (html, dcc) = (dir.join("r.html"), dir.join("c.xml"));
    let out = polycal(&[
        "report",
        DATA,
        "--budget",
        "examples/budgets/instrument.toml",
        "--meta",
        "examples/report/meta.toml",
        "--kc",
        kc_json.to_str().unwrap(),
        "--out",
        html.to_str().unwrap(),
        "--dcc",
        dcc.to_str().unwrap(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report = std::fs::read_to_string(&html).unwrap();
    assert!(
        report.contains("id=\"figure-kc-kcdb\""),
        "the KCDB graphs in the report"
    );

    let mut outputs: Vec<(String, String)> = vec![
        ("JSON".into(), json_text.clone()),
        ("JSON with the pilot".into(), pilot_text),
        ("JSON with --keep".into(), kept_text),
        ("table".into(), table),
        ("CSV".into(), csv),
        ("report".into(), report),
        ("DCC".into(), std::fs::read_to_string(&dcc).unwrap()),
    ];
    for (dir, count) in [(&plot, 4), (&pilot_plot, 5)] {
        let mut figures = 0;
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            outputs.push((
                path.display().to_string(),
                std::fs::read_to_string(&path).unwrap(),
            ));
            figures += 1;
        }
        assert_eq!(figures, count, "the kc figures (and the pilot's)");
    }
    for ((_, name, file), path) in NAMES.iter().zip(&paths) {
        let full = path.display().to_string();
        for (what, text) in &outputs {
            for leak in [*name, *file, full.as_str()] {
                assert!(!text.contains(leak), "{what} holds {leak:?}");
            }
        }
        let key_text = String::from_utf8_lossy(&written);
        assert!(key_text.contains(name), "the key holds {name}");
    }
}

#[test]
fn kc_anonymise_draws_the_letters_at_random() {
    let dir = temp_dir("kc-draft", "random");
    let (labs, _) = laboratories(&dir);
    let key = dir.join("key.csv");
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend(["--anonymise", key.to_str().unwrap(), "--format", "csv"]);
    // 8 drafts of 6 laboratories: all alike by chance once in 720⁷
    let mut keys = std::collections::BTreeSet::new();
    for _ in 0..8 {
        let _ = std::fs::remove_file(&key);
        stdout_of(&polycal(&args));
        keys.insert(key_of(&key));
    }
    assert!(keys.len() > 1, "one key in 8 draws: {keys:?}");
}

#[test]
fn kc_anonymise_refusals_name_the_key_and_write_nothing() {
    let dir = temp_dir("kc-draft", "refused");
    let (labs, paths) = laboratories(&dir);
    let mut base: Vec<&str> = vec!["kc"];
    base.extend(labs.iter().map(String::as_str));
    let run = |extra: &[&str]| {
        let mut args = base.clone();
        args.extend_from_slice(extra);
        refused(&args)
    };
    let key_file = |name: &str, text: &str| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path.display().to_string()
    };
    let rows: Vec<String> = NAMES
        .iter()
        .enumerate()
        .map(|(i, n)| format!("{},\"{}\"\n", ["Q", "R", "S", "T", "U", "V"][i], n.1))
        .collect();
    // a laboratory the key lacks, named
    let short = key_file("short.csv", &format!("code,lab\n{}", rows[..5].concat()));
    let line = run(&["--anonymise", &short]);
    assert!(
        line.contains("\"Sirius, Inc.\" is not in the key") && line.contains(&short),
        "{line}"
    );
    // a code twice, at its line and column
    let twice = key_file(
        "twice.csv",
        &format!("code,lab\n{}Q,Extra\n", rows.concat()),
    );
    let line = run(&["--anonymise", &twice]);
    assert!(
        line.contains(&format!(
            "{twice}:8:1: code \"Q\" is given twice (first on line 2)"
        )),
        "{line}"
    );
    // a row without its laboratory
    let empty = key_file("empty.csv", &format!("code,lab\n{}W,\n", rows.concat()));
    let line = run(&["--anonymise", &empty]);
    assert!(
        line.contains(&format!("{empty}:8:3:")) && line.contains("no laboratory"),
        "{line}"
    );
    // a result file given as the key is read as one, and refused
    let line = run(&["--anonymise", paths[0].to_str().unwrap()]);
    assert!(line.contains("not a key of code letters"), "{line}");
    // the key on standard output, or as one of the figures
    let line = run(&["--anonymise", "-"]);
    assert!(line.contains("--anonymise"), "{line}");
    let plot = dir.join("plot");
    std::fs::create_dir_all(&plot).unwrap();
    let over = plot.join("kc-kcdb.svg");
    let line = run(&[
        "--anonymise",
        over.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(line.contains("one of the figures"), "{line}");
    assert!(!over.exists());
    // the key given as --plot's directory (found in review: the key was written, then the
    // figures refused): refused before anything is written
    let both = dir.join("both");
    let line = run(&[
        "--anonymise",
        both.to_str().unwrap(),
        "--plot",
        both.to_str().unwrap(),
    ]);
    assert!(line.contains("is the directory --plot writes"), "{line}");
    assert!(!both.exists());
    // a directory that does not exist: refused before any work
    let nowhere = dir.join("no-such-dir/key.csv");
    let line = run(&["--anonymise", nowhere.to_str().unwrap()]);
    assert!(line.contains("--anonymise"), "{line}");
    // an input refused: no key written
    let fresh = dir.join("fresh.csv");
    let bad = key_file(
        "bad-result.csv",
        "quantity,index,value,U,k\npitch_deviation,1,x,0.2,2\n",
    );
    let bad_lab = format!("Bad={bad}");
    let line = run(&["--anonymise", fresh.to_str().unwrap(), &bad_lab]);
    assert!(line.contains(&format!("{bad}:2:")), "{line}");
    assert!(!fresh.exists(), "no key for a comparison refused");
}

/// `kc --help` names every figure `--plot` may write (the library's list).
#[test]
fn kc_help_names_every_figure() {
    let out = polycal(&["kc", "--help"]);
    let help = String::from_utf8(out.stdout).unwrap();
    let names = polycal::figure::FigureSet::Kc { pilot: true }.file_names();
    assert_eq!(names.len(), 5);
    for name in names {
        assert!(help.contains(&name), "--help lacks {name}");
    }
    assert!(help.contains("--anonymise <KEY.csv>"));
}

/// χ² of 10¹² (a laboratory 1000″ off with u = 0.001″) is written `1.xxe12` in the
/// table and the report, never as a thirteen-digit number; the JSON keeps it whole.
#[test]
fn kc_a_huge_chi2_reads_at_a_glance() {
    let dir = temp_dir("kc-draft", "chi2");
    let lab = |name: &str, off: f64| {
        let mut text = String::from("quantity,index,value,U,k\n");
        for face in 1..=6 {
            let value = match face {
                1 => off,
                2 => -off,
                _ => 0.0,
            };
            text.push_str(&format!("pitch_deviation,{face},{value},0.002,2\n"));
        }
        let path = dir.join(format!("{name}.csv"));
        std::fs::write(&path, text).unwrap();
        format!("{name}={}", path.display())
    };
    let labs = [lab("A", 0.0), lab("B", 0.0), lab("C", 1000.0)];
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    let table = stdout_of(&polycal(&args));
    let mut json_args = args.clone();
    json_args.extend(["--format", "json"]);
    let json_text = stdout_of(&polycal(&json_args));
    let json: Value = serde_json::from_str(&json_text).unwrap();
    let chi2 = json["vector_all"]["chi2"].as_f64().unwrap();
    assert!(chi2 > 1e11, "{chi2}");
    // the vector's χ² at three significant digits, as written here
    let shown = format!("{chi2:.2e}");
    assert!(table.contains(&format!("χ² = {shown}")), "{shown}\n{table}");
    let long_number = |text: &str| {
        text.split(|c: char| !c.is_ascii_digit())
            .any(|run| run.len() >= 10)
    };
    assert!(!long_number(&table), "{table}");

    let kc_json = dir.join("kc.json");
    std::fs::write(&kc_json, &json_text).unwrap();
    let html = dir.join("r.html");
    let out = polycal(&[
        "report",
        DATA,
        "--kc",
        kc_json.to_str().unwrap(),
        "--out",
        html.to_str().unwrap(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report = std::fs::read_to_string(&html).unwrap();
    let section = report
        .split("id=\"key-comparison\"")
        .nth(1)
        .expect("the key comparison section");
    // the words people read: no thirteen-digit number outside the data-value attributes
    let words: String = section
        .split("data-value=\"")
        .enumerate()
        .map(|(i, part)| {
            if i == 0 {
                part
            } else {
                part.split_once('"').map_or("", |p| p.1)
            }
        })
        .collect();
    assert!(words.contains(&shown), "{shown}");
    assert!(!long_number(&words));
    assert!(
        section.contains(&format!("data-value=\"{chi2}\"")),
        "the JSON's value kept"
    );
}
