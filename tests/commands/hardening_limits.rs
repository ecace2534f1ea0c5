//! Hardening (issue 13), sizes: inputs and work too big for the machine are refused up
//! front with the size and the limit — budgets of many components and correlations, Monte
//! Carlo trials, designs, inputs beyond the read limit, the address-space limit
//! (`ulimit -v`), a line of commas, trial counts at their edges — and a long Monte Carlo
//! that is allowed shows its progress and ends within a second of Ctrl-C. Each class is
//! tried with its own input, through the binary as a user meets it. The limits are
//! docs/FORMAT.md §2.2; the positions and the arithmetic below are derived by hand from
//! the texts written here.

use std::process::{Command, Output, Stdio};

use crate::hardening_support::{BUDGET, EXAMPLE, one_error_line, polycal, temp_dir, write};

/// `n` type-B components `c0` … of u = 0.01 each, as budget TOML.
fn components(n: usize) -> String {
    (0..n)
        .map(|i| format!("[[component]]\nname = \"c{i}\"\ntype = \"B\"\nu = 0.01\n"))
        .collect()
}

#[test]
fn a_budget_of_sixty_thousand_components_combines_and_too_many_correlations_are_refused() {
    let dir = temp_dir("big-budget");
    let n = 60_000;
    let text = format!("p = 0.95\n{}", components(n));
    let path = write(&dir, "sixty.toml", &text);
    let out = polycal(&["budget", &path, "--format", "json"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // u_c = 0.01·√60000, k = 1.96 (ν infinite)
    let u_c = json["combined_u"].as_f64().unwrap();
    assert!((u_c - 0.01 * (n as f64).sqrt()).abs() < 1e-12, "{u_c}");
    assert_eq!(json["components"].as_array().unwrap().len(), n);

    // correlations need a matrix of the correlated components: more than 1000 refused
    let mut text = components(2004);
    for i in 0..1001 {
        text.push_str(&format!(
            "[[correlation]]\nbetween = [\"c{}\", \"c{}\"]\nr = 0.1\n",
            2 * i,
            2 * i + 1
        ));
    }
    let path = write(&dir, "correlated.toml", &text);
    assert_eq!(
        one_error_line(&polycal(&["budget", &path])),
        format!(
            "{path}: the budget gives 1001 correlation coefficients; at most 1000 are evaluated \
             (their consistency is checked on a matrix of the correlated components)"
        )
    );
}

#[test]
fn a_monte_carlo_too_big_for_the_machine_is_refused_up_front() {
    // The trials are not stored: the values kept grow like √M per output, so 10¹² trials
    // of the example's 71 outputs fit in about 17 GiB. Of 1440 positions' 4319 outputs
    // they need about 990 GiB: refused before the first trial.
    let dir = temp_dir("mc-too-big");
    let path = dir.join("p1440.csv").display().to_string();
    let out = polycal(&[
        "simulate",
        "--faces",
        "1440",
        "--cycles",
        "1",
        "--closing",
        "--out",
        &path,
    ]);
    assert!(out.status.success());
    let message = one_error_line(&polycal(&[
        "solve",
        &path,
        "--budget",
        BUDGET,
        "--monte-carlo",
        "1e12",
    ]));
    assert!(
        message.starts_with(&format!(
            "{path}: Monte Carlo failed: 1000000000000 trials of 4319 outputs need about "
        )) && message.contains(" GiB of memory; "),
        "{message}"
    );
    assert!(
        message.ends_with("are available on this machine: ask for fewer trials"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_design_too_big_for_the_machine_is_refused_up_front() {
    let dir = temp_dir("design");
    let path = dir.join("sub-pitch.csv").display().to_string();
    // 40 000 faces in two mountings 0.01° apart, the second mounting's second
    // autocollimator read at every third step only: too irregular for the coset engine
    // (that stream reads most positions zero times), so the cosets' differences are
    // effect columns, 39 999 of them of 266 668 readings, 8 bytes each, about 79.5 GiB
    // before the engine allocates anything.
    let out = polycal(&[
        "simulate",
        "--faces",
        "40000",
        "--cycles",
        "2",
        "--setups",
        "2",
        "--shift-deg",
        "0,0.01",
        "--out",
        &path,
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&path).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|line| {
            // cycle,step,ac,face,reading,direction,setup,…
            let fields: Vec<&str> = line.split(',').collect();
            let number = |i: usize| fields.get(i).and_then(|f| f.parse::<usize>().ok());
            !(number(6) == Some(2) && number(2) == Some(2) && number(1).is_some_and(|s| s % 3 != 0))
        })
        .collect();
    std::fs::write(&path, kept.join("\n") + "\n").unwrap();
    let message = one_error_line(&polycal(&["solve", &path]));
    assert!(
        message.starts_with(&format!(
            "{path}: cannot solve: the design (40000 positions, 4 autocollimator streams, 39999 \
             effect terms, 266668 readings) needs about 79.5 GiB of memory for the sub-pitch solver; "
        )),
        "{message}"
    );
    assert!(
        message.ends_with("are available on this machine"),
        "{message}"
    );
}

#[test]
fn inputs_beyond_the_read_limit_are_refused_not_read_to_the_end() {
    let limit = 256u64 << 20;
    // a stream is read to the limit and no further
    for args in [
        vec!["solve", "/dev/zero"],
        vec!["selfcal", "/dev/zero"],
        vec!["budget", "/dev/zero"],
        vec!["compare", "/dev/zero", EXAMPLE],
        vec!["diagnose", EXAMPLE, "--truth", "/dev/zero"],
    ] {
        assert_eq!(
            one_error_line(&polycal(&args)),
            format!(
                "/dev/zero: at least {} bytes, more than polycal reads from one input ({limit} bytes at most)",
                limit + 1
            ),
            "{args:?}"
        );
    }
    // a regular file is refused by its size, before it is read (a sparse file)
    let dir = temp_dir("large-file");
    let path = dir.join("large.csv");
    std::fs::File::create(&path)
        .unwrap()
        .set_len(300 << 20)
        .unwrap();
    let name = path.display().to_string();
    assert_eq!(
        one_error_line(&polycal(&["solve", &name])),
        format!(
            "{name}: 314572800 bytes, more than polycal reads from one input ({limit} bytes at most)"
        )
    );
    std::fs::remove_file(&path).unwrap();
}

/// Runs polycal with `args` under `ulimit -v KB` (the address-space limit).
fn polycal_under_ulimit_v(kilobytes: u64, args: &[&str]) -> Output {
    let quoted: Vec<String> = args
        .iter()
        .map(|a| format!("'{}'", a.replace('\'', "'\\''")))
        .collect();
    Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v {kilobytes} && exec '{}' {}",
            env!("CARGO_BIN_EXE_polycal"),
            quoted.join(" ")
        ))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("sh runs")
}

#[test]
fn work_beyond_the_address_space_limit_is_refused_up_front() {
    // The machine may have gigabytes available while `ulimit -v` leaves 1.43 GiB: the
    // guard takes the tightest. The dense solver of 6000 positions needs (2·6000)² · 8
    // bytes and more, about 7.5 GiB; a plan of 4 000 000 faces about 11.4 GiB.
    let dir = temp_dir("ulimit");
    let path = dir.join("d6000.csv").display().to_string();
    let out = polycal(&[
        "simulate", "--faces", "6000", "--cycles", "1", "--out", &path,
    ]);
    assert_eq!(out.status.code(), Some(0));
    let limited = "are left under this process's address-space limit (ulimit -v)";
    let message = one_error_line(&polycal_under_ulimit_v(
        1_500_000,
        &["solve", &path, "--method", "dense"],
    ));
    assert!(
        message.starts_with(&format!("{path}: cannot solve: the design (6000 positions")),
        "{message}"
    );
    // what is left is the limit less the process's own address space at the check (its
    // threads' malloc arenas included, which vary with the machine's load): 1.2–1.43 GiB
    let left: f64 = message
        .split("GiB of memory for the dense solver; ")
        .nth(1)
        .and_then(|rest| rest.split(" GiB ").next())
        .and_then(|number| number.parse().ok())
        .unwrap_or_else(|| panic!("{message}"));
    assert!((1.2..=1.43).contains(&left), "{message}");
    assert!(message.ends_with(limited), "{message}");
    let message = one_error_line(&polycal_under_ulimit_v(
        4_000_000,
        &["plan", "--sigma", "0.05", "--faces", "4000000"],
    ));
    assert!(
        message.contains("need about 11.4 GiB of memory; 3."),
        "{message}"
    );
    assert!(message.ends_with(limited), "{message}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The one error line of `solve EXAMPLE --budget BUDGET --monte-carlo TRIALS [extra]`.
fn monte_carlo_refusal(trials: &str, extra: &[&str]) -> String {
    let mut args = vec![
        "solve",
        EXAMPLE,
        "--budget",
        BUDGET,
        "--monte-carlo",
        trials,
    ];
    args.extend_from_slice(extra);
    one_error_line(&polycal(&args))
}

#[test]
fn trial_counts_at_their_edges_are_refused_or_bounded() {
    // 0, 1 and 2 trials are too few for a 95 % interval (at least 20); 2⁶³ and 2⁶⁴ − 1
    // trials are planned and refused on their memory (a doubling counter once wrapped to
    // 0 and aborted); 1e13 is read as the number it is; a negative count is named as
    // such, not taken for an option.
    for (trials, expected) in [
        (
            "0",
            "0 trials are too few for a 0.95 coverage interval: use at least 20",
        ),
        ("1", "1 trials are too few"),
        ("2", "2 trials are too few"),
        (
            "9223372036854775808",
            "9223372036854775808 trials of 71 outputs need about ",
        ),
        (
            "18446744073709551615",
            "18446744073709551615 trials of 71 outputs need about ",
        ),
        ("1e13", "10000000000000 trials of 71 outputs need about "),
    ] {
        let message = monte_carlo_refusal(trials, &[]);
        assert!(
            message.starts_with(&format!("{EXAMPLE}: Monte Carlo failed: {expected}")),
            "{trials}: {message}"
        );
    }
    for (trials, why) in [
        ("-1", "\"-1\": a number of trials is not negative"),
        ("1e20", "\"1e20\": more than 18446744073709551615 trials"),
    ] {
        let message = monte_carlo_refusal(trials, &[]);
        assert!(message.contains(why), "{trials}: {message}");
    }
    // the adaptive procedure needs room for two sequences of 10 000 trials at p = 0.95
    for (max, expected) in [
        (
            "0",
            "the adaptive procedure may run at most 0 trials, fewer than the 20000 of two sequences",
        ),
        (
            "19999",
            "the adaptive procedure may run at most 19999 trials, fewer than the 20000 of two sequences",
        ),
        (
            "18446744073709551615",
            "18446744073709551615 trials of 71 outputs need about ",
        ),
    ] {
        let message = monte_carlo_refusal("adaptive", &["--mc-max-trials", max]);
        assert!(
            message.starts_with(&format!("{EXAMPLE}: Monte Carlo failed: {expected}")),
            "{max}: {message}"
        );
    }
}

#[test]
fn a_line_of_commas_is_refused_within_a_small_memory() {
    // 20 million commas in a header or a row took about 64 bytes of memory per byte
    // (1.3 GB: an abort under a 1 GB limit); refused at the 1024th comma now (the 1025th
    // field), with the file held once: under a 200 MB address-space limit. Columns by
    // hand: the header's 1024th comma is character 1024; the row `1,0,1,1,0.5` has 11
    // characters and 4 commas, so its 1024th is character 11 + 1020 = 1031; the
    // self-calibration header has 34 characters and 4 commas: 34 + 1020 = 1054.
    let dir = temp_dir("commas");
    let commas = ",".repeat(20_000_000);
    let cases = [
        (
            "header.csv",
            "solve",
            format!("# a comment, with, commas\n{commas}\n"),
            "2:1024",
        ),
        (
            "row.csv",
            "solve",
            format!("cycle,step,ac,face,reading\n1,0,1,1,0.5{commas}\n"),
            "2:1031",
        ),
        (
            "selfcal-header.csv",
            "selfcal",
            format!("cycle,step,head,head_angle,reading{commas}\n"),
            "1:1054",
        ),
    ];
    for (name, command, text, at) in cases {
        let path = write(&dir, name, &text);
        let message = one_error_line(&polycal_under_ulimit_v(200_000, &[command, &path]));
        assert_eq!(
            message,
            format!(
                "{path}:{at}: a line of more than 1024 fields; polycal's CSV files have a few \
                 columns (docs/FORMAT.md §2.2)"
            )
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_long_monte_carlo_shows_its_progress_and_ends_within_a_second_of_ctrl_c() {
    // 10⁹ trials take hours: on a pseudo-terminal (util-linux `script`) the bar shows the
    // trials and the time left after a second; Ctrl-C (SIGINT from `timeout` after 3 s)
    // ends the process within a second of it.
    let started = std::time::Instant::now();
    let out = Command::new("script")
        .args([
            "-qec",
            &format!(
                "timeout -s INT 3 {} solve {EXAMPLE} --budget {BUDGET} --monte-carlo 1e9",
                env!("CARGO_BIN_EXE_polycal")
            ),
            "/dev/null",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::null())
        .output()
        .expect("script (util-linux) runs");
    let elapsed = started.elapsed();
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(
        shown.contains("Monte Carlo [") && shown.contains("/1000000000 trials · "),
        "no progress bar:\n{shown}"
    );
    assert!(
        shown.contains(" left"),
        "no estimate of the time left:\n{shown}"
    );
    assert!(
        elapsed < std::time::Duration::from_secs(4),
        "ended {elapsed:?} after its start, 3 s of it before Ctrl-C"
    );
}
