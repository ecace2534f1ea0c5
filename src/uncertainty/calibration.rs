//! Uncertainty of the calibration results: the fit's covariance (type A) combined with
//! the instrument's type-B budget, per quantity and from the actual design (GUM), and the
//! same propagated by Monte Carlo through the solver (GUM Supplement 1, JCGM 101:2008).
//!
//! # The propagation (GUM)
//!
//! The solver is linear in the readings: θ̂ = L y with θ = [β (N), α (N), U (K)], and for
//! independent readings of equal weight Cov(θ̂) = σ² Q with Q = L Lᵀ the fit's cofactor
//! matrix ([`Solution::cofactor`]); L = Q Xᵀ with X the design matrix of the model, so
//! L is built from Q without solving again. A type-B component is an error of the
//! readings; its *scope* says which readings share one draw of it. If the readings of
//! group g share the error e_g (standard uncertainty u, independent between groups),
//! quantity j moves by Σ_g e_g Σ_{i∈g} L_ji and receives
//!
//! ```text
//! u_j² = u² · G_j,   G_j = Σ_g (Σ_{i∈g} L_ji)²
//! ```
//!
//! | `acts_on` | one draw shared by | G_j |
//! |---|---|---|
//! | `each-reading` | one reading (resolution, an angle error varying from reading to reading) | Q_jj, the same pattern as the noise |
//! | `each-autocollimator` | all readings of one autocollimator (a constant offset) | 0 for β, φ and α: the setup error absorbs it (computed, not assumed) |
//! | `each-position` | all readings at one table position p = step mod N, in every cycle | (1 − 1/N) for α, 0 for β and φ |
//! | `each-stop` | the readings of one stop of the table (setup, cycle, step) | (1 − 1/N)/R for α with R cycles of the paper's design |
//! | `result` (default) | nothing: added directly to every quantity, as the paper's Table 1 does | 1 (0 for the reference face φ\[N\]) |
//!
//! u_c,j² = u_A,j² + Σ_B u_B² G_B,j with u_A,j = σ√Q_jj the fit's type A, and the
//! effective degrees of freedom by Welch–Satterthwaite, ν_eff = u_c⁴ / (u_A⁴/ν_A + Σ
//! u_B,j⁴/ν_B), with ν_A the fit's residual degrees of freedom (infinite for a stated σ);
//! k = t_p(ν_eff) under the budget's `dof_policy`, U = k·u_c ([`evaluate`]).
//!
//! # The budget file
//!
//! The budget file of FORMAT.md §5 with one more key per component, `acts_on` (above;
//! default `"result"`). On a nested component it is the default of its components.
//! The fit supplies the type A uncertainty of the readings (repeatability) from its
//! residuals: the budget lists the instrument's other sources. See
//! `examples/budgets/instrument.toml` and [`InstrumentBudget`].
//!
//! # Monte Carlo
//!
//! [`monte_carlo`] draws, per trial, the readings as the fitted model plus noise plus the
//! type-B errors (each drawn from its distribution with its scope), solves them, and adds
//! the `result` components to the outputs. The noise is normal with the stated σ, or,
//! when σ comes from the residuals with ν degrees of freedom, normal with a standard
//! deviation drawn per trial as s·√(ν/χ²_ν) — the multivariate t of a regression
//! (JCGM 101 §6.4.9 for the mean of repeated indications, generalised), which is what
//! the GUM's t factor with ν_A = ν assumes. Each trial is solved with the paper's closed
//! form (generic over `Const<N>` for the usual N, no heap) when the design is the
//! paper's, and with the least-squares solution operator θ = Q Xᵀ y otherwise. Results
//! per quantity: mean, standard uncertainty, the probabilistically symmetric coverage
//! interval, and the validation of the GUM interval (JCGM 101 §8).
//!
//! Trials come in blocks of [`BLOCK_SIZE`], block b drawing from ChaCha8 (`seed`, stream
//! b; ChaCha8 rather than the general engine's ChaCha12 for speed), spread over rayon's threads and combined in block order: the same seed gives the
//! same numbers whatever the number of threads. The coverage interval is exact (the
//! order statistics of all M trials, as a full sort would give) without storing every
//! trial: the first 10⁴ trials bracket each interval end, later trials only count the
//! values below a bracket and keep the few inside it, and a bracket that missed is
//! widened and the trials re-run.

use std::ops::Range;
use std::path::Path;
use std::str::FromStr;

use nalgebra::{DVector, DefaultAllocator, Dim, SVector, allocator::Allocator};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{ChiSquared, Distribution as _, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::budget::{Budget, BudgetError, DofPolicy, EvaluationType, Source};
use super::budget_file::{BudgetFile, line_column, read_budget_text};
use super::distribution::{Distribution, Sampler};
use super::monte_carlo::{
    BLOCK_SIZE, McError, OutputSummary, Trials, adaptive_sequence_length, minimum_trials,
    numerical_tolerance, standard_deviation_of_mean, symmetric_interval_positions, validate_gum,
};
use super::student::t_quantile;
use crate::measurement::MeasurementSet;
use crate::solve::{ClosedFormSolution, PaperDesign, SigmaSource, Solution, closed_form};

// ---------------------------------------------------------------------------------------
// Scopes and the instrument budget
// ---------------------------------------------------------------------------------------

/// Which readings share one draw of a type-B component (`acts_on` in the budget file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Scope {
    /// An independent error of every reading (`"each-reading"`).
    EachReading,
    /// One error for all readings of one autocollimator, in every mounting: a constant
    /// offset (`"each-autocollimator"`).
    EachAutocollimator,
    /// One error per table position p = step mod N, the same in every cycle
    /// (`"each-position"`), shared by all autocollimators reading there.
    EachPosition,
    /// One error per stop of the table — (setup, cycle, step) — shared by the
    /// autocollimators reading at that stop (`"each-stop"`).
    EachStop,
    /// Added directly to every quantity, as the paper's Table 1 does (`"result"`, the
    /// default).
    #[default]
    Result,
}

impl Scope {
    /// Every scope, in the order of the documentation.
    pub const ALL: [Scope; 5] = [
        Scope::EachReading,
        Scope::EachAutocollimator,
        Scope::EachPosition,
        Scope::EachStop,
        Scope::Result,
    ];

    /// The spelling in budget files and outputs.
    pub fn as_str(self) -> &'static str {
        match self {
            Scope::EachReading => "each-reading",
            Scope::EachAutocollimator => "each-autocollimator",
            Scope::EachPosition => "each-position",
            Scope::EachStop => "each-stop",
            Scope::Result => "result",
        }
    }
}

impl std::fmt::Display for Scope {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Scope {
    type Err = String;
    fn from_str(s: &str) -> Result<Scope, String> {
        Scope::ALL
            .into_iter()
            .find(|scope| scope.as_str() == s)
            .ok_or_else(|| {
                format!(
                    "unknown acts_on {s:?}: expected \"each-reading\", \"each-autocollimator\", \
                     \"each-position\", \"each-stop\" or \"result\""
                )
            })
    }
}

/// One type-B (or externally evaluated type-A) source of the instrument with its scope.
#[derive(Debug, Clone, PartialEq)]
pub struct ScopedComponent {
    /// Name (nested names joined by ` / `).
    pub name: String,
    /// Type A or B (a label: the combination is the same).
    pub evaluation: EvaluationType,
    /// Distribution of the error of one draw, before the sensitivity.
    pub distribution: Distribution,
    /// Sensitivity coefficient (product of the enclosing nested components'): the error
    /// of a reading is `sensitivity ×` the draw.
    pub sensitivity: f64,
    /// Degrees of freedom of its standard uncertainty, `None` for infinitely many.
    pub dof: Option<f64>,
    /// Which readings share one draw.
    pub scope: Scope,
}

impl ScopedComponent {
    /// A type-B component with sensitivity 1 and infinite degrees of freedom (a t
    /// distribution keeps its own).
    pub fn type_b(name: impl Into<String>, distribution: Distribution, scope: Scope) -> Self {
        ScopedComponent {
            name: name.into(),
            evaluation: EvaluationType::B,
            distribution,
            sensitivity: 1.0,
            dof: distribution.own_dof(),
            scope,
        }
    }

    /// The same component with `dof` degrees of freedom (`None`: infinite).
    pub fn with_dof(mut self, dof: Option<f64>) -> Self {
        self.dof = dof;
        self
    }

    /// The same component with sensitivity coefficient `c`.
    pub fn with_sensitivity(mut self, c: f64) -> Self {
        self.sensitivity = c;
        self
    }

    /// Standard uncertainty of one draw as it enters a reading: |c|·u(x).
    pub fn standard_uncertainty(&self) -> f64 {
        self.sensitivity.abs() * self.distribution.standard_uncertainty()
    }

    /// The distribution Monte Carlo draws from: a type-A normal with finite degrees of
    /// freedom becomes a scaled t (JCGM 101 §6.4.9), as in
    /// [`super::monte_carlo::linear_budget_inputs`].
    fn mc_distribution(&self) -> Distribution {
        match (self.evaluation, self.distribution, self.dof) {
            (EvaluationType::A, Distribution::Normal { u }, Some(nu)) => {
                Distribution::StudentT { scale: u, dof: nu }
            }
            (_, d, _) => d,
        }
    }
}

/// The instrument's uncertainty budget for `polycal solve --budget`: coverage
/// probability, degrees-of-freedom policy and scoped components.
#[derive(Debug, Clone, PartialEq)]
pub struct InstrumentBudget {
    /// Where it came from (a path, `<stdin>`, or `<budget>` when built in code).
    pub source: String,
    /// Coverage probability (default 0.95).
    pub p: f64,
    /// How k follows from ν_eff (default fractional).
    pub dof_policy: DofPolicy,
    /// The components, in file order, nested budgets flattened.
    pub components: Vec<ScopedComponent>,
}

impl InstrumentBudget {
    /// A budget of the given components, p = 0.95, fractional policy.
    pub fn new(components: Vec<ScopedComponent>) -> Self {
        InstrumentBudget {
            source: "<budget>".to_string(),
            p: 0.95,
            dof_policy: DofPolicy::Fractional,
            components,
        }
    }

