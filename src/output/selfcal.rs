//! The outputs of `polycal selfcal` (docs/FORMAT.md §9): its JSON object, its table for
//! people, and its result rows (docs/FORMAT.md §3, with `angle_deg`).

use std::fmt::{self, Write};

use serde::Serialize;

use crate::results::{Quantity, ResultRow};
use crate::selfcal::{
    COVERAGE_PROBABILITY, HeadGrid, SelfcalMonteCarlo, SelfcalSolution, SelfcalUncertainty,
};
use crate::solve::{Engine, SigmaSource};
use crate::uncertainty::calibration::McFamily;

/// Up to this many positions the table lists every position; above it, a summary
/// (the JSON and the CSV always carry every position).
pub const TABLE_POSITIONS_LISTED: usize = 360;

/// One head of the JSON's `head_error`.
#[derive(Debug, Clone, Serialize)]
pub struct HeadErrorReport {
    /// Head number.
    pub head: u32,
    /// Nominal angle from head 1, degrees.
    pub angle_deg: f64,
    /// c\[head\] − c\[1\], arcsec.
    pub value: f64,
    /// Standard uncertainty, arcsec (`null` when σ is unknown).
    pub u: Option<f64>,
    /// Expanded uncertainty k·u, arcsec.
    #[serde(rename = "U")]
    pub expanded_u: Option<f64>,
    /// Coverage factor.
    pub k: Option<f64>,
}

/// The JSON object of `polycal selfcal --format json` (docs/FORMAT.md §9).
#[derive(Debug, Clone, Serialize)]
pub struct SelfcalReport {
    /// The file solved.
    pub file: String,
    /// P.
    pub positions: usize,
    /// M.
    pub heads: usize,
    /// C.
    pub cycles: usize,
    /// Number of readings.
    pub readings: usize,
    /// Residual degrees of freedom.
    pub dof: usize,
    /// √(RSS/dof), arcsec; `null` when dof = 0.
    pub residual_rms: Option<f64>,
    /// σ of one reading, arcsec, used for the uncertainties; `null` when unknown.
    pub sigma: Option<f64>,
    /// `residual` or `stated`; `null` when σ is unknown.
    pub sigma_source: Option<&'static str>,
    /// `on-grid` (the closure engine) or `off-grid` (the band-limited solver).
    pub head_grid: &'static str,
    /// The engine (`circulant`, `dense`).
    pub engine: &'static str,
    /// e at every position, arcsec.
    pub encoder_error: Vec<f64>,
    /// u(e), arcsec (`null` when σ is unknown).
    pub encoder_error_u: Option<Vec<f64>>,
    /// Coverage probability of the expanded uncertainties.
    pub p: f64,
    /// U(e) = k·u(e), arcsec.
    #[serde(rename = "encoder_error_U")]
    pub encoder_error_expanded_u: Option<Vec<f64>>,
    /// k of each U(e): Student's t for the Welch–Satterthwaite degrees of freedom.
    pub encoder_error_k: Option<Vec<f64>>,
    /// The angle of each position, degrees.
    pub encoder_angle_deg: Vec<f64>,
    /// What the heads' angle uncertainty adds to each u(e), arcsec (`null` without it).
    pub head_angle_u: Option<Vec<f64>>,
    /// n when e is in the gauge Σe = 0 over the n angles k·360°/n; `null`: over all
    /// positions.
    pub gauge_positions: Option<usize>,
    /// Heads 2 … M.
    pub head_error: Vec<HeadErrorReport>,
    /// Harmonic orders 1 … P/2 the layout cannot determine (set to 0).
    pub lost_harmonics: Vec<usize>,
    /// What a bound on the lost harmonics adds to every u(e), arcsec (`null` without a
    /// bound).
    pub lost_harmonic_u: Option<f64>,
    /// Sentences for people.
    pub notes: Vec<String>,
    /// With an instrument budget: the GUM combination per quantity and what each
    /// component contributes (then `encoder_error_U`, `encoder_error_k` and the heads'
    /// `U` and `k` are the budget's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<SelfcalUncertainty>,
    /// With `--monte-carlo`: the JCGM 101 evaluation and the validation of the budget's
    /// GUM intervals.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub monte_carlo: Option<SelfcalMonteCarlo>,
}

