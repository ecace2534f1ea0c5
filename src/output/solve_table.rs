//! The table of `polycal solve` for people: rounded, with units, the uncertainty budget
//! and the Monte Carlo validation when they were evaluated. Its results section
//! ([`write_results`]) is also what `polycal diagnose` prints for its final model
//! ([`write_final_model_results`]).

use super::fixed;
use crate::solve::sub_pitch::SubPitchSolution;
use crate::solve::{Engine, SigmaSource, Solution};
use crate::uncertainty::calibration::{CalibrationMonteCarlo, CalibrationUncertainty, McFamily};
use std::fmt::{self, Write};

/// Writes the table for people: per face β, u(β), φ, u(φ); per position the angle, α,
/// u(α); the setup errors; dof and residual RMS. With `uncertainty` (an instrument
/// budget), the type A u_A, combined u_c, k and U per quantity and what each budget
/// component contributes; with `monte_carlo`, the Monte Carlo results and the JCGM 101 §8
/// validation.
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: Write>(
    out: &mut W,
    solution: &Solution,
    source: &str,
    uncertainty: Option<&CalibrationUncertainty>,
    monte_carlo: Option<&CalibrationMonteCarlo>,
) -> fmt::Result {
    write_summary(out, solution, source)?;
    write_results(out, solution, uncertainty)?;
    if let Some(mc) = monte_carlo {
        write_monte_carlo(out, solution, uncertainty, mc)?;
    }
    Ok(())
}

/// The two summary lines of the table: the file, then N, readings, method, dof and
/// residual RMS.
fn write_summary<W: Write>(out: &mut W, solution: &Solution, source: &str) -> fmt::Result {
    let n = solution.faces;
    let method = match solution.engine {
        Engine::ClosedForm => "closed form (paper eqs. (6)-(10))".to_string(),
        Engine::Circulant { low_rank } => {
            format!("least squares (circulant engine, low rank {low_rank})")
        }
        Engine::CosetCirculant { cosets, low_rank } => {
            format!("least squares (coset-circulant engine, {cosets} cosets, low rank {low_rank})")
        }
        _ => "least squares (dense)".to_string(),
    };
    writeln!(out, "polycal solve: {source}")?;
    writeln!(
        out,
        "{n} faces, {} readings, {method}, dof {}, residual RMS {}",
        solution.readings,
        solution.dof,
        rms_text(solution)
    )
}

/// Writes the results section of the table, what [`write_table`] prints after its two
/// summary lines: where the standard uncertainties come from; per face β, u(β), φ, u(φ);
/// per position the angle, α, u(α); the setup errors. With `uncertainty` (an instrument
/// budget), the type A u_A, combined u_c, k and U per quantity and what each budget
/// component contributes.
///
/// # Errors
///
/// The writer's error.
pub fn write_results<W: Write>(
    out: &mut W,
    solution: &Solution,
    uncertainty: Option<&CalibrationUncertainty>,
) -> fmt::Result {
    write_results_with(out, solution, uncertainty, None)
}

/// Writes the table of a set with shifted mountings
/// ([`solve_shifted`](crate::solve::sub_pitch::solve_shifted)): as [`write_table`]
/// without a budget, except that for sub-pitch mountings the encoder section lists every
/// table angle of every coset, sorted by angle (index, angle, α, u(α)), and the notes
/// follow the table.
///
/// # Errors
///
/// The writer's error.
pub fn write_sub_pitch_table<W: Write>(
    out: &mut W,
    solved: &SubPitchSolution,
    source: &str,
) -> fmt::Result {
    let solution = &solved.solution;
    write_summary(out, solution, source)?;
    write_results_with(out, solution, None, Some(solved))?;
    if !solved.notes.is_empty() {
        writeln!(out)?;
        for note in &solved.notes {
            writeln!(out, "note: {note}")?;
        }
    }
    Ok(())
}

/// The nominal angle of face `face` (1 … N), degrees: f·360°/N from face N, the face
/// whose deviation φ is 0 by definition (docs/FORMAT.md §1), so face N is at 360°.
fn nominal_face_deg(face: usize, faces: usize) -> f64 {
    face as f64 * 360.0 / faces as f64
}

