//! Interlaboratory (key) comparisons of a polygon or an encoder (docs/FORMAT.md §12,
//! `polycal kc`): the reference value of every face (or common table angle), its
//! consistency, the degrees of equivalence of every laboratory, and for pitch deviations
//! the test of the whole closed vector.
//!
//! Per quantity (face or angle), with the laboratories i in the reference:
//!
//! ```text
//! weighted mean (Cox 2002, procedure A):
//!   x_ref = Σ x_i/u_i² / Σ 1/u_i²,   u_ref = (Σ 1/u_i²)^(−1/2)
//!   χ² = Σ (x_i − x_ref)²/u_i²,  ν = n − 1,  consistent when χ² ≤ χ²_{0.95}(ν)
//! DerSimonian–Laird (random effects):
//!   τ² = max(0, (χ² − ν) / (S1 − S2/S1)),  S1 = Σ 1/u_i²,  S2 = Σ 1/u_i⁴
//!   x_ref = Σ x_i/(u_i² + τ²) / Σ 1/(u_i² + τ²),  u_ref² = 1 / Σ 1/(u_i² + τ²)
//! degrees of equivalence: d_i = x_i − x_ref,
//!   U(d_i) = 2·√(u_i² + u_stab² + τ² − u_ref²)   laboratory i in the reference
//!   U(d_i) = 2·√(u_i² + u_stab² + τ² + u_ref²)   not in it (excluded, a pilot's repeat)
//! pairs: d_ij = x_i − x_j,  U(d_ij) = 2·√(u_i² + u_j² + 2u_stab² + 2τ²),
//!   each pair's closed vector tested at 5 %: χ² = d_ijᵀ (V_i + V_j)⁺ d_ij, ν = N − 1
//! ```
//!
//! The in-reference formula is exact for both methods: with v_i = u_i² + u_stab² + τ² and
//! the normalised weights w'_i = (1/v_i)/Σ 1/v_j, u²(d_i) = (1 − w'_i)² v_i + Σ_{j≠i} w'_j²
//! v_j = v_i − u_ref², since w'_i v_i = u_ref². `u_stab` is the pilot's instability term (0
//! without pilot repeats or when they agree; see [`PilotStability`]): when the repeats show
//! that the artefact moved, every laboratory's u is taken as √(u_i² + u_stab²) — in the
//! reference, in every test and in the search for the largest consistent subset — so that a
//! laboratory is not left out for the artefact's motion. (The weighted mean's and
//! DerSimonian–Laird's u_i below are then these.)
//!
//! **Decisions at their stated rate** (docs/FORMAT.md §12). The comparison's consistency is
//! one test at 5 %: the closed vector's χ² over every laboratory ([`KeyComparison::vector_all`],
//! reported before any exclusion). Only when it fails (weighted mean only) are laboratories
//! left out, each from every face: the largest subset whose closed vector passes, found by
//! trying every subset of each size from n − 1 down while that is cheap (else greedily,
//! said in a note), ties broken by the smaller χ² ([`SubsetSearch`], each size with the
//! statistic that decided it); laboratories the pilot keeps ([`KcOptions::with_keep`]) are
//! in every subset. When that subset would leave out more than half of the laboratories,
//! nobody is left out ([`KeyComparison::withheld`]): the comparison is not consistent, and
//! the stated uncertainties look too small for the spread of the results — a random-effects
//! method takes that spread into the reference. Each pair of laboratories has its own
//! closed-vector test at 5 % ([`PairDifference::vector`]), what the pairwise figure shades. The per-quantity χ² tests are information. The DerSimonian–Laird
//! method leaves nobody out: its dark uncertainty τ takes the spread into the reference's
//! uncertainty, and its verdict is the test of τ = 0 (the same closed vector of every
//! laboratory). The pilot's repeats are one test of their closed vectors at 5 % too.
//!
//! **The reference** is the closed GLS reference of the laboratories in it (Σ x_ref = 0,
//! so Σ_k d_ik = 0); with the same u on every face it is the per-face weighted mean above.
//! Encoder errors are defined up to a constant: each result's mean over the compared
//! positions is taken out first, so that they too are closed vectors.
//!
//! **The closed vector** (pitch deviations only): a laboratory's own covariance V_i of its
//! pitch deviations ([`LabResult::with_covariance`], or `pitch_deviation_covariance` of a
//! solve result in JSON, [`lab_from_solve_json`]) is used as given once checked
//! (symmetric, positive semi-definite, rows summing to 0, rank N − 1); a result without
//! one is taken as closed (Σβ = 0) with V_i = N/(N − 1)·P·diag(u_i²)·P, P = I − J/N. The
//! per-face tests use each row's u either way. The GLS reference
//! x_ref = (Σ V_i⁺)⁺ Σ V_i⁺ x_i (pseudo-inverses on the closed subspace) and
//! χ²_vector = Σ (x_i − x_ref)ᵀ V_i⁺ (x_i − x_ref) with ν = (N − 1)(n − 1), in O(N·n²) time
//! when no laboratory gives its own covariance (the closed covariance is diagonal plus rank
//! one). With a laboratory's covariance, u(d_i)² is the diagonal of V_i ∓ (Σ V_j⁺)⁺.

