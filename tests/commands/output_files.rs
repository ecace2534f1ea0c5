//! Writing files (issue 34, docs/FORMAT.md §8.1): every command writes an output only
//! where the user meant it — never over one of its inputs, never two outputs into one
//! file, never over a device, a FIFO or a directory — and whole or not at all, keeping
//! the mode of the file it replaces. Tried through the binary as a user meets it, in a
//! scratch directory with the bundled example; every expectation below is what the
//! files on disk must be, read back byte for byte.

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::files_support::{bytes, names, polycal_in, refused, scratch_with};

const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const META: &str = "examples/report/meta.toml";

/// A scratch directory holding copies of the example, its budget and its metadata.
fn scratch(name: &str) -> PathBuf {
    scratch_with(
        "outputs",
        name,
        &[(EXAMPLE, "m.csv"), (BUDGET, "b.toml"), (META, "meta.toml")],
    )
}

#[test]
fn an_input_named_as_an_output_is_refused_and_kept() {
    let dir = scratch("input");
    std::fs::hard_link(dir.join("m.csv"), dir.join("same.csv")).expect("hard link");
    std::os::unix::fs::symlink("m.csv", dir.join("link.csv")).expect("symlink");
    let before: Vec<(String, Vec<u8>)> = ["m.csv", "b.toml", "meta.toml"]
        .iter()
        .map(|n| (n.to_string(), bytes(&dir.join(n))))
        .collect();
    let names_before = names(&dir);
    let report = [
        "report",
        "m.csv",
        "--budget",
        "b.toml",
        "--meta",
        "meta.toml",
    ];
    for (extra, flag, input) in [
        (&["--out", "m.csv"][..], "--out m.csv", "m.csv"),
        (&["--out", "./m.csv"], "--out ./m.csv", "m.csv"),
        (&["--out", "same.csv"], "--out same.csv", "m.csv"),
        (&["--out", "link.csv"], "--out link.csv", "m.csv"),
        (&["--out", "b.toml"], "--out b.toml", "b.toml"),
        (&["--out", "meta.toml"], "--out meta.toml", "meta.toml"),
        (
            &["--out", "r.html", "--dcc", "m.csv"],
            "--dcc m.csv",
            "m.csv",
        ),
        (&["--dcc", "meta.toml"], "--dcc meta.toml", "meta.toml"),
    ] {
        let args: Vec<&str> = report.iter().chain(extra).copied().collect();
        let line = refused(&polycal_in(&dir, &args));
        assert!(
            line.starts_with(&format!(
                "error: {flag}: is the input {input} (the same file)"
            )),
            "{args:?}: {line}"
        );
    }
    for (name, was) in &before {
        assert_eq!(&bytes(&dir.join(name)), was, "{name} kept");
    }
    assert_eq!(
        names(&dir),
        names_before,
        "nothing written, no temporary file left"
    );

    // the figures of --plot are never written over an input either
    std::fs::create_dir_all(dir.join("plots")).expect("mkdir");
    std::fs::copy(dir.join("m.csv"), dir.join("plots/pitch-deviation.svg")).expect("copy");
    let line = refused(&polycal_in(
        &dir,
        &["solve", "plots/pitch-deviation.svg", "--plot", "plots"],
    ));
    assert!(
        line.contains("is the input plots/pitch-deviation.svg"),
        "{line}"
    );
    assert_eq!(bytes(&dir.join("plots/pitch-deviation.svg")), before[0].1);
    assert_eq!(names(&dir.join("plots")), ["pitch-deviation.svg"]);
}

#[test]
fn two_outputs_of_one_file_are_refused_before_anything_is_written() {
    let dir = scratch("twice");
    for args in [
        &["simulate", "--out", "x.csv", "--truth-out", "x.csv"][..],
        &["simulate", "--out", "x.csv", "--truth-out", "./x.csv"],
        &[
            "simulate",
            "--selfcal",
            "--out",
            "s.csv",
            "--truth-out",
            "s.csv",
        ],
        &[
            "report",
            "m.csv",
            "--budget",
            "b.toml",
            "--meta",
            "meta.toml",
            "--out",
            "r.xml",
            "--dcc",
            "r.xml",
        ],
    ] {
        let line = refused(&polycal_in(&dir, args));
        assert!(
            line.contains("(the same file); give each output its own file"),
            "{line}"
        );
    }
    assert_eq!(names(&dir), ["b.toml", "m.csv", "meta.toml"]);
}

