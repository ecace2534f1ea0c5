//! The settings of a simulated self-calibration run, and why they may be refused.

use serde::{Deserialize, Serialize};

use super::super::SimulateError;
use super::super::config::{Harmonic, HarmonicError, MAX_READINGS};
use super::selfa_head_angles_deg;

/// Fewest table positions P of a simulated self-calibration.
pub const MIN_POSITIONS: usize = 3;
/// Highest order the drawn encoder error may have (`max_order`).
pub const MAX_DRAWN_ORDER: usize = 1_000_000;
/// Largest number of harmonic terms a run may evaluate: P · heads · harmonics (a guard
/// against absurd settings, a few seconds of work).
pub const MAX_HARMONIC_TERMS: usize = 200_000_000;
/// Two head angles closer than this (degrees) are the same angle; a head angle this close
/// to a multiple of 360°/P is on the grid of the P positions.
const ANGLE_TOLERANCE_DEG: f64 = 1e-9;

/// Settings of a simulated self-calibration run (see [`simulate_selfcal`](super::simulate_selfcal)
/// for the model, the run and the random draws).
///
/// The default is the SelfA design: 168 positions, 2 clockwise cycles, the 12 heads of
/// [`selfa_head_angles_deg`], a drawn encoder error of orders 1 … 60 (0.3″/√k), head
/// errors in ±2″, a table error of 1″, noise 0.02″, no time column, seed 1. The struct is
/// `#[non_exhaustive]`: start from `SelfcalSimConfig::default()` and set the fields.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct SelfcalSimConfig {
    /// P, the number of table positions per turn (≥ 3); step p is at p·360°/P.
    pub positions: usize,
    /// Number of cycles (full turns), ≥ 1.
    pub cycles: u32,
    /// Nominal angle of each head from head 1, degrees: `head_angles_deg[j-1]` is head j's.
    /// Head 1 is the reference, at 0; every angle finite, in [0, 360) and distinct; at
    /// least 2 heads. Angles that are not multiples of 360°/P are allowed (the readings
    /// are then at angles between the P positions; see
    /// [`SelfcalSimConfig::heads_off_grid`]).
    pub head_angles_deg: Vec<f64>,
    /// The disc's graduation error as a continuous function of the angle: the sum of these
    /// harmonics, `a·cos(2π·k·θ/360° + phase)` at the angle θ (degrees). Empty: draw one
    /// from the seed (orders 1 … `max_order`, amplitudes `drawn_amplitude_arcsec`/√k,
    /// random phases).
    pub encoder_harmonics: Vec<Harmonic>,
    /// Highest order of the drawn encoder error (1 … [`MAX_DRAWN_ORDER`]); used only when
    /// `encoder_harmonics` is empty.
    pub max_order: usize,
    /// Amplitude of order 1 of the drawn encoder error, arcsec (≥ 0); order k has this
    /// divided by √k. Used only when `encoder_harmonics` is empty.
    pub drawn_amplitude_arcsec: f64,
    /// Range of the head placement errors, arcsec (≥ 0): c\[j\] is drawn uniformly in
    /// ±this for heads 2 … M; c\[1\] = 0.
    pub head_error_arcsec: f64,
    /// Standard deviation of the table's position error t\[cycle, step\] at every stop,
    /// arcsec (≥ 0): the table does not return to the same angle.
    pub table_error_arcsec: f64,
    /// Standard deviation of the reading noise, arcsec (≥ 0).
    pub noise_arcsec: f64,
    /// Whether every second cycle (2, 4, …) runs counter-clockwise, steps P−1 … 0.
    pub bidirectional: bool,
    /// Time between consecutive stops, seconds (finite, > 0); `None`: the readings have no
    /// time.
    pub step_seconds: Option<f64>,
    /// Seed of the random draws.
    pub seed: u64,
}

impl Default for SelfcalSimConfig {
    fn default() -> Self {
        SelfcalSimConfig {
            positions: 168,
            cycles: 2,
            head_angles_deg: selfa_head_angles_deg(),
            encoder_harmonics: Vec::new(),
            max_order: 60,
            drawn_amplitude_arcsec: 0.3,
            head_error_arcsec: 2.0,
            table_error_arcsec: 1.0,
            noise_arcsec: 0.02,
            bidirectional: false,
            step_seconds: None,
            seed: 1,
        }
    }
}

