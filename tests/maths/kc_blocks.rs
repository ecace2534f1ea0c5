//! Angle blocks in a key comparison (`polycal::kc` with `Quantity::AngleBlock`,
//! docs/FORMAT.md §12): every number worked by hand in the test from the formulas — each
//! block's weighted mean among the laboratories that report it, the joint χ² with
//! ν = Σ_b (n_b − 1), the degrees of equivalence, the pairs, DerSimonian–Laird's τ per
//! block, the search, the pilot's repeats, the link, Welch–Satterthwaite and Monte Carlo —
//! never copied from polycal's output. The verdicts' rates are in
//! `tests/sweeps/kc_blocks_rates.rs`.

// The hand calculations are written with indices, as the textbooks write them.
#![allow(clippy::needless_range_loop)]

use crate::kc_support::blocks::{BlockFit, block_fit, block_lab};
use crate::kc_support::critical;
use polycal::kc::{
    KcError, KcOptions, KeyComparison, LabResult, ReferenceMethod, evaluate, read_json,
};
use polycal::results::{Quantity, read_results_from};

/// The options of a comparison of angle blocks.
pub(crate) fn blocks() -> KcOptions {
    KcOptions::new().with_quantity(Quantity::AngleBlock)
}

/// Laboratories' angle blocks: names, values (`None`: not reported) and u, arcsec.
pub(crate) struct Data {
    pub names: Vec<&'static str>,
    pub x: Vec<Vec<Option<f64>>>,
    pub u: Vec<Vec<f64>>,
}

/// One laboratory of three blocks: its name, values (`None`: not reported) and u.
pub(crate) type Lab = (&'static str, [Option<f64>; 3], [f64; 3]);

impl Data {
    pub fn new(labs: &[Lab]) -> Data {
        Data {
            names: labs.iter().map(|l| l.0).collect(),
            x: labs.iter().map(|l| l.1.to_vec()).collect(),
            u: labs.iter().map(|l| l.2.to_vec()).collect(),
        }
    }

    pub fn results(&self) -> Vec<LabResult> {
        (0..self.names.len())
            .map(|i| {
                let blocks: Vec<Option<(f64, f64)>> = self.x[i]
                    .iter()
                    .zip(&self.u[i])
                    .map(|(x, u)| x.map(|x| (x, *u)))
                    .collect();
                block_lab(self.names[i], &blocks)
            })
            .collect()
    }

    /// Every u widened by `extra[b]` in quadrature (τ or u_stab per block).
    fn widened(&self, extra: &[f64]) -> Vec<Vec<f64>> {
        self.u
            .iter()
            .map(|u| u.iter().zip(extra).map(|(u, e)| u.hypot(*e)).collect())
            .collect()
    }
}

/// Four laboratories, three blocks (truth about 12.30″, −4.10″, 0.70″), consistent.
pub(crate) fn four_labs() -> Data {
    Data::new(&[
        (
            "A",
            [Some(12.31), Some(-4.12), Some(0.69)],
            [0.05, 0.06, 0.05],
        ),
        (
            "B",
            [Some(12.18), Some(-4.02), Some(0.85)],
            [0.10, 0.08, 0.12],
        ),
        (
            "C",
            [Some(12.36), Some(-4.15), Some(0.62)],
            [0.07, 0.07, 0.09],
        ),
        (
            "D",
            [Some(12.12), Some(-3.95), Some(0.80)],
            [0.15, 0.20, 0.10],
        ),
    ])
}

pub(crate) fn close(got: f64, expected: f64, tolerance: f64, what: &str) {
    assert!(
        (got - expected).abs() <= tolerance,
        "{what}: {got} vs {expected} (by hand)"
    );
}

/// NaN where the hand calculation has none, else within `tolerance`.
pub(crate) fn close_or_nan(got: f64, expected: f64, tolerance: f64, what: &str) {
    if expected.is_nan() {
        assert!(got.is_nan(), "{what}: {got}, expected none (NaN)");
    } else {
        close(got, expected, tolerance, what);
    }
}

/// Every laboratory's degree of equivalence against the hand `fit`: d = x − x_ref and
/// U = 2√(v ∓ u_ref²) with v the square of `v_u` (u with τ or u_stab in it), − in the
/// reference (`inside[i]`), + out of it; NaN where the laboratory reports no value.
fn check_degrees(
    kc: &KeyComparison,
    data: &Data,
    v_u: &[Vec<f64>],
    fit: &BlockFit,
    inside: &[bool],
) {
    for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
        assert_eq!(doe.lab, data.names[i]);
        assert_eq!(doe.in_reference, inside[i], "{}", doe.lab);
        for b in 0..data.x[i].len() {
            let (d, expanded_u) = match data.x[i][b] {
                Some(x) => {
                    let sign = if inside[i] { -1.0 } else { 1.0 };
                    let v = v_u[i][b] * v_u[i][b] + sign * fit.reference_u[b].powi(2);
                    (x - fit.reference[b], 2.0 * v.sqrt())
                }
                None => (f64::NAN, f64::NAN),
            };
            let what = format!("{} block {}", doe.lab, b + 1);
            close_or_nan(doe.d[b], d, 1e-12, &format!("d {what}"));
            close_or_nan(doe.expanded_u[b], expanded_u, 1e-12, &format!("U {what}"));
        }
    }
}

