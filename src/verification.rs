//! The paper's verification reproduced from a simulated truth (its section 3.1 and
//! Figs. 4–7): one truth — a polygon and an encoder whose error has harmonics up to a
//! high order — measured three ways, each evaluated with its uncertainty, and compared
//! as the paper does (En, ISO 13528):
//!
//! - **two autocollimators** (the paper's method: faces p+1 and p+2 read at step p,
//!   `cycles` cycles with closing readings);
//! - **the shift-angle method** (cross-calibration: the polygon remounted at every
//!   whole-face shift, read by one autocollimator);
//! - **self-calibration** of the encoder with several read heads (SelfA by default) at
//!   P positions, P a multiple of N, so that it shares the polygon's N angles.
//!
//! β of the two-autocollimator method is compared with the shift-angle method's (face by
//! face) and α with the self-calibration's (by angle, the self-calibration in the gauge of
//! the N-faced polygon: Σ = 0 over the N shared angles). Each method is also compared
//! with the truth as it can see it. The self-calibration cannot see the harmonics its
//! head layout loses (SelfA: multiples of 84); a bound on them
//! ([`VerificationConfig::lost_harmonic_bound_arcsec`]) puts that in its uncertainty.

use crate::compare::{CompareError, CompareOptions, Comparison, compare};
use crate::output::result_rows_with;
use crate::output::selfcal::result_rows as selfcal_rows;
use crate::results::{Quantity, ResultRow};
use crate::selfcal::{self, SelfcalOptions, SelfcalSolveError};
use crate::simulate::{
    SelfcalSimConfig, SimulateError, SimulationConfig, Truth, simulate_selfcal, simulate_with_truth,
};
use crate::solve::{SigmaSource, Solution, SolveError, SolveOptions, solve};
use crate::uncertainty::calibration::{CalibrationError, InstrumentBudget, evaluate};
use crate::uncertainty::student::t_quantile;

/// The three simulated measurements and how they are evaluated.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct VerificationConfig {
    /// Number of polygon faces N (24).
    pub faces: usize,
    /// Cycles of the two-autocollimator method (6, each with its closing reading).
    pub cycles: u32,
    /// Cycles per mounting of the shift-angle method (2); it has N mountings.
    pub mounting_cycles: u32,
    /// σ of an autocollimator reading, arcsec (0.05).
    pub noise_arcsec: f64,
    /// Spread of the drawn pitch deviations, arcsec (0.5).
    pub pitch_spread_arcsec: f64,
    /// The self-calibration: its positions (a multiple of N), heads, noise and the
    /// encoder's drawn error (orders 1 … `max_order`, amplitude a/√k with random phases),
    /// which is the truth of all three methods. Default: SelfA, 168 positions, 2 cycles,
    /// orders up to 150.
    pub selfcal: SelfcalSimConfig,
    /// The instrument budget of the polygon methods (the paper's Table 1, say); `None`:
    /// their type A with k from Student's t at 95 %.
    pub budget: Option<InstrumentBudget>,
    /// A bound on the amplitude of the harmonics the head layout cannot see, arcsec; the
    /// default is the envelope of the drawn spectrum at order 84 (a/√84), what a lab
    /// would take from the encoder's measured spectrum around it.
    pub lost_harmonic_bound_arcsec: Option<f64>,
    /// Seed of everything drawn.
    pub seed: u64,
}

impl Default for VerificationConfig {
    fn default() -> Self {
        let selfcal = SelfcalSimConfig {
            positions: 168,
            cycles: 2,
            max_order: 150,
            ..SelfcalSimConfig::default()
        };
        let envelope_84 = selfcal.drawn_amplitude_arcsec / 84f64.sqrt();
        VerificationConfig {
            faces: 24,
            cycles: 6,
            mounting_cycles: 2,
            noise_arcsec: 0.05,
            pitch_spread_arcsec: 0.5,
            selfcal,
            budget: None,
            lost_harmonic_bound_arcsec: Some(envelope_84),
            seed: 1,
        }
    }
}

/// One method checked against the truth it can see.
#[derive(Debug, Clone, PartialEq)]
pub struct AgainstTruth {
    /// The method.
    pub method: &'static str,
    /// What is checked (`pitch_deviation`, `encoder_error`).
    pub quantity: Quantity,
    /// Largest |estimate − truth|, arcsec.
    pub max_abs_error_arcsec: f64,
    /// Largest |estimate − truth|/U.
    pub max_abs_en: f64,
    /// How many values have |estimate − truth|/U > 1 (at 95 % coverage, about one in
    /// twenty by chance).
    pub beyond_one: usize,
    /// (estimate − truth)/u of every value.
    pub normalised_errors: Vec<f64>,
}