    /// The same budget at coverage probability `p`.
    pub fn with_coverage(mut self, p: f64) -> Self {
        self.p = p;
        self
    }

    /// The same budget with another degrees-of-freedom policy.
    pub fn with_dof_policy(mut self, policy: DofPolicy) -> Self {
        self.dof_policy = policy;
        self
    }

    /// Reads a budget file (`-` reads standard input).
    ///
    /// # Errors
    ///
    /// [`BudgetError::Io`] if it cannot be read; otherwise as
    /// [`InstrumentBudget::from_toml_str`].
    pub fn read_path(path: impl AsRef<Path>) -> Result<Self, BudgetError> {
        let (source, text) = read_budget_text(path.as_ref())?;
        Self::from_toml_str(&text, &source)
    }

    /// Parses a budget file: the budget TOML of FORMAT.md §5 read as strictly as by
    /// `polycal budget`, plus `acts_on` on any component (default `"result"`; on a nested
    /// component, the default of its components).
    ///
    /// ```
    /// use polycal::uncertainty::calibration::{InstrumentBudget, Scope};
    /// let text = r#"
    /// [[component]]
    /// name = "Resolution of the autocollimator"
    /// type = "B"
    /// distribution = "rectangular"
    /// full_width = 0.001
    /// acts_on = "each-reading"
    ///
    /// [[component]]
    /// name = "Mounting"
    /// type = "B"
    /// u = 0.02
    /// "#;
    /// let budget = InstrumentBudget::from_toml_str(text, "instrument.toml")?;
    /// assert_eq!(budget.components[0].scope, Scope::EachReading);
    /// assert_eq!(budget.components[1].scope, Scope::Result);
    /// # Ok::<(), polycal::uncertainty::BudgetError>(())
    /// ```
    ///
    /// # Errors
    ///
    /// [`BudgetError::File`] with the file, line and column for anything the budget
    /// reader refuses and for an unknown `acts_on`; [`BudgetError::InFile`] for
    /// correlations (not supported: the correlated components may act on different
    /// readings) and for a budget that cannot be evaluated.
    pub fn from_toml_str(text: &str, source: &str) -> Result<Self, BudgetError> {
        let at = |span: Range<usize>, message: String| {
            let (line, column) = line_column(text, span.start);
            BudgetError::File {
                file: source.to_string(),
                line,
                column,
                message,
            }
        };
        let raw: RawScopeFile = toml::from_str(text)
            .map_err(|e| at(e.span().unwrap_or(0..0), e.message().trim_end().to_string()))?;
        let mut spans = Vec::new();
        let tree = scope_tree(&raw.component, &at, &mut spans)?;
        // Blank the acts_on entries (bytes kept, so every line and column stays) and let
        // the budget reader check the rest.
        let mut bytes = text.as_bytes().to_vec();
        for span in spans {
            let key =
                acts_on_key(text, span.clone()).map_err(|message| at(span.clone(), message))?;
            for b in &mut bytes[key.start..span.end] {
                if *b != b'\n' && *b != b'\r' {
                    *b = b' ';
                }
            }
        }
        let blanked = String::from_utf8(bytes)
            .unwrap_or_else(|_| unreachable!("whole UTF-8 sequences were replaced by spaces"));
        let file = BudgetFile::from_toml_str(&blanked, source)?;
        let in_file = |error: BudgetError| BudgetError::InFile {
            file: source.to_string(),
            error: Box::new(error),
        };
        file.budget.combine().map_err(in_file)?;
        let mut components = Vec::new();
        flatten(&file.budget, &tree, Scope::Result, 1.0, "", &mut components).map_err(in_file)?;
        Ok(InstrumentBudget {
            source: source.to_string(),
            p: file.p,
            dof_policy: file.dof_policy,
            components,
        })
    }

    /// Checks p and every component (distribution, sensitivity, degrees of freedom).
    ///
    /// # Errors
    ///
    /// [`CalibrationError::Coverage`] or [`CalibrationError::Component`].
    pub fn check(&self) -> Result<(), CalibrationError> {
        if !(self.p > 0.0 && self.p < 1.0) {
            return Err(CalibrationError::Coverage(self.p));
        }
        for c in &self.components {
            let bad = |message: String| CalibrationError::Component {
                name: c.name.clone(),
                message,
            };
            c.distribution.check().map_err(bad)?;
            if !c.sensitivity.is_finite() {
                return Err(bad(format!(
                    "sensitivity must be a finite number, got {}",
                    c.sensitivity
                )));
            }
            if let Some(nu) = c.dof
                && !(nu.is_finite() && nu >= 1.0)
            {
                return Err(bad(format!(
                    "degrees of freedom must be at least 1 (None for infinitely many), got {nu}"
                )));
            }
        }
        Ok(())
    }

    /// Cautions worth printing: type-A components (the fit already supplies the
    /// repeatability of the readings; one listed here as well counts twice).
    pub fn notes(&self) -> Vec<String> {
        self.components
            .iter()
            .filter(|c| c.evaluation == EvaluationType::A)
            .map(|c| {
                format!(
                    "{}: component {:?} is type A: the fit already gives the type A uncertainty \
                     of the readings (repeatability) from its residuals or --sigma; keep it only \
                     if it was evaluated elsewhere, or it counts twice",
                    self.source, c.name
                )
            })
            .collect()
    }
}

#[derive(Deserialize)]
struct RawScopeFile {
    #[serde(default)]
    component: Vec<RawScopeComponent>,
}

#[derive(Deserialize)]
struct RawScopeComponent {
    acts_on: Option<Spanned<String>>,
    #[serde(default)]
    component: Vec<RawScopeComponent>,
}

/// The `acts_on` of a component and of its nested components.
struct ScopeNode {
    scope: Option<Scope>,
    children: Vec<ScopeNode>,
}

fn scope_tree(
    raw: &[RawScopeComponent],
    at: &dyn Fn(Range<usize>, String) -> BudgetError,
    spans: &mut Vec<Range<usize>>,
) -> Result<Vec<ScopeNode>, BudgetError> {
    raw.iter()
        .map(|c| {
            let scope = match &c.acts_on {
                None => None,
                Some(s) => {
                    spans.push(s.span());
                    Some(s.get_ref().parse::<Scope>().map_err(|e| at(s.span(), e))?)
                }
            };
            Ok(ScopeNode {
                scope,
                children: scope_tree(&c.component, at, spans)?,
            })
        })
        .collect()
}

/// The byte range from the `acts_on` key to the end of its value, for a value at `value`.
fn acts_on_key(text: &str, value: Range<usize>) -> Result<Range<usize>, String> {
    let before = &text[..value.start];
    let trimmed = before.trim_end_matches([' ', '\t']);
    let trimmed = trimmed
        .strip_suffix('=')
        .map(|t| t.trim_end_matches([' ', '\t']));
    let key_start = trimmed.and_then(|t| {
        ["acts_on", "\"acts_on\"", "'acts_on'"]
            .iter()
            .find_map(|key| t.strip_suffix(key).map(|rest| rest.len()))
    });
    let inline = |start: usize| {
        let previous = text[..start].trim_end_matches([' ', '\t']);
        previous.ends_with(',') || previous.ends_with('{')
    };
    match key_start {
        Some(start) if !inline(start) => Ok(start..value.end),
        _ => Err("write acts_on on a line of its own, as acts_on = \"each-reading\"".into()),
    }
}

/// Flattens a (nested) budget into scoped components.
fn flatten(
    budget: &Budget,
    nodes: &[ScopeNode],
    inherited: Scope,
    factor: f64,
    prefix: &str,
    out: &mut Vec<ScopedComponent>,
) -> Result<(), BudgetError> {
    if let Some(c) = budget.correlations.iter().find(|c| c.r != 0.0) {
        return Err(BudgetError::Correlation {
            a: format!("{prefix}{}", c.a),
            b: format!("{prefix}{}", c.b),
            message: "correlations are not supported in an instrument budget (the components \
                      may act on different readings); combine correlated sources into one \
                      component"
                .into(),
        });
    }
    for (i, component) in budget.components.iter().enumerate() {
        let node = nodes.get(i);
        let scope = node.and_then(|n| n.scope).unwrap_or(inherited);
        let name = format!("{prefix}{}", component.name);
        let c = factor * component.sensitivity;
        match &component.source {
            Source::Input {
                evaluation,
                distribution,
                dof,
            } => out.push(ScopedComponent {
                name,
                evaluation: *evaluation,
                distribution: *distribution,
                sensitivity: c,
                dof: *dof,
                scope,
            }),
            Source::Budget(inner) => flatten(
                inner,
                node.map_or(&[][..], |n| &n.children),
                scope,
                c,
                &format!("{name} / "),
                out,
            )?,
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Errors
// ---------------------------------------------------------------------------------------

/// Why the uncertainty of a calibration cannot be evaluated.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// No σ: the fit is exactly determined and none was stated.
    #[error(
        "the fit is exactly determined (dof = 0) and no reading noise was stated, so the type A \
         uncertainty is unknown: state the standard deviation of one reading (--sigma)"
    )]
    NoSigma,
    /// The solution has effect terms, which this propagation does not cover.
    #[error(
        "the fit has {0} effect terms: the propagation of the budget covers the base model only"
    )]
    Effects(usize),
    /// The solution is not the solution of this measurement set.
    #[error("the solution does not belong to the measurement set: {0}")]
    Mismatch(String),
    /// The coverage probability is not in (0, 1).
    #[error("coverage probability p must be between 0 and 1 (exclusive), got {0}")]
    Coverage(f64),
    /// A component is invalid.
    #[error("component {name:?}: {message}")]
    Component {
        /// Its name.
        name: String,
        /// What is wrong.
        message: String,
    },
    /// ⌊ν_eff⌋ < 1 under the floor policy.
    #[error(
        "{quantity} {index}: effective degrees of freedom {dof} round down to 0: no t factor; \
         use dof_policy = \"fractional\""
    )]
    FloorBelowOne {
        /// The quantity.
        quantity: &'static str,
        /// Its index (face, position or stream).
        index: usize,
        /// ν_eff.
        dof: f64,
    },
    /// The Monte Carlo run failed.
    #[error(transparent)]
    MonteCarlo(#[from] McError),
}