#[test]
fn only_regular_files_are_replaced() {
    let dir = scratch("kinds");
    assert!(
        Command::new("mkfifo")
            .arg(dir.join("fifo"))
            .status()
            .expect("mkfifo runs")
            .success()
    );
    std::fs::create_dir(dir.join("sub")).expect("mkdir");
    for (args, what) in [
        (
            &["report", "m.csv", "--out", "/dev/null"][..],
            "--out /dev/null: is a character device",
        ),
        (&["simulate", "--out", "fifo"], "--out fifo: is a FIFO"),
        (
            &["simulate", "--truth-out", "sub"],
            "--truth-out sub: is a directory",
        ),
        (
            &["report", "m.csv", "--out", "sub"],
            "--out sub: is a directory",
        ),
    ] {
        let line = refused(&polycal_in(&dir, args));
        assert!(
            line.starts_with(&format!("error: {what}, not a regular file")),
            "{args:?}: {line}"
        );
    }
    // a symbolic link the user names is followed and kept; one to nothing is refused
    std::os::unix::fs::symlink("reports/r1.html", dir.join("latest.html")).expect("symlink");
    let line = refused(&polycal_in(
        &dir,
        &["report", "m.csv", "--out", "latest.html"],
    ));
    assert!(
        line.contains("--out latest.html: is a symbolic link to nothing"),
        "{line}"
    );
    std::fs::create_dir(dir.join("reports")).expect("mkdir");
    std::fs::write(dir.join("reports/r1.html"), "old").expect("write");
    let out = polycal_in(&dir, &["report", "m.csv", "--out", "latest.html"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        std::fs::symlink_metadata(dir.join("latest.html"))
            .expect("link")
            .file_type()
            .is_symlink()
    );
    assert!(bytes(&dir.join("reports/r1.html")).starts_with(b"<!DOCTYPE html>"));
    assert_eq!(names(&dir.join("reports")), ["r1.html"]);
}

#[test]
fn a_replaced_file_keeps_its_mode_and_a_new_one_gets_the_umask() {
    let dir = scratch("mode");
    for (args, file) in [
        (&["report", "m.csv", "--out", "r.html"][..], "r.html"),
        (
            &["simulate", "--out", "s.csv", "--truth-out", "t.json"],
            "s.csv",
        ),
        (
            &["simulate", "--out", "s.csv", "--truth-out", "t.json"],
            "t.json",
        ),
    ] {
        std::fs::write(dir.join(file), "old").expect("write");
        std::fs::set_permissions(dir.join(file), std::fs::Permissions::from_mode(0o640))
            .expect("chmod");
        let out = polycal_in(&dir, args);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let metadata = std::fs::metadata(dir.join(file)).expect("metadata");
        assert_eq!(metadata.permissions().mode() & 0o7777, 0o640, "{file}");
        assert_ne!(bytes(&dir.join(file)), b"old", "{file} rewritten");
    }
    // a new file: 0666 less the umask (027, set by the shell that runs it)
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "umask 027 && exec '{}' simulate --out new.csv",
            env!("CARGO_BIN_EXE_polycal")
        ))
        .current_dir(&dir)
        .output()
        .expect("sh runs");
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mode = std::fs::metadata(dir.join("new.csv"))
        .expect("metadata")
        .permissions()
        .mode();
    assert_eq!(mode & 0o777, 0o640);
}

/// `report m.csv` with the budget and metadata, the HTML to `out` and the DCC to `dcc`.
fn report_with_dcc(dir: &Path, out: &str, dcc: &str) -> Output {
    polycal_in(
        dir,
        &[
            "report",
            "m.csv",
            "--budget",
            "b.toml",
            "--meta",
            "meta.toml",
            "--out",
            out,
            "--dcc",
            dcc,
        ],
    )
}

