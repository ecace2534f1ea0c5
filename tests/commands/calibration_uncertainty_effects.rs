//! The uncertainty of the calibration results through a model with effect terms (the
//! final model of `diagnose`), checked against independent truth: every component's
//! contribution against refits of moved readings, the budget of the final model against
//! its covariance, and Monte Carlo through the effect columns.

use polycal::measurement::MeasurementSet;
use polycal::solve;
use polycal::uncertainty::budget::EvaluationType;
use polycal::uncertainty::calibration::{
    self, CalibrationUncertainty, InstrumentBudget, McSolver, Scope, ScopedComponent,
};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::student::t_quantile;

use crate::calibration_uncertainty_support::{close, mc, propagated_u};

/// A diagnosed run whose final model has effect terms: 12 faces, 3 cycles with closing
/// readings, autocollimator 2 drifting 1.5″/h and one reading 2″ off.
fn diagnosed_run() -> (MeasurementSet, polycal::diagnose::Diagnosis) {
    use polycal::effects::Effect;
    use polycal::simulate::{SimulationConfig, simulate};
    let config = SimulationConfig {
        faces: 12,
        cycles: 3,
        closing: true,
        noise_arcsec: 0.05,
        effects: vec![
            Effect::Drift {
                ac: 2,
                value: 1.5,
                quadratic: None,
            },
            Effect::Outlier {
                cycle: 2,
                step: 5,
                ac: 1,
                setup: None,
                value: 2.0,
            },
        ],
        seed: 11,
        ..SimulationConfig::default()
    };
    let (set, _) = simulate(&config).unwrap();
    let diagnosis =
        polycal::diagnose::diagnose(&set, &polycal::diagnose::DiagnoseOptions::default()).unwrap();
    assert!(
        !diagnosis.effects.is_empty(),
        "the injected effects are found"
    );
    assert_eq!(diagnosis.after.layout.effects, diagnosis.effects.len());
    (set, diagnosis)
}

/// The reported quantities of a refit with the given effect columns:
/// [β (N), φ (N), α (N), setup errors (K)].
fn refit(set: &MeasurementSet, regressors: &[Vec<f64>]) -> Vec<f64> {
    let s = solve::least_squares_with_regressors(set, regressors, None).unwrap();
    let mut out = s.pitch_deviation.clone();
    out.extend_from_slice(&s.face_deviation);
    out.extend_from_slice(&s.encoder_error);
    out.extend(s.setup_error.iter().map(|e| e.value));
    out
}

/// The budget through a model with effect terms, against independent truth: the
/// regressors are rebuilt from the effects found (`Effect::regressor`), and the gain of
/// every scope, G_j = Σ_g (Σ_{i∈g} L_ji)², is measured by refitting the readings with
/// those of one group g moved by 1″ (the fit is linear, so the change of quantity j is
/// Σ_{i∈g} L_ji) — no solution operator, no cofactor matrix. Every component's
/// contribution to every β, φ, α and setup error is u·√G_j.
#[test]
fn effect_terms_propagate_like_refits() {
    use polycal::effects::EffectContext;
    let (set, diagnosis) = diagnosed_run();
    let context = EffectContext::of(&set.readings);
    let regressors: Vec<Vec<f64>> = diagnosis
        .effects
        .iter()
        .map(|found| {
            set.readings
                .iter()
                .map(|r| found.effect.regressor(r, &context))
                .collect()
        })
        .collect();
    let centre = refit(&set, &regressors);
    let after = &diagnosis.after;
    for (f, b) in after.pitch_deviation.iter().enumerate() {
        assert!((centre[f] - b).abs() < 1e-12, "the final model, refitted");
    }
    let u = 0.01;
    let scopes = [
        Scope::EachReading,
        Scope::EachAutocollimator,
        Scope::EachPosition,
        Scope::EachStop,
    ];
    let budget = InstrumentBudget::new(
        scopes
            .iter()
            .map(|&scope| {
                ScopedComponent::type_b(scope.as_str(), Distribution::Normal { u }, scope)
            })
            .collect(),
    );
    let unc = calibration::evaluate(&set, after, &budget).unwrap();
    let n = set.faces;
    for (c, scope) in unc.components.iter().zip(scopes) {
        let mut groups: std::collections::BTreeMap<(u32, u32, usize, usize), Vec<usize>> =
            Default::default();
        for (i, r) in set.readings.iter().enumerate() {
            let key = match scope {
                Scope::EachReading => (0, 0, 0, i),
                Scope::EachAutocollimator => (r.ac, 0, 0, 0),
                Scope::EachPosition => (0, 0, r.step % n, 0),
                _ => (r.setup, r.cycle, r.step, 0),
            };
            groups.entry(key).or_default().push(i);
        }
        let mut gain = vec![0.0; centre.len()];
        for members in groups.values() {
            let mut moved = set.clone();
            for &i in members {
                moved.readings[i].reading_arcsec += 1.0;
            }
            for (g, (m, c)) in gain
                .iter_mut()
                .zip(refit(&moved, &regressors).iter().zip(&centre))
            {
                *g += (m - c).powi(2);
            }
        }
        let got: Vec<f64> = c
            .pitch_deviation
            .iter()
            .chain(&c.face_deviation)
            .chain(&c.encoder_error)
            .chain(&c.setup_error)
            .copied()
            .collect();
        assert_eq!(got.len(), gain.len());
        for (j, (got, g)) in got.iter().zip(&gain).enumerate() {
            let expected = u * g.sqrt();
            assert!(
                (got - expected).abs() < 1e-9,
                "{scope}, quantity {j}: {got} vs {expected}"
            );
        }
    }
}

