//! Planning a calibration: what a design will give before the polygon is on the table.
//!
//! The cofactor Q of a design (paper eqs. (2)–(10) as least squares) does not depend on
//! the readings, so a design and the reading noise σ alone give:
//!
//! - the standard uncertainty of every β, φ, α and setup error, u = σ·√Q_jj — exactly
//!   what `solve` reports for a run of that design whose residuals give σ (both are the
//!   cofactor), and with an instrument budget U and k exactly as `solve --budget`
//!   ([`crate::uncertainty::calibration`]); the paper's design gives
//!   u(α_p) = σ·√((N² − 1)/(6·N·R)) for R cycles;
//! - the harmonics the design loses ([`crate::solve::lost_harmonics`]), reported rather
//!   than refused;
//! - what a diagnosis can see ([`detect`]): for each effect term of `diagnose`, whether
//!   the design can tell it from the model and the smallest size its F test finds with
//!   90 % probability at the selection's false-alarm rate ([`power`]), and which pairs of
//!   explanations the design cannot tell apart;
//! - the fewest cycles that reach a target u(α) ([`fewest_cycles`]).
//!
//! ```
//! use polycal::measurement::Sigma;
//! use polycal::plan::{Design, PlanOptions, plan};
//!
//! let sigma = Sigma::new(0.05)?;
//! // the paper's design: two adjacent autocollimators, 6 cycles without closing readings
//! let paper = Design::default().with_spec("closing=false")?;
//! let planned = plan(&paper, &PlanOptions::new(sigma).with_detect(false))?;
//! let u_alpha = planned.prediction.as_ref().unwrap().encoder_error_u.clone();
//! // the paper's design: u(α) = σ·√((N² − 1)/(6·N·R)), N = 24, R = 6 cycles
//! let by_hand = 0.05 * ((24.0f64 * 24.0 - 1.0) / (6.0 * 24.0 * 6.0)).sqrt();
//! assert!(u_alpha.iter().all(|u| (u - by_hand).abs() < 1e-12));
//! assert!(planned.lost_harmonics.is_empty());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod design;
pub mod detect;
pub mod power;
pub mod selection;

pub use design::{DESIGN_KEYS, Design, DesignSpecError};
pub use detect::{Ambiguity, Detectable};

use crate::diagnose::DiagnoseOptions;
use crate::input::Location;
use crate::measurement::{MeasurementSet, Sigma};
use crate::progress::Progress;
use crate::solve::sub_pitch::{ShiftGeometry, solve_shifted};
use crate::solve::{SigmaSource, Solution, SolveError, SolveOptions};
use crate::uncertainty::calibration::{
    self, CalibrationError, CalibrationUncertainty, InstrumentBudget,
};

/// What one reading of a design costs in memory while it is planned (the reading and
/// its share of the solver's per-reading arrays), bytes.
pub const BYTES_PER_READING: u128 = 256;

/// The probability with which a detectable size is found (90 %).
pub const DETECTION_POWER: f64 = 0.9;

/// The most cycles [`fewest_cycles`] tries.
pub const MAX_TARGET_CYCLES: u32 = 1000;

/// Why a design could not be planned.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanError {
    /// The design breaks a rule (faces, autocollimators, cycles, shifts…).
    #[error("invalid design: {0}")]
    Design(String),
    /// A design's written form is not valid.
    #[error("design \"{spec}\": {problem}")]
    Spec {
        /// The written form.
        spec: String,
        /// What is wrong.
        problem: DesignSpecError,
    },
    /// A designs file could not be read.
    #[error("{file}: {source}")]
    Io {
        /// The file's name.
        file: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A designs file is not valid.
    #[error("{location}: {message}")]
    File {
        /// The file, line and column.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// The solver refused the design for another reason than lost harmonics (too large
    /// for the memory, say).
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The budget could not be evaluated through the design.
    #[error("the budget through the design: {0}")]
    Budget(#[from] CalibrationError),
    /// The planning would need more memory than the machine may give.
    #[error(
        "{what} need about {} of memory; {} {limit_source}",
        crate::solve::memory::human_bytes(*needed_bytes),
        crate::solve::memory::human_bytes(u128::from(*limit_bytes))
    )]
    TooLarge {
        /// What would need it.
        what: &'static str,
        /// Bytes needed.
        needed_bytes: u128,
        /// Bytes allowed.
        limit_bytes: u64,
        /// Where the limit comes from.
        limit_source: &'static str,
    },
    /// The target u(α) is not a finite number > 0.
    #[error("the target u(α) must be a finite number > 0 arcsec, not {0}")]
    InvalidTarget(f64),
}

