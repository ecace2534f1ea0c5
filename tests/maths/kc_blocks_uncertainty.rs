//! Angle blocks in a key comparison, their uncertainties beyond the formulas' U (docs/FORMAT.md
//! §12): two comparisons of blocks linked, the Welch–Satterthwaite ν_eff of each degree of
//! equivalence, and Monte Carlo U — each worked by hand in the test from the laboratories'
//! results, never copied from polycal's output (the reference and the tests are in
//! `kc_blocks`).

// The hand calculations are written with indices, as the textbooks write them.
#![allow(clippy::needless_range_loop)]

use crate::kc_blocks::{Data, blocks, close, close_or_nan, four_labs};
use crate::kc_support::blocks::block_fit;
use crate::kc_support::critical;
use polycal::kc::{LabResult, evaluate, link, read_json};
use polycal::results::{Quantity, ResultRow};
use statrs::distribution::{ContinuousCDF, StudentsT};

/// One comparison's degrees of equivalence by hand: (d, u(d)) per laboratory and block
/// (NaN where not reported), and u_ref per block.
struct Hand {
    d: Vec<Vec<f64>>,
    u_d: Vec<Vec<f64>>,
    u_ref: Vec<f64>,
    inside: Vec<bool>,
}

fn by_hand(data: &Data, inside: &[bool]) -> Hand {
    let set: Vec<usize> = (0..inside.len()).filter(|&i| inside[i]).collect();
    let fit = block_fit(&data.x, &data.u, &set);
    let (mut d, mut u_d) = (Vec::new(), Vec::new());
    for i in 0..data.names.len() {
        let sign = if inside[i] { -1.0 } else { 1.0 };
        d.push(
            (0..3)
                .map(|b| data.x[i][b].map_or(f64::NAN, |x| x - fit.reference[b]))
                .collect(),
        );
        u_d.push(
            (0..3)
                .map(|b| match data.x[i][b] {
                    Some(_) => (data.u[i][b].powi(2) + sign * fit.reference_u[b].powi(2)).sqrt(),
                    None => f64::NAN,
                })
                .collect(),
        );
    }
    Hand {
        d,
        u_d,
        u_ref: fit.reference_u,
        inside: inside.to_vec(),
    }
}

impl Hand {
    /// Cov(d_j, d_l) at block b: u²(d_j) for j = l; −u_ref² both in the reference, +u_ref²
    /// both out, 0 one in and one out.
    fn cov(&self, j: usize, l: usize, b: usize) -> f64 {
        if j == l {
            return self.u_d[j][b].powi(2);
        }
        match (self.inside[j], self.inside[l]) {
            (true, true) => -self.u_ref[b].powi(2),
            (false, false) => self.u_ref[b].powi(2),
            _ => 0.0,
        }
    }
}

