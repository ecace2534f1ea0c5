//! Shifted mountings solved (docs/FORMAT.md §2 `shift`, §9.1); where each mounting puts
//! the encoder is [`ShiftGeometry`]'s bookkeeping ([`super::shift_geometry`]).
//!
//! # Sub-pitch cosets
//!
//! Each coset c has encoder errors α_c of its own; the polygon (β, φ) and the setup
//! errors are shared. An N-faced polygon sees the encoder only through its N faces, so it
//! cannot see encoder harmonics whose order is a multiple of N: on the N angles of one
//! coset such a harmonic is a constant, a different constant in each coset. Each coset's
//! errors are therefore determined only up to a constant, fixed by Σα_c = 0 within the
//! coset (the notes of [`SubPitchSolution`] say so).
//!
//! The result is written α_c = α_0 + δ_c for c = 1 … C−1, with α_0 the encoder errors
//! at the readings' positions from [`ShiftGeometry::encoder_set`] and δ_c (Σδ_c = 0) the
//! differences, whichever engine fits them:
//!
//! - the coset engine ([`super::coset`]), where the design's structure serves it: every
//!   coset is the regular design in its own positions, so the unknowns of each harmonic
//!   form a (C + 1) × (C + 1) block, solved by FFT in near-linear time, with the cofactor
//!   as an operator in the same θ as below;
//! - otherwise (and for [`Method::Dense`]) δ_c as effect columns of the least-squares
//!   engine, in contrast coding: for q = 0 … N−2 a column that is +1 on the readings of
//!   coset c at position q and −1 on those at position N−1, so that
//!   δ_c\[N−1\] = −Σ_{q<N−1} δ_c\[q\]. The engine (circulant or dense, as
//!   [`super::least_squares_with_options`] decides) returns α_0, δ and their cofactor.
//!   This is the reference the coset engine is tested against.
//!
//! From either, α_c\[q\] = α_0\[q\] + δ_c\[q\] and u²(α_c\[q\]) = σ²·wᵀQw for the w that
//! forms it.

use super::least_squares::{dense_observed, least_squares_observed, least_squares_on_cosets};
use super::{Method, Solution, SolveError, SolveOptions, Unobservable, solve_positions};
use crate::measurement::MeasurementSet;
use crate::progress::Progress;

pub use super::shift_geometry::{Mounting, POSITION_TOLERANCE, ShiftGeometry};

/// A solved set with shifted mountings: the engine's solution and the encoder errors at
/// every table angle of every coset ([`solve_shifted`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SubPitchSolution {
    /// The engine's solution of the set in encoder positions
    /// ([`ShiftGeometry::encoder_set`]): β, φ, the setup errors, σ, the residuals and the
    /// cofactor; its `encoder_error` is coset 0's, and its effect terms are the
    /// differences δ_c\[q\], q = 0 … N−2, of cosets c = 1 … C−1 (module documentation).
    pub solution: Solution,
    /// α at every table angle of every coset, in the order of `encoder_angle_deg`,
    /// arcsec; Σα = 0 within each coset.
    pub encoder_error: Vec<f64>,
    /// u(α), k = 1, in the same order; `None` when σ is unknown.
    pub encoder_error_u: Option<Vec<f64>>,
    /// The table angle of each entry, degrees, ascending: position q of coset c is
    /// entry q·C + c.
    pub encoder_angle_deg: Vec<f64>,
    /// Each coset's shift modulo 360°/N, degrees, ascending (0 for the whole positions).
    pub cosets: Vec<f64>,
    /// What a reader must know about the result: for sub-pitch mountings, that each
    /// coset's encoder errors are determined up to a constant, fixed by Σα = 0 within the
    /// coset. Empty for whole-face shifts.
    pub notes: Vec<String>,
}

impl SubPitchSolution {
    /// N.
    pub fn faces(&self) -> usize {
        self.solution.faces
    }

    /// Whether there are encoder errors between the whole positions (a coset whose shift
    /// is not 0); `false` for whole-face shifts, whose result is an ordinary [`Solution`].
    pub fn is_sub_pitch(&self) -> bool {
        self.cosets.iter().any(|&d| d != 0.0)
    }

