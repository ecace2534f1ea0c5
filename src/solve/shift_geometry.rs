//! Where a shifted mounting puts the encoder (docs/FORMAT.md §2 `shift`, §9.1): the one
//! place that knows it. [`super::sub_pitch`] solves a set of such mountings.
//!
//! A mounting (`setup`) whose table stands at angle σ at step 0 stops at σ + p·360°/N.
//! In positions (units of 360°/N) that is x + p with x = σ·N/360; write
//! x = m + f with m = ⌊x + 10⁻⁶⌋ whole positions and f the fraction (0 when x is within
//! 10⁻⁶ of a whole number). Step p of the mounting is then at position (p + m) mod N of
//! the **coset** f: the N table angles (q + f)·360°/N, q = 0 … N−1. Mountings whose
//! fractions agree to 10⁻⁶ positions share a coset; the cosets are numbered by their
//! fraction, smallest first (coset 0 is the whole positions when some mounting is there).
//! [`ShiftGeometry`] is this bookkeeping.
//!
//! # Whole-face shifts
//!
//! When every fraction is 0 there is one coset, the N positions of the unshifted table:
//! the reading model is today's with each reading's encoder position (step + m) mod N.
//! [`ShiftGeometry::encoder_set`] renumbers the steps so (the closing step N of a mounting
//! with m ≠ 0 becomes step m, the position it stands at), and [`fn@super::solve`] solves that
//! set: a set without shifts is solved exactly as before.
//!
use std::collections::BTreeMap;

use crate::measurement::MeasurementSet;

/// Tolerance, in positions (units of 360°/N): a shift within it of a whole number of
/// positions is a whole-face shift, and two fractions within it are one coset.
pub const POSITION_TOLERANCE: f64 = 1e-6;

/// Where one mounting puts the encoder: its whole positions m and its coset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mounting {
    /// m, 0 … N−1: step p of the mounting is at position (p + m) mod N of its coset.
    pub whole_positions: usize,
    /// Its coset: an index into [`ShiftGeometry::coset_shift_deg`].
    pub coset: usize,
}

/// The cosets of table angles the mountings' shifts make (module documentation).
///
/// ```
/// use polycal::solve::sub_pitch::ShiftGeometry;
///
/// // 24 faces (15° apart): mountings at 0°, 5°, 20° (= 15° + 5°) and 30° (2 faces)
/// let g = ShiftGeometry::new(24, [(1, 0.0), (2, 5.0), (3, 20.0), (4, 30.0)]);
/// assert_eq!(g.coset_shift_deg(), &[0.0, 5.0]);
/// assert!(g.is_sub_pitch());
/// let m = g.mounting(3).unwrap();
/// assert_eq!((m.whole_positions, m.coset), (1, 1));
/// assert_eq!(g.mounting(4).unwrap().whole_positions, 2);
/// assert_eq!(g.angle_deg(1, 2), 35.0);
/// assert_eq!(&g.angles_deg()[..4], &[0.0, 5.0, 15.0, 20.0]);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ShiftGeometry {
    faces: usize,
    mountings: BTreeMap<u32, Mounting>,
    coset_shift_deg: Vec<f64>,
}

impl ShiftGeometry {
    /// The geometry of `faces` positions and the mountings `(setup, shift)`, each shift the
    /// table's angle at step 0 in degrees (any finite angle: taken modulo 360°; a
    /// non-finite one, which no valid set or simulation has, counts as 0). A setup given
    /// twice keeps its last shift. With no mounting at all the geometry has the one coset
    /// of the whole positions.
    pub fn new(faces: usize, shifts: impl IntoIterator<Item = (u32, f64)>) -> Self {
        let n = faces.max(1);
        let pitch = 360.0 / n as f64;
        // per setup: (whole positions, fraction in positions, fraction in degrees)
        let mut split: BTreeMap<u32, (usize, f64, f64)> = BTreeMap::new();
        for (setup, shift) in shifts {
            let shift = if shift.is_finite() { shift } else { 0.0 };
            let x = shift * n as f64 / 360.0;
            let whole = (x + POSITION_TOLERANCE).floor();
            let fraction = x - whole;
            let (fraction, degrees) = if fraction < POSITION_TOLERANCE {
                (0.0, 0.0)
            } else {
                (fraction, (shift - whole * pitch).max(0.0))
            };
            let m = (whole.rem_euclid(n as f64) as usize) % n;
            split.insert(setup, (m, fraction, degrees));
        }
        let mut fractions: Vec<(f64, f64)> = split.values().map(|&(_, f, d)| (f, d)).collect();
        fractions.sort_by(|a, b| a.0.total_cmp(&b.0));
        // cosets: fractions within the tolerance of the first of their run
        let mut cosets: Vec<(f64, f64)> = Vec::new();
        for (f, d) in fractions {
            if cosets
                .last()
                .is_none_or(|&(first, _)| f - first > POSITION_TOLERANCE)
            {
                cosets.push((f, d));
            }
        }
        if cosets.is_empty() {
            cosets.push((0.0, 0.0));
        }
        let coset_of = |f: f64| {
            cosets
                .iter()
                .rposition(|&(first, _)| f >= first)
                .unwrap_or(0)
        };
        let mountings = split
            .into_iter()
            .map(|(setup, (m, f, _))| {
                (
                    setup,
                    Mounting {
                        whole_positions: m,
                        coset: coset_of(f),
                    },
                )
            })
            .collect();
        ShiftGeometry {
            faces,
            mountings,
            coset_shift_deg: cosets.into_iter().map(|(_, d)| d).collect(),
        }
    }

