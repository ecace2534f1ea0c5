//! Least squares for any design: the one place that decides which engine solves it.
//!
//! Unknowns: α\[0..N) (Σα = 0), φ[1..N−1\] (φ\[N\] = 0, so Σβ = 0), one setup error U per
//! (setup, ac) stream, and optional effect terms (extra regressor columns). The decision:
//!
//! 1. the design is planned ([`super::circulant`]): a position nobody reads, or harmonics
//!    the face offsets cannot see ([`super::lost_harmonics`]), are refused at once;
//! 2. when every stream reads most positions equally often and the cells that differ
//!    plus the effect terms are few (at most a quarter of the unknowns), the circulant
//!    engine solves it in O(N log N + (2N + K)·r);
//! 3. otherwise — or when its corrections turn out singular, so that what is lost must be
//!    named — the dense reference ([`super::dense`]).
//!
//! Sub-pitch mountings ([`super::sub_pitch`]) are tried on the coset engine first
//! ([`super::coset`], by the same rule: a regular part in every coset and few
//! corrections), and otherwise fitted with their cosets' differences as effect columns
//! by the decision above.
//!
//! Before any engine allocates, its memory is estimated and a design that does not
//! fit is refused ([`SolveError::TooLarge`]). [`Solution::engine`] says which one ran.

use super::circulant::{self, Plan};
use super::coset;
use super::dense::{check_regressors, dense_bytes_needed, dense_least_squares_observed};
use super::observability::describe;
use super::shift_geometry::ShiftGeometry;
use super::{Solution, SolveError, SolveOptions, memory};
use crate::measurement::{MeasurementSet, Sigma};
use crate::progress::Progress;

/// Fits the base model (no effect terms) by least squares.
///
/// `stated_sigma` is the σ of one reading used for the covariance when dof = 0.
///
/// ```
/// use polycal::simulate::{simulate, SimulationConfig};
/// use polycal::solve::{least_squares, Engine};
///
/// // 360 positions, 6 cycles with closing readings: the circulant engine, rank 2
/// let config = SimulationConfig { faces: 360, closing: true, ..SimulationConfig::default() };
/// let (set, truth) = simulate(&config)?;
/// let solution = least_squares(&set, None)?;
/// assert_eq!(solution.engine, Engine::Circulant { low_rank: 2 });
/// let u = solution.encoder_error_u().unwrap();
/// for ((estimate, true_value), u) in solution.encoder_error.iter().zip(&truth.encoder_error).zip(&u) {
///     assert!((estimate - true_value).abs() < 5.0 * u);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn least_squares(
    set: &MeasurementSet,
    stated_sigma: Option<Sigma>,
) -> Result<Solution, SolveError> {
    least_squares_with_options(set, &[], &SolveOptions::new().with_sigma_opt(stated_sigma))
}

/// Fits the model with extra effect terms: reading += Σ_e value_e · `regressors[e][i]`.
///
/// Each regressor has one value per reading of `set`, in order. Returns the estimates,
/// their cofactor in the Σα = 0 gauge, residuals and degrees of freedom. A design (or an
/// effect term) that the data cannot determine is refused with
/// [`SolveError::Unobservable`], one too large for the machine's available memory with
/// [`SolveError::TooLarge`].
pub fn least_squares_with_regressors(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    stated_sigma: Option<Sigma>,
) -> Result<Solution, SolveError> {
    least_squares_with_options(
        set,
        regressors,
        &SolveOptions::new().with_sigma_opt(stated_sigma),
    )
}

/// [`least_squares_with_regressors`] with the options' stated σ and memory limit (the
/// options' method is not consulted: this is least squares).
pub fn least_squares_with_options(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    options: &SolveOptions,
) -> Result<Solution, SolveError> {
    least_squares_observed(set, regressors, options, None)
}

/// [`least_squares_with_options`] telling `progress` how far the dense reference is,
/// when it is the engine that runs (the circulant engine takes well under a second and
/// reports nothing).
pub(crate) fn least_squares_observed(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    options: &SolveOptions,
    progress: Option<&dyn Progress>,
) -> Result<Solution, SolveError> {
    check_regressors(set, regressors)?;
    let streams = set.streams();
    let n = set.faces;
    let (k, e) = (streams.len(), regressors.len());
    let refuse = |engine, needed_bytes| fits(set, k, e, engine, needed_bytes, options);
    match circulant::plan(set, &streams, e, false)? {
        Plan::Circulant(plan) if plan.is_cheaper_than_dense(n) => {
            refuse("circulant", plan.bytes_needed(n, set.readings.len()))?;
            if let Some(solution) =
                circulant::solve(set, &streams, &plan, regressors, options.sigma)?
            {
                return Ok(solution);
            }
        }
        Plan::Lost(harmonics) if refuse("dense", dense_bytes_needed(n, k, e)).is_err() => {
            // too large for the dense path to name more: what the offsets lose
            return Err(describe(harmonics, Vec::new(), set).into());
        }
        _ => {}
    }
    refuse("dense", dense_bytes_needed(n, k, e))?;
    dense_least_squares_observed(set, regressors, options.sigma, progress)
}

