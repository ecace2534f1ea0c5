//! The polygon: pitch deviations β and face deviations φ, with the closure condition.
//!
//! [`Polygon`] is generic over nalgebra's dimension `D`: `Polygon<Const<24>>` keeps its
//! deviations on the stack (a polygon whose face count is known at compile time), and
//! `Polygon<Dyn>` on the heap (a face count read from a file). Both run the same code.

use nalgebra::{Const, DefaultAllocator, Dim, Dyn, OVector, allocator::Allocator};

/// Tolerance, in arcseconds, for the closure Σβ = 0 of an entered polygon.
pub const CLOSURE_TOLERANCE_ARCSEC: f64 = 1e-9;

/// Why a polygon could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PolygonError {
    /// Fewer than three faces.
    #[error("a polygon needs at least 3 faces, got {0}")]
    TooFewFaces(usize),
    /// The pitch deviations do not close: Σβ ≠ 0 (paper eq. (1)).
    #[error("pitch deviations do not close: their sum is {sum_arcsec}″, not 0")]
    NotClosed {
        /// Σβ, arcseconds.
        sum_arcsec: f64,
    },
    /// A value is NaN or infinite.
    #[error("pitch deviation of face {face} is not a finite number")]
    NotFinite {
        /// The face, 1-based.
        face: usize,
    },
}

/// An N-faced polygon: pitch deviation β\[k\] and face deviation φ\[k\] of every face
/// k = 1 … N, in arcseconds.
///
/// Conventions (docs/FORMAT.md §1): Σβ = 0 (the paper's closure, eq. (1)) and
/// φ\[f\] = β\[1\] + … + β\[f\], so φ\[N\] = 0. Index 0 of the vectors is face 1.
///
/// ```
/// use nalgebra::{Const, SVector};
/// use polycal::polygon::Polygon;
///
/// let beta = SVector::<f64, 4>::new(0.5, -0.25, 0.25, -0.5);
/// let polygon: Polygon<Const<4>> = Polygon::from_pitch_deviation(beta)?;
/// assert_eq!(polygon.face_deviation_arcsec().as_slice(), &[0.5, 0.25, 0.5, 0.0]);
/// # Ok::<(), polycal::polygon::PolygonError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    pitch_deviation: OVector<f64, D>,
    face_deviation: OVector<f64, D>,
}

/// A polygon whose face count is known at compile time (no heap allocation).
pub type SPolygon<const N: usize> = Polygon<Const<N>>;
/// A polygon whose face count is known at run time.
pub type DPolygon = Polygon<Dyn>;

impl<D: Dim> Polygon<D>
where
    DefaultAllocator: Allocator<D>,
{
    /// Builds a polygon from its pitch deviations β\[1..=N\] (arcsec), which must close
    /// (|Σβ| ≤ [`CLOSURE_TOLERANCE_ARCSEC`] × N).
    pub fn from_pitch_deviation(pitch_deviation: OVector<f64, D>) -> Result<Self, PolygonError> {
        let faces = pitch_deviation.len();
        if faces < 3 {
            return Err(PolygonError::TooFewFaces(faces));
        }
        if let Some(k) = pitch_deviation.iter().position(|b| !b.is_finite()) {
            return Err(PolygonError::NotFinite { face: k + 1 });
        }
        let sum_arcsec: f64 = pitch_deviation.iter().sum();
        if sum_arcsec.abs() > CLOSURE_TOLERANCE_ARCSEC * faces as f64 {
            return Err(PolygonError::NotClosed { sum_arcsec });
        }
        let face_deviation = face_deviation_of(&pitch_deviation);
        Ok(Self {
            pitch_deviation,
            face_deviation,
        })
    }

    /// Builds a polygon from pitch deviations that need not close, by removing their mean
    /// (the least-squares projection onto Σβ = 0).
    pub fn from_pitch_deviation_closed(
        mut pitch_deviation: OVector<f64, D>,
    ) -> Result<Self, PolygonError> {
        let faces = pitch_deviation.len();
        if faces < 3 {
            return Err(PolygonError::TooFewFaces(faces));
        }
        let mean = pitch_deviation.iter().sum::<f64>() / faces as f64;
        pitch_deviation.iter_mut().for_each(|b| *b -= mean);
        Self::from_pitch_deviation(pitch_deviation)
    }

    /// A polygon from pitch deviations that close by construction (solver output):
    /// no checks, φ computed as the cumulative sum.
    pub(crate) fn from_closed_pitch(pitch_deviation: OVector<f64, D>) -> Self {
        let face_deviation = face_deviation_of(&pitch_deviation);
        Self {
            pitch_deviation,
            face_deviation,
        }
    }

    /// Number of faces N.
    pub fn faces(&self) -> usize {
        self.pitch_deviation.len()
    }

    /// Pitch deviations β\[1..=N\], arcsec (index 0 is face 1).
    pub fn pitch_deviation_arcsec(&self) -> &OVector<f64, D> {
        &self.pitch_deviation
    }

    /// Face deviations φ\[1..=N\] = cumulative sums of β, arcsec (φ\[N\] = 0).
    pub fn face_deviation_arcsec(&self) -> &OVector<f64, D> {
        &self.face_deviation
    }

    /// Nominal angle of face k (1-based) from face 1, degrees: (k − 1)·360°/N.
    pub fn nominal_angle_degrees(&self, face: usize) -> f64 {
        (face as f64 - 1.0) * 360.0 / self.faces() as f64
    }
}

