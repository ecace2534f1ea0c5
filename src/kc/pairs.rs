//! Every pair of laboratories of a key comparison, d_ij and U(d_ij), formed when they are
//! read rather than stored: 100 laboratories × 3 000 faces make 4 950 pairs and 30 million
//! numbers (240 MB), from 100 closed vectors and their variances (5 MB). The numbers are
//! those the evaluation computed before, to the last bit: the same operations on the same
//! scaled values.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::closed::{self, ClosedCovariance};
use super::evaluate::vector_test;
use super::reference::chi2_quantile_95;
use super::scaled::Scaled;
use super::{PairDifference, VectorTest};

/// Every pair of laboratories (a before b, in the order given), each a
/// [`PairDifference`]: d_ab = x_a − x_b and U(d_ab) = 2·√(v_a + v_b) per position (the
/// diagonals of the laboratories' covariances, u_stab and τ in them), and the pair's one
/// closed-vector test (docs/FORMAT.md §12). Iterate it (`for pair in &kc.pairs`) or take one with
/// [`Pairs::get`]; it serializes as the JSON list `pairs` and reads back from it.
#[derive(Debug, Clone)]
pub struct Pairs(Held);

/// What the pairs are formed from.
#[derive(Debug, Clone)]
enum Held {
    /// From each laboratory's closed vector and variances.
    Formed(Formed),
    /// As listed (read back from a key comparison's JSON).
    Listed(Vec<PairDifference>),
}

/// Each laboratory's closed vector and variances, in units of `scale`.
#[derive(Debug, Clone)]
struct Formed {
    /// The laboratories, in the order given.
    labs: Vec<String>,
    /// Per laboratory, its closed values, in units of `scale`.
    values: Vec<Vec<f64>>,
    /// Per laboratory, the variances of its closed values, in units of `scale`².
    variances: Vec<Vec<f64>>,
    /// Each pair's closed-vector test, in the order of [`Pairs::iter`].
    vectors: Vec<Option<VectorTest>>,
    /// Whether each pair's d is closed over the positions both report (closed results
    /// that report different positions: each is closed over its own).
    closed_over_common: bool,
    /// The unit of `values`, arcseconds.
    scale: f64,
}

impl Formed {
    /// The pair of laboratories `a` and `b`: d_ab = (x_a − x_b)·scale,
    /// U(d_ab) = 2·√(v_a + v_b)·scale.
    fn pair(&self, a: usize, b: usize) -> PairDifference {
        let scale = self.scale;
        let n = self.labs.len();
        // pairs (0, 1) … (0, n−1), (1, 2) …: those before row a, then b's place in it
        let at = a * n - a * (a + 1) / 2 + (b - a - 1);
        let d: Vec<f64> = self.values[a]
            .iter()
            .zip(&self.values[b])
            .map(|(x_a, x_b)| (x_a - x_b) * scale)
            .collect();
        if self.closed_over_common {
            return self.closed_over_common(a, b, d, at);
        }
        PairDifference {
            a: self.labs[a].clone(),
            b: self.labs[b].clone(),
            d,
            expanded_u: self.variances[a]
                .iter()
                .zip(&self.variances[b])
                .map(|(v_a, v_b)| {
                    let v = v_a + v_b;
                    // not reported by either (an angle block): no U, as no d
                    if v.is_finite() {
                        2.0 * v.sqrt() * scale
                    } else {
                        f64::NAN
                    }
                })
                .collect(),
            vector: self.vectors.get(at).cloned().flatten(),
        }
    }
}