/// Every pair: d_ab = x_a − x_b, U = 2√(v_a + v_b) (NaN where either lacks the block) and
/// its test χ² = Σ_b d²/(v_a + v_b) over the blocks both report, ν = their number.
fn check_pairs(kc: &KeyComparison, data: &Data, v_u: &[Vec<f64>]) {
    let n = data.names.len();
    let mut pairs = kc.pairs.iter();
    for a in 0..n {
        for b in a + 1..n {
            let pair = pairs.next().expect("every pair");
            assert_eq!(
                (pair.a.as_str(), pair.b.as_str()),
                (data.names[a], data.names[b])
            );
            let (mut chi2, mut dof) = (0.0, 0);
            for k in 0..data.x[a].len() {
                let v = v_u[a][k].powi(2) + v_u[b][k].powi(2);
                let (d, expanded_u) = match (data.x[a][k], data.x[b][k]) {
                    (Some(x_a), Some(x_b)) => {
                        chi2 += (x_a - x_b).powi(2) / v;
                        dof += 1;
                        (x_a - x_b, 2.0 * v.sqrt())
                    }
                    _ => (f64::NAN, f64::NAN),
                };
                let what = format!("pair {}–{} block {}", pair.a, pair.b, k + 1);
                close_or_nan(pair.d[k], d, 1e-12, &format!("d {what}"));
                close_or_nan(pair.expanded_u[k], expanded_u, 1e-12, &format!("U {what}"));
            }
            let test = pair.vector.as_ref().expect("a pair's test");
            close(test.chi2, chi2, 1e-12 * chi2.max(1.0), "pair χ²");
            assert_eq!(test.dof, dof, "{}–{}", pair.a, pair.b);
            assert_eq!(test.consistent, chi2 <= critical(dof));
        }
    }
    assert!(pairs.next().is_none());
}

/// (a) Four laboratories, three blocks, each u its own: each block's weighted mean, u_ref,
/// every d and U, the joint χ² with ν = 3·(4 − 1), the verdict, the per-block χ² and every
/// pair, by hand.
#[test]
fn kc_blocks_weighted_mean_by_hand() {
    let data = four_labs();
    let kc = evaluate(&data.results(), &[], &blocks()).unwrap();
    let hand = block_fit(&data.x, &data.u, &[0, 1, 2, 3]);
    assert_eq!(kc.quantity, Quantity::AngleBlock);
    assert_eq!(kc.index, [1, 2, 3]);
    for b in 0..3 {
        close(kc.reference[b], hand.reference[b], 1e-12, "x_ref");
        close(kc.reference_u[b], hand.reference_u[b], 1e-12, "u_ref");
        close(kc.chi2[b], hand.chi2_per_block[b], 1e-12, "χ² of a block");
        assert_eq!(kc.chi2_dof[b], 3);
        assert_eq!(kc.tau[b], 0.0);
    }
    check_degrees(&kc, &data, &data.u, &hand, &[true; 4]);
    check_pairs(&kc, &data, &data.u);
    let all = kc.vector_all.as_ref().unwrap();
    assert_eq!(hand.dof, 9);
    assert_eq!(all.dof, 9);
    close(all.chi2, hand.chi2, 1e-12 * hand.chi2, "joint χ²");
    close(all.chi2_critical, critical(9), 1e-9, "χ²_0.95(9)");
    // as designed: consistent, the verdict the hand test's
    assert!(hand.chi2 <= critical(9), "{}", hand.chi2);
    assert!(all.consistent && kc.comparison_consistent);
    assert!(kc.excluded.is_empty() && kc.search.is_none());
    assert!(
        kc.verdict_statement()
            .starts_with("Consistent: the blocks' joint χ² of all 4 laboratories passes"),
        "{}",
        kc.verdict_statement()
    );
}