/// The results section, with the encoder errors of every coset when `sub_pitch` has
/// sub-pitch mountings.
fn write_results_with<W: Write>(
    out: &mut W,
    solution: &Solution,
    uncertainty: Option<&CalibrationUncertainty>,
    sub_pitch: Option<&SubPitchSolution>,
) -> fmt::Result {
    write_uncertainty_basis(out, solution, uncertainty)?;
    // the angle φ is measured against: face f at f·360°/N from face N (φ[N] = 0)
    writeln!(
        out,
        "\nPolygon (arcsec; nominal/°: face f at f·360°/N from face N, where φ = 0, so face N at 360°)"
    )?;
    match uncertainty {
        None => write_polygon_u(out, solution)?,
        Some(unc) => write_polygon_expanded_u(out, solution, unc)?,
    }
    writeln!(out, "\nEncoder (arcsec)")?;
    match uncertainty {
        None if let Some(solved) = sub_pitch.filter(|s| s.is_sub_pitch()) => {
            write_coset_encoder_u(out, solved)?;
        }
        None => write_encoder_u(out, solution)?,
        Some(unc) => write_encoder_expanded_u(out, solution, unc)?,
    }
    write_setup_errors(out, solution, uncertainty)?;
    if let Some(unc) = uncertainty {
        write_budget_contributions(out, unc)?;
    }
    Ok(())
}

/// Element `i` of optional values (an uncertainty the fit may not have).
fn value_at(v: &Option<Vec<f64>>, i: usize) -> Option<f64> {
    v.as_ref().map(|v| v[i])
}

/// Where the uncertainties come from: the residual or the stated σ (or none), and with
/// a budget, how U and k are formed.
fn write_uncertainty_basis<W: Write>(
    out: &mut W,
    solution: &Solution,
    uncertainty: Option<&CalibrationUncertainty>,
) -> fmt::Result {
    match solution.sigma {
        Some((s, SigmaSource::Residual)) => {
            writeln!(out, "uncertainties (k = 1) from the residual σ = {s:.4}″")?;
        }
        Some((s, SigmaSource::Stated)) => {
            writeln!(
                out,
                "uncertainties (k = 1) from the stated reading noise σ = {s:.4}″"
            )?;
        }
        None => {
            writeln!(
                out,
                "no uncertainties: the fit has no residual degrees of freedom; state the reading noise σ to get them"
            )?;
        }
    }
    if let Some(unc) = uncertainty {
        writeln!(
            out,
            "expanded uncertainties U = k·u_c at p = {} %: the fit's type A u_A combined with the budget {} \
             (k = {})",
            crate::uncertainty::format::percent(unc.p),
            unc.budget,
            match unc.dof_policy {
                crate::uncertainty::DofPolicy::K2 => "2 by policy".to_string(),
                policy => format!("t for each quantity's ν_eff, {policy}"),
            }
        )?;
    }
    Ok(())
}

/// The polygon's pitch deviations β and face deviations φ per face, with their nominal
/// angle and the fit's u (k = 1), arcsec.
fn write_polygon_u<W: Write>(out: &mut W, solution: &Solution) -> fmt::Result {
    let n = solution.faces;
    let pitch_u = solution.pitch_deviation_u();
    let face_u = solution.face_deviation_u();
    writeln!(
        out,
        "{:>5} {:>11} {:>9} {:>8} {:>9} {:>8}",
        "face", "nominal/°", "β", "u(β)", "φ", "u(φ)"
    )?;
    for f in 0..n {
        writeln!(
            out,
            "{:>5} {:>11.4} {:>9.4} {:>8} {:>9.4} {:>8}",
            f + 1,
            nominal_face_deg(f + 1, n),
            solution.pitch_deviation[f],
            fixed(value_at(&pitch_u, f), 4),
            solution.face_deviation[f],
            fixed(value_at(&face_u, f), 4),
        )?;
    }
    Ok(())
}

