//! What a self-calibration gives and how it is asked for: the options of
//! [`solve`](fn@super::solve), its error, the solution (e, c, their uncertainties, the lost
//! harmonics), and the closure model's solution that both solvers — on the grid
//! (the engine, [`mod@super::solve`]) and off it ([`super::fourier`]) — hand to the assembly.

use nalgebra::DMatrix;

use super::Head;
use crate::input::FileError;
use crate::input::limits::READING_ARCSEC;
use crate::measurement::Sigma;
use crate::solve::cofactor::Cofactor;
use crate::solve::{Engine, SigmaSource, SolveError};
use crate::uncertainty::student::t_quantile;

/// A head is on the position grid when ψ·P/360° is within this many positions of a
/// whole number.
pub const ON_GRID_TOLERANCE_POSITIONS: f64 = 1e-6;

/// Options of [`solve`](fn@super::solve). Build with [`SelfcalOptions::new`] and the `with_…` methods.
///
/// ```
/// use polycal::selfcal::SelfcalOptions;
/// let options = SelfcalOptions::new().with_lost_harmonic_bound(0.05)?;
/// assert_eq!(options.lost_harmonic_bound_arcsec, Some(0.05));
/// assert!(SelfcalOptions::new().with_lost_harmonic_bound(f64::NAN).is_err());
/// # Ok::<(), polycal::selfcal::SelfcalSolveError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct SelfcalOptions {
    /// σ of one reading stated by the caller; used only when the fit has no residual
    /// degrees of freedom.
    pub sigma: Option<Sigma>,
    /// A bound A on the amplitude of every harmonic the head layout cannot see, arcsec:
    /// each such harmonic is taken as a sinusoid of amplitude A with unknown phase
    /// (arcsine distribution, u = A/√2) and added to u(e) (type B).
    pub lost_harmonic_bound_arcsec: Option<f64>,
    /// The most memory, in bytes, the solver may plan to use (as
    /// [`SolveOptions::memory_limit_bytes`](crate::solve::SolveOptions::memory_limit_bytes)).
    pub memory_limit_bytes: Option<u64>,
    /// The standard uncertainty of every head's nominal angle (heads 2 … M, relative to
    /// head 1), arcsec: through the slope of the disc's error it adds to u(e) and u(c)
    /// (type B; `head_angle.rs`).
    pub head_angle_u_arcsec: Option<f64>,
    /// The gauge of e: `None` for Σe = 0 over all P positions; `Some(n)` for Σe = 0 over
    /// the n angles k·360°/n (n divides P) — the gauge of an n-faced polygon's encoder
    /// errors, for comparing with them angle by angle.
    pub gauge_positions: Option<usize>,
}

impl SelfcalOptions {
    /// No stated σ, no bound on the lost harmonics.
    pub fn new() -> Self {
        Self::default()
    }

    /// With a stated σ when given.
    pub fn with_sigma_opt(mut self, sigma: Option<Sigma>) -> Self {
        self.sigma = sigma;
        self
    }

    /// With a bound on the amplitude of the lost harmonics, arcsec (0 … 10⁶, the range
    /// of a reading: docs/FORMAT.md §2.2).
    ///
    /// # Errors
    ///
    /// [`SelfcalSolveError::InvalidBound`] for a negative, non-finite or larger value.
    pub fn with_lost_harmonic_bound(mut self, arcsec: f64) -> Result<Self, SelfcalSolveError> {
        if !(arcsec >= 0.0 && arcsec <= READING_ARCSEC.max()) {
            return Err(SelfcalSolveError::InvalidBound { arcsec });
        }
        self.lost_harmonic_bound_arcsec = Some(arcsec);
        Ok(self)
    }

    /// With a standard uncertainty of the heads' nominal angles, arcsec (0 … 10⁶, the
    /// range of a reading: docs/FORMAT.md §2.2).
    ///
    /// # Errors
    ///
    /// [`SelfcalSolveError::InvalidHeadAngleU`] for a negative, non-finite or larger value.
    pub fn with_head_angle_u(mut self, arcsec: f64) -> Result<Self, SelfcalSolveError> {
        if !(arcsec >= 0.0 && arcsec <= READING_ARCSEC.max()) {
            return Err(SelfcalSolveError::InvalidHeadAngleU { arcsec });
        }
        self.head_angle_u_arcsec = Some(arcsec);
        Ok(self)
    }

    /// With the gauge Σe = 0 over the n angles k·360°/n instead of over all positions
    /// (checked against P by [`solve`](fn@super::solve)).
    pub fn with_gauge_positions(mut self, n: usize) -> Self {
        self.gauge_positions = Some(n);
        self
    }

    /// With a memory limit, bytes.
    pub fn with_memory_limit(mut self, bytes: u64) -> Self {
        self.memory_limit_bytes = Some(bytes);
        self
    }
}

