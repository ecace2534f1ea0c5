//! The scatter every autocollimator shares at a stop: table or encoder, not autocollimator
//! noise, and what it leaves unseen in α.
//!
//! At every stop all autocollimators look through the same table angle. When the table
//! stops a little off its nominal angle each time and the encoder's error varies faster
//! than the positions can follow (an interpolation error whose period is a few
//! arcseconds: orders far above N/2, which N positions cannot resolve), every stop
//! samples that error at another phase. The readings of one stop then share a term that
//! changes from stop to stop. The base model holds one α per position: it takes the mean
//! of that term over the stops at a position, and leaves the rest in the residuals as if
//! it were noise — but noise that two autocollimators share at a stop, so the fit's
//! u(α), which counts every reading as independent, claims more than the data show. And
//! the encoder's error at the nominal angle itself was sampled by no stop.
//!
//! [`stop_scatter`] measures that term. The final model with one more parameter per stop
//! (every stop's readings minus their mean: the per-stop nuisance nests α) leaves only
//! the autocollimators' own noise, σ², with `dof_stop` degrees of freedom; the final
//! model without it leaves, in expectation, σ²·dof + σ_s²·tr(M Z Zᵀ) (M the residual
//! projector of the final model, Z the stops' indicators). One F test at
//! [`STOP_SCATTER_ALPHA`] of the per-stop columns decides whether the scatter is there;
//! when it is, σ_s² is estimated by those moments, and every α gets the variance σ_s² on
//! top of the fit's (in the closed gauge: σ_s²·(I − J/N) on the α block,
//! [`crate::solve::Cofactor::with_encoder_variance`]): the error at the nominal angle is,
//! like the error at every stop, within that scatter of the mean the stops measured. The
//! note names the band limit.
//!
//! The computation is dense (an orthonormal basis of the final model's columns): it is
//! made for designs of up to [`MAX_PARAMETERS`] parameters (polygons of up to about 190
//! faces), and reported as not evaluated beyond.

use nalgebra::DMatrix;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::measurement::MeasurementSet;
use crate::solve::Solution;

/// False-alarm probability of the test of a scatter shared at the stops (one test per
/// run): 0.1 %. A scatter called fails the verdict and widens u(α), so the test is held
/// to the level of the verdict's other checks of structure (serial correlation, slow
/// variation); the scatters that matter for u(α) stand far above it.
pub const STOP_SCATTER_ALPHA: f64 = 0.001;

/// Largest number of the final model's columns for which the scatter is evaluated (the
/// dense basis costs readings × parameters²).
pub const MAX_PARAMETERS: usize = 400;

/// The scatter all autocollimators share at a stop ([`stop_scatter`]).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct StopScatter {
    /// The F statistic of one parameter per stop against the final model.
    pub f_statistic: f64,
    /// Its numerator degrees of freedom (the stops' columns beyond the final model's).
    pub dof_numerator: usize,
    /// Its denominator degrees of freedom (the residual dof with a parameter per stop).
    pub dof_denominator: usize,
    /// Its p-value.
    pub p_value: f64,
    /// The F at which the scatter is called ([`STOP_SCATTER_ALPHA`]'s upper quantile).
    pub f_limit: f64,
    /// Whether the scatter is there at [`STOP_SCATTER_ALPHA`].
    pub significant: bool,
    /// σ of the autocollimators' own noise (the readings of one stop against each
    /// other), arcsec.
    pub noise_sigma_arcsec: f64,
    /// σ_s of the shared scatter, estimated by moments (0 when the moments give less),
    /// arcsec.
    pub sigma_arcsec: f64,
}

/// The readings' stops: (setup, cycle, step, direction) numbered, per reading.
fn stops(set: &MeasurementSet) -> (Vec<usize>, usize) {
    let key = |r: &crate::measurement::Reading| (r.setup, r.cycle, r.step, r.direction.as_str());
    let mut keys: Vec<_> = set.readings.iter().map(key).collect();
    keys.sort_unstable();
    keys.dedup();
    let of = set
        .readings
        .iter()
        .map(|r| keys.binary_search(&key(r)).unwrap_or(0))
        .collect();
    (of, keys.len())
}

