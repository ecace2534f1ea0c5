//! The measurement CSV (docs/FORMAT.md §2): read, then solved (and diagnosed when
//! small), with the reports and figures of `solve` and `diagnose`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::diagnose::{DiagnoseOptions, diagnose};
use polycal::figure::{diagnose_figures, solve_figures};
use polycal::measurement::{MeasurementSet, read_rows};
use polycal::output::SolveReport;
use polycal::output::diagnose::DiagnoseReport;
use polycal::solve::sub_pitch::solve_shifted;
use polycal::solve::{SolveError, SolveOptions, solve};
use polycal_fuzz::{SOURCE, accepted};

fuzz_target!(|data: &[u8]| {
    let _ = accepted(read_rows(data, SOURCE), SOURCE, data);
    let Some(set) = accepted(MeasurementSet::read_from(data, SOURCE, None), SOURCE, data) else {
        return;
    };
    let options = SolveOptions::default();
    match solve(&set, &options) {
        Ok(solution) => {
            let mut table = String::new();
            let _ = polycal::output::write_table(&mut table, &solution, SOURCE, None, None);
            let report = SolveReport::new(&solution, None);
            let _ = report.to_json();
            let _ = solve_figures(&report);
        }
        Err(SolveError::SubPitch { .. }) => {
            if let Ok(solved) = solve_shifted(&set, &options) {
                let _ = solve_figures(&SolveReport::sub_pitch(&solved, None));
            }
        }
        Err(_) => {}
    }
    if set.readings.len() <= 400
        && !set.has_shifts()
        && let Ok(diagnosis) = diagnose(&set, &DiagnoseOptions::new())
    {
        let report = DiagnoseReport::new(&diagnosis, None, None).with_residuals(&diagnosis, &set);
        let _ = report.to_json();
        let _ = diagnose_figures(&report);
    }
});
