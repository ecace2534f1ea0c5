//! Outliers with a twin: readings whose outlier columns the data cannot tell apart, and
//! whether leaving out either gives the same calibration.

use crate::diagnose::base::Base;
use crate::diagnose::geometry::FitGeometry;

/// Readings whose outlier column is nearly the same as reading `i`'s (|correlation of
/// their residual directions| ≥ 0.9) and that explain nearly as much (t² within 4 of
/// reading i's): the data cannot say which of them is bad.
/// Whether leaving out reading `i` or any of its `twins` instead gives the same
/// calibration ([`Base::calibrated`], to 1e-9 of its size): in a self-calibration with two
/// heads, the two readings of a stop differ only by the table's error there, so the bad
/// one cannot be named but the calibration does not depend on which it is.
pub(super) fn exchangeable(
    base: &Base<'_>,
    columns: &[Vec<f64>],
    i: usize,
    twins: &[(usize, f64)],
    sigma: Option<crate::measurement::Sigma>,
) -> bool {
    let n = base.positions().readings.len();
    let calibration = |reading: usize| {
        let mut all = columns.to_vec();
        let mut column = vec![0.0; n];
        column[reading] = 1.0;
        all.push(column);
        base.fit(&all, sigma).ok().map(|fit| base.calibrated(&fit))
    };
    let Some([a0, a1]) = calibration(i) else {
        return false;
    };
    let scale = a0.iter().chain(&a1).fold(1.0_f64, |m, v| m.max(v.abs()));
    twins.iter().all(|&(j, _)| {
        calibration(j).is_some_and(|[b0, b1]| {
            a0.iter()
                .chain(&a1)
                .zip(b0.iter().chain(&b1))
                .all(|(x, y)| (x - y).abs() <= 1e-9 * scale)
        })
    })
}

pub(super) fn twins(
    geometry: &FitGeometry,
    studentized: &[Option<f64>],
    i: usize,
    t_i: f64,
) -> Vec<(usize, f64)> {
    let h_ii = geometry.hat(i, i);
    (0..studentized.len())
        .filter(|&j| j != i)
        .filter_map(|j| {
            let t_j = studentized[j]?;
            if t_j * t_j < t_i * t_i - 4.0 {
                return None;
            }
            let h_jj = geometry.hat(j, j);
            let room = (1.0 - h_ii) * (1.0 - h_jj);
            if room <= 0.0 {
                return None;
            }
            let correlation = -geometry.hat(i, j) / room.sqrt();
            (correlation.abs() >= 0.9).then_some((j, t_j))
        })
        .collect()
}
