//! How results are written for people and for programs: one file per command.
//!
//! - [`solve`]: the JSON object of `polycal solve` (docs/FORMAT.md §5) and the result rows
//!   of its CSV (§3); [`solve_table`]: its table for people, whose results section
//!   (β, φ, α with their uncertainties) `diagnose` also prints for its final model;
//! - [`diagnose`]: the JSON object and the table of `polycal diagnose`;
//! - [`compare`]: the table of `polycal compare` (its JSON is [`crate::compare::Comparison`]);
//! - [`selfcal`]: the JSON object, the table and the result rows of `polycal selfcal`.
//!
//! Every JSON object a command prints carries the software version ([`to_json`] adds it as
//! the first member, `"version"`). JSON and CSV carry numbers at full precision (the
//! shortest text that reads back to the same double); only tables round. Tables are
//! written into any [`std::fmt::Write`], and a writer's error is passed on, never dropped.

pub mod compare;
pub mod diagnose;
pub mod html;
pub mod selfcal;
pub mod solve;
pub mod solve_table;

pub use solve::{
    Format, SetupErrorReport, SolveReport, result_rows, result_rows_with, sub_pitch_result_rows,
    write_results_with_file,
};
pub use solve_table::{
    write_final_model_results, write_results, write_sub_pitch_table, write_table,
};

use serde::Serialize;

/// The software version every JSON output carries (`"version"`), e.g. `0.1.0`.
pub const SOFTWARE_VERSION: &str = env!("CARGO_PKG_VERSION");

/// A JSON object with the software version as its first member.
#[derive(Serialize)]
struct Versioned<'a, T: Serialize> {
    version: &'static str,
    #[serde(flatten)]
    object: &'a T,
}

/// One line of JSON for a command's output object: `{"version": "…", …the object's
/// members…}` (docs/FORMAT.md §5).
///
/// ```
/// #[derive(serde::Serialize)]
/// struct Out { faces: usize }
/// let line = polycal::report::to_json(&Out { faces: 24 })?;
/// assert_eq!(line, format!(r#"{{"version":"{}","faces":24}}"#, polycal::report::SOFTWARE_VERSION));
/// # Ok::<(), serde_json::Error>(())
/// ```
///
/// # Errors
///
/// serde_json's error for a value that is not a JSON object with string keys.
pub fn to_json<T: Serialize>(object: &T) -> Result<String, serde_json::Error> {
    serde_json::to_string(&Versioned {
        version: SOFTWARE_VERSION,
        object,
    })
}

/// A number with `decimals` decimals, or `—` when unknown.
fn fixed(value: Option<f64>, decimals: usize) -> String {
    match value {
        Some(v) => format!("{v:.decimals$}"),
        None => "—".to_string(),
    }
}