/// Why a self-calibration could not be solved.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SelfcalSolveError {
    /// The closure engine refused the design (too large for the machine's memory, say).
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The readings do not form a closure design (a set not validated by the file's
    /// rules).
    #[error("the self-calibration readings do not form a closure design: {0}")]
    Design(FileError),
    /// A set that breaks the self-calibration file's rules (built field by field).
    #[error("the self-calibration set is not valid: {0}")]
    Invalid(FileError),
    /// The bound on the lost harmonics is negative, not finite, or beyond a reading's range.
    #[error(
        "the bound on the lost harmonics must be a number from 0 to 1e6 arcsec (the range of a reading), not {}",
        crate::input::limits::show(*arcsec)
    )]
    InvalidBound {
        /// The value given.
        arcsec: f64,
    },
    /// The uncertainty of the head angles is negative, not finite, or beyond a reading's
    /// range.
    #[error(
        "the uncertainty of the head angles must be a number from 0 to 1e6 arcsec (the range of a reading), not {}",
        crate::input::limits::show(*arcsec)
    )]
    InvalidHeadAngleU {
        /// The value given.
        arcsec: f64,
    },
    /// The gauge's positions do not divide P.
    #[error(
        "the gauge over {gauge} angles needs {gauge} to divide the {positions} positions (and be at least 1)"
    )]
    InvalidGauge {
        /// P.
        positions: usize,
        /// The n asked for.
        gauge: usize,
    },
    /// A diagnosis of a self-calibration whose heads sit between the positions (the
    /// diagnosis fits the closure model, which needs every head on the position grid).
    #[error(
        "head{} {} sit{} between the {positions} positions: the diagnosis needs every head on the position grid (head angles multiples of 360°/{positions})",
        if heads.len() == 1 { "" } else { "s" },
        heads.iter().map(u32::to_string).collect::<Vec<_>>().join(", "),
        if heads.len() == 1 { "s" } else { "" }
    )]
    HeadsOffGrid {
        /// The heads between positions.
        heads: Vec<u32>,
        /// P.
        positions: usize,
    },
    /// The design is too large to solve here.
    #[error(
        "{positions} positions × {heads} heads: the band-limited solver needs {needed_bytes} bytes, more than the {limit_bytes} bytes allowed"
    )]
    TooLarge {
        /// P.
        positions: usize,
        /// M.
        heads: usize,
        /// Bytes the solver would need.
        needed_bytes: u128,
        /// Bytes allowed.
        limit_bytes: u64,
    },
}

/// The placement error of one read head relative to head 1, arcsec.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadError {
    /// Head number (2 … M).
    pub head: u32,
    /// Nominal angle from head 1, degrees.
    pub angle_deg: f64,
    /// c\[head\] − c\[1\], arcsec.
    pub value: f64,
    /// Standard uncertainty, arcsec (type A, with the heads' angle uncertainty when
    /// given); `None` when σ is unknown.
    pub u: Option<f64>,
    /// The type A part of `u`.
    pub u_type_a: Option<f64>,
    /// What the heads' angle uncertainty adds to `u`, arcsec, when given.
    pub head_angle_u: Option<f64>,
}

/// How the heads sit on the position grid, and so which solver ran.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum HeadGrid {
    /// Every head on the position grid: the closure engine of [`crate::solve`].
    OnGrid,
    /// Some head between positions: the band-limited solver (same normal equations,
    /// fractional phases).
    OffGrid,
}

/// A solved self-calibration (docs/FORMAT.md §9).
#[derive(Debug, Clone, PartialEq)]
pub struct SelfcalSolution {
    /// P, the number of positions.
    pub positions: usize,
    /// The heads, by number.
    pub heads: Vec<Head>,
    /// Number of cycles C.
    pub cycles: usize,
    /// Number of readings.
    pub readings: usize,
    /// e at the positions k·360°/P, arcsec (Σe = 0 over all positions, or over the
    /// gauge's: [`SelfcalOptions::gauge_positions`]).
    pub encoder_error: Vec<f64>,
    /// The gauge's n, when e is referenced to n angles.
    pub gauge_positions: Option<usize>,
    /// Standard uncertainty of each e, arcsec: type A, plus the bound on the lost
    /// harmonics when one was given; `None` when σ is unknown.
    pub encoder_error_u: Option<Vec<f64>>,
    /// The type A part of `encoder_error_u`.
    pub encoder_error_u_type_a: Option<Vec<f64>>,
    /// The lost harmonics' part of `encoder_error_u` (one number for every position),
    /// when a bound was given.
    pub lost_harmonic_u: Option<f64>,
    /// What the uncertainty of the heads' angles adds to each u(e) (type B), arcsec, when
    /// one was given.
    pub head_angle_u: Option<Vec<f64>>,
    /// The angle of each position, degrees (k·360/P).
    pub encoder_angle_deg: Vec<f64>,
    /// Heads 2 … M relative to head 1.
    pub head_error: Vec<HeadError>,
    /// Harmonic orders 1 … P/2 the head layout cannot determine (set to zero).
    pub lost_harmonics: Vec<usize>,
    /// Residual degrees of freedom: readings − C·P − (P − 1 − L) − (M − 1), L the lost
    /// dimensions.
    pub dof: usize,
    /// Residual sum of squares, arcsec².
    pub rss: f64,
    /// σ of one reading and where it comes from.
    pub sigma: Option<(f64, SigmaSource)>,
    /// Reading minus model, in the order of the set's readings.
    pub residuals: Vec<f64>,
    /// Where the heads sit: which solver ran.
    pub grid: HeadGrid,
    /// The engine that solved the closure model.
    pub engine: Engine,
    /// The cofactor of the closure model θ = [β, α, U] with the disc as the polygon:
    /// e = φ − φ̄ ([`Cofactor::centered_face_deviation_diagonal`]).
    pub cofactor: Cofactor,
    /// Sentences for people: what was lost, what was assumed.
    pub notes: Vec<String>,
}

