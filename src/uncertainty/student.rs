//! Student's t distribution and the standard normal distribution, written from scratch.
//!
//! The coverage factor of a GUM budget is the two-sided Student's t quantile
//! `k = t_p(ν)` (JCGM 100:2008, annex G): the value with `P(|T| ≤ k) = p` for a t variable
//! with `ν` degrees of freedom. [`t_quantile`] gives it for any real `ν ≥ 1` (fractional
//! effective degrees of freedom from the Welch–Satterthwaite formula included) and for
//! `ν = ∞` (the normal distribution).
//!
//! # Method
//!
//! - The two-sided tail `P(|T| > t) = I_x(ν/2, 1/2)` with `x = ν/(ν + t²)` is the
//!   regularized incomplete beta function, evaluated by its continued fraction (modified
//!   Lentz, as in *Numerical Recipes* `betacf`). The prefactor is formed without
//!   cancellation: `(ν/2)·ln x = −(ν/2)·ln1p(t²/ν)` and `Γ(a + 1/2)/Γ(a)` from Stirling's
//!   series of the *difference* of the log-gammas, so the result stays accurate for
//!   `ν` in the millions.
//! - The quantile solves `P(|T| > t) = 1 − p` by Newton's method on `ln P` against `ln t`,
//!   safeguarded by bisection inside a bracket, to full double precision.
//! - For `ν ≥ 4000` the quantile is Fisher's expansion in powers of `1/ν` (Abramowitz &
//!   Stegun 26.7.5, four terms), and the distribution function (for `|t| ≤ 10`) that
//!   expansion inverted by Newton's method, while `t² ≤ ν/100`. There the truncation error
//!   is about `10⁻¹⁵` and the continued fraction, which converges slowly and loses digits for large `ν`,
//!   is not needed: the values approach the normal ones smoothly and never take long.
//! - The normal quantile is Wichura's algorithm AS 241 (`PPND16`, relative accuracy about
//!   `10⁻¹⁶`); the normal distribution function uses `erfc` from the regularized incomplete
//!   gamma function `Q(1/2, x²)`.

use std::f64::consts::{FRAC_1_SQRT_2, PI};

/// `ln √π`.
const LN_SQRT_PI: f64 = 0.572_364_942_924_700_1;
/// From this many degrees of freedom on, the asymptotic expansion in `1/ν` is used.
const LARGE_DOF: f64 = 4000.0;
/// The expansion is used while `t² ≤ ν/100`: then its truncation error is about `10⁻¹⁴`
/// or less, and beyond, the continued fraction is as accurate (`x = ν/(ν + t²) ≤ 100/101`).
const EXPANSION_MAX_T2_OVER_NU: f64 = 1.0 / 100.0;
/// Relative tolerance of the continued fractions.
const CF_EPS: f64 = 1.0e-16;
/// Smallest magnitude allowed in Lentz's method.
const FPMIN: f64 = 1.0e-300;
/// Iteration cap of the continued fractions (never reached for `ν ≤ 10⁷`).
const CF_MAX_ITER: usize = 100_000;