impl Formed {
    /// The pair `a`, `b` of closed results that report different positions: d closed over
    /// the M positions both report, its covariance P·D·P with D = diag(c_a·u_a² + c_b·u_b²)
    /// (`variances` hold each laboratory's c·u², c = N/(N − 1) of its own N positions),
    /// so U(d_ab) = 2·√(D_k(1 − 2/M) + Σ D/M²): the covariance its test uses.
    fn closed_over_common(&self, a: usize, b: usize, mut d: Vec<f64>, at: usize) -> PairDifference {
        let scale = self.scale;
        let sum_d: Vec<f64> = self.variances[a]
            .iter()
            .zip(&self.variances[b])
            .map(|(v_a, v_b)| v_a + v_b)
            .collect();
        let common: Vec<bool> = (0..d.len())
            .map(|k| d[k].is_finite() && sum_d[k].is_finite())
            .collect();
        let count = common.iter().filter(|c| **c).count();
        let m = count as f64;
        let mean = (0..d.len())
            .filter(|&k| common[k])
            .map(|k| d[k])
            .sum::<f64>()
            / m.max(1.0);
        let total: f64 = (0..d.len()).filter(|&k| common[k]).map(|k| sum_d[k]).sum();
        let mut expanded_u = vec![f64::NAN; d.len()];
        for (k, d) in d.iter_mut().enumerate() {
            // closed over one common position a difference is 0 by construction: not given
            if !common[k] || count < 2 {
                *d = f64::NAN;
                continue;
            }
            *d -= mean;
            let v = sum_d[k] * (1.0 - 2.0 / m) + total / (m * m);
            expanded_u[k] = 2.0 * v.max(0.0).sqrt() * scale;
        }
        PairDifference {
            a: self.labs[a].clone(),
            b: self.labs[b].clone(),
            d,
            expanded_u,
            vector: self.vectors.get(at).cloned().flatten(),
        }
    }
}

impl Pairs {
    /// The pairs of the laboratories `labs`, from their closed `values` and their
    /// `variances` per position (both in units of `scale` arcsec, one list per
    /// laboratory, in the order of `labs`), with each pair's test `vectors` in the order of
    /// [`Pairs::iter`].
    pub(crate) fn formed(
        labs: Vec<String>,
        closed_over_common: bool,
        values: Vec<Vec<f64>>,
        variances: Vec<Vec<f64>>,
        vectors: Vec<Option<VectorTest>>,
        scale: f64,
    ) -> Pairs {
        Pairs(Held::Formed(Formed {
            labs,
            values,
            variances,
            vectors,
            closed_over_common,
            scale,
        }))
    }

    /// How many pairs: n(n − 1)/2 of n laboratories.
    pub fn len(&self) -> usize {
        match &self.0 {
            Held::Formed(formed) => {
                let n = formed.labs.len();
                n * n.saturating_sub(1) / 2
            }
            Held::Listed(list) => list.len(),
        }
    }

    /// Whether there is no pair.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Pair `i` (in the order of [`Pairs::iter`]), or `None` beyond the last.
    pub fn get(&self, i: usize) -> Option<PairDifference> {
        match &self.0 {
            Held::Listed(list) => list.get(i).cloned(),
            Held::Formed(formed) => {
                // Pairs (0, 1) … (0, n−1), (1, 2) …: find the row a that holds i.
                let n = formed.labs.len();
                let mut first = 0;
                for a in 0..n {
                    let in_row = n - a - 1;
                    if i < first + in_row {
                        return Some(formed.pair(a, a + 1 + (i - first)));
                    }
                    first += in_row;
                }
                None
            }
        }
    }

    /// Every pair: (A, B), (A, C), … (B, C), … for the laboratories in the order given.
    pub fn iter(&self) -> PairsIter<'_> {
        PairsIter {
            pairs: self,
            a: 0,
            b: 1,
            listed: 0,
        }
    }

    /// Applies `fix` to every laboratory name the pairs carry (the table escapes them).
    pub(crate) fn for_each_name(&mut self, mut fix: impl FnMut(&mut String)) {
        match &mut self.0 {
            Held::Formed(formed) => formed.labs.iter_mut().for_each(fix),
            Held::Listed(list) => {
                for pair in list {
                    fix(&mut pair.a);
                    fix(&mut pair.b);
                }
            }
        }
    }
}

impl From<Vec<PairDifference>> for Pairs {
    /// Pairs as listed, in the order given.
    fn from(list: Vec<PairDifference>) -> Pairs {
        Pairs(Held::Listed(list))
    }
}

/// The pairs one by one, each formed as it is reached ([`Pairs::iter`]).
#[derive(Debug, Clone)]
pub struct PairsIter<'a> {
    pairs: &'a Pairs,
    a: usize,
    b: usize,
    listed: usize,
}

impl Iterator for PairsIter<'_> {
    type Item = PairDifference;

    fn next(&mut self) -> Option<PairDifference> {
        match &self.pairs.0 {
            Held::Listed(list) => {
                let pair = list.get(self.listed).cloned();
                self.listed += 1;
                pair
            }
            Held::Formed(formed) => {
                let n = formed.labs.len();
                if self.b >= n {
                    return None;
                }
                let pair = formed.pair(self.a, self.b);
                self.b += 1;
                if self.b == n {
                    self.a += 1;
                    self.b = self.a + 1;
                }
                Some(pair)
            }
        }
    }
}

