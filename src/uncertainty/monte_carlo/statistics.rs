//! The statistics of Monte Carlo outputs (JCGM 101 §7.6–§7.9): running sums for the mean
//! and the standard uncertainty, the exact order statistics of the probabilistically
//! symmetric coverage interval from brackets, the shortest interval, and the numerical
//! tolerance of the adaptive procedure.
//!
//! The interval ends are order statistics of all `M` values. Rather than storing and
//! sorting them, a pilot of the first trials brackets each end: the pilot's order
//! statistics (found by selection, not a sort) give, for the wanted rank, a range of
//! values that holds it with a margin of six binomial standard deviations (plus ten).
//! The trials are then counted below the low bracket and above the high one, and the few
//! inside a bracket are kept; the order statistic is selected among those. After more
//! trials the brackets can be refined the same way from the values kept so far
//! ([`Acc::refine`]), narrower and inside the old ones. A bracket that did not hold its
//! rank is reported by [`finish`], and the engine widens it and runs the trials again.

use rayon::prelude::*;

/// Per output: mean, u, low and high end of the interval.
pub(crate) type Moments = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

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

/// Per output, the two brackets around the interval ends: values in
/// `[low_from, low_to]` and in `[high_from, high_to]` are kept, values below `low_from`
/// and above `high_to` only counted (one vector per bound, for the vector units).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Brackets {
    low_from: Vec<f64>,
    low_to: Vec<f64>,
    high_from: Vec<f64>,
    high_to: Vec<f64>,
}

impl Brackets {
    /// Brackets that keep every value (both reach from −∞ to +∞).
    pub(crate) fn everything(outputs: usize) -> Self {
        Brackets {
            low_from: vec![f64::NEG_INFINITY; outputs],
            low_to: vec![f64::INFINITY; outputs],
            high_from: vec![f64::NEG_INFINITY; outputs],
            high_to: vec![f64::INFINITY; outputs],
        }
    }
}

/// Trials recorded together by [`Acc::record_rows`].
pub(crate) const ROWS: usize = 8;

/// Some trials' outputs against the running sums and counts of every output.
struct Columns<'a> {
    /// Trials, trial-major: output j of row r at `r·n + j`.
    rows: &'a [f64],
    centre: &'a [f64],
    /// Low bracket from, to; high bracket from, to.
    brackets: [&'a [f64]; 4],
    s1: &'a mut [f64],
    s2: &'a mut [f64],
    below: &'a mut [u64],
    above: &'a mut [u64],
    /// Per row and output: 1 if inside the low bracket, 2 the high, 3 both.
    hits: &'a mut [u64],
}

impl Columns<'_> {
    /// Adds the rows, one after the other, to the sums and counts and marks the values
    /// inside a bracket: no branch, in the vector units (across the outputs), the same
    /// arithmetic value by value whatever the vector width.
    #[inline(always)]
    fn add(&mut self) {
        let n = self.centre.len();
        let [low_from, low_to, high_from, high_to] = self.brackets;
        let (centre, low_from, low_to) = (&self.centre[..n], &low_from[..n], &low_to[..n]);
        let (high_from, high_to) = (&high_from[..n], &high_to[..n]);
        let (s1, s2) = (&mut self.s1[..n], &mut self.s2[..n]);
        let (below, above) = (&mut self.below[..n], &mut self.above[..n]);
        for (out, hits) in self.rows.chunks_exact(n).zip(self.hits.chunks_exact_mut(n)) {
            for j in 0..n {
                let x = out[j];
                let d = x - centre[j];
                s1[j] += d;
                s2[j] += d * d;
                below[j] += u64::from(x < low_from[j]);
                above[j] += u64::from(x > high_to[j]);
                let low = (x >= low_from[j]) & (x <= low_to[j]);
                let high = (x >= high_from[j]) & (x <= high_to[j]);
                hits[j] = u64::from(low) | (u64::from(high) << 1);
            }
        }
    }

    /// [`Columns::add`] with the AVX2 vector units (four outputs at a time).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn add_avx2(&mut self) {
        self.add()
    }

    /// [`Columns::add`], with the vector units the processor has.
    fn add_fastest(&mut self) {
        #[cfg(target_arch = "x86_64")]
        if super::stream::has_avx2() {
            // SAFETY: the processor has AVX2 (just checked).
            unsafe { self.add_avx2() };
            return;
        }
        self.add()
    }
}