/// Two methods compared (En), with the differences normalised by their standard
/// uncertainties.
#[derive(Debug, Clone, PartialEq)]
pub struct Agreement {
    /// What is compared, for people.
    pub label: &'static str,
    /// The comparison (rows, En, max |En|).
    pub comparison: Comparison,
    /// Largest |a − b|, arcsec.
    pub max_abs_difference_arcsec: f64,
    /// (a − b)/√(u_a² + u_b²) of every compared value.
    pub normalised_differences: Vec<f64>,
}

/// The outcome of [`verify`].
#[derive(Debug, Clone, PartialEq)]
pub struct Verification {
    /// β: two autocollimators against the shift-angle method.
    pub pitch_deviation: Agreement,
    /// α: two autocollimators against the self-calibration, at the shared angles.
    pub encoder_error: Agreement,
    /// Every method against the truth.
    pub truth: Vec<AgainstTruth>,
    /// Harmonic orders the self-calibration's head layout cannot see.
    pub lost_harmonics: Vec<usize>,
    /// Highest order of the encoder's true error.
    pub max_order: usize,
}

impl Verification {
    /// Whether every method agrees with the truth and the comparisons agree: every
    /// |En| ≤ 1.
    pub fn all_agree(&self) -> bool {
        self.pitch_deviation.comparison.max_abs_en <= 1.0
            && self.encoder_error.comparison.max_abs_en <= 1.0
            && self.truth.iter().all(|t| t.max_abs_en <= 1.0)
    }
}

