//! The uncertainty of the calibration results (`polycal solve --budget`), propagated
//! through the paper's design and checked against hand derivation: on the bare N-face
//! cycle an each-reading error u_B gives u(β_k)² = 2(σ² + u_B²)(1 − 1/N) and
//! u(φ_f)² = 2(σ² + u_B²)·f(N − f)/N exactly; a constant offset per autocollimator adds
//! exactly 0 to β, φ and α (and u² to its setup error); an error per table position adds
//! u²(1 − 1/N) to α only, one per stop u²(1 − 1/N)/R; a `result` component adds u² to
//! every quantity; Welch–Satterthwaite and k by hand; no σ refused; the budget file's
//! scopes.

use std::path::PathBuf;

use crate::common::{Stream, readings};
use polycal::solve::Method;
use polycal::uncertainty::DofPolicy;
use polycal::uncertainty::calibration::{self, InstrumentBudget, Scope, ScopedComponent};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::student::t_quantile;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution as _, Normal};

use crate::calibration_uncertainty_support::{close, design, one, solved, truth};

/// The bare cycle with a stated σ and an each-reading error: the hand-derived variances,
/// φ[N] without uncertainty, ν_eff and k by hand, for both solvers.
#[test]
fn bare_cycle_each_reading_error_is_hand_derived() {
    let n = 24;
    let (sigma, u_b, nu_b) = (0.05, 0.03, 20.0);
    let set = design(n, 1, false, 1);
    for method in [Method::ClosedForm, Method::LeastSquares] {
        let solution = solved(&set, method, Some(sigma));
        assert_eq!(solution.dof, 0);
        let budget = InstrumentBudget::new(vec![
            ScopedComponent::type_b(
                "resolution",
                Distribution::Rectangular {
                    half_width: u_b * 3f64.sqrt(),
                },
                Scope::EachReading,
            )
            .with_dof(Some(nu_b)),
        ]);
        let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
        assert_eq!((unc.sigma_source, unc.type_a_dof), ("stated", None));
        let nf = n as f64;
        for k in 0..n {
            let expected = 2.0 * (sigma * sigma + u_b * u_b) * (1.0 - 1.0 / nf);
            let got = unc.pitch_deviation.u[k].powi(2);
            assert!(
                close(got, expected, 1e-12),
                "β{}: {got} vs {expected}",
                k + 1
            );
            // ν_eff = u_c⁴ / (c_B⁴/ν_B), the type A part having ν = ∞ (stated σ)
            let c_b2 = 2.0 * u_b * u_b * (1.0 - 1.0 / nf);
            let nu = expected * expected / (c_b2 * c_b2 / nu_b);
            assert!(close(unc.pitch_deviation.dof_eff[k].unwrap(), nu, 1e-9));
            let kf = t_quantile(0.95, Some(nu));
            assert!(close(unc.pitch_deviation.k[k].unwrap(), kf, 1e-12));
            assert!(close(
                unc.pitch_deviation.expanded_u[k],
                kf * expected.sqrt(),
                1e-12
            ));
        }
        for f in 1..n {
            let ff = f as f64;
            let expected = 2.0 * (sigma * sigma + u_b * u_b) * ff * (nf - ff) / nf;
            let got = unc.face_deviation.u[f - 1].powi(2);
            assert!(close(got, expected, 1e-10), "φ{f}: {got} vs {expected}");
        }
        // φ[N] is the reference: no uncertainty, no k
        assert_eq!(unc.face_deviation.u[n - 1], 0.0);
        assert_eq!(unc.face_deviation.expanded_u[n - 1], 0.0);
        assert_eq!(unc.face_deviation.k[n - 1], None);
        // the type A part is the fit's own u(β), u(α)
        let fit_u = solution.pitch_deviation_u().unwrap();
        let fit_ua = solution.encoder_error_u().unwrap();
        for k in 0..n {
            assert!(close(unc.pitch_deviation.u_a[k], fit_u[k], 1e-12));
            assert!(close(unc.encoder_error.u_a[k], fit_ua[k], 1e-12));
        }
    }
}

