//! The closure solvers: the paper's closed form and a general constrained least squares.
//!
//! Both estimate, from a [`MeasurementSet`], the pitch deviations β, the face
//! deviations φ, the encoder errors α and the setup errors U of the model
//! (docs/FORMAT.md §1, the paper's eq. (2) written for any design)
//!
//! ```text
//! reading = α[step mod N] + φ[face] + U[setup, ac] + (effects) + noise,   Σα = 0, Σβ = 0.
//! ```
//!
//! - [`closed_form()`] is the paper's eqs. (6)–(10) for two autocollimators on adjacent
//!   faces, generic over nalgebra's dimension (no heap allocation for `Const<N>`);
//! - [`least_squares()`] handles any design a file describes (any number of
//!   autocollimators at any faces, repeated cycles, closing readings, both directions,
//!   several mountings) and returns the full covariance;
//! - [`solve`] picks between them ([`Method::Auto`]) and is the entry point of
//!   `polycal solve`;
//! - [`sub_pitch`] knows where shifted mountings (the `shift` column) put the encoder:
//!   [`solve`] maps whole-face shifts to encoder positions itself, and
//!   [`sub_pitch::solve_shifted`] solves mountings at any angle, with encoder errors at
//!   every table angle of every coset.
//!
//! The lower-level solvers ([`least_squares()`], [`closed_form()`], …) do not consult the
//! set's shifts: each reading's encoder position is its step mod N.
//!
//! Before solving, the design is checked for observability ([`observability`]): a design
//! that cannot determine every β and α is refused with the Fourier harmonics it loses.

pub mod circulant;
pub mod closed_form;
pub mod cofactor;
pub mod coset;
pub mod dense;
pub mod least_squares;
pub mod memory;
pub mod observability;
pub mod shift_geometry;
pub mod sub_pitch;
pub(crate) mod woodbury;

pub use closed_form::{ClosedFormSolution, NotPaperDesign, PaperDesign, closed_form};
pub use cofactor::Cofactor;
pub use dense::dense_least_squares;
pub use least_squares::{
    dense_with_options, least_squares, least_squares_with_options, least_squares_with_regressors,
};
pub use observability::{Unobservable, lost_harmonics};

use crate::measurement::{MeasurementSet, Sigma};
use crate::progress::Progress;
use nalgebra::{DMatrix, DVector, Dyn};

/// Which solver to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The closed form where it gives the least-squares answer (the paper's design with
    /// the same number of readings at every step and no closing readings), else least
    /// squares.
    #[default]
    Auto,
    /// The paper's closed form, eqs. (6)–(10); refused for other designs.
    ClosedForm,
    /// General constrained least squares: the circulant engine where it serves the
    /// design, else the dense factorisation ([`least_squares_with_options`] decides).
    LeastSquares,
    /// Least squares by the dense reference factorisation only (a cross-check of the
    /// circulant engine; O(N³) work and O(N²) memory, refused when it does not fit).
    Dense,
}

impl Method {
    /// The name used on the command line and in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::ClosedForm => "closed-form",
            Method::LeastSquares => "lsq",
            Method::Dense => "dense",
        }
    }
}

/// The engine that computed a [`Solution`]: which structure of the design it used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Engine {
    /// The paper's closed form, eqs. (6)–(10), with its covariance in closed form.
    ClosedForm,
    /// The circulant engine: the regular part of the design solved harmonic by harmonic
    /// (FFT), what breaks the symmetry (closing, missing or extra readings, effect
    /// columns) as a low-rank correction of rank `low_rank`.
    Circulant {
        /// Rank of the correction: irregular (stream, position) cells plus effect terms.
        low_rank: usize,
    },
    /// The coset engine ([`coset`]) of a set with sub-pitch mountings: every coset's
    /// regular part solved harmonic by harmonic (FFT, a (C + 1) × (C + 1) block per
    /// harmonic), what breaks the symmetry as a low-rank correction of rank `low_rank`.
    CosetCirculant {
        /// The number of cosets C.
        cosets: usize,
        /// Rank of the correction: irregular (stream, position) cells.
        low_rank: usize,
    },
    /// The dense reference: the reduced normal matrix factorised by Cholesky.
    Dense,
}

