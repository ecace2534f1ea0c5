//! The forward selection of a diagnosis: round by round, every candidate term is scored
//! against the current fit without refitting, the most significant (by its family's
//! Bonferroni-adjusted F test) is refitted and kept unless the lack of fit then fails and
//! is no smaller, judged against one pure error ([`refused_for_lack_of_fit`]); outliers
//! with an indistinguishable twin are named, not dropped; a jump beyond
//! [`MAX_JUMPS_PER_STREAM`] of one zero is not added.

mod columns;
mod rank;
mod stop;
mod systematic;
mod twins;

use std::collections::HashSet;

use super::base::Base;
use super::candidates::{self, Candidate, Family, StepScore, StepSearch, SystematicLayout, Term};
use super::findings::{Finding, candidate_effect, difference, max_abs, record_not_significant};
use super::geometry::{ColumnScore, FitGeometry};
use super::lack_of_fit::LackOfFit;
use super::{
    DiagnoseOptions, Evidence, FoundEffect, MAX_JUMPS_PER_STREAM, Rejection, TriedEffect, notes,
    residuals,
};
use crate::effects::{Effect, EffectContext};
use crate::measurement::MeasurementSet;
use crate::solve::Solution;
use columns::Columns;
use rank::{RoundCandidates, rank};
pub use stop::SearchStop;
use systematic::Systematic;
use twins::{exchangeable, twins};

/// What the search ends with.
pub(super) struct Outcome {
    /// The terms of the model.
    pub terms: Vec<Term>,
    /// The findings behind them.
    pub findings: Vec<Finding>,
    /// The terms tried and not added.
    pub tried: Vec<TriedEffect>,
    /// Outliers with their indistinguishable twins: (reading, studentized residual).
    pub unattributed_sets: Vec<Vec<(usize, f64)>>,
    /// Streams whose zero would need one jump too many in the last round.
    pub jumps_exceeded: Vec<(u32, Option<u32>)>,
    /// The fit of the model.
    pub fit: Solution,
    /// Its lack-of-fit test.
    pub lack_of_fit: Option<LackOfFit>,
    /// The limit that ended the search, if one did (`None`: nothing more was significant).
    pub stopped: Option<SearchStop>,
}

impl Outcome {
    /// The base model, searched no further (no redundancy, or noise-free data).
    pub fn base(before: &Solution) -> Self {
        Outcome {
            terms: Vec::new(),
            findings: Vec::new(),
            tried: Vec::new(),
            unattributed_sets: Vec::new(),
            jumps_exceeded: Vec::new(),
            fit: before.clone(),
            lack_of_fit: None,
            stopped: None,
        }
    }
}

/// The most candidates a round refits (tries) before it gives up.
pub(crate) const MAX_ATTEMPTS: usize = 4;

