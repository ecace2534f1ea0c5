//! Student's t, GUM budgets and budget files against published numbers:
//! JCGM 100:2008 (GUM) Table G.2 and example H.1, and Table 1 of the reference paper
//! (Hsieh, Lin, Yeh, Watanabe, Appl. Sci. 2023, 13, 1865, section 3.2).

use polycal::uncertainty::budget::{Budget, BudgetError, Component, DofPolicy};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::student::{normal_quantile, t_cdf, t_coverage, t_quantile};
use polycal::uncertainty::{BudgetFile, render_table};

fn round(x: f64, decimals: usize) -> String {
    format!("{x:.decimals$}")
}

// ---------------------------------------------------------------- Student's t

#[test]
fn t_at_95_percent_matches_the_tables() {
    // Standard two-sided t table, p = 95 %, to 4 decimals.
    for (nu, k) in [
        (Some(5.0), "2.5706"),
        (Some(43.0), "2.0167"),
        (Some(50.0), "2.0086"),
        (Some(60.0), "2.0003"),
        (Some(74.0), "1.9925"),
        (None, "1.9600"),
    ] {
        assert_eq!(round(t_quantile(0.95, nu), 4), k, "ν = {nu:?}");
    }
}

#[test]
fn t_matches_gum_table_g2() {
    // JCGM 100:2008 Table G.2. Its columns 68.27 %, 95.45 % and 99.73 % are the normal
    // coverage of ±1σ, ±2σ, ±3σ (so that t → 1, 2, 3 as ν → ∞): p = erf(n/√2).
    let sigma = |n: f64| t_coverage(n, None);
    assert_eq!(round(sigma(2.0), 4), "0.9545");
    // Column p = 95.45 %, with the table's decimals.
    for (nu, decimals, k) in [
        (1.0, 2, "13.97"),
        (2.0, 2, "4.53"),
        (3.0, 2, "3.31"),
        (4.0, 2, "2.87"),
        (5.0, 2, "2.65"),
        (6.0, 2, "2.52"),
        (7.0, 2, "2.43"),
        (8.0, 2, "2.37"),
        (9.0, 2, "2.32"),
        (10.0, 2, "2.28"),
        (20.0, 2, "2.13"),
        (50.0, 2, "2.05"),
        (100.0, 3, "2.025"),
    ] {
        assert_eq!(
            round(t_quantile(sigma(2.0), Some(nu)), decimals),
            k,
            "ν = {nu}"
        );
        // The rounded 0.9545 gives the same table values.
        assert_eq!(round(t_quantile(0.9545, Some(nu)), decimals), k, "ν = {nu}");
    }
    assert_eq!(round(t_quantile(sigma(2.0), None), 3), "2.000");
    // Other columns of Table G.2.
    assert_eq!(round(t_quantile(0.99, Some(10.0)), 2), "3.17");
    assert_eq!(round(t_quantile(0.99, Some(16.0)), 2), "2.92"); // GUM H.1.6
    assert_eq!(round(t_quantile(sigma(1.0), Some(1.0)), 2), "1.84");
    assert_eq!(round(t_quantile(sigma(1.0), Some(10.0)), 2), "1.05");
    assert_eq!(round(t_quantile(0.90, Some(2.0)), 2), "2.92");
    assert_eq!(round(t_quantile(0.95, Some(1.0)), 2), "12.71");
    assert_eq!(round(t_quantile(0.99, Some(1.0)), 2), "63.66");
    assert_eq!(round(t_quantile(sigma(3.0), Some(1.0)), 2), "235.80");
    assert_eq!(round(t_quantile(sigma(3.0), Some(2.0)), 2), "19.21");
    assert_eq!(round(t_quantile(sigma(3.0), Some(10.0)), 2), "3.96");
    assert_eq!(round(t_quantile(sigma(1.0), None), 3), "1.000");
    assert_eq!(round(t_quantile(sigma(3.0), None), 3), "3.000");
}

#[test]
fn t_for_fractional_dof_lies_between_its_integer_neighbours() {
    // ν_eff = 72.6 of the paper's budget: between t(72) and t(73), at 1.9932.
    let k = t_quantile(0.95, Some(72.6));
    assert!(t_quantile(0.95, Some(73.0)) < k && k < t_quantile(0.95, Some(72.0)));
    assert_eq!(round(k, 4), "1.9932");
    // Closed forms at ν = 1 (Cauchy) and ν = 2 agree with the general solver nearby.
    for p in [0.5, 0.9, 0.95, 0.9973] {
        for nu in [1.0, 2.0] {
            let below = t_quantile(p, Some(nu - 1e-9));
            let at = t_quantile(p, Some(nu));
            assert!(
                (below / at - 1.0).abs() < 1e-7,
                "p {p} ν {nu}: {below} vs {at}"
            );
        }
    }
}