mod anonymise;
mod blocks;
pub(crate) mod closed;
mod closure;
mod covariance;
mod dof;
mod error;
mod evaluate;
pub(crate) mod input;
mod json;
mod link;
mod link_positions;
mod monte_carlo;
mod names;
mod notes;
mod nullable;
mod pairs;
mod positions;
mod reference;
mod scaled;
mod search;
mod shared;
mod wording;

use serde::{Deserialize, Serialize};

use crate::results::{Quantity, ResultFile, ResultRow, RowColumns};

pub use anonymise::{
    CodeEntry, CodeKey, CodeKeyError, DRAFT_A_NOTE, anonymise, code_letter, code_order,
};
pub use covariance::lab_from_solve_json;
pub use error::KcError;
pub use evaluate::evaluate;
pub use input::MIN_STANDARD_U_ARCSEC;
pub use json::{KcJsonError, KeyComparisonShapeError, read_json, read_json_lines};
pub use link::{Link, link, note_not_linked};
pub use nullable::is_given;
pub use pairs::{Pairs, PairsIter};
pub use reference::chi2_text;
pub use reference::{chi2_quantile_95, closed_covariance};
pub use search::{SearchMethod, SearchStep, SubsetSearch};
pub use shared::{COMPARED_QUANTITIES, shared_quantities};
pub use wording::Wording;

/// How the reference value of each quantity is formed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum ReferenceMethod {
    /// The weighted mean (Cox 2002, procedure A), with the largest consistent subset.
    WeightedMean,
    /// The DerSimonian–Laird random-effects mean, with its dark uncertainty τ (method of
    /// moments).
    DersimonianLaird,
    /// The Mandel–Paule random-effects mean: τ² such that the χ² about the mean with the
    /// widened uncertainties equals its degrees of freedom, n − 1 (Paule & Mandel 1982).
    MandelPaule,
}

impl ReferenceMethod {
    /// Every method, in the order of their names in messages.
    pub const ALL: [ReferenceMethod; 3] = [
        ReferenceMethod::WeightedMean,
        ReferenceMethod::DersimonianLaird,
        ReferenceMethod::MandelPaule,
    ];

    /// The name as spelled in the JSON and on the command line, e.g. `weighted-mean`.
    pub fn name(self) -> &'static str {
        match self {
            ReferenceMethod::WeightedMean => "weighted-mean",
            ReferenceMethod::DersimonianLaird => "dersimonian-laird",
            ReferenceMethod::MandelPaule => "mandel-paule",
        }
    }

    /// The name in prose, e.g. `DerSimonian–Laird`.
    pub fn title(self) -> &'static str {
        match self {
            ReferenceMethod::WeightedMean => "weighted mean",
            ReferenceMethod::DersimonianLaird => "DerSimonian–Laird",
            ReferenceMethod::MandelPaule => "Mandel–Paule",
        }
    }

    /// Whether the method is a random-effects one (a dark uncertainty τ, nobody left out,
    /// the verdict the test of τ = 0).
    pub fn is_random_effects(self) -> bool {
        self != ReferenceMethod::WeightedMean
    }
}

/// A name a key comparison does not know: one message for every caller (the command
/// line, Python).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum KcNameError {
    /// Not a reference method's name.
    #[error("method {0:?}: expected weighted-mean, dersimonian-laird or mandel-paule")]
    Method(String),
    /// Not the name of a compared quantity.
    #[error("quantity {0:?}: expected {expected}", expected = shared::compared_names())]
    Quantity(String),
}

impl std::str::FromStr for ReferenceMethod {
    type Err = KcNameError;