#[test]
fn a_command_writes_all_its_outputs_or_none() {
    let dir = scratch("all-or-none");
    std::fs::write(dir.join("r.html"), "old report").expect("write");
    // the DCC cannot be written (its directory does not exist): the report is not
    // replaced either, and no temporary file is left
    let line = refused(&report_with_dcc(&dir, "r.html", "missing/c.xml"));
    assert!(
        line.starts_with("error: --dcc missing/c.xml: cannot be written"),
        "{line}"
    );
    assert_eq!(bytes(&dir.join("r.html")), b"old report");
    assert_eq!(names(&dir), ["b.toml", "m.csv", "meta.toml", "r.html"]);
    // simulate: a truth that cannot be written keeps the run's file from being written
    let line = refused(&polycal_in(
        &dir,
        &[
            "simulate",
            "--out",
            "run.csv",
            "--truth-out",
            "missing/t.json",
        ],
    ));
    assert!(
        line.contains("--truth-out missing/t.json: cannot be written"),
        "{line}"
    );
    assert!(!dir.join("run.csv").exists());
    // and both written when both can be
    let out = report_with_dcc(&dir, "r.html", "c.xml");
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(bytes(&dir.join("r.html")).starts_with(b"<!DOCTYPE html>"));
    assert!(bytes(&dir.join("c.xml")).starts_with(b"<?xml"));
}

#[test]
fn file_names_cannot_run_as_formulas_nor_recolour_the_terminal() {
    let dir = scratch("names");
    for name in ["=HYPERLINK(1).csv", "-2.csv", "+3.csv", "@4.csv"] {
        std::fs::copy(dir.join("m.csv"), dir.join(name)).expect("copy");
    }
    let out = polycal_in(
        &dir,
        &[
            "solve",
            "--format",
            "csv",
            "--",
            "=HYPERLINK(1).csv",
            "-2.csv",
            "+3.csv",
            "@4.csv",
            "m.csv",
        ],
    );
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("UTF-8");
    let mut first_cells: Vec<&str> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap_or_default())
        .collect();
    first_cells.dedup();
    assert_eq!(
        first_cells,
        [
            "'=HYPERLINK(1).csv",
            "'-2.csv",
            "'+3.csv",
            "'@4.csv",
            "m.csv"
        ]
    );
    // an escape sequence and a line feed in a file name are shown escaped: in the
    // tables, the CSV's file column and the JSON's file as in the messages
    let odd = "a\u{1b}[31mred\nb.csv";
    std::fs::copy(dir.join("m.csv"), dir.join(odd)).expect("copy");
    for format in ["table", "csv", "json"] {
        let out = polycal_in(&dir, &["solve", "--format", format, "m.csv", odd]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).expect("UTF-8");
        assert!(!text.contains('\u{1b}'), "{format}: {text}");
        // (in JSON the backslashes are escaped in turn)
        let shown = if format == "json" {
            "a\\\\u{1b}[31mred\\\\nb.csv"
        } else {
            "a\\u{1b}[31mred\\nb.csv"
        };
        assert!(text.contains(shown), "{format}: {text}");
    }
    let line = refused(&polycal_in(
        &dir,
        &["solve", "a\u{1b}[31mred\nerror: forged.csv"],
    ));
    assert!(!line.contains('\u{1b}'), "{line:?}");
    assert!(
        line.contains("a\\u{1b}[31mred\\nerror: forged.csv"),
        "{line:?}"
    );
}

/// A temporary file of `name` in `dir`, if one is there.
fn temporary_of(dir: &Path, name: &str) -> Option<PathBuf> {
    std::fs::read_dir(dir).ok()?.find_map(|e| {
        let e = e.ok()?;
        let n = e.file_name().to_string_lossy().into_owned();
        (n.starts_with(&format!(".{name}.")) && n.ends_with(".polycal-tmp")).then(|| e.path())
    })
}