// ---------------------------------------------------------------------------------------
// The solution operator L = Q Xᵀ
// ---------------------------------------------------------------------------------------

/// The fit as a linear map of the readings: θ̂ = Q Xᵀ y.
#[derive(Debug, Clone)]
struct Operator {
    faces: usize,
    streams: usize,
    /// Q, row-major, (2N + K)².
    q: Vec<f64>,
    /// Q with its β columns summed cumulatively: qc\[j·N + f\] = Σ_{k ≤ f} Q\[j, k\].
    qc: Vec<f64>,
    /// Per reading: position, face − 1, stream.
    position: Vec<usize>,
    face: Vec<usize>,
    stream: Vec<usize>,
}

impl Operator {
    fn new(set: &MeasurementSet, solution: &Solution) -> Result<Self, CalibrationError> {
        let n = solution.faces;
        let layout = solution.layout;
        if layout.effects > 0 {
            return Err(CalibrationError::Effects(layout.effects));
        }
        if set.faces != n
            || set.readings.len() != solution.readings
            || solution.residuals.len() != set.readings.len()
        {
            return Err(CalibrationError::Mismatch(format!(
                "{} faces and {} readings, the solution {} faces and {} readings",
                set.faces,
                set.readings.len(),
                n,
                solution.readings
            )));
        }
        let len = layout.len();
        let q: Vec<f64> = (0..len * len)
            .map(|i| solution.cofactor[(i / len, i % len)])
            .collect();
        let mut qc = vec![0.0; len * n];
        for j in 0..len {
            let mut running = 0.0;
            for f in 0..n {
                running += q[j * len + f];
                qc[j * n + f] = running;
            }
        }
        let mut stream = Vec::with_capacity(set.readings.len());
        for r in &set.readings {
            let s = solution
                .setup_error
                .iter()
                .position(|s| (s.setup, s.ac) == (r.setup, r.ac))
                .ok_or_else(|| {
                    CalibrationError::Mismatch(format!(
                        "no setup error for setup {} autocollimator {}",
                        r.setup, r.ac
                    ))
                })?;
            stream.push(s);
        }
        Ok(Operator {
            faces: n,
            streams: layout.setups,
            q,
            qc,
            position: set.readings.iter().map(|r| r.position(n)).collect(),
            face: set.readings.iter().map(|r| r.face - 1).collect(),
            stream,
        })
    }

    fn len(&self) -> usize {
        2 * self.faces + self.streams
    }

    /// Adds w·L\[:, i\] (the response of θ̂ to reading i) to `theta`.
    fn add_column(&self, i: usize, w: f64, theta: &mut [f64]) {
        let (n, len) = (self.faces, self.len());
        let (a, f, s) = (n + self.position[i], self.face[i], 2 * n + self.stream[i]);
        for (j, t) in theta.iter_mut().enumerate() {
            let row = &self.q[j * len..(j + 1) * len];
            *t += w * (row[a] + self.qc[j * n + f] + row[s]);
        }
    }

    /// θ̂ rows `rows` for the readings `y`: b = Xᵀy, then θ = Q b. `face_sums` (N) and
    /// `b` (2N + K) are scratch.
    fn solve(
        &self,
        y: &[f64],
        face_sums: &mut [f64],
        b: &mut [f64],
        rows: Range<usize>,
        theta: &mut [f64],
    ) {
        let n = self.faces;
        face_sums.fill(0.0);
        b.fill(0.0);
        for (i, &v) in y.iter().enumerate() {
            face_sums[self.face[i]] += v;
            b[n + self.position[i]] += v;
            b[2 * n + self.stream[i]] += v;
        }
        // X has a 1 in β_k for every face ≥ k (φ_f = β_1 + … + β_f).
        let mut suffix = 0.0;
        for k in (0..n).rev() {
            suffix += face_sums[k];
            b[k] = suffix;
        }
        let len = self.len();
        for (t, j) in theta.iter_mut().zip(rows) {
            let row = &self.q[j * len..(j + 1) * len];
            *t = row.iter().zip(b.iter()).map(|(q, b)| q * b).sum();
        }
    }
}

/// The quantities reported, from θ = [β, α, U]: [β (N), φ (N), α (N), U (K)], with
/// φ\[N\] = 0 exactly.
fn quantities(theta: &[f64], n: usize, out: &mut [f64]) {
    let k = theta.len() - 2 * n;
    out[..n].copy_from_slice(&theta[..n]);
    let mut running = 0.0;
    for f in 0..n {
        running += theta[f];
        out[n + f] = running;
    }
    out[2 * n - 1] = 0.0;
    out[2 * n..3 * n].copy_from_slice(&theta[n..2 * n]);
    out[3 * n..3 * n + k].copy_from_slice(&theta[2 * n..]);
}

/// Dense group number of every reading for a scope (not for [`Scope::Result`]).
fn groups(set: &MeasurementSet, scope: Scope) -> Vec<Vec<usize>> {
    let n = set.faces;
    let mut keys: Vec<(u64, u64, u64)> = set
        .readings
        .iter()
        .enumerate()
        .map(|(i, r)| match scope {
            Scope::EachReading | Scope::Result => (i as u64, 0, 0),
            Scope::EachAutocollimator => (u64::from(r.ac), 0, 0),
            Scope::EachPosition => (r.position(n) as u64, 0, 0),
            Scope::EachStop => (u64::from(r.setup), u64::from(r.cycle), r.step as u64),
        })
        .collect();
    let mut distinct = keys.clone();
    distinct.sort_unstable();
    distinct.dedup();
    let mut members = vec![Vec::new(); distinct.len()];
    for (i, key) in keys.drain(..).enumerate() {
        let g = distinct
            .binary_search(&key)
            .unwrap_or_else(|_| unreachable!("every key was listed"));
        members[g].push(i);
    }
    members
}

/// G_j = Σ_g (Σ_{i∈g} L_ji)² for every reported quantity j ([`quantities`] order).
fn gains(op: &Operator, set: &MeasurementSet, scope: Scope) -> Vec<f64> {
    let n = op.faces;
    let total = 3 * n + op.streams;
    if scope == Scope::Result {
        let mut g = vec![1.0; total];
        g[2 * n - 1] = 0.0;
        return g;
    }
    let mut g = vec![0.0; total];
    let mut theta = vec![0.0; op.len()];
    let mut q = vec![0.0; total];
    for members in groups(set, scope) {
        theta.fill(0.0);
        for i in members {
            op.add_column(i, 1.0, &mut theta);
        }
        quantities(&theta, n, &mut q);
        for (g, v) in g.iter_mut().zip(&q) {
            *g += v * v;
        }
    }
    g
}

// ---------------------------------------------------------------------------------------
// GUM evaluation
// ---------------------------------------------------------------------------------------

/// The uncertainties of one family of quantities (all β, all φ, all α, or all setup
/// errors), index as in the solution.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FamilyUncertainty {
    /// Type A standard uncertainty from the fit, σ·√Q_jj (the report's `*_u`).
    pub u_a: Vec<f64>,
    /// Combined standard uncertainty u_c.
    pub u: Vec<f64>,
    /// Effective degrees of freedom (Welch–Satterthwaite), `null` when infinite.
    pub dof_eff: Vec<Option<f64>>,
    /// Coverage factor; `null` where u_c = 0 (the reference face φ\[N\]).
    pub k: Vec<Option<f64>>,
    /// Expanded uncertainty U = k·u_c.
    #[serde(rename = "U")]
    pub expanded_u: Vec<f64>,
}

/// What one component contributes to every quantity (standard uncertainties, arcsec).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComponentContribution {
    /// Name.
    pub name: String,
    /// `A` or `B`.
    #[serde(rename = "type")]
    pub evaluation: EvaluationType,
    /// Distribution name.
    pub distribution: &'static str,
    /// Scope.
    pub acts_on: Scope,
    /// Standard uncertainty of one draw as it enters a reading, |c|·u(x).
    pub u: f64,
    /// Sensitivity coefficient c.
    pub sensitivity: f64,
    /// Degrees of freedom, `null` if infinite.
    pub dof: Option<f64>,
    /// Contribution to each β, u·√G.
    pub pitch_deviation: Vec<f64>,
    /// Contribution to each φ.
    pub face_deviation: Vec<f64>,
    /// Contribution to each α.
    pub encoder_error: Vec<f64>,
    /// Contribution to each setup error.
    pub setup_error: Vec<f64>,
}