#[test]
fn t_is_monotone_in_dof_and_tends_to_the_normal_quantile() {
    for p in [0.6827, 0.9, 0.95, 0.9545, 0.99, 0.9973, 1.0 - 1e-9] {
        let z = t_quantile(p, None);
        assert_eq!(z, -normal_quantile((1.0 - p) / 2.0));
        let mut previous = f64::INFINITY;
        let mut nu = 1.0;
        while nu < 1e9 {
            let k = t_quantile(p, Some(nu));
            assert!(
                k.is_finite() && k < previous,
                "p {p}: t({nu}) = {k} ≥ {previous}"
            );
            assert!(k > z, "p {p}: t({nu}) = {k} ≤ z = {z}");
            previous = k;
            nu *= 1.07;
        }
        // Large ν: t − z ≈ (z³ + z)/(4ν) (A&S 26.7.5, first term).
        for nu in [1e6, 1e8, 1e12] {
            let first_term = (z * z * z + z) / (4.0 * nu);
            let k = t_quantile(p, Some(nu));
            assert!(
                ((k - z) / first_term - 1.0).abs() < 1e-3,
                "p {p} ν {nu}: {k} vs {z}"
            );
        }
        assert_eq!(t_quantile(p, Some(f64::INFINITY)), z);
    }
}

#[test]
fn t_cdf_inverts_t_quantile() {
    for nu in [
        1.0, 1.5, 2.0, 3.7, 10.0, 72.6, 500.0, 3999.0, 4000.0, 1e5, 1e9,
    ] {
        for p in [0.1, 0.5, 0.6827, 0.95, 0.99, 0.9999, 1.0 - 1e-10] {
            let k = t_quantile(p, Some(nu));
            let back = t_coverage(k, Some(nu));
            assert!(
                ((1.0 - back) / (1.0 - p) - 1.0).abs() < 1e-11,
                "ν {nu} p {p}: coverage({k}) = {back}"
            );
            assert!((t_cdf(k, Some(nu)) - (1.0 + p) / 2.0).abs() < 1e-15);
            assert!((t_cdf(-k, Some(nu)) - (1.0 - p) / 2.0).abs() < 1e-15);
        }
    }
}

#[test]
fn t_cdf_matches_closed_forms_for_small_integer_dof() {
    use std::f64::consts::PI;
    // Closed forms of P(T ≤ t) (e.g. Abramowitz & Stegun 26.7.3/26.7.4 for ν = 1 … 5).
    let closed = |nu: u32, t: f64| -> f64 {
        let theta = (t / f64::from(nu).sqrt()).atan();
        let (s, c) = theta.sin_cos();
        match nu {
            1 => 0.5 + theta / PI,
            2 => 0.5 + t / (2.0 * (2.0 + t * t).sqrt()),
            3 => 0.5 + (theta + s * c) / PI,
            4 => 0.5 + 0.5 * s * (1.0 + 0.5 * c * c),
            5 => 0.5 + (theta + s * c * (1.0 + 2.0 / 3.0 * c * c)) / PI,
            _ => unreachable!(),
        }
    };
    for nu in 1..=5u32 {
        for t in [0.05, 0.3, 1.0, 1.96, 2.5706, 4.0, 6.0] {
            let want_upper = 1.0 - closed(nu, t);
            let got_upper = 1.0 - t_cdf(t, Some(f64::from(nu)));
            assert!(
                (got_upper / want_upper - 1.0).abs() < 1e-12,
                "ν {nu} t {t}: {got_upper} vs {want_upper}"
            );
            assert!((t_cdf(-t, Some(f64::from(nu))) - (1.0 - closed(nu, t))).abs() < 1e-15);
        }
    }
}

#[test]
fn t_refuses_out_of_domain_arguments() {
    assert!(t_quantile(1.5, Some(3.0)).is_nan());
    assert!(t_quantile(-0.1, None).is_nan());
    assert!(t_quantile(f64::NAN, None).is_nan());
    assert!(t_quantile(0.95, Some(0.0)).is_nan());
    assert!(t_quantile(0.95, Some(-2.0)).is_nan());
    assert!(t_quantile(0.95, Some(f64::NAN)).is_nan());
    assert_eq!(t_quantile(0.0, Some(3.0)), 0.0);
    assert_eq!(t_quantile(1.0, Some(3.0)), f64::INFINITY);
}

// ---------------------------------------------------------------- budgets

