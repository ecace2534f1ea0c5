//! An instrument budget on a self-calibration (docs/FORMAT.md §9, `--budget` as for
//! `solve`): the fit's type A combined with the budget's components through the design,
//! per encoder error and per head error (GUM, as [`crate::uncertainty::calibration`]).
//!
//! A component's scope (`acts_on`) says which readings share one draw of it; what the
//! draw does to a result follows from the model, reading = t\[cycle, step\] + e + c\[head\]:
//!
//! | `acts_on` | in a self-calibration | gain on e | gain on c\[j\] − c\[1\] |
//! |---|---|---|---|
//! | `each-reading` | one reading of one head | Q_ee (the type A pattern) | Q_cc |
//! | `each-autocollimator` | every reading of one read head (an offset) | 0: c absorbs it | 2 (head j's draw and head 1's) |
//! | `each-position` | every reading at one table position, all heads and cycles | 0: t absorbs it | 0 |
//! | `each-stop` | every reading of one stop (cycle, step) | 0: t absorbs it | 0 |
//! | `result` | added to every result | 1 | 1 |
//!
//! The zeros are exact: t is free at every stop and c for every head, so an error shared
//! by a stop or a head moves only them (the tests solve such errors to check it). The
//! bound on the lost harmonics and the heads' angle uncertainty, when given, are more
//! type-B components of infinite degrees of freedom (the heads' angles on e and on the
//! head errors).

use serde::Serialize;

use super::SelfcalSolution;
use crate::results::Quantity;
use crate::solve::SigmaSource;
use crate::uncertainty::budget::DofPolicy;
use crate::uncertainty::calibration::{
    CalibrationError, Combined, FamilyUncertainty, InstrumentBudget, Scope, combine,
};

/// What one component contributes (standard uncertainties, arcsec).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SelfcalContribution {
    /// Name.
    pub name: String,
    /// Scope.
    pub acts_on: Scope,
    /// Standard uncertainty of one draw as it enters a reading, |c|·u(x).
    pub u: f64,
    /// Degrees of freedom, `null` if infinite.
    pub dof: Option<f64>,
    /// Contribution to each e.
    pub encoder_error: Vec<f64>,
    /// Contribution to each head error.
    pub head_error: Vec<f64>,
}

/// The GUM uncertainty of a self-calibration under an instrument budget
/// ([`evaluate_budget`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SelfcalUncertainty {
    /// The budget's source.
    pub budget: String,
    /// Coverage probability.
    pub p: f64,
    /// How k follows from ν_eff.
    pub dof_policy: DofPolicy,
    /// Degrees of freedom of the type A part (`null`: infinite, a stated σ).
    pub type_a_dof: Option<f64>,
    /// The encoder errors e.
    pub encoder_error: FamilyUncertainty,
    /// The head errors, heads 2 … M.
    pub head_error: FamilyUncertainty,
    /// Every component's contributions (the lost harmonics' bound last, when given).
    pub components: Vec<SelfcalContribution>,
}

/// The gains G (module documentation) of a scope on e (relative to the type A pattern
/// where it is the reading's) and on the head errors.
fn gains(scope: Scope, q_ee: &[f64], q_cc: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let zeros = |n: usize| vec![0.0; n];
    match scope {
        Scope::EachReading => (q_ee.to_vec(), q_cc.to_vec()),
        Scope::EachAutocollimator => (zeros(q_ee.len()), vec![2.0; q_cc.len()]),
        Scope::EachPosition | Scope::EachStop => (zeros(q_ee.len()), zeros(q_cc.len())),
        Scope::Result => (vec![1.0; q_ee.len()], vec![1.0; q_cc.len()]),
    }
}