/// Whether a candidate the round's F test chose is refused because the lack of fit
/// against pure error still fails with it and is no smaller (`new`: the lack-of-fit test
/// of the fit with it; `old_against_new_pure_error`: the current fit's lack-of-fit test
/// recomputed with the candidate's within-cell columns in the full model).
///
/// # The rule: both fits judged against one pure error
///
/// Let the current model M₀ hold the terms T, the candidate add the columns X_c (rank
/// r), and M₁ = M₀ + X_c. The lack-of-fit test of a model M compares it with its full
/// model F(M): one free mean per cell (and the stops' table errors of a
/// self-calibration) plus the within-cell part W of every effect column of M (its
/// deviations from its cells' means), so that M is nested in F(M). A term that varies
/// within cells (a drift, a jump, a zero per cycle, a temperature, a reading) has a
/// within-cell part W_c, so F(M₁) = F(M₀) + W_c: the two fits' F statistics
///
/// ```text
/// F(M) = [(RSS_M − RSS_F) / (dof_M − ν_F)] / [RSS_F / ν_F]
/// ```
///
/// have different denominators. When the candidate is real, RSS_{F(M₀)} holds its
/// within-cell signal (a head drifting 0.6″/h inflates the pure error of the old fit
/// many times over): the old fit's F is small because its yardstick is inflated, and
/// once the term is fitted the yardstick shrinks to σ², so that a lack of fit the term
/// was hiding (say an encoder's orders above a band limit) shows with a larger F. The
/// comparison `F₁ ≥ F₀` then throws away a real term for a finding that is not its own
/// (issue 46) — the same reason that exempts single readings, in a new form.
///
/// Both M₀ and M₁ are nested in F₁ = F(M₁) (M₀'s columns are cell means, stop effects
/// and terms of T, whose within-cell parts F₁ holds). Judged against that one full
/// model, with s² = RSS_{F₁}/ν₁, ν_L = dof₀ − ν₁ and dof₁ = dof₀ − r,
///
/// ```text
/// F₀* = [(RSS₀ − RSS_{F₁}) / ν_L] / s²,   F₁ = [(RSS₁ − RSS_{F₁}) / (ν_L − r)] / s²,
/// F₁ < F₀*  ⇔  (RSS₀ − RSS₁) / r  >  (RSS₀ − RSS_{F₁}) / ν_L :
/// ```
///
/// the term is kept when its mean square exceeds the mean square of all the current
/// model lacks against F₁ — it explains more per degree of freedom than the average
/// direction the current model falls short in, which is what "reduces the lack of fit"
/// means on one scale. F₀* is the current fit's lack-of-fit test with the candidate's
/// columns in the full model (`old_against_new_pure_error`).
///
/// # Why no false finding comes through it
///
/// The rule differs from the comparison with F₀ only by moving the candidate's
/// within-cell sum of squares w from the pure error into the lack of fit. When the
/// candidate is not real, w is noise, about r_w·σ² for r_w within-cell directions; as a
/// lack of fit that fails has a mean square above σ², moving w pulls the lack-of-fit
/// mean square towards σ² and leaves s² about as it was, so F₀* is at most about F₀: a
/// term that only mops up the between-cell structure of a lack of fit is refused about
/// as often as before, or more. Only a term whose within-cell part is signal — evidence
/// no between-cell structure can give — raises F₀*. When that signal is another term's
/// of the same zero (a drift taken for a jump), the term is kept as any significant
/// term is, and the rules of doubt decide (a drift's orders the final model does not
/// need dropped, a zero that needs several kinds of terms left out as a wander). A candidate
/// without within-cell part (a direction offset) has F₀* = F₀: the rule is then the
/// old one. The search's F tests and their Bonferroni families are not touched, so the
/// false-alarm rates stay as stated (`tests/maths/diagnose_monte_carlo.rs`,
/// `tests/maths/diagnose_selfcal_within_cells.rs`). F₀* is formed only when `new` fails
/// (one more projection onto the within-cell columns, no refit).
fn refused_for_lack_of_fit(
    new: &LackOfFit,
    old_against_new_pure_error: impl FnOnce() -> Option<LackOfFit>,
) -> bool {
    !new.passed()
        && old_against_new_pure_error().is_none_or(|old| new.f_statistic >= old.f_statistic)
}