impl Engine {
    /// The name used in reports: `closed-form`, `circulant`, `coset-circulant` or `dense`.
    pub fn as_str(self) -> &'static str {
        match self {
            Engine::ClosedForm => "closed-form",
            Engine::Circulant { .. } => "circulant",
            Engine::CosetCirculant { .. } => "coset-circulant",
            Engine::Dense => "dense",
        }
    }
}

/// Options of [`solve`]: built with [`SolveOptions::new`] (or `default()`) and the
/// `with_…` methods.
///
/// ```
/// use polycal::measurement::Sigma;
/// use polycal::solve::{Method, SolveOptions};
///
/// let options = SolveOptions::new().with_method(Method::LeastSquares).with_sigma(Sigma::new(0.05)?);
/// assert_eq!(options.sigma.map(Sigma::arcsec), Some(0.05));
/// # Ok::<(), polycal::measurement::SigmaError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct SolveOptions {
    /// Solver choice.
    pub method: Method,
    /// Standard deviation of one reading stated by the caller. Used for the uncertainties
    /// only when the fit has no residual degrees of freedom (the bare two-autocollimator
    /// cycle is exactly determined); with dof > 0 the residual standard deviation is used.
    pub sigma: Option<Sigma>,
    /// The most memory, in bytes, the solver may plan to use; `None`: the memory the
    /// machine has available ([`memory::available_bytes`]). A design whose engine would
    /// need more is refused with [`SolveError::TooLarge`] before anything is allocated.
    pub memory_limit_bytes: Option<u64>,
}

impl SolveOptions {
    /// The defaults: [`Method::Auto`], no stated σ.
    pub fn new() -> Self {
        Self::default()
    }

    /// With this solver.
    pub fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    /// With a stated σ of one reading.
    pub fn with_sigma(mut self, sigma: Sigma) -> Self {
        self.sigma = Some(sigma);
        self
    }

    /// With a memory limit in bytes (instead of the machine's available memory).
    pub fn with_memory_limit(mut self, bytes: u64) -> Self {
        self.memory_limit_bytes = Some(bytes);
        self
    }

    /// With a stated σ when given (`None`: none stated).
    pub fn with_sigma_opt(mut self, sigma: Option<Sigma>) -> Self {
        self.sigma = sigma;
        self
    }
}

/// Why a measurement set could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolveError {
    /// The design does not determine every pitch deviation and encoder error.
    #[error(transparent)]
    Unobservable(#[from] Unobservable),
    /// `--method closed-form` on a design it does not cover.
    #[error(
        "the closed form (paper eqs. (6)–(10)) does not apply: {0}; the least-squares method does"
    )]
    ClosedFormNotApplicable(String),
    /// The design is too large for the memory the solver may use.
    #[error(
        "the design ({faces} positions, {streams} autocollimator streams, {effects} effect terms, {readings} readings) needs about {} of memory for the {engine} solver; {} {limit_source}",
        memory::human_bytes(*needed_bytes),
        memory::human_bytes(u128::from(*limit_bytes))
    )]
    TooLarge {
        /// N.
        faces: usize,
        /// K.
        streams: usize,
        /// E.
        effects: usize,
        /// Readings.
        readings: usize,
        /// The engine the design needs (`dense`, `circulant`, `coset-circulant`, or
        /// `sub-pitch` for the effect columns of sub-pitch cosets).
        engine: &'static str,
        /// Bytes it would need.
        needed_bytes: u128,
        /// Bytes it may use.
        limit_bytes: u64,
        /// Where the limit comes from (`are available on this machine`, `is the limit set`).
        limit_source: &'static str,
    },
    /// An effect regressor has the wrong length or a non-finite value.
    #[error("effect regressor {index}: {reason}")]
    BadRegressor {
        /// Index of the regressor.
        index: usize,
        /// What is wrong.
        reason: String,
    },
    /// [`solve`] of a set with sub-pitch mountings (a shift that is not a whole multiple
    /// of 360°/N): its encoder errors lie at other angles than the N positions, which a
    /// [`Solution`] cannot hold; [`sub_pitch::solve_shifted`] solves it.
    #[error(
        "the mountings' shifts are not all whole multiples of 360°/{faces}: their encoder \
         errors lie at {cosets} coset(s) of {faces} table angles, which sub_pitch::solve_shifted \
         evaluates"
    )]
    SubPitch {
        /// N.
        faces: usize,
        /// The number of cosets of table angles.
        cosets: usize,
    },
}