/// (b) C does not report block 2, D not block 3: their d and U are NaN there, each block's
/// reference is of the laboratories that report it, ν = 3 + 2 + 2; the JSON has null there
/// and reads back equal in every finite number.
#[test]
fn kc_blocks_a_laboratory_missing_a_block_is_compared_on_the_others() {
    let mut data = four_labs();
    data.x[2][1] = None;
    data.x[3][2] = None;
    let kc = evaluate(&data.results(), &[], &blocks()).unwrap();
    let hand = block_fit(&data.x, &data.u, &[0, 1, 2, 3]);
    assert_eq!(hand.dof, 7);
    for b in 0..3 {
        close(kc.reference[b], hand.reference[b], 1e-12, "x_ref");
        close(kc.reference_u[b], hand.reference_u[b], 1e-12, "u_ref");
    }
    assert_eq!(kc.chi2_dof, [3, 2, 2]);
    check_degrees(&kc, &data, &data.u, &hand, &[true; 4]);
    check_pairs(&kc, &data, &data.u);
    let all = kc.vector_all.as_ref().unwrap();
    assert_eq!(all.dof, 7);
    close(all.chi2, hand.chi2, 1e-12 * hand.chi2, "joint χ²");
    assert_eq!(all.consistent, hand.chi2 <= critical(7));

    // the JSON: null where C and D report nothing, and read back
    let text = serde_json::to_string(&kc).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let doe = &json["degrees_of_equivalence"];
    assert!(doe[2]["d"][1].is_null() && doe[2]["U"][1].is_null());
    assert!(doe[3]["d"][2].is_null() && doe[3]["U"][2].is_null());
    assert!(doe[2]["d"][0].is_f64() && doe[3]["d"][1].is_f64());
    // pair C–D (the last) shares block 1 only
    let cd = &json["pairs"][5];
    assert_eq!((cd["a"].as_str(), cd["b"].as_str()), (Some("C"), Some("D")));
    assert!(cd["d"][0].is_f64() && cd["d"][1].is_null() && cd["d"][2].is_null());
    assert_eq!(cd["vector"]["dof"], 1);
    let back = read_json(text.as_bytes(), "blocks.json").unwrap();
    assert_eq!(serde_json::to_value(&back).unwrap(), json);
    let same = |a: &[f64], b: &[f64], what: &str| {
        assert_eq!(a.len(), b.len(), "{what}");
        for (x, y) in a.iter().zip(b) {
            assert!(
                x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()),
                "{what}: {x} vs {y}"
            );
        }
    };
    same(&back.reference, &kc.reference, "reference");
    same(&back.reference_u, &kc.reference_u, "reference_u");
    same(&back.chi2, &kc.chi2, "chi2");
    for (a, b) in back
        .degrees_of_equivalence
        .iter()
        .zip(&kc.degrees_of_equivalence)
    {
        same(&a.d, &b.d, "d");
        same(&a.expanded_u, &b.expanded_u, "U");
    }
    for (a, b) in back.pairs.iter().zip(kc.pairs.iter()) {
        same(&a.d, &b.d, "pair d");
        same(&a.expanded_u, &b.expanded_u, "pair U");
        assert_eq!(a.vector, b.vector);
    }
    assert_eq!(back.vector_all, kc.vector_all);
}

