//! Solving a self-calibration: the closure model with the disc in the polygon's place.
//!
//! Head j at nominal angle ψ_j sits at the (possibly fractional) position offset
//! d_j = ψ_j·P/360° of the P-position grid. In the closure model of docs/FORMAT.md §1 it
//! is the stream (autocollimator) with face offset d_j: the table's error t plays the
//! encoder error α, the disc's graduation error e plays the face deviation φ′ (in the
//! gauge Σφ′ = 0) and the head's placement error c plays the setup error U.
//!
//! - **Heads on the grid** (every d_j a whole number, to 1e-6 of a position): the
//!   readings are a closure design and [`crate::solve`]'s circulant engine solves them,
//!   with the harmonics the head layout loses set to zero instead of refused.
//! - **Heads off the grid**: e is taken as band-limited (harmonics below P/2, and the
//!   harmonic P/2 as a cosine on the grid) and evaluated between the positions by its
//!   Fourier series; [`super::fourier`] solves the same normal equations harmonic by
//!   harmonic with fractional phases, and its cofactor is the engine's.
//!
//! The table's error is a nuisance per (cycle, step): in a balanced design (every head
//! reads every step in every cycle) the estimates of e and c, and their cofactor, are
//! those of the closure model with one t per step on the readings of all cycles; the
//! residuals of the full model are those residuals minus their mean over the heads of
//! each stop, with C·P table parameters instead of P.

use nalgebra::DMatrix;

use super::head_angle::head_angle_u;
use super::{Head, SelfcalError, SelfcalSet, fourier};
use crate::input::limits::READING_ARCSEC;
use crate::measurement::{MeasurementError, MeasurementSet, Reading, Sigma, step_angle_deg};
use crate::solve::cofactor::Cofactor;
use crate::solve::least_squares::least_squares_zeroing_lost;
use crate::solve::{Engine, ParameterLayout, SigmaSource, Solution, SolveError, SolveOptions};
use crate::uncertainty::student::t_quantile;

/// A head is on the position grid when ψ·P/360° is within this many positions of a
/// whole number.
pub const ON_GRID_TOLERANCE_POSITIONS: f64 = 1e-6;

