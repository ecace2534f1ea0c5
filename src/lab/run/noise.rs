//! The noise the run measures itself: the readings repeated at every stop
//! ([`RunSettings::reads_per_stop`](super::RunSettings::reads_per_stop)) scatter by the
//! autocollimator's own noise, and their scatter pooled over the stops so far in the
//! session estimates it (docs/FORMAT.md §7.3, *The noise the run measures*).
//!
//! The estimate is kept per autocollimator: each is its own instrument with its own air
//! path, and a quiet one pooled with a noisy one would judge the noisy one's readings
//! by too small a noise. The stated `--reading-noise` bounds it from above: a stop's
//! readings agree when they lie within [`RepeatNoise::agreement_arcsec`], the smaller of
//! 5·√2·σ_stated and √2·s·q_ν, where s² is the pooled variance of the repeats on ν
//! degrees of freedom and q_ν the quantile of Student's t with ν degrees of freedom at
//! the same two-sided probability as 5 normal standard deviations, 2Φ(−5) = 5.7·10⁻⁷.
//! The repeats of a stop are independent of those pooled before it, so the difference
//! of two honest readings, divided by √2·s, is t-distributed with ν degrees of freedom:
//! two honest readings are refused with probability 2Φ(−5) exactly, as with σ known.
//! With few repeats q_ν is large (q₂ ≈ 1300, q₁₀ ≈ 13.4, q₅₀ ≈ 6.3, q_∞ = 5) and the
//! stated bound applies; no separate guard on ν is needed.

use serde::{Deserialize, Serialize};
use statrs::function::beta::checked_beta_reg;
use statrs::function::erf::erfc;

use super::settings::AGREEMENT_SIGMAS;

/// The smallest repeat noise the run takes from its own readings, arcsec: readings that
/// repeat to the last printed digit do not make the tolerance zero.
pub const NOISE_FLOOR_ARCSEC: f64 = 0.002;

/// One autocollimator's repeated readings at the stops so far: the sum of their squared
/// deviations from each stop's mean, and its degrees of freedom (readings at a stop
/// minus one, summed over the stops).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RepeatNoise {
    sum_squares_arcsec2: f64,
    dof: u32,
}

impl RepeatNoise {
    /// Adds the X of the readings accepted at one stop (their mean stored).
    pub fn add_stop(&mut self, x_arcsec: &[f64]) {
        if x_arcsec.len() < 2 || x_arcsec.iter().any(|x| !x.is_finite()) {
            return;
        }
        let mean = x_arcsec.iter().sum::<f64>() / x_arcsec.len() as f64;
        self.sum_squares_arcsec2 += x_arcsec.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
        self.dof += x_arcsec.len() as u32 - 1;
    }

    /// The pool a manifest recorded ([`NoiseRecord`]): s² on ν degrees of freedom, as
    /// the session before left it, for a resumed session to go on from.
    pub fn from_record(record: &NoiseRecord) -> RepeatNoise {
        match record.measured_arcsec {
            Some(s) if s.is_finite() && s >= 0.0 && record.dof > 0 => RepeatNoise {
                sum_squares_arcsec2: s * s * f64::from(record.dof),
                dof: record.dof,
            },
            _ => RepeatNoise::default(),
        }
    }

    /// The degrees of freedom pooled, ν.
    pub fn dof(&self) -> u32 {
        self.dof
    }

    /// The pooled standard deviation s of one reading, arcsec; `None` before any stop.
    pub fn measured_arcsec(&self) -> Option<f64> {
        (self.dof > 0).then(|| (self.sum_squares_arcsec2 / f64::from(self.dof)).sqrt())
    }

    /// How far apart the readings at a stop may lie, arcsec: the smaller of
    /// [`AGREEMENT_SIGMAS`]·√2·`stated_arcsec` and √2·s·q_ν (module doc; s not below
    /// [`NOISE_FLOOR_ARCSEC`]).
    pub fn agreement_arcsec(&self, stated_arcsec: f64) -> f64 {
        self.agreement_at(stated_arcsec, AGREEMENT_SIGMAS)
    }

    /// [`RepeatNoise::agreement_arcsec`] for `sigmas` normal standard deviations instead
    /// of [`AGREEMENT_SIGMAS`]: two honest readings lie further apart with probability
    /// 2Φ(−`sigmas`), whatever ν (what `tests/sweeps/verdict_rates_repeat_noise.rs`
    /// measures).
    pub fn agreement_at(&self, stated_arcsec: f64, sigmas: f64) -> f64 {
        let stated = sigmas * std::f64::consts::SQRT_2 * stated_arcsec;
        let Some(s) = self.measured_arcsec() else {
            return stated;
        };
        let q = t_quantile_two_sided(f64::from(self.dof), erfc(sigmas / std::f64::consts::SQRT_2));
        (std::f64::consts::SQRT_2 * s.max(NOISE_FLOOR_ARCSEC) * q).min(stated)
    }

    /// The noise σ of one reading the run judges by, arcsec: the agreement tolerance
    /// divided by [`AGREEMENT_SIGMAS`]·√2 — `stated_arcsec` until the repeats show a
    /// smaller noise with confidence, then s·q_ν/5, which tends to s. The live check's
    /// floor for a stored reading is this over √`reads`.
    pub fn sigma_used_arcsec(&self, stated_arcsec: f64) -> f64 {
        self.agreement_arcsec(stated_arcsec) / (AGREEMENT_SIGMAS * std::f64::consts::SQRT_2)
    }
}

