//! The paper's closed form, eqs. (6)–(10), for two autocollimators on adjacent faces.
//!
//! Autocollimator 1 reads face p+1 and autocollimator 2 face p+2 (wrapping) at step p.
//! With the differences δ\[p\] = m₂\[p\] − m₁\[p\] of the (mean) readings:
//!
//! - eq. (7): β\[k\] − β\[1\] = δ\[k−2\] − δ\[N−1\] for k = 2 … N;
//! - eq. (8) with Σβ = 0 (eq. (1)): β\[1\] = −(1/N) Σ_p (δ\[p\] − δ\[N−1\]);
//! - eqs. (9), (10) with Σα = 0 (eq. (3)): U₁ = (Σm₁ − Σφ)/N, U₂ = (Σm₂ − Σφ)/N
//!   (generic gauge of docs/FORMAT.md §1: the paper's U₂ is this U₂ + β\[1\]);
//! - eqs. (4), (5): α\[p\] = m₁\[p\] − φ\[p+1\] − U₁ = m₂\[p\] − φ\[p+2\] − U₂ (identical for exact
//!   data; the mean of both is used).

use super::cofactor::{Base, Structured};
use super::{
    Cofactor, Engine, Method, ParameterLayout, SetupError, Solution, SolveError, choose_sigma,
};
use crate::measurement::{MeasurementSet, Sigma};
use crate::polygon::face_deviation_from_pitch;
use crate::polygon::{Polygon, PolygonError};
use nalgebra::{Const, DMatrix, DVector, DefaultAllocator, Dim, OVector, allocator::Allocator};

/// The closed-form result: the polygon, the encoder errors α[0..N) and the setup errors
/// [U₁, U₂] (generic gauge), all in arcsec.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedFormSolution<D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    /// Pitch and face deviations.
    pub polygon: Polygon<D>,
    /// α\[p\] at the nominal angle p·360°/N.
    pub encoder_error: OVector<f64, D>,
    /// Setup errors of autocollimators 1 and 2 (docs/FORMAT.md §1 gauge).
    pub setup_error: [f64; 2],
}

