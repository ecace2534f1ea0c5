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
//! Files: `file.rs` reads and writes the self-calibration CSV; `solve.rs` maps the
//! readings onto the closure model and back ([`solve()`]); `fourier.rs` solves heads
//! that sit between the positions.

use crate::measurement::Direction;

mod file;
mod fourier;
mod solve;

pub use file::SelfcalError;
pub use solve::{
    HeadError, HeadGrid, ON_GRID_TOLERANCE_POSITIONS, SelfcalOptions, SelfcalSolution,
    SelfcalSolveError, solve,
};

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