/// (f) Linking two comparisons of angle blocks by hand. CIPM: A, B, X, Z, all in the
/// reference, X without block 3. RMO: A, B, Y, W, A and B kept out of the reference, B
/// without block 2. The linking laboratories per block: A and B on blocks 1 and 3, A alone
/// on 2; C = Cov_CIPM + Cov_RMO with the diagonal u²(d) and off it the sum of
/// −u_ref²(CIPM, both in) and +u_ref²(RMO, both out); for two, a = (C₂₂ − C₁₂, C₁₁ − C₁₂)/s,
/// s = C₁₁ + C₂₂ − 2C₁₂,
/// u²(Δ) = det C/s, χ²_b = (o₁ − o₂)²/s; for one, Δ its offset and u²(Δ) = C₁₁. The link's
/// χ² = Σ_b χ²_b, ν = Σ_b (L_b − 1) = 2. The CIPM comparison is read back from its JSON.
#[test]
fn kc_blocks_linking_matches_a_hand_worked_case() {
    let cipm_data = Data::new(&[
        (
            "A",
            [Some(5.02), Some(-0.98), Some(2.51)],
            [0.05, 0.06, 0.07],
        ),
        (
            "B",
            [Some(4.95), Some(-1.04), Some(2.44)],
            [0.09, 0.08, 0.10],
        ),
        ("X", [Some(5.10), Some(-0.90), None], [0.12, 0.10, 0.10]),
        (
            "Z",
            [Some(4.98), Some(-1.10), Some(2.56)],
            [0.07, 0.15, 0.08],
        ),
    ]);
    let rmo_data = Data::new(&[
        (
            "A",
            [Some(-2.96), Some(0.43), Some(1.05)],
            [0.06, 0.05, 0.07],
        ),
        ("B", [Some(-3.08), None, Some(1.20)], [0.10, 0.10, 0.09]),
        (
            "Y",
            [Some(-3.01), Some(0.38), Some(1.12)],
            [0.08, 0.08, 0.12],
        ),
        (
            "W",
            [Some(-2.93), Some(0.47), Some(1.06)],
            [0.11, 0.09, 0.06],
        ),
    ]);
    let cipm = evaluate(&cipm_data.results(), &[], &blocks()).unwrap();
    let cipm = read_json(
        serde_json::to_string(&cipm).unwrap().as_bytes(),
        "cipm.json",
    )
    .unwrap();
    let options = blocks().with_not_in_reference(["A", "B"]);
    let mut rmo = evaluate(&rmo_data.results(), &[], &options).unwrap();
    link(&mut rmo, &cipm).unwrap();
    let there = by_hand(&cipm_data, &[true; 4]);
    let here = by_hand(&rmo_data, &[false, false, true, true]);
    let linked = rmo.link.as_ref().unwrap();
    assert_eq!(linked.labs, ["A", "B"]);
    let (mut chi2, mut dof) = (0.0, 0);
    for b in 0..3 {
        // A and B are laboratories 0 and 1 of both comparisons
        let linking: Vec<usize> = (0..2).filter(|&j| here.d[j][b].is_finite()).collect();
        let c = |j: usize, l: usize| there.cov(j, l, b) + here.cov(j, l, b);
        let offset = |j: usize| there.d[j][b] - here.d[j][b];
        let (delta, u2_delta, weights) = match linking.as_slice() {
            [j] => (offset(*j), c(*j, *j), vec![(*j, 1.0)]),
            [j, l] => {
                let s = c(*j, *j) + c(*l, *l) - 2.0 * c(*j, *l);
                let a = [(c(*l, *l) - c(*j, *l)) / s, (c(*j, *j) - c(*j, *l)) / s];
                chi2 += (offset(*j) - offset(*l)).powi(2) / s;
                let det = c(*j, *j) * c(*l, *l) - c(*j, *l).powi(2);
                (
                    a[0] * offset(*j) + a[1] * offset(*l),
                    det / s,
                    vec![(*j, a[0]), (*l, a[1])],
                )
            }
            other => panic!("{other:?}"),
        };
        dof += linking.len() - 1;
        close(linked.correction[b], delta, 1e-9, "Δ");
        close(linked.correction_u[b], u2_delta.sqrt(), 1e-9, "u(Δ)");
        for (i, doe) in rmo.degrees_of_equivalence.iter().enumerate() {
            let covariance: f64 = weights.iter().map(|&(j, a)| a * here.cov(i, j, b)).sum();
            let u2 = here.u_d[i][b].powi(2) + u2_delta - 2.0 * covariance;
            let what = format!("{} block {}", doe.lab, b + 1);
            close_or_nan(
                doe.d_linked.as_ref().unwrap()[b],
                here.d[i][b] + delta,
                1e-9,
                &what,
            );
            close_or_nan(
                doe.expanded_u_linked.as_ref().unwrap()[b],
                2.0 * u2.sqrt(),
                1e-9,
                &format!("U_linked {what}"),
            );
        }
    }
    let test = linked.vector.as_ref().unwrap();
    assert_eq!(dof, 2);
    assert_eq!(test.dof, 2);
    close(test.chi2, chi2, 1e-9, "the link's χ²");
    assert_eq!(test.consistent, chi2 <= critical(2));
}

