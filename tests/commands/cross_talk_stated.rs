//! Cross-talk stated from an autocollimator's calibration (`--cross-talk AC:C[:U]`,
//! docs/FORMAT.md §6), checked against independent truth:
//!
//! - the correction is reading − C·`reading_y` exactly (a hand-built set with dyadic
//!   numbers, so that the expected values are exact), and corrected with the true C a
//!   simulated run is its clean twin, readings and solution;
//! - the budget component u_j = U·|Σᵢ L_ji·yᵢ| against finite differences of the solver,
//!   and against the hand-derived paper design: a constant `reading_y` Y moves only the
//!   setup error (by U·|Y|), a `reading_y` W\[p\] of the step moves β\[p + 2\] by
//!   U·|W\[p\] − mean W|;
//! - the Monte Carlo draws it: its u matches the GUM u_c on both trial solvers;
//! - the refusals, and what the command line says it stated: the JSON's
//!   `stated_cross_talk`, the table's line, the report's paragraph, the warning without a
//!   budget, the Monte Carlo (that a stated cross-talk decides what the closure alone
//!   cannot place is tested on the command line in `diagnose_cli_identify.rs`).

use std::process::{Command, Output};

use polycal::effects::Effect;
use polycal::measurement::cross_talk::{
    CrossTalkError, StatedCrossTalk, check_distinct, correct_cross_talk,
};
use polycal::measurement::{Direction, MeasurementSet, Reading};
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::{SolveOptions, solve};
use polycal::uncertainty::calibration::{
    self, InstrumentBudget, KnownCorrection, McOptions, evaluate, evaluate_with_corrections,
};
use polycal::uncertainty::monte_carlo::Trials;

const BUDGET: &str = "examples/budgets/instrument.toml";
const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";

use crate::undeclared;

fn config(effects: Vec<Effect>) -> SimulationConfig {
    undeclared::two_mountings_with_y(11, effects)
}

/// The paper's design by hand: N faces, `cycles` cycles, autocollimator 1 on face p + 1
/// and autocollimator 2 on face p + 2 at step p, no closing reading; reading i is
/// `value(ac, cycle, step)` and its `reading_y` is `y(ac, step)`.
fn paper_set(
    n: usize,
    cycles: u32,
    value: impl Fn(u32, u32, usize) -> f64,
    y: impl Fn(u32, usize) -> Option<f64>,
) -> MeasurementSet {
    let mut readings = Vec::new();
    for cycle in 1..=cycles {
        for step in 0..n {
            for ac in 1..=2u32 {
                readings.push(Reading {
                    setup: 1,
                    cycle,
                    step,
                    ac,
                    face: (step + ac as usize - 1) % n + 1,
                    reading_arcsec: value(ac, cycle, step),
                    direction: Direction::Cw,
                    time_seconds: None,
                    reading_y_arcsec: y(ac, step),
                    temperature_celsius: None,
                    encoder_degrees: None,
                    line: 0,
                });
            }
        }
    }
    MeasurementSet::from_readings(readings, Some(n), "hand.csv").unwrap()
}

/// A reading value that is not noise-free (so that the fit has a residual σ) but the
/// same on every run.
fn scatter(ac: u32, cycle: u32, step: usize) -> f64 {
    ((ac as f64 * 7.3 + cycle as f64 * 3.1 + step as f64 * 1.7).sin()) * 0.05 + 0.2 * step as f64
}