/// Where the standard deviation of one reading, σ, comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SigmaSource {
    /// √(RSS/dof) of the fit.
    Residual,
    /// Stated by the caller (`--sigma`), used because dof = 0.
    Stated,
}

/// The setup error of one autocollimator in one mounting, arcsec (generic gauge of
/// docs/FORMAT.md §1: for the paper's adjacent pair, paper U₁ = U₁ and paper U₂ = U₂ + β\[1\]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SetupError {
    /// Polygon mounting.
    pub setup: u32,
    /// Autocollimator number.
    pub ac: u32,
    /// Estimate, arcsec.
    pub value: f64,
}

/// Positions of the quantities in the parameter vector θ = [β (N), α (N), U (K),
/// effects (E)] that indexes [`Solution::cofactor`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParameterLayout {
    /// N.
    pub faces: usize,
    /// K, the number of (setup, ac) streams.
    pub setups: usize,
    /// E, the number of effect terms.
    pub effects: usize,
}

impl ParameterLayout {
    /// Index of β\[face\] (face 1-based).
    pub fn pitch(&self, face: usize) -> usize {
        face - 1
    }
    /// Index of α\[position\] (position 0-based).
    pub fn encoder(&self, position: usize) -> usize {
        self.faces + position
    }
    /// Index of the k-th setup error (0-based, in [`Solution::setup_error`] order).
    pub fn setup(&self, k: usize) -> usize {
        2 * self.faces + k
    }
    /// Index of the e-th effect term (0-based).
    pub fn effect(&self, e: usize) -> usize {
        2 * self.faces + self.setups + e
    }
    /// Length of θ.
    pub fn len(&self) -> usize {
        2 * self.faces + self.setups + self.effects
    }
    /// Whether θ is empty (never, for a solved polygon).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A solved calibration: estimates, residuals and covariance.
///
/// All values in arcseconds. Index 0 of `pitch_deviation`/`face_deviation` is face 1;
/// index p of `encoder_error` is the position p·360°/N.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Number of faces N.
    pub faces: usize,
    /// The solver that produced it (never [`Method::Auto`]).
    pub method: Method,
    /// The engine that computed it.
    pub engine: Engine,
    /// β\[1..=N\], Σβ = 0.
    pub pitch_deviation: Vec<f64>,
    /// φ\[1..=N\] (φ\[N\] = 0).
    pub face_deviation: Vec<f64>,
    /// α[0..N), Σα = 0.
    pub encoder_error: Vec<f64>,
    /// One per (setup, ac) stream, ascending.
    pub setup_error: Vec<SetupError>,
    /// Estimates of the effect terms (regressors), in the order given.
    pub effect_values: Vec<f64>,
    /// The effect columns of the design matrix, in the order of `effect_values`: one
    /// regressor per effect term, one value per reading of the measurement set (empty for
    /// the base model, and for the coset engine's sub-pitch fit, whose effect terms are
    /// the cosets' differences and whose columns it never forms: [`coset`]). The uncertainty propagation through the design
    /// ([`crate::uncertainty::calibration`]) needs them.
    pub effect_regressors: Vec<Vec<f64>>,
    /// Reading minus model, in the order of the measurement set.
    pub residuals: Vec<f64>,
    /// Number of readings used.
    pub readings: usize,
    /// Residual degrees of freedom: readings − (2N − 2 + K + E).
    pub dof: usize,
    /// Residual sum of squares, arcsec².
    pub rss: f64,
    /// σ of one reading and where it comes from; `None` when dof = 0 and none was stated.
    pub sigma: Option<(f64, SigmaSource)>,
    /// Cofactor matrix Q of θ ([`ParameterLayout`]): Cov(θ) = σ²·Q, as an operator
    /// (entries, diagonal, products; the dense matrix only on request).
    pub cofactor: Cofactor,
    /// Layout of θ.
    pub layout: ParameterLayout,
    /// The cycles of the measurement set with fewer steps than a whole cycle
    /// ([`MeasurementSet::incomplete_cycles`]): evaluated with the readings they have, and
    /// reported as warnings (docs/FORMAT.md §5.1 `warnings`). Set by [`solve`] and
    /// [`sub_pitch::solve_shifted`] from the set as read; empty from an engine alone.
    pub incomplete_cycles: Vec<crate::measurement::IncompleteCycle>,
}

