//! Which designs determine every pitch deviation and encoder error.
//!
//! Write the readings of one stream (an autocollimator in one mounting) whose face
//! offset is d — it reads face (p + d) mod N + 1 at step p — in the discrete Fourier
//! domain over the steps. For harmonic k ≠ 0 the stream sees
//! `α̂(k) + e^{2πi k d / N} φ̂(k)`: two unknowns, one equation per distinct phase
//! factor. Harmonic k of β and α is therefore determined exactly when two streams have
//! different phase factors, i.e. when k·(d_a − d_b) ≢ 0 (mod N) for some pair. With
//! g = gcd(N, all offset differences), harmonic k is lost exactly when N/g divides k:
//! a second autocollimator 3 faces away on a 24-faced polygon loses harmonics 8 and 16.
//! [`lost_harmonics`] is this rule. The circulant engine applies it directly (its regular
//! part is singular exactly at those harmonics, no eigen-decomposition needed); for
//! irregular designs (missing readings, effect terms that cannot be separated) the dense
//! path finds the null space of its normal matrix numerically and names the harmonics
//! it contains, so that those designs are judged as exactly.

use crate::measurement::MeasurementSet;

/// A design that cannot determine every quantity.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct Unobservable {
    /// Fourier harmonics k (1 … N−1) of the pitch deviations and encoder errors that the
    /// design cannot determine.
    pub harmonics: Vec<usize>,
    /// Effect terms (indices into the regressors) that cannot be separated.
    pub effects: Vec<usize>,
    /// The explanation, naming what is lost.
    pub message: String,
}

impl Unobservable {
    pub(crate) fn position_unread(position: usize, faces: usize) -> Self {
        Self {
            harmonics: Vec::new(),
            effects: Vec::new(),
            message: format!(
                "encoder position {position} ({:.4}°) has no reading, so its encoder error cannot be determined",
                position as f64 * 360.0 / faces as f64
            ),
        }
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// The harmonics k in 1 … N−1 lost by a design whose streams (autocollimator ×
/// mounting) read all N steps with the face offsets `offsets` (face = (step + d) mod N + 1).
///
/// ```
/// use polycal::solve::lost_harmonics;
/// assert_eq!(lost_harmonics(24, &[0, 1]), Vec::<usize>::new()); // the paper's design
/// assert_eq!(lost_harmonics(24, &[0, 3]), vec![8, 16]);
/// assert_eq!(lost_harmonics(6, &[2]).len(), 5); // one autocollimator sees nothing
/// ```
pub fn lost_harmonics(faces: usize, offsets: &[usize]) -> Vec<usize> {
    let Some(&first) = offsets.first() else {
        return (1..faces).collect();
    };
    let g = offsets.iter().fold(faces, |g, &d| {
        let difference = (d + faces - first % faces) % faces;
        gcd(g, difference)
    });
    let period = faces / g.max(1);
    (1..faces).filter(|k| k % period == 0).collect()
}

/// The refusal of a design that loses `harmonics` (and cannot separate the effect terms
/// `effects`), explained from its face offsets.
pub(crate) fn describe(
    harmonics: Vec<usize>,
    effects: Vec<usize>,
    set: &MeasurementSet,
) -> Unobservable {
    let n = set.faces;
    let offsets = set.face_offsets();
    let mut message =
        String::from("the design cannot determine every pitch deviation and encoder error: ");
    if !harmonics.is_empty() {
        message.push_str(&format!(
            "{} {} of the pitch deviations and the encoder errors {} undetermined",
            if harmonics.len() == 1 {
                "harmonic"
            } else {
                "harmonics"
            },
            join_and(&harmonics),
            if harmonics.len() == 1 { "is" } else { "are" },
        ));
        let described: Vec<String> = offsets
            .iter()
            .map(|((setup, ac), d)| format!("setup {setup} ac {ac} reads face step+{}", d + 1))
            .collect();
        let g = offsets
            .iter()
            .fold(n, |g, (_, d)| gcd(g, (d + n - offsets[0].1) % n));
        message.push_str(&format!(
            " ({}; harmonic k is lost when k times every difference of face offsets is a multiple of {n}",
            described.join(", ")
        ));
        if g > 1 && offsets.len() > 1 {
            message.push_str(&format!(
                "; here all offsets differ by multiples of {g} faces: add an autocollimator or a mounting whose offset differs by a number of faces sharing no factor with {n}"
            ));
        } else if offsets.len() <= 1 {
            message.push_str("; one autocollimator alone cannot separate the polygon from the encoder: add a second autocollimator or a shifted mounting");
        }
        message.push(')');
    }
    if !effects.is_empty() {
        if !harmonics.is_empty() {
            message.push_str("; ");
        }
        message.push_str(&format!(
            "effect term{} {} cannot be separated from the other unknowns",
            if effects.len() == 1 { "" } else { "s" },
            join_and(&effects.iter().map(|e| e + 1).collect::<Vec<_>>())
        ));
    }
    if harmonics.is_empty() && effects.is_empty() {
        message.push_str("the setup errors cannot be separated from the other unknowns");
    }
    Unobservable {
        harmonics,
        effects,
        message,
    }
}

/// |Σ_f x_f e^{−2πi k f / N}|² / N.
fn join_and(values: &[usize]) -> String {
    match values {
        [] => String::new(),
        [one] => one.to_string(),
        [init @ .., last] => format!(
            "{} and {last}",
            init.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rule_by_hand() {
        assert!(lost_harmonics(24, &[0, 1]).is_empty());
        assert_eq!(lost_harmonics(24, &[0, 3]), vec![8, 16]);
        assert_eq!(lost_harmonics(24, &[0, 2]), vec![12]);
        assert_eq!(lost_harmonics(24, &[0, 6, 3]), vec![8, 16]);
        assert!(lost_harmonics(24, &[0, 3, 8]).is_empty());
        assert_eq!(lost_harmonics(12, &[5, 9]), vec![3, 6, 9]);
        assert_eq!(lost_harmonics(7, &[0, 3]), Vec::<usize>::new());
    }
}