/// The GUM uncertainty of every calibration result ([`evaluate`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationUncertainty {
    /// The budget's source.
    pub budget: String,
    /// Coverage probability.
    pub p: f64,
    /// How k follows from ν_eff.
    pub dof_policy: DofPolicy,
    /// σ of one reading, arcsec.
    pub sigma: f64,
    /// `residual` or `stated`.
    pub sigma_source: &'static str,
    /// Degrees of freedom of the type A part: the fit's residual dof, `null` (infinite)
    /// for a stated σ.
    pub type_a_dof: Option<f64>,
    /// Pitch deviations β\[1..=N\].
    pub pitch_deviation: FamilyUncertainty,
    /// Face deviations φ\[1..=N\] (φ\[N\] = 0 exactly: u = U = 0, k null).
    pub face_deviation: FamilyUncertainty,
    /// Encoder errors α[0..N).
    pub encoder_error: FamilyUncertainty,
    /// Setup errors, in the solution's order.
    pub setup_error: FamilyUncertainty,
    /// Every component's contributions.
    pub components: Vec<ComponentContribution>,
}

impl CalibrationUncertainty {
    /// The families in report order, with their names.
    pub fn families(&self) -> [(&'static str, &FamilyUncertainty); 4] {
        [
            ("pitch_deviation", &self.pitch_deviation),
            ("face_deviation", &self.face_deviation),
            ("encoder_error", &self.encoder_error),
            ("setup_error", &self.setup_error),
        ]
    }
}

/// Splits a vector in [`quantities`] order into the four families.
fn split<T: Clone>(v: &[T], n: usize) -> [Vec<T>; 4] {
    [
        v[..n].to_vec(),
        v[n..2 * n].to_vec(),
        v[2 * n..3 * n].to_vec(),
        v[3 * n..].to_vec(),
    ]
}

fn family_name_and_index(j: usize, n: usize) -> (&'static str, usize) {
    match j / n {
        0 => ("pitch_deviation", j + 1),
        1 => ("face_deviation", j - n + 1),
        2 => ("encoder_error", j - 2 * n),
        _ => ("setup_error", j - 3 * n + 1),
    }
}

/// The expanded uncertainty of every pitch deviation, face deviation, encoder error and
/// setup error: the fit's type A (σ²Q) combined with the budget's components through the
/// design (module documentation), Welch–Satterthwaite, k and U per quantity.
///
/// # Errors
///
/// [`CalibrationError`]: no σ (exactly determined fit without `--sigma`), effect terms,
/// a solution of another set, an invalid budget, or ⌊ν_eff⌋ < 1 under the floor policy.
pub fn evaluate(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
) -> Result<CalibrationUncertainty, CalibrationError> {
    budget.check()?;
    let op = Operator::new(set, solution)?;
    let (sigma, source) = solution.sigma.ok_or(CalibrationError::NoSigma)?;
    let n = op.faces;
    let total = 3 * n + op.streams;
    let type_a_dof = match source {
        SigmaSource::Residual => Some(solution.dof as f64),
        SigmaSource::Stated => None,
    };
    let reading_gains = gains(&op, set, Scope::EachReading);
    let u_a: Vec<f64> = reading_gains.iter().map(|g| sigma * g.sqrt()).collect();
    let mut scope_gains: Vec<(Scope, Vec<f64>)> = vec![(Scope::EachReading, reading_gains)];
    let mut contributions: Vec<Vec<f64>> = Vec::with_capacity(budget.components.len());
    for c in &budget.components {
        if !scope_gains.iter().any(|(s, _)| *s == c.scope) {
            scope_gains.push((c.scope, gains(&op, set, c.scope)));
        }
        let g = &scope_gains
            .iter()
            .find(|(s, _)| *s == c.scope)
            .unwrap_or_else(|| unreachable!("computed above"))
            .1;
        let u = c.standard_uncertainty();
        contributions.push(g.iter().map(|g| u * g.max(0.0).sqrt()).collect());
    }
    let mut u = vec![0.0; total];
    let mut dof_eff = vec![None; total];
    let mut k = vec![None; total];
    let mut expanded = vec![0.0; total];
    for j in 0..total {
        let mut variance = u_a[j] * u_a[j];
        let mut denominator = type_a_dof.map_or(0.0, |nu| u_a[j].powi(4) / nu);
        for (c, contribution) in budget.components.iter().zip(&contributions) {
            let x = contribution[j];
            variance += x * x;
            if let Some(nu) = c.dof {
                denominator += x.powi(4) / nu;
            }
        }
        u[j] = variance.sqrt();
        if variance <= 0.0 {
            continue; // φ[N]: no uncertainty, no k
        }
        let nu = (denominator > 0.0)
            .then(|| variance * variance / denominator)
            .filter(|nu| nu.is_finite());
        dof_eff[j] = nu;
        let factor = match budget.dof_policy {
            DofPolicy::K2 => 2.0,
            DofPolicy::Fractional => t_quantile(budget.p, nu),
            DofPolicy::Floor => match nu {
                Some(nu) if nu.floor() < 1.0 => {
                    let (quantity, index) = family_name_and_index(j, n);
                    return Err(CalibrationError::FloorBelowOne {
                        quantity,
                        index,
                        dof: nu,
                    });
                }
                other => t_quantile(budget.p, other.map(f64::floor)),
            },
        };
        k[j] = Some(factor);
        expanded[j] = factor * u[j];
    }
    let [a0, a1, a2, a3] = split(&u_a, n);
    let [u0, u1, u2, u3] = split(&u, n);
    let [d0, d1, d2, d3] = split(&dof_eff, n);
    let [k0, k1, k2, k3] = split(&k, n);
    let [e0, e1, e2, e3] = split(&expanded, n);
    let family = |u_a, u, dof_eff, k, expanded_u| FamilyUncertainty {
        u_a,
        u,
        dof_eff,
        k,
        expanded_u,
    };
    let components = budget
        .components
        .iter()
        .zip(contributions)
        .map(|(c, contribution)| {
            let [pitch, face, encoder, setup] = split(&contribution, n);
            ComponentContribution {
                name: c.name.clone(),
                evaluation: c.evaluation,
                distribution: c.distribution.name(),
                acts_on: c.scope,
                u: c.standard_uncertainty(),
                sensitivity: c.sensitivity,
                dof: c.dof,
                pitch_deviation: pitch,
                face_deviation: face,
                encoder_error: encoder,
                setup_error: setup,
            }
        })
        .collect();
    Ok(CalibrationUncertainty {
        budget: budget.source.clone(),
        p: budget.p,
        dof_policy: budget.dof_policy,
        sigma,
        sigma_source: match source {
            SigmaSource::Residual => "residual",
            SigmaSource::Stated => "stated",
        },
        type_a_dof,
        pitch_deviation: family(a0, u0, d0, k0, e0),
        face_deviation: family(a1, u1, d1, k1, e1),
        encoder_error: family(a2, u2, d2, k2, e2),
        setup_error: family(a3, u3, d3, k3, e3),
        components,
    })
}

// ---------------------------------------------------------------------------------------
// Monte Carlo: the trial model
// ---------------------------------------------------------------------------------------

/// Which solver the Monte Carlo trials use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum McSolver {
    /// The paper's closed form when the design is the paper's, else least squares.
    #[default]
    Auto,
    /// The least-squares solution operator θ = Q Xᵀ y, whatever the design.
    LeastSquares,
}

/// Solves one trial's targets into the outputs; false on failure.
type ClosedFormFn = fn(&[f64], usize, &mut [f64]) -> bool;

fn write_closed_form<D: Dim>(s: &ClosedFormSolution<D>, offset: usize, out: &mut [f64])
where
    DefaultAllocator: Allocator<D>,
{
    let n = s.encoder_error.len();
    let beta = s.polygon.pitch_deviation_arcsec();
    let phi = s.polygon.face_deviation_arcsec();
    for f in 0..n {
        out[f] = beta[f];
    }
    for f in 0..n - 1 {
        out[n + f] = phi[f];
    }
    for p in 0..n {
        out[2 * n - 1 + p] = s.encoder_error[(p + offset) % n];
    }
}

fn closed_form_const<const N: usize>(t: &[f64], offset: usize, out: &mut [f64]) -> bool {
    let m1 = SVector::<f64, N>::from_column_slice(&t[..N]);
    let m2 = SVector::<f64, N>::from_column_slice(&t[N..2 * N]);
    match closed_form(&m1, &m2) {
        Ok(s) => {
            write_closed_form(&s, offset, out);
            true
        }
        Err(_) => false,
    }
}

fn closed_form_dyn(t: &[f64], offset: usize, out: &mut [f64]) -> bool {
    let n = t.len() / 2;
    let m1 = DVector::from_column_slice(&t[..n]);
    let m2 = DVector::from_column_slice(&t[n..]);
    match closed_form(&m1, &m2) {
        Ok(s) => {
            write_closed_form(&s, offset, out);
            true
        }
        Err(_) => false,
    }
}

macro_rules! closed_form_for {
    ($n:expr; $($c:literal),*) => {
        match $n {
            $($c => closed_form_const::<$c> as ClosedFormFn,)*
            _ => closed_form_dyn as ClosedFormFn,
        }
    };
}