/// A constant offset of each autocollimator is absorbed by the setup errors: exactly
/// (to rounding) nothing for β, φ and α, the whole u for the setup errors — for the bare
/// cycle, for repeated cycles with closing readings, and for three autocollimators.
#[test]
fn constant_offsets_add_nothing_to_beta_phi_alpha() {
    let u = 0.5;
    let three: [Stream; 3] = [(1, 1, 0, 0.1), (1, 2, 1, 0.2), (1, 3, 5, -0.3)];
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let sets = [
        design(24, 1, false, 2),
        design(12, 4, true, 3),
        readings(&truth(12), &three, 2, true, || noise.sample(&mut rng)),
    ];
    for set in &sets {
        let solution = solved(set, Method::Auto, Some(0.05));
        let budget = one(Distribution::Normal { u }, Scope::EachAutocollimator);
        let unc = calibration::evaluate(set, &solution, &budget).unwrap();
        let c = &unc.components[0];
        for v in c
            .pitch_deviation
            .iter()
            .chain(&c.face_deviation)
            .chain(&c.encoder_error)
        {
            assert!(v.abs() < 1e-12, "offset leaks {v}");
        }
        for v in &c.setup_error {
            assert!(close(*v, u, 1e-12), "setup error gets {v}");
        }
        let fit_u = solution.pitch_deviation_u().unwrap();
        for (uc, ua) in unc.pitch_deviation.u.iter().zip(&fit_u) {
            assert!(close(*uc, *ua, 1e-12));
        }
    }
}

/// An error per table position moves α[p] by e_p − ē and nothing else: u²(1 − 1/N) for
/// α, 0 for β and φ, whatever the design; one per stop of R cycles of the paper's design
/// averages to u²(1 − 1/N)/R.
#[test]
fn position_and_stop_errors_reach_alpha_only() {
    let u = 0.02;
    for (set, n) in [(design(24, 1, false, 4), 24), (design(10, 3, true, 5), 10)] {
        let solution = solved(&set, Method::Auto, Some(0.05));
        let unc = calibration::evaluate(
            &set,
            &solution,
            &one(
                Distribution::Rectangular {
                    half_width: u * 3f64.sqrt(),
                },
                Scope::EachPosition,
            ),
        )
        .unwrap();
        let c = &unc.components[0];
        let expected = u * (1.0 - 1.0 / n as f64).sqrt();
        for p in 0..n {
            assert!(close(c.encoder_error[p], expected, 1e-12));
            assert!(c.pitch_deviation[p].abs() < 1e-12);
            assert!(c.face_deviation[p].abs() < 1e-12);
        }
    }
    let (n, r) = (16, 5);
    let set = design(n, r, false, 6);
    let solution = solved(&set, Method::Auto, None);
    let unc = calibration::evaluate(
        &set,
        &solution,
        &one(Distribution::Normal { u }, Scope::EachStop),
    )
    .unwrap();
    let c = &unc.components[0];
    let expected = u * ((1.0 - 1.0 / n as f64) / r as f64).sqrt();
    for p in 0..n {
        assert!(close(c.encoder_error[p], expected, 1e-12));
        assert!(c.pitch_deviation[p].abs() < 1e-12);
    }
}

/// A `result` component adds u² to every quantity (the paper's Table 1 way), except the
/// reference face φ[N].
#[test]
fn result_components_add_directly() {
    let set = design(12, 3, true, 7);
    let solution = solved(&set, Method::Auto, None);
    let u = 0.2050;
    let unc = calibration::evaluate(
        &set,
        &solution,
        &one(
            Distribution::Rectangular {
                half_width: 0.71 / 2.0,
            },
            Scope::Result,
        ),
    )
    .unwrap();
    for (name, family) in unc.families() {
        for (i, (uc, ua)) in family.u.iter().zip(&family.u_a).enumerate() {
            if name == "face_deviation" && i == 11 {
                assert_eq!(*uc, 0.0);
                continue;
            }
            assert!(
                close(uc * uc, ua * ua + (0.71f64 / 12f64.sqrt()).powi(2), 1e-12),
                "{name} {i}"
            );
            assert!((uc * uc - ua * ua).sqrt() - u < 1e-4);
        }
    }
}

