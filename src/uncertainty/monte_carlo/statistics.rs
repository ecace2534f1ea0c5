//! The statistics of Monte Carlo outputs (JCGM 101 §7.6–§7.9): running sums for the mean
//! and the standard uncertainty, the exact order statistics of the probabilistically
//! symmetric coverage interval from brackets, the shortest interval, and the numerical
//! tolerance of the adaptive procedure.
//!
//! The interval ends are order statistics of all `M` values. Rather than storing and
//! sorting them, a pilot of the first trials brackets each end: the sorted pilot gives,
//! for the wanted rank, a range of values that holds it with a margin of six binomial
//! standard deviations (plus ten). The trials are then counted below the low bracket and
//! above the high one, and the few inside a bracket are kept; the order statistic is
//! selected among those. A bracket that did not hold its rank is reported by [`finish`],
//! and the engine widens it and runs the trials again.

use rayon::prelude::*;

/// Per output: mean, u, low and high end of the interval.
pub(crate) type Moments = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// Per output: [low bracket start, low bracket end, high bracket start, high bracket end].
pub(crate) type Brackets = Vec<[f64; 4]>;

/// The 0-based positions, in the sorted values of `m` trials, of the ends of the
/// probabilistically symmetric `p` coverage interval (JCGM 101 §7.7.1): with `q = pM` if
/// an integer, else `⌊pM + 1/2⌋`, the interval is `[y_(r), y_(r+q)]` with `r = (M − q)/2`
/// if an integer, else `⌊(M − q + 1)/2⌋` (1-based), clamped to the sample.
///
/// ```
/// use polycal::uncertainty::monte_carlo::symmetric_interval_positions;
/// // M = 10⁶, p = 0.95: q = 950 000, r = 25 000: y_(25 000) and y_(975 000).
/// assert_eq!(symmetric_interval_positions(1_000_000, 0.95), (24_999, 974_999));
/// ```
pub fn symmetric_interval_positions(m: usize, p: f64) -> (usize, usize) {
    let pm = p * m as f64;
    let q = if (pm - pm.round()).abs() < 1e-9 * m as f64 {
        pm.round() as usize
    } else {
        (pm + 0.5).floor() as usize
    };
    let q = q.min(m - 1);
    let r = (m - q).div_ceil(2).max(1);
    (r - 1, (r + q - 1).min(m - 1))
}

/// The numerical tolerance `δ` of a standard uncertainty `u` to `n_dig` significant
/// digits (JCGM 101 §7.9.2): write `u = c × 10^ℓ` with `c` an `n_dig`-digit integer;
/// `δ = 10^ℓ / 2`. E.g. `u = 0.02847`, 2 digits: `c = 28`, `ℓ = −3`, `δ = 0.0005`.
///
/// ```
/// use polycal::uncertainty::monte_carlo::numerical_tolerance;
/// assert!((numerical_tolerance(0.028_47, 2) - 0.0005).abs() < 1e-18);
/// ```
pub fn numerical_tolerance(u: f64, significant_digits: u32) -> f64 {
    if !(u > 0.0 && u.is_finite()) {
        return 0.0;
    }
    let n = significant_digits.max(1) as i32;
    let mut l = u.log10().floor() as i32 - (n - 1);
    if (u / 10f64.powi(l)).round() >= 10f64.powi(n) {
        l += 1;
    }
    0.5 * 10f64.powi(l)
}

/// The shortest `p` coverage interval of sorted values (JCGM 101 §7.7.2): the `r*`
/// minimizing `y_(r+q) − y_(r)`, `q` as in [`symmetric_interval_positions`].
pub(crate) fn shortest_interval(sorted: &[f64], p: f64) -> (f64, f64) {
    let m = sorted.len();
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    let q = r_high - r_low;
    let (best, _) = (0..m - q).fold((0, f64::INFINITY), |(best, width), i| {
        let w = sorted[i + q] - sorted[i];
        if w < width { (i, w) } else { (best, width) }
    });
    (sorted[best], sorted[best + q])
}

fn mean(values: &[f64]) -> f64 {
    // Pairwise-ish: sum in chunks to keep rounding small.
    let sum: f64 = values.chunks(4096).map(|c| c.iter().sum::<f64>()).sum();
    sum / values.len() as f64
}