/// Running sums and bracket contents of some trials.
pub(crate) struct Acc {
    /// Σ (x − c) and Σ (x − c)², c the centre.
    pub(crate) s1: Vec<f64>,
    pub(crate) s2: Vec<f64>,
    /// Values below the low bracket, and above the high bracket.
    below: Vec<u64>,
    above: Vec<u64>,
    /// Values inside a bracket, in no order: (2j for the low bracket of output j,
    /// 2j + 1 for the high one; the value). One store per block of trials.
    inside: Vec<(u32, f64)>,
    /// The bracket contents of the accumulators merged into this one.
    merged: Vec<Vec<(u32, f64)>>,
    /// Per row and output of the last trials recorded: 1 if inside the low bracket, 2
    /// the high, 3 both.
    hits: Vec<u64>,
}

impl Acc {
    pub(crate) fn new(outputs: usize) -> Self {
        Acc::with_capacity(outputs, 0)
    }

    /// An accumulator with room for `values` bracket contents.
    pub(crate) fn with_capacity(outputs: usize, values: usize) -> Self {
        Acc {
            s1: vec![0.0; outputs],
            s2: vec![0.0; outputs],
            below: vec![0; outputs],
            above: vec![0; outputs],
            inside: Vec::with_capacity(values),
            merged: Vec::new(),
            hits: vec![0; ROWS * outputs],
        }
    }

    /// Adds the outputs of some trials, trial-major (`rows` of [`ROWS`] or fewer trials),
    /// as one trial after the other.
    #[inline]
    pub(crate) fn record_rows(&mut self, rows: &[f64], centre: &[f64], brackets: &Brackets) {
        let n = centre.len();
        let count = rows.len() / n;
        debug_assert!(count <= ROWS && rows.len() == count * n);
        Columns {
            rows,
            centre,
            brackets: [
                &brackets.low_from,
                &brackets.low_to,
                &brackets.high_from,
                &brackets.high_to,
            ],
            s1: &mut self.s1,
            s2: &mut self.s2,
            below: &mut self.below,
            above: &mut self.above,
            hits: &mut self.hits[..count * n],
        }
        .add_fastest();
        // The few values inside a bracket (about 2 % of the trials at each end, fewer
        // after a refinement).
        let hits = self.hits[..count * n].chunks_exact(n);
        for (hits, out) in hits.zip(rows.chunks_exact(n)) {
            for (j, (&hit, &x)) in hits.iter().zip(out).enumerate() {
                if hit != 0 {
                    if hit & 1 != 0 {
                        self.inside.push((2 * j as u32, x));
                    }
                    if hit & 2 != 0 {
                        self.inside.push((2 * j as u32 + 1, x));
                    }
                }
            }
        }
    }

    /// Adds trial-major outputs in trial order.
    pub(crate) fn feed(&mut self, raw: &[f64], centre: &[f64], brackets: &Brackets) {
        for rows in raw.chunks(ROWS * centre.len()) {
            self.record_rows(rows, centre, brackets);
        }
    }

    /// Adds the sums and bracket contents of later trials.
    pub(crate) fn merge(&mut self, other: Acc) {
        for j in 0..self.s1.len() {
            self.s1[j] += other.s1[j];
            self.s2[j] += other.s2[j];
            self.below[j] += other.below[j];
            self.above[j] += other.above[j];
        }
        self.merged.push(other.inside);
        self.merged.extend(other.merged);
    }

    /// The number of values kept inside the brackets (what the accumulator's memory grows
    /// with: 16 bytes each).
    pub(crate) fn kept(&self) -> usize {
        self.inside.len() + self.merged.iter().map(Vec::len).sum::<usize>()
    }

    /// Gives back the room reserved beyond the values kept when the store is more than
    /// half empty (a block's store is reserved for the values expected inside).
    pub(crate) fn shrink(&mut self) {
        if self.inside.capacity() > 2 * self.inside.len() + 64 {
            self.inside.shrink_to_fit();
        }
    }

    /// The values inside every bracket so far, per bracket (2j low, 2j + 1 high); the
    /// accumulator keeps none. Each store is freed as soon as its values are bucketed, so
    /// that the values are held about once, not twice.
    fn take_inside(&mut self) -> Vec<Vec<f64>> {
        let mut chunks = std::mem::take(&mut self.merged);
        chunks.push(std::mem::take(&mut self.inside));
        let brackets = 2 * self.s1.len();
        let bucket = |chunks: Vec<Vec<(u32, f64)>>| {
            let mut counts = vec![0; brackets];
            for &(i, _) in chunks.iter().flatten() {
                counts[i as usize] += 1;
            }
            let mut buckets: Vec<Vec<f64>> = counts.into_iter().map(Vec::with_capacity).collect();
            for chunk in chunks {
                for (i, x) in chunk {
                    buckets[i as usize].push(x);
                }
            }
            buckets
        };
        // Two halves side by side, then joined: the order of the values does not matter.
        let second = chunks.split_off(chunks.len() / 2);
        let (mut a, b) = rayon::join(|| bucket(chunks), || bucket(second));
        for (a, b) in a.iter_mut().zip(b) {
            a.extend(b);
        }
        a
    }
}