/// Welch–Satterthwaite with the fit's residual degrees of freedom, and the three dof
/// policies, by hand on R cycles of the paper's design.
#[test]
fn welch_satterthwaite_and_policies_by_hand() {
    let (n, r) = (24, 6);
    let set = design(n, r, false, 8);
    let solution = solved(&set, Method::Auto, None);
    let dof = (2 * n * r as usize - 2 * n) as f64;
    assert_eq!(solution.dof as f64, dof);
    let sigma = solution.sigma.unwrap().0;
    let (u_b, nu_b) = (0.04, 12.0);
    let component =
        ScopedComponent::type_b("e", Distribution::Normal { u: u_b }, Scope::EachReading)
            .with_dof(Some(nu_b));
    let gain = 2.0 * (1.0 - 1.0 / n as f64) / r as f64;
    let ua2 = sigma * sigma * gain;
    let ub2 = u_b * u_b * gain;
    let nu = (ua2 + ub2).powi(2) / (ua2 * ua2 / dof + ub2 * ub2 / nu_b);
    for (policy, k) in [
        (DofPolicy::Fractional, t_quantile(0.95, Some(nu))),
        (DofPolicy::Floor, t_quantile(0.95, Some(nu.floor()))),
        (DofPolicy::K2, 2.0),
    ] {
        let budget = InstrumentBudget::new(vec![component.clone()]).with_dof_policy(policy);
        let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
        assert_eq!(unc.type_a_dof, Some(dof));
        for j in 0..n {
            assert!(close(unc.pitch_deviation.u[j], (ua2 + ub2).sqrt(), 1e-12));
            assert!(close(unc.pitch_deviation.dof_eff[j].unwrap(), nu, 1e-9));
            assert!(
                close(unc.pitch_deviation.k[j].unwrap(), k, 1e-12),
                "{policy}"
            );
        }
    }
    // p = 0.99 gives the t factor at 99 %
    let budget = InstrumentBudget::new(vec![component]).with_coverage(0.99);
    let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
    assert!(close(
        unc.pitch_deviation.k[0].unwrap(),
        t_quantile(0.99, Some(nu)),
        1e-12
    ));
}

/// Without σ (exactly determined, nothing stated) there is no type A: refused.
#[test]
fn no_sigma_is_refused() {
    let set = design(8, 1, false, 9);
    let solution = solved(&set, Method::Auto, None);
    let error = calibration::evaluate(
        &set,
        &solution,
        &one(Distribution::Normal { u: 0.1 }, Scope::Result),
    )
    .unwrap_err();
    assert!(
        matches!(error, calibration::CalibrationError::NoSigma),
        "{error}"
    );
    assert!(!error.to_string().contains("--"), "{error}");
}

/// The budget file: `acts_on` per component, inherited by nested components, default
/// `result`; unknown values, `acts_on` inside an inline table, typos and correlations are
/// refused with the place.
#[test]
fn budget_file_scopes() {
    let text = r#"
p = 0.99
dof_policy = "k2"

[[component]]
name = "Autocollimator"
acts_on = "each-reading"

  [[component.component]]
  name = "Resolution"
  type = "B"
  distribution = "rectangular"
  full_width = 0.001

  [[component.component]]
  name = "Zero"
  type = "B"
  u = 0.3
  sensitivity = 2
  acts_on = "each-autocollimator"

[[component]]
name = "Mounting"
type = "B"
u = 0.02
"#;
    let budget = InstrumentBudget::from_toml_str(text, "b.toml").unwrap();
    assert_eq!((budget.p, budget.dof_policy), (0.99, DofPolicy::K2));
    let scopes: Vec<(&str, Scope)> = budget
        .components
        .iter()
        .map(|c| (c.name.as_str(), c.scope))
        .collect();
    assert_eq!(
        scopes,
        [
            ("Autocollimator / Resolution", Scope::EachReading),
            ("Autocollimator / Zero", Scope::EachAutocollimator),
            ("Mounting", Scope::Result),
        ]
    );
    assert!(close(
        budget.components[1].standard_uncertainty(),
        0.6,
        1e-15
    ));

    let refused = |text: &str, wanted: &str| {
        let error = InstrumentBudget::from_toml_str(text, "b.toml")
            .unwrap_err()
            .to_string();
        assert!(error.contains(wanted), "{error:?} lacks {wanted:?}");
    };
    refused(
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 0.1\nacts_on = \"each-cycle\"\n",
        "b.toml:5:11: unknown acts_on \"each-cycle\"",
    );
    refused(
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 0.1\nact_on = \"result\"\n",
        "b.toml:5:1",
    );
    refused(
        "component = [{ name = \"a\", type = \"B\", u = 0.1, acts_on = \"result\" }]\n",
        "acts_on on a line of its own",
    );
    refused(
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 0.1\n[[component]]\nname = \"b\"\n\
         type = \"B\"\nu = 0.1\n[[correlation]]\nbetween = [\"a\", \"b\"]\nr = 0.5\n",
        "correlations are not supported",
    );
    // the paper's Table 1 file reads (every line acting on the result) and its type A
    // lines draw a caution: the fit gives the repeatability already
    let paper = InstrumentBudget::read_path(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/budgets/paper-table1.toml"),
    )
    .unwrap();
    assert!(paper.components.iter().all(|c| c.scope == Scope::Result));
    assert_eq!(paper.notes().len(), 2);
}