/// [`least_squares_with_options`] of a design `prepared` once
/// ([`circulant::Prepared::of`] of `set`): the same decision and the same numbers,
/// without planning the design and forming its regular cofactor again at every fit
/// (the diagnosis refits one design with each round's effect columns). `None` fits as
/// [`least_squares_with_options`].
pub(crate) fn least_squares_prepared(
    set: &MeasurementSet,
    prepared: Option<&circulant::Prepared>,
    regressors: &[Vec<f64>],
    options: &SolveOptions,
) -> Result<Solution, SolveError> {
    let Some(prepared) = prepared else {
        return least_squares_with_options(set, regressors, options);
    };
    check_regressors(set, regressors)?;
    let n = set.faces;
    let (k, e) = (prepared.streams().len(), regressors.len());
    let plan = prepared.plan(e);
    if plan.is_cheaper_than_dense(n) {
        circulant_fits(set, &plan, k, e, options)?;
        if let Some(solution) = prepared.solve(set, regressors, options.sigma)? {
            return Ok(solution);
        }
    }
    fits(set, k, e, "dense", dense_bytes_needed(n, k, e), options)?;
    dense_least_squares_observed(set, regressors, options.sigma, None)
}

/// Least squares of a set with sub-pitch mountings on the coset engine
/// ([`super::coset`]): the set in encoder `positions`
/// ([`ShiftGeometry::encoder_set`]) and its `geometry`. `Ok(None)` where the design's
/// structure breaks (the caller then fits the cosets' differences as effect columns); a
/// design the engine serves but whose memory does not fit is refused
/// ([`SolveError::TooLarge`]) before anything is allocated.
pub(crate) fn least_squares_on_cosets(
    positions: &MeasurementSet,
    geometry: &ShiftGeometry,
    options: &SolveOptions,
) -> Result<Option<Solution>, SolveError> {
    let streams = positions.streams();
    let Some(plan) = coset::plan(positions, geometry, &streams) else {
        return Ok(None);
    };
    if !plan.is_cheaper_than_dense() {
        return Ok(None);
    }
    let n = positions.faces;
    let effects = geometry.cosets().saturating_sub(1) * n.saturating_sub(1);
    fits(
        positions,
        streams.len(),
        effects,
        "coset-circulant",
        plan.bytes_needed(positions.readings.len()),
        options,
    )?;
    coset::solve(positions, &streams, &plan, options.sigma)
}

/// Least squares by the dense reference only ([`super::Method::Dense`]), refused when its
/// O((2N + K + E)²) memory does not fit.
pub fn dense_with_options(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    options: &SolveOptions,
) -> Result<Solution, SolveError> {
    dense_observed(set, regressors, options, None)
}

/// [`dense_with_options`] telling `progress` how far it is.
pub(crate) fn dense_observed(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    options: &SolveOptions,
    progress: Option<&dyn Progress>,
) -> Result<Solution, SolveError> {
    check_regressors(set, regressors)?;
    let k = set.streams().len();
    let e = regressors.len();
    fits(
        set,
        k,
        e,
        "dense",
        dense_bytes_needed(set.faces, k, e),
        options,
    )?;
    dense_least_squares_observed(set, regressors, options.sigma, progress)
}

/// Refuses a plan of `needed_bytes` for `engine` that exceeds the memory limit.
fn fits(
    set: &MeasurementSet,
    streams: usize,
    effects: usize,
    engine: &'static str,
    needed_bytes: u128,
    options: &SolveOptions,
) -> Result<(), SolveError> {
    match memory::limit_for(needed_bytes, options.memory_limit_bytes) {
        Some((limit_bytes, limit_source)) if needed_bytes > u128::from(limit_bytes) => {
            Err(SolveError::TooLarge {
                faces: set.faces,
                streams,
                effects,
                readings: set.readings.len(),
                engine,
                needed_bytes,
                limit_bytes,
                limit_source,
            })
        }
        _ => Ok(()),
    }
}

