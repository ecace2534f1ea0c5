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
//! ([`lack_of_fit`]) failing and no better than before. The search stops when nothing
//! significant remains; the final residuals are then checked for structure the model
//! still lacks ([`residuals::adequacy`]).

pub mod candidates;
pub mod clock;
mod doubt;
pub mod findings;
pub mod geometry;
pub mod identify;
pub mod lack_of_fit;
mod notes;
pub mod residuals;

use std::collections::HashSet;

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::effects::{Effect, EffectContext};
use crate::measurement::{MeasurementSet, Sigma};
use crate::solve::{Solution, SolveError, least_squares_with_regressors};
use crate::uncertainty::student::t_two_sided_tail;
use candidates::{Candidate, Family, Term};
pub use clock::Clock;
use findings::{
    Finding, candidate_effect, difference, final_effects, max_abs, record_not_significant,
};
use geometry::FitGeometry;
pub use identify::Alternative;
use lack_of_fit::LackOfFit;
use residuals::{Adequacy, AdequacyInputs, Check};

/// Options of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct DiagnoseOptions {
    /// False-alarm probability of each family of effects per round (Bonferroni over the
    /// candidates of the family: systematic effects; jumps at every stop; outliers over
    /// all readings). The default 0.005 keeps a false effect on clean data to about 1 % of
    /// runs.
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
    /// Reading noise σ stated by the caller (uncertainties for dof = 0 and a χ² check of
    /// the final residuals).
    pub sigma: Option<Sigma>,
    /// Autocollimators whose cross-talk the caller stated from their calibration and
    /// corrected the readings for (docs/FORMAT.md §6, `--cross-talk AC:C[:U]`): no
    /// cross-talk term is tried for them, and they resolve the ambiguity of the others'.
    pub stated_cross_talk: Vec<u32>,
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

    /// With another largest number of effects.
    pub fn with_max_effects(mut self, max_effects: usize) -> Self {
        self.max_effects = max_effects;
        self
    }
}

