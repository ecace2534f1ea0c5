//! Probability distributions of input quantities, shared by GUM budgets and Monte Carlo.
//!
//! A [`Distribution`] describes the state of knowledge about an input quantity around its
//! estimate (it is centred on zero: the estimate is added separately). A GUM budget uses
//! only its standard uncertainty ([`Distribution::standard_uncertainty`], GUM 4.3.7–4.3.9);
//! Monte Carlo (JCGM 101:2008 §6.4) draws from it.

use std::sync::LazyLock;

use rand::Rng;
use rand_distr::{Distribution as _, StandardNormal};

/// The probability distribution of an input quantity, centred on its estimate.
///
/// Widths are *half* widths `a` (the quantity lies in `[x − a, x + a]`); the
/// [`Distribution::rectangular_full_width`] family of constructors takes full widths.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Distribution {
    /// Gaussian with standard deviation `u` (JCGM 101 §6.4.7).
    Normal {
        /// Standard uncertainty.
        u: f64,
    },
    /// Rectangular (uniform) on `[−a, a]`: `u = a/√3` (GUM 4.3.7; JCGM 101 §6.4.2).
    Rectangular {
        /// Half width `a`.
        half_width: f64,
    },
    /// Symmetric triangular on `[−a, a]`: `u = a/√6` (GUM 4.3.9; JCGM 101 §6.4.5).
    Triangular {
        /// Half width `a`.
        half_width: f64,
    },
    /// Arcsine (U-shaped) on `[−a, a]`: `u = a/√2` (JCGM 101 §6.4.6), e.g. a sinusoidal
    /// quantity of amplitude `a`.
    Arcsine {
        /// Half width (amplitude) `a`.
        half_width: f64,
    },
    /// Scaled and shifted Student's t with `dof` degrees of freedom (JCGM 101 §6.4.9):
    /// the input is `scale · T_ν`. A GUM budget takes `u = scale` with `ν = dof`
    /// (GUM 4.2.3: `scale = s/√n` from `n` observations, `ν = n − 1`); the distribution's
    /// own standard deviation is `scale·√(ν/(ν − 2))` for `ν > 2`, which is what Monte Carlo
    /// propagates.
    StudentT {
        /// Scale factor (the GUM standard uncertainty `s/√n`).
        scale: f64,
        /// Degrees of freedom `ν > 0`.
        dof: f64,
    },
}

impl Distribution {
    /// A normal distribution from an expanded uncertainty `U` and its coverage factor `k`
    /// (e.g. from a calibration certificate): `u = U/k`.
    pub fn normal_expanded(expanded_u: f64, k: f64) -> Distribution {
        Distribution::Normal { u: expanded_u / k }
    }

    /// A rectangular distribution of full width `w` (e.g. a resolution): `a = w/2`,
    /// `u = w/√12`.
    pub fn rectangular_full_width(full_width: f64) -> Distribution {
        Distribution::Rectangular {
            half_width: 0.5 * full_width,
        }
    }

    /// A triangular distribution of full width `w`: `a = w/2`, `u = w/√24`.
    pub fn triangular_full_width(full_width: f64) -> Distribution {
        Distribution::Triangular {
            half_width: 0.5 * full_width,
        }
    }

    /// An arcsine distribution of full width `w`: `a = w/2`, `u = w/√8`.
    pub fn arcsine_full_width(full_width: f64) -> Distribution {
        Distribution::Arcsine {
            half_width: 0.5 * full_width,
        }
    }

    /// The standard uncertainty a GUM budget assigns to the input: `u`, `a/√3`, `a/√6`,
    /// `a/√2`, or the scale of a t distribution.
    pub fn standard_uncertainty(&self) -> f64 {
        match *self {
            Distribution::Normal { u } => u,
            Distribution::Rectangular { half_width } => half_width / 3f64.sqrt(),
            Distribution::Triangular { half_width } => half_width / 6f64.sqrt(),
            Distribution::Arcsine { half_width } => half_width / 2f64.sqrt(),
            Distribution::StudentT { scale, .. } => scale,
        }
    }

    /// The standard deviation of the distribution itself; differs from
    /// [`Distribution::standard_uncertainty`] only for the t distribution
    /// (`scale·√(ν/(ν − 2))`), and is `None` when it does not exist (t with `ν ≤ 2`).
    pub fn standard_deviation(&self) -> Option<f64> {
        match *self {
            Distribution::StudentT { scale, dof } => {
                (dof > 2.0).then(|| scale * (dof / (dof - 2.0)).sqrt())
            }
            _ => Some(self.standard_uncertainty()),
        }
    }

