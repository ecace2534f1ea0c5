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

use super::solution::{
    Closure, HeadError, HeadGrid, ON_GRID_TOLERANCE_POSITIONS, SelfcalOptions, SelfcalSolution,
    SelfcalSolveError,
};
use super::{Head, SelfcalSet, fourier};
use crate::input::FileError;
use crate::measurement::{MeasurementSet, Reading, step_angle_deg};
use crate::solve::cofactor::Cofactor;
use crate::solve::least_squares::least_squares_zeroing_lost;
use crate::solve::{ParameterLayout, Solution, SolveOptions};

/// [`super::solve`](fn@super::solve) without the heads' angle uncertainty (which is computed by solving the
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
    let closure_set = closure_set(set, heads, offsets).map_err(SelfcalSolveError::Design)?;
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
) -> Result<MeasurementSet, FileError> {
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
/// [`solve`](fn@super::solve) reports them, without the heads' angle uncertainty.
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