fn standard_deviation(values: &[f64]) -> f64 {
    let n = values.len();
    if n < 2 {
        return 0.0;
    }
    let m = mean(values);
    let ss: f64 = values
        .chunks(4096)
        .map(|c| c.iter().map(|v| (v - m) * (v - m)).sum::<f64>())
        .sum();
    (ss / (n - 1) as f64).sqrt()
}

/// `s(x̄) = √(Σ(x_r − x̄)²/(h(h − 1)))` (JCGM 101 §7.9.4 f).
pub(crate) fn standard_deviation_of_mean(xs: &[f64]) -> f64 {
    standard_deviation(xs) / (xs.len() as f64).sqrt()
}

/// The `i`-th smallest value (0-based); reorders `values`.
pub(crate) fn order_statistic(values: &mut [f64], i: usize) -> f64 {
    *values.select_nth_unstable_by(i, f64::total_cmp).1
}

/// Running sums and bracket contents of some trials.
pub(crate) struct Acc {
    /// Σ (x − c) and Σ (x − c)², c the centre.
    pub(crate) s1: Vec<f64>,
    pub(crate) s2: Vec<f64>,
    /// Values below the low bracket, and above the high bracket.
    outside: Vec<[u64; 2]>,
    /// Values inside the low and the high bracket.
    inside: Vec<[Vec<f64>; 2]>,
}

impl Acc {
    pub(crate) fn new(outputs: usize) -> Self {
        Acc {
            s1: vec![0.0; outputs],
            s2: vec![0.0; outputs],
            outside: vec![[0; 2]; outputs],
            inside: (0..outputs).map(|_| [Vec::new(), Vec::new()]).collect(),
        }
    }

    /// Adds the outputs of one trial.
    #[inline]
    pub(crate) fn record(&mut self, out: &[f64], centre: &[f64], brackets: &[[f64; 4]]) {
        for ((s1, s2), (&x, &c)) in self
            .s1
            .iter_mut()
            .zip(self.s2.iter_mut())
            .zip(out.iter().zip(centre))
        {
            let d = x - c;
            *s1 += d;
            *s2 += d * d;
        }
        for (j, (&x, b)) in out.iter().zip(brackets).enumerate() {
            if x > b[1] && x < b[2] {
                continue; // between the brackets, the common case: nothing to count
            }
            if x < b[0] {
                self.outside[j][0] += 1;
            } else if x <= b[1] {
                self.inside[j][0].push(x);
            }
            if x > b[3] {
                self.outside[j][1] += 1;
            } else if x >= b[2] {
                self.inside[j][1].push(x);
            }
        }
    }

    /// Adds trial-major outputs in trial order.
    pub(crate) fn feed(&mut self, raw: &[f64], centre: &[f64], brackets: &[[f64; 4]]) {
        for out in raw.chunks_exact(centre.len()) {
            self.record(out, centre, brackets);
        }
    }

    /// Adds the sums and bracket contents of later trials.
    pub(crate) fn merge(&mut self, other: Acc) {
        for j in 0..self.s1.len() {
            self.s1[j] += other.s1[j];
            self.s2[j] += other.s2[j];
            for side in 0..2 {
                self.outside[j][side] += other.outside[j][side];
            }
        }
        for (mine, [low, high]) in self.inside.iter_mut().zip(other.inside) {
            mine[0].extend(low);
            mine[1].extend(high);
        }
    }
}

/// Brackets around the interval ends of `m` trials from the sorted pilot columns,
/// `factor` times wider than a 6-σ binomial margin; ±∞ beyond the pilot.
pub(crate) fn brackets_from(pilot: &[Vec<f64>], m: usize, p: f64, factor: f64) -> Brackets {
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    pilot
        .iter()
        .map(|sorted| {
            let len = sorted.len();
            let mut b = [0.0; 4];
            for (side, r) in [r_low, r_high].into_iter().enumerate() {
                let pi = (r as f64 + 0.5) / m as f64;
                let centre = pi * len as f64;
                let margin = factor * (6.0 * (len as f64 * pi * (1.0 - pi)).sqrt() + 10.0);
                let lo = centre - margin;
                let hi = centre + margin;
                b[2 * side] = if lo < 0.0 {
                    f64::NEG_INFINITY
                } else {
                    sorted[lo as usize]
                };
                b[2 * side + 1] = if hi >= (len - 1) as f64 {
                    f64::INFINITY
                } else {
                    sorted[hi.ceil() as usize]
                };
            }
            b
        })
        .collect()
}

