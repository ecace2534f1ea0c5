//! Monte Carlo of a diagnosis's final model (docs/FORMAT.md §5.2, `diagnose --budget
//! --monte-carlo`): the trials are solved with the effect columns the diagnosis added, and
//! for a linear model with normal inputs they agree with the GUM, whose k is then exactly
//! the normal one.

use polycal::diagnose::{DiagnoseOptions, diagnose};
use polycal::effects::Effect;
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::{SigmaSource, Solution};
use polycal::uncertainty::calibration::{
    self, FamilyUncertainty, InstrumentBudget, McFamily, McOptions,
};
use polycal::uncertainty::monte_carlo::Trials;

/// Normal components of infinite degrees of freedom on every scope the design has.
const NORMAL_BUDGET: &str = r#"
p = 0.95
dof_policy = "fractional"

[[component]]
name = "Angle error (normal)"
type = "B"
distribution = "normal"
u = 0.03
acts_on = "each-reading"

[[component]]
name = "Table position (normal)"
type = "B"
distribution = "normal"
u = 0.02
acts_on = "each-stop"

[[component]]
name = "Result offset (normal)"
type = "B"
distribution = "normal"
u = 0.01
acts_on = "result"
"#;

/// The fit's σ stated (normal noise, infinite degrees of freedom), as a lab states the
/// repeatability of its autocollimators: every input of the model is then normal.
fn stated(solution: &Solution, sigma: f64) -> Solution {
    let mut solution = solution.clone();
    solution.sigma = Some((sigma, SigmaSource::Stated));
    solution
}

/// Per family (name, Monte Carlo, the final model's GUM, the base model's GUM, the
/// estimates): every u within five Monte Carlo standard errors (relative √(1/2M)) of
/// u_c, every interval end within five of its standard errors (√(p(1 − p)/M)/f(1.96)·u,
/// f the normal density) of y ± U, k within `k_tolerance` of the normal 1.959964; returns
/// the largest relative difference of the base model's u_c from the final model's.
fn agree_with_the_gum(
    families: &[(
        &str,
        &McFamily,
        &FamilyUncertainty,
        &FamilyUncertainty,
        &Vec<f64>,
    )],
    m: usize,
    k_tolerance: f64,
) -> f64 {
    let relative_u_noise = (1.0 / (2.0 * m as f64)).sqrt();
    let end_noise = (0.025 * 0.975 / m as f64).sqrt() / 0.058_445;
    let mut largest_change = 0.0_f64;
    for &(family, mc_family, gum_family, gum_before_family, estimates) in families {
        for (i, &estimate) in estimates.iter().enumerate() {
            let u = gum_family.u[i];
            if u == 0.0 {
                continue; // φ[N] = 0 by definition
            }
            let k = gum_family.k[i].expect("a finite k");
            assert!((k - 1.959_964).abs() < k_tolerance, "{family} {i}: k {k}");
            let u_mc = mc_family.u[i];
            assert!(
                (u_mc / u - 1.0).abs() < 5.0 * relative_u_noise,
                "{family} {i}: u {u_mc} against u_c {u}"
            );
            let expanded = gum_family.expanded_u[i];
            for (end, gum_end) in [
                (mc_family.low[i], estimate - expanded),
                (mc_family.high[i], estimate + expanded),
            ] {
                assert!(
                    (end - gum_end).abs() < 5.0 * end_noise * u,
                    "{family} {i}: interval end {end} against {gum_end}"
                );
            }
            largest_change = largest_change.max((gum_before_family.u[i] / u - 1.0).abs());
        }
    }
    largest_change
}

/// A drift and a zero jump found by the diagnosis change the design through which every
/// error propagates; the Monte Carlo of the final model draws the readings and solves
/// them with the effects' columns. With normal inputs its u is the GUM's u_c within the Monte Carlo
/// noise (√(1/2M) relative), its interval ends the GUM's y ± 1.96·u_c within their noise,
/// and JCGM 101 §8 validates the GUM at one significant digit; the base model's GUM
/// differs from the final model's by more than three times the tolerance on u, so a Monte
/// Carlo that left the effect columns out would fail.
#[test]
fn final_model_monte_carlo_agrees_with_the_gum_for_normal_inputs() {
    let (set, _) = simulate(&SimulationConfig {
        faces: 24,
        cycles: 3,
        closing: true,
        noise_arcsec: 0.05,
        effects: vec![
            Effect::Drift {
                ac: 2,
                value: 3.0,
                quadratic: None,
            },
            Effect::OffsetStep {
                ac: 1,
                cycle: 2,
                step: Some(10),
                setup: None,
                value: 0.6,
            },
        ],
        seed: 3,
        ..SimulationConfig::default()
    })
    .unwrap();
    let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
    assert_eq!(d.effects.len(), 2, "{:?}", d.effects);
    assert!(d.after.layout.effects >= 1);
    let budget = InstrumentBudget::from_toml_str(NORMAL_BUDGET, "normal.toml").unwrap();
    let after = stated(&d.after, 0.05);
    let before = stated(&d.before, 0.05);
    let gum = calibration::evaluate(&set, &after, &budget).unwrap();
    let gum_before = calibration::evaluate(&set, &before, &budget).unwrap();
    let m = 200_000;
    let options = McOptions::new(Trials::Fixed(m))
        .with_seed(5)
        .with_significant_digits(1);
    let mc = calibration::monte_carlo(&set, &after, &budget, &gum, &options).unwrap();
    assert_eq!(mc.trials, m);
    assert!(mc.validated, "JCGM 101 §8 at one digit");
    let families = [
        (
            "pitch",
            &mc.pitch_deviation,
            &gum.pitch_deviation,
            &gum_before.pitch_deviation,
            &after.pitch_deviation,
        ),
        (
            "face",
            &mc.face_deviation,
            &gum.face_deviation,
            &gum_before.face_deviation,
            &after.face_deviation,
        ),
        (
            "encoder",
            &mc.encoder_error,
            &gum.encoder_error,
            &gum_before.encoder_error,
            &after.encoder_error,
        ),
    ];
    // normal inputs of infinite degrees of freedom: k is the normal one
    let largest_change = agree_with_the_gum(&families, m, 1e-5);
    let relative_u_noise = (1.0 / (2.0 * m as f64)).sqrt();
    assert!(
        largest_change > 3.0 * 5.0 * relative_u_noise,
        "the effect columns change some u_c by {largest_change}"
    );
}

