//! The noise of each cycle and each autocollimator: one test of equal noise per run, and,
//! when it fails, the noise described as groups and the fits weighted by them.
//!
//! The groups are (setup, autocollimator, cycle). Each group's σ̂² is Σeᵢ²/Σ(1 − hᵢᵢ) over
//! its readings: the residuals e and leverages h of the final model of an unweighted
//! diagnosis (its terms and outliers in the model, so that a drift, a jump or one bad
//! reading is not taken for noise; a reading whose |studentized residual| exceeds
//! [`TRIM_T`] is left out of the sums, a reading the model fits exactly adds nothing).
//! E\[Σe²\] = σ² Σ(1 − h) exactly under equal noise, so Σ(1 − h) is the group's effective
//! degrees of freedom νg. Bartlett's statistic with those degrees of freedom,
//!
//! ```text
//! T = [ν ln s² − Σ νg ln sg²] / C,   C = 1 + (Σ 1/νg − 1/ν) / (3(k − 1)),
//! ```
//!
//! (ν = Σνg, s² = Σνg sg²/ν, k groups of νg ≥ [`MIN_GROUP_DOF`]) is referred to χ²(k − 1)
//! at the level [`NOISE_ALPHA`] (the false-alarm rate measured on clean runs:
//! docs/verdicts.md).
//!
//! When it fails, each autocollimator's cycles (in each mounting) are split at the change
//! point that the data locate best (the two-group Bartlett statistic largest), kept when
//! significant at the level with a Bonferroni factor over the splits and the streams:
//! every stream is then one group or two (the cycles before and from the change). The
//! fits of the diagnosis are then weighted by 1/σg² ([`super::base::Base::with_weights`],
//! `reweight.rs`), and the report says "autocollimator 2's noise rose from cycle 4:
//! 0.035″ → 0.105″".

use std::collections::BTreeMap;
use std::sync::Arc;

use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::measurement::MeasurementSet;

/// The default level of the test of equal noise (docs/verdicts.md).
pub const NOISE_ALPHA: f64 = 0.01;

/// A reading whose |studentized residual| in the final model exceeds this is left out of
/// its group's sums: one bad reading is an outlier, not a noisy group.
pub const TRIM_T: f64 = 5.0;

/// The least effective degrees of freedom Σ(1 − hᵢᵢ) of a group that takes part in the
/// test.
pub const MIN_GROUP_DOF: f64 = 2.0;

/// One group of the noise's description: an autocollimator's cycles of one noise.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct NoiseGroup {
    /// Mounting.
    pub setup: u32,
    /// Autocollimator.
    pub ac: u32,
    /// The cycles of the group, ascending.
    pub cycles: Vec<u32>,
    /// Its σ̂ = √(Σe²/Σ(1 − h)), arcsec.
    pub sigma_arcsec: f64,
    /// Its effective degrees of freedom Σ(1 − h).
    pub dof: f64,
}

/// A change of an autocollimator's noise the data locate.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct NoiseChange {
    /// Mounting.
    pub setup: u32,
    /// Autocollimator.
    pub ac: u32,
    /// The first cycle of the new noise.
    pub from_cycle: u32,
    /// σ̂ of the cycles before, arcsec.
    pub sigma_before_arcsec: f64,
    /// σ̂ of the cycles from `from_cycle` on, arcsec.
    pub sigma_after_arcsec: f64,
}

/// The test of equal noise of a run and the noise's description.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct NoiseTest {
    /// Whether the noise of every (setup, autocollimator, cycle) group is consistent with
    /// one σ at the level `alpha`.
    pub equal: bool,
    /// Bartlett's statistic T.
    pub statistic: f64,
    /// Its degrees of freedom, k − 1.
    pub dof: usize,
    /// P(χ²(k − 1) > T).
    pub p_value: f64,
    /// The level of the test.
    pub alpha: f64,
    /// The number of (setup, autocollimator, cycle) groups tested, k.
    pub groups: usize,
    /// The noise as groups: every autocollimator of every mounting with its cycles, split
    /// at its change when it has one.
    pub sigma: Vec<NoiseGroup>,
    /// The changes of noise the data locate (at most one per autocollimator and mounting).
    pub changes: Vec<NoiseChange>,
    /// Whether the diagnosis's fits weight each group by its own σ (the test failed and
    /// the design allows it).
    pub weighted: bool,
    /// Every tested (setup, ac, cycle) group's Σe² and Σ(1 − h).
    sums: Vec<((u32, u32, u32), Sums)>,
}