    /// The same solution with the uncertainties of σ = `sigma_arcsec` (k = 1) instead of
    /// the fit's: `encoder_error_u` anew from the cofactor, and the solution's σ stated.
    /// What a design gives before any reading is taken (`plan`).
    pub fn with_sigma(mut self, sigma_arcsec: f64) -> Self {
        self.solution.sigma = Some((sigma_arcsec, super::SigmaSource::Stated));
        self.encoder_error_u = Some(coset_encoder_error_u(
            &self.solution,
            self.cosets.len(),
            sigma_arcsec,
        ));
        self
    }
}

/// Solves a measurement set whose mountings may be shifted by any angle (docs/FORMAT.md
/// §9.1): the polygon, the setup errors, and the encoder errors at every table angle of
/// every coset (module documentation), sorted by angle.
///
/// With whole-face shifts only (or none) this is [`super::solve`] of the set in encoder
/// positions, its α at the N angles p·360°/N and no notes. With sub-pitch cosets
/// [`Method::Auto`] and [`Method::LeastSquares`] take the coset engine
/// ([`super::Engine::CosetCirculant`]) where the design's structure serves it and fit
/// the differences as effect columns otherwise; [`Method::Dense`] fits them as effect
/// columns of the dense reference; the closed form does not apply to several cosets.
///
/// ```
/// use polycal::simulate::{simulate, SimulationConfig};
/// use polycal::solve::SolveOptions;
/// use polycal::solve::sub_pitch::solve_shifted;
///
/// // 12 faces (30° apart), three mountings: the table at 0°, 10° and 20° at step 0
/// let config = SimulationConfig {
///     faces: 12,
///     setups: 3,
///     table_shift_deg: vec![0.0, 10.0, 20.0],
///     noise_arcsec: 0.0,
///     ..SimulationConfig::default()
/// };
/// let (set, truth) = simulate(&config)?;
/// let solved = solve_shifted(&set, &SolveOptions::default())?;
/// assert_eq!(solved.cosets, [0.0, 10.0, 20.0]);
/// assert_eq!(solved.encoder_angle_deg[..4], [0.0, 10.0, 20.0, 30.0]);
/// assert_eq!(solved.encoder_error.len(), 36);
/// // each coset up to its constant: compare differences within a coset
/// let truth_alpha = truth.encoder_error;
/// let (a, t) = (&solved.encoder_error, &truth_alpha);
/// assert!(((a[4] - a[1]) - (t[4] - t[1])).abs() < 1e-9);
/// for (estimate, true_value) in solved.solution.pitch_deviation.iter().zip(&truth.pitch_deviation) {
///     assert!((estimate - true_value).abs() < 1e-9);
/// }
/// assert_eq!(solved.notes.len(), 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// As [`super::solve`]: a design that cannot determine the polygon and every coset's
/// encoder errors ([`SolveError::Unobservable`], naming the cosets that cannot be
/// separated), [`SolveError::TooLarge`], and [`SolveError::ClosedFormNotApplicable`] for
/// [`Method::ClosedForm`] with several cosets.
pub fn solve_shifted(
    set: &MeasurementSet,
    options: &SolveOptions,
) -> Result<SubPitchSolution, SolveError> {
    solve_shifted_with_progress(set, options, None)
}

/// [`solve_shifted`] telling `progress` how far it is, as
/// [`super::solve_with_progress`] does: a set the coset engine cannot take is fitted by
/// the dense reference with the cosets' differences as effect columns, which takes
/// seconds to minutes for hundreds of faces and reports a count rising to a total known
/// from the start (the coset engine, near-linear, reports nothing). The solution is the
/// one [`solve_shifted`] gives, number for number.
///
/// # Errors
///
/// As [`solve_shifted`].
pub fn solve_shifted_with_progress(
    set: &MeasurementSet,
    options: &SolveOptions,
    progress: Option<&dyn Progress>,
) -> Result<SubPitchSolution, SolveError> {
    let mut solved = solve_shifted_positions(set, options, progress)?;
    solved.solution.incomplete_cycles = set.incomplete_cycles();
    Ok(solved)
}

