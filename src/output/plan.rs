//! Outputs of `polycal plan`: the JSON object of one design (docs/FORMAT.md §5.6), its
//! table for people, and the table comparing designs side by side.
//!
//! The uncertainties carry `solve`'s names and come through [`SolveReport`], so that a
//! plan and a solve of a run of the design print the same numbers the same way.

use std::fmt::{self, Write};

use serde::Serialize;

use super::{SetupErrorReport, SolveReport};
use crate::plan::detect::Ambiguity;
use crate::plan::{Design, Detectable, Plan};
use crate::uncertainty::calibration::CalibrationUncertainty;

/// The design of a plan as written in its JSON.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DesignReport {
    /// N.
    pub faces: usize,
    /// The face each autocollimator reads at step 0 of mounting 1.
    pub ac_faces: Vec<usize>,
    /// Cycles per mounting.
    pub cycles: u32,
    /// The closing reading.
    pub closing: bool,
    /// Counter-clockwise cycles.
    pub bidirectional: bool,
    /// Mountings.
    pub setups: u32,
    /// Whole faces between mountings.
    pub setup_shift: usize,
    /// The table's angle at step 0 of each mounting, degrees (empty: all at 0).
    pub shift_deg: Vec<f64>,
    /// Seconds per stop.
    pub step_seconds: f64,
    /// The temperature profile recorded, as `simulate --temperature` takes it (absent
    /// without one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temperature: Option<String>,
}

impl DesignReport {
    /// The design as written.
    pub fn new(design: &Design) -> Self {
        DesignReport {
            faces: design.faces,
            ac_faces: design.ac_faces.clone(),
            cycles: design.cycles,
            closing: design.closing || design.bidirectional,
            bidirectional: design.bidirectional,
            setups: design.setups,
            setup_shift: design.setup_shift_faces,
            shift_deg: design.table_shift_deg.clone(),
            step_seconds: design.step_seconds,
            temperature: design.temperature.as_ref().map(|t| t.to_string()),
        }
    }
}

/// The largest uncertainties of a design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorstReport {
    /// The largest u(β).
    pub pitch_deviation_u: f64,
    /// The largest u(α).
    pub encoder_error_u: f64,
    /// The largest U(β) with a budget.
    #[serde(rename = "pitch_deviation_U", skip_serializing_if = "Option::is_none")]
    pub pitch_deviation_expanded_u: Option<f64>,
    /// The largest U(α) with a budget.
    #[serde(rename = "encoder_error_U", skip_serializing_if = "Option::is_none")]
    pub encoder_error_expanded_u: Option<f64>,
}

/// The fewest cycles that reach a target u(α).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetReport {
    /// The target, arcsec.
    pub encoder_error_u: f64,
    /// The fewest cycles; `null` when not reached within the most tried.
    pub cycles: Option<u32>,
    /// The largest u(α) with them.
    pub reached_u: Option<f64>,
    /// The readings of a run with them; `null` when not reached.
    pub readings: Option<usize>,
    /// From the first stop to the last of a run with them, seconds; `null` when not
    /// reached or without times.
    pub duration_seconds: Option<f64>,
}

