//! The budget file of docs/FORMAT.md §5 (TOML), read strictly.
//!
//! ```toml
//! p = 0.95                       # coverage probability (default 0.95)
//! dof_policy = "fractional"      # "fractional" (default), "floor" or "k2"
//!
//! [[component]]
//! name = "Angle error of autocollimator"
//! type = "B"                     # "A" or "B"
//! distribution = "rectangular"   # "normal" (default), "rectangular", "triangular",
//!                                # "arcsine", "t"
//! full_width = 0.27              # or half_width; or u; or expanded + k (normal);
//!                                # or scale (t)
//! sensitivity = 1.0              # default 1
//! dof = 50                       # omit for infinite (or write inf)
//! ```
//!
//! Additions to docs/FORMAT.md §5 (all optional):
//!
//! - `distribution = "t"` with `scale` (or `u`) and `dof`: a scaled Student's t
//!   (JCGM 101 §6.4.9); the budget takes `u = scale` with `ν = dof`.
//! - Nested budgets: a `[[component]]` that holds `[[component.component]]` tables (and no
//!   `type`, `distribution`, width or `dof` of its own) is an intermediate quantity whose
//!   standard uncertainty is the nested `u_c` and whose degrees of freedom are the nested
//!   `ν_eff`, both unrounded. Its output `type` is `A`, `B`, or `A+B` when it combines both.
//! - Correlations: `[[correlation]]` tables with `between = ["name 1", "name 2"]` and
//!   `r = 0.5` (also `[[component.correlation]]` inside a nested budget). Welch–Satterthwaite
//!   is then refused if a correlated component has finite degrees of freedom.
//!
//! Anything ambiguous, missing or unknown is refused with the file, line and column: two
//! of `full_width`/`half_width`/`u`/`expanded`/`scale`, `expanded` without `k`, an unknown
//! key or distribution, a negative width, `dof < 1`, `p` outside (0, 1), duplicate names,
//! and so on. Nothing is guessed.

use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::budget::{
    Budget, BudgetError, BudgetResult, Component, Correlation, DofPolicy, EvaluationType,
};
use super::distribution::Distribution;
use crate::input::kind::{self, FileKind};
use crate::input::limits;
use crate::input::{self, Location};

/// A budget read from a file, with its coverage probability and degrees-of-freedom policy.
#[derive(Debug, Clone, PartialEq)]
pub struct BudgetFile {
    /// Where it came from: the path, or `<stdin>`.
    pub source: String,
    /// Coverage probability `p` (default 0.95).
    pub p: f64,
    /// Degrees-of-freedom policy (default fractional).
    pub dof_policy: DofPolicy,
    /// The budget.
    pub budget: Budget,
}

/// The name and text of a budget file; the path `-` reads standard input (named
/// [`crate::input::STDIN_NAME`] in messages).
pub(crate) fn read_budget_text(path: &Path) -> Result<(String, String), BudgetError> {
    let io = |name: String, source| BudgetError::Io {
        location: Location::file_only(name),
        source,
    };
    let (bytes, name) = input::read_bytes(path).map_err(|(name, e)| io(name, e))?;
    match input::text::utf8(&bytes) {
        Ok(text) => {
            // a table given as a budget: say what it is rather than TOML's "key with no value"
            if let Some(found) =
                kind::recognize(text).filter(|k| !matches!(k, FileKind::Budget | FileKind::Json))
            {
                return Err(BudgetError::WrongKind {
                    location: Location::new(name.clone(), kind::telling_line(text), 1),
                    message: kind::other_kind_message(found, FileKind::Budget.name(), text),
                    found,
                });
            }
            Ok((name, text.to_string()))
        }
        Err(((line, column), message)) => Err(BudgetError::File {
            location: Location::new(name, line, column),
            message,
        }),
    }
}

