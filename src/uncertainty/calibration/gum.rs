//! The GUM propagation (JCGM 100 §5.1, G.4): the fit's type A σ²Q combined with every
//! budget component through its scope's gains, Welch–Satterthwaite, k and U per
//! quantity ([`evaluate`]).

use crate::results::Quantity;
use serde::Serialize;

use super::operator::{Operator, gains};
use super::{CalibrationError, InstrumentBudget, Scope};
use crate::measurement::MeasurementSet;
use crate::solve::{SigmaSource, Solution};
use crate::uncertainty::budget::{DofPolicy, EvaluationType};
use crate::uncertainty::student::t_quantile;

/// The uncertainties of one family of quantities (all β, all φ, all α, or all setup
/// errors; in a self-calibration all e or all head errors), index as in the solution.
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
    pub fn families(&self) -> [(Quantity, &FamilyUncertainty); 4] {
        [
            (Quantity::PitchDeviation, &self.pitch_deviation),
            (Quantity::FaceDeviation, &self.face_deviation),
            (Quantity::EncoderError, &self.encoder_error),
            (Quantity::SetupError, &self.setup_error),
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

fn family_name_and_index(j: usize, n: usize) -> (Quantity, usize) {
    match j / n {
        0 => (Quantity::PitchDeviation, j + 1),
        1 => (Quantity::FaceDeviation, j - n + 1),
        2 => (Quantity::EncoderError, j - 2 * n),
        _ => (Quantity::SetupError, j - 3 * n + 1),
    }
}

/// The expanded uncertainty of every pitch deviation, face deviation, encoder error and
/// setup error: the fit's type A (σ²Q) combined with the budget's components through the
/// design (module documentation of [`super`]) by the law of propagation for independent
/// inputs (JCGM 100 §5.1.2, eq. (10)), the effective degrees of freedom by
/// Welch–Satterthwaite (JCGM 100 G.4.1, eq. (G.2b)), k = t_p(ν_eff) under the budget's
/// degrees-of-freedom policy and U = k·u_c (JCGM 100 §6.2.1, eq. (18)), per quantity.
/// A `result` component adds its u to every quantity, as the paper's Table 1 does.
///
/// # Errors
///
/// [`CalibrationError`]: no σ (an exactly determined fit without a stated σ), a solution
/// of another set, an invalid budget, or ⌊ν_eff⌋ < 1 under the floor policy.
pub fn evaluate(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
) -> Result<CalibrationUncertainty, CalibrationError> {
    evaluate_with_corrections(set, solution, budget, &[])
}

/// A known correction applied to the readings, whose standard uncertainty enters the
/// budget: an error e of it moves reading i by e·`column[i]` (one draw shared by every
/// reading it touches), so quantity j moves by e·Σᵢ L_ji·column\[i\] and receives
/// u·|Σᵢ L_ji·column\[i\]|. A stated cross-talk coefficient C of autocollimator A with
/// standard uncertainty u is one: its column is `reading_y` on A's readings.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct KnownCorrection {
    /// The name it has among the components.
    pub name: String,
    /// Its standard uncertainty, in the unit of the correction's coefficient.
    pub u: f64,
    /// How far an error of one unit moves each reading, arcsec, in the set's order.
    pub column: Vec<f64>,
}

impl KnownCorrection {
    /// A correction named `name` with standard uncertainty `u` and its column.
    pub fn new(name: impl Into<String>, u: f64, column: Vec<f64>) -> Self {
        Self {
            name: name.into(),
            u,
            column,
        }
    }

    /// Refuses a correction whose column does not have one finite value per reading
    /// (`readings`), or whose u is not a finite number ≥ 0.
    pub(super) fn check(&self, readings: usize) -> Result<(), CalibrationError> {
        if self.column.len() != readings
            || !self.column.iter().all(|x| x.is_finite())
            || !(self.u.is_finite() && self.u >= 0.0)
        {
            return Err(CalibrationError::Component {
                name: self.name.clone(),
                problem: crate::uncertainty::ComponentError::CorrectionColumn { readings },
            });
        }
        Ok(())
    }

    /// The corrections of the stated cross-talks that carry a U, on `set`: each named
    /// `cross-talk of autocollimator AC (stated)`, its column `reading_y` on AC's
    /// readings (docs/FORMAT.md §6).
    pub fn of_stated_cross_talk(
        set: &MeasurementSet,
        stated: &[crate::measurement::cross_talk::StatedCrossTalk],
    ) -> Vec<KnownCorrection> {
        stated
            .iter()
            .filter_map(|s| {
                s.u.map(|u| {
                    KnownCorrection::new(
                        format!("cross-talk of autocollimator {} (stated)", s.ac),
                        u,
                        s.column(set),
                    )
                })
            })
            .collect()
    }
}

/// [`evaluate`] with the uncertainties of known corrections applied to the readings
/// ([`KnownCorrection`]), each a component of type B with infinite degrees of freedom,
/// listed after the budget's own as acting on each autocollimator.
///
/// # Errors
///
/// As [`evaluate`]; a correction whose column does not have one value per reading, or
/// whose u is not a finite number ≥ 0, is refused as an invalid component.
pub fn evaluate_with_corrections(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
    corrections: &[KnownCorrection],
) -> Result<CalibrationUncertainty, CalibrationError> {
    budget.check()?;
    for c in corrections {
        c.check(set.readings.len())?;
    }
    let op = Operator::new(set, solution)?;
    let (sigma, source) = solution.sigma.ok_or(CalibrationError::NoSigma)?;
    let n = op.faces;
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
    for c in corrections {
        let s = super::operator::sensitivities(&op, &c.column);
        contributions.push(s.iter().map(|s| c.u * s.abs()).collect());
    }
    let component_dof: Vec<Option<f64>> = budget
        .components
        .iter()
        .map(|c| c.dof)
        .chain(corrections.iter().map(|_| None))
        .collect();
    let Combined {
        u,
        dof_eff,
        k,
        expanded,
    } = combine(
        budget,
        &u_a,
        type_a_dof,
        &component_dof,
        &contributions,
        |j| family_name_and_index(j, n),
    )?;
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
    let correction_rows: Vec<ComponentContribution> = corrections
        .iter()
        .zip(&contributions[budget.components.len()..])
        .map(|(c, contribution)| {
            let [pitch, face, encoder, setup] = split(contribution, n);
            ComponentContribution {
                name: c.name.clone(),
                evaluation: EvaluationType::B,
                distribution: "normal",
                acts_on: Scope::EachAutocollimator,
                u: c.u,
                sensitivity: 1.0,
                dof: None,
                pitch_deviation: pitch,
                face_deviation: face,
                encoder_error: encoder,
                setup_error: setup,
            }
        })
        .collect();
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
        .chain(correction_rows)
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

/// Per quantity: u_c, ν_eff, k and U = k·u_c.
pub(crate) struct Combined {
    pub(crate) u: Vec<f64>,
    pub(crate) dof_eff: Vec<Option<f64>>,
    pub(crate) k: Vec<Option<f64>>,
    pub(crate) expanded: Vec<f64>,
}

/// The GUM combination of one set of quantities: u_c² = u_A² + Σ contribution², ν_eff
/// by Welch–Satterthwaite (type A with `type_a_dof`, each component with its own), k
/// under the budget's p and degrees-of-freedom policy, U = k·u_c; no k where u_c = 0.
/// `contributions[c][j]` is component c's standard uncertainty in quantity j; `name`
/// names quantity j for the floor policy's refusal.
pub(crate) fn combine(
    budget: &InstrumentBudget,
    u_a: &[f64],
    type_a_dof: Option<f64>,
    component_dof: &[Option<f64>],
    contributions: &[Vec<f64>],
    name: impl Fn(usize) -> (Quantity, usize),
) -> Result<Combined, CalibrationError> {
    let total = u_a.len();
    let mut u = vec![0.0; total];
    let mut dof_eff = vec![None; total];
    let mut k = vec![None; total];
    let mut expanded = vec![0.0; total];
    for j in 0..total {
        let mut variance = u_a[j] * u_a[j];
        let mut denominator = type_a_dof.map_or(0.0, |nu| u_a[j].powi(4) / nu);
        for (dof, contribution) in component_dof.iter().zip(contributions) {
            let x = contribution[j];
            variance += x * x;
            if let Some(nu) = dof {
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
                    let (quantity, index) = name(j);
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
    Ok(Combined {
        u,
        dof_eff,
        k,
        expanded,
    })
}