    /// `weighted-mean` or `dersimonian-laird`, exactly.
    ///
    /// ```
    /// use polycal::kc::ReferenceMethod;
    /// assert_eq!("dersimonian-laird".parse(), Ok(ReferenceMethod::DersimonianLaird));
    /// assert!("mean".parse::<ReferenceMethod>().is_err());
    /// ```
    fn from_str(name: &str) -> Result<Self, Self::Err> {
        ReferenceMethod::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| KcNameError::Method(name.to_string()))
    }
}

/// The quantity a key comparison compares, by its name: `pitch_deviation`,
/// `encoder_error` or `angle_block` (exactly; face deviations and setup errors are not
/// compared).
///
/// # Errors
///
/// [`KcNameError::Quantity`] for any other word.
///
/// ```
/// use polycal::results::Quantity;
/// assert_eq!(polycal::kc::compared_quantity("encoder_error"), Ok(Quantity::EncoderError));
/// assert!(polycal::kc::compared_quantity("face_deviation").is_err());
/// ```
pub fn compared_quantity(name: &str) -> Result<Quantity, KcNameError> {
    COMPARED_QUANTITIES
        .into_iter()
        .find(|q| q.name() == name)
        .ok_or_else(|| KcNameError::Quantity(name.to_string()))
}

/// Options of a key comparison: [`KcOptions::new`] and the `with_…` methods.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct KcOptions {
    /// Which quantity is compared: pitch deviations (default) or encoder errors.
    pub quantity: Quantity,
    /// The reference method (default the weighted mean).
    pub method: ReferenceMethod,
    /// Whether laboratories are left out when the closed vector of all of them fails
    /// (default `true`; the weighted mean only): the largest consistent subset.
    pub largest_consistent_subset: bool,
    /// Laboratories held in the reference whatever the tests say (the pilot's decision).
    pub keep: Vec<String>,
    /// Laboratories kept out of the reference but given degrees of equivalence against it
    /// (the pilot's decision): not in the one test nor in the search.
    pub not_in_reference: Vec<String>,
    /// Monte Carlo draws for every U (`None`: the formulas): a parametric bootstrap of the
    /// fitted model, τ estimated again in every draw for the random-effects methods.
    pub monte_carlo: Option<usize>,
}

impl Default for KcOptions {
    fn default() -> Self {
        KcOptions {
            quantity: Quantity::PitchDeviation,
            method: ReferenceMethod::WeightedMean,
            largest_consistent_subset: true,
            keep: Vec::new(),
            not_in_reference: Vec::new(),
            monte_carlo: None,
        }
    }
}

impl KcOptions {
    /// Pitch deviations, the weighted mean, with exclusions.
    pub fn new() -> Self {
        Self::default()
    }

    /// With the compared quantity (pitch deviations or encoder errors).
    pub fn with_quantity(mut self, quantity: Quantity) -> Self {
        self.quantity = quantity;
        self
    }

    /// With the reference method.
    pub fn with_method(mut self, method: ReferenceMethod) -> Self {
        self.method = method;
        self
    }

    /// With (`true`, the default) or without the search for the largest consistent
    /// subset: without it every laboratory stays in the reference.
    pub fn with_largest_consistent_subset(mut self, on: bool) -> Self {
        self.largest_consistent_subset = on;
        self
    }

    /// With laboratories held in the reference, by name: every subset the search tries
    /// contains them ([`evaluate`] refuses a name that is not a laboratory's).
    pub fn with_keep(mut self, names: impl IntoIterator<Item = impl Into<String>>) -> Self {
        self.keep = names.into_iter().map(Into::into).collect();
        self
    }

    /// With every U(d_i) and u_ref by `draws` Monte Carlo draws from the fitted model (at
    /// least 1 000; refused with a laboratory's own covariance, or beyond 2.5·10⁷ numbers
    /// kept): τ's own uncertainty is then in U for the random-effects methods.
    pub fn with_monte_carlo(mut self, draws: usize) -> Self {
        self.monte_carlo = Some(draws);
        self
    }

    /// With laboratories kept out of the reference, by name: they are not in the one test
    /// at 5 % nor in the search, and have degrees of equivalence against the reference
    /// (`in_reference` false). [`evaluate`] refuses a name that is not a laboratory's, one
    /// also held in ([`KcOptions::with_keep`]), and fewer than 2 laboratories left.
    pub fn with_not_in_reference(
        mut self,
        names: impl IntoIterator<Item = impl Into<String>>,
    ) -> Self {
        self.not_in_reference = names.into_iter().map(Into::into).collect();
        self
    }
}

