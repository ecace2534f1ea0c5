//! GUM uncertainty budgets (JCGM 100:2008, the law of propagation of uncertainty).
//!
//! A [`Budget`] lists the [`Component`]s of a measurement model `Y = f(X₁, …, X_N)`: each
//! with its standard uncertainty `u(xᵢ)` (from a [`Distribution`]), its sensitivity
//! coefficient `cᵢ = ∂f/∂xᵢ` and its degrees of freedom `νᵢ`. [`Budget::evaluate`] gives
//!
//! - the contributions `uᵢ(y) = |cᵢ| u(xᵢ)` (GUM 5.1.3),
//! - the combined standard uncertainty `u_c = √(Σ uᵢ(y)² + 2 Σ_{i<j} cᵢ cⱼ u(xᵢ) u(xⱼ) r(xᵢ, xⱼ))`
//!   (GUM 5.1.2 and 5.2.2),
//! - the effective degrees of freedom by Welch–Satterthwaite,
//!   `ν_eff = u_c⁴ / Σ uᵢ(y)⁴/νᵢ` (GUM G.4.1), from the unrounded values,
//! - each component's index, `100 · uᵢ(y)² / u_c²` %,
//! - the coverage factor `k` (Student's t at `p` for `ν_eff`, see [`DofPolicy`]) and the
//!   expanded uncertainty `U = k·u_c`.
//!
//! A component may itself be a budget (a *nested* budget: an intermediate quantity such as
//! the paper's "measured value" `u(α)`, combined from five sources). Its standard
//! uncertainty is the nested budget's `u_c` and its degrees of freedom the nested `ν_eff`,
//! both unrounded. Because Welch–Satterthwaite composes exactly (`u_c(α)⁴/ν_eff(α) =
//! Σ uᵢ⁴/νᵢ`), nesting gives the same `u_c` and `ν_eff` as listing the sources flat.
//!
//! The budget files of docs/FORMAT.md §5 are read by [`crate::uncertainty::budget_file`].

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use super::distribution::{Distribution, DistributionError};
use super::student::t_quantile;
use crate::input::Location;
use crate::input::limits::{BUDGET_VALUE, LimitError};

/// The most correlation coefficients a budget may give (docs/FORMAT.md §5.3): their
/// consistency is checked on the matrix of the components they name (at most twice as
/// many), whose Cholesky factorization takes a time growing with the cube of their number.
pub const MAX_CORRELATIONS: usize = 1000;

/// How a standard uncertainty was evaluated (GUM 4.2 and 4.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum EvaluationType {
    /// Type A: by statistical analysis of series of observations.
    A,
    /// Type B: by other means (certificates, specifications, experience).
    B,
}

impl fmt::Display for EvaluationType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            EvaluationType::A => "A",
            EvaluationType::B => "B",
        })
    }
}

/// The type shown for a component in a result: that of an input, or, for a nested budget,
/// `A+B` when it combines both types.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum ResultType {
    /// Type A only.
    A,
    /// Type B only.
    B,
    /// A nested budget combining Type A and Type B components.
    #[serde(rename = "A+B")]
    Mixed,
}

impl ResultType {
    fn join(self, other: ResultType) -> ResultType {
        if self == other {
            self
        } else {
            ResultType::Mixed
        }
    }
}

impl From<EvaluationType> for ResultType {
    fn from(t: EvaluationType) -> ResultType {
        match t {
            EvaluationType::A => ResultType::A,
            EvaluationType::B => ResultType::B,
        }
    }
}

impl fmt::Display for ResultType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ResultType::A => "A",
            ResultType::B => "B",
            ResultType::Mixed => "A+B",
        })
    }
}

/// How the coverage factor `k` follows from the effective degrees of freedom.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DofPolicy {
    /// `k = t_p(ν_eff)` with `ν_eff` as computed, fractional (`"fractional"`, the default).
    #[default]
    Fractional,
    /// `k = t_p(⌊ν_eff⌋)`: `ν_eff` rounded down to an integer, as GUM G.4.1 prescribes for
    /// tables of integer `ν` (`"floor"`).
    Floor,
    /// `k = 2` whatever `ν_eff` (`"k2"`); `ν_eff` is still computed and reported.
    K2,
}