/// Turns pitch deviations β\[1..=N\] into face deviations φ\[f\] = β\[1\] + … + β\[f\]
/// in place (docs/FORMAT.md §1; the paper's eq. (1) gives Σβ = 0, so φ\[N\] = 0).
///
/// This is the crate's one definition of φ: summed left to right, with φ\[N\] set to
/// exactly 0, which drops the rounding of a closed β (callers pass a closed β: a solver's
/// output, a checked [`Polygon`] or a checked truth).
///
/// ```
/// let mut values = [0.5, -0.25, -0.25];
/// polycal::polygon::accumulate_face_deviation(&mut values);
/// assert_eq!(values, [0.5, 0.25, 0.0]);
/// ```
pub fn accumulate_face_deviation(values: &mut [f64]) {
    let mut running = 0.0;
    for value in values.iter_mut() {
        running += *value;
        *value = running;
    }
    if let Some(last) = values.last_mut() {
        *last = 0.0;
    }
}

/// The face deviations φ of pitch deviations β, as a new vector
/// ([`accumulate_face_deviation`]).
pub fn face_deviation_from_pitch(pitch_deviation: &[f64]) -> Vec<f64> {
    let mut face_deviation = pitch_deviation.to_vec();
    accumulate_face_deviation(&mut face_deviation);
    face_deviation
}

/// φ of a β held in an nalgebra vector, without a heap allocation for `Const<N>`.
fn face_deviation_of<D: Dim>(pitch_deviation: &OVector<f64, D>) -> OVector<f64, D>
where
    DefaultAllocator: Allocator<D>,
{
    let mut face_deviation = pitch_deviation.clone();
    accumulate_face_deviation(face_deviation.as_mut_slice());
    face_deviation
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DVector, SVector};

    #[test]
    fn const_and_dyn_agree() {
        let beta = [0.3, -0.1, 0.4, -0.2, -0.4];
        let s = SPolygon::<5>::from_pitch_deviation(SVector::from(beta)).unwrap();
        let d = DPolygon::from_pitch_deviation(DVector::from_column_slice(&beta)).unwrap();
        assert_eq!(
            s.face_deviation_arcsec().as_slice(),
            d.face_deviation_arcsec().as_slice()
        );
        // hand-derived cumulative sums
        let phi = [0.3, 0.2, 0.6, 0.4, 0.0];
        for (a, b) in d.face_deviation_arcsec().iter().zip(phi) {
            assert!((a - b).abs() < 1e-15);
        }
    }

    #[test]
    fn refuses_open_and_small() {
        let open = DVector::from_column_slice(&[0.1, 0.1, 0.1]);
        assert!(matches!(
            DPolygon::from_pitch_deviation(open.clone()),
            Err(PolygonError::NotClosed { .. })
        ));
        let closed = DPolygon::from_pitch_deviation_closed(open).unwrap();
        assert!(
            closed
                .pitch_deviation_arcsec()
                .iter()
                .all(|b| b.abs() < 1e-15)
        );
        assert_eq!(
            DPolygon::from_pitch_deviation(DVector::from_column_slice(&[0.0, 0.0])),
            Err(PolygonError::TooFewFaces(2))
        );
        let nan = DVector::from_column_slice(&[0.0, f64::NAN, 0.0]);
        assert_eq!(
            DPolygon::from_pitch_deviation(nan),
            Err(PolygonError::NotFinite { face: 2 })
        );
    }
}
