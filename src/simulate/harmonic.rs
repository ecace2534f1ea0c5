//! One Fourier harmonic of a simulated encoder error, and why one is refused: a leaf that
//! the run's settings (`config.rs`) and the truth file (`truth_file.rs`) both read.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::effects::{SpecError, SpecProblem, finite};

/// One Fourier harmonic of the true encoder error:
/// `amplitude_arcsec · cos(2π·order·p/N + phase_rad)` at position p.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Harmonic {
    /// Harmonic order k (≥ 1): k undulations per turn.
    pub order: usize,
    /// Amplitude, arcsec.
    pub amplitude_arcsec: f64,
    /// Phase, radians.
    pub phase_rad: f64,
}

/// Why an encoder harmonic is refused: the one rule of every run's settings and truth
/// file that gives harmonics.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HarmonicError {
    /// A harmonic of order 0.
    #[error("encoder harmonic {0} has order 0; orders start at 1")]
    OrderZero(Harmonic),
    /// A harmonic whose amplitude or phase is not finite.
    #[error("encoder harmonic {0} is not finite")]
    NotFinite(Harmonic),
}

impl Harmonic {
    /// Checks the harmonic: order ≥ 1, amplitude and phase finite.
    ///
    /// # Errors
    ///
    /// [`HarmonicError`] naming the harmonic.
    pub fn check(&self) -> Result<(), HarmonicError> {
        if self.order == 0 {
            return Err(HarmonicError::OrderZero(self.clone()));
        }
        if !(self.amplitude_arcsec.is_finite() && self.phase_rad.is_finite()) {
            return Err(HarmonicError::NotFinite(self.clone()));
        }
        Ok(())
    }

    /// The harmonic's value at position `p` of `faces` positions.
    pub fn value_at(&self, p: usize, faces: usize) -> f64 {
        let x = std::f64::consts::TAU * (self.order as f64) * (p as f64) / (faces as f64);
        self.amplitude_arcsec * (x + self.phase_rad).cos()
    }

    /// The harmonic's value at the angle `angle_deg` (degrees) of a full turn:
    /// `amplitude_arcsec · cos(2π·order·angle_deg/360 + phase_rad)`, the continuous function
    /// whose samples at the angles p·360/N are [`Harmonic::value_at`]`(p, N)` (equal up to
    /// rounding). The angle is taken modulo 360° first (exactly), so any angle may be given.
    ///
    /// ```
    /// use polycal::simulate::Harmonic;
    ///
    /// let h = Harmonic { order: 2, amplitude_arcsec: 0.5, phase_rad: 0.3 };
    /// assert!((h.value_at_deg(45.0) - h.value_at(1, 8)).abs() < 1e-15);
    /// assert!((h.value_at_deg(405.0) - h.value_at_deg(45.0)).abs() < 1e-15);
    /// ```
    pub fn value_at_deg(&self, angle_deg: f64) -> f64 {
        let turn = angle_deg.rem_euclid(360.0) / 360.0;
        let x = std::f64::consts::TAU * (self.order as f64) * turn;
        self.amplitude_arcsec * (x + self.phase_rad).cos()
    }
}

impl FromStr for Harmonic {
    type Err = SpecError;

    /// Parses `ORDER:AMPLITUDE:PHASE` (order ≥ 1, amplitude in arcsec, phase in radians;
    /// `:PHASE` may be left out for phase 0), e.g. `2:0.35:1.3` or `1:0.6`.
    fn from_str(s: &str) -> Result<Harmonic, SpecError> {
        let form = "ORDER:AMPLITUDE[:PHASE], e.g. 2:0.35:1.3";
        let at = |problem| SpecError::part("harmonic", s, problem, form);
        let parts: Vec<&str> = s.split(':').map(str::trim).collect();
        if !(2..=3).contains(&parts.len()) {
            return Err(at(SpecProblem::part_count(parts.len(), "2 or 3")));
        }
        let order = match parts[0].parse::<usize>() {
            Ok(k) if k >= 1 => k,
            _ => {
                return Err(at(SpecProblem::NotFromOne {
                    part: "ORDER",
                    text: parts[0].to_string(),
                }));
            }
        };
        let amplitude_arcsec = finite("AMPLITUDE", parts[1]).map_err(at)?;
        let phase_rad = match parts.get(2) {
            Some(text) => finite("PHASE", text).map_err(at)?,
            None => 0.0,
        };
        Ok(Harmonic {
            order,
            amplitude_arcsec,
            phase_rad,
        })
    }
}

impl fmt::Display for Harmonic {
    /// `ORDER:AMPLITUDE:PHASE`, readable back by [`Harmonic::from_str`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}",
            self.order, self.amplitude_arcsec, self.phase_rad
        )
    }
}