/// The most weighted diagnoses of one run: the groups' σ are estimated anew from the
/// residuals and leverages of each weighted fit (under unequal noise the unweighted fit's
/// Σe²/Σ(1 − h) mixes the groups' noise), until they change by less than
/// [`SIGMA_TOLERANCE`].
pub const MAX_WEIGHTINGS: usize = 3;

/// The relative change of every group's σ below which the weights are final.
pub const SIGMA_TOLERANCE: f64 = 0.05;

impl NoiseTest {
    /// This description with every group's σ and degrees of freedom formed anew from the
    /// sums of `refit` (a test of a weighted fit's residuals in arcsec and its whitened
    /// leverages: Σe²/Σ(1 − h_w) is then unbiased for each group's σ²), the groups and
    /// changes kept; and the largest relative change of a σ.
    pub(super) fn with_sums_of(&self, refit: &NoiseTest) -> (NoiseTest, f64) {
        let mut out = self.clone();
        let mut largest = 0.0_f64;
        for g in &mut out.sigma {
            let sums = refit
                .sums
                .iter()
                .filter(|((setup, ac, cycle), _)| {
                    *setup == g.setup && *ac == g.ac && g.cycles.contains(cycle)
                })
                .fold(Sums::default(), |a, (_, s)| Sums {
                    ss: a.ss + s.ss,
                    dof: a.dof + s.dof,
                });
            if sums.dof > 0.0 && sums.ss > 0.0 {
                let sigma = (sums.ss / sums.dof).sqrt();
                largest = largest.max((sigma / g.sigma_arcsec - 1.0).abs());
                g.sigma_arcsec = sigma;
                g.dof = sums.dof;
            }
        }
        let sigma_of = |setup: u32, ac: u32, cycle: u32, groups: &[NoiseGroup]| {
            groups
                .iter()
                .find(|g| g.setup == setup && g.ac == ac && g.cycles.contains(&cycle))
                .map(|g| g.sigma_arcsec)
        };
        let groups = out.sigma.clone();
        for c in &mut out.changes {
            if let Some(before) = groups
                .iter()
                .filter(|g| g.setup == c.setup && g.ac == c.ac)
                .find(|g| g.cycles.iter().all(|&k| k < c.from_cycle))
            {
                c.sigma_before_arcsec = before.sigma_arcsec;
            }
            if let Some(after) = sigma_of(c.setup, c.ac, c.from_cycle, &groups) {
                c.sigma_after_arcsec = after;
            }
        }
        (out, largest)
    }

    /// The whitening factor of every reading of `set` (σ_ref/σg of its group, σ_ref the
    /// pooled σ̂): the fits' weights are their squares.
    pub fn weights(&self, set: &MeasurementSet) -> Vec<f64> {
        let (ss, dof) = self.sigma.iter().fold((0.0, 0.0), |(s, d), g| {
            (s + g.sigma_arcsec * g.sigma_arcsec * g.dof, d + g.dof)
        });
        let reference = if dof > 0.0 { (ss / dof).sqrt() } else { 1.0 };
        set.readings
            .iter()
            .map(|r| {
                // the stream's last group that begins at or before the reading's cycle
                let group = self
                    .sigma
                    .iter()
                    .filter(|g| g.setup == r.setup && g.ac == r.ac)
                    .rfind(|g| g.cycles.first().is_none_or(|&first| r.cycle >= first))
                    .or_else(|| {
                        self.sigma
                            .iter()
                            .find(|g| g.setup == r.setup && g.ac == r.ac)
                    });
                match group {
                    Some(g) if g.sigma_arcsec > 0.0 => reference / g.sigma_arcsec,
                    _ => 1.0,
                }
            })
            .collect()
    }
}

