//! A case's evaluation through the library function its command calls, giving the
//! command's JSON (docs/FORMAT.md §13.1).

use serde::Serialize;
use serde_json::Value;

use super::case::{Case, Evaluation};
use crate::compare::{CompareOptions, compare_files};
use crate::diagnose::DiagnoseOptions;
use crate::kc::{KcOptions, LabResult};
use crate::measurement::{MeasurementSet, Sigma};
use crate::output::SolveReport;
use crate::output::diagnose::DiagnoseReport;
use crate::output::selfcal::SelfcalReport;
use crate::results::read_results_from;
use crate::selfcal::{SelfcalOptions, SelfcalSet};
use crate::solve::sub_pitch::{ShiftGeometry, solve_shifted};
use crate::solve::{SolveOptions, solve};
use crate::uncertainty::BudgetFile;
use crate::uncertainty::calibration::{self, InstrumentBudget, McOptions};
use crate::uncertainty::monte_carlo::Trials;

/// The JSON the case's command prints; `Err` says why the evaluation refused (the case
/// then fails with that problem).
pub(super) fn evaluate(case: &Case) -> Result<Value, String> {
    let spec = &case.spec;
    let input = |i: usize| {
        let name = spec.inputs.get(i).map_or("", String::as_str);
        (case.bytes(name), case.source.shown(name))
    };
    let sigma = spec
        .sigma
        .map(Sigma::new)
        .transpose()
        .map_err(|e| format!("sigma: {e}"))?;
    match spec.evaluation {
        Evaluation::Solve => {
            let (bytes, name) = input(0);
            let set = MeasurementSet::read_from(bytes, &name, None).map_err(text)?;
            let options = SolveOptions::new().with_sigma_opt(sigma);
            if set.has_shifts() && ShiftGeometry::of(&set).is_sub_pitch() {
                let solved = solve_shifted(&set, &options).map_err(text)?;
                return json(&SolveReport::sub_pitch(&solved, None));
            }
            json(&SolveReport::new(
                &solve(&set, &options).map_err(text)?,
                None,
            ))
        }
        Evaluation::MonteCarlo => {
            let (bytes, name) = input(0);
            let set = MeasurementSet::read_from(bytes, &name, None).map_err(text)?;
            let solution = solve(&set, &SolveOptions::new().with_sigma_opt(sigma)).map_err(text)?;
            let budget_name = spec.budget.as_deref().ok_or("no budget named")?;
            let budget_text = std::str::from_utf8(case.bytes(budget_name)).map_err(text)?;
            let budget =
                InstrumentBudget::from_toml_str(budget_text, &case.source.shown(budget_name))
                    .map_err(text)?;
            let gum = calibration::evaluate(&set, &solution, &budget).map_err(text)?;
            let trials = spec.trials.ok_or("no trials named")?;
            let options = McOptions::new(Trials::Fixed(trials)).with_seed(spec.seed.unwrap_or(1));
            let mc =
                calibration::monte_carlo(&set, &solution, &budget, &gum, &options).map_err(text)?;
            json(
                &SolveReport::new(&solution, None)
                    .with_uncertainty(&gum)
                    .with_monte_carlo(mc),
            )
        }
        Evaluation::Budget => {
            let (bytes, name) = input(0);
            let text_in = std::str::from_utf8(bytes).map_err(text)?;
            let budget = BudgetFile::from_toml_str(text_in, &name).map_err(text)?;
            json(&budget.evaluate().map_err(text)?)
        }
        Evaluation::Selfcal => {
            let (bytes, name) = input(0);
            let set = SelfcalSet::read_from(bytes, &name, None).map_err(text)?;
            let options = SelfcalOptions::new().with_sigma_opt(sigma);
            let solution = crate::selfcal::solve(&set, &options).map_err(text)?;
            json(&SelfcalReport::new(&solution, &name))
        }
        Evaluation::Diagnose => {
            let (bytes, name) = input(0);
            let set = MeasurementSet::read_from(bytes, &name, None).map_err(text)?;
            let options = DiagnoseOptions::new().with_sigma_opt(sigma);
            let diagnosis = crate::diagnose::diagnose(&set, &options).map_err(text)?;
            json(&DiagnoseReport::new(&diagnosis, None, None))
        }
        Evaluation::Compare => {
            let (a, name_a) = input(0);
            let (b, name_b) = input(1);
            let a = read_results_from(a, &name_a).map_err(text)?;
            let b = read_results_from(b, &name_b).map_err(text)?;
            json(&compare_files(&a, &b, &CompareOptions::new()).map_err(text)?)
        }
        Evaluation::Kc => {
            let names = spec.labs.as_deref().unwrap_or_default();
            if names.len() != spec.inputs.len() {
                return Err("labs: one name per input".into());
            }
            let mut labs = Vec::new();
            for (i, lab) in names.iter().enumerate() {
                let (bytes, name) = input(i);
                let file = read_results_from(bytes, &name).map_err(text)?;
                labs.push(LabResult::from_file(lab.clone(), file));
            }
            let kc = crate::kc::evaluate(&labs, &[], &KcOptions::new()).map_err(text)?;
            json(&kc)
        }
    }
}

/// An error's message.
fn text(error: impl std::fmt::Display) -> String {
    error.to_string()
}

/// A report as its command's JSON (`output::to_json`, read back).
fn json<T: Serialize>(report: &T) -> Result<Value, String> {
    let written = crate::output::to_json(report).map_err(text)?;
    serde_json::from_str(&written).map_err(text)
}