/// A place in a budget file's text: its name, and the line and column of a byte offset.
pub(crate) fn location(source: &str, text: &str, offset: usize) -> Location {
    let (line, column) = line_column(text, offset);
    Location::new(source, line as u64, column as u64)
}

impl BudgetFile {
    /// Reads and checks a budget file; `-` reads standard input.
    ///
    /// # Errors
    ///
    /// [`BudgetError::Io`] if the file cannot be read, [`BudgetError::File`] (file, line,
    /// column, message) if it is not a valid budget.
    pub fn read_path(path: impl AsRef<Path>) -> Result<BudgetFile, BudgetError> {
        let (source, text) = read_budget_text(path.as_ref())?;
        BudgetFile::from_toml_str(&text, &source)
    }

    /// Parses and checks a budget from TOML text; `source` names it in error messages.
    ///
    /// # Errors
    ///
    /// [`BudgetError::File`] naming `source`, the line and the column.
    pub fn from_toml_str(text: &str, source: &str) -> Result<BudgetFile, BudgetError> {
        let at = |span: Range<usize>, message: String| BudgetError::File {
            location: location(source, text, span.start),
            message,
        };
        let raw: RawFile = toml::from_str(text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            let mut message = e
                .message()
                .trim_end()
                .replace("expected f64", "expected a number");
            if message == "duplicate key"
                && let Some(key) = text.get(span.clone())
            {
                message = format!("duplicate key `{}`", key.trim());
            }
            at(span, message)
        })?;
        let p = match &raw.p {
            None => 0.95,
            Some(p) => {
                let value = *p.get_ref();
                if !limits::COVERAGE_PROBABILITY.contains(value) {
                    let hint = if value > 1.0 && value < 100.0 {
                        format!(" (a probability: write {} for {value} %)", value / 100.0)
                    } else {
                        String::new()
                    };
                    return Err(at(
                        p.span(),
                        format!(
                            "p must be within 0.5 … 0.9999 (docs/FORMAT.md §2.2), got {}{hint}",
                            limits::show(value)
                        ),
                    ));
                }
                value
            }
        };
        let dof_policy = match &raw.dof_policy {
            None => DofPolicy::Fractional,
            Some(s) => s
                .get_ref()
                .parse()
                .map_err(|e: BudgetError| at(s.span(), e.to_string()))?,
        };
        if raw.component.is_empty() {
            return Err(at(
                0..0,
                "the budget has no [[component]] tables".to_string(),
            ));
        }
        let budget = build_budget(&raw.component, &raw.correlation, &at)?;
        Ok(BudgetFile {
            source: source.to_string(),
            p,
            dof_policy,
            budget,
        })
    }

    /// Evaluates the budget with the file's `p` and policy. Errors of the whole budget
    /// (such as a zero combined uncertainty) name the file.
    ///
    /// # Errors
    ///
    /// [`BudgetError::InFile`] wrapping the evaluation error.
    pub fn evaluate(&self) -> Result<BudgetResult, BudgetError> {
        self.budget
            .evaluate(self.p, self.dof_policy)
            .map_err(|e| BudgetError::InFile {
                location: Location::file_only(&self.source),
                error: Box::new(e),
            })
    }
}

/// Reads and checks a budget file (`-` = standard input); see [`BudgetFile::read_path`].
///
/// # Errors
///
/// As [`BudgetFile::read_path`].
pub fn read_budget_path(path: impl AsRef<Path>) -> Result<BudgetFile, BudgetError> {
    BudgetFile::read_path(path)
}

