//! The diagnosis of a self-calibration run (docs/FORMAT.md §5.2, §9.2).
//!
//! The heads stand in the autocollimators' place and the disc in the polygon's: the
//! readings are `selfcal`'s closure set, fitted with the table's error at every stop of
//! every cycle as a nuisance ([`Base::self_calibration`]), and the same forward selection
//! and adequacy checks as a polygon run's find what the model lacks: a drift of a head's
//! zero, a jump of a head's zero at any stop, an outlier, a direction offset of
//! bidirectional runs, and the lack of fit against pure error (each (step, head) is read
//! once per cycle, so with two cycles or more every cell is replicated; the pure error is
//! the scatter within cells beyond the table's nuisance). The base model's fit and the
//! final model's are given as self-calibrations ([`SelfcalSolution`], the encoder error e
//! and the heads' errors), exactly as [`crate::selfcal::solve`] reports them.
//!
//! Heads between the positions (SelfA's 7-fold heads on a grid of 72, say) are diagnosed
//! on the band-limited closure model `selfcal` solves them with (docs/FORMAT.md §9.3.1):
//! the same candidates, checks and verdicts, the fits and the hat matrix through the
//! band-limited design (`crate::selfcal::OffGridDesign`) in near-linear time. Its
//! readings keep their file's steps; a head's nominal face (its nearest position) only
//! names the stream.
//!
//! What the closure model cannot place: a change common to every head at a stop is the
//! table's, so a drift or jump of all heads together is invisible, and with two heads a
//! head's drift is the other's with the opposite sign (the finding names one and its
//! alternative the other; both give the same e and head errors).

use super::base::Base;
use super::{DiagnoseOptions, Diagnosis, clock, diagnose_base};
use crate::measurement::MeasurementSet;
use crate::selfcal::{
    HeadGrid, OffGridDesign, SelfcalOptions, SelfcalSet, SelfcalSolution, SelfcalSolveError,
    add_head_angle_u, closure_set, from_closure_fit, grid_offsets,
};
use crate::selfcal::{
    SelfcalMonteCarlo, SelfcalUncertainty, monte_carlo_of_closure_fit, monte_carlo_of_off_grid_fit,
};
use crate::solve::least_squares::least_squares_zeroing_lost;
use crate::solve::observability::Unobservable;
use crate::solve::{SolveError, SolveOptions};
use crate::uncertainty::calibration::{CalibrationError, InstrumentBudget, McOptions};

/// The diagnosis of a self-calibration: the diagnosis of its closure model (effects on
/// the heads: an effect's `ac` is the head), and the self-calibration before and after.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SelfcalDiagnosis {
    /// The diagnosis of the closure model (its `before` and `after` are the closure
    /// model's fits; the effects name heads in the autocollimators' field).
    pub diagnosis: Diagnosis,
    /// The base model: what [`crate::selfcal::solve`] gives.
    pub before: SelfcalSolution,
    /// The final model: e and the heads' errors with the effects found in the model.
    pub after: SelfcalSolution,
}

