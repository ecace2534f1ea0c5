//! Closing the loop: find the residual structure of a fit, trace it to an effect the
//! model lacks, add that effect, and report the calibration before and after.
//!
//! The bare two-autocollimator cycle is exactly determined, so effects such as a
//! drifting autocollimator bias the result without leaving a residual. With redundancy
//! (closing readings, repeated cycles, counter-clockwise cycles, several mountings) they
//! leave structure in the residuals. [`diagnose`] fits the base model, then, round by
//! round, scores every candidate effect term of docs/FORMAT.md §6 against the current fit
//! ([`candidates`]: drift and its curvature, temperature, cross-talk, direction, a jump of
//! a zero at any stop of the run, one bad reading) by the reduction of the residual sum of
//! squares it would bring ([`geometry`], no refit), and adds the most significant by an
//! extra-sum-of-squares F test with a Bonferroni threshold within its family. The chosen
//! term is refitted and kept only if it does not leave the lack of fit against pure error
//! ([`lack_of_fit`]) failing and no better than before, the fits with and without it
//! judged against one pure error (the full model of the fit with it, so that a term
//! varying within cells is not refused for a lack of fit it was hiding). A lack of fit
//! left beside the effects found is reported as a finding of its own. The search stops
//! when nothing significant remains; the final residuals are then checked for structure
//! the model still lacks ([`residuals::adequacy`]).

pub mod base;
pub mod candidates;
pub mod clock;
pub mod cycles;
mod doubt;
mod drift_shape;
pub mod findings;
pub mod geometry;
pub mod identify;
pub mod lack_of_fit;
pub mod noise;
mod notes;
pub mod nuisance;
pub mod residuals;
mod reweight;
mod search;
pub mod selfcal;
pub mod stop_scatter;
mod verdict;

use std::sync::Arc;

use rayon::prelude::*;

use crate::effects::{Effect, EffectContext};
use crate::measurement::{MeasurementSet, Sigma};
use crate::progress::Progress;
use crate::solve::sub_pitch::SubPitchSolution;
use crate::solve::{Solution, SolveError};
use base::Base;
use candidates::Term;
pub use clock::Clock;
pub use drift_shape::{DriftKink, MAX_KINK_POSITIONS};
use findings::final_effects;
pub use identify::Alternative;
use lack_of_fit::LackOfFit;
use residuals::{Adequacy, AdequacyInputs};
pub use search::SearchStop;

/// Options of [`diagnose`].
#[derive(Clone)]
#[non_exhaustive]
pub struct DiagnoseOptions {
    /// False-alarm probability of each family of effects per round (Bonferroni over the
    /// candidates of the family: systematic effects; jumps at every stop; outliers over
    /// all readings). The default 0.005 bounds a false effect on clean data by 3 × 0.5 % =
    /// 1.5 % of runs (measured 0.4–1.1 % over nine kinds of run: docs/verdicts.md).
    pub family_alpha: f64,
    /// False-alarm probability of the serial-correlation checks (divided among the
    /// streams) and of the χ² check.
    pub adequacy_alpha: f64,
    /// False-alarm probability of the lack-of-fit test against pure error.
    pub lack_of_fit_alpha: f64,
    /// False-alarm probability of the check that a drift found has the same shape in both
    /// halves of the run (a wandering zero fails it).
    pub stability_alpha: f64,
    /// Most effects to add.
    pub max_effects: usize,
    /// Level of the test of equal noise of every (setup, autocollimator, cycle) group
    /// ([`noise`]).
    pub noise_alpha: f64,
    /// Reading noise σ stated by the caller (uncertainties for dof = 0 and a χ² check of
    /// the final residuals).
    pub sigma: Option<Sigma>,
    /// Autocollimators whose cross-talk the caller stated from their calibration and
    /// corrected the readings for (docs/FORMAT.md §6, `--cross-talk AC:C[:U]`): no
    /// cross-talk term is tried for them, and they resolve the ambiguity of the others'.
    pub stated_cross_talk: Vec<u32>,
    /// Score candidates with the dense geometry ([`geometry::FitGeometry::dense`])
    /// whatever the fits' cofactors: the reference the structured geometry is tested
    /// against (memory O((2N + K + E)²)).
    pub dense_geometry: bool,
    /// Told, from the diagnosing thread, how many rounds of the forward selection are done,
    /// with no total (`None`: the search ends when nothing significant remains), and told
    /// again after every fit, so that a command can show the work going on (default none;
    /// the library draws nothing).
    pub progress: Option<Arc<dyn Progress + Send>>,
}

