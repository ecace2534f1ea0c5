//! The settings that define a run, and its plan: the stops in order, the face each
//! autocollimator reads at each, the readings of the whole run.

use serde::{Deserialize, Serialize};

use crate::measurement::{Stop, face_at, run_stops};

/// The settings that define a run; a resumed run must have the same.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct RunSettings {
    /// Number of polygon faces N (≥ 3).
    pub faces: usize,
    /// Number of cycles R (≥ 1).
    pub cycles: u32,
    /// Whether clockwise cycles end with the closing step N (implied by `bidirectional`).
    pub closing: bool,
    /// Whether every second cycle runs counter-clockwise.
    pub bidirectional: bool,
    /// Wait after the table arrived before reading, seconds.
    pub settle_seconds: f64,
}

/// A setting out of its range. The message starts with the setting's name and value
/// (`faces 2: …`), the way a command line names its option.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SettingsError {
    /// Fewer than 3 faces.
    #[error("faces {0}: a polygon has at least 3 faces")]
    TooFewFaces(usize),
    /// More than 100000 faces.
    #[error("faces {0}: at most 100000")]
    TooManyFaces(usize),
    /// No cycle.
    #[error("cycles 0: a run has at least one cycle")]
    NoCycle,
    /// A settle time that is not a number of seconds from 0 to 3600.
    #[error("settle {0}: must be a number of seconds from 0 to 3600")]
    Settle(f64),
}

impl SettingsError {
    /// The setting's name, as in [`RunSettings::as_options`] without the dashes:
    /// `faces`, `cycles` or `settle`.
    pub fn setting(&self) -> &'static str {
        match self {
            SettingsError::TooFewFaces(_) | SettingsError::TooManyFaces(_) => "faces",
            SettingsError::NoCycle => "cycles",
            SettingsError::Settle(_) => "settle",
        }
    }
}

impl Stop {
    /// The commanded table position, degrees: step·360/N (360 for the closing step).
    pub fn degrees(&self, faces: usize) -> f64 {
        if self.step == faces {
            360.0
        } else {
            self.step as f64 * 360.0 / faces as f64
        }
    }
}

impl RunSettings {
    /// A run of `cycles` clockwise cycles of a polygon of `faces` faces, without the
    /// closing step and without a settle time.
    pub fn new(faces: usize, cycles: u32) -> RunSettings {
        RunSettings {
            faces,
            cycles,
            closing: false,
            bidirectional: false,
            settle_seconds: 0.0,
        }
    }

    /// Sets whether clockwise cycles end with the closing step N.
    pub fn with_closing(mut self, closing: bool) -> RunSettings {
        self.closing = closing;
        self
    }

    /// Sets whether every second cycle runs counter-clockwise (the closing step is then
    /// implied for every cycle).
    pub fn with_bidirectional(mut self, bidirectional: bool) -> RunSettings {
        self.bidirectional = bidirectional;
        self
    }

    /// Sets the wait after the table arrived before reading, seconds.
    pub fn with_settle_seconds(mut self, settle_seconds: f64) -> RunSettings {
        self.settle_seconds = settle_seconds;
        self
    }