/// Runs the forward selection from the base model `before`; notes for people go to
/// `notes`.
pub(super) fn run(
    set: &MeasurementSet,
    base: &Base<'_>,
    context: &EffectContext,
    options: &DiagnoseOptions,
    before: &Solution,
    tiny: f64,
    notes: &mut Vec<String>,
) -> Outcome {
    let mut search = Search {
        set,
        base,
        options,
        tiny,
        known: Columns {
            set,
            context,
            known: Vec::new(),
        },
        step_search: StepSearch::new(),
        layout: SystematicLayout::of(set, &options.stated_cross_talk),
        candidates: Vec::new(),
        steps: Vec::new(),
        terms: Vec::new(),
        findings: Vec::new(),
        tried: Vec::new(),
        suspects: HashSet::new(),
        unattributed_sets: Vec::new(),
        cross_talk_noted: false,
        jumps_exceeded: Vec::new(),
        current: before.clone(),
        lof_current: None,
        lof_pending: true,
        core_grams: Vec::new(),
        core_of_grams: None,
    };
    let mut stopped = None;
    loop {
        // too few residual degrees of freedom to score another term: a limit, since the
        // model has changed since the last round (the first round needs dof ≥ 2 to run)
        if search.current.dof < 2 {
            stopped = Some(SearchStop::TooFewDegreesOfFreedom {
                dof: search.current.dof,
            });
            break;
        }
        let round = search.score(notes);
        if search.findings.len() >= options.max_effects {
            // the limit on the number of effects ends the search only when something more
            // is significant (else the search would have ended here anyway)
            if round
                .scored
                .iter()
                .any(|(_, e)| e.p_adjusted < options.family_alpha)
            {
                stopped = Some(SearchStop::MaxEffects {
                    limit: options.max_effects,
                });
            } else {
                record_not_significant(&mut search.tried, &round.scored, options.family_alpha);
            }
            break;
        }
        let attempt = search.attempt(&round);
        base.ticker().round_done();
        if let Attempt::Added = attempt {
            continue;
        }
        if let Attempt::Stopped(stop) = attempt {
            stopped = Some(stop);
        }
        // The last round's verdict on every kind of term not in the model.
        record_not_significant(&mut search.tried, &round.scored, options.family_alpha);
        break;
    }
    let lack_of_fit = if search.lof_pending {
        // no round ran: the fit is the base fit
        base.lack_of_fit(set, before, &[], options.lack_of_fit_alpha)
    } else {
        search.lof_current
    };
    Outcome {
        terms: search.terms,
        findings: search.findings,
        tried: search.tried,
        unattributed_sets: search.unattributed_sets,
        jumps_exceeded: search.jumps_exceeded,
        fit: search.current,
        lack_of_fit,
        stopped,
    }
}

/// The state of a forward selection between its rounds.
struct Search<'s, 'b> {
    set: &'s MeasurementSet,
    base: &'s Base<'b>,
    options: &'s DiagnoseOptions,
    /// The readings' rounding level of the residual sum of squares.
    tiny: f64,
    /// The columns of every term met so far.
    known: Columns<'s>,
    step_search: StepSearch,
    layout: SystematicLayout,
    /// The candidates of a round other than the jumps (a few).
    candidates: Vec<Candidate>,
    /// The jumps of a round (thousands), one vector for every round.
    steps: Vec<StepScore>,
    terms: Vec<Term>,
    findings: Vec<Finding>,
    tried: Vec<TriedEffect>,
    /// Readings named in an outlier that cannot be attributed (not offered again).
    suspects: HashSet<usize>,
    unattributed_sets: Vec<Vec<(usize, f64)>>,
    cross_talk_noted: bool,
    jumps_exceeded: Vec<(u32, Option<u32>)>,
    current: Solution,
    /// The base fit's lack-of-fit test, formed beside the first round's candidates (its
    /// cells are the longest part of it; nothing before the round's loop reads it).
    lof_current: Option<LackOfFit>,
    lof_pending: bool,
    /// The Gram matrices of the systematic blocks off the base fit's span (geometry's
    /// `core_projected_gram`): (the longest block of nested ones, its matrix).
    core_grams: Vec<(Vec<Term>, nalgebra::DMatrix<f64>)>,
    core_of_grams: Option<FitGeometry>,
}

/// A round scored: what its attempts need.
struct Round {
    /// The columns of the model's terms.
    columns: Vec<Vec<f64>>,
    /// The geometry of the current fit.
    geometry: FitGeometry,
    /// Its studentized residuals.
    studentized: Vec<Option<f64>>,
    /// The candidates the round can use with their F tests, most significant first.
    scored: Vec<(Candidate, Evidence)>,
}

/// How a round's attempts ended.
enum Attempt {
    /// A term was added.
    Added,
    /// A limit ended the search with significant candidates left.
    Stopped(SearchStop),
    /// Nothing more significant could be added.
    NothingMore,
}