/// The five sources of the angle error u(α), Table 1 and items (1)–(5) of section 3.2.
fn paper_angle_error() -> Budget {
    Budget::new(vec![
        Component::type_a(
            "Repeatability of angle error measurement",
            Distribution::Normal { u: 0.0450 },
            Some(5.0),
        ),
        Component::type_b(
            "Resolution of the autocollimator",
            Distribution::rectangular_full_width(0.001),
            Some(50.0),
        ),
        Component::type_b(
            "Traceability of the autocollimator",
            Distribution::normal_expanded(0.01, 2.0),
            Some(60.0),
        ),
        Component::type_b(
            "Angle error of autocollimator",
            Distribution::rectangular_full_width(0.27),
            Some(50.0),
        ),
        Component::type_b(
            "Resolution of the rotary encoder",
            Distribution::rectangular_full_width(0.04),
            Some(50.0),
        ),
    ])
}

fn paper_table1() -> Budget {
    Budget::new(vec![
        Component::nested("Measured value, ε", paper_angle_error()),
        Component::type_a(
            "Pitch angle deviation, β",
            Distribution::Normal { u: 0.0450 },
            Some(5.0),
        ),
        Component::type_b(
            "Setup error, U",
            Distribution::rectangular_full_width(0.71),
            Some(50.0),
        ),
    ])
}

#[test]
fn paper_table1_angle_error_u_alpha() {
    let r = paper_angle_error()
        .evaluate(0.95, DofPolicy::Fractional)
        .unwrap();
    // Reproduces: u(α) = 0.0909″ (the paper prints 0.0910″, from its rounded sources);
    // ν_eff = 43.8, which the paper rounds down to 43.
    assert_eq!(round(r.combined_u, 4), "0.0909");
    assert_eq!(round(r.dof_eff.unwrap(), 1), "43.8");
    assert_eq!(r.dof_eff.unwrap().floor(), 43.0);
    // The source values as the paper prints them (u = 0.0003, 0.0050, 0.0780, 0.0116):
    // the rectangular ones are 0.000289, 0.0779, 0.0115 unrounded.
    let u: Vec<String> = r.components.iter().map(|c| round(c.u, 4)).collect();
    assert_eq!(u, ["0.0450", "0.0003", "0.0050", "0.0779", "0.0115"]);
}

#[test]
fn paper_table1_combined_budget() {
    let r = paper_table1()
        .evaluate(0.95, DofPolicy::Fractional)
        .unwrap();
    // Reproduces the printed u_c = 0.23″ (0.22867″ unrounded; 4 decimals: 0.2287).
    assert_eq!(round(r.combined_u, 2), "0.23");
    assert_eq!(round(r.combined_u, 4), "0.2287");
    // Does NOT reproduce the printed ν_eff = 74: Welch–Satterthwaite gives 72.6.
    assert_eq!(round(r.dof_eff.unwrap(), 1), "72.6");
    // Does NOT reproduce the printed k = 2.00: t at 95 % for ν = 72.6 is 1.993.
    assert_eq!(round(r.k, 3), "1.993");
    // Reproduces the printed U = 0.46″ (0.456″).
    assert_eq!(round(r.expanded_u, 3), "0.456");
    assert_eq!(round(r.expanded_u, 2), "0.46");
    // The nested measured value is u(α) with its unrounded ν_eff.
    assert_eq!(round(r.components[0].u, 4), "0.0909");
    assert_eq!(round(r.components[0].dof.unwrap(), 1), "43.8");
    // Nesting is exact: the flat list of all seven sources gives the same u_c and ν_eff.
    let mut flat = paper_angle_error();
    flat.components
        .extend(paper_table1().components.into_iter().skip(1));
    let f = flat.evaluate(0.95, DofPolicy::Fractional).unwrap();
    assert!((f.combined_u - r.combined_u).abs() < 1e-15);
    assert!((f.dof_eff.unwrap() / r.dof_eff.unwrap() - 1.0).abs() < 1e-12);
    // Indices: setup error dominates (80 %), and they sum to 100.
    assert_eq!(round(r.components[2].index_percent, 1), "80.3");
    let total: f64 = r.components.iter().map(|c| c.index_percent).sum();
    assert!((total - 100.0).abs() < 1e-9);
    let nested: f64 = r.components[0]
        .components
        .iter()
        .map(|c| c.index_percent)
        .sum();
    assert!((nested - r.components[0].index_percent).abs() < 1e-9);
}

#[test]
fn paper_table1_printed_74_comes_from_the_rounded_values() {
    // With the values as Table 1 prints them (0.0910 ν 43, 0.0450 ν 5, 0.2050 ν 50) the
    // combined uncertainty is 0.2288″, and W–S with u_c rounded to 0.23″ gives 74.
    let rounded = Budget::new(vec![
        Component::type_b("ε", Distribution::Normal { u: 0.0910 }, Some(43.0)),
        Component::type_a("β", Distribution::Normal { u: 0.0450 }, Some(5.0)),
        Component::type_b("U", Distribution::Normal { u: 0.2050 }, Some(50.0)),
    ]);
    let r = rounded.evaluate(0.95, DofPolicy::Fractional).unwrap();
    assert_eq!(round(r.combined_u, 4), "0.2288");
    let denominator: f64 = r
        .components
        .iter()
        .map(|c| c.contribution.powi(4) / c.dof.unwrap())
        .sum();
    assert_eq!(round(0.23f64.powi(4) / denominator, 0), "74");
}