/// Refuses up front what would not fit in memory.
pub(crate) fn check_memory(
    needed_bytes: u128,
    what: &'static str,
    stated_limit_bytes: Option<u64>,
) -> Result<(), PlanError> {
    if let Some((limit_bytes, limit_source)) =
        crate::solve::memory::limit_for(needed_bytes, stated_limit_bytes)
        && needed_bytes > u128::from(limit_bytes)
    {
        return Err(PlanError::TooLarge {
            what,
            needed_bytes,
            limit_bytes,
            limit_source,
        });
    }
    Ok(())
}

/// Options of [`plan`].
#[derive(Clone)]
#[non_exhaustive]
pub struct PlanOptions {
    /// σ of one reading, arcsec.
    pub sigma: Sigma,
    /// An instrument budget: U and k of every quantity as `solve --budget` gives them.
    pub budget: Option<InstrumentBudget>,
    /// The diagnosis whose power is predicted (its false-alarm rate per family, the
    /// autocollimators whose cross-talk is stated).
    pub diagnose: DiagnoseOptions,
    /// A target u(α), arcsec: the fewest cycles of the design that reach it.
    pub target_encoder_u: Option<f64>,
    /// Whether to predict what a diagnosis can see (the default; the uncertainties alone
    /// are much faster).
    pub detect: bool,
    /// The most memory, in bytes, the planning may use (else the machine's available
    /// memory); a design that needs more is refused up front.
    pub memory_limit_bytes: Option<u64>,
    /// Told, from any thread, how many of the sizes a diagnosis finds are known and how
    /// many there are (the part of planning that takes long: seconds with several
    /// autocollimators).
    pub progress: Option<std::sync::Arc<dyn Progress + Send>>,
}

impl std::fmt::Debug for PlanOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlanOptions")
            .field("sigma", &self.sigma)
            .field("budget", &self.budget)
            .field("diagnose", &self.diagnose)
            .field("target_encoder_u", &self.target_encoder_u)
            .field("detect", &self.detect)
            .field("memory_limit_bytes", &self.memory_limit_bytes)
            .field("progress", &self.progress.as_ref().map(|_| "observer"))
            .finish()
    }
}

impl PlanOptions {
    /// σ alone: no budget, the default diagnosis, no target.
    pub fn new(sigma: Sigma) -> Self {
        PlanOptions {
            sigma,
            budget: None,
            diagnose: DiagnoseOptions::default(),
            target_encoder_u: None,
            detect: true,
            memory_limit_bytes: None,
            progress: None,
        }
    }

    /// With a progress observer of the detection sizes ([`PlanOptions::progress`]).
    pub fn with_progress(mut self, progress: std::sync::Arc<dyn Progress + Send>) -> Self {
        self.progress = Some(progress);
        self
    }

    /// With or without the prediction of what a diagnosis can see.
    pub fn with_detect(mut self, detect: bool) -> Self {
        self.detect = detect;
        self
    }

    /// With a memory limit, bytes.
    pub fn with_memory_limit(mut self, bytes: u64) -> Self {
        self.memory_limit_bytes = Some(bytes);
        self
    }

    /// With an instrument budget.
    pub fn with_budget(mut self, budget: Option<InstrumentBudget>) -> Self {
        self.budget = budget;
        self
    }

    /// With the diagnosis whose power is predicted.
    pub fn with_diagnose(mut self, diagnose: DiagnoseOptions) -> Self {
        self.diagnose = diagnose;
        self
    }

    /// With a target u(α), arcsec (finite, > 0).
    ///
    /// # Errors
    ///
    /// [`PlanError::InvalidTarget`].
    pub fn with_target_encoder_u(mut self, arcsec: Option<f64>) -> Result<Self, PlanError> {
        if let Some(a) = arcsec
            && !(a.is_finite() && a > 0.0)
        {
            return Err(PlanError::InvalidTarget(a));
        }
        self.target_encoder_u = arcsec;
        Ok(self)
    }
}