/// Bartlett's statistic of groups given as (Σe², effective degrees of freedom), and its
/// degrees of freedom k − 1; `None` with fewer than two groups, no noise at all, or a
/// group without scatter (its variance below 10⁻²⁰ of the pooled one: readings the fit
/// meets to the rounding level, where the logarithm of its variance, and the statistic,
/// are not defined).
pub fn bartlett(groups: &[(f64, f64)]) -> Option<(f64, usize)> {
    let k = groups.len();
    if k < 2 {
        return None;
    }
    let (ss, nu): (f64, f64) = groups
        .iter()
        .fold((0.0, 0.0), |(s, n), &(ss, nu)| (s + ss, n + nu));
    if ss <= 0.0 || nu <= 0.0 {
        return None;
    }
    let pooled = ss / nu;
    if groups
        .iter()
        .any(|&(ss, nu)| (ss / nu).is_nan() || ss / nu <= 1e-20 * pooled)
    {
        return None;
    }
    let m = nu * pooled.ln()
        - groups
            .iter()
            .map(|&(ss, nu)| {
                if ss > 0.0 {
                    nu * (ss / nu).ln()
                } else {
                    f64::NEG_INFINITY
                }
            })
            .sum::<f64>();
    let c = 1.0
        + (groups.iter().map(|&(_, nu)| 1.0 / nu).sum::<f64>() - 1.0 / nu)
            / (3.0 * (k as f64 - 1.0));
    Some((m / c, k - 1))
}

/// P(χ²(dof) > statistic).
fn chi2_sf(statistic: f64, dof: usize) -> f64 {
    if !statistic.is_finite() {
        return 0.0;
    }
    ChiSquared::new(dof as f64).map_or(1.0, |d| d.sf(statistic.max(0.0)))
}

/// The sums of one (setup, ac, cycle) group.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Sums {
    ss: f64,
    dof: f64,
}

/// The test of equal noise of `set` from the residuals and leverages of a fit of it, at
/// level `alpha` (module documentation). `None` when fewer than two groups have
/// [`MIN_GROUP_DOF`] or the residuals are all zero.
pub fn test(
    set: &MeasurementSet,
    residuals: &[f64],
    leverage: &[f64],
    alpha: f64,
) -> Option<NoiseTest> {
    let n = set.readings.len();
    if residuals.len() != n || leverage.len() != n {
        return None;
    }
    let room = |i: usize| (1.0 - leverage[i]).max(0.0);
    let (ss, dof) = (0..n).fold((0.0, 0.0), |(s, d), i| {
        (s + residuals[i] * residuals[i], d + room(i))
    });
    if ss <= 0.0 || dof <= 0.0 {
        return None;
    }
    let pooled = (ss / dof).sqrt();
    let mut groups: BTreeMap<(u32, u32, u32), Sums> = BTreeMap::new();
    for (i, r) in set.readings.iter().enumerate() {
        let room = room(i);
        if room < 1e-9 || (residuals[i] / (pooled * room.sqrt())).abs() > TRIM_T {
            continue;
        }
        let sums = groups.entry((r.setup, r.ac, r.cycle)).or_default();
        sums.ss += residuals[i] * residuals[i];
        sums.dof += room;
    }
    groups.retain(|_, s| s.dof >= MIN_GROUP_DOF);
    let tested: Vec<(f64, f64)> = groups.values().map(|s| (s.ss, s.dof)).collect();
    let (statistic, k1) = bartlett(&tested)?;
    let p_value = chi2_sf(statistic, k1);
    let equal = p_value >= alpha;
    let (sigma, changes) = describe(&groups, alpha, !equal);
    Some(NoiseTest {
        equal,
        statistic,
        dof: k1,
        p_value,
        alpha,
        groups: tested.len(),
        sigma,
        changes,
        weighted: false,
        sums: groups.into_iter().collect(),
    })
}