/// One laboratory's result (or one of the pilot's repeats), by name.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LabResult {
    /// The laboratory's name.
    pub name: String,
    /// Where the result came from (its file), for messages.
    pub source: String,
    /// Its rows.
    pub rows: Vec<ResultRow>,
    /// The 1-based line of each row in its file (empty for rows given in memory).
    pub lines: Vec<u64>,
    /// Where each row's fields start on its line (empty when not known).
    pub columns: Vec<RowColumns>,
    /// The laboratory's covariance of its pitch deviations, faces 1 … N row-major
    /// (N × N), arcsec², when it gives one; else `None` (taken as closed with its u).
    pub covariance: Option<Vec<f64>>,
}

impl LabResult {
    /// A laboratory's result read from a file: rows are named by file and line.
    pub fn from_file(name: impl Into<String>, file: ResultFile) -> LabResult {
        LabResult {
            name: name.into(),
            source: file.source,
            rows: file.rows,
            lines: file.lines,
            columns: file.columns,
            covariance: None,
        }
    }

    /// A laboratory's result from rows in memory: rows are named by the laboratory and
    /// their row number.
    pub fn from_rows(name: impl Into<String>, rows: Vec<ResultRow>) -> LabResult {
        let name = name.into();
        LabResult {
            source: name.clone(),
            name,
            rows,
            lines: Vec::new(),
            columns: Vec::new(),
            covariance: None,
        }
    }

    /// With the laboratory's covariance of its pitch deviations, faces 1 … N row-major
    /// (N × N), arcsec²; [`evaluate`] checks it (symmetric, positive semi-definite,
    /// closed, rank N − 1) and refuses it with the reason.
    pub fn with_covariance(mut self, covariance_arcsec2: Vec<f64>) -> LabResult {
        self.covariance = Some(covariance_arcsec2);
        self
    }
}

/// A laboratory left out of the reference, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Exclusion {
    /// The laboratory.
    pub lab: String,
    /// The reason in words: the test of every laboratory that failed and the subset that
    /// passes, with their χ² (the steps are in [`KeyComparison::search`]).
    pub reason: String,
}

/// The test of a whole closed vector (pitch deviations, or encoder errors less their mean).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct VectorTest {
    /// χ²_vector = Σ (x_i − x_ref)ᵀ V_i⁺ (x_i − x_ref).
    pub chi2: f64,
    /// ν = (N − 1)(n − 1).
    pub dof: usize,
    /// Whether χ² ≤ χ²_{0.95}(ν).
    pub consistent: bool,
    /// χ²_{0.95}(ν).
    #[serde(deserialize_with = "nullable::quantile")]
    pub chi2_critical: f64,
    /// The GLS reference vector x_ref = (Σ V_i⁺)⁺ Σ V_i⁺ x_i, arcseconds (empty for a
    /// pair's test, whose reference is of no use; NaN, `null` in the JSON, for an angle
    /// block no laboratory in the reference reports).
    #[serde(
        default,
        skip_serializing_if = "Vec::is_empty",
        deserialize_with = "nullable::numbers"
    )]
    pub reference: Vec<f64>,
}

impl VectorTest {
    /// The test of χ² with ν degrees of freedom at 5 %: consistent when χ² ≤ χ²_0.95(ν);
    /// no reference vector (a pair's or a link's test).
    pub(crate) fn at_five_percent(chi2: f64, dof: usize) -> VectorTest {
        let critical = chi2_quantile_95(dof);
        VectorTest {
            chi2,
            dof,
            consistent: chi2 <= critical,
            chi2_critical: critical,
            reference: Vec::new(),
        }
    }

    /// The test of a closed vector in words ([`Wording::statement`]; a comparison's
    /// own words are [`KeyComparison::vector_statement`]).
    pub fn statement(&self) -> String {
        Wording::of(Quantity::PitchDeviation).statement(self)
    }
}

