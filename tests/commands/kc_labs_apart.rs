//! `polycal kc` keeps laboratories apart (issue 48, item 11; docs/FORMAT.md §12): a
//! laboratory's name with control characters cannot reach the terminal as they are; in the
//! figures every laboratory has its own marker and colour; the pairwise figure shows
//! d_ij = x_i − x_j against U(d_ij) = 2·√(u_i² + u_j²), checked on a hand-worked case; and
//! the refusals of results that cannot be lined up name file, line and column.

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

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-kc-apart-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write(dir: &std::path::Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

/// The one `error:` line of a refused run with status 2.
fn refused(args: &[&str]) -> String {
    let out = polycal(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    lines[0].to_string()
}

#[test]
fn control_characters_in_a_laboratory_name_are_shown_escaped_in_the_table() {
    let a = format!("A\u{1b}[31m={DATA}/A.csv");
    let b = format!("B\u{9b}2J={DATA}/B.csv");
    let c = format!("C\nforged line={DATA}/C.csv");
    let d = format!("D={DATA}/D.csv");
    let out = polycal(&["kc", &a, &b, &c, &d]);
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8(out.stdout).unwrap();
    // No control character but the table's own line feeds reaches the terminal.
    assert!(
        !text.chars().any(|c| c.is_control() && c != '\n'),
        "a control character in the table"
    );
    assert!(
        !text.lines().any(|l| l.starts_with("forged line")),
        "a name's line feed made a line of its own"
    );
    assert!(text.contains("A\\u{1b}[31m"), "{text}");
    assert!(text.contains("B\\u{9b}2J"), "{text}");
    assert!(text.contains("C\\nforged line"), "{text}");
    // The JSON keeps the names as given.
    let out = polycal(&[
        "kc",
        &a,
        &b,
        &c,
        &d,
        "--quantity",
        "pitch_deviation",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["labs"][2], "C\nforged line");
}

/// (shape, colour) of each point of a series in an SVG figure.
fn markers_of(svg: &str, series: &str) -> Vec<(String, String)> {
    let needle = format!("data-series=\"{series}\"");
    svg.lines()
        .filter(|l| l.contains("class=\"point\"") && l.contains(&needle))
        .map(|l| {
            let attribute = |name: &str| {
                let start = l
                    .find(&format!("{name}=\""))
                    .unwrap_or_else(|| panic!("no {name} in {l}"))
                    + name.len()
                    + 2;
                let end = start + l[start..].find('"').unwrap();
                l[start..end].to_string()
            };
            (attribute("data-shape"), attribute("data-colour"))
        })
        .collect()
}

#[test]
fn every_laboratory_has_its_own_marker_and_colour_in_both_figures() {
    let dir = scratch_dir("markers");
    let labs: Vec<String> = ["A", "B", "C", "D", "E", "F"]
        .iter()
        .map(|n| format!("{n}={DATA}/{n}.csv"))
        .collect();
    let plot = dir.join("fig");
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend(["--plot", plot.to_str().unwrap()]);
    let out = polycal(&args);
    assert!(out.status.code().is_some_and(|c| c <= 1));
    for figure in ["kc-degrees-of-equivalence.svg", "kc-reference.svg"] {
        let svg = std::fs::read_to_string(plot.join(figure)).unwrap();
        let mut seen = Vec::new();
        for i in 0..labs.len() {
            let markers = markers_of(&svg, &format!("lab{i}"));
            assert_eq!(markers.len(), 12, "{figure}: lab{i} has a point per face");
            // one marker for all of a laboratory's points …
            assert!(markers.iter().all(|m| m == &markers[0]), "{figure} lab{i}");
            // … and no other laboratory's
            assert!(
                !seen.contains(&markers[0]),
                "{figure}: lab{i} shares {:?}",
                markers[0]
            );
            // the reference is black: no laboratory is
            assert_ne!(markers[0].1, "#000", "{figure}");
            seen.push(markers[0].clone());
        }
        // The laboratory left out (F) keeps its own marker and says so in the legend.
        if figure == "kc-degrees-of-equivalence.svg" {
            assert!(svg.contains("F (left out of the reference)"));
        }
    }
}

/// The cells of the pairwise figure: (a, b, largest |d|/U, its position, positions over U).
fn cells(svg: &str) -> Vec<(usize, usize, f64, usize, usize)> {
    svg.lines()
        .filter(|l| l.contains("class=\"cell\""))
        .map(|l| {
            let attribute = |name: &str| {
                let start = l.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
                let end = start + l[start..].find('"').unwrap();
                l[start..end].to_string()
            };
            (
                attribute("data-a").parse().unwrap(),
                attribute("data-b").parse().unwrap(),
                attribute("data-ratio").parse().unwrap(),
                attribute("data-at").parse().unwrap(),
                attribute("data-exceeding").parse().unwrap(),
            )
        })
        .collect()
}

/// Three laboratories, four faces, one u each (so the closed covariance's diagonal is
/// u_i², and U(d_ij) = 2·√(u_i² + u_j²)), worked by hand:
///
/// | pair | d_ij per face | U(d_ij) | largest \|d\|/U (face) | faces over U |
/// |---|---|---|---|---|
/// | A − B | 0.3, −0.35, 0.15, −0.1 | 2·√0.05 = 0.447214 | 0.35/0.447214 = 0.782624 (2) | 0 |
/// | A − C | 0.4, −0.2, −0.2, 0 | 2·√0.0125 = 0.223607 | 0.4/0.223607 = 1.788854 (1) | 1 |
/// | B − C | 0.1, 0.15, −0.35, 0.1 | 2·√0.0425 = 0.412311 | 0.35/0.412311 = 0.848875 (3) | 0 |
///
/// Each pair's one test: V_a + V_b = N/(N−1)·(u_a² + u_b²)·P, so χ² = (N−1)/N·Σd²/(u_a² + u_b²)
/// with ν = 3, χ²_0.95(3) = 7.814728: A − B 0.75·0.245/0.05 = 3.675, A − C 0.75·0.24/0.0125
/// = 14.4 (fails: the shaded pair), B − C 0.75·0.165/0.0425 = 2.911765.
#[test]
fn the_pairwise_figure_against_a_hand_worked_three_laboratory_case() {
    let dir = scratch_dir("pairwise");
    let file = |name: &str, values: [f64; 4], u: f64| {
        let mut text = String::from("quantity,index,value,u\n");
        for (face, value) in values.iter().enumerate() {
            text.push_str(&format!("pitch_deviation,{},{value},{u}\n", face + 1));
        }
        format!("{name}={}", write(&dir, &format!("{name}.csv"), &text))
    };
    let a = file("A", [0.3, -0.1, -0.1, -0.1], 0.1);
    let b = file("B", [0.0, 0.25, -0.25, 0.0], 0.2);
    let c = file("C", [-0.1, 0.1, 0.1, -0.1], 0.05);
    let plot = dir.join("fig");
    let out = polycal(&[
        "kc",
        &a,
        &b,
        &c,
        "--format",
        "json",
        "--plot",
        plot.to_str().unwrap(),
    ]);
    assert!(out.status.code().is_some_and(|c| c <= 1));
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let expected = [
        (
            0,
            1,
            [0.3, -0.35, 0.15, -0.1],
            0.447_213_595_5,
            0.782_623_792_1,
            1,
            0,
        ),
        (
            0,
            2,
            [0.4, -0.2, -0.2, 0.0],
            0.223_606_797_7,
            1.788_854_382_0,
            0,
            1,
        ),
        (
            1,
            2,
            [0.1, 0.15, -0.35, 0.1],
            0.412_310_562_6,
            0.848_874_687_6,
            2,
            0,
        ),
    ];
    let pairs = json["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 3);
    for ((_, _, d, u, _, _, _), pair) in expected.iter().zip(pairs) {
        for face in 0..4 {
            let got_d = pair["d"][face].as_f64().unwrap();
            let got_u = pair["U"][face].as_f64().unwrap();
            assert!((got_d - d[face]).abs() < 1e-12, "{pair}");
            assert!((got_u - u).abs() < 1e-9, "{pair}");
        }
    }
    let svg = std::fs::read_to_string(plot.join("kc-pairwise.svg")).unwrap();
    let found = cells(&svg);
    assert_eq!(found.len(), 6, "both cells of each of 3 pairs");
    for (a, b, _, _, ratio, at, over) in expected {
        for (row, column) in [(a, b), (b, a)] {
            let cell = found
                .iter()
                .find(|c| c.0 == row && c.1 == column)
                .unwrap_or_else(|| panic!("no cell {row},{column}"));
            assert!((cell.2 - ratio).abs() < 1e-9, "{cell:?} against {ratio}");
            assert_eq!((cell.3, cell.4), (at, over), "{cell:?}");
        }
    }
    // each pair's test, by hand; the shaded cells are the pair that fails it, A − C
    for (pair, (chi2, consistent)) in
        pairs
            .iter()
            .zip([(3.675, true), (14.4, false), (0.75 * 0.165 / 0.0425, true)])
    {
        let vector = &pair["vector"];
        assert!(
            (vector["chi2"].as_f64().unwrap() - chi2).abs() < 1e-9,
            "{pair}"
        );
        assert_eq!(vector["dof"], 3);
        assert_eq!(vector["consistent"], consistent);
        assert!((vector["chi2_critical"].as_f64().unwrap() - 7.814_727_903).abs() < 1e-6);
    }
    for line in svg.lines().filter(|l| l.contains("class=\"cell\"")) {
        let shaded = line.contains("fill=\"#f4b6a8\"");
        assert_eq!(shaded, line.contains("data-consistent=\"false\""), "{line}");
    }
    assert_eq!(svg.matches("fill=\"#f4b6a8\"").count(), 2);
}

#[test]
fn refusals_of_results_that_cannot_be_lined_up_name_the_column() {
    let dir = scratch_dir("columns");
    let four = "quantity,index,value,U,k\n\
                pitch_deviation,1,0.1,0.2,2\n\
                pitch_deviation,2,-0.1,0.2,2\n\
                pitch_deviation,3,0.05,0.2,2\n\
                pitch_deviation,4,-0.05,0.2,2\n";
    let good = format!("A={}", write(&dir, "good.csv", four));
    // three faces: the last face's index, line 4, column 17
    let three = write(
        &dir,
        "three.csv",
        "quantity,index,value,U,k\n\
         pitch_deviation,1,0.1,0.2,2\n\
         pitch_deviation,2,-0.1,0.2,2\n\
         pitch_deviation,3,0.0,0.2,2\n",
    );
    let message = refused(&["kc", &good, &format!("B={three}")]);
    assert!(message.contains(&format!("{three}:4:17:")), "{message}");
    // face 3 missing: at the last face's index, line 4, column 17
    let gap = write(
        &dir,
        "gap.csv",
        "quantity,index,value,U,k\n\
         pitch_deviation,1,0.1,0.2,2\n\
         pitch_deviation,2,-0.1,0.2,2\n\
         pitch_deviation,4,0.0,0.2,2\n",
    );
    let message = refused(&["kc", &good, &format!("B={gap}")]);
    assert!(
        message.contains(&format!("{gap}:4:17:")) && message.contains("face 3"),
        "{message}"
    );
    // U = 0 on face 2: line 3, the U field at column 24 ("pitch_deviation,2,-0.1," is 23)
    let zero = write(
        &dir,
        "zero.csv",
        &four.replace("2,-0.1,0.2,2", "2,-0.1,0,2"),
    );
    let message = refused(&["kc", &good, &format!("B={zero}")]);
    assert!(
        message.contains(&format!("{zero}:3:24:")) && message.contains("U = 0"),
        "{message}"
    );
    // U without its k on face 3: line 4, the k field at column 28
    // ("pitch_deviation,3,0.05,0.2," is 27)
    let no_k = write(
        &dir,
        "no-k.csv",
        &four.replace("3,0.05,0.2,2", "3,0.05,0.2,"),
    );
    let message = refused(&["kc", &good, &format!("B={no_k}")]);
    assert!(
        message.contains(&format!("{no_k}:4:28:")) && message.contains("no standard uncertainty"),
        "{message}"
    );
}
