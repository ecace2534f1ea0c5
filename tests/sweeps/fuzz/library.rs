//! The library-level checks of one mutated file: read it, and push what was read
//! through the computation it feeds. Each returns the first [`Finding`].

use std::path::Path;
use std::sync::OnceLock;

use polycal::certificate::meta;
use polycal::compare::{CompareOptions, compare_files};
use polycal::diagnose::{DiagnoseOptions, Diagnosis, diagnose};
use polycal::figure;
use polycal::measurement::{MeasurementSet, read_rows};
use polycal::output::diagnose::DiagnoseReport;
use polycal::output::diagnose_table::write_table;
use polycal::output::selfcal::SelfcalReport;
use polycal::output::{self, SolveReport};
use polycal::results::read_results_from;
use polycal::selfcal::{SelfcalOptions, SelfcalSet, SelfcalSolution, evaluate_budget};
use polycal::simulate::{SelfcalTruth, Truth};
use polycal::solve::sub_pitch::solve_shifted;
use polycal::solve::{Solution, SolveError, SolveOptions, solve};
use polycal::uncertainty::calibration::{InstrumentBudget, evaluate};
use polycal::uncertainty::{BudgetFile, budget_table};

use super::harness::{Finding, no_panic, read, scratch};
use super::mutate::Case;

/// The names the readers are given for the input: their errors must contain them.
const CSV: &str = "fuzzed-input.csv";
const TOML: &str = "fuzzed-input.toml";

/// Diagnose (the slowest computation) only sets up to this many readings.
const DIAGNOSE_MAX_READINGS: usize = 800;

/// A file of the repository, read.
fn repo_file(path: &str) -> Vec<u8> {
    let full = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    std::fs::read(&full).unwrap_or_else(|e| panic!("{}: {e}", full.display()))
}

/// A valid measurement set, its solution and its diagnosis.
struct Solved {
    set: MeasurementSet,
    solution: Solution,
    diagnosis: Diagnosis,
}

fn solved(path: &str) -> Solved {
    let set = MeasurementSet::read_from(&repo_file(path)[..], path, None).expect("a valid seed");
    let solution = solve(&set, &SolveOptions::default()).expect("solvable");
    let diagnosis = diagnose(&set, &DiagnoseOptions::new()).expect("diagnosable");
    Solved {
        set,
        solution,
        diagnosis,
    }
}

/// The 24-faced example, solved and diagnosed (once).
fn example24() -> &'static Solved {
    static CELL: OnceLock<Solved> = OnceLock::new();
    CELL.get_or_init(|| solved("examples/data/polygon24-2ac-6cycles.csv"))
}

/// A bare 12-faced cycle, solved and diagnosed (once).
fn bare12() -> &'static Solved {
    static CELL: OnceLock<Solved> = OnceLock::new();
    CELL.get_or_init(|| solved("tests/fixtures/expected/sim-bare.file.bare.csv"))
}

/// A small self-calibration, solved (once).
fn selfcal_solution() -> &'static SelfcalSolution {
    static CELL: OnceLock<SelfcalSolution> = OnceLock::new();
    CELL.get_or_init(|| {
        let path = "tests/fixtures/expected/sim-selfcal.file.selfcal.csv";
        let set = SelfcalSet::read_from(&repo_file(path)[..], path, None).expect("a valid seed");
        polycal::selfcal::solve(&set, &SelfcalOptions::new()).expect("solvable")
    })
}

/// An instrument budget read from the repository.
fn read_instrument_budget(path: &'static str) -> InstrumentBudget {
    let text = String::from_utf8(repo_file(path)).expect("UTF-8");
    InstrumentBudget::from_toml_str(&text, path).expect("a valid budget")
}

fn example_budget() -> &'static InstrumentBudget {
    static CELL: OnceLock<InstrumentBudget> = OnceLock::new();
    CELL.get_or_init(|| read_instrument_budget("examples/budgets/instrument.toml"))
}