/// Dyadic numbers, so that reading − C·y is exact and the expected values are written
/// out by hand: C = 0.125 on autocollimator 1, autocollimator 2 untouched.
#[test]
fn the_correction_is_the_reading_minus_c_times_reading_y() {
    let set = paper_set(
        3,
        1,
        |ac, _, step| [[1.5, -0.25, 4.0], [2.0, 3.0, -1.0]][ac as usize - 1][step],
        |ac, step| Some([[2.0, -8.0, 0.5], [16.0, 16.0, 16.0]][ac as usize - 1][step]),
    );
    let stated = StatedCrossTalk::new(1, 0.125, Some(0.01)).unwrap();
    let corrected = correct_cross_talk(&set, &[stated]).unwrap();
    let got: Vec<(u32, f64)> = corrected
        .readings
        .iter()
        .map(|r| (r.ac, r.reading_arcsec))
        .collect();
    // 1.5 − 0.125·2 = 1.25, −0.25 + 0.125·8 = 0.75, 4 − 0.125·0.5 = 3.9375
    assert_eq!(
        got,
        [
            (1, 1.25),
            (2, 2.0),
            (1, 0.75),
            (2, 3.0),
            (1, 3.9375),
            (2, -1.0)
        ]
    );
    // nothing else changes
    for (c, r) in corrected.readings.iter().zip(&set.readings) {
        assert_eq!(c.reading_y_arcsec, r.reading_y_arcsec);
        assert_eq!((c.cycle, c.step, c.face), (r.cycle, r.step, r.face));
    }
    // the column of its budget component is reading_y on autocollimator 1, 0 elsewhere
    assert_eq!(stated.column(&corrected), [2.0, 0.0, -8.0, 0.0, 0.5, 0.0]);
}

/// Corrected with the true coefficient, the readings are the clean twin's (the simulator
/// adds C·reading_y as written), and so is the solution.
#[test]
fn the_correction_with_the_true_coefficient_gives_the_clean_twin() {
    let (set, _) = simulate(&config(vec![Effect::CrossTalk { ac: 1, value: 0.01 }])).unwrap();
    let (clean, _) = simulate(&config(Vec::new())).unwrap();
    let stated = StatedCrossTalk::new(1, 0.01, None).unwrap();
    let corrected = correct_cross_talk(&set, &[stated]).unwrap();
    let mut largest_change: f64 = 0.0;
    for ((c, k), r) in corrected
        .readings
        .iter()
        .zip(&clean.readings)
        .zip(&set.readings)
    {
        assert!((c.reading_arcsec - k.reading_arcsec).abs() < 1e-12);
        largest_change = largest_change.max((r.reading_arcsec - k.reading_arcsec).abs());
    }
    // the effect was there to be corrected
    assert!(largest_change > 0.01, "{largest_change}");
    let a = solve(&corrected, &SolveOptions::default()).unwrap();
    let b = solve(&clean, &SolveOptions::default()).unwrap();
    let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(x, y)| (x - y).abs() < 1e-9);
    assert!(close(&a.encoder_error, &b.encoder_error));
    assert!(close(&a.pitch_deviation, &b.pitch_deviation));
    assert!(close(&a.face_deviation, &b.face_deviation));
    for (x, y) in a.setup_error.iter().zip(&b.setup_error) {
        assert!((x.value - y.value).abs() < 1e-9);
    }
}

