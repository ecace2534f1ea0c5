//! How a trial is drawn: the fitted model plus the noise, the trapezoids and the scoped
//! draws of each target, and the `result` draws per output, in the vector units where the
//! processor has them (the same bits as the portable code).

use rand::Rng;
use rand_distr::Distribution as _;

use super::{McModel, McScratch, Noise};
use crate::uncertainty::calibration::draws::{Spread, draw_into};
use crate::uncertainty::distribution::{standard_normals, uniforms};

impl McModel {
    /// Draws one trial's targets and the per-output offsets of the `result` components
    /// (into `scratch`), without solving.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R, scratch: &mut McScratch) {
        #[cfg(target_arch = "x86_64")]
        if crate::uncertainty::monte_carlo::has_avx2() {
            // SAFETY: the processor has AVX2 (just checked).
            unsafe { self.sample_avx2(rng, scratch) };
            return;
        }
        self.sample_portable(rng, scratch);
    }

    /// [`McModel::sample`] in the AVX2 vector units: the same arithmetic, value by value.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn sample_avx2<R: Rng + ?Sized>(&self, rng: &mut R, scratch: &mut McScratch) {
        self.sample_portable(rng, scratch);
    }

    #[inline(always)]
    pub(super) fn sample_portable<R: Rng + ?Sized>(&self, rng: &mut R, scratch: &mut McScratch) {
        let t = &mut scratch.targets;
        let n = t.len();
        let bits = &mut scratch.bits;
        let sd = match &self.noise {
            Noise::Normal => &self.normal_sd,
            Noise::ScaledT { sigma, dof, chi } => {
                let s2 = sigma * sigma * dof / chi.sample(rng);
                match self.uniform_var {
                    // every target alike (each one reading): one square root, the same
                    // value as per target
                    Some((v, f)) => scratch.sd.fill((s2 * v + f).sqrt()),
                    None => {
                        for ((sd, v), f) in scratch
                            .sd
                            .iter_mut()
                            .zip(&self.noise_var)
                            .zip(&self.fixed_var)
                        {
                            *sd = (s2 * v + f).sqrt();
                        }
                    }
                }
                &scratch.sd
            }
        };
        let z = &mut scratch.draws[..n];
        standard_normals(rng, bits, z);
        let q = &mut scratch.quantiles[..self.trapezoids.len()];
        if !q.is_empty() {
            let u = &mut scratch.uniforms[..q.len()];
            uniforms(rng, bits, u);
            self.trapezoids.quantiles(u, q);
        }
        // The noise, the normal errors and the trapezoids of each target.
        if self.one_trapezoid_each {
            for ((((x, b), sd), z), q) in t
                .iter_mut()
                .zip(&self.base)
                .zip(sd)
                .zip(z.iter())
                .zip(q.iter())
            {
                *x = b + sd * z + q;
            }
        } else {
            let trapezoids = self.trapezoid_starts.windows(2);
            for ((((x, b), sd), z), range) in t
                .iter_mut()
                .zip(&self.base)
                .zip(sd)
                .zip(z.iter())
                .zip(trapezoids)
            {
                *x = b + sd * z + q[range[0]..range[1]].iter().sum::<f64>();
            }
        }
        for plan in &self.plans {
            let draws = &mut scratch.draws[..plan.spread.groups()];
            draw_into(&plan.sampler, rng, bits, draws);
            match &plan.spread {
                Spread::Single(targets) => {
                    for (&(target, w), e) in targets.iter().zip(draws.iter()) {
                        t[target] += w * e;
                    }
                }
                Spread::Groups { entries, .. } => {
                    for &(target, w, group) in entries {
                        t[target] += w * draws[group];
                    }
                }
                Spread::Dense {
                    weights, group_of, ..
                } => {
                    for ((x, w), &g) in t.iter_mut().zip(weights).zip(group_of) {
                        *x += w * draws[g];
                    }
                }
            }
        }
        if !self.result_draws.is_empty() {
            scratch.offsets.fill(0.0);
            let draws = &mut scratch.draws[..scratch.offsets.len()];
            for (sampler, c) in &self.result_draws {
                draw_into(sampler, rng, &mut scratch.bits, draws);
                for (o, d) in scratch.offsets.iter_mut().zip(draws.iter()) {
                    *o += c * d;
                }
            }
        }
    }
}