/// The columns (one per output) of trial-major outputs.
pub(crate) fn columns(raw: &[f64], outputs: usize) -> Vec<Vec<f64>> {
    (0..outputs)
        .into_par_iter()
        .map(|j| raw.iter().skip(j).step_by(outputs).copied().collect())
        .collect()
}

/// Sorted columns of trial-major outputs.
pub(crate) fn sorted_columns(raw: &[f64], outputs: usize) -> Vec<Vec<f64>> {
    let mut columns = columns(raw, outputs);
    columns
        .par_iter_mut()
        .for_each(|column| column.sort_unstable_by(f64::total_cmp));
    columns
}

/// Mean, u and the exact interval of `m` accumulated trials; `None` if a bracket missed
/// its order statistic.
pub(crate) fn finish(acc: Acc, m: usize, p: f64, centre: &[f64]) -> Option<Moments> {
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    let mf = m as f64;
    let mut mean = Vec::with_capacity(centre.len());
    let mut u = Vec::with_capacity(centre.len());
    let mut low = Vec::with_capacity(centre.len());
    let mut high = Vec::with_capacity(centre.len());
    for (j, [mut in_low, mut in_high]) in acc.inside.into_iter().enumerate() {
        mean.push(centre[j] + acc.s1[j] / mf);
        let ss = acc.s2[j] - acc.s1[j] * acc.s1[j] / mf;
        u.push(if m > 1 {
            (ss.max(0.0) / (mf - 1.0)).sqrt()
        } else {
            0.0
        });
        for (side, r, values, target) in [
            (0, r_low, &mut in_low, &mut low),
            (1, r_high, &mut in_high, &mut high),
        ] {
            // values below the bracket: counted below the low one; all but those in
            // and above the high one
            let below = if side == 0 {
                acc.outside[j][0] as usize
            } else {
                m - acc.outside[j][1] as usize - values.len()
            };
            if r < below || r >= below + values.len() {
                return None;
            }
            target.push(order_statistic(values, r - below));
        }
    }
    Some((mean, u, low, high))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bracket too narrow to hold its order statistic is reported, and brackets from
    /// the pilot give the interval a full sort gives.
    #[test]
    fn missed_brackets_are_reported() {
        let raw: Vec<f64> = (0..2000).map(|i| ((i * 7919) % 2000) as f64).collect();
        let centre = [0.0];
        let brackets = vec![[10.0, 11.0, 1900.0, 1901.0]];
        let mut acc = Acc::new(1);
        acc.feed(&raw, &centre, &brackets);
        assert!(finish(acc, 2000, 0.95, &centre).is_none());
        let pilot = sorted_columns(&raw, 1);
        let brackets = brackets_from(&pilot, 2000, 0.95, 1.0);
        let mut acc = Acc::new(1);
        acc.feed(&raw, &centre, &brackets);
        let (_, _, low, high) = finish(acc, 2000, 0.95, &centre).unwrap();
        let (r_low, r_high) = symmetric_interval_positions(2000, 0.95);
        assert_eq!((low[0], high[0]), (pilot[0][r_low], pilot[0][r_high]));
    }

    /// The shortest interval of a skewed sample lies towards its mode.
    #[test]
    fn shortest_interval_of_a_skewed_sample() {
        // 0, 1, 4, 9, …: dense near 0.
        let sorted: Vec<f64> = (0..1000).map(|i| (i * i) as f64).collect();
        let (lo, hi) = shortest_interval(&sorted, 0.95);
        let (r_low, r_high) = symmetric_interval_positions(1000, 0.95);
        assert_eq!((lo, hi), (0.0, sorted[r_high - r_low]));
    }
}