/// [`solve_shifted_with_progress`] without the set's incomplete cycles.
fn solve_shifted_positions(
    set: &MeasurementSet,
    options: &SolveOptions,
    progress: Option<&dyn Progress>,
) -> Result<SubPitchSolution, SolveError> {
    let geometry = ShiftGeometry::of(set);
    let positions = geometry.encoder_set(set);
    let n = set.faces;
    let c_count = geometry.cosets();
    if c_count > 1
        && matches!(options.method, Method::Auto | Method::LeastSquares)
        && let Some(solution) = least_squares_on_cosets(&positions, &geometry, options)?
    {
        return Ok(from_engine_solution(solution, &geometry));
    }
    // The contrast columns are dense (one value per reading each): check that they fit
    // before building them; the engine checks what it needs beyond them.
    let column_count = c_count.saturating_sub(1) * n.saturating_sub(1);
    let needed_bytes = 8 * column_count as u128 * set.readings.len() as u128;
    if let Some((limit_bytes, limit_source)) =
        super::memory::limit_for(needed_bytes, options.memory_limit_bytes)
        && needed_bytes > u128::from(limit_bytes)
    {
        return Err(SolveError::TooLarge {
            faces: n,
            streams: positions.streams().len(),
            effects: column_count,
            readings: set.readings.len(),
            engine: "sub-pitch",
            needed_bytes,
            limit_bytes,
            limit_source,
        });
    }
    let columns = coset_columns(&geometry, set);
    let solution = if columns.is_empty() {
        solve_positions(&positions, options, progress)?
    } else {
        match options.method {
            Method::Auto | Method::LeastSquares => {
                least_squares_observed(&positions, &columns, options, progress)
            }
            Method::Dense => dense_observed(&positions, &columns, options, progress),
            Method::ClosedForm => Err(SolveError::ClosedFormNotApplicable(format!(
                "the mountings' shifts put the encoder errors at {c_count} cosets of table \
                 angles, whose differences the paper's design does not have"
            ))),
        }
        .map_err(|e| name_cosets(e, &geometry, n))?
    };

    Ok(from_engine_solution(solution, &geometry))
}

/// The encoder errors at every table angle of every coset from an engine's `solution` of
/// the set in encoder positions whose first (C − 1)·(N − 1) effect terms are the cosets'
/// differences ([`coset_columns`], in that order; further effect terms may follow, as in
/// a diagnosis), with u(α) from its cofactor and σ.
pub fn from_engine_solution(solution: Solution, geometry: &ShiftGeometry) -> SubPitchSolution {
    let n = solution.faces;
    let c_count = geometry.cosets();
    let cosets = geometry.coset_shift_deg().to_vec();
    let layout = solution.layout;
    let delta = |c: usize, q: usize| layout.effect((c - 1) * (n - 1) + q);
    let mut encoder_error = Vec::with_capacity(n * c_count);
    for q in 0..n {
        for c in 0..c_count {
            let alpha0 = solution.encoder_error[q];
            let value = if c == 0 {
                alpha0
            } else if q + 1 < n {
                alpha0 + solution.effect_values[delta(c, q) - layout.effect(0)]
            } else {
                let first = delta(c, 0) - layout.effect(0);
                alpha0
                    - solution.effect_values[first..first + n - 1]
                        .iter()
                        .sum::<f64>()
            };
            encoder_error.push(value);
        }
    }
    let encoder_error_u = solution
        .sigma
        .map(|(s, _)| coset_encoder_error_u(&solution, c_count, s));
    let notes = if geometry.is_sub_pitch() {
        vec![constant_note(geometry)]
    } else {
        Vec::new()
    };
    SubPitchSolution {
        encoder_angle_deg: geometry.angles_deg(),
        solution,
        encoder_error,
        encoder_error_u,
        cosets,
        notes,
    }
}