/// The JSON object of one design (docs/FORMAT.md §5.6).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanReport {
    /// The design's name or description.
    pub name: String,
    /// The design, when it was given as one (absent for a measurement file's design).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub design: Option<DesignReport>,
    /// The measurement file whose design was planned.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// N.
    pub faces: usize,
    /// Readings of a run.
    pub readings: usize,
    /// From the first stop to the last, seconds; `null` without times.
    pub duration_seconds: Option<f64>,
    /// σ of one reading, arcsec.
    pub sigma: f64,
    /// Residual degrees of freedom of a run; `null` when the design cannot calibrate.
    pub dof: Option<usize>,
    /// The false-alarm probability of each family of candidates of the diagnosis whose
    /// power `detectable` predicts.
    pub false_alarm_per_family: f64,
    /// Harmonics the design loses (empty when none).
    pub lost_harmonics: Vec<usize>,
    /// Why the design cannot determine everything, when it cannot.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unobservable: Option<String>,
    /// u(β), k = 1; `null` when the design cannot determine them.
    pub pitch_deviation_u: Option<Vec<f64>>,
    /// u(φ), k = 1.
    pub face_deviation_u: Option<Vec<f64>>,
    /// u(α), k = 1.
    pub encoder_error_u: Option<Vec<f64>>,
    /// The table angle of each u(α), degrees.
    pub encoder_angle_deg: Option<Vec<f64>>,
    /// u (and with a budget U, k) of each setup error (`value` is 0: no readings).
    pub setup_error: Vec<SetupErrorReport>,
    /// Coverage probability with a budget.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p: Option<f64>,
    /// U(β) with a budget.
    #[serde(rename = "pitch_deviation_U", skip_serializing_if = "Option::is_none")]
    pub pitch_deviation_expanded_u: Option<Vec<f64>>,
    /// k of each U(β).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pitch_deviation_k: Option<Vec<Option<f64>>>,
    /// U(φ) with a budget.
    #[serde(rename = "face_deviation_U", skip_serializing_if = "Option::is_none")]
    pub face_deviation_expanded_u: Option<Vec<f64>>,
    /// k of each U(φ).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub face_deviation_k: Option<Vec<Option<f64>>>,
    /// U(α) with a budget.
    #[serde(rename = "encoder_error_U", skip_serializing_if = "Option::is_none")]
    pub encoder_error_expanded_u: Option<Vec<f64>>,
    /// k of each U(α).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub encoder_error_k: Option<Vec<Option<f64>>>,
    /// The whole budget evaluation, as `solve --budget` prints it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<CalibrationUncertainty>,
    /// The largest uncertainties; `null` when the design cannot determine them.
    pub worst: Option<WorstReport>,
    /// What a diagnosis can see, one object per effect term.
    pub detectable: Vec<Detectable>,
    /// Pairs of explanations the design cannot tell apart.
    pub cannot_tell_apart: Vec<Ambiguity>,
    /// With a target u(α).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub target: Option<TargetReport>,
    /// Plain statements for people.
    pub notes: Vec<String>,
}

impl PlanReport {
    /// The report of a plan; `design` when it was given as a design, `file` when it is a
    /// measurement file's.
    pub fn new(plan: &Plan, design: Option<&Design>, file: Option<String>) -> Self {
        let mut report = PlanReport {
            name: plan.name.clone(),
            design: design.map(DesignReport::new),
            file,
            faces: plan.faces,
            readings: plan.readings,
            duration_seconds: plan.duration_seconds,
            sigma: plan.sigma,
            dof: plan.prediction.as_ref().map(|_| plan.dof),
            false_alarm_per_family: plan.false_alarm_per_family,
            lost_harmonics: plan.lost_harmonics.clone(),
            unobservable: plan.unobservable.clone(),
            pitch_deviation_u: None,
            face_deviation_u: None,
            encoder_error_u: None,
            encoder_angle_deg: None,
            setup_error: Vec::new(),
            p: None,
            pitch_deviation_expanded_u: None,
            pitch_deviation_k: None,
            face_deviation_expanded_u: None,
            face_deviation_k: None,
            encoder_error_expanded_u: None,
            encoder_error_k: None,
            uncertainty: None,
            worst: None,
            detectable: plan.detectable.clone(),
            cannot_tell_apart: plan.cannot_tell_apart.clone(),
            target: plan.target.as_ref().map(|t| TargetReport {
                encoder_error_u: t.encoder_error_u,
                cycles: t.cycles,
                reached_u: t.reached_u,
                readings: t.readings,
                duration_seconds: t.duration_seconds,
            }),
            notes: plan.notes.clone(),
        };
        if let Some(p) = &plan.prediction {
            // solve's report of the same solution: the same numbers, the same way
            let mut solved = SolveReport::new(&p.solution, None);
            if let Some(u) = &p.uncertainty {
                solved = solved.with_uncertainty(u);
            }
            report.pitch_deviation_u = Some(p.pitch_deviation_u.clone());
            report.face_deviation_u = Some(p.face_deviation_u.clone());
            report.encoder_error_u = Some(p.encoder_error_u.clone());
            report.encoder_angle_deg = Some(p.encoder_angle_deg.clone());
            report.setup_error = solved
                .setup_error
                .into_iter()
                .map(|mut s| {
                    s.value = 0.0;
                    s
                })
                .collect();
            report.p = solved.p;
            report.pitch_deviation_expanded_u = solved.pitch_deviation_expanded_u;
            report.pitch_deviation_k = solved.pitch_deviation_k;
            report.face_deviation_expanded_u = solved.face_deviation_expanded_u;
            report.face_deviation_k = solved.face_deviation_k;
            report.encoder_error_expanded_u = solved.encoder_error_expanded_u;
            report.encoder_error_k = solved.encoder_error_k;
            report.uncertainty = solved.uncertainty;
            report.worst = Some(WorstReport {
                pitch_deviation_u: p.worst_pitch_deviation_u(),
                encoder_error_u: p.worst_encoder_error_u(),
                pitch_deviation_expanded_u: p.worst_pitch_deviation_expanded_u(),
                encoder_error_expanded_u: p.worst_encoder_error_expanded_u(),
            });
        }
        report
    }