/// The two-sided coverage factor `k = t_p(ν)`: the value with `P(|T| ≤ k) = p` for a
/// Student's t variable `T` with `ν` degrees of freedom.
///
/// `p_two_sided` is the coverage probability (e.g. `0.95`); `dof` is `ν`, `None` (or
/// `Some(f64::INFINITY)`) for infinitely many degrees of freedom, where the result is the
/// normal quantile `Φ⁻¹((1 + p)/2)`. `ν` may be fractional (an effective number of degrees
/// of freedom): the function is exact for any real `ν > 0`, monotonically decreasing in
/// `ν`, and approaches the normal value smoothly as `ν → ∞`.
///
/// Out-of-domain arguments give NaN: `p` outside `[0, 1]` or NaN, `ν ≤ 0` or NaN.
/// `p = 0` gives 0 and `p = 1` gives `+∞`.
///
/// # Examples
///
/// ```
/// use polycal::uncertainty::student::t_quantile;
///
/// // JCGM 100:2008 Table G.2, p = 95.45 %: ν = 10 → 2.28, ν = ∞ → 2.000.
/// assert!((t_quantile(0.9545, Some(10.0)) - 2.28).abs() < 0.005);
/// assert!((t_quantile(0.9545, None) - 2.000).abs() < 0.0005);
/// // The familiar 95 % factors.
/// assert!((t_quantile(0.95, Some(5.0)) - 2.5706).abs() < 5e-5);
/// assert!((t_quantile(0.95, None) - 1.9600).abs() < 5e-5);
/// // Fractional degrees of freedom, as Welch–Satterthwaite gives them.
/// let k = t_quantile(0.95, Some(72.6));
/// assert!(t_quantile(0.95, Some(73.0)) < k && k < t_quantile(0.95, Some(72.0)));
/// ```
pub fn t_quantile(p_two_sided: f64, dof: Option<f64>) -> f64 {
    let p = p_two_sided;
    if !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    let nu = match dof {
        None => f64::INFINITY,
        Some(nu) if nu > 0.0 => nu,
        Some(_) => return f64::NAN,
    };
    if p == 0.0 {
        return 0.0;
    }
    if p == 1.0 {
        return f64::INFINITY;
    }
    let alpha = 1.0 - p;
    if nu.is_infinite() {
        return -normal_quantile(0.5 * alpha);
    }
    if nu >= LARGE_DOF {
        let t = t_quantile_asymptotic(alpha, nu);
        if t * t <= EXPANSION_MAX_T2_OVER_NU * nu {
            return t;
        }
    }
    if nu == 1.0 {
        // Cauchy: P(|T| ≤ t) = (2/π)·atan(t), so t = cot(π(1 − p)/2).
        return 1.0 / (0.5 * PI * alpha).tan();
    }
    if nu == 2.0 {
        // P(|T| ≤ t) = t/√(2 + t²).
        return p * (2.0 / (alpha * (1.0 + p))).sqrt();
    }
    solve_two_sided_tail(alpha, nu)
}

/// The distribution function `P(T ≤ t)` of Student's t with `ν` degrees of freedom
/// (`None` for infinitely many: the standard normal `Φ(t)`).
///
/// Out-of-domain arguments (`t` NaN, `ν ≤ 0` or NaN) give NaN.
///
/// ```
/// use polycal::uncertainty::student::t_cdf;
/// assert!((t_cdf(2.5706, Some(5.0)) - 0.975).abs() < 1e-5);
/// assert!((t_cdf(0.0, Some(3.3)) - 0.5).abs() < 1e-15);
/// ```
pub fn t_cdf(t: f64, dof: Option<f64>) -> f64 {
    let nu = match dof {
        None => f64::INFINITY,
        Some(nu) if nu > 0.0 => nu,
        Some(_) => return f64::NAN,
    };
    if t.is_nan() {
        return f64::NAN;
    }
    if nu.is_infinite() {
        return normal_cdf(t);
    }
    let half_tail = 0.5 * two_sided_tail(t.abs(), nu);
    if t >= 0.0 { 1.0 - half_tail } else { half_tail }
}

/// The two-sided coverage probability `P(|T| ≤ k)` of a Student's t variable with `ν`
/// degrees of freedom (`None`: normal), the inverse of [`t_quantile`] in `k`.
///
/// ```
/// use polycal::uncertainty::student::{t_coverage, t_quantile};
/// let k = t_quantile(0.99, Some(16.0));
/// assert!((t_coverage(k, Some(16.0)) - 0.99).abs() < 1e-14);
/// ```
pub fn t_coverage(k: f64, dof: Option<f64>) -> f64 {
    let nu = match dof {
        None => f64::INFINITY,
        Some(nu) if nu > 0.0 => nu,
        Some(_) => return f64::NAN,
    };
    if k.is_nan() {
        return f64::NAN;
    }
    if k <= 0.0 {
        return 0.0;
    }
    if nu.is_infinite() {
        return 1.0 - erfc(k * FRAC_1_SQRT_2);
    }
    1.0 - two_sided_tail(k, nu)
}

/// The standard normal distribution function `Φ(x)`.
///
/// ```
/// use polycal::uncertainty::student::normal_cdf;
/// assert!((normal_cdf(1.959963984540054) - 0.975).abs() < 1e-15);
/// ```
pub fn normal_cdf(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        0.5 * erfc(-x * FRAC_1_SQRT_2)
    } else {
        1.0 - 0.5 * erfc(x * FRAC_1_SQRT_2)
    }
}