/// u_j = U·|∂θ_j/∂C|: the component of a stated U equals U times the change of every β,
/// α and setup error per unit of C, taken by finite differences of the solver on the
/// corrected readings; the other components are those of the budget without it.
#[test]
fn a_stated_u_enters_the_budget_through_the_design() {
    let (set, _) = simulate(&config(vec![Effect::CrossTalk { ac: 1, value: 0.01 }])).unwrap();
    let budget = InstrumentBudget::read_path(BUDGET).unwrap();
    let (c, u, delta) = (0.01, 0.001, 1e-4);
    let stated = StatedCrossTalk::new(1, c, Some(u)).unwrap();
    let corrected = correct_cross_talk(&set, &[stated]).unwrap();
    let moved =
        correct_cross_talk(&set, &[StatedCrossTalk::new(1, c + delta, None).unwrap()]).unwrap();
    let base = solve(&corrected, &SolveOptions::default()).unwrap();
    let shifted = solve(&moved, &SolveOptions::default()).unwrap();
    let corrections = KnownCorrection::of_stated_cross_talk(&corrected, &[stated]);
    assert_eq!(corrections.len(), 1);
    let with = evaluate_with_corrections(&corrected, &base, &budget, &corrections).unwrap();
    let without = evaluate(&corrected, &base, &budget).unwrap();
    assert_eq!(with.components.len(), without.components.len() + 1);
    let component = with.components.last().unwrap();
    assert_eq!(component.name, "cross-talk of autocollimator 1 (stated)");
    let check = |name: &str, got: &[f64], after: &[f64], before: &[f64]| {
        for (j, g) in got.iter().enumerate() {
            let expected = u * (after[j] - before[j]).abs() / delta;
            assert!((g - expected).abs() < 1e-7, "{name}{j}: {g} vs {expected}");
        }
    };
    check(
        "β",
        &component.pitch_deviation,
        &shifted.pitch_deviation,
        &base.pitch_deviation,
    );
    check(
        "φ",
        &component.face_deviation,
        &shifted.face_deviation,
        &base.face_deviation,
    );
    check(
        "α",
        &component.encoder_error,
        &shifted.encoder_error,
        &base.encoder_error,
    );
    let setup = |s: &polycal::solve::Solution| -> Vec<f64> {
        s.setup_error.iter().map(|e| e.value).collect()
    };
    check("U", &component.setup_error, &setup(&shifted), &setup(&base));
    // it reaches α and β: reading_y varies with the step and the face
    assert!(component.encoder_error.iter().any(|c| *c > 1e-3));
    assert!(component.pitch_deviation.iter().any(|c| *c > 1e-3));
    // combined in quadrature with the rest
    for j in 0..base.faces {
        let (w, o, c) = (
            with.encoder_error.u[j],
            without.encoder_error.u[j],
            component.encoder_error[j],
        );
        assert!((w * w - o * o - c * c).abs() < 1e-12, "{w} {o} {c}");
    }
    // a stated cross-talk without U is no component
    let no_u = StatedCrossTalk::new(1, c, None).unwrap();
    assert!(KnownCorrection::of_stated_cross_talk(&corrected, &[no_u]).is_empty());
}

/// The paper's design by hand (N = 6, two cycles). A constant `reading_y` Y on
/// autocollimator 1 is an offset of its readings: the error e of C moves its setup error
/// by e·Y and nothing else, so the component is U·|Y| on that setup error and 0 on β, φ,
/// α and the other setup error. A `reading_y` W\[p\] of the step on autocollimator 1:
/// β\[p + 2\] is the mean of (reading₂ − reading₁) at step p minus its mean over the
/// steps, so the component on β\[p + 2\] is U·|W\[p\] − mean W|.
#[test]
fn the_component_on_the_papers_design_by_hand() {
    let n = 6;
    let u = 0.002;
    let budget = InstrumentBudget::read_path(BUDGET).unwrap();
    let evaluated = |y: &dyn Fn(usize) -> f64| {
        let set = paper_set(n, 2, scatter, |ac, step| {
            Some(if ac == 1 { y(step) } else { 3.0 })
        });
        let stated = StatedCrossTalk::new(1, 0.0, Some(u)).unwrap();
        let solution = solve(&set, &SolveOptions::default()).unwrap();
        let corrections = KnownCorrection::of_stated_cross_talk(&set, &[stated]);
        let result = evaluate_with_corrections(&set, &solution, &budget, &corrections).unwrap();
        result.components.last().unwrap().clone()
    };

    let y_constant = 40.0;
    let offset = evaluated(&|_| y_constant);
    for c in offset
        .pitch_deviation
        .iter()
        .chain(&offset.face_deviation)
        .chain(&offset.encoder_error)
    {
        assert!(c.abs() < 1e-12, "{c}");
    }
    assert!((offset.setup_error[0] - u * y_constant).abs() < 1e-12);
    assert!(offset.setup_error[1].abs() < 1e-12);

    let w = [0.0, 10.0, -5.0, 20.0, 3.0, 7.0];
    let mean = w.iter().sum::<f64>() / n as f64;
    let by_step = evaluated(&|step| w[step]);
    for (p, wp) in w.iter().enumerate() {
        // face p + 2 (1-based) is index p + 1 of the list, wrapping
        let got = by_step.pitch_deviation[(p + 1) % n];
        let expected = u * (wp - mean).abs();
        assert!(
            (got - expected).abs() < 1e-12,
            "β{}: {got} vs {expected}",
            p + 2
        );
    }
}

