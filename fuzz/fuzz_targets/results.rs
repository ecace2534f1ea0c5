//! The result CSV (docs/FORMAT.md §3): read, then compared with itself, with the
//! comparison's table, JSON and figures.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::compare::{CompareOptions, compare_files};
use polycal::results::read_results_from;
use polycal_fuzz::{SOURCE, accepted};

fuzz_target!(|data: &[u8]| {
    let Some(file) = accepted(read_results_from(data, SOURCE), SOURCE, data) else {
        return;
    };
    let options = CompareOptions::new().with_include_setup(true);
    if let Ok(comparison) = compare_files(&file, &file, &options) {
        let mut table = String::new();
        let _ = polycal::output::compare::write_table(&mut table, &comparison);
        let _ = polycal::output::to_json(&comparison);
        let _ = polycal::figure::compare_figures(&comparison);
    }
});