impl DofPolicy {
    /// The spelling in files and outputs: `fractional`, `floor` or `k2`.
    pub fn as_str(self) -> &'static str {
        match self {
            DofPolicy::Fractional => "fractional",
            DofPolicy::Floor => "floor",
            DofPolicy::K2 => "k2",
        }
    }
}

impl fmt::Display for DofPolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for DofPolicy {
    type Err = BudgetError;

    /// Reads `fractional`, `floor` or `k2`.
    ///
    /// # Errors
    ///
    /// [`BudgetError::UnknownDofPolicy`] for any other text.
    fn from_str(s: &str) -> Result<DofPolicy, BudgetError> {
        match s {
            "fractional" => Ok(DofPolicy::Fractional),
            "floor" => Ok(DofPolicy::Floor),
            "k2" => Ok(DofPolicy::K2),
            other => Err(BudgetError::UnknownDofPolicy(other.to_string())),
        }
    }
}

/// What a component's standard uncertainty comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// An input quantity with a distribution.
    Input {
        /// Type A or B.
        evaluation: EvaluationType,
        /// Its distribution; the standard uncertainty is
        /// [`Distribution::standard_uncertainty`].
        distribution: Distribution,
        /// Degrees of freedom, `None` for infinitely many. For a t distribution this is its
        /// `ν` (and must equal it if both are given).
        dof: Option<f64>,
    },
    /// A nested budget: the component's standard uncertainty is the nested `u_c`, its
    /// degrees of freedom the nested `ν_eff` (Welch–Satterthwaite, unrounded).
    Budget(Budget),
}

/// One line of a budget: a named input quantity, or a nested budget, with its sensitivity
/// coefficient.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    /// Name of the quantity (unique within its budget).
    pub name: String,
    /// Sensitivity coefficient `cᵢ = ∂f/∂xᵢ` (default 1).
    pub sensitivity: f64,
    /// Where the standard uncertainty comes from.
    pub source: Source,
}

impl Component {
    /// A Type A input with sensitivity 1. `dof` is `None` for infinitely many degrees of
    /// freedom (for a t distribution, `None` takes its `ν`).
    pub fn type_a(name: impl Into<String>, distribution: Distribution, dof: Option<f64>) -> Self {
        Component::input(name, EvaluationType::A, distribution, dof)
    }

    /// A Type B input with sensitivity 1; see [`Component::type_a`].
    pub fn type_b(name: impl Into<String>, distribution: Distribution, dof: Option<f64>) -> Self {
        Component::input(name, EvaluationType::B, distribution, dof)
    }

    /// An input of either type with sensitivity 1.
    pub fn input(
        name: impl Into<String>,
        evaluation: EvaluationType,
        distribution: Distribution,
        dof: Option<f64>,
    ) -> Self {
        Component {
            name: name.into(),
            sensitivity: 1.0,
            source: Source::Input {
                evaluation,
                distribution,
                dof: dof.or(distribution.own_dof()),
            },
        }
    }

    /// A nested budget as a component, with sensitivity 1.
    pub fn nested(name: impl Into<String>, budget: Budget) -> Self {
        Component {
            name: name.into(),
            sensitivity: 1.0,
            source: Source::Budget(budget),
        }
    }

    /// The same component with sensitivity coefficient `c`.
    pub fn with_sensitivity(mut self, c: f64) -> Self {
        self.sensitivity = c;
        self
    }
}

/// A correlation coefficient `r(xᵢ, xⱼ)` between two components of the same budget
/// (GUM 5.2.2), named by their names.
#[derive(Debug, Clone, PartialEq)]
pub struct Correlation {
    /// Name of the first component.
    pub a: String,
    /// Name of the second component.
    pub b: String,
    /// Correlation coefficient, `−1 ≤ r ≤ 1`.
    pub r: f64,
}