/// Why a [`SelfcalSimConfig`] was refused ([`SelfcalSimConfig::validate`]); inside
/// [`SimulateError::SelfcalConfig`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SelfcalConfigError {
    /// Fewer than [`MIN_POSITIONS`] table positions.
    #[error("{positions} table positions; need at least {MIN_POSITIONS}")]
    TooFewPositions {
        /// The number of positions asked for.
        positions: usize,
    },
    /// No cycle.
    #[error("cycles is 0; need at least 1")]
    NoCycles,
    /// Fewer than 2 heads (one head cannot tell the disc from the table).
    #[error("{heads} read head(s); a self-calibration needs at least 2")]
    TooFewHeads {
        /// The number of heads.
        heads: usize,
    },
    /// Head 1 is not at 0°.
    #[error("head 1 is at {angle_deg}°; it is the reference and must be at 0°")]
    FirstHeadNotAtZero {
        /// Head 1's angle, degrees.
        angle_deg: f64,
    },
    /// A head angle that is not finite or outside [0°, 360°).
    #[error("head {head} is at {angle_deg}°; a head angle must be a finite number in [0, 360)")]
    HeadAngleOutOfRange {
        /// The head.
        head: u32,
        /// Its angle, degrees.
        angle_deg: f64,
    },
    /// Two heads at the same angle.
    #[error("heads {first} and {head} are both at {angle_deg}°")]
    SameHeadAngle {
        /// The earlier head.
        first: u32,
        /// The later head.
        head: u32,
        /// The angle, degrees.
        angle_deg: f64,
    },
    /// A spread, range, amplitude or noise that is negative or not finite.
    #[error("{what} is {value}; must be a finite number ≥ 0")]
    NotNonNegative {
        /// Which setting: `noise`, `table error`, `head error range` or
        /// `drawn encoder amplitude`.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A step time that is not a finite number > 0.
    #[error("step time is {seconds} s; must be a finite number > 0")]
    StepSeconds {
        /// The step time, seconds.
        seconds: f64,
    },
    /// An encoder harmonic of order 0, or not finite.
    #[error(transparent)]
    Harmonic(#[from] HarmonicError),
    /// A highest order of the drawn encoder error outside 1 … [`MAX_DRAWN_ORDER`].
    #[error(
        "the drawn encoder error's highest order is {max_order}; must be 1 … {MAX_DRAWN_ORDER}"
    )]
    MaxOrder {
        /// The highest order asked for.
        max_order: usize,
    },
    /// More than [`MAX_READINGS`] readings.
    #[error("the run would have {readings} readings, more than {MAX_READINGS}")]
    TooManyReadings {
        /// Cycles · positions · heads (saturating).
        readings: usize,
    },
    /// More than [`MAX_HARMONIC_TERMS`] harmonic terms to evaluate.
    #[error(
        "the encoder error would take {terms} harmonic terms to evaluate (positions · heads · \
         harmonics), more than {MAX_HARMONIC_TERMS}"
    )]
    TooManyHarmonicTerms {
        /// Positions · heads · harmonics (saturating).
        terms: usize,
    },
}

impl SelfcalSimConfig {
    /// The comment line `polycal simulate --selfcal` writes at the head of the
    /// self-calibration CSV. `harmonic_specs` are the encoder harmonics as the user wrote
    /// them (`ORDER:AMPLITUDE[:PHASE]`); empty when the encoder error is drawn. The CLI
    /// and the Python package write the same line.
    pub fn comment(&self, harmonic_specs: &[String]) -> String {
        let angles: Vec<String> = self.head_angles_deg.iter().map(f64::to_string).collect();
        let encoder = if harmonic_specs.is_empty() {
            format!("encoder error drawn to order {}", self.max_order)
        } else {
            format!("encoder harmonics {}", harmonic_specs.join(" "))
        };
        format!(
            "polycal {} simulate --selfcal: {} positions, {} heads at {} degrees, {} cycles{}, \
             {encoder}, table error {} arcsec, head error ±{} arcsec, noise {} arcsec, seed {}",
            crate::SOFTWARE_VERSION,
            self.positions,
            self.head_count(),
            angles.join(","),
            self.cycles,
            if self.bidirectional {
                " (bidirectional)"
            } else {
                ""
            },
            self.table_error_arcsec,
            self.head_error_arcsec,
            self.noise_arcsec,
            self.seed
        )
    }

    /// Number of heads M (`head_angles_deg.len()`).
    pub fn head_count(&self) -> usize {
        self.head_angles_deg.len()
    }

    /// Number of readings of the run: cycles · positions · heads (saturating).
    pub fn reading_count(&self) -> usize {
        (self.cycles as usize)
            .saturating_mul(self.positions)
            .saturating_mul(self.head_count())
    }