/// A degree of equivalence: one laboratory (or pilot repeat) against the reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct DegreeOfEquivalence {
    /// The laboratory.
    pub lab: String,
    /// d_i = x_i − x_ref per quantity, arcseconds (NaN, `null` in the JSON, where the
    /// laboratory does not report an angle block).
    #[serde(deserialize_with = "nullable::numbers")]
    pub d: Vec<f64>,
    /// U(d_i) at k = 2 per quantity, arcseconds (NaN where `d` is).
    #[serde(rename = "U", deserialize_with = "nullable::numbers")]
    pub expanded_u: Vec<f64>,
    /// Whether the laboratory is in the reference.
    pub in_reference: bool,
    /// d_i against the linked reference (d_i + Δ per quantity, arcseconds; closed over the
    /// laboratory's own positions when laboratories report different encoder positions),
    /// when the comparison is linked to another ([`link`]).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "nullable::optional_numbers"
    )]
    pub d_linked: Option<Vec<f64>>,
    /// U of `d_linked` at k = 2 per quantity, arcseconds.
    #[serde(
        rename = "U_linked",
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "nullable::optional_numbers"
    )]
    pub expanded_u_linked: Option<Vec<f64>>,
    /// The Welch–Satterthwaite degrees of freedom of d_i per quantity (`None` in a list
    /// entry: infinitely many), when some laboratory states the degrees of freedom of its
    /// u (column `dof`); U is then k·u(d_i) with k below.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dof_effective: Option<Vec<Option<f64>>>,
    /// The coverage factor k = t_95.45(ν_eff) of U per quantity, with `dof_effective`
    /// (NaN, `null` in the JSON, where the laboratory does not report an angle block).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "nullable::optional_numbers"
    )]
    pub k: Option<Vec<f64>>,
}

/// A pair of laboratories: d_ij = x_i − x_j, U(d_ij) = 2·√(u_i² + u_j² + 2u_stab² + 2τ²)
/// (the diagonal of V_i + V_j), and the one test of the pair at 5 %.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct PairDifference {
    /// The first laboratory.
    pub a: String,
    /// The second.
    pub b: String,
    /// d_ab per quantity, arcseconds (NaN, `null` in the JSON, where either does not
    /// report an angle block).
    #[serde(deserialize_with = "nullable::numbers")]
    pub d: Vec<f64>,
    /// U(d_ab) at k = 2 per quantity, arcseconds: both laboratories' u, the pilot's
    /// stability u_stab and the dark uncertainty τ, each laboratory's (NaN where `d` is).
    #[serde(rename = "U", deserialize_with = "nullable::numbers")]
    pub expanded_u: Vec<f64>,
    /// The pair's closed-vector test at 5 %: χ² = d_abᵀ (V_a + V_b)⁺ d_ab with
    /// ν = N − 1, the covariances as in U(d_ab). Whether the two laboratories agree is
    /// this one decision, not a test per position (`None` in JSON written before it).
    #[serde(default)]
    pub vector: Option<VectorTest>,
}

impl PairDifference {
    /// The position where |d_ab|/U(d_ab) is largest (the first of equals), and that ratio
    /// (`None` with no position both report): what the pairwise figure shows of a pair.
    pub fn largest_ratio(&self) -> Option<(usize, f64)> {
        let ratios = self
            .d
            .iter()
            .zip(&self.expanded_u)
            .map(|(d, u)| d.abs() / u);
        ratios
            .enumerate()
            // (a block one of them does not report has no ratio)
            .filter(|(_, ratio)| ratio.is_finite())
            .fold(None, |best: Option<(usize, f64)>, (k, ratio)| match best {
                Some((_, largest)) if ratio <= largest => best,
                _ => Some((k, ratio)),
            })
    }

    /// How many positions have |d_ab| > U(d_ab).
    pub fn exceeding(&self) -> usize {
        self.d
            .iter()
            .zip(&self.expanded_u)
            .filter(|(d, u)| d.abs() > **u)
            .count()
    }
}

/// The pilot's repeated results (start, middle, end of the circulation): how stable the
/// artefact was. One test at 5 %: the repeats' closed vectors, χ² about their GLS reference
/// with ν = (N − 1)(m − 1). When it fails, the repeats' sample standard deviation
/// s = √(Σ (y_r − ȳ)²/(m − 1)) on each quantity is the instability u_stab, added in
/// quadrature to u_ref and to every u(d_i). Per quantity, χ² about the weighted mean is
/// information.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct PilotStability {
    /// The repeats' names, in the order given.
    pub repeats: Vec<String>,
    /// The repeats' plain mean ȳ per quantity, arcseconds.
    pub mean: Vec<f64>,
    /// Their sample standard deviation s per quantity, arcseconds.
    pub spread: Vec<f64>,
    /// χ² of the repeats about their weighted mean per quantity.
    pub chi2: Vec<f64>,
    /// m − 1.
    pub chi2_dof: usize,
    /// Whether χ² > χ²_{0.95}(m − 1) per quantity (information: the decision is
    /// [`PilotStability::vector`]'s).
    pub significant: Vec<bool>,
    /// u_stab per quantity: s on every quantity when the repeats' closed vector fails its
    /// test, else 0, arcseconds.
    pub stability_u: Vec<f64>,
    /// The one test of the repeats' closed vectors at 5 %, ν = (N − 1)(m − 1).
    #[serde(default)]
    pub vector: Option<VectorTest>,
    /// Each repeat against the reference (never in it).
    pub degrees_of_equivalence: Vec<DegreeOfEquivalence>,
    /// The pilot's test and what follows from it, in words
    /// ([`KeyComparison::pilot_statement`]), for readers of the JSON.
    #[serde(default)]
    pub statement: String,
}