impl std::fmt::Debug for DiagnoseOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DiagnoseOptions")
            .field("family_alpha", &self.family_alpha)
            .field("adequacy_alpha", &self.adequacy_alpha)
            .field("lack_of_fit_alpha", &self.lack_of_fit_alpha)
            .field("stability_alpha", &self.stability_alpha)
            .field("max_effects", &self.max_effects)
            .field("noise_alpha", &self.noise_alpha)
            .field("sigma", &self.sigma)
            .field("stated_cross_talk", &self.stated_cross_talk)
            .field("dense_geometry", &self.dense_geometry)
            .field("progress", &self.progress.as_ref().map(|_| "observer"))
            .finish()
    }
}

impl PartialEq for DiagnoseOptions {
    /// Equal settings, and the same progress observer (or none on both).
    fn eq(&self, other: &Self) -> bool {
        self.family_alpha == other.family_alpha
            && self.adequacy_alpha == other.adequacy_alpha
            && self.lack_of_fit_alpha == other.lack_of_fit_alpha
            && self.stability_alpha == other.stability_alpha
            && self.max_effects == other.max_effects
            && self.noise_alpha == other.noise_alpha
            && self.sigma == other.sigma
            && self.stated_cross_talk == other.stated_cross_talk
            && self.dense_geometry == other.dense_geometry
            && match (&self.progress, &other.progress) {
                (None, None) => true,
                (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                _ => false,
            }
    }
}

impl DiagnoseOptions {
    /// The defaults (see [`DiagnoseOptions::default`]).
    pub fn new() -> Self {
        Self::default()
    }

    /// With a stated σ of one reading (adds a χ² check).
    pub fn with_sigma(mut self, sigma: Sigma) -> Self {
        self.sigma = Some(sigma);
        self
    }

    /// With a stated σ when given.
    pub fn with_sigma_opt(mut self, sigma: Option<Sigma>) -> Self {
        self.sigma = sigma;
        self
    }

    /// With another false-alarm probability per family of effects.
    pub fn with_family_alpha(mut self, family_alpha: f64) -> Self {
        self.family_alpha = family_alpha;
        self
    }

    /// With another false-alarm probability of the serial-correlation and χ² checks.
    pub fn with_adequacy_alpha(mut self, adequacy_alpha: f64) -> Self {
        self.adequacy_alpha = adequacy_alpha;
        self
    }

    /// With another false-alarm probability of the lack-of-fit test.
    pub fn with_lack_of_fit_alpha(mut self, lack_of_fit_alpha: f64) -> Self {
        self.lack_of_fit_alpha = lack_of_fit_alpha;
        self
    }

    /// With the autocollimators whose cross-talk is stated (and corrected for).
    pub fn with_stated_cross_talk(mut self, acs: Vec<u32>) -> Self {
        self.stated_cross_talk = acs;
        self
    }

    /// With another false-alarm probability of the drift's stability check.
    pub fn with_stability_alpha(mut self, stability_alpha: f64) -> Self {
        self.stability_alpha = stability_alpha;
        self
    }

    /// With the dense reference geometry (or not).
    pub fn with_dense_geometry(mut self, dense: bool) -> Self {
        self.dense_geometry = dense;
        self
    }

