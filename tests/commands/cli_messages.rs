//! What the `polycal` binary says besides its results: usage errors with exit status 2,
//! only the formats a command has offered, an OS error printed once, standard input named
//! `<stdin>`, the option that is the way out named, `-q` silencing warnings only, and
//! `--color` on the prefixes of warnings and errors.

use std::process::{Command, Output};

use crate::cli_support::{EXAMPLE, polycal, polycal_stdin};

/// Usage errors exit with status 2 and an `error:` line.
#[test]
fn usage_error() {
    let out = polycal(&["solve", EXAMPLE, "--format", "yaml"]);
    assert_eq!(out.status.code(), Some(2));
    // docs/FORMAT.md §8: one line, beginning `error:`, naming the value and the choices.
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: invalid value 'yaml'"),
        "{stderr}"
    );
    assert!(stderr.contains("table, json, csv"), "{stderr}");
    let missing = polycal(&["solve"]);
    assert_eq!(missing.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&missing.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("<FILES>"), "{stderr}");
    let out = polycal(&["solve", "no-such-file.csv"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("error: ") && stderr.contains("no-such-file.csv"),
        "{stderr}"
    );
}

/// Every command offers only the formats it has: another is refused by the parser
/// (status 2), which lists them (`budget`: table and json; `diagnose`: also csv).
#[test]
fn only_accepted_formats_are_offered() {
    for (args, offered) in [
        (
            &["diagnose", EXAMPLE, "--format", "yaml"][..],
            "[possible values: table, json, csv]",
        ),
        (
            &[
                "budget",
                "examples/budgets/paper-table1.toml",
                "--format",
                "csv",
            ],
            "[possible values: table, json]",
        ),
    ] {
        let out = polycal(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert!(stderr.contains(offered), "{args:?}: {stderr}");
        assert!(out.stdout.is_empty());
    }
}

/// A file that cannot be opened: one `error:` line naming it, with the OS error once.
#[test]
fn os_error_is_printed_once() {
    for args in [
        &["solve", "no-such-file.csv"][..],
        &["diagnose", "no-such-file.csv"],
        &["budget", "no-such-file.toml"],
        &["compare", "no-such-file.csv", "no-such-file.csv"],
    ] {
        let out = polycal(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            stderr.starts_with(&format!("error: {}: ", args[1])),
            "{stderr}"
        );
        assert_eq!(stderr.matches("os error").count(), 1, "{stderr}");
    }
}

/// polycal's own messages name standard input `<stdin>`.
#[test]
fn stdin_is_named_in_messages() {
    let unobservable = polycal(&[
        "simulate",
        "--faces",
        "12",
        "--cycles",
        "2",
        "--ac-faces",
        "1,4",
    ]);
    assert!(unobservable.status.success());
    let out = polycal_stdin(&["solve", "-"], &unobservable.stdout);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("error: <stdin>: cannot solve: "),
        "{stderr}"
    );
}

/// Where a library error needs an option to be actionable, the message names it, once.
#[test]
fn closed_form_refusal_names_the_way_out() {
    let out = polycal(&["solve", EXAMPLE, "--method", "closed-form"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.matches("use --method lsq").count(), 1, "{stderr}");
}

const PAPER_BUDGET: &str = "examples/budgets/paper-table1.toml";

/// `-q` (before or after the command) silences warnings, never results or errors.
#[test]
fn quiet_silences_warnings_only() {
    let loud = polycal(&[
        "solve",
        EXAMPLE,
        "--budget",
        PAPER_BUDGET,
        "--format",
        "csv",
    ]);
    assert!(loud.status.success());
    let stderr = String::from_utf8(loud.stderr).unwrap();
    assert!(stderr.starts_with("warning: "), "{stderr}");
    for args in [
        &[
            "-q",
            "solve",
            EXAMPLE,
            "--budget",
            PAPER_BUDGET,
            "--format",
            "csv",
        ][..],
        &[
            "solve",
            EXAMPLE,
            "--budget",
            PAPER_BUDGET,
            "--format",
            "csv",
            "--quiet",
        ],
    ] {
        let quiet = polycal(args);
        assert!(quiet.status.success());
        assert!(quiet.stderr.is_empty(), "{args:?}");
        assert_eq!(quiet.stdout, loud.stdout, "{args:?}");
    }
    let out = polycal(&["solve", "-q", "no-such-file.csv"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .starts_with("error: ")
    );
}

fn polycal_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_polycal"));
    command
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env_remove("NO_COLOR")
        .env_remove("CLICOLOR_FORCE");
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().expect("the binary runs")
}

/// `--color`: polycal's own prefixes are coloured with `always` (bold yellow, bold red),
/// plain with `never` and with `auto` when standard error is not a terminal; `NO_COLOR`
/// does not override `always`. The rest of the line is never coloured.
#[test]
fn color_of_warning_and_error_prefixes() {
    let warn = |color: &str, env: &[(&str, &str)]| {
        let out = polycal_env(
            &["solve", EXAMPLE, "--budget", PAPER_BUDGET, "--color", color],
            env,
        );
        assert!(out.status.success());
        String::from_utf8(out.stderr).unwrap()
    };
    let always = warn("always", &[]);
    assert!(
        always.starts_with("\x1b[1m\x1b[33mwarning:\x1b[0m examples/budgets/paper-table1.toml"),
        "{always:?}"
    );
    assert_eq!(always, warn("always", &[("NO_COLOR", "1")]));
    let plain = warn("never", &[]);
    assert!(plain.starts_with("warning: examples/"), "{plain:?}");
    assert!(!plain.contains('\x1b'));
    assert_eq!(plain, warn("auto", &[]), "standard error is not a terminal");
    assert_eq!(plain, warn("auto", &[("NO_COLOR", "1")]));

    let out = polycal_env(&["--color=always", "solve", "no-such-file.csv"], &[]);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("\x1b[1m\x1b[31merror:\x1b[0m no-such-file.csv: "),
        "{stderr:?}"
    );
}