    /// The geometry of a measurement set: every setup it reads, with its shift
    /// ([`MeasurementSet::shift_deg`]).
    pub fn of(set: &MeasurementSet) -> Self {
        let mut setups: Vec<u32> = set.readings.iter().map(|r| r.setup).collect();
        setups.sort_unstable();
        setups.dedup();
        Self::new(set.faces, setups.into_iter().map(|s| (s, set.shift_deg(s))))
    }

    /// N.
    pub fn faces(&self) -> usize {
        self.faces
    }

    /// The number of cosets C (at least 1).
    pub fn cosets(&self) -> usize {
        self.coset_shift_deg.len()
    }

    /// Each coset's shift modulo 360°/N, degrees, ascending: coset c holds the table
    /// angles `coset_shift_deg[c]` + q·360°/N. 0 for the whole positions.
    pub fn coset_shift_deg(&self) -> &[f64] {
        &self.coset_shift_deg
    }

    /// Whether some mounting stands between the whole positions (some coset's shift is
    /// not 0): its encoder errors are at other angles than p·360°/N.
    pub fn is_sub_pitch(&self) -> bool {
        self.coset_shift_deg.iter().any(|&d| d != 0.0)
    }

    /// Where mounting `setup` puts the encoder; `None` for a setup the geometry was not
    /// given.
    pub fn mounting(&self, setup: u32) -> Option<Mounting> {
        self.mountings.get(&setup).copied()
    }

    /// The table angle of position q of coset c, degrees: q·360°/N + the coset's shift.
    ///
    /// # Panics
    ///
    /// When `coset` is not below [`ShiftGeometry::cosets`].
    pub fn angle_deg(&self, coset: usize, position: usize) -> f64 {
        position as f64 * 360.0 / self.faces as f64 + self.coset_shift_deg[coset]
    }

    /// Every table angle of every coset, ascending, degrees: position q of coset c is
    /// entry q·C + c (each coset's shift is below 360°/N).
    pub fn angles_deg(&self) -> Vec<f64> {
        (0..self.faces)
            .flat_map(|q| (0..self.cosets()).map(move |c| (c, q)))
            .map(|(c, q)| self.angle_deg(c, q))
            .collect()
    }

    /// The set with each reading's step replaced by its encoder position in its coset,
    /// (step + m) mod N, and no shifts: the set the engine fits. The closing step N stays
    /// N for a mounting with m = 0 (position 0) and becomes m otherwise (the position it
    /// stands at); a setup the geometry was not given keeps its steps. Not revalidated: a
    /// (setup, cycle, position, ac) may be read twice (step 0 and the closing step).
    pub fn encoder_set(&self, set: &MeasurementSet) -> MeasurementSet {
        let n = set.faces;
        let readings = set
            .readings
            .iter()
            .map(|r| {
                let m = self.mounting(r.setup).map_or(0, |m| m.whole_positions);
                let mut r = r.clone();
                if m != 0 && n > 0 {
                    r.step = (r.step % n + m) % n;
                }
                r
            })
            .collect();
        MeasurementSet {
            faces: n,
            readings,
            source: set.source.clone(),
            setup_shift_deg: BTreeMap::new(),
        }
    }

    /// The coset of each reading of `set` (0 for a setup the geometry was not given).
    pub(super) fn reading_cosets(&self, set: &MeasurementSet) -> Vec<usize> {
        set.readings
            .iter()
            .map(|r| self.mounting(r.setup).map_or(0, |m| m.coset))
            .collect()
    }
}
