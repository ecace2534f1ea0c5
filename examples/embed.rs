//! Embedding polycal in a lab's own program: read a measurement file, solve it, and
//! print the pitch deviations of the polygon with their standard uncertainties.
//!
//! ```text
//! cargo run --example embed -- examples/data/polygon24-2ac-6cycles.csv
//! ```

use polycal::measurement::MeasurementSet;
use polycal::solve::{SolveOptions, solve};
use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let path = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("examples/data/polygon24-2ac-6cycles.csv"));
    // A refused file names the file, the line and the column.
    let set = match MeasurementSet::read_path(&path, None) {
        Ok(set) => set,
        Err(error) => {
            eprintln!("error: {error}");
            return ExitCode::from(2);
        }
    };
    let solution = match solve(&set, &SolveOptions::default()) {
        Ok(solution) => solution,
        Err(error) => {
            eprintln!("error: {}: {error}", path.display());
            return ExitCode::from(2);
        }
    };
    let u = solution.pitch_deviation_u();
    println!("face  pitch deviation/arcsec  u/arcsec");
    for (k, beta) in solution.pitch_deviation.iter().enumerate() {
        let u = u
            .as_ref()
            .map_or("-".to_string(), |u| format!("{:.4}", u[k]));
        println!("{:>4}  {beta:>22.4}  {u:>8}", k + 1);
    }
    ExitCode::SUCCESS
}
