//! Encoder errors compared on the positions each laboratory reports (docs/FORMAT.md §12,
//! "What each laboratory measured"), written out densely from the formulas — not the
//! library's two-way additive fit: each laboratory's closed vector over its own positions
//! S_i with V_i = N_i/(N_i − 1)·P_S·diag(u²)·P_S, the GLS reference
//! A = Σ_i M_iᵀ V_i⁺ M_i, x_ref = A⁺ Σ_i M_iᵀ V_i⁺ x_i, C = A⁺, its χ² with
//! ν = Σ_i N_i − n − (K − 1), the degrees of equivalence d_i = P_S(x_i − M_i x_ref) with
//! U = 2√diag(V_i ∓ P_S M_i C M_iᵀ P_S), each pair's closed vector over the positions both
//! report, and the search for the largest consistent subset by brute force; and a
//! generator of such comparisons with a known truth.

use nalgebra::{DMatrix, DVector};
use polycal::kc::LabResult;
use polycal::results::{Quantity, ResultRow};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::{critical, pinv};

/// Laboratories' encoder errors at K positions: `x[i][k]` lab i's raw value (its own zero,
/// `None` where it does not report position k) and `u[i][k]` its standard uncertainty,
/// arcsec.
#[derive(Debug, Clone)]
pub struct Encoder {
    pub names: Vec<String>,
    pub x: Vec<Vec<Option<f64>>>,
    pub u: Vec<Vec<f64>>,
}

/// The table angle of position `k` of `positions`, degrees.
pub fn angle_of(k: usize, positions: usize) -> f64 {
    360.0 * k as f64 / positions as f64
}

impl Encoder {
    /// The number of positions K.
    pub fn positions(&self) -> usize {
        self.x[0].len()
    }

    /// The positions laboratory `i` reports, ascending.
    pub fn reported(&self, i: usize) -> Vec<usize> {
        (0..self.positions())
            .filter(|&k| self.x[i][k].is_some())
            .collect()
    }

    /// Each laboratory's rows: `encoder_error` with u and the table angle, indexed 1, 2, …
    /// over the positions it reports (so that only the angle can match them).
    pub fn results(&self) -> Vec<LabResult> {
        let positions = self.positions();
        (0..self.names.len())
            .map(|i| {
                let rows = self
                    .reported(i)
                    .iter()
                    .enumerate()
                    .map(|(row, &k)| {
                        ResultRow::new(
                            Quantity::EncoderError,
                            row as u32 + 1,
                            self.x[i][k].unwrap(),
                        )
                        .with_u(self.u[i][k])
                        .with_angle_deg(angle_of(k, positions))
                    })
                    .collect();
                LabResult::from_rows(self.names[i].clone(), rows)
            })
            .collect()
    }

    /// Laboratory i's values over its own positions, less their mean there.
    pub fn closed(&self, i: usize) -> Vec<f64> {
        let s = self.reported(i);
        let mean = s.iter().map(|&k| self.x[i][k].unwrap()).sum::<f64>() / s.len() as f64;
        s.iter().map(|&k| self.x[i][k].unwrap() - mean).collect()
    }
}

/// P = I − J/n.
pub fn projector(n: usize) -> DMatrix<f64> {
    DMatrix::identity(n, n) - DMatrix::from_element(n, n, 1.0 / n as f64)
}

/// V = c·P·diag(u²)·P, c = n/(n − 1), over the n values of `u`.
pub fn closed_covariance(u: &[f64]) -> DMatrix<f64> {
    let n = u.len();
    let p = projector(n);
    let d = DMatrix::from_diagonal(&DVector::from_iterator(n, u.iter().map(|u| u * u)));
    (&p * d * &p) * (n as f64 / (n as f64 - 1.0))
}

/// The dense GLS of the laboratories `set` over the positions some of them report.
#[derive(Debug, Clone)]
pub struct SubsetFit {
    /// x_ref per position of the comparison (NaN where no laboratory of the set reports it).
    pub reference: Vec<f64>,
    /// C = A⁺ over the comparison's positions (NaN rows and columns where `reference` is).
    pub covariance: DMatrix<f64>,
    pub chi2: f64,
    pub dof: usize,
}