/// An uncertainty budget: components and, optionally, correlations between them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Budget {
    /// The components, in the order they are reported.
    pub components: Vec<Component>,
    /// Correlation coefficients between components (all others are uncorrelated).
    pub correlations: Vec<Correlation>,
}

/// Why one component of a budget is refused (the message after the component's name,
/// [`BudgetError::Component`], [`crate::uncertainty::calibration::CalibrationError::Component`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ComponentError {
    /// A name that is empty or white space.
    #[error("the name is empty")]
    EmptyName,
    /// A sensitivity coefficient that is not finite.
    #[error("sensitivity must be a finite number, got {sensitivity}")]
    SensitivityNotFinite {
        /// The sensitivity coefficient.
        sensitivity: f64,
    },
    /// A sensitivity coefficient beyond the limits of a budget value (docs/FORMAT.md §2.2).
    #[error("sensitivity: {0}")]
    SensitivityBeyondLimits(Box<LimitError>),
    /// An invalid distribution.
    #[error(transparent)]
    Distribution(#[from] DistributionError),
    /// Degrees of freedom below 1 (or not a number).
    #[error("degrees of freedom must be at least 1 ({infinite} for infinitely many), got {dof}")]
    DofBelowOne {
        /// The degrees of freedom.
        dof: f64,
        /// How infinitely many are written where the component came from: `omit them`
        /// (a budget file), `None` (a budget in memory).
        infinite: &'static str,
    },
    /// Degrees of freedom that differ from those of the component's t distribution.
    #[error("the t distribution has {own} degrees of freedom but dof = {given}")]
    DofDisagrees {
        /// The t distribution's degrees of freedom.
        own: f64,
        /// The component's `dof`.
        given: f64,
    },
    /// A standard uncertainty beyond the limits of a budget value.
    #[error("the standard uncertainty: {0}")]
    StandardUncertaintyBeyondLimits(Box<LimitError>),
    /// A contribution |cᵢ|·uᵢ beyond the limits of a budget value.
    #[error("the contribution |cᵢ|·uᵢ: {0}")]
    ContributionBeyondLimits(Box<LimitError>),
    /// An instrument's contribution |c|·u beyond the largest reading (docs/FORMAT.md §2.2),
    /// so that a result it adds to could leave the limits of a result file.
    #[error("its contribution |c|·u: {0}")]
    ContributionBeyondReadings(Box<LimitError>),
    /// A known correction whose column is not one finite value per reading, or whose u is
    /// not a finite number ≥ 0.
    #[error("needs one finite value per reading ({readings}) and a finite u ≥ 0")]
    CorrectionColumn {
        /// The number of readings.
        readings: usize,
    },
}

