//! The polygon's mountings on the table (docs/FORMAT.md §7.3, *Several mountings*): a
//! run measures its cycles in one mounting, then the operator remounts the polygon and
//! the same run directory goes on with the next. Each mounting is its own `setup` in the
//! measurement file, with its `shift` (the table's angle at step 0) and the faces the
//! polygon is turned by against the first mounting.

use serde::{Deserialize, Serialize};

use super::{RunSettings, SettingsError};
use crate::measurement::{Stop, face_at};

/// Most mountings of one run.
pub const MAX_MOUNTINGS: u32 = 1000;

/// How far the position the table reports when the remount is confirmed may lie from
/// the mounting's step 0, degrees (the table's own tolerance at a stop, 3.6″): farther,
/// the table was moved while the polygon was remounted.
pub const REMOUNT_TOLERANCE_DEG: f64 = 0.001;

/// One mounting of the polygon on the table.
///
/// At step p of mounting `setup` the table stands at `shift_deg` + p·360°/N, and
/// autocollimator j reads face `((ac_faces[j-1] − 1) + face_shift + p) mod N + 1`: the
/// operator mounts the polygon so that, with the table at `shift_deg`, autocollimator j
/// faces face `ac_faces[j-1] + face_shift` (wrapping). The first mounting is
/// `Mounting::default()`: setup 1, shift 0, no face shift.
///
/// ```
/// use polycal::lab::run::{Mounting, RunSettings};
/// use polycal::measurement::{Direction, Stop};
///
/// let settings = RunSettings::new(8, 2);
/// let second = Mounting::new(2).with_shift_deg(22.5).with_face_shift(3);
/// second.validate(&settings)?;
/// let stop = Stop { cycle: 1, step: 1, direction: Direction::Cw };
/// assert_eq!(second.table_deg(&stop, settings.faces), 67.5);
/// assert_eq!(second.face(&settings, 1, 1), 5); // face 1 + 3 faces + step 1
/// # Ok::<(), polycal::lab::run::SettingsError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Mounting {
    /// The mounting's number, the `setup` column (1, 2, …, measured in this order).
    pub setup: u32,
    /// The table's angle at step 0, degrees, 0 ≤ shift < 360 (the `shift` column).
    pub shift_deg: f64,
    /// Whole faces the polygon is turned against the first mounting, 0 … N−1.
    pub face_shift: usize,
}

impl Default for Mounting {
    fn default() -> Mounting {
        Mounting::new(1)
    }
}

impl Mounting {
    /// Mounting `setup`, unshifted.
    pub fn new(setup: u32) -> Mounting {
        Mounting {
            setup,
            shift_deg: 0.0,
            face_shift: 0,
        }
    }

    /// Sets the table's angle at step 0, degrees.
    pub fn with_shift_deg(mut self, shift_deg: f64) -> Mounting {
        self.shift_deg = shift_deg;
        self
    }

    /// Sets the whole faces the polygon is turned against the first mounting.
    pub fn with_face_shift(mut self, face_shift: usize) -> Mounting {
        self.face_shift = face_shift;
        self
    }

    /// Checks the mounting against the run's settings.
    ///
    /// # Errors
    ///
    /// A setup of 0 or beyond [`MAX_MOUNTINGS`], a shift that is not a number of degrees
    /// in 0 ≤ shift < 360, a face shift of N or more.
    pub fn validate(&self, settings: &RunSettings) -> Result<(), SettingsError> {
        if !(1..=MAX_MOUNTINGS).contains(&self.setup) {
            return Err(SettingsError::Setup(self.setup));
        }
        if !(self.shift_deg.is_finite() && (0.0..360.0).contains(&self.shift_deg)) {
            return Err(SettingsError::Shift(self.shift_deg));
        }
        if self.face_shift >= settings.faces {
            return Err(SettingsError::FaceShift {
                face_shift: self.face_shift,
                faces: settings.faces,
            });
        }
        Ok(())
    }

    /// The commanded table position at `stop`, degrees: the shift plus step·360/N (a
    /// full turn from step 0 at the closing step).
    pub fn table_deg(&self, stop: &Stop, faces: usize) -> f64 {
        self.shift_deg + stop.degrees(faces)
    }

    /// The face autocollimator `ac` (1 … K) reads at `step` in this mounting.
    pub fn face(&self, settings: &RunSettings, ac: u32, step: usize) -> usize {
        let first = settings
            .ac_faces
            .get((ac as usize).saturating_sub(1))
            .copied()
            .unwrap_or(ac as usize);
        face_at(
            step,
            first.saturating_sub(1) + self.face_shift,
            settings.faces,
        )
    }

