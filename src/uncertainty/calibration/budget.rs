//! Scopes (`acts_on`: which readings share one draw of a type-B error) and the
//! instrument budget file read by `polycal solve --budget`: the budget TOML of docs/FORMAT.md
//! §5 with `acts_on` per component.

use std::ops::Range;
use std::path::Path;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::CalibrationError;
use crate::input::Location;
use crate::uncertainty::budget::{
    Budget, BudgetError, ComponentError, DofPolicy, EvaluationType, Source,
};
use crate::uncertainty::budget_file::{BudgetFile, location, read_budget_text};
use crate::uncertainty::distribution::Distribution;
use crate::uncertainty::monte_carlo::monte_carlo_distribution;

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
    type Err = BudgetError;

    /// Reads a scope as spelled in budget files ([`Scope::as_str`]).
    ///
    /// # Errors
    ///
    /// [`BudgetError::UnknownScope`] for any other text.
    fn from_str(s: &str) -> Result<Scope, BudgetError> {
        Scope::ALL
            .into_iter()
            .find(|scope| scope.as_str() == s)
            .ok_or_else(|| BudgetError::UnknownScope(s.to_string()))
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
    /// [`crate::uncertainty::monte_carlo::linear_budget_inputs`].
    pub(super) fn mc_distribution(&self) -> Distribution {
        monte_carlo_distribution(self.evaluation, self.distribution, self.dof)
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

    /// Parses a budget file: the budget TOML of docs/FORMAT.md §5 read as strictly as by
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
        let at = |span: Range<usize>, message: String| BudgetError::File {
            location: location(source, text, span.start),
            message,
        };
        let raw: RawScopeFile = toml::from_str(text)
            .map_err(|e| at(e.span().unwrap_or(0..0), e.message().trim_end().to_string()))?;
        let mut spans = Vec::new();
        let tree = scope_tree(&raw.component, &at, &mut spans)?;
        // Blank the acts_on entries (bytes kept, so every line and column stays) and let
        // the budget reader check the rest.
        let mut bytes = text.as_bytes().to_vec();
        for span in spans {
            let key = acts_on_key(text, span.clone()).ok_or_else(|| {
                at(
                    span.clone(),
                    "write acts_on on a line of its own, as acts_on = \"each-reading\"".into(),
                )
            })?;
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
            location: Location::file_only(source),
            error: Box::new(error),
        };
        file.budget.combine().map_err(in_file)?;
        let mut components = Vec::new();
        flatten(&file.budget, &tree, Scope::Result, 1.0, "", &mut components).map_err(in_file)?;
        for c in &components {
            if let Err(problem) = contribution_within_limits(c) {
                return Err(in_file(BudgetError::Component {
                    component: c.name.clone(),
                    problem,
                }));
            }
        }
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
        if !crate::input::limits::COVERAGE_PROBABILITY.contains(self.p) {
            return Err(CalibrationError::Coverage(self.p));
        }
        for c in &self.components {
            let bad = |problem: ComponentError| CalibrationError::Component {
                name: c.name.clone(),
                problem,
            };
            c.distribution.check().map_err(|e| bad(e.into()))?;
            if !c.sensitivity.is_finite() {
                return Err(bad(ComponentError::SensitivityNotFinite {
                    sensitivity: c.sensitivity,
                }));
            }
            if let Some(dof) = c.dof
                && !(dof.is_finite() && dof >= 1.0)
            {
                return Err(bad(ComponentError::DofBelowOne {
                    dof,
                    infinite: "None",
                }));
            }
            contribution_within_limits(c).map_err(bad)?;
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
                     of the readings (repeatability) from its residuals or a stated σ; keep it only \
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
                    Some(
                        s.get_ref()
                            .parse::<Scope>()
                            .map_err(|e| at(s.span(), e.to_string()))?,
                    )
                }
            };
            Ok(ScopeNode {
                scope,
                children: scope_tree(&c.component, at, spans)?,
            })
        })
        .collect()
}

/// The byte range from the `acts_on` key to the end of its value, for a value at `value`;
/// `None` unless the key stands on a line of its own.
fn acts_on_key(text: &str, value: Range<usize>) -> Option<Range<usize>> {
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
    key_start
        .filter(|&start| !inline(start))
        .map(|start| start..value.end)
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

/// An instrument's error reaches the readings in arcseconds: its contribution |c|·u may
/// be at most the largest reading (docs/FORMAT.md §2.2), so that every result it adds to
/// stays within the limits of a result file.
fn contribution_within_limits(c: &ScopedComponent) -> Result<(), ComponentError> {
    let contribution = c.sensitivity.abs() * c.distribution.standard_uncertainty();
    crate::input::limits::READING_ARCSEC
        .check(
            contribution,
            "an instrument's contribution |c|·u (arcseconds)",
        )
        .map(|_| ())
        .map_err(|rule| ComponentError::ContributionBeyondReadings(Box::new(rule)))
}