impl SelfcalReport {
    /// The report of a solution of the file `file`.
    pub fn new(solution: &SelfcalSolution, file: &str) -> Self {
        let k = solution.encoder_error_k();
        let head_k = solution.head_error_k();
        Self {
            file: file.to_string(),
            positions: solution.positions,
            heads: solution.heads.len(),
            cycles: solution.cycles,
            readings: solution.readings,
            dof: solution.dof,
            residual_rms: solution.residual_rms(),
            sigma: solution.sigma.map(|(s, _)| s),
            sigma_source: solution.sigma.map(|(_, source)| sigma_source(source)),
            head_grid: grid_name(solution.grid),
            engine: solution.engine.as_str(),
            encoder_error: solution.encoder_error.clone(),
            encoder_error_u: solution.encoder_error_u.clone(),
            p: COVERAGE_PROBABILITY,
            encoder_error_expanded_u: expanded(solution.encoder_error_u.as_ref(), k.as_ref()),
            encoder_error_k: k,
            encoder_angle_deg: solution.encoder_angle_deg.clone(),
            gauge_positions: solution.gauge_positions,
            head_angle_u: solution.head_angle_u.clone(),
            head_error: solution
                .head_error
                .iter()
                .enumerate()
                .map(|(j, h)| {
                    let k = head_k.as_ref().map(|k| k[j]);
                    HeadErrorReport {
                        head: h.head,
                        angle_deg: h.angle_deg,
                        value: h.value,
                        u: h.u,
                        expanded_u: h.u.zip(k).map(|(u, k)| k * u),
                        k,
                    }
                })
                .collect(),
            lost_harmonics: solution.lost_harmonics.clone(),
            lost_harmonic_u: solution.lost_harmonic_u,
            notes: solution.notes.clone(),
            uncertainty: None,
            monte_carlo: None,
        }
    }

    /// With the uncertainty of an instrument budget: U and k of every quantity are the
    /// budget's.
    pub fn with_uncertainty(mut self, uncertainty: &SelfcalUncertainty) -> Self {
        self.encoder_error_expanded_u = Some(uncertainty.encoder_error.expanded_u.clone());
        self.encoder_error_k = Some(
            uncertainty
                .encoder_error
                .k
                .iter()
                .map(|k| k.unwrap_or(0.0))
                .collect(),
        );
        self.p = uncertainty.p;
        for (h, j) in self.head_error.iter_mut().zip(0..) {
            h.expanded_u = Some(uncertainty.head_error.expanded_u[j]);
            h.k = uncertainty.head_error.k[j];
        }
        self.uncertainty = Some(uncertainty.clone());
        self
    }

    /// With the Monte Carlo of the budget ([`crate::selfcal::monte_carlo()`]).
    pub fn with_monte_carlo(mut self, monte_carlo: SelfcalMonteCarlo) -> Self {
        self.monte_carlo = Some(monte_carlo);
        self
    }

    /// One line of JSON with the software version first ([`super::to_json`]).
    ///
    /// # Errors
    ///
    /// serde_json's error (not expected: every number is finite).
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        super::to_json(self)
    }
}

fn expanded(u: Option<&Vec<f64>>, k: Option<&Vec<f64>>) -> Option<Vec<f64>> {
    Some(u?.iter().zip(k?).map(|(u, k)| u * k).collect())
}

/// The result rows (docs/FORMAT.md §3) of a self-calibration: `encoder_error` at every
/// position with its `angle_deg`. Without a budget: `u` (type A, with the lost
/// harmonics' bound when given), `k` at [`COVERAGE_PROBABILITY`] and `U` = k·u where σ is
/// known; with a budget: its u_c, k and U. The heads' errors are not rows (they are no
/// quantity of the result file: a head is not an autocollimator, and a comparison by
/// index would pair unrelated numbers); they are in the JSON.
pub fn result_rows(
    solution: &SelfcalSolution,
    uncertainty: Option<&SelfcalUncertainty>,
) -> Vec<ResultRow> {
    let (u, k) = match uncertainty {
        Some(budget) => (
            Some(budget.encoder_error.u.clone()),
            Some(
                budget
                    .encoder_error
                    .k
                    .iter()
                    .map(|k| k.unwrap_or(0.0))
                    .collect(),
            ),
        ),
        None => (solution.encoder_error_u.clone(), solution.encoder_error_k()),
    };
    solution
        .encoder_error
        .iter()
        .enumerate()
        .map(|(x, &value)| {
            let row = ResultRow::new(Quantity::EncoderError, x as u32, value)
                .with_angle_deg(solution.encoder_angle_deg[x]);
            match (&u, &k) {
                (Some(u), Some(k)) => row.with_u(u[x]).with_k(k[x]).with_expanded_u(k[x] * u[x]),
                _ => row,
            }
        })
        .collect()
}

fn sigma_source(source: SigmaSource) -> &'static str {
    match source {
        SigmaSource::Residual => "residual",
        SigmaSource::Stated => "stated",
    }
}

fn grid_name(grid: HeadGrid) -> &'static str {
    match grid {
        HeadGrid::OnGrid => "on-grid",
        HeadGrid::OffGrid => "off-grid",
    }
}

