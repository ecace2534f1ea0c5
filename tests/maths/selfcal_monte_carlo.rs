//! Monte Carlo of a self-calibration (docs/FORMAT.md §9.3.2, `selfcal --budget
//! --monte-carlo`): trials drawn with every scope of the budget and solved through the
//! closure model, against the GUM budget of `selfcal::evaluate_budget`.

use polycal::selfcal::{
    self, SelfcalMonteCarlo, SelfcalOptions, SelfcalSet, SelfcalSolution, SelfcalUncertainty,
};
use polycal::simulate::{SelfcalSimConfig, simulate_selfcal};
use polycal::uncertainty::calibration::FamilyUncertainty;
use polycal::uncertainty::calibration::{InstrumentBudget, McFamily, McOptions};
use polycal::uncertainty::monte_carlo::Trials;

/// Normal components of infinite degrees of freedom on every scope: the GUM's u_c is then
/// exact and its k the normal one (but for the t of the type A, ν in the thousands).
const NORMAL_BUDGET: &str = r#"
p = 0.95
dof_policy = "fractional"

[[component]]
name = "Interpolation (normal)"
type = "B"
distribution = "normal"
u = 0.01
acts_on = "each-reading"

[[component]]
name = "Zero offset of a read head"
type = "B"
distribution = "normal"
u = 0.05
acts_on = "each-autocollimator"

[[component]]
name = "Table position"
type = "B"
distribution = "normal"
u = 0.2
acts_on = "each-position"

[[component]]
name = "Table wobble at a stop"
type = "B"
distribution = "normal"
u = 0.2
acts_on = "each-stop"

[[component]]
name = "Disc drift"
type = "B"
distribution = "normal"
u = 0.004
acts_on = "result"
"#;

fn run(config: &SelfcalSimConfig, options: &SelfcalOptions) -> (SelfcalSet, SelfcalSolution) {
    let (set, _) = simulate_selfcal(config).unwrap();
    let solution = selfcal::solve(&set, options).unwrap();
    (set, solution)
}

/// Checks one family: u within five Monte Carlo standard errors (relative √(1/2M)) of the
/// GUM's u_c, and, when `normal`, the interval ends within five of their standard errors
/// (√(p(1 − p)/M)/f(1.96) · u) of y ± U.
fn agrees(
    name: &str,
    mc: &McFamily,
    gum: &FamilyUncertainty,
    estimates: &[f64],
    m: usize,
    normal: bool,
) {
    let u_noise = (1.0 / (2.0 * m as f64)).sqrt();
    let end_noise = (0.025 * 0.975 / m as f64).sqrt() / 0.058_445;
    for (i, &y) in estimates.iter().enumerate() {
        let u = gum.u[i];
        assert!(
            (mc.u[i] / u - 1.0).abs() < 5.0 * u_noise,
            "{name} {i}: Monte Carlo u {} against u_c {u}",
            mc.u[i]
        );
        if normal {
            let expanded = gum.expanded_u[i];
            let k = gum.k[i].expect("a finite k");
            assert!((k - 1.96).abs() < 0.002, "{name} {i}: k {k}");
            for (end, gum_end) in [(mc.low[i], y - expanded), (mc.high[i], y + expanded)] {
                assert!(
                    (end - gum_end).abs() < 5.0 * end_noise * u,
                    "{name} {i}: interval end {end} against {gum_end}"
                );
            }
        }
    }
}

/// [`agrees`] for e and for the heads' errors.
fn both_agree(
    mc: &SelfcalMonteCarlo,
    gum: &SelfcalUncertainty,
    solution: &SelfcalSolution,
    m: usize,
    normal: bool,
) {
    let e = &solution.encoder_error;
    agrees("e", &mc.encoder_error, &gum.encoder_error, e, m, normal);
    let heads: Vec<f64> = solution.head_error.iter().map(|h| h.value).collect();
    agrees("c", &mc.head_error, &gum.head_error, &heads, m, normal);
}

