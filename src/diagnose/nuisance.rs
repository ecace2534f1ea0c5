//! The table's error at every stop of a self-calibration: a nuisance taken out exactly,
//! without a column per stop.
//!
//! A self-calibration's reading is t[cycle, step] + e + c + effects + noise. The closure
//! model of `selfcal` holds one table error per step (the columns A); the rest of the
//! per-stop nuisance is D, the differences between the cycles at every step (S = A ⊕ D,
//! S the stop indicators). In a self-calibration every head reads every stop, so the
//! closure model's other columns Z (e, c) read alike at every stop of a step: D ⊥ Z. With
//! M = I − P_S (every reading minus the mean of its stop; Frisch–Waugh–Lovell), fitting
//! the closure model with the effect columns M·T to the readings M·y gives the estimates,
//! the residuals and the cofactor of e, c and the effects of the full model exactly; only
//! the degrees of freedom lose D's dimension, stops − steps ([`StopNuisance::parameters`]),
//! and the hat matrix gains P_D = P_S − P_A ([`StopNuisance::hat`]).

use crate::measurement::MeasurementSet;

/// Which stop and which step every reading of a self-calibration's closure set belongs to
/// (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct StopNuisance {
    /// The stop (cycle, step) of every reading, numbered.
    stop_of: Vec<usize>,
    /// The step (the closure model's position) of every reading, numbered.
    step_of: Vec<usize>,
    /// Readings per stop.
    stop_size: Vec<f64>,
    /// Readings per step.
    step_size: Vec<f64>,
}

impl StopNuisance {
    /// The stops and steps of `set`'s readings.
    pub fn of(set: &MeasurementSet) -> Self {
        let mut stops: Vec<(u32, usize)> = set.readings.iter().map(|r| (r.cycle, r.step)).collect();
        stops.sort_unstable();
        stops.dedup();
        let mut steps: Vec<usize> = set.readings.iter().map(|r| r.step).collect();
        steps.sort_unstable();
        steps.dedup();
        let stop_of: Vec<usize> = set
            .readings
            .iter()
            .map(|r| stops.binary_search(&(r.cycle, r.step)).unwrap_or(0))
            .collect();
        let step_of: Vec<usize> = set
            .readings
            .iter()
            .map(|r| steps.binary_search(&r.step).unwrap_or(0))
            .collect();
        let mut stop_size = vec![0.0; stops.len()];
        let mut step_size = vec![0.0; steps.len()];
        for (&s, &p) in stop_of.iter().zip(&step_of) {
            stop_size[s] += 1.0;
            step_size[p] += 1.0;
        }
        StopNuisance {
            stop_of,
            step_of,
            stop_size,
            step_size,
        }
    }

    /// The dimension of D, the nuisance beyond the closure model's table error per step:
    /// stops − steps (the degrees of freedom the fit of M·y does not count).
    pub fn parameters(&self) -> usize {
        self.stop_size.len() - self.step_size.len()
    }

    /// M·x: every value minus the mean of its stop.
    pub fn project(&self, x: &[f64]) -> Vec<f64> {
        let mut sum = vec![0.0; self.stop_size.len()];
        for (&s, v) in self.stop_of.iter().zip(x) {
            sum[s] += v;
        }
        self.stop_of
            .iter()
            .zip(x)
            .map(|(&s, v)| v - sum[s] / self.stop_size[s])
            .collect()
    }

    /// Every value minus the mean of its stop, in place (as [`StopNuisance::project`]).
    pub fn center_within_stops(&self, x: &mut [f64]) {
        let projected = self.project(x);
        x.copy_from_slice(&projected);
    }

    /// P_D\[i, j\] = [same stop]/(readings of the stop) − [same step]/(readings of the step).
    pub fn hat(&self, i: usize, j: usize) -> f64 {
        let mut h = 0.0;
        if self.stop_of[i] == self.stop_of[j] {
            h += 1.0 / self.stop_size[self.stop_of[i]];
        }
        if self.step_of[i] == self.step_of[j] {
            h -= 1.0 / self.step_size[self.step_of[i]];
        }
        h
    }