/// An orthonormal basis of the columns of `x` (n × p), by the thin SVD with the rank
/// tolerance of the largest singular value × n × ε.
fn basis(x: DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = x.nrows();
    let svd = x.svd(true, false);
    let u = svd.u?;
    let largest = svd.singular_values.iter().copied().fold(0.0, f64::max);
    let tolerance = largest * n as f64 * f64::EPSILON * 16.0;
    let kept: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&j| svd.singular_values[j] > tolerance)
        .collect();
    let mut q = DMatrix::zeros(n, kept.len());
    for (c, &j) in kept.iter().enumerate() {
        q.set_column(c, &u.column(j));
    }
    Some(q)
}

/// ‖y − Q Qᵀ y‖².
fn residual_ss(q: &DMatrix<f64>, y: &[f64]) -> f64 {
    let coefficients: Vec<f64> = (0..q.ncols())
        .map(|j| (0..q.nrows()).map(|i| q[(i, j)] * y[i]).sum())
        .collect();
    (0..q.nrows())
        .map(|i| {
            let fitted: f64 = coefficients
                .iter()
                .enumerate()
                .map(|(j, c)| q[(i, j)] * c)
                .sum();
            (y[i] - fitted).powi(2)
        })
        .sum()
}

/// The final model's columns for the readings of `set` (no shifted mountings): α per
/// position, φ per face but face N (φ\[N\] = 0), a setup error per stream, and the fit's
/// effect regressors.
fn design(set: &MeasurementSet, fit: &Solution) -> DMatrix<f64> {
    let n = set.faces;
    let streams = set.streams();
    let p = n + (n - 1) + streams.len() + fit.effect_regressors.len();
    let mut x = DMatrix::zeros(set.readings.len(), p);
    for (i, r) in set.readings.iter().enumerate() {
        x[(i, r.step % n)] = 1.0;
        if r.face < n {
            x[(i, n + r.face - 1)] = 1.0;
        }
        if let Ok(s) = streams.binary_search(&(r.setup, r.ac)) {
            x[(i, 2 * n - 1 + s)] = 1.0;
        }
        for (e, column) in fit.effect_regressors.iter().enumerate() {
            x[(i, 2 * n - 1 + streams.len() + e)] = column[i];
        }
    }
    x
}