impl Acc {
    /// Narrower brackets for the interval ends of `m` trials from the `s` trials
    /// accumulated so far with `brackets`: each bound is the order statistic of the `s`
    /// trials at a 6-σ binomial margin (times `factor`) around the rank the end will have,
    /// found among the values kept, or the old bound where the margin reaches beyond
    /// them. The kept values and the counts are re-classified against the new brackets,
    /// which lie inside the old ones, so that later trials can be accumulated with them.
    pub(crate) fn refine(
        &mut self,
        s: usize,
        m: usize,
        p: f64,
        factor: f64,
        brackets: &Brackets,
    ) -> Brackets {
        let (r_low, r_high) = symmetric_interval_positions(m, p);
        let inside = self.take_inside();
        let refined: Vec<(Vec<f64>, u64, f64, f64)> = inside
            .into_par_iter()
            .enumerate()
            .map(|(i, mut kept)| {
                let (j, side) = (i / 2, i % 2);
                let (old_from, old_to) = if side == 0 {
                    (brackets.low_from[j], brackets.low_to[j])
                } else {
                    (brackets.high_from[j], brackets.high_to[j])
                };
                // The rank (among the s trials) of the smallest kept value.
                let first = if side == 0 {
                    self.below[j] as usize
                } else {
                    s - self.above[j] as usize - kept.len()
                };
                let r = if side == 0 { r_low } else { r_high };
                let pi = (r as f64 + 0.5) / m as f64;
                let centre = pi * s as f64;
                let margin = rank_margin(s, pi, factor);
                let index = |rank: f64| {
                    let k = rank - first as f64;
                    (k >= 0.0 && k < kept.len() as f64).then_some(k as usize)
                };
                let lo = index((centre - margin).floor());
                let hi = index((centre + margin).ceil());
                let mut wanted: Vec<usize> = [lo, hi].into_iter().flatten().collect();
                wanted.dedup();
                let values = select_ranks(&mut kept, &wanted);
                let value = |k: Option<usize>, old: f64| match k {
                    Some(k) => values[wanted.partition_point(|&w| w < k)],
                    None => old,
                };
                let (from, to) = (value(lo, old_from), value(hi, old_to));
                let outside = if side == 0 {
                    kept.iter().filter(|&&x| x < from).count()
                } else {
                    kept.iter().filter(|&&x| x > to).count()
                };
                kept.retain(|&x| x >= from && x <= to);
                (kept, outside as u64, from, to)
            })
            .collect();
        let mut refined_brackets = brackets.clone();
        for (i, (kept, outside, from, to)) in refined.into_iter().enumerate() {
            let j = i / 2;
            if i % 2 == 0 {
                self.below[j] += outside;
                refined_brackets.low_from[j] = from;
                refined_brackets.low_to[j] = to;
            } else {
                self.above[j] += outside;
                refined_brackets.high_from[j] = from;
                refined_brackets.high_to[j] = to;
            }
            self.inside.extend(kept.into_iter().map(|x| (i as u32, x)));
        }
        refined_brackets
    }
}

/// The half-width, in ranks among `s` trials, of a bracket around the order statistic
/// at fraction `pi`: six binomial standard deviations plus ten, times `factor`.
pub(crate) fn rank_margin(s: usize, pi: f64, factor: f64) -> f64 {
    factor * (6.0 * (s as f64 * pi * (1.0 - pi)).sqrt() + 10.0)
}

/// The values at the ascending 0-based `ranks` of `values` (as a full sort would place
/// them), by successive selection; reorders `values`.
fn select_ranks(values: &mut [f64], ranks: &[usize]) -> Vec<f64> {
    let mut start = 0;
    let mut last: Option<(usize, f64)> = None;
    ranks
        .iter()
        .map(|&r| {
            if let Some((at, v)) = last
                && at == r
            {
                return v;
            }
            let v = *values[start..]
                .select_nth_unstable_by(r - start, f64::total_cmp)
                .1;
            start = r + 1;
            last = Some((r, v));
            v
        })
        .collect()
}

