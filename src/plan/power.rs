//! The power of a diagnosis's F test: the noncentral F law of its statistic when an
//! effect is in the data, and its critical values.
//!
//! `diagnose` adds a term of r columns when its extra-sum-of-squares statistic
//! F = (Δ/r)/(RSS′/ν), ν the residual degrees of freedom with the term, exceeds the
//! critical value of its family: p·m < α, m the candidates of the family (Bonferroni).
//! With an effect of true size δ in the data, F follows the noncentral F distribution
//! F′(r, ν, λ) with noncentrality λ = δ²·‖x̃‖²/σ², x̃ the term's column projected off the
//! model's span (for a block, λ = δᵀ X̃ᵀX̃ δ/σ²). Its survival function is the Poisson
//! mixture of central F laws (Johnson, Kotz & Balakrishnan, *Continuous Univariate
//! Distributions*, vol. 2, ch. 30):
//!
//! ```text
//! P(F′ > f) = 1 − Σⱼ e^(−λ/2) (λ/2)ʲ/j! · I_x(r/2 + j, ν/2),   x = r·f/(r·f + ν)
//! ```
//!
//! with I the regularized incomplete beta function.

use statrs::function::beta::beta_reg;
use statrs::function::gamma::ln_gamma;

/// P(F′ > f) for the noncentral F distribution with `r` and `nu` degrees of freedom and
/// noncentrality `lambda` (≥ 0); `nu` = ∞ (`f64::INFINITY`) gives the noncentral χ²/r law.
pub fn noncentral_f_sf(f: f64, r: usize, nu: f64, lambda: f64) -> f64 {
    if f.is_nan() || f <= 0.0 {
        return 1.0;
    }
    let r = r.max(1) as f64;
    let half = 0.5 * lambda.max(0.0);
    // The Poisson weights that are not spent: those within 12√(λ/2) + 40 of their mean
    // (the rest weigh below 1e-30 together), so that a large λ costs O(√λ) terms, not λ.
    let (first, last) = if half > 0.0 {
        let spread = 12.0 * half.sqrt() + 40.0;
        (
            (half - spread).floor().max(0.0) as usize,
            (half + spread).ceil() as usize,
        )
    } else {
        (0, 0)
    };
    let mut log_weight = if half > 0.0 {
        -half + first as f64 * half.ln() - ln_gamma(first as f64 + 1.0)
    } else {
        0.0
    };
    let mut cdf = 0.0;
    for j in first..=last {
        if j > first {
            log_weight += half.ln() - (j as f64).ln();
        }
        let weight = log_weight.exp();
        let a = 0.5 * r + j as f64;
        let term = if nu.is_infinite() {
            // χ²_{r+2j} cdf at r·f: the regularized lower gamma P(a, r·f/2)
            statrs::function::gamma::gamma_lr(a, 0.5 * r * f)
        } else {
            beta_reg(a, 0.5 * nu, r * f / (r * f + nu))
        };
        cdf += weight * term;
    }
    // the weights sum to 1 up to the tails left out (below 1e-15 outside the window)
    (1.0 - cdf).clamp(0.0, 1.0)
}

/// The largest noncentrality [`noncentrality_for_power`] searches: a test that needs
/// more — an effect some thousand times the noise over the reach of its columns — is
/// said not to detect it with the design.
pub const MAX_NONCENTRALITY: f64 = 1e4;