/// The scatter the readings of `set` share at their stops beyond the final model `fit`
/// (module documentation), or `None` when it cannot be evaluated: shifted mountings, a
/// design of more than [`MAX_PARAMETERS`] columns, no stop read by two readings, or no
/// degrees of freedom left.
pub fn stop_scatter(set: &MeasurementSet, fit: &Solution) -> Option<StopScatter> {
    if set.has_shifts() || fit.residuals.len() != set.readings.len() {
        return None;
    }
    let n_readings = set.readings.len();
    let columns = 2 * set.faces - 1 + set.streams().len() + fit.effect_regressors.len();
    if columns > MAX_PARAMETERS {
        return None;
    }
    let (stop_of, stops) = stops(set);
    let x = design(set, fit);
    let y: Vec<f64> = set.readings.iter().map(|r| r.reading_arcsec).collect();
    let q_final = basis(x.clone())?;
    let rank_final = q_final.ncols();
    let rss_final = residual_ss(&q_final, &y);

    // with a parameter per stop: every reading and column minus its stop's mean
    let mut size = vec![0.0; stops];
    for &s in &stop_of {
        size[s] += 1.0;
    }
    let centred = |v: &mut [f64]| {
        let mut mean = vec![0.0; stops];
        for (value, &s) in v.iter().zip(&stop_of) {
            mean[s] += value / size[s];
        }
        for (value, &s) in v.iter_mut().zip(&stop_of) {
            *value -= mean[s];
        }
    };
    let mut y_within = y.clone();
    centred(&mut y_within);
    let mut x_within = x;
    for j in 0..x_within.ncols() {
        let mut column: Vec<f64> = x_within.column(j).iter().copied().collect();
        centred(&mut column);
        x_within.set_column(j, &nalgebra::DVector::from_vec(column));
    }
    let q_within = basis(x_within)?;
    let rss_within = residual_ss(&q_within, &y_within);
    let rank_stop = q_within.ncols() + stops;
    let dof_within = n_readings.checked_sub(rank_stop)?;
    let dof_numerator = rank_stop.checked_sub(rank_final)?;
    if dof_within == 0 || dof_numerator == 0 {
        return None;
    }
    let noise_variance = rss_within / dof_within as f64;
    let f_statistic = if noise_variance > 0.0 {
        ((rss_final - rss_within).max(0.0) / dof_numerator as f64) / noise_variance
    } else {
        0.0
    };
    let distribution = FisherSnedecor::new(dof_numerator as f64, dof_within as f64).ok()?;
    let p_value = distribution.sf(f_statistic);
    let f_limit = distribution.inverse_cdf(1.0 - STOP_SCATTER_ALPHA);

    // moments: E[RSS_final] = σ²·dof_final + σ_s²·Σ_s (n_s − ‖Q_finalᵀ z_s‖²)
    let mut projection = DMatrix::<f64>::zeros(stops, rank_final);
    for (i, &s) in stop_of.iter().enumerate() {
        for j in 0..rank_final {
            projection[(s, j)] += q_final[(i, j)];
        }
    }
    let trace: f64 = (0..stops)
        .map(|s| {
            size[s]
                - (0..rank_final)
                    .map(|j| projection[(s, j)].powi(2))
                    .sum::<f64>()
        })
        .sum();
    let dof_final = (n_readings - rank_final) as f64;
    let sigma_arcsec = if trace > 0.0 {
        ((rss_final - noise_variance * dof_final) / trace)
            .max(0.0)
            .sqrt()
    } else {
        0.0
    };
    Some(StopScatter {
        f_statistic,
        dof_numerator,
        dof_denominator: dof_within,
        p_value,
        f_limit,
        significant: p_value < STOP_SCATTER_ALPHA,
        noise_sigma_arcsec: noise_variance.sqrt(),
        sigma_arcsec,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Direction, Reading, face_at};

    fn reading(cycle: u32, step: usize, ac: u32, face: usize, value: f64) -> Reading {
        Reading {
            setup: 1,
            cycle,
            step,
            ac,
            face,
            reading_arcsec: value,
            direction: Direction::Cw,
            time_seconds: None,
            reading_y_arcsec: None,
            temperature_celsius: None,
            encoder_degrees: None,
            line: 0,
        }
    }

    /// Readings that the base model fits exactly but for a term t[stop] shared by both
    /// autocollimators: the F is infinite-like, the autocollimators' noise 0, and σ_s
    /// follows from the hand-computed moments.
    #[test]
    fn a_shared_term_alone_is_all_scatter() {
        let faces = 4;
        // t: +0.1 at every stop of cycle 1, −0.1 at every stop of cycle 2: per position
        // the mean is 0, so the base model's residuals are exactly ±0.1 on both readings
        let mut readings = Vec::new();
        for cycle in 1..=2u32 {
            let t = if cycle == 1 { 0.1 } else { -0.1 };
            for step in 0..faces {
                for (ac, offset) in [(1u32, 0usize), (2, 1)] {
                    readings.push(reading(cycle, step, ac, face_at(step, offset, faces), t));
                }
            }
        }
        let set = MeasurementSet::from_readings(readings, Some(faces), "t.csv").expect("valid");
        let fit = crate::solve::solve(&set, &crate::solve::SolveOptions::new()).expect("solves");
        assert!((fit.rss - 16.0 * 0.01).abs() < 1e-12, "RSS {}", fit.rss);
        let scatter = stop_scatter(&set, &fit).expect("evaluated");
        // within stops the readings agree exactly
        assert!(scatter.noise_sigma_arcsec < 1e-9);
        // 8 stops, the final model already holds 4 positions: 4 more columns
        assert_eq!(scatter.dof_numerator, 4);
        // trace: each stop has n_s = 2 and ‖Qᵀz_s‖² = 1 (α's indicator for the stop's
        // position holds 4 readings, two of them the stop's: (2·2)²/4... (z·q)² with
        // q = indicator/2 gives (2/2)² = 1), φ and U add nothing to a stop's sum
        // beyond it: trace = 8·(2 − 1) = 8, σ_s² = RSS/trace = 0.16/8 = 0.02
        assert!(
            (scatter.sigma_arcsec - 0.02f64.sqrt()).abs() < 1e-9,
            "{}",
            scatter.sigma_arcsec
        );
    }
}