/// The dense GLS of the laboratories `set` of `data` (their u as in `data.u`); `None` when
/// A's null space is more than the constants (the laboratories of the set do not link every
/// position they report).
pub fn subset_gls(data: &Encoder, set: &[usize]) -> Option<SubsetFit> {
    let positions = data.positions();
    let fitted: Vec<usize> = (0..positions)
        .filter(|&k| set.iter().any(|&i| data.x[i][k].is_some()))
        .collect();
    let kk = fitted.len();
    let compact = |k: usize| fitted.iter().position(|&f| f == k).unwrap();
    let mut a = DMatrix::zeros(kk, kk);
    let mut b = DVector::zeros(kk);
    let mut pieces = Vec::new();
    for &i in set {
        let s: Vec<usize> = data.reported(i).into_iter().map(compact).collect();
        let u: Vec<f64> = data.reported(i).iter().map(|&k| data.u[i][k]).collect();
        let v_plus = pinv(&closed_covariance(&u));
        let x = DVector::from_vec(data.closed(i));
        // M_i: N_i × K′, row j picks position s[j]
        let m = DMatrix::from_fn(s.len(), kk, |j, k| if s[j] == k { 1.0 } else { 0.0 });
        a += m.transpose() * &v_plus * &m;
        b += m.transpose() * &v_plus * &x;
        pieces.push((m, v_plus, x));
    }
    let eigen = a.clone().symmetric_eigen();
    let largest = eigen.eigenvalues.amax();
    let null = eigen
        .eigenvalues
        .iter()
        .filter(|l| l.abs() <= 1e-10 * largest)
        .count();
    if null != 1 {
        return None;
    }
    let c = pinv(&a);
    let x_ref = &c * b;
    let mut chi2 = 0.0;
    let mut observations = 0;
    for (m, v_plus, x) in &pieces {
        let r = x - m * &x_ref;
        chi2 += (r.transpose() * v_plus * &r)[(0, 0)];
        observations += x.len();
    }
    let mut reference = vec![f64::NAN; positions];
    let mut covariance = DMatrix::from_element(positions, positions, f64::NAN);
    for (p, &k) in fitted.iter().enumerate() {
        reference[k] = x_ref[p];
        for (q, &l) in fitted.iter().enumerate() {
            covariance[(k, l)] = c[(p, q)];
        }
    }
    Some(SubsetFit {
        reference,
        covariance,
        chi2,
        dof: observations - set.len() - (kk - 1),
    })
}

/// Laboratory i's degree of equivalence against `fit`, per position of the comparison:
/// d = P_S(x_i − M_i x_ref) and U = 2√diag(V_i ∓ P_S M_i C M_iᵀ P_S), − when it is in the
/// reference (`inside`); NaN where it does not report a position. A position it reports
/// that the fit lacks (NaN there) is left out: S′ = S_i ∩ the fit's positions, d closed
/// over S′ and its own variance P_S′·V_i·P_S′ = c_i·P_S′·diag(u²)·P_S′ with c_i its own
/// N_i/(N_i − 1) (the covariance it states, propagated).
pub fn degree_of_equivalence(
    data: &Encoder,
    fit: &SubsetFit,
    i: usize,
    inside: bool,
) -> (Vec<f64>, Vec<f64>) {
    let positions = data.positions();
    let own = data.reported(i);
    let c_i = own.len() as f64 / (own.len() as f64 - 1.0);
    let closed_own = data.closed(i);
    let s: Vec<usize> = own
        .iter()
        .copied()
        .filter(|&k| fit.reference[k].is_finite())
        .collect();
    let n = s.len();
    let p = projector(n);
    let v =
        &p * DMatrix::from_diagonal(&DVector::from_iterator(
            n,
            s.iter().map(|&k| c_i * data.u[i][k].powi(2)),
        )) * &p;
    let x = DVector::from_iterator(
        n,
        s.iter()
            .map(|&k| closed_own[own.iter().position(|&q| q == k).unwrap()]),
    );
    let x_ref = DVector::from_iterator(n, s.iter().map(|&k| fit.reference[k]));
    let c = DMatrix::from_fn(n, n, |a, b| fit.covariance[(s[a], s[b])]);
    let d = &p * (x - x_ref);
    let sign = if inside { -1.0 } else { 1.0 };
    let variance = v + (&p * c * &p) * sign;
    let (mut d_all, mut u_all) = (vec![f64::NAN; positions], vec![f64::NAN; positions]);
    for (j, &k) in s.iter().enumerate() {
        d_all[k] = d[j];
        u_all[k] = 2.0 * variance[(j, j)].max(0.0).sqrt();
    }
    (d_all, u_all)
}

