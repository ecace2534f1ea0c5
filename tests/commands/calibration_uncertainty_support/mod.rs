//! What the tests of the calibration results' uncertainty
//! (`tests/commands/calibration_uncertainty_*.rs`) share: the noisy readings of the paper's
//! two-autocollimator design and their solution, a budget of one component, a relative
//! comparison, and a Monte Carlo evaluation with the propagated u_c it is checked against.

use crate::common::{Stream, Truth, readings};
use polycal::measurement::MeasurementSet;
use polycal::measurement::Sigma;
use polycal::solve::{self, Method, Solution, SolveOptions};
use polycal::uncertainty::calibration::{
    self, CalibrationUncertainty, InstrumentBudget, McOptions, McSolver, Scope, ScopedComponent,
};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::monte_carlo::Trials;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution as _, Normal};

pub const PAIR: [Stream; 2] = [(1, 1, 0, 0.4), (1, 2, 1, -0.7)];

pub fn truth(n: usize) -> Truth {
    let beta: Vec<f64> = (0..n).map(|k| (k as f64 * 1.3).sin() * 0.6).collect();
    let alpha: Vec<f64> = (0..n)
        .map(|p| (2.0 * std::f64::consts::PI * p as f64 / n as f64 + 0.3).sin() * 0.5)
        .collect();
    Truth::closed(&beta, &alpha)
}

/// Noisy readings of the two-autocollimator design.
pub fn design(n: usize, cycles: u32, closing: bool, seed: u64) -> MeasurementSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.05).unwrap();
    readings(&truth(n), &PAIR, cycles, closing, || noise.sample(&mut rng))
}

pub fn solved(set: &MeasurementSet, method: Method, sigma: Option<f64>) -> Solution {
    solve::solve(
        set,
        &SolveOptions::new()
            .with_method(method)
            .with_sigma_opt(sigma.map(|s| Sigma::new(s).unwrap())),
    )
    .unwrap()
}

pub fn one(distribution: Distribution, scope: Scope) -> InstrumentBudget {
    InstrumentBudget::new(vec![ScopedComponent::type_b("x", distribution, scope)])
}

pub fn close(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() <= tolerance * b.abs().max(1e-300)
}

/// u_c of Monte Carlo: the propagated variance, with the type A part inflated to the
/// variance of the multivariate t noise, ν/(ν − 2), when σ comes from the residuals.
pub fn propagated_u(unc: &CalibrationUncertainty, family: usize, j: usize) -> f64 {
    let f = unc.families()[family].1;
    let inflation = unc.type_a_dof.map_or(1.0, |nu| nu / (nu - 2.0));
    (f.u_a[j].powi(2) * inflation + f.u[j].powi(2) - f.u_a[j].powi(2)).sqrt()
}

pub fn mc(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
    trials: usize,
    seed: u64,
    solver: McSolver,
) -> (CalibrationUncertainty, calibration::CalibrationMonteCarlo) {
    let unc = calibration::evaluate(set, solution, budget).unwrap();
    let options = McOptions::new(Trials::Fixed(trials))
        .with_seed(seed)
        .with_significant_digits(2)
        .with_solver(solver);
    let result = calibration::monte_carlo(set, solution, budget, &unc, &options).unwrap();
    (unc, result)
}