#[test]
fn a_reader_never_sees_half_a_file_and_a_kill_leaves_the_old_one() {
    let dir = scratch("kill");
    let args = [
        "simulate", "--faces", "5760", "--cycles", "20", "--out", "big.csv",
    ];
    let spawn = || {
        std::fs::write(dir.join("big.csv"), "old\n").expect("write");
        Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(args)
            .current_dir(&dir)
            .spawn()
            .expect("the binary runs")
    };
    // watched while it is written: the old file, then the whole new one, nothing between
    // (written in place, 12 MB showed thousands of sizes between)
    let mut child = spawn();
    let mut sizes = std::collections::BTreeSet::new();
    while child.try_wait().expect("wait").is_none() {
        if let Ok(m) = std::fs::metadata(dir.join("big.csv")) {
            sizes.insert(m.len());
        }
    }
    let whole = bytes(&dir.join("big.csv"));
    assert!(
        whole.len() > 10_000_000,
        "a file that takes a while to write"
    );
    sizes.remove(&4);
    sizes.remove(&(whole.len() as u64));
    assert!(
        sizes.is_empty(),
        "sizes seen between the old and the new file: {sizes:?}"
    );
    // killed while its temporary file is being written: the old file stays
    let mut killed = 0;
    for _ in 0..5 {
        let mut child = spawn();
        let mut this_one = false;
        while child.try_wait().expect("wait").is_none() {
            if let Some(temporary) = temporary_of(&dir, "big.csv") {
                let _ = child.kill();
                let _ = child.wait();
                this_one = true;
                let _ = std::fs::remove_file(temporary);
                break;
            }
        }
        killed += usize::from(this_one);
        let now = bytes(&dir.join("big.csv"));
        let expected: &[u8] = if this_one { b"old\n" } else { &whole };
        assert!(now == expected, "killed: {this_one}; {} bytes", now.len());
    }
    assert!(killed > 0, "no kill came while the file was written");
}

#[test]
fn ctrl_c_while_writing_leaves_the_old_file_and_no_temporary() {
    use std::os::unix::process::ExitStatusExt;
    let dir = scratch("interrupt");
    let mut interrupted = 0;
    for _ in 0..5 {
        std::fs::write(dir.join("big.csv"), "old\n").expect("write");
        let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args([
                "simulate", "--faces", "5760", "--cycles", "20", "--out", "big.csv",
            ])
            .current_dir(&dir)
            .spawn()
            .expect("the binary runs");
        let mut this_one = false;
        while child.try_wait().expect("wait").is_none() {
            if temporary_of(&dir, "big.csv").is_some() {
                let sent = Command::new("kill")
                    .args(["-INT", &child.id().to_string()])
                    .status()
                    .expect("kill runs");
                assert!(sent.success());
                this_one = true;
                break;
            }
        }
        let started = std::time::Instant::now();
        let status = child.wait().expect("wait");
        if !this_one {
            continue;
        }
        interrupted += 1;
        assert!(
            started.elapsed() < std::time::Duration::from_secs(1),
            "ended {:?} after Ctrl-C",
            started.elapsed()
        );
        // ended as Ctrl-C ends a program, so that a calling script stops too
        assert!(
            status.signal() == Some(2) || status.code() == Some(130),
            "{status:?}"
        );
        assert_eq!(bytes(&dir.join("big.csv")), b"old\n");
        assert_eq!(
            temporary_of(&dir, "big.csv"),
            None,
            "the temporary file removed"
        );
    }
    assert!(interrupted > 0, "no Ctrl-C came while the file was written");
}

/// When a signal is sent to a command: after a delay, or as soon as one of its
/// temporary files appears in a directory.
#[derive(Clone, Copy, Debug)]
enum When {
    After(std::time::Duration),
    Writing,
}

