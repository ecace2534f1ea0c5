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
    /// How many readings of each autocollimator are taken at a stop and must agree
    /// before their mean is stored (≥ 2; docs/FORMAT.md §7.3, *No reading on the wrong
    /// stop*). Absent from manifests written before it existed: 2.
    #[serde(default = "default_reads_per_stop")]
    pub reads_per_stop: u32,
    /// The autocollimators' noise, the standard deviation σ of one reading, arcsec: the
    /// readings at a stop agree when they lie within [`RunSettings::agreement_arcsec`]
    /// (5·√2·σ) of each other. Absent from older manifests: [`DEFAULT_READING_NOISE_ARCSEC`].
    #[serde(default = "default_reading_noise")]
    pub reading_noise_arcsec: f64,
    /// The face each autocollimator reads at step 0, autocollimator 1 first (docs/FORMAT.md
    /// §7.3, as `plan` and `simulate` take it): at step p autocollimator j reads face
    /// `((ac_faces[j-1] − 1) + p) mod N + 1`. Absent from older manifests: `[1, 2]`.
    #[serde(default = "default_ac_faces")]
    pub ac_faces: Vec<usize>,
}

/// Readings of each autocollimator at a stop unless set otherwise.
pub const DEFAULT_READS_PER_STOP: u32 = 2;
/// The autocollimators' noise σ unless stated otherwise, arcsec.
pub const DEFAULT_READING_NOISE_ARCSEC: f64 = 0.1;
/// Most readings of an autocollimator at a stop.
pub const MAX_READS_PER_STOP: u32 = 20;
/// How many standard deviations of a difference of two readings the readings at a
/// stop may lie apart: 5, so that two honest readings are refused once in 1.7 million.
pub const AGREEMENT_SIGMAS: f64 = 5.0;

fn default_reads_per_stop() -> u32 {
    DEFAULT_READS_PER_STOP
}

fn default_reading_noise() -> f64 {
    DEFAULT_READING_NOISE_ARCSEC
}

/// The paper's design: autocollimators on faces 1 and 2.
fn default_ac_faces() -> Vec<usize> {
    vec![1, 2]
}

/// Most autocollimators of a run.
pub const MAX_AUTOCOLLIMATORS: usize = 16;

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
    /// Fewer than 2 or more than [`MAX_READS_PER_STOP`] readings at a stop.
    #[error(
        "reads {0}: each autocollimator is read 2 to 20 times at a stop (two readings that agree tie a reading to its stop)"
    )]
    Reads(u32),
    /// A reading noise that is not a number of arcseconds above 0 and at most 100.
    #[error("reading-noise {0}: must be a number of arcseconds above 0 and at most 100")]
    ReadingNoise(f64),
    /// Autocollimators' faces that are fewer than 2 or more than
    /// [`MAX_AUTOCOLLIMATORS`], outside 1 … N, or repeated.
    #[error("ac-faces {faces}: {problem}")]
    AcFaces {
        /// The faces as given, e.g. `1,2,2`.
        faces: String,
        /// What is wrong.
        problem: String,
    },
    /// A mounting numbered 0 or beyond [`MAX_MOUNTINGS`](super::MAX_MOUNTINGS).
    #[error("setup {0}: mountings are numbered 1 … 1000")]
    Setup(u32),
    /// A table shift that is not a number of degrees in 0 ≤ shift < 360.
    #[error("shift {0}: the table's angle at step 0 is a number of degrees, 0 ≤ shift < 360")]
    Shift(f64),
    /// A face shift of N or more.
    #[error("face-shift {face_shift}: the polygon has {faces} faces: 0 … {}", faces.saturating_sub(1))]
    FaceShift {
        /// The face shift given.
        face_shift: usize,
        /// N.
        faces: usize,
    },
}