/// What the run judged one autocollimator's readings by, as the manifest records it
/// (`repeat_noise`, docs/FORMAT.md §7.3), at the latest check after a cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct NoiseRecord {
    /// The autocollimator, 1 … K.
    pub ac: u32,
    /// The session (1 for the first) at whose check the record was made; a resumed
    /// session goes on from the pool recorded.
    pub session: usize,
    /// The degrees of freedom pooled, ν (readings at a stop minus one, summed).
    pub dof: u32,
    /// The pooled standard deviation s of one reading, arcsec; `null` before any stop.
    pub measured_arcsec: Option<f64>,
    /// The stated noise, `--reading-noise`, arcsec: the upper bound.
    pub stated_arcsec: f64,
    /// The noise of one reading the run judged by, arcsec
    /// ([`RepeatNoise::sigma_used_arcsec`]).
    pub used_arcsec: f64,
    /// The agreement tolerance of the readings at a stop, arcsec
    /// ([`RepeatNoise::agreement_arcsec`]).
    pub agreement_arcsec: f64,
}

impl NoiseRecord {
    /// The record of autocollimator `ac`'s `noise` in `session`, with the stated noise.
    pub fn of(ac: u32, session: usize, noise: &RepeatNoise, stated_arcsec: f64) -> NoiseRecord {
        NoiseRecord {
            ac,
            session,
            dof: noise.dof(),
            measured_arcsec: noise.measured_arcsec(),
            stated_arcsec,
            used_arcsec: noise.sigma_used_arcsec(stated_arcsec),
            agreement_arcsec: noise.agreement_arcsec(stated_arcsec),
        }
    }
}

/// The t such that a Student's t variable with `dof` degrees of freedom exceeds |t| with
/// probability `p` (two-sided): P(|T| > t) = I_{ν/(ν+t²)}(ν/2, 1/2), solved by bisection
/// on x = ν/(ν+t²). Infinite for `dof` 0.
fn t_quantile_two_sided(dof: f64, p: f64) -> f64 {
    if dof <= 0.0 || p.is_nan() || p <= 0.0 {
        return f64::INFINITY;
    }
    if p >= 1.0 {
        return 0.0;
    }
    let tail = |x: f64| checked_beta_reg(dof / 2.0, 0.5, x).unwrap_or(f64::NAN);
    // tail(x) rises from 0 at x = 0 to 1 at x = 1.
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        let v = tail(mid);
        if v.is_nan() {
            return f64::INFINITY;
        }
        if v < p { lo = mid } else { hi = mid }
    }
    let x = 0.5 * (lo + hi);
    if x <= 0.0 {
        return f64::INFINITY;
    }
    (dof * (1.0 - x) / x).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recorded_pool_is_the_pool() {
        let mut noise = RepeatNoise::default();
        for i in 0..30 {
            noise.add_stop(&[0.0, 0.01 * f64::from(i % 4)]);
        }
        let again = RepeatNoise::from_record(&NoiseRecord::of(1, 1, &noise, 0.1));
        assert_eq!(again.dof(), noise.dof());
        assert!((again.agreement_arcsec(0.1) - noise.agreement_arcsec(0.1)).abs() < 1e-12);
        let empty = RepeatNoise::from_record(&NoiseRecord::of(1, 1, &RepeatNoise::default(), 0.1));
        assert_eq!(empty, RepeatNoise::default());
    }

    #[test]
    fn the_t_quantile_matches_tables_and_tends_to_the_normal() {
        // t tables: two-sided 5 % at ν = 10 is 2.228, 1 % at ν = 5 is 4.032.
        assert!((t_quantile_two_sided(10.0, 0.05) - 2.228).abs() < 1e-3);
        assert!((t_quantile_two_sided(5.0, 0.01) - 4.032).abs() < 1e-3);
        // ν = 1 is Cauchy: P(|T| > t) = 1 − 2 atan(t)/π.
        let t = t_quantile_two_sided(1.0, 0.1);
        assert!((t - (std::f64::consts::FRAC_PI_2 * 0.9).tan()).abs() < 1e-6 * t);
        // Large ν: the normal's 5σ.
        let p5 = erfc(5.0 / std::f64::consts::SQRT_2);
        assert!((t_quantile_two_sided(1e7, p5) - 5.0).abs() < 1e-3);
        assert!(t_quantile_two_sided(0.0, p5).is_infinite());
    }

    #[test]
    fn the_stated_noise_rules_until_the_repeats_show_less_then_the_measured_one_does() {
        let mut noise = RepeatNoise::default();
        assert_eq!(noise.measured_arcsec(), None);
        assert!((noise.agreement_arcsec(0.1) - 0.5 * 2f64.sqrt()).abs() < 1e-12);
        // Pairs 0.04″ apart: s = 0.04/√2 per pair.
        noise.add_stop(&[1.0, 1.04]);
        assert_eq!(noise.dof(), 1);
        assert!((noise.measured_arcsec().unwrap() - 0.04 / 2f64.sqrt()).abs() < 1e-12);
        // One degree of freedom: the quantile is huge, the stated bound applies.
        assert!((noise.sigma_used_arcsec(0.1) - 0.1).abs() < 1e-12);
        for _ in 0..99 {
            noise.add_stop(&[-3.0, -2.96]);
        }
        let s = 0.04 / 2f64.sqrt();
        let used = noise.sigma_used_arcsec(0.1);
        // ν = 100: q ≈ 5.5, so σ used ≈ 1.1 s.
        assert!(used > s && used < 1.2 * s, "{used}");
        // A stated noise below the measured one bounds it.
        assert!((noise.sigma_used_arcsec(0.01) - 0.01).abs() < 1e-12);
        // Readings that repeat exactly are judged by the floor, not by zero.
        let mut exact = RepeatNoise::default();
        for _ in 0..100 {
            exact.add_stop(&[2.0, 2.0, 2.0]);
        }
        assert!(exact.agreement_arcsec(0.1) > 2f64.sqrt() * NOISE_FLOOR_ARCSEC * 5.0);
    }
}
