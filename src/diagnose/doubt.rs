//! When in doubt, do not add: terms that approximate a structure no term expresses — a
//! string of jumps of one zero, the drifts and jumps of a zero that wanders — are left
//! out of the final model, since a fitted wander can leave β and α worse than the base
//! model. The verdict is then "not adequate" and the notes say what remains.

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::base::Base;
use super::candidates::{self, Term};
use super::findings::Finding;
use super::lack_of_fit::LackOfFit;
use super::residuals::{self, AdequacyInputs, Check};
use super::{DiagnoseOptions, Rejection, TriedEffect};
use crate::effects::{Effect, EffectContext};
use crate::measurement::{MeasurementSet, Sigma};
use crate::solve::Solution;
use crate::uncertainty::student::t_two_sided_tail;

/// Whether a term follows autocollimator `ac`'s zero in time (a drift of any order, a
/// jump): what a wandering zero makes untrustworthy.
pub(super) fn wanders_with(term: &Term, ac: u32) -> bool {
    term.is_drift_of(ac)
        || matches!(term, Term::Effect(Effect::OffsetStep { ac: a, .. }) if *a == ac)
}

/// The model at the end of the search: its terms, fit, findings and lack of fit.
pub(super) struct Model<'a> {
    /// The readings, as the file has them.
    pub set: &'a MeasurementSet,
    /// The base model they are fitted with.
    pub base: &'a Base<'a>,
    /// The effects' context.
    pub context: &'a EffectContext,
    /// The stated σ.
    pub sigma: Option<Sigma>,
    /// The lack-of-fit test's false-alarm probability.
    pub lack_of_fit_alpha: f64,
    /// The terms.
    pub terms: Vec<Term>,
    /// The fit with them.
    pub fit: Solution,
    /// The findings behind them.
    pub findings: Vec<Finding>,
    /// The lack-of-fit test of the fit.
    pub lack_of_fit: Option<LackOfFit>,
}

