//! The true values behind a simulated self-calibration run, and its truth file.

use std::path::Path;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::super::SimulateError;
use super::super::config::Harmonic;
use super::super::truth::{check_noise, check_values, close};
use super::super::truth_file::{self, TruthError, TruthJson};
use super::config::{MIN_POSITIONS, SelfcalSimConfig};
use super::{ENCODER_STREAM, HEAD_STREAM, TABLE_STREAM, harmonics_at_deg, position_deg};

/// The true placement error of one head, relative to head 1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeadErrorTruth {
    /// Head number, ≥ 2.
    pub head: u32,
    /// The head's nominal angle from head 1, degrees.
    pub angle_deg: f64,
    /// Its placement error c\[head\], arcsec (c\[1\] = 0).
    pub value: f64,
}

/// The true values behind a simulated self-calibration run: the self-calibration truth
/// file (docs/FORMAT.md §4).
///
/// Two views of the same encoder error:
///
/// - `encoder_error` is e at the P positions k·360°/P **with its mean over them removed**
///   (Σe = 0), the gauge of the self-calibration model (docs/FORMAT.md §9): what a self-calibration
///   (`polycal selfcal`) estimates, to be compared with its `encoder_error`;
/// - `encoder_harmonics` is the continuous error the readings were made with:
///   [`SelfcalTruth::encoder_error_at_deg`] evaluates it at any angle, **without** removing
///   a mean. The readings use it (at θ_p + ψ_j); the same encoder can be evaluated at
///   other angles, for instance the 24 positions of a polygon calibration (pass the
///   harmonics as [`SimulationConfig::encoder_harmonics`](crate::simulate::SimulationConfig::encoder_harmonics)
///   with N = 24).
///
/// The two differ by a constant, the mean of the harmonics over the P positions, which is
/// 0 unless a harmonic's order is a multiple of P (the table error t absorbs it in the
/// readings).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SelfcalTruth {
    /// P, the number of positions.
    pub positions: usize,
    /// e at the positions k·360°/P, k = 0 … P−1, arcsec, mean removed (Σe = 0; the last
    /// is minus the sum of the others, so the sum is exactly 0 in floating point).
    pub encoder_error: Vec<f64>,
    /// The angles of `encoder_error`, k·360/P degrees; empty in a file means "compute".
    #[serde(default)]
    pub encoder_angle_deg: Vec<f64>,
    /// The placement errors of heads 2 … M, relative to head 1 (c\[1\] = 0).
    #[serde(default)]
    pub head_error: Vec<HeadErrorTruth>,
    /// The continuous encoder error: e(θ) = Σ `a·cos(2π·k·θ/360° + phase)`, θ in degrees.
    /// Empty in a hand-written file: not known (then [`SelfcalTruth::encoder_error_at_deg`]
    /// is NaN).
    #[serde(default)]
    pub encoder_harmonics: Vec<Harmonic>,
    /// The table's position error t\[cycle, step\] at every stop, arcsec:
    /// `table_error[cycle-1][step]`; empty in a hand-written file: not known.
    #[serde(default)]
    pub table_error: Vec<Vec<f64>>,
    /// Standard deviation of the reading noise the run was made with, arcsec.
    #[serde(default)]
    pub noise_arcsec: Option<f64>,
}

impl SelfcalTruth {
    /// Draws the true values for a valid `config` ([`simulate_selfcal`](super::simulate_selfcal)
    /// gives the streams and the order of the draws).
    pub(super) fn draw(config: &SelfcalSimConfig) -> SelfcalTruth {
        let rng = |stream| {
            let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
            rng.set_stream(stream);
            rng
        };
        let p_count = config.positions;
        let encoder_harmonics = if config.encoder_harmonics.is_empty() {
            let mut rng = rng(ENCODER_STREAM);
            (1..=config.max_order)
                .map(|order| {
                    let u: f64 = rng.random();
                    Harmonic {
                        order,
                        amplitude_arcsec: config.drawn_amplitude_arcsec / (order as f64).sqrt(),
                        phase_rad: std::f64::consts::TAU * u,
                    }
                })
                .collect()
        } else {
            config.encoder_harmonics.clone()
        };
        let encoder_angle_deg: Vec<f64> = (0..p_count).map(|k| position_deg(k, p_count)).collect();
        let mut encoder_error: Vec<f64> = encoder_angle_deg
            .iter()
            .map(|&angle| harmonics_at_deg(&encoder_harmonics, angle))
            .collect();
        close(&mut encoder_error);

        let mut head_rng = rng(HEAD_STREAM);
        let head_error = config
            .head_angles_deg
            .iter()
            .enumerate()
            .skip(1)
            .map(|(j, &angle_deg)| {
                let u: f64 = head_rng.random();
                HeadErrorTruth {
                    head: j as u32 + 1,
                    angle_deg,
                    value: config.head_error_arcsec * (2.0 * u - 1.0),
                }
            })
            .collect();

        let mut table_rng = rng(TABLE_STREAM);
        let table_error = (0..config.cycles)
            .map(|_| {
                (0..p_count)
                    .map(|_| {
                        let z: f64 = StandardNormal.sample(&mut table_rng);
                        config.table_error_arcsec * z
                    })
                    .collect()
            })
            .collect();

        SelfcalTruth {
            positions: p_count,
            encoder_error,
            encoder_angle_deg,
            head_error,
            encoder_harmonics,
            table_error,
            noise_arcsec: Some(config.noise_arcsec),
        }
    }

