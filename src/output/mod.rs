//! The views every command prints, for people and for programs: one file per command
//! (the documents a lab hands over, built from these, are [`crate::certificate`]).
//!
//! - [`solve`]: the JSON object of `polycal solve` (docs/FORMAT.md §5) and the result rows
//!   of its CSV (§3); [`solve_table`]: its table for people, whose results section
//!   (β, φ, α with their uncertainties) `diagnose` also prints for its final model;
//! - [`diagnose`]: the JSON object of `polycal diagnose`; [`diagnose_table`]: its table;
//! - [`compare`]: the table of `polycal compare` (its JSON is [`crate::compare::Comparison`]);
//! - [`kc`]: the table and the CSV of `polycal kc` (its JSON is [`crate::kc::KeyComparison`]);
//! - [`history`]: the table of `polycal history` (its JSON is [`crate::history::History`]);
//! - [`selfcal`]: the JSON object, the table and the result rows of `polycal selfcal`;
//! - [`plan`]: the JSON object of one design of `polycal plan`, its table, and the table
//!   comparing designs.
//!
//! Every JSON object a command prints carries the software version ([`to_json`] adds it as
//! the first member, `"version"`). JSON and CSV carry numbers at full precision (the
//! shortest text that reads back to the same double); only tables round. Tables are
//! written into any [`std::fmt::Write`], and a writer's error is passed on, never dropped.

pub mod compare;
pub mod diagnose;
pub mod diagnose_selfcal;
pub mod diagnose_table;
pub mod history;
pub mod kc;
pub mod plan;
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

use crate::measurement::cross_talk::StatedCrossTalk;

pub use crate::SOFTWARE_VERSION;

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
/// let line = polycal::output::to_json(&Out { faces: 24 })?;
/// assert_eq!(line, format!(r#"{{"version":"{}","faces":24}}"#, polycal::output::SOFTWARE_VERSION));
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

/// [`to_json`]'s line written into `writer` as it is formed, and a line feed: the same
/// bytes without the whole text in memory (a key comparison of 100 laboratories × 3 000
/// faces writes 600 MB of pairs). Wrap a slow writer (standard output) in a
/// [`std::io::BufWriter`].
///
/// ```
/// #[derive(serde::Serialize)]
/// struct Out { faces: usize }
/// let mut bytes = Vec::new();
/// polycal::output::write_json(&mut bytes, &Out { faces: 24 })?;
/// assert_eq!(bytes, format!("{}\n", polycal::output::to_json(&Out { faces: 24 })?).into_bytes());
/// # Ok::<(), std::io::Error>(())
/// ```
///
/// # Errors
///
/// The writer's error as it came (a broken pipe stays one), or serde_json's for a value
/// that is not a JSON object with string keys.
pub fn write_json<W: std::io::Write, T: Serialize>(
    mut writer: W,
    object: &T,
) -> std::io::Result<()> {
    serde_json::to_writer(
        &mut writer,
        &Versioned {
            version: SOFTWARE_VERSION,
            object,
        },
    )
    .map_err(std::io::Error::from)?;
    writer.write_all(b"\n")
}

/// A command's object with the cross-talk stated from the autocollimators' calibrations,
/// as its last member.
#[derive(Serialize)]
struct Stating<'a, T: Serialize> {
    #[serde(flatten)]
    object: &'a T,
    stated_cross_talk: &'a [StatedCrossTalk],
}

/// [`to_json`] of a command's object that evaluated readings corrected for a stated
/// cross-talk (docs/FORMAT.md §6): the object gains the member `stated_cross_talk`, one
/// `{"ac", "coefficient", "u"}` object per autocollimator as stated. With none stated the
/// line is exactly [`to_json`]'s.
///
/// ```
/// use polycal::measurement::cross_talk::StatedCrossTalk;
///
/// #[derive(serde::Serialize)]
/// struct Out { faces: usize }
/// let stated = [StatedCrossTalk::new(1, 0.01, Some(0.001))?];
/// let line = polycal::output::to_json_with_stated_cross_talk(&Out { faces: 24 }, &stated)?;
/// assert!(line.ends_with(r#""faces":24,"stated_cross_talk":[{"ac":1,"coefficient":0.01,"u":0.001}]}"#));
/// let plain = polycal::output::to_json_with_stated_cross_talk(&Out { faces: 24 }, &[])?;
/// assert_eq!(plain, polycal::output::to_json(&Out { faces: 24 })?);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// As [`to_json`].
pub fn to_json_with_stated_cross_talk<T: Serialize>(
    object: &T,
    stated: &[StatedCrossTalk],
) -> Result<String, serde_json::Error> {
    if stated.is_empty() {
        return to_json(object);
    }
    to_json(&Stating {
        object,
        stated_cross_talk: stated,
    })
}

/// The line a table ends with when the readings were corrected for a stated cross-talk
/// (docs/FORMAT.md §6), nothing when none is stated:
/// `stated cross-talk, readings corrected by C·reading_y: autocollimator 1: C = 0.01, u(C) = 0.001`.
///
/// # Errors
///
/// The writer's error.
pub fn write_stated_cross_talk(
    out: &mut impl std::fmt::Write,
    stated: &[StatedCrossTalk],
) -> std::fmt::Result {
    if stated.is_empty() {
        return Ok(());
    }
    let each: Vec<String> = stated.iter().map(StatedCrossTalk::describe).collect();
    writeln!(
        out,
        "\nstated cross-talk, readings corrected by C·reading_y: {}",
        each.join("; ")
    )
}

/// A number with `decimals` decimals, or `—` when unknown.
fn fixed(value: Option<f64>, decimals: usize) -> String {
    match value {
        Some(v) => format!("{v:.decimals$}"),
        None => "—".to_string(),
    }
}