    /// The mounting as the options of `polycal run` name it, e.g.
    /// `--setup 2 --shift 22.5 --face-shift 3` (the shift and face shift when not 0).
    pub fn as_options(&self) -> String {
        let mut s = format!("--setup {}", self.setup);
        if self.shift_deg != 0.0 {
            s.push_str(&format!(" --shift {}", self.shift_deg));
        }
        if self.face_shift != 0 {
            s.push_str(&format!(" --face-shift {}", self.face_shift));
        }
        s
    }
}

impl std::fmt::Display for Mounting {
    /// `mounting 2 (shift 22.5°, turned 3 faces)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "mounting {} (shift {}°", self.setup, self.shift_deg)?;
        match self.face_shift {
            0 => {}
            1 => f.write_str(", turned 1 face")?,
            k => write!(f, ", turned {k} faces")?,
        }
        f.write_str(")")
    }
}

/// A mounting as the manifest records it: the mounting and when its remount was
/// confirmed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct MountingRecord {
    /// The mounting.
    #[serde(flatten)]
    pub mounting: Mounting,
    /// When the operator confirmed the polygon was remounted, RFC 3339 UTC; `null` for the
    /// first mounting (mounted before the run started) and until confirmed.
    pub confirmed: Option<String>,
    /// The position the table reported when the remount was confirmed, degrees.
    pub table_deg: Option<f64>,
    /// The latest warning that the mounting's readings do not fit those of the mountings
    /// before it (docs/FORMAT.md §7.3); absent when they fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub misfit: Option<String>,
}

impl MountingRecord {
    /// A mounting not yet confirmed.
    pub(super) fn new(mounting: Mounting) -> MountingRecord {
        MountingRecord {
            mounting,
            confirmed: None,
            table_deg: None,
            misfit: None,
        }
    }

    /// Whether the operator still has to remount the polygon and confirm it: a mounting
    /// after the first that was not confirmed.
    pub fn awaits_remount(&self) -> bool {
        self.mounting.setup > 1 && self.confirmed.is_none()
    }
}

/// What the run asks of the person at the table before it measures a new mounting.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Remount {
    /// The mounting to measure.
    pub mounting: Mounting,
    /// The position the table reports, degrees: the mounting's step 0, where the
    /// polygon is to be mounted.
    pub table_deg: f64,
    /// The face each autocollimator is to face there, (autocollimator, face), in order.
    pub faces: Vec<(u32, usize)>,
}

/// The Fourier harmonics (1 … N−1) of the pitch deviations and encoder errors that a
/// run of `settings` in `mountings` cannot determine ([`crate::solve::lost_harmonics`] of
/// its face offsets: autocollimator j in mounting m reads face step +
/// `ac_faces[j-1] − 1 + face_shift`). Judged only when every mounting stands at shift 0:
/// a shifted mounting reads other encoder positions, which `solve` judges from the
/// readings (empty then, as for a design that loses nothing).
///
/// ```
/// use polycal::lab::run::{Mounting, RunSettings, lost_harmonics};
/// let s = RunSettings::new(8, 1).with_ac_faces(vec![1, 5]);
/// assert_eq!(lost_harmonics(&s, &[Mounting::new(1)]), [2, 4, 6]);
/// // A second mounting turned by one face completes it.
/// let both = [Mounting::new(1), Mounting::new(2).with_face_shift(1)];
/// assert!(lost_harmonics(&s, &both).is_empty());
/// ```
pub fn lost_harmonics(settings: &RunSettings, mountings: &[Mounting]) -> Vec<usize> {
    let n = settings.faces;
    if n < 2 || mountings.iter().any(|m| m.shift_deg != 0.0) {
        return Vec::new();
    }
    let offsets: Vec<usize> = mountings
        .iter()
        .flat_map(|m| {
            settings
                .ac_faces
                .iter()
                .map(move |&f| (f.saturating_sub(1) + m.face_shift) % n)
        })
        .collect();
    crate::solve::lost_harmonics(n, &offsets)
}