impl Solution {
    /// √(RSS/dof), or `None` when dof = 0 (docs/FORMAT.md §5 `residual_rms`).
    pub fn residual_rms(&self) -> Option<f64> {
        (self.dof > 0).then(|| (self.rss / self.dof as f64).sqrt())
    }

    /// Covariance of θ, arcsec², when σ is known: the whole (2N + K + E)² matrix
    /// ([`Cofactor::to_dense`]); u of single quantities come from the `…_u` methods
    /// without it.
    pub fn covariance(&self) -> Option<DMatrix<f64>> {
        self.sigma.map(|(s, _)| self.cofactor.to_dense() * (s * s))
    }

    fn diagonal_u(&self, start: usize, len: usize) -> Option<Vec<f64>> {
        let (s, _) = self.sigma?;
        Some(
            (start..start + len)
                .map(|i| s * self.cofactor.entry(i, i).max(0.0).sqrt())
                .collect(),
        )
    }

    /// Standard uncertainties u(β) (k = 1), arcsec.
    pub fn pitch_deviation_u(&self) -> Option<Vec<f64>> {
        self.diagonal_u(self.layout.pitch(1), self.faces)
    }

    /// Standard uncertainties u(α) (k = 1), arcsec.
    pub fn encoder_error_u(&self) -> Option<Vec<f64>> {
        self.diagonal_u(self.layout.encoder(0), self.faces)
    }

    /// Standard uncertainties of the setup errors, arcsec.
    pub fn setup_error_u(&self) -> Option<Vec<f64>> {
        self.diagonal_u(self.layout.setup(0), self.layout.setups)
    }

    /// Standard uncertainties of the effect terms.
    pub fn effect_u(&self) -> Option<Vec<f64>> {
        self.diagonal_u(self.layout.effect(0), self.layout.effects)
    }

    /// Standard uncertainties u(φ) of the face deviations, arcsec (φ\[N\] = 0 exactly,
    /// so its u is 0): var φ\[f\] = Σ_{i,j ≤ f} Cov(β_i, β_j).
    pub fn face_deviation_u(&self) -> Option<Vec<f64>> {
        let (s, _) = self.sigma?;
        Some(
            self.cofactor
                .face_deviation_diagonal()
                .into_iter()
                .map(|q| s * q.max(0.0).sqrt())
                .collect(),
        )
    }

