//! The table of `polycal diagnose` for people: the base fit, each effect with the pattern
//! that pointed to it, its size, evidence and what it changed, the verdict with its
//! checks, what was tried and not added, and (with a truth) the errors before and after.

use super::diagnose::{ErrorSummary, direction_text, explanation_on};
use crate::diagnose::{Clock, Diagnosis, FoundEffect};
use crate::effects::Effect;
use crate::simulate::Truth;
use crate::solve::Solution;

fn rms_text(solution: &Solution) -> String {
    solution
        .residual_rms()
        .map_or("— (no residual degrees of freedom)".into(), |r| {
            format!("{r:.4}″")
        })
}

/// An F statistic for people: one decimal, or `∞ (no residual left)` for the infinite F
/// of a term that explains the rest exactly (`null` in the JSON, docs/FORMAT.md §5.2).
fn f_text(f: f64) -> String {
    if f.is_finite() {
        format!("{f:.1}")
    } else {
        "∞ (no residual left)".into()
    }
}

/// The test of equal noise: one line when equal; the groups, the changes in words and
/// the weighting when not.
fn write_noise<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    let Some(noise) = &diagnosis.noise else {
        return Ok(());
    };
    let several_setups = noise.sigma.iter().any(|g| g.setup != noise.sigma[0].setup);
    if noise.equal {
        return writeln!(
            out,
            "Noise: the same in every cycle and autocollimator (Bartlett T = {:.1}, {} dof, p = {})",
            noise.statistic,
            noise.dof,
            p_text(noise.p_value)
        );
    }
    writeln!(
        out,
        "Noise: not the same in every cycle and autocollimator (Bartlett T = {:.1}, {} dof, p = {} < {}){}",
        noise.statistic,
        noise.dof,
        p_text(noise.p_value),
        noise.alpha,
        if noise.weighted {
            "; every fit weights each group by 1/σ²"
        } else {
            "; the fits keep equal weights"
        }
    )?;
    for change in &noise.changes {
        writeln!(
            out,
            "  {}",
            crate::diagnose::noise::change_words(change, several_setups)
        )?;
    }
    for g in &noise.sigma {
        let cycles: Vec<String> = g.cycles.iter().map(u32::to_string).collect();
        let mounting = if several_setups {
            format!("setup {} ", g.setup)
        } else {
            String::new()
        };
        writeln!(
            out,
            "  {mounting}autocollimator {} cycles {}: σ {:.4}″",
            g.ac,
            cycles.join(", "),
            g.sigma_arcsec
        )?;
    }
    Ok(())
}

fn p_text(p: f64) -> String {
    if p < 1e-300 {
        "< 1e-300".into()
    } else {
        format!("{p:.2e}")
    }
}

/// The table for people: the base fit, each effect with the pattern that pointed to it,
/// its size and evidence and what it changed, the final fit, the verdict and (with a
/// truth) the errors before and after.
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: std::fmt::Write>(
    out: &mut W,
    diagnosis: &Diagnosis,
    truth: Option<&Truth>,
    source: &str,
) -> std::fmt::Result {
    let before = &diagnosis.before;
    writeln!(out, "polycal diagnose: {source}")?;
    writeln!(
        out,
        "Base model: {} faces, {} readings, dof {}, residual RMS {}",
        before.faces,
        before.readings,
        before.dof,
        rms_text(before)
    )?;
    for note in &diagnosis.notes {
        writeln!(out, "  note: {note}")?;
    }
    write_noise(out, diagnosis)?;
    write_cycles(out, diagnosis)?;
    write_mountings(out, diagnosis)?;
    write_effects(out, diagnosis)?;
    if let Some(stop) = diagnosis.search_stopped {
        writeln!(
            out,
            "\nSearch STOPPED by a limit ({}): {}.",
            stop.as_str(),
            stop.describe()
        )?;
    }
    if diagnosis.testable {
        write_adequacy(out, diagnosis)?;
    }
    write_worst_cells(out, diagnosis)?;
    write_tried(out, diagnosis)?;
    if let Some(truth) = truth {
        write_truth_errors(out, diagnosis, truth)?;
    }
    Ok(())
}