/// The jumps of stream (`ac`, `setup`) among `terms`.
fn jumps_of(ac: u32, setup: Option<u32>, terms: &[Term]) -> usize {
    terms
        .iter()
        .filter(|t| {
            matches!(t, Term::Effect(Effect::OffsetStep { ac: a, setup: s, .. }) if *a == ac && *s == setup)
        })
        .count()
}

impl Search<'_, '_> {
    /// Scores every candidate of a round against the current fit: the systematic blocks,
    /// the jumps of every stream and the reading with the largest studentized residual,
    /// each with its family's Bonferroni-adjusted F test ([`rank`]).
    fn score(&mut self, notes: &mut Vec<String>) -> Round {
        let (set, base, options) = (self.set, self.base, self.options);
        let columns = self.known.of(&self.terms);
        let geometry = base.geometry(&self.current, &columns);
        // the Gram matrices kept are of the core they were formed with (a new one with
        // the dense reference geometry, formed from every round's fit)
        if self
            .core_of_grams
            .as_ref()
            .is_none_or(|core| !core.same_core(&geometry))
        {
            self.core_grams.clear();
            self.core_of_grams = Some(geometry.clone());
        }
        self.candidates.clear();
        let blocks = self.layout.blocks(&self.terms);
        // the systematic blocks (their columns formed first), the jumps of every stream
        // and the leverages side by side
        let residuals = &self.current.residuals;
        self.steps.clear();
        let step_candidates = &mut self.steps;
        let known_columns = &mut self.known;
        let core_grams = &mut self.core_grams;
        let (terms, current) = (&self.terms, &self.current);
        let (lof_current, lof_pending) = (&mut self.lof_current, &mut self.lof_pending);
        let step_search = &mut self.step_search;
        let ((leverage, systematic), ()) = rayon::join(
            || {
                rayon::join(
                    || geometry.leverage(),
                    || {
                        known_columns.form(blocks.iter().flatten());
                        let known = &*known_columns;
                        let systematic = Systematic {
                            geometry: &geometry,
                            known,
                            residuals,
                            terms,
                            ticker: base.ticker(),
                        };
                        systematic.candidates(&blocks, core_grams)
                    },
                )
            },
            || {
                if *lof_pending {
                    *lof_current = base.lack_of_fit(set, current, &[], options.lack_of_fit_alpha);
                    *lof_pending = false;
                }
                candidates::offset_step_scores_with(
                    set,
                    &geometry,
                    residuals,
                    terms,
                    step_search,
                    step_candidates,
                );
            },
        );
        let (systematic, cross_talk_untestable) = systematic;
        for ac in cross_talk_untestable {
            if !self.cross_talk_noted
                && let Some(note) = notes::cross_talk_untestable(set, ac)
            {
                notes.push(note);
                self.cross_talk_noted = true;
            }
        }
        self.candidates.extend(systematic);
        let studentized = residuals::studentized(&self.current, &leverage);
        let eligible = studentized.iter().filter(|t| t.is_some()).count();
        if let Some(candidate) = self.outlier_candidate(&studentized, &leverage) {
            self.candidates.push(candidate);
        }
        // in the order systematic, jumps, outlier
        let candidates = &self.candidates;
        let (systematic, outlier) = match candidates.last() {
            Some(c) if c.family == Family::Outlier => candidates.split_at(candidates.len() - 1),
            _ => candidates.split_at(candidates.len()),
        };
        let round = RoundCandidates {
            systematic,
            steps: &self.steps,
            outlier: outlier.first(),
        };
        let systematic_count = systematic
            .iter()
            .filter(|c| c.family == Family::Systematic)
            .count();
        let step_count = self.steps.len();
        let family_size = |family: Family| match family {
            Family::Outlier => eligible,
            Family::Systematic => systematic_count,
            Family::OffsetStep => step_count,
        };
        let terms = &self.terms;
        let full = |ac: u32, setup: Option<u32>| jumps_of(ac, setup, terms) >= MAX_JUMPS_PER_STREAM;
        let step_search = &self.step_search;
        let scored = rank(
            &round,
            &self.current,
            self.tiny,
            options.family_alpha,
            family_size,
            |score| step_search.stream(score),
            full,
        );
        let mut scored: Vec<(Candidate, Evidence)> = scored
            .into_iter()
            .filter_map(|(i, e)| Some((round.candidate(i, set, step_search)?, e)))
            .collect();
        scored.sort_by(|a, b| {
            a.1.p_adjusted
                .total_cmp(&b.1.p_adjusted)
                .then(b.1.f_statistic.total_cmp(&a.1.f_statistic))
        });
        Round {
            columns,
            geometry,
            studentized,
            scored,
        }
    }