#[test]
fn paper_table1_policies() {
    let b = paper_table1();
    let floor = b.evaluate(0.95, DofPolicy::Floor).unwrap();
    assert_eq!(floor.dof_for_k(), Some(72.0));
    assert_eq!(floor.k, t_quantile(0.95, Some(72.0)));
    assert_eq!(round(floor.k, 4), "1.9935");
    let k2 = b.evaluate(0.95, DofPolicy::K2).unwrap();
    assert_eq!(k2.k, 2.0);
    assert_eq!(round(k2.expanded_u, 4), "0.4573");
    assert_eq!(round(k2.dof_eff.unwrap(), 1), "72.6"); // still reported
}

/// GUM Table H.1, the contributions |cᵢ|u(xᵢ) as the table gives them (nm):
/// ls 25 (ν 18), d 9.7 (ν 25.6), αs and θ zero to first order, δα 2.9 (ν 50),
/// δθ 16.6 (ν 2).
#[test]
fn gum_h1_end_gauge_from_table_h1() {
    let b = Budget::new(vec![
        Component::type_b("ls", Distribution::Normal { u: 25.0 }, Some(18.0)),
        Component::type_a("d", Distribution::Normal { u: 9.7 }, Some(25.6)),
        Component::type_b("αs", Distribution::Normal { u: 1.2e-6 }, None).with_sensitivity(0.0),
        Component::type_a("θ", Distribution::Normal { u: 0.41 }, None).with_sensitivity(0.0),
        Component::type_b("δα", Distribution::Normal { u: 2.9 }, Some(50.0)),
        Component::type_b("δθ", Distribution::Normal { u: 16.6 }, Some(2.0)),
    ]);
    let r = b.evaluate(0.99, DofPolicy::Floor).unwrap();
    assert_eq!(round(r.combined_u, 1), "31.7"); // GUM: u_c = 32 nm
    assert_eq!(round(r.dof_eff.unwrap(), 1), "16.8"); // GUM rounds down to 16
    assert_eq!(r.dof_for_k(), Some(16.0));
    assert_eq!(round(r.k, 2), "2.92"); // k = t99(16)
    assert_eq!(round(r.expanded_u, 0), "93"); // U99 = 93 nm
}

#[test]
fn gum_h1_end_gauge_file_with_its_inputs() {
    let f = BudgetFile::read_path("examples/budgets/gum-h1-end-gauge.toml").unwrap();
    assert_eq!(f.p, 0.99);
    assert_eq!(f.dof_policy, DofPolicy::Floor);
    let r = f.evaluate().unwrap();
    let d = &r.components[1];
    assert_eq!(round(d.u, 1), "9.7"); // GUM H.1.3.2: u(d) = 9.7 nm
    assert_eq!(round(d.dof.unwrap(), 1), "25.6"); // ν(d) = 25.6
    assert_eq!(round(r.components[2].u * 1e6, 1), "1.2"); // u(αs) = 1.2e-6 /°C
    assert_eq!(round(r.components[3].u, 2), "0.41"); // u(θ) = 0.41 °C
    assert_eq!(round(r.components[4].contribution, 1), "2.9"); // δα: 2.9 nm
    assert_eq!(round(r.components[5].contribution, 1), "16.6"); // δθ: 16.6 nm
    assert_eq!(round(r.combined_u, 0), "32"); // u_c = 32 nm
    assert_eq!(round(r.combined_u.powi(2), 0), "1002"); // u_c² = 1002 nm²
    assert_eq!(round(r.dof_eff.unwrap(), 1), "16.7"); // ν_eff = 16.7
    assert_eq!(round(r.k, 2), "2.92");
    assert_eq!(round(r.expanded_u, 0), "92"); // 92.5; the GUM's 93 = 2.92 × 32 (rounded u_c)
    assert_eq!(round(2.92 * 32.0, 0), "93");
}

#[test]
fn paper_table1_file_reproduces_the_library_budget() {
    let f = BudgetFile::read_path("examples/budgets/paper-table1.toml").unwrap();
    assert_eq!(f.budget, {
        // Same numbers as paper_table1(), names as in the file.
        let mut b = paper_table1();
        let names = [
            "Measured value, ε (angle error α)",
            "Pitch angle deviation, β",
            "Setup error, U",
        ];
        for (c, n) in b.components.iter_mut().zip(names) {
            c.name = n.to_string();
        }
        b
    });
    let r = f.evaluate().unwrap();
    assert_eq!(round(r.combined_u, 4), "0.2287");
    assert_eq!(round(r.dof_eff.unwrap(), 1), "72.6");
    assert_eq!(round(r.k, 3), "1.993");
    assert_eq!(round(r.expanded_u, 2), "0.46");
}