/// Why a budget cannot be read or evaluated. Budgets read from a file are reported with
/// the file, line and column where possible ([`BudgetError::File`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BudgetError {
    /// A problem at a place in a budget file.
    #[error("{location}: {message}")]
    File {
        /// File (named [`crate::input::STDIN_NAME`] for standard input), line and column.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// A problem of a whole budget read from a file (no single place to point at).
    #[error("{location}: {error}")]
    InFile {
        /// The file.
        location: Location,
        /// The problem.
        error: Box<BudgetError>,
    },
    /// A file of another kind given as a budget: a measurement file, a result file, …
    /// (docs/FORMAT.md §8). Displayed as `file:line:column: … this is a measurement file
    /// (…), not a budget`.
    #[error("{location}: {message}")]
    WrongKind {
        /// Where: the file and the line that tells its kind.
        location: Location,
        /// What the file is, and what was expected.
        message: String,
        /// What the file is.
        found: crate::input::kind::FileKind,
    },
    /// The file could not be read.
    #[error("{location}: {source}")]
    Io {
        /// The file.
        location: Location,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A `dof_policy` that is not `fractional`, `floor` or `k2`.
    #[error("unknown dof_policy {0:?}: expected \"fractional\", \"floor\" or \"k2\"")]
    UnknownDofPolicy(String),
    /// An `acts_on` that is not one of the scopes of an instrument budget
    /// ([`crate::uncertainty::calibration::Scope`]).
    #[error(
        "unknown acts_on {0:?}: expected \"each-reading\", \"each-autocollimator\", \
         \"each-position\", \"each-stop\" or \"result\""
    )]
    UnknownScope(String),
    /// The coverage probability is not within 0.5 … 0.9999 (docs/FORMAT.md §2.2).
    #[error("coverage probability p must be within 0.5 … 0.9999 (docs/FORMAT.md §2.2), got {0}")]
    Coverage(f64),
    /// A budget without components.
    #[error("budget {0}has no components")]
    Empty(String),
    /// A component's specification is invalid.
    #[error("component {component:?}: {problem}")]
    Component {
        /// The component's name (nested names joined by ` / `).
        component: String,
        /// What is wrong.
        problem: ComponentError,
    },
    /// Two components of one budget share a name.
    #[error("two components are named {0:?}: names must be unique within a budget")]
    DuplicateName(String),
    /// A correlation is invalid (unknown name, `|r| > 1`, duplicate pair, …).
    #[error("correlation between {a:?} and {b:?}: {message}")]
    Correlation {
        /// First name.
        a: String,
        /// Second name.
        b: String,
        /// What is wrong.
        message: String,
    },
    /// The correlation coefficients do not form a positive semi-definite matrix.
    #[error(
        "the correlation coefficients are inconsistent (their matrix is not positive \
         semi-definite), e.g. r(a,b) = r(b,c) = 0.9 with r(a,c) = -0.9"
    )]
    NotPositiveSemidefinite,
    /// Welch–Satterthwaite does not apply to correlated inputs with finite degrees of
    /// freedom.
    #[error(
        "components {a:?} and {b:?} are correlated and at least one has finite degrees of \
         freedom: the Welch–Satterthwaite formula holds for independent inputs only; give \
         correlated inputs infinite degrees of freedom (omit dof) if that is justified, or \
         use Monte Carlo"
    )]
    CorrelatedFiniteDof {
        /// First name.
        a: String,
        /// Second name.
        b: String,
    },
    /// More correlation coefficients than a budget may give ([`MAX_CORRELATIONS`]): their
    /// consistency check needs a matrix of the correlated components, and its time grows
    /// with the cube of their number.
    #[error(
        "the budget gives {given} correlation coefficients; at most {max} are evaluated \
         (their consistency is checked on a matrix of the correlated components)"
    )]
    TooManyCorrelations {
        /// The number of coefficients given.
        given: usize,
        /// The most allowed.
        max: usize,
    },
    /// The sum of the squared contributions overflows (not reached by components within
    /// their limits, docs/FORMAT.md §2.2).
    #[error(
        "the combined standard uncertainty overflows: the contributions are too large to \
         square and add (docs/FORMAT.md §2.2)"
    )]
    Overflow,
    /// The combined standard uncertainty is zero (or the correlations make it negative).
    #[error(
        "the combined standard uncertainty is {0}: every contribution is zero (or negative \
         correlations cancel them); nothing to expand"
    )]
    NoUncertainty(f64),
    /// `⌊ν_eff⌋ < 1` under the floor policy.
    #[error("effective degrees of freedom {0} round down to 0: no t factor; use \"fractional\"")]
    FloorBelowOne(f64),
}

/// The evaluated line of a component.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComponentResult {
    /// Name of the quantity.
    pub name: String,
    /// Type A, B (or `A+B` for a nested budget combining both).
    #[serde(rename = "type")]
    pub evaluation: ResultType,
    /// Standard uncertainty `u(xᵢ)` (for a nested budget: its `u_c`).
    pub u: f64,
    /// Sensitivity coefficient `cᵢ`.
    pub sensitivity: f64,
    /// Contribution `uᵢ(y) = |cᵢ| u(xᵢ)` to the uncertainty of this component's budget.
    pub contribution: f64,
    /// Degrees of freedom `νᵢ` (for a nested budget: its `ν_eff`), `null` if infinite.
    pub dof: Option<f64>,
    /// `normal`, `rectangular`, `triangular`, `arcsine`, `t`, or `budget` (nested).
    pub distribution: String,
    /// Share of the *top-level* `u_c²`, in percent: `100·(c·uᵢ(y))²/u_c²` with `c` the
    /// product of the sensitivities of the enclosing nested components. Without
    /// correlations the indices of a budget sum to 100 (and those of a nested budget to its
    /// own index); covariance terms are not attributed to components.
    pub index_percent: f64,
    /// The evaluated components of a nested budget (absent for an input).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub components: Vec<ComponentResult>,
}