/// Brackets around the interval ends of `m` trials from the pilot columns (one per
/// output, reordered), `factor` times wider than a 6-σ binomial margin; ±∞ beyond the
/// pilot. Each bound is an order statistic of the pilot, found by selection.
pub(crate) fn brackets_from(pilot: &mut [Vec<f64>], m: usize, p: f64, factor: f64) -> Brackets {
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    let bounds: Vec<[f64; 4]> = pilot
        .par_iter_mut()
        .map(|column| {
            let len = column.len();
            // Per bound: the rank in the pilot, or None for ±∞.
            let mut ranks = [None; 4];
            for (side, r) in [r_low, r_high].into_iter().enumerate() {
                let pi = (r as f64 + 0.5) / m as f64;
                let centre = pi * len as f64;
                let margin = rank_margin(len, pi, factor);
                let lo = centre - margin;
                let hi = centre + margin;
                ranks[2 * side] = (lo >= 0.0).then_some(lo as usize);
                ranks[2 * side + 1] = (hi < (len - 1) as f64).then(|| hi.ceil() as usize);
            }
            let mut wanted: Vec<usize> = ranks.iter().flatten().copied().collect();
            wanted.sort_unstable();
            let values = select_ranks(column, &wanted);
            let value = |rank: Option<usize>, infinite: f64| match rank {
                Some(r) => values[wanted.partition_point(|&w| w < r)],
                None => infinite,
            };
            [
                value(ranks[0], f64::NEG_INFINITY),
                value(ranks[1], f64::INFINITY),
                value(ranks[2], f64::NEG_INFINITY),
                value(ranks[3], f64::INFINITY),
            ]
        })
        .collect();
    Brackets {
        low_from: bounds.iter().map(|b| b[0]).collect(),
        low_to: bounds.iter().map(|b| b[1]).collect(),
        high_from: bounds.iter().map(|b| b[2]).collect(),
        high_to: bounds.iter().map(|b| b[3]).collect(),
    }
}

/// Bytes of columns [`brackets_from_raw`] forms at a time.
pub(crate) const COLUMN_BYTES: usize = 16 << 20;

/// [`brackets_from`] of trial-major outputs (`outputs` values per trial), without
/// holding a second copy of them: the columns are formed and bracketed a few outputs at
/// a time (at most [`COLUMN_BYTES`] of them).
pub(crate) fn brackets_from_raw(
    raw: &[f64],
    outputs: usize,
    m: usize,
    p: f64,
    factor: f64,
) -> Brackets {
    let trials = (raw.len() / outputs).max(1);
    let chunk = (COLUMN_BYTES / (8 * trials)).max(2);
    let mut all = Brackets {
        low_from: Vec::with_capacity(outputs),
        low_to: Vec::with_capacity(outputs),
        high_from: Vec::with_capacity(outputs),
        high_to: Vec::with_capacity(outputs),
    };
    let mut from = 0;
    while from < outputs {
        let to = (from + chunk).min(outputs);
        let b = brackets_from(&mut columns_of(raw, outputs, from..to), m, p, factor);
        all.low_from.extend(b.low_from);
        all.low_to.extend(b.low_to);
        all.high_from.extend(b.high_from);
        all.high_to.extend(b.high_to);
        from = to;
    }
    all
}

/// The columns (one per output) of trial-major outputs: the trials read in order, in
/// two halves of the outputs side by side.
pub(crate) fn columns(raw: &[f64], outputs: usize) -> Vec<Vec<f64>> {
    columns_of(raw, outputs, 0..outputs)
}

/// The columns of outputs `range` of trial-major outputs (`outputs` values per trial).
fn columns_of(raw: &[f64], outputs: usize, range: std::ops::Range<usize>) -> Vec<Vec<f64>> {
    let trials = raw.len() / outputs;
    let some = |from: usize, to: usize| {
        let mut columns: Vec<Vec<f64>> = (from..to).map(|_| Vec::with_capacity(trials)).collect();
        for row in raw.chunks_exact(outputs) {
            for (column, &x) in columns.iter_mut().zip(&row[from..to]) {
                column.push(x);
            }
        }
        columns
    };
    let half = range.start + range.len() / 2;
    let (mut first, second) = rayon::join(|| some(range.start, half), || some(half, range.end));
    first.extend(second);
    first
}