#[test]
fn budget_json_has_the_format_md_fields() {
    let f = BudgetFile::read_path("examples/budgets/paper-table1.toml").unwrap();
    let r = f.evaluate().unwrap();
    let json: serde_json::Value = serde_json::to_value(&r).unwrap();
    let top: Vec<&str> = json
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    for key in [
        "components",
        "combined_u",
        "dof_eff",
        "k",
        "expanded_u",
        "p",
        "dof_policy",
    ] {
        assert!(top.contains(&key), "missing {key}");
    }
    assert_eq!(json["p"], 0.95);
    assert_eq!(json["dof_policy"], "fractional");
    let c = &json["components"][2];
    assert_eq!(c["name"], "Setup error, U");
    assert_eq!(c["type"], "B");
    assert_eq!(c["sensitivity"], 1.0);
    assert_eq!(c["dof"], 50.0);
    assert_eq!(c["u"].as_f64().unwrap(), r.components[2].u);
    assert_eq!(
        c["contribution"].as_f64().unwrap(),
        r.components[2].contribution
    );
    assert_eq!(json["components"][0]["type"], "A+B");
    // Full precision: the JSON number reads back to the same double.
    assert_eq!(json["combined_u"].as_f64().unwrap(), r.combined_u);
    // Infinite degrees of freedom are null.
    let b = Budget::new(vec![Component::type_b(
        "x",
        Distribution::Normal { u: 1.0 },
        None,
    )]);
    let json = serde_json::to_value(b.evaluate(0.95, DofPolicy::Fractional).unwrap()).unwrap();
    assert!(json["dof_eff"].is_null());
    assert!(json["components"][0]["dof"].is_null());
    assert_eq!(round(json["k"].as_f64().unwrap(), 4), "1.9600");
}

#[test]
fn table_shows_gum_workbench_columns() {
    let r = paper_table1()
        .evaluate(0.95, DofPolicy::Fractional)
        .unwrap();
    let mut table = String::new();
    render_table(&mut table, &r).unwrap();
    assert_eq!(table, polycal::uncertainty::budget_table(&r).to_string());
    for needle in [
        "Quantity",
        "Type",
        "Distribution",
        "u(x_i)",
        "c_i",
        "u_i(y)",
        "ν_i",
        "Index",
        "0.09088",
        "43.8",
        "80.3 %",
        "u_c   = 0.2287",
        "ν_eff = 72.6",
        "k     = 1.993",
        "U     = 0.456",
        "  Angle error of autocollimator",
    ] {
        assert!(table.contains(needle), "{needle:?} not in\n{table}");
    }
}

#[test]
fn distributions_give_the_gum_standard_uncertainties() {
    let a = 0.3;
    assert!(
        (Distribution::Rectangular { half_width: a }.standard_uncertainty() - a / 3f64.sqrt())
            .abs()
            < 1e-17
    );
    assert!(
        (Distribution::Triangular { half_width: a }.standard_uncertainty() - a / 6f64.sqrt()).abs()
            < 1e-17
    );
    assert!(
        (Distribution::Arcsine { half_width: a }.standard_uncertainty() - a / 2f64.sqrt()).abs()
            < 1e-17
    );
    assert!(
        (Distribution::rectangular_full_width(0.27).standard_uncertainty() - 0.27 / 12f64.sqrt())
            .abs()
            < 1e-17
    );
    assert_eq!(
        Distribution::normal_expanded(0.01, 2.0).standard_uncertainty(),
        0.005
    );
    let t = Distribution::StudentT {
        scale: 0.1,
        dof: 5.0,
    };
    assert_eq!(t.standard_uncertainty(), 0.1);
    assert!((t.standard_deviation().unwrap() - 0.1 * (5.0f64 / 3.0).sqrt()).abs() < 1e-17);
    assert_eq!(
        Distribution::StudentT {
            scale: 0.1,
            dof: 2.0
        }
        .standard_deviation(),
        None
    );
}

// ---------------------------------------------------------------- refusals