/// The closed form for N faces: `Const<N>` (stack only) for the usual N, else `Dyn`.
fn closed_form_fn(n: usize) -> ClosedFormFn {
    closed_form_for!(n; 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 14, 15, 16, 18, 20, 24, 30, 36, 40, 45, 48, 60, 72)
}

enum TrialSolver {
    ClosedForm { offset: usize, solve: ClosedFormFn },
    LeastSquares(Operator),
}

enum Noise {
    /// Stated σ: normal, folded into `McModel::normal_sd`.
    Normal,
    ScaledT {
        sigma: f64,
        dof: f64,
        chi: ChiSquared<f64>,
    },
}

/// A component drawn once per group and added, weighted, to the group's targets.
struct Plan {
    sampler: Sampler,
    scale: f64,
    starts: Vec<usize>,
    entries: Vec<(usize, f64)>,
}

/// Fills `buf` with draws of `sampler` — the formulas of `Sampler::sample` with the match
/// outside the loop, which is what makes the trials fast (a unit test checks that the
/// draws are the same).
fn draw_into<R: Rng + ?Sized>(sampler: &Sampler, rng: &mut R, buf: &mut [f64]) {
    match *sampler {
        Sampler::Normal(u) => {
            for x in buf {
                let z: f64 = StandardNormal.sample(rng);
                *x = u * z;
            }
        }
        Sampler::Rectangular(a) => {
            for x in buf {
                *x = a * (2.0 * rng.random::<f64>() - 1.0);
            }
        }
        Sampler::Triangular(a) => {
            for x in buf {
                *x = a * (rng.random::<f64>() - rng.random::<f64>());
            }
        }
        Sampler::Arcsine(_) | Sampler::StudentT(..) => {
            for x in buf {
                *x = sampler.sample(rng);
            }
        }
    }
}

/// One Monte Carlo trial of a calibration: draws the readings (as targets of the solver:
/// per-step means for the closed form, the readings for least squares) and solves them.
/// Built by [`McModel::new`]; [`monte_carlo`] runs it.
pub struct McModel {
    faces: usize,
    solver: TrialSolver,
    base: Vec<f64>,
    noise: Noise,
    /// Per target: Σw² of the noise, the variance of the normal components whose draws
    /// each land on one target (drawn together with the noise), and the total standard
    /// deviation when the noise is normal.
    noise_var: Vec<f64>,
    fixed_var: Vec<f64>,
    normal_sd: Vec<f64>,
    plans: Vec<Plan>,
    result_draws: Vec<(Sampler, f64)>,
    centre: Vec<f64>,
}

impl McModel {
    /// The trial model of a solved measurement set and a budget.
    ///
    /// # Errors
    ///
    /// As [`evaluate`].
    pub fn new(
        set: &MeasurementSet,
        solution: &Solution,
        budget: &InstrumentBudget,
        solver: McSolver,
    ) -> Result<Self, CalibrationError> {
        budget.check()?;
        let op = Operator::new(set, solution)?;
        let (sigma, source) = solution.sigma.ok_or(CalibrationError::NoSigma)?;
        let n = op.faces;
        let design = match solver {
            McSolver::Auto => PaperDesign::detect(set).ok(),
            McSolver::LeastSquares => None,
        };
        // Where each reading lands: (target, weight).
        let (targets, map): (usize, Vec<(usize, f64)>) = match &design {
            Some(d) => (
                2 * n,
                set.readings
                    .iter()
                    .map(|r| {
                        let slot = usize::from((r.setup, r.ac) == d.second);
                        (slot * n + (r.step + d.offset) % n, 1.0 / d.repeats as f64)
                    })
                    .collect(),
            ),
            None => (
                set.readings.len(),
                (0..set.readings.len()).map(|i| (i, 1.0)).collect(),
            ),
        };
        let mut base = vec![0.0; targets];
        let mut noise_var = vec![0.0; targets];
        for (i, r) in set.readings.iter().enumerate() {
            let (t, w) = map[i];
            base[t] += w * (r.reading_arcsec - solution.residuals[i]);
            noise_var[t] += w * w;
        }
        let noise = match source {
            SigmaSource::Stated => Noise::Normal,
            SigmaSource::Residual => {
                let dof = solution.dof as f64;
                Noise::ScaledT {
                    sigma,
                    dof,
                    chi: ChiSquared::new(dof).map_err(|e| {
                        CalibrationError::Mismatch(format!("residual dof {dof}: {e}"))
                    })?,
                }
            }
        };
        let mut plans = Vec::new();
        let mut fixed_var = vec![0.0; targets];
        let mut result_draws = Vec::new();
        for c in &budget.components {
            let distribution = c.mc_distribution();
            let sampler =
                distribution
                    .sampler()
                    .map_err(|message| CalibrationError::Component {
                        name: c.name.clone(),
                        message,
                    })?;
            if c.scope == Scope::Result {
                result_draws.push((sampler, c.sensitivity));
                continue;
            }
            let mut starts = vec![0];
            let mut entries: Vec<(usize, f64)> = Vec::new();
            for members in groups(set, c.scope) {
                let from = entries.len();
                for i in members {
                    let (t, w) = map[i];
                    match entries[from..].iter_mut().find(|(target, _)| *target == t) {
                        Some((_, weight)) => *weight += w,
                        None => entries.push((t, w)),
                    }
                }
                starts.push(entries.len());
            }
            let single = starts.windows(2).all(|w| w[1] - w[0] == 1);
            if let (true, Distribution::Normal { u }) = (single, distribution) {
                // Independent normals per target: one normal with the summed variance.
                let scale = c.sensitivity * u;
                for &(t, w) in &entries {
                    fixed_var[t] += (scale * w).powi(2);
                }
            } else {
                plans.push(Plan {
                    sampler,
                    scale: c.sensitivity,
                    starts,
                    entries,
                });
            }
        }
        let mut centre = Vec::with_capacity(3 * n - 1);
        centre.extend_from_slice(&solution.pitch_deviation);
        centre.extend_from_slice(&solution.face_deviation[..n - 1]);
        centre.extend_from_slice(&solution.encoder_error);
        let solver = match design {
            Some(d) => TrialSolver::ClosedForm {
                offset: d.offset,
                solve: closed_form_fn(n),
            },
            None => TrialSolver::LeastSquares(op),
        };
        Ok(McModel {
            faces: n,
            solver,
            base,
            normal_sd: noise_var
                .iter()
                .zip(&fixed_var)
                .map(|(v, f)| (sigma * sigma * v + f).sqrt())
                .collect(),
            noise,
            noise_var,
            fixed_var,
            plans,
            result_draws,
            centre,
        })
    }

    /// Number of targets a trial draws (2N per-step means for the closed form, else the
    /// number of readings).
    pub fn targets(&self) -> usize {
        self.base.len()
    }

    /// Number of outputs: β (N), φ\[1..N−1\] (φ\[N\] = 0 is not drawn), α (N).
    pub fn outputs(&self) -> usize {
        3 * self.faces - 1
    }

    /// `closed-form` or `lsq`.
    pub fn solver_name(&self) -> &'static str {
        match self.solver {
            TrialSolver::ClosedForm { .. } => "closed-form",
            TrialSolver::LeastSquares(_) => "lsq",
        }
    }

    /// `normal` (stated σ) or `t` (σ from the residuals), with the degrees of freedom.
    pub fn reading_noise(&self) -> (&'static str, Option<f64>) {
        match self.noise {
            Noise::Normal => ("normal", None),
            Noise::ScaledT { dof, .. } => ("t", Some(dof)),
        }
    }

    /// A scratch buffer for [`McModel::trial`].
    pub fn scratch(&self) -> McScratch {
        let (faces_len, b_len) = match &self.solver {
            TrialSolver::LeastSquares(op) => (op.faces, op.len()),
            TrialSolver::ClosedForm { .. } => (0, 0),
        };
        McScratch {
            targets: vec![0.0; self.targets()],
            offsets: vec![0.0; self.outputs()],
            draws: vec![
                0.0;
                self.plans
                    .iter()
                    .map(|p| p.starts.len() - 1)
                    .chain([self.outputs()])
                    .max()
                    .unwrap_or(0)
            ],
            theta: vec![0.0; 2 * self.faces],
            face_sums: vec![0.0; faces_len],
            b: vec![0.0; b_len],
        }
    }

    /// Draws one trial's targets and the per-output offsets of the `result` components
    /// (into `scratch`), without solving.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R, scratch: &mut McScratch) {
        let t = &mut scratch.targets;
        t.copy_from_slice(&self.base);
        match &self.noise {
            Noise::Normal => {
                for (x, sd) in t.iter_mut().zip(&self.normal_sd) {
                    let z: f64 = StandardNormal.sample(rng);
                    *x += sd * z;
                }
            }
            Noise::ScaledT { sigma, dof, chi } => {
                let s2 = sigma * sigma * dof / chi.sample(rng);
                for ((x, v), f) in t.iter_mut().zip(&self.noise_var).zip(&self.fixed_var) {
                    let z: f64 = StandardNormal.sample(rng);
                    *x += (s2 * v + f).sqrt() * z;
                }
            }
        }
        for plan in &self.plans {
            let draws = &mut scratch.draws[..plan.starts.len() - 1];
            draw_into(&plan.sampler, rng, draws);
            for (g, e) in plan.starts.windows(2).zip(draws.iter()) {
                let e = plan.scale * e;
                for &(target, w) in &plan.entries[g[0]..g[1]] {
                    t[target] += w * e;
                }
            }
        }
        if !self.result_draws.is_empty() {
            scratch.offsets.fill(0.0);
            let draws = &mut scratch.draws[..scratch.offsets.len()];
            for (sampler, c) in &self.result_draws {
                draw_into(sampler, rng, draws);
                for (o, d) in scratch.offsets.iter_mut().zip(draws.iter()) {
                    *o += c * d;
                }
            }
        }
    }

    /// Solves the targets drawn by [`McModel::sample`] into `out` ([`McModel::outputs`]
    /// values: β, φ\[1..N−1\], α), without the `result` offsets. False if the solver
    /// failed.
    pub fn solve(&self, scratch: &mut McScratch, out: &mut [f64]) -> bool {
        let n = self.faces;
        match &self.solver {
            TrialSolver::ClosedForm { offset, solve } => solve(&scratch.targets, *offset, out),
            TrialSolver::LeastSquares(op) => {
                op.solve(
                    &scratch.targets,
                    &mut scratch.face_sums,
                    &mut scratch.b,
                    0..2 * n,
                    &mut scratch.theta,
                );
                let theta = &scratch.theta;
                out[..n].copy_from_slice(&theta[..n]);
                let mut running = 0.0;
                for f in 0..n - 1 {
                    running += theta[f];
                    out[n + f] = running;
                }
                out[2 * n - 1..3 * n - 1].copy_from_slice(&theta[n..2 * n]);
                true
            }
        }
    }

    /// One trial: draw, solve, add the `result` draws. False if the solver failed.
    pub fn trial<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        scratch: &mut McScratch,
        out: &mut [f64],
    ) -> bool {
        self.sample(rng, scratch);
        if !self.solve(scratch, out) {
            return false;
        }
        if !self.result_draws.is_empty() {
            for (o, d) in out.iter_mut().zip(&scratch.offsets) {
                *o += d;
            }
        }
        true
    }

    /// The outputs at the fitted values (no noise, no draws): the solution's estimates.
    pub fn estimates(&self) -> &[f64] {
        &self.centre
    }
}

