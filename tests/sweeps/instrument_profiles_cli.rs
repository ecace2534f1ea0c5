//! `polycal run` with profiles, as a lab uses it (docs/FORMAT.md §7.5): a run on each
//! bundled table profile against `polycal sim-lab` serving it (over TCP for the makes
//! usually on a network, a pseudo-terminal for the others), evaluated by `solve` against
//! the lab's truth; `--check-instruments` on each profile; a profile file read, and
//! refused when broken with its file, line and column.

#![cfg(unix)]

use crate::instrument_support::*;

const DESIGN: [&str; 8] = [
    "--faces",
    "8",
    "--cycles",
    "2",
    "--closing",
    "--settle",
    "0",
    "-q",
];

#[test]
fn a_run_on_each_bundled_table_profile_solves_to_the_truth() {
    for (profile, tcp) in [
        ("smc100", false),
        ("pi-gcs2", true),
        ("aerotech-ascii", true),
        ("esp301", false),
    ] {
        let dir = scratch(&format!("profile-run-{profile}"));
        let mut extra = vec!["--table-profile", profile];
        if tcp {
            extra.push("--tcp");
        }
        let lab = SimLab::start(&dir, &extra);
        assert_eq!(
            lab.table.starts_with("tcp://127.0.0.1:"),
            tcp,
            "{}",
            lab.table
        );
        let out = dir.join("run");
        let mut args = lab.run_args(&out, &DESIGN);
        args.extend(["--table-profile".to_string(), profile.to_string()]);
        let result = polycal(&args);
        assert_eq!(
            result.status.code(),
            Some(0),
            "{profile}: {}",
            stderr(&result)
        );
        assert_solves_to_truth(&out, &lab.truth);
        // The traffic log names the profiles of the session.
        let traffic = std::fs::read_to_string(out.join("traffic.jsonl")).unwrap();
        assert!(
            traffic.contains(&format!(
                "--ac-profile elcomat3000 --table-profile {profile}"
            )),
            "{profile}"
        );
    }
}

#[test]
fn check_instruments_talks_to_each_once_and_moves_nothing() {
    for (profile, tcp) in [
        ("smc100", true),
        ("pi-gcs2", false),
        ("aerotech-ascii", true),
        ("esp301", true),
    ] {
        let dir = scratch(&format!("profile-check-{profile}"));
        let mut extra = vec!["--table-profile", profile];
        if tcp {
            extra.push("--tcp");
        }
        let lab = SimLab::start(&dir, &extra);
        let out = polycal(&[
            "run",
            "--ac1",
            &lab.acs[0],
            "--ac2",
            &lab.acs[1],
            "--table",
            &lab.table,
            "--table-profile",
            profile,
            "--check-instruments",
        ]);
        assert_eq!(out.status.code(), Some(0), "{profile}: {}", stderr(&out));
        let text = String::from_utf8_lossy(&out.stdout);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3, "{text}");
        assert!(
            lines[0].starts_with(&format!(
                "autocollimator 1 at {} (elcomat3000): ",
                lab.acs[0]
            )) && lines[0].contains("SIM-1")
                && lines[0].contains("; reading X ")
                && lines[0].ends_with("; ok"),
            "{text}"
        );
        assert!(
            lines[1].contains("SIM-2") && lines[1].ends_with("; ok"),
            "{text}"
        );
        // The table is not homed by a check: the simulated table powers up at 0°.
        assert!(
            lines[2].starts_with(&format!("rotary table at {} ({profile}): ", lab.table))
                && lines[2].contains("; position 0°; ok"),
            "{text}"
        );
        assert!(!dir.join("run").exists());
    }
}

#[test]
fn check_instruments_names_an_instrument_that_speaks_another_protocol() {
    // An SMC100 served, a PI profile given for it: its *IDN? is not answered.
    let dir = scratch("profile-check-wrong");
    let lab = SimLab::start(&dir, &[]);
    let out = polycal(&[
        "run",
        "--ac1",
        &lab.acs[0],
        "--ac2",
        &lab.acs[1],
        "--table",
        &lab.table,
        "--table-profile",
        "pi-gcs2",
        "--check-instruments",
        "--timeout",
        "0.1",
    ]);
    assert_error(
        &out,
        "1 of 3 instruments did not answer as their profiles say: rotary table",
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("rotary table at") && text.contains("FAILED: ") && text.contains("*IDN?"),
        "{text}"
    );
}