/// Mean, u and the exact interval of `m` accumulated trials; `None` if a bracket missed
/// its order statistic.
pub(crate) fn finish(mut acc: Acc, m: usize, p: f64, centre: &[f64]) -> Option<Moments> {
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    let mf = m as f64;
    let mut inside = acc.take_inside();
    let per_output: Vec<Option<[f64; 4]>> = inside
        .par_chunks_mut(2)
        .enumerate()
        .map(|(j, values)| {
            let mean = centre[j] + acc.s1[j] / mf;
            let ss = acc.s2[j] - acc.s1[j] * acc.s1[j] / mf;
            let u = if m > 1 {
                (ss.max(0.0) / (mf - 1.0)).sqrt()
            } else {
                0.0
            };
            let mut ends = [0.0; 2];
            for (side, r) in [(0, r_low), (1, r_high)] {
                let values = &mut values[side];
                // values below the bracket: counted below the low one; all but those in
                // and above the high one
                let below = if side == 0 {
                    acc.below[j] as usize
                } else {
                    m - acc.above[j] as usize - values.len()
                };
                if r < below || r >= below + values.len() {
                    return None;
                }
                ends[side] = order_statistic(values, r - below);
            }
            Some([mean, u, ends[0], ends[1]])
        })
        .collect();
    let mut moments: Moments = (
        Vec::with_capacity(centre.len()),
        Vec::with_capacity(centre.len()),
        Vec::with_capacity(centre.len()),
        Vec::with_capacity(centre.len()),
    );
    for [mean, u, low, high] in per_output.into_iter().collect::<Option<Vec<_>>>()? {
        moments.0.push(mean);
        moments.1.push(u);
        moments.2.push(low);
        moments.3.push(high);
    }
    Some(moments)
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
        let brackets = Brackets {
            low_from: vec![10.0],
            low_to: vec![11.0],
            high_from: vec![1900.0],
            high_to: vec![1901.0],
        };
        let mut acc = Acc::new(1);
        acc.feed(&raw, &centre, &brackets);
        assert!(finish(acc, 2000, 0.95, &centre).is_none());
        let mut pilot = columns(&raw, 1);
        let brackets = brackets_from(&mut pilot, 2000, 0.95, 1.0);
        let mut sorted = raw.clone();
        sorted.sort_unstable_by(f64::total_cmp);
        // The bounds are the pilot's order statistics at the 6-σ margins (the values are
        // 0 … 1999, so value = rank), ±∞ beyond the pilot.
        let margin = |pi: f64| 6.0 * (2000.0 * pi * (1.0 - pi)).sqrt() + 10.0;
        let (low, high) = (49.5 / 2000.0, 1949.5 / 2000.0);
        assert_eq!(brackets.low_from[0], f64::NEG_INFINITY);
        assert_eq!(brackets.low_to[0], (49.5 + margin(low)).ceil());
        assert_eq!(brackets.high_from[0], (1949.5 - margin(high)).floor());
        assert_eq!(brackets.high_to[0], f64::INFINITY);
        // Fed in two halves, merged: the same interval as a full sort.
        let mut acc = Acc::new(1);
        acc.feed(&raw[..700], &centre, &brackets);
        let mut rest = Acc::new(1);
        rest.feed(&raw[700..], &centre, &brackets);
        acc.merge(rest);
        let (_, _, low, high) = finish(acc, 2000, 0.95, &centre).unwrap();
        let (r_low, r_high) = symmetric_interval_positions(2000, 0.95);
        assert_eq!((low[0], high[0]), (sorted[r_low], sorted[r_high]));
    }

    /// Brackets refined after part of the trials lie inside the old ones, are narrower,
    /// and give the interval a full sort gives.
    #[test]
    fn refined_brackets_hold_the_order_statistics() {
        // 0 … 99 999 in a scrambled order (7919 and 10⁵ are coprime).
        let m = 100_000;
        let raw: Vec<f64> = (0..m).map(|i| ((i * 7919) % m) as f64).collect();
        let centre = [0.0];
        let mut pilot = columns(&raw[..2_000], 1);
        let old = brackets_from(&mut pilot, m, 0.95, 1.0);
        let mut acc = Acc::new(1);
        acc.feed(&raw[..20_000], &centre, &old);
        let new = acc.refine(20_000, m, 0.95, 1.0, &old);
        assert!(old.low_from[0] <= new.low_from[0] && new.low_to[0] <= old.low_to[0]);
        assert!(old.high_from[0] <= new.high_from[0] && new.high_to[0] <= old.high_to[0]);
        assert!(new.low_to[0] - new.low_from[0] < 0.6 * (old.low_to[0] - old.low_from[0]));
        let mut rest = Acc::new(1);
        rest.feed(&raw[20_000..], &centre, &new);
        acc.merge(rest);
        let (_, _, low, high) = finish(acc, m, 0.95, &centre).unwrap();
        let (r_low, r_high) = symmetric_interval_positions(m, 0.95);
        assert_eq!((low[0], high[0]), (r_low as f64, r_high as f64));
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