impl<'a> IntoIterator for &'a Pairs {
    type Item = PairDifference;
    type IntoIter = PairsIter<'a>;

    fn into_iter(self) -> PairsIter<'a> {
        self.iter()
    }
}

impl PartialEq for Pairs {
    /// Equal when they hold the same pairs in the same order, however held.
    fn eq(&self, other: &Pairs) -> bool {
        self.len() == other.len() && self.iter().eq(other.iter())
    }
}

impl Serialize for Pairs {
    /// The JSON list of pairs, each formed as it is written.
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_seq(self.iter())
    }
}

impl<'de> Deserialize<'de> for Pairs {
    /// The JSON list of pairs, held as listed.
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Pairs, D::Error> {
        Vec::<PairDifference>::deserialize(deserializer).map(Pairs::from)
    }
}

/// Every pair of laboratories: d_ij and U(d_ij) (k = 2) formed when read ([`Pairs`]) from
/// the covariances `widened` (the pilot's stability and τ in them), and each pair's
/// closed-vector test at 5 %, made here.
pub(super) fn pair_differences(scaled: &Scaled, widened: &[ClosedCovariance]) -> Pairs {
    let labs = scaled.labs;
    let n = labs.len();
    let mut vectors = Vec::with_capacity(n * n.saturating_sub(1) / 2);
    let reported: Vec<Vec<f64>> = (0..n).map(|r| scaled.reported_values(r)).collect();
    let dof = scaled.positions.saturating_sub(1);
    let critical = chi2_quantile_95(dof);
    let closing = scaled.positions as f64 / dof.max(1) as f64;
    for a in 0..n {
        for b in a + 1..n {
            let test = match (&widened[a], &widened[b]) {
                // blocks: each on its own, over the blocks both report (ν = their number)
                (ClosedCovariance::Independent(u_a), ClosedCovariance::Independent(u_b)) => {
                    let d: Vec<f64> = reported[a]
                        .iter()
                        .zip(&reported[b])
                        .map(|(x_a, x_b)| x_a - x_b)
                        .collect();
                    let variance: Vec<f64> = u_a
                        .iter()
                        .zip(u_b)
                        .map(|(u_a, u_b)| u_a * u_a + u_b * u_b)
                        .collect();
                    super::blocks::pair_chi2(&d, &variance)
                        .map(|(chi2, dof)| VectorTest::at_five_percent(chi2, dof))
                }
                // results that report different positions: over those both report
                (ClosedCovariance::Stated(u_a), ClosedCovariance::Stated(u_b))
                    if scaled.measured.is_some() =>
                {
                    common_positions_test(
                        &reported[a],
                        &reported[b],
                        &own_variances(u_a),
                        &own_variances(u_b),
                    )
                }
                // V_a + V_b = c·P·diag(u_a² + u_b²)·P: its χ² in O(N), no fit
                (ClosedCovariance::Stated(u_a), ClosedCovariance::Stated(u_b)) => {
                    let d: Vec<f64> = scaled.values[a]
                        .iter()
                        .zip(&scaled.values[b])
                        .map(|(x_a, x_b)| x_a - x_b)
                        .collect();
                    let variance: Vec<f64> = u_a
                        .iter()
                        .zip(u_b)
                        .map(|(u_a, u_b)| closing * (u_a * u_a + u_b * u_b))
                        .collect();
                    let (chi2, _) = closed::difference_chi2(&d, &variance);
                    // χ²_0.95(ν) worked out once for every pair (thousands of them)
                    chi2.is_finite().then(|| VectorTest {
                        chi2,
                        dof,
                        consistent: chi2 <= critical,
                        chi2_critical: critical,
                        reference: Vec::new(),
                    })
                }
                _ => scaled.fit(&[a, b], widened).map(|fit| VectorTest {
                    reference: Vec::new(),
                    ..vector_test(&fit, scaled.scale)
                }),
            };
            vectors.push(test);
        }
    }
    let over_common = scaled.closed && scaled.measured.is_some();
    let variances = widened[..n]
        .iter()
        .map(|v| match v {
            ClosedCovariance::Stated(u) if over_common => own_variances(u),
            v => v.diagonal(),
        })
        .collect();
    Pairs::formed(
        labs.iter().map(|l| l.name.clone()).collect(),
        over_common,
        reported,
        variances,
        vectors,
        scaled.scale,
    )
}

