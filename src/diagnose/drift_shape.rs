//! A time term the data demand: before a zero whose drift the model does not follow is
//! called wandering, the shapes of drift the catalogue can express are tried — the
//! polynomial orders up to [`MAX_DRIFT_ORDER`] and a drift whose rate changes at a time
//! the data locate (continuous and piecewise linear, [`Term::DriftKink`]) — and the one
//! the data demand is kept.
//!
//! # The rule
//!
//! For an autocollimator whose zero shows time structure the final model does not follow
//! ([`Model::time_structure`]) and that has a drift in the model, let M_line be the model
//! with that autocollimator's drift orders and jumps replaced by its linear drift. Every
//! shape beyond the line is one candidate of one family, tested against M_line by an
//! extra-sum-of-squares F test with a Bonferroni threshold `family_alpha` (the search's
//! level) over the family's size m = (polynomial orders tried) + (kink positions tried):
//! the orders 2 … 4 (their columns together, r = k − 1 numerator degrees of freedom), and
//! the hinge max(0, t − t_k) at each of at most [`MAX_KINK_POSITIONS`] positions t_k
//! spread evenly over the stops of the stream's middle 80 % (one degree of freedom; the
//! position with the largest reduction of the residual sum of squares is the kink the
//! data locate, and its Bonferroni factor counts every position tried). Of the line and
//! the significant shapes, the one with the fewest columns (then the smallest residual sum
//! of squares) whose fit leaves no time structure of that zero — its streams' serial
//! correlation and slow variation pass, its drift has the same shape in both halves of
//! the run —, no failing lack of fit, and to which the jumps of that zero it replaces add
//! nothing significant (their F test at `family_alpha`, Bonferroni over the stops of the
//! stream, as the search found them) is kept; those jumps are withdrawn as explained by the drift's
//! shape. When none passes, nothing changes and the
//! rules of doubt leave the zero out as a wander, as before.
//!
//! # Why the false-alarm rates stay as stated
//!
//! The shapes are tried only for a drift already in the model (found by the search at its
//! stated level) whose zero the model does not follow: on clean data that needs a false
//! drift first (at most `family_alpha` of runs), so the chance of a false effect on a clean
//! run is unchanged, and the verdict can only move from "not adequate" to a model that
//! passes every check. A shape is kept only when its own F test passes at `family_alpha`
//! with its family's Bonferroni factor and the checks of the final model pass with it.

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::candidates::{MAX_DRIFT_ORDER, Term};
use super::clock::Clock;
use super::doubt::Model;
use super::{DiagnoseOptions, Evidence, Rejection, TriedEffect};
use crate::effects::Effect;
use crate::solve::Solution;
use crate::uncertainty::student::t_two_sided_tail;

/// The most kink positions tried for one drift (evenly spread over the stops of the
/// stream's middle 80 %): the Bonferroni factor of the kink search.
pub const MAX_KINK_POSITIONS: usize = 300;

/// The fraction of a stream's stops at either end where no kink is tried (a kink there is
/// seen by too few readings to be told from a bad reading or a curvature).
const KINK_EDGE_FRACTION: f64 = 0.1;

/// A drift whose rate changes at a time the data locate (docs/FORMAT.md §6, `drift`'s
/// `kink`): continuous and piecewise linear, its rate before the kink the drift's value.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct DriftKink {
    /// Where the rate changes, seconds of the run's `time` (on the stop clock: the stop's
    /// ordinal × 3600, reported as the ordinal).
    pub at_seconds: f64,
    /// The change of rate at the kink, arcsec/h (per stop on the stop clock).
    pub rate_change: f64,
    /// Its standard uncertainty in the final model.
    pub rate_change_u: Option<f64>,
    /// The F test of the kink against the linear drift, its p-value times the size of the
    /// drift shapes' family (the kink positions tried and the polynomial orders).
    pub evidence: Evidence,
    /// The kink positions tried.
    pub positions_tried: usize,
}

/// The shape kept for a drift the model did not follow.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct ChosenShape {
    /// Its autocollimator.
    pub ac: u32,
    /// The polynomial order kept (1: the line; with `kink`, the line and its kink).
    pub order: usize,
    /// The kink kept, if one.
    pub kink: Option<DriftKink>,
    /// The shape's F test against the line (`None` for the line itself).
    pub evidence: Option<Evidence>,
    /// The jumps of that zero it replaced.
    pub jumps_replaced: usize,
}

