//! Linking comparisons whose laboratories report different encoder positions
//! (docs/FORMAT.md §12, "Linking"), against a dense implementation written here from the
//! model — not the library's Schur-complement solution: every offset y_jk = Δ_k + γ_j + e
//! stacked, the GLS with the closure Σ Δ = 0 by a bordered (N + L + 1)² system, Cov(Δ) as
//! G·Cov(y)·Gᵀ with Cov(y) built from both comparisons' closed vectors (each laboratory's
//! opened positions z with covariance s_j s_l Cov(d_j, d_l) at each position, closed
//! again over the positions it reports), and every d_i + P_iΔ with its u from the same
//! covariances, nothing taken from the library but the two comparisons' degrees of
//! equivalence.

use nalgebra::{DMatrix, DVector};
use polycal::kc::{DegreeOfEquivalence, KcOptions, KeyComparison, evaluate, link};
use polycal::results::Quantity;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::kc_support::encoder::{Design, draw};

/// The stated covariance of d_a and d_b of `kc` at position `k` (docs/FORMAT.md §12,
/// "Linking"): u²(d) for one laboratory, ∓u_ref² for two in / out of the reference, 0
/// across.
fn stated(kc: &KeyComparison, a: &DegreeOfEquivalence, b: &DegreeOfEquivalence, k: usize) -> f64 {
    if a.lab == b.lab {
        let factor = a.k.as_ref().map_or(2.0, |f| f[k]);
        return (a.expanded_u[k] / factor).powi(2);
    }
    let u_ref2 = kc.reference_u[k].powi(2);
    match (a.in_reference, b.in_reference) {
        (true, true) => -u_ref2,
        (false, false) => u_ref2,
        _ => 0.0,
    }
}

/// The positions `d` reports.
fn own(d: &DegreeOfEquivalence) -> Vec<usize> {
    (0..d.d.len()).filter(|&k| d.d[k].is_finite()).collect()
}

/// √(n/(n − 1)) over the n positions `d` reports.
fn opening(d: &DegreeOfEquivalence) -> f64 {
    let n = own(d).len() as f64;
    (n / (n - 1.0)).sqrt()
}

fn doe<'a>(kc: &'a KeyComparison, name: &str) -> &'a DegreeOfEquivalence {
    kc.degrees_of_equivalence
        .iter()
        .find(|d| d.lab == name)
        .unwrap()
}

/// The dense link: Δ, u(Δ), χ², ν and every laboratory's (d_linked, U_linked) of `this`.
struct Dense {
    correction: Vec<f64>,
    correction_u: Vec<f64>,
    chi2: f64,
    dof: usize,
    linked: Vec<(Vec<f64>, Vec<f64>)>,
}

/// The opened positions of the linking laboratories in `kc`: (lab, position) pairs and the
/// matrix taking them to the laboratories' closed degrees of equivalence, row per
/// observation `obs`, with `sign`.
fn closing(
    kc: &KeyComparison,
    labs: &[&str],
    obs: &[(usize, usize)],
    sign: f64,
) -> (Vec<(usize, usize)>, DMatrix<f64>) {
    let z: Vec<(usize, usize)> = labs
        .iter()
        .enumerate()
        .flat_map(|(j, name)| own(doe(kc, name)).into_iter().map(move |p| (j, p)))
        .collect();
    let a = DMatrix::from_fn(obs.len(), z.len(), |r, c| {
        let ((j, k), (jz, p)) = (obs[r], z[c]);
        if j != jz {
            return 0.0;
        }
        let n = own(doe(kc, labs[j])).len() as f64;
        sign * (f64::from(u8::from(k == p)) - 1.0 / n)
    });
    (z, a)
}

/// The opened covariance of `kc`'s laboratories `a` at `za` and `b` at `zb`.
fn opened(
    kc: &KeyComparison,
    a: &DegreeOfEquivalence,
    za: &[usize],
    b: &DegreeOfEquivalence,
    zb: &[usize],
) -> DMatrix<f64> {
    DMatrix::from_fn(za.len(), zb.len(), |r, c| {
        if za[r] != zb[c] {
            return 0.0;
        }
        stated(kc, a, b, za[r]) * opening(a) * opening(b)
    })
}