impl Default for DiagnoseOptions {
    /// Families at 0.005, serial correlation and χ² at 0.001, lack of fit and a drift's
    /// stability at 0.01 (so that
    /// clean data are called inadequate in about 1 % of runs, well inside 5 %), at most 12
    /// effects, no stated σ.
    fn default() -> Self {
        Self {
            family_alpha: 0.005,
            adequacy_alpha: 0.001,
            lack_of_fit_alpha: 0.01,
            stability_alpha: 0.01,
            max_effects: 12,
            sigma: None,
            stated_cross_talk: Vec::new(),
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

/// The F test of a scored candidate against the current fit: F = (Δ/r)/(rest/(dof − r))
/// with r the directions it adds (for r = 1 through Student's t, as before blocks).
fn evidence(candidate: &Candidate, current: &Solution, family_size: usize, tiny: f64) -> Evidence {
    let reduction = candidate.reduction;
    let r = candidate.rank.max(1);
    let dof = current.dof.saturating_sub(r);
    let rest = (current.rss - reduction).max(0.0);
    let f_statistic = if dof == 0 {
        0.0
    } else if rest > tiny {
        (reduction / r as f64) / (rest / dof as f64)
    } else if reduction > tiny {
        f64::INFINITY
    } else {
        0.0
    };
    let p_value = if dof == 0 || f_statistic <= 0.0 {
        1.0
    } else if r == 1 {
        t_two_sided_tail(f_statistic.sqrt(), Some(dof as f64))
    } else if f_statistic.is_infinite() {
        0.0
    } else {
        FisherSnedecor::new(r as f64, dof as f64).map_or(1.0, |d| d.sf(f_statistic))
    };
    Evidence {
        f_statistic,
        p_value,
        p_adjusted: (p_value * family_size.max(1) as f64).min(1.0),
    }
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
/// [`SolveError::ShiftedMountings`] for a set with shifted mountings (not handled yet).
pub fn diagnose(set: &MeasurementSet, options: &DiagnoseOptions) -> Result<Diagnosis, SolveError> {
    if set.has_shifts() {
        // its candidates and reports are in steps and time order, not encoder positions
        return Err(SolveError::ShiftedMountings {
            evaluation: "the diagnosis",
        });
    }
    let (work, clock) = clock::clocked(set);
    let set: &MeasurementSet = &work;
    let sigma = options.sigma;
    let context = EffectContext::of(&set.readings);
    let before = least_squares_with_regressors(set, &[], sigma)?;
    // the hat-matrix geometry holds the cofactor densely (three matrices of the
    // parameters with every effect term the search may add): refused up front when it
    // cannot fit, before the search allocates it
    let parameters =
        (before.layout.len() + options.max_effects * candidates::MAX_DRIFT_ORDER) as u128;
    let needed_bytes = 3 * parameters * parameters * 8;
    if let Some((limit_bytes, limit_source)) = crate::solve::memory::limit_for(needed_bytes, None)
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
    let mut notes = Vec::new();
    let testable = before.dof >= 2;
    if !testable {
        notes.push(format!(
            "The fit has {} residual degree{} of freedom: the readings determine the model exactly, so an effect (drift, a zero jump, a direction offset, an outlier) biases the result without leaving a residual, and none can be detected. To make effects visible, measure with redundancy: closing readings (step N), repeated cycles, and a counter-clockwise cycle.",
            before.dof,
            if before.dof == 1 { "" } else { "s" }
        ));
    }
    notes.extend(notes::untestable_kinds(set, clock));
    if let Some(note) = notes::common_cross_talk(set, &options.stated_cross_talk) {
        notes.push(note);
    }
    let tiny = rounding_rss(set);
    let exact = testable && before.rss <= tiny;
    if exact {
        notes.push("The residuals are at the rounding level of the readings (noise-free data): the base model explains them exactly, and no effect is tested.".into());
    }

    let columns_of = |terms: &[Term]| -> Vec<Vec<f64>> {
        terms.iter().map(|t| t.column(set, &context)).collect()
    };
    let mut terms: Vec<Term> = Vec::new();
    let mut findings: Vec<Finding> = Vec::new();
    let mut tried: Vec<TriedEffect> = Vec::new();
    let mut suspects: HashSet<usize> = HashSet::new();
    let mut unattributed_sets: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut cross_talk_noted = false;
    let mut jumps_exceeded: Vec<(u32, Option<u32>)> = Vec::new();
    let mut current = before.clone();
    let mut lof_current = lack_of_fit::lack_of_fit(set, &current, &[], options.lack_of_fit_alpha);
    while testable && !exact && findings.len() < options.max_effects && current.dof >= 2 {
        let columns = columns_of(&terms);
        let geometry = FitGeometry::new(&current, set, &columns);
        let leverage = geometry.leverage();
        let studentized = residuals::studentized(&current, &leverage);
        let mut candidates: Vec<Candidate> = Vec::new();
        for block in candidates::systematic_blocks(set, &terms, &options.stated_cross_talk) {
            if let [term] = block.as_slice() {
                let column = term.column(set, &context);
                let score = geometry.score(&column, &current.residuals);
                if let Term::Effect(Effect::CrossTalk { ac, .. }) = term
                    && score.new_fraction() < 0.1
                {
                    if !cross_talk_noted && let Some(note) = notes::cross_talk_untestable(set, *ac)
                    {
                        notes.push(note);
                        cross_talk_noted = true;
                    }
                    continue;
                }
                if score.is_new() {
                    candidates.push(Candidate::single(term.clone(), Family::Systematic, &score));
                }
            } else {
                let score = geometry.score_block(&columns_of(&block), &current.residuals);
                if score.rank > 0
                    && let Some(c) = Candidate::block(block, Family::Systematic, &score)
                {
                    candidates.push(c);
                }
            }
        }
        candidates.extend(candidates::offset_step_candidates(
            set,
            &geometry,
            &current.residuals,
            &terms,
        ));
        let eligible = studentized.iter().filter(|t| t.is_some()).count();
        if let Some((i, t)) = studentized
            .iter()
            .enumerate()
            .filter(|(i, _)| !suspects.contains(i))
            .filter_map(|(i, t)| t.map(|t| (i, t)))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        {
            let r = &set.readings[i];
            let several_setups = set.readings.iter().any(|q| q.setup != r.setup);
            let mut column = vec![0.0; set.readings.len()];
            column[i] = 1.0;
            let score = geometry.score(&column, &current.residuals);
            let mut candidate = Candidate::single(
                Term::Effect(Effect::Outlier {
                    cycle: r.cycle,
                    step: r.step,
                    ac: r.ac,
                    setup: several_setups.then_some(r.setup),
                    value: 0.0,
                }),
                Family::Outlier,
                &score,
            );
            candidate.outlier = Some((i, t));
            candidates.push(candidate);
        }
        let count = |family: Family| candidates.iter().filter(|c| c.family == family).count();
        let (systematic_count, step_count) = (count(Family::Systematic), count(Family::OffsetStep));
        let family_size = |family: Family| match family {
            Family::Outlier => eligible,
            Family::Systematic => systematic_count,
            Family::OffsetStep => step_count,
        };
        let mut scored: Vec<(Candidate, Evidence)> = candidates
            .iter()
            .map(|c| {
                let e = evidence(c, &current, family_size(c.family), tiny);
                (c.clone(), e)
            })
            .collect();
        scored.sort_by(|a, b| {
            a.1.p_adjusted
                .total_cmp(&b.1.p_adjusted)
                .then(b.1.f_statistic.total_cmp(&a.1.f_statistic))
        });
        // A further jump of a zero that already jumped as often as a diagnosis accepts is
        // not tried: the stream is marked, and a smooth drift or a zero per cycle of it
        // may still take the structure.
        jumps_exceeded.clear();
        let jumps_of = |ac: u32, setup: Option<u32>, terms: &[Term]| {
            terms
                .iter()
                .filter(|t| {
                    matches!(t, Term::Effect(Effect::OffsetStep { ac: a, setup: s, .. }) if *a == ac && *s == setup)
                })
                .count()
        };
        let mut attempts = 0;
        let mut accepted = false;
        for (candidate, ev) in &scored {
            if attempts >= 4 || ev.p_adjusted >= options.family_alpha {
                break;
            }
            let rejected = |rejection| TriedEffect {
                effect: candidate_effect(candidate),
                quadratic: matches!(candidate.term, Term::Quadratic { .. }),
                evidence: *ev,
                rejection,
            };
            if let Term::Effect(Effect::OffsetStep { ac, setup, .. }) = candidate.term
                && jumps_of(ac, setup, &terms) >= MAX_JUMPS_PER_STREAM
            {
                if !jumps_exceeded.contains(&(ac, setup)) {
                    jumps_exceeded.push((ac, setup));
                    tried.push(rejected(Rejection::TooManyJumps));
                }
                continue;
            }
            attempts += 1;
            if let Some((i, t)) = candidate.outlier {
                let twins = twins(&geometry, &studentized, i, t);
                if !twins.is_empty() {
                    let mut group = vec![(i, t)];
                    group.extend(twins);
                    for &(j, _) in &group {
                        suspects.insert(j);
                    }
                    unattributed_sets.push(group);
                    tried.push(rejected(Rejection::Unattributable));
                    continue;
                }
            }
            let added = candidate.terms();
            // a zero per cycle holds every jump of its stream at a cycle's start
            let absorbed: Vec<Term> = match candidate.term {
                Term::RezeroCycle { ac, setup, .. } => terms
                    .iter()
                    .filter(|t| {
                        matches!(t, Term::Effect(Effect::OffsetStep { ac: a, setup: s, step: None, .. }) if *a == ac && *s == setup)
                    })
                    .cloned()
                    .collect(),
                _ => Vec::new(),
            };
            let mut new_terms: Vec<Term> = terms
                .iter()
                .filter(|t| !absorbed.contains(t))
                .cloned()
                .collect();
            new_terms.extend(added.iter().cloned());
            let new_columns = columns_of(&new_terms);
            let Ok(fit) = least_squares_with_regressors(set, &new_columns, sigma) else {
                tried.push(rejected(Rejection::NotDetermined));
                continue;
            };
            let lof_new =
                lack_of_fit::lack_of_fit(set, &fit, &new_columns, options.lack_of_fit_alpha);
            if let Some(new) = &lof_new
                && !new.passed()
                && lof_current
                    .as_ref()
                    .is_none_or(|old| new.f_statistic >= old.f_statistic)
            {
                tried.push(rejected(Rejection::DoesNotReduceLackOfFit));
                continue;
            }
            for gone in &absorbed {
                if let Some(k) = findings.iter().position(|f| f.terms.contains(gone)) {
                    let f = findings.remove(k);
                    tried.push(TriedEffect {
                        effect: f.entry.effect.clone(),
                        quadratic: false,
                        evidence: Evidence {
                            f_statistic: f.entry.f_statistic,
                            p_value: f.entry.p_value,
                            p_adjusted: f.entry.p_adjusted,
                        },
                        rejection: Rejection::Absorbed,
                    });
                }
            }
            let pitch_change = difference(&fit.pitch_deviation, &current.pitch_deviation);
            let encoder_change = difference(&fit.encoder_error, &current.encoder_error);
            let entry = FoundEffect {
                effect: candidate_effect(candidate),
                u: None,
                quadratic_u: None,
                quadratic_evidence: None,
                f_statistic: ev.f_statistic,
                p_value: ev.p_value,
                p_adjusted: ev.p_adjusted,
                residual_rms_before: current.residual_rms().unwrap_or(0.0),
                residual_rms_after: fit.residual_rms().unwrap_or(0.0),
                pitch_change_max: max_abs(&pitch_change),
                encoder_change_max: max_abs(&encoder_change),
                changes_calibration: true,
                studentized_residual: candidate.outlier.map(|(_, t)| t),
                dof_numerator: candidate.rank.max(1),
                drift_order: None,
                shape: Vec::new(),
                shape_u: None,
                alternatives: Vec::new(),
            };
            findings.push(Finding {
                terms: added,
                entry,
                pitch_change,
                encoder_change,
            });
            terms = new_terms;
            current = fit;
            lof_current = lof_new;
            accepted = true;
            break;
        }
        if !accepted {
            // The last round's verdict on every kind of term not in the model.
            record_not_significant(&mut tried, &scored, options.family_alpha);
            break;
        }
    }
    if exact || !testable {
        lof_current = None;
    }
    // When in doubt, do not add (docs/FORMAT.md §5.2): a string of jumps, and the
    // drifts and jumps of a wandering zero, are left out of the final model.
    let mut model = doubt::Model {
        set,
        context: &context,
        sigma,
        lack_of_fit_alpha: options.lack_of_fit_alpha,
        terms,
        fit: current,
        findings,
        lack_of_fit: lof_current,
    };
    if !jumps_exceeded.is_empty() {
        model.leave_out(
            |t| matches!(t, Term::Effect(Effect::OffsetStep { ac, setup, .. }) if jumps_exceeded.contains(&(*ac, *setup))),
            Rejection::LeftOutOfString,
            &mut tried,
        );
    }
    let (wandering, stability) = if testable && !exact {
        model.wandering(options, tiny)
    } else {
        (Vec::new(), Vec::new())
    };
    if !wandering.is_empty()
        && model.leave_out(
            |t| wandering.iter().any(|&ac| doubt::wanders_with(t, ac)),
            Rejection::LeftOutWandering,
            &mut tried,
        )
    {
        notes.extend(wandering.iter().map(|&ac| notes::wandering(ac)));
    }
    let doubt::Model {
        terms,
        fit: current,
        findings,
        lack_of_fit: lof_current,
        ..
    } = model;
    let columns = columns_of(&terms);

    let with_blocks = final_effects(&current, &terms, findings);
    // identifiability: the alternatives of every finding, against the final model
    let model = identify::FinalModel {
        set,
        context: &context,
        terms: &terms,
        fit: &current,
        sigma,
        stated_cross_talk: &options.stated_cross_talk,
        tiny,
    };
    let effects: Vec<FoundEffect> = with_blocks
        .into_iter()
        .map(|(mut found, block)| {
            found.alternatives = identify::alternatives(model, &block);
            found
        })
        .collect();
    tried.retain(|t| {
        !effects
            .iter()
            .any(|f| same_effect(&f.effect, &t.effect) && !t.quadratic)
    });
    let unattributed: Vec<Vec<SuspectReading>> = unattributed_sets
        .iter()
        .map(|group| {
            group
                .iter()
                .map(|&(i, t)| {
                    let r = &set.readings[i];
                    SuspectReading {
                        setup: r.setup,
                        cycle: r.cycle,
                        step: r.step,
                        ac: r.ac,
                        residual_arcsec: current.residuals[i],
                        studentized_residual: t,
                    }
                })
                .collect()
        })
        .collect();
    for group in &unattributed {
        let names: Vec<String> = group
            .iter()
            .map(|s| {
                format!(
                    "setup {} cycle {} step {} autocollimator {} (residual {:+.4}″)",
                    s.setup, s.cycle, s.step, s.ac, s.residual_arcsec
                )
            })
            .collect();
        notes.push(format!(
            "One of these readings is bad, but the data cannot tell which: {}. Their residuals are equally large because the design determines their cell only by these readings. Both are kept in the fit, so the result carries about half of the bad reading's error there; repeat that stop (a third reading tells which one is bad).",
            names.join(" and ")
        ));
    }

    let geometry = FitGeometry::new(&current, set, &columns);
    let studentized = residuals::studentized(&current, &geometry.leverage());
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
        for check in stability {
            adequacy.adequate &= check.passed;
            adequacy.checks.push(check);
        }
    }
    for found in &effects {
        if found.alternatives.is_empty() {
            continue;
        }
        let worst = found
            .alternatives
            .iter()
            .map(|a| a.change_over_expanded_u)
            .fold(0.0, f64::max);
        let passed = worst <= 1.0;
        adequacy.checks.push(Check {
            name: format!(
                "identifiability of the {} (largest change of β or α by an explanation that fits as well, in expanded uncertainties)",
                crate::report::diagnose::label(&found.effect)
            ),
            statistic: worst,
            limit: 1.0,
            passed,
            stream: None,
        });
        adequacy.adequate &= passed;
        notes.push(notes::ambiguity(found, clock));
    }
    if !options.stated_cross_talk.is_empty() {
        let stated: Vec<String> = options
            .stated_cross_talk
            .iter()
            .map(u32::to_string)
            .collect();
        let found: Vec<String> = effects
            .iter()
            .filter_map(|f| match f.effect {
                Effect::CrossTalk { ac, value } if !f.ambiguous() => {
                    Some(format!("autocollimator {ac}'s ({value:+.5}″/″)"))
                }
                _ => None,
            })
            .collect();
        notes.push(format!(
            "The cross-talk of autocollimator{} {} is stated from its calibration and corrected for{}",
            if stated.len() == 1 { "" } else { "s" },
            stated.join(", "),
            if found.is_empty() {
                ": no further cross-talk is significant.".to_string()
            } else {
                format!(
                    "; against it, {} follows from the data, and the ambiguity of a cross-talk the closure cannot place is resolved.",
                    found.join(" and ")
                )
            }
        ));
    }
    for &(ac, setup) in &jumps_exceeded {
        notes.push(notes::string_of_jumps(ac, setup));
    }
    if let Some(lof) = &lof_current
        && !lof.passed()
    {
        notes.extend(lof.carriers.iter().cloned());
    }
    Ok(Diagnosis {
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
    })
}

/// Readings whose outlier column is nearly the same as reading `i`'s (|correlation of
/// their residual directions| ≥ 0.9) and that explain nearly as much (t² within 4 of
/// reading i's): the data cannot say which of them is bad.
fn twins(
    geometry: &FitGeometry,
    studentized: &[Option<f64>],
    i: usize,
    t_i: f64,
) -> Vec<(usize, f64)> {
    let h_ii = geometry.hat(i, i);
    (0..studentized.len())
        .filter(|&j| j != i)
        .filter_map(|j| {
            let t_j = studentized[j]?;
            if t_j * t_j < t_i * t_i - 4.0 {
                return None;
            }
            let h_jj = geometry.hat(j, j);
            let room = (1.0 - h_ii) * (1.0 - h_jj);
            if room <= 0.0 {
                return None;
            }
            let correlation = -geometry.hat(i, j) / room.sqrt();
            (correlation.abs() >= 0.9).then_some((j, t_j))
        })
        .collect()
}

fn same_effect(a: &Effect, b: &Effect) -> bool {
    a.clone().with_value(0.0) == b.clone().with_value(0.0)
}