/// The polygon's β and φ per face with the budget's u_A, u_c, k and U, arcsec.
fn write_polygon_expanded_u<W: Write>(
    out: &mut W,
    solution: &Solution,
    unc: &CalibrationUncertainty,
) -> fmt::Result {
    let n = solution.faces;
    let (b, p) = (&unc.pitch_deviation, &unc.face_deviation);
    writeln!(
        out,
        "{:>5} {:>11} {:>9} {:>8} {:>8} {:>6} {:>8} {:>9} {:>8} {:>6} {:>8}",
        "face", "nominal/°", "β", "u_A(β)", "u_c(β)", "k", "U(β)", "φ", "u_c(φ)", "k", "U(φ)"
    )?;
    for f in 0..n {
        writeln!(
            out,
            "{:>5} {:>11.4} {:>9.4} {:>8.4} {:>8.4} {:>6} {:>8.4} {:>9.4} {:>8.4} {:>6} {:>8.4}",
            f + 1,
            nominal_face_deg(f + 1, n),
            solution.pitch_deviation[f],
            b.u_a[f],
            b.u[f],
            fixed(b.k[f], 3),
            b.expanded_u[f],
            solution.face_deviation[f],
            p.u[f],
            fixed(p.k[f], 3),
            p.expanded_u[f],
        )?;
    }
    Ok(())
}

/// The encoder errors α at every table angle of every coset of sub-pitch mountings,
/// with their u (k = 1), arcsec.
fn write_coset_encoder_u<W: Write>(out: &mut W, solved: &SubPitchSolution) -> fmt::Result {
    writeln!(
        out,
        "{:>8} {:>11} {:>9} {:>8}",
        "index", "angle/°", "α", "u(α)"
    )?;
    for (i, (angle, alpha)) in solved
        .encoder_angle_deg
        .iter()
        .zip(&solved.encoder_error)
        .enumerate()
    {
        writeln!(
            out,
            "{:>8} {:>11.4} {:>9.4} {:>8}",
            i,
            angle,
            alpha,
            fixed(value_at(&solved.encoder_error_u, i), 4),
        )?;
    }
    Ok(())
}

/// The encoder errors α per position with their u (k = 1), arcsec.
fn write_encoder_u<W: Write>(out: &mut W, solution: &Solution) -> fmt::Result {
    let n = solution.faces;
    let encoder_u = solution.encoder_error_u();
    writeln!(
        out,
        "{:>8} {:>11} {:>9} {:>8}",
        "position", "angle/°", "α", "u(α)"
    )?;
    for p in 0..n {
        writeln!(
            out,
            "{:>8} {:>11.4} {:>9.4} {:>8}",
            p,
            p as f64 * 360.0 / n as f64,
            solution.encoder_error[p],
            fixed(value_at(&encoder_u, p), 4),
        )?;
    }
    Ok(())
}

/// The encoder errors α per position with the budget's u_A, u_c, k and U, arcsec.
fn write_encoder_expanded_u<W: Write>(
    out: &mut W,
    solution: &Solution,
    unc: &CalibrationUncertainty,
) -> fmt::Result {
    let n = solution.faces;
    let a = &unc.encoder_error;
    writeln!(
        out,
        "{:>8} {:>11} {:>9} {:>8} {:>8} {:>6} {:>8}",
        "position", "angle/°", "α", "u_A(α)", "u_c(α)", "k", "U(α)"
    )?;
    for p in 0..n {
        writeln!(
            out,
            "{:>8} {:>11.4} {:>9.4} {:>8.4} {:>8.4} {:>6} {:>8.4}",
            p,
            p as f64 * 360.0 / n as f64,
            solution.encoder_error[p],
            a.u_a[p],
            a.u[p],
            fixed(a.k[p], 3),
            a.expanded_u[p],
        )?;
    }
    Ok(())
}

/// The setup errors per mounting and autocollimator with their u (and U with a budget),
/// arcsec.
fn write_setup_errors<W: Write>(
    out: &mut W,
    solution: &Solution,
    uncertainty: Option<&CalibrationUncertainty>,
) -> fmt::Result {
    let setup_u = solution.setup_error_u();
    writeln!(out, "\nSetup errors (arcsec, gauge of docs/FORMAT.md §1)")?;
    writeln!(
        out,
        "{:>5} {:>4} {:>9} {:>8}{}",
        "setup",
        "ac",
        "U",
        "u(U)",
        if uncertainty.is_some() {
            format!(" {:>8}", "U(U)")
        } else {
            String::new()
        }
    )?;
    for (i, s) in solution.setup_error.iter().enumerate() {
        writeln!(
            out,
            "{:>5} {:>4} {:>9.4} {:>8}{}",
            s.setup,
            s.ac,
            s.value,
            fixed(value_at(&setup_u, i), 4),
            uncertainty.map_or(String::new(), |unc| format!(
                " {:>8.4}",
                unc.setup_error.expanded_u[i]
            ))
        )?;
    }
    Ok(())
}

