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
pub mod input;
pub mod kc;
#[cfg(feature = "lab")]
pub mod lab;
pub mod measurement;
pub mod output;
pub mod output_file;
pub mod plan;
pub mod polygon;
pub mod results;
pub mod selfcal;
pub mod simulate;
pub mod solve;
pub mod uncertainty;

pub use measurement::{Direction, MeasurementSet, Reading};

pub use polygon::Polygon;

/// The README's library example, compiled and run as a doctest so that it stays true.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