/// A self-calibration's diagnosis (`diagnose --budget --monte-carlo` on a
/// self-calibration file): a jump of head 3's zero, found, adds a column through which
/// every error reaches the heads' errors; the Monte Carlo of the final model solves each
/// trial with it (and with the table's error at every stop) and agrees with the GUM
/// budget of the final model — u within five times its noise, interval ends within five
/// times theirs — while the base model's budget differs by far more: a Monte Carlo
/// without the effect's column would fail.
#[test]
fn selfcal_final_model_monte_carlo_agrees_with_the_gum() {
    selfcal_final_model_check(vec![0.0, 50.0, 130.0, 230.0], None);
}

/// As [`selfcal_final_model_monte_carlo_agrees_with_the_gum`] with heads between the
/// positions (52° and 233° on 36 positions: 5.2 and 23.3 positions), their disc error
/// band-limited: the trials solved by the band-limited design with the jump's column.
#[test]
fn selfcal_final_model_monte_carlo_with_heads_between_the_positions_agrees_with_the_gum() {
    selfcal_final_model_check(vec![0.0, 52.0, 130.0, 233.0], Some(17));
}

fn selfcal_final_model_check(heads: Vec<f64>, max_order: Option<usize>) {
    use polycal::diagnose::selfcal::{self as diagnose_selfcal, diagnose_selfcal as run};
    use polycal::selfcal::{self, HeadGrid, SelfcalOptions};
    use polycal::simulate::{SelfcalSimConfig, simulate_selfcal};

    let mut config = SelfcalSimConfig::default();
    config.positions = 36;
    config.cycles = 12;
    config.head_angles_deg = heads;
    if let Some(order) = max_order {
        config.max_order = order;
    }
    config.noise_arcsec = 0.02;
    config.seed = 6;
    let (mut set, _) = simulate_selfcal(&config).unwrap();
    for r in &mut set.readings {
        if r.head == 3 && (r.cycle, r.step) >= (3, 10) {
            r.reading_arcsec += 0.5;
        }
    }
    let found = run(&set, &DiagnoseOptions::default(), &SelfcalOptions::new()).unwrap();
    assert!(
        matches!(
            found.diagnosis.effects[0].effect,
            Effect::OffsetStep {
                ac: 3,
                cycle: 3,
                step: Some(10),
                ..
            }
        ),
        "{:?}",
        found.diagnosis.effects
    );
    assert!(found.after.dof > 1000, "dof {}", found.after.dof);
    let grid = if max_order.is_some() {
        HeadGrid::OffGrid
    } else {
        HeadGrid::OnGrid
    };
    assert_eq!(found.after.grid, grid);
    let budget = InstrumentBudget::from_toml_str(NORMAL_BUDGET, "normal.toml").unwrap();
    let gum = selfcal::evaluate_budget(&found.after, &budget).unwrap();
    let gum_before = selfcal::evaluate_budget(&found.before, &budget).unwrap();
    let m = 200_000;
    let options = McOptions::new(Trials::Fixed(m))
        .with_seed(4)
        .with_significant_digits(1);
    let mc = diagnose_selfcal::monte_carlo(&set, &found, &budget, &gum, &options).unwrap();
    assert_eq!(mc.trials, m);
    assert!(mc.validated, "JCGM 101 §8 at one digit");
    let heads: Vec<f64> = found.after.head_error.iter().map(|h| h.value).collect();
    let families = [
        (
            "e",
            &mc.encoder_error,
            &gum.encoder_error,
            &gum_before.encoder_error,
            &found.after.encoder_error,
        ),
        (
            "c",
            &mc.head_error,
            &gum.head_error,
            &gum_before.head_error,
            &heads,
        ),
    ];
    // σ from more than 1000 residual degrees of freedom: k within 0.002 of the normal
    let largest_change = agree_with_the_gum(&families, m, 0.002);
    let relative_u_noise = (1.0 / (2.0 * m as f64)).sqrt();
    assert!(
        largest_change > 3.0 * 5.0 * relative_u_noise,
        "the base model's u differ by {largest_change}"
    );
}