/// Scratch space of one thread for [`McModel`] trials.
pub struct McScratch {
    targets: Vec<f64>,
    offsets: Vec<f64>,
    draws: Vec<f64>,
    theta: Vec<f64>,
    face_sums: Vec<f64>,
    b: Vec<f64>,
}

impl McScratch {
    /// The targets of the last [`McModel::sample`].
    pub fn targets(&self) -> &[f64] {
        &self.targets
    }
}

// ---------------------------------------------------------------------------------------
// Monte Carlo: the run
// ---------------------------------------------------------------------------------------

/// Options of [`monte_carlo`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct McOptions {
    /// Fixed M, or the adaptive procedure of JCGM 101 §7.9.
    pub trials: Trials,
    /// Seed of the random streams.
    pub seed: u64,
    /// Significant digits of u_c for the validation of the GUM result (JCGM 101 §8.2).
    pub significant_digits: u32,
    /// Solver of the trials.
    pub solver: McSolver,
}

impl Default for McOptions {
    /// 10⁶ trials, seed 1, 2 significant digits, automatic solver.
    fn default() -> Self {
        McOptions {
            trials: Trials::Fixed(1_000_000),
            seed: 1,
            significant_digits: 2,
            solver: McSolver::Auto,
        }
    }
}

/// Monte Carlo results of one family of quantities, per index.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct McFamily {
    /// Mean of the trials.
    pub mean: Vec<f64>,
    /// Standard deviation of the trials: the standard uncertainty.
    pub u: Vec<f64>,
    /// Lower end of the probabilistically symmetric coverage interval.
    pub low: Vec<f64>,
    /// Upper end.
    pub high: Vec<f64>,
    /// |y − U − low| of the GUM result (JCGM 101 §8.2).
    pub d_low: Vec<f64>,
    /// |y + U − high|.
    pub d_high: Vec<f64>,
    /// Numerical tolerance δ of the GUM u_c.
    pub delta: Vec<f64>,
    /// Whether d_low and d_high are both within δ.
    pub passed: Vec<bool>,
}

/// The Monte Carlo evaluation of a calibration ([`monte_carlo`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationMonteCarlo {
    /// Trials M run.
    pub trials: usize,
    /// Sequences of the adaptive procedure (`null` for a fixed M).
    pub sequences: Option<usize>,
    /// Seed.
    pub seed: u64,
    /// Coverage probability.
    pub p: f64,
    /// Significant digits of the validation (and of the adaptive procedure).
    pub significant_digits: u32,
    /// `closed-form` or `lsq`.
    pub solver: &'static str,
    /// `normal` (stated σ) or `t` (σ from the residuals: scaled by √(ν/χ²_ν) per trial).
    pub reading_noise: &'static str,
    /// ν of the reading noise, `null` for normal.
    pub reading_noise_dof: Option<f64>,
    /// Whether every quantity's GUM interval is validated.
    pub validated: bool,
    /// Pitch deviations.
    pub pitch_deviation: McFamily,
    /// Face deviations (φ\[N\] = 0 exactly in every trial).
    pub face_deviation: McFamily,
    /// Encoder errors.
    pub encoder_error: McFamily,
}

/// Monte Carlo (GUM Supplement 1) of a calibration through its solver: per quantity the
/// mean, standard uncertainty, 95 % (the budget's p) probabilistically symmetric coverage
/// interval, and the validation of the GUM result `gum` (JCGM 101 §8).
///
/// # Errors
///
/// As [`evaluate`]; [`McError`] for too few trials, a non-finite trial, or an adaptive
/// run that does not stabilise.
pub fn monte_carlo(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
    gum: &CalibrationUncertainty,
    options: &McOptions,
) -> Result<CalibrationMonteCarlo, CalibrationError> {
    let model = McModel::new(set, solution, budget, options.solver)?;
    let summary = run(&model, options.trials, budget.p, options.seed)?;
    let n = model.faces;
    let digits = options.significant_digits.max(1);
    let family = |estimates: &[f64], gum: &FamilyUncertainty, first: usize, len: usize| {
        let mut f = McFamily {
            mean: Vec::with_capacity(n),
            u: Vec::with_capacity(n),
            low: Vec::with_capacity(n),
            high: Vec::with_capacity(n),
            d_low: Vec::with_capacity(n),
            d_high: Vec::with_capacity(n),
            delta: Vec::with_capacity(n),
            passed: Vec::with_capacity(n),
        };
        for (i, &estimate) in estimates.iter().enumerate() {
            let (mean, u, low, high) = if i < len {
                let j = first + i;
                (
                    summary.mean[j],
                    summary.u[j],
                    summary.low[j],
                    summary.high[j],
                )
            } else {
                (0.0, 0.0, 0.0, 0.0) // φ[N] = 0 in every trial
            };
            let mc = OutputSummary {
                mean,
                u,
                p: budget.p,
                low,
                high,
                shortest_low: f64::NAN,
                shortest_high: f64::NAN,
            };
            let v = validate_gum(estimate, gum.u[i], gum.expanded_u[i], &mc, digits);
            f.mean.push(mean);
            f.u.push(u);
            f.low.push(low);
            f.high.push(high);
            f.d_low.push(v.d_low);
            f.d_high.push(v.d_high);
            f.delta.push(v.delta);
            f.passed.push(v.passed);
        }
        f
    };
    let pitch = family(&solution.pitch_deviation, &gum.pitch_deviation, 0, n);
    let face = family(&solution.face_deviation, &gum.face_deviation, n, n - 1);
    let encoder = family(&solution.encoder_error, &gum.encoder_error, 2 * n - 1, n);
    let validated = [&pitch, &face, &encoder]
        .iter()
        .all(|f| f.passed.iter().all(|&p| p));
    let (reading_noise, reading_noise_dof) = model.reading_noise();
    Ok(CalibrationMonteCarlo {
        trials: summary.trials,
        sequences: summary.sequences,
        seed: options.seed,
        p: budget.p,
        significant_digits: digits,
        solver: model.solver_name(),
        reading_noise,
        reading_noise_dof,
        validated,
        pitch_deviation: pitch,
        face_deviation: face,
        encoder_error: encoder,
    })
}

/// Per output: mean, u, interval.
struct Summary {
    trials: usize,
    sequences: Option<usize>,
    mean: Vec<f64>,
    u: Vec<f64>,
    low: Vec<f64>,
    high: Vec<f64>,
}

/// Per output: [low bracket start, low bracket end, high bracket start, high bracket end].
type Brackets = Vec<[f64; 4]>;

/// Running sums and bracket contents of some trials.
struct Acc {
    /// Σ (x − c) and Σ (x − c)², c the estimate.
    s1: Vec<f64>,
    s2: Vec<f64>,
    /// Values below the low bracket, and above the high bracket.
    outside: Vec<[u64; 2]>,
    /// Values inside the low and the high bracket.
    inside: Vec<[Vec<f64>; 2]>,
}

impl Acc {
    fn new(outputs: usize) -> Self {
        Acc {
            s1: vec![0.0; outputs],
            s2: vec![0.0; outputs],
            outside: vec![[0; 2]; outputs],
            inside: (0..outputs).map(|_| [Vec::new(), Vec::new()]).collect(),
        }
    }

    #[inline]
    fn record(&mut self, out: &[f64], centre: &[f64], brackets: &[[f64; 4]]) {
        for ((s1, s2), (&x, &c)) in self
            .s1
            .iter_mut()
            .zip(self.s2.iter_mut())
            .zip(out.iter().zip(centre))
        {
            let d = x - c;
            *s1 += d;
            *s2 += d * d;
        }
        for (j, (&x, b)) in out.iter().zip(brackets).enumerate() {
            if x > b[1] && x < b[2] {
                continue; // between the brackets, the common case: nothing to count
            }
            if x < b[0] {
                self.outside[j][0] += 1;
            } else if x <= b[1] {
                self.inside[j][0].push(x);
            }
            if x > b[3] {
                self.outside[j][1] += 1;
            } else if x >= b[2] {
                self.inside[j][1].push(x);
            }
        }
    }

