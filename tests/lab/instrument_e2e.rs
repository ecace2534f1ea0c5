//! `polycal run` (the built binary) against `polycal sim-lab` over real pseudo-terminals:
//! a short 8-face run whose file `polycal solve` turns back into the simulated truth,
//! the bidirectional design, the run directory's files, and the refusals.

#![cfg(unix)]

use crate::instrument_support::*;
use polycal::lab::run::RunSettings;

fn design(cycles: u32, bidirectional: bool) -> RunSettings {
    RunSettings::new(8, cycles)
        .with_closing(true)
        .with_bidirectional(bidirectional)
}

#[test]
fn a_run_against_the_simulated_lab_is_a_calibration() {
    let dir = scratch("e2e-cw");
    let lab = SimLab::start(&dir, &[]);
    let out = dir.join("run");
    let args = lab.run_args(
        &out,
        &[
            "--faces",
            "8",
            "--cycles",
            "2",
            "--closing",
            "--settle",
            "0",
            "-q",
        ],
    );
    let result = polycal(&args);
    assert!(result.status.success(), "{}", stderr(&result));
    assert_eq!(stderr(&result), "", "-q: nothing on standard error");
    assert!(result.stdout.is_empty());

    let settings = design(2, false);
    assert_complete(&out, &settings);
    assert_solves_to_truth(&out, &lab.truth);

    let m = manifest(&out);
    assert_eq!(m["outcome"], "completed");
    assert_eq!(m["readings"], 36);
    assert_eq!(m["expected_readings"], 36);
    assert_eq!(m["settings"]["faces"], 8);
    assert_eq!(m["settings"]["closing"], true);
    assert_eq!(m["ports"]["table"], lab.table.as_str());
    assert!(
        m["instruments"]["ac1"]
            .as_str()
            .unwrap()
            .contains("ELCOMAT 3000")
    );
    assert!(
        m["instruments"]["table"]
            .as_str()
            .unwrap()
            .contains("SMC100")
    );
    assert!(m["software"].as_str().unwrap().starts_with("polycal "));
    for key in ["started", "ended"] {
        assert!(
            m[key].as_str().unwrap().ends_with('Z'),
            "{key}: RFC 3339 UTC"
        );
    }

    let sessions = sessions(&out);
    assert_eq!(sessions.len(), 1);
    assert_moves_follow_plan(&sessions[0], &settings, 0);
    assert_eq!(moves(&sessions[0]).len(), 18, "one move per stop");
    let sent: Vec<&str> = sessions[0]
        .iter()
        .filter(|r| r["event"] == "sent")
        .map(|r| r["text"].as_str().unwrap())
        .collect();
    assert_eq!(
        sent[..2],
        ["s\n", "d\n"],
        "ELCOMAT start, then identification"
    );
    assert!(sent.contains(&"1VE\r\n") && sent.contains(&"1OR\r\n"));
    // Two readings of each autocollimator at every stop (docs/FORMAT.md §7.3).
    assert_eq!(sent.iter().filter(|s| **s == "a\n").count(), 72);
    assert!(!sent.contains(&"1ST\r\n"), "a completed run needs no stop");

    // time rises, encoder is the reported position, the closing step at 360°.
    let text = std::fs::read_to_string(out.join("measurements.csv")).unwrap();
    let data: Vec<Vec<&str>> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let times: Vec<f64> = data.iter().map(|f| f[6].parse().unwrap()).collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]));
    assert!(data.iter().all(|f| f[7] == "1" && f[5] == "cw"));
    let closing = data.iter().find(|f| f[1] == "8").unwrap();
    assert_eq!(closing[9], "360");
    assert!(
        data.iter().all(|f| !f[8].is_empty()),
        "the lab's Y is valid"
    );
}