/// The budget's contribution of each source (standard uncertainty, arcsec, largest over
/// the quantities), the fit's repeatability first, the combined u_c last.
fn write_budget_contributions<W: Write>(out: &mut W, unc: &CalibrationUncertainty) -> fmt::Result {
    let largest = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    writeln!(
        out,
        "\nBudget {}: contribution of each source (standard uncertainty, largest over the quantities)",
        unc.budget
    )?;
    writeln!(
        out,
        "{:<44} {:<20} {:>8} {:>8} {:>8} {:>8}",
        "source", "acts on", "u", "to β", "to φ", "to α"
    )?;
    let type_a = format!(
        "Repeatability (fit, σ = {:.4}″, ν = {})",
        unc.sigma,
        unc.type_a_dof.map_or("∞".to_string(), |nu| format!("{nu}"))
    );
    writeln!(
        out,
        "{:<44} {:<20} {:>8.4} {:>8.4} {:>8.4} {:>8.4}",
        type_a,
        "each-reading",
        unc.sigma,
        largest(&unc.pitch_deviation.u_a),
        largest(&unc.face_deviation.u_a),
        largest(&unc.encoder_error.u_a),
    )?;
    for c in &unc.components {
        let name: String = c.name.chars().take(44).collect();
        writeln!(
            out,
            "{:<44} {:<20} {:>8.4} {:>8.4} {:>8.4} {:>8.4}",
            name,
            c.acts_on.as_str(),
            c.u,
            largest(&c.pitch_deviation),
            largest(&c.face_deviation),
            largest(&c.encoder_error),
        )?;
    }
    writeln!(
        out,
        "{:<44} {:<20} {:>8} {:>8.4} {:>8.4} {:>8.4}",
        "Combined u_c",
        "",
        "",
        largest(&unc.pitch_deviation.u),
        largest(&unc.face_deviation.u),
        largest(&unc.encoder_error.u),
    )
}

/// Writes the results section ([`write_results`]) of the final model of
/// `polycal diagnose` under a heading that says so: the calibration corrected for the
/// effect terms of `solution` (base model + effects), with its dof and residual RMS;
/// with `monte_carlo`, its Monte Carlo and the JCGM 101 §8 validation, as `solve`'s
/// table has them.
///
/// # Errors
///
/// The writer's error.
pub fn write_final_model_results<W: Write>(
    out: &mut W,
    solution: &Solution,
    uncertainty: Option<&CalibrationUncertainty>,
    sub_pitch: Option<&SubPitchSolution>,
    monte_carlo: Option<&CalibrationMonteCarlo>,
) -> fmt::Result {
    // the cosets' differences of sub-pitch mountings are part of the base model
    let base_terms = sub_pitch.map_or(0, |s| {
        s.cosets.len().saturating_sub(1) * solution.faces.saturating_sub(1)
    });
    let terms = solution.layout.effects.saturating_sub(base_terms);
    let model = match terms {
        0 => "the base model, no effect added".to_string(),
        1 => "base model + the effect above, 1 fitted term".to_string(),
        e => format!("base model + the effects above, {e} fitted terms"),
    };
    writeln!(
        out,
        "\nCalibration of the final model ({model}){}: dof {}, residual RMS {}",
        if terms > 0 {
            ", corrected for the effects"
        } else {
            ""
        },
        solution.dof,
        rms_text(solution)
    )?;
    write_results_with(out, solution, uncertainty, sub_pitch)?;
    if let Some(solved) = sub_pitch {
        for note in &solved.notes {
            writeln!(out, "note: {note}")?;
        }
    }
    if let Some(mc) = monte_carlo {
        write_monte_carlo(out, solution, uncertainty, mc)?;
    }
    Ok(())
}

/// The residual RMS for the table, or why there is none.
fn rms_text(solution: &Solution) -> String {
    solution
        .residual_rms()
        .map_or("— (exactly determined)".to_string(), |r| {
            format!("{r:.4}″")
        })
}

/// What the heading of a Monte Carlo section says of its run.
pub(super) struct McRun<'a> {
    pub(super) trials: usize,
    pub(super) sequences: Option<usize>,
    pub(super) seed: u64,
    /// `closed-form` or `lsq`, when the command chooses.
    pub(super) solver: Option<&'a str>,
    pub(super) reading_noise: &'a str,
    pub(super) reading_noise_dof: Option<f64>,
    pub(super) p: f64,
    pub(super) significant_digits: u32,
}