    /// P_D·x: every value's stop mean less its step mean.
    pub fn hat_times(&self, x: &[f64]) -> Vec<f64> {
        let mut stop = vec![0.0; self.stop_size.len()];
        let mut step = vec![0.0; self.step_size.len()];
        for (i, v) in x.iter().enumerate() {
            stop[self.stop_of[i]] += v;
            step[self.step_of[i]] += v;
        }
        (0..x.len())
            .map(|i| {
                let (s, p) = (self.stop_of[i], self.step_of[i]);
                stop[s] / self.stop_size[s] - step[p] / self.step_size[p]
            })
            .collect()
    }

    /// xᵀ P_D y = Σ_stops (Σx)(Σy)/size − Σ_steps (Σx)(Σy)/size.
    pub fn quadratic(&self, x: &[f64], y: &[f64]) -> f64 {
        let mut stop = vec![(0.0, 0.0); self.stop_size.len()];
        let mut step = vec![(0.0, 0.0); self.step_size.len()];
        for (i, (a, b)) in x.iter().zip(y).enumerate() {
            let s = &mut stop[self.stop_of[i]];
            s.0 += a;
            s.1 += b;
            let p = &mut step[self.step_of[i]];
            p.0 += a;
            p.1 += b;
        }
        let part = |sums: &[(f64, f64)], size: &[f64]| -> f64 {
            sums.iter().zip(size).map(|((a, b), n)| a * b / n).sum()
        };
        part(&stop, &self.stop_size) - part(&step, &self.step_size)
    }

    /// A running xᵀ P_D x of an indicator column growing one reading at a time (a
    /// suffix of a stream, [`super::geometry::FitGeometry::suffix_scores`]).
    pub(super) fn suffix(&self) -> SuffixQuadratic<'_> {
        SuffixQuadratic {
            nuisance: self,
            stop: vec![0.0; self.stop_size.len()],
            step: vec![0.0; self.step_size.len()],
            value: 0.0,
        }
    }
}

/// xᵀ P_D x of an indicator column, one reading added at a time.
pub(super) struct SuffixQuadratic<'a> {
    nuisance: &'a StopNuisance,
    stop: Vec<f64>,
    step: Vec<f64>,
    value: f64,
}

impl SuffixQuadratic<'_> {
    /// Adds reading `i` (value 1) and returns the new xᵀ P_D x.
    pub(super) fn add(&mut self, i: usize) -> f64 {
        let (s, p) = (self.nuisance.stop_of[i], self.nuisance.step_of[i]);
        self.value += (2.0 * self.stop[s] + 1.0) / self.nuisance.stop_size[s];
        self.value -= (2.0 * self.step[p] + 1.0) / self.nuisance.step_size[p];
        self.stop[s] += 1.0;
        self.step[p] += 1.0;
        self.value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hat_times_is_the_hat_matrix_applied() {
        let nuisance = StopNuisance {
            stop_of: vec![0, 0, 1, 1, 1, 2],
            step_of: vec![0, 0, 1, 1, 1, 0],
            stop_size: vec![2.0, 3.0, 1.0],
            step_size: vec![3.0, 3.0],
        };
        let x = [1.0, -2.0, 0.5, 4.0, 3.0, 7.0];
        let applied = nuisance.hat_times(&x);
        for (i, a) in applied.iter().enumerate() {
            let by_entries: f64 = (0..x.len()).map(|j| nuisance.hat(i, j) * x[j]).sum();
            assert!(
                (a - by_entries).abs() < 1e-12,
                "{i}: {a} against {by_entries}"
            );
        }
        // by hand, reading 0: stop mean (1 − 2)/2 less step mean (1 − 2 + 7)/3
        assert!((applied[0] - (-0.5 - 2.0)).abs() < 1e-12);
    }
}