    /// With a progress observer of the forward selection's rounds
    /// ([`DiagnoseOptions::progress`]).
    ///
    /// ```
    /// use std::sync::Arc;
    /// use std::sync::atomic::{AtomicU64, Ordering};
    /// use polycal::diagnose::{diagnose, DiagnoseOptions};
    /// use polycal::effects::Effect;
    /// use polycal::simulate::{simulate, SimulationConfig};
    ///
    /// let config = SimulationConfig {
    ///     effects: vec![Effect::Drift { ac: 2, value: 2.0, quadratic: None }],
    ///     ..SimulationConfig::default()
    /// };
    /// let (set, _truth) = simulate(&config)?;
    /// let rounds = Arc::new(AtomicU64::new(0));
    /// let seen = Arc::clone(&rounds);
    /// let options = DiagnoseOptions::new().with_progress(Arc::new(
    ///     move |done: u64, total: Option<u64>| {
    ///         assert_eq!(total, None);
    ///         seen.store(done, Ordering::Relaxed);
    ///     },
    /// ));
    /// let diagnosis = diagnose(&set, &options)?;
    /// // a round that found the drift, and one that found nothing more
    /// assert_eq!(diagnosis.effects.len(), 1);
    /// assert_eq!(rounds.load(Ordering::Relaxed), 2);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn with_progress(mut self, progress: Arc<dyn Progress + Send>) -> Self {
        self.progress = Some(progress);
        self
    }

    /// With another level of the test of equal noise.
    pub fn with_noise_alpha(mut self, noise_alpha: f64) -> Self {
        self.noise_alpha = noise_alpha;
        self
    }

    /// With another largest number of effects.
    pub fn with_max_effects(mut self, max_effects: usize) -> Self {
        self.max_effects = max_effects;
        self
    }
}

impl Default for DiagnoseOptions {
    /// Families at 0.005, serial correlation and χ² at 0.001, lack of fit and a drift's
    /// stability at 0.01 (so that
    /// clean data are called inadequate in at most 2.8 % of runs by the union of the checks;
    /// measured 1.0–2.0 % over nine kinds of run, docs/verdicts.md), at most 12
    /// effects, no stated σ.
    fn default() -> Self {
        Self {
            family_alpha: 0.005,
            adequacy_alpha: 0.001,
            lack_of_fit_alpha: 0.01,
            stability_alpha: 0.01,
            max_effects: 12,
            noise_alpha: noise::NOISE_ALPHA,
            sigma: None,
            stated_cross_talk: Vec::new(),
            dense_geometry: false,
            progress: None,
        }
    }
}

/// The statistics of one F test of a term against the model before it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evidence {
    /// Extra-sum-of-squares F statistic (per numerator degree of freedom).
    pub f_statistic: f64,
    /// p-value of that F test.
    pub p_value: f64,
    /// p-value times the number of candidates of its family (Bonferroni), at most 1.
    pub p_adjusted: f64,
}