    /// One line of JSON, with the software version ([`crate::output::to_json`]).
    ///
    /// # Errors
    ///
    /// serde_json's error (not expected for this plain data).
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        crate::output::to_json(self)
    }

    /// The smallest 90 % size over the terms of `kind` (a drift: of order 1).
    fn smallest(&self, kind: &str) -> Option<f64> {
        self.detectable
            .iter()
            .filter(|d| d.kind == kind && d.order.is_none_or(|o| o == 1))
            .filter_map(|d| d.size)
            .reduce(f64::min)
    }
}

fn num(value: Option<f64>, digits: usize) -> String {
    value.map_or("—".into(), |v| {
        if v != 0.0 && v.abs() < 0.5 * 10f64.powi(-(digits as i32)) {
            // a size too small for the fixed digits (a drift per stop, say)
            format!("{v:.2e}")
        } else {
            format!("{v:.digits$}")
        }
    })
}

/// A probability as a percentage, to the digits it has (0.005 → "0.5 %").
fn percent(p: f64) -> String {
    format!("{} %", (p * 100.0 * 1e9).round() / 1e9)
}

fn hours(seconds: Option<f64>) -> String {
    seconds.map_or("—".into(), |s| format!("{:.2} h", s / 3600.0))
}

/// The table of one design: summary, u per face and per position (U with a budget),
/// setup errors, what a diagnosis can see, what it cannot tell apart, notes.
pub fn write_plan_table<W: Write>(out: &mut W, report: &PlanReport) -> fmt::Result {
    writeln!(out, "polycal plan: {}", report.name)?;
    writeln!(
        out,
        "{} faces, {} readings, {} of measuring, σ = {}″, dof {}",
        report.faces,
        report.readings,
        hours(report.duration_seconds),
        report.sigma,
        report.dof.map_or("—".into(), |d| d.to_string())
    )?;
    writeln!(
        out,
        "(time: first stop to last; dof: residual degrees of freedom of a run, readings less parameters)"
    )?;
    if !report.lost_harmonics.is_empty() {
        let list: Vec<String> = report.lost_harmonics.iter().map(usize::to_string).collect();
        writeln!(
            out,
            "LOST harmonics {}: the design cannot calibrate",
            list.join(", ")
        )?;
    } else if report.unobservable.is_some() {
        writeln!(out, "the design cannot calibrate")?;
    }
    if let (Some(u_beta), Some(u_phi)) = (&report.pitch_deviation_u, &report.face_deviation_u) {
        writeln!(out)?;
        writeln!(out, "predicted standard uncertainties (k = 1), arcsec")?;
        let budget = report.pitch_deviation_expanded_u.is_some();
        if budget {
            writeln!(
                out,
                "{:>5} {:>9} {:>9} {:>6} {:>9}",
                "face", "u(β)", "U(β)", "k", "u(φ)"
            )?;
        } else {
            writeln!(out, "{:>5} {:>9} {:>9}", "face", "u(β)", "u(φ)")?;
        }
        for (f, (ub, uf)) in u_beta.iter().zip(u_phi).enumerate() {
            if budget {
                let big = report
                    .pitch_deviation_expanded_u
                    .as_ref()
                    .and_then(|v| v.get(f).copied());
                let k = report
                    .pitch_deviation_k
                    .as_ref()
                    .and_then(|v| v.get(f).copied().flatten());
                writeln!(
                    out,
                    "{:>5} {:>9.4} {:>9} {:>6} {:>9.4}",
                    f + 1,
                    ub,
                    num(big, 4),
                    num(k, 2),
                    uf
                )?;
            } else {
                writeln!(out, "{:>5} {:>9.4} {:>9.4}", f + 1, ub, uf)?;
            }
        }
    }
    if let (Some(u_alpha), Some(angles)) = (&report.encoder_error_u, &report.encoder_angle_deg) {
        writeln!(out)?;
        let budget = report.encoder_error_expanded_u.is_some();
        if budget {
            writeln!(
                out,
                "{:>10} {:>9} {:>9} {:>6}",
                "angle/°", "u(α)", "U(α)", "k"
            )?;
        } else {
            writeln!(out, "{:>10} {:>9}", "angle/°", "u(α)")?;
        }
        for (j, (ua, angle)) in u_alpha.iter().zip(angles).enumerate() {
            if budget {
                let big = report
                    .encoder_error_expanded_u
                    .as_ref()
                    .and_then(|v| v.get(j).copied());
                let k = report
                    .encoder_error_k
                    .as_ref()
                    .and_then(|v| v.get(j).copied().flatten());
                writeln!(
                    out,
                    "{:>10.4} {:>9.4} {:>9} {:>6}",
                    angle,
                    ua,
                    num(big, 4),
                    num(k, 2)
                )?;
            } else {
                writeln!(out, "{angle:>10.4} {ua:>9.4}")?;
            }
        }
    }
    if !report.setup_error.is_empty() {
        writeln!(out)?;
        writeln!(out, "{:>5} {:>3} {:>9}", "setup", "ac", "u(U)")?;
        for s in &report.setup_error {
            writeln!(out, "{:>5} {:>3} {:>9}", s.setup, s.ac, num(s.u, 4))?;
        }
    }
    if !report.detectable.is_empty() {
        writeln!(out)?;
        writeln!(
            out,
            "what a diagnosis can see: the smallest size it finds in 90 % of runs of the design"
        )?;
        writeln!(
            out,
            "(size in its unit, \"not seen\" when the design cannot tell the term from the base model;"
        )?;
        writeln!(
            out,
            " df: the degrees of freedom of the term's F test; false alarms: {} per family of candidates",
            percent(report.false_alarm_per_family)
        )?;
        writeln!(
            out,
            " — systematic terms, offset steps, outliers —, shared by its candidates (Bonferroni), as diagnose tests them)"
        )?;
        writeln!(
            out,
            "{:<16} {:>3} {:>5} {:>12} {:<14} {:>4} where",
            "effect", "ac", "setup", "size", "unit", "df"
        )?;
        for d in &report.detectable {
            write_detectable(out, d)?;
        }
    }
    for a in &report.cannot_tell_apart {
        writeln!(
            out,
            "CANNOT TELL {} from {} (correlation {:.3} of their columns off the model)",
            explanation(a.first.kind, a.first.ac, a.first.setup),
            explanation(a.second.kind, a.second.ac, a.second.setup),
            a.correlation
        )?;
    }
    if let Some(t) = &report.target {
        writeln!(out)?;
        match t.cycles {
            Some(c) => writeln!(
                out,
                "target u(α) ≤ {}″: {c} cycle{} per mounting (largest u(α) {}), {} readings, {} of measuring",
                t.encoder_error_u,
                if c == 1 { "" } else { "s" },
                num(t.reached_u, 4),
                t.readings.map_or("—".into(), |n| n.to_string()),
                hours(t.duration_seconds)
            )?,
            None => writeln!(
                out,
                "target u(α) ≤ {}″: not reached with up to {} cycles",
                t.encoder_error_u,
                crate::plan::MAX_TARGET_CYCLES
            )?,
        }
    }
    for note in &report.notes {
        writeln!(out)?;
        writeln!(out, "note: {note}")?;
    }
    Ok(())
}