/// The evaluated budget. Serializes to the JSON of docs/FORMAT.md §5 (`polycal budget`), with
/// the extra fields `distribution`, `index_percent` (and `components` of nested budgets)
/// in each component.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BudgetResult {
    /// The evaluated components, in budget order.
    pub components: Vec<ComponentResult>,
    /// Combined standard uncertainty `u_c`.
    pub combined_u: f64,
    /// Effective degrees of freedom (Welch–Satterthwaite, unrounded), `null` if infinite.
    pub dof_eff: Option<f64>,
    /// Coverage factor.
    pub k: f64,
    /// Expanded uncertainty `U = k·u_c`.
    pub expanded_u: f64,
    /// Coverage probability.
    pub p: f64,
    /// How `k` was obtained.
    pub dof_policy: DofPolicy,
}

impl BudgetResult {
    /// The degrees of freedom `k` was computed with: `ν_eff`, `⌊ν_eff⌋` (floor policy), or
    /// `None` when infinite or when the policy is `k2`.
    pub fn dof_for_k(&self) -> Option<f64> {
        match self.dof_policy {
            DofPolicy::Fractional => self.dof_eff,
            DofPolicy::Floor => self.dof_eff.map(f64::floor),
            DofPolicy::K2 => None,
        }
    }
}

/// The combination of a budget without a coverage factor: `u_c`, `ν_eff` and the
/// component lines. What a nested budget contributes to its parent.
#[derive(Debug, Clone, PartialEq)]
pub struct Combined {
    /// The evaluated components (indices relative to this budget's `u_c²`).
    pub components: Vec<ComponentResult>,
    /// Combined standard uncertainty.
    pub combined_u: f64,
    /// Effective degrees of freedom, `None` if infinite.
    pub dof_eff: Option<f64>,
    /// Type of the whole: `A`, `B` or `A+B`.
    pub evaluation: ResultType,
}

impl Budget {
    /// A budget of uncorrelated components.
    pub fn new(components: Vec<Component>) -> Budget {
        Budget {
            components,
            correlations: Vec::new(),
        }
    }

    /// The same budget with a correlation coefficient `r` between the components named
    /// `a` and `b`.
    pub fn with_correlation(mut self, a: impl Into<String>, b: impl Into<String>, r: f64) -> Self {
        self.correlations.push(Correlation {
            a: a.into(),
            b: b.into(),
            r,
        });
        self
    }