    fn merge(&mut self, other: Acc) {
        for j in 0..self.s1.len() {
            self.s1[j] += other.s1[j];
            self.s2[j] += other.s2[j];
            for side in 0..2 {
                self.outside[j][side] += other.outside[j][side];
            }
        }
        for (mine, [low, high]) in self.inside.iter_mut().zip(other.inside) {
            mine[0].extend(low);
            mine[1].extend(high);
        }
    }
}

fn order_statistic(values: &mut [f64], i: usize) -> f64 {
    *values.select_nth_unstable_by(i, f64::total_cmp).1
}

/// Runs trials `range` (its start a multiple of [`BLOCK_SIZE`]) in parallel blocks. With
/// `brackets`, returns the accumulated sums and brackets; without, every trial's outputs
/// (trial-major).
fn run_blocks(
    model: &McModel,
    seed: u64,
    range: Range<usize>,
    brackets: Option<&[[f64; 4]]>,
) -> Result<(Option<Acc>, Vec<f64>), CalibrationError> {
    debug_assert_eq!(range.start % BLOCK_SIZE, 0);
    let outputs = model.outputs();
    let first = range.start / BLOCK_SIZE;
    let last = range.end.div_ceil(BLOCK_SIZE);
    let blocks: Vec<(Option<Acc>, Vec<f64>)> = (first..last)
        .into_par_iter()
        .map(|b| {
            let from = b * BLOCK_SIZE;
            let to = ((b + 1) * BLOCK_SIZE).min(range.end);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(b as u64);
            let mut scratch = model.scratch();
            let mut out = vec![0.0; outputs];
            let mut acc = brackets.map(|_| Acc::new(outputs));
            let mut raw = Vec::new();
            if brackets.is_none() {
                raw.reserve((to - from) * outputs);
            }
            for trial in from..to {
                let solved = model.trial(&mut rng, &mut scratch, &mut out);
                if let Some((output, &value)) = out
                    .iter()
                    .enumerate()
                    .find(|(_, v)| !solved || !v.is_finite())
                {
                    return Err(McError::NonFinite {
                        trial,
                        output,
                        value,
                        inputs: scratch.targets.clone(),
                    });
                }
                match (&mut acc, brackets) {
                    (Some(acc), Some(b)) => acc.record(&out, &model.centre, b),
                    _ => raw.extend_from_slice(&out),
                }
            }
            Ok((acc, raw))
        })
        .collect::<Result<_, McError>>()?;
    let mut total = brackets.map(|_| Acc::new(outputs));
    let mut raw = Vec::new();
    for (acc, values) in blocks {
        if let (Some(total), Some(acc)) = (&mut total, acc) {
            total.merge(acc);
        }
        raw.extend(values);
    }
    Ok((total, raw))
}

/// Brackets around the interval ends of `m` trials from the sorted pilot columns,
/// `factor` times wider than a 6-σ binomial margin; ±∞ beyond the pilot.
fn brackets_from(pilot: &[Vec<f64>], m: usize, p: f64, factor: f64) -> Brackets {
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    pilot
        .iter()
        .map(|sorted| {
            let len = sorted.len();
            let mut b = [0.0; 4];
            for (side, r) in [r_low, r_high].into_iter().enumerate() {
                let pi = (r as f64 + 0.5) / m as f64;
                let centre = pi * len as f64;
                let margin = factor * (6.0 * (len as f64 * pi * (1.0 - pi)).sqrt() + 10.0);
                let lo = centre - margin;
                let hi = centre + margin;
                b[2 * side] = if lo < 0.0 {
                    f64::NEG_INFINITY
                } else {
                    sorted[lo as usize]
                };
                b[2 * side + 1] = if hi >= (len - 1) as f64 {
                    f64::INFINITY
                } else {
                    sorted[hi.ceil() as usize]
                };
            }
            b
        })
        .collect()
}

/// Sorted columns of trial-major raw outputs.
fn sorted_columns(raw: &[f64], outputs: usize) -> Vec<Vec<f64>> {
    (0..outputs)
        .into_par_iter()
        .map(|j| {
            let mut column: Vec<f64> = raw.iter().skip(j).step_by(outputs).copied().collect();
            column.sort_unstable_by(f64::total_cmp);
            column
        })
        .collect()
}

/// Accumulates trial-major raw outputs in trial order.
fn feed(acc: &mut Acc, raw: &[f64], centre: &[f64], brackets: &[[f64; 4]]) {
    for out in raw.chunks_exact(centre.len()) {
        acc.record(out, centre, brackets);
    }
}

/// Per output: mean, u, low and high end of the interval.
type Moments = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// Mean, u and the exact interval from the accumulated trials; `None` if a bracket
/// missed its order statistic.
fn finish(acc: Acc, m: usize, p: f64, centre: &[f64]) -> Option<Moments> {
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    let mf = m as f64;
    let mut mean = Vec::with_capacity(centre.len());
    let mut u = Vec::with_capacity(centre.len());
    let mut low = Vec::with_capacity(centre.len());
    let mut high = Vec::with_capacity(centre.len());
    for (j, [mut in_low, mut in_high]) in acc.inside.into_iter().enumerate() {
        mean.push(centre[j] + acc.s1[j] / mf);
        let ss = acc.s2[j] - acc.s1[j] * acc.s1[j] / mf;
        u.push(if m > 1 {
            (ss.max(0.0) / (mf - 1.0)).sqrt()
        } else {
            0.0
        });
        for (side, r, values, target) in [
            (0, r_low, &mut in_low, &mut low),
            (1, r_high, &mut in_high, &mut high),
        ] {
            // values below the bracket: counted below the low one; all but those in
            // and above the high one
            let below = if side == 0 {
                acc.outside[j][0] as usize
            } else {
                m - acc.outside[j][1] as usize - values.len()
            };
            if r < below || r >= below + values.len() {
                return None;
            }
            target.push(order_statistic(values, r - below));
        }
    }
    Some((mean, u, low, high))
}