    /// The outlier candidate of a round: the reading with the largest |studentized
    /// residual| not already named in an unattributed outlier.
    fn outlier_candidate(
        &self,
        studentized: &[Option<f64>],
        leverage: &[f64],
    ) -> Option<Candidate> {
        let (i, t) = studentized
            .iter()
            .enumerate()
            .filter(|(i, _)| !self.suspects.contains(i))
            .filter_map(|(i, t)| t.map(|t| (i, t)))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
        let set = self.set;
        let r = &set.readings[i];
        let several_setups = set.readings.iter().any(|q| q.setup != r.setup);
        // the reading's own column: eᵢ against the residuals, 1 − hᵢᵢ outside the span
        let score = ColumnScore {
            projection: self.current.residuals[i],
            new_length_squared: 1.0 - leverage[i],
            length_squared: 1.0,
        };
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
        Some(candidate)
    }

    /// Tries the round's significant candidates, most significant first, at most
    /// [`MAX_ATTEMPTS`] refits: the first one kept is added. A further jump of a zero that
    /// already jumped as often as a diagnosis accepts is not tried: the stream is marked,
    /// and a smooth drift or a zero per cycle of it may still take the structure.
    fn attempt(&mut self, round: &Round) -> Attempt {
        let alpha = self.options.family_alpha;
        self.jumps_exceeded.clear();
        let mut attempts = 0;
        for (candidate, ev) in &round.scored {
            if ev.p_adjusted >= alpha {
                break;
            }
            if attempts >= MAX_ATTEMPTS {
                return Attempt::Stopped(SearchStop::AttemptsPerRound {
                    attempts: MAX_ATTEMPTS,
                });
            }
            if let Term::Effect(Effect::OffsetStep { ac, setup, .. }) = candidate.term
                && jumps_of(ac, setup, &self.terms) >= MAX_JUMPS_PER_STREAM
            {
                if !self.jumps_exceeded.contains(&(ac, setup)) {
                    self.jumps_exceeded.push((ac, setup));
                    self.tried
                        .push(rejected(candidate, ev, Rejection::TooManyJumps));
                }
                continue;
            }
            attempts += 1;
            match self.try_candidate(round, candidate, ev) {
                Ok(()) => return Attempt::Added,
                Err(rejection) => self.tried.push(rejected(candidate, ev, rejection)),
            }
        }
        if self.jumps_exceeded.is_empty() {
            Attempt::NothingMore
        } else {
            Attempt::Stopped(SearchStop::JumpsPerZero {
                limit: MAX_JUMPS_PER_STREAM,
            })
        }
    }