#[test]
fn a_bidirectional_run_turns_back_every_second_cycle() {
    let dir = scratch("e2e-bidi");
    let lab = SimLab::start(&dir, &["--cycles", "2", "--bidirectional"]);
    let out = dir.join("run");
    let args = lab.run_args(
        &out,
        &[
            "--faces",
            "8",
            "--cycles",
            "2",
            "--bidirectional",
            "--settle",
            "0",
        ],
    );
    let result = polycal(&args);
    assert!(result.status.success(), "{}", stderr(&result));
    assert!(stderr(&result).contains("completed"), "{}", stderr(&result));
    let settings = design(2, true);
    assert_complete(&out, &settings);
    assert_solves_to_truth(&out, &lab.truth);
    let sessions = sessions(&out);
    assert_moves_follow_plan(&sessions[0], &settings, 0);
    let m = moves(&sessions[0]);
    assert_eq!(
        m[8..10],
        [360.0, 360.0],
        "cycle 1 ends and cycle 2 starts at 360°"
    );
    assert_eq!(*m.last().unwrap(), 0.0);
    let text = std::fs::read_to_string(out.join("measurements.csv")).unwrap();
    assert!(text.contains("\n2,8,1,1,") && text.contains(",ccw,"));
}

#[test]
fn refusals_are_one_error_line_and_status_2() {
    let dir = scratch("e2e-refuse");
    let lab = SimLab::start(&dir, &[]);
    let out = dir.join("run");
    let short = ["--faces", "8", "--cycles", "1", "--settle", "0", "-q"];
    assert!(polycal(&lab.run_args(&out, &short)).status.success());

    // The same directory again, without --resume.
    let again = polycal(&lab.run_args(&out, &short));
    assert_error(&again, "already holds a run");

    // --resume with other settings.
    let mut other = lab.run_args(&out, &["--faces", "8", "--cycles", "2", "--settle", "0"]);
    other.push("--resume".into());
    assert_error(&polycal(&other), "refusing to resume");

    // --resume of a complete run: nothing to do.
    let mut same = lab.run_args(&out, &short);
    same.push("--resume".into());
    let done = polycal(&same);
    assert!(done.status.success(), "{}", stderr(&done));

    // A port that does not exist: nothing measured, the manifest says why.
    let missing = dir.join("missing");
    let mut args = lab.run_args(&missing, &short);
    args[2] = "/dev/polycal-no-such-port".into();
    let first = polycal(&args);
    assert_error(&first, "/dev/polycal-no-such-port");
    // the line says how to go on: the directory holds the run, so only --resume does
    assert!(
        stderr(&first).contains("0 of 16 readings are in") // 8 stops × 2 autocollimators
            && stderr(&first).contains("continue with the same command and --resume"),
        "{}",
        stderr(&first)
    );
    // and as it says, once the port is there --resume measures the run
    let mut resumed = lab.run_args(&missing, &short);
    resumed.push("--resume".into());
    let done = polycal(&resumed);
    assert!(done.status.success(), "{}", stderr(&done));
    let m = manifest(&missing);
    assert_eq!(m["outcome"], "completed", "{m}");
    let missing = dir.join("missing-again");
    let mut args = lab.run_args(&missing, &short);
    args[2] = "/dev/polycal-no-such-port".into();
    assert_error(&polycal(&args), "/dev/polycal-no-such-port");
    let m = manifest(&missing);
    assert!(
        m["outcome"]
            .as_str()
            .unwrap()
            .starts_with("instrument-error: ")
    );

    // Bad settings.
    let bad = dir.join("bad");
    assert_error(
        &polycal(&lab.run_args(&bad, &["--faces", "2", "--cycles", "1"])),
        "--faces 2",
    );
    assert_error(
        &polycal(&lab.run_args(&bad, &["--faces", "8", "--cycles", "1", "--settle=-1"])),
        "--settle",
    );
    assert!(!bad.exists(), "nothing created for refused settings");

    // --out naming a regular file: refused, the file left as it was.
    let file = dir.join("results.csv");
    std::fs::write(&file, "kept\n").unwrap();
    for resume in [false, true] {
        let mut args = lab.run_args(&file, &short);
        if resume {
            args.push("--resume".into());
        }
        let text = assert_error(&polycal(&args), "is a file, not a directory");
        assert_eq!(
            text.trim_end(),
            format!(
                "error: {}: is a file, not a directory; choose another --out",
                file.display()
            )
        );
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "kept\n");

    // A bad fault spec for the lab.
    let lab_bad = polycal(&["sim-lab", "--fault", "melt:ac1"]);
    assert_error(&lab_bad, "melt");
}