/// The Monte Carlo draws the stated U: with U the dominant component, its u agrees with
/// the GUM u_c (which holds the component) and not with the u_c without it, on the paper's
/// design (closed-form trials, per-step means) and on two mountings (least-squares
/// trials).
#[test]
fn the_monte_carlo_draws_the_stated_u() {
    let budget = InstrumentBudget::from_toml_str(
        "p = 0.95\n[[component]]\nname = \"r\"\ntype = \"B\"\nu = 0.001\nacts_on = \"each-reading\"\n",
        "small.toml",
    )
    .unwrap();
    let paper = paper_set(12, 3, scatter, |ac, step| {
        Some(if ac == 1 {
            (step as f64 * 0.9).sin() * 30.0
        } else {
            0.0
        })
    });
    let (two_mountings, _) = simulate(&config(Vec::new())).unwrap();
    for (set, solver) in [(&paper, "closed-form"), (&two_mountings, "lsq")] {
        let stated = StatedCrossTalk::new(1, 0.0, Some(0.02)).unwrap();
        let solution = solve(set, &SolveOptions::default()).unwrap();
        let corrections = KnownCorrection::of_stated_cross_talk(set, &[stated]);
        let gum = evaluate_with_corrections(set, &solution, &budget, &corrections).unwrap();
        let plain = evaluate(set, &solution, &budget).unwrap();
        let options = McOptions::new(Trials::Fixed(100_000)).with_seed(7);
        let mc = calibration::monte_carlo_with_corrections(
            set,
            &solution,
            &budget,
            &corrections,
            &gum,
            &options,
        )
        .unwrap();
        assert_eq!(mc.solver, solver);
        let mut compared = 0;
        for (family, mc_u, gum_u, plain_u) in [
            (
                "β",
                &mc.pitch_deviation.u,
                &gum.pitch_deviation.u,
                &plain.pitch_deviation.u,
            ),
            (
                "α",
                &mc.encoder_error.u,
                &gum.encoder_error.u,
                &plain.encoder_error.u,
            ),
        ] {
            for j in 0..mc_u.len() {
                // where the stated U dominates
                if gum_u[j] > 2.0 * plain_u[j] {
                    compared += 1;
                    let ratio = mc_u[j] / gum_u[j];
                    assert!(
                        (ratio - 1.0).abs() < 0.02,
                        "{solver} {family}{j}: MC {} vs GUM {}",
                        mc_u[j],
                        gum_u[j]
                    );
                }
            }
        }
        assert!(compared >= 6, "{solver}: {compared} quantities compared");
    }
}

/// Specs: both forms read, the text form written back, and every refusal quoting the
/// spec and naming the part that is wrong.
#[test]
fn stated_cross_talk_is_read_and_checked() {
    let s: StatedCrossTalk = "2:0.004:0.0005".parse().unwrap();
    assert_eq!((s.ac, s.coefficient, s.u), (2, 0.004, Some(0.0005)));
    assert_eq!(s.to_string(), "2:0.004:0.0005");
    let s: StatedCrossTalk = "1:-0.01".parse().unwrap();
    assert_eq!((s.ac, s.coefficient, s.u), (1, -0.01, None));
    assert_eq!(s.to_string(), "1:-0.01");
    assert_eq!(s.describe(), "autocollimator 1: C = -0.01");
    for (bad, part) in [
        ("1", "1 part(s)"),
        ("1:0.1:0.1:0.1", "4 part(s)"),
        ("x:0.1", "AC \"x\""),
        ("-1:0.1", "AC \"-1\""),
        ("0:0.1", "start at 1"),
        ("1:x", "C \"x\""),
        ("1:", "C \"\""),
        ("1:NaN", "C \"NaN\""),
        ("1:2", "C must be"),
        ("1:0.1:inf", "U \"inf\""),
        ("1:0.1:-1", "U must be"),
        ("1:0.1:2", "U must be"),
    ] {
        let message = bad.parse::<StatedCrossTalk>().unwrap_err().to_string();
        assert!(
            message.starts_with(&format!("cross-talk \"{bad}\": ")),
            "{bad}: {message}"
        );
        assert!(message.contains(part), "{bad}: {message}");
    }
    let twice = [
        StatedCrossTalk::new(2, 0.0, None).unwrap(),
        StatedCrossTalk::new(2, 0.1, None).unwrap(),
    ];
    assert_eq!(check_distinct(&twice), Err(CrossTalkError::Twice { ac: 2 }));
}