/// u(α) at every table angle of every coset (the order of `encoder_angle_deg`) for σ = `s`,
/// from the engine's cofactor: u²(α_c[q]) = s²·wᵀQw for the w that forms α_c[q] from α_0
/// and the differences δ_c.
fn coset_encoder_error_u(solution: &Solution, c_count: usize, s: f64) -> Vec<f64> {
    let n = solution.faces;
    let layout = solution.layout;
    let delta = |c: usize, q: usize| layout.effect((c - 1) * (n - 1) + q);
    let q_matrix = &solution.cofactor;
    // the variance of α_c[N−1] needs Σ_q δ_c[q]: one product per coset
    let last: Vec<f64> = (1..c_count)
        .map(|c| {
            let mut w = vec![0.0; layout.len()];
            w[layout.encoder(n - 1)] = 1.0;
            for q in 0..n - 1 {
                w[delta(c, q)] = -1.0;
            }
            let qw = q_matrix.apply(&w);
            w.iter().zip(&qw).map(|(a, b)| a * b).sum::<f64>()
        })
        .collect();
    let mut u = Vec::with_capacity(n * c_count);
    for q in 0..n {
        let a = layout.encoder(q);
        for c in 0..c_count {
            let variance = if c == 0 {
                q_matrix.entry(a, a)
            } else if q + 1 < n {
                let d = delta(c, q);
                q_matrix.entry(a, a) + q_matrix.entry(d, d) + 2.0 * q_matrix.entry(a, d)
            } else {
                last[c - 1]
            };
            u.push(s * variance.max(0.0).sqrt());
        }
    }
    u
}

/// The contrast columns of cosets 1 … C−1 (module documentation), (C − 1)·(N − 1) of
/// them, coset by coset, one value per reading of `set` (as the file has it); none for
/// whole-face shifts. Fitted with the set in encoder positions, they give the cosets'
/// differences δ_c.
pub fn coset_columns(geometry: &ShiftGeometry, set: &MeasurementSet) -> Vec<Vec<f64>> {
    let n = set.faces;
    let c_count = geometry.cosets();
    if c_count < 2 || n < 2 {
        return Vec::new();
    }
    let cosets = geometry.reading_cosets(set);
    let mut columns = vec![vec![0.0; set.readings.len()]; (c_count - 1) * (n - 1)];
    for (i, r) in set.readings.iter().enumerate() {
        let c = cosets[i];
        if c == 0 {
            continue;
        }
        let m = geometry.mounting(r.setup).map_or(0, |m| m.whole_positions);
        let q = (r.step % n + m) % n;
        let base = (c - 1) * (n - 1);
        if q + 1 < n {
            columns[base + q][i] = 1.0;
        } else {
            for column in &mut columns[base..base + n - 1] {
                column[i] = -1.0;
            }
        }
    }
    columns
}

/// The note of a sub-pitch result (docs/FORMAT.md §9.1).
fn constant_note(geometry: &ShiftGeometry) -> String {
    let n = geometry.faces();
    let shifts: Vec<String> = geometry
        .coset_shift_deg()
        .iter()
        .map(|d| format!("{d}°"))
        .collect();
    format!(
        "The mountings' shifts put the encoder errors at {} coset{} of {n} table angles \
         (shifts {} modulo {}°). A polygon with {n} faces cannot see encoder harmonics whose \
         order is a multiple of {n}, so each coset's encoder errors are determined only up \
         to a constant, fixed by Σα = 0 within the coset.",
        geometry.cosets(),
        if geometry.cosets() == 1 { "" } else { "s" },
        shifts.join(", "),
        360.0 / n as f64
    )
}