fn explanation(kind: &str, ac: Option<u32>, setup: Option<u32>) -> String {
    let who = match ac {
        Some(ac) => format!(" of autocollimator {ac}"),
        None => " of all autocollimators".into(),
    };
    let mounting = setup.map_or(String::new(), |s| format!(" in mounting {s}"));
    format!("the {kind}{who}{mounting}")
}

fn write_detectable<W: Write>(out: &mut W, d: &Detectable) -> fmt::Result {
    let place = match (d.cycle, d.step) {
        (Some(c), Some(s)) => format!(
            "best at cycle {c} step {s}; median over stops {}",
            num(d.median_size, 4)
        ),
        (Some(c), None) => format!(
            "best from cycle {c} on; median over stops {}",
            num(d.median_size, 4)
        ),
        _ => String::new(),
    };
    writeln!(
        out,
        "{:<16} {:>3} {:>5} {:>12} {:<14} {:>4} {}",
        if d.order == Some(2) {
            "drift curvature"
        } else {
            d.kind
        },
        d.ac.map_or("all".into(), |a| a.to_string()),
        d.setup.map_or("".into(), |s| s.to_string()),
        if d.identifiable {
            num(d.size, 4)
        } else {
            "not seen".into()
        },
        d.unit,
        d.df,
        place
    )
}

