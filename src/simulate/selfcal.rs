//! Simulated self-calibration runs (docs/FORMAT.md §9): several read heads on one
//! graduated disc, with a known truth. [`simulate_selfcal`] documents the model, the run
//! and the random draws; `config` holds the settings, `truth` the true values and their
//! file.

mod config;
mod truth;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

pub use config::{
    MAX_DRAWN_ORDER, MAX_HARMONIC_TERMS, MIN_POSITIONS, SelfcalConfigError, SelfcalSimConfig,
};
pub use truth::{HeadErrorTruth, SelfcalTruth};

use super::SimulateError;
use super::config::Harmonic;
use crate::measurement::Direction;
use crate::selfcal::{HeadReading, SelfcalSet};

/// ChaCha stream of the drawn encoder error.
const ENCODER_STREAM: u64 = 0;
/// ChaCha stream of the reading noise.
const NOISE_STREAM: u64 = 1;
/// ChaCha stream of the head errors.
const HEAD_STREAM: u64 = 2;
/// ChaCha stream of the table errors.
const TABLE_STREAM: u64 = 3;

/// The head angles of the SelfA encoder (the paper's section 1 and 3.1), degrees from
/// head 1: head 1 at 0°; the group of 3 equally spaced heads adds 120° and 240° (heads 2
/// and 3); the group of 4 adds 90°, 180° and 270° (heads 4 … 6); the group of 7 adds
/// k·360°/7 for k = 1 … 6 (heads 7 … 12). Twelve heads; every group shares head 1.
///
/// ```
/// let angles = polycal::simulate::selfa_head_angles_deg();
/// assert_eq!(angles.len(), 12);
/// assert_eq!(&angles[..6], &[0.0, 120.0, 240.0, 90.0, 180.0, 270.0]);
/// assert_eq!(angles[6], 360.0 / 7.0);
/// ```
pub fn selfa_head_angles_deg() -> Vec<f64> {
    let mut angles = vec![0.0, 120.0, 240.0, 90.0, 180.0, 270.0];
    angles.extend((1..7).map(|k| f64::from(k) * 360.0 / 7.0));
    angles
}

/// The angles of `m` equally spaced heads, degrees from head 1: k·360°/m for k = 0 … m−1
/// (empty for m = 0).
///
/// ```
/// assert_eq!(polycal::simulate::equally_spaced_head_angles_deg(4), vec![0.0, 90.0, 180.0, 270.0]);
/// ```
pub fn equally_spaced_head_angles_deg(m: usize) -> Vec<f64> {
    (0..m).map(|k| k as f64 * 360.0 / m as f64).collect()
}

/// The sum of the harmonics at `angle_deg`, in their order.
fn harmonics_at_deg(harmonics: &[Harmonic], angle_deg: f64) -> f64 {
    harmonics.iter().map(|h| h.value_at_deg(angle_deg)).sum()
}

/// The angle of position k of P, degrees.
fn position_deg(k: usize, positions: usize) -> f64 {
    k as f64 * 360.0 / positions as f64
}