/// Solves the paper's design exactly from the per-step readings (or their means over
/// repeated cycles) of autocollimator 1 (`ac1_reading_arcsec\[p\]`, face p+1) and
/// autocollimator 2 (`ac2_reading_arcsec\[p\]`, face p+2). Generic over the dimension:
/// for `Const<N>` nothing is allocated on the heap.
///
/// ```
/// use nalgebra::SVector;
/// use polycal::solve::closed_form;
///
/// // readings made from β = [0.5, -0.25, 0.25, -0.5], α = [0.1, -0.2, 0.3, -0.2], U = [1, 2]
/// let beta = [0.5, -0.25, 0.25, -0.5];
/// let phi = [0.5, 0.25, 0.5, 0.0];
/// let alpha = [0.1, -0.2, 0.3, -0.2];
/// let m1 = SVector::<f64, 4>::from_fn(|p, _| alpha[p] + phi[p] + 1.0);
/// let m2 = SVector::<f64, 4>::from_fn(|p, _| alpha[p] + phi[(p + 1) % 4] + 2.0);
/// let solution = closed_form(&m1, &m2)?;
/// for (estimate, truth) in solution.polygon.pitch_deviation_arcsec().iter().zip(beta) {
///     assert!((estimate - truth).abs() < 1e-12);
/// }
/// assert!((solution.setup_error[1] - 2.0).abs() < 1e-12);
/// # Ok::<(), polycal::polygon::PolygonError>(())
/// ```
pub fn closed_form<D: Dim>(
    ac1_reading_arcsec: &OVector<f64, D>,
    ac2_reading_arcsec: &OVector<f64, D>,
) -> Result<ClosedFormSolution<D>, PolygonError>
where
    DefaultAllocator: Allocator<D>,
{
    let n = ac1_reading_arcsec.len();
    if n < 3 || ac2_reading_arcsec.len() != n {
        return Err(PolygonError::TooFewFaces(n.min(ac2_reading_arcsec.len())));
    }
    let dim = ac1_reading_arcsec.shape_generic().0;
    let nf = n as f64;
    // slices of one length: the loops below need no bounds checks and no `% n`
    let m1 = ac1_reading_arcsec.as_slice();
    let m2 = &ac2_reading_arcsec.as_slice()[..n];
    // δ[p] = m₂[p] − m₁[p]; eqs. (7), (8) with Σβ = 0 are β[1] = δ[N−1] − mean(δ) and
    // β[k] = δ[k−2] − mean(δ). Everything else waits for mean(δ) and then for the
    // cumulative sum φ, so the work is arranged to keep that path short:
    // - one pass over the readings for Σδ (in two partial sums: half the chain of
    //   dependent additions), Σm₁, Σm₂ and Σφ;
    // - Σ_f φ[f] = Σ_p ((N−3)/2 − p) δ[p] + N δ[N−1] (0-based p, from φ = cumulative β),
    //   so that U₁ and U₂ (eqs. (9), (10) with Σα = 0) do not wait for φ;
    // - the result is built once and filled in place.
    let last = m2[n - 1] - m1[n - 1];
    let (mut even, mut odd) = (0.0, 0.0);
    let (mut sum1, mut sum2, mut sum_phi) = (0.0, 0.0, nf * last);
    let weight_0 = 0.5 * (nf - 3.0);
    let (pairs1, rest1) = m1.as_chunks::<2>();
    let (pairs2, rest2) = m2.as_chunks::<2>();
    for (i, (a, b)) in pairs1.iter().zip(pairs2).enumerate() {
        let (delta_0, delta_1) = (b[0] - a[0], b[1] - a[1]);
        even += delta_0;
        odd += delta_1;
        sum1 += a[0] + a[1];
        sum2 += b[0] + b[1];
        let weight = weight_0 - (2 * i) as f64;
        sum_phi += weight * delta_0 + (weight - 1.0) * delta_1;
    }
    for (&a, &b) in rest1.iter().zip(rest2) {
        // odd N: p = N − 1
        even += b - a;
        sum1 += a;
        sum2 += b;
        sum_phi += (weight_0 - (n - 1) as f64) * (b - a);
    }
    let mean_delta = (even + odd) / nf;
    let u1 = (sum1 - sum_phi) / nf;
    let u2 = (sum2 - sum_phi) / nf;
    let mut beta = OVector::<f64, D>::zeros_generic(dim, Const::<1>);
    let (beta_1, beta_rest) = beta.as_mut_slice().split_at_mut(1);
    beta_1[0] = last - mean_delta;
    for ((beta_k, &a), &b) in beta_rest.iter_mut().zip(m1).zip(m2) {
        *beta_k = (b - a) - mean_delta;
    }
    let mut solution = ClosedFormSolution {
        polygon: Polygon::from_closed_pitch(beta),
        encoder_error: OVector::<f64, D>::zeros_generic(dim, Const::<1>),
        setup_error: [u1, u2],
    };
    // eqs. (4), (5), the mean of both: α[p] = (m₁[p] + m₂[p] − φ[p+1] − φ[p+2] − U₁ − U₂)/2
    // (faces 1-based, wrapping: φ[N+1] = φ[1])
    let phi = &solution.polygon.face_deviation_arcsec().as_slice()[..n];
    let u_mean = 0.5 * (u1 + u2);
    let alpha = &mut solution.encoder_error.as_mut_slice()[..n];
    for p in 0..n - 1 {
        alpha[p] = 0.5 * ((m1[p] + m2[p]) - (phi[p] + phi[p + 1])) - u_mean;
    }
    alpha[n - 1] = 0.5 * ((m1[n - 1] + m2[n - 1]) - (phi[n - 1] + phi[0])) - u_mean;
    Ok(solution)
}

/// A measurement set recognised as the paper's design: one mounting, two
/// autocollimators on adjacent faces, the same number of readings at every step and no
/// closing readings — the designs on which the closed form is the least-squares answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PaperDesign {
    /// The (setup, ac) stream that plays autocollimator 1 (reads face p + d + 1).
    pub first: (u32, u32),
    /// The stream that plays autocollimator 2 (reads the next face).
    pub second: (u32, u32),
    /// Face offset d of the first stream.
    pub offset: usize,
    /// Readings per (stream, step).
    pub repeats: usize,
}

/// Why a measurement set is not the paper's design (two autocollimators on adjacent
/// faces, one mounting, the same number of readings at every step, no closing readings),
/// so that the closed form of eqs. (6)–(10) does not apply.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum NotPaperDesign {
    /// Not two (setup, autocollimator) streams of one mounting.
    #[error(
        "it needs exactly two autocollimators in one mounting, the file has {streams} (setup, ac) streams"
    )]
    NotTwoStreams {
        /// The number of (setup, ac) streams.
        streams: usize,
    },
    /// The two autocollimators do not read adjacent faces.
    #[error("the two autocollimators do not read adjacent faces")]
    NotAdjacent,
    /// Closing readings (step N).
    #[error("closing readings (step N) make the steps unequally weighted")]
    ClosingReadings,
    /// Steps with different numbers of readings.
    #[error("the steps do not all have the same number of readings")]
    UnequalSteps,
}

