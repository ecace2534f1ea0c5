//! The seed files: valid inputs of every reader, from the bundled examples and the test
//! data, that the mutations start from.

use std::fmt;

/// A seed file: its path (relative to the repository root) and its bytes.
#[derive(Clone)]
pub struct Seed {
    pub path: &'static str,
    pub bytes: Vec<u8>,
}

impl fmt::Debug for Seed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path)
    }
}

/// Reads seeds (paths relative to the repository root).
pub fn seeds(paths: &[&'static str]) -> Vec<Seed> {
    paths
        .iter()
        .map(|&path| {
            let full = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
            let bytes = std::fs::read(&full)
                .unwrap_or_else(|e| panic!("fuzz seed {}: {e}", full.display()));
            Seed { path, bytes }
        })
        .collect()
}

/// The seeds of each kind of file.
pub mod seed {
    /// Measurement CSVs (docs/FORMAT.md §2).
    pub const MEASUREMENT: &[&str] = &[
        "examples/data/polygon24-2ac-6cycles.csv",
        "examples/data/polygon24-shift-angle-5setups.csv",
        "tests/data/measurement/good_4faces.csv",
        "tests/data/measurement/good_setups_crlf.csv",
        "tests/data/measurement/good_shifts.csv",
        "tests/fixtures/expected/sim-bare.file.bare.csv",
        "tests/fixtures/expected/sim-setups.file.setups.csv",
        "tests/fixtures/expected/sim-subpitch.file.subpitch.csv",
    ];
    /// Self-calibration CSVs (§9.2); the 168-position example only at binary level.
    pub const SELFCAL: &[&str] = &[
        "tests/data/selfcal/good_3heads.csv",
        "tests/fixtures/expected/sim-selfcal.file.selfcal.csv",
        "tests/fixtures/expected/sim-selfcal-12.file.selfa12.csv",
    ];
    /// Result CSVs (§3).
    pub const RESULTS: &[&str] = &[
        "examples/data/polygon24-shift-angle.result.csv",
        "tests/data/results/two-ac-24.csv",
        "tests/data/results/two-ac-24-no-angle.csv",
        "tests/data/results/selfcal-168.csv",
        "tests/data/results/setup-a.csv",
        "tests/data/results/setup-b.csv",
        "tests/fixtures/inputs/result-a.csv",
        "tests/fixtures/inputs/result-b.csv",
    ];
    /// Budget TOMLs (§5.3 and §5.1).
    pub const BUDGET: &[&str] = &[
        "examples/budgets/gum-h1-end-gauge.toml",
        "examples/budgets/instrument.toml",
        "examples/budgets/paper-table1.toml",
        "examples/budgets/selfcal.toml",
    ];
    /// Truth JSONs of polygon runs (§4).
    pub const TRUTH: &[&str] = &[
        "examples/data/polygon24-2ac-6cycles.truth.json",
        "tests/fixtures/expected/sim-bare.file.bare.json",
        "tests/fixtures/expected/sim-drift.file.drift.json",
        "tests/fixtures/expected/sim-subpitch.file.subpitch.json",
    ];
    /// Truth JSONs of self-calibration runs (§4.1).
    pub const SELFCAL_TRUTH: &[&str] = &[
        "tests/fixtures/expected/sim-selfcal.file.selfcal.json",
        "examples/data/selfa-168.truth.json",
    ];
    /// The designs TOML of `plan --designs` (§5.6).
    pub const DESIGNS: &[&str] = &["examples/designs.toml"];
    /// The report's metadata TOML (§10.2).
    pub const META: &[&str] = &["examples/report/meta.toml"];
}
