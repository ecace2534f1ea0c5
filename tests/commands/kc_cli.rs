//! `polycal kc` on the command line (docs/FORMAT.md §12, §8): the bundled example, its
//! JSON and CSV, the exit statuses, and each refusal as one `error:` line naming the file
//! (and line) with status 2.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");
const DATA: &str = "examples/data/kc";

fn polycal(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env_remove("NO_COLOR")
        .output()
        .expect("polycal runs")
}

fn example(name: &str) -> String {
    format!("{name}={DATA}/{name}.csv")
}

fn scratch(name: &str, text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("polycal-kc-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path: PathBuf = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

/// A result file of `faces` pitch deviations, all with U = 0.2, k = 2; `skip` leaves a
/// face out and `zero_u` writes U = 0 on that face.
fn result(faces: u32, skip: Option<u32>, zero_u: Option<u32>) -> String {
    let mut text = String::from("quantity,index,value,U,k\n");
    for face in 1..=faces {
        if Some(face) == skip {
            continue;
        }
        let expanded_u = if Some(face) == zero_u { 0.0 } else { 0.2 };
        let value = 0.01 * f64::from(face % 3) - 0.01;
        text.push_str(&format!("pitch_deviation,{face},{value},{expanded_u},2\n"));
    }
    text
}

/// The one `error:` line of a refused run with status 2.
fn refused(args: &[&str]) -> String {
    let out = polycal(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(out.stdout.is_empty(), "{args:?}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    lines[0].to_string()
}

#[test]
fn kc_the_bundled_example_in_json_table_and_csv() {
    let labs: Vec<String> = ["A", "B", "C", "D", "E", "F"]
        .iter()
        .map(|l| example(l))
        .collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    // the pitch deviations (the files carry encoder errors too: tests/commands/kc_shared.rs)
    args.extend(["--quantity", "pitch_deviation"]);
    let mut json_args = args.clone();
    json_args.extend(["--format", "json"]);
    let out = polycal(&json_args);
    assert_eq!(out.status.code(), Some(0));
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["version"].is_string());
    for key in [
        "quantity",
        "index",
        "labs",
        "reference",
        "reference_u",
        "chi2",
        "chi2_dof",
        "consistent",
        "vector",
        "excluded",
        "tau",
        "degrees_of_equivalence",
        "pairs",
    ] {
        assert!(json.get(key).is_some(), "{key}");
    }
    assert_eq!(json["index"].as_array().unwrap().len(), 12);
    assert_eq!(json["excluded"][0]["lab"], "F");
    assert_eq!(json["excluded"].as_array().unwrap().len(), 1);
    assert_eq!(json["vector"]["dof"], 44);
    assert_eq!(json["vector_all"]["dof"], 55);
    assert_eq!(json["vector_all"]["consistent"], false);
    assert_eq!(json["search"]["method"], "exhaustive");
    assert_eq!(
        json["search"]["steps"][0]["best"],
        serde_json::json!(["A", "B", "C", "D", "E"])
    );
    assert_eq!(json["pairs"].as_array().unwrap().len(), 15);

    let out = polycal(&args);
    assert_eq!(out.status.code(), Some(0));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("Excluded (left out of every quantity):"));
    assert!(table.contains("Consistent after leaving out F: the closed vector of all 6"));
    assert!(table.contains("Cox 2002"));

    let mut csv_args = args.clone();
    csv_args.extend(["--format", "csv"]);
    let out = polycal(&csv_args);
    let csv = String::from_utf8(out.stdout).unwrap();
    assert!(csv.starts_with("lab,index,angle_deg,d,U,in_reference,quantity\nA,1,,"));
    assert_eq!(csv.lines().count(), 1 + 6 * 12);
    assert!(
        csv.lines()
            .any(|l| l.starts_with("F,4,") && l.ends_with(",false,pitch_deviation"))
    );
}

#[test]
fn kc_status_1_when_not_consistent_after_the_exclusions() {
    // Two laboratories cannot be reduced: 1″ apart on one face with u = 0.1″.
    let a = scratch("far-a.csv", &result(6, None, None));
    let far = result(6, None, None).replace("pitch_deviation,1,0,", "pitch_deviation,1,1.0,");
    let b = scratch("far-b.csv", &far);
    let out = polycal(&["kc", &format!("A={a}"), &format!("B={b}")]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(
        String::from_utf8_lossy(&out.stdout).contains("NOT consistent: the closed vector of all 2")
    );
}

#[test]
fn kc_refusals_are_one_error_line_naming_file_and_line() {
    let twelve = scratch("twelve.csv", &result(12, None, None));
    let eight = scratch("eight.csv", &result(8, None, None));
    let missing = scratch("missing.csv", &result(12, Some(5), None));
    let zero = scratch("zero.csv", &result(12, None, Some(3)));
    let lab = |name: &str, path: &str| format!("{name}={path}");

    // a standard uncertainty below 1e-9″ (U = 1e-12 at k = 2 on face 4, line 5)
    let tiny = scratch(
        "tiny.csv",
        &result(12, None, None).replace("pitch_deviation,4,0,0.2,2", "pitch_deviation,4,0,1e-12,2"),
    );
    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &tiny)]);
    assert!(
        message.contains(&format!("{tiny}:5")) && message.contains("below 1e-9″"),
        "{message}"
    );
    // --keep of a name that is not a laboratory's
    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &twelve), "--keep", "Z"]);
    assert!(
        message.contains("\"Z\"") && message.contains("--keep"),
        "{message}"
    );

    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &eight)]);
    assert!(message.contains(&format!("{eight}:9:")), "{message}");
    assert!(
        message.contains("8 faces") && message.contains("12"),
        "{message}"
    );

    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &missing)]);
    assert!(
        message.contains(&missing) && message.contains("face 5"),
        "{message}"
    );

    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &zero)]);
    assert!(message.contains(&format!("{zero}:4:")), "{message}");
    assert!(message.contains("U = 0"), "{message}");

    let message = refused(&["kc", &lab("A", &twelve), &lab("A", &eight)]);
    assert!(message.contains("\"A\" is given twice"), "{message}");
    assert!(
        message.contains(&twelve) && message.contains(&eight),
        "{message}"
    );

    let message = refused(&["kc", &lab("A", &twelve), &twelve]);
    assert!(message.contains("expected NAME=RESULT.csv"), "{message}");
    assert!(message.contains(&twelve), "{message}");

    let message = refused(&["kc", &lab("A", &twelve)]);
    assert!(
        message.contains("at least 2 laboratories, 1 given"),
        "{message}"
    );

    let message = refused(&[
        "kc",
        &lab("A", &twelve),
        &lab("B", &twelve),
        "--pilot",
        &lab("P", &twelve),
    ]);
    assert!(message.contains("--pilot"), "{message}");

    // A row the result reader refuses is named with its column.
    let bad = scratch(
        "bad.csv",
        "quantity,index,value,U,k\npitch_deviation,1,x,0.2,2\n",
    );
    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &bad)]);
    assert!(message.contains(&format!("{bad}:2:")), "{message}");
}