impl Model<'_> {
    pub(super) fn columns(&self, terms: &[Term]) -> Vec<Vec<f64>> {
        terms
            .iter()
            .map(|t| t.column(self.set, self.context))
            .collect()
    }

    /// Leaves the terms `drop` picks out of the model and refits; their findings go to
    /// `tried` with `rejection`. Whether anything was left out.
    pub fn leave_out(
        &mut self,
        drop: impl Fn(&Term) -> bool,
        rejection: Rejection,
        tried: &mut Vec<TriedEffect>,
    ) -> bool {
        let kept: Vec<Term> = self.terms.iter().filter(|t| !drop(t)).cloned().collect();
        if kept.len() == self.terms.len() {
            return false;
        }
        let Some((fit, lack_of_fit)) = self.refitted(&kept) else {
            return false;
        };
        self.findings.retain(|f| {
            let gone = f.terms.iter().any(&drop);
            if gone {
                tried.push(f.withdrawn(rejection));
            }
            !gone
        });
        (self.terms, self.fit, self.lack_of_fit) = (kept, fit, lack_of_fit);
        true
    }

    /// The fit with the terms `kept` and its lack-of-fit test (when the model had one);
    /// `None` when the refit fails.
    pub(super) fn refitted(&self, kept: &[Term]) -> Option<(Solution, Option<LackOfFit>)> {
        let columns = self.columns(kept);
        let fit = self.base.fit(&columns, self.sigma).ok()?;
        let lack_of_fit = self.lack_of_fit.as_ref().and_then(|_| {
            self.base
                .lack_of_fit(self.set, &fit, &columns, self.lack_of_fit_alpha)
        });
        Some((fit, lack_of_fit))
    }

    /// Drops a drift's highest order while it is not significant in the final model
    /// (two-sided t test of its value against its u, at `alpha`): a drift picked before a
    /// jump of the same zero may have taken higher orders to mimic the jump, which the
    /// jump then explains. Returns whether anything was dropped.
    pub fn prune_drift_orders(&mut self, alpha: f64) -> bool {
        let mut pruned = false;
        loop {
            let (Some(u), values) = (
                self.base.term_u(&self.fit),
                self.base.term_values(&self.fit),
            ) else {
                return pruned;
            };
            let dof = Some(self.fit.dof as f64);
            let weakest = candidates::autocollimators(self.set)
                .into_iter()
                .filter_map(|ac| {
                    let (j, order) = self
                        .terms
                        .iter()
                        .enumerate()
                        .filter_map(|(j, t)| t.drift_order(ac).map(|o| (j, o)))
                        .max_by_key(|&(_, o)| o)?;
                    if order < 2 || u[j] <= 0.0 {
                        return None;
                    }
                    let p = t_two_sided_tail((values[j] / u[j]).abs(), dof);
                    (p > alpha).then_some((j, p))
                })
                .max_by(|a, b| a.1.total_cmp(&b.1));
            let Some((j, _)) = weakest else {
                return pruned;
            };
            let gone = self.terms[j].clone();
            let kept: Vec<Term> = self.terms.iter().filter(|t| **t != gone).cloned().collect();
            let Some((fit, lack_of_fit)) = self.refitted(&kept) else {
                return pruned;
            };
            for finding in &mut self.findings {
                finding.terms.retain(|t| *t != gone);
            }
            (self.terms, self.fit, self.lack_of_fit) = (kept, fit, lack_of_fit);
            pruned = true;
        }
    }

    /// The autocollimators whose drifts and jumps a wandering zero makes untrustworthy
    /// (every one with such terms, when any stream's residuals fail a check of time order,
    /// a drift fails its stability check, or one zero needs several kinds of terms to
    /// follow it — a drift and jumps, a drift and a zero per cycle, jumps and a zero per
    /// cycle), and the stability checks of every drift: the drift's columns restricted to
    /// the second half of the run, tested together.
    pub fn wandering(&self, options: &DiagnoseOptions, tiny: f64) -> (Vec<u32>, Vec<Check>) {
        let (flagged, stability) = self.time_structure(options, tiny);
        let wandering = if flagged.is_empty() {
            Vec::new()
        } else {
            candidates::autocollimators(self.set)
                .into_iter()
                .filter(|&ac| self.terms.iter().any(|t| wanders_with(t, ac)))
                .collect()
        };
        (wandering, stability)
    }

    /// The autocollimators whose zero shows time structure the model does not follow —
    /// a stream's residuals failing a check of time order, a drift failing its stability
    /// check, one zero needing several kinds of terms — and the stability checks of every
    /// drift ([`Model::wandering`]).
    pub fn time_structure(&self, options: &DiagnoseOptions, tiny: f64) -> (Vec<u32>, Vec<Check>) {
        let (set, terms, current) = (self.set, &self.terms, &self.fit);
        let columns = self.columns(terms);
        let geometry = self.base.geometry(current, &columns);
        let studentized = residuals::studentized(current, &geometry.leverage());
        let check = residuals::adequacy(
            current,
            set,
            &studentized,
            self.sigma,
            options.adequacy_alpha,
            AdequacyInputs {
                lack_of_fit: None,
                unattributed_outliers: 0,
                jumps_exceeded: &[],
                exact: false,
            },
        );
        let mut flagged: Vec<u32> = check
            .checks
            .iter()
            .filter(|c| !c.passed)
            .filter_map(|c| c.stream.map(|(_, ac)| ac))
            .collect();
        let mut stability: Vec<Check> = Vec::new();
        let (lo, hi) = candidates::time_span(set);
        let middle = 0.5 * (lo + hi);
        for ac in candidates::autocollimators(set) {
            let drift: Vec<Term> = terms
                .iter()
                .filter(|t| t.is_drift_of(ac))
                .cloned()
                .collect();
            if drift.is_empty() {
                continue;
            }
            // the drift's columns restricted to the second half, scored against the
            // model's geometry: what a refit with them would reduce the residuals by
            let second_half: Vec<Vec<f64>> = drift
                .iter()
                .map(|t| {
                    let mut x = t.column(set, self.context);
                    for (v, r) in x.iter_mut().zip(&set.readings) {
                        if r.time_seconds.is_none_or(|t| t <= middle) {
                            *v = 0.0;
                        }
                    }
                    x
                })
                .collect();
            let score = geometry.score_block(&second_half, &current.residuals);
            if score.rank < drift.len() {
                // the restricted columns are not new to the model: nothing to compare
                continue;
            }
            let r = drift.len() as f64;
            let dof = current.dof.saturating_sub(drift.len()) as f64;
            let rss = (current.rss - score.reduction).max(0.0);
            if dof > 0.0
                && rss > tiny
                && let Ok(distribution) = FisherSnedecor::new(r, dof)
            {
                let f = (score.reduction.max(0.0) / r) / (rss / dof);
                let limit = distribution.inverse_cdf(1.0 - options.stability_alpha);
                let passed = f <= limit;
                if !passed {
                    flagged.push(ac);
                }
                stability.push(Check {
                    name: format!(
                        "drift of ac {ac} the same in both halves of the run (F of its {} column{} restricted to the second half)",
                        drift.len(),
                        if drift.len() == 1 { "" } else { "s" }
                    ),
                    statistic: f,
                    limit,
                    passed,
                    stream: None,
                });
            }
        }
        // a zero that needs several kinds of terms to follow it in time (a drift and
        // jumps, a drift and a zero per cycle, jumps and a zero per cycle) wanders
        for ac in candidates::autocollimators(set) {
            let drift = terms.iter().any(|t| t.is_drift_of(ac));
            let jumps = terms
                .iter()
                .any(|t| matches!(t, Term::Effect(Effect::OffsetStep { ac: a, .. }) if *a == ac));
            let rezero = terms
                .iter()
                .any(|t| matches!(t, Term::RezeroCycle { ac: a, .. } if *a == ac));
            if usize::from(drift) + usize::from(jumps) + usize::from(rezero) >= 2 {
                flagged.push(ac);
            }
        }
        flagged.sort_unstable();
        flagged.dedup();
        (flagged, stability)
    }
}