/// Options of [`solve`]. Build with [`SelfcalOptions::new`] and the `with_…` methods.
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
    /// [`SolveOptions::memory_limit_bytes`]).
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
    /// (checked against P by [`solve`]).
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
    Design(#[from] MeasurementError),
    /// A set that breaks the self-calibration file's rules (built field by field).
    #[error("the self-calibration set is not valid: {0}")]
    Invalid(#[from] SelfcalError),
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

/// Solves a self-calibration: e at every position with Σe = 0, every head's c relative
/// to head 1, their uncertainties, and the harmonics the layout cannot see.
///
/// ```
/// use polycal::measurement::Direction;
/// use polycal::selfcal::{self, HeadReading, SelfcalOptions, SelfcalSet};
///
/// // three heads 120° apart on a 12-position grid, no noise: e is recovered except
/// // for its harmonics 3 and 6, which three equally spaced heads cannot see
/// let (p, angles) = (12, [0.0, 120.0, 240.0]);
/// let e = |x: f64| 0.4 * (x.to_radians() * 2.0).cos() + 0.1 * (x.to_radians() * 3.0).sin();
/// let mut readings = Vec::new();
/// for step in 0..p {
///     for (j, &psi) in angles.iter().enumerate() {
///         let angle = step as f64 * 30.0 + psi;
///         readings.push(HeadReading {
///             cycle: 1, step, head: j as u32 + 1, head_angle_deg: psi,
///             reading_arcsec: 0.7 * step as f64 + e(angle) + 0.5 * j as f64,
///             direction: Direction::Cw, time_seconds: None, line: 0,
///         });
///     }
/// }
/// let set = SelfcalSet::from_readings(readings, None)?;
/// let solution = selfcal::solve(&set, &SelfcalOptions::new())?;
/// assert_eq!(solution.lost_harmonics, [3, 6]);
/// for (x, value) in solution.encoder_error.iter().enumerate() {
///     let harmonic_2 = 0.4 * (x as f64 * 30f64.to_radians() * 2.0).cos();
///     assert!((value - harmonic_2).abs() < 1e-9);
/// }
/// assert!((solution.head_error[0].value - 0.5).abs() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// [`SelfcalSolveError::Invalid`] for a set that breaks the file's rules (a set built
/// field by field), [`SelfcalSolveError::Solve`] when the engine refuses the design
/// (memory).
pub fn solve(
    set: &SelfcalSet,
    options: &SelfcalOptions,
) -> Result<SelfcalSolution, SelfcalSolveError> {
    set.check()?;
    let solution = solve_closure(set, options)?;
    add_head_angle_u(set, solution, options)
}

/// `solution` with what the uncertainty of the heads' angles adds to u(e) and u(c), when
/// the options state one (`head_angle.rs`), and a note saying how much.
pub(crate) fn add_head_angle_u(
    set: &SelfcalSet,
    mut solution: SelfcalSolution,
    options: &SelfcalOptions,
) -> Result<SelfcalSolution, SelfcalSolveError> {
    if let Some(u_angle) = options.head_angle_u_arcsec {
        let (on_e, on_c) = head_angle_u(set, &solution, u_angle, options)?;
        if let Some(u) = &mut solution.encoder_error_u {
            for (u, b) in u.iter_mut().zip(&on_e) {
                *u = u.hypot(*b);
            }
        }
        for (h, b) in solution.head_error.iter_mut().zip(&on_c) {
            h.u = h.u.map(|u| u.hypot(*b));
            h.head_angle_u = Some(*b);
        }
        solution.notes.push(format!(
            "the heads' angles, each with u = {u_angle} arcsec, add up to {:.2e} arcsec to u(e) through the slope of the disc's error",
            on_e.iter().copied().fold(0.0, f64::max)
        ));
        solution.head_angle_u = Some(on_e);
    }
    Ok(solution)
}

/// [`solve`] without the heads' angle uncertainty (which is computed by solving the
/// patterns it puts into the readings).
pub(super) fn solve_closure(
    set: &SelfcalSet,
    options: &SelfcalOptions,
) -> Result<SelfcalSolution, SelfcalSolveError> {
    let p = set.positions;
    if let Some(gauge) = options.gauge_positions
        && (gauge == 0 || !p.is_multiple_of(gauge))
    {
        return Err(SelfcalSolveError::InvalidGauge {
            positions: p,
            gauge,
        });
    }
    let heads = set.heads();
    let cycles = set.cycles().len();
    let (closure, grid) = match grid_offsets(set, &heads) {
        Some(whole) => (
            closure_on_grid(set, &heads, &whole, options)?,
            HeadGrid::OnGrid,
        ),
        None => {
            let offsets: Vec<f64> = heads
                .iter()
                .map(|h| h.angle_deg * p as f64 / 360.0)
                .collect();
            (
                fourier::closure_off_grid(set, &heads, &offsets, options)?,
                HeadGrid::OffGrid,
            )
        }
    };
    Ok(assemble(set, heads, cycles, closure, grid, options))
}

/// The heads on the grid: the readings as a closure design (disc positions as faces,
/// heads as autocollimators), solved by the engine with the lost harmonics set to zero.
fn closure_on_grid(
    set: &SelfcalSet,
    heads: &[Head],
    offsets: &[usize],
    options: &SelfcalOptions,
) -> Result<Closure, SelfcalSolveError> {
    let closure_set = closure_set(set, heads, offsets)?;
    let mut solve_options = SolveOptions::new().with_sigma_opt(options.sigma);
    if let Some(bytes) = options.memory_limit_bytes {
        solve_options = solve_options.with_memory_limit(bytes);
    }
    let (solution, lost): (Solution, Vec<usize>) =
        least_squares_zeroing_lost(&closure_set, &solve_options)?;
    Ok(Closure::of_fit(solution, lost, 0))
}

/// The whole position offset of every head (in `heads`' order) when every head sits on
/// the position grid; `None` when some head sits between positions.
pub(crate) fn grid_offsets(set: &SelfcalSet, heads: &[Head]) -> Option<Vec<usize>> {
    let p = set.positions;
    let offsets: Vec<f64> = heads
        .iter()
        .map(|h| h.angle_deg * p as f64 / 360.0)
        .collect();
    offsets
        .iter()
        .all(|d| (d - d.round()).abs() <= ON_GRID_TOLERANCE_POSITIONS)
        .then(|| offsets.iter().map(|d| (d.round() as usize) % p).collect())
}

/// The readings of heads on the grid as a closure design: the disc's positions as the
/// faces, the heads as the autocollimators (head j reads face (step + d_j) mod P + 1), one
/// mounting; cycle, step, direction, time and line as the file has them.
pub(crate) fn closure_set(
    set: &SelfcalSet,
    heads: &[Head],
    offsets: &[usize],
) -> Result<MeasurementSet, MeasurementError> {
    let p = set.positions;
    let offset_of = |head: u32| {
        heads
            .binary_search_by_key(&head, |h| h.head)
            .map(|i| offsets[i])
            .unwrap_or(0)
    };
    let readings: Vec<Reading> = set
        .readings
        .iter()
        .map(|r| Reading {
            setup: 1,
            cycle: r.cycle,
            step: r.step,
            ac: r.head,
            face: (r.step + offset_of(r.head)) % p + 1,
            reading_arcsec: r.reading_arcsec,
            direction: r.direction,
            time_seconds: r.time_seconds,
            reading_y_arcsec: None,
            temperature_celsius: None,
            encoder_degrees: None,
            line: r.line,
        })
        .collect();
    MeasurementSet::from_readings(readings, Some(p), "self-calibration")
}

impl Closure {
    /// The closure model's solution from a fit of [`closure_set`] with `extra_parameters`
    /// columns beyond the closure model and the table's per-stop nuisance (a diagnosis's
    /// effect terms), whose residuals are then those of the full model.
    pub(super) fn of_fit(solution: Solution, lost: Vec<usize>, extra_parameters: usize) -> Self {
        Closure {
            face_deviation: solution.face_deviation,
            setup: solution.setup_error.iter().map(|s| s.value).collect(),
            residuals: solution.residuals,
            cofactor: solution.cofactor,
            lost,
            engine: solution.engine,
            extra_parameters,
        }
    }
}

/// The self-calibration's results from a fit of [`closure_set`] that holds the table's
/// per-stop nuisance and `extra_parameters` further columns (a diagnosis's effect terms;
/// docs/FORMAT.md §9.2): e, c, their uncertainties and the degrees of freedom as
/// [`solve`] reports them, without the heads' angle uncertainty.
pub(crate) fn from_closure_fit(
    set: &SelfcalSet,
    fit: Solution,
    lost: Vec<usize>,
    extra_parameters: usize,
    grid: HeadGrid,
    options: &SelfcalOptions,
) -> SelfcalSolution {
    let heads = set.heads();
    let cycles = set.cycles().len();
    let closure = Closure::of_fit(fit, lost, extra_parameters);
    assemble(set, heads, cycles, closure, grid, options)
}

/// The self-calibration's results from the closure model's.
fn assemble(
    set: &SelfcalSet,
    heads: Vec<Head>,
    cycles: usize,
    closure: Closure,
    grid: HeadGrid,
    options: &SelfcalOptions,
) -> SelfcalSolution {
    let p = set.positions;
    let m = heads.len();
    // the table's error per (cycle, step): the residuals' mean over the heads of each stop
    let cycle_list = set.cycles();
    let stop_of =
        |cycle: u32, step: usize| cycle_list.binary_search(&cycle).unwrap_or(0) * p + step;
    let mut stop_sum = vec![0.0; cycle_list.len() * p];
    let mut stop_count = vec![0usize; cycle_list.len() * p];
    for (r, e) in set.readings.iter().zip(&closure.residuals) {
        let s = stop_of(r.cycle, r.step);
        stop_sum[s] += e;
        stop_count[s] += 1;
    }
    let residuals: Vec<f64> = set
        .readings
        .iter()
        .zip(&closure.residuals)
        .map(|(r, e)| {
            let s = stop_of(r.cycle, r.step);
            e - stop_sum[s] / stop_count[s].max(1) as f64
        })
        .collect();
    let rss: f64 = residuals.iter().map(|v| v * v).sum();
    let parameters = cycles * p
        + (p - 1).saturating_sub(closure.lost.len())
        + (m - 1)
        + closure.extra_parameters;
    let dof = set.readings.len().saturating_sub(parameters);
    let sigma = crate::solve::choose_sigma(rss, dof, options.sigma);

    // the gauge: Σe = 0 over the gauge's positions (all P, or every (P/n)-th)
    let stride = options.gauge_positions.map_or(1, |n| p / n);
    let gauge: Vec<usize> = (0..p).step_by(stride).collect();
    let mean_phi = gauge
        .iter()
        .map(|&x| closure.face_deviation[x])
        .sum::<f64>()
        / gauge.len() as f64;
    let encoder_error: Vec<f64> = closure
        .face_deviation
        .iter()
        .map(|phi| phi - mean_phi)
        .collect();
    let lost_harmonics: Vec<usize> = closure
        .lost
        .iter()
        .copied()
        .filter(|&k| 2 * k <= p)
        .collect();
    let encoder_error_u_type_a = sigma.map(|(s, _)| {
        let variances = if stride == 1 {
            closure.cofactor.centered_face_deviation_diagonal()
        } else {
            referenced_variances(&closure.cofactor, &gauge)
        };
        variances
            .into_iter()
            .map(|q| s * q.max(0.0).sqrt())
            .collect::<Vec<f64>>()
    });
    let lost_harmonic_u = options
        .lost_harmonic_bound_arcsec
        .map(|a| a / 2f64.sqrt() * (lost_harmonics.len() as f64).sqrt());
    let encoder_error_u = encoder_error_u_type_a.as_ref().map(|u| {
        u.iter()
            .map(|ua| ua.hypot(lost_harmonic_u.unwrap_or(0.0)))
            .collect()
    });
    let layout: ParameterLayout = closure.cofactor.layout();
    let q = &closure.cofactor;
    let first = layout.setup(0);
    let head_error = heads
        .iter()
        .enumerate()
        .skip(1)
        .map(|(j, h)| {
            let a = layout.setup(j);
            let var = q.entry(a, a) + q.entry(first, first) - 2.0 * q.entry(a, first);
            HeadError {
                head: h.head,
                angle_deg: h.angle_deg,
                value: closure.setup[j] - closure.setup[0],
                u: sigma.map(|(s, _)| s * var.max(0.0).sqrt()),
                u_type_a: sigma.map(|(s, _)| s * var.max(0.0).sqrt()),
                head_angle_u: None,
            }
        })
        .collect();
    let mut notes = Vec::new();
    if !lost_harmonics.is_empty() {
        notes.push(format!(
            "the head layout cannot determine the encoder error's harmonics of order {}: they are set to 0 in encoder_error{}",
            join(&lost_harmonics),
            match options.lost_harmonic_bound_arcsec {
                Some(a) => format!(
                    "; the bound of {a} arcsec on their amplitude adds u = {:.4} arcsec to every position",
                    lost_harmonic_u.unwrap_or(0.0)
                ),
                None => "; their content is not in the uncertainty (give a bound on their amplitude to include it)".into(),
            }
        ));
    }
    if let Some(n) = options.gauge_positions {
        notes.push(format!(
            "encoder_error in the gauge Σe = 0 over the {n} angles k·360°/{n} (the gauge of the encoder errors of a polygon with {n} faces), not over all {p} positions"
        ));
    }
    if grid == HeadGrid::OffGrid {
        notes.push(format!(
            "some heads sit between the {p} positions: the encoder error is taken as band-limited (harmonics below {}, the harmonic {} as a cosine on the grid)",
            p.div_ceil(2),
            p / 2
        ));
    }
    notes.push(
        "the table's position error is estimated at every stop of every cycle (a nuisance, not reported)"
            .into(),
    );
    if sigma.is_none() {
        notes.push(
            "no residual degrees of freedom and no stated σ: uncertainties are not available"
                .into(),
        );
    }
    SelfcalSolution {
        positions: p,
        cycles,
        readings: set.readings.len(),
        encoder_error,
        gauge_positions: options.gauge_positions,
        encoder_error_u,
        encoder_error_u_type_a,
        lost_harmonic_u,
        head_angle_u: None,
        encoder_angle_deg: (0..p as u32).map(|k| step_angle_deg(k, p)).collect(),
        head_error,
        lost_harmonics,
        dof,
        rss,
        sigma,
        residuals,
        grid,
        engine: closure.engine,
        cofactor: closure.cofactor,
        notes,
        heads,
    }
}

/// Var(e_x − ē_S)/σ² for every position x, e in the gauge Σ_{s∈S} e_s = 0: with
/// e_x − ē_S = φ_{x+1} − m_S, m_S the mean of φ over S (φ = Tβ the face deviations of the
/// closure model), var φ − 2 cov(φ, m_S) + var m_S, from one product Q·w (w: m_S's
/// coefficients on β).
fn referenced_variances(cofactor: &Cofactor, subset: &[usize]) -> Vec<f64> {
    let p = cofactor.layout().faces;
    // w_i = #{s ∈ S : s + 1 ≥ i}/|S| for β_i (i = 1 … P)
    let mut w = vec![0.0; cofactor.len()];
    for &s in subset {
        for v in &mut w[..=s] {
            *v += 1.0;
        }
    }
    for v in &mut w[..p] {
        *v /= subset.len() as f64;
    }
    let y = cofactor.apply(&w);
    let var_mean: f64 = w[..p].iter().zip(&y[..p]).map(|(a, b)| a * b).sum();
    let mut cov = 0.0;
    cofactor
        .face_deviation_diagonal()
        .into_iter()
        .zip(&y[..p])
        .map(|(var, yi)| {
            cov += yi;
            var - 2.0 * cov + var_mean
        })
        .collect()
}

fn join(values: &[usize]) -> String {
    let text: Vec<String> = values.iter().map(usize::to_string).collect();
    text.join(", ")
}

/// An empty low-rank part, for a cofactor that is the regular part alone.
pub(super) fn no_correction() -> DMatrix<f64> {
    DMatrix::zeros(0, 0)
}