#[test]
fn budget_refuses_bad_budgets() {
    let n = |u| Distribution::Normal { u };
    let err = |b: Budget| {
        b.evaluate(0.95, DofPolicy::Fractional)
            .unwrap_err()
            .to_string()
    };
    assert!(err(Budget::default()).contains("no components"));
    assert!(
        err(Budget::new(vec![Component::type_a("x", n(-1.0), None)]))
            .contains("must not be negative")
    );
    assert!(
        err(Budget::new(vec![Component::type_a("x", n(1.0), Some(0.5))])).contains("at least 1")
    );
    assert!(
        err(Budget::new(vec![
            Component::type_a("x", n(1.0), None),
            Component::type_b("x", n(1.0), None)
        ]))
        .contains("two components are named \"x\"")
    );
    assert!(err(Budget::new(vec![Component::type_a("x", n(0.0), None)])).contains("is 0"));
    assert!(matches!(
        Budget::new(vec![Component::type_a("x", n(1.0), None)]).evaluate(95.0, DofPolicy::Floor),
        Err(BudgetError::Coverage(_))
    ));
    // Correlations.
    let two = || {
        Budget::new(vec![
            Component::type_b("a", n(1.0), None),
            Component::type_b("b", n(1.0), Some(10.0)),
            Component::type_b("c", n(1.0), None),
        ])
    };
    assert!(err(two().with_correlation("a", "b", 0.5)).contains("Welch–Satterthwaite"));
    assert!(err(two().with_correlation("a", "z", 0.5)).contains("no component is named \"z\""));
    assert!(err(two().with_correlation("a", "c", 1.5)).contains("between -1 and 1"));
    assert!(err(two().with_correlation("a", "a", 0.5)).contains("itself"));
    assert!(
        err(two()
            .with_correlation("a", "c", 0.5)
            .with_correlation("c", "a", 0.5))
        .contains("twice")
    );
    let three = Budget::new(vec![
        Component::type_b("a", n(1.0), None),
        Component::type_b("b", n(1.0), None),
        Component::type_b("c", n(1.0), None),
    ])
    .with_correlation("a", "b", 0.9)
    .with_correlation("b", "c", 0.9)
    .with_correlation("a", "c", -0.9);
    assert!(matches!(
        three.evaluate(0.95, DofPolicy::Fractional),
        Err(BudgetError::NotPositiveSemidefinite)
    ));
}

#[test]
fn correlated_inputs_with_infinite_dof_are_combined_with_covariance() {
    // GUM 5.2.2: u_c² = u_a² + u_b² + 2 r u_a u_b (sensitivities 1 and −1 flip the sign).
    let b = Budget::new(vec![
        Component::type_b("a", Distribution::Normal { u: 0.3 }, None),
        Component::type_b("b", Distribution::Normal { u: 0.4 }, None).with_sensitivity(-1.0),
        Component::type_a("c", Distribution::Normal { u: 0.1 }, Some(9.0)),
    ])
    .with_correlation("a", "b", 0.5);
    let r = b.evaluate(0.95, DofPolicy::Fractional).unwrap();
    let var: f64 = 0.09 + 0.16 - 2.0 * 0.5 * 0.3 * 0.4 + 0.01;
    assert!((r.combined_u - var.sqrt()).abs() < 1e-15);
    assert!((r.dof_eff.unwrap() - var * var / (0.1f64.powi(4) / 9.0)).abs() < 1e-9);
}

fn file_error(text: &str) -> String {
    BudgetFile::from_toml_str(text, "bad.toml")
        .and_then(|f| f.evaluate().map(|_| f))
        .expect_err(text)
        .to_string()
}