    /// The fit's covariance of one family of results, σ²·Q restricted to it (arcsec²),
    /// row-major `n × n` with `n` its length: β and φ over faces 1 … N, α over positions
    /// 0 … N−1, the setup errors in [`Solution::setup_error`] order. φ\[f\] = β\[1\] + … +
    /// β\[f\], so Cov(φ_f, φ_g) = Σ_{i ≤ f, j ≤ g} Cov(β_i, β_j), with φ\[N\]'s row and
    /// column exactly 0 (φ\[N\] = 0 by definition). Only this family's block
    /// is formed (O(n²) entries of the cofactor operator), never the whole matrix. `None`
    /// when σ is unknown (dof = 0 and none stated). Its diagonal is the square of the
    /// family's `…_u`.
    ///
    /// ```
    /// use polycal::results::Quantity;
    /// use polycal::simulate::{simulate, SimulationConfig};
    /// use polycal::solve::{solve, SolveOptions};
    ///
    /// let (set, _) = simulate(&SimulationConfig::default())?;
    /// let solution = solve(&set, &SolveOptions::default())?;
    /// let (n, cov) = solution.family_covariance(Quantity::EncoderError).unwrap();
    /// let u = solution.encoder_error_u().unwrap();
    /// assert_eq!(n, u.len());
    /// for p in 0..n {
    ///     assert!((cov[p * n + p] - u[p] * u[p]).abs() < 1e-12);
    /// }
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn family_covariance(&self, family: crate::results::Quantity) -> Option<(usize, Vec<f64>)> {
        use crate::results::Quantity;
        let (s, _) = self.sigma?;
        let variance = s * s;
        let block = |indices: &[usize]| -> Vec<f64> {
            let mut out = Vec::with_capacity(indices.len() * indices.len());
            for &i in indices {
                for &j in indices {
                    out.push(variance * self.cofactor.entry(i, j));
                }
            }
            out
        };
        let layout = &self.layout;
        let n = self.faces;
        Some(match family {
            // not estimated by a polygon's calibration
            Quantity::AngleBlock => return None,
            Quantity::PitchDeviation => {
                let indices: Vec<usize> = (1..=n).map(|f| layout.pitch(f)).collect();
                (n, block(&indices))
            }
            Quantity::EncoderError => {
                let indices: Vec<usize> = (0..n).map(|p| layout.encoder(p)).collect();
                (n, block(&indices))
            }
            Quantity::SetupError => {
                let indices: Vec<usize> = (0..layout.setups).map(|k| layout.setup(k)).collect();
                (layout.setups, block(&indices))
            }
            Quantity::FaceDeviation => {
                let indices: Vec<usize> = (1..=n).map(|f| layout.pitch(f)).collect();
                // running sums along each row, then down each column:
                // out[f][g] = Σ_{i ≤ f, j ≤ g} Cov(β_i, β_j)
                let mut out = block(&indices);
                for f in 0..n {
                    for g in 1..n {
                        out[f * n + g] += out[f * n + g - 1];
                    }
                }
                for f in 1..n {
                    for g in 0..n {
                        out[f * n + g] += out[(f - 1) * n + g];
                    }
                }
                // φ[N] = Σβ = 0 by definition: exactly, not to rounding
                for k in 0..n {
                    out[(n - 1) * n + k] = 0.0;
                    out[k * n + n - 1] = 0.0;
                }
                (n, out)
            }
        })
    }

    /// The polygon as a [`crate::polygon::DPolygon`].
    pub fn polygon(&self) -> crate::polygon::DPolygon {
        crate::polygon::Polygon::<Dyn>::from_pitch_deviation_closed(DVector::from_column_slice(
            &self.pitch_deviation,
        ))
        .unwrap_or_else(|_| unreachable!("a solution has at least 3 faces and finite values"))
    }
}

/// Solves a measurement set with the chosen method (the entry point of `polycal solve`).
///
/// ```
/// use polycal::simulate::{simulate, SimulationConfig};
/// use polycal::solve::{solve, SolveOptions};
///
/// let config = SimulationConfig { noise_arcsec: 0.0, ..SimulationConfig::default() };
/// let (set, truth) = simulate(&config)?;
/// let solution = solve(&set, &SolveOptions::default())?;
/// for (estimate, true_value) in solution.pitch_deviation.iter().zip(&truth.pitch_deviation) {
///     assert!((estimate - true_value).abs() < 1e-9);
/// }
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// Mountings shifted by whole faces (docs/FORMAT.md §2 `shift`) are solved in encoder
/// positions ([`sub_pitch::ShiftGeometry::encoder_set`]); a set without shifts is solved
/// as it stands.
///
/// # Errors
///
/// [`SolveError::SubPitch`] for a set with sub-pitch mountings (use
/// [`sub_pitch::solve_shifted`]); a design that cannot be determined
/// ([`SolveError::Unobservable`]), is too large ([`SolveError::TooLarge`]) or, for
/// [`Method::ClosedForm`], is not the paper's ([`SolveError::ClosedFormNotApplicable`]).
pub fn solve(set: &MeasurementSet, options: &SolveOptions) -> Result<Solution, SolveError> {
    solve_with_progress(set, options, None)
}