/// An effect found in the data, with the evidence for it.
#[derive(Debug, Clone, PartialEq)]
pub struct FoundEffect {
    /// The effect with its fitted value (docs/FORMAT.md §6), in the final model.
    pub effect: Effect,
    /// Standard uncertainty of the value in the final model.
    pub u: Option<f64>,
    /// For a curved drift: standard uncertainty of its `quadratic`.
    pub quadratic_u: Option<f64>,
    /// For a curved drift: the F test of the curvature against the linear drift.
    pub quadratic_evidence: Option<Evidence>,
    /// Extra-sum-of-squares F statistic (1 numerator degree of freedom) when added.
    pub f_statistic: f64,
    /// p-value of that F test.
    pub p_value: f64,
    /// p-value times the number of candidates of its family (Bonferroni), at most 1.
    pub p_adjusted: f64,
    /// Residual RMS before adding it, arcsec.
    pub residual_rms_before: f64,
    /// Residual RMS after adding it, arcsec.
    pub residual_rms_after: f64,
    /// Largest change it made to a pitch deviation, arcsec.
    pub pitch_change_max: f64,
    /// Largest change it made to an encoder error, arcsec.
    pub encoder_change_max: f64,
    /// Whether it changed some β or α by more than that quantity's standard uncertainty
    /// in the final model ("found, but it does not change β or α" when false).
    pub changes_calibration: bool,
    /// For an outlier: its studentized residual in the model before it was added.
    pub studentized_residual: Option<f64>,
    /// Numerator degrees of freedom of its F test: 1 for one column, more for a block
    /// (a drift's orders, a zero per cycle) tested together.
    pub dof_numerator: usize,
    /// For a drift: its polynomial order (1 linear, 2 curved, 3 … with Legendre shapes).
    pub drift_order: Option<usize>,
    /// For a drift of order 3 or more: the coefficients of its Legendre shapes P₃ … over
    /// the run's clock span mapped onto −1 … 1, arcsec.
    pub shape: Vec<f64>,
    /// Their standard uncertainties, when the fit gives them.
    pub shape_u: Option<Vec<f64>>,
    /// For a drift whose rate changes at a time the data locate: the kink (a continuous
    /// piecewise-linear drift; `effect`'s value is the rate before it).
    pub kink: Option<DriftKink>,
    /// Other explanations that fit the data as well ([`identify`]), best first.
    pub alternatives: Vec<Alternative>,
}

impl FoundEffect {
    /// Whether an alternative that fits as well moves some β or α by more than its
    /// expanded uncertainty: the data cannot tell which calibration is right.
    pub fn ambiguous(&self) -> bool {
        self.alternatives
            .iter()
            .any(Alternative::changes_calibration)
    }
}

/// Why a tried term was not added.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Rejection {
    /// Its Bonferroni-adjusted p-value is not below the family's false-alarm probability.
    NotSignificant,
    /// Significant, but with it the lack of fit against pure error still fails and is
    /// no smaller: it mops up residual without explaining the structure.
    DoesNotReduceLackOfFit,
    /// An outlier the data cannot attribute to one reading (see [`Diagnosis::unattributed`]).
    Unattributable,
    /// The refit with it failed (the term cannot be told apart from the model).
    NotDetermined,
    /// A further jump of a zero that already jumped [`MAX_JUMPS_PER_STREAM`] times: a
    /// string of jumps is a slow variation no term expresses, not a series of events.
    TooManyJumps,
    /// A jump found earlier that a term found later contains (a zero set anew every
    /// cycle holds every jump at a cycle's start).
    Absorbed,
    /// A drift or jump of an autocollimator whose residuals still vary slowly in time
    /// with it in the model: a wandering zero no term expresses; the final model leaves it
    /// out rather than chase the wander.
    LeftOutWandering,
    /// A jump found earlier of a zero that then jumped once too often: a string of jumps
    /// approximates a slow variation and can make β and α worse than the base model, so
    /// the final model leaves it out.
    LeftOutOfString,
    /// A jump of a zero whose drift, given the shape the data demand (a higher order or a
    /// kink), explains it: a jump found beside a drift of the wrong shape.
    ExplainedByDriftShape,
}

/// The most jumps (`offset-step`) of one autocollimator's zero in one mounting that a
/// diagnosis accepts as events; a further significant jump ends the search with the
/// verdict "not adequate".
pub const MAX_JUMPS_PER_STREAM: usize = 2;

impl Rejection {
    /// The reason as spelled in the JSON: `not significant`, `does not reduce the lack of
    /// fit`, `cannot be attributed`, `not determined`, `one jump too many: …`.
    pub fn as_str(self) -> &'static str {
        match self {
            Rejection::NotSignificant => "not significant",
            Rejection::DoesNotReduceLackOfFit => "does not reduce the lack of fit",
            Rejection::Unattributable => "cannot be attributed",
            Rejection::NotDetermined => "not determined",
            Rejection::TooManyJumps => "one jump too many: a slow variation no term expresses",
            Rejection::Absorbed => "absorbed by a term found later",
            Rejection::LeftOutWandering => "left out: the zero wanders in a way no term expresses",
            Rejection::LeftOutOfString => {
                "left out: one of a string of jumps, a slow variation no term expresses"
            }
            Rejection::ExplainedByDriftShape => {
                "explained by the drift's shape the data demand (a higher order or a kink)"
            }
        }
    }
}

