//! A file of another kind given to a command (a budget as the measurement file, a
//! measurement file as a result file or a budget): the library's refusal says what the
//! file is (`polycal::input::kind`); this adds what to do on the command line
//! (docs/FORMAT.md §8).

use polycal::input::FileError;
use polycal::input::kind::FileKind;
use polycal::uncertainty::BudgetError;

use super::with_hint;

/// What to do with a file of kind `found` given where `expected` is wanted: the flag or
/// command the hint names (not added twice) and the hint.
fn hint(found: FileKind, expected: FileKind) -> Option<(&'static str, &'static str)> {
    use FileKind::*;
    Some(match (found, expected) {
        (Budget, Result) => (
            "--budget",
            "a budget goes with --budget to the evaluation of a measurement \
             (`polycal solve FILE --budget BUDGET.toml`)",
        ),
        (Budget, _) => (
            "--budget",
            "give a budget with --budget, after the file it is the budget of \
             (`polycal solve FILE --budget BUDGET.toml`)",
        ),
        (Result, _) => (
            "polycal compare",
            "result files are compared with `polycal compare A.csv B.csv` or `polycal kc`",
        ),
        (Measurement, Result) => (
            "polycal solve",
            "evaluate it first: `polycal solve FILE --format csv > result.csv` writes its result file",
        ),
        (Measurement, Budget) => (
            "polycal solve",
            "evaluate it with `polycal solve FILE --budget BUDGET.toml`",
        ),
        (Measurement, _) => ("polycal solve", "evaluate it with `polycal solve FILE`"),
        (SelfCalibration, Result) => (
            "polycal selfcal",
            "evaluate it first: `polycal selfcal FILE --format csv > result.csv` writes its result file",
        ),
        (SelfCalibration, _) => ("polycal selfcal", "evaluate it with `polycal selfcal FILE`"),
        _ => return None,
    })
}

/// `error` with its hint when it names `found`, else as it is.
fn hinted(
    error: impl std::fmt::Display,
    found: Option<FileKind>,
    expected: FileKind,
) -> anyhow::Error {
    match found.and_then(|found| hint(found, expected)) {
        Some((flag, text)) => with_hint(error, flag, text),
        None => anyhow::Error::msg(error.to_string()),
    }
}

/// A table file's refusal, with what to do when the file is of another kind than
/// `expected`.
fn table_file(error: FileError, expected: FileKind) -> anyhow::Error {
    match error.found_kind() {
        found @ Some(_) => hinted(error, found, expected),
        None => error.into(),
    }
}

/// A measurement file's refusal, with what to do when the file is of another kind.
pub fn measurement(error: FileError) -> anyhow::Error {
    table_file(error, FileKind::Measurement)
}

/// A self-calibration file's refusal, with what to do when the file is of another kind.
pub fn selfcal(error: FileError) -> anyhow::Error {
    table_file(error, FileKind::SelfCalibration)
}

/// A result file's refusal, with what to do when the file is of another kind.
pub fn results(error: FileError) -> anyhow::Error {
    table_file(error, FileKind::Result)
}

/// The refusal of the file given with `--budget`, saying so when it is of another kind.
pub fn budget_option(error: BudgetError) -> anyhow::Error {
    match &error {
        BudgetError::WrongKind { .. } => with_hint(
            &error,
            "--budget takes",
            "--budget takes a budget: the instrument budget's TOML file",
        ),
        _ => error.into(),
    }
}

/// A budget's refusal (`polycal budget`), with what to do when the file is of another
/// kind.
pub fn budget(error: BudgetError) -> anyhow::Error {
    match &error {
        BudgetError::WrongKind { found, .. } => hinted(&error, Some(*found), FileKind::Budget),
        _ => error.into(),
    }
}