/// (c) DerSimonian–Laird per block, B and D spread on block 2, C not reporting it, block 3
/// tight: τ²_b =
/// max(0, (Q_b − (n_b − 1))/(S1 − S2/S1)) over the laboratories reporting b, x_ref and
/// u_ref with u² + τ², U = 2√(u² + τ² − u_ref²); the verdict is the joint χ² at τ = 0.
#[test]
fn kc_blocks_dersimonian_laird_has_its_tau_per_block() {
    let mut data = four_labs();
    data.x[1][1] = Some(-3.70);
    data.x[3][1] = Some(-4.55);
    data.x[2][1] = None;
    // block 3 closer than its u: τ = 0 there
    data.x[1][2] = Some(0.72);
    data.x[2][2] = Some(0.70);
    data.x[3][2] = Some(0.71);
    let options = blocks().with_method(ReferenceMethod::DersimonianLaird);
    let kc = evaluate(&data.results(), &[], &options).unwrap();
    let plain = block_fit(&data.x, &data.u, &[0, 1, 2, 3]);
    let mut tau = Vec::new();
    for b in 0..3 {
        let reporting: Vec<usize> = (0..4).filter(|&i| data.x[i][b].is_some()).collect();
        let w: Vec<f64> = reporting.iter().map(|&i| data.u[i][b].powi(-2)).collect();
        let s1: f64 = w.iter().sum();
        let s2: f64 = w.iter().map(|w| w * w).sum();
        let q = plain.chi2_per_block[b];
        let dof = reporting.len() as f64 - 1.0;
        tau.push(((q - dof) / (s1 - s2 / s1)).max(0.0).sqrt());
    }
    assert!(tau[1] > 0.1, "block 2 spread beyond its u: τ = {}", tau[1]);
    assert!(tau.contains(&0.0), "{tau:?}");
    let v_u = data.widened(&tau);
    let hand = block_fit(&data.x, &v_u, &[0, 1, 2, 3]);
    for b in 0..3 {
        close(kc.tau[b], tau[b], 1e-12, "τ");
        close(kc.reference[b], hand.reference[b], 1e-12, "x_ref");
        close(kc.reference_u[b], hand.reference_u[b], 1e-12, "u_ref");
    }
    check_degrees(&kc, &data, &v_u, &hand, &[true; 4]);
    check_pairs(&kc, &data, &v_u);
    let all = kc.vector_all.as_ref().unwrap();
    close(all.chi2, plain.chi2, 1e-12 * plain.chi2, "joint χ² (τ = 0)");
    assert_eq!(all.dof, 8);
    assert!(plain.chi2 > critical(8), "as designed, τ = 0 rejected");
    assert!(!all.consistent && !kc.comparison_consistent);
    let vector = kc.vector.as_ref().unwrap();
    close(vector.chi2, hand.chi2, 1e-12 * hand.chi2, "χ² with τ");
    assert!(kc.excluded.is_empty() && kc.search.is_none());
}