/// 1-based line and column (in characters) of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFile {
    p: Option<Spanned<f64>>,
    dof_policy: Option<Spanned<String>>,
    #[serde(default)]
    component: Vec<Spanned<RawComponent>>,
    #[serde(default)]
    correlation: Vec<Spanned<RawCorrelation>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawComponent {
    name: Option<Spanned<String>>,
    #[serde(rename = "type")]
    kind: Option<Spanned<String>>,
    distribution: Option<Spanned<String>>,
    full_width: Option<Spanned<f64>>,
    half_width: Option<Spanned<f64>>,
    u: Option<Spanned<f64>>,
    expanded: Option<Spanned<f64>>,
    k: Option<Spanned<f64>>,
    scale: Option<Spanned<f64>>,
    sensitivity: Option<Spanned<f64>>,
    dof: Option<Spanned<f64>>,
    #[serde(default)]
    component: Vec<Spanned<RawComponent>>,
    #[serde(default)]
    correlation: Vec<Spanned<RawCorrelation>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCorrelation {
    between: Spanned<Vec<Spanned<String>>>,
    r: Spanned<f64>,
}

const EXPANDED_NEEDS_K: &str = "expanded needs its coverage factor k (e.g. k = 2)";

type At<'a> = dyn Fn(Range<usize>, String) -> BudgetError + 'a;

fn build_budget(
    components: &[Spanned<RawComponent>],
    correlations: &[Spanned<RawCorrelation>],
    at: &At<'_>,
) -> Result<Budget, BudgetError> {
    let mut built: Vec<Component> = Vec::with_capacity(components.len());
    let mut by_name: HashMap<String, usize> = HashMap::with_capacity(components.len());
    for raw in components {
        let c = build_component(raw, at)?;
        if by_name.insert(c.name.clone(), built.len()).is_some() {
            let span = raw
                .get_ref()
                .name
                .as_ref()
                .map_or(raw.span(), Spanned::span);
            return Err(at(
                span,
                format!(
                    "a second component is named {:?}: names must be unique within a budget",
                    c.name
                ),
            ));
        }
        built.push(c);
    }
    let mut pairs: HashSet<(usize, usize)> = HashSet::new();
    let mut built_correlations = Vec::with_capacity(correlations.len());
    for corr in correlations {
        let raw = corr.get_ref();
        let names = raw.between.get_ref();
        if names.len() != 2 {
            return Err(at(
                raw.between.span(),
                format!(
                    "between must name exactly two components, got {}",
                    names.len()
                ),
            ));
        }
        let mut index = [0usize; 2];
        for (slot, name) in index.iter_mut().zip(names) {
            *slot = by_name
                .get(name.get_ref().as_str())
                .copied()
                .ok_or_else(|| {
                    at(
                        name.span(),
                        format!("no component of this budget is named {:?}", name.get_ref()),
                    )
                })?;
        }
        if index[0] == index[1] {
            return Err(at(
                raw.between.span(),
                "a component cannot be correlated with itself".to_string(),
            ));
        }
        let pair = (index[0].min(index[1]), index[0].max(index[1]));
        if !pairs.insert(pair) {
            return Err(at(
                raw.between.span(),
                "this pair of components is already correlated above".to_string(),
            ));
        }
        let r = *raw.r.get_ref();
        if !(r.is_finite() && (-1.0..=1.0).contains(&r)) {
            return Err(at(
                raw.r.span(),
                format!("r must be between -1 and 1, got {}", limits::show(r)),
            ));
        }
        if r != 0.0 {
            for &i in &index {
                if let super::budget::Source::Input { dof: Some(nu), .. } = &built[i].source {
                    return Err(at(
                        corr.span(),
                        format!(
                            "{:?} has {nu} degrees of freedom and is correlated: the \
                             Welch–Satterthwaite formula holds for independent inputs only; \
                             give correlated inputs infinite degrees of freedom (omit dof) if \
                             that is justified, or use Monte Carlo",
                            built[i].name
                        ),
                    ));
                }
            }
        }
        built_correlations.push(Correlation {
            a: names[0].get_ref().clone(),
            b: names[1].get_ref().clone(),
            r,
        });
    }
    Ok(Budget {
        components: built,
        correlations: built_correlations,
    })
}

fn build_component(raw: &Spanned<RawComponent>, at: &At<'_>) -> Result<Component, BudgetError> {
    // The span of an array-of-tables element begins at its [[component]] header, where
    // errors about the whole component point.
    let span = raw.span();
    let c = raw.get_ref();
    let name = c.checked_name(&span, at)?;
    let sensitivity = c.checked_sensitivity(at)?;
    if !c.component.is_empty() {
        // A nested budget: everything but the name and sensitivity comes from inside.
        let budget = c.nested_budget(&name, at)?;
        return Ok(Component::nested(name, budget).with_sensitivity(sensitivity));
    }
    if let Some(corr) = c.correlation.first() {
        return Err(at(
            corr.span(),
            format!(
                "component {name:?} has no nested components: correlations belong to the \
                 budget that holds both components ([[correlation]])"
            ),
        ));
    }
    let evaluation = c.evaluation_type(&span, &name, at)?;
    let distribution_name = c.distribution_name(&span, at)?;
    c.check_numbers(at)?;
    let dof = c.degrees_of_freedom(at)?;
    let given = c.uncertainty_given(distribution_name, &name, &span, at)?;
    let distribution = c.distribution(distribution_name, given, dof, &name, &span, at)?;
    Ok(Component::input(name, evaluation, distribution, dof).with_sensitivity(sensitivity))
}

impl RawComponent {
    /// Its numbers by key: widths, uncertainties, k, the t distribution's scale, dof.
    fn numbers(&self) -> [(&'static str, &Option<Spanned<f64>>); 7] {
        [
            ("full_width", &self.full_width),
            ("half_width", &self.half_width),
            ("u", &self.u),
            ("expanded", &self.expanded),
            ("k", &self.k),
            ("scale", &self.scale),
            ("dof", &self.dof),
        ]
    }

    /// Its name, which must be given and not empty (`span`: the component's header).
    fn checked_name(&self, span: &Range<usize>, at: &At<'_>) -> Result<String, BudgetError> {
        match &self.name {
            None => Err(at(
                span.clone(),
                "this component has no name (name = \"...\")".to_string(),
            )),
            Some(n) if n.get_ref().trim().is_empty() => {
                Err(at(n.span(), "the name is empty".to_string()))
            }
            Some(n) => Ok(n.get_ref().clone()),
        }
    }

    /// Its sensitivity coefficient: 1 unless given, finite and within the budget's limits.
    fn checked_sensitivity(&self, at: &At<'_>) -> Result<f64, BudgetError> {
        match &self.sensitivity {
            None => Ok(1.0),
            Some(s) => {
                let v = *s.get_ref();
                if !v.is_finite() {
                    return Err(at(
                        s.span(),
                        format!("sensitivity must be a finite number, got {v}"),
                    ));
                }
                limits::BUDGET_VALUE
                    .check(v, "a sensitivity")
                    .map_err(|rule| at(s.span(), format!("sensitivity: {rule}")))
            }
        }
    }

    /// The budget of its nested components, which give its standard uncertainty, type and
    /// degrees of freedom (refused beside a type, distribution or number of its own).
    fn nested_budget(&self, name: &str, at: &At<'_>) -> Result<Budget, BudgetError> {
        let own = [
            ("type", self.kind.as_ref().map(Spanned::span)),
            (
                "distribution",
                self.distribution.as_ref().map(Spanned::span),
            ),
        ]
        .into_iter()
        .chain(
            self.numbers()
                .iter()
                .map(|(key, v)| (*key, v.as_ref().map(Spanned::span))),
        )
        .find_map(|(key, s)| s.map(|s| (key, s)));
        if let Some((key, s)) = own {
            return Err(at(
                s,
                format!(
                    "component {name:?} has nested components, which give its standard \
                     uncertainty, type and degrees of freedom: remove {key}"
                ),
            ));
        }
        build_budget(&self.component, &self.correlation, at)
    }

    /// Its type of evaluation, A or B, which must be given.
    fn evaluation_type(
        &self,
        span: &Range<usize>,
        name: &str,
        at: &At<'_>,
    ) -> Result<EvaluationType, BudgetError> {
        match &self.kind {
            None => Err(at(
                span.clone(),
                format!("component {name:?} has no type: write type = \"A\" or type = \"B\""),
            )),
            Some(t) => match t.get_ref().as_str() {
                "A" => Ok(EvaluationType::A),
                "B" => Ok(EvaluationType::B),
                other => Err(at(
                    t.span(),
                    format!("type must be \"A\" or \"B\", got {other:?}"),
                )),
            },
        }
    }

    /// The name of its distribution: normal unless given, one of those known.
    fn distribution_name(&self, span: &Range<usize>, at: &At<'_>) -> Result<&str, BudgetError> {
        let distribution_name = self
            .distribution
            .as_ref()
            .map_or("normal", |d| d.get_ref().as_str());
        let distribution_span = self
            .distribution
            .as_ref()
            .map_or(span.clone(), Spanned::span);
        if !matches!(
            distribution_name,
            "normal" | "rectangular" | "triangular" | "arcsine" | "t"
        ) {
            return Err(at(
                distribution_span,
                format!(
                    "unknown distribution {distribution_name:?}: expected \"normal\", \
                     \"rectangular\", \"triangular\", \"arcsine\" or \"t\""
                ),
            ));
        }
        Ok(distribution_name)
    }

    /// Every number finite and within its limit; widths and uncertainties not negative;
    /// k only with expanded (and expanded only with k), greater than 0.
    fn check_numbers(&self, at: &At<'_>) -> Result<(), BudgetError> {
        for (key, value) in &self.numbers() {
            if let Some(v) = value {
                let x = *v.get_ref();
                if x.is_nan() || (x.is_infinite() && *key != "dof") {
                    return Err(at(
                        v.span(),
                        format!("{key} must be a finite number, got {x}"),
                    ));
                }
                if x < 0.0 && *key != "dof" && *key != "k" {
                    return Err(at(v.span(), format!("{key} must not be negative, got {x}")));
                }
                let limit = match *key {
                    "dof" => None,
                    "k" => Some(limits::COVERAGE_FACTOR),
                    _ => Some(limits::BUDGET_VALUE),
                };
                if let Some(limit) = limit
                    && x > 0.0
                    && let Err(rule) = limit.check(x, &format!("a budget's {key}"))
                {
                    return Err(at(v.span(), format!("{key}: {rule}")));
                }
            }
        }
        if let (Some(k), None) = (&self.k, &self.expanded) {
            return Err(at(
                k.span(),
                "k is given without expanded: k is the coverage factor of an expanded uncertainty"
                    .to_string(),
            ));
        }
        if let (Some(e), None) = (&self.expanded, &self.k) {
            return Err(at(e.span(), EXPANDED_NEEDS_K.to_string()));
        }
        if let Some(k) = &self.k
            && *k.get_ref() <= 0.0
        {
            return Err(at(
                k.span(),
                format!("k must be greater than 0, got {}", k.get_ref()),
            ));
        }
        Ok(())
    }

    /// Its degrees of freedom: at least 1, `None` for infinitely many (omitted or `inf`).
    fn degrees_of_freedom(&self, at: &At<'_>) -> Result<Option<f64>, BudgetError> {
        match &self.dof {
            None => Ok(None),
            Some(d) => {
                let nu = *d.get_ref();
                if nu == f64::INFINITY {
                    Ok(None)
                } else if nu >= 1.0 {
                    Ok(Some(nu))
                } else {
                    Err(at(
                        d.span(),
                        format!(
                            "dof must be at least 1 (omit it, or write inf, for infinitely \
                             many), got {nu}"
                        ),
                    ))
                }
            }
        }
    }

    /// Its one specification of the width or uncertainty (key and value), one that the
    /// distribution `distribution_name` takes.
    fn uncertainty_given(
        &self,
        distribution_name: &str,
        name: &str,
        span: &Range<usize>,
        at: &At<'_>,
    ) -> Result<(&'static str, &Spanned<f64>), BudgetError> {
        let numbers = self.numbers();
        let specs: Vec<(&'static str, &Spanned<f64>)> = numbers
            .iter()
            .filter(|(key, _)| {
                matches!(
                    *key,
                    "full_width" | "half_width" | "u" | "expanded" | "scale"
                )
            })
            .filter_map(|(key, v)| v.as_ref().map(|v| (*key, v)))
            .collect();
        let allowed: &[&str] = match distribution_name {
            "normal" => &["u", "expanded"],
            "t" => &["scale", "u"],
            _ => &["full_width", "half_width", "u"],
        };
        let allowed_text = match distribution_name {
            "normal" => "u, or expanded and k",
            "t" => "scale (or u) and dof",
            _ => "full_width, half_width or u",
        };
        let (key, value) = match specs.as_slice() {
            [] => {
                return Err(at(
                    span.clone(),
                    format!(
                        "component {name:?} gives no uncertainty: a {distribution_name} \
                         distribution takes {allowed_text}"
                    ),
                ));
            }
            [one] => *one,
            [first, second, ..] => {
                return Err(at(
                    second.1.span(),
                    format!(
                        "component {name:?} gives both {} and {}: give exactly one",
                        first.0, second.0
                    ),
                ));
            }
        };
        if !allowed.contains(&key) {
            return Err(at(
                value.span(),
                format!("a {distribution_name} distribution takes {allowed_text}, not {key}"),
            ));
        }
        Ok((key, value))
    }

    /// Its distribution, from the specification `given` (key, value) and the degrees of
    /// freedom `dof`.
    fn distribution(
        &self,
        distribution_name: &str,
        (key, value): (&str, &Spanned<f64>),
        dof: Option<f64>,
        name: &str,
        span: &Range<usize>,
        at: &At<'_>,
    ) -> Result<Distribution, BudgetError> {
        let x = *value.get_ref();
        Ok(match (distribution_name, key) {
            ("normal", "u") => Distribution::Normal { u: x },
            ("normal", "expanded") => match &self.k {
                Some(k) => Distribution::normal_expanded(x, *k.get_ref()),
                None => return Err(at(value.span(), EXPANDED_NEEDS_K.to_string())),
            },
            ("t", _) => match dof {
                Some(nu) => Distribution::StudentT { scale: x, dof: nu },
                None => {
                    return Err(at(
                        self.dof.as_ref().map_or(span.clone(), Spanned::span),
                        format!(
                            "component {name:?}: a t distribution needs finite degrees of \
                             freedom (dof = ...)"
                        ),
                    ));
                }
            },
            (shape, key) => bounded_distribution(shape, key, x),
        })
    }
}

/// A rectangular, triangular or arcsine distribution (`shape`) from its full width, half
/// width or standard uncertainty (`key`) `x`; a u given is kept exact.
fn bounded_distribution(shape: &str, key: &str, x: f64) -> Distribution {
    let half_width = match key {
        "full_width" => 0.5 * x,
        "half_width" => x,
        _ => {
            // u given: the half width that yields it.
            x * match shape {
                "rectangular" => 3f64.sqrt(),
                "triangular" => 6f64.sqrt(),
                _ => 2f64.sqrt(),
            }
        }
    };
    let make = |half_width| match shape {
        "rectangular" => Distribution::Rectangular { half_width },
        "triangular" => Distribution::Triangular { half_width },
        _ => Distribution::Arcsine { half_width },
    };
    let mut d = make(half_width);
    if key == "u" {
        // Keep the given u exact: nudge the half width by an ulp or two.
        let mut a = half_width;
        for _ in 0..4 {
            let got = d.standard_uncertainty();
            if got == x {
                break;
            }
            a = if got < x { a.next_up() } else { a.next_down() };
            d = make(a);
        }
    }
    d
}