fn dense(this: &KeyComparison, linked: &KeyComparison, labs: &[&str]) -> Dense {
    let n = this.index.len();
    let l = labs.len();
    let obs: Vec<(usize, usize)> = labs
        .iter()
        .enumerate()
        .flat_map(|(j, name)| {
            let (h, t) = (doe(this, name), doe(linked, name));
            (0..n)
                .filter(move |&k| h.d[k].is_finite() && t.d[k].is_finite())
                .map(move |k| (j, k))
        })
        .collect();
    let m = obs.len();
    let y = DVector::from_fn(m, |r, _| {
        let (j, k) = obs[r];
        doe(linked, labs[j]).d[k] - doe(this, labs[j]).d[k]
    });
    // the GLS weight: the opened covariance at each position, both comparisons
    let sigma = DMatrix::from_fn(m, m, |r, c| {
        let ((j, k), (q, p)) = (obs[r], obs[c]);
        if k != p {
            return 0.0;
        }
        let part = |kc: &KeyComparison| {
            let (a, b) = (doe(kc, labs[j]), doe(kc, labs[q]));
            stated(kc, a, b, k) * opening(a) * opening(b)
        };
        part(this) + part(linked)
    });
    let w = sigma.clone().try_inverse().unwrap();
    let x = DMatrix::from_fn(m, n + l, |r, c| {
        let (j, k) = obs[r];
        f64::from(u8::from(c == k || c == n + j))
    });
    let mut bordered = DMatrix::zeros(n + l + 1, n + l + 1);
    bordered
        .view_mut((0, 0), (n + l, n + l))
        .copy_from(&(x.transpose() * &w * &x));
    for k in 0..n {
        bordered[(k, n + l)] = 1.0;
        bordered[(n + l, k)] = 1.0;
    }
    let inverse = bordered.try_inverse().unwrap();
    let t = inverse.view((0, 0), (n + l, n + l)).into_owned();
    let g_all = &t * x.transpose() * &w;
    let theta = &g_all * &y;
    let residual = &y - &x * &theta;
    let chi2 = residual.dot(&(&w * &residual));
    let g = g_all.rows(0, n).into_owned();
    // Cov(y) from both comparisons' closed vectors
    let (z_this, a_this) = closing(this, labs, &obs, -1.0);
    let (z_linked, a_linked) = closing(linked, labs, &obs, 1.0);
    let z_cov = |kc: &KeyComparison, z: &[(usize, usize)]| {
        DMatrix::from_fn(z.len(), z.len(), |r, c| {
            let ((j, p), (q, s)) = (z[r], z[c]);
            opened(kc, doe(kc, labs[j]), &[p], doe(kc, labs[q]), &[s])[(0, 0)]
        })
    };
    let cov_y = &a_this * z_cov(this, &z_this) * a_this.transpose()
        + &a_linked * z_cov(linked, &z_linked) * a_linked.transpose();
    let cov_delta = &g * &cov_y * g.transpose();
    let delta: Vec<f64> = (0..n).map(|k| theta[k]).collect();
    let linked_does = every_degree(this)
        .map(|d| {
            let s = own(d);
            let ni = s.len() as f64;
            let p = DMatrix::from_fn(s.len(), n, |r, c| {
                f64::from(u8::from(s[r] == c)) - if s.contains(&c) { 1.0 / ni } else { 0.0 }
            });
            // Cov(d_i, y) = P_i·Cov(z_i, z_this)·A_thisᵀ (d_i closed over its own positions)
            let z_own_cov = DMatrix::from_fn(n, z_this.len(), |r, c| {
                let (j, q) = z_this[c];
                if r != q || !d.d[r].is_finite() {
                    return 0.0;
                }
                opened(this, d, &[r], doe(this, labs[j]), &[q])[(0, 0)]
            });
            let cov_d_y = &p * z_own_cov * a_this.transpose();
            let var_p = &p * &cov_delta * p.transpose();
            let cross = &cov_d_y * g.transpose() * p.transpose();
            let p_delta = &p * DVector::from_column_slice(&delta);
            let mut value = vec![f64::NAN; n];
            let mut expanded = vec![f64::NAN; n];
            for (r, &k) in s.iter().enumerate() {
                let u = stated(this, d, d, k);
                value[k] = d.d[k] + p_delta[r];
                expanded[k] = 2.0 * (u + var_p[(r, r)] + 2.0 * cross[(r, r)]).sqrt();
            }
            (value, expanded)
        })
        .collect();
    Dense {
        correction: delta,
        correction_u: (0..n).map(|k| cov_delta[(k, k)].sqrt()).collect(),
        chi2,
        dof: m - (n + l - 1),
        linked: linked_does,
    }
}

/// Every degree of equivalence of `kc`, the pilot's repeats' after the laboratories'.
fn every_degree(kc: &KeyComparison) -> impl Iterator<Item = &DegreeOfEquivalence> {
    kc.degrees_of_equivalence
        .iter()
        .chain(kc.pilot.iter().flat_map(|p| &p.degrees_of_equivalence))
}

fn encoder() -> KcOptions {
    KcOptions::new()
        .with_quantity(Quantity::EncoderError)
        .with_largest_consistent_subset(false)
}

