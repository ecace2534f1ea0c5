//! Every design `run` acquires (docs/FORMAT.md §7.3): three autocollimators at any
//! faces and a bidirectional run, each against `polycal sim-lab` serving the same
//! design on pseudo-terminals, evaluated by `solve` and compared with the lab's truth.

#![cfg(unix)]

use crate::instrument_support::*;
use polycal::lab::run::RunSettings;
use polycal::measurement::MeasurementSet;

/// The run's options beside a design: no settle time, short deadlines, the lab's noise.
const RUN_OPTIONS: [&str; 7] = [
    "--settle",
    "0",
    "--timeout",
    "0.3",
    "--reading-noise",
    "0.05",
    "-q",
];

/// `polycal plan --sigma 0.05 --format json` of `designs`, written to `dir/name`.
fn planned(dir: &std::path::Path, name: &str, designs: &[&str]) -> std::path::PathBuf {
    let mut args = vec!["plan", "--sigma", "0.05", "--format", "json"];
    for d in designs {
        args.extend(["--design", d]);
    }
    let out = polycal(&args);
    assert!(out.status.success(), "{}", stderr(&out));
    let path = dir.join(name);
    std::fs::write(&path, &out.stdout).unwrap();
    path
}

/// A lab of two cycles with the closing step and two mountings.
const TWO_MOUNTINGS: [&str; 7] = [
    "--cycles",
    "2",
    "--closing",
    "--noise",
    "0.05",
    "--setups",
    "2",
];

/// A lab of three autocollimators on faces 1, 2 and 5, two cycles with the closing step.
const THREE: [&str; 7] = [
    "--ac-faces",
    "1,2,5",
    "--cycles",
    "2",
    "--closing",
    "--noise",
    "0.05",
];