#[test]
fn budget_files_are_refused_with_file_line_and_column() {
    let head = "p = 0.95\n\n[[component]]\nname = \"x\"\ntype = \"B\"\n";
    for (body, want) in [
        // Two specifications.
        (
            "distribution = \"rectangular\"\nfull_width = 0.27\nu = 0.1\n",
            "bad.toml:8:5: component \"x\" gives both full_width and u: give exactly one",
        ),
        (
            "distribution = \"rectangular\"\nfull_width = 0.27\nhalf_width = 0.1\n",
            "bad.toml:8:14: component \"x\" gives both full_width and half_width",
        ),
        // None.
        (
            "distribution = \"rectangular\"\n",
            "bad.toml:3:1: component \"x\" gives no uncertainty: a rectangular distribution takes full_width, half_width or u",
        ),
        // Unknown distribution.
        (
            "distribution = \"uniform\"\nfull_width = 1\n",
            "bad.toml:6:16: unknown distribution \"uniform\"",
        ),
        // Negative width.
        (
            "distribution = \"triangular\"\nhalf_width = -0.1\n",
            "bad.toml:7:14: half_width must not be negative, got -0.1",
        ),
        // Width for a normal, expanded for a rectangular, k alone.
        (
            "full_width = 1\n",
            "bad.toml:6:14: a normal distribution takes u, or expanded and k, not full_width",
        ),
        (
            "distribution = \"rectangular\"\nexpanded = 1\nk = 2\n",
            "bad.toml:7:12: a rectangular distribution takes full_width, half_width or u, not expanded",
        ),
        (
            "u = 1\nk = 2\n",
            "bad.toml:7:5: k is given without expanded",
        ),
        (
            "expanded = 1\n",
            "bad.toml:6:12: expanded needs its coverage factor k",
        ),
        (
            "expanded = 1\nk = 0\n",
            "bad.toml:7:5: k must be greater than 0",
        ),
        // Degrees of freedom.
        ("u = 1\ndof = 0.5\n", "bad.toml:7:7: dof must be at least 1"),
        (
            "u = 1\ndof = nan\n",
            "bad.toml:7:7: dof must be a finite number",
        ),
        (
            "distribution = \"t\"\nscale = 1\n",
            "bad.toml:3:1: component \"x\": a t distribution needs finite degrees of freedom",
        ),
        // Types, unknown keys, duplicates.
        (
            "u = \"0.1\"\n",
            "bad.toml:6:5: invalid type: string \"0.1\", expected a number",
        ),
        (
            "u = 1\nunit = \"arcsec\"\n",
            "bad.toml:7:1: unknown field `unit`",
        ),
        ("u = 1\nu = 2\n", "bad.toml:7:1: duplicate key `u`"),
        (
            "u = 1\nsensitivity = inf\n",
            "bad.toml:7:15: sensitivity must be a finite number",
        ),
    ] {
        let got = file_error(&format!("{head}{body}"));
        assert!(
            got.starts_with(want),
            "for {body:?}\n got: {got}\nwant: {want}"
        );
    }
    // Missing type, name; bad type; p; policy; no components.
    for (text, want) in [
        (
            "[[component]]\nname = \"x\"\nu = 1\n",
            "bad.toml:1:1: component \"x\" has no type",
        ),
        (
            "[[component]]\ntype = \"A\"\nu = 1\n",
            "bad.toml:1:1: this component has no name",
        ),
        (
            "[[component]]\nname = \"x\"\ntype = \"a\"\nu = 1\n",
            "bad.toml:3:8: type must be \"A\" or \"B\", got \"a\"",
        ),
        (
            "p = 95\n[[component]]\nname = \"x\"\ntype = \"A\"\nu = 1\n",
            "bad.toml:1:5: p must be within 0.5 … 0.9999 (docs/FORMAT.md §2.2), got 95 (a probability: write 0.95 for 95 %)",
        ),
        (
            "dof_policy = \"round\"\n[[component]]\nname = \"x\"\ntype = \"A\"\nu = 1\n",
            "bad.toml:1:14: unknown dof_policy \"round\"",
        ),
        (
            "p = 0.95\n",
            "bad.toml:1:1: the budget has no [[component]] tables",
        ),
        (
            "p = 0.95\n[component]\nname = 1\n",
            "bad.toml:2:1: invalid type",
        ),
        (
            "[[component]]\nname = \"x\"\ntype = \"A\"\nu = 1\n[[component]]\nname = \"x\"\ntype = \"A\"\nu = 1\n",
            "bad.toml:6:8: a second component is named \"x\"",
        ),
        (
            "[[component]]\nname = \"x\"\n  [[component.component]]\n  name = \"y\"\n  type = \"A\"\n  u = 1\n  dof = 3\n",
            "ok",
        ),
        (
            "[[component]]\nname = \"x\"\nu = 2\n  [[component.component]]\n  name = \"y\"\n  type = \"A\"\n  u = 1\n",
            "bad.toml:3:5: component \"x\" has nested components, which give its standard uncertainty, type and degrees of freedom: remove u",
        ),
        (
            "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 1\n[[component]]\nname = \"b\"\ntype = \"B\"\nu = 1\ndof = 8\n[[correlation]]\nbetween = [\"a\", \"b\"]\nr = 0.3\n",
            "bad.toml:10:1: \"b\" has 8 degrees of freedom and is correlated",
        ),
        (
            "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 1\n[[correlation]]\nbetween = [\"a\", \"c\"]\nr = 0.3\n",
            "bad.toml:6:17: no component of this budget is named \"c\"",
        ),
        (
            "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 1\n[[component]]\nname = \"b\"\ntype = \"B\"\nu = 1\n[[correlation]]\nbetween = [\"a\", \"b\"]\nr = 1.2\n",
            "bad.toml:11:5: r must be between -1 and 1, got 1.2",
        ),
        (
            "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 1\n[[component]]\nname = \"b\"\ntype = \"B\"\nu = 1\nsensitivity = -1\n[[correlation]]\nbetween = [\"a\", \"b\"]\nr = 1\n",
            "bad.toml: the combined standard uncertainty is 0",
        ),
    ] {
        let got = BudgetFile::from_toml_str(text, "bad.toml")
            .and_then(|f| f.evaluate().map(|_| f))
            .map_or_else(|e| e.to_string(), |_| "ok".to_string());
        assert!(
            got.starts_with(want),
            "for {text:?}\n got: {got}\nwant: {want}"
        );
    }
}