/// A profile of one's own: the bundled `pi-gcs2` written to a file under another name,
/// served by the lab from the file and run from it.
#[test]
fn a_profile_file_is_served_and_run() {
    let dir = scratch("profile-file");
    let text = polycal::lab::profile::BUNDLED
        .iter()
        .find(|(n, _, _)| *n == "pi-gcs2")
        .map(|(_, _, t)| t.replace("profile = \"pi-gcs2\"", "profile = \"our-c884\""))
        .unwrap();
    let file = dir.join("our-c884.toml");
    std::fs::write(&file, text).unwrap();
    let file = file.display().to_string();
    let lab = SimLab::start(&dir, &["--table-profile", &file]);
    let out = dir.join("run");
    let mut args = lab.run_args(&out, &DESIGN);
    args.extend(["--table-profile".to_string(), file.clone()]);
    let result = polycal(&args);
    assert_eq!(result.status.code(), Some(0), "{}", stderr(&result));
    assert_solves_to_truth(&out, &lab.truth);
    let traffic = std::fs::read_to_string(out.join("traffic.jsonl")).unwrap();
    // The session line gives the command's options: the file as given.
    assert!(traffic.contains(&format!("--table-profile {file}")));
    assert!(
        traffic.contains("MOV 1 45\\n"),
        "the PI command set on the wire"
    );

    // The manifest records each profile as given, with the SHA-256 of its text.
    let sha256 = |text: &[u8]| -> String {
        use sha2::Digest;
        sha2::Sha256::digest(text)
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    };
    let profiles = &manifest(&out)["profiles"];
    assert_eq!(profiles["table"]["name"], file.as_str());
    assert_eq!(
        profiles["table"]["sha256"],
        sha256(&std::fs::read(&file).unwrap()).as_str()
    );
    assert_eq!(profiles["ac"]["name"], "elcomat3000");
    let elcomat = polycal::lab::profile::BUNDLED
        .iter()
        .find(|(n, _, _)| *n == "elcomat3000")
        .map(|(_, _, t)| *t)
        .unwrap();
    assert_eq!(
        profiles["ac"]["sha256"],
        sha256(elcomat.as_bytes()).as_str()
    );

    // --resume takes the profiles from there: without --table-profile, the file.
    let resume = |extra: &[&str]| {
        let mut args = lab.run_args(&out, &DESIGN);
        args.push("--resume".into());
        args.extend(extra.iter().map(|s| s.to_string()));
        polycal(&args)
    };
    let again = resume(&[]);
    assert_eq!(again.status.code(), Some(0), "{}", stderr(&again));
    // Another profile is refused, naming both.
    let other = resume(&["--table-profile", "pi-gcs2"]);
    let message = assert_error(&other, "through the profile");
    assert!(
        message.contains(&format!("{file:?}, not \"pi-gcs2\"")),
        "{message}"
    );
    // The file's text changed since the run started: refused, naming both hashes.
    let before = sha256(&std::fs::read(&file).unwrap());
    let mut edited = std::fs::read_to_string(&file).unwrap();
    edited.push_str("# edited after the run started\n");
    std::fs::write(&file, &edited).unwrap();
    let changed = resume(&[]);
    let message = assert_error(&changed, "changed since the run started");
    assert!(
        message.contains(&before) && message.contains(&sha256(edited.as_bytes())),
        "{message}"
    );
}