/// Why a run of `settings` in `mountings` cannot be evaluated, in the words of `polycal
/// plan` (the harmonics it loses and the face each autocollimator reads); `None` when
/// [`lost_harmonics`] finds nothing lost.
pub fn unevaluable(settings: &RunSettings, mountings: &[Mounting]) -> Option<String> {
    let lost = lost_harmonics(settings, mountings);
    if lost.is_empty() {
        return None;
    }
    let n = settings.faces;
    let names: Vec<String> = lost.iter().map(ToString::to_string).collect();
    let list = match names.as_slice() {
        [one] => one.clone(),
        [init @ .., last] => format!("{} and {last}", init.join(", ")),
        [] => String::new(),
    };
    let reads: Vec<String> = mountings
        .iter()
        .flat_map(|m| {
            settings.ac_faces.iter().enumerate().map(move |(j, &f)| {
                format!(
                    "setup {} ac {} reads face step+{}",
                    m.setup,
                    j + 1,
                    (f.saturating_sub(1) + m.face_shift) % n + 1
                )
            })
        })
        .collect();
    // Every offset differs from the first by a multiple of g faces (g = N / the period of
    // the harmonics seen), as `plan` says it.
    let g = n / lost.first().copied().unwrap_or(n).max(1);
    let advice = if reads.len() > 1 {
        format!(
            "; here all offsets differ by multiples of {g} faces: add an autocollimator or a \
             mounting whose offset differs by a number of faces sharing no factor with {n}"
        )
    } else {
        String::new()
    };
    Some(format!(
        "the design cannot determine every pitch deviation and encoder error: {} {list} of \
         the pitch deviations and the encoder errors {} undetermined ({}; harmonic k is lost \
         when k times every difference of face offsets is a multiple of {n}{advice})",
        if lost.len() == 1 {
            "harmonic"
        } else {
            "harmonics"
        },
        if lost.len() == 1 { "is" } else { "are" },
        reads.join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Direction;

    #[test]
    fn a_mounting_puts_the_stops_and_faces_where_simulate_does() {
        let settings = RunSettings::new(8, 1).with_ac_faces(vec![1, 2, 5]);
        let m = Mounting::new(3).with_shift_deg(10.0).with_face_shift(7);
        // simulate: ((ac_faces[j-1] − 1) + face shift + p) mod N + 1.
        for ac in 1..=3u32 {
            for p in 0..=8 {
                let f0 = settings.ac_faces[ac as usize - 1];
                assert_eq!(m.face(&settings, ac, p), (f0 - 1 + 7 + p) % 8 + 1);
            }
        }
        let closing = Stop {
            cycle: 1,
            step: 8,
            direction: Direction::Cw,
        };
        assert_eq!(m.table_deg(&closing, 8), 370.0);
        assert_eq!(
            Mounting::default().face(&settings, 2, 7),
            settings.face(2, 7)
        );
        assert_eq!(m.as_options(), "--setup 3 --shift 10 --face-shift 7");
        assert_eq!(m.to_string(), "mounting 3 (shift 10°, turned 7 faces)");
        assert_eq!(
            Mounting::new(2).with_face_shift(1).to_string(),
            "mounting 2 (shift 0°, turned 1 face)"
        );
    }

    #[test]
    fn a_design_that_loses_harmonics_is_named_until_a_mounting_completes_it() {
        let s = RunSettings::new(8, 1).with_ac_faces(vec![1, 5]);
        let first = [Mounting::new(1)];
        // Offsets 0 and 4 of 8: only the even harmonics' period 2 is seen.
        assert_eq!(lost_harmonics(&s, &first), [2, 4, 6]);
        let why = unevaluable(&s, &first).unwrap_or_default();
        assert!(why.contains("harmonics 2, 4 and 6"), "{why}");
        assert!(why.contains("setup 1 ac 2 reads face step+5"), "{why}");
        assert!(why.contains("differ by multiples of 4 faces"), "{why}");
        // A second mounting turned by 2 faces leaves offsets 0, 2, 4, 6: harmonic 4 lost.
        let two = [Mounting::new(1), Mounting::new(2).with_face_shift(2)];
        assert_eq!(lost_harmonics(&s, &two), [4]);
        let three = [Mounting::new(1), Mounting::new(2).with_face_shift(1)];
        assert!(unevaluable(&s, &three).is_none());
        // The paper's design loses nothing; a shifted mounting is left to `solve`.
        assert!(lost_harmonics(&RunSettings::new(8, 1), &first).is_empty());
        let shifted = [Mounting::new(1), Mounting::new(2).with_shift_deg(22.5)];
        assert!(lost_harmonics(&s, &shifted).is_empty());
    }

    #[test]
    fn a_mounting_out_of_range_is_named() {
        let s = RunSettings::new(8, 1);
        assert_eq!(Mounting::new(0).validate(&s), Err(SettingsError::Setup(0)));
        for shift in [-1.0, 360.0, f64::NAN] {
            let e = Mounting::new(2)
                .with_shift_deg(shift)
                .validate(&s)
                .unwrap_err();
            assert_eq!(e.setting(), "shift");
        }
        let e = Mounting::new(2)
            .with_face_shift(8)
            .validate(&s)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "face-shift 8: the polygon has 8 faces: 0 … 7"
        );
        assert!(Mounting::new(2).with_shift_deg(359.9).validate(&s).is_ok());
    }
}