/// Diagnoses a self-calibration: the base fit, the effects the data demand, the final fit.
///
/// ```
/// use polycal::diagnose::{DiagnoseOptions, selfcal::diagnose_selfcal};
/// use polycal::effects::Effect;
/// use polycal::selfcal::SelfcalOptions;
/// use polycal::simulate::{SelfcalSimConfig, equally_spaced_head_angles_deg, simulate_selfcal};
///
/// // four heads, 24 positions, 3 cycles; head 3's zero jumps by 0.5″ at cycle 2, step 10
/// let mut config = SelfcalSimConfig::default();
/// config.positions = 24;
/// config.cycles = 3;
/// config.head_angles_deg = equally_spaced_head_angles_deg(4);
/// config.noise_arcsec = 0.02;
/// let (mut set, _truth) = simulate_selfcal(&config)?;
/// for r in &mut set.readings {
///     if r.head == 3 && (r.cycle, r.step) >= (2, 10) {
///         r.reading_arcsec += 0.5;
///     }
/// }
/// let found = diagnose_selfcal(&set, &DiagnoseOptions::default(), &SelfcalOptions::new())?;
/// assert!(matches!(
///     found.diagnosis.effects[0].effect,
///     Effect::OffsetStep { ac: 3, cycle: 2, step: Some(10), .. }
/// ));
/// assert!(found.diagnosis.adequacy.adequate);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// [`SelfcalSolveError::Invalid`] for a set that breaks the file's rules,
/// [`SelfcalSolveError::InvalidGauge`] for a gauge that does not divide P,
/// [`SelfcalSolveError::Solve`] when the engine refuses the design (memory),
/// [`SelfcalSolveError::TooLarge`] when the band-limited design of heads between the
/// positions would not fit in memory.
pub fn diagnose_selfcal(
    set: &SelfcalSet,
    options: &DiagnoseOptions,
    selfcal_options: &SelfcalOptions,
) -> Result<SelfcalDiagnosis, SelfcalSolveError> {
    set.check().map_err(SelfcalSolveError::Invalid)?;
    let p = set.positions;
    if let Some(gauge) = selfcal_options.gauge_positions
        && (gauge == 0 || !p.is_multiple_of(gauge))
    {
        return Err(SelfcalSolveError::InvalidGauge {
            positions: p,
            gauge,
        });
    }
    let (closure, off_grid) = diagnosed_closure(set)?;
    let (clocked, clock) = clock::clocked(&closure);
    let clocked = clocked.into_owned();
    let (base, lost) = match off_grid {
        None => {
            let mut solve_options = SolveOptions::new().with_sigma_opt(selfcal_options.sigma);
            if let Some(bytes) = selfcal_options.memory_limit_bytes {
                solve_options = solve_options.with_memory_limit(bytes);
            }
            let (_, lost) = least_squares_zeroing_lost(&closure, &solve_options)?;
            let base = Base::self_calibration(&clocked).with_dense_geometry(options.dense_geometry);
            (base, lost)
        }
        Some(offsets) => {
            check_off_grid_memory(set, options, selfcal_options)?;
            let heads: Vec<u32> = set.heads().iter().map(|h| h.head).collect();
            // a checked set reads every (step, head) once per cycle, as the design needs
            let design = OffGridDesign::new(&clocked, &heads, &offsets).ok_or_else(|| {
                SelfcalSolveError::Solve(SolveError::Unobservable(Unobservable {
                    harmonics: Vec::new(),
                    effects: Vec::new(),
                    message: "the band-limited closure model needs every head to read every step equally often".into(),
                }))
            })?;
            let lost = design.lost().to_vec();
            (Base::self_calibration_off_grid(&clocked, design), lost)
        }
    };
    let base = base.with_progress(options.progress.clone());
    let options = options
        .clone()
        .with_sigma_opt(options.sigma.or(selfcal_options.sigma));
    let diagnosis = diagnose_base(&clocked, &base, clock, &options)?;
    let terms = diagnosis.after.effect_values.len() - base.offset();
    let grid = if base.is_off_grid() {
        HeadGrid::OffGrid
    } else {
        HeadGrid::OnGrid
    };
    let before = from_closure_fit(
        set,
        diagnosis.before.clone(),
        lost.clone(),
        0,
        grid,
        selfcal_options,
    );
    let after = from_closure_fit(
        set,
        diagnosis.after.clone(),
        lost,
        terms,
        grid,
        selfcal_options,
    );
    Ok(SelfcalDiagnosis {
        before: add_head_angle_u(set, before, selfcal_options)?,
        after: add_head_angle_u(set, after, selfcal_options)?,
        diagnosis,
    })
}