/// The expanded uncertainty of every encoder error and head error of a self-calibration
/// under an instrument budget: u_c² = u_A² + Σ u_B²·G per quantity (module
/// documentation), ν_eff by Welch–Satterthwaite, k = t_p(ν_eff) under the budget's policy,
/// U = k·u_c.
///
/// # Errors
///
/// [`CalibrationError::NoSigma`] without σ, an invalid budget, or ⌊ν_eff⌋ < 1 under the
/// floor policy.
pub fn evaluate_budget(
    solution: &SelfcalSolution,
    budget: &InstrumentBudget,
) -> Result<SelfcalUncertainty, CalibrationError> {
    budget.check()?;
    let (sigma, source) = solution.sigma.ok_or(CalibrationError::NoSigma)?;
    let type_a_dof = match source {
        SigmaSource::Residual => Some(solution.dof as f64),
        SigmaSource::Stated => None,
    };
    let u_a_e = solution
        .encoder_error_u_type_a
        .clone()
        .ok_or(CalibrationError::NoSigma)?;
    let u_a_c: Vec<f64> = solution
        .head_error
        .iter()
        .map(|h| h.u_type_a.unwrap_or(0.0))
        .collect();
    let q_ee: Vec<f64> = u_a_e.iter().map(|u| (u / sigma).powi(2)).collect();
    let q_cc: Vec<f64> = u_a_c.iter().map(|u| (u / sigma).powi(2)).collect();
    let p = u_a_e.len();

    let mut components = Vec::new();
    for c in &budget.components {
        let u = c.standard_uncertainty();
        let (g_e, g_c) = gains(c.scope, &q_ee, &q_cc);
        components.push(SelfcalContribution {
            name: c.name.clone(),
            acts_on: c.scope,
            u,
            dof: c.dof,
            encoder_error: g_e.iter().map(|g| u * g.sqrt()).collect(),
            head_error: g_c.iter().map(|g| u * g.sqrt()).collect(),
        });
    }
    if let Some(u) = solution.lost_harmonic_u {
        components.push(SelfcalContribution {
            name: "Harmonics the head layout cannot see (bound)".into(),
            acts_on: Scope::Result,
            u,
            dof: None,
            encoder_error: vec![u; p],
            head_error: vec![0.0; u_a_c.len()],
        });
    }
    if let Some(on_e) = &solution.head_angle_u {
        components.push(SelfcalContribution {
            name: "Nominal angles of the read heads".into(),
            acts_on: Scope::Result,
            u: on_e.iter().copied().fold(0.0, f64::max),
            dof: None,
            encoder_error: on_e.clone(),
            head_error: solution
                .head_error
                .iter()
                .map(|h| h.head_angle_u.unwrap_or(0.0))
                .collect(),
        });
    }
    let family = |u_a: Vec<f64>,
                  contributions: Vec<Vec<f64>>,
                  quantity: Quantity,
                  index: &dyn Fn(usize) -> usize|
     -> Result<FamilyUncertainty, CalibrationError> {
        let dof: Vec<Option<f64>> = components.iter().map(|c| c.dof).collect();
        let Combined {
            u,
            dof_eff,
            k,
            expanded,
        } = combine(budget, &u_a, type_a_dof, &dof, &contributions, |j| {
            (quantity, index(j))
        })?;
        Ok(FamilyUncertainty {
            u_a,
            u,
            dof_eff,
            k,
            expanded_u: expanded,
        })
    };
    let heads: Vec<usize> = solution
        .head_error
        .iter()
        .map(|h| h.head as usize)
        .collect();
    let encoder_error = family(
        u_a_e,
        components.iter().map(|c| c.encoder_error.clone()).collect(),
        Quantity::EncoderError,
        &|j| j,
    )?;
    let head_error = family(
        u_a_c,
        components.iter().map(|c| c.head_error.clone()).collect(),
        Quantity::SetupError,
        &|j| heads[j],
    )?;
    Ok(SelfcalUncertainty {
        budget: budget.source.clone(),
        p: budget.p,
        dof_policy: budget.dof_policy,
        type_a_dof,
        encoder_error,
        head_error,
        components,
    })
}
