//! Self-calibration of a rotary encoder with several read heads on one graduated disc
//! (docs/FORMAT.md §9), such as the SelfA encoder of the paper's section 1 (12 heads in
//! groups of 3, 4 and 7 equally spaced heads sharing head 1).
//!
//! At every table stop p = 0 … P−1 each head j, at nominal angle ψ_j from head 1, reads
//! the disc. The model of one reading is
//!
//! ```text
//! reading = t[cycle, p] + e(p·360°/P + ψ_j) + c[j] + noise
//! ```
//!
//! with t the table's position error at that stop (a nuisance), e the disc's graduation
//! error — the encoder error being calibrated, Σe = 0 over the P positions — and c the
//! head's placement error (c\[1\] = 0). This is the closure model of the polygon
//! (docs/FORMAT.md §1) with the disc in the polygon's place and the heads in the
//! autocollimators' place, and it is solved by the same engine ([`crate::solve`]).
//!
//! The self-calibration file (docs/FORMAT.md §9.2) is read with [`SelfcalSet::read_path`]
//! or [`SelfcalSet::read_from`] and written with [`SelfcalSet::write_to`]; readings built
//! in memory are checked by the same rules with [`SelfcalSet::from_readings`]. A refused
//! file gives one [`FileError::Invalid`](crate::input::FileError::Invalid) naming the
//! file, line and column (the reader, its columns, its validation and its writer live in
//! `file.rs`, `file/parse.rs`, `file/columns.rs`, `file/validate.rs` and `file/write.rs`).
//!
//! # The rules
//!
//! The file follows the measurement file's reading rules (docs/FORMAT.md §2.1): UTF-8 (a
//! leading byte-order mark is allowed), comma separated with the usual CSV quoting, one
//! header row and one reading per row, the columns in any order. Lines that start with
//! `#` before the header are comments; blank lines are skipped anywhere. Fields are not
//! trimmed.
//!
//! - Required columns: `cycle` (integer ≥ 1), `step` (integer 0 … P−1), `head`
//!   (integer ≥ 1), `head_angle` (degrees, a finite number with 0 ≤ angle < 360) and
//!   `reading` (arcseconds, a finite number). A required field may not be empty.
//! - Optional columns: `direction` (`cw` or `ccw`; empty means `cw`) and `time`
//!   (seconds, a finite number; empty means not recorded).
//! - Other columns are ignored, except a near miss of a known name (one that becomes
//!   the known name once surrounding spaces are trimmed, letters lower-cased and `-` or
//!   a space read as `_`, such as `Head_Angle` or `head-angle`): that is refused, so that
//!   no recorded value is silently dropped. A column name may appear only once.
//! - Every row has as many fields as the header.
//! - Row by row, in file order: `step` below P; a (cycle, step, head) is read at most
//!   once; a cycle has one direction; head 1, the reference, has angle 0; a head has the
//!   same `head_angle` on every row; two different heads are not at the same angle
//!   (equal modulo 360 within 1e-9 degrees).
//! - Then the set as a whole: at least 2 heads; head 1 among them; every step 0 … P−1
//!   read by every head in every cycle (the first missing (cycle, step, head) is named).
//!
//! P, the number of positions, is the largest `step` + 1 unless given (`--positions P`);
//! it must be at least 3.
//!
//! Nothing is guessed. The first problem found is reported as one
//! [`FileError::Invalid`](crate::input::FileError::Invalid) naming the file, the 1-based
//! line and the 1-based character column where the offending field starts, the column
//! name and the offending text (cut after 40 characters), e.g.
//! `run.csv:4:5: column "head": "0" is not allowed; head must be at least 1`. A rule
//! about the file or the set as a whole points at the header: a missing column at the
//! header's start; a stated P below 3, and a step never read, at the header's `step`;
//! too few heads, or no head 1, at the header's `head`. A P below 3 found from the
//! largest step points at that step's field, a duplicate reading at the start of its row.
//! An empty file, one of comments only and a header without data rows are refused too.
//! Standard input (the path `-`) is named `<stdin>`; readings checked by
//! [`SelfcalSet::from_readings`] are named `<readings>`, with their line and column 0.
//!
//! The solving: `solve.rs` maps the readings onto the closure model and back
//! ([`solve()`]); `fourier/` solves heads that sit between the positions (and
//! `fourier/design.rs` fits them with effect columns, for the diagnosis);
//! `head_angle.rs` propagates the uncertainty of the heads' angles; `budget.rs` combines
//! an instrument budget with the fit ([`evaluate_budget`]).

use crate::measurement::Direction;

mod budget;
mod file;
mod fourier;
mod head_angle;
mod monte_carlo;
mod solution;
mod solve;