/// The balanced design (every head reads every position in every cycle), normal inputs on
/// every scope: the Monte Carlo's u and intervals are the GUM budget's within their noise
/// — for e and for the heads' errors, which a head's zero offset (gain 2 on c[j] − c[1])
/// dominates, while the table's errors (each position, each stop) reach neither — and
/// JCGM 101 §8 validates the GUM at one digit.
#[test]
fn balanced_design_monte_carlo_agrees_with_the_gum_budget() {
    let mut config = SelfcalSimConfig::default();
    config.positions = 72;
    config.cycles = 6;
    config.head_angles_deg = vec![0.0, 30.0, 60.0, 90.0, 150.0, 210.0];
    config.seed = 4;
    let (set, solution) = run(&config, &SelfcalOptions::new());
    assert!(solution.dof > 1000, "dof {}", solution.dof);
    let budget = InstrumentBudget::from_toml_str(NORMAL_BUDGET, "normal.toml").unwrap();
    let gum = selfcal::evaluate_budget(&solution, &budget).unwrap();
    // the heads' zero offsets dominate their errors' u_c
    let offset = &gum.components[1];
    assert!(offset.head_error[0] > 0.7 * gum.head_error.u[0]);
    assert_eq!(
        offset.encoder_error.iter().copied().fold(0.0, f64::max),
        0.0
    );
    let m = 200_000;
    let options = McOptions::new(Trials::Fixed(m))
        .with_seed(6)
        .with_significant_digits(1);
    let mc = selfcal::monte_carlo(&set, &solution, &budget, &gum, &options).unwrap();
    assert_eq!((mc.trials, mc.reading_noise), (m, "t"));
    assert!(mc.validated, "JCGM 101 §8 at one digit");
    both_agree(&mc, &gum, &solution, m, true);
    // the same seed gives the same numbers
    let again = selfcal::monte_carlo(&set, &solution, &budget, &gum, &options).unwrap();
    assert_eq!(mc, again);
}

/// A layout that loses harmonics, with a bound on them and an uncertainty of the heads'
/// angles: the Monte Carlo draws each lost harmonic with a random phase and the angles'
/// contributions, and its u is the GUM's (whose components are then not normal: the
/// intervals are not compared).
#[test]
fn lost_harmonics_and_head_angles_are_drawn_as_the_gum_states_them() {
    let mut config = SelfcalSimConfig::default();
    config.positions = 24;
    config.cycles = 8;
    config.head_angles_deg = vec![0.0, 90.0, 180.0, 270.0];
    config.seed = 2;
    let options = SelfcalOptions::new()
        .with_lost_harmonic_bound(0.03)
        .unwrap()
        .with_head_angle_u(2.0)
        .unwrap();
    let (set, solution) = run(&config, &options);
    assert!(!solution.lost_harmonics.is_empty());
    let lost_u = solution.lost_harmonic_u.unwrap();
    let type_a = solution.encoder_error_u_type_a.as_ref().unwrap();
    assert!(
        lost_u > type_a[0],
        "the bound matters: {lost_u} against {}",
        type_a[0]
    );
    let budget = InstrumentBudget::from_toml_str(NORMAL_BUDGET, "normal.toml").unwrap();
    let gum = selfcal::evaluate_budget(&solution, &budget).unwrap();
    let m = 100_000;
    let mc = selfcal::monte_carlo(
        &set,
        &solution,
        &budget,
        &gum,
        &McOptions::new(Trials::Fixed(m)).with_seed(3),
    )
    .unwrap();
    both_agree(&mc, &gum, &solution, m, false);
}

/// Heads between the positions (97° on 36 positions: 9.7 positions), normal inputs on
/// every scope: the trials are solved by the band-limited closure the fit uses, and the
/// Monte Carlo's u and intervals are the GUM budget's within their noise, e and heads'
/// errors alike; the table's errors reach neither here either.
#[test]
fn heads_off_the_grid_agree_with_the_gum_budget() {
    let mut config = SelfcalSimConfig::default();
    config.positions = 36;
    config.cycles = 20;
    config.head_angles_deg = vec![0.0, 97.0, 180.0, 250.0];
    config.seed = 8;
    let (set, solution) = run(&config, &SelfcalOptions::new());
    assert_eq!(solution.grid, selfcal::HeadGrid::OffGrid);
    assert!(solution.dof > 1000, "dof {}", solution.dof);
    let budget = InstrumentBudget::from_toml_str(NORMAL_BUDGET, "normal.toml").unwrap();
    let gum = selfcal::evaluate_budget(&solution, &budget).unwrap();
    let m = 200_000;
    let options = McOptions::new(Trials::Fixed(m))
        .with_seed(2)
        .with_significant_digits(1);
    let mc = selfcal::monte_carlo(&set, &solution, &budget, &gum, &options).unwrap();
    assert_eq!(mc.trials, m);
    both_agree(&mc, &gum, &solution, m, true);
    assert!(mc.validated, "JCGM 101 §8 at one digit");
}