    /// The distribution's name as spelled in budget files and outputs: `normal`,
    /// `rectangular`, `triangular`, `arcsine` or `t`.
    pub fn name(&self) -> &'static str {
        match self {
            Distribution::Normal { .. } => "normal",
            Distribution::Rectangular { .. } => "rectangular",
            Distribution::Triangular { .. } => "triangular",
            Distribution::Arcsine { .. } => "arcsine",
            Distribution::StudentT { .. } => "t",
        }
    }

    /// The degrees of freedom the distribution itself carries (the t distribution's `ν`).
    pub fn own_dof(&self) -> Option<f64> {
        match *self {
            Distribution::StudentT { dof, .. } => Some(dof),
            _ => None,
        }
    }

    /// Checks the parameters: widths and uncertainties finite and not negative, `ν > 0`.
    ///
    /// # Errors
    ///
    /// [`DistributionError`] naming the offending parameter.
    pub fn check(&self) -> Result<(), DistributionError> {
        let (what, value) = match *self {
            Distribution::Normal { u } => ("standard uncertainty u", u),
            Distribution::Rectangular { half_width }
            | Distribution::Triangular { half_width }
            | Distribution::Arcsine { half_width } => ("half width", half_width),
            Distribution::StudentT { scale, dof } => {
                if !(dof.is_finite() && dof > 0.0) {
                    return Err(DistributionError::TDof(dof));
                }
                ("scale", scale)
            }
        };
        if !value.is_finite() {
            return Err(DistributionError::NotFinite { what, value });
        }
        if value < 0.0 {
            return Err(DistributionError::Negative { what, value });
        }
        Ok(())
    }

    /// A sampler ready to draw from the distribution (centred on zero).
    pub(crate) fn sampler(&self) -> Result<Sampler, DistributionError> {
        self.check()?;
        Ok(match *self {
            Distribution::Normal { u } => Sampler::Normal(u),
            Distribution::Rectangular { half_width } => Sampler::Rectangular(half_width),
            Distribution::Triangular { half_width } => Sampler::Triangular(half_width),
            Distribution::Arcsine { half_width } => Sampler::Arcsine(half_width),
            Distribution::StudentT { scale, dof } => Sampler::StudentT(
                scale,
                rand_distr::StudentT::new(dof).map_err(|_| DistributionError::TDof(dof))?,
            ),
        })
    }
}

/// Why a [`Distribution`]'s parameters are invalid ([`Distribution::check`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DistributionError {
    /// The degrees of freedom of a t distribution are not finite and positive.
    #[error("degrees of freedom of the t distribution must be finite and > 0, got {0}")]
    TDof(f64),
    /// A width, uncertainty or scale is not finite.
    #[error("{what} must be a finite number, got {value}")]
    NotFinite {
        /// The parameter (`standard uncertainty u`, `half width` or `scale`).
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A width, uncertainty or scale is negative.
    #[error("{what} must not be negative, got {value}")]
    Negative {
        /// The parameter (`standard uncertainty u`, `half width` or `scale`).
        what: &'static str,
        /// Its value.
        value: f64,
    },
}

/// A prepared draw from a [`Distribution`] (JCGM 101 §6.4 and annex C).
#[derive(Debug, Clone, Copy)]
pub(crate) enum Sampler {
    Normal(f64),
    Rectangular(f64),
    Triangular(f64),
    Arcsine(f64),
    StudentT(f64, rand_distr::StudentT<f64>),
}

impl Sampler {
    /// One draw, centred on zero.
    #[inline]
    pub(crate) fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        match self {
            Sampler::Normal(u) => {
                let z: f64 = StandardNormal.sample(rng);
                u * z
            }
            // a·(2r − 1), r uniform on [0, 1) (JCGM 101 §6.4.2.4).
            Sampler::Rectangular(a) => a * (2.0 * rng.random::<f64>() - 1.0),
            // The difference of two uniforms is symmetric triangular (JCGM 101 §6.4.5.4).
            Sampler::Triangular(a) => a * (rng.random::<f64>() - rng.random::<f64>()),
            // a·sin(π(r − 1/2)) is arcsine on [−a, a] (JCGM 101 §6.4.6.4, monotone form).
            Sampler::Arcsine(a) => a * (std::f64::consts::PI * (rng.random::<f64>() - 0.5)).sin(),
            Sampler::StudentT(scale, t) => scale * t.sample(rng),
        }
    }
}