/// Runs polycal and returns its standard output (status 0 expected).
fn stdout_of(args: &[&str]) -> String {
    let out = polycal(args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// P = I − J/N.
fn projector(n: usize) -> nalgebra::DMatrix<f64> {
    nalgebra::DMatrix::identity(n, n) - nalgebra::DMatrix::from_element(n, n, 1.0 / n as f64)
}

/// Laboratories given as `solve --covariance --format json` (two designs, so two
/// correlation structures) beside one result CSV: the closed vector's GLS reference is
/// (Σ V_i⁺)⁺ Σ V_i⁺ x_i computed here by SVD with the JSON's covariances and
/// N/(N − 1)·P·diag(u²)·P for the CSV; the per-face tests use the JSON's u.
#[test]
fn kc_reads_solve_json_with_its_covariance() {
    use nalgebra::{DMatrix, DVector};
    let faces = 12;
    let designs: [(&str, &[&str]); 3] = [
        ("A", &["--ac-faces", "1,2"]),
        ("B", &["--ac-faces", "1,6", "--noise", "0.08"]),
        ("C", &["--ac-faces", "1,8", "--noise", "0.06"]),
    ];
    let mut args = vec!["kc".to_string()];
    let mut solved = Vec::new();
    for (name, extra) in designs {
        let mut sim = vec!["simulate", "--faces", "12", "--seed", "7", "--closing"];
        sim.extend_from_slice(extra);
        let run = scratch(&format!("{name}-run.csv"), &stdout_of(&sim));
        let format = if name == "C" { "csv" } else { "json" };
        let mut solve = vec!["solve", run.as_str(), "--format", format];
        if name != "C" {
            solve.push("--covariance");
        }
        let text = stdout_of(&solve);
        let path = scratch(&format!("{name}.{format}"), &text);
        args.push(format!("{name}={path}"));
        solved.push(text);
    }
    args.extend(["--quantity", "pitch_deviation", "--format", "json"].map(String::from));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = polycal(&args);
    assert!(out.status.code() == Some(0) || out.status.code() == Some(1));
    let kc: Value = serde_json::from_slice(&out.stdout).unwrap();
    // the laboratories' x and V, read here
    let mut x = Vec::new();
    let mut v = Vec::new();
    for text in &solved[..2] {
        let json: Value = serde_json::from_str(text).unwrap();
        let beta: Vec<f64> = json["pitch_deviation"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| b.as_f64().unwrap())
            .collect();
        let cov = &json["pitch_deviation_covariance"];
        let c = DMatrix::from_fn(faces, faces, |i, j| cov[i][j].as_f64().unwrap());
        let u = json["pitch_deviation_u"][0].as_f64().unwrap();
        assert!((c[(0, 0)].sqrt() - u).abs() < 1e-12 * u);
        x.push(DVector::from_vec(beta));
        v.push(c);
    }
    let mut beta = vec![0.0; faces];
    let mut u2 = vec![0.0; faces];
    for line in solved[2]
        .lines()
        .filter(|l| l.starts_with("pitch_deviation,"))
    {
        let cells: Vec<&str> = line.split(',').collect();
        let face: usize = cells[1].parse().unwrap();
        beta[face - 1] = cells[2].parse().unwrap();
        // columns quantity,index,value,U,u,k,… (docs/FORMAT.md §3.1)
        let u: f64 = cells[4].parse().unwrap();
        u2[face - 1] = u * u;
    }
    let p = projector(faces);
    let n = faces as f64;
    v.push(&p * DMatrix::from_diagonal(&DVector::from_vec(u2)) * &p * (n / (n - 1.0)));
    x.push(&p * DVector::from_vec(beta));
    let pinv = |m: &DMatrix<f64>| m.clone().pseudo_inverse(1e-12).unwrap();
    let mut sum_inverse = DMatrix::zeros(faces, faces);
    let mut sum_weighted = DVector::zeros(faces);
    for (x, v) in x.iter().zip(&v) {
        sum_inverse += pinv(v);
        sum_weighted += pinv(v) * x;
    }
    let reference = pinv(&sum_inverse) * sum_weighted;
    let got = &kc["vector"]["reference"];
    for f in 0..faces {
        let g = got[f].as_f64().unwrap();
        assert!(
            (g - reference[f]).abs() < 1e-9,
            "face {}: {g} vs {}",
            f + 1,
            reference[f]
        );
    }
    let notes = kc["notes"].to_string();
    assert!(
        notes.contains("own covariances") && notes.contains("for A, B;"),
        "{notes}"
    );
    // the per-face test of lab A uses the JSON's u: U(d) ≥ 2u_A·√(1 − w) > 0, finite
    assert!(kc["degrees_of_equivalence"][0]["U"][0].as_f64().unwrap() > 0.0);
}

#[test]
fn kc_refuses_a_solve_json_whose_covariance_is_not_closed_or_not_json() {
    let run = scratch(
        "cov-run.csv",
        &stdout_of(&["simulate", "--faces", "8", "--seed", "3"]),
    );
    let text = stdout_of(&["solve", run.as_str(), "--covariance", "--format", "json"]);
    let mut json: Value = serde_json::from_str(&text).unwrap();
    json["pitch_deviation_covariance"][0][0] = Value::from(1.0);
    let bad = scratch("open.json", &json.to_string());
    let good = scratch("good.json", &text);
    let line = refused(&["kc", &format!("A={bad}"), &format!("B={good}")]);
    assert!(
        line.contains(&bad) && line.contains("laboratory A") && line.contains("not closed"),
        "{line}"
    );
    let broken = scratch(
        "broken.json",
        "{\n  \"faces\": 8,\n  \"pitch_deviation\": [1, 2,\n",
    );
    let line = refused(&["kc", &format!("A={broken}"), &format!("B={good}")]);
    assert!(
        line.contains(&broken) && line.contains("line 4 column 0"),
        "{line}"
    );
    let line = refused(&["solve", run.as_str(), "--covariance"]);
    assert!(line.contains("--format json"), "{line}");
}

/// `--method` and `--quantity` are parsed by the library (as Python's `polycal.kc` is):
/// the same words refused with the library's message.
#[test]
fn kc_method_and_quantity_words_are_the_librarys() {
    use polycal::kc::{ReferenceMethod, compared_quantity};
    let (a, b) = (example("A"), example("B"));
    for word in ["weighted-mean", "dersimonian-laird"] {
        let out = polycal(&[
            "kc",
            &a,
            &b,
            "--method",
            word,
            "--quantity",
            "pitch_deviation",
            "--format",
            "json",
        ]);
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["method"], word);
        assert!(word.parse::<ReferenceMethod>().is_ok());
    }
    for word in ["weighted_mean", "Weighted-Mean", "mean", ""] {
        let line = refused(&["kc", &a, &b, "--method", word]);
        let message = word.parse::<ReferenceMethod>().unwrap_err().to_string();
        assert!(line.contains(&message), "{line} / {message}");
    }
    for word in ["face_deviation", "setup_error", "pitch-deviation"] {
        let line = refused(&["kc", &a, &b, "--quantity", word]);
        let message = compared_quantity(word).unwrap_err().to_string();
        assert!(line.contains(&message), "{line} / {message}");
    }
}

/// A solve JSON with a budget: its u is the budget's U/k (not the fit's u); its covariance
/// is the fit's plus the budget's excess e_f² = u_f² − C_ff closed, V = C + P·diag(e²)·P,
/// so two copies of one result give U(d) = 2·√(V_ff − V_ff/2) = √2·√V_ff on every face.
#[test]
fn kc_solve_json_with_a_budget_uses_u_from_its_expanded_uncertainty() {
    let text = stdout_of(&[
        "solve",
        "examples/data/polygon24-2ac-6cycles.csv",
        "--budget",
        "examples/budgets/instrument.toml",
        "--covariance",
        "--format",
        "json",
    ]);
    let path = scratch("budget.json", &text);
    let solve: Value = serde_json::from_str(&text).unwrap();
    let out = polycal(&[
        "kc",
        &format!("A={path}"),
        &format!("B={path}"),
        "--quantity",
        "pitch_deviation",
        "--format",
        "json",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let kc: Value = serde_json::from_slice(&out.stdout).unwrap();
    let expanded = solve["pitch_deviation_U"].as_array().unwrap();
    let k = solve["pitch_deviation_k"].as_array().unwrap();
    let fit_u = solve["pitch_deviation_u"].as_array().unwrap();
    let got = kc["degrees_of_equivalence"][0]["U"].as_array().unwrap();
    let covariance = solve["pitch_deviation_covariance"].as_array().unwrap();
    let n = expanded.len();
    let excess: Vec<f64> = (0..n)
        .map(|f| {
            let u = expanded[f].as_f64().unwrap() / k[f].as_f64().unwrap();
            (u * u - covariance[f][f].as_f64().unwrap()).max(0.0)
        })
        .collect();
    let mean_excess = excess.iter().sum::<f64>() / (n * n) as f64;
    for f in 0..n {
        let u = expanded[f].as_f64().unwrap() / k[f].as_f64().unwrap();
        assert!(u > fit_u[f].as_f64().unwrap(), "the budget adds to the fit");
        // (P·diag(e²)·P)_ff = e_f²(1 − 2/N) + Σ e²/N²
        let v_ff =
            covariance[f][f].as_f64().unwrap() + excess[f] * (1.0 - 2.0 / n as f64) + mean_excess;
        let want = 2f64.sqrt() * v_ff.sqrt();
        let g = got[f].as_f64().unwrap();
        assert!(
            (g - want).abs() < 1e-12 * want,
            "face {}: {g} vs {want}",
            f + 1
        );
    }
    assert!(kc["vector"]["chi2"].as_f64().unwrap().abs() < 1e-20);
}

/// `--link`: a comparison linked to one whose laboratories B, C, D measured the same files:
/// each linking laboratory's degree of equivalence against the linked reference is its own
/// there (d_linked = d(linked) exactly, as Δ_j is the same for all three); refusals of a
/// file that is not a comparison's JSON (its line and column) and of comparisons that
/// share no laboratory.
#[test]
fn kc_link_gives_degrees_of_equivalence_against_the_linked_reference() {
    let cipm_args: Vec<String> = ["A", "B", "C", "D"].iter().map(|n| example(n)).collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(cipm_args.iter().map(String::as_str));
    args.extend(["--quantity", "pitch_deviation", "--format", "json"]);
    let cipm_text = stdout_of(&args);
    let cipm: Value = serde_json::from_str(&cipm_text).unwrap();
    let cipm_path = scratch("cipm.json", &cipm_text);
    let rmo_args: Vec<String> = ["B", "C", "D", "E"].iter().map(|n| example(n)).collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(rmo_args.iter().map(String::as_str));
    args.extend([
        "--quantity",
        "pitch_deviation",
        "--link",
        &cipm_path,
        "--format",
        "json",
    ]);
    let rmo: Value = serde_json::from_str(&stdout_of(&args)).unwrap();
    assert_eq!(rmo["link"]["labs"], serde_json::json!(["B", "C", "D"]));
    assert_eq!(rmo["link"]["vector"]["dof"], 11 * 2);
    assert!(rmo["link"]["vector"]["chi2"].as_f64().unwrap() < 1e-9);
    for (i, name) in ["B", "C", "D"].iter().enumerate() {
        let there = &cipm["degrees_of_equivalence"][i + 1];
        assert_eq!(there["lab"], *name);
        let here = &rmo["degrees_of_equivalence"][i];
        for k in 0..12 {
            let (a, b) = (
                here["d_linked"][k].as_f64().unwrap(),
                there["d"][k].as_f64().unwrap(),
            );
            assert!((a - b).abs() < 1e-12, "{name} face {}: {a} vs {b}", k + 1);
        }
    }
    // the table says it too
    args.retain(|a| *a != "--format" && *a != "json");
    assert!(stdout_of(&args).contains("Linked through B, C, D"));
    // Draft A of a linked comparison: linked by the real names, shown by the codes
    let key = std::path::Path::new(&scratch("unused", "")).with_file_name("link-key.csv");
    let _ = std::fs::remove_file(&key);
    let key = key.to_string_lossy().into_owned();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(rmo_args.iter().map(String::as_str));
    args.extend([
        "--quantity",
        "pitch_deviation",
        "--link",
        &cipm_path,
        "--anonymise",
        &key,
        "--format",
        "json",
    ]);
    let coded: Value = serde_json::from_str(&stdout_of(&args)).unwrap();
    let key_text = std::fs::read_to_string(&key).unwrap();
    let code_of = |name: &str| -> String {
        key_text
            .lines()
            .find_map(|l| {
                l.split_once(',')
                    .filter(|(_, lab)| *lab == name)
                    .map(|(c, _)| c.to_string())
            })
            .unwrap()
    };
    let mut expected: Vec<String> = ["B", "C", "D"].iter().map(|n| code_of(n)).collect();
    let mut got: Vec<String> = coded["link"]["labs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap().to_string())
        .collect();
    expected.sort();
    got.sort();
    assert_eq!(got, expected);
    assert!(coded["link"]["vector"]["chi2"].as_f64().unwrap() < 1e-9);
    // refusals
    let garbage = scratch(
        "garbage.json",
        "{\"quantity\": \"pitch_deviation\",\n  \"index\": oops}\n",
    );
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(rmo_args.iter().map(String::as_str));
    args.extend(["--link", &garbage]);
    let line = refused(&args);
    assert!(line.contains(&format!("{garbage}:2:")), "{line}");
    let lonely_args: Vec<String> = ["E", "F"].iter().map(|n| example(n)).collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(lonely_args.iter().map(String::as_str));
    args.extend(["--link", &cipm_path]);
    assert!(refused(&args).contains("no laboratory is in both"));
}

/// A `dof` column is read and gives the degrees of equivalence their ν_eff and k; a `dof`
/// that is not positive is refused at its field.
#[test]
fn kc_reads_a_dof_column() {
    let file = |name: &str, dof: &str| {
        let mut text = String::from("quantity,index,value,u,dof\n");
        for (face, value) in [0.1, -0.05, 0.0, -0.05].iter().enumerate() {
            text.push_str(&format!("pitch_deviation,{},{value},0.1,{dof}\n", face + 1));
        }
        format!("{name}={}", scratch(&format!("dof-{name}.csv"), &text))
    };
    let (a, b) = (file("A", "5"), file("B", ""));
    let json: Value =
        serde_json::from_str(&stdout_of(&["kc", &a, &b, "--format", "json"])).unwrap();
    let doe = &json["degrees_of_equivalence"][0];
    let nu = doe["dof_effective"][0].as_f64().unwrap();
    // two laboratories of one u: d_A = (x_A − x_B)/2, u_c⁴/((u²/4)²/5) = (u²/2)²·80/u⁴ = 20
    assert!((nu - 20.0).abs() < 1e-9, "{nu}");
    assert!(doe["k"][0].as_f64().unwrap() > 2.0);
    let bad = file("C", "-1");
    let line = refused(&["kc", &a, &bad]);
    assert!(line.contains(":2:27: column \"dof\""), "{line}");
}
