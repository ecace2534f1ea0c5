//! How a comparison's one test and its reference are put in words: the closed vector of
//! pitch deviations or encoder errors, or the angle blocks' joint χ² (each block on its
//! own), so that every statement (table, notes, report, DCC) names the test it made.

use super::{KeyComparison, VectorTest, chi2_text, is_given};
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
    /// Whether the laboratories report different positions (each closed over its own).
    uneven: bool,
}

impl Wording {
    /// The words of a comparison of `quantity`.
    pub fn of(quantity: Quantity) -> Wording {
        Wording {
            blocks: quantity == Quantity::AngleBlock,
            uneven: false,
        }
    }

    /// With the laboratories reporting different positions (`uneven`): a closed vector's
    /// ν is then Σ_i N_i − n − (N − 1), each laboratory's vector closed over its own.
    pub fn with_uneven(mut self, uneven: bool) -> Wording {
        self.uneven = uneven;
        self
    }

    /// Whether the laboratories report different positions.
    pub fn is_uneven(self) -> bool {
        self.uneven
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

    /// The test `v` in words, as the text table and the DCC state it: the covariance used,
    /// χ², ν and χ²_0.95(ν) (two decimals, as the report states numbers without U) and the
    /// verdict, `consistent` or `not consistent`, without a final stop.
    pub fn statement(self, v: &VectorTest) -> String {
        let what = if self.blocks {
            "Blocks' joint χ² (each block on its own, V_i = diag(u²)): χ² = Σ_b Σ_i \
             (x_ib − x_ref,b)²/u_ib² = {chi2}, ν = Σ_b (n_b − 1) = {dof}"
        } else if self.uneven {
            "Closed vector (GLS, each laboratory's closed over the N_i positions it reports, \
             V_i = N_i/(N_i−1)·P·diag(u²)·P): χ² = {chi2}, ν = Σ N_i − n − (N − 1) = {dof}"
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

impl KeyComparison {
    /// The words of this comparison's quantity ([`Wording`]).
    pub fn wording(&self) -> Wording {
        let uneven = self
            .degrees_of_equivalence
            .iter()
            .chain(self.pilot.iter().flat_map(|p| &p.degrees_of_equivalence))
            .any(|d| d.d.iter().any(|x| !is_given(*x)));
        Wording::of(self.quantity).with_uneven(uneven)
    }

    /// A test of this comparison in words ([`Wording::statement`]).
    pub fn vector_statement(&self, v: &VectorTest) -> String {
        self.wording().statement(v)
    }

    /// The closed vector's (or the blocks' joint) test in words of the laboratories in
    /// the reference, or why it was not tested.
    pub fn closed_vector_statement(&self) -> String {
        match &self.vector {
            Some(v) => self.vector_statement(v),
            None => format!(
                "Closed vector: not tested ({} is not a closed vector)",
                self.quantity.name()
            ),
        }
    }

    /// The pilot's one test in words, when there are repeats: the repeats' closed vector,
    /// its χ², ν, χ²_0.95(ν), and what follows (u_stab added or not); no final stop.
    pub fn pilot_statement(&self) -> Option<String> {
        let p = self.pilot.as_ref()?;
        let names = p.repeats.join(", ");
        let whole = self.wording().whole();
        Some(match &p.vector {
            Some(v) if v.consistent => format!(
                "The pilot's repeats ({names}) agree: their {whole} χ² = {} ≤ \
                 χ²_0.95({}) = {:.2}; the artefact is taken as stable (u_stab = 0)",
                chi2_text(v.chi2, 2),
                v.dof,
                v.chi2_critical
            ),
            Some(v) => format!(
                "The pilot's repeats ({names}) differ beyond their uncertainties: their {whole} \
                 χ² = {} > χ²_0.95({}) = {:.2}; the artefact is taken as unstable, \
                 and the repeats' sample standard deviation on each quantity (u_stab) is added \
                 in quadrature to every laboratory's u: in the reference, in every test and in \
                 the search for laboratories to leave out, so that none is left out for the \
                 artefact's motion",
                chi2_text(v.chi2, 2),
                v.dof,
                v.chi2_critical
            ),
            None => format!("The pilot's repeats ({names}): not tested"),
        })
    }

    /// The comparison's verdict in words, as the text table, the HTML report and the DCC
    /// state it: the one test of every laboratory at 5 %, the subset that passes when it
    /// failed (weighted mean), or for DerSimonian–Laird the test of τ = 0; no final stop.
    pub fn verdict_statement(&self) -> String {
        // the laboratories the one test is of: all but those kept out of the reference
        let n = self.labs.len().saturating_sub(self.not_in_reference.len());
        let whole = self.wording().whole();
        let all = match &self.vector_all {
            Some(v) => format!(
                "the {whole} of all {n} laboratories {} (χ² = {} {} χ²_0.95({}) = {:.2})",
                if v.consistent {
                    "passes its test at 5 %"
                } else {
                    "fails its test at 5 %"
                },
                chi2_text(v.chi2, 2),
                if v.consistent { "≤" } else { ">" },
                v.dof,
                v.chi2_critical
            ),
            None => format!("the {whole} of every laboratory was not tested"),
        };
        if self.method.is_random_effects() {
            let title = self.method.title();
            return if self.comparison_consistent {
                format!("Consistent ({title}, τ = 0 not rejected): {all}; nobody is left out")
            } else {
                format!(
                    "NOT consistent ({title}, τ = 0 rejected): {all}; the laboratories \
                     differ beyond their stated uncertainties, nobody is left out, and τ carries \
                     the spread into u_ref and every U(d_i)"
                )
            };
        }
        let left_out: Vec<&str> = self.excluded.iter().map(|e| e.lab.as_str()).collect();
        if self.comparison_consistent && left_out.is_empty() {
            return format!("Consistent: {all}");
        }
        if self.comparison_consistent {
            let subset = match self.search.as_ref().and_then(|s| s.steps.last()) {
                Some(step) => format!(
                    "; the largest subset that passes is {} (χ² = {} ≤ χ²_0.95({}) = {:.2})",
                    step.best.join(", "),
                    chi2_text(step.chi2, 2),
                    step.dof,
                    step.chi2_critical
                ),
                None => String::new(),
            };
            return format!(
                "Consistent after leaving out {}: {all}{subset}",
                left_out.join(", ")
            );
        }
        if !self.withheld.is_empty() {
            return format!(
                "NOT consistent: {all}; the largest subset that passes would leave out {} of the \
                 {n} laboratories ({}), more than half, so nobody is left out: the stated \
                 uncertainties look too small for the spread of the results (a random-effects \
                 reference, dersimonian-laird or mandel-paule, takes that spread into its dark \
                 uncertainty τ)",
                self.withheld.len(),
                self.withheld.join(", ")
            );
        }
        let why = if self.search.is_some() {
            "; no subset of them passes"
        } else {
            ""
        };
        format!("NOT consistent: {all}{why}")
    }
}