    /// Checks the settings.
    ///
    /// # Errors
    ///
    /// The first setting out of its range.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.faces < 3 {
            return Err(SettingsError::TooFewFaces(self.faces));
        }
        if self.faces > 100_000 {
            return Err(SettingsError::TooManyFaces(self.faces));
        }
        if self.cycles == 0 {
            return Err(SettingsError::NoCycle);
        }
        if !(self.settle_seconds.is_finite() && (0.0..=3600.0).contains(&self.settle_seconds)) {
            return Err(SettingsError::Settle(self.settle_seconds));
        }
        Ok(())
    }

    /// Whether every cycle has the closing step.
    pub fn has_closing(&self) -> bool {
        self.closing || self.bidirectional
    }

    /// The stops in order ([`run_stops`]).
    pub fn plan(&self) -> Vec<Stop> {
        run_stops(self.faces, self.cycles, self.closing, self.bidirectional)
    }

    /// The face autocollimator `ac` (1 or 2) reads at `step`: p+1 for autocollimator 1,
    /// p+2 (wrapping) for autocollimator 2 ([`face_at`] with the face offset `ac` − 1).
    pub fn face(&self, ac: u32, step: usize) -> usize {
        face_at(step, (ac as usize).saturating_sub(1), self.faces)
    }

    /// Number of stops in one cycle: N, or N+1 with the closing step.
    pub fn stops_per_cycle(&self) -> usize {
        run_stops(self.faces, 1, self.closing, self.bidirectional).len()
    }

    /// Number of readings of the whole run.
    pub fn reading_count(&self) -> usize {
        self.stops_per_cycle() * self.cycles as usize * 2
    }

    /// The readings of the whole run in order, (stop, autocollimator): at each stop
    /// autocollimator 1, then 2.
    pub fn readings(&self) -> Vec<(Stop, u32)> {
        self.plan()
            .into_iter()
            .flat_map(|stop| [(stop, 1), (stop, 2)])
            .collect()
    }

    /// The settings as the options of `polycal run`, e.g.
    /// `--faces 8 --cycles 2 --closing --settle 0`: the form the measurement file's first
    /// comment and the traffic log record them in.
    pub fn as_options(&self) -> String {
        let mut s = format!("--faces {} --cycles {}", self.faces, self.cycles);
        if self.closing {
            s.push_str(" --closing");
        }
        if self.bidirectional {
            s.push_str(" --bidirectional");
        }
        s.push_str(&format!(" --settle {}", self.settle_seconds));
        s
    }

    /// The settings that differ from `other`, as `name: this vs other`.
    pub fn differences(&self, other: &RunSettings) -> Vec<String> {
        let mut d = Vec::new();
        if self.faces != other.faces {
            d.push(format!("faces {} vs {}", self.faces, other.faces));
        }
        if self.cycles != other.cycles {
            d.push(format!("cycles {} vs {}", self.cycles, other.cycles));
        }
        if self.has_closing() != other.has_closing() {
            d.push(format!(
                "closing {} vs {}",
                self.has_closing(),
                other.has_closing()
            ));
        }
        if self.bidirectional != other.bidirectional {
            d.push(format!(
                "bidirectional {} vs {}",
                self.bidirectional, other.bidirectional
            ));
        }
        if self.settle_seconds != other.settle_seconds {
            d.push(format!(
                "settle {} s vs {} s",
                self.settle_seconds, other.settle_seconds
            ));
        }
        d
    }
}

impl std::fmt::Display for RunSettings {
    /// `faces 8, cycles 2, closing, settle 0 s` (`bidirectional` when it is).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "faces {}, cycles {}", self.faces, self.cycles)?;
        if self.closing {
            f.write_str(", closing")?;
        }
        if self.bidirectional {
            f.write_str(", bidirectional")?;
        }
        write!(f, ", settle {} s", self.settle_seconds)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_counts_and_spells_its_settings() {
        let s = RunSettings::new(8, 2)
            .with_closing(true)
            .with_settle_seconds(0.5);
        assert_eq!(s.reading_count(), 36);
        assert_eq!(s.readings().len(), 36);
        assert_eq!(
            s.as_options(),
            "--faces 8 --cycles 2 --closing --settle 0.5"
        );
        assert_eq!(s.to_string(), "faces 8, cycles 2, closing, settle 0.5 s");
        let other = s.clone().with_bidirectional(true);
        assert_eq!(other.differences(&s), ["bidirectional true vs false"]);
        assert_eq!(RunSettings::new(8, 1).reading_count(), 16);
        assert_eq!(
            (s.face(1, 0), s.face(2, 0), s.face(2, 7), s.face(1, 8)),
            (1, 2, 1, 1)
        );
    }

    #[test]
    fn a_setting_out_of_range_is_named_with_its_value() {
        let e = RunSettings::new(2, 1).validate().unwrap_err();
        assert_eq!(e.to_string(), "faces 2: a polygon has at least 3 faces");
        assert_eq!(e.setting(), "faces");
        let e = RunSettings::new(8, 0).validate().unwrap_err();
        assert_eq!((e.setting(), e), ("cycles", SettingsError::NoCycle));
        let e = RunSettings::new(8, 1).with_settle_seconds(-1.0).validate();
        assert_eq!(e, Err(SettingsError::Settle(-1.0)));
        assert!(RunSettings::new(100_001, 1).validate().is_err());
        assert!(RunSettings::new(8, 1).validate().is_ok());
    }
}
