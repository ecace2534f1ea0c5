//! The instrument budget of `solve --budget` (docs/FORMAT.md §5.1): read, then evaluated
//! through a simulated 12-faced design.
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use polycal::measurement::MeasurementSet;
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::{Solution, SolveOptions, solve};
use polycal::uncertainty::calibration::{InstrumentBudget, evaluate};
use polycal_fuzz::{SOURCE, accepted};

fn design() -> &'static (MeasurementSet, Solution) {
    static CELL: OnceLock<(MeasurementSet, Solution)> = OnceLock::new();
    CELL.get_or_init(|| {
        let config = SimulationConfig {
            faces: 12,
            cycles: 2,
            ..SimulationConfig::default()
        };
        let (set, _) = simulate(&config).expect("a valid simulation");
        let solution = solve(&set, &SolveOptions::default()).expect("solvable");
        (set, solution)
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Some(budget) = accepted(InstrumentBudget::from_toml_str(text, SOURCE), SOURCE, data) else {
        return;
    };
    let (set, solution) = design();
    let _ = evaluate(set, solution, &budget);
});