/// Writes the table of `polycal selfcal` for people.
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: Write>(
    out: &mut W,
    solution: &SelfcalSolution,
    source: &str,
    uncertainty: Option<&SelfcalUncertainty>,
) -> fmt::Result {
    let p = solution.positions;
    let engine = match (solution.grid, solution.engine) {
        (HeadGrid::OffGrid, _) => "band-limited solver (heads off the grid)".to_string(),
        (_, Engine::Circulant { .. }) => "closure engine (circulant)".to_string(),
        (_, engine) => format!("closure engine ({})", engine.as_str()),
    };
    writeln!(out, "polycal selfcal: {source}")?;
    writeln!(
        out,
        "{p} positions, {} heads, {} cycle{}, {} readings, {engine}, dof {}, residual RMS {}",
        solution.heads.len(),
        solution.cycles,
        if solution.cycles == 1 { "" } else { "s" },
        solution.readings,
        solution.dof,
        super::fixed(solution.residual_rms(), 4)
    )?;
    match solution.sigma {
        Some((s, SigmaSource::Residual)) => writeln!(
            out,
            "u: type A from the residuals (σ = {s:.4} arcsec, {} dof), k = 1",
            solution.dof
        )?,
        Some((s, SigmaSource::Stated)) => {
            writeln!(out, "u: from the stated σ = {s:.4} arcsec, k = 1")?
        }
        None => writeln!(out, "u: not available (no residual dof, no stated σ)")?,
    }
    match uncertainty {
        Some(budget) => writeln!(
            out,
            "U = k·u_c with the budget {} (p = {}, {} dof policy): u_c combines type A and {} component(s)",
            budget.budget,
            budget.p,
            budget.dof_policy,
            budget.components.len()
        )?,
        None => {
            if let Some(u) = solution.lost_harmonic_u {
                writeln!(
                    out,
                    "   including {u:.4} arcsec for the lost harmonics' bound"
                )?;
            }
            writeln!(
                out,
                "U = k·u, k from Student's t at p = {COVERAGE_PROBABILITY} for the type A degrees of freedom"
            )?;
        }
    }
    if solution.lost_harmonics.is_empty() {
        writeln!(out, "lost harmonics: none")?;
    } else {
        writeln!(
            out,
            "lost harmonics (set to 0): {}",
            solution
                .lost_harmonics
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        )?;
    }
    writeln!(out)?;
    writeln!(out, "head errors c (relative to head 1), arcsec")?;
    writeln!(
        out,
        "{:>6} {:>12} {:>10} {:>8} {:>6} {:>8}",
        "head", "angle °", "c", "u", "k", "U"
    )?;
    let head_k = solution.head_error_k();
    for (j, h) in solution.head_error.iter().enumerate() {
        let (u, k) = match uncertainty {
            Some(budget) => (Some(budget.head_error.u[j]), budget.head_error.k[j]),
            None => (h.u, head_k.as_ref().map(|k| k[j])),
        };
        writeln!(
            out,
            "{:>6} {:>12.6} {:>10.4} {:>8} {:>6} {:>8}",
            h.head,
            h.angle_deg,
            h.value,
            super::fixed(u, 4),
            super::fixed(k, 3),
            super::fixed(u.zip(k).map(|(u, k)| u * k), 4)
        )?;
    }
    writeln!(out)?;
    writeln!(out, "encoder error e (Σe = 0), arcsec")?;
    let (u_all, k_all) = match uncertainty {
        Some(budget) => (
            Some(budget.encoder_error.u.clone()),
            Some(
                budget
                    .encoder_error
                    .k
                    .iter()
                    .map(|k| k.unwrap_or(0.0))
                    .collect::<Vec<f64>>(),
            ),
        ),
        None => (solution.encoder_error_u.clone(), solution.encoder_error_k()),
    };
    if p <= TABLE_POSITIONS_LISTED {
        let k = k_all.clone();
        writeln!(
            out,
            "{:>6} {:>12} {:>10} {:>8} {:>6} {:>8}",
            "pos", "angle °", "e", "u", "k", "U"
        )?;
        for x in 0..p {
            let u = u_all.as_ref().map(|u| u[x]);
            let k = k.as_ref().map(|k| k[x]);
            writeln!(
                out,
                "{:>6} {:>12.6} {:>10.4} {:>8} {:>6} {:>8}",
                x,
                solution.encoder_angle_deg[x],
                solution.encoder_error[x],
                super::fixed(u, 4),
                super::fixed(k, 3),
                super::fixed(u.zip(k).map(|(u, k)| u * k), 4)
            )?;
        }
    } else {
        let (worst, max_abs) =
            solution
                .encoder_error
                .iter()
                .enumerate()
                .fold(
                    (0, 0.0f64),
                    |(i, m), (x, v)| {
                        if v.abs() > m { (x, v.abs()) } else { (i, m) }
                    },
                );
        let rms = (solution.encoder_error.iter().map(|v| v * v).sum::<f64>() / p as f64).sqrt();
        writeln!(
            out,
            "{p} positions (every one in the JSON and CSV outputs): RMS {rms:.4}, largest |e| {max_abs:.4} at {:.6}°",
            solution.encoder_angle_deg[worst]
        )?;
        if let Some(u) = &u_all {
            let (lo, hi) = u
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
            writeln!(out, "u(e) from {lo:.4} to {hi:.4}")?;
        }
    }
    if let Some(budget) = uncertainty {
        writeln!(out)?;
        writeln!(
            out,
            "budget contributions (largest over the positions), arcsec"
        )?;
        for c in &budget.components {
            let largest = |v: &[f64]| v.iter().copied().fold(0.0f64, f64::max);
            writeln!(
                out,
                "  {:<48} {:<20} e {:>8.4}   c {:>8.4}",
                c.name,
                c.acts_on.as_str(),
                largest(&c.encoder_error),
                largest(&c.head_error)
            )?;
        }
    }
    if !solution.notes.is_empty() {
        writeln!(out)?;
        for note in &solution.notes {
            writeln!(out, "note: {note}")?;
        }
    }
    Ok(())
}