fn selfcal_budget() -> &'static InstrumentBudget {
    static CELL: OnceLock<InstrumentBudget> = OnceLock::new();
    CELL.get_or_init(|| read_instrument_budget("examples/budgets/selfcal.toml"))
}

/// Writes the mutated bytes to a scratch file named `name` (for the readers that take
/// a path); returns the path and the name the reader gives it in messages.
fn to_file(target: &str, name: &str, bytes: &[u8]) -> (std::path::PathBuf, String) {
    let path = scratch(target).join(name);
    std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let shown = path.display().to_string();
    (path, shown)
}

/// The measurement CSV: `MeasurementSet::read_from` and `read_rows`; an accepted set is
/// solved (`solve`, or `solve_shifted` for sub-pitch mountings), its instrument budget
/// evaluated and, when small, diagnosed; its comment lines go to the report's metadata.
pub fn measurement(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    read(case, "csv", "measurement::read_rows", CSV, || {
        read_rows(&bytes[..], CSV)
    })?;
    let set = read(case, "csv", "MeasurementSet::read_from", CSV, || {
        MeasurementSet::read_from(&bytes[..], CSV, None)
    })?;
    let Some(set) = set else {
        return Ok(());
    };
    if let Ok(text) = std::str::from_utf8(&bytes) {
        no_panic(case, "csv", "meta::comment_metadata", || {
            meta::comment_metadata(text)
        })?;
    }
    let options = SolveOptions::default();
    match no_panic(case, "csv", "solve", || solve(&set, &options))? {
        Ok(solution) => {
            let gum = no_panic(case, "csv", "calibration::evaluate", || {
                evaluate(&set, &solution, example_budget()).ok()
            })?;
            no_panic(
                case,
                "csv",
                "the solve report (table, JSON, CSV, figures)",
                || {
                    let mut table = String::new();
                    let _ = output::write_table(&mut table, &solution, CSV, gum.as_ref(), None);
                    let mut report = SolveReport::new(&solution, None);
                    if let Some(gum) = &gum {
                        report = report.with_uncertainty(gum);
                        let _ = figure::budget_figures(gum);
                    }
                    let _ = report.to_json();
                    let _ = figure::solve_figures(&report);
                    let rows = output::result_rows_with(&solution, gum.as_ref());
                    let _ = output::write_results_with_file(std::io::sink(), &[(CSV.into(), rows)]);
                },
            )?;
        }
        Err(SolveError::SubPitch { .. }) => {
            if let Ok(solved) = no_panic(case, "csv", "solve_shifted", || {
                solve_shifted(&set, &options)
            })? {
                no_panic(case, "csv", "the sub-pitch solve report", || {
                    let mut table = String::new();
                    let _ = output::write_sub_pitch_table(&mut table, &solved, CSV);
                    let report = SolveReport::sub_pitch(&solved, None);
                    let _ = report.to_json();
                    let _ = figure::solve_figures(&report);
                })?;
            }
        }
        Err(_) => {}
    }
    if set.readings.len() <= DIAGNOSE_MAX_READINGS && !set.has_shifts() {
        let diagnosis = no_panic(case, "csv", "diagnose", || {
            diagnose(&set, &DiagnoseOptions::new())
        })?;
        if let Ok(diagnosis) = diagnosis {
            no_panic(
                case,
                "csv",
                "the diagnose report (table, JSON, figures)",
                || {
                    let mut table = String::new();
                    let _ = write_table(&mut table, &diagnosis, None, CSV);
                    let _ = output::write_final_model_results(
                        &mut table,
                        &diagnosis.after,
                        None,
                        diagnosis.after_sub_pitch.as_ref(),
                        None,
                    );
                    let report = DiagnoseReport::new(&diagnosis, None, None)
                        .with_residuals(&diagnosis, &set);
                    let _ = report.to_json();
                    let _ = figure::diagnose_figures(&report);
                },
            )?;
        }
    }
    Ok(())
}

