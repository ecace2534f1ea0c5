//! Uncertainty of the calibration results: the fit's covariance (type A) combined with
//! the instrument's type-B budget, per quantity and from the actual design (GUM), and the
//! same propagated by Monte Carlo through the solver (GUM Supplement 1, JCGM 101:2008).
//!
//! # The propagation (GUM)
//!
//! The solver is linear in the readings: θ̂ = L y with θ = [β (N), α (N), U (K),
//! effects (E)], and for independent readings of equal weight Cov(θ̂) = σ² Q with
//! Q = L Lᵀ the fit's cofactor matrix
//! ([`Solution::cofactor`](crate::solve::Solution::cofactor)); L = Q Xᵀ with X the design
//! matrix of the model, so L is built from Q without solving again. The effect terms of
//! a model with effects (the final model of [`crate::diagnose`]) are columns of X like
//! the others ([`Solution::effect_regressors`](crate::solve::Solution::effect_regressors)):
//! the results are those of that model, and so are their uncertainties. A type-B component is an error of the
//! readings; its *scope* says which readings share one draw of it. If the readings of
//! group g share the error e_g (standard uncertainty u, independent between groups),
//! quantity j moves by Σ_g e_g Σ_{i∈g} L_ji and receives
//!
//! ```text
//! u_j² = u² · G_j,   G_j = Σ_g (Σ_{i∈g} L_ji)²
//! ```
//!
//! | `acts_on` | one draw shared by | G_j |
//! |---|---|---|
//! | `each-reading` | one reading (resolution, an angle error varying from reading to reading) | Q_jj, the same pattern as the noise |
//! | `each-autocollimator` | all readings of one autocollimator (a constant offset) | 0 for β, φ and α: the setup error absorbs it (computed, not assumed) |
//! | `each-position` | all readings at one table position p = step mod N, in every cycle | (1 − 1/N) for α, 0 for β and φ |
//! | `each-stop` | the readings of one stop of the table (setup, cycle, step) | (1 − 1/N)/R for α with R cycles of the paper's design |
//! | `result` (default) | nothing: added directly to every quantity, as the paper's Table 1 does | 1 (0 for the reference face φ\[N\]) |
//!
//! u_c,j² = u_A,j² + Σ_B u_B² G_B,j with u_A,j = σ√Q_jj the fit's type A, and the
//! effective degrees of freedom by Welch–Satterthwaite, ν_eff = u_c⁴ / (u_A⁴/ν_A + Σ
//! u_B,j⁴/ν_B), with ν_A the fit's residual degrees of freedom (infinite for a stated σ);
//! k = t_p(ν_eff) under the budget's `dof_policy`, U = k·u_c ([`evaluate`]).
//!
//! # Known corrections
//!
//! A correction applied to the readings with a coefficient known to a standard
//! uncertainty u ([`KnownCorrection`]; a cross-talk coefficient C stated from an
//! autocollimator's calibration is one, its readings corrected by C·`reading_y`) is one
//! more type-B component: the error e of the coefficient moves reading i by e·wᵢ, w the
//! correction's column, one draw shared by every reading, so quantity j receives
//! u·|Σᵢ L_ji wᵢ| with infinite degrees of freedom ([`evaluate_with_corrections`]); the
//! Monte Carlo draws e once per trial, normal ([`monte_carlo_with_corrections`]).
//!
//! # The budget file
//!
//! The budget file of docs/FORMAT.md §5 with one more key per component, `acts_on` (above;
//! default `"result"`). On a nested component it is the default of its components.
//! The fit supplies the type A uncertainty of the readings (repeatability) from its
//! residuals: the budget lists the instrument's other sources. See
//! `examples/budgets/instrument.toml` and [`InstrumentBudget`].
//!
//! # Monte Carlo
//!
//! [`monte_carlo`] draws, per trial, the readings as the fitted model plus noise plus the
//! type-B errors (each drawn from its distribution with its scope), solves them, and adds
//! the `result` components to the outputs. The noise is normal with the stated σ, or,
//! when σ comes from the residuals with ν degrees of freedom, normal with a standard
//! deviation drawn per trial as s·√(ν/χ²_ν) — the multivariate t of a regression
//! (JCGM 101 §6.4.9 for the mean of repeated indications, generalised), which is what
//! the GUM's t factor with ν_A = ν assumes. Each trial is solved with the paper's closed
//! form (generic over `Const<N>` for the usual N, no heap) when the design is the
//! paper's, and with the least-squares solution operator θ = Q Xᵀ y otherwise. Results
//! per quantity: mean, standard uncertainty, the probabilistically symmetric coverage
//! interval, and the validation of the GUM interval (JCGM 101 §8).
//!
//! The draws follow the model's structure, which is linear: a normal error of each
//! reading is folded into the noise (one normal draw per target), two rectangular errors
//! of each reading are drawn as their sum, a trapezoid, from one uniform number, an error
//! shared by a group of readings is drawn once per group, and an error that reaches no
//! result (an offset the setup errors absorb) is not drawn at all.
//!
//! The trials run on the crate's one Monte Carlo engine
//! ([`crate::uncertainty::monte_carlo::run`], with [`McModel`] as its
//! [`Trial`](crate::uncertainty::monte_carlo::Trial)): blocks of
//! [`BLOCK_SIZE`](crate::uncertainty::monte_carlo::BLOCK_SIZE) trials, block b drawing
//! from its own stream ([`block_rng`](crate::uncertainty::monte_carlo::block_rng):
//! xoshiro256++ lanes seeded from ChaCha8 stream b of `seed`), spread over rayon's
//! threads and combined in block order, so the same seed gives the same numbers whatever
//! the number of threads. The coverage interval is exact (the order statistics of all M
//! trials, as a full sort would give) without storing every trial.
//! [`McOptions::with_progress`] reports the trials done after every block, for a
//! progress bar.
//!
//! # Files
//!
//! - `budget.rs`: scopes ([`Scope`], `acts_on`) and the instrument budget file
//!   ([`InstrumentBudget`]);
//! - `operator.rs`: the solution operator L = Q Xᵀ and the gains G_j of a scope;
//! - `gum.rs`: the GUM propagation ([`evaluate`], [`CalibrationUncertainty`]);
//! - `trial.rs`: the Monte Carlo trial model ([`McModel`]), and `draws.rs`: how it
//!   draws the budget's errors (per group, two rectangles as one trapezoid, in bulk);
//! - `mc.rs`: the Monte Carlo run and its validation of the GUM result ([`monte_carlo`],
//!   [`McOptions`], [`CalibrationMonteCarlo`]).