/// The budget of the final model with no component but the fit's own type A gives
/// U/k = σ√Q_jj of that model's covariance, read directly from the solution (β and α
/// from its diagonal, φ_f from the sum of the β block up to f); one more each-reading
/// type-A component of u = σ with the fit's dof doubles the variance, with
/// ν_eff = 2·dof (Welch–Satterthwaite: (2u²)² / (u⁴/dof + u⁴/dof)).
#[test]
fn final_model_budget_is_its_covariance() {
    let (set, diagnosis) = diagnosed_run();
    let after = &diagnosis.after;
    let n = set.faces;
    let cov = after.covariance().unwrap();
    let sigma = after.sigma.unwrap().0;
    let dof = after.dof as f64;
    let mut fit_u = vec![0.0; 3 * n];
    for f in 0..n {
        fit_u[f] = cov[(f, f)].sqrt();
        fit_u[2 * n + f] = cov[(n + f, n + f)].sqrt();
        let mut var = 0.0;
        for i in 0..=f {
            for j in 0..=f {
                var += cov[(i, j)];
            }
        }
        fit_u[n + f] = var.max(0.0).sqrt();
    }
    let families = |unc: &CalibrationUncertainty| {
        let mut v: Vec<(f64, Option<f64>, Option<f64>)> = Vec::new();
        for fam in [
            &unc.pitch_deviation,
            &unc.face_deviation,
            &unc.encoder_error,
        ] {
            for i in 0..n {
                v.push((fam.expanded_u[i], fam.k[i], fam.dof_eff[i]));
            }
        }
        v
    };
    let alone = calibration::evaluate(&set, after, &InstrumentBudget::new(Vec::new())).unwrap();
    let doubled = calibration::evaluate(
        &set,
        after,
        &InstrumentBudget::new(vec![ScopedComponent {
            evaluation: EvaluationType::A,
            ..ScopedComponent::type_b(
                "reading noise",
                Distribution::Normal { u: sigma },
                Scope::EachReading,
            )
            .with_dof(Some(dof))
        }]),
    )
    .unwrap();
    for (j, ((big_u, k, nu), (big_u2, k2, nu2))) in families(&alone)
        .into_iter()
        .zip(families(&doubled))
        .enumerate()
    {
        if j == 2 * n - 1 {
            assert_eq!((big_u, k, big_u2, k2), (0.0, None, 0.0, None), "φ[N]");
            continue;
        }
        let (k, k2) = (k.unwrap(), k2.unwrap());
        assert!(
            close(big_u / k, fit_u[j], 1e-9),
            "{j}: {} vs {}",
            big_u / k,
            fit_u[j]
        );
        assert!(close(nu.unwrap(), dof, 1e-9));
        assert!(close(k, t_quantile(0.95, Some(dof)), 1e-12));
        assert!(
            close(big_u2 / k2, 2f64.sqrt() * fit_u[j], 1e-9),
            "{j}: {} vs √2·{}",
            big_u2 / k2,
            fit_u[j]
        );
        assert!(close(nu2.unwrap(), 2.0 * dof, 1e-9), "{j}: ν_eff {nu2:?}");
        assert!(close(k2, t_quantile(0.95, Some(2.0 * dof)), 1e-12));
    }
}

/// Monte Carlo through a model with effect terms: each trial is solved by the
/// least-squares operator with the effect columns (the closed form has none), and its
/// means are the final model's estimates and its u the propagated u_c, within the Monte
/// Carlo noise.
#[test]
fn monte_carlo_through_a_model_with_effects() {
    let (set, diagnosis) = diagnosed_run();
    let budget = InstrumentBudget::new(vec![
        ScopedComponent::type_b(
            "angle",
            Distribution::Normal { u: 0.04 },
            Scope::EachReading,
        ),
        ScopedComponent::type_b(
            "encoder",
            Distribution::Normal { u: 0.02 },
            Scope::EachPosition,
        ),
    ]);
    let (unc, result) = mc(&set, &diagnosis.after, &budget, 40_000, 7, McSolver::Auto);
    assert_eq!(result.solver, "lsq");
    for (family_index, mc_family, estimates) in [
        (0, &result.pitch_deviation, &diagnosis.after.pitch_deviation),
        (2, &result.encoder_error, &diagnosis.after.encoder_error),
    ] {
        for (j, estimate) in estimates.iter().enumerate() {
            let u = propagated_u(&unc, family_index, j);
            assert!(
                (mc_family.mean[j] - estimate).abs() < 5.0 * u / (40_000f64).sqrt(),
                "family {family_index}, {j}: mean {} vs {estimate}",
                mc_family.mean[j]
            );
            assert!(
                close(mc_family.u[j], u, 0.03),
                "family {family_index}, {j}: u {} vs {u}",
                mc_family.u[j]
            );
        }
    }
}