/// A term that was tried and not added, with its statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct TriedEffect {
    /// The effect with the value it would have had (for a curved drift's curvature: the
    /// drift with that `quadratic`).
    pub effect: Effect,
    /// Whether the term is the curvature of a drift.
    pub quadratic: bool,
    /// Its F test against the model of that round.
    pub evidence: Evidence,
    /// Why it was not added.
    pub rejection: Rejection,
}

/// One reading of an outlier the data cannot attribute.
#[derive(Debug, Clone, PartialEq)]
pub struct SuspectReading {
    /// Mounting.
    pub setup: u32,
    /// Cycle.
    pub cycle: u32,
    /// Table stop.
    pub step: usize,
    /// Autocollimator.
    pub ac: u32,
    /// Its residual in the final model, arcsec.
    pub residual_arcsec: f64,
    /// Its studentized residual when the outlier was found.
    pub studentized_residual: f64,
}

/// The result of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    /// Fit of the base model.
    pub before: Solution,
    /// Fit of the final model (base model plus `effects`).
    pub after: Solution,
    /// The effects added, in the order they were found.
    pub effects: Vec<FoundEffect>,
    /// The terms tried and not added, with the reason (the last verdict on each).
    pub tried: Vec<TriedEffect>,
    /// Outliers the data cannot attribute to one reading: each entry names the readings
    /// of which one is bad (kept in the fit; the verdict is then not adequate).
    pub unattributed: Vec<Vec<SuspectReading>>,
    /// The lack-of-fit test of the final model, when the design has replicated cells.
    pub lack_of_fit: Option<LackOfFit>,
    /// The verdict on the final residuals.
    pub adequacy: Adequacy,
    /// Whether the data had redundancy enough to test any effect.
    pub testable: bool,
    /// Plain statements for people: what could not be tested and which added readings
    /// would make it visible.
    pub notes: Vec<String>,
    /// The clock drift terms ran on: `time`, or the stop order in a file without it.
    pub clock: Clock,
    /// For sub-pitch mountings: the base model with the encoder errors at every table
    /// angle of every coset (as `solve` reports them; `before` holds coset 0's).
    pub before_sub_pitch: Option<SubPitchSolution>,
    /// For sub-pitch mountings: the final model likewise.
    pub after_sub_pitch: Option<SubPitchSolution>,
    /// The scatter the autocollimators share at a stop beyond the final model
    /// ([`stop_scatter`]), when it could be evaluated; when it is significant, `after`'s
    /// u(α) carries it.
    pub stop_scatter: Option<stop_scatter::StopScatter>,
    /// The limit that ended the search while something more was significant; `None` when
    /// it ended because nothing more was (or did not run). A stopped search is never
    /// adequate (docs/FORMAT.md §5).
    pub search_stopped: Option<SearchStop>,
    /// The test of equal noise of every (setup, autocollimator, cycle) group and the
    /// noise's description ([`noise`]); `None` when it could not run. When it fails the
    /// fits are weighted by the groups' σ (`weighted`), `after`'s residual sum of squares
    /// and σ are the whitened ones and its residuals are in arcsec.
    pub noise: Option<noise::NoiseTest>,
    /// The cycles that disagree with the others ([`cycles`]), repaired or set aside;
    /// empty when none (and for self-calibration runs, which are not tested).
    pub cycles: Vec<cycles::CycleFinding>,
    /// The mountings that disagree with the others ([`cycles::mountings`]), repaired or
    /// set aside; empty when none (runs of fewer than three mountings, shifted mountings
    /// and self-calibration runs are not tested).
    pub mountings: Vec<cycles::mountings::MountingFinding>,
}