/// The effects found, in the order added, each with its size, pattern, evidence, effect
/// on the calibration and alternatives, then the final model (or that none is
/// significant).
fn write_effects<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    if diagnosis.effects.is_empty() {
        if diagnosis.testable {
            writeln!(
                out,
                "\nNo effect is significant: the base model explains the readings."
            )?;
        }
        return Ok(());
    }
    writeln!(
        out,
        "\nEffects found, in the order added (each by an F test against the model before it):"
    )?;
    for (i, found) in diagnosis.effects.iter().enumerate() {
        write_effect(out, i + 1, found, diagnosis.clock)?;
    }
    let after = &diagnosis.after;
    writeln!(
        out,
        "\nFinal model: base + {} effect{}, dof {}, residual RMS {}",
        diagnosis.effects.len(),
        if diagnosis.effects.len() == 1 {
            ""
        } else {
            "s"
        },
        after.dof,
        rms_text(after)
    )
}

/// Effect number `number` found: its value (and a drift's curvature) with u, the
/// pattern that pointed to it, its evidence, what it changed, and its alternatives.
fn write_effect<W: std::fmt::Write>(
    out: &mut W,
    number: usize,
    found: &FoundEffect,
    clock: Clock,
) -> std::fmt::Result {
    let value = found.effect.value();
    let unit = match found.effect {
        Effect::Drift { .. } => clock.drift_unit_text(),
        Effect::CrossTalk { .. } => "″/″",
        _ => "″",
    };
    let u = found
        .u
        .map_or(String::new(), |u| format!(" ± {u:.4}{unit} (k = 1)"));
    writeln!(
        out,
        "{:>3}. {} = {value:+.4}{unit}{u}",
        number,
        found.effect.label()
    )?;
    if let Effect::Drift {
        quadratic: Some(q), ..
    } = found.effect
    {
        let u = found
            .quadratic_u
            .map_or(String::new(), |u| format!(" ± {u:.4}{unit}² (k = 1)"));
        let evidence = found.quadratic_evidence.map_or(String::new(), |e| {
            format!(
                "; curvature added by F = {}, Bonferroni p = {}",
                f_text(e.f_statistic),
                p_text(e.p_adjusted)
            )
        });
        writeln!(
            out,
            "     curvature (quadratic) = {q:+.4}{unit}²{u}{evidence}"
        )?;
    }
    writeln!(out, "     pattern: {}", explanation_on(found, clock))?;
    writeln!(
        out,
        "     evidence: F = {}, p = {}, Bonferroni p = {}; residual RMS {:.4}″ → {:.4}″",
        f_text(found.f_statistic),
        p_text(found.p_value),
        p_text(found.p_adjusted),
        found.residual_rms_before,
        found.residual_rms_after
    )?;
    writeln!(
        out,
        "     effect on the calibration: pitch deviations changed by up to {:.4}″, encoder errors by up to {:.4}″",
        found.pitch_change_max, found.encoder_change_max
    )?;
    for alternative in &found.alternatives {
        let names: Vec<String> = alternative
            .effects
            .iter()
            .map(|e| format!("{} = {:+.5}", e.label(), e.value()))
            .collect();
        if alternative.equivalent && !alternative.changes_calibration() {
            writeln!(
                out,
                "     equivalently: {} (the same fit and the same calibration: the data cannot tell them apart)",
                names.join(" with ")
            )?;
            continue;
        }
        writeln!(
            out,
            "     {}: {} fits as well (F = {}, p = {:.2}) and changes pitch deviations by up to {:.4}″, encoder errors by up to {:.4}″ ({:.1} expanded uncertainties)",
            if alternative.changes_calibration() {
                "CANNOT TELL"
            } else {
                "alternative"
            },
            names.join(" with "),
            f_text(alternative.f_statistic),
            alternative.p_value,
            alternative.pitch_change_max,
            alternative.encoder_change_max,
            alternative.change_over_expanded_u
        )?;
    }
    Ok(())
}

