//! Residual analysis: studentized residuals from the fit's leverages, and the adequacy
//! checks of the final model (serial correlation of the time-ordered residuals per
//! autocollimator, the lack-of-fit test against pure error, χ² against a stated reading
//! noise, outliers the data cannot attribute), with the place where structure is left.

use super::lack_of_fit::LackOfFit;
use crate::measurement::{MeasurementSet, Sigma};
use crate::solve::Solution;
use crate::uncertainty::student::normal_quantile;

/// Internally studentized residuals r_i / (s √(1 − h_ii)); `None` where the reading
/// determines its own fitted value (h_ii ≈ 1) or σ is unknown.
pub fn studentized(solution: &Solution, leverage: &[f64]) -> Vec<Option<f64>> {
    let sigma = solution.residual_rms();
    solution
        .residuals
        .iter()
        .zip(leverage)
        .map(|(r, h)| {
            let s = sigma?;
            let room = 1.0 - h;
            (room > 1e-9 && s > 0.0).then(|| r / (s * room.sqrt()))
        })
        .collect()
}

/// One adequacy check of the final model.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// What was checked, e.g. "serial correlation, setup 1 ac 2".
    pub name: String,
    /// The statistic (z for serial correlation, χ²/dof for the noise check).
    pub statistic: f64,
    /// The value beyond which the check fails.
    pub limit: f64,
    /// Whether the check passed.
    pub passed: bool,
    /// The stream (setup, ac) a check of time order is about (serial correlation, slow
    /// variation); `None` for the others.
    pub stream: Option<(u32, u32)>,
}

/// Where structure is left: a run of residuals of one stream whose sum stands out.
#[derive(Debug, Clone, PartialEq)]
pub struct StructureLeft {
    /// Polygon mounting.
    pub setup: u32,
    /// Autocollimator.
    pub ac: u32,
    /// First reading of the span: (cycle, step) and time in seconds if recorded.
    pub from: (u32, usize, Option<f64>),
    /// Last reading of the span.
    pub to: (u32, usize, Option<f64>),
    /// Mean residual over the span, arcsec.
    pub mean_residual_arcsec: f64,
    /// Number of readings in the span.
    pub readings: usize,
}

/// The verdict on the final model's residuals.
#[derive(Debug, Clone, PartialEq)]
pub struct Adequacy {
    /// Whether every check passed.
    pub adequate: bool,
    /// The checks made.
    pub checks: Vec<Check>,
    /// Where structure is left, for the failed checks.
    pub structure: Vec<StructureLeft>,
}

/// Readings of one stream in time order (by `time`, else by cycle and file order).
fn stream_order(set: &MeasurementSet, setup: u32, ac: u32) -> Vec<usize> {
    let mut order: Vec<usize> = (0..set.readings.len())
        .filter(|&i| (set.readings[i].setup, set.readings[i].ac) == (setup, ac))
        .collect();
    order.sort_by(|&a, &b| {
        let (ra, rb) = (&set.readings[a], &set.readings[b]);
        match (ra.time_seconds, rb.time_seconds) {
            (Some(ta), Some(tb)) => ta.total_cmp(&tb).then(a.cmp(&b)),
            _ => ra.cycle.cmp(&rb.cycle).then(a.cmp(&b)),
        }
    });
    order
}

/// What the adequacy checks are given besides the residuals.
#[derive(Debug, Clone, Copy)]
pub struct AdequacyInputs<'a> {
    /// The lack-of-fit test of the final model, when the design has replicated cells.
    pub lack_of_fit: Option<&'a LackOfFit>,
    /// Outliers the data could not attribute to one reading (each a pair or more).
    pub unattributed_outliers: usize,
    /// Streams (autocollimator, setup) whose zero jumped more often than a diagnosis
    /// accepts as events.
    pub jumps_exceeded: &'a [(u32, Option<u32>)],
    /// Whether the residuals are at rounding level (noise-free data): the serial
    /// correlation of rounding errors means nothing.
    pub exact: bool,
}