/// The self-calibration CSV: `SelfcalSet::read_from`; an accepted set is solved (with
/// the default options and with those of the fixture `selfcal-budget`) and its
/// instrument budget evaluated.
pub fn selfcal(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let set = read(case, "csv", "SelfcalSet::read_from", CSV, || {
        SelfcalSet::read_from(&bytes[..], CSV, None)
    })?;
    let Some(set) = set else {
        return Ok(());
    };
    let plain = SelfcalOptions::new();
    if let Ok(solution) = no_panic(case, "csv", "selfcal::solve", || {
        polycal::selfcal::solve(&set, &plain)
    })? {
        let uncertainty = no_panic(case, "csv", "selfcal::evaluate_budget", || {
            evaluate_budget(&solution, selfcal_budget()).ok()
        })?;
        no_panic(
            case,
            "csv",
            "the selfcal report (table, JSON, figures)",
            || {
                let mut table = String::new();
                let _ =
                    output::selfcal::write_table(&mut table, &solution, CSV, uncertainty.as_ref());
                let mut report = SelfcalReport::new(&solution, CSV);
                if let Some(uncertainty) = &uncertainty {
                    report = report.with_uncertainty(uncertainty);
                }
                let _ = report.to_json();
                let _ = figure::selfcal_figures(&report);
            },
        )?;
    }
    no_panic(
        case,
        "csv",
        "selfcal::solve (bound, gauge, head-angle u)",
        || {
            let options = SelfcalOptions::new()
                .with_lost_harmonic_bound(0.01)
                .and_then(|o| o.with_head_angle_u(0.5))
                .map(|o| o.with_gauge_positions(24))
                .expect("valid options");
            polycal::selfcal::solve(&set, &options).is_ok()
        },
    )?;
    Ok(())
}

/// The result CSV: `read_results_from`; an accepted file is compared with its seed and
/// with itself (setup errors included), and the comparison's table written.
pub fn results(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let file = read(case, "csv", "read_results_from", CSV, || {
        read_results_from(&bytes[..], CSV)
    })?;
    let Some(file) = file else {
        return Ok(());
    };
    let seed = read_results_from(&case.seed.bytes[..], case.seed.path).expect("a valid seed");
    let options = CompareOptions::new().with_include_setup(true);
    for (a, b, what) in [
        (&file, &seed, "compare_files(mutated, seed) and its report"),
        (&seed, &file, "compare_files(seed, mutated) and its report"),
        (
            &file,
            &file,
            "compare_files(mutated, mutated) and its report",
        ),
    ] {
        no_panic(case, "csv", what, || {
            if let Ok(comparison) = compare_files(a, b, &options) {
                let mut table = String::new();
                let _ = output::compare::write_table(&mut table, &comparison);
                let _ = output::to_json(&comparison);
                let _ = figure::compare_figures(&comparison);
            }
        })?;
    }
    Ok(())
}

/// The text of a budget-like file: from the bytes when they are UTF-8 (the reader is
/// then given [`TOML`] as the name), else `None` (read from a scratch file by path).
fn utf8(bytes: &[u8]) -> Option<&str> {
    std::str::from_utf8(bytes).ok()
}

/// The budget TOML of `polycal budget`: `BudgetFile::from_toml_str` (or `read_path` for
/// bytes that are not UTF-8); an accepted budget is evaluated and its table written.
pub fn budget(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let file = match utf8(&bytes) {
        Some(text) => read(case, "toml", "BudgetFile::from_toml_str", TOML, || {
            BudgetFile::from_toml_str(text, TOML)
        })?,
        None => {
            let (path, shown) = to_file("budget", TOML, &bytes);
            read(case, "toml", "BudgetFile::read_path", &shown, || {
                BudgetFile::read_path(&path)
            })?
        }
    };
    let Some(file) = file else {
        return Ok(());
    };
    no_panic(case, "toml", "BudgetFile::evaluate", || {
        if let Ok(result) = file.evaluate() {
            let _ = budget_table(&result).to_string();
        }
    })?;
    Ok(())
}

