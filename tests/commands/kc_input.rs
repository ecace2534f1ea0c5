//! `polycal kc`'s inputs as a pilot meets them (docs/FORMAT.md §12): pitch deviations that
//! do not close (noted beyond their rounding, refused when gross), an encoder file without
//! angles beside files with angles, a missing last face, names with bidirectional
//! formatting characters (escaped wherever they are printed) and names that look alike
//! (noted). Every expected figure is worked out by hand from the files written here.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");

fn polycal(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env_remove("NO_COLOR")
        .output()
        .expect("polycal runs")
}

fn scratch_dir() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-kc-input-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn scratch(name: &str, text: &str) -> String {
    let path = scratch_dir().join(name);
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

/// Twelve pitch deviations written to 0.01″ that sum to 0 (±0.10, ±0.05, ±0.02 in
/// pairs), U = 0.2″ at k = 2 (u = 0.1″); `first` replaces face 1's 0.10.
fn polygon(first: &str, faces: u32) -> String {
    let values = [
        "0.10", "-0.10", "0.05", "-0.05", "0.02", "-0.02", "0.10", "-0.10", "0.05", "-0.05",
        "0.02", "-0.02",
    ];
    let mut text = String::from("quantity,index,value,U,k\n");
    for face in 1..=faces {
        let value = if face == 1 {
            first
        } else {
            values[face as usize - 1]
        };
        text.push_str(&format!("pitch_deviation,{face},{value},0.2,2\n"));
    }
    text
}

/// The one `error:` line of a refused run with status 2 and nothing on standard output.
fn refused(args: &[&str]) -> String {
    let out = polycal(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(out.stdout.is_empty(), "{args:?}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
    lines[0].to_string()
}

/// Standard output of a run that evaluated (status 0 or 1).
fn evaluated(args: &[&str]) -> String {
    let out = polycal(args);
    assert!(
        matches!(out.status.code(), Some(0 | 1)),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn json_notes(args: &[&str]) -> Vec<String> {
    let mut args = args.to_vec();
    args.extend(["--format", "json"]);
    let json: Value = serde_json::from_str(&evaluated(&args)).unwrap();
    json["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap().to_string())
        .collect()
}

#[test]
fn pitch_deviations_that_do_not_close_are_noted_beyond_their_rounding_and_refused_when_gross() {
    let closed = scratch("closed.csv", &polygon("0.10", 12));
    // Σβ = 0.05: within 12 × 0.005 = 0.06″, what rounding to 0.01″ explains: no note.
    let rounded = scratch("rounded.csv", &polygon("0.15", 12));
    let a = format!("A={closed}");
    let notes = json_notes(&["kc", &a, &format!("B={rounded}")]);
    assert!(
        !notes.iter().any(|n| n.contains("pitch deviations sum")),
        "{notes:?}"
    );
    // Σβ = 0.10 > 0.06: noted, its mean 0.10/12 = 0.00833″ taken out (≤ 2u = 0.2″).
    let open = scratch("open.csv", &polygon("0.20", 12));
    let b = format!("B={open}");
    let expected = format!(
        "B ({open}): its pitch deviations sum to 0.100″ over 12 faces, more than the rounding \
         of its written digits explains (at most 0.0600″, 12 × half a unit of its last \
         decimal, 10^−2″); their mean, 0.00833″, is taken out of every face, as the \
         comparison does for every result"
    );
    let notes = json_notes(&["kc", &a, &b]);
    assert!(notes.contains(&expected), "{notes:?}");
    let table = evaluated(&["kc", &a, &b]);
    assert!(table.contains(&expected), "{table}");
    // Σβ = 60″: the mean 5″ would move every face by more than 2u = 0.2″: refused.
    let face_deviations = scratch("gross.csv", &polygon("60.10", 12));
    let message = refused(&["kc", &a, &format!("G={face_deviations}")]);
    assert_eq!(
        message,
        format!(
            "error: {face_deviations} (laboratory G): its pitch deviations sum to 60.00″ over \
             12 faces, but a polygon's pitch deviations sum to 0: taking out their mean would \
             move every face by 5.00″, more than the result's expanded uncertainty 2u = 0.200″ \
             of face 1 (face deviations given as pitch deviations, a face left out, a sign or a \
             nominal angle wrong?)"
        )
    );
    // The same for a pilot's repeat.
    let message = refused(&[
        "kc",
        &a,
        &b,
        "--pilot",
        &format!("start={closed}"),
        "--pilot",
        &format!("end={face_deviations}"),
    ]);
    assert!(message.contains("(laboratory end)"), "{message}");
}

/// Encoder errors at 0°, 90°, 180°, 270° with `angle_deg`, or the same rows without it.
fn encoder(angles: bool) -> String {
    let mut text = String::from(if angles {
        "quantity,index,value,U,k,angle_deg\n"
    } else {
        "quantity,index,value,U,k\n"
    });
    for (p, value) in ["0.1", "-0.2", "0.05", "0.05"].iter().enumerate() {
        let angle = if angles {
            format!(",{}", p * 90)
        } else {
            String::new()
        };
        text.push_str(&format!("encoder_error,{p},{value},0.2,2{angle}\n"));
    }
    text
}

#[test]
fn an_encoder_file_without_angles_beside_files_with_angles_is_refused_at_its_first_row() {
    let with = scratch("with-angles.csv", &encoder(true));
    let without = scratch("without-angles.csv", &encoder(false));
    let expected = format!(
        "error: {without}:2:15: encoder_error 0 has no angle_deg, but {with} gives the table \
         angle of its encoder errors: results are matched by angle when they carry angles, so \
         every encoder error of every result needs angle_deg (or none, to be matched by index)"
    );
    for order in [[&with, &without], [&without, &with]] {
        let message = refused(&[
            "kc",
            &format!("A={}", order[0]),
            &format!("B={}", order[1]),
            "--format",
            "json",
            "--quantity",
            "encoder_error",
        ]);
        assert_eq!(message, expected);
    }
    // Every file with angles, or none: compared.
    for file in [&with, &without] {
        let a = format!("A={file}");
        let b = format!("B={file}");
        evaluated(&["kc", &a, &b, "--quantity", "encoder_error"]);
    }
}

#[test]
fn a_missing_last_face_is_reported_as_missing() {
    let twelve = scratch("twelve.csv", &polygon("0.10", 12));
    // Faces 1 … 11 (they need not close: refused before that is looked at).
    let eleven = scratch("eleven.csv", &polygon("0.10", 11));
    let expected = format!(
        "error: {eleven}:12:17: pitch_deviation of face 12 is missing: this result ends at \
         face 11, and {twelve} has faces 1 … 12"
    );
    let a = format!("A={twelve}");
    let b = format!("B={eleven}");
    assert_eq!(refused(&["kc", &a, &b]), expected);
    // The short file first: it is still the one missing its last face.
    assert_eq!(refused(&["kc", &b, &a]), expected);
    // Two faces short: another polygon, as before.
    let ten = scratch("ten.csv", &polygon("0.10", 10));
    let message = refused(&["kc", &a, &format!("C={ten}")]);
    assert!(
        message.contains(&format!("{ten}:11:17: 10 faces, but {twelve} has 12")),
        "{message}"
    );
}

#[test]
fn names_with_bidirectional_controls_are_shown_escaped_wherever_they_are_printed() {
    let closed = scratch("bidi.csv", &polygon("0.10", 12));
    let other = scratch("bidi-other.csv", &polygon("0.12", 12));
    let name = "PTB\u{202e}LPN";
    let a = format!("{name}={closed}");
    let b = format!("NPL={other}");
    let table = evaluated(&["kc", &a, &b]);
    assert!(!table.contains('\u{202e}'), "{table}");
    assert!(table.contains("PTB\\u{202e}LPN"), "{table}");
    // The figures, whose texts the HTML report escapes alike.
    let plots = scratch_dir().join("bidi-plots");
    let plot_arg = plots.to_string_lossy().into_owned();
    evaluated(&["kc", &a, &b, "--plot", &plot_arg]);
    let mut figures = 0;
    for entry in std::fs::read_dir(&plots).unwrap() {
        let svg = std::fs::read_to_string(entry.unwrap().path()).unwrap();
        assert!(!svg.contains('\u{202e}'));
        figures += usize::from(svg.contains("PTB\\u{202e}LPN"));
    }
    assert!(figures >= 2, "{figures}");
    // The error line.
    let message = refused(&["kc", &a, &format!("{name}={other}")]);
    assert!(!message.contains('\u{202e}'), "{message}");
    assert!(message.contains("PTB\\u{202e}LPN"), "{message}");
    // The JSON is data: the name as given.
    let json: Value =
        serde_json::from_str(&evaluated(&["kc", &a, &b, "--format", "json"])).unwrap();
    assert_eq!(json["labs"][0], name);
    // Every one of the controls.
    for c in [
        '\u{61c}', '\u{200e}', '\u{200f}', '\u{202a}', '\u{202b}', '\u{202c}', '\u{202d}',
        '\u{2066}', '\u{2067}', '\u{2068}', '\u{2069}',
    ] {
        let named = format!("X{c}Y={closed}");
        let table = evaluated(&["kc", &named, &b]);
        assert!(!table.contains(c), "U+{:04X}", c as u32);
        assert!(
            table.contains(&format!("X\\u{{{:x}}}Y", c as u32)),
            "U+{:04X}",
            c as u32
        );
    }
}

#[test]
fn names_that_differ_by_case_space_or_look_alike_letters_are_noted() {
    let a = scratch("alike-a.csv", &polygon("0.10", 12));
    let b = scratch("alike-b.csv", &polygon("0.12", 12));
    let c = scratch("alike-c.csv", &polygon("0.08", 12));
    // "РТВ": Cyrillic Er, Te, Ve.
    let args = [
        "kc".to_string(),
        format!("PTB={a}"),
        format!("РТВ={b}"),
        format!("NPL={c}"),
    ];
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let expected = format!(
        "the names \"PTB\" ({a}) and \"РТВ\" ({b}) differ only by case, white space or \
         look-alike letters (U+0420, U+0422, U+0412 in the second): they are compared as two \
         laboratories; if they are one, give its result once"
    );
    let notes = json_notes(&args);
    assert_eq!(notes[0], expected, "{notes:?}");
    assert_eq!(notes.iter().filter(|n| n.contains("look-alike")).count(), 1);
    assert!(evaluated(&args).contains(&expected));
    // Case and white space.
    let spaced = ["kc".to_string(), format!("N PL={a}"), format!("npl={b}")];
    let spaced: Vec<&str> = spaced.iter().map(String::as_str).collect();
    let notes = json_notes(&spaced);
    assert!(
        notes[0].starts_with("the names \"N PL\" (") && notes[0].contains("and \"npl\" ("),
        "{notes:?}"
    );
    // Names unlike each other: no such note.
    let distinct = ["kc".to_string(), format!("PTB={a}"), format!("NPL={b}")];
    let distinct: Vec<&str> = distinct.iter().map(String::as_str).collect();
    assert!(
        !json_notes(&distinct)
            .iter()
            .any(|n| n.contains("look-alike"))
    );
}