/// The standard normal quantile `Φ⁻¹(p)` (Wichura, algorithm AS 241, Appl. Statist. 37
/// (1988) 477–484; relative accuracy about `10⁻¹⁶`).
///
/// `p = 0` gives `−∞`, `p = 1` gives `+∞`, `p` outside `[0, 1]` or NaN gives NaN.
///
/// ```
/// use polycal::uncertainty::student::normal_quantile;
/// assert!((normal_quantile(0.975) - 1.959963984540054).abs() < 1e-15);
/// ```
#[allow(clippy::excessive_precision)] // AS 241's coefficients as published
pub fn normal_quantile(p: f64) -> f64 {
    if !(0.0..=1.0).contains(&p) {
        return f64::NAN;
    }
    if p == 0.0 {
        return f64::NEG_INFINITY;
    }
    if p == 1.0 {
        return f64::INFINITY;
    }
    const A: [f64; 8] = [
        3.387_132_872_796_366_608,
        1.331_416_678_917_843_774_5e2,
        1.971_590_950_306_551_442_7e3,
        1.373_169_376_550_946_112_5e4,
        4.592_195_393_154_987_145_7e4,
        6.726_577_092_700_870_085_3e4,
        3.343_057_558_358_812_810_5e4,
        2.509_080_928_730_122_672_7e3,
    ];
    const B: [f64; 8] = [
        1.0,
        4.231_333_070_160_091_125_2e1,
        6.871_870_074_920_579_083e2,
        5.394_196_021_424_751_107_7e3,
        2.121_379_430_158_659_586_7e4,
        3.930_789_580_009_271_061e4,
        2.872_908_573_572_194_267_4e4,
        5.226_495_278_852_854_561e3,
    ];
    const C: [f64; 8] = [
        1.423_437_110_749_683_577_34,
        4.630_337_846_156_545_295_9,
        5.769_497_221_460_691_405_5,
        3.647_848_324_763_204_605_04,
        1.270_458_252_452_368_382_58,
        2.417_807_251_774_506_117_7e-1,
        2.272_384_498_926_918_458_33e-2,
        7.745_450_142_783_414_076_4e-4,
    ];
    const D: [f64; 8] = [
        1.0,
        2.053_191_626_637_758_821_87,
        1.676_384_830_183_803_849_4,
        6.897_673_349_851_000_045_5e-1,
        1.481_039_764_274_800_745_9e-1,
        1.519_866_656_361_645_719_66e-2,
        5.475_938_084_995_344_946e-4,
        1.050_750_071_644_416_843_24e-9,
    ];
    const E: [f64; 8] = [
        6.657_904_643_501_103_777_2,
        5.463_784_911_164_114_369_9,
        1.784_826_539_917_291_335_8,
        2.965_605_718_285_048_912_3e-1,
        2.653_218_952_657_612_309_3e-2,
        1.242_660_947_388_078_438_6e-3,
        2.711_555_568_743_487_578_15e-5,
        2.010_334_399_292_288_132_65e-7,
    ];
    const F: [f64; 8] = [
        1.0,
        5.998_322_065_558_879_376_9e-1,
        1.369_298_809_227_358_053_1e-1,
        1.487_536_129_085_061_485_25e-2,
        7.868_691_311_456_132_591e-4,
        1.846_318_317_510_054_681_8e-5,
        1.421_511_758_316_445_888_7e-7,
        2.044_263_103_389_939_785_64e-15,
    ];
    fn poly(c: &[f64; 8], x: f64) -> f64 {
        c.iter().rev().fold(0.0, |acc, &ci| acc * x + ci)
    }
    let q = p - 0.5;
    if q.abs() <= 0.425 {
        let r = 0.180625 - q * q;
        return q * poly(&A, r) / poly(&B, r);
    }
    let r = if q < 0.0 { p } else { 1.0 - p };
    let r = (-r.ln()).sqrt();
    let value = if r <= 5.0 {
        let r = r - 1.6;
        poly(&C, r) / poly(&D, r)
    } else {
        let r = r - 5.0;
        poly(&E, r) / poly(&F, r)
    };
    if q < 0.0 { -value } else { value }
}

