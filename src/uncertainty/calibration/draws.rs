//! How the errors of a budget are drawn in a Monte Carlo trial of a calibration: once
//! per group of readings that shares a draw ([`Plan`], [`Spread`]), two rectangular
//! errors of each reading as one trapezoid ([`Trapezoids`], [`pair_rectangles`]), and the
//! draws of a distribution in bulk ([`draw_into`]).

use rand::Rng;

use crate::uncertainty::distribution::{Sampler, standard_normals, uniforms};

/// A component drawn once per group and added, weighted, to the group's targets.
pub(super) struct Plan {
    pub(super) sampler: Sampler,
    pub(super) spread: Spread,
}

/// Where the draws of a [`Plan`] land: per group the targets and their weights
/// (sensitivity included).
pub(super) enum Spread {
    /// Every group lands on one target (an error of each reading): (target, weight).
    Single(Vec<(usize, f64)>),
    /// Groups of several targets: `groups` draws, each entry (target, weight, group).
    Groups {
        groups: usize,
        entries: Vec<(usize, f64, usize)>,
    },
    /// Groups of several targets, every target in one group at most: per target its
    /// weight (0 if in none) and group.
    Dense {
        groups: usize,
        weights: Vec<f64>,
        group_of: Vec<usize>,
    },
}

impl Spread {
    pub(super) fn groups(&self) -> usize {
        match self {
            Spread::Single(targets) => targets.len(),
            Spread::Groups { groups, .. } | Spread::Dense { groups, .. } => *groups,
        }
    }

    /// The targets and weights of group `g`.
    pub(super) fn group(&self, g: usize) -> Vec<(usize, f64)> {
        match self {
            Spread::Single(targets) => vec![targets[g]],
            Spread::Groups { entries, .. } => entries
                .iter()
                .filter(|e| e.2 == g)
                .map(|&(t, w, _)| (t, w))
                .collect(),
            Spread::Dense {
                weights, group_of, ..
            } => (0..weights.len())
                .filter(|&t| group_of[t] == g && weights[t] != 0.0)
                .map(|t| (t, weights[t]))
                .collect(),
        }
    }

    /// The same spread, per target when every target is in one group at most.
    pub(super) fn densified(self, targets: usize) -> Spread {
        let Spread::Groups { groups, entries } = self else {
            return self;
        };
        let mut seen = vec![false; targets];
        if entries
            .iter()
            .any(|&(t, _, _)| std::mem::replace(&mut seen[t], true))
        {
            return Spread::Groups { groups, entries };
        }
        let mut weights = vec![0.0; targets];
        let mut group_of = vec![0; targets];
        for (t, w, g) in entries {
            weights[t] = w;
            group_of[t] = g;
        }
        Spread::Dense {
            groups,
            weights,
            group_of,
        }
    }
}

/// Sums of two independent rectangular errors, `U(−c₁, c₁) + U(−c₂, c₂)` each: symmetric
/// trapezoids, drawn from one uniform number each by the inverse distribution function.
/// With `a = max(c₁, c₂)`, `b = min(c₁, c₂)`: `F(x) = (x + a + b)²/(8ab)` up to
/// `x = −(a − b)`, where `F = b/(2a)`, then `F(x) = (x + a)/(2a)` on the flat top, and
/// symmetric above. Two rectangular errors of every reading (resolution, angle error)
/// thus cost one draw instead of two, and the draws have the same distribution.
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct Trapezoids {
    /// Per trapezoid: the half width `a` of the wider rectangle, `b/(2a)` (the
    /// probability of each sloped side, 0 for `a = 0`), `√(8ab)` and `a + b`.
    a: Vec<f64>,
    side: Vec<f64>,
    root: Vec<f64>,
    reach: Vec<f64>,
}

impl Trapezoids {
    fn push(&mut self, c1: f64, c2: f64) {
        let (a, b) = (c1.abs().max(c2.abs()), c1.abs().min(c2.abs()));
        self.a.push(a);
        self.side.push(if a > 0.0 { b / (2.0 * a) } else { 0.0 });
        self.root.push((8.0 * a * b).sqrt());
        self.reach.push(a + b);
    }

    pub(super) fn len(&self) -> usize {
        self.a.len()
    }

    /// The trapezoids in the order `order` (indices into these).
    pub(super) fn permuted(&self, order: &[usize]) -> Trapezoids {
        let pick = |v: &[f64]| order.iter().map(|&k| v[k]).collect();
        Trapezoids {
            a: pick(&self.a),
            side: pick(&self.side),
            root: pick(&self.root),
            reach: pick(&self.reach),
        }
    }