impl ChosenShape {
    /// The plain words on it.
    pub fn note(&self, clock: Clock) -> String {
        let unit = clock.drift_unit_text();
        let shape = match (&self.kink, self.order) {
            (Some(kink), _) => {
                let at = match clock {
                    Clock::Time => format!("t = {:.0} s", kink.at_seconds),
                    Clock::StopOrder => format!("stop {:.0}", kink.at_seconds / 3600.0),
                };
                format!(
                    "a drift whose rate changes by {:+.4}{unit} at {at} (continuous, piecewise linear; the kink located among {} positions)",
                    kink.rate_change, kink.positions_tried
                )
            }
            (None, 1) => "a linear drift".to_string(),
            (None, order) => format!("a drift of polynomial order {order}"),
        };
        let evidence = self.evidence.map_or(String::new(), |e| {
            format!(
                " (F = {:.1} against the line, Bonferroni p = {:.2e})",
                e.f_statistic, e.p_adjusted
            )
        });
        let jumps = match self.jumps_replaced {
            0 => String::new(),
            1 => "; it explains the jump of that zero found beside the drift".into(),
            n => format!("; it explains the {n} jumps of that zero found beside the drift"),
        };
        format!(
            "The zero of autocollimator {} does not follow the drift first found; before calling it a wander, the drift shapes the catalogue allows were tried, and {shape}{evidence} leaves no time structure and no lack of fit{jumps}.",
            self.ac
        )
    }
}

/// One shape tried for a drift: its terms (the model's others included), its fit and its
/// evidence against the line.
struct Trial {
    terms: Vec<Term>,
    fit: Solution,
    order: usize,
    kink: Option<(f64, Evidence)>,
    evidence: Option<Evidence>,
}

/// The F test of `rank` columns that bring `fit`'s residual sum of squares down from
/// `rss_line`, Bonferroni over `family`.
fn shape_evidence(rss_line: f64, fit: &Solution, rank: usize, family: usize) -> Option<Evidence> {
    let dof = fit.dof;
    if dof == 0 || fit.rss <= 0.0 {
        return None;
    }
    let f_statistic = ((rss_line - fit.rss).max(0.0) / rank as f64) / (fit.rss / dof as f64);
    let p_value = if rank == 1 {
        t_two_sided_tail(f_statistic.sqrt(), Some(dof as f64))
    } else {
        FisherSnedecor::new(rank as f64, dof as f64).map_or(1.0, |d| d.sf(f_statistic))
    };
    Some(Evidence {
        f_statistic,
        p_value,
        p_adjusted: (p_value * family as f64).min(1.0),
    })
}

/// The kink positions of autocollimator `ac`'s stream: the distinct clock times of its
/// stops, the first and last [`KINK_EDGE_FRACTION`] left out, at most
/// [`MAX_KINK_POSITIONS`] of them evenly spread.
fn kink_positions(model: &Model<'_>, ac: u32) -> Vec<f64> {
    let mut times: Vec<f64> = model
        .set
        .readings
        .iter()
        .filter(|r| r.ac == ac)
        .filter_map(|r| r.time_seconds)
        .collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let edge = (KINK_EDGE_FRACTION * times.len() as f64).ceil() as usize;
    if times.len() < 2 * edge + 1 || edge < 2 {
        return Vec::new();
    }
    let inner = &times[edge..times.len() - edge];
    if inner.len() <= MAX_KINK_POSITIONS {
        return inner.to_vec();
    }
    (0..MAX_KINK_POSITIONS)
        .map(|k| inner[k * (inner.len() - 1) / (MAX_KINK_POSITIONS - 1)])
        .collect()
}