/// The coverage probability of the expanded uncertainties U = k·u of a self-calibration.
pub const COVERAGE_PROBABILITY: f64 = 0.95;

impl SelfcalSolution {
    /// √(RSS/dof), or `None` when dof = 0.
    pub fn residual_rms(&self) -> Option<f64> {
        (self.dof > 0).then(|| (self.rss / self.dof as f64).sqrt())
    }

    /// Degrees of freedom of the type A part: the residual dof for σ from the residuals,
    /// infinite (`None`) for a stated σ.
    fn type_a_dof(&self) -> Option<f64> {
        match self.sigma {
            Some((_, SigmaSource::Residual)) => Some(self.dof as f64),
            _ => None,
        }
    }

    /// The coverage factor k of each u(e) at [`COVERAGE_PROBABILITY`]: Student's t for
    /// the Welch–Satterthwaite ν_eff = u⁴/(u_A⁴/ν_A) (the lost harmonics' bound has
    /// infinite degrees of freedom); `None` when σ is unknown.
    pub fn encoder_error_k(&self) -> Option<Vec<f64>> {
        let (u, u_a) = (
            self.encoder_error_u.as_ref()?,
            self.encoder_error_u_type_a.as_ref()?,
        );
        let nu_a = self.type_a_dof();
        Some(
            u.iter()
                .zip(u_a)
                .map(|(&u, &ua)| {
                    let nu = nu_a.map(|nu| {
                        if ua > 0.0 {
                            nu * (u / ua).powi(4)
                        } else {
                            f64::INFINITY
                        }
                    });
                    t_quantile(COVERAGE_PROBABILITY, nu.filter(|v| v.is_finite()))
                })
                .collect(),
        )
    }

    /// The coverage factor k of each head error at [`COVERAGE_PROBABILITY`] (as
    /// [`SelfcalSolution::encoder_error_k`]: Welch–Satterthwaite with the heads' angle
    /// term of infinite degrees of freedom); `None` when σ is unknown.
    pub fn head_error_k(&self) -> Option<Vec<f64>> {
        self.sigma?;
        let nu_a = self.type_a_dof();
        Some(
            self.head_error
                .iter()
                .map(|h| {
                    let (u, ua) = (h.u.unwrap_or(0.0), h.u_type_a.unwrap_or(0.0));
                    let nu = nu_a.map(|nu| {
                        if ua > 0.0 {
                            nu * (u / ua).powi(4)
                        } else {
                            f64::INFINITY
                        }
                    });
                    t_quantile(COVERAGE_PROBABILITY, nu.filter(|v| v.is_finite()))
                })
                .collect(),
        )
    }
}

/// The closure model's solution in the reported gauge of docs/FORMAT.md §1, from either
/// solver.
pub(super) struct Closure {
    /// φ[1..=P] (φ[P] = 0): e = φ − φ̄.
    pub(super) face_deviation: Vec<f64>,
    /// U per head, in head order.
    pub(super) setup: Vec<f64>,
    /// Residuals of the closure model (one t per step), in the set's order.
    pub(super) residuals: Vec<f64>,
    pub(super) cofactor: Cofactor,
    /// Lost harmonics k in 1 … P−1.
    pub(super) lost: Vec<usize>,
    pub(super) engine: Engine,
    /// Columns fitted beyond the closure model and the table's nuisance (0 for a solve).
    pub(super) extra_parameters: usize,
}

/// An empty low-rank part, for a cofactor that is the regular part alone.
pub(super) fn no_correction() -> DMatrix<f64> {
    DMatrix::zeros(0, 0)
}