impl SettingsError {
    /// The setting's name, as in [`RunSettings::as_options`] without the dashes:
    /// `faces`, `cycles`, `settle`, `reads`, `reading-noise`, `ac-faces`, or of a
    /// mounting `setup`, `shift`, `face-shift`.
    pub fn setting(&self) -> &'static str {
        match self {
            SettingsError::TooFewFaces(_) | SettingsError::TooManyFaces(_) => "faces",
            SettingsError::NoCycle => "cycles",
            SettingsError::Settle(_) => "settle",
            SettingsError::Reads(_) => "reads",
            SettingsError::ReadingNoise(_) => "reading-noise",
            SettingsError::AcFaces { .. } => "ac-faces",
            SettingsError::Setup(_) => "setup",
            SettingsError::Shift(_) => "shift",
            SettingsError::FaceShift { .. } => "face-shift",
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
            reads_per_stop: DEFAULT_READS_PER_STOP,
            reading_noise_arcsec: DEFAULT_READING_NOISE_ARCSEC,
            ac_faces: default_ac_faces(),
        }
    }

    /// Sets the face each autocollimator reads at step 0 (autocollimator 1 first).
    pub fn with_ac_faces(mut self, ac_faces: Vec<usize>) -> RunSettings {
        self.ac_faces = ac_faces;
        self
    }

    /// Number of autocollimators K.
    pub fn autocollimators(&self) -> usize {
        self.ac_faces.len()
    }

    /// The faces as written in options and messages, e.g. `1,2,9`.
    pub fn ac_faces_text(&self) -> String {
        self.ac_faces
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(",")
    }

    /// Sets how many readings of each autocollimator are taken at a stop.
    pub fn with_reads_per_stop(mut self, reads_per_stop: u32) -> RunSettings {
        self.reads_per_stop = reads_per_stop;
        self
    }

    /// Sets the autocollimators' noise σ of one reading, arcsec.
    pub fn with_reading_noise_arcsec(mut self, reading_noise_arcsec: f64) -> RunSettings {
        self.reading_noise_arcsec = reading_noise_arcsec;
        self
    }

    /// How far apart the readings of an autocollimator at one stop may lie, arcsec:
    /// [`AGREEMENT_SIGMAS`]·√2·σ.
    pub fn agreement_arcsec(&self) -> f64 {
        AGREEMENT_SIGMAS * std::f64::consts::SQRT_2 * self.reading_noise_arcsec
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
        if !(2..=MAX_READS_PER_STOP).contains(&self.reads_per_stop) {
            return Err(SettingsError::Reads(self.reads_per_stop));
        }
        let noise = self.reading_noise_arcsec;
        if !(noise.is_finite() && noise > 0.0 && noise <= 100.0) {
            return Err(SettingsError::ReadingNoise(noise));
        }
        let bad = |problem: String| SettingsError::AcFaces {
            faces: self.ac_faces_text(),
            problem,
        };
        let k = self.ac_faces.len();
        if !(2..=MAX_AUTOCOLLIMATORS).contains(&k) {
            return Err(bad(format!(
                "a run has 2 to {MAX_AUTOCOLLIMATORS} autocollimators, not {k}"
            )));
        }
        for (j, &face) in self.ac_faces.iter().enumerate() {
            if !(1..=self.faces).contains(&face) {
                return Err(bad(format!(
                    "autocollimator {}: face {face} is not one of 1 … {}",
                    j + 1,
                    self.faces
                )));
            }
            if self.ac_faces[..j].contains(&face) {
                return Err(bad(format!(
                    "autocollimator {}: face {face} is read by an autocollimator before it",
                    j + 1
                )));
            }
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

    /// The face autocollimator `ac` (1 … K) reads at `step`: with the default faces p+1
    /// for autocollimator 1, p+2 (wrapping) for autocollimator 2 ([`face_at`] with the
    /// face offset `ac_faces[ac − 1]` − 1).
    pub fn face(&self, ac: u32, step: usize) -> usize {
        let first = self
            .ac_faces
            .get((ac as usize).saturating_sub(1))
            .copied()
            .unwrap_or(ac as usize);
        face_at(step, first.saturating_sub(1), self.faces)
    }

    /// The autocollimators, 1 … K.
    pub fn acs(&self) -> std::ops::RangeInclusive<u32> {
        1..=self.ac_faces.len() as u32
    }

    /// Number of stops in one cycle: N, or N+1 with the closing step.
    pub fn stops_per_cycle(&self) -> usize {
        run_stops(self.faces, 1, self.closing, self.bidirectional).len()
    }

    /// Number of readings of the whole run.
    pub fn reading_count(&self) -> usize {
        self.stops_per_cycle() * self.cycles as usize * self.autocollimators()
    }

    /// The readings of the whole run in order, (stop, autocollimator): at each stop
    /// autocollimator 1, 2, … K.
    pub fn readings(&self) -> Vec<(Stop, u32)> {
        self.plan()
            .into_iter()
            .flat_map(|stop| self.acs().map(move |ac| (stop, ac)))
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
        s.push_str(&format!(
            " --settle {} --reads {} --reading-noise {}",
            self.settle_seconds, self.reads_per_stop, self.reading_noise_arcsec
        ));
        if self.ac_faces != default_ac_faces() {
            s.push_str(&format!(" --ac-faces {}", self.ac_faces_text()));
        }
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
        if self.reads_per_stop != other.reads_per_stop {
            d.push(format!(
                "reads {} vs {}",
                self.reads_per_stop, other.reads_per_stop
            ));
        }
        if self.reading_noise_arcsec != other.reading_noise_arcsec {
            d.push(format!(
                "reading noise {}″ vs {}″",
                self.reading_noise_arcsec, other.reading_noise_arcsec
            ));
        }
        if self.ac_faces != other.ac_faces {
            d.push(format!(
                "autocollimators' faces {} vs {}",
                self.ac_faces_text(),
                other.ac_faces_text()
            ));
        }
        d
    }
}

impl std::fmt::Display for RunSettings {
    /// `faces 8, cycles 2, closing, settle 0 s, 2 readings per stop, reading noise 0.1″`
    /// (`bidirectional` when it is).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "faces {}, cycles {}", self.faces, self.cycles)?;
        if self.closing {
            f.write_str(", closing")?;
        }
        if self.bidirectional {
            f.write_str(", bidirectional")?;
        }
        write!(
            f,
            ", settle {} s, {} readings per stop, reading noise {}″",
            self.settle_seconds, self.reads_per_stop, self.reading_noise_arcsec
        )?;
        if self.ac_faces != default_ac_faces() {
            write!(f, ", autocollimators on faces {}", self.ac_faces_text())?;
        }
        Ok(())
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
            "--faces 8 --cycles 2 --closing --settle 0.5 --reads 2 --reading-noise 0.1"
        );
        assert_eq!(
            s.to_string(),
            "faces 8, cycles 2, closing, settle 0.5 s, 2 readings per stop, reading noise 0.1″"
        );
        // 5·√2·0.1″ = √2/2″
        assert!((s.agreement_arcsec() - 2f64.sqrt() / 2.0).abs() < 1e-15);
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
        let e = RunSettings::new(8, 1).with_reads_per_stop(1).validate();
        assert_eq!(e, Err(SettingsError::Reads(1)));
        let e = RunSettings::new(8, 1)
            .with_reading_noise_arcsec(0.0)
            .validate();
        assert_eq!(e.map_err(|e| e.setting()), Err("reading-noise"));
    }
}