/// The readings' rounding level: residual sums of squares below it are zero.
fn rounding_rss(set: &MeasurementSet) -> f64 {
    let scale = set
        .readings
        .iter()
        .map(|r| r.reading_arcsec.abs())
        .fold(1.0, f64::max);
    set.readings.len() as f64 * (64.0 * f64::EPSILON * scale).powi(2)
}

/// Fits the base model, then adds the effects the data demand, one at a time.
///
/// ```
/// use polycal::diagnose::{diagnose, DiagnoseOptions};
/// use polycal::effects::Effect;
/// use polycal::simulate::{simulate, SimulationConfig};
///
/// // autocollimator 2 drifts 2″ per hour; nobody tells diagnose
/// let config = SimulationConfig {
///     effects: vec![Effect::Drift { ac: 2, value: 2.0, quadratic: None }],
///     ..SimulationConfig::default()
/// };
/// let (set, _truth) = simulate(&config)?;
/// let diagnosis = diagnose(&set, &DiagnoseOptions::default())?;
/// assert!(matches!(diagnosis.effects[0].effect, Effect::Drift { ac: 2, .. }));
/// assert!(diagnosis.adequacy.adequate);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// The base model's [`SolveError`] when the design cannot be solved;
/// Shifted mountings (a `shift` column) are fitted in encoder positions ([`base`]).
pub fn diagnose(set: &MeasurementSet, options: &DiagnoseOptions) -> Result<Diagnosis, SolveError> {
    let (work, clock) = clock::clocked(set);
    cycles::diagnose_checked(&work, options, |set| {
        let base = Base::of(set)
            .with_dense_geometry(options.dense_geometry)
            .with_progress(options.progress.clone());
        diagnose_base(set, &base, clock, options)
    })
}

/// [`diagnose`] of `set` (on `clock`) with the base model `base` (of `set`, or of a
/// self-calibration's closure set: `selfcal`).
pub(crate) fn diagnose_base(
    set: &MeasurementSet,
    base: &Base<'_>,
    clock: Clock,
    options: &DiagnoseOptions,
) -> Result<Diagnosis, SolveError> {
    let first = diagnose_fitted(set, base, clock, options)?;
    reweight::reweighted(set, base, clock, options, first, diagnose_fitted)
}