mod budget;
mod draws;
mod gum;
mod mc;
mod operator;
mod trial;

pub use budget::{InstrumentBudget, Scope, ScopedComponent};
pub use gum::{
    CalibrationUncertainty, ComponentContribution, FamilyUncertainty, KnownCorrection, evaluate,
    evaluate_with_corrections,
};
pub(crate) use gum::{Combined, combine};
pub use mc::{
    CalibrationMonteCarlo, McFamily, McOptions, monte_carlo, monte_carlo_with_corrections,
};
pub(crate) use trial::{CellMap, CellRoute};
pub use trial::{McModel, McScratch, McSolver};

use super::monte_carlo::McError;

/// Why the uncertainty of a calibration cannot be evaluated.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationError {
    /// No σ: the fit is exactly determined and none was stated.
    #[error(
        "the fit is exactly determined (dof = 0) and no reading noise was stated, so the type A \
         uncertainty is unknown: state the standard deviation of one reading"
    )]
    NoSigma,
    /// The solution is not the solution of this measurement set.
    #[error("the solution does not belong to the measurement set: {0}")]
    Mismatch(String),
    /// The coverage probability is not within 0.5 … 0.9999 (docs/FORMAT.md §2.2).
    #[error("coverage probability p must be within 0.5 … 0.9999 (docs/FORMAT.md §2.2), got {0}")]
    Coverage(f64),
    /// A component is invalid.
    #[error("component {name:?}: {problem}")]
    Component {
        /// Its name.
        name: String,
        /// What is wrong.
        problem: crate::uncertainty::ComponentError,
    },
    /// ⌊ν_eff⌋ < 1 under the floor policy.
    #[error(
        "{quantity} {index}: effective degrees of freedom {dof} round down to 0: no t factor; \
         use dof_policy = \"fractional\""
    )]
    FloorBelowOne {
        /// The quantity.
        quantity: crate::results::Quantity,
        /// Its index (face, position or stream).
        index: usize,
        /// ν_eff.
        dof: f64,
    },
    /// The Monte Carlo run failed.
    #[error(transparent)]
    MonteCarlo(#[from] McError),
    /// The set has shifted mountings (a `shift` other than 0), which the propagation
    /// through the design does not handle yet.
    #[error(
        "the uncertainty budget does not handle shifted mountings (a mounting whose shift is \
         not 0) yet"
    )]
    ShiftedMountings,
}

#[cfg(test)]
pub(crate) mod test_support {
    //! Measurement sets for the unit tests of the calibration uncertainty.

    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution as _, StandardNormal};

    use crate::measurement::{Direction, MeasurementSet, Reading};

    /// Two autocollimators one face apart, `cycles` cycles of `n` steps (one more with
    /// `closing`), smooth readings with noise 0.1.
    pub(crate) fn set(n: usize, cycles: u32, closing: bool, seed: u64) -> MeasurementSet {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut readings = Vec::new();
        for cycle in 1..=cycles {
            for step in 0..(if closing { n + 1 } else { n }) {
                for (ac, d) in [(1u32, 0usize), (2, 1)] {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    readings.push(Reading {
                        setup: 1,
                        cycle,
                        step,
                        ac,
                        face: (step + d) % n + 1,
                        reading_arcsec: (step as f64 * 0.7).sin() + 0.3 * d as f64 + 0.1 * z,
                        direction: Direction::Cw,
                        time_seconds: None,
                        reading_y_arcsec: None,
                        temperature_celsius: None,
                        encoder_degrees: None,
                        line: 0,
                    });
                }
            }
        }
        MeasurementSet {
            faces: n,
            readings,
            source: "test".into(),
            setup_shift_deg: Default::default(),
        }
    }
}