/// The verdict on the final model: adequate or not (and why, with a caution on the
/// effects found), every check against its limit, and the structure left.
fn write_adequacy<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    if diagnosis.adequacy.adequate {
        writeln!(
            out,
            "\nAdequate: the final residuals are consistent with noise."
        )?;
    } else {
        write_not_adequate(out, diagnosis)?;
    }
    for check in &diagnosis.adequacy.checks {
        writeln!(
            out,
            "  {} {}: {} (limit {:.2})",
            if check.passed { "pass" } else { "FAIL" },
            check.name,
            if check.statistic.is_finite() {
                format!("{:.2}", check.statistic)
            } else {
                "∞".to_string()
            },
            check.limit
        )?;
    }
    for s in &diagnosis.adequacy.structure {
        let time = |t: Option<f64>| t.map_or(String::new(), |t| format!(", t = {t:.0} s"));
        writeln!(
            out,
            "  structure left: setup {} autocollimator {}, from cycle {} step {}{} to cycle {} step {}{}: mean residual {:+.4}″ over {} readings",
            s.setup,
            s.ac,
            s.from.0,
            s.from.1,
            time(s.from.2),
            s.to.0,
            s.to.1,
            time(s.to.2),
            s.mean_residual_arcsec,
            s.readings
        )?;
    }
    Ok(())
}

/// Why the final model is not adequate: an ambiguity, or structure left; with the
/// band-limit's finding or a caution on the effects found.
fn write_not_adequate<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    let failed: Vec<&str> = diagnosis
        .adequacy
        .checks
        .iter()
        .filter(|c| !c.passed)
        .map(|c| c.name.as_str())
        .collect();
    let ambiguous_only = !failed.is_empty()
        && failed
            .iter()
            .all(|name| name.starts_with("identifiability"));
    if ambiguous_only {
        writeln!(
            out,
            "\nNOT adequate: an effect found cannot be told apart from another explanation that gives a different calibration (see the notes); the result is not certified."
        )?;
    } else {
        writeln!(
            out,
            "\nNOT adequate: structure is left that no known effect explains."
        )?;
    }
    // a lack of fit the band-limited model of heads between the positions leaves
    // (and nothing else failed) has a cause of its own beside the effects found
    let band_limit = diagnosis
        .lack_of_fit
        .as_ref()
        .and_then(|lof| lof.band_limit_order)
        .filter(|_| failed.iter().all(|name| name.starts_with("lack of fit")));
    if let (Some(order), false) = (band_limit, diagnosis.effects.is_empty()) {
        writeln!(
            out,
            "  The lack of fit is left beside the effects above, a finding of its own: the band-limited model of heads between the positions cannot fit the encoder error's orders of {order} or more (see the notes). Each effect was kept because it reduces the lack of fit, judged against one pure error with and without it; the result is not certified until that cause is settled."
        )?;
    } else if !diagnosis.effects.is_empty() && !ambiguous_only {
        writeln!(
            out,
            "  Caution: the effects above are the closest terms the model has to a structure it cannot express, not a confirmed explanation; do not take the final model's result as corrected until the cause of the structure below is found."
        )?;
    }
    Ok(())
}

/// A failed lack-of-fit test: the five cells whose mean residual stands out most.
fn write_worst_cells<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    if let Some(lof) = &diagnosis.lack_of_fit
        && !lof.passed()
    {
        writeln!(
            out,
            "  cells whose mean residual stands out most (pure-error σ {:.4}″):",
            lof.pure_error_sigma
        )?;
        for c in lof.worst_cells.iter().take(5) {
            writeln!(
                out,
                "    setup {} step {} autocollimator {} {} (face {}): mean residual {:+.4}″ over {} readings, z = {:+.1}",
                c.setup,
                c.step,
                c.ac,
                direction_text(c.direction),
                c.face,
                c.mean_residual_arcsec,
                c.readings,
                c.z
            )?;
        }
    }
    Ok(())
}

/// The candidates tried and not added, with their evidence and why.
fn write_tried<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    if diagnosis.tried.is_empty() {
        return Ok(());
    }
    writeln!(out, "\nTried and not added:")?;
    for t in &diagnosis.tried {
        let name = if t.quadratic {
            format!("curvature of the {}", t.effect.label())
        } else {
            t.effect.label()
        };
        writeln!(
            out,
            "  {name}: F = {}, Bonferroni p = {} — {}",
            f_text(t.evidence.f_statistic),
            p_text(t.evidence.p_adjusted),
            t.rejection.as_str()
        )?;
    }
    Ok(())
}