/// [`diagnose_base`] with the fits of `base` as they are (weighted or not); an unweighted
/// one tests the noise of its final model ([`noise::test`]).
fn diagnose_fitted(
    set: &MeasurementSet,
    base: &Base<'_>,
    clock: Clock,
    options: &DiagnoseOptions,
) -> Result<Diagnosis, SolveError> {
    let sigma = options.sigma;
    let context = EffectContext::of(&set.readings).with_weights(base.weights().cloned());
    let before = base.fit(&[], sigma)?;
    refuse_too_large(set, &before, options)?;
    let testable = before.dof >= 2;
    let tiny = rounding_rss(set);
    let exact = testable && before.rss <= tiny;
    let mut notes = opening_notes(set, base, clock, options, before.dof, exact);

    let search::Outcome {
        terms,
        findings,
        mut tried,
        unattributed_sets,
        jumps_exceeded,
        fit: current,
        lack_of_fit: mut lof_current,
        stopped: search_stopped,
    } = if testable && !exact {
        search::run(set, base, &context, options, &before, tiny, &mut notes)
    } else {
        search::Outcome::base(&before)
    };
    let columns_of = |terms: &[Term]| -> Vec<Vec<f64>> {
        terms.iter().map(|t| t.column(set, &context)).collect()
    };
    if exact || !testable {
        lof_current = None;
    }
    // When in doubt, do not add (docs/FORMAT.md §5.2): a string of jumps, and the
    // drifts and jumps of a wandering zero, are left out of the final model.
    let mut model = doubt::Model {
        set,
        base,
        context: &context,
        sigma,
        lack_of_fit_alpha: options.lack_of_fit_alpha,
        terms,
        fit: current,
        findings,
        lack_of_fit: lof_current,
    };
    if testable && !exact {
        model.prune_drift_orders(options.family_alpha);
    }
    if !jumps_exceeded.is_empty() {
        model.leave_out(
            |t| matches!(t, Term::Effect(Effect::OffsetStep { ac, setup, .. }) if jumps_exceeded.contains(&(*ac, *setup))),
            Rejection::LeftOutOfString,
            &mut tried,
        );
    }
    // before a zero is called wandering, the drift shapes the data demand are tried
    let shapes = if testable && !exact {
        model.demanded_drift_shapes(options, tiny, &mut tried)
    } else {
        Vec::new()
    };
    let (wandering, stability) = if testable && !exact {
        model.wandering(options, tiny)
    } else {
        (Vec::new(), Vec::new())
    };
    let left_out_wandering = !wandering.is_empty()
        && model.leave_out(
            |t| wandering.iter().any(|&ac| doubt::wanders_with(t, ac)),
            Rejection::LeftOutWandering,
            &mut tried,
        );
    if left_out_wandering {
        notes.extend(wandering.iter().map(|&ac| notes::wandering(ac)));
    }
    notes.extend(
        shapes
            .iter()
            .filter(|shape| !(left_out_wandering && wandering.contains(&shape.ac)))
            .map(|shape| shape.note(clock)),
    );
    let doubt::Model {
        terms,
        fit: current,
        findings,
        lack_of_fit: mut lof_current,
        ..
    } = model;
    let columns = columns_of(&terms);

    let effects = with_alternatives(
        final_effects(&current, base, &terms, findings),
        identify::FinalModel {
            set,
            base,
            context: &context,
            terms: &terms,
            fit: &current,
            sigma,
            stated_cross_talk: &options.stated_cross_talk,
            tiny,
        },
    );
    tried.retain(|t| {
        !effects
            .iter()
            .any(|f| same_effect(&f.effect, &t.effect) && !t.quadratic)
    });
    let unattributed = verdict::unattributed(set, &current, &unattributed_sets, &mut notes);

    let geometry = base.geometry(&current, &columns);
    let leverage = geometry.leverage();
    let studentized = residuals::studentized(&current, &leverage);
    let noise = (testable && !exact)
        .then(|| {
            let residuals = &current.residuals;
            noise::test_of_fit(
                set,
                base.weights(),
                residuals,
                &leverage,
                options.noise_alpha,
            )
        })
        .flatten();
    let mut adequacy = if testable {
        residuals::adequacy(
            &current,
            set,
            &studentized,
            sigma,
            options.adequacy_alpha,
            AdequacyInputs {
                lack_of_fit: lof_current.as_ref(),
                unattributed_outliers: unattributed.len(),
                jumps_exceeded: &jumps_exceeded,
                exact,
            },
        )
    } else {
        Adequacy {
            adequate: true,
            checks: Vec::new(),
            structure: Vec::new(),
        }
    };
    if testable && !exact {
        verdict::stability(stability, &mut adequacy);
    }
    if left_out_wandering {
        verdict::wandering(&wandering, &mut adequacy);
    }
    verdict::identifiability(&effects, clock, &mut adequacy, &mut notes);
    notes.extend(verdict::stated_cross_talk_note(
        &options.stated_cross_talk,
        &effects,
    ));
    for &(ac, setup) in &jumps_exceeded {
        notes.push(notes::string_of_jumps(ac, setup));
    }
    if let Some(stop) = search_stopped {
        verdict::search_stopped(stop, &mut adequacy, &mut notes);
    }
    verdict::lack_of_fit_notes(&mut lof_current, base, effects.len(), &mut notes);
    // what the stops share and no position resolves enters u(α), and is not certified
    // (a weighted diagnosis's columns and residuals are whitened: not evaluated there)
    let mut current = current;
    let stop_scatter =
        if testable && !exact && !base.is_self_calibration() && base.weights().is_none() {
            verdict::stop_scatter(set, &mut current, &mut adequacy, &mut notes)
        } else {
            None
        };
    let before_sub_pitch = base.sub_pitch_solution(&before);
    let after_sub_pitch = base.sub_pitch_solution(&current);
    Ok(Diagnosis {
        before_sub_pitch,
        after_sub_pitch,
        before,
        after: current,
        effects,
        tried,
        unattributed,
        lack_of_fit: lof_current,
        adequacy,
        testable,
        notes,
        clock,
        stop_scatter,
        search_stopped,
        noise,
        cycles: Vec::new(),
        mountings: Vec::new(),
    })
}

