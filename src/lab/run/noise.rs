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
//!
//! A stop whose readings the pool of the other stops would refuse now is left out of the
//! pool ([`SET_ASIDE_MOST`] such stops at most, the widest first). The first stops are
//! judged by the stated noise alone, which lets through a pair of readings far apart (a
//! sign lost on the way, X and Y exchanged, a burst of air for one reading): pooled, that
//! one pair would raise s for the rest of the run, and with it the tolerance of every
//! stop and the floor of the check after every cycle, so that the reading stored from
//! it would never be judged by the noise the run measured. Honest stops are left out
//! with probability 2Φ(−5) each, which takes nothing measurable off s.

use serde::{Deserialize, Serialize};
use statrs::function::beta::checked_beta_reg;
use statrs::function::erf::erfc;

use super::settings::AGREEMENT_SIGMAS;

/// The smallest repeat noise the run takes from its own readings, arcsec: readings that
/// repeat to the last printed digit do not make the tolerance zero.
pub const NOISE_FLOOR_ARCSEC: f64 = 0.002;

/// The most stops of the widest spread a pool keeps apart, to be left out of it when the
/// other stops would refuse their readings (module documentation).
pub(super) const SET_ASIDE_MOST: usize = 4;

/// One stop's readings as a pool remembers them: their spread (largest minus smallest),
/// the sum of their squared deviations from their mean, and its degrees of freedom.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct StopScatter {
    spread_arcsec: f64,
    sum_squares_arcsec2: f64,
    dof: u32,
}

/// One autocollimator's repeated readings at the stops so far: the sum of their squared
/// deviations from each stop's mean, and its degrees of freedom (readings at a stop
/// minus one, summed over the stops), with the four stops of the widest spread
/// remembered apart: those the other stops would refuse are left out of the pool
/// (module documentation).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RepeatNoise {
    /// The sum of squares of the stops not among `widest`.
    sum_squares_arcsec2: f64,
    /// Its degrees of freedom.
    dof: u32,
    /// The widest stops so far, widest first.
    widest: [Option<StopScatter>; SET_ASIDE_MOST],
    /// How many of `widest`, from the first, the pool leaves out (decided when a stop is
    /// added, [`RepeatNoise::left_out`]).
    left_out: usize,
}

impl RepeatNoise {
    /// Adds the X of the readings accepted at one stop (their mean stored).
    pub fn add_stop(&mut self, x_arcsec: &[f64]) {
        if x_arcsec.len() < 2 || x_arcsec.iter().any(|x| !x.is_finite()) {
            return;
        }
        let mean = x_arcsec.iter().sum::<f64>() / x_arcsec.len() as f64;
        let stop = StopScatter {
            spread_arcsec: x_arcsec.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - x_arcsec.iter().copied().fold(f64::INFINITY, f64::min),
            sum_squares_arcsec2: x_arcsec.iter().map(|x| (x - mean).powi(2)).sum::<f64>(),
            dof: x_arcsec.len() as u32 - 1,
        };
        // Kept among the widest, in order; the narrowest of them, or the stop itself,
        // joins the rest.
        let mut carried = Some(stop);
        for slot in &mut self.widest {
            match (*slot, carried) {
                (_, None) => break,
                (None, _) => {
                    *slot = carried.take();
                }
                (Some(kept), Some(new)) if new.spread_arcsec > kept.spread_arcsec => {
                    *slot = Some(new);
                    carried = Some(kept);
                }
                _ => {}
            }
        }
        if let Some(rest) = carried {
            self.sum_squares_arcsec2 += rest.sum_squares_arcsec2;
            self.dof += rest.dof;
        }
        self.left_out = self.left_out();
    }

    /// The pool once the `k` widest stops are left out: (sum of squares, degrees of
    /// freedom).
    fn without_widest(&self, k: usize) -> (f64, u32) {
        self.widest
            .iter()
            .flatten()
            .skip(k)
            .fold((self.sum_squares_arcsec2, self.dof), |(sum, dof), stop| {
                (sum + stop.sum_squares_arcsec2, dof + stop.dof)
            })
    }

    /// How many stops the pool leaves out: of the widest stops, widest first, each whose
    /// spread lies beyond the agreement tolerance (√2·s·q_ν at [`AGREEMENT_SIGMAS`], not
    /// bounded by the stated noise) of the pool without it and the stops left out before
    /// it — the stops the others would refuse now; the first that does not ends the
    /// search.
    fn left_out(&self) -> usize {
        let mut left_out = 0;
        for stop in self.widest.iter().flatten() {
            let (sum_squares_arcsec2, dof) = self.without_widest(left_out + 1);
            if dof == 0 {
                break;
            }
            // q_ν ≥ q_∞ = AGREEMENT_SIGMAS: a spread within √2·s·q_∞ is within the
            // tolerance, without the quantile (every honest stop, nearly).
            let s = (sum_squares_arcsec2 / f64::from(dof)).sqrt();
            if stop.spread_arcsec
                <= std::f64::consts::SQRT_2 * s.max(NOISE_FLOOR_ARCSEC) * AGREEMENT_SIGMAS
            {
                break;
            }
            let others = RepeatNoise {
                sum_squares_arcsec2,
                dof,
                ..RepeatNoise::default()
            };
            if stop.spread_arcsec <= others.agreement_at(f64::INFINITY, AGREEMENT_SIGMAS) {
                break;
            }
            left_out += 1;
        }
        left_out
    }