/// Simulates a self-calibration run: draws the truth for `config`, then the readings of
/// every head at every stop.
///
/// # The model
///
/// At every table stop p = 0 … P−1 (nominal table angle θ_p = p·360°/P) of every cycle,
/// each head j at nominal angle ψ_j from head 1 reads the disc. The reading is
///
/// ```text
/// reading = t[cycle, p] + e(θ_p + ψ_j) + c[j] + noise
/// ```
///
/// (added in that order), with
///
/// - e the disc's graduation error, a continuous function of the angle: the sum of the
///   [`Harmonic`]s `a·cos(2π·k·θ/360° + phase)`, evaluated at the exact angle θ_p + ψ_j
///   (which need not be one of the P positions when ψ_j is not a multiple of 360°/P);
/// - c\[j\] the head's placement error, drawn uniformly in ±`head_error_arcsec`, c\[1\] = 0;
/// - t\[cycle, p\] the table's position error at that stop (the table is not repeatable),
///   normal with standard deviation `table_error_arcsec`;
/// - the noise, normal with standard deviation `noise_arcsec`.
///
/// # The run
///
/// Cycles 1 … C in time order. A clockwise cycle visits the steps 0, 1, …, P−1; with
/// `bidirectional`, cycles 2, 4, … are counter-clockwise and visit P−1, …, 0. At every stop
/// every head gives one reading; readings are ordered by time, then head. With
/// `step_seconds` = Some(s), `time_seconds` is the number of stops before this one times s
/// (shared by the heads of one stop, starting at 0); otherwise there is no time.
///
/// # Reproducibility
///
/// Everything random comes from `ChaCha8Rng::seed_from_u64(config.seed)`, each part from a
/// stream of its own, so that changing one setting changes nothing else:
///
/// - stream 0, the drawn encoder error (only when `encoder_harmonics` is empty): for the
///   orders k = 1 … `max_order` in turn, one uniform number u in \[0, 1); the harmonic of
///   order k has the amplitude `drawn_amplitude_arcsec`/√k and the phase 2π·u;
/// - stream 1, the reading noise: one standard normal per reading, in row order;
/// - stream 2, the head errors: one uniform number u in \[0, 1) per head 2 … M, in head
///   order, c\[j\] = `head_error_arcsec`·(2u − 1);
/// - stream 3, the table errors: one standard normal per (cycle, step), cycle 1 first and
///   within a cycle step 0 first (whatever the direction of the cycle).
///
/// Draws are taken even when a spread is 0. The same configuration gives the same readings
/// and truth bit for bit (with the same versions of `rand_chacha` and `rand_distr`).
///
/// The set's `positions` is P; its readings have `line` 0.
///
/// # Example
///
/// ```
/// use polycal::simulate::{SelfcalSimConfig, equally_spaced_head_angles_deg, simulate_selfcal};
///
/// // Four equally spaced heads, 12 positions, without table error and noise.
/// let mut config = SelfcalSimConfig::default();
/// config.positions = 12;
/// config.head_angles_deg = equally_spaced_head_angles_deg(4);
/// config.table_error_arcsec = 0.0;
/// config.noise_arcsec = 0.0;
/// let (set, truth) = simulate_selfcal(&config)?;
/// assert_eq!(set.positions, 12);
/// assert_eq!(set.readings.len(), 2 * 12 * 4); // cycles · positions · heads
/// let r = &set.readings[5]; // cycle 1, step 1, head 2 (at 90°): reads the disc at 120°
/// assert_eq!((r.cycle, r.step, r.head, r.head_angle_deg), (1, 1, 2, 90.0));
/// let expected = truth.encoder_error_at_deg(120.0) + truth.head_error_of(2).unwrap();
/// assert!((r.reading_arcsec - expected).abs() < 1e-12);
/// # Ok::<(), polycal::simulate::SimulateError>(())
/// ```
///
/// # Errors
///
/// [`SimulateError::SelfcalConfig`] for invalid settings
/// ([`SelfcalSimConfig::validate`]), before anything is drawn; [`SimulateError::Selfcal`]
/// if the readings break a rule of the self-calibration file (not expected).
pub fn simulate_selfcal(
    config: &SelfcalSimConfig,
) -> Result<(SelfcalSet, SelfcalTruth), SimulateError> {
    config.validate()?;
    let truth = SelfcalTruth::draw(config);
    let p_count = config.positions;
    let heads = &config.head_angles_deg;
    let m = heads.len();
    // e at every (step, head), read in every cycle: evaluated once.
    let mut encoder = Vec::with_capacity(p_count * m);
    for step in 0..p_count {
        let table_deg = position_deg(step, p_count);
        for &psi in heads {
            encoder.push(harmonics_at_deg(&truth.encoder_harmonics, table_deg + psi));
        }
    }
    let head_error: Vec<f64> = (1..=m as u32)
        .map(|head| truth.head_error_of(head).unwrap_or(0.0))
        .collect();

    let mut noise_rng = ChaCha8Rng::seed_from_u64(config.seed);
    noise_rng.set_stream(NOISE_STREAM);
    let mut readings = Vec::with_capacity(config.reading_count());
    let mut stop: usize = 0;
    for cycle in 1..=config.cycles {
        let direction = if config.bidirectional && cycle % 2 == 0 {
            Direction::Ccw
        } else {
            Direction::Cw
        };
        for i in 0..p_count {
            let step = match direction {
                Direction::Cw => i,
                Direction::Ccw => p_count - 1 - i,
            };
            let t = truth.table_error[cycle as usize - 1][step];
            let time_seconds = config.step_seconds.map(|s| stop as f64 * s);
            for (j, &head_angle_deg) in heads.iter().enumerate() {
                let z: f64 = StandardNormal.sample(&mut noise_rng);
                let reading_arcsec =
                    t + encoder[step * m + j] + head_error[j] + config.noise_arcsec * z;
                readings.push(HeadReading {
                    cycle,
                    step,
                    head: j as u32 + 1,
                    head_angle_deg,
                    reading_arcsec,
                    direction,
                    time_seconds,
                    line: 0,
                });
            }
            stop += 1;
        }
    }
    let set = SelfcalSet::from_readings(readings, Some(p_count)).map_err(SimulateError::Selfcal)?;
    Ok((set, truth))
}