/// [`fits`] of the circulant engine's `plan` (`streams` streams, `effects` effect terms).
fn circulant_fits(
    set: &MeasurementSet,
    plan: &circulant::CirculantPlan,
    streams: usize,
    effects: usize,
    options: &SolveOptions,
) -> Result<(), SolveError> {
    let needed_bytes = plan.bytes_needed(set.faces, set.readings.len());
    fits(set, streams, effects, "circulant", needed_bytes, options)
}

/// Least squares of a design whose face offsets lose harmonics, with those harmonics of φ
/// set to zero instead of refused, on the circulant engine (self-calibration,
/// [`crate::selfcal`]: a head layout always loses some). Returns the solution and the
/// harmonics k in 1 … N−1 set to zero. A design the rule of the offsets does not cover
/// (no regular part, missing readings) is solved, or refused, as
/// [`least_squares_with_options`] does.
pub(crate) fn least_squares_zeroing_lost(
    set: &MeasurementSet,
    options: &SolveOptions,
) -> Result<(Solution, Vec<usize>), SolveError> {
    least_squares_zeroing_lost_with(set, &[], options)
}

/// [`least_squares_zeroing_lost`] with effect terms (as [`least_squares_with_options`]):
/// the diagnosis of a self-calibration fits its effect columns this way.
pub(crate) fn least_squares_zeroing_lost_with(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    options: &SolveOptions,
) -> Result<(Solution, Vec<usize>), SolveError> {
    check_regressors(set, regressors)?;
    let streams = set.streams();
    let (k, e) = (streams.len(), regressors.len());
    if let Plan::Circulant(plan) = circulant::plan(set, &streams, e, true)? {
        circulant_fits(set, &plan, k, e, options)?;
        if let Some(solution) = circulant::solve(set, &streams, &plan, regressors, options.sigma)? {
            return Ok((solution, plan.lost));
        }
    }
    least_squares_with_options(set, regressors, options).map(|solution| (solution, Vec::new()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{SimulationConfig, simulate};
    use crate::solve::circulant::Prepared;

    /// A fit of a prepared design is the unprepared fit to the bit (the same engine and
    /// the same arithmetic), and both agree with the dense reference — an independent
    /// implementation — to 1e-9″; a column the design already holds is refused alike.
    #[test]
    fn a_prepared_design_fits_as_the_unprepared_one_and_the_dense_reference() {
        let config = SimulationConfig {
            faces: 36,
            closing: true,
            step_seconds: 2.0,
            ..SimulationConfig::default()
        };
        let (set, _) = simulate(&config).expect("a valid simulation");
        let n = set.readings.len();
        let time: Vec<f64> = set
            .readings
            .iter()
            .map(|r| r.time_seconds.unwrap_or(0.0) / 3600.0)
            .collect();
        let jump: Vec<f64> = (0..n).map(|i| if i >= n / 2 { 1.0 } else { 0.0 }).collect();
        let prepared = Prepared::of(&set).expect("the circulant engine serves the design");
        let options = SolveOptions::new();
        for regressors in [vec![], vec![time.clone()], vec![time.clone(), jump.clone()]] {
            let a = least_squares_prepared(&set, Some(&prepared), &regressors, &options)
                .expect("a fit");
            let b = least_squares_with_options(&set, &regressors, &options).expect("a fit");
            let dense = dense_with_options(&set, &regressors, &options).expect("a fit");
            assert_eq!(a.pitch_deviation, b.pitch_deviation);
            assert_eq!(a.encoder_error, b.encoder_error);
            assert_eq!(a.effect_values, b.effect_values);
            assert_eq!(a.residuals, b.residuals);
            assert_eq!(a.pitch_deviation_u(), b.pitch_deviation_u());
            assert_eq!(a.dof, dense.dof);
            for (x, y) in a.encoder_error.iter().zip(&dense.encoder_error) {
                assert!((x - y).abs() < 1e-9, "{x} against {y}");
            }
            for (x, y) in a.effect_values.iter().zip(&dense.effect_values) {
                assert!((x - y).abs() < 1e-9, "{x} against {y}");
            }
        }
        // a constant column is the setup errors' own: neither path determines it
        let constant = vec![vec![1.0; n]];
        let prepared_fit = least_squares_prepared(&set, Some(&prepared), &constant, &options);
        let unprepared = least_squares_with_options(&set, &constant, &options);
        assert!(prepared_fit.is_err() && unprepared.is_err());
        assert_eq!(
            prepared_fit.err().map(|e| e.to_string()),
            unprepared.err().map(|e| e.to_string())
        );
    }
}