/// (d) A fifth laboratory E 6u off on block 2: the joint χ² of all five fails; every
/// subset of four is tried by hand, the one that passes with the smallest χ² leaves out E
/// alone, whose exclusion states both tests; E's U is 2√(u² + u_ref²) against A–D.
#[test]
fn kc_blocks_a_laboratory_six_u_off_on_one_block_is_left_out() {
    let mut labs = vec![
        (
            "A",
            [Some(12.31), Some(-4.12), Some(0.69)],
            [0.05, 0.06, 0.05],
        ),
        (
            "B",
            [Some(12.18), Some(-4.02), Some(0.85)],
            [0.10, 0.08, 0.12],
        ),
        (
            "C",
            [Some(12.36), Some(-4.15), Some(0.62)],
            [0.07, 0.07, 0.09],
        ),
        (
            "D",
            [Some(12.12), Some(-3.95), Some(0.80)],
            [0.15, 0.20, 0.10],
        ),
    ];
    labs.push((
        "E",
        [Some(12.29), Some(-4.10 + 6.0 * 0.08), Some(0.72)],
        [0.08, 0.08, 0.08],
    ));
    let data = Data::new(&labs);
    let kc = evaluate(&data.results(), &[], &blocks()).unwrap();
    let everyone = block_fit(&data.x, &data.u, &[0, 1, 2, 3, 4]);
    assert_eq!(everyone.dof, 12);
    assert!(everyone.chi2 > critical(12));
    // every subset of four by hand: the passing one of the smallest χ²
    let best = (0..5)
        .map(|out| {
            let set: Vec<usize> = (0..5).filter(|&i| i != out).collect();
            (block_fit(&data.x, &data.u, &set), out)
        })
        .filter(|(fit, _)| fit.chi2 <= critical(fit.dof))
        .min_by(|a, b| a.0.chi2.total_cmp(&b.0.chi2))
        .expect("a subset of four passes");
    assert_eq!(best.1, 4, "E is the one left out");
    let all = kc.vector_all.as_ref().unwrap();
    close(
        all.chi2,
        everyone.chi2,
        1e-12 * everyone.chi2,
        "joint χ² of all",
    );
    assert!(!all.consistent);
    assert!(kc.comparison_consistent);
    assert_eq!(kc.excluded.len(), 1);
    let e = &kc.excluded[0];
    assert_eq!(e.lab, "E");
    for said in [
        "blocks' joint χ² of all 5 laboratories fails".to_string(),
        format!(
            "χ² = {:.3} > χ²_0.95(12) = {:.3}",
            everyone.chi2,
            critical(12)
        ),
        format!(
            "the largest subset that passes is A, B, C, D (4 laboratories, χ² = {:.3} ≤ \
             χ²_0.95(9) = {:.3}",
            best.0.chi2,
            critical(9)
        ),
    ] {
        assert!(e.reason.contains(&said), "{said:?} not in {:?}", e.reason);
    }
    let search = kc.search.as_ref().unwrap();
    assert_eq!(search.steps.last().unwrap().best, ["A", "B", "C", "D"]);
    let vector = kc.vector.as_ref().unwrap();
    close(vector.chi2, best.0.chi2, 1e-12 * best.0.chi2, "χ² of A–D");
    for b in 0..3 {
        close(kc.reference[b], best.0.reference[b], 1e-12, "x_ref of A–D");
    }
    check_degrees(
        &kc,
        &data,
        &data.u,
        &best.0,
        &[true, true, true, true, false],
    );
    assert!(
        kc.verdict_statement()
            .contains("Consistent after leaving out E"),
        "{}",
        kc.verdict_statement()
    );
}

/// (e) A block only A reports is left out with a note naming it and A; a pilot's repeat
/// that lacks a compared block is refused; two nominal angles of one block are refused at
/// the second's file:line:column, read from CSV text.
#[test]
fn kc_blocks_left_out_and_refused() {
    let mut data = four_labs();
    data.x[1][2] = None;
    data.x[2][2] = None;
    data.x[3][2] = None;
    let kc = evaluate(&data.results(), &[], &blocks()).unwrap();
    assert_eq!(kc.index, [1, 2]);
    assert_eq!(kc.reference.len(), 2);
    assert_eq!(kc.vector_all.as_ref().unwrap().dof, 6);
    assert!(
        kc.notes.iter().any(
            |n| n.contains("reported by fewer than two laboratories left out")
                && n.contains("block 3 (by A only)")
        ),
        "{:#?}",
        kc.notes
    );
    assert!(kc.degrees_of_equivalence.iter().all(|d| d.d.len() == 2));

    // the pilot's repeats report every block compared
    let labs = four_labs().results();
    let full = [Some((12.3, 0.03)), Some((-4.1, 0.03)), Some((0.7, 0.03))];
    let short = [Some((12.3, 0.03)), None, Some((0.7, 0.03))];
    let pilot = [block_lab("start", &full), block_lab("end", &short)];
    match evaluate(&labs, &pilot, &blocks()) {
        Err(KcError::RepeatMissesBlock { repeat, block, .. }) => {
            assert_eq!((repeat.as_str(), block), ("end", 2));
        }
        other => panic!("expected RepeatMissesBlock, got {other:?}"),
    }

    // nominal angles: equal ones are the block's, two different ones refused
    let file = |source: &str, text: &str| {
        LabResult::from_file(source, read_results_from(text.as_bytes(), source).unwrap())
    };
    let a = "quantity,index,value,u,nominal_deg\n\
             angle_block,1,0.10,0.05,15\n\
             angle_block,2,-0.20,0.05,30\n";
    let b_same = "quantity,index,value,u,nominal_deg\n\
                  angle_block,1,0.12,0.05,15\n\
                  angle_block,2,-0.18,0.05,30.0000000001\n";
    let c_none = "quantity,index,value,u\nangle_block,1,0.11,0.05\nangle_block,2,-0.21,0.05\n";
    let agreed = evaluate(
        &[
            file("a.csv", a),
            file("b.csv", b_same),
            file("c.csv", c_none),
        ],
        &[],
        &blocks(),
    )
    .unwrap();
    assert_eq!(agreed.nominal_deg, Some(vec![Some(15.0), Some(30.0)]));
    let b_other = "quantity,index,value,u,nominal_deg\n\
                   angle_block,1,0.12,0.05,15\n\
                   angle_block,2,-0.18,0.05,30.5\n";
    match evaluate(&[file("a.csv", a), file("b.csv", b_other)], &[], &blocks()) {
        Err(e @ KcError::NominalsDiffer { .. }) => {
            let message = e.to_string();
            // line 3, the nominal_deg field of each (column 26)
            assert!(
                message.starts_with(
                    "b.csv:3:26: angle_block 2 has nominal_deg 30.5, but 30 at a.csv:3:26"
                ),
                "{message}"
            );
        }
        other => panic!("expected NominalsDiffer, got {other:?}"),
    }
}