/// [`solve`] telling `progress` how far it is: `update(done, Some(total))` with a total
/// known from the start, a count weighted by the work each step takes (about one unit per
/// column of the reduced matrix's inverse), rising to its total when the solution is
/// done. Only the dense reference reports (the closed form and the circulant engine take
/// well under a second); the solution is the one [`solve`] gives, number for number.
///
/// ```
/// use std::sync::atomic::{AtomicU64, Ordering};
/// use polycal::simulate::{simulate, SimulationConfig};
/// use polycal::solve::{solve, solve_with_progress, Method, SolveOptions};
///
/// let (set, _) = simulate(&SimulationConfig::default())?;
/// let options = SolveOptions::new().with_method(Method::Dense);
/// let (done, total) = (AtomicU64::new(0), AtomicU64::new(0));
/// let observer = |d: u64, t: Option<u64>| {
///     done.store(d, Ordering::Relaxed);
///     total.store(t.unwrap_or(0), Ordering::Relaxed);
/// };
/// let observed = solve_with_progress(&set, &options, Some(&observer))?;
/// assert_eq!(observed.encoder_error, solve(&set, &options)?.encoder_error);
/// assert!(total.load(Ordering::Relaxed) > 0);
/// assert_eq!(done.load(Ordering::Relaxed), total.load(Ordering::Relaxed));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// As [`solve`].
pub fn solve_with_progress(
    set: &MeasurementSet,
    options: &SolveOptions,
    progress: Option<&dyn Progress>,
) -> Result<Solution, SolveError> {
    let mut solution = if !set.has_shifts() {
        solve_positions(set, options, progress)?
    } else {
        let geometry = sub_pitch::ShiftGeometry::of(set);
        if geometry.is_sub_pitch() {
            return Err(SolveError::SubPitch {
                faces: set.faces,
                cosets: geometry.cosets(),
            });
        }
        solve_positions(&geometry.encoder_set(set), options, progress)?
    };
    solution.incomplete_cycles = set.incomplete_cycles();
    Ok(solution)
}

/// [`solve`] of a set whose steps are its encoder positions (shifts not consulted), the
/// dense reference telling `progress` how far it is.
pub(crate) fn solve_positions(
    set: &MeasurementSet,
    options: &SolveOptions,
    progress: Option<&dyn Progress>,
) -> Result<Solution, SolveError> {
    match options.method {
        Method::LeastSquares => least_squares::least_squares_observed(set, &[], options, progress),
        Method::Dense => least_squares::dense_observed(set, &[], options, progress),
        Method::ClosedForm => match PaperDesign::detect(set) {
            Ok(design) => Ok(design.solve(set, options.sigma)?),
            Err(reason) => Err(SolveError::ClosedFormNotApplicable(reason.to_string())),
        },
        Method::Auto => match PaperDesign::detect(set) {
            Ok(design) => Ok(design.solve(set, options.sigma)?),
            Err(_) => least_squares::least_squares_observed(set, &[], options, progress),
        },
    }
}

/// σ from the residuals when dof > 0, else the stated σ.
pub(crate) fn choose_sigma(
    rss: f64,
    dof: usize,
    stated: Option<Sigma>,
) -> Option<(f64, SigmaSource)> {
    if dof > 0 {
        Some(((rss / dof as f64).sqrt(), SigmaSource::Residual))
    } else {
        stated.map(|s| (s.arcsec(), SigmaSource::Stated))
    }
}
