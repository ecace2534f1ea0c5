//! `polycal kc` without `--quantity` (docs/FORMAT.md §12, "Every quantity the files
//! share"): every compared quantity that every result carries is compared with the same
//! options — JSON one object per line (JSON Lines), each equal to the run of that
//! `--quantity`; the tables one after another under a heading each; the CSV's rows told
//! apart by their `quantity` column; status 1 when any comparison is not consistent;
//! `--plot` puts the other quantities' figures in DIR/QUANTITY/; `--link` links each
//! comparison to the linked file's of its quantity; `report --kc` of a JSON Lines file
//! has a section (and a DCC result) per comparison. A file lacking every compared
//! quantity is refused with status 2, naming what each file lacks.

use std::path::Path;
use std::process::Output;

use scraper::Selector;
use serde_json::Value;

use crate::document_support::{polycal, temp_dir};

const KC: &str = "examples/data/kc";

fn labs(names: &[&str]) -> Vec<String> {
    names.iter().map(|n| format!("{n}={KC}/{n}.csv")).collect()
}

/// `kc` of `labs` with `extra`.
fn kc(labs: &[String], extra: &[&str]) -> Output {
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend_from_slice(extra);
    polycal(&args)
}

fn stdout(out: &Output) -> String {
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout.clone()).unwrap()
}