/// Identifiability: the alternatives of every finding against the final `model`, each
/// finding's side by side (their refits are independent).
fn with_alternatives(
    with_blocks: Vec<(FoundEffect, Vec<Term>)>,
    model: identify::FinalModel<'_>,
) -> Vec<FoundEffect> {
    with_blocks
        .into_par_iter()
        .map(|(mut found, block)| {
            found.alternatives = identify::alternatives(model, &block);
            found
        })
        .collect()
}

/// The notes a diagnosis opens with: no residual degrees of freedom (`dof` < 2), the
/// kinds of effect the file cannot test, a cross-talk common to every autocollimator,
/// noise-free (`exact`) readings.
fn opening_notes(
    set: &MeasurementSet,
    base: &Base<'_>,
    clock: Clock,
    options: &DiagnoseOptions,
    dof: usize,
    exact: bool,
) -> Vec<String> {
    let mut notes = Vec::new();
    if dof < 2 {
        notes.push(format!(
            "The fit has {} residual degree{} of freedom: the readings determine the model exactly, so an effect (drift, a zero jump, a direction offset, an outlier) biases the result without leaving a residual, and none can be detected. To make effects visible, measure with redundancy: closing readings (step N), repeated cycles, and a counter-clockwise cycle.",
            dof,
            if dof == 1 { "" } else { "s" }
        ));
    }
    notes.extend(notes::untestable_kinds(set, clock));
    if let Some(note) = notes::common_cross_talk(set, base, &options.stated_cross_talk) {
        notes.push(note);
    }
    if exact {
        notes.push("The residuals are at the rounding level of the readings (noise-free data): the base model explains them exactly, and no effect is tested.".into());
    }
    notes
}

/// The dense hat-matrix geometry (the dense reference solver's fits) holds the cofactor
/// densely (three matrices of the parameters with every effect term the search may add):
/// refused up front when it cannot fit, before the search allocates it; the structured
/// geometry needs O(n + N·r).
fn refuse_too_large(
    set: &MeasurementSet,
    before: &Solution,
    options: &DiagnoseOptions,
) -> Result<(), SolveError> {
    let parameters =
        (before.layout.len() + options.max_effects * candidates::MAX_DRIFT_ORDER) as u128;
    let needed_bytes = 3 * parameters * parameters * 8;
    if (before.cofactor.is_dense() || options.dense_geometry)
        && let Some((limit_bytes, limit_source)) =
            crate::solve::memory::limit_for(needed_bytes, None)
        && needed_bytes > u128::from(limit_bytes)
    {
        return Err(SolveError::TooLarge {
            faces: set.faces,
            streams: before.layout.setups,
            effects: options.max_effects,
            readings: set.readings.len(),
            engine: "diagnose hat-matrix",
            needed_bytes,
            limit_bytes,
            limit_source,
        });
    }
    Ok(())
}

fn same_effect(a: &Effect, b: &Effect) -> bool {
    a.clone().with_value(0.0) == b.clone().with_value(0.0)
}
