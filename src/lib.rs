//! # polycal
//!
//! Simultaneous calibration of an optical polygon and a rotary encoder from the readings
//! of two (or more) autocollimators — the *two-autocollimator method* of Hsieh, Lin, Yeh
//! and Watanabe, "Calibration of a Rotary Encoder and a Polygon Using a
//! Two-Autocollimator Method", Appl. Sci. 2023, 13, 1865 (called "the paper" below).
//!
//! The model of one reading (the paper's equation (2), written for any design) is
//!
//! ```text
//! reading = α[p mod N] + φ[face] + U[setup, ac] + (effects) + noise
//! ```
//!
//! with the closure conditions Σα = 0 (eq. (3)) and Σβ = 0 (eq. (1)), where
//! φ\[f\] = β\[1\] + … + β\[f\] is the face angle deviation and β the pitch deviation.
//! All angles in this crate are in **arcseconds** unless a name says otherwise.
//!
//! Modules, by the concept a metrologist would name:
//! - [`polygon`]: the polygon's pitch and face deviations, generic over a compile-time
//!   or run-time number of faces;
//! - [`measurement`]: readings and the measurement CSV file;
//! - [`solve`]: the paper's closed form and the general least-squares closure solver;
//! - [`simulate`]: simulated runs with a known truth;
//! - [`output`]: the JSON, CSV and table outputs every command prints;
//! - [`results`]: the result CSV file (one row per calibrated quantity);
//! - [`uncertainty`]: GUM uncertainty budgets and Student's t;
//! - [`compare`]: En numbers between two results;
//! - [`kc`]: interlaboratory (key) comparisons: reference values, χ² tests, degrees of equivalence;
//! - [`diagnose`]: residual analysis that finds, adds and reports the effects a model lacks;
//! - [`figure`]: the figures (SVG) of every command, drawn from its report object;
//! - [`certificate`]: the documents a lab hands over, both built from one evaluated
//!   [`certificate::CalibrationReport`]: the HTML calibration report
//!   ([`certificate::html`]) and the Digital Calibration Certificate
//!   ([`certificate::dcc`]);
//! - [`clock`]: RFC 3339 time stamps;
//! - [`verification`]: the paper's verification (its section 3.1) reproduced from one
//!   simulated truth measured three ways, evaluated and compared;
//! - [`progress`]: the observer every long computation tells how far it is;
//! - [`output_file`]: how every file polycal writes is written: only where meant (never
//!   an input, never a device), whole or not at all;
//! - `lab` (cargo feature `lab`): the instruments on serial lines, simulated instruments,
//!   and the run procedure that drives them through a calibration.

pub mod certificate;
pub mod clock;
pub mod compare;
pub mod diagnose;
pub mod effects;
pub mod figure;
pub mod history;
pub mod input;
pub mod kc;
#[cfg(feature = "lab")]
pub mod lab;
pub mod measurement;
pub mod output;
pub mod output_file;
pub mod plan;
pub mod polygon;
pub mod progress;
pub mod results;
pub mod selfcal;
pub mod simulate;
pub mod solve;
pub mod uncertainty;
pub mod validation;
pub mod verification;

/// The software version every output carries (the JSON's `"version"`, a simulated file's
/// header, a report's and a certificate's generator), e.g. `0.1.0`.
pub const SOFTWARE_VERSION: &str = env!("CARGO_PKG_VERSION");

pub use measurement::{Direction, MeasurementSet, Reading};

pub use polygon::Polygon;

/// The README's library example, compiled and run as a doctest so that it stays true.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// Every `.rs` file under `dir`.
    fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("src is readable").flatten() {
            let path = entry.path();
            if path.is_dir() {
                sources(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }

    /// Only the binary (`src/cli`, `main.rs`), the instrument layer (`src/lab`) and this
    /// file's `lab` module line depend on a cargo feature: the maths is the same code in
    /// both configurations, which is why CI runs the integration tests in one of them
    /// only (docs/ARCHITECTURE.md, "Cargo features").
    #[test]
    fn only_the_binary_and_the_instrument_layer_depend_on_a_feature() {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut files = Vec::new();
        sources(&src, &mut files);
        assert!(files.len() > 50, "the sources were found: {}", files.len());
        let mut offending = Vec::new();
        for file in &files {
            let relative = file.strip_prefix(&src).expect("under src");
            let first = relative.components().next().map(|c| c.as_os_str());
            if first.is_some_and(|c| c == "cli" || c == "lab" || c == "main.rs") {
                continue;
            }
            let text = std::fs::read_to_string(file).expect("a source file is text");
            // (spelt in pieces, so that these lines are not what they look for)
            let lab_module = concat!("#[cfg(feat", "ure = \"lab\")]");
            for (number, line) in text.lines().enumerate() {
                let allowed = relative == Path::new("lib.rs") && line.trim() == lab_module;
                if line.contains(concat!("feat", "ure =")) && line.contains("cfg") && !allowed {
                    offending.push(format!("{}:{}: {line}", relative.display(), number + 1));
                }
            }
        }
        assert!(offending.is_empty(), "{offending:#?}");
    }
}
