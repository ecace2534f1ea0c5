//! What the tests of result files and their comparisons (`tests/maths/compare_en.rs`,
//! `tests/maths/result_file.rs`, `tests/maths/compare_angles.rs`) share: a result row, the
//! per-row rule and a temporary file.

use std::path::PathBuf;

use polycal::compare::{CompareOptions, VerdictRule};
use polycal::results::{Quantity, ResultRow};

pub fn row(quantity: &str, index: u32, value: f64, expanded_u: Option<f64>) -> ResultRow {
    ResultRow {
        expanded_u,
        ..ResultRow::new(
            Quantity::from_name(quantity).expect("a quantity"),
            index,
            value,
        )
    }
}

/// The per-row rule: rows with U alone (no u, no k) and single rows have no vector test.
pub fn en_rule() -> CompareOptions {
    CompareOptions::default().with_verdict(VerdictRule::En)
}

pub fn temp_file(name: &str, contents: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-compare-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}