/// Runs `model`: fixed M or adaptive, with exact intervals (see the module doc).
fn run(model: &McModel, trials: Trials, p: f64, seed: u64) -> Result<Summary, CalibrationError> {
    if !(p > 0.0 && p < 1.0) {
        return Err(CalibrationError::Coverage(p));
    }
    let outputs = model.outputs();
    let centre = &model.centre;
    let j = adaptive_sequence_length(p);
    // Exact summary of all trials `0..m` from a pilot and brackets, re-running the trials
    // after the pilot with wider brackets if one missed.
    let bracketed = |m: usize, pilot_raw: &[f64], pilot_len: usize| {
        let pilot = sorted_columns(pilot_raw, outputs);
        let mut factor = 1.0;
        loop {
            let wide = factor > 1000.0;
            let brackets = if wide {
                vec![
                    [
                        f64::NEG_INFINITY,
                        f64::INFINITY,
                        f64::NEG_INFINITY,
                        f64::INFINITY
                    ];
                    outputs
                ]
            } else {
                brackets_from(&pilot, m, p, factor)
            };
            let mut acc = Acc::new(outputs);
            feed(&mut acc, pilot_raw, centre, &brackets);
            if m > pilot_len {
                let (rest, _) = run_blocks(model, seed, pilot_len..m, Some(&brackets))?;
                acc.merge(rest.unwrap_or_else(|| unreachable!("brackets were given")));
            }
            if let Some(result) = finish(acc, m, p, centre) {
                return Ok::<_, CalibrationError>(result);
            }
            factor *= 16.0;
        }
    };
    match trials {
        Trials::Fixed(m) => {
            let needed = minimum_trials(p);
            if m < needed {
                return Err(McError::TooFewTrials {
                    trials: m,
                    p,
                    needed,
                }
                .into());
            }
            let pilot_len = m.min(j);
            let (_, pilot_raw) = run_blocks(model, seed, 0..pilot_len, None)?;
            let (mean, u, low, high) = bracketed(m, &pilot_raw, pilot_len)?;
            Ok(Summary {
                trials: m,
                sequences: None,
                mean,
                u,
                low,
                high,
            })
        }
        Trials::Adaptive {
            significant_digits,
            max_trials,
        } => {
            let digits = significant_digits.max(1);
            let (r_low, r_high) = symmetric_interval_positions(j, p);
            // Per output, per sequence: mean, u, low, high.
            let mut estimates: Vec<Vec<[f64; 4]>> = vec![Vec::new(); outputs];
            // All sequences so far, bracketed around the interval ends of the first.
            let mut first_raw = Vec::new();
            let mut brackets = Vec::new();
            let mut acc = Acc::new(outputs);
            let mut h = 0;
            loop {
                if (h + 1) * j > max_trials.max(2 * j) {
                    return Err(McError::NotStabilized {
                        trials: h * j,
                        digits,
                    }
                    .into());
                }
                let (_, raw) = run_blocks(model, seed, h * j..(h + 1) * j, None)?;
                let per_sequence: Vec<[f64; 4]> = (0..outputs)
                    .into_par_iter()
                    .map(|o| {
                        let mut column: Vec<f64> =
                            raw.iter().skip(o).step_by(outputs).copied().collect();
                        let jf = column.len() as f64;
                        let (a, b) = column.iter().fold((0.0, 0.0), |(a, b), &x| {
                            let d = x - centre[o];
                            (a + d, b + d * d)
                        });
                        let mean = centre[o] + a / jf;
                        let u = ((b - a * a / jf).max(0.0) / (jf - 1.0)).sqrt();
                        let low = order_statistic(&mut column, r_low);
                        let high = order_statistic(&mut column, r_high);
                        [mean, u, low, high]
                    })
                    .collect();
                for (o, e) in per_sequence.into_iter().enumerate() {
                    estimates[o].push(e);
                }
                if h == 0 {
                    brackets = brackets_from(&sorted_columns(&raw, outputs), j, p, 1.0);
                }
                feed(&mut acc, &raw, centre, &brackets);
                if h == 0 {
                    first_raw = raw;
                }
                h += 1;
                if h < 2 {
                    continue;
                }
                let m = (h * j) as f64;
                let stable = (0..outputs).all(|o| {
                    let (s1, s2) = (acc.s1[o], acc.s2[o]);
                    let u_all = ((s2 - s1 * s1 / m).max(0.0) / (m - 1.0)).sqrt();
                    let delta = numerical_tolerance(u_all, digits);
                    (0..4).all(|q| {
                        let xs: Vec<f64> = estimates[o].iter().map(|e| e[q]).collect();
                        2.0 * standard_deviation_of_mean(&xs) <= delta
                    })
                });
                if stable {
                    let m = h * j;
                    // The brackets were set for j trials; if one missed for m, re-run.
                    let (mean, u, low, high) = match finish(acc, m, p, centre) {
                        Some(result) => result,
                        None => bracketed(m, &first_raw, j)?,
                    };
                    return Ok(Summary {
                        trials: m,
                        sequences: Some(h),
                        mean,
                        u,
                        low,
                        high,
                    });
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Direction, Reading};
    use crate::solve::{Method, SolveOptions, solve};

    fn set(n: usize, cycles: u32, closing: bool, seed: u64) -> MeasurementSet {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut readings = Vec::new();
        for cycle in 1..=cycles {
            for step in 0..(if closing { n + 1 } else { n }) {
                for (ac, d) in [(1u32, 0usize), (2, 1)] {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    readings.push(Reading {
                        setup: 1,
                        cycle,
                        step,
                        ac,
                        face: (step + d) % n + 1,
                        reading_arcsec: (step as f64 * 0.7).sin() + 0.3 * d as f64 + 0.1 * z,
                        direction: Direction::Cw,
                        time_seconds: None,
                        reading_y_arcsec: None,
                        temperature_celsius: None,
                        encoder_degrees: None,
                        line: 0,
                    });
                }
            }
        }
        MeasurementSet {
            faces: n,
            readings,
            source: "test".into(),
        }
    }

    /// L = Q Xᵀ reproduces the solver: θ̂ = L y, for least squares and the closed form.
    #[test]
    fn operator_is_the_solver() {
        for (closing, method) in [(true, Method::LeastSquares), (false, Method::ClosedForm)] {
            let s = set(7, 3, closing, 4);
            let solution = solve(
                &s,
                &SolveOptions {
                    method,
                    ..Default::default()
                },
            )
            .unwrap();
            let op = Operator::new(&s, &solution).unwrap();
            let y: Vec<f64> = s.readings.iter().map(|r| r.reading_arcsec).collect();
            let mut theta = vec![0.0; op.len()];
            for (i, &v) in y.iter().enumerate() {
                op.add_column(i, v, &mut theta);
            }
            let mut theta2 = vec![0.0; op.len()];
            op.solve(
                &y,
                &mut [0.0; 7],
                &mut vec![0.0; op.len()],
                0..op.len(),
                &mut theta2,
            );
            for k in 0..7 {
                assert!((theta[k] - solution.pitch_deviation[k]).abs() < 1e-12);
                assert!((theta2[k] - solution.pitch_deviation[k]).abs() < 1e-12);
                assert!((theta[7 + k] - solution.encoder_error[k]).abs() < 1e-12);
                assert!((theta2[7 + k] - solution.encoder_error[k]).abs() < 1e-12);
            }
            // Σ_i L_ji² = Q_jj (L Lᵀ = Q)
            let g = gains(&op, &s, Scope::EachReading);
            let sigma = solution.sigma.unwrap().0;
            let u = solution.pitch_deviation_u().unwrap();
            let uf = solution.face_deviation_u().unwrap();
            let ua = solution.encoder_error_u().unwrap();
            for k in 0..7 {
                assert!((sigma * g[k].sqrt() - u[k]).abs() < 1e-12);
                assert!((sigma * g[7 + k].sqrt() - uf[k]).abs() < 1e-12);
                assert!((sigma * g[14 + k].sqrt() - ua[k]).abs() < 1e-12);
            }
        }
    }

    /// The closed-form trial and the least-squares trial solve the same targets alike.
    #[test]
    fn closed_form_and_least_squares_trials_agree() {
        let s = set(24, 2, false, 9);
        let solution = solve(&s, &SolveOptions::default()).unwrap();
        let budget = InstrumentBudget::new(vec![
            ScopedComponent::type_b(
                "r",
                Distribution::Rectangular { half_width: 0.1 },
                Scope::EachStop,
            ),
            ScopedComponent::type_b("n", Distribution::Normal { u: 0.1 }, Scope::EachReading),
        ]);
        let cf = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
        let ls = McModel::new(&s, &solution, &budget, McSolver::LeastSquares).unwrap();
        assert_eq!((cf.solver_name(), ls.solver_name()), ("closed-form", "lsq"));
        let mut scratch = cf.scratch();
        let mut out = vec![0.0; cf.outputs()];
        scratch.targets.copy_from_slice(&cf.base);
        assert!(cf.solve(&mut scratch, &mut out));
        for (a, b) in out.iter().zip(cf.estimates()) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
        let mut ls_scratch = ls.scratch();
        let mut ls_out = vec![0.0; ls.outputs()];
        ls_scratch.targets.copy_from_slice(&ls.base);
        assert!(ls.solve(&mut ls_scratch, &mut ls_out));
        for (a, b) in ls_out.iter().zip(ls.estimates()) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
    }

    /// The bracketed run gives the mean, u and interval of a full sort of every trial.
    #[test]
    fn bracketed_run_is_the_full_sort() {
        let s = set(9, 2, true, 5);
        let solution = solve(&s, &SolveOptions::default()).unwrap();
        let budget = InstrumentBudget::new(vec![ScopedComponent::type_b(
            "r",
            Distribution::Rectangular { half_width: 0.2 },
            Scope::Result,
        )]);
        let model = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
        let adaptive = Trials::Adaptive {
            significant_digits: 1,
            max_trials: 500_000,
        };
        for trials in [Trials::Fixed(34_500), adaptive] {
            let summary = run(&model, trials, 0.95, 11).unwrap();
            let m = summary.trials;
            let (_, raw) = run_blocks(&model, 11, 0..m, None).unwrap();
            let columns = sorted_columns(&raw, model.outputs());
            let (r_low, r_high) = symmetric_interval_positions(m, 0.95);
            for (j, column) in columns.iter().enumerate() {
                assert_eq!(summary.low[j], column[r_low]);
                assert_eq!(summary.high[j], column[r_high]);
                let mean = column.iter().sum::<f64>() / m as f64;
                let ss = column.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
                let u = (ss / (m - 1) as f64).sqrt();
                assert!((summary.mean[j] - mean).abs() < 1e-12);
                assert!((summary.u[j] - u).abs() < 1e-12 * u);
            }
        }
    }

    /// The fast draws are the draws of `Sampler::sample`, value for value.
    #[test]
    fn draws_are_the_sampler_draws() {
        for d in [
            Distribution::Normal { u: 0.3 },
            Distribution::Rectangular { half_width: 0.2 },
            Distribution::Triangular { half_width: 0.2 },
            Distribution::Arcsine { half_width: 0.2 },
            Distribution::StudentT {
                scale: 0.1,
                dof: 4.0,
            },
        ] {
            let sampler = d.sampler().unwrap();
            let mut a = ChaCha8Rng::seed_from_u64(3);
            let mut b = ChaCha8Rng::seed_from_u64(3);
            let mut buf = [0.0; 50];
            draw_into(&sampler, &mut a, &mut buf);
            for x in buf {
                assert_eq!(x, sampler.sample(&mut b), "{d:?}");
            }
        }
    }

    /// A bracket too narrow to hold its order statistic is widened, and the interval is
    /// the one a full sort gives.
    #[test]
    fn missed_brackets_are_widened() {
        let raw: Vec<f64> = (0..2000).map(|i| ((i * 7919) % 2000) as f64).collect();
        let centre = [0.0];
        let brackets = vec![[10.0, 11.0, 1900.0, 1901.0]];
        let mut acc = Acc::new(1);
        feed(&mut acc, &raw, &centre, &brackets);
        assert!(finish(acc, 2000, 0.95, &centre).is_none());
        let pilot = sorted_columns(&raw, 1);
        let brackets = brackets_from(&pilot, 2000, 0.95, 1.0);
        let mut acc = Acc::new(1);
        feed(&mut acc, &raw, &centre, &brackets);
        let (_, _, low, high) = finish(acc, 2000, 0.95, &centre).unwrap();
        let (r_low, r_high) = symmetric_interval_positions(2000, 0.95);
        assert_eq!((low[0], high[0]), (pilot[0][r_low], pilot[0][r_high]));
    }
}
