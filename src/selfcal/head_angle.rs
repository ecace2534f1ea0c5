//! The uncertainty of the heads' nominal angles (type B).
//!
//! A head that sits δψ_j (radians) away from its nominal angle reads
//! e(θ_p + ψ_j + δψ_j) ≈ e(θ_p + ψ_j) + e′(θ_p + ψ_j)·δψ_j: besides a constant, which its
//! head error absorbs, it adds the slope of the disc's error times δψ_j to its readings.
//! That pattern is solved like readings (the fit is linear), head by head, so its effect
//! on every e and every head error is computed, not assumed; with the heads' angles
//! independent, each of standard uncertainty u_ψ, u²(e_x) gains u_ψ²·Σ_j r_j,x², r_j the
//! response to head j's unit pattern. The slope is that of the estimated e (its Fourier
//! series, so between the positions too). Head 1 is the angles' reference (ψ_1 = 0).

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::solution::{SelfcalOptions, SelfcalSolution, SelfcalSolveError};
use super::solve::solve_closure;
use super::{HeadReading, SelfcalSet};

/// Arcseconds per radian.
const ARCSEC_PER_RADIAN: f64 = 180.0 * 3600.0 / std::f64::consts::PI;

/// The standard uncertainty that u_ψ (arcsec) of every head's angle (heads 2 … M) adds to
/// every e and every head error: (per position, per head 2 … M).
pub(super) fn head_angle_u(
    set: &SelfcalSet,
    solution: &SelfcalSolution,
    u_angle_arcsec: f64,
    options: &SelfcalOptions,
) -> Result<(Vec<f64>, Vec<f64>), SelfcalSolveError> {
    let p = solution.positions;
    let m = solution.heads.len();
    let mut var_e = vec![0.0; p];
    let mut var_c = vec![0.0; m.saturating_sub(1)];
    if u_angle_arcsec == 0.0 {
        return Ok((var_e, var_c));
    }
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(p);
    let inverse = planner.plan_fft_inverse(p);
    let mut spectrum: Vec<Complex<f64>> = solution
        .encoder_error
        .iter()
        .map(|&v| Complex::new(v, 0.0))
        .collect();
    forward.process(&mut spectrum);
    let signed = |k: usize| -> Option<f64> {
        // the harmonic P/2 is a cosine on the grid: its slope there is not known
        if 2 * k == p {
            None
        } else if 2 * k < p {
            Some(k as f64)
        } else {
            Some(k as f64 - p as f64)
        }
    };
    // the response options: the same gauge, nothing else
    let mut response_options = SelfcalOptions::new();
    response_options.gauge_positions = options.gauge_positions;
    response_options.memory_limit_bytes = options.memory_limit_bytes;
    let u_radian = u_angle_arcsec / ARCSEC_PER_RADIAN;
    for head in solution.heads.iter().skip(1) {
        let delta = head.angle_deg * p as f64 / 360.0;
        // e′ (arcsec per radian) at the head's positions θ_p + ψ_j
        let mut slope: Vec<Complex<f64>> = (0..p)
            .map(|k| match signed(k) {
                Some(kappa) if k > 0 => {
                    let phase =
                        Complex::from_polar(1.0, std::f64::consts::TAU * kappa * delta / p as f64);
                    spectrum[k] * Complex::new(0.0, kappa) * phase
                }
                _ => Complex::new(0.0, 0.0),
            })
            .collect();
        inverse.process(&mut slope);
        let pattern: Vec<f64> = slope.iter().map(|c| c.re / p as f64 * u_radian).collect();
        let readings: Vec<HeadReading> = set
            .readings
            .iter()
            .map(|r| HeadReading {
                reading_arcsec: if r.head == head.head {
                    pattern[r.step]
                } else {
                    0.0
                },
                ..r.clone()
            })
            .collect();
        let unit = SelfcalSet {
            positions: p,
            readings,
        };
        let response = solve_closure(&unit, &response_options)?;
        for (v, r) in var_e.iter_mut().zip(&response.encoder_error) {
            *v += r * r;
        }
        for (v, h) in var_c.iter_mut().zip(&response.head_error) {
            *v += h.value * h.value;
        }
    }
    Ok((
        var_e.into_iter().map(f64::sqrt).collect(),
        var_c.into_iter().map(f64::sqrt).collect(),
    ))
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