/// The uncertainties a design gives (k = 1 unless said), arcsec.
#[derive(Debug, Clone, PartialEq)]
pub struct Prediction {
    /// The fit of the design with σ in place of the residuals' σ: its cofactor is the
    /// design's (for sub-pitch mountings, the engine's solution in encoder positions).
    pub solution: Solution,
    /// u(β).
    pub pitch_deviation_u: Vec<f64>,
    /// u(φ).
    pub face_deviation_u: Vec<f64>,
    /// u(α); for sub-pitch mountings at every table angle of every coset, in the order
    /// of `encoder_angle_deg`.
    pub encoder_error_u: Vec<f64>,
    /// The table angle of each u(α), degrees.
    pub encoder_angle_deg: Vec<f64>,
    /// u of each setup error, in the order of the solution's `setup_error`.
    pub setup_error_u: Vec<f64>,
    /// With a budget: the evaluation `solve --budget` would give.
    pub uncertainty: Option<CalibrationUncertainty>,
    /// What a reader must know (each coset's constant for sub-pitch mountings).
    pub notes: Vec<String>,
}

impl Prediction {
    /// The largest u(β).
    pub fn worst_pitch_deviation_u(&self) -> f64 {
        self.pitch_deviation_u.iter().copied().fold(0.0, f64::max)
    }

    /// The largest u(α).
    pub fn worst_encoder_error_u(&self) -> f64 {
        self.encoder_error_u.iter().copied().fold(0.0, f64::max)
    }

    /// The largest U(α) with a budget.
    pub fn worst_encoder_error_expanded_u(&self) -> Option<f64> {
        self.uncertainty.as_ref().map(|u| {
            u.encoder_error
                .expanded_u
                .iter()
                .copied()
                .fold(0.0, f64::max)
        })
    }

    /// The largest U(β) with a budget.
    pub fn worst_pitch_deviation_expanded_u(&self) -> Option<f64> {
        self.uncertainty.as_ref().map(|u| {
            u.pitch_deviation
                .expanded_u
                .iter()
                .copied()
                .fold(0.0, f64::max)
        })
    }
}

/// The fewest cycles of a design that reach a target u(α).
#[derive(Debug, Clone, PartialEq)]
pub struct TargetCycles {
    /// The target, arcsec.
    pub encoder_error_u: f64,
    /// The fewest cycles whose largest u(α) is at most the target; `None` when even
    /// [`MAX_TARGET_CYCLES`] do not reach it (or the design loses harmonics).
    pub cycles: Option<u32>,
    /// The largest u(α) with that many cycles.
    pub reached_u: Option<f64>,
    /// The readings of a run with that many cycles.
    pub readings: Option<usize>,
    /// From the first stop to the last of a run with that many cycles, seconds (as
    /// [`Plan::duration_seconds`]); `None` when not reached or without times.
    pub duration_seconds: Option<f64>,
}

/// What a design gives ([`plan`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The design's name or description.
    pub name: String,
    /// N.
    pub faces: usize,
    /// The readings a run takes.
    pub readings: usize,
    /// From the first to the last stop, seconds (readings' `time`); `None` without.
    pub duration_seconds: Option<f64>,
    /// σ of one reading, arcsec.
    pub sigma: f64,
    /// Residual degrees of freedom.
    pub dof: usize,
    /// The false-alarm probability of each family of the diagnosis whose power
    /// [`Plan::detectable`] predicts (`diagnose`'s, Bonferroni-divided within a family).
    pub false_alarm_per_family: f64,
    /// The harmonics the design loses (empty when none); then there is no prediction.
    pub lost_harmonics: Vec<usize>,
    /// Why the design determines nothing when it loses something other than harmonics
    /// (a position without a reading).
    pub unobservable: Option<String>,
    /// The uncertainties; `None` when the design cannot determine every quantity.
    pub prediction: Option<Prediction>,
    /// What a diagnosis of a run of this design can see.
    pub detectable: Vec<Detectable>,
    /// Pairs of explanations the design cannot tell apart.
    pub cannot_tell_apart: Vec<Ambiguity>,
    /// With a target: the fewest cycles that reach it.
    pub target: Option<TargetCycles>,
    /// Plain statements for people.
    pub notes: Vec<String>,
}

impl Plan {
    /// Whether the design determines every β, φ and α.
    pub fn determines_everything(&self) -> bool {
        self.prediction.is_some()
    }
}

/// Plans a design: its readings are built (all 0) and [`plan_set`] plans them; with a
/// target u(α), [`fewest_cycles`] adds the fewest cycles that reach it.
///
/// # Errors
///
/// An invalid design, one too large for the memory, or a budget that cannot be
/// evaluated; a design that loses harmonics is planned, not refused.
pub fn plan(design: &Design, options: &PlanOptions) -> Result<Plan, PlanError> {
    let set = design.measurement_set_within(options.memory_limit_bytes)?;
    let mut planned = plan_set(&set, options)?;
    planned.name = design.label();
    if let Some(target) = options.target_encoder_u {
        planned.target = Some(fewest_cycles_within(
            design,
            options.sigma,
            target,
            options.memory_limit_bytes,
        )?);
    }
    Ok(planned)
}