/// Every line of a JSON Lines output, parsed by serde_json alone.
fn json_lines(out: &Output) -> Vec<Value> {
    stdout(out)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The one `error:` line of a refused run (status 2, nothing on standard output).
fn refused(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(out.stdout.is_empty());
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    lines[0].to_string()
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

/// Rows of `quantity` with U = 0.2, k = 2 at indices from `first`.
fn rows(quantity: &str, first: u32, values: &[f64]) -> String {
    values
        .iter()
        .zip(first..)
        .map(|(v, i)| format!("{quantity},{i},{v},0.2,2\n"))
        .collect()
}

const HEADER: &str = "quantity,index,value,U,k\n";
const PITCH: [f64; 6] = [0.1, -0.1, 0.05, -0.05, 0.0, 0.0];
const ENCODER: [f64; 6] = [0.2, -0.1, 0.0, 0.1, -0.2, 0.0];

#[test]
fn json_lines_are_the_objects_of_each_quantitys_run() {
    let labs = labs(&["A", "B", "C", "D", "E", "F"]);
    let pilot = [
        "--pilot",
        "start=examples/data/kc/pilot-start.csv",
        "--pilot",
        "end=examples/data/kc/pilot-end.csv",
    ];
    let mut extra = pilot.to_vec();
    extra.extend(["--format", "json"]);
    let whole = kc(&labs, &extra);
    assert_eq!(whole.status.code(), Some(0));
    let lines = json_lines(&whole);
    assert_eq!(lines.len(), 3, "one object per shared quantity");
    for (line, quantity) in lines
        .iter()
        .zip(["pitch_deviation", "encoder_error", "angle_block"])
    {
        let mut single = extra.clone();
        single.extend(["--quantity", quantity]);
        let alone = json_lines(&kc(&labs, &single));
        assert_eq!(alone.len(), 1);
        assert_eq!(line, &alone[0], "{quantity}");
        assert_eq!(line["quantity"], quantity);
    }
}

#[test]
fn the_tables_follow_each_other_under_a_heading_and_the_csv_names_the_quantity() {
    let labs = labs(&["A", "B", "C", "D", "E", "F"]);
    let table = stdout(&kc(&labs, &[]));
    let first = "=== Key comparison 1 of 3: pitch_deviation ===\n";
    let second = "=== Key comparison 2 of 3: encoder_error ===\n";
    let third = "=== Key comparison 3 of 3: angle_block ===\n";
    assert!(table.starts_with(first), "{table}");
    let (pitch, rest) = table[first.len()..].split_once(second).unwrap();
    let (encoder, blocks) = rest.split_once(third).unwrap();
    for (part, quantity) in [
        (pitch, "pitch_deviation"),
        (encoder, "encoder_error"),
        (blocks, "angle_block"),
    ] {
        let alone = stdout(&kc(&labs, &["--quantity", quantity]));
        assert_eq!(part.trim_end(), alone.trim_end(), "{quantity}");
    }

    let csv = stdout(&kc(&labs, &["--format", "csv"]));
    let mut csv_lines = csv.lines();
    assert_eq!(
        csv_lines.next(),
        Some("lab,index,angle_deg,d,U,in_reference,quantity")
    );
    let rows: Vec<&str> = csv_lines.collect();
    // six laboratories, 12 faces and 12 common encoder angles; four angle blocks, but D's
    // 90° block (not measured: no row)
    assert_eq!(rows.len(), 6 * 12 + 6 * 12 + (6 * 4 - 1));
    for quantity in ["pitch_deviation", "encoder_error", "angle_block"] {
        let alone = stdout(&kc(&labs, &["--quantity", quantity, "--format", "csv"]));
        let mine: Vec<&str> = rows
            .iter()
            .copied()
            .filter(|r| r.ends_with(&format!(",{quantity}")))
            .collect();
        assert_eq!(
            mine,
            alone.lines().skip(1).collect::<Vec<_>>(),
            "{quantity}"
        );
    }
}

/// Two laboratories that agree on their pitch deviations and whose encoder errors differ
/// by 1″ at one position with u = 0.1″: the encoder errors cannot be consistent (χ² about
/// (1 − 1/6)²/(2·0.01) ≫ χ²_0.95(5) = 11.07) and two laboratories cannot be reduced.
#[test]
fn status_1_when_one_quantity_is_not_consistent() {
    let dir = temp_dir("kc-shared", "status");
    let mut far = ENCODER;
    far[1] += 1.0;
    let p = format!(
        "{HEADER}{}{}",
        rows("pitch_deviation", 1, &PITCH),
        rows("encoder_error", 0, &ENCODER)
    );
    let q = format!(
        "{HEADER}{}{}",
        rows("pitch_deviation", 1, &PITCH),
        rows("encoder_error", 0, &far)
    );
    let labs = [
        format!("P={}", write(&dir, "p.csv", &p)),
        format!("Q={}", write(&dir, "q.csv", &q)),
    ];
    let whole = kc(&labs, &["--format", "json"]);
    assert_eq!(whole.status.code(), Some(1));
    let lines = json_lines(&whole);
    assert_eq!(lines[0]["quantity"], "pitch_deviation");
    assert_eq!(lines[0]["comparison_consistent"], true);
    assert_eq!(lines[1]["quantity"], "encoder_error");
    assert_eq!(lines[1]["comparison_consistent"], false);
    let status = |q: &str| kc(&labs, &["--quantity", q]).status.code();
    assert_eq!(status("pitch_deviation"), Some(0));
    assert_eq!(status("encoder_error"), Some(1));
    // every format: the same status
    for format in ["table", "csv"] {
        assert_eq!(kc(&labs, &["--format", format]).status.code(), Some(1));
    }
}

#[test]
fn no_shared_quantity_is_refused_naming_what_each_file_lacks() {
    let dir = temp_dir("kc-shared", "none");
    let faces = write(
        &dir,
        "faces.csv",
        &format!("{HEADER}{}", rows("face_deviation", 1, &PITCH)),
    );
    let plot = dir.join("plot");
    let out = kc(
        &[format!("A={KC}/A.csv"), format!("B={faces}")],
        &["--plot", plot.to_str().unwrap()],
    );
    let line = refused(&out);
    assert!(
        line.contains(&format!(
            "no pitch_deviation rows in {faces} (laboratory B)"
        )),
        "{line}"
    );
    assert!(
        line.contains(&format!("no encoder_error rows in {faces} (laboratory B)")),
        "{line}"
    );
    assert!(
        !line.contains("--"),
        "the library's message names no flag: {line}"
    );
    assert!(!plot.exists(), "nothing written");
    // one file of pitch deviations only, another of encoder errors only
    let pitch = write(
        &dir,
        "pitch.csv",
        &format!("{HEADER}{}", rows("pitch_deviation", 1, &PITCH)),
    );
    let encoder = write(
        &dir,
        "encoder.csv",
        &format!("{HEADER}{}", rows("encoder_error", 0, &ENCODER)),
    );
    let line = refused(&kc(&[format!("P={pitch}"), format!("E={encoder}")], &[]));
    assert!(line.contains(&format!(
        "no pitch_deviation rows in {encoder} (laboratory E)"
    )));
    assert!(line.contains(&format!("no encoder_error rows in {pitch} (laboratory P)")));
    // one quantity shared: the output is that quantity's run, byte for byte
    let labs = [format!("A={KC}/A.csv"), format!("P={pitch}")];
    for format in ["table", "json", "csv"] {
        let whole = kc(&labs, &["--format", format]);
        let alone = kc(
            &labs,
            &["--quantity", "pitch_deviation", "--format", format],
        );
        assert_eq!(whole.stdout, alone.stdout, "{format}");
        assert_eq!(whole.status.code(), alone.status.code());
    }
}

fn svgs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .map(|p| {
            let name = p.file_name().unwrap().to_str().unwrap().to_string();
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    files.sort();
    files
}

#[test]
fn plot_puts_the_other_quantities_figures_in_a_subdirectory() {
    let dir = temp_dir("kc-shared", "plot");
    let labs = labs(&["A", "B", "C", "D"]);
    let whole = dir.join("whole");
    stdout(&kc(&labs, &["--plot", whole.to_str().unwrap()]));
    for (quantity, figures) in [
        ("pitch_deviation", whole.clone()),
        ("encoder_error", whole.join("encoder_error")),
    ] {
        let alone = dir.join(quantity);
        stdout(&kc(
            &labs,
            &["--quantity", quantity, "--plot", alone.to_str().unwrap()],
        ));
        let (got, want) = (svgs(&figures), svgs(&alone));
        assert_eq!(got.len(), 4, "{quantity}");
        assert!(got == want, "{quantity}: the figures of its run alone");
    }
    // DIR/encoder_error taken by a file: refused before anything is written
    let blocked = dir.join("blocked");
    std::fs::create_dir_all(&blocked).unwrap();
    std::fs::write(blocked.join("encoder_error"), "not a directory").unwrap();
    let line = refused(&kc(&labs, &["--plot", blocked.to_str().unwrap()]));
    assert!(line.contains("--plot"), "{line}");
    assert_eq!(
        std::fs::read_dir(&blocked).unwrap().count(),
        1,
        "nothing written"
    );
}

#[test]
fn link_links_each_comparison_to_the_linked_one_of_its_quantity() {
    let dir = temp_dir("kc-shared", "link");
    let cipm = write(
        &dir,
        "cipm.json",
        &stdout(&kc(&labs(&["A", "B", "C", "D"]), &["--format", "json"])),
    );
    let rmo = labs(&["B", "C", "E", "F"]);
    let lines = json_lines(&kc(&rmo, &["--link", &cipm, "--format", "json"]));
    assert_eq!(lines.len(), 3);
    for (line, quantity) in lines
        .iter()
        .zip(["pitch_deviation", "encoder_error", "angle_block"])
    {
        assert_eq!(
            line["link"]["labs"],
            serde_json::json!(["B", "C"]),
            "{quantity}"
        );
        let alone = json_lines(&kc(
            &rmo,
            &["--quantity", quantity, "--link", &cipm, "--format", "json"],
        ));
        assert_eq!(line, &alone[0], "{quantity}");
    }
    // a file of one comparison, of pitch deviations: the encoder errors are not linked
    let pitch_only = write(
        &dir,
        "cipm-pitch.json",
        &stdout(&kc(
            &labs(&["A", "B", "C", "D"]),
            &["--quantity", "pitch_deviation", "--format", "json"],
        )),
    );
    let lines = json_lines(&kc(&rmo, &["--link", &pitch_only, "--format", "json"]));
    assert!(lines[0].get("link").is_some());
    assert!(lines[1].get("link").is_none());
    assert!(lines[2].get("link").is_none());
    // linked to encoder errors alone, results of pitch deviations alone: refused
    let encoder_only = write(
        &dir,
        "cipm-encoder.json",
        &stdout(&kc(
            &labs(&["A", "B", "C", "D"]),
            &["--quantity", "encoder_error", "--format", "json"],
        )),
    );
    let pitch_labs: Vec<String> = ["B", "C", "E", "F"]
        .iter()
        .map(|n| {
            let text = std::fs::read_to_string(format!("{KC}/{n}.csv")).unwrap();
            let kept: String = text
                .lines()
                .filter(|l| !l.starts_with("encoder_error"))
                .map(|l| format!("{l}\n"))
                .collect();
            format!("{n}={}", write(&dir, &format!("{n}.csv"), &kept))
        })
        .collect();
    let line = refused(&kc(&pitch_labs, &["--link", &encoder_only]));
    assert!(line.contains("--link"), "{line}");
    assert!(line.contains("encoder_error"), "{line}");
}

#[test]
fn anonymise_gives_every_comparison_the_same_codes_and_writes_one_key() {
    let dir = temp_dir("kc-shared", "draft");
    let key = dir.join("key.csv");
    let labs = labs(&["A", "B", "C", "D"]);
    let out = kc(
        &labs,
        &["--anonymise", key.to_str().unwrap(), "--format", "json"],
    );
    let lines = json_lines(&out);
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[0]["labs"], lines[1]["labs"]);
    assert_eq!(lines[0]["labs"], lines[2]["labs"]);
    for line in &lines {
        assert!(line["notes"].to_string().contains("code letters"));
    }
    let written = std::fs::read_to_string(&key).unwrap();
    assert_eq!(
        written.lines().count(),
        1 + 4,
        "one key, one row per laboratory"
    );
}

/// `report --kc` of a JSON Lines file: a section per comparison, its numbers the line's,
/// a DCC result per comparison (the DCC valid), the figures of each under their own ids;
/// a broken second line refused at its line.
#[test]
fn report_of_a_json_lines_file_has_every_section() {
    let dir = temp_dir("kc-shared", "report");
    let text = stdout(&kc(
        &labs(&["A", "B", "C", "D", "E", "F"]),
        &["--format", "json"],
    ));
    let kc_path = write(&dir, "kc.json", &text);
    let lines: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (html, dcc) =
        crate::document_support::report_with_kc(&dir, std::path::Path::new(&kc_path), &[]);
    let count = |css: &str| html.select(&Selector::parse(css).unwrap()).count();
    assert_eq!(count("section#key-comparison"), 0);
    for line in &lines {
        let quantity = line["quantity"].as_str().unwrap();
        assert_eq!(count(&format!("section#key-comparison-{quantity}")), 1);
        assert_eq!(count(&format!("figure#figure-kc-kcdb-{quantity}")), 1);
        let rows = Selector::parse(&format!("table#kc-reference-{quantity} tbody tr")).unwrap();
        let shown: Vec<Vec<f64>> = html
            .select(&rows)
            .map(|tr| {
                tr.select(&Selector::parse("td[data-value]").unwrap())
                    .map(|td| td.value().attr("data-value").unwrap().parse().unwrap())
                    .collect()
            })
            .collect();
        let reference = line["reference"].as_array().unwrap();
        assert_eq!(shown.len(), reference.len(), "{quantity}");
        for (cells, x) in shown.iter().zip(reference) {
            assert!(
                cells.contains(&x.as_f64().unwrap()),
                "{quantity}: {x} in {cells:?}"
            );
        }
    }
    assert_eq!(dcc.matches("refType=\"polycal_keyComparison\"").count(), 3);
    assert!(dcc.contains("Key comparison of the pitch_deviation"));
    assert!(dcc.contains("Key comparison of the encoder_error"));
    assert!(dcc.contains("Key comparison of the angle_block"));
    // D did not measure the 90° block: its degrees of equivalence in the DCC are of
    // blocks 1 … 3 only (no number where none is due)
    assert!(dcc.contains("<si:labelXMLList>block1 block2 block3</si:labelXMLList>"));
    // the second line broken: refused at line 2
    let first = text.lines().next().unwrap();
    let broken = write(
        &dir,
        "broken.json",
        &format!("{first}\n{{\"quantity\": oops}}\n"),
    );
    let html2 = dir.join("r2.html");
    let line = refused(&polycal(&[
        "report",
        "examples/data/polygon24-2ac-6cycles.csv",
        "--kc",
        &broken,
        "--out",
        html2.to_str().unwrap(),
    ]));
    assert!(line.contains(&format!("{broken}:2:")), "{line}");
    assert!(!html2.exists());
    // one quantity twice: refused at the second
    let twice = write(&dir, "twice.json", &format!("{first}\n{first}\n"));
    let line = refused(&polycal(&[
        "report",
        "examples/data/polygon24-2ac-6cycles.csv",
        "--kc",
        &twice,
        "--out",
        html2.to_str().unwrap(),
    ]));
    assert!(line.contains(&format!("{twice}:2:1")), "{line}");
    assert!(
        line.contains("a second comparison of pitch_deviation"),
        "{line}"
    );
}

/// Without `--quantity`, a `--link` file that holds only the encoder errors' comparison
/// links those, and the pitch deviations' and the angle blocks' comparisons say in a note
/// that they are not linked (not silently left unlinked).
#[test]
fn kc_shared_a_quantity_the_link_file_lacks_is_said_not_linked() {
    let dir = temp_dir("kc-shared", "link-one-quantity");
    let out = kc(
        &labs(&["A", "B", "C", "D"]),
        &["--quantity", "encoder_error", "--format", "json"],
    );
    let cipm = dir.join("cipm.json");
    std::fs::write(&cipm, &out.stdout).unwrap();
    let out = kc(
        &labs(&["B", "C", "E", "F"]),
        &["--link", cipm.to_str().unwrap(), "--format", "json"],
    );
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{}",
        stdout(&out)
    );
    let lines: Vec<Value> = stdout(&out)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    for kc in &lines {
        let quantity = kc["quantity"].as_str().unwrap();
        let notes = kc["notes"].to_string();
        if quantity == "encoder_error" {
            assert_eq!(kc["link"]["labs"], serde_json::json!(["B", "C"]));
            assert!(!notes.contains("not linked"), "{notes}");
        } else {
            assert!(kc.get("link").is_none(), "{quantity}");
            assert!(
                notes.contains(&format!(
                    "not linked: the linked comparisons hold none of {quantity}"
                )),
                "{notes}"
            );
        }
    }
}