/// A set the correction cannot be made on is refused, naming what is wrong.
#[test]
fn the_correction_refuses_what_it_cannot_do() {
    let y = |missing: Option<(u32, usize)>| {
        move |ac: u32, step: usize| (missing != Some((ac, step))).then_some(4.0)
    };
    let stated = |ac| [StatedCrossTalk::new(ac, 0.01, None).unwrap()];
    let set = paper_set(4, 2, scatter, y(None));
    // an autocollimator the set does not have
    let e = correct_cross_talk(&set, &stated(3)).unwrap_err();
    assert_eq!(
        e.to_string(),
        "hand.csv: no autocollimator 3 for its stated cross-talk"
    );
    // twice
    let mut both = stated(1).to_vec();
    both.extend(stated(1));
    assert_eq!(
        correct_cross_talk(&set, &both),
        Err(CrossTalkError::Twice { ac: 1 })
    );
    // readings without reading_y: step 2 of autocollimator 2, in both cycles
    let set = paper_set(4, 2, scatter, y(Some((2, 2))));
    assert!(correct_cross_talk(&set, &stated(1)).is_ok());
    let e = correct_cross_talk(&set, &stated(2))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(
            "2 reading(s) of autocollimator 2 have no reading_y (the first at cycle 1, step 2)"
        ),
        "{e}"
    );
    // a corrected reading beyond the limits of a reading (docs/FORMAT.md §2.2)
    let set = paper_set(4, 1, |_, _, _| 999_999.0, |_, _| Some(-1e6));
    let e = correct_cross_talk(&set, &[StatedCrossTalk::new(1, 1.0, None).unwrap()])
        .unwrap_err()
        .to_string();
    assert!(e.contains("beyond the limits of a reading"), "{e}");
}

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .output()
        .expect("the polycal binary runs")
}

fn error_lines(o: &Output) -> Vec<String> {
    String::from_utf8_lossy(&o.stderr)
        .lines()
        .filter(|l| l.starts_with("error:"))
        .map(str::to_string)
        .collect()
}