/// The covariance of the pair (a, b)'s difference closed over the M positions both report,
/// each result closed over its own N positions with V = N/(N − 1)·P·diag(u²)·P:
/// P_M·diag(c_a·u_a² + c_b·u_b²)·P_M, c = N/(N − 1) of each (the constants of each
/// closure taken out by P_M), and those positions.
pub fn pair_covariance(data: &Encoder, a: usize, b: usize) -> (DMatrix<f64>, Vec<usize>) {
    let positions = data.positions();
    let common: Vec<usize> = (0..positions)
        .filter(|&k| data.x[a][k].is_some() && data.x[b][k].is_some())
        .collect();
    let c = |i: usize| {
        let n = data.reported(i).len() as f64;
        n / (n - 1.0)
    };
    let (c_a, c_b) = (c(a), c(b));
    let m = common.len();
    let diagonal = DMatrix::from_diagonal(&DVector::from_iterator(
        m,
        common
            .iter()
            .map(|&k| c_a * data.u[a][k].powi(2) + c_b * data.u[b][k].powi(2)),
    ));
    let p = projector(m);
    (&p * diagonal * &p, common)
}

/// The pair (a, b) over the M positions both report: d = x_a − x_b there (each closed over
/// its own; the projector takes any constant out), χ² = dᵀ V⁺ d with V its closed
/// covariance ([`pair_covariance`]), ν = M − 1; and d closed over those positions (NaN
/// elsewhere). `None` below 2 common positions.
pub fn pair_test(data: &Encoder, a: usize, b: usize) -> Option<(f64, usize, Vec<f64>)> {
    let positions = data.positions();
    let common: Vec<usize> = (0..positions)
        .filter(|&k| data.x[a][k].is_some() && data.x[b][k].is_some())
        .collect();
    let m = common.len();
    if m < 2 {
        return None;
    }
    let (xa, xb) = (data.closed(a), data.closed(b));
    let (sa, sb) = (data.reported(a), data.reported(b));
    let at = |s: &[usize], x: &[f64], k: usize| x[s.iter().position(|&q| q == k).unwrap()];
    let d = DVector::from_iterator(m, common.iter().map(|&k| at(&sa, &xa, k) - at(&sb, &xb, k)));
    let (v, _) = pair_covariance(data, a, b);
    let v_plus = pinv(&v);
    let chi2 = (d.transpose() * v_plus * &d)[(0, 0)];
    let closed = projector(m) * d;
    let mut d_all = vec![f64::NAN; positions];
    for (j, &k) in common.iter().enumerate() {
        d_all[k] = closed[j];
    }
    Some((chi2, m - 1, d_all))
}

/// P(χ²_ν > χ²), 1 with ν = 0.
pub fn p_value(chi2: f64, dof: usize) -> f64 {
    if dof == 0 {
        return 1.0;
    }
    ChiSquared::new(dof as f64).unwrap().sf(chi2)
}

/// The decision of docs/FORMAT.md §12 by brute force over every subset, the dense GLS's χ²
/// each time: every laboratory when all pass; else the largest subset that passes, among
/// those of its size the most consistent (the smaller χ² at one ν, else the larger p-value,
/// then the smaller χ²); every laboratory when none passes or when that subset leaves out
/// more than half. Laboratories indexed 0 … n − 1, n ≤ 16.
pub fn largest_subset(data: &Encoder) -> Vec<usize> {
    let labs = data.names.len();
    let all: Vec<usize> = (0..labs).collect();
    let passes = |f: &SubsetFit| f.chi2 <= critical(f.dof);
    if subset_gls(data, &all).is_some_and(|f| passes(&f)) {
        return all;
    }
    let better = |f: &SubsetFit, b: &SubsetFit| {
        if f.dof == b.dof {
            return f.chi2 < b.chi2;
        }
        let (pf, pb) = (p_value(f.chi2, f.dof), p_value(b.chi2, b.dof));
        if pf != pb {
            return pf > pb;
        }
        f.chi2 < b.chi2
    };
    for size in (2..labs).rev() {
        let mut best: Option<(Vec<usize>, SubsetFit)> = None;
        for mask in 0u32..(1 << labs) {
            if mask.count_ones() as usize != size {
                continue;
            }
            let set: Vec<usize> = (0..labs).filter(|&r| mask & (1 << r) != 0).collect();
            // (no degree of freedom: no test, passed over)
            let Some(f) = subset_gls(data, &set).filter(|f| f.dof > 0) else {
                continue;
            };
            if passes(&f) && best.as_ref().is_none_or(|(_, b)| better(&f, b)) {
                best = Some((set, f));
            }
        }
        if let Some((set, _)) = best {
            return if 2 * (labs - set.len()) > labs {
                all
            } else {
                set
            };
        }
    }
    all
}