/// A CIPM comparison of 8 laboratories and an RMO one of 6 (L1, L4, L6 in both), 12
/// positions: drawn with up to `missing` positions missed per laboratory and u per
/// position (`equal_u`: per laboratory); with `missing` > 0 the RMO comparison has the
/// pilot's two repeats too.
fn pair(rng: &mut ChaCha8Rng, missing: usize, equal_u: bool) -> (KeyComparison, KeyComparison) {
    let design = |labs| Design {
        positions: 12,
        labs,
        missing: 0.0,
        missing_count: Some(missing),
        u_range: (0.05, 0.2),
        equal_u,
        closed_noise: true,
    };
    let cipm = draw(rng, design(8), None);
    let mut rmo = draw(rng, design(6), None);
    rmo.names = ["L1", "L4", "L6", "R1", "R2", "R3"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    // the pilot's repeats, at every position
    let mut repeats = draw(
        rng,
        Design {
            missing_count: Some(0),
            ..design(2)
        },
        None,
    );
    repeats.names = vec!["start".into(), "end".into()];
    // (with gaps only: their stability term varies u from position to position)
    let repeats = if missing > 0 {
        repeats.results()
    } else {
        Vec::new()
    };
    (
        evaluate(&rmo.results(), &repeats, &encoder()).unwrap(),
        evaluate(&cipm.results(), &[], &encoder()).unwrap(),
    )
}

fn close(a: f64, b: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-9 * (1.0 + b.abs()) || (a.is_nan() && b.is_nan()),
        "{what}: {a} against {b}"
    );
}

fn agree(this: &KeyComparison, dense: &Dense) {
    let link = this.link.as_ref().unwrap();
    for k in 0..this.index.len() {
        close(link.correction[k], dense.correction[k], "Δ");
        close(link.correction_u[k], dense.correction_u[k], "u(Δ)");
    }
    match &link.vector {
        Some(v) => {
            close(v.chi2, dense.chi2, "χ²");
            assert_eq!(v.dof, dense.dof);
        }
        None => assert_eq!(dense.dof, 0),
    }
    assert_eq!(every_degree(this).count(), dense.linked.len());
    for (d, (value, expanded)) in every_degree(this).zip(&dense.linked) {
        let (d_linked, u_linked) = (
            d.d_linked.as_ref().unwrap(),
            d.expanded_u_linked.as_ref().unwrap(),
        );
        for k in 0..value.len() {
            close(d_linked[k], value[k], &format!("{} d_linked at {k}", d.lab));
            close(
                u_linked[k],
                expanded[k],
                &format!("{} U_linked at {k}", d.lab),
            );
        }
    }
}

/// Laboratories missing up to 3 of 12 positions in either comparison, linking ones among
/// them: Δ, u(Δ), the link's χ² and ν, and every d_linked and U_linked (the pilot's two
/// repeats' too) equal the dense
/// implementation's to 1e-9 on the drawn pairs of comparisons that can be linked (27 of 30;
/// the others have a position no linking laboratory reports in both, and are refused);
/// every d_linked is closed over its laboratory's own positions.
#[test]
fn kc_link_over_different_positions_equals_a_dense_implementation() {
    let mut rng = ChaCha8Rng::seed_from_u64(5505);
    let (mut linked_count, mut gapped_links) = (0, 0);
    for _ in 0..30 {
        let (mut rmo, cipm) = pair(&mut rng, 3, false);
        let labs = ["L1", "L4", "L6"];
        if let Err(e) = link(&mut rmo, &cipm) {
            // a position that no linking laboratory reports in both: its Δ is not
            // determined (only differences within each laboratory's positions are seen)
            let message = e.to_string();
            assert!(
                message.contains("no linking laboratory reports")
                    && message.contains("in both comparisons: the offset there cannot be found"),
                "{message}"
            );
            continue;
        }
        linked_count += 1;
        gapped_links += usize::from(labs.iter().any(|name| {
            doe(&rmo, name).d.iter().any(|x| x.is_nan())
                || doe(&cipm, name).d.iter().any(|x| x.is_nan())
        }));
        assert_eq!(rmo.pilot.as_ref().unwrap().degrees_of_equivalence.len(), 2);
        agree(&rmo, &dense(&rmo, &cipm, &labs));
        for d in every_degree(&rmo) {
            let sum: f64 = d
                .d_linked
                .as_ref()
                .unwrap()
                .iter()
                .filter(|x| x.is_finite())
                .sum();
            assert!(sum.abs() < 1e-9, "{}: Σ d_linked = {sum}", d.lab);
        }
    }
    assert!(linked_count >= 25, "{linked_count}");
    assert!(gapped_links >= 20, "{gapped_links}");
}

/// Every laboratory reporting every position with one u: the library takes its
/// per-position path ((N − 1)/N · Σ_k χ²_k), and the dense model over positions gives the
/// same Δ, u(Δ), χ², ν and linked degrees of equivalence to 1e-9 — the model over
/// positions is the closed vectors' link where they report the same positions.
#[test]
fn kc_link_over_positions_is_the_closed_link_when_every_position_is_reported() {
    let mut rng = ChaCha8Rng::seed_from_u64(5506);
    for _ in 0..10 {
        let (mut rmo, cipm) = pair(&mut rng, 0, true);
        link(&mut rmo, &cipm).unwrap();
        agree(&rmo, &dense(&rmo, &cipm, &["L1", "L4", "L6"]));
    }
}