    /// Evaluates the budget at coverage probability `p` (e.g. 0.95) with the given
    /// degrees-of-freedom policy: contributions, `u_c`, `ν_eff`, indices, `k`, `U`.
    ///
    /// # Errors
    ///
    /// A [`BudgetError`] naming the problem: `p` outside (0, 1); an empty budget; a
    /// negative or non-finite width, uncertainty, `k` or sensitivity; `ν < 1`; duplicate
    /// names; an invalid or inconsistent correlation; correlated inputs with finite `ν`
    /// (Welch–Satterthwaite does not apply); a zero combined uncertainty.
    ///
    /// # Examples
    ///
    /// The uncertainty of the angle error `u(α)` in Table 1 of the reference paper
    /// (Hsieh et al., Appl. Sci. 2023, 13, 1865), from its five sources:
    ///
    /// ```
    /// use polycal::uncertainty::budget::{Budget, Component, DofPolicy};
    /// use polycal::uncertainty::distribution::Distribution;
    ///
    /// let budget = Budget::new(vec![
    ///     Component::type_a("Repeatability", Distribution::Normal { u: 0.0450 }, Some(5.0)),
    ///     Component::type_b("Autocollimator resolution",
    ///         Distribution::rectangular_full_width(0.001), Some(50.0)),
    ///     Component::type_b("Autocollimator traceability",
    ///         Distribution::normal_expanded(0.01, 2.0), Some(60.0)),
    ///     Component::type_b("Autocollimator angle error",
    ///         Distribution::rectangular_full_width(0.27), Some(50.0)),
    ///     Component::type_b("Encoder resolution",
    ///         Distribution::rectangular_full_width(0.04), Some(50.0)),
    /// ]);
    /// let r = budget.evaluate(0.95, DofPolicy::Fractional)?;
    /// assert!((r.combined_u - 0.0909).abs() < 5e-5);      // the paper prints 0.0910
    /// assert!((r.dof_eff.unwrap() - 43.8).abs() < 0.05);  // the paper prints 43
    /// assert!((r.k - 2.016).abs() < 5e-4);
    /// assert!((r.expanded_u - r.k * r.combined_u).abs() < 1e-15);
    /// # Ok::<(), polycal::uncertainty::budget::BudgetError>(())
    /// ```
    pub fn evaluate(&self, p: f64, policy: DofPolicy) -> Result<BudgetResult, BudgetError> {
        if !crate::input::limits::COVERAGE_PROBABILITY.contains(p) {
            return Err(BudgetError::Coverage(p));
        }
        let combined = self.combine()?;
        let dof_for_k = match policy {
            DofPolicy::Fractional => combined.dof_eff,
            DofPolicy::Floor => match combined.dof_eff {
                Some(nu) if nu.floor() < 1.0 => return Err(BudgetError::FloorBelowOne(nu)),
                other => other.map(f64::floor),
            },
            DofPolicy::K2 => None,
        };
        let k = match policy {
            DofPolicy::K2 => 2.0,
            _ => t_quantile(p, dof_for_k),
        };
        let mut components = combined.components;
        scale_nested_indices(&mut components, 1.0);
        Ok(BudgetResult {
            components,
            combined_u: combined.combined_u,
            dof_eff: combined.dof_eff,
            k,
            expanded_u: k * combined.combined_u,
            p,
            dof_policy: policy,
        })
    }

    /// Combines the budget without a coverage factor: `u_c`, `ν_eff` and the component lines
    /// (nested budgets' component indices relative to their own `u_c²`).
    ///
    /// # Errors
    ///
    /// As [`Budget::evaluate`], except for `p`.
    pub fn combine(&self) -> Result<Combined, BudgetError> {
        self.combine_at("")
    }