/// From the first stop to the last, seconds: the span of the readings' `time`; `None`
/// when a reading has none.
fn duration_of(set: &MeasurementSet) -> Option<f64> {
    let times: Vec<f64> = set.readings.iter().filter_map(|r| r.time_seconds).collect();
    (!times.is_empty() && times.len() == set.readings.len()).then(|| {
        let (lo, hi) = times
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
                (lo.min(t), hi.max(t))
            });
        hi - lo
    })
}

/// Plans the design of a measurement set (its readings are not used): the uncertainties
/// with σ, the lost harmonics, and what a diagnosis can see.
///
/// # Errors
///
/// As [`plan`].
pub fn plan_set(set: &MeasurementSet, options: &PlanOptions) -> Result<Plan, PlanError> {
    check_memory(
        set.readings.len() as u128 * BYTES_PER_READING,
        "the readings of the design",
        options.memory_limit_bytes,
    )?;
    let sigma = options.sigma.arcsec();
    let duration_seconds = duration_of(set);
    let mut planned = Plan {
        name: set.source.clone(),
        faces: set.faces,
        readings: set.readings.len(),
        duration_seconds,
        sigma,
        dof: 0,
        false_alarm_per_family: options.diagnose.family_alpha,
        lost_harmonics: Vec::new(),
        unobservable: None,
        prediction: None,
        detectable: Vec::new(),
        cannot_tell_apart: Vec::new(),
        target: None,
        notes: Vec::new(),
    };
    let predicted = match predict(set, options) {
        Ok(p) => p,
        Err(PlanError::Solve(SolveError::Unobservable(lost))) => {
            planned.lost_harmonics = lost.harmonics.clone();
            planned.unobservable = Some(lost.message.clone());
            let mut note: Vec<char> = lost.message.chars().collect();
            if let Some(first) = note.first_mut() {
                *first = first.to_ascii_uppercase();
            }
            planned
                .notes
                .push(format!("{}.", note.into_iter().collect::<String>()));
            return Ok(planned);
        }
        Err(e) => return Err(e),
    };
    planned.dof = predicted.solution.dof;
    if predicted.solution.dof < 2 {
        planned.notes.push(format!(
            "The design has {} residual degree{} of freedom: no effect can be detected. Add \
             closing readings, cycles or a counter-clockwise cycle.",
            predicted.solution.dof,
            if predicted.solution.dof == 1 { "" } else { "s" }
        ));
    } else if options.detect {
        match detect::detectable(
            set,
            &predicted.solution,
            sigma,
            &options.diagnose,
            options.memory_limit_bytes,
            options.progress.as_deref(),
        ) {
            Ok((detectable, ambiguous)) => {
                planned.detectable = detectable;
                planned.cannot_tell_apart = ambiguous;
            }
            Err(PlanError::TooLarge {
                needed_bytes,
                limit_bytes,
                ..
            }) => planned.notes.push(format!(
                "What a diagnosis can see is not predicted: its geometry would need about {} \
                 of memory, {} may be used.",
                crate::solve::memory::human_bytes(needed_bytes),
                crate::solve::memory::human_bytes(u128::from(limit_bytes))
            )),
            Err(e) => return Err(e),
        }
    }
    planned.notes.extend(predicted.notes.iter().cloned());
    planned.prediction = Some(predicted);
    Ok(planned)
}

/// σ as a run of the design would have it: estimated from the residuals (ν = dof) when
/// the design has redundancy, stated when it has none — what `solve` uses.
fn as_run_sigma(solution: &mut Solution, sigma: f64) {
    let source = if solution.dof > 0 {
        SigmaSource::Residual
    } else {
        SigmaSource::Stated
    };
    solution.sigma = Some((sigma, source));
}

