//! `--plot DIR` checked before any work (issue 34, docs/FORMAT.md §8.1, §10.1): every
//! command that writes figures refuses, before it reads, computes or prints anything, a
//! DIR whose figures would replace one of its inputs, and a DIR that is not a directory.
//! One `error:` line naming `--plot`, status 2, nothing on standard output, the input
//! kept byte for byte and nothing written. Tried through the binary in a scratch
//! directory with the bundled examples.

use std::path::PathBuf;
use std::process::Output;

use crate::files_support::{bytes, names, polycal_in, refused, scratch_with};

use polycal::figure::FigureSet;

/// A scratch directory holding copies of the examples a command with `--plot` reads.
fn scratch(name: &str) -> PathBuf {
    scratch_with(
        "outputs-plot",
        name,
        &[
            ("examples/data/polygon24-2ac-6cycles.csv", "m.csv"),
            ("examples/budgets/instrument.toml", "b.toml"),
            ("examples/data/selfa-168.csv", "selfa.csv"),
            ("examples/data/polygon24-shift-angle.result.csv", "r.csv"),
            ("examples/designs.toml", "designs.toml"),
        ],
    )
}

/// Status 2, one `error:` line and nothing on standard output; returns the line.
fn refused_before_work(out: &Output) -> String {
    let stderr = refused(out);
    assert!(
        out.stdout.is_empty(),
        "nothing printed: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    stderr
}

#[test]
fn every_command_refuses_a_figure_over_an_input_before_any_work() {
    let dir = scratch("over-input");
    // (the example the input is a copy of, the figure name it takes in plots/, the
    // command with `{}` for the input's path)
    let cases: [(&str, &str, &[&str]); 8] = [
        ("m.csv", "pitch-deviation.svg", &["solve", "{}"]),
        (
            "b.toml",
            "budget-encoder-error.svg",
            &["solve", "m.csv", "--budget", "{}"],
        ),
        ("m.csv", "diagnose-residuals-ac1.svg", &["diagnose", "{}"]),
        (
            "b.toml",
            "budget-face-deviation.svg",
            &["diagnose", "m.csv", "--budget", "{}"],
        ),
        ("selfa.csv", "selfcal-head-error.svg", &["diagnose", "{}"]),
        ("selfa.csv", "selfcal-encoder-error.svg", &["selfcal", "{}"]),
        (
            "r.csv",
            "compare-pitch-deviation-difference.svg",
            &["compare", "r.csv", "{}"],
        ),
        (
            "designs.toml",
            "plan-pitch-deviation-u.svg",
            &["plan", "--sigma", "0.05", "--designs", "{}"],
        ),
    ];
    for (example, figure, command) in cases {
        let plots = dir.join("plots");
        let _ = std::fs::remove_dir_all(&plots);
        std::fs::create_dir(&plots).expect("mkdir");
        let input = format!("plots/{figure}");
        std::fs::copy(dir.join(example), dir.join(&input)).expect("copy");
        let mut args: Vec<&str> = command
            .iter()
            .map(|a| if *a == "{}" { input.as_str() } else { a })
            .collect();
        args.extend(["--plot", "plots"]);
        let line = refused_before_work(&polycal_in(&dir, &args));
        assert!(
            line.starts_with(&format!(
                "error: --plot {input}: is the input {input} (the same file)"
            )),
            "{args:?}: {line}"
        );
        assert_eq!(
            bytes(&dir.join(&input)),
            bytes(&dir.join(example)),
            "{args:?}"
        );
        assert_eq!(names(&plots), [figure], "{args:?}: nothing written");
    }
    // plan's measurement file, too
    let plots = dir.join("plots");
    std::fs::remove_dir_all(&plots).expect("rm");
    std::fs::create_dir(&plots).expect("mkdir");
    std::fs::copy(dir.join("m.csv"), plots.join("plan-encoder-error-u.svg")).expect("copy");
    let line = refused_before_work(&polycal_in(
        &dir,
        &[
            "plan",
            "plots/plan-encoder-error-u.svg",
            "--sigma",
            "0.05",
            "--plot",
            "plots",
        ],
    ));
    assert!(
        line.starts_with("error: --plot plots/plan-encoder-error-u.svg: is the input"),
        "{line}"
    );
}

#[test]
fn a_figure_linked_to_an_input_is_refused_whatever_its_name() {
    let dir = scratch("links");
    let plots = dir.join("plots");
    std::fs::create_dir(&plots).expect("mkdir");
    let before = bytes(&dir.join("m.csv"));
    // a hard link under a fixed name of solve's figures
    std::fs::hard_link(dir.join("m.csv"), plots.join("face-deviation.svg")).expect("link");
    let line = refused_before_work(&polycal_in(&dir, &["solve", "m.csv", "--plot", "plots"]));
    assert!(
        line.starts_with(
            "error: --plot plots/face-deviation.svg: is the input m.csv (the same file)"
        ),
        "{line}"
    );
    std::fs::remove_file(plots.join("face-deviation.svg")).expect("rm");
    // a symbolic link under a name diagnose takes only once it has read the file (its
    // second autocollimator's residuals): found among the directory's files up front
    std::os::unix::fs::symlink("../m.csv", plots.join("diagnose-residuals-ac2.svg"))
        .expect("symlink");
    let line = refused_before_work(&polycal_in(&dir, &["diagnose", "m.csv", "--plot", "plots"]));
    assert!(
        line.starts_with(
            "error: --plot plots/diagnose-residuals-ac2.svg: is the input m.csv (the same file)"
        ),
        "{line}"
    );
    assert_eq!(bytes(&dir.join("m.csv")), before);
    assert_eq!(names(&plots), ["diagnose-residuals-ac2.svg"]);
}

#[test]
fn a_plot_directory_that_cannot_be_one_is_refused_before_any_work() {
    let dir = scratch("not-a-directory");
    let before = names(&dir);
    for (args, line_start) in [
        (
            &["solve", "m.csv", "--plot", "m.csv"][..],
            "error: --plot m.csv: is a file, not a directory",
        ),
        (
            &["solve", "m.csv", "--plot", "m.csv/figures"],
            "error: --plot m.csv: is a file, not a directory",
        ),
        (
            &["compare", "r.csv", "r.csv", "--plot", "b.toml"],
            "error: --plot b.toml: is a file, not a directory",
        ),
        (
            &["selfcal", "selfa.csv", "--plot", "selfa.csv"],
            "error: --plot selfa.csv: is a file, not a directory",
        ),
        (
            &["plan", "--sigma", "0.05", "--plot", "designs.toml/x"],
            "error: --plot designs.toml: is a file, not a directory",
        ),
    ] {
        let line = refused_before_work(&polycal_in(&dir, args));
        assert!(line.starts_with(line_start), "{args:?}: {line}");
    }
    assert_eq!(names(&dir), before, "nothing written");
}

#[test]
fn every_figure_a_command_writes_is_a_name_checked_up_front() {
    let dir = scratch("names");
    let sets: [(&[&str], FigureSet); 6] = [
        (
            &["solve", "m.csv", "--budget", "b.toml"],
            FigureSet::Solve { budget: true },
        ),
        (
            &["diagnose", "m.csv", "--budget", "b.toml"],
            FigureSet::Diagnose { budget: true },
        ),
        (
            &["diagnose", "selfa.csv"],
            FigureSet::Diagnose { budget: false },
        ),
        (&["selfcal", "selfa.csv"], FigureSet::Selfcal),
        (&["compare", "r.csv", "r.csv"], FigureSet::Compare),
        (
            &["plan", "--sigma", "0.05", "--designs", "designs.toml"],
            FigureSet::Plan,
        ),
    ];
    for (command, set) in sets {
        let plots = dir.join("plots");
        let _ = std::fs::remove_dir_all(&plots);
        let mut args = command.to_vec();
        args.extend(["--plot", "plots", "--format", "json"]);
        let out = polycal_in(&dir, &args);
        assert!(
            matches!(out.status.code(), Some(0 | 1)),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let written = names(&plots);
        assert!(!written.is_empty(), "{args:?}: figures written");
        for name in written {
            assert!(set.may_take(&name), "{args:?}: {name} not checked up front");
        }
    }
}