/// The tables of the ziggurat for the standard normal distribution: 256 layers of equal
/// area (Marsaglia and Tsang 2000, in the form of Doornik 2005, "An improved ziggurat
/// method to generate normal random samples"; the same layers as `rand_distr`).
struct Ziggurat {
    /// `x[i]`: the right end of layer `i` (`x[0] = v/f(r)`, `x[1] = r`, …, `x[256] = 0`).
    x: [f64; 257],
    /// `f(x[i]) = exp(−x[i]²/2)`.
    f: [f64; 257],
}

/// The start of the tail, `r`, and the area `v` of every layer.
const ZIGGURAT_R: f64 = 3.654_152_885_361_009;
const ZIGGURAT_V: f64 = 0.004_928_673_233_99;

static ZIGGURAT: LazyLock<Ziggurat> = LazyLock::new(|| {
    let f = |x: f64| (-0.5 * x * x).exp();
    let mut x = [0.0; 257];
    x[0] = ZIGGURAT_V / f(ZIGGURAT_R);
    x[1] = ZIGGURAT_R;
    // Layer i spans [f(x[i]), f(x[i + 1])] with width x[i]: area v.
    for i in 1..256 {
        x[i + 1] = (-2.0 * (ZIGGURAT_V / x[i] + f(x[i])).ln()).sqrt();
    }
    x[256] = 0.0;
    Ziggurat { x, f: x.map(f) }
});

/// The candidate of one 64-bit draw: layer `i` (the low 8 bits) and `x = u·x[i]` with `u`
/// uniform on [−1, 1) from the high 52 bits; accepted at once when `|x| < x[i + 1]`
/// (inside the layer's rectangle under the curve, about 99 % of draws).
#[inline(always)]
fn ziggurat_candidate(z: &Ziggurat, bits: u64) -> (usize, f64, bool) {
    let i = (bits & 0xff) as usize;
    let u = f64::from_bits((bits >> 12) | 0x4000_0000_0000_0000) - 3.0;
    let x = u * z.x[i];
    (i, x, x.abs() < z.x[i + 1])
}