/// The uncertainties of the design's set.
fn predict(set: &MeasurementSet, options: &PlanOptions) -> Result<Prediction, PlanError> {
    let sigma = options.sigma.arcsec();
    let mut solve_options = SolveOptions::new().with_sigma(options.sigma);
    if let Some(bytes) = options.memory_limit_bytes {
        solve_options = solve_options.with_memory_limit(bytes);
    }
    if set.has_shifts() && ShiftGeometry::of(set).is_sub_pitch() {
        if options.budget.is_some() {
            return Err(PlanError::Budget(CalibrationError::ShiftedMountings));
        }
        let solved = solve_shifted(set, &solve_options)?.with_sigma(sigma);
        let mut solution = solved.solution.clone();
        as_run_sigma(&mut solution, sigma);
        return Ok(Prediction {
            pitch_deviation_u: solution.pitch_deviation_u().unwrap_or_default(),
            face_deviation_u: solution.face_deviation_u().unwrap_or_default(),
            encoder_error_u: solved.encoder_error_u.clone().unwrap_or_default(),
            encoder_angle_deg: solved.encoder_angle_deg.clone(),
            setup_error_u: solution.setup_error_u().unwrap_or_default(),
            uncertainty: None,
            notes: solved.notes.clone(),
            solution,
        });
    }
    let mut solution = crate::solve::solve(set, &solve_options)?;
    as_run_sigma(&mut solution, sigma);
    let uncertainty = match &options.budget {
        Some(budget) => {
            if set.has_shifts() {
                return Err(PlanError::Budget(CalibrationError::ShiftedMountings));
            }
            Some(calibration::evaluate_with_corrections(
                set,
                &solution,
                budget,
                &[],
            )?)
        }
        None => None,
    };
    let n = set.faces;
    Ok(Prediction {
        pitch_deviation_u: solution.pitch_deviation_u().unwrap_or_default(),
        face_deviation_u: solution.face_deviation_u().unwrap_or_default(),
        encoder_error_u: solution.encoder_error_u().unwrap_or_default(),
        encoder_angle_deg: (0..n as u32)
            .map(|p| crate::measurement::step_angle_deg(p, n))
            .collect(),
        setup_error_u: solution.setup_error_u().unwrap_or_default(),
        uncertainty,
        notes: Vec::new(),
        solution,
    })
}

/// The fewest cycles of `design` whose largest u(α) is at most `target_arcsec` with σ:
/// u(α) falls as cycles are added, so the search doubles, then bisects (each step a
/// solve of the design with that many cycles), up to [`MAX_TARGET_CYCLES`].
///
/// # Errors
///
/// As [`plan`]; [`PlanError::InvalidTarget`] for a target that is not > 0.
pub fn fewest_cycles(
    design: &Design,
    sigma: Sigma,
    target_arcsec: f64,
) -> Result<TargetCycles, PlanError> {
    fewest_cycles_within(design, sigma, target_arcsec, None)
}

fn fewest_cycles_within(
    design: &Design,
    sigma: Sigma,
    target_arcsec: f64,
    memory_limit_bytes: Option<u64>,
) -> Result<TargetCycles, PlanError> {
    if !(target_arcsec.is_finite() && target_arcsec > 0.0) {
        return Err(PlanError::InvalidTarget(target_arcsec));
    }
    let mut options = PlanOptions::new(sigma);
    options.memory_limit_bytes = memory_limit_bytes;
    let worst = |cycles: u32| -> Result<Option<f64>, PlanError> {
        let set = design
            .with_cycles(cycles)
            .measurement_set_within(memory_limit_bytes)?;
        match predict(&set, &options) {
            Ok(p) => Ok(Some(p.worst_encoder_error_u())),
            Err(PlanError::Solve(SolveError::Unobservable(_))) => Ok(None),
            Err(e) => Err(e),
        }
    };
    let none = TargetCycles {
        encoder_error_u: target_arcsec,
        cycles: None,
        reached_u: None,
        readings: None,
        duration_seconds: None,
    };
    let (mut lo, mut hi) = (0u32, 1u32);
    let mut at_hi = match worst(1)? {
        Some(u) => u,
        None => return Ok(none),
    };
    while at_hi > target_arcsec {
        if hi >= MAX_TARGET_CYCLES {
            return Ok(none);
        }
        lo = hi;
        hi = (hi * 2).min(MAX_TARGET_CYCLES);
        at_hi = worst(hi)?.unwrap_or(f64::INFINITY);
    }
    // u(α) at lo is above the target (or lo = 0), at hi at most the target
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        let u = worst(mid)?.unwrap_or(f64::INFINITY);
        if u <= target_arcsec {
            hi = mid;
            at_hi = u;
        } else {
            lo = mid;
        }
    }
    // the run those cycles make: its readings and how long it takes
    let set = design
        .with_cycles(hi)
        .measurement_set_within(memory_limit_bytes)?;
    Ok(TargetCycles {
        encoder_error_u: target_arcsec,
        cycles: Some(hi),
        reached_u: Some(at_hi),
        readings: Some(set.readings.len()),
        duration_seconds: duration_of(&set),
    })
}