/// The two heading lines of a Monte Carlo section (`solve`, `diagnose`, `selfcal`): the
/// run, then the intervals and the validation rule, ending with `verdict`.
pub(super) fn write_monte_carlo_heading<W: Write>(
    out: &mut W,
    run: &McRun<'_>,
    verdict: &str,
) -> fmt::Result {
    writeln!(
        out,
        "\nMonte Carlo (JCGM 101): {} trials{}, seed {}, {}reading noise {}",
        run.trials,
        run.sequences
            .map_or(String::new(), |h| format!(" (adaptive, {h} sequences)")),
        run.seed,
        run.solver
            .map_or(String::new(), |s| format!("{s} solver, ")),
        match run.reading_noise_dof {
            Some(nu) => format!("t (ν = {nu})"),
            None => run.reading_noise.to_string(),
        }
    )?;
    writeln!(
        out,
        "{} % probabilistically symmetric intervals; GUM validated when |y ∓ U − end| ≤ δ ({} significant digits of u_c){verdict}",
        crate::uncertainty::format::percent(run.p),
        run.significant_digits
    )
}

fn write_monte_carlo<W: Write>(
    out: &mut W,
    solution: &Solution,
    uncertainty: Option<&CalibrationUncertainty>,
    mc: &CalibrationMonteCarlo,
) -> fmt::Result {
    let n = solution.faces;
    let run = McRun {
        trials: mc.trials,
        sequences: mc.sequences,
        seed: mc.seed,
        solver: Some(mc.solver),
        reading_noise: mc.reading_noise,
        reading_noise_dof: mc.reading_noise_dof,
        p: mc.p,
        significant_digits: mc.significant_digits,
    };
    write_monte_carlo_heading(out, &run, "")?;
    // (index name, symbol, Monte Carlo, estimates, GUM U)
    type Row<'a> = (&'a str, &'a str, &'a McFamily, &'a [f64], Option<&'a [f64]>);
    let families: [Row<'_>; 3] = [
        (
            "face",
            "β",
            &mc.pitch_deviation,
            &solution.pitch_deviation,
            uncertainty.map(|u| u.pitch_deviation.expanded_u.as_slice()),
        ),
        (
            "face",
            "φ",
            &mc.face_deviation,
            &solution.face_deviation,
            uncertainty.map(|u| u.face_deviation.expanded_u.as_slice()),
        ),
        (
            "position",
            "α",
            &mc.encoder_error,
            &solution.encoder_error,
            uncertainty.map(|u| u.encoder_error.expanded_u.as_slice()),
        ),
    ];
    for (index_name, symbol, family, estimates, expanded) in families {
        writeln!(
            out,
            "\n{:>8} {:>9} {:>9} {:>8} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8}  GUM",
            index_name, symbol, "mean", "u", "low", "high", "U(GUM)", "d_low", "d_high", "δ"
        )?;
        for i in 0..n {
            let index = if symbol == "α" { i } else { i + 1 };
            writeln!(
                out,
                "{:>8} {:>9.4} {:>9.4} {:>8.4} {:>9.4} {:>9.4} {:>8} {:>8.5} {:>8.5} {:>8.5}  {}",
                index,
                estimates[i],
                family.mean[i],
                family.u[i],
                family.low[i],
                family.high[i],
                fixed(expanded.map(|e| e[i]), 4),
                family.d_low[i],
                family.d_high[i],
                family.delta[i],
                if family.passed[i] {
                    "validated"
                } else {
                    "NOT validated"
                }
            )?;
        }
    }
    let failed: usize = [&mc.pitch_deviation, &mc.face_deviation, &mc.encoder_error]
        .iter()
        .map(|f| f.passed.iter().filter(|&&p| !p).count())
        .sum();
    writeln!(
        out,
        "\n{}",
        if mc.validated {
            "The GUM uncertainties are validated by Monte Carlo (JCGM 101 §8).".to_string()
        } else {
            format!(
                "{failed} GUM intervals are NOT validated by Monte Carlo (JCGM 101 §8): use the \
                 Monte Carlo intervals for those quantities, or more trials if δ is below the \
                 Monte Carlo noise."
            )
        }
    )?;
    Ok(())
}