/// Checks the final model's residuals for structure the model lacks.
///
/// - The lack-of-fit F test against pure error ([`super::lack_of_fit`]), when cells are
///   replicated: independent of time order and of any stated σ.
/// - An outlier that the data cannot attribute to one reading fails the verdict: one of
///   the named readings is bad, and the result carries part of its error.
/// - For every (setup, ac) stream, the lag-1 autocorrelation ρ of its time-ordered
///   studentized residuals: z = ρ√n is about standard normal for independent noise;
///   slow structure (a drift the model does not carry) makes it large and positive. The
///   limit is the one-sided normal quantile at `alpha` divided among the streams.
/// - With a stated reading noise σ, χ² = RSS/σ² against χ²(dof) (Wilson–Hilferty
///   approximation of its upper quantile at `alpha`).
pub fn adequacy(
    solution: &Solution,
    set: &MeasurementSet,
    studentized: &[Option<f64>],
    stated_sigma: Option<Sigma>,
    alpha: f64,
    inputs: AdequacyInputs<'_>,
) -> Adequacy {
    let mut checks = Vec::new();
    let mut structure = Vec::new();
    if let Some(lof) = inputs.lack_of_fit {
        checks.push(Check {
            name: format!(
                "lack of fit against pure error (F with {} and {} degrees of freedom, {} of {} cells read more than once)",
                lof.dof_lack, lof.dof_pure, lof.replicated_cells, lof.cells
            ),
            statistic: lof.f_statistic,
            limit: lof.limit,
            passed: lof.passed(),
            stream: None,
        });
        checks.push(Check {
            name: format!(
                "lack of fit not too small to be true (F must not fall below the limit, its lower {} % quantile: the scatter within cells no larger than the model's lack of fit can explain)",
                100.0 * super::lack_of_fit::LOWER_TAIL_ALPHA
            ),
            statistic: lof.f_statistic,
            limit: lof.lower_limit,
            passed: !lof.too_good(),
            stream: None,
        });
    }
    if inputs.unattributed_outliers > 0 {
        checks.push(Check {
            name: "every outlier attributed to one reading (count of outliers that are not)".into(),
            statistic: inputs.unattributed_outliers as f64,
            limit: 0.0,
            passed: false,
            stream: None,
        });
    }
    for (ac, setup) in inputs.jumps_exceeded {
        checks.push(Check {
            name: format!(
                "jumps of the zero of ac {ac}{} (significant jumps; the limit is the most a run explains as events)",
                setup.map_or(String::new(), |s| format!(" in setup {s}"))
            ),
            statistic: (super::MAX_JUMPS_PER_STREAM + 1) as f64,
            limit: super::MAX_JUMPS_PER_STREAM as f64,
            passed: false,
            stream: None,
        });
    }
    if inputs.exact {
        return Adequacy {
            adequate: checks.iter().all(|c| c.passed),
            checks,
            structure,
        };
    }
    let streams: Vec<(u32, u32)> = solution
        .setup_error
        .iter()
        .map(|s| (s.setup, s.ac))
        .collect();
    let limit = normal_quantile(1.0 - alpha / streams.len().max(1) as f64);
    for &(setup, ac) in &streams {
        let order: Vec<usize> = stream_order(set, setup, ac)
            .into_iter()
            .filter(|&i| studentized[i].is_some())
            .collect();
        let e: Vec<f64> = order.iter().filter_map(|&i| studentized[i]).collect();
        if e.len() < 8 {
            continue;
        }
        let sum_squares: f64 = e.iter().map(|v| v * v).sum();
        if sum_squares <= 0.0 {
            continue;
        }
        let lag: f64 = e.windows(2).map(|w| w[0] * w[1]).sum();
        let z = lag / sum_squares * (e.len() as f64).sqrt();
        let passed = z <= limit;
        checks.push(Check {
            name: format!("serial correlation of residuals, setup {setup} ac {ac}"),
            statistic: z,
            limit,
            passed,
            stream: Some((setup, ac)),
        });
        let slow = slow_variation(&e, alpha / streams.len().max(1) as f64);
        if let Some((f, limit_f, block)) = slow {
            checks.push(Check {
                name: format!(
                    "slow variation of residuals in time, setup {setup} ac {ac} (F of the means of {block} consecutive readings)"
                ),
                statistic: f,
                limit: limit_f,
                passed: f <= limit_f,
                stream: Some((setup, ac)),
            });
        }
        let slow_failed = slow.is_some_and(|(f, limit_f, _)| f > limit_f);
        if (!passed || slow_failed)
            && let Some(span) = largest_run(set, solution, &order)
        {
            structure.push(span);
        }
    }
    if let Some(sigma) = stated_sigma
        && solution.dof > 0
    {
        let dof = solution.dof as f64;
        let sigma = sigma.arcsec();
        let chi2 = solution.rss / (sigma * sigma);
        // Wilson–Hilferty: (χ²/ν)^(1/3) ≈ N(1 − 2/(9ν), 2/(9ν))
        let a = 2.0 / (9.0 * dof);
        let z = normal_quantile(1.0 - alpha);
        let upper = dof * (1.0 - a + z * a.sqrt()).powi(3);
        checks.push(Check {
            name: format!("χ² of residuals against the stated noise σ = {sigma}″"),
            statistic: chi2 / dof,
            limit: upper / dof,
            passed: chi2 <= upper,
            stream: None,
        });
    }
    Adequacy {
        adequate: checks.iter().all(|c| c.passed),
        checks,
        structure,
    }
}

