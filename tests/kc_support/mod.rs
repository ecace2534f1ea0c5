//! An independent implementation of a key comparison's closed vector and of its decision
//! (docs/FORMAT.md §12), written here with dense matrices —
//! not the library's two-way additive fit — with the eigen-decomposition's pseudo-inverse,
//! and a generator of closed comparisons.
#![allow(dead_code, clippy::needless_range_loop)]

pub mod blocks;
pub mod encoder;

use nalgebra::{DMatrix, DVector};
use polycal::kc::LabResult;
use polycal::results::{Quantity, ResultRow};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// A laboratory's pitch deviations with U = 2u, k = 2.
pub fn lab(name: &str, values: &[f64], u: &[f64]) -> LabResult {
    let rows = values
        .iter()
        .zip(u)
        .enumerate()
        .map(|(f, (&x, &u))| {
            ResultRow::new(Quantity::PitchDeviation, f as u32 + 1, x)
                .with_expanded_u(2.0 * u)
                .with_k(2.0)
        })
        .collect();
    LabResult::from_rows(name, rows)
}

/// χ²_0.95(ν), from statrs directly.
pub fn critical(dof: usize) -> f64 {
    ChiSquared::new(dof as f64).unwrap().inverse_cdf(0.95)
}

/// The Moore–Penrose pseudo-inverse of a symmetric matrix by its eigen-decomposition
/// (eigenvalues below 1e-10 of the largest taken as zero).
pub fn pinv(a: &DMatrix<f64>) -> DMatrix<f64> {
    let eigen = a.clone().symmetric_eigen();
    let largest = eigen.eigenvalues.amax();
    let mut inverse = DMatrix::zeros(a.nrows(), a.ncols());
    for (k, &lambda) in eigen.eigenvalues.iter().enumerate() {
        if lambda.abs() > 1e-10 * largest {
            let v = eigen.eigenvectors.column(k);
            inverse += (v * v.transpose()) / lambda;
        }
    }
    inverse
}

/// V = N/(N−1)·P·diag(u²)·P, formed densely.
pub fn closed_cov(u: &[f64]) -> DMatrix<f64> {
    let n = u.len();
    let p = DMatrix::identity(n, n) - DMatrix::from_element(n, n, 1.0 / n as f64);
    let d = DMatrix::from_diagonal(&DVector::from_iterator(n, u.iter().map(|u| u * u)));
    (&p * d * &p) * (n as f64 / (n as f64 - 1.0))
}

/// The dense closed GLS of `x` (closed first) with covariances `v`: the reference, its
/// covariance and χ².
pub struct Gls {
    pub reference: DVector<f64>,
    pub covariance: DMatrix<f64>,
    pub chi2: f64,
    pub dof: usize,
}

pub fn gls(x: &[Vec<f64>], v: &[DMatrix<f64>]) -> Gls {
    let n = x[0].len();
    let p = DMatrix::identity(n, n) - DMatrix::from_element(n, n, 1.0 / n as f64);
    let plus: Vec<DMatrix<f64>> = v.iter().map(pinv).collect();
    let mut a = DMatrix::zeros(n, n);
    let mut b = DVector::zeros(n);
    let closed: Vec<DVector<f64>> = x
        .iter()
        .map(|x| &p * DVector::from_column_slice(x))
        .collect();
    for (xi, vp) in closed.iter().zip(&plus) {
        a += vp;
        b += vp * xi;
    }
    let covariance = pinv(&a);
    let reference = &covariance * b;
    let mut chi2 = 0.0;
    for (xi, vp) in closed.iter().zip(&plus) {
        let d = xi - &reference;
        chi2 += (d.transpose() * vp * &d)[(0, 0)];
    }
    Gls {
        reference,
        covariance,
        chi2,
        dof: (n - 1) * (x.len() - 1),
    }
}

/// The decision of docs/FORMAT.md §12 by brute force: the laboratories in the reference
/// (indices) — all when every laboratory passes; else the largest subset (holding `kept`)
/// that passes, ties by the smaller χ²; all when none does, and all when that subset
/// leaves out more than half of the laboratories.
pub fn largest_subset(x: &[Vec<f64>], u: &[Vec<f64>], kept: &[usize]) -> Vec<usize> {
    let labs = x.len();
    let test = |set: &[usize]| {
        let xs: Vec<Vec<f64>> = set.iter().map(|&r| x[r].clone()).collect();
        let vs: Vec<DMatrix<f64>> = set.iter().map(|&r| closed_cov(&u[r])).collect();
        let g = gls(&xs, &vs);
        (g.chi2, g.chi2 <= critical(g.dof))
    };
    let all: Vec<usize> = (0..labs).collect();
    if test(&all).1 {
        return all;
    }
    for size in (kept.len().max(2)..labs).rev() {
        let mut best: Option<(f64, Vec<usize>)> = None;
        for mask in 0u32..(1 << labs) {
            if mask.count_ones() as usize != size || kept.iter().any(|&k| mask & (1 << k) == 0) {
                continue;
            }
            let set: Vec<usize> = (0..labs).filter(|&r| mask & (1 << r) != 0).collect();
            let (chi2, passes) = test(&set);
            if passes && best.as_ref().is_none_or(|(b, _)| chi2 < *b) {
                best = Some((chi2, set));
            }
        }
        if let Some((_, set)) = best {
            return if 2 * (labs - set.len()) > labs {
                all
            } else {
                set
            };
        }
    }
    all
}