    /// Refits with `candidate` and adds it, unless it is an outlier the data cannot
    /// attribute, cannot be determined, or leaves the lack of fit failing and no smaller
    /// ([`refused_for_lack_of_fit`]): the reason it is not added.
    fn try_candidate(
        &mut self,
        round: &Round,
        candidate: &Candidate,
        ev: &Evidence,
    ) -> Result<(), Rejection> {
        let (set, base, options) = (self.set, self.base, self.options);
        let sigma = options.sigma;
        let columns = &round.columns;
        if let Some((i, t)) = candidate.outlier {
            let twins = twins(&round.geometry, &round.studentized, i, t);
            if !twins.is_empty() && !exchangeable(base, columns, i, &twins, sigma) {
                let mut group = vec![(i, t)];
                group.extend(twins);
                for &(j, _) in &group {
                    self.suspects.insert(j);
                }
                self.unattributed_sets.push(group);
                return Err(Rejection::Unattributable);
            }
        }
        let added = candidate.terms();
        // a zero per cycle holds every jump of its stream at a cycle's start
        let absorbed: Vec<Term> = match candidate.term {
            Term::RezeroCycle { ac, setup, .. } => self
                .terms
                .iter()
                .filter(|t| {
                    matches!(t, Term::Effect(Effect::OffsetStep { ac: a, setup: s, step: None, .. }) if *a == ac && *s == setup)
                })
                .cloned()
                .collect(),
            _ => Vec::new(),
        };
        let mut new_terms: Vec<Term> = self
            .terms
            .iter()
            .filter(|t| !absorbed.contains(t))
            .cloned()
            .collect();
        new_terms.extend(added.iter().cloned());
        let new_columns = self.known.of(&new_terms);
        let Ok(fit) = base.fit(&new_columns, sigma) else {
            return Err(Rejection::NotDetermined);
        };
        let lof_new = base.lack_of_fit(set, &fit, &new_columns, options.lack_of_fit_alpha);
        // A term that acts on many cells must reduce a lack of fit the data shows,
        // judged against the pure error it leaves ([`refused_for_lack_of_fit`]); a
        // single reading is decided by its own statistic (its externally studentized
        // residual, Bonferroni over the readings): a gross error must never stay in
        // the fit for a lack of fit it has no part in.
        if candidate.outlier.is_none()
            && let Some(new) = &lof_new
            && refused_for_lack_of_fit(new, || {
                let mut full = columns.clone();
                full.extend(self.known.of(&added));
                base.lack_of_fit(set, &self.current, &full, options.lack_of_fit_alpha)
            })
        {
            return Err(Rejection::DoesNotReduceLackOfFit);
        }
        for gone in &absorbed {
            if let Some(k) = self.findings.iter().position(|f| f.terms.contains(gone)) {
                let withdrawn = self.findings.remove(k).withdrawn(Rejection::Absorbed);
                self.tried.push(withdrawn);
            }
        }
        let ([pitch_new, encoder_new], [pitch_old, encoder_old]) =
            (base.calibrated(&fit), base.calibrated(&self.current));
        let pitch_change = difference(&pitch_new, &pitch_old);
        let encoder_change = difference(&encoder_new, &encoder_old);
        let entry = FoundEffect {
            effect: candidate_effect(candidate),
            u: None,
            quadratic_u: None,
            quadratic_evidence: None,
            f_statistic: ev.f_statistic,
            p_value: ev.p_value,
            p_adjusted: ev.p_adjusted,
            residual_rms_before: self.current.residual_rms().unwrap_or(0.0),
            residual_rms_after: fit.residual_rms().unwrap_or(0.0),
            pitch_change_max: max_abs(&pitch_change),
            encoder_change_max: max_abs(&encoder_change),
            changes_calibration: true,
            studentized_residual: candidate.outlier.map(|(_, t)| t),
            dof_numerator: candidate.rank.max(1),
            drift_order: None,
            shape: Vec::new(),
            shape_u: None,
            kink: None,
            alternatives: Vec::new(),
        };
        self.findings.push(Finding {
            terms: added,
            entry,
            pitch_change,
            encoder_change,
        });
        self.terms = new_terms;
        self.current = fit;
        self.lof_current = lof_new;
        Ok(())
    }
}

/// `candidate` (with its F test `ev`) as a term tried and not added, for `rejection`.
fn rejected(candidate: &Candidate, ev: &Evidence, rejection: Rejection) -> TriedEffect {
    TriedEffect {
        effect: candidate_effect(candidate),
        quadratic: matches!(candidate.term, Term::Quadratic { .. }),
        evidence: *ev,
        rejection,
    }
}