#[test]
fn sim_lab_prints_its_paths_as_json_too() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};
    let mut child = Command::new(BIN)
        .args(["sim-lab", "--faces", "6", "--format", "json"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let paths: serde_json::Value = serde_json::from_str(&line).unwrap();
    for key in ["ac1", "ac2", "table"] {
        assert!(paths[key].as_str().unwrap().starts_with("/dev/"), "{line}");
    }
    // Closing standard input ends the lab.
    drop(child.stdin.take());
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success());
            break;
        }
        if start.elapsed() > std::time::Duration::from_secs(5) {
            let _ = child.kill();
            panic!("sim-lab did not end when its standard input closed");
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// The library's pseudo-terminal lab and serial transport, in process: exact values with
/// noise 0, and a port opened twice is refused.
#[test]
fn serial_transport_against_the_library_lab() {
    use polycal::lab::driver::ProfileAutocollimator;
    use polycal::lab::driver::{ProfileTable, TableOptions};
    use polycal::lab::profile::Profile;
    use polycal::lab::serial::SerialTransport;
    use polycal::lab::sim::{Devices, Lab, LabConfig};
    use polycal::lab::{Autocollimator, QueryOptions, RotaryTable};
    use polycal::simulate::SimulationConfig;

    let config = LabConfig::new(SimulationConfig {
        faces: 8,
        noise_arcsec: 0.0,
        ..SimulationConfig::default()
    })
    .with_time_scale(0.0);
    let lab = Lab::start(Devices::new(config).unwrap()).unwrap();
    let truth = lab.truth();
    let paths = lab.paths().clone();
    let q = QueryOptions::default();
    let (elcomat, smc100) = (
        Profile::load("elcomat3000").unwrap(),
        Profile::load("smc100").unwrap(),
    );
    let open = |path: &str, p: &Profile| SerialTransport::open(path, &p.line).unwrap();
    let mut ac1 = ProfileAutocollimator::elcomat3000(open(&paths.autocollimators[0], &elcomat), q);
    let mut ac2 = ProfileAutocollimator::elcomat3000(open(&paths.autocollimators[1], &elcomat), q);
    let mut table = ProfileTable::smc100(open(&paths.table, &smc100), TableOptions::default());
    assert!(matches!(
        SerialTransport::open(&paths.autocollimators[0], &elcomat.line),
        Err(polycal::lab::InstrumentError::Open { .. })
    ));
    ac1.start().unwrap();
    ac2.start().unwrap();
    table.start().unwrap();
    for step in [0usize, 3, 8] {
        assert_eq!(
            table.move_to(step as f64 * 45.0).unwrap(),
            step as f64 * 45.0
        );
        for (ac, device) in [(1u32, &mut ac1), (2, &mut ac2)] {
            let x = device.measure().unwrap().x_arcsec;
            let face = (step + ac as usize - 1) % 8 + 1;
            let want = truth.encoder_error[step % 8]
                + truth.face_deviation_at(face)
                + truth.setup_error_of(1, ac).unwrap();
            assert!(
                (x - want).abs() < 1e-6,
                "step {step} ac {ac}: {x} vs {want}"
            );
        }
    }
    assert_eq!(table.position().unwrap(), 360.0);
    drop((ac1, ac2, table));
    lab.shutdown();
}