/// The designs TOML of `plan --designs`: `Design::parse_designs_file` (or
/// `read_designs_file` for bytes that are not UTF-8); every accepted design of at most
/// [`DIAGNOSE_MAX_READINGS`] readings is planned (its uncertainties; what a diagnosis
/// can see takes half a second a design, and `tests/sweeps/plan.rs` runs it).
pub fn designs(case: &Case) -> Result<(), Box<Finding>> {
    use polycal::measurement::Sigma;
    use polycal::plan::{Design, PlanOptions, plan};
    let bytes = case.bytes();
    let base = Design::default();
    let designs = match utf8(&bytes) {
        Some(text) => read(case, "toml", "Design::parse_designs_file", TOML, || {
            Design::parse_designs_file(text, TOML, &base)
        })?,
        None => {
            let (path, shown) = to_file("designs", TOML, &bytes);
            read(case, "toml", "Design::read_designs_file", &shown, || {
                Design::read_designs_file(&path, &base)
            })?
        }
    };
    let Some(designs) = designs else {
        return Ok(());
    };
    let sigma = Sigma::new(0.05).expect("a valid σ");
    for design in &designs {
        if design.reading_count() > DIAGNOSE_MAX_READINGS {
            continue;
        }
        let options = PlanOptions::new(sigma)
            .with_detect(false)
            .with_memory_limit(1 << 30);
        no_panic(case, "toml", "plan::plan", || {
            let _ = plan(design, &options);
        })?;
    }
    Ok(())
}

/// The instrument budget of `solve --budget` and `selfcal --budget`:
/// `InstrumentBudget::from_toml_str` (or `read_path`); an accepted budget is evaluated
/// through the 24-faced example's design and through a self-calibration's.
pub fn instrument_budget(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let budget = match utf8(&bytes) {
        Some(text) => read(
            case,
            "toml",
            "InstrumentBudget::from_toml_str",
            TOML,
            || InstrumentBudget::from_toml_str(text, TOML),
        )?,
        None => {
            let (path, shown) = to_file("instrument-budget", TOML, &bytes);
            read(case, "toml", "InstrumentBudget::read_path", &shown, || {
                InstrumentBudget::read_path(&path)
            })?
        }
    };
    let Some(budget) = budget else {
        return Ok(());
    };
    let example = example24();
    no_panic(case, "toml", "calibration::evaluate and its report", || {
        if let Ok(gum) = evaluate(&example.set, &example.solution, &budget) {
            let mut table = String::new();
            let _ = output::write_results(&mut table, &example.solution, Some(&gum));
            let report = SolveReport::new(&example.solution, None).with_uncertainty(&gum);
            let _ = report.to_json();
            let _ = figure::budget_figures(&gum);
        }
    })?;
    no_panic(case, "toml", "selfcal::evaluate_budget", || {
        evaluate_budget(selfcal_solution(), &budget).is_ok()
    })?;
    Ok(())
}

/// The truth JSON of `diagnose --truth`: `Truth::read_path`; an accepted truth is
/// compared with the diagnosis of a set with its number of faces (as `diagnose --truth`
/// does: JSON and table) and asked for its values at every face and several angles.
pub fn truth(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let (path, shown) = to_file("truth", "fuzzed-truth.json", &bytes);
    let truth = read(case, "json", "Truth::read_path", &shown, || {
        Truth::read_path(&path)
    })?;
    let Some(truth) = truth else {
        return Ok(());
    };
    no_panic(case, "json", "Truth's values", || {
        // Faces 0 and N + 1 are documented as NaN.
        for face in 0..=truth.faces.saturating_add(1).min(1000) {
            let _ = truth.face_deviation_at(face);
        }
        for angle in [0.0, 7.5, 15.0, 180.0, 359.999_999_9, 360.0, -15.0] {
            let _ = truth.encoder_error_at_deg(angle);
        }
        let _ = truth.to_json_pretty();
    })?;
    for solved in [example24(), bare12()] {
        if solved.set.faces != truth.faces {
            continue;
        }
        no_panic(case, "json", "DiagnoseReport with a truth", || {
            let report = DiagnoseReport::new(&solved.diagnosis, Some(&truth), None);
            let _ = report.to_json();
            let mut table = String::new();
            let _ = write_table(&mut table, &solved.diagnosis, Some(&truth), "set");
        })?;
        no_panic(case, "json", "Truth::model_reading", || {
            for reading in &solved.set.readings {
                let _ = truth.model_reading(reading);
            }
        })?;
    }
    Ok(())
}