/// (g) Welch–Satterthwaite with blocks: A (u 0.1″, ν 4), B (0.2″, none stated), C (0.1″,
/// ν 9), D (0.15″, ν 6) without block 2. Per block over the laboratories reporting it,
/// d_A = Σ_j c_j x_j with c_j = δ_Aj − w'_j, u_c² = Σ c_j² u_j², ν_eff = u_c⁴ / Σ_j
/// (c_j² u_j²)²/ν_j, U = t_95.45(ν_eff)·u_c; D has none on block 2.
#[test]
fn kc_blocks_welch_satterthwaite_by_hand() {
    let stated = [
        (0.1, Some(4.0)),
        (0.2, None),
        (0.1, Some(9.0)),
        (0.15, Some(6.0)),
    ];
    let values = [
        [0.31, -0.12],
        [0.18, -0.02],
        [0.36, -0.15],
        [0.12, f64::NAN],
    ];
    let labs: Vec<LabResult> = ["A", "B", "C", "D"]
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let (u, dof) = stated[i];
            let rows = (0..2)
                .filter(|&b| values[i][b].is_finite())
                .map(|b| {
                    let row =
                        ResultRow::new(Quantity::AngleBlock, b as u32 + 1, values[i][b]).with_u(u);
                    match dof {
                        Some(dof) => row.with_dof(dof),
                        None => row,
                    }
                })
                .collect();
            LabResult::from_rows(*name, rows)
        })
        .collect();
    let kc = evaluate(&labs, &[], &blocks()).unwrap();
    for b in 0..2 {
        let reporting: Vec<usize> = (0..4).filter(|&j| values[j][b].is_finite()).collect();
        let total: f64 = reporting.iter().map(|&j| stated[j].0.powi(-2)).sum();
        for &i in &reporting {
            let (mut u_c2, mut denominator) = (0.0, 0.0);
            for &j in &reporting {
                let c = f64::from(u8::from(i == j)) - stated[j].0.powi(-2) / total;
                let part = c * c * stated[j].0 * stated[j].0;
                u_c2 += part;
                if let Some(nu) = stated[j].1 {
                    denominator += part * part / nu;
                }
            }
            let nu = u_c2 * u_c2 / denominator;
            let k = StudentsT::new(0.0, 1.0, nu)
                .unwrap()
                .inverse_cdf(0.5 + 0.9545 / 2.0);
            let doe = &kc.degrees_of_equivalence[i];
            let what = format!("{} block {}", doe.lab, b + 1);
            let got = doe.dof_effective.as_ref().unwrap()[b].expect("finite");
            close(got, nu, 1e-9 * nu, &format!("ν_eff {what}"));
            close(doe.k.as_ref().unwrap()[b], k, 1e-9, &format!("k {what}"));
            close(
                doe.expanded_u[b],
                k * u_c2.sqrt(),
                1e-12,
                &format!("U {what}"),
            );
        }
    }
    let d = &kc.degrees_of_equivalence[3];
    assert_eq!(d.dof_effective.as_ref().unwrap()[1], None);
    assert!(d.k.as_ref().unwrap()[1].is_nan() && d.expanded_u[1].is_nan());
}

/// (h) Monte Carlo on blocks with the weighted mean, C and D each missing a block: every U
/// and u_ref of 20 000 draws within 3 % of the formulas worked by hand (the 95.45 %
/// quantile of 20 000 draws has a relative standard error of about 0.7 %); none where a
/// laboratory reports nothing.
#[test]
fn kc_blocks_monte_carlo_u_is_the_formulas_for_the_weighted_mean() {
    let mut data = four_labs();
    data.x[2][1] = None;
    data.x[3][2] = None;
    let options = blocks().with_monte_carlo(20_000);
    let kc = evaluate(&data.results(), &[], &options).unwrap();
    let hand = by_hand(&data, &[true; 4]);
    for b in 0..3 {
        let ratio = kc.reference_u[b] / hand.u_ref[b];
        assert!((ratio - 1.0).abs() < 0.03, "u_ref block {}: {ratio}", b + 1);
    }
    for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
        for b in 0..3 {
            let formula = 2.0 * hand.u_d[i][b];
            if formula.is_nan() {
                assert!(doe.expanded_u[b].is_nan(), "{} block {}", doe.lab, b + 1);
                continue;
            }
            let ratio = doe.expanded_u[b] / formula;
            assert!(
                (ratio - 1.0).abs() < 0.03,
                "{} block {}: Monte Carlo U / formula {ratio}",
                doe.lab,
                b + 1
            );
            close(doe.d[b], hand.d[i][b], 1e-12, "d");
        }
    }
}

/// Two comparisons whose block 2 has different nominal angles (15° here, 30° there) are
/// not of the same artefact's blocks: refused; with the same nominal angles, linked.
#[test]
fn kc_blocks_a_link_between_different_nominal_angles_is_refused() {
    let lab = |name: &str, shift: f64, nominal_2: f64| {
        let rows = [(1, 0.1, 10.0), (2, -0.2, nominal_2), (3, 0.05, 45.0)]
            .iter()
            .map(|&(b, x, nominal)| {
                ResultRow::new(Quantity::AngleBlock, b, x + shift)
                    .with_u(0.05)
                    .with_nominal_deg(nominal)
            })
            .collect();
        LabResult::from_rows(name, rows)
    };
    let options = polycal::kc::KcOptions::new().with_quantity(Quantity::AngleBlock);
    let cipm = evaluate(&[lab("A", 0.0, 15.0), lab("B", 0.02, 15.0)], &[], &options).unwrap();
    let other = evaluate(&[lab("A", 0.0, 30.0), lab("C", 0.01, 30.0)], &[], &options).unwrap();
    let mut rmo = other.clone();
    let e = link(&mut rmo, &cipm).unwrap_err();
    assert!(e.to_string().contains("not of the same positions"), "{e}");
    let same = evaluate(&[lab("A", 0.0, 15.0), lab("C", 0.01, 15.0)], &[], &options).unwrap();
    let mut rmo = same;
    link(&mut rmo, &cipm).unwrap();
    assert_eq!(rmo.link.unwrap().labs, ["A"]);
}