    /// `q[k] = F⁻¹(u[k])` for `u[k]` ∈ [0, 1): eight values at a time on the flat tops
    /// (in the vector units), then, only in the few chunks of eight where some value is
    /// on a sloped side (for the instrument budget's resolution and angle error, 0.4 %
    /// of the values), those values.
    #[inline]
    pub(super) fn quantiles(&self, u: &[f64], q: &mut [f64]) {
        const CHUNK: usize = 8;
        let n = self.len();
        let (u, q) = (&u[..n], &mut q[..n]);
        let chunks = q
            .chunks_mut(CHUNK)
            .zip(u.chunks(CHUNK))
            .zip(self.a.chunks(CHUNK).zip(self.side.chunks(CHUNK)));
        for (c, ((q, u), (a, side))) in chunks.enumerate() {
            let mut sloped = false;
            if let (Ok(q), Ok(u), Ok(a), Ok(side)) = (
                <&mut [f64; CHUNK]>::try_from(&mut *q),
                <&[f64; CHUNK]>::try_from(u),
                <&[f64; CHUNK]>::try_from(a),
                <&[f64; CHUNK]>::try_from(side),
            ) {
                for k in 0..CHUNK {
                    q[k] = a[k] * (2.0 * u[k] - 1.0);
                    sloped |= (u[k] < side[k]) | (u[k] >= 1.0 - side[k]);
                }
            } else {
                for k in 0..q.len() {
                    q[k] = a[k] * (2.0 * u[k] - 1.0);
                    sloped |= (u[k] < side[k]) | (u[k] >= 1.0 - side[k]);
                }
            }
            if sloped {
                for k in 0..q.len() {
                    if (u[k] < side[k]) | (u[k] >= 1.0 - side[k]) {
                        q[k] = self.slope(c * CHUNK + k, u[k]);
                    }
                }
            }
        }
    }

    /// `F⁻¹(u)` of trapezoid `k` on its sloped sides.
    #[cold]
    fn slope(&self, k: usize, u: f64) -> f64 {
        if u < self.side[k] {
            self.root[k] * u.sqrt() - self.reach[k]
        } else {
            self.reach[k] - self.root[k] * (1.0 - u).sqrt()
        }
    }
}

/// Fills `buf` with draws of `sampler` — the formulas of `Sampler::sample` with the match
/// outside the loop and the 64-bit draws of the normal and the rectangular distributions
/// fetched in bulk into `bits` (at least as long as `buf`), which is what makes the
/// trials fast (a unit test checks that the draws have the sampler's distribution).
pub(super) fn draw_into<R: Rng + ?Sized>(
    sampler: &Sampler,
    rng: &mut R,
    bits: &mut [u64],
    buf: &mut [f64],
) {
    match *sampler {
        Sampler::Normal(u) => {
            standard_normals(rng, bits, buf);
            for x in buf {
                *x *= u;
            }
        }
        Sampler::Rectangular(a) => {
            uniforms(rng, bits, buf);
            for x in buf {
                *x = a * (2.0 * *x - 1.0);
            }
        }
        Sampler::Triangular(a) => {
            for x in buf {
                *x = a * (rng.random::<f64>() - rng.random::<f64>());
            }
        }
        Sampler::Arcsine(_) | Sampler::StudentT(..) => {
            for x in buf {
                *x = sampler.sample(rng);
            }
        }
    }
}