/// [`test`] of a fit of a diagnosis whose fits are weighted by `weights` (whitening
/// factors) or not: the residuals in arcsec (a weighted fit's divided by wᵢ) against the
/// fit's leverages.
pub(super) fn test_of_fit(
    set: &MeasurementSet,
    weights: Option<&Arc<[f64]>>,
    residuals: &[f64],
    leverage: &[f64],
    alpha: f64,
) -> Option<NoiseTest> {
    match weights {
        Some(w) if w.len() == residuals.len() => {
            let raw: Vec<f64> = residuals.iter().zip(w.iter()).map(|(e, w)| e / w).collect();
            test(set, &raw, leverage, alpha)
        }
        _ => test(set, residuals, leverage, alpha),
    }
}

/// Every stream's groups: split at its best change point when `look_for_changes` and it
/// is significant at `alpha` (Bonferroni over the splits of every stream).
fn describe(
    groups: &BTreeMap<(u32, u32, u32), Sums>,
    alpha: f64,
    look_for_changes: bool,
) -> (Vec<NoiseGroup>, Vec<NoiseChange>) {
    let mut streams: BTreeMap<(u32, u32), Vec<(u32, Sums)>> = BTreeMap::new();
    for (&(setup, ac, cycle), &sums) in groups {
        streams.entry((setup, ac)).or_default().push((cycle, sums));
    }
    let splits: usize = streams
        .values()
        .map(|c| c.len().saturating_sub(1))
        .sum::<usize>()
        .max(1);
    let total = |cycles: &[(u32, Sums)]| {
        cycles.iter().fold(Sums::default(), |acc, (_, s)| Sums {
            ss: acc.ss + s.ss,
            dof: acc.dof + s.dof,
        })
    };
    let group = |setup: u32, ac: u32, cycles: &[(u32, Sums)]| {
        let sums = total(cycles);
        NoiseGroup {
            setup,
            ac,
            cycles: cycles.iter().map(|&(c, _)| c).collect(),
            sigma_arcsec: (sums.ss / sums.dof).sqrt(),
            dof: sums.dof,
        }
    };
    let (mut out, mut changes) = (Vec::new(), Vec::new());
    for (&(setup, ac), cycles) in &streams {
        let best = (1..cycles.len())
            .filter_map(|j| {
                let (a, b) = (total(&cycles[..j]), total(&cycles[j..]));
                bartlett(&[(a.ss, a.dof), (b.ss, b.dof)]).map(|(t, _)| (j, t))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            Some((j, t)) if look_for_changes && chi2_sf(t, 1) * (splits as f64) < alpha => {
                let (before, after) = (
                    group(setup, ac, &cycles[..j]),
                    group(setup, ac, &cycles[j..]),
                );
                changes.push(NoiseChange {
                    setup,
                    ac,
                    from_cycle: cycles[j].0,
                    sigma_before_arcsec: before.sigma_arcsec,
                    sigma_after_arcsec: after.sigma_arcsec,
                });
                out.push(before);
                out.push(after);
            }
            _ => out.push(group(setup, ac, cycles)),
        }
    }
    (out, changes)
}

/// The words of a change: "autocollimator 2's noise rose from cycle 4: 0.035″ → 0.105″"
/// (with its mounting when `several_setups`).
pub fn change_words(change: &NoiseChange, several_setups: bool) -> String {
    let verb = if change.sigma_after_arcsec >= change.sigma_before_arcsec {
        "rose"
    } else {
        "fell"
    };
    let mounting = if several_setups {
        format!(" in setup {}", change.setup)
    } else {
        String::new()
    };
    format!(
        "autocollimator {}'s noise{mounting} {verb} from cycle {}: {:.3}″ → {:.3}″",
        change.ac, change.from_cycle, change.sigma_before_arcsec, change.sigma_after_arcsec
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bartlett_of_two_groups_by_hand() {
        // s² = 1 and 4 on 4 dof each: s² pooled 2.5, M = 8 ln 2.5 − 4 ln 4,
        // C = 1 + (1/4 + 1/4 − 1/8)/3 = 1.125, T = M/C = 1.586798587…, p = 0.20778…
        let (t, dof) = bartlett(&[(4.0, 4.0), (16.0, 4.0)]).expect("two groups");
        assert_eq!(dof, 1);
        assert!((t - 1.586_798_587_123_27).abs() < 1e-12, "{t}");
        assert!((chi2_sf(t, dof) - 0.207_784_123_345_636).abs() < 1e-9);
    }

    #[test]
    fn a_group_without_scatter_leaves_the_test_undefined() {
        // Σe² = 0 in one group: ln 0 would make the statistic infinite
        assert_eq!(bartlett(&[(0.0, 3.0), (0.02, 4.0), (0.03, 5.0)]), None);
        assert!(
            bartlett(&[(1e-6, 3.0), (0.02, 4.0), (0.03, 5.0)]).is_some_and(|(t, _)| t.is_finite())
        );
    }

    #[test]
    fn bartlett_of_equal_groups_is_zero() {
        let (t, dof) = bartlett(&[(3.0, 3.0), (5.0, 5.0), (2.0, 2.0)]).expect("groups");
        assert_eq!(dof, 2);
        assert!(t.abs() < 1e-12, "{t}");
        assert!(bartlett(&[(3.0, 3.0)]).is_none());
        assert!(bartlett(&[(0.0, 3.0), (0.0, 3.0)]).is_none());
    }

    /// Four cycles of 4 faces, two adjacent autocollimators, no closing reading.
    fn small_set() -> MeasurementSet {
        use crate::measurement::{Direction, Reading, face_at};
        let mut readings = Vec::new();
        for cycle in 1..=4 {
            for step in 0..4 {
                for ac in 1..=2_u32 {
                    readings.push(Reading {
                        setup: 1,
                        cycle,
                        step,
                        ac,
                        face: face_at(step, ac as usize - 1, 4),
                        reading_arcsec: 0.0,
                        direction: Direction::Cw,
                        time_seconds: None,
                        reading_y_arcsec: None,
                        temperature_celsius: None,
                        encoder_degrees: None,
                        line: readings.len() as u64 + 2,
                    });
                }
            }
        }
        MeasurementSet::from_readings(readings, Some(4), "small.csv").expect("a valid set")
    }

    #[test]
    fn every_reading_weighs_its_groups_sigma() {
        // ac 1 one group of σ 0.03 (100 dof); ac 2 σ 0.03 in cycles 1–3 and 0.09 from
        // cycle 4 (50 dof each): σ_ref² = (0.0009·100 + 0.0009·50 + 0.0081·50)/200 = 0.0027
        let group = |ac, cycles: Vec<u32>, sigma_arcsec, dof| NoiseGroup {
            setup: 1,
            ac,
            cycles,
            sigma_arcsec,
            dof,
        };
        let test = NoiseTest {
            equal: false,
            statistic: 0.0,
            dof: 7,
            p_value: 0.0,
            alpha: NOISE_ALPHA,
            groups: 8,
            sigma: vec![
                group(1, vec![1, 2, 3, 4], 0.03, 100.0),
                group(2, vec![1, 2, 3], 0.03, 50.0),
                group(2, vec![4], 0.09, 50.0),
            ],
            changes: Vec::new(),
            weighted: false,
            sums: Vec::new(),
        };
        let set = small_set();
        let weights = test.weights(&set);
        let reference = 0.0027_f64.sqrt();
        for (r, w) in set.readings.iter().zip(&weights) {
            let sigma = if r.ac == 2 && r.cycle == 4 {
                0.09
            } else {
                0.03
            };
            assert!((w - reference / sigma).abs() < 1e-12, "{r:?}: {w}");
        }
    }

    #[test]
    fn change_in_words() {
        let change = NoiseChange {
            setup: 1,
            ac: 2,
            from_cycle: 4,
            sigma_before_arcsec: 0.035,
            sigma_after_arcsec: 0.105,
        };
        assert_eq!(
            change_words(&change, false),
            "autocollimator 2's noise rose from cycle 4: 0.035″ → 0.105″"
        );
    }
}