/// c·u² of a closed result reporting N of the positions (u finite there), c = N/(N − 1):
/// its covariance is c·P·diag(u²)·P over them; NaN where it does not report a position.
fn own_variances(u: &[f64]) -> Vec<f64> {
    let n = u.iter().filter(|u| u.is_finite()).count() as f64;
    let c = n / (n - 1.0);
    u.iter()
        .map(|u| if u.is_finite() { c * u * u } else { f64::NAN })
        .collect()
}

/// The closed-vector test of a pair of results that report different positions, over the
/// M positions both report (`x_a`, `x_b` NaN elsewhere): the difference closed there, with
/// V = P·diag(c_a·u_a² + c_b·u_b²)·P (`w_a`, `w_b`: each result's c·u², [`own_variances`]) —
/// the covariance of the closed difference when each result is closed over its own
/// positions — and ν = M − 1 (`None` below 2 common positions).
fn common_positions_test(x_a: &[f64], x_b: &[f64], w_a: &[f64], w_b: &[f64]) -> Option<VectorTest> {
    let common: Vec<usize> = (0..x_a.len())
        .filter(|&k| x_a[k].is_finite() && x_b[k].is_finite())
        .collect();
    let m = common.len();
    if m < 2 {
        return None;
    }
    let d: Vec<f64> = common.iter().map(|&k| x_a[k] - x_b[k]).collect();
    let variance: Vec<f64> = common.iter().map(|&k| w_a[k] + w_b[k]).collect();
    let (chi2, _) = closed::difference_chi2(&d, &variance);
    chi2.is_finite()
        .then(|| VectorTest::at_five_percent(chi2, m - 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three laboratories, two positions, scale 2: every pair by hand.
    fn three() -> Pairs {
        Pairs::formed(
            vec!["A".into(), "B".into(), "C".into()],
            false,
            vec![vec![0.5, -0.5], vec![0.25, -0.25], vec![-1.0, 1.0]],
            vec![vec![0.04, 0.09], vec![0.12, 0.07], vec![0.0, 0.16]],
            (0..3)
                .map(|i| {
                    Some(VectorTest {
                        chi2: f64::from(i),
                        dof: 1,
                        consistent: i < 2,
                        chi2_critical: 3.84,
                        reference: Vec::new(),
                    })
                })
                .collect(),
            2.0,
        )
    }

    #[test]
    fn formed_pairs_are_the_differences_with_their_u() {
        let pairs = three();
        assert_eq!(pairs.len(), 3);
        let all: Vec<PairDifference> = pairs.iter().collect();
        let names: Vec<(&str, &str)> = all.iter().map(|p| (&p.a[..], &p.b[..])).collect();
        assert_eq!(names, [("A", "B"), ("A", "C"), ("B", "C")]);
        // d_AC = (0.5 − (−1.0))·2 = 3, U = 2·√(0.04 + 0)·2 = 0.8
        assert_eq!(all[1].d, [3.0, -3.0]);
        assert!((all[1].expanded_u[0] - 0.8).abs() < 1e-15);
        // d_BC at position 2 = (−0.25 − 1)·2 = −2.5, U = 2·√(0.07 + 0.16)·2
        assert_eq!(all[2].d[1], -2.5);
        assert!((all[2].expanded_u[1] - 4.0 * 0.23f64.sqrt()).abs() < 1e-15);
        for (i, pair) in all.iter().enumerate() {
            assert_eq!(pairs.get(i).as_ref(), Some(pair));
            // each pair carries its own test, in the order of the pairs
            assert_eq!(pair.vector.as_ref().map(|v| v.chi2), Some(i as f64));
        }
        assert_eq!(pairs.get(3), None);
    }

    #[test]
    fn pairs_read_back_from_their_json_are_equal() {
        let pairs = three();
        let json = serde_json::to_string(&pairs).unwrap();
        let listed: Vec<PairDifference> = serde_json::from_str(&json).unwrap();
        assert_eq!(listed.len(), 3);
        let back: Pairs = serde_json::from_str(&json).unwrap();
        assert_eq!(back, pairs);
        assert_eq!(serde_json::to_string(&back).unwrap(), json);
        assert_ne!(Pairs::from(listed[..2].to_vec()), pairs);
        assert!(
            Pairs::formed(
                vec!["A".into()],
                false,
                vec![vec![]],
                vec![vec![]],
                Vec::new(),
                1.0
            )
            .is_empty()
        );
    }
}