    fn combine_at(&self, prefix: &str) -> Result<Combined, BudgetError> {
        if self.components.is_empty() {
            let label = if prefix.is_empty() {
                String::new()
            } else {
                format!("{:?} ", prefix.trim_end_matches(" / "))
            };
            return Err(BudgetError::Empty(label));
        }
        let mut lines = Vec::with_capacity(self.components.len());
        let mut by_name: HashMap<&str, usize> = HashMap::new();
        let mut evaluation: Option<ResultType> = None;
        for (i, c) in self.components.iter().enumerate() {
            let path = format!("{prefix}{}", c.name);
            let bad = |problem: ComponentError| BudgetError::Component {
                component: path.clone(),
                problem,
            };
            if c.name.trim().is_empty() {
                return Err(bad(ComponentError::EmptyName));
            }
            if by_name.insert(c.name.as_str(), i).is_some() {
                return Err(BudgetError::DuplicateName(path));
            }
            if !c.sensitivity.is_finite() {
                return Err(bad(ComponentError::SensitivityNotFinite {
                    sensitivity: c.sensitivity,
                }));
            }
            BUDGET_VALUE
                .check(c.sensitivity, "a sensitivity")
                .map_err(|rule| bad(ComponentError::SensitivityBeyondLimits(Box::new(rule))))?;
            let line = match &c.source {
                Source::Input {
                    evaluation,
                    distribution,
                    dof,
                } => {
                    distribution.check().map_err(|e| bad(e.into()))?;
                    let dof = check_dof(*dof).map_err(bad)?;
                    if let (Some(own), Some(given)) = (distribution.own_dof(), dof)
                        && own != given
                    {
                        return Err(bad(ComponentError::DofDisagrees { own, given }));
                    }
                    let u = distribution.standard_uncertainty();
                    BUDGET_VALUE
                        .check(u, "a standard uncertainty")
                        .map_err(|rule| {
                            bad(ComponentError::StandardUncertaintyBeyondLimits(Box::new(
                                rule,
                            )))
                        })?;
                    ComponentResult {
                        name: c.name.clone(),
                        evaluation: (*evaluation).into(),
                        u,
                        sensitivity: c.sensitivity,
                        contribution: c.sensitivity.abs() * u,
                        dof,
                        distribution: distribution.name().to_string(),
                        index_percent: 0.0,
                        components: Vec::new(),
                    }
                }
                Source::Budget(nested) => {
                    let inner = nested.combine_at(&format!("{path} / "))?;
                    ComponentResult {
                        name: c.name.clone(),
                        evaluation: inner.evaluation,
                        u: inner.combined_u,
                        sensitivity: c.sensitivity,
                        contribution: c.sensitivity.abs() * inner.combined_u,
                        dof: inner.dof_eff,
                        distribution: "budget".to_string(),
                        index_percent: 0.0,
                        components: inner.components,
                    }
                }
            };
            BUDGET_VALUE
                .check(line.contribution, "a contribution |cᵢ|·uᵢ")
                .map_err(|rule| bad(ComponentError::ContributionBeyondLimits(Box::new(rule))))?;
            evaluation = Some(match evaluation {
                None => line.evaluation,
                Some(e) => e.join(line.evaluation),
            });
            lines.push(line);
        }

        // Correlations: the covariance terms, and the consistency of the coefficients,
        // checked on the matrix of the correlated components alone (the others are
        // independent of everything), so that a budget without correlations combines
        // in O(n).
        let mut covariance_sum = 0.0;
        let mut correlated_pairs = Vec::new();
        if self.correlations.len() > MAX_CORRELATIONS {
            return Err(BudgetError::TooManyCorrelations {
                given: self.correlations.len(),
                max: MAX_CORRELATIONS,
            });
        }
        for corr in &self.correlations {
            let bad = |message: String| BudgetError::Correlation {
                a: format!("{prefix}{}", corr.a),
                b: format!("{prefix}{}", corr.b),
                message,
            };
            let i = *by_name
                .get(corr.a.as_str())
                .ok_or_else(|| bad(format!("no component is named {:?}", corr.a)))?;
            let j = *by_name
                .get(corr.b.as_str())
                .ok_or_else(|| bad(format!("no component is named {:?}", corr.b)))?;
            if i == j {
                return Err(bad("a component cannot be correlated with itself".into()));
            }
            if !(corr.r.is_finite() && (-1.0..=1.0).contains(&corr.r)) {
                return Err(bad(format!("r must be between -1 and 1, got {}", corr.r)));
            }
            if correlated_pairs.contains(&(i.min(j), i.max(j))) {
                return Err(bad("this pair is given twice".into()));
            }
            correlated_pairs.push((i.min(j), i.max(j)));
            if corr.r != 0.0 {
                if lines[i].dof.is_some() || lines[j].dof.is_some() {
                    return Err(BudgetError::CorrelatedFiniteDof {
                        a: format!("{prefix}{}", lines[i].name),
                        b: format!("{prefix}{}", lines[j].name),
                    });
                }
                let si = lines[i].sensitivity * lines[i].u;
                let sj = lines[j].sensitivity * lines[j].u;
                covariance_sum += 2.0 * corr.r * si * sj;
            }
        }
        if !correlated_pairs.is_empty() && !consistent(&self.correlations, &correlated_pairs) {
            return Err(BudgetError::NotPositiveSemidefinite);
        }

        let variance: f64 = lines
            .iter()
            .map(|l| l.contribution * l.contribution)
            .sum::<f64>()
            + covariance_sum;
        if !variance.is_finite() {
            // Not reached with contributions within their limits (their squares sum to
            // at most n·1e200); said plainly rather than as a zero uncertainty.
            return Err(BudgetError::Overflow);
        }
        if variance <= 0.0 {
            return Err(BudgetError::NoUncertainty(variance.max(0.0).sqrt()));
        }
        let combined_u = variance.sqrt();
        // Welch–Satterthwaite, GUM (G.2b), with the unrounded contributions, each taken
        // as its share of u_c: ν_eff = 1 / Σ (cᵢuᵢ/u_c)⁴/νᵢ, so that no fourth power of a
        // large contribution overflows.
        let denominator: f64 = lines
            .iter()
            .filter_map(|l| l.dof.map(|nu| (l.contribution / combined_u).powi(4) / nu))
            .sum();
        let dof_eff = (denominator > 0.0)
            .then(|| 1.0 / denominator)
            .filter(|nu| nu.is_finite());
        for l in &mut lines {
            l.index_percent = 100.0 * l.contribution * l.contribution / variance;
        }
        Ok(Combined {
            components: lines,
            combined_u,
            dof_eff,
            evaluation: evaluation.unwrap_or(ResultType::B),
        })
    }
}