/// Uniform on (0, 1), never 0: from the high 53 bits, centred in its cell.
#[inline]
fn open01<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    ((rng.next_u64() >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
}

/// The rest of the ziggurat for a candidate outside its rectangle: the tail beyond `r`
/// for layer 0 (Marsaglia 1964), else the wedge test, and on rejection a fresh draw
/// (from `rand_distr`'s ziggurat: the accepted candidates are standard normal, so any
/// exact sampler may stand in for the rest).
#[cold]
fn ziggurat_slow<R: Rng + ?Sized>(z: &Ziggurat, rng: &mut R, i: usize, x: f64) -> f64 {
    if i == 0 {
        loop {
            let t = open01(rng).ln() / ZIGGURAT_R;
            let y = open01(rng).ln();
            if -2.0 * y >= t * t {
                return if x < 0.0 {
                    t - ZIGGURAT_R
                } else {
                    ZIGGURAT_R - t
                };
            }
        }
    }
    let uniform = (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
    if z.f[i + 1] + (z.f[i] - z.f[i + 1]) * uniform < (-0.5 * x * x).exp() {
        x
    } else {
        StandardNormal.sample(rng)
    }
}

/// Fills `out` with standard normal draws by the ziggurat, the 64-bit draws fetched in
/// bulk into `bits` (at least as long as `out`) first: one 64-bit draw gives the value
/// for about 99 % of them, and the draws of the rare slow path are taken after the bulk.
#[inline]
pub(crate) fn standard_normals<R: Rng + ?Sized>(rng: &mut R, bits: &mut [u64], out: &mut [f64]) {
    let z = &*ZIGGURAT;
    let bits = &mut bits[..out.len()];
    rng.fill(bits);
    for (o, &b) in out.iter_mut().zip(bits.iter()) {
        let (i, x, accepted) = ziggurat_candidate(z, b);
        *o = if accepted {
            x
        } else {
            ziggurat_slow(z, rng, i, x)
        };
    }
}

/// Fills `out` with uniform draws on [0, 1), fetched in bulk into `bits`: the high 52
/// bits of a 64-bit draw as the mantissa of a number in [1, 2), less 1 (a step of
/// 2⁻⁵², without an integer conversion, so the loop runs in the vector units).
#[inline]
pub(crate) fn uniforms<R: Rng + ?Sized>(rng: &mut R, bits: &mut [u64], out: &mut [f64]) {
    let bits = &mut bits[..out.len()];
    rng.fill(bits);
    for (o, &b) in out.iter_mut().zip(bits.iter()) {
        *o = f64::from_bits((b >> 12) | 0x3ff0_0000_0000_0000) - 1.0;
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_xoshiro::Xoshiro256PlusPlus;
    use statrs::distribution::{ContinuousCDF, Normal};

    use super::*;

    /// The Kolmogorov–Smirnov distance of sorted values to a distribution function.
    fn ks_distance(sorted: &[f64], cdf: impl Fn(f64) -> f64) -> f64 {
        let n = sorted.len() as f64;
        sorted
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let f = cdf(x);
                (f - i as f64 / n).abs().max(((i + 1) as f64 / n - f).abs())
            })
            .fold(0.0, f64::max)
    }

    /// Every layer of the ziggurat has the same area `v`, the base layer (rectangle plus
    /// tail) included, and the top layer reaches the mode.
    #[test]
    fn ziggurat_layers_have_equal_areas() {
        let z = &*ZIGGURAT;
        let phi = |x: f64| (-0.5 * x * x).exp();
        let tail = (std::f64::consts::PI / 2.0).sqrt()
            * statrs::function::erf::erfc(ZIGGURAT_R / std::f64::consts::SQRT_2);
        assert!((ZIGGURAT_R * phi(ZIGGURAT_R) + tail - ZIGGURAT_V).abs() < 1e-12);
        assert!((z.x[0] * phi(ZIGGURAT_R) - ZIGGURAT_V).abs() < 1e-15);
        assert_eq!((z.x[256], z.f[256]), (0.0, 1.0));
        for i in 1..256 {
            let area = z.x[i] * (z.f[i + 1] - z.f[i]);
            assert!(
                (area - ZIGGURAT_V).abs() < 1e-9 * ZIGGURAT_V,
                "layer {i}: {area}"
            );
        }
    }

    /// In bulk, large or small, the draws follow the standard normal distribution
    /// (statrs' Φ), in the body and in the tail beyond `r` that has its own method.
    #[test]
    fn ziggurat_draws_are_standard_normal() {
        let n = 1_000_000;
        let normal = Normal::new(0.0, 1.0).unwrap();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(5);
        let mut bits = vec![0; 1000];
        for size in [1000, 7] {
            let mut draws = vec![0.0; n];
            for chunk in draws.chunks_mut(size) {
                standard_normals(&mut rng, &mut bits, chunk);
            }
            let mean = draws.iter().sum::<f64>() / n as f64;
            let var = draws.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            assert!(mean.abs() < 5.0 / (n as f64).sqrt(), "{mean}");
            assert!((var - 1.0).abs() < 5.0 * (2.0 / n as f64).sqrt(), "{var}");
            // Beyond r (p = 2.58e-4, about 258 draws): within 5 binomial σ.
            let expected = 2.0 * normal.sf(ZIGGURAT_R) * n as f64;
            let beyond = draws.iter().filter(|z| z.abs() > ZIGGURAT_R).count() as f64;
            assert!(
                (beyond - expected).abs() < 5.0 * expected.sqrt(),
                "{beyond}"
            );
            draws.sort_unstable_by(f64::total_cmp);
            // 1.95/√n: the 0.1 % critical value of the Kolmogorov–Smirnov distance.
            let d = ks_distance(&draws, |x| normal.cdf(x));
            assert!(d < 1.95 / (n as f64).sqrt(), "KS distance {d}");
        }
    }

    /// The bulk uniforms lie in [0, 1) and are uniform.
    #[test]
    fn bulk_uniforms_are_uniform() {
        let n = 200_000;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(6);
        let mut u = vec![0.0; n];
        let mut bits = vec![0; n];
        uniforms(&mut rng, &mut bits, &mut u);
        assert!(u.iter().all(|&x| (0.0..1.0).contains(&x)));
        u.sort_unstable_by(f64::total_cmp);
        let d = ks_distance(&u, |x| x);
        assert!(d < 1.95 / (n as f64).sqrt(), "KS distance {d}");
    }
}
