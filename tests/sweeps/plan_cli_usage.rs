//! `polycal plan` (docs/FORMAT.md §5.6) as a user meets it at the command line: invalid
//! designs and options refused with one error line, `--design`'s help listing exactly the
//! keys the parser accepts, and the progress bar of a long plan, on a terminal only.

use std::process::Command;

use crate::plan_cli_support::{one_error_line, polycal, stderr, stdout, temp_dir};

const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";

/// 6. Refusals: status 2, one `error:` line naming what is wrong.
#[test]
fn invalid_designs_and_options_are_refused_with_one_error_line() {
    let err = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "cycles=abc",
    ]));
    assert!(err.contains("cycles") && err.contains("abc"), "{err}");

    let err = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "colour=red",
    ]));
    assert!(err.contains("colour"), "{err}");
    assert!(err.contains("unknown"), "{err}");

    let dir = temp_dir("refusals");
    let designs = dir.join("designs.toml");
    // line 5 holds the bad value, in the second table
    std::fs::write(
        &designs,
        "[[design]]\nname = \"first\"\n\n[[design]]\ncycles = \"x\"\n",
    )
    .unwrap();
    let designs_text = designs.display().to_string();
    let err = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--designs",
        &designs_text,
    ]));
    assert!(
        err.contains(&format!("{designs_text}:5:")),
        "the file and line 5: {err}"
    );

    let err = one_error_line(&polycal(&[
        "plan", EXAMPLE, "--sigma", "0.05", "--faces", "12",
    ]));
    assert!(err.contains("--faces"), "{err}");

    let err = one_error_line(&polycal(&["plan", "--sigma", "0.05", "--target-u", "-1"]));
    assert!(err.contains("--target-u"), "{err}");

    let err = one_error_line(&polycal(&["plan", "--closing"]));
    assert!(err.contains("--sigma"), "{err}");

    let err = one_error_line(&polycal(&["plan", "--sigma", "-0.1"]));
    assert!(err.contains("--sigma") && err.contains("-0.1"), "{err}");
}

/// `polycal ARGS` on a pseudo-terminal (util-linux `script`, which Debian always has):
/// what the terminal showed, standard output and error together.
fn on_a_terminal(args: &str) -> String {
    let out = Command::new("script")
        .args([
            "-qec",
            &format!("{} {args}", env!("CARGO_BIN_EXE_polycal")),
            "/dev/null",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(std::process::Stdio::null())
        .output()
        .expect("script (util-linux) runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn a_long_plan_shows_its_progress_on_a_terminal_only() {
    // four autocollimators on 24 faces: seconds of predicting what a diagnosis finds
    let args = "plan --sigma 0.05 --faces 24 --ac-faces 1,2,3,4 --cycles 6";
    let shown = on_a_terminal(args);
    let bar = "Planning 24 faces, autocollimators at 1,2,3,4, 6 cycles [";
    assert!(shown.contains(bar), "no progress bar:\n{shown}");
    assert!(
        shown.contains(" sizes · ") && shown.contains(" left"),
        "{shown}"
    );
    // the bar is cleared (erased, line by line) before the table is printed
    let table = shown
        .find("polycal plan: 24 faces")
        .expect("the table follows");
    assert!(shown[..table].ends_with("\u{1b}[1A"), "{shown}");
    // -q, and standard error not a terminal: no bar
    assert!(!on_a_terminal(&format!("-q {args}")).contains("Planning"));
    let out = polycal(&args.split(' ').collect::<Vec<_>>());
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(out.stderr.is_empty(), "{}", stderr(&out));
}

/// 10. `--design`'s help lists exactly the keys the parser accepts: the keys of the
///     parser's own refusal of an unknown key, each of which a design takes.
#[test]
fn the_design_help_lists_every_key_the_parser_accepts() {
    let out = polycal(&["plan", "--help"]);
    assert_eq!(out.status.code(), Some(0));
    let help = stdout(&out).replace('\n', " ");
    let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
    let keys_of = |text: &str, after: &str| -> Vec<String> {
        let start = text
            .find(after)
            .unwrap_or_else(|| panic!("{after:?} in {text}"))
            + after.len();
        let rest = &text[start..];
        let end = rest.find([';', ')']).expect("the end of the list");
        rest[..end]
            .split(',')
            .map(|k| k.trim().to_string())
            .collect()
    };
    let in_help = keys_of(&help, "joined by `;` (keys ");
    let refusal = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "colour=red",
    ]));
    let in_parser = keys_of(&refusal, "(keys: ");
    assert_eq!(in_help, in_parser, "help:\n{help}\nrefusal: {refusal}");
    assert!(in_help.iter().any(|k| k == "temperature"), "{in_help:?}");
    // each key listed is one a design takes
    let value = |key: &str| match key {
        "name" => "x",
        "faces" => "24",
        "ac-faces" => "1,2",
        "cycles" | "setups" => "2",
        "closing" | "bidirectional" => "true",
        "setup-shift" => "5",
        "shift-deg" => "0,15",
        "step-seconds" => "10",
        "temperature" => "default",
        other => panic!("a key the test does not know: {other}"),
    };
    for key in &in_help {
        let spec = format!("{key}={}", value(key));
        polycal::plan::Design::default()
            .with_spec(&spec)
            .unwrap_or_else(|e| panic!("{spec}: {e}"));
    }
}