/// What the command line says it stated, on a run with `reading_y`: `stated_cross_talk`
/// in the JSON of `solve` and `diagnose` (and nothing without the option), the line the
/// tables end with, the warning for a U without a budget, the stated U in the budget and
/// the Monte Carlo of `solve`, the report's paragraph and budget row; the refusals are one
/// `error:` line, status 2.
#[test]
fn the_command_line_says_what_was_stated() {
    let dir = std::env::temp_dir().join(format!("polycal-xtalk-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("run.csv");
    let file = file.to_str().unwrap();
    let o = polycal(&[
        "simulate",
        "--faces",
        "12",
        "--cycles",
        "3",
        "--closing",
        "--elevation",
        "10:0:1:5:0.05",
        "--cross-talk",
        "1:0.01",
        "--seed",
        "3",
        "--out",
        file,
    ]);
    assert!(o.status.success());

    let json_of = |args: &[&str]| -> serde_json::Value {
        let o = polycal(args);
        assert!(
            matches!(o.status.code(), Some(0 | 1)),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let json = json_of(&[
        "solve",
        file,
        "--cross-talk",
        "1:0.01:0.001",
        "--budget",
        BUDGET,
        "--format",
        "json",
    ]);
    assert_eq!(
        json["stated_cross_talk"],
        serde_json::json!([{"ac": 1, "coefficient": 0.01, "u": 0.001}])
    );
    let component = json["uncertainty"]["components"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "cross-talk of autocollimator 1 (stated)")
        .expect("the stated U is a component");
    assert_eq!(component["u"], 0.001);
    assert_eq!(component["type"], "B");
    assert_eq!(component["acts_on"], "each-autocollimator");
    assert_eq!(component["encoder_error"].as_array().unwrap().len(), 12);
    let json = json_of(&[
        "diagnose",
        file,
        "--cross-talk",
        "1:0.01",
        "--format",
        "json",
    ]);
    assert_eq!(
        json["stated_cross_talk"],
        serde_json::json!([{"ac": 1, "coefficient": 0.01, "u": null}])
    );
    for command in ["solve", "diagnose"] {
        let json = json_of(&[command, file, "--format", "json"]);
        assert!(json.get("stated_cross_talk").is_none(), "{command}");
    }

    // U without a budget: a warning, the correction made all the same; the table says so
    let o = polycal(&["solve", file, "--cross-talk", "1:0.01:0.001"]);
    assert!(o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains(
            "warning: --cross-talk: the stated U enters the uncertainty only with --budget"
        ),
        "{stderr}"
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    let last = "stated cross-talk, readings corrected by C·reading_y: \
                autocollimator 1: C = 0.01, u(C) = 0.001";
    assert!(stdout.trim_end().ends_with(last), "{stdout}");
    let o = polycal(&["diagnose", file, "--cross-talk", "1:0.01"]);
    assert!(
        String::from_utf8_lossy(&o.stdout)
            .trim_end()
            .ends_with("autocollimator 1: C = 0.01")
    );

    // the Monte Carlo draws it (status 0, or 1 for a validation that fails)
    let json = json_of(&[
        "solve",
        file,
        "--cross-talk",
        "1:0.01:0.001",
        "--budget",
        BUDGET,
        "--monte-carlo",
        "2000",
        "--format",
        "json",
    ]);
    assert_eq!(json["monte_carlo"]["trials"], 2000);

    // the report: its method paragraph and the budget's row, and nothing without it
    let html = dir.join("report.html");
    let html = html.to_str().unwrap();
    let o = polycal(&["report", file, "--budget", BUDGET, "--out", html]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        !std::fs::read_to_string(html)
            .unwrap()
            .contains("stated-cross-talk")
    );
    let o = polycal(&[
        "report",
        file,
        "--cross-talk",
        "2:0:0.0005",
        "--budget",
        BUDGET,
        "--out",
        html,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(html).unwrap();
    assert!(text.contains("<p id=\"stated-cross-talk\">"));
    assert!(text.contains("autocollimator 2: C = 0, u(C) = 0.0005"));
    assert!(text.contains("cross-talk of autocollimator 2 (stated)"));

    // refusals: one error line, status 2
    for (args, says) in [
        (
            vec![
                "diagnose",
                file,
                "--cross-talk",
                "1:0",
                "--cross-talk",
                "1:0.1",
            ],
            "stated twice",
        ),
        (
            vec!["solve", file, "--cross-talk", "1:0.1:-0.5"],
            "U must be",
        ),
        (
            vec!["solve", EXAMPLE, "--cross-talk", "1:0.01"],
            "have no reading_y",
        ),
        (
            vec![
                "report",
                "examples/data/selfa-168.csv",
                "--cross-talk",
                "1:0",
                "--out",
                html,
            ],
            "self-calibration",
        ),
    ] {
        let o = polycal(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let errors = error_lines(&o);
        assert_eq!(errors.len(), 1, "{args:?}: {errors:?}");
        assert!(errors[0].contains(says), "{args:?}: {errors:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