/// A broken profile file: one `error:` line naming the option, the file, its line and
/// its column (counted by hand below), status 2, nothing opened.
#[test]
fn a_broken_profile_file_is_refused_at_its_line_and_column() {
    let dir = scratch("profile-broken");
    let good = polycal::lab::profile::BUNDLED
        .iter()
        .find(|(n, _, _)| *n == "esp301")
        .map(|(_, _, t)| t.to_string())
        .unwrap();
    let cases: [(&str, &str, String, &str); 5] = [
        (
            "kind",
            // line 1, the value of `instrument` at column 14
            "instrument = \"rotary\"\n",
            String::new(),
            ":1:14: instrument \"rotary\": it is \"autocollimator\" or \"table\"",
        ),
        (
            "template",
            // the field `{deg:q}` starts at character 2 of the value, column 9 + 1 + 1 = 11
            "",
            "[position]\nsend = \"1TP?\"\nreply = \"1{deg:q}\"\n".to_string(),
            ":3:11: the template \"1{deg:q}\": the field `{deg:q}`: the kind is f",
        ),
        (
            "condition",
            "",
            "[state]\nsend = \"1MD?\"\nreply = \"{done:d1}\"\nready = { field = \"don\", equals = [\"1\"] }\nmoving = { field = \"done\", equals = [\"0\"] }\n".to_string(),
            ":4:9: the reply `{done:d1}` has no field `don` (its fields: done)",
        ),
        (
            "identification",
            "",
            "[identify]\nsend = \"VE?\"\nreply = \"{version:s}\"\n".to_string(),
            ":3:9: a state reply such as \"1\" would pass for the identification",
        ),
        (
            "unknown key",
            "",
            "[move]\nsend = \"{axis}PA{deg}\"\nspeed = 10\n".to_string(),
            ":3:1: unknown field `speed`",
        ),
    ];
    for (what, head, section, says) in cases {
        let mut text = String::new();
        if head.is_empty() {
            // The bundled file with one section replaced, moved to the top.
            let name = section.lines().next().unwrap();
            let mut skipping = false;
            let mut rest = String::new();
            for line in good.lines() {
                if line.starts_with('[') {
                    skipping = line == name;
                }
                if !skipping {
                    rest.push_str(line);
                    rest.push('\n');
                }
            }
            // Keys before the first table stay at the top; the section goes first among
            // the tables, so that its line numbers are those written above.
            let first_table = rest.find("\n[").unwrap() + 1;
            let (top, tables) = rest.split_at(first_table);
            let top_lines = top.lines().count();
            text.push_str(top);
            text.push_str(&section);
            text.push_str(tables);
            // Line numbers in `says` count from the section's first line.
            let shifted = says.replacen(
                &format!(":{}:", says.split(':').nth(1).unwrap()),
                &format!(
                    ":{}:",
                    says.split(':').nth(1).unwrap().parse::<usize>().unwrap() + top_lines
                ),
                1,
            );
            let file = dir.join(format!("{}.toml", what.replace(' ', "-")));
            std::fs::write(&file, &text).unwrap();
            let path = file.display().to_string();
            let out = polycal(&[
                "run",
                "--ac1",
                "x",
                "--ac2",
                "y",
                "--table",
                "z",
                "--table-profile",
                &path,
                "--check-instruments",
            ]);
            assert_error(&out, &format!("--table-profile {path}: {path}{shifted}"));
        } else {
            text.push_str(head);
            text.push_str(&good.replace("instrument = \"table\"\n", ""));
            let file = dir.join(format!("{}.toml", what.replace(' ', "-")));
            std::fs::write(&file, &text).unwrap();
            let path = file.display().to_string();
            let out = polycal(&[
                "run",
                "--ac1",
                "x",
                "--ac2",
                "y",
                "--table",
                "z",
                "--table-profile",
                &path,
                "--check-instruments",
            ]);
            assert_error(&out, &format!("--table-profile {path}: {path}{says}"));
        }
    }
    // An autocollimator's profile given for the table, and an unknown name.
    let out = polycal(&[
        "run",
        "--ac1",
        "x",
        "--ac2",
        "y",
        "--table",
        "z",
        "--table-profile",
        "elcomat3000",
        "--check-instruments",
    ]);
    assert_error(
        &out,
        "--table-profile elcomat3000: elcomat3000: a profile of an autocollimator, given for a rotary table",
    );
    let out = polycal(&[
        "run",
        "--ac1",
        "x",
        "--ac2",
        "y",
        "--table",
        "z",
        "--table-profile",
        "pi-gsc2",
        "--check-instruments",
    ]);
    assert_error(
        &out,
        "no bundled profile \"pi-gsc2\" and no such file: the bundled profiles are elcomat3000, smc100, pi-gcs2, aerotech-ascii, esp301",
    );
}
