//! Unit tests of the trial model.

use rand::SeedableRng;

use super::*;
use crate::solve::{SolveOptions, solve};
use crate::uncertainty::calibration::ScopedComponent;
use crate::uncertainty::calibration::test_support::set;
use crate::uncertainty::monte_carlo::{self, EngineOptions, Trials};

/// The closed-form trial and the least-squares trial solve the same targets alike.
#[test]
fn closed_form_and_least_squares_trials_agree() {
    let s = set(24, 2, false, 9);
    let solution = solve(&s, &SolveOptions::default()).unwrap();
    let budget = InstrumentBudget::new(vec![
        ScopedComponent::type_b(
            "r",
            Distribution::Rectangular { half_width: 0.1 },
            Scope::EachStop,
        ),
        ScopedComponent::type_b("n", Distribution::Normal { u: 0.1 }, Scope::EachReading),
    ]);
    let cf = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
    let ls = McModel::new(&s, &solution, &budget, McSolver::LeastSquares).unwrap();
    assert_eq!((cf.solver_name(), ls.solver_name()), ("closed-form", "lsq"));
    let mut scratch = cf.scratch();
    let mut out = vec![0.0; cf.outputs()];
    scratch.targets.copy_from_slice(&cf.base);
    assert!(cf.solve(&mut scratch, &mut out));
    for (a, b) in out.iter().zip(cf.estimates()) {
        assert!((a - b).abs() < 1e-12, "{a} {b}");
    }
    let mut ls_scratch = ls.scratch();
    let mut ls_out = vec![0.0; ls.outputs()];
    ls_scratch.targets.copy_from_slice(&ls.base);
    assert!(ls.solve(&mut ls_scratch, &mut ls_out));
    for (a, b) in ls_out.iter().zip(ls.estimates()) {
        assert!((a - b).abs() < 1e-12, "{a} {b}");
    }
}

/// The instrument budget on the paper's bare cycle: the two rectangular errors of
/// each reading become one trapezoid per target, in order; the zero offset of each
/// autocollimator, which reaches no result, is not drawn; the encoder's error of each
/// position remains.
#[test]
fn instrument_budget_draws() {
    let s = set(24, 1, false, 4);
    let solution = solve(
        &s,
        &SolveOptions::new().with_sigma(crate::measurement::Sigma::new(0.05).unwrap()),
    )
    .unwrap();
    let budget = InstrumentBudget::read_path("examples/budgets/instrument.toml").unwrap();
    let model = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
    assert_eq!(model.solver_name(), "closed-form");
    assert_eq!(model.trapezoids.len(), 48);
    assert_eq!(model.trapezoid_starts, (0..=48).collect::<Vec<_>>());
    assert!(model.one_trapezoid_each);
    assert_eq!(model.plans.len(), 1);
    assert!(matches!(model.plans[0].sampler, Sampler::Rectangular(a) if a == 0.02));
    assert_eq!(model.plans[0].spread.groups(), 24);
    // With least squares the same: the offset is absorbed by the setup errors there
    // too.
    let lsq = McModel::new(&s, &solution, &budget, McSolver::LeastSquares).unwrap();
    assert_eq!((lsq.trapezoids.len(), lsq.plans.len()), (48, 1));
}

/// Least squares draws one sum per cell (here 24 positions × 2 autocollimators over
/// three cycles, each cycle's closing readings in the cells of position 0): each
/// sum's noise variance is its number of readings; the vector units draw the same
/// bits as the portable code.
#[test]
fn least_squares_draws_the_sums_per_cell() {
    let s = set(24, 3, true, 4);
    let solution = solve(&s, &SolveOptions::default()).unwrap();
    let budget = InstrumentBudget::read_path("examples/budgets/instrument.toml").unwrap();
    let model = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
    assert_eq!(model.solver_name(), "lsq");
    assert_eq!((model.targets(), s.readings.len()), (48, 150));
    let mut counts = vec![0.0; 48];
    counts[..2].fill(6.0);
    counts[2..].fill(3.0);
    assert_eq!(model.noise_var, counts);
    // 150 readings' trapezoids, six or three per cell, in cell order
    assert_eq!(model.trapezoids.len(), 150);
    assert_eq!(model.trapezoid_starts[..4], [0, 6, 12, 15]);
    assert!(!model.one_trapezoid_each);
    let (mut a, mut b) = (model.scratch(), model.scratch());
    let (mut rng_a, mut rng_b) = (
        rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9),
        rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9),
    );
    for _ in 0..100 {
        model.sample(&mut rng_a, &mut a);
        model.sample_portable(&mut rng_b, &mut b);
        assert_eq!(a.targets, b.targets);
        assert_eq!(a.offsets, b.offsets);
    }
}

/// The calibration trial on the engine: the summary of every trial without storing
/// them is the summary of the stored trials, for 9 positions (fixed and adaptive), 24
/// (the paper's polygon, closing readings: least squares, stages after a pilot of J)
/// and for 1440 positions (4319 outputs: a pilot shorter than `J`, brackets refined
/// at every doubling of the trials).
#[test]
fn the_engine_summarizes_every_trial() {
    let adaptive = Trials::Adaptive {
        significant_digits: 1,
        max_trials: 500_000,
    };
    for (faces, trials) in [
        (9, Trials::Fixed(34_500)),
        (9, adaptive),
        (24, Trials::Fixed(25_000)),
        (1440, Trials::Fixed(9_000)),
    ] {
        the_engine_summarizes(faces, trials);
    }
}

fn the_engine_summarizes(faces: usize, trials: Trials) {
    let s = set(faces, 2, true, 5);
    let solution = solve(&s, &SolveOptions::default()).unwrap();
    let budget = InstrumentBudget::new(vec![
        ScopedComponent::type_b(
            "r",
            Distribution::Rectangular { half_width: 0.2 },
            Scope::Result,
        ),
        ScopedComponent::type_b(
            "each stop",
            Distribution::Rectangular { half_width: 0.05 },
            Scope::EachStop,
        ),
    ]);
    let model = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
    {
        let options = EngineOptions::new(trials).with_seed(11);
        let summary = monte_carlo::run(&model, &options).unwrap();
        let kept = monte_carlo::run(&model, &options.with_samples(true)).unwrap();
        let m = summary.trials;
        let (r_low, r_high) = monte_carlo::symmetric_interval_positions(m, 0.95);
        let samples = kept.samples.unwrap();
        assert_eq!(samples.len(), model.outputs());
        for (j, column) in samples.iter().enumerate() {
            let mut column = column.clone();
            column.sort_unstable_by(f64::total_cmp);
            let y = summary.outputs[j];
            assert_eq!(y.low, column[r_low]);
            assert_eq!(y.high, column[r_high]);
            let mean = column.iter().sum::<f64>() / m as f64;
            let ss = column.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
            let u = (ss / (m - 1) as f64).sqrt();
            assert!((y.mean - mean).abs() < 1e-12);
            assert!((y.u - u).abs() < 1e-12 * u);
        }
    }
}