/// Runs `args` in `dir` and sends `signal` (`KILL` or `INT`) when `when` says, looking
/// for temporary files in `watch`; returns the status and whether the signal was sent
/// (false when the command ended first).
fn signalled(
    dir: &Path,
    args: &[&str],
    watch: &Path,
    when: When,
    signal: &str,
) -> (std::process::ExitStatus, bool) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(dir)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("the binary runs");
    let started = std::time::Instant::now();
    let mut sent = false;
    while child.try_wait().expect("wait").is_none() {
        let now = match when {
            When::After(delay) => started.elapsed() >= delay,
            // an output's temporary file, not the probe of its directory's check
            When::Writing => temporaries(watch).iter().any(|t| {
                t.file_name()
                    .is_some_and(|n| !n.to_string_lossy().starts_with(".polycal-probe."))
            }),
        };
        if now {
            let status = Command::new("kill")
                .args([format!("-{signal}"), child.id().to_string()])
                .status()
                .expect("kill runs");
            // (it may have ended between the two)
            sent = status.success();
            break;
        }
        if matches!(when, When::After(_)) {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
    }
    (child.wait().expect("wait"), sent)
}

/// The temporary files in `dir`.
fn temporaries(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .filter(|e| e.file_name().to_string_lossy().ends_with(".polycal-tmp"))
                .map(|e| e.path())
                .collect()
        })
        .unwrap_or_default()
}