/// The pilot's repeats of blocks: their joint χ² about each block's weighted mean,
/// ν = 3·(3 − 1); when it fails, u_stab,b = the repeats' sample standard deviation on each
/// block, in every laboratory's u (the reference, every U) and in the repeats' U (out of
/// the reference).
#[test]
fn kc_blocks_pilot_repeats_that_disagree_widen_every_u() {
    let mut data = four_labs();
    data.x[3][0] = None;
    let repeats = Data::new(&[
        ("P1", [Some(12.30), Some(-4.10), Some(0.70)], [0.02; 3]),
        ("P2", [Some(12.38), Some(-4.14), Some(0.64)], [0.02; 3]),
        ("P3", [Some(12.25), Some(-4.03), Some(0.73)], [0.02; 3]),
    ]);
    let kc = evaluate(&data.results(), &repeats.results(), &blocks()).unwrap();
    let pilot = kc.pilot.as_ref().unwrap();
    let repeats_fit = block_fit(&repeats.x, &repeats.u, &[0, 1, 2]);
    let test = pilot.vector.as_ref().unwrap();
    assert_eq!(test.dof, 6);
    close(
        test.chi2,
        repeats_fit.chi2,
        1e-12 * repeats_fit.chi2,
        "the repeats' χ²",
    );
    assert!(
        repeats_fit.chi2 > critical(6),
        "as designed, the repeats disagree"
    );
    assert!(!test.consistent);
    let spread: Vec<f64> = (0..3)
        .map(|b| {
            let y: Vec<f64> = (0..3).map(|r| repeats.x[r][b].unwrap()).collect();
            let mean = y.iter().sum::<f64>() / 3.0;
            (y.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / 2.0).sqrt()
        })
        .collect();
    for b in 0..3 {
        close(pilot.stability_u[b], spread[b], 1e-12, "u_stab");
    }
    let v_u = data.widened(&spread);
    let hand = block_fit(&data.x, &v_u, &[0, 1, 2, 3]);
    for b in 0..3 {
        close(kc.reference[b], hand.reference[b], 1e-12, "x_ref");
        close(kc.reference_u[b], hand.reference_u[b], 1e-12, "u_ref");
    }
    check_degrees(&kc, &data, &v_u, &hand, &[true; 4]);
    close(
        kc.vector_all.as_ref().unwrap().chi2,
        hand.chi2,
        1e-12 * hand.chi2,
        "joint χ² with u_stab",
    );
    for (r, doe) in pilot.degrees_of_equivalence.iter().enumerate() {
        assert!(!doe.in_reference);
        for b in 0..3 {
            let y = repeats.x[r][b].unwrap();
            let v = repeats.u[r][b].powi(2) + spread[b].powi(2) + hand.reference_u[b].powi(2);
            close(doe.d[b], y - hand.reference[b], 1e-12, "a repeat's d");
            close(doe.expanded_u[b], 2.0 * v.sqrt(), 1e-12, "a repeat's U");
        }
    }
}