#[test]
fn budget_file_accepts_every_specification() {
    let text = r#"
p = 0.9545
dof_policy = "k2"

[[component]]
name = "normal u"
type = "A"
u = 0.5
dof = 9

[[component]]
name = "normal expanded"
type = "B"
expanded = 0.2
k = 2

[[component]]
name = "rectangular half width"
type = "B"
distribution = "rectangular"
half_width = 0.3
sensitivity = -2

[[component]]
name = "triangular u"
type = "B"
distribution = "triangular"
u = 0.1
dof = inf

[[component]]
name = "arcsine full width"
type = "B"
distribution = "arcsine"
full_width = 0.4

[[component]]
name = "t"
type = "A"
distribution = "t"
scale = 0.05
dof = 4
"#;
    let f = BudgetFile::from_toml_str(text, "ok.toml").unwrap();
    assert_eq!(f.p, 0.9545);
    assert_eq!(f.dof_policy, DofPolicy::K2);
    let r = f.evaluate().unwrap();
    let u: Vec<f64> = r.components.iter().map(|c| c.u).collect();
    assert_eq!(u[0], 0.5);
    assert_eq!(u[1], 0.1);
    assert!((u[2] - 0.3 / 3f64.sqrt()).abs() < 1e-16);
    assert_eq!(u[3], 0.1); // the given u is kept exactly
    assert!((u[4] - 0.2 / 2f64.sqrt()).abs() < 1e-16);
    assert_eq!(u[5], 0.05);
    assert_eq!(r.components[2].contribution, 2.0 * u[2]);
    assert_eq!(r.components[3].dof, None);
    assert_eq!(r.components[5].dof, Some(4.0));
    assert_eq!(r.components[5].distribution, "t");
    assert_eq!(r.k, 2.0);
}

#[test]
fn budget_file_io_errors_name_the_file() {
    let e = BudgetFile::read_path("no/such/budget.toml")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("no/such/budget.toml: "), "{e}");
}

/// Every refusal is a typed error: the place of a problem in a file is a
/// `polycal::input::Location`, unknown keywords and bad distributions have their own
/// variants, and no message names a command-line flag.
#[test]
fn refusals_are_typed() {
    use polycal::uncertainty::DistributionError;
    use polycal::uncertainty::calibration::Scope;

    let e = "fractionnal".parse::<DofPolicy>().unwrap_err();
    assert!(matches!(&e, BudgetError::UnknownDofPolicy(s) if s == "fractionnal"));
    assert_eq!(
        e.to_string(),
        "unknown dof_policy \"fractionnal\": expected \"fractional\", \"floor\" or \"k2\""
    );
    assert_eq!("floor".parse::<DofPolicy>().unwrap(), DofPolicy::Floor);
    let e = "everywhere".parse::<Scope>().unwrap_err();
    assert!(matches!(&e, BudgetError::UnknownScope(s) if s == "everywhere"));
    assert_eq!("each-stop".parse::<Scope>().unwrap(), Scope::EachStop);

    assert_eq!(
        Distribution::Rectangular { half_width: -0.1 }.check(),
        Err(DistributionError::Negative {
            what: "half width",
            value: -0.1
        })
    );
    assert!(matches!(
        Distribution::StudentT {
            scale: 1.0,
            dof: f64::NAN
        }
        .check(),
        Err(DistributionError::TDof(nu)) if nu.is_nan()
    ));
    assert_eq!(Distribution::Normal { u: 0.1 }.check(), Ok(()));

    let text = "[[component]]\nname = \"x\"\ntype = \"B\"\ndistribution = \"normal\"\nu = -1\n";
    match BudgetFile::from_toml_str(text, "b.toml").unwrap_err() {
        BudgetError::File { location, message } => {
            assert_eq!(
                (location.file(), location.line(), location.column()),
                ("b.toml", 5, 5)
            );
            assert_eq!(message, "u must not be negative, got -1");
        }
        other => panic!("{other:?}"),
    }
    match BudgetFile::read_path("no/such/budget.toml").unwrap_err() {
        BudgetError::Io { location, .. } => {
            assert_eq!(location.to_string(), "no/such/budget.toml");
            assert_eq!(location.line(), 0);
        }
        other => panic!("{other:?}"),
    }
    let dir = std::env::temp_dir().join(format!("polycal-unc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let latin1 = dir.join("latin1.toml");
    std::fs::write(&latin1, b"[[component]]\nname = \"\xe9\"\n").unwrap();
    let e = BudgetFile::read_path(&latin1).unwrap_err().to_string();
    assert_eq!(
        e,
        // the invalid byte's own line and column: `name = "` is 8 characters
        format!(
            "{}:2:9: not valid UTF-8 (byte 0xe9); the file must be UTF-8 text",
            latin1.display()
        )
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
