//! Hardening (issue 13), file names that are not UTF-8: a Latin-1 `café.csv` is a file
//! like any other for `report`, `solve`, `diagnose` and `plan` (issue 34), and no command
//! panics on a path argument that is not UTF-8 (proptest), through the binary as a user
//! meets it.

use std::process::Command;

use crate::hardening_support::{BUDGET, EXAMPLE, EXAMPLE_TRUTH, SELFCAL, temp_dir};

/// A file argument that is not UTF-8 (a Latin-1 `café.csv`) is a file like any other:
/// `report` records the command line without panicking (it did, status 101), and `solve`,
/// `diagnose` and `plan` read the same file (issue 34).
#[cfg(unix)]
#[test]
fn a_file_name_that_is_not_utf8_is_read_without_a_panic() {
    use std::ffi::OsStr;
    use std::os::unix::ffi::OsStrExt;
    let dir = temp_dir("latin1-name");
    let name = dir.join(OsStr::from_bytes(b"caf\xe9.csv"));
    std::fs::copy(EXAMPLE, &name).unwrap();
    let html = dir.join("r.html");
    let run = |args: &[&OsStr]| {
        Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("the binary runs")
    };
    let report = run(&[
        OsStr::new("report"),
        name.as_os_str(),
        OsStr::new("--out"),
        html.as_os_str(),
    ]);
    assert_eq!(
        report.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&report.stderr)
    );
    let text = std::fs::read_to_string(&html).unwrap();
    assert!(
        text.contains("caf\u{fffd}.csv"),
        "the name as it could be shown"
    );
    for command in ["solve", "diagnose"] {
        let out = run(&[OsStr::new(command), name.as_os_str()]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{command}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let plan = run(&[
        OsStr::new("plan"),
        name.as_os_str(),
        OsStr::new("--sigma"),
        OsStr::new("0.05"),
    ]);
    assert_eq!(
        plan.status.code(),
        Some(0),
        "plan: {}",
        String::from_utf8_lossy(&plan.stderr)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

mod not_utf8_arguments {
    //! Every command's path arguments, given names that are not UTF-8 (bytes 0x80 … 0xFF
    //! of Latin-1 and others, drawn by proptest): no command may panic (status 101); it
    //! reads, writes or refuses the file with its usual statuses.
    use std::ffi::{OsStr, OsString};
    use std::os::unix::ffi::{OsStrExt, OsStringExt};
    use std::path::{Path, PathBuf};
    use std::process::Command;

    use proptest::prelude::*;

    use super::{BUDGET, EXAMPLE, EXAMPLE_TRUTH, SELFCAL};

    /// A command line with `@` where the drawn path goes, and the repository file copied
    /// to that path first, or `text:` and the text written there (`None`: the path is an
    /// output, or names nothing). The designs planned are of one bare cycle (dof 0), which
    /// are planned in milliseconds.
    const LINES: &[(&[&str], Option<&str>)] = &[
        (&["solve", "@"], Some(EXAMPLE)),
        (&["solve", EXAMPLE, "--budget", "@"], Some(BUDGET)),
        (&["solve", EXAMPLE, "--plot", "@"], None),
        (&["diagnose", "@"], Some(EXAMPLE)),
        (&["diagnose", EXAMPLE, "--truth", "@"], Some(EXAMPLE_TRUTH)),
        (
            &["diagnose", EXAMPLE, "--budget", "@", "--format", "csv"],
            Some(BUDGET),
        ),
        (&["diagnose", EXAMPLE, "--plot", "@"], None),
        (&["selfcal", "@"], Some(SELFCAL)),
        (&["selfcal", SELFCAL, "--plot", "@"], None),
        (
            &[
                "compare",
                "@",
                "examples/data/polygon24-shift-angle.result.csv",
            ],
            Some("examples/data/polygon24-shift-angle.result.csv"),
        ),
        (
            &["budget", "@"],
            Some("examples/budgets/gum-h1-end-gauge.toml"),
        ),
        (
            &["plan", "@", "--sigma", "0.05"],
            Some("tests/fixtures/expected/sim-bare.file.bare.csv"),
        ),
        (
            &["plan", "--sigma", "0.05", "--designs", "@"],
            Some("text:[[design]]\nfaces = 8\n"),
        ),
        (
            &[
                "plan", "--sigma", "0.05", "--faces", "8", "--cycles", "1", "--plot", "@",
            ],
            None,
        ),
        (&["report", "@", "--out", "@.html"], Some(EXAMPLE)),
        (&["report", EXAMPLE, "--out", "@"], None),
        (
            &[
                "report", EXAMPLE, "--budget", BUDGET, "--meta", "@", "--dcc", "@.xml",
            ],
            Some("examples/report/meta.toml"),
        ),
        (
            &["report", EXAMPLE, "--run-dir", "@", "--out", "@.html"],
            None,
        ),
        (&["simulate", "--out", "@", "--truth-out", "@.json"], None),
        (&["simulate", "--selfcal", "--out", "@"], None),
        (
            &[
                "run",
                "--ac1",
                "@",
                "--ac2",
                "@",
                "--table",
                "@",
                "--out",
                "@.run",
                "--timeout",
                "0.1",
            ],
            None,
        ),
        (&["sim-lab", "--truth-out", "@"], None),
        (&["completions", "bash"], None),
    ];

    fn not_utf8_name() -> impl Strategy<Value = Vec<u8>> {
        // a name of 1 … 12 bytes, one of them at least not UTF-8, never `/` or NUL
        (
            proptest::collection::vec(1u8..=255, 0..8),
            0x80u8..=0xff,
            proptest::collection::vec(1u8..=255, 0..4),
        )
            .prop_map(|(head, bad, tail)| {
                let mut name: Vec<u8> = head.into_iter().chain([bad]).chain(tail).collect();
                name.retain(|&b| b != b'/');
                if std::str::from_utf8(&name).is_ok() {
                    name.push(0xff);
                }
                name
            })
    }

    fn run(dir: &Path, name: &[u8], line: &[&str], copy: Option<&str>) -> std::process::Output {
        let path = dir.join(OsStr::from_bytes(name));
        let _ = std::fs::remove_dir_all(&path);
        let _ = std::fs::remove_file(&path);
        match copy.map(|c| (c, c.strip_prefix("text:"))) {
            Some((_, Some(text))) => std::fs::write(&path, text).expect("write"),
            Some((from, None)) => {
                std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join(from), &path)
                    .map(|_| ())
                    .expect("copy")
            }
            None => {}
        }
        let args: Vec<OsString> = line
            .iter()
            .map(|a| match a.strip_prefix('@') {
                Some(suffix) => {
                    let mut bytes = path.as_os_str().as_bytes().to_vec();
                    bytes.extend_from_slice(suffix.as_bytes());
                    OsString::from_vec(bytes)
                }
                None => OsString::from(a),
            })
            .collect();
        // standard input a pipe closed at once: `sim-lab` then ends (with /dev/null it
        // serves until killed)
        let child = Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(&args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("the binary runs");
        child.wait_with_output().expect("the binary ends")
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 6, failure_persistence: None, ..ProptestConfig::default() })]
        #[test]
        fn no_command_panics_on_a_path_that_is_not_utf8(name in not_utf8_name()) {
            let dir: PathBuf = super::temp_dir("not-utf8-args");
            for (line, copy) in LINES {
                let out = run(&dir, &name, line, *copy);
                let stderr = String::from_utf8_lossy(&out.stderr);
                prop_assert!(
                    matches!(out.status.code(), Some(0..=2)) && !stderr.contains("panicked"),
                    "{line:?} with {name:?}: {:?}\n{stderr}",
                    out.status
                );
            }
        }
    }
}