pub use budget::{SelfcalContribution, SelfcalUncertainty, evaluate_budget};
pub(crate) use fourier::design::OffGridDesign;
pub(crate) use head_angle::add_head_angle_u;
pub use monte_carlo::{SelfcalMonteCarlo, monte_carlo};
pub(crate) use monte_carlo::{monte_carlo_of_closure_fit, monte_carlo_of_off_grid_fit};
pub use solution::{
    COVERAGE_PROBABILITY, HeadError, HeadGrid, ON_GRID_TOLERANCE_POSITIONS, SelfcalOptions,
    SelfcalSolution, SelfcalSolveError,
};
pub(crate) use solve::{closure_set, from_closure_fit, grid_offsets};

/// One reading of one read head: one row of the self-calibration file.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadReading {
    /// Repeat number (one full turn), ≥ 1.
    pub cycle: u32,
    /// Table stop 0 … P−1; nominal table angle step·360°/P.
    pub step: usize,
    /// Read head, ≥ 1; head 1 is the reference.
    pub head: u32,
    /// Nominal angle of the head from head 1, degrees (0 for head 1).
    pub head_angle_deg: f64,
    /// The head's reading minus its nominal angle (table angle + head angle), arcseconds.
    pub reading_arcsec: f64,
    /// Rotation direction of the cycle.
    pub direction: Direction,
    /// Time since the run started, seconds, if recorded.
    pub time_seconds: Option<f64>,
    /// Line of the source file the reading came from (1-based); 0 when not from a file.
    pub line: u64,
}

/// A validated self-calibration data set: every head reads every step 0 … P−1 once in
/// every cycle, each head at one nominal angle.
#[derive(Debug, Clone, PartialEq)]
pub struct SelfcalSet {
    /// P, the number of table positions (disc positions calibrated).
    pub positions: usize,
    /// The readings, in file order.
    pub readings: Vec<HeadReading>,
}

/// A read head of a set: its number and nominal angle from head 1, degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Head {
    /// Head number, ≥ 1.
    pub head: u32,
    /// Nominal angle from head 1, degrees, in [0, 360).
    pub angle_deg: f64,
}

impl SelfcalSet {
    /// The heads, sorted by number.
    pub fn heads(&self) -> Vec<Head> {
        let mut heads: Vec<Head> = Vec::new();
        for r in &self.readings {
            if let Err(i) = heads.binary_search_by_key(&r.head, |h| h.head) {
                heads.insert(
                    i,
                    Head {
                        head: r.head,
                        angle_deg: r.head_angle_deg,
                    },
                );
            }
        }
        heads
    }

    /// The cycles, sorted.
    pub fn cycles(&self) -> Vec<u32> {
        let mut cycles: Vec<u32> = self.readings.iter().map(|r| r.cycle).collect();
        cycles.sort_unstable();
        cycles.dedup();
        cycles
    }
}

/// Solves a self-calibration: e at every position with Σe = 0, every head's c relative
/// to head 1, their uncertainties, and the harmonics the layout cannot see.
///
/// ```
/// use polycal::measurement::Direction;
/// use polycal::selfcal::{self, HeadReading, SelfcalOptions, SelfcalSet};
///
/// // three heads 120° apart on a 12-position grid, no noise: e is recovered except
/// // for its harmonics 3 and 6, which three equally spaced heads cannot see
/// let (p, angles) = (12, [0.0, 120.0, 240.0]);
/// let e = |x: f64| 0.4 * (x.to_radians() * 2.0).cos() + 0.1 * (x.to_radians() * 3.0).sin();
/// let mut readings = Vec::new();
/// for step in 0..p {
///     for (j, &psi) in angles.iter().enumerate() {
///         let angle = step as f64 * 30.0 + psi;
///         readings.push(HeadReading {
///             cycle: 1, step, head: j as u32 + 1, head_angle_deg: psi,
///             reading_arcsec: 0.7 * step as f64 + e(angle) + 0.5 * j as f64,
///             direction: Direction::Cw, time_seconds: None, line: 0,
///         });
///     }
/// }
/// let set = SelfcalSet::from_readings(readings, None)?;
/// let solution = selfcal::solve(&set, &SelfcalOptions::new())?;
/// assert_eq!(solution.lost_harmonics, [3, 6]);
/// for (x, value) in solution.encoder_error.iter().enumerate() {
///     let harmonic_2 = 0.4 * (x as f64 * 30f64.to_radians() * 2.0).cos();
///     assert!((value - harmonic_2).abs() < 1e-9);
/// }
/// assert!((solution.head_error[0].value - 0.5).abs() < 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// [`SelfcalSolveError::Invalid`] for a set that breaks the file's rules (a set built
/// field by field), [`SelfcalSolveError::Solve`] when the engine refuses the design
/// (memory).
pub fn solve(
    set: &SelfcalSet,
    options: &SelfcalOptions,
) -> Result<SelfcalSolution, SelfcalSolveError> {
    set.check().map_err(SelfcalSolveError::Invalid)?;
    let solution = solve::solve_closure(set, options)?;
    head_angle::add_head_angle_u(set, solution, options)
}