/// The one-at-a-time removal the issue measured: while the laboratories in fail, the one
/// whose removal lowers χ² most is left out.
pub fn one_at_a_time(x: &[Vec<f64>], u: &[Vec<f64>]) -> Vec<usize> {
    let chi2_of = |set: &[usize]| {
        let xs: Vec<Vec<f64>> = set.iter().map(|&r| x[r].clone()).collect();
        let vs: Vec<DMatrix<f64>> = set.iter().map(|&r| closed_cov(&u[r])).collect();
        let g = gls(&xs, &vs);
        (g.chi2, g.dof)
    };
    let mut set: Vec<usize> = (0..x.len()).collect();
    while set.len() > 2 {
        let (chi2, dof) = chi2_of(&set);
        if chi2 <= critical(dof) {
            break;
        }
        let worst = (0..set.len())
            .map(|i| {
                let rest: Vec<usize> = set.iter().copied().filter(|&r| r != set[i]).collect();
                (chi2_of(&rest).0, i)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap()
            .1;
        set.remove(worst);
    }
    set
}

/// A closed draw with marginal standard deviations `u`: e = √(N/(N−1))·P·(u ⊙ z), whose
/// covariance is N/(N−1)·P·diag(u²)·P.
pub fn closed_noise(rng: &mut ChaCha8Rng, u: &[f64]) -> Vec<f64> {
    let n = u.len() as f64;
    let scaled: Vec<f64> = u
        .iter()
        .map(|u| {
            let z: f64 = StandardNormal.sample(rng);
            u * z
        })
        .collect();
    let mean = scaled.iter().sum::<f64>() / n;
    scaled
        .iter()
        .map(|e| (n / (n - 1.0)).sqrt() * (e - mean))
        .collect()
}

/// A closed truth of `faces` pitch deviations.
pub fn truth(faces: usize) -> Vec<f64> {
    let raw: Vec<f64> = (0..faces).map(|f| (f as f64 * 1.3).sin() * 0.5).collect();
    let mean = raw.iter().sum::<f64>() / faces as f64;
    raw.iter().map(|b| b - mean).collect()
}

/// One consistent comparison: `labs` laboratories with u from 0.04″ to 0.2″ (the same on
/// every face), each result the truth plus closed noise; `bias` adds `(faces, amount in u)`
/// to laboratory `biased` before its result is closed again.
pub fn comparison(
    rng: &mut ChaCha8Rng,
    faces: usize,
    labs: usize,
    bias: Option<(usize, &[(usize, f64)])>,
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let truth = truth(faces);
    let mut values = Vec::new();
    let mut us = Vec::new();
    for i in 0..labs {
        let u_lab = 0.04 + 0.16 * i as f64 / (labs - 1) as f64;
        let u = vec![u_lab; faces];
        let noise = closed_noise(rng, &u);
        let mut x: Vec<f64> = truth.iter().zip(&noise).map(|(t, e)| t + e).collect();
        if let Some((biased, shifts)) = bias
            && biased == i
        {
            for &(face, amount) in shifts {
                x[face] += amount * u_lab;
            }
            let mean = x.iter().sum::<f64>() / faces as f64;
            x.iter_mut().for_each(|x| *x -= mean);
        }
        values.push(x);
        us.push(u);
    }
    (values, us)
}

/// The laboratories of a comparison as results named L0, L1, …
pub fn results(values: &[Vec<f64>], u: &[Vec<f64>]) -> Vec<LabResult> {
    values
        .iter()
        .zip(u)
        .enumerate()
        .map(|(i, (x, u))| lab(&format!("L{i}"), x, u))
        .collect()
}

/// A uniformly drawn number of laboratories in `range`.
pub fn labs_in(rng: &mut ChaCha8Rng, range: std::ops::RangeInclusive<usize>) -> usize {
    rng.random_range(range)
}