/// An unobservable design's message with the effect columns named as the cosets they are.
fn name_cosets(error: SolveError, geometry: &ShiftGeometry, n: usize) -> SolveError {
    let SolveError::Unobservable(u) = error else {
        return error;
    };
    if u.effects.is_empty() || n < 2 {
        return SolveError::Unobservable(u);
    }
    let mut cosets: Vec<usize> = u.effects.iter().map(|e| e / (n - 1) + 1).collect();
    cosets.dedup();
    let named: Vec<String> = cosets
        .iter()
        .filter_map(|&c| geometry.coset_shift_deg().get(c))
        .map(|d| format!("{d}° + p·{}°", 360.0 / n as f64))
        .collect();
    let head = match u.message.find("effect term") {
        Some(at) => u.message[..at].to_string(),
        None => "the design cannot determine every pitch deviation and encoder error: ".to_string(),
    };
    SolveError::Unobservable(Unobservable {
        message: format!(
            "{head}the encoder errors at the table angles {} cannot be separated from the \
             other unknowns (their mountings need more autocollimators, or the other \
             mountings must determine the polygon)",
            named.join(" and ")
        ),
        ..u
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Direction, Reading};

    #[test]
    fn whole_positions_within_the_tolerance() {
        let pitch = 360.0 / 24.0;
        // a hair below and above a whole face is that face; 10⁻⁵ positions is not
        let g = ShiftGeometry::new(
            24,
            [
                (1, 3.0 * pitch - 1e-9),
                (2, 3.0 * pitch + 1e-9),
                (3, 359.999_999_99),
                (4, 1e-5 * pitch),
            ],
        );
        assert_eq!(
            g.mounting(1).unwrap(),
            Mounting {
                whole_positions: 3,
                coset: 0
            }
        );
        assert_eq!(
            g.mounting(2).unwrap(),
            Mounting {
                whole_positions: 3,
                coset: 0
            }
        );
        assert_eq!(
            g.mounting(3).unwrap(),
            Mounting {
                whole_positions: 0,
                coset: 0
            }
        );
        assert_eq!(g.mounting(4).unwrap().coset, 1);
        assert_eq!(g.cosets(), 2);
        // fractions within 10⁻⁶ positions of each other are one coset
        let g = ShiftGeometry::new(24, [(1, 5.0), (2, 5.0 + 1e-7 * pitch), (3, 20.0)]);
        assert_eq!(g.coset_shift_deg(), &[5.0]);
        assert!(g.is_sub_pitch());
        assert_eq!(
            g.mounting(3).unwrap(),
            Mounting {
                whole_positions: 1,
                coset: 0
            }
        );
        // no mounting: the whole positions
        let g = ShiftGeometry::new(5, []);
        assert_eq!((g.cosets(), g.is_sub_pitch()), (1, false));
        assert_eq!(g.angles_deg(), [0.0, 72.0, 144.0, 216.0, 288.0]);
    }

    fn reading(setup: u32, step: usize, face: usize) -> Reading {
        Reading {
            setup,
            cycle: 1,
            step,
            ac: 1,
            face,
            reading_arcsec: 0.0,
            direction: Direction::Cw,
            time_seconds: None,
            reading_y_arcsec: None,
            temperature_celsius: None,
            encoder_degrees: None,
            line: 0,
        }
    }

    #[test]
    fn encoder_positions_and_contrast_columns() {
        // 3 faces (120°): setup 1 at 0°, setup 2 at 250° (2 faces + 10°), closing steps
        let mut readings = Vec::new();
        for setup in [1, 2] {
            for step in 0..=3 {
                readings.push(reading(setup, step, step % 3 + 1));
            }
        }
        let set = MeasurementSet::from_readings(readings, None, "test")
            .unwrap()
            .with_setup_shifts([(2, 250.0)])
            .unwrap();
        let g = ShiftGeometry::of(&set);
        assert_eq!(g.coset_shift_deg(), &[0.0, 10.0]);
        let positions = g.encoder_set(&set);
        let steps: Vec<usize> = positions.readings.iter().map(|r| r.step).collect();
        assert_eq!(steps, [0, 1, 2, 3, 2, 0, 1, 2]);
        assert!(positions.setup_shift_deg.is_empty());
        // coset 1 at positions 2, 0, 1, 2: +1 at q = 0, 1, −1 on both at q = N − 1 = 2
        let columns = coset_columns(&g, &set);
        assert_eq!(columns.len(), 2);
        assert_eq!(columns[0], [0.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.0, -1.0]);
        assert_eq!(columns[1], [0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, -1.0]);
        assert_eq!(g.angles_deg(), [0.0, 10.0, 120.0, 130.0, 240.0, 250.0]);
    }
}