/// Writes the Monte Carlo section of `polycal selfcal --monte-carlo` after its table:
/// the run, then per head error and per e (every position up to
/// [`TABLE_POSITIONS_LISTED`], else a summary) the mean, u, the interval, the GUM's U and
/// the JCGM 101 §8 validation.
///
/// # Errors
///
/// The writer's error.
pub fn write_monte_carlo<W: Write>(
    out: &mut W,
    solution: &SelfcalSolution,
    uncertainty: &SelfcalUncertainty,
    mc: &SelfcalMonteCarlo,
) -> fmt::Result {
    let run = super::solve_table::McRun {
        trials: mc.trials,
        sequences: mc.sequences,
        seed: mc.seed,
        solver: None,
        reading_noise: mc.reading_noise,
        reading_noise_dof: mc.reading_noise_dof,
        p: mc.p,
        significant_digits: mc.significant_digits,
    };
    let verdict = if mc.validated {
        ": validated"
    } else {
        ": NOT validated"
    };
    super::solve_table::write_monte_carlo_heading(out, &run, verdict)?;
    let header = |out: &mut W, index: &str, symbol: &str| {
        writeln!(
            out,
            "\n{index:>8} {symbol:>9} {:>9} {:>8} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8}  GUM",
            "mean", "u", "low", "high", "U(GUM)", "d_low", "d_high", "δ"
        )
    };
    let row = |out: &mut W, index: u64, value: f64, f: &McFamily, i: usize, expanded: f64| {
        writeln!(
            out,
            "{:>8} {:>9.4} {:>9.4} {:>8.4} {:>9.4} {:>9.4} {:>8.4} {:>8.5} {:>8.5} {:>8.5}  {}",
            index,
            value,
            f.mean[i],
            f.u[i],
            f.low[i],
            f.high[i],
            expanded,
            f.d_low[i],
            f.d_high[i],
            f.delta[i],
            if f.passed[i] { "passed" } else { "FAILED" }
        )
    };
    header(out, "head", "c")?;
    for (j, h) in solution.head_error.iter().enumerate() {
        let expanded = uncertainty.head_error.expanded_u[j];
        row(out, u64::from(h.head), h.value, &mc.head_error, j, expanded)?;
    }
    let p = solution.positions;
    if p <= TABLE_POSITIONS_LISTED {
        header(out, "pos", "e")?;
        for x in 0..p {
            let expanded = uncertainty.encoder_error.expanded_u[x];
            let value = solution.encoder_error[x];
            row(out, x as u64, value, &mc.encoder_error, x, expanded)?;
        }
    } else {
        let f = &mc.encoder_error;
        let failed = f.passed.iter().filter(|&&p| !p).count();
        let worst = (0..p)
            .map(|x| f.d_low[x].max(f.d_high[x]) / f.delta[x].max(f64::MIN_POSITIVE))
            .fold(0.0f64, f64::max);
        writeln!(
            out,
            "e: {p} positions (every one in the JSON), {failed} not validated, largest d/δ {worst:.3}; u from {:.4} to {:.4}",
            f.u.iter().copied().fold(f64::INFINITY, f64::min),
            f.u.iter().copied().fold(0.0f64, f64::max)
        )?;
    }
    Ok(())
}