/// Monte Carlo of a self-calibration's final model (JCGM 101; docs/FORMAT.md §5.2,
/// §9.3.2): as [`crate::selfcal::monte_carlo()`], every trial solved through the closure
/// model with the effects found and the table's error at every stop (effect columns
/// included), so that it checks `gum`, the budget evaluated on `diagnosis.after`
/// ([`crate::selfcal::evaluate_budget`]).
///
/// ```
/// use polycal::diagnose::{DiagnoseOptions, selfcal::{diagnose_selfcal, monte_carlo}};
/// use polycal::selfcal::{self, SelfcalOptions};
/// use polycal::simulate::{SelfcalSimConfig, equally_spaced_head_angles_deg, simulate_selfcal};
/// use polycal::uncertainty::calibration::{InstrumentBudget, McOptions};
/// use polycal::uncertainty::monte_carlo::Trials;
///
/// let mut config = SelfcalSimConfig::default();
/// config.positions = 24;
/// config.cycles = 3;
/// config.head_angles_deg = equally_spaced_head_angles_deg(4);
/// let (set, _truth) = simulate_selfcal(&config)?;
/// let found = diagnose_selfcal(&set, &DiagnoseOptions::default(), &SelfcalOptions::new())?;
/// let budget = InstrumentBudget::from_toml_str(
///     "[[component]]\nname = \"r\"\ntype = \"B\"\ndistribution = \"normal\"\nu = 0.02\nacts_on = \"each-reading\"\n",
///     "budget.toml",
/// )?;
/// let gum = selfcal::evaluate_budget(&found.after, &budget)?;
/// let mc = monte_carlo(&set, &found, &budget, &gum, &McOptions::new(Trials::Fixed(5_000)))?;
/// assert!((mc.encoder_error.u[3] / gum.encoder_error.u[3] - 1.0).abs() < 0.1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// As [`crate::selfcal::monte_carlo()`]; [`CalibrationError::Mismatch`] when the
/// diagnosis is not of `set`.
pub fn monte_carlo(
    set: &SelfcalSet,
    diagnosis: &SelfcalDiagnosis,
    budget: &InstrumentBudget,
    gum: &SelfcalUncertainty,
    options: &McOptions<'_>,
) -> Result<SelfcalMonteCarlo, CalibrationError> {
    let (closure, off_grid) =
        diagnosed_closure(set).map_err(|e| CalibrationError::Mismatch(e.to_string()))?;
    let (clocked, _) = clock::clocked(&closure);
    if let Some(offsets) = off_grid {
        let heads: Vec<u32> = set.heads().iter().map(|h| h.head).collect();
        let design = OffGridDesign::new(&clocked, &heads, &offsets).ok_or_else(|| {
            CalibrationError::Mismatch("readings not read equally often by every head".into())
        })?;
        return monte_carlo_of_off_grid_fit(
            &clocked,
            design,
            &diagnosis.diagnosis.after,
            &diagnosis.after,
            budget,
            gum,
            options,
        );
    }
    monte_carlo_of_closure_fit(
        &clocked,
        &diagnosis.diagnosis.after,
        &diagnosis.after,
        budget,
        gum,
        options,
    )
}

/// The closure set of a self-calibration, and the heads' fractional offsets (positions)
/// when some head sits between the positions (the closure set then gives every head the
/// nearest position as its face, which names its stream only).
fn diagnosed_closure(
    set: &SelfcalSet,
) -> Result<(MeasurementSet, Option<Vec<f64>>), SelfcalSolveError> {
    let p = set.positions;
    let heads = set.heads();
    if let Some(offsets) = grid_offsets(set, &heads) {
        let closure = closure_set(set, &heads, &offsets).map_err(SelfcalSolveError::Design)?;
        return Ok((closure, None));
    }
    let fractional: Vec<f64> = heads
        .iter()
        .map(|h| h.angle_deg * p as f64 / 360.0)
        .collect();
    let nearest: Vec<usize> = fractional
        .iter()
        .map(|d| (d.round() as usize) % p)
        .collect();
    let closure = closure_set(set, &heads, &nearest).map_err(SelfcalSolveError::Design)?;
    Ok((closure, Some(fractional)))
}

/// Refuses up front a diagnosis of heads between the positions that would not fit in
/// memory: per reading the set, its closure set, the projected readings, the residuals
/// and the candidates' columns (a few dozen values each), per low-rank column of a fit
/// two values, and M² kernels of length P.
fn check_off_grid_memory(
    set: &SelfcalSet,
    options: &DiagnoseOptions,
    selfcal_options: &SelfcalOptions,
) -> Result<(), SelfcalSolveError> {
    let n = set.readings.len() as u128;
    let m = set.heads().len() as u128;
    let p = set.positions as u128;
    let columns = 64 + 4 * options.max_effects as u128;
    let needed_bytes = 8 * n * columns + 8 * m * m * p + 16 * 12 * m * p;
    if let Some((limit_bytes, _)) =
        crate::solve::memory::limit_for(needed_bytes, selfcal_options.memory_limit_bytes)
        && needed_bytes > u128::from(limit_bytes)
    {
        return Err(SelfcalSolveError::TooLarge {
            positions: set.positions,
            heads: m as usize,
            needed_bytes,
            limit_bytes,
        });
    }
    Ok(())
}