/// How long `args` take in `dir` (run to the end, status 0).
fn duration_of(dir: &Path, args: &[&str]) -> std::time::Duration {
    let started = std::time::Instant::now();
    let out = polycal_in(dir, args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    started.elapsed()
}

/// Kill moments for a command that takes `whole`: `n` delays spread over 0 … 1.2·whole
/// (each moved by up to a tenth of its step, from the clock), and as many at the moment
/// a temporary file appears.
fn moments(whole: std::time::Duration, n: u32) -> Vec<When> {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    let step = whole.mul_f64(1.2) / n;
    let mut moments = Vec::new();
    for i in 0..n {
        let jitter = step.mul_f64(f64::from((nanos / (i + 1)) % 100) / 1000.0);
        moments.push(When::After(step * i + jitter));
        moments.push(When::Writing);
    }
    moments
}

/// A big run (360 faces) as `big.csv` in `dir`, for commands that take a while.
fn big_run(dir: &Path) {
    let out = polycal_in(dir, &["simulate", "--faces", "360", "--out", "big.csv"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The report `r.html` and DCC `c.xml` of `big.csv`.
const BIG_REPORT: [&str; 10] = [
    "report",
    "big.csv",
    "--budget",
    "b.toml",
    "--meta",
    "meta.toml",
    "--out",
    "r.html",
    "--dcc",
    "c.xml",
];

/// `r.html` and `c.xml` are each their old content or a whole new document.
fn old_or_whole_report(dir: &Path, why: &str) {
    let html = bytes(&dir.join("r.html"));
    assert!(
        html == b"old\n"
            || (html.starts_with(b"<!DOCTYPE html>")
                && html.trim_ascii_end().ends_with(b"</html>")),
        "{why}: r.html is neither the old file nor a whole report ({} bytes)",
        html.len()
    );
    let xml = bytes(&dir.join("c.xml"));
    if xml != b"old\n" {
        let text = String::from_utf8(xml).expect("UTF-8");
        let doc = roxmltree::Document::parse(&text)
            .unwrap_or_else(|e| panic!("{why}: c.xml is not well-formed: {e}"));
        assert_eq!(
            doc.root_element().tag_name().name(),
            "digitalCalibrationCertificate",
            "{why}"
        );
    }
}

#[test]
fn a_kill_during_report_leaves_each_file_old_or_whole() {
    let dir = scratch("kill-report");
    big_run(&dir);
    let whole = duration_of(&dir, &BIG_REPORT);
    let mut during = 0;
    for when in moments(whole, 4) {
        for name in ["r.html", "c.xml"] {
            std::fs::write(dir.join(name), "old\n").expect("write");
        }
        let (_, sent) = signalled(&dir, &BIG_REPORT, &dir, when, "KILL");
        let why = format!("SIGKILL {when:?}");
        old_or_whole_report(&dir, &why);
        let left = temporaries(&dir);
        during += usize::from(sent && matches!(when, When::Writing));
        // at most the temporary files of the two outputs
        assert!(left.len() <= 2, "{why}: {left:?}");
        for temporary in left {
            std::fs::remove_file(temporary).expect("rm");
        }
    }
    assert!(during > 0, "no kill came while the report was written");
}

#[test]
fn ctrl_c_during_report_leaves_each_file_old_or_whole_and_no_temporary() {
    use std::os::unix::process::ExitStatusExt;
    let dir = scratch("interrupt-report");
    big_run(&dir);
    let whole = duration_of(&dir, &BIG_REPORT);
    for when in moments(whole, 4) {
        for name in ["r.html", "c.xml"] {
            std::fs::write(dir.join(name), "old\n").expect("write");
        }
        let (status, sent) = signalled(&dir, &BIG_REPORT, &dir, when, "INT");
        let why = format!("SIGINT {when:?}: {status:?}");
        assert!(
            status.code() == Some(0)
                || (sent && (status.signal() == Some(2) || status.code() == Some(130))),
            "{why}"
        );
        old_or_whole_report(&dir, &why);
        assert_eq!(temporaries(&dir), Vec::<PathBuf>::new(), "{why}");
    }
}

/// The six figures of `solve big.csv --budget b.toml --plot plots`.
const BIG_FIGURES: [&str; 6] = [
    "pitch-deviation.svg",
    "face-deviation.svg",
    "encoder-error.svg",
    "budget-pitch-deviation.svg",
    "budget-face-deviation.svg",
    "budget-encoder-error.svg",
];

/// Every figure in `plots` is its old content or a whole SVG document.
fn old_or_whole_figures(plots: &Path, why: &str) {
    for name in BIG_FIGURES {
        let svg = bytes(&plots.join(name));
        if svg == b"old\n" {
            continue;
        }
        let text = String::from_utf8(svg).expect("UTF-8");
        assert!(
            text.trim_end().ends_with("</svg>"),
            "{why}: {name} cut short"
        );
        let doc = roxmltree::Document::parse(&text)
            .unwrap_or_else(|e| panic!("{why}: {name} is not well-formed: {e}"));
        assert_eq!(doc.root_element().tag_name().name(), "svg", "{why}: {name}");
    }
}

/// Puts the old content in every figure of `plots`.
fn old_figures(plots: &Path) {
    std::fs::create_dir_all(plots).expect("mkdir");
    for name in BIG_FIGURES {
        std::fs::write(plots.join(name), "old\n").expect("write");
    }
}

const BIG_PLOT: [&str; 6] = ["solve", "big.csv", "--budget", "b.toml", "--plot", "plots"];

#[test]
fn a_kill_while_the_figures_are_written_leaves_each_old_or_whole() {
    let dir = scratch("kill-plot");
    big_run(&dir);
    let plots = dir.join("plots");
    old_figures(&plots);
    let whole = duration_of(&dir, &BIG_PLOT);
    let mut during = 0;
    for when in moments(whole, 4) {
        old_figures(&plots);
        let (_, sent) = signalled(&dir, &BIG_PLOT, &plots, when, "KILL");
        let why = format!("SIGKILL {when:?}");
        old_or_whole_figures(&plots, &why);
        during += usize::from(sent && matches!(when, When::Writing));
        for temporary in temporaries(&plots) {
            std::fs::remove_file(temporary).expect("rm");
        }
    }
    assert!(during > 0, "no kill came while the figures were written");
}

#[test]
fn ctrl_c_while_the_figures_are_written_leaves_no_temporary() {
    use std::os::unix::process::ExitStatusExt;
    let dir = scratch("interrupt-plot");
    big_run(&dir);
    let plots = dir.join("plots");
    old_figures(&plots);
    let whole = duration_of(&dir, &BIG_PLOT);
    for when in moments(whole, 4) {
        old_figures(&plots);
        let (status, sent) = signalled(&dir, &BIG_PLOT, &plots, when, "INT");
        let why = format!("SIGINT {when:?}: {status:?}");
        assert!(
            status.code() == Some(0)
                || (sent && (status.signal() == Some(2) || status.code() == Some(130))),
            "{why}"
        );
        old_or_whole_figures(&plots, &why);
        assert_eq!(temporaries(&plots), Vec::<PathBuf>::new(), "{why}");
    }
}

/// How the read-only test runs the binary: as root through `setpriv` as the unprivileged
/// user 65534 (root ignores permissions), as it is otherwise; `None`, with the reason,
/// when neither can.
fn unprivileged() -> Result<Vec<String>, String> {
    let binary = env!("CARGO_BIN_EXE_polycal").to_string();
    let root = Command::new("id")
        .arg("-u")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
        .map_err(|e| format!("id -u: {e}"))?;
    if !root {
        return Ok(vec![binary]);
    }
    let prefix: Vec<String> = [
        "setpriv",
        "--reuid=65534",
        "--regid=65534",
        "--clear-groups",
    ]
    .map(String::from)
    .to_vec();
    let tried = Command::new(&prefix[0])
        .args(&prefix[1..])
        .args([binary.as_str(), "--version"])
        .output()
        .map_err(|e| format!("running as root and setpriv cannot run: {e}"))?;
    if !tried.status.success() {
        return Err(format!(
            "running as root and the binary cannot run as user 65534 through setpriv: {}",
            String::from_utf8_lossy(&tried.stderr).trim()
        ));
    }
    let mut command = prefix;
    command.push(binary);
    Ok(command)
}

#[test]
fn a_directory_the_process_cannot_write_is_refused_and_nothing_is_left() {
    let command = match unprivileged() {
        Ok(command) => command,
        Err(why) => {
            eprintln!("skipped: {why}");
            return;
        }
    };
    // a directory of /tmp (parents 0755 or sticky 1777) the user can read but not write
    let dir = std::env::temp_dir().join(format!("polycal-outputs-ro-{}", std::process::id()));
    if dir.exists() {
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755)).expect("chmod");
        std::fs::remove_dir_all(&dir).expect("rm");
    }
    std::fs::create_dir(&dir).expect("mkdir");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (from, to) in [(EXAMPLE, "m.csv"), (BUDGET, "b.toml"), (META, "meta.toml")] {
        std::fs::copy(root.join(from), dir.join(to)).expect("copy");
        std::fs::set_permissions(dir.join(to), std::fs::Permissions::from_mode(0o644))
            .expect("chmod");
    }
    std::fs::create_dir(dir.join("plots")).expect("mkdir");
    for d in [dir.join("plots"), dir.clone()] {
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o555)).expect("chmod");
    }
    let before = names(&dir);
    for (args, path) in [
        (&["report", "m.csv", "--out", "r.html"][..], "--out r.html"),
        (
            &[
                "report",
                "m.csv",
                "--dcc",
                "c.xml",
                "--budget",
                "b.toml",
                "--meta",
                "meta.toml",
            ],
            "--dcc c.xml",
        ),
        (&["simulate", "--out", "s.csv"], "--out s.csv"),
        (&["simulate", "--truth-out", "t.json"], "--truth-out t.json"),
        (&["solve", "m.csv", "--plot", "plots"], "--plot plots"),
        (
            &["solve", "m.csv", "--plot", "new-plots"],
            "--plot new-plots",
        ),
    ] {
        let out = Command::new(&command[0])
            .args(&command[1..])
            .args(args)
            .current_dir(&dir)
            .output()
            .expect("the binary runs");
        let line = refused(&out);
        assert_eq!(
            line.trim_end(),
            format!("error: {path}: cannot be written: Permission denied (os error 13)"),
            "{args:?}"
        );
        // refused before any work: nothing printed
        assert!(out.stdout.is_empty(), "{args:?}");
    }
    assert_eq!(names(&dir), before, "nothing left");
    assert!(names(&dir.join("plots")).is_empty(), "nothing left");
    for d in [dir.clone(), dir.join("plots")] {
        std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    }
    std::fs::remove_dir_all(&dir).expect("rm");
}