fn design(extra: &[&'static str]) -> Vec<&'static str> {
    let mut d = vec!["--faces", "8", "--cycles", "2", "--closing"];
    d.extend_from_slice(&RUN_OPTIONS);
    d.extend_from_slice(extra);
    d
}

#[test]
fn three_autocollimators_at_any_faces_are_run_and_solve_to_the_truth() {
    let dir = scratch("three-acs");
    let lab = SimLab::start(&dir, &THREE);
    assert_eq!(lab.acs.len(), 3);
    let out = dir.join("run");
    let result = polycal(&lab.run_args(&out, &design(&["--ac-faces", "1,2,5"])));
    assert!(result.status.success(), "{}", stderr(&result));
    let settings = RunSettings::new(8, 2)
        .with_closing(true)
        .with_ac_faces(vec![1, 2, 5]);
    assert_eq!(rows(&out), plan_readings(&settings));
    let set = MeasurementSet::read_path(&out.join("measurements.csv"), None).unwrap();
    // Autocollimator 3 reads face 5 at step 0 and face 4 at step 7.
    for r in set.readings.iter().filter(|r| r.ac == 3) {
        assert_eq!(r.face, (r.step + 4) % 8 + 1, "{r:?}");
    }
    assert_solves_to_truth(&out, &lab.truth);
    let m = manifest(&out);
    assert!(m["instruments"]["ac3"].as_str().unwrap().ends_with("SIM-3"));
    assert_eq!(m["ports"]["ac3"], lab.acs[2]);
    assert_eq!(m["settings"]["ac_faces"], serde_json::json!([1, 2, 5]));
}

#[test]
fn a_bidirectional_run_solves_to_the_truth() {
    let dir = scratch("bidirectional");
    let lab = SimLab::start(
        &dir,
        &["--cycles", "2", "--bidirectional", "--noise", "0.05"],
    );
    let out = dir.join("run");
    let result = polycal(&lab.run_args(&out, &design(&["--bidirectional"])));
    assert!(result.status.success(), "{}", stderr(&result));
    let settings = RunSettings::new(8, 2)
        .with_closing(true)
        .with_bidirectional(true);
    assert_eq!(rows(&out), plan_readings(&settings));
    let set = MeasurementSet::read_path(&out.join("measurements.csv"), None).unwrap();
    assert!(
        set.readings
            .iter()
            .any(|r| r.cycle == 2 && r.direction == polycal::measurement::Direction::Ccw)
    );
    assert_solves_to_truth(&out, &lab.truth);
}

#[test]
fn a_late_reply_on_the_third_autocollimator_is_discarded_too() {
    let dir = scratch("three-acs-late");
    let lab = SimLab::start(
        &dir,
        &[&THREE[..], &["--fault", "late:ac3:after=17:seconds=0.5"]].concat(),
    );
    let out = dir.join("run");
    let result = polycal(&lab.run_args(&out, &design(&["--ac-faces", "1,2,5"])));
    assert!(result.status.success(), "{}", stderr(&result));
    assert_solves_to_truth(&out, &lab.truth);
    let discarded = sessions(&out)
        .concat()
        .into_iter()
        .filter(|r| r["event"] == "discarded" && r["device"] == "ac3")
        .count();
    assert_eq!(discarded, 1);
}

#[test]
fn ports_that_do_not_match_the_autocollimators_are_refused() {
    let dir = scratch("three-acs-two-ports");
    let lab = SimLab::start(&dir, &["--ac-faces", "1,2,5"]);
    let out = dir.join("run");
    // Two ports for three autocollimators.
    let mut args = vec![
        "run".to_string(),
        "--ac1".into(),
        lab.acs[0].clone(),
        "--ac2".into(),
        lab.acs[1].clone(),
        "--table".into(),
        lab.table.clone(),
        "--out".into(),
        out.display().to_string(),
    ];
    args.extend(
        design(&["--ac-faces", "1,2,5"])
            .iter()
            .map(|s| s.to_string()),
    );
    assert_error(
        &polycal(&args),
        "2 autocollimator port(s) given for the 3 autocollimators",
    );
    assert!(!out.exists(), "nothing written");
    // A fault on an autocollimator the lab does not have.
    let refused = polycal(&["sim-lab", "--fault", "late:ac3"]);
    assert_error(&refused, "the lab has 2 autocollimators, not an ac3");
}

#[test]
fn a_planned_design_is_run_exactly() {
    let dir = scratch("planned");
    // Two designs planned; the run takes the one named.
    let plan = planned(
        &dir,
        "plan.json",
        &[
            "name=paper;faces=8;cycles=2;closing=true",
            "name=three;faces=8;ac-faces=1,2,5;cycles=2;bidirectional=true",
        ],
    );
    let lab = SimLab::start(
        &dir,
        &[
            "--ac-faces",
            "1,2,5",
            "--cycles",
            "2",
            "--bidirectional",
            "--noise",
            "0.05",
        ],
    );
    let out = dir.join("run");
    let mut args = lab.run_args(
        &out,
        &[
            &["--plan", plan.to_str().unwrap(), "--design", "three"][..],
            &RUN_OPTIONS,
        ]
        .concat(),
    );
    let result = polycal(&args);
    assert!(result.status.success(), "{}", stderr(&result));
    let settings = RunSettings::new(8, 2)
        .with_closing(true)
        .with_bidirectional(true)
        .with_ac_faces(vec![1, 2, 5]);
    assert_eq!(rows(&out), plan_readings(&settings));
    let m = manifest(&out);
    assert_eq!(m["settings"]["ac_faces"], serde_json::json!([1, 2, 5]));
    assert_eq!(m["settings"]["bidirectional"], true);
    assert_solves_to_truth(&out, &lab.truth);

    // Without a name, a file of two designs is refused, naming them and the option.
    args.retain(|a| a != "--design" && a != "three");
    let out2 = dir.join("run2");
    let i = args.iter().position(|a| a == "--out").unwrap();
    args[i + 1] = out2.display().to_string();
    let text = assert_error(&polycal(&args), "holds 2 designs (paper, three)");
    assert!(text.contains("--design NAME"), "{text}");
    assert!(!out2.exists());
    // A mounting the design does not have is refused at its line.
    let plan2 = planned(&dir, "two.json", &["name=two;faces=8;cycles=2;setups=2"]);
    let i = args.iter().position(|a| a == "--plan").unwrap();
    args[i + 1] = plan2.display().to_string();
    args.extend(["--setup".into(), "3".into()]);
    assert_error(
        &polycal(&args),
        "two.json:1:1: design \"two\" has 2 mounting(s), not a mounting 3",
    );
    assert!(!out2.exists());
}

/// The (setup, cycle, step, ac) of every data row of a run's measurement file, and its
/// `shift` per row.
fn places(dir: &std::path::Path) -> Vec<((u32, u32, usize, u32), f64)> {
    let set = MeasurementSet::read_path(&dir.join("measurements.csv"), None).unwrap();
    set.readings
        .iter()
        .map(|r| ((r.setup, r.cycle, r.step, r.ac), set.shift_deg(r.setup)))
        .collect()
}

/// Every reading of mountings 1 … `setups` of `settings`, in order, with its shift.
fn planned_places(settings: &RunSettings, shifts: &[f64]) -> Vec<((u32, u32, usize, u32), f64)> {
    let mut all = Vec::new();
    for (s, shift) in shifts.iter().enumerate() {
        for (cycle, step, ac) in plan_readings(settings) {
            all.push(((s as u32 + 1, cycle, step, ac), *shift));
        }
    }
    all
}

#[test]
fn a_run_in_two_mountings_between_the_stops_solves_to_the_truth() {
    let dir = scratch("two-mountings");
    let mut lab = SimLab::start(
        &dir,
        &[&TWO_MOUNTINGS[..], &["--shift-deg", "0,22.5"]].concat(),
    );
    let out = dir.join("run");
    let first = polycal(&lab.run_args(&out, &design(&[])));
    assert!(first.status.success(), "{}", stderr(&first));
    let second_args = lab.run_args(
        &out,
        &design(&["--setup", "2", "--shift", "22.5", "--face-shift", "1"]),
    );
    // Nobody confirms the remount (standard input closed): the prompt, then one error
    // line; nothing measured.
    let declined = polycal(&second_args);
    let text = stderr(&declined);
    assert_eq!(declined.status.code(), Some(2), "{text}");
    let lines: Vec<&str> = text.lines().collect();
    assert!(
        lines[0].starts_with(
            "polycal run: mounting 2 (shift 22.5°, turned 1 face): the table stands at 22.5°."
        ),
        "{text}"
    );
    assert_eq!(
        lines.iter().filter(|l| l.starts_with("error:")).count(),
        1,
        "{text}"
    );
    assert!(
        lines[lines.len() - 1].starts_with("error: no confirmation that the polygon is remounted for mounting 2 (shift 22.5°, turned 1 face) (standard input closed); the run stopped; 36 of 72 readings"),
        "{text}"
    );
    assert_eq!(places(&out).len(), 36);
    // The operator remounts, the run is told so: the second mounting is measured.
    assert_eq!(lab.remount(), 2);
    let result = polycal_with_input(&second_args, "\n");
    let err = stderr(&result);
    assert!(result.status.success(), "{err}");
    assert!(
        err.contains("Remount the polygon with the table there, not moved: face 2 faces autocollimator 1, face 3 faces autocollimator 2."),
        "{err}"
    );
    let settings = RunSettings::new(8, 2).with_closing(true);
    assert_eq!(places(&out), planned_places(&settings, &[0.0, 22.5]));
    let m = manifest(&out);
    assert_eq!(m["mountings"][1]["setup"], 2);
    assert_eq!(m["mountings"][1]["table_deg"], 22.5);
    // α at 16 table angles, two cosets, and β, against the truth.
    assert_solves_to_truth(&out, &lab.truth);
    // A third mounting the run was not told of is refused before anything is moved.
    let third = lab.run_args(&out, &design(&["--setup", "4"]));
    assert_error(&polycal(&third), "the next one is 3, not 4");
}

#[test]
fn a_planned_design_of_two_mountings_is_run_mounting_by_mounting() {
    let dir = scratch("planned-mountings");
    let plan = planned(
        &dir,
        "plan.json",
        &["name=turned;faces=8;cycles=2;closing=true;setups=2;setup-shift=3"],
    );
    let mut lab = SimLab::start(
        &dir,
        &[&TWO_MOUNTINGS[..], &["--setup-shift", "3"]].concat(),
    );
    let out = dir.join("run");
    let options = |extra: &[&'static str]| {
        let mut o = vec!["--plan", plan.to_str().unwrap()];
        o.extend_from_slice(&RUN_OPTIONS);
        o.extend_from_slice(extra);
        o.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let first = polycal(&lab.run_args(&out, &strs(&options(&[]))));
    assert!(first.status.success(), "{}", stderr(&first));
    // The plan's second mounting turns the polygon 3 faces; another face shift is refused.
    assert_error(
        &polycal(&lab.run_args(
            &out,
            &strs(&options(&["--setup", "2", "--face-shift", "1"])),
        )),
        "--face-shift 1: the plan turns the polygon 3 faces in mounting 2",
    );
    assert_eq!(lab.remount(), 2);
    let second = polycal_with_input(
        &lab.run_args(&out, &strs(&options(&["--setup", "2"]))),
        "\n",
    );
    assert!(second.status.success(), "{}", stderr(&second));
    let set = MeasurementSet::read_path(&out.join("measurements.csv"), None).unwrap();
    for r in set.readings.iter().filter(|r| r.setup == 2) {
        assert_eq!(r.face, (r.ac as usize - 1 + 3 + r.step) % 8 + 1, "{r:?}");
    }
    let settings = RunSettings::new(8, 2).with_closing(true);
    assert_eq!(places(&out), planned_places(&settings, &[0.0, 0.0]));
    assert_solves_to_truth(&out, &lab.truth);
}

/// The strings of `v` borrowed.
fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

#[test]
fn a_forgotten_remount_stops_the_run_at_the_mountings_first_stop() {
    let dir = scratch("forgotten-remount");
    // Mounting 2 with the table at 0° at step 0, the polygon turned 1 face.
    let mut lab = SimLab::start(&dir, &TWO_MOUNTINGS);
    let out = dir.join("run");
    let first = polycal(&lab.run_args(&out, &design(&[])));
    assert!(first.status.success(), "{}", stderr(&first));
    let second_args = lab.run_args(&out, &design(&["--setup", "2", "--face-shift", "1"]));
    // Enter pressed, the polygon where it was: every autocollimator sees a face (faces
    // 1, 2 of mounting 1, not 2, 3), and the first stop says so in one error line.
    let forgot = polycal_with_input(&second_args, "\n");
    let text = stderr(&forgot);
    assert_eq!(forgot.status.code(), Some(2), "{text}");
    let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{text}");
    assert_eq!(text.lines().last(), errors.first().copied(), "{text}");
    assert!(
        errors[0].starts_with(
            "error: at the first stop of mounting 2 (shift 0°, turned 1 face), cycle 1, step 0, \
             the table at 0°, the autocollimators read what they read at this table angle in \
             mounting 1"
        ),
        "{text}"
    );
    assert!(
        errors[0]
            .contains("Y as faces 1, 2 (not faces 2, 3 as stated): the polygon was not remounted"),
        "{text}"
    );
    assert_eq!(places(&out).len(), 36, "nothing of mounting 2 stored");
    assert_eq!(
        manifest(&out)["mountings"][1]["confirmed"],
        serde_json::Value::Null
    );
    // Remounted when asked again: measured, and solved to the lab's truth.
    assert_eq!(lab.remount(), 2);
    let result = polycal_with_input(&second_args, "\n");
    assert!(result.status.success(), "{}", stderr(&result));
    let settings = RunSettings::new(8, 2).with_closing(true);
    assert_eq!(places(&out), planned_places(&settings, &[0.0, 0.0]));
    assert_solves_to_truth(&out, &lab.truth);
}

#[test]
fn a_misstated_face_shift_stops_the_run_at_the_mountings_first_stop() {
    let dir = scratch("misstated-face-shift");
    // Mounting 2 with the table at 22.5° at step 0, the polygon turned 1 face.
    let mut lab = SimLab::start(
        &dir,
        &[&TWO_MOUNTINGS[..], &["--shift-deg", "0,22.5"]].concat(),
    );
    let out = dir.join("run");
    let first = polycal(&lab.run_args(&out, &design(&[])));
    assert!(first.status.success(), "{}", stderr(&first));
    assert_eq!(lab.remount(), 2);
    // Told 2 faces: faces 3, 4 expected at step 0, faces 2, 3 there.
    let told = lab.run_args(
        &out,
        &design(&["--setup", "2", "--shift", "22.5", "--face-shift", "2"]),
    );
    let result = polycal_with_input(&told, "\n");
    let text = stderr(&result);
    assert_eq!(result.status.code(), Some(2), "{text}");
    let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{text}");
    assert!(
        errors[0].starts_with(
            "error: at the first stop of mounting 2 (shift 22.5°, turned 2 faces), cycle 1, \
             step 0, the autocollimators see faces 2, 3 (the polygon turned 1 face(s)), not \
             faces 3, 4 as stated"
        ),
        "{text}"
    );
    // The way on is the mounting stated as it is, not the same command.
    assert!(
        errors[0].ends_with(&format!(
            "state the mounting as it is (--setup 2 --shift 22.5 --face-shift 1) or mount it \
             as stated, and run again; nothing of mounting 2 was stored; the run stopped; 36 \
             of 72 readings are in {}",
            out.join("measurements.csv").display()
        )),
        "{text}"
    );
    assert_eq!(places(&out).len(), 36, "nothing of mounting 2 stored");
    // Stated as it is (and confirmed again): every reading of mounting 2 measured.
    let as_is = lab.run_args(
        &out,
        &design(&["--setup", "2", "--shift", "22.5", "--face-shift", "1"]),
    );
    let result = polycal_with_input(&as_is, "\n");
    assert!(result.status.success(), "{}", stderr(&result));
    let settings = RunSettings::new(8, 2).with_closing(true);
    assert_eq!(places(&out), planned_places(&settings, &[0.0, 22.5]));
}
/// Asserts that nothing was measured: the run directory not created (or empty) and no
/// move sent to the lab's table (none logged, nothing created to log it in).
fn assert_nothing_moved(out: &std::path::Path) {
    let entries = std::fs::read_dir(out).map(|d| d.count()).unwrap_or(0);
    assert_eq!(entries, 0, "the run directory {} is empty", out.display());
}

#[test]
fn a_design_that_loses_harmonics_is_refused_before_the_first_move() {
    // Autocollimators at faces 1 and 5 of 8: face offsets 0 and 4 lose harmonics 2, 4, 6.
    let dir = scratch("lost-harmonics");
    let lab = SimLab::start(&dir, &["--ac-faces", "1,5", "--cycles", "1", "--closing"]);
    let out = dir.join("run");
    let one = [
        "--faces",
        "8",
        "--cycles",
        "1",
        "--closing",
        "--ac-faces",
        "1,5",
    ];
    let args = lab.run_args(&out, &[&one[..], &RUN_OPTIONS[..]].concat());
    let text = assert_error(&polycal(&args), "harmonics 2, 4 and 6");
    assert!(text.contains("run from a plan"), "{text}");
    assert!(text.contains("--plan"), "{text}");
    assert_nothing_moved(&out);

    // The same design from a plan is refused with the plan's file named.
    // `plan` writes the design and warns that it cannot calibrate (status 1).
    let planned_out = polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--format",
        "json",
        "--design",
        "name=lost;faces=8;ac-faces=1,5;cycles=1;closing=true",
    ]);
    assert!(stderr(&planned_out).contains("cannot calibrate"));
    let plan = dir.join("lost.json");
    std::fs::write(&plan, &planned_out.stdout).unwrap();
    let mut with_plan = vec!["--plan", plan.to_str().unwrap()];
    with_plan.extend_from_slice(&RUN_OPTIONS);
    let text = assert_error(
        &polycal(&lab.run_args(&out, &with_plan)),
        "harmonics 2, 4 and 6",
    );
    assert!(text.contains("lost.json"), "{text}");
    assert_nothing_moved(&out);
}

#[test]
fn a_planned_design_whose_second_mounting_completes_the_first_is_run() {
    // Faces 1 and 5 lose the even harmonics in the first mounting; the second, turned by
    // one face, adds offsets 1 and 5: the whole plan is evaluable, so the first mounting
    // is measured.
    let dir = scratch("completed-by-plan");
    let plan = planned(
        &dir,
        "plan.json",
        &["name=two;faces=8;ac-faces=1,5;cycles=1;closing=true;setups=2;setup-shift=1"],
    );
    let lab = SimLab::start(
        &dir,
        &[
            "--ac-faces",
            "1,5",
            "--cycles",
            "1",
            "--closing",
            "--setups",
            "2",
            "--setup-shift",
            "1",
        ],
    );
    let out = dir.join("run");
    let mut with_plan = vec!["--plan", plan.to_str().unwrap()];
    with_plan.extend_from_slice(&RUN_OPTIONS);
    let first = polycal(&lab.run_args(&out, &with_plan));
    assert!(first.status.success(), "{}", stderr(&first));
    assert_eq!(rows(&out).len(), 9 * 2, "the first mounting measured");
}

/// The stops a session approached, in order, each with the position commanded just
/// before its final move (`None` for the session's first move): every move followed by
/// an autocollimator's query before the next move.
fn approaches(session: &[serde_json::Value]) -> Vec<(f64, Option<f64>)> {
    let position = |r: &serde_json::Value| -> Option<f64> {
        let text = r["text"].as_str()?;
        (r["event"] == "sent" && r["device"] == "table")
            .then(|| text.strip_prefix("1PA"))??
            .trim()
            .parse()
            .ok()
    };
    let mut out = Vec::new();
    let mut previous: Option<f64> = None;
    for (i, r) in session.iter().enumerate() {
        let Some(target) = position(r) else { continue };
        let rest = &session[i + 1..];
        let next = rest
            .iter()
            .position(|e| position(e).is_some())
            .unwrap_or(rest.len());
        let read = rest[..next]
            .iter()
            .any(|e| e["device"].as_str().is_some_and(|d| d.starts_with("ac")));
        if read {
            out.push((target, previous));
        }
        previous = Some(target);
    }
    out
}

#[test]
fn every_stop_is_approached_from_its_cycles_direction() {
    use polycal::measurement::Direction;
    // Three cycles, the second counter-clockwise; the reading of cycle 2, step 3,
    // autocollimator 1 is 2″ off, so that a check measures it again.
    let dir = scratch("approach");
    let lab = SimLab::start(
        &dir,
        &[
            "--cycles",
            "3",
            "--bidirectional",
            "--noise",
            "0.05",
            "--seed",
            "7",
            "--outlier",
            "2:3:1:2",
        ],
    );
    let out = dir.join("run");
    let mut args = lab.run_args(&out, &design(&["--bidirectional"]));
    let cycles = args.iter().position(|a| a == "--cycles").unwrap() + 1;
    args[cycles] = "3".into();
    let result = polycal(&args);
    // Completed, with a reading measured again: status 1.
    assert_eq!(result.status.code(), Some(1), "{}", stderr(&result));
    assert_eq!(manifest(&out)["outcome"], "completed");
    let settings = RunSettings::new(8, 3)
        .with_closing(true)
        .with_bidirectional(true);
    let plan = settings.plan();
    let set = MeasurementSet::read_path(&out.join("measurements.csv"), None).unwrap();
    // The outlier was measured again, in its own (counter-clockwise) cycle.
    let m = manifest(&out);
    let remeasured = m["remeasured"].as_array().unwrap();
    assert_eq!(remeasured.len(), 1, "{m:#}");
    assert_eq!(
        (
            &remeasured[0]["cycle"],
            &remeasured[0]["step"],
            &remeasured[0]["ac"]
        ),
        (&2.into(), &3.into(), &1.into())
    );
    let stored = set
        .readings
        .iter()
        .find(|r| (r.cycle, r.step, r.ac) == (2, 3, 1))
        .unwrap();
    assert_eq!(stored.direction, Direction::Ccw);
    let session = &sessions(&out)[0];
    let visits = approaches(session);
    // The planned stops, and after each cycle's check the stops it measured again
    // (measured again or suspect, from the manifest), each in its reading's direction.
    let direction_of = |cycle: u64| {
        if cycle == 2 {
            Direction::Ccw
        } else {
            Direction::Cw
        }
    };
    let again: Vec<(u64, f64, Direction)> = m["remeasured"]
        .as_array()
        .unwrap()
        .iter()
        .chain(m["suspect"].as_array().unwrap())
        .map(|r| {
            (
                r["found_after_cycle"].as_u64().unwrap(),
                r["step"].as_f64().unwrap() * 45.0,
                direction_of(r["cycle"].as_u64().unwrap()),
            )
        })
        .collect();
    let mut directions: Vec<(f64, Direction)> = Vec::new();
    for (i, s) in plan.iter().enumerate() {
        directions.push((s.degrees(8), s.direction));
        if plan.get(i + 1).is_none_or(|n| n.cycle != s.cycle) {
            directions.extend(
                again
                    .iter()
                    .filter(|a| a.0 == u64::from(s.cycle))
                    .map(|a| (a.1, a.2)),
            );
        }
    }
    assert_eq!(visits.len(), directions.len(), "{visits:?}");
    // Among them the counter-clockwise reading, measured again after cycle 3.
    assert!(again.contains(&(3, 135.0, Direction::Ccw)), "{again:?}");
    for (i, ((target, previous), (planned, direction))) in
        visits.iter().zip(&directions).enumerate()
    {
        assert!(
            (target - planned).abs() < 1e-9,
            "visit {i}: {target}°, not {planned}°"
        );
        let previous = previous.unwrap_or_else(|| panic!("visit {i}: no move before"));
        match direction {
            Direction::Cw => assert!(previous < *target, "visit {i} cw from {previous}°"),
            Direction::Ccw => assert!(previous > *target, "visit {i} ccw from {previous}°"),
        }
    }
    // The first stop of the counter-clockwise cycle (360°, where cycle 1 ended) is
    // approached from above, and the table was sent there again.
    assert_eq!(plan[9].direction, Direction::Ccw);
    assert_eq!(visits[9].0, 360.0);
    assert!(visits[9].1.is_some_and(|p| p > 360.0));
    // Every stored reading of a ccw cycle is labelled so.
    for r in &set.readings {
        let want = if r.cycle == 2 {
            Direction::Ccw
        } else {
            Direction::Cw
        };
        assert_eq!(r.direction, want, "{r:?}");
    }
    // The reading that replaced the outlier was taken after a move onto 135° from a
    // position above it (the traffic's `remeasured` record follows its readings).
    let i = session
        .iter()
        .position(|r| r["event"] == "remeasured")
        .unwrap();
    let last_two: Vec<f64> = session[..i]
        .iter()
        .rev()
        .filter_map(|r| r["text"].as_str()?.strip_prefix("1PA"))
        .take(2)
        .map(|t| t.trim().parse::<f64>().unwrap())
        .collect();
    assert_eq!(last_two[0], 135.0);
    assert!(last_two[1] > 135.0, "{last_two:?}");
    assert_solves_to_truth(&out, &lab.truth);
}