    /// The continuous encoder error at `angle_deg` (degrees, any value; taken modulo 360°):
    /// the sum of `encoder_harmonics` there, **not** mean-removed. At a position
    /// k·360°/P it differs from `encoder_error[k]` by the mean of the harmonics over the P
    /// positions (see [`SelfcalTruth`]). NaN when the truth has no harmonics.
    ///
    /// ```
    /// use polycal::simulate::{Harmonic, SelfcalSimConfig, simulate_selfcal};
    ///
    /// let mut config = SelfcalSimConfig::default();
    /// config.encoder_harmonics = vec![Harmonic { order: 2, amplitude_arcsec: 0.4, phase_rad: 0.0 }];
    /// let (_, truth) = simulate_selfcal(&config)?;
    /// assert!((truth.encoder_error_at_deg(45.0) - 0.0).abs() < 1e-12); // 0.4·cos(90°)
    /// assert!((truth.encoder_error_at_deg(180.0) - 0.4).abs() < 1e-12);
    /// # Ok::<(), polycal::simulate::SimulateError>(())
    /// ```
    pub fn encoder_error_at_deg(&self, angle_deg: f64) -> f64 {
        if self.encoder_harmonics.is_empty() {
            return f64::NAN;
        }
        harmonics_at_deg(&self.encoder_harmonics, angle_deg)
    }

    /// The true placement error c\[head\]: 0 for head 1, the `head_error` entry for the
    /// others, `None` for a head the truth does not have.
    pub fn head_error_of(&self, head: u32) -> Option<f64> {
        if head == 1 {
            return Some(0.0);
        }
        self.head_error
            .iter()
            .find(|h| h.head == head)
            .map(|h| h.value)
    }

    /// The true table error t\[cycle, step\], if the truth has it.
    pub fn table_error_at(&self, cycle: u32, step: usize) -> Option<f64> {
        let row = (cycle as usize).checked_sub(1)?;
        self.table_error.get(row)?.get(step).copied()
    }

    /// Reads a self-calibration truth file (JSON) and checks it
    /// ([`SelfcalTruth::validate`]). An empty or missing `encoder_angle_deg` is filled
    /// with k·360/P. Errors name the file, and for bad JSON also the line and column.
    /// [`TruthFile::read_path`](crate::simulate::TruthFile::read_path) reads a truth file
    /// of either kind.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Io`], [`SimulateError::Json`] or [`SimulateError::Truth`].
    pub fn read_path(path: &Path) -> Result<SelfcalTruth, SimulateError> {
        let (bytes, name) = truth_file::read_bytes(path)?;
        SelfcalTruth::from_json_bytes(&bytes, &name)
    }

    /// [`SelfcalTruth::read_path`] of bytes already read; `source` names them in
    /// messages.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Json`] or [`SimulateError::Truth`].
    pub fn from_json_bytes(bytes: &[u8], source: &str) -> Result<SelfcalTruth, SimulateError> {
        truth_file::from_json_bytes(bytes, source)
    }

    /// Checks the truth: P ≥ [`MIN_POSITIONS`]; `encoder_error` has P values, and
    /// `encoder_angle_deg` P values unless empty; every table-error row has P values;
    /// every number is finite; head errors name heads ≥ 2, each once; harmonics have
    /// orders ≥ 1; the noise is ≥ 0. Σe = 0 is not enforced (a file written by hand may be
    /// rounded).
    ///
    /// # Errors
    ///
    /// [`SimulateError::Truth`] (origin `truth`) with the [`TruthError`] of the first
    /// problem.
    pub fn validate(&self) -> Result<(), SimulateError> {
        self.check().map_err(|problem| SimulateError::Truth {
            origin: "truth".into(),
            problem,
        })
    }

    fn check(&self) -> Result<(), TruthError> {
        let p = self.positions;
        if p < MIN_POSITIONS {
            return Err(TruthError::TooFewPositions { positions: p });
        }
        for (list, values, may_be_empty) in [
            ("encoder_error", &self.encoder_error, false),
            ("encoder_angle_deg", &self.encoder_angle_deg, true),
        ] {
            if values.len() != p && !(may_be_empty && values.is_empty()) {
                return Err(TruthError::LengthNotPositions {
                    list,
                    len: values.len(),
                    positions: p,
                });
            }
            check_values(list, values)?;
        }
        for (c, row) in self.table_error.iter().enumerate() {
            if row.len() != p {
                return Err(TruthError::TableErrorLength {
                    cycle: c + 1,
                    len: row.len(),
                    positions: p,
                });
            }
            if let Some(step) = row.iter().position(|v| !v.is_finite()) {
                return Err(TruthError::TableErrorNotFinite { cycle: c + 1, step });
            }
        }
        let mut seen = std::collections::HashSet::new();
        for h in &self.head_error {
            let head = h.head;
            if head < 2 {
                return Err(TruthError::HeadErrorOfReference { head });
            }
            if !(h.value.is_finite() && h.angle_deg.is_finite()) {
                return Err(TruthError::HeadErrorNotFinite { head });
            }
            if !seen.insert(head) {
                return Err(TruthError::HeadErrorTwice { head });
            }
        }
        for h in &self.encoder_harmonics {
            h.check()?;
        }
        check_noise(self.noise_arcsec)
    }

    /// The truth as pretty-printed JSON (numbers at full precision: they read back to the
    /// same doubles).
    pub fn to_json_pretty(&self) -> String {
        serde_json::to_string_pretty(self).expect("a SelfcalTruth always serializes to JSON")
    }
}

impl TruthJson for SelfcalTruth {
    fn check(&self) -> Result<(), TruthError> {
        SelfcalTruth::check(self)
    }

    fn fill_left_out(&mut self) {
        if self.encoder_angle_deg.is_empty() {
            self.encoder_angle_deg = (0..self.positions)
                .map(|k| position_deg(k, self.positions))
                .collect();
        }
    }
}