/// How a comparison is drawn.
#[derive(Debug, Clone, Copy)]
pub struct Design {
    /// K.
    pub positions: usize,
    /// The number of laboratories.
    pub labs: usize,
    /// Each laboratory misses each position with this probability (when `missing_count`
    /// is `None`).
    pub missing: f64,
    /// Else each laboratory misses a number of positions drawn in 0 ..= this.
    pub missing_count: Option<usize>,
    /// u drawn uniformly in this range per laboratory and position (`equal_u`: per
    /// laboratory), arcsec.
    pub u_range: (f64, f64),
    /// One u per laboratory on every position.
    pub equal_u: bool,
    /// Each laboratory's noise closed over its own N_i positions with covariance
    /// N_i/(N_i − 1)·P_S·diag(u²)·P_S — its u the u of its closed values, the model the
    /// comparison states — rather than N(0, u²) on each value independently.
    pub closed_noise: bool,
}

/// The true encoder error at position k of K: a smooth curve with Σ_k = 0, arcsec.
pub fn truth(k: usize, positions: usize) -> f64 {
    let t = std::f64::consts::TAU * k as f64 / positions as f64;
    0.8 * t.sin() - 0.3 * (2.0 * t).cos() + 0.15 * (3.0 * t + 0.4).sin()
}

/// A comparison drawn with `design`: each laboratory's zero a constant in ±5″, its values
/// the truth plus that constant plus its noise (N(0, u²) on each value, or closed over its
/// own positions: [`Design::closed_noise`]); each position reported by at least two
/// laboratories and each laboratory reporting at least 2 (the missing positions drawn
/// again until so). `bias`: (laboratory, positions, amount in its u) added to its values.
pub fn draw(rng: &mut ChaCha8Rng, design: Design, bias: Option<(usize, &[usize], f64)>) -> Encoder {
    let (k_count, n) = (design.positions, design.labs);
    let u: Vec<Vec<f64>> = (0..n)
        .map(|_| {
            let one = rng.random_range(design.u_range.0..=design.u_range.1);
            (0..k_count)
                .map(|_| {
                    if design.equal_u {
                        one
                    } else {
                        rng.random_range(design.u_range.0..=design.u_range.1)
                    }
                })
                .collect()
        })
        .collect();
    let reported = loop {
        let reported: Vec<Vec<bool>> = (0..n)
            .map(|_| match design.missing_count {
                Some(most) => {
                    let missing = rng.random_range(0..=most);
                    let mut row = vec![true; k_count];
                    let mut taken = 0;
                    while taken < missing {
                        let k = rng.random_range(0..k_count);
                        if row[k] {
                            row[k] = false;
                            taken += 1;
                        }
                    }
                    row
                }
                None => (0..k_count)
                    .map(|_| rng.random::<f64>() >= design.missing)
                    .collect(),
            })
            .collect();
        let per_position = (0..k_count).all(|k| reported.iter().filter(|r| r[k]).count() >= 2);
        let per_lab = reported
            .iter()
            .all(|r| r.iter().filter(|m| **m).count() >= 2);
        if per_position && per_lab {
            break reported;
        }
    };
    let x = (0..n)
        .map(|i| {
            let zero = rng.random_range(-5.0..=5.0);
            let mut noise: Vec<f64> = (0..k_count)
                .map(|k| {
                    let z: f64 = StandardNormal.sample(rng);
                    z * u[i][k]
                })
                .collect();
            if design.closed_noise {
                // √c·P_S(u ⊙ z) over the positions the laboratory reports
                let count = reported[i].iter().filter(|r| **r).count() as f64;
                let mean = (0..k_count)
                    .filter(|&k| reported[i][k])
                    .map(|k| noise[k])
                    .sum::<f64>()
                    / count;
                let c = (count / (count - 1.0)).sqrt();
                noise.iter_mut().for_each(|e| *e = c * (*e - mean));
            }
            (0..k_count)
                .map(|k| {
                    let mut value = truth(k, k_count) + zero + noise[k];
                    if let Some((lab, at, amount)) = bias
                        && lab == i
                        && at.contains(&k)
                    {
                        value += amount * u[i][k];
                    }
                    reported[i][k].then_some(value)
                })
                .collect()
        })
        .collect();
    Encoder {
        names: (0..n).map(|i| format!("L{i}")).collect(),
        x,
        u,
    }
}