/// The header of the comparison's target columns.
const TARGET_CYCLES: &str = "target cycles";
/// The header of the time the target's cycles take.
const TARGET_TIME: &str = "target time";

/// The table comparing designs side by side: the cycles planned with their readings and
/// time, worst u(β), worst u(α), U with the budget, the smallest detectable drift and
/// offset step, and with a target the cycles it needs and the time they take; a legend
/// line below for every column.
pub fn write_comparison_table<W: Write>(out: &mut W, reports: &[PlanReport]) -> fmt::Result {
    let budget = reports.iter().any(|r| r.encoder_error_expanded_u.is_some());
    let target = reports
        .iter()
        .find_map(|r| r.target.as_ref().map(|t| t.encoder_error_u));
    writeln!(out, "polycal plan: {} designs", reports.len())?;
    let width = reports
        .iter()
        .map(|r| r.name.chars().count())
        .max()
        .unwrap_or(6)
        .clamp(6, 40);
    write!(
        out,
        "{:<width$} {:>6} {:>8} {:>8} {:>9} {:>9}",
        "design", "cycles", "readings", "time", "u(β)max", "u(α)max"
    )?;
    if budget {
        write!(out, " {:>9}", "U(α)max")?;
    }
    write!(out, " {:>10} {:>8}", "drift″/h", "step″")?;
    if target.is_some() {
        write!(out, " {TARGET_CYCLES:>13} {TARGET_TIME:>11}")?;
    }
    writeln!(out)?;
    for r in reports {
        let name: String = r.name.chars().take(width).collect();
        let worst = r.worst.as_ref();
        write!(
            out,
            "{:<width$} {:>6} {:>8} {:>8} {:>9} {:>9}",
            name,
            r.design
                .as_ref()
                .map_or("—".into(), |d| d.cycles.to_string()),
            r.readings,
            hours(r.duration_seconds),
            num(worst.map(|w| w.pitch_deviation_u), 4),
            num(worst.map(|w| w.encoder_error_u), 4)
        )?;
        if budget {
            write!(
                out,
                " {:>9}",
                num(worst.and_then(|w| w.encoder_error_expanded_u), 4)
            )?;
        }
        write!(
            out,
            " {:>10} {:>8}",
            num(r.smallest("drift"), 4),
            num(r.smallest("offset-step"), 4)
        )?;
        if target.is_some() {
            let t = r.target.as_ref();
            write!(
                out,
                " {:>13} {:>11}",
                t.and_then(|t| t.cycles)
                    .map_or("—".into(), |c| c.to_string()),
                hours(t.and_then(|t| t.duration_seconds))
            )?;
        }
        if !r.lost_harmonics.is_empty() {
            let list: Vec<String> = r.lost_harmonics.iter().map(usize::to_string).collect();
            write!(out, "  LOST harmonics {}", list.join(", "))?;
        }
        writeln!(out)?;
    }
    writeln!(
        out,
        "cycles: planned per mounting; readings and time (first stop to last): those of the planned cycles"
    )?;
    writeln!(
        out,
        "u(β)max, u(α)max: the largest u (k = 1) of a pitch deviation and of an encoder error, arcsec"
    )?;
    if budget {
        writeln!(
            out,
            "U(α)max: the largest expanded uncertainty of an encoder error with the budget"
        )?;
    }
    let alarms = reports
        .first()
        .map_or("—".into(), |r| percent(r.false_alarm_per_family));
    writeln!(
        out,
        "drift″/h: the smallest autocollimator drift a diagnosis finds in 90 % of runs"
    )?;
    writeln!(
        out,
        "step″: the smallest offset step (a jump of an autocollimator's zero) it finds in 90 % of runs"
    )?;
    writeln!(
        out,
        "(each with {alarms} false alarms per family of candidates, as diagnose tests them)"
    )?;
    if let Some(a) = target {
        writeln!(
            out,
            "{TARGET_CYCLES}: the fewest cycles per mounting that bring u(α)max to {a}″ or below"
        )?;
        writeln!(
            out,
            "{TARGET_TIME}: how long a run of the target cycles takes (first stop to last)"
        )?;
    }
    Ok(())
}