/// A search whose subsets of one size have different ν (angle blocks a laboratory does not
/// report): D reports block 1 only, 4.24u off there; C is √7·u off on blocks 2–4. Of the
/// subsets of three, A, B, D has the smallest χ² (12.0 with ν = 5: fails, χ²_0.95(5) =
/// 11.07) and A, B, C passes (14.0 with ν = 8, χ²_0.95(8) = 15.51); A, C, D and B, C, D
/// have 22.5 with ν = 5. D is left out, and the search's step, the exclusion's reason and
/// the verdict state the subset that passed, A, B, C, with its χ².
#[test]
fn kc_blocks_the_search_states_the_subset_it_chose_when_the_sizes_nu_differ() {
    let u = 0.1;
    let c = 7f64.sqrt() * u;
    let d = 18f64.sqrt() * u;
    let data = Data {
        names: vec!["A", "B", "C", "D"],
        x: vec![
            vec![Some(0.0); 4],
            vec![Some(0.0); 4],
            vec![Some(0.0), Some(c), Some(c), Some(c)],
            vec![Some(d), None, None, None],
        ],
        u: vec![vec![u; 4]; 4],
    };
    let kc = evaluate(&data.results(), &[], &blocks()).unwrap();
    let subset = |set: &[usize]| block_fit(&data.x, &data.u, set);
    let (abd, abc) = (subset(&[0, 1, 3]), subset(&[0, 1, 2]));
    assert_eq!((abd.dof, abc.dof), (5, 8));
    close(abd.chi2, 12.0, 1e-9, "χ² A, B, D");
    close(abc.chi2, 14.0, 1e-9, "χ² A, B, C");
    assert!(abd.chi2 > critical(5) && abc.chi2 <= critical(8));
    assert!(subset(&[0, 2, 3]).chi2 > critical(5) && subset(&[1, 2, 3]).chi2 > critical(5));
    assert!(!kc.vector_all.as_ref().unwrap().consistent);
    // the decision is right
    let out: Vec<&str> = kc.excluded.iter().map(|e| e.lab.as_str()).collect();
    assert_eq!(out, ["D"]);
    assert!(kc.comparison_consistent);
    // and so must be what is said of it
    let step = kc.search.as_ref().unwrap().steps.last().unwrap().clone();
    let said = format!(
        "the largest subset that passes is A, B, C (3 laboratories, χ² = 14.000 ≤ \
         χ²_0.95(8) = {:.3}",
        critical(8)
    );
    assert!(
        kc.excluded[0].reason.contains(&said),
        "{}",
        kc.excluded[0].reason
    );
    assert!(
        kc.verdict_statement()
            .contains("the largest subset that passes is A, B, C (χ² = 14.00 ≤"),
        "{}",
        kc.verdict_statement()
    );
    assert_eq!(step.best, ["A", "B", "C"], "{step:?}");
    assert!(step.consistent && step.dof == 8);
}

/// D reports only block 7, which nobody else reports: block 7 is left out, and D then has
/// no block compared at all. Such a laboratory is refused (as a result without angle_block
/// rows is), naming it, not counted among "all 4 laboratories" whose joint χ² passes.
#[test]
fn kc_blocks_a_laboratory_with_no_block_compared_is_not_counted_silently() {
    let mut data = four_labs();
    data.x[3] = vec![None, None, None];
    let mut labs = data.results();
    labs[3] = block_lab(
        "D",
        &[None, None, None, None, None, None, Some((0.36, 0.07))],
    );
    match evaluate(&labs, &[], &blocks()) {
        Err(
            e @ KcError::LabNotCompared {
                compared: 0,
                needed: 1,
                ..
            },
        ) => {
            let message = e.to_string();
            assert!(
                message.starts_with("D (laboratory D): 0 of its"),
                "{message}"
            );
        }
        other => panic!("expected LabNotCompared for D, got {other:?}"),
    }
}