/// The length of the blocks of consecutive readings whose means the slow-variation check
/// compares: ⌊√n/2⌋, at least 4.
pub fn slow_variation_block(n: usize) -> usize {
    (((n as f64).sqrt() / 2.0).floor() as usize).max(4)
}

/// The slow-variation check of one stream's time-ordered studentized residuals `e`: a
/// one-way analysis of variance of blocks of [`slow_variation_block`] consecutive
/// readings (the last block takes the remainder), F = [between-block mean square] /
/// [within-block mean square] against the upper `alpha` quantile of F(B − 1, n − B).
/// A zero that wanders (a random walk, a drift no polynomial expresses) makes
/// neighbouring residuals alike over many lags, which the lag-1 correlation sees only
/// weakly. Returns (F, limit, block length); `None` with fewer than 3 blocks or fewer than
/// 5 degrees of freedom within them.
pub fn slow_variation(e: &[f64], alpha: f64) -> Option<(f64, f64, usize)> {
    use statrs::distribution::{ContinuousCDF, FisherSnedecor};
    let n = e.len();
    let k = slow_variation_block(n);
    let blocks = n / k;
    if blocks < 3 || n < blocks + 5 {
        return None;
    }
    let mean = e.iter().sum::<f64>() / n as f64;
    let (mut between, mut within) = (0.0, 0.0);
    for b in 0..blocks {
        let end = if b + 1 == blocks { n } else { (b + 1) * k };
        let block = &e[b * k..end];
        let m = block.iter().sum::<f64>() / block.len() as f64;
        between += block.len() as f64 * (m - mean).powi(2);
        within += block.iter().map(|v| (v - m).powi(2)).sum::<f64>();
    }
    let (df1, df2) = ((blocks - 1) as f64, (n - blocks) as f64);
    if within <= 0.0 {
        return None;
    }
    let f = (between / df1) / (within / df2);
    let limit = FisherSnedecor::new(df1, df2).ok()?.inverse_cdf(1.0 - alpha);
    Some((f, limit, k))
}

/// The contiguous run of a stream's residuals with the largest |sum| (Kadane on r and −r).
fn largest_run(
    set: &MeasurementSet,
    solution: &Solution,
    order: &[usize],
) -> Option<StructureLeft> {
    let residual = |k: usize| solution.residuals[order[k]];
    let mut best: Option<(f64, usize, usize)> = None;
    for sign in [1.0, -1.0] {
        let (mut sum, mut start) = (0.0, 0);
        for k in 0..order.len() {
            if sum <= 0.0 {
                sum = 0.0;
                start = k;
            }
            sum += sign * residual(k);
            if best.is_none_or(|(b, _, _)| sum > b) {
                best = Some((sum, start, k));
            }
        }
    }
    let (_, start, end) = best?;
    let first = &set.readings[order[start]];
    let last = &set.readings[order[end]];
    let count = end - start + 1;
    let mean = (start..=end).map(residual).sum::<f64>() / count as f64;
    Some(StructureLeft {
        setup: first.setup,
        ac: first.ac,
        from: (first.cycle, first.step, first.time_seconds),
        to: (last.cycle, last.step, last.time_seconds),
        mean_residual_arcsec: mean,
        readings: count,
    })
}