/// The complementary error function for `x ≥ 0`, as `Q(1/2, x²)` (regularized upper
/// incomplete gamma function): power series of `P` below `x² = 0.5`, continued fraction of
/// `Q` above (Numerical Recipes `gser`/`gcf`; the fraction from 0.5 on keeps the relative
/// error of small results at a few ulp).
pub(crate) fn erfc(x: f64) -> f64 {
    debug_assert!(x >= 0.0);
    let z = x * x;
    if z < 0.5 {
        // P(1/2, z) = e^{-z} z^{1/2} / Γ(3/2) · Σ zⁿ / ((3/2)(5/2)…(1/2+n)).
        let mut ap = 0.5;
        let mut term = 1.0 / 0.5;
        let mut sum = term;
        for _ in 0..200 {
            ap += 1.0;
            term *= z / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        let p = sum * (-z + 0.5 * z.ln() - LN_SQRT_PI).exp();
        1.0 - p
    } else {
        // Q(1/2, z) by the continued fraction, modified Lentz.
        let a = 0.5;
        let mut b = z + 1.0 - a;
        let mut c = 1.0 / FPMIN;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let i = i as f64;
            let an = -i * (i - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < FPMIN {
                d = FPMIN;
            }
            c = b + an / c;
            if c.abs() < FPMIN {
                c = FPMIN;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < CF_EPS {
                break;
            }
        }
        exp_minus_square(x) * x / PI.sqrt() * h
    }
}

/// `exp(−x²)` without the error of rounding `x²` (which the exponential would amplify by
/// `x²`): `x = x_h + δ` with `x_h` on a grid of `2⁻¹⁶`, so `x_h²` is exact, and
/// `exp(−x²) = exp(−x_h²)·exp(−δ(x + x_h))`.
fn exp_minus_square(x: f64) -> f64 {
    let xh = (x * 65536.0).trunc() / 65536.0;
    let d = x - xh;
    (-(xh * xh)).exp() * (-(d * (x + xh))).exp()
}

/// `Γ(a + 1/2) / Γ(a)` for `a > 0`, accurate to a few ulp for every `a`.
fn gamma_half_ratio(a: f64) -> f64 {
    // Stirling's series S(z) of ln Γ(z) − [(z − 1/2) ln z − z + ln √(2π)].
    fn stirling(z: f64) -> f64 {
        let z2 = z * z;
        (1.0 / 12.0
            + (-1.0 / 360.0 + (1.0 / 1260.0 + (-1.0 / 1680.0 + 1.0 / (1188.0 * z2)) / z2) / z2)
                / z2)
            / z
    }
    let mut prod = 1.0;
    let mut x = a;
    while x < 30.0 {
        // r(x) = r(x + 1) · x / (x + 1/2)
        prod *= x / (x + 0.5);
        x += 1.0;
    }
    let ln_ratio = 0.5 * x.ln() + (x * (0.5 / x).ln_1p() - 0.5) + (stirling(x + 0.5) - stirling(x));
    prod * ln_ratio.exp()
}

/// The two-sided tail `P(|T| > t)` for `t ≥ 0` and finite `ν > 0`.
fn two_sided_tail(t: f64, nu: f64) -> f64 {
    if t == 0.0 {
        return 1.0;
    }
    if t.is_infinite() {
        return 0.0;
    }
    if nu >= LARGE_DOF && t * t <= EXPANSION_MAX_T2_OVER_NU * nu {
        return two_sided_tail_asymptotic(t, nu);
    }
    let a = 0.5 * nu;
    let t2 = t * t;
    // x = ν/(ν + t²), 1 − x = t²/(ν + t²), both without cancellation.
    let x = nu / (nu + t2);
    let one_minus_x = t2 / (nu + t2);
    // ln[x^a (1−x)^{1/2} / B(a, 1/2)], B(a, 1/2) = √π Γ(a) / Γ(a + 1/2).
    let ln_front =
        -a * (t2 / nu).ln_1p() + 0.5 * one_minus_x.ln() - LN_SQRT_PI + gamma_half_ratio(a).ln();
    let front = ln_front.exp();
    if x < (a + 1.0) / (a + 2.5) {
        front * beta_cf(a, 0.5, x) / a
    } else {
        1.0 - front * beta_cf(0.5, a, one_minus_x) / 0.5
    }
}

/// The continued fraction of the incomplete beta function (Numerical Recipes `betacf`,
/// modified Lentz).
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let qab = a + b;
    let qap = a + 1.0;
    let qam = a - 1.0;
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < FPMIN {
        d = FPMIN;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..=CF_MAX_ITER {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < FPMIN {
            d = FPMIN;
        }
        c = 1.0 + aa / c;
        if c.abs() < FPMIN {
            c = FPMIN;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < FPMIN {
            d = FPMIN;
        }
        c = 1.0 + aa / c;
        if c.abs() < FPMIN {
            c = FPMIN;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < CF_EPS {
            break;
        }
    }
    h
}

/// The density of Student's t at `t` (finite `ν`).
fn t_density(t: f64, nu: f64) -> f64 {
    let a = 0.5 * nu;
    gamma_half_ratio(a) / (nu * PI).sqrt() * (-(a + 0.5) * (t * t / nu).ln_1p()).exp()
}

/// Solves `P(|T| > t) = alpha` for `t` (finite `ν ≤ 10⁷`, `0 < alpha < 1`).
fn solve_two_sided_tail(alpha: f64, nu: f64) -> f64 {
    // Start from the normal value corrected by the first terms of A&S 26.7.5.
    let z = -normal_quantile(0.5 * alpha);
    let t0 = (z + (z * z * z + z) / (4.0 * nu)).max(f64::MIN_POSITIVE);
    // Bracket: tail(lo) > alpha > tail(hi).
    let mut lo = t0;
    while two_sided_tail(lo, nu) <= alpha {
        lo *= 0.5;
        if lo < 1e-300 {
            return lo;
        }
    }
    let mut hi = t0.max(lo);
    while two_sided_tail(hi, nu) >= alpha {
        hi *= 2.0;
        if hi > 1e300 {
            return f64::INFINITY;
        }
    }
    let ln_alpha = alpha.ln();
    let mut t = t0.clamp(lo, hi);
    for _ in 0..200 {
        let tail = two_sided_tail(t, nu);
        if tail > alpha {
            lo = t;
        } else {
            hi = t;
        }
        // Newton on g(s) = ln tail(e^s) − ln alpha, s = ln t:
        // g'(s) = −2 f(t) t / tail.
        let g = tail.ln() - ln_alpha;
        let slope = -2.0 * t_density(t, nu) * t / tail;
        let mut next = t * (-g / slope).exp();
        if !(next > lo && next < hi && next.is_finite()) {
            next = (lo * hi).sqrt();
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
        }
        if (next - t).abs() <= 4.0 * f64::EPSILON * t || hi - lo <= 4.0 * f64::EPSILON * hi {
            return next;
        }
        t = next;
    }
    t
}

/// A&S 26.7.5 (Fisher's expansion): `t = z + g₁(z)/ν + g₂(z)/ν² + g₃(z)/ν³ + g₄(z)/ν⁴`,
/// with `z` the normal quantile, and its derivative in `z`.
fn fisher_expansion(z: f64, nu: f64) -> (f64, f64) {
    let z2 = z * z;
    let g1 = (z2 + 1.0) * z / 4.0;
    let g2 = ((5.0 * z2 + 16.0) * z2 + 3.0) * z / 96.0;
    let g3 = (((3.0 * z2 + 19.0) * z2 + 17.0) * z2 - 15.0) * z / 384.0;
    let g4 = ((((79.0 * z2 + 776.0) * z2 + 1482.0) * z2 - 1920.0) * z2 - 945.0) * z / 92160.0;
    let d1 = (3.0 * z2 + 1.0) / 4.0;
    let d2 = ((25.0 * z2 + 48.0) * z2 + 3.0) / 96.0;
    let d3 = (((21.0 * z2 + 95.0) * z2 + 51.0) * z2 - 15.0) / 384.0;
    let d4 = ((((711.0 * z2 + 5432.0) * z2 + 7410.0) * z2 - 5760.0) * z2 - 945.0) / 92160.0;
    let t = z + (g1 + (g2 + (g3 + g4 / nu) / nu) / nu) / nu;
    let dt = 1.0 + (d1 + (d2 + (d3 + d4 / nu) / nu) / nu) / nu;
    (t, dt)
}

/// The two-sided quantile for `ν ≥ LARGE_DOF` from Fisher's expansion.
fn t_quantile_asymptotic(alpha: f64, nu: f64) -> f64 {
    fisher_expansion(-normal_quantile(0.5 * alpha), nu).0
}

/// The two-sided tail for `ν ≥ LARGE_DOF`, `0 < t² ≤ ν/100`: Fisher's expansion
/// inverted for `z` by Newton's method, then `P(|T| > t) = erfc(z/√2)`; consistent with
/// [`t_quantile_asymptotic`] to rounding.
fn two_sided_tail_asymptotic(t: f64, nu: f64) -> f64 {
    let mut z = t - (t * t + 1.0) * t / (4.0 * nu);
    for _ in 0..50 {
        let (tz, dt) = fisher_expansion(z, nu);
        let step = (tz - t) / dt;
        z -= step;
        if step.abs() <= f64::EPSILON * z.abs() {
            break;
        }
    }
    erfc(z.max(0.0) * FRAC_1_SQRT_2)
}

/// The two-sided tail probability P(|T| > t) of Student's t with ν degrees of freedom
/// (`None`: normal), accurate also for tiny tails (the p-values of significance tests,
/// where `1 − t_coverage` would lose every digit).
///
/// ```
/// use polycal::uncertainty::student::t_two_sided_tail;
/// assert!((t_two_sided_tail(2.5706, Some(5.0)) - 0.05).abs() < 1e-5);
/// assert!((t_two_sided_tail(1.959963984540054, None) - 0.05).abs() < 1e-15);
/// assert!(t_two_sided_tail(40.0, Some(100.0)) < 1e-60);
/// ```
pub fn t_two_sided_tail(t: f64, dof: Option<f64>) -> f64 {
    match dof {
        _ if t.is_nan() => f64::NAN,
        None => erfc(t.abs() * FRAC_1_SQRT_2),
        Some(nu) if nu > 0.0 => two_sided_tail(t.abs(), nu),
        Some(_) => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expansion_and_continued_fraction_agree_where_they_meet() {
        // Just below the switch the continued fraction, at it the expansion: the quantile
        // and the tail must agree to near double precision (ν moves by 1e-9 only).
        for &alpha in &[0.5, 0.05, 0.0455, 0.01, 1e-6, 1e-9] {
            let below = solve_two_sided_tail(alpha, LARGE_DOF - 1e-9);
            let at = t_quantile_asymptotic(alpha, LARGE_DOF);
            assert!(
                ((below - at) / at).abs() < 5e-14,
                "alpha {alpha}: {below} vs {at}"
            );
        }
        for &t in &[0.1, 1.0, 1.96, 3.0, 6.0, 6.3, 6.4, 9.9] {
            let a = two_sided_tail(t, LARGE_DOF - 1e-9);
            let b = two_sided_tail(t, LARGE_DOF);
            assert!(((a - b) / a).abs() < 5e-13, "t {t}: {a} vs {b}");
        }
    }

    #[test]
    fn gamma_half_ratio_matches_closed_forms() {
        // Γ(1)/Γ(1/2) = 1/√π; Γ(3/2)/Γ(1) = √π/2; Γ(n + 1/2)/Γ(n) for n = 40 via the product.
        assert!((gamma_half_ratio(0.5) - 1.0 / PI.sqrt()).abs() < 1e-15);
        assert!((gamma_half_ratio(1.0) - PI.sqrt() / 2.0).abs() < 1e-15);
        let mut r = PI.sqrt() / 2.0; // n = 1
        for n in 1..40 {
            let n = n as f64;
            r *= (n + 0.5) / n; // r(n + 1) = r(n)·(n + 1/2)/n
        }
        assert!((gamma_half_ratio(40.0) / r - 1.0).abs() < 1e-14);
    }

    #[test]
    #[allow(clippy::excessive_precision)]
    fn erfc_matches_known_values() {
        // Reference values from the Taylor series of erf (and, at x = 12/√2, the asymptotic
        // series of erfc) in 60-digit decimal arithmetic.
        for (x, want) in [
            (0.1, 0.887_537_083_981_715_101_6),
            (0.5, 0.479_500_122_186_953_462_3),
            (0.7, 0.322_198_806_162_581_557_7),
            (1.0, 0.157_299_207_050_285_130_7),
            (3.0, 2.209_049_699_858_544_137e-5),
            (8.485_281_374_238_571, 3.552_964_224_155_295_822e-33),
        ] {
            let got = erfc(x);
            assert!(
                (got / want - 1.0).abs() < 2e-15,
                "erfc({x}) = {got}, want {want}"
            );
        }
    }

    #[test]
    fn huge_dof_beyond_the_expansion_range_terminates() {
        // |t| > 10 with ν = 1e12 takes the continued fraction: it must stop and be sane.
        let tail = two_sided_tail(12.0, 1e12);
        let normal = erfc(12.0 * FRAC_1_SQRT_2) * (1.0 + (12f64.powi(4) + 144.0) / 4e12);
        assert!((tail / normal - 1.0).abs() < 1e-8, "{tail} vs {normal}");
    }
}