/// Degrees of freedom: `None`/`+∞` = infinite; otherwise finite and ≥ 1.
fn check_dof(dof: Option<f64>) -> Result<Option<f64>, ComponentError> {
    match dof {
        None => Ok(None),
        Some(nu) if nu == f64::INFINITY => Ok(None),
        Some(nu) if nu.is_finite() && nu >= 1.0 => Ok(Some(nu)),
        Some(dof) => Err(ComponentError::DofBelowOne {
            dof,
            infinite: "omit them",
        }),
    }
}

/// Rescales the indices of nested components from "share of their budget" to "share of
/// the top-level budget".
fn scale_nested_indices(lines: &mut [ComponentResult], factor: f64) {
    for l in lines {
        l.index_percent *= factor;
        let inner = l.index_percent / 100.0;
        scale_nested_indices(&mut l.components, inner);
    }
}

/// Whether the correlation coefficients of `pairs` (component indices, smaller first;
/// `correlations` in the same order) form a positive semi-definite matrix over the
/// components they name. At most [`MAX_CORRELATIONS`] pairs, so at most twice as many
/// components: the matrix is built over those alone.
fn consistent(correlations: &[Correlation], pairs: &[(usize, usize)]) -> bool {
    let mut members: Vec<usize> = pairs.iter().flat_map(|&(i, j)| [i, j]).collect();
    members.sort_unstable();
    members.dedup();
    let n = members.len();
    let at = |i: usize| members.binary_search(&i).unwrap_or(0);
    let mut m = vec![0.0; n * n];
    for i in 0..n {
        m[i * n + i] = 1.0;
    }
    for (corr, &(i, j)) in correlations.iter().zip(pairs) {
        let (a, b) = (at(i), at(j));
        m[a * n + b] = corr.r;
        m[b * n + a] = corr.r;
    }
    positive_semidefinite(&m, n)
}

/// Whether the symmetric `n × n` matrix is positive semi-definite (Cholesky with a small
/// tolerance for rounding).
fn positive_semidefinite(m: &[f64], n: usize) -> bool {
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let mut d = m[j * n + j];
        for k in 0..j {
            d -= l[j * n + k] * l[j * n + k];
        }
        if d < -1e-12 {
            return false;
        }
        let d = d.max(0.0).sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            let mut s = m[i * n + j];
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            l[i * n + j] = if d > 1e-12 {
                s / d
            } else if s.abs() > 1e-9 {
                return false;
            } else {
                0.0
            };
        }
    }
    true
}
