//! Probability distributions of input quantities, shared by GUM budgets and Monte Carlo.
//!
//! A [`Distribution`] describes the state of knowledge about an input quantity around its
//! estimate (it is centred on zero: the estimate is added separately). A GUM budget uses
//! only its standard uncertainty ([`Distribution::standard_uncertainty`], GUM 4.3.7–4.3.9);
//! Monte Carlo (JCGM 101:2008 §6.4) draws from it.

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