impl Model<'_> {
    /// For every autocollimator whose zero the model does not follow and that has a drift
    /// in the model, the drift shape the data demand, when one leaves no time structure
    /// and no lack of fit (module documentation); the model takes it, the jumps it
    /// replaces go to `tried`. Returns the shapes kept.
    pub fn demanded_drift_shapes(
        &mut self,
        options: &DiagnoseOptions,
        tiny: f64,
        tried: &mut Vec<TriedEffect>,
    ) -> Vec<ChosenShape> {
        let (flagged, _) = self.time_structure(options, tiny);
        let mut chosen = Vec::new();
        for ac in flagged {
            if !self.terms.iter().any(|t| t.is_drift_of(ac)) {
                continue;
            }
            if let Some(shape) = self.demanded_shape(ac, options, tiny, tried) {
                chosen.push(shape);
            }
        }
        chosen
    }

    /// The shape kept for autocollimator `ac`'s drift, if one passes.
    fn demanded_shape(
        &mut self,
        ac: u32,
        options: &DiagnoseOptions,
        tiny: f64,
        tried: &mut Vec<TriedEffect>,
    ) -> Option<ChosenShape> {
        let is_jump =
            |t: &Term| matches!(t, Term::Effect(Effect::OffsetStep { ac: a, .. }) if *a == ac);
        let others: Vec<Term> = self
            .terms
            .iter()
            .filter(|t| !t.is_drift_of(ac) && !is_jump(t))
            .cloned()
            .collect();
        let with = |extra: Vec<Term>| -> Vec<Term> {
            let mut terms = others.clone();
            terms.extend(extra);
            terms
        };
        let line_terms = with(vec![Term::drift_of_order(ac, 1)]);
        let line_columns = self.columns(&line_terms);
        let line = self.base.fit(&line_columns, self.sigma).ok()?;
        let readings = self.set.readings.iter().filter(|r| r.ac == ac).count();
        let orders: Vec<usize> = (2..=MAX_DRIFT_ORDER)
            .take_while(|&k| readings >= 4 * k)
            .collect();
        let positions = kink_positions(self, ac);
        let family = orders.len() + positions.len();
        let mut trials = vec![Trial {
            terms: line_terms.clone(),
            fit: line.clone(),
            order: 1,
            kink: None,
            evidence: None,
        }];
        for &order in &orders {
            let terms = with((1..=order).map(|k| Term::drift_of_order(ac, k)).collect());
            let Ok(fit) = self.base.fit(&self.columns(&terms), self.sigma) else {
                continue;
            };
            let evidence = shape_evidence(line.rss, &fit, order - 1, family);
            trials.push(Trial {
                terms,
                fit,
                order,
                kink: None,
                evidence,
            });
        }
        if !positions.is_empty() {
            let geometry = self.base.geometry(&line, &line_columns);
            let best = positions
                .iter()
                .map(|&at_seconds| {
                    let column = Term::DriftKink { ac, at_seconds }.column(self.set, self.context);
                    (
                        at_seconds,
                        geometry.score(&column, &line.residuals).reduction(),
                    )
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((at_seconds, reduction)) = best
                && reduction > tiny
            {
                let terms = with(vec![
                    Term::drift_of_order(ac, 1),
                    Term::DriftKink { ac, at_seconds },
                ]);
                if let Ok(fit) = self.base.fit(&self.columns(&terms), self.sigma) {
                    let evidence = shape_evidence(line.rss, &fit, 1, family);
                    trials.push(Trial {
                        terms,
                        fit,
                        order: 1,
                        kink: evidence.map(|e| (at_seconds, e)),
                        evidence,
                    });
                }
            }
        }
        // the line and the significant shapes, fewest columns first, then the best fit
        trials.retain(|t| {
            t.evidence
                .is_none_or(|e| e.p_adjusted < options.family_alpha)
        });
        trials.sort_by(|a, b| {
            a.terms
                .len()
                .cmp(&b.terms.len())
                .then(a.fit.rss.total_cmp(&b.fit.rss))
        });
        let current_terms = self.terms.clone();
        for trial in trials {
            let Some((fit, lack_of_fit)) = self.refitted(&trial.terms) else {
                continue;
            };
            if lack_of_fit.as_ref().is_some_and(|lof| !lof.passed()) {
                continue;
            }
            // the jumps of that zero it would replace must add nothing significant to it
            // (at the search's level for a jump, Bonferroni over the stream's stops)
            if self.jumps_still_significant(&current_terms, &trial.terms, &fit, options) {
                continue;
            }
            // judged as the final model would be: the trial in the model's place
            let saved = (
                std::mem::replace(&mut self.terms, trial.terms.clone()),
                std::mem::replace(&mut self.fit, fit),
                std::mem::replace(&mut self.lack_of_fit, lack_of_fit),
            );
            let (flagged, _) = self.time_structure(options, tiny);
            if flagged.contains(&ac) {
                (self.terms, self.fit, self.lack_of_fit) = saved;
                continue;
            }
            return Some(self.adopt(ac, &current_terms, &trial, tried));
        }
        None
    }

    /// Whether the jumps among `before` that `trial` leaves out still reduce the residuals
    /// of its fit `fit` significantly: their F test, its p-value times the readings of the
    /// zero's stream (the stops a jump was searched at), below `family_alpha`.
    fn jumps_still_significant(
        &self,
        before: &[Term],
        trial: &[Term],
        fit: &Solution,
        options: &DiagnoseOptions,
    ) -> bool {
        let jumps: Vec<Term> = before
            .iter()
            .filter(|t| !trial.contains(t))
            .filter(|t| matches!(t, Term::Effect(Effect::OffsetStep { .. })))
            .cloned()
            .collect();
        if jumps.is_empty() {
            return false;
        }
        let geometry = self.base.geometry(fit, &self.columns(trial));
        let score = geometry.score_block(&self.columns(&jumps), &fit.residuals);
        if score.rank == 0 || fit.dof <= score.rank {
            return false;
        }
        let dof = fit.dof - score.rank;
        let rest = (fit.rss - score.reduction).max(0.0);
        if rest <= 0.0 {
            return true;
        }
        let f = (score.reduction.max(0.0) / score.rank as f64) / (rest / dof as f64);
        let p = FisherSnedecor::new(score.rank as f64, dof as f64).map_or(1.0, |d| d.sf(f));
        let of_ac = |t: &Term| match *t {
            Term::Effect(Effect::OffsetStep { ac, .. }) => Some(ac),
            _ => None,
        };
        let stops = self
            .set
            .readings
            .iter()
            .filter(|r| jumps.iter().filter_map(of_ac).any(|ac| ac == r.ac))
            .count();
        p * (stops.max(1) as f64) < options.family_alpha
    }

    /// The model has taken `trial`'s terms: the drift's finding holds its terms (and its
    /// kink), the jumps of that zero among `before` are withdrawn.
    fn adopt(
        &mut self,
        ac: u32,
        before: &[Term],
        trial: &Trial,
        tried: &mut Vec<TriedEffect>,
    ) -> ChosenShape {
        let drift_terms: Vec<Term> = trial
            .terms
            .iter()
            .filter(|t| t.is_drift_of(ac))
            .cloned()
            .collect();
        let replaced: Vec<Term> = before
            .iter()
            .filter(|t| !trial.terms.contains(t))
            .filter(|t| matches!(t, Term::Effect(Effect::OffsetStep { .. })))
            .cloned()
            .collect();
        let mut first_drift = true;
        let mut jumps_replaced = 0;
        let kink = trial.kink.map(|(at_seconds, evidence)| DriftKink {
            at_seconds,
            rate_change: 0.0,
            rate_change_u: None,
            evidence,
            positions_tried: 0,
        });
        let positions = kink_positions(self, ac).len();
        self.findings.retain_mut(|finding| {
            if finding.terms.iter().any(|t| t.is_drift_of(ac)) {
                if !first_drift {
                    return false;
                }
                first_drift = false;
                finding.terms = drift_terms.clone();
                finding.entry.kink = kink.map(|k| DriftKink {
                    positions_tried: positions,
                    ..k
                });
                return true;
            }
            if finding.terms.iter().any(|t| replaced.contains(t)) {
                tried.push(finding.withdrawn(Rejection::ExplainedByDriftShape));
                jumps_replaced += 1;
                return false;
            }
            true
        });
        ChosenShape {
            ac,
            order: trial.order,
            kink: kink.map(|k| DriftKink {
                positions_tried: positions,
                ..k
            }),
            evidence: trial.evidence,
            jumps_replaced,
        }
    }
}