    /// The pool the run judges by: (sum of squares, degrees of freedom) of every stop
    /// but those left out ([`RepeatNoise::left_out`]).
    fn pool(&self) -> (f64, u32) {
        self.without_widest(self.left_out)
    }

    /// How many stops the pool leaves out: stops whose readings the other stops would
    /// refuse now (module documentation).
    pub fn set_aside(&self) -> usize {
        self.left_out
    }

    /// The pool a manifest recorded ([`NoiseRecord`]): s² on ν degrees of freedom, as
    /// the session before left it, for a resumed session to go on from.
    pub fn from_record(record: &NoiseRecord) -> RepeatNoise {
        match record.measured_arcsec {
            Some(s) if s.is_finite() && s >= 0.0 && record.dof > 0 => RepeatNoise {
                sum_squares_arcsec2: s * s * f64::from(record.dof),
                dof: record.dof,
                ..RepeatNoise::default()
            },
            _ => RepeatNoise::default(),
        }
    }

    /// The degrees of freedom pooled, ν (of the stops not left out).
    pub fn dof(&self) -> u32 {
        self.pool().1
    }

    /// The pooled standard deviation s of one reading, arcsec (of the stops not left
    /// out); `None` before any stop.
    pub fn measured_arcsec(&self) -> Option<f64> {
        let (sum_squares, dof) = self.pool();
        (dof > 0).then(|| (sum_squares / f64::from(dof)).sqrt())
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
        let (sum_squares, dof) = self.pool();
        if dof == 0 {
            return stated;
        }
        let s = (sum_squares / f64::from(dof)).sqrt();
        let q = t_quantile_two_sided(f64::from(dof), erfc(sigmas / std::f64::consts::SQRT_2));
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

    /// A pair far apart at the first stop, let through by the stated noise (a sign lost
    /// on one reading), is left out of the pool once the other stops show it lies beyond
    /// their agreement: s and σ_used are those of the honest stops, and the tolerance of
    /// every later stop with them. Before the others can tell (few degrees of freedom,
    /// q_ν huge) it stays in.
    #[test]
    fn a_pair_the_other_stops_would_refuse_is_left_out_of_the_pool() {
        let stated = 0.35;
        // Honest pairs 0.1″ apart: s = 0.1/√2.
        let honest = [0.0, 0.1];
        let mut noise = RepeatNoise::default();
        // 1.45″ apart: within the stated 5·√2·0.35 = 2.47″.
        noise.add_stop(&[0.725, -0.725]);
        assert!(1.45 < noise.agreement_arcsec(stated));
        noise.add_stop(&honest);
        noise.add_stop(&honest);
        assert_eq!((noise.set_aside(), noise.dof()), (0, 3));
        let mut clean = RepeatNoise::default();
        for _ in 2..26 {
            noise.add_stop(&honest);
            clean.add_stop(&honest);
        }
        clean.add_stop(&honest);
        clean.add_stop(&honest);
        assert_eq!((noise.set_aside(), noise.dof()), (1, 26));
        assert_eq!(noise.measured_arcsec(), clean.measured_arcsec());
        assert_eq!(
            noise.sigma_used_arcsec(stated),
            clean.sigma_used_arcsec(stated)
        );
        // Pooled, the pair would make s = √((26·0.005 + 1.05)/27) = 0.21″ and σ_used
        // 0.27″, near the stated 0.35″; left out, s is the honest 0.071″ and σ_used 0.093″.
        assert!((noise.sigma_used_arcsec(stated) - 0.093).abs() < 0.001);
        // Recorded and taken up again: the pool without it.
        let again = RepeatNoise::from_record(&NoiseRecord::of(1, 1, &noise, stated));
        assert_eq!(again.dof(), 26);
        // Honest stops alone: nothing left out, however many.
        let mut rng_like = 0.0_f64;
        let mut honest_only = RepeatNoise::default();
        for i in 0..200 {
            rng_like = (rng_like + 0.618_034).fract();
            honest_only.add_stop(&[0.0, 0.1 * (rng_like - 0.5) + 0.001 * f64::from(i % 3)]);
        }
        assert_eq!(honest_only.set_aside(), 0);
    }

    /// At most [`SET_ASIDE_MOST`] stops are left out, the widest first; one within the
    /// others' agreement ends the search.
    #[test]
    fn the_widest_stops_are_left_out_first_and_at_most_four() {
        let mut noise = RepeatNoise::default();
        for _ in 0..100 {
            noise.add_stop(&[0.0, 0.1]);
        }
        for spread in [2.0, 3.0, 4.0, 5.0, 6.0] {
            noise.add_stop(&[0.0, spread]);
        }
        assert_eq!(noise.set_aside(), SET_ASIDE_MOST);
        // The 2″ stop is still in: s above the honest 0.1/√2.
        assert!(noise.measured_arcsec().unwrap() > 0.1);
        let mut one = RepeatNoise::default();
        for _ in 0..100 {
            one.add_stop(&[0.0, 0.1]);
        }
        one.add_stop(&[0.0, 0.3]);
        one.add_stop(&[0.0, 5.0]);
        assert_eq!(one.set_aside(), 1);
    }
}