    /// The heads (numbers, 1-based) whose angle is not a multiple of 360°/P (to 1e-9°):
    /// their readings are at angles between the P positions, where the truth's
    /// `encoder_error` has no value. Empty for the default SelfA design (P = 168 is a
    /// multiple of 3·4·7 = 84).
    ///
    /// ```
    /// use polycal::simulate::SelfcalSimConfig;
    ///
    /// let mut config = SelfcalSimConfig::default();
    /// assert!(config.heads_off_grid().is_empty());
    /// config.positions = 12; // 360°/7 is not a multiple of 30°
    /// assert_eq!(config.heads_off_grid(), (7..=12).collect::<Vec<u32>>());
    /// ```
    pub fn heads_off_grid(&self) -> Vec<u32> {
        if self.positions == 0 {
            return Vec::new();
        }
        let pitch = 360.0 / self.positions as f64;
        self.head_angles_deg
            .iter()
            .enumerate()
            .filter(|&(_, &angle)| {
                let units = angle / pitch;
                (units - units.round()).abs() * pitch > ANGLE_TOLERANCE_DEG
            })
            .map(|(j, _)| j as u32 + 1)
            .collect()
    }

    /// Checks the settings; the error names the first problem found.
    ///
    /// Refused: fewer than [`MIN_POSITIONS`] positions; no cycle; fewer than 2 heads; head
    /// 1 not at 0°; a head angle that is not finite or outside [0, 360); two heads at the
    /// same angle (to 1e-9°); a negative or non-finite noise, table error, head error range
    /// or drawn amplitude; a step time that is not a finite number > 0; a given harmonic of
    /// order 0 or with a non-finite number; with no harmonics given, a `max_order` outside
    /// 1 … [`MAX_DRAWN_ORDER`]; more than [`MAX_READINGS`] readings; more than
    /// [`MAX_HARMONIC_TERMS`] harmonic terms.
    ///
    /// # Errors
    ///
    /// [`SimulateError::SelfcalConfig`] with the [`SelfcalConfigError`] of the first
    /// problem.
    pub fn validate(&self) -> Result<(), SimulateError> {
        self.check().map_err(SimulateError::SelfcalConfig)
    }

    fn check(&self) -> Result<(), SelfcalConfigError> {
        use SelfcalConfigError as E;
        if self.positions < MIN_POSITIONS {
            return Err(E::TooFewPositions {
                positions: self.positions,
            });
        }
        if self.cycles == 0 {
            return Err(E::NoCycles);
        }
        let heads = self.head_count();
        if heads < 2 {
            return Err(E::TooFewHeads { heads });
        }
        for (j, &angle_deg) in self.head_angles_deg.iter().enumerate() {
            let head = j as u32 + 1;
            if !(angle_deg.is_finite() && (0.0..360.0).contains(&angle_deg)) {
                return Err(E::HeadAngleOutOfRange { head, angle_deg });
            }
            if head == 1 && angle_deg != 0.0 {
                return Err(E::FirstHeadNotAtZero { angle_deg });
            }
            let same = |other: f64| {
                let d = (other - angle_deg).abs();
                d.min(360.0 - d) <= ANGLE_TOLERANCE_DEG
            };
            if let Some(i) = self.head_angles_deg[..j].iter().position(|&a| same(a)) {
                return Err(E::SameHeadAngle {
                    first: i as u32 + 1,
                    head,
                    angle_deg,
                });
            }
        }
        for (what, value) in [
            ("noise", self.noise_arcsec),
            ("table error", self.table_error_arcsec),
            ("head error range", self.head_error_arcsec),
            ("drawn encoder amplitude", self.drawn_amplitude_arcsec),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(E::NotNonNegative { what, value });
            }
        }
        if let Some(seconds) = self.step_seconds
            && !(seconds.is_finite() && seconds > 0.0)
        {
            return Err(E::StepSeconds { seconds });
        }
        for h in &self.encoder_harmonics {
            h.check()?;
        }
        let harmonics = if self.encoder_harmonics.is_empty() {
            if !(1..=MAX_DRAWN_ORDER).contains(&self.max_order) {
                return Err(E::MaxOrder {
                    max_order: self.max_order,
                });
            }
            self.max_order
        } else {
            self.encoder_harmonics.len()
        };
        let readings = self.reading_count();
        if readings > MAX_READINGS {
            return Err(E::TooManyReadings { readings });
        }
        let terms = self
            .positions
            .saturating_mul(heads)
            .saturating_mul(harmonics);
        if terms > MAX_HARMONIC_TERMS {
            return Err(E::TooManyHarmonicTerms { terms });
        }
        Ok(())
    }
}