/// The errors of the base and final models against the `truth`, in arcsec (nothing when
/// either cannot be compared).
fn write_truth_errors<W: std::fmt::Write>(
    out: &mut W,
    diagnosis: &Diagnosis,
    truth: &Truth,
) -> std::fmt::Result {
    let (Some(b), Some(a)) = (
        ErrorSummary::new(&diagnosis.before, truth),
        ErrorSummary::new(&diagnosis.after, truth),
    ) else {
        return Ok(());
    };
    writeln!(
        out,
        "\nError against the truth (arcsec)   pitch RMS  pitch max  encoder RMS  encoder max"
    )?;
    for (label, e) in [("before", b), ("after", a)] {
        writeln!(
            out,
            "  {label:<32} {:>9.4}  {:>9.4}  {:>11.4}  {:>11.4}",
            e.pitch_rms, e.pitch_max, e.encoder_rms, e.encoder_max
        )?;
    }
    Ok(())
}

/// The cycles that disagree with the others: which, the statistic, the cause, what was
/// done, what it changed, and the readings that left the fit.
fn write_cycles<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    if diagnosis.cycles.is_empty() {
        return Ok(());
    }
    writeln!(
        out,
        "\nCycles that disagree with the others (each tested against the rest of its mounting, 1 % for the run):"
    )?;
    for c in &diagnosis.cycles {
        let cause = if c.alternatives.is_empty() {
            c.cause.as_str().to_string()
        } else {
            let names: Vec<&str> = c.alternatives.iter().map(|a| a.as_str()).collect();
            format!("unexplained ({} fit equally well)", names.join(" or "))
        };
        let repaired = c.repaired.map_or(String::new(), |(f, p)| {
            format!("; undone, F = {f:.2} (p = {})", p_text(p))
        });
        writeln!(
            out,
            "  setup {} cycle {}: F = {} on {} and {} dof, p = {} (level {:.1e}); cause {cause}; {}{repaired}",
            c.setup,
            c.cycle,
            f_text(c.f_statistic),
            c.dof_numerator,
            c.dof_denominator,
            p_text(c.p_value),
            c.level,
            c.action.as_str(),
        )?;
        writeln!(
            out,
            "    changes against the readings as logged: β by up to {:.4}″, α by up to {:.4}″; {} reading{} left the fit",
            c.pitch_change_max,
            c.encoder_change_max,
            c.set_aside.len(),
            if c.set_aside.len() == 1 { "" } else { "s" }
        )?;
        for r in c.set_aside.iter().take(4) {
            writeln!(
                out,
                "    left out: step {} ac {} (line {}, {:+.4}″): {}",
                r.step, r.ac, r.line, r.reading_arcsec, r.reason
            )?;
        }
        if c.set_aside.len() > 4 {
            writeln!(
                out,
                "    … and {} more (see the JSON)",
                c.set_aside.len() - 4
            )?;
        }
    }
    Ok(())
}

/// The mountings that disagree with the others: which, the statistic, the cause and what
/// was done.
fn write_mountings<W: std::fmt::Write>(out: &mut W, diagnosis: &Diagnosis) -> std::fmt::Result {
    if diagnosis.mountings.is_empty() {
        return Ok(());
    }
    writeln!(
        out,
        "\nMountings that disagree with the others (each tested against the rest, 1 % for the run):"
    )?;
    for m in &diagnosis.mountings {
        let cause = if m.alternatives.is_empty() {
            m.cause.as_str().to_string()
        } else {
            let names: Vec<&str> = m.alternatives.iter().map(|a| a.as_str()).collect();
            format!("unexplained ({} fit equally well)", names.join(" or "))
        };
        let repaired = m.repaired.map_or(String::new(), |(f, p)| {
            format!("; undone, F = {f:.2} (p = {})", p_text(p))
        });
        writeln!(
            out,
            "  setup {}: F = {} on {} and {} dof, p = {} (level {:.1e}); cause {cause} in every cycle; {}{repaired}; {} reading{} left the fit",
            m.setup,
            f_text(m.f_statistic),
            m.dof_numerator,
            m.dof_denominator,
            p_text(m.p_value),
            m.level,
            m.action.as_str(),
            m.set_aside.len(),
            if m.set_aside.len() == 1 { "" } else { "s" }
        )?;
    }
    Ok(())
}