/// Why the verification could not be run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VerificationError {
    /// A simulation was refused.
    #[error(transparent)]
    Simulate(#[from] SimulateError),
    /// A polygon method could not be solved.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The self-calibration could not be solved.
    #[error(transparent)]
    Selfcal(#[from] SelfcalSolveError),
    /// The budget could not be evaluated.
    #[error(transparent)]
    Uncertainty(#[from] CalibrationError),
    /// The comparison was refused.
    #[error(transparent)]
    Compare(#[from] CompareError),
    /// The self-calibration's positions are not a multiple of the polygon's faces.
    #[error("the self-calibration's {positions} positions are not a multiple of the {faces} faces")]
    Positions {
        /// P.
        positions: usize,
        /// N.
        faces: usize,
    },
}

/// Draws the truth, measures it three ways, evaluates and compares (module
/// documentation).
///
/// ```
/// use polycal::verification::{verify, VerificationConfig};
/// let outcome = verify(&VerificationConfig::default())?;
/// assert_eq!(outcome.lost_harmonics, [84]);
/// assert_eq!(outcome.encoder_error.comparison.rows.len(), 24); // the shared angles
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// [`VerificationError`]: settings a simulation refuses, or a P that is not a multiple
/// of N.
pub fn verify(config: &VerificationConfig) -> Result<Verification, VerificationError> {
    let n = config.faces;
    let mut selfcal_config = config.selfcal.clone();
    selfcal_config.seed = config.seed;
    if !selfcal_config.positions.is_multiple_of(n) {
        return Err(VerificationError::Positions {
            positions: selfcal_config.positions,
            faces: n,
        });
    }
    // the encoder's truth, a continuous function of angle, shared by the three methods
    let (selfcal_set, selfcal_truth) = simulate_selfcal(&selfcal_config)?;
    let polygon_config = SimulationConfig {
        faces: n,
        ac_faces: vec![1, 2],
        setups: 1,
        setup_shift_faces: 0,
        cycles: config.cycles,
        closing: true,
        noise_arcsec: config.noise_arcsec,
        pitch_spread_arcsec: config.pitch_spread_arcsec,
        encoder_harmonics: selfcal_truth.encoder_harmonics.clone(),
        seed: config.seed,
        ..SimulationConfig::default()
    };
    let truth = Truth::draw(&polygon_config)?;
    let two_ac_set = simulate_with_truth(&polygon_config, &truth)?;
    let shift_config = SimulationConfig {
        ac_faces: vec![1],
        setups: n as u32,
        setup_shift_faces: 1,
        cycles: config.mounting_cycles,
        closing: false,
        seed: config.seed.wrapping_add(1),
        ..polygon_config.clone()
    };
    let shift_set = simulate_with_truth(&shift_config, &truth)?;

    let options = SolveOptions::new();
    let two_ac = solve(&two_ac_set, &options)?;
    let shift = solve(&shift_set, &options)?;
    let polygon_rows = |set, solution: &Solution| -> Result<Vec<ResultRow>, VerificationError> {
        Ok(match &config.budget {
            Some(budget) => result_rows_with(solution, Some(&evaluate(set, solution, budget)?)),
            None => type_a_rows(solution),
        })
    };
    let two_ac_rows = polygon_rows(&two_ac_set, &two_ac)?;
    let shift_rows = polygon_rows(&shift_set, &shift)?;

    let mut selfcal_options = SelfcalOptions::new().with_gauge_positions(n);
    if let Some(bound) = config.lost_harmonic_bound_arcsec {
        selfcal_options = selfcal_options.with_lost_harmonic_bound(bound)?;
    }
    let selfcal_solution = selfcal::solve(&selfcal_set, &selfcal_options)?;
    let selfcal_result = selfcal_rows(&selfcal_solution, None);

    let family = |rows: &[ResultRow], quantity| -> Vec<ResultRow> {
        rows.iter()
            .filter(|r| r.quantity == quantity)
            .cloned()
            .collect()
    };
    let pitch_deviation = agreement(
        "β: two autocollimators vs shift-angle method",
        &family(&two_ac_rows, Quantity::PitchDeviation),
        &family(&shift_rows, Quantity::PitchDeviation),
    )?;
    let encoder_error = agreement(
        "α: two autocollimators vs self-calibration (shared angles)",
        &family(&two_ac_rows, Quantity::EncoderError),
        &selfcal_result,
    )?;

    // the truths: β and α of the polygon run, e of the disc in the gauge of N angles
    let p = selfcal_config.positions;
    let stride = p / n;
    let shared_mean = (0..p)
        .step_by(stride)
        .map(|x| selfcal_truth.encoder_error[x])
        .sum::<f64>()
        / n as f64;
    let disc_truth: Vec<f64> = selfcal_truth
        .encoder_error
        .iter()
        .map(|e| e - shared_mean)
        .collect();
    let against = |method, quantity, rows: &[ResultRow], truth: &[f64]| {
        let rows: Vec<&ResultRow> = rows.iter().filter(|r| r.quantity == quantity).collect();
        let index = |r: &ResultRow| match quantity {
            Quantity::PitchDeviation => r.index as usize - 1,
            _ => r.index as usize,
        };
        let errors: Vec<f64> = rows.iter().map(|r| r.value - truth[index(r)]).collect();
        AgainstTruth {
            method,
            quantity,
            max_abs_error_arcsec: errors.iter().fold(0.0, |m, e| m.max(e.abs())),
            max_abs_en: rows
                .iter()
                .zip(&errors)
                .map(|(r, e)| (e / r.expanded_u.unwrap_or(f64::NAN)).abs())
                .fold(0.0, f64::max),
            beyond_one: rows
                .iter()
                .zip(&errors)
                .filter(|(r, e)| (*e / r.expanded_u.unwrap_or(f64::NAN)).abs() > 1.0)
                .count(),
            normalised_errors: rows
                .iter()
                .zip(&errors)
                .map(|(r, e)| e / r.u.unwrap_or(f64::NAN))
                .collect(),
        }
    };
    let truth_checks = vec![
        against(
            "two autocollimators",
            Quantity::PitchDeviation,
            &two_ac_rows,
            &truth.pitch_deviation,
        ),
        against(
            "two autocollimators",
            Quantity::EncoderError,
            &two_ac_rows,
            &truth.encoder_error,
        ),
        against(
            "shift-angle method",
            Quantity::PitchDeviation,
            &shift_rows,
            &truth.pitch_deviation,
        ),
        against(
            "self-calibration",
            Quantity::EncoderError,
            &selfcal_result,
            &disc_truth,
        ),
    ];
    Ok(Verification {
        pitch_deviation,
        encoder_error,
        truth: truth_checks,
        lost_harmonics: selfcal_solution.lost_harmonics,
        max_order: selfcal_truth
            .encoder_harmonics
            .iter()
            .map(|h| h.order)
            .max()
            .unwrap_or(0),
    })
}

/// Result rows with the fit's type A: u, k = Student's t at 95 % for the residual dof
/// (∞ for a stated σ), U = k·u.
fn type_a_rows(solution: &Solution) -> Vec<ResultRow> {
    let k = match solution.sigma {
        Some((_, SigmaSource::Residual)) => t_quantile(0.95, Some(solution.dof as f64)),
        _ => t_quantile(0.95, None),
    };
    result_rows_with(solution, None)
        .into_iter()
        .filter(|r| r.quantity != Quantity::FaceDeviation)
        .map(|r| match r.u {
            Some(u) => r.with_k(k).with_expanded_u(k * u),
            None => r,
        })
        .collect()
}

fn agreement(
    label: &'static str,
    a: &[ResultRow],
    b: &[ResultRow],
) -> Result<Agreement, VerificationError> {
    let comparison = compare(a, b, &CompareOptions::new())?;
    let max_abs_difference_arcsec = comparison
        .rows
        .iter()
        .fold(0.0f64, |m, r| m.max(r.difference.abs()));
    let u_of = |rows: &[ResultRow], quantity: Quantity, index: u32| {
        rows.iter()
            .find(|r| r.quantity == quantity && r.index == index)
            .and_then(|r| r.u)
            .unwrap_or(f64::NAN)
    };
    let normalised_differences = comparison
        .rows
        .iter()
        .map(|r| {
            let ua = u_of(a, r.quantity, r.index);
            let ub = u_of(b, r.quantity, r.index_b.unwrap_or(r.index));
            r.difference / ua.hypot(ub)
        })
        .collect();
    Ok(Agreement {
        label,
        comparison,
        max_abs_difference_arcsec,
        normalised_differences,
    })
}