/// Pairs the rectangular plans whose groups are single targets, the same targets in the
/// same order (two errors of each reading), into one trapezoid per group; returns the
/// trapezoids, their targets and the other plans, in order.
pub(super) fn pair_rectangles(plans: Vec<Plan>) -> (Trapezoids, Vec<usize>, Vec<Plan>) {
    let mut trapezoids = Trapezoids::default();
    let mut targets_of = Vec::new();
    let mut rest = Vec::new();
    let mut waiting: Option<(Vec<(usize, f64)>, f64)> = None;
    for plan in plans {
        match (plan.sampler, &plan.spread) {
            (Sampler::Rectangular(half_width), Spread::Single(targets)) => match waiting.take() {
                Some((first, first_width))
                    if first.len() == targets.len()
                        && first.iter().zip(targets).all(|(x, y)| x.0 == y.0) =>
                {
                    for (x, y) in first.iter().zip(targets) {
                        trapezoids.push(x.1 * first_width, y.1 * half_width);
                        targets_of.push(x.0);
                    }
                }
                other => {
                    if let Some((targets, half_width)) = other {
                        rest.push(Plan {
                            sampler: Sampler::Rectangular(half_width),
                            spread: Spread::Single(targets),
                        });
                    }
                    let Spread::Single(targets) = plan.spread else {
                        unreachable!("matched above")
                    };
                    waiting = Some((targets, half_width));
                }
            },
            _ => rest.push(plan),
        }
    }
    if let Some((targets, half_width)) = waiting {
        rest.push(Plan {
            sampler: Sampler::Rectangular(half_width),
            spread: Spread::Single(targets),
        });
    }
    (trapezoids, targets_of, rest)
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::uncertainty::distribution::Distribution;

    /// The fast draws (in bulk) have the distribution of `Sampler::sample`: the
    /// two-sample Kolmogorov–Smirnov distance is within its 0.1 % critical value, and the
    /// standard deviation is the distribution's.
    #[test]
    fn draws_have_the_sampler_distribution() {
        let n = 100_000;
        for d in [
            Distribution::Normal { u: 0.3 },
            Distribution::Rectangular { half_width: 0.2 },
            Distribution::Triangular { half_width: 0.2 },
            Distribution::Arcsine { half_width: 0.2 },
            Distribution::StudentT {
                scale: 0.1,
                dof: 5.0,
            },
        ] {
            let sampler = d.sampler().unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(3);
            let mut fast = vec![0.0; n];
            let mut bits = [0; 50];
            for chunk in fast.chunks_mut(50) {
                draw_into(&sampler, &mut rng, &mut bits, chunk);
            }
            let mut slow: Vec<f64> = (0..n).map(|_| sampler.sample(&mut rng)).collect();
            let sd = (fast.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
            let expected = d.standard_deviation().unwrap();
            assert!(
                (sd / expected - 1.0).abs() < 0.02,
                "{d:?}: {sd} vs {expected}"
            );
            fast.sort_unstable_by(f64::total_cmp);
            slow.sort_unstable_by(f64::total_cmp);
            let (mut i, mut j, mut distance) = (0, 0, 0.0f64);
            while i < n && j < n {
                if fast[i] <= slow[j] {
                    i += 1;
                } else {
                    j += 1;
                }
                distance = distance.max((i as f64 - j as f64).abs() / n as f64);
            }
            assert!(
                distance < 1.95 * (2.0 / n as f64).sqrt(),
                "{d:?}: {distance}"
            );
        }
    }

    /// The trapezoid's inverse is the inverse of the convolution of the two rectangles:
    /// `F(x) = [H(x + c₁ + c₂) − H(x + c₁ − c₂)]/(4c₁c₂)` with `H` the antiderivative of
    /// `clamp(s, 0, 2c₁)`, written independently of `Trapezoids`.
    #[test]
    fn trapezoids_invert_the_convolution_of_two_rectangles() {
        for (c1, c2) in [(0.135, 0.0005), (0.0005, -0.135), (0.3, 0.2), (0.1, 0.1)] {
            let (a1, a2) = (f64::abs(c1), f64::abs(c2));
            let h = |s: f64| {
                if s < 0.0 {
                    0.0
                } else if s <= 2.0 * a1 {
                    0.5 * s * s
                } else {
                    2.0 * a1 * a1 + 2.0 * a1 * (s - 2.0 * a1)
                }
            };
            let cdf = |x: f64| (h(x + a1 + a2) - h(x + a1 - a2)) / (4.0 * a1 * a2);
            let mut trapezoids = Trapezoids::default();
            trapezoids.push(c1, c2);
            for i in 0..=10_000 {
                let u = (i as f64 / 10_000.0).min(1.0 - f64::EPSILON);
                let mut q = [0.0];
                trapezoids.quantiles(&[u], &mut q);
                assert!((cdf(q[0]) - u).abs() < 1e-12, "{c1} {c2} u {u}: {}", q[0]);
            }
        }
        // One rectangle of zero width: the other rectangle; both zero: 0.
        let mut trapezoids = Trapezoids::default();
        trapezoids.push(0.2, 0.0);
        trapezoids.push(0.0, 0.0);
        let mut q = [0.0; 2];
        trapezoids.quantiles(&[0.75, 0.75], &mut q);
        assert_eq!(q, [0.1, 0.0]);
    }
}
