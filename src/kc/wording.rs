//! How a comparison's one test and its reference are put in words: the closed vector of
//! pitch deviations or encoder errors, or the angle blocks' joint χ² (each block on its
//! own), so that every statement (table, notes, report, DCC) names the test it made.

use super::{VectorTest, chi2_text};
use crate::results::Quantity;

/// The words of a comparison of `quantity` ([`Wording::of`]).
///
/// ```
/// use polycal::kc::Wording;
/// use polycal::results::Quantity;
/// assert_eq!(Wording::of(Quantity::PitchDeviation).whole(), "closed vector");
/// assert_eq!(Wording::of(Quantity::AngleBlock).whole(), "blocks' joint χ²");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wording {
    /// Angle blocks (scalars each on its own), else a closed vector.
    blocks: bool,
}

impl Wording {
    /// The words of a comparison of `quantity`.
    pub fn of(quantity: Quantity) -> Wording {
        Wording {
            blocks: quantity == Quantity::AngleBlock,
        }
    }

    /// Whether the quantity's positions make a closed vector (not angle blocks).
    pub fn is_closed(self) -> bool {
        !self.blocks
    }

    /// The whole comparison's test, as a noun: `closed vector` or `blocks' joint χ²`.
    pub fn whole(self) -> &'static str {
        if self.blocks {
            "blocks' joint χ²"
        } else {
            "closed vector"
        }
    }

    /// The whole comparison's statistic, as a noun: `closed vector's χ²` or `blocks' joint
    /// χ²`.
    pub fn whole_chi2(self) -> &'static str {
        if self.blocks {
            "blocks' joint χ²"
        } else {
            "closed vector's χ²"
        }
    }

    /// The reference, as a noun: `closed GLS reference` or `weighted mean of each block`.
    pub fn reference(self) -> &'static str {
        if self.blocks {
            "weighted mean of each block"
        } else {
            "closed GLS reference"
        }
    }

    /// A pair's test, as a noun.
    pub fn pair_test(self) -> &'static str {
        if self.blocks {
            "blocks d_ij (over the blocks both report, ν their number)"
        } else {
            "closed vector d_ij"
        }
    }

    /// The test `v` in words, as the text table and the DCC state it: the covariance used,
    /// χ², ν and χ²_0.95(ν) (two decimals, as the report states numbers without U) and the
    /// verdict, `consistent` or `not consistent`, without a final stop.
    pub fn statement(self, v: &VectorTest) -> String {
        let what = if self.blocks {
            "Blocks' joint χ² (each block on its own, V_i = diag(u²)): χ² = Σ_b Σ_i \
             (x_ib − x_ref,b)²/u_ib² = {chi2}, ν = Σ_b (n_b − 1) = {dof}"
        } else {
            "Closed vector (GLS, V_i = N/(N−1)·P·diag(u²)·P unless the laboratory sent its \
             covariance, P = I − J/N): χ² = {chi2}, ν = (N − 1)(n − 1) = {dof}"
        };
        format!(
            "{}, χ²_0.95(ν) = {:.2}: {}",
            what.replace("{chi2}", &chi2_text(v.chi2, 2))
                .replace("{dof}", &v.dof.to_string()),
            v.chi2_critical,
            if v.consistent {
                "consistent"
            } else {
                "not consistent"
            }
        )
    }
}