/// The critical value f with P(F > f) = `alpha` under the central F(r, ν) law (ν may be
/// ∞); bisection on the survival function, to a relative 1e-12.
pub fn critical_f(alpha: f64, r: usize, nu: f64) -> f64 {
    let sf = |f: f64| noncentral_f_sf(f, r, nu, 0.0);
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    while sf(hi) > alpha && hi < 1e300 {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if sf(mid) > alpha {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The noncentrality λ at which the F test of `r` numerator and `nu` denominator degrees
/// of freedom at level `alpha` rejects with probability `power` (the test alone, with no
/// other candidate competing): bisection on λ, to a relative 1e-10. `None` when ν is not
/// positive, the levels are not probabilities, or λ would exceed [`MAX_NONCENTRALITY`]
/// (a design with few residual degrees of freedom and a small level: not detectable).
pub fn noncentrality_for_power(alpha: f64, power: f64, r: usize, nu: f64) -> Option<f64> {
    let probability = |p: f64| p > 0.0 && p < 1.0;
    if nu.is_nan() || nu <= 0.0 || !probability(alpha) || !probability(power) {
        return None;
    }
    let f = critical_f(alpha, r, nu);
    let reach = |lambda: f64| noncentral_f_sf(f, r, nu, lambda);
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    while reach(hi) < power {
        lo = hi;
        hi *= 2.0;
        if hi > MAX_NONCENTRALITY {
            return None;
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if reach(mid) < power {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-10 * hi {
            break;
        }
    }
    Some(0.5 * (lo + hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use statrs::distribution::{ContinuousCDF, FisherSnedecor, Normal};

    #[test]
    fn central_law_is_statrs_fisher_snedecor() {
        for (r, nu) in [(1, 5.0), (2, 30.0), (5, 12.0)] {
            let d = FisherSnedecor::new(r as f64, nu).unwrap();
            for f in [0.3, 1.0, 2.5, 7.0] {
                assert!((noncentral_f_sf(f, r, nu, 0.0) - d.sf(f)).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn one_column_with_known_variance_is_the_two_sided_normal_test() {
        // r = 1, ν = ∞: F = Z², Z ~ N(μ, 1) with λ = μ²
        let z = Normal::new(0.0, 1.0).unwrap();
        for mu in [0.0, 1.0, 2.5, 4.0] {
            for c in [1.0_f64, 1.96, 3.0] {
                let truth = z.sf(c - mu) + z.cdf(-c - mu);
                let got = noncentral_f_sf(c * c, 1, f64::INFINITY, mu * mu);
                assert!((got - truth).abs() < 1e-9, "μ {mu} c {c}: {got} vs {truth}");
            }
        }
        // the two-sided 5 % critical value of the normal test: z = 1.959964
        let c = critical_f(0.05, 1, f64::INFINITY);
        assert!((c.sqrt() - 1.959_963_985).abs() < 1e-8);
        // 90 % power at α = 0.05 for μ ≈ 1.959964 + 1.281552: P(Z > 1.959964 − μ) = 0.9,
        // plus the far tail P(Z < −1.959964 − μ) ≈ 1e-7, which moves μ by about 6e-7
        let mu: f64 = 1.959_963_985 + 1.281_551_566;
        let power = z.sf(c.sqrt() - mu) + z.cdf(-c.sqrt() - mu);
        assert!((power - 0.9).abs() < 2e-7, "{power}");
        assert!((noncentral_f_sf(c, 1, f64::INFINITY, mu * mu) - power).abs() < 1e-9);
        let lambda = noncentrality_for_power(0.05, 0.9, 1, f64::INFINITY).unwrap();
        assert!((lambda.sqrt() - mu).abs() < 2e-6);
    }

    #[test]
    fn noncentral_f_against_a_monte_carlo_of_its_definition() {
        // F′ = ((Z₁ + μ)² + Z₂²)/2 / (χ²₈/8), λ = μ², by a fixed-seed simulation
        use rand::{Rng, SeedableRng};
        use rand_distr::StandardNormal;
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (mu, trials, f) = (2.0_f64, 200_000, 3.0);
        let mut hits = 0;
        for _ in 0..trials {
            let mut n = || -> f64 { rng.sample(StandardNormal) };
            let num = ((n() + mu).powi(2) + n().powi(2)) / 2.0;
            let den: f64 = (0..8).map(|_| n().powi(2)).sum::<f64>() / 8.0;
            if num / den > f {
                hits += 1;
            }
        }
        let p = hits as f64 / trials as f64;
        let exact = noncentral_f_sf(f, 2, 8.0, mu * mu);
        // four standard errors of a proportion near 0.3 over 2·10⁵ trials: 0.004
        assert!((p - exact).abs() < 0.004, "{p} vs {exact}");
    }

    /// The window of Poisson weights against the whole sum from j = 0, written out here,
    /// where the whole sum is still cheap (λ up to 4000: the window starts at j > 0 from
    /// λ/2 ≈ 1300 on).
    #[test]
    fn the_window_of_weights_is_the_whole_sum() {
        let whole = |f: f64, r: usize, nu: f64, lambda: f64| {
            let half = 0.5 * lambda;
            let mut log_weight = -half;
            let mut cdf = 0.0;
            for j in 0..(half + 20.0 * half.sqrt() + 60.0) as usize {
                if j > 0 {
                    log_weight += half.ln() - (j as f64).ln();
                }
                let a = 0.5 * r as f64 + j as f64;
                cdf += log_weight.exp() * beta_reg(a, 0.5 * nu, r as f64 * f / (r as f64 * f + nu));
            }
            1.0 - cdf
        };
        for (f, r, nu, lambda) in [
            (3.0, 1, 2.0, 10.0),
            (50.0, 2, 3.0, 900.0),
            (400.0, 1, 1.0, 2700.0),
            (1500.0, 3, 2.0, 4000.0),
        ] {
            let (a, b) = (noncentral_f_sf(f, r, nu, lambda), whole(f, r, nu, lambda));
            assert!(
                (a - b).abs() < 1e-12,
                "f {f} r {r} ν {nu} λ {lambda}: {a} vs {b}"
            );
        }
    }

    /// A test with one or two residual degrees of freedom at a Bonferroni level of 1e-4
    /// needs a noncentrality beyond [`MAX_NONCENTRALITY`] (at ν = 2, λ ≈ 23 000, found by
    /// the bisection before the cap): not detectable. The search went on to 10¹², summing
    /// λ/2 terms at each step, and did not come back for minutes.
    #[test]
    fn a_test_of_few_degrees_of_freedom_is_not_detectable_rather_than_endless() {
        assert_eq!(noncentrality_for_power(1e-5, 0.9, 3, 1.0), None);
        assert_eq!(noncentrality_for_power(1e-4, 0.9, 1, 2.0), None);
        // the law at the λ the bisection found for ν = 2 before the cap: power 0.9
        let f = critical_f(1e-4, 1, 2.0);
        assert!((noncentral_f_sf(f, 1, 2.0, 23_026.002_136) - 0.9).abs() < 1e-6);
        // with ν = 20 it is an ordinary answer
        let lambda = noncentrality_for_power(1e-4, 0.9, 1, 20.0).unwrap();
        let f = critical_f(1e-4, 1, 20.0);
        assert!((noncentral_f_sf(f, 1, 20.0, lambda) - 0.9).abs() < 1e-6);
    }
}