impl PaperDesign {
    /// Recognises the design, or says why the closed form does not apply.
    ///
    /// # Errors
    ///
    /// [`NotPaperDesign`] saying which condition of the paper's design the set breaks.
    pub fn detect(set: &MeasurementSet) -> Result<Self, NotPaperDesign> {
        let n = set.faces;
        let streams = set.streams();
        if streams.len() != 2 || streams[0].0 != streams[1].0 {
            return Err(NotPaperDesign::NotTwoStreams {
                streams: streams.len(),
            });
        }
        let offsets = set.face_offsets();
        let (d_a, d_b) = (offsets[0].1, offsets[1].1);
        let (first, second, offset) = if (d_b + n - d_a) % n == 1 {
            (streams[0], streams[1], d_a)
        } else if (d_a + n - d_b) % n == 1 {
            (streams[1], streams[0], d_b)
        } else {
            return Err(NotPaperDesign::NotAdjacent);
        };
        if set.readings.iter().any(|r| r.step == n) {
            return Err(NotPaperDesign::ClosingReadings);
        }
        let mut counts = vec![0usize; 2 * n];
        for r in &set.readings {
            let s = usize::from((r.setup, r.ac) == second);
            counts[s * n + r.step] += 1;
        }
        let repeats = counts[0];
        if repeats == 0 || counts.iter().any(|&c| c != repeats) {
            return Err(NotPaperDesign::UnequalSteps);
        }
        Ok(Self {
            first,
            second,
            offset,
            repeats,
        })
    }

    /// θ = [β (N), α (N), U_first, U_second] from the rotated means (q = (p + d) mod N).
    fn theta(&self, m1: &DVector<f64>, m2: &DVector<f64>) -> Result<Vec<f64>, PolygonError> {
        let n = m1.len();
        let solution = closed_form(m1, m2)?;
        let mut theta = Vec::with_capacity(2 * n + 2);
        theta.extend(solution.polygon.pitch_deviation_arcsec().iter());
        theta.extend((0..n).map(|p| solution.encoder_error[(p + self.offset) % n]));
        theta.extend(solution.setup_error);
        Ok(theta)
    }

    /// Solves the set with the closed form: estimates from the per-step means, residuals
    /// against them, and the covariance by propagating the means through the (linear)
    /// closed form.
    pub fn solve(
        &self,
        set: &MeasurementSet,
        stated_sigma: Option<Sigma>,
    ) -> Result<Solution, SolveError> {
        let n = set.faces;
        let mut m1 = DVector::<f64>::zeros(n);
        let mut m2 = DVector::<f64>::zeros(n);
        for r in &set.readings {
            let q = (r.step + self.offset) % n;
            if (r.setup, r.ac) == self.first {
                m1[q] += r.reading_arcsec;
            } else {
                m2[q] += r.reading_arcsec;
            }
        }
        let repeats = self.repeats as f64;
        m1 /= repeats;
        m2 /= repeats;
        let theta = self
            .theta(&m1, &m2)
            .map_err(|e| SolveError::ClosedFormNotApplicable(e.to_string()))?;
        // streams in ascending order for the report
        let first_is_lower = self.first < self.second;
        let (u_first, u_second) = (theta[2 * n], theta[2 * n + 1]);
        let face_deviation = face_deviation_from_pitch(&theta[..n]);
        let residuals: Vec<f64> = set
            .readings
            .iter()
            .map(|r| {
                let u = if (r.setup, r.ac) == self.first {
                    u_first
                } else {
                    u_second
                };
                r.reading_arcsec - (theta[n + r.step] + face_deviation[r.face - 1] + u)
            })
            .collect();
        let rss: f64 = residuals.iter().map(|r| r * r).sum();
        let dof = set.readings.len() - 2 * n;

        // Cofactor in closed form (module documentation of `cofactor`): the regular
        // design of two streams on adjacent faces, R readings per step.
        let layout = ParameterLayout {
            faces: n,
            setups: 2,
            effects: 0,
        };
        let cofactor = Cofactor::structured(
            layout,
            Structured::new(
                Base::paper(n, self.offset, repeats),
                Vec::new(),
                &DMatrix::zeros(0, 0),
            ),
        );
        let (low, high) = if first_is_lower {
            ((self.first, u_first), (self.second, u_second))
        } else {
            ((self.second, u_second), (self.first, u_first))
        };
        Ok(Solution {
            faces: n,
            method: Method::ClosedForm,
            engine: Engine::ClosedForm,
            pitch_deviation: theta[..n].to_vec(),
            face_deviation,
            encoder_error: theta[n..2 * n].to_vec(),
            setup_error: [low, high]
                .into_iter()
                .map(|((setup, ac), value)| SetupError { setup, ac, value })
                .collect(),
            effect_values: Vec::new(),
            effect_regressors: Vec::new(),
            residuals,
            readings: set.readings.len(),
            dof,
            rss,
            sigma: choose_sigma(rss, dof, stated_sigma),
            cofactor,
            layout,
            incomplete_cycles: Vec::new(),
        })
    }
}
