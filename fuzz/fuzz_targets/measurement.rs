//! The measurement CSV (docs/FORMAT.md §2): read, then solved (and diagnosed when small).
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::diagnose::{DiagnoseOptions, diagnose};
use polycal::measurement::{MeasurementSet, read_rows};
use polycal::solve::sub_pitch::solve_shifted;
use polycal::solve::{SolveError, SolveOptions, solve};
use polycal_fuzz::{SOURCE, accepted};

fuzz_target!(|data: &[u8]| {
    let _ = accepted(read_rows(data, SOURCE), SOURCE);
    let Some(set) = accepted(MeasurementSet::read_from(data, SOURCE, None), SOURCE) else {
        return;
    };
    let options = SolveOptions::default();
    if let Err(SolveError::SubPitch { .. }) = solve(&set, &options) {
        let _ = solve_shifted(&set, &options);
    }
    if set.readings.len() <= 400 && !set.has_shifts() {
        let _ = diagnose(&set, &DiagnoseOptions::new());
    }
});