/// A key comparison evaluated. Serializes to the JSON of docs/FORMAT.md §12, and reads it
/// back (`polycal report --kc`, [`crate::certificate::KeyComparisonSection`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct KeyComparison {
    /// The compared quantity.
    pub quantity: Quantity,
    /// The reference method.
    pub method: ReferenceMethod,
    /// Face 1 … N, or the first laboratory's index of each common encoder error.
    pub index: Vec<u32>,
    /// The table angle of each common encoder error, degrees (when matched by angle).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<Vec<f64>>,
    /// The nominal angle of each angle block, degrees, where the results state it (`None`
    /// in a list entry: not stated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal_deg: Option<Vec<Option<f64>>>,
    /// The laboratories, in the order given.
    pub labs: Vec<String>,
    /// The reference value per quantity, arcseconds (NaN, `null` in the JSON, for an angle
    /// block no laboratory in the reference reports).
    #[serde(deserialize_with = "nullable::numbers")]
    pub reference: Vec<f64>,
    /// Its standard uncertainty per quantity (with u_stab where the pilot's repeats call
    /// for it), arcseconds.
    #[serde(deserialize_with = "nullable::numbers")]
    pub reference_u: Vec<f64>,
    /// χ² per quantity, about the weighted mean of the laboratories in the reference.
    pub chi2: Vec<f64>,
    /// n − 1 per quantity.
    pub chi2_dof: Vec<usize>,
    /// χ²_{0.95}(n − 1) per quantity (+∞, `null` in the JSON, where n = 1).
    #[serde(deserialize_with = "nullable::quantiles")]
    pub chi2_critical: Vec<f64>,
    /// Whether χ² ≤ χ²_{0.95}(n − 1) per quantity.
    pub consistent: Vec<bool>,
    /// The closed vector's test of the laboratories in the reference (with τ for
    /// DerSimonian–Laird).
    pub vector: Option<VectorTest>,
    /// The closed vector's test of every laboratory, before any exclusion: the one
    /// decision of the comparison's consistency.
    #[serde(default)]
    pub vector_all: Option<VectorTest>,
    /// The search for the largest consistent subset, when the test of every laboratory
    /// failed (weighted mean).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub search: Option<SubsetSearch>,
    /// The laboratories held in the reference whatever the tests say.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub kept: Vec<String>,
    /// The laboratories kept out of the reference by the pilot's decision (with degrees of
    /// equivalence, `in_reference` false; not in `excluded`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_in_reference: Vec<String>,
    /// The laboratories left out, in the order given.
    pub excluded: Vec<Exclusion>,
    /// The dark uncertainty τ per quantity (0 for the weighted mean), arcseconds.
    pub tau: Vec<f64>,
    /// Every laboratory against the reference, in the order given.
    pub degrees_of_equivalence: Vec<DegreeOfEquivalence>,
    /// Every pair of laboratories (formed when read).
    pub pairs: Pairs,
    /// The pilot's repeats, when given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pilot: Option<PilotStability>,
    /// The link to another comparison through the laboratories in both ([`link`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link: Option<Link>,
    /// Whether the comparison is consistent: the closed vector of every laboratory passes,
    /// or (weighted mean) a subset passes after the stated exclusions; for
    /// DerSimonian–Laird, whether τ = 0 passes (the vector of every laboratory).
    pub comparison_consistent: bool,
    /// The laboratories the largest consistent subset would have left out when they were
    /// more than half of them: nobody is left out, and the comparison is not consistent
    /// (the stated uncertainties look too small for the spread of the results).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub withheld: Vec<String>,
    /// What was left out or added, in words.
    pub notes: Vec<String>,
}