/// The self-calibration truth JSON: `SelfcalTruth::read_path`; an accepted truth is
/// asked for its values.
pub fn selfcal_truth(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let (path, shown) = to_file("selfcal-truth", "fuzzed-truth.json", &bytes);
    let truth = read(case, "json", "SelfcalTruth::read_path", &shown, || {
        SelfcalTruth::read_path(&path)
    })?;
    let Some(truth) = truth else {
        return Ok(());
    };
    no_panic(case, "json", "SelfcalTruth's values", || {
        for angle in [0.0, 2.5, 90.0, 359.999_999_9, 360.0, -1.0] {
            let _ = truth.encoder_error_at_deg(angle);
        }
        for head in 0..=13 {
            let _ = truth.head_error_of(head);
        }
        for (cycle, step) in [(0, 0), (1, 0), (1, 11), (2, 167), (9, 1000)] {
            let _ = truth.table_error_at(cycle, step);
        }
        let _ = truth.to_json_pretty();
    })?;
    Ok(())
}

/// The report's metadata TOML: `meta::gather` with the 24-faced example as the
/// measurement file (bytes that are not UTF-8 only reach it at the binary level).
pub fn meta(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let Some(text) = utf8(&bytes) else {
        return Ok(());
    };
    let measurement = repo_file("examples/data/polygon24-2ac-6cycles.csv");
    let measurement = String::from_utf8(measurement).expect("UTF-8");
    let metadata = read(case, "toml", "meta::gather", TOML, || {
        // The message only (the error type is large).
        meta::gather(Some((text, TOML)), (&measurement, "measurement.csv"), None)
            .map_err(|e| e.to_string())
    })?;
    if let Some(metadata) = metadata {
        no_panic(case, "toml", "Metadata::value", || {
            for field in &metadata.fields {
                let _ = metadata.value(field.key);
            }
        })?;
        // the documents a lab hands over, with this metadata: the HTML report and the
        // DCC, which is well-formed XML or refused with a message
        let mut report = report24().clone();
        report.metadata = metadata;
        no_panic(case, "toml", "CalibrationReport::to_html", || {
            let _ = report.to_html();
        })?;
        let dcc = no_panic(case, "toml", "CalibrationReport::to_dcc", || {
            report.to_dcc()
        })?;
        if let Ok(xml) = dcc
            && let Err(e) = roxmltree::Document::parse(&xml)
        {
            return Err(Finding::of(
                case,
                "toml",
                "a DCC that is not well-formed XML",
                e.to_string(),
            ));
        }
    }
    Ok(())
}

/// The 24-faced example's report with the instrument budget (once): the documents the
/// fuzzed metadata goes into.
fn report24() -> &'static polycal::certificate::CalibrationReport {
    use polycal::certificate::{CalibrationReport, ReportInputs};
    static CELL: OnceLock<CalibrationReport> = OnceLock::new();
    CELL.get_or_init(|| {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let inputs = ReportInputs::new(root.join("examples/data/polygon24-2ac-6cycles.csv"))
            .with_budget(root.join("examples/budgets/instrument.toml"))
            .with_generated_utc("2026-11-26T12:00:00.000Z");
        CalibrationReport::build(&inputs).expect("the example's report")
    })
}
