//! The geometry of a fit of a self-calibration whose heads sit between the positions:
//! the hat matrix H = X Q_g Xᵀ of the band-limited closure design
//! ([`crate::selfcal::OffGridDesign`]) without forming it.
//!
//! A reading's design row is dense in φ′ (head j reads the disc through S_j, a fractional
//! shift), so the rows are never formed: products go through the design (X and Xᵀ, M FFTs
//! of length P) and Q_g (the fit's structured cofactor, B + W M Wᵀ). B is block-circulant
//! and every S_j commutes with a shift, so the base part of H between head j′ at step p
//! and head j at step q is one kernel K_{j′j}(p − q), all M² kernels from M products
//! with B (one unit reading per head, read back at every step of every head). The
//! low-rank part is (WM)ᵀcᵢ · Wᵀcⱼ, with Wᵀcᵢ = (X w)ᵢ the model of W's column w at
//! reading i. Then
//!
//! - a column's fitted values X Q_g Xᵀx cost O(n·E + M·P log P);
//! - an entry H_ij costs O(r), the leverages O(n·r);
//! - the suffixes of one head's time-ordered readings (a change-point search) are the
//!   kernel K_jj summed over the later readings by the blocked FFT convolution of the
//!   structured form, and the low-rank part's running sums, O(r) per reading.

use std::sync::Arc;

use super::structured::suffix_convolution;
use crate::selfcal::OffGridDesign;
use crate::solve::Solution;
use crate::solve::cofactor::Structured;

/// The geometry of one fit of the band-limited closure design (module documentation).
#[derive(Debug, Clone)]
pub(super) struct OffGridGeometry {
    design: Arc<OffGridDesign>,
    /// Q_g of the fit.
    q: Structured,
    /// The fit's effect columns.
    columns: Vec<Vec<f64>>,
    /// K_{j′j}(d) at (j′·M + j)·P + d: B between head j′ at step d and head j at step 0.
    kernels: Vec<f64>,
    /// Per low-rank column k: Wᵀcᵢ and (WM)ᵀcᵢ of every reading i.
    low: Vec<Vec<f64>>,
    low_m: Vec<Vec<f64>>,
}

impl OffGridGeometry {
    /// The geometry of `solution`, a fit of `design`'s readings with the effect `columns`
    /// ([`OffGridDesign::fit`]); `None` when its cofactor is not the structured one that
    /// fit gives.
    pub(super) fn new(
        solution: &Solution,
        design: Arc<OffGridDesign>,
        columns: &[Vec<f64>],
    ) -> Option<Self> {
        let q = solution.cofactor.as_structured()?.clone();
        let (p, m) = (design.positions(), design.heads());
        if q.size() != design.size(columns.len()) || q.faces() != p {
            return None;
        }
        let mut kernels = vec![0.0; m * m * p];
        for j in 0..m {
            let mut b_c = vec![0.0; q.size()];
            q.base
                .apply_add(&design.unit_row(j, 0, columns.len()), &mut b_c);
            let views = design.views(&b_c[p..2 * p]);
            for (jp, view) in views.iter().enumerate() {
                let kernel = &mut kernels[(jp * m + j) * p..(jp * m + j + 1) * p];
                for (d, k) in kernel.iter_mut().enumerate() {
                    *k = b_c[d] + view[d] + b_c[2 * p + jp];
                }
            }
        }
        let (low, low_m) = (0..q.rank())
            .map(|k| {
                let (w, wm) = q.low_rank_column(k);
                (design.model(w, columns), design.model(wm, columns))
            })
            .unzip();
        Some(Self {
            design,
            q,
            columns: columns.to_vec(),
            kernels,
            low,
            low_m,
        })
    }

    /// The length of g.
    pub(super) fn size(&self) -> usize {
        self.q.size()
    }

    /// H·x without a stop nuisance's part: the fitted values of a fit of `x`.
    pub(super) fn fitted(&self, x: &[f64]) -> Vec<f64> {
        let g = self.q.apply(&self.design.transpose(x, &self.columns));
        self.design.model(&g, &self.columns)
    }

    /// The base part of H between readings i and j.
    fn kernel(&self, i: usize, j: usize) -> f64 {
        let (p, m) = (self.design.positions(), self.design.heads());
        let ((hi, pi), (hj, pj)) = (self.design.cell(i), self.design.cell(j));
        self.kernels[(hi * m + hj) * p + (pi + p - pj) % p]
    }

    /// H_ij (without a stop nuisance's part).
    pub(super) fn hat(&self, i: usize, j: usize) -> f64 {
        let low: f64 = self
            .low_m
            .iter()
            .zip(&self.low)
            .map(|(wm, w)| wm[i] * w[j])
            .sum();
        self.kernel(i, j) + low
    }

    /// xᵀHx of every suffix `order[k..]` of one head's readings (element k); readings of
    /// several heads by their pairs.
    pub(super) fn suffix_quads(&self, order: &[usize]) -> Vec<f64> {
        let m = order.len();
        let Some(&first) = order.first() else {
            return Vec::new();
        };
        let (p, heads) = (self.design.positions(), self.design.heads());
        let head = self.design.cell(first).0;
        let later = if order.iter().all(|&i| self.design.cell(i).0 == head) {
            let kernel = &self.kernels[(head * heads + head) * p..(head * heads + head + 1) * p];
            suffix_convolution(kernel, order.iter().map(|&i| self.design.cell(i).1), m)
        } else {
            (0..m)
                .map(|k| (k + 1..m).map(|t| self.kernel(order[k], order[t])).sum())
                .collect()
        };
        let rank = self.low.len();
        let mut running = vec![0.0; rank];
        let mut quads = vec![0.0; m];
        let mut quad = 0.0;
        for (k, &i) in order.iter().enumerate().rev() {
            let cross: f64 = (0..rank).map(|r| self.low_m[r][i] * running[r]).sum();
            let own: f64 = (0..rank).map(|r| self.low_m[r][i] * self.low[r][i]).sum();
            quad += 2.0 * (later[k] + cross) + self.kernel(i, i) + own;
            for (t, w) in running.iter_mut().zip(&self.low) {
                *t += w[i];
            }
            quads[k] = quad;
        }
        quads
    }
}

#[cfg(test)]
mod tests {
    //! The off-grid geometry against the projection onto the design's columns formed
    //! densely here: every head's view of the disc written out from the band-limited
    //! interpolation's definition, the projection by the SVD's pseudo-inverse.

    use std::sync::Arc;

    use nalgebra::{DMatrix, DVector};

    use super::OffGridGeometry;
    use crate::measurement::{Direction, MeasurementSet, Reading};
    use crate::selfcal::OffGridDesign;

    /// P = 12, heads at 0°, 100° and 250° (offsets 0, 3⅓, 8⅓ positions), 2 cycles, head
    /// order by cycle, step, head (one stream per head in time order).
    fn design_set() -> (MeasurementSet, Vec<f64>) {
        let p = 12;
        let offsets = vec![0.0, 100.0 * 12.0 / 360.0, 250.0 * 12.0 / 360.0];
        let mut readings = Vec::new();
        for cycle in 1..=2 {
            for step in 0..p {
                for (j, d) in offsets.iter().enumerate() {
                    readings.push(Reading {
                        setup: 1,
                        cycle,
                        step,
                        ac: j as u32 + 1,
                        face: (step + f64::round(*d) as usize) % p + 1,
                        reading_arcsec: 0.1 * ((7 * step + 3 * j + cycle as usize) % 5) as f64,
                        direction: Direction::Cw,
                        time_seconds: None,
                        reading_y_arcsec: None,
                        temperature_celsius: None,
                        encoder_degrees: None,
                        line: 0,
                    });
                }
            }
        }
        let set = MeasurementSet::from_readings(readings, Some(p), "test").unwrap();
        (set, offsets)
    }

    /// The design's columns: α per step, the disc's real Fourier basis read at every
    /// head's fractional position x = p + δ (cos and sin of 2πkx/P for k < P/2, cos πx
    /// for k = P/2), a constant per head, and the effect columns.
    fn dense_columns(set: &MeasurementSet, offsets: &[f64], effects: &[Vec<f64>]) -> DMatrix<f64> {
        let p = set.faces;
        let m = offsets.len();
        let width = p + (p - 1) + m + effects.len();
        let mut x = DMatrix::zeros(set.readings.len(), width);
        for (i, r) in set.readings.iter().enumerate() {
            let j = r.ac as usize - 1;
            x[(i, r.step)] = 1.0;
            let position = r.step as f64 + offsets[j];
            let mut c = p;
            for k in 1..=p / 2 {
                let angle = 2.0 * std::f64::consts::PI * k as f64 * position / p as f64;
                x[(i, c)] = angle.cos();
                c += 1;
                if 2 * k != p {
                    x[(i, c)] = angle.sin();
                    c += 1;
                }
            }
            x[(i, 2 * p - 1 + j)] = 1.0;
            for (e, column) in effects.iter().enumerate() {
                x[(i, 2 * p - 1 + m + e)] = column[i];
            }
        }
        x
    }

    fn projection(x: &DMatrix<f64>) -> DMatrix<f64> {
        let svd = x.clone().svd(true, true);
        let u = svd.u.unwrap();
        let largest = svd.singular_values.max();
        let mut h = DMatrix::zeros(x.nrows(), x.nrows());
        for (k, &s) in svd.singular_values.iter().enumerate() {
            if s > 1e-9 * largest {
                let column = u.column(k).into_owned();
                h += &column * column.transpose();
            }
        }
        h
    }

    #[test]
    fn the_hat_matrix_off_the_grid_is_the_projection_onto_the_design() {
        let (set, offsets) = design_set();
        let n = set.readings.len();
        let effects: Vec<Vec<f64>> = vec![
            (0..n)
                .map(|i| if i >= 40 && i % 3 == 1 { 1.0 } else { 0.0 })
                .collect(),
            (0..n)
                .map(|i| ((i * 37) % 11) as f64 / 11.0 - 0.4)
                .collect(),
        ];
        let design = Arc::new(OffGridDesign::new(&set, &[1, 2, 3], &offsets).unwrap());
        let values: Vec<f64> = set.readings.iter().map(|r| r.reading_arcsec).collect();
        let fit = design.fit(&values, &effects, None).unwrap();
        let geometry = OffGridGeometry::new(&fit, Arc::clone(&design), &effects).unwrap();
        let h = projection(&dense_columns(&set, &offsets, &effects));
        // every entry
        for i in 0..n {
            for j in 0..n {
                assert!(
                    (geometry.hat(i, j) - h[(i, j)]).abs() < 1e-10,
                    "H[{i}, {j}]: {} against {}",
                    geometry.hat(i, j),
                    h[(i, j)]
                );
            }
        }
        // the fit's residuals and a product
        let y = DVector::from_column_slice(&values);
        let residuals = &y - &h * &y;
        for (a, b) in fit.residuals.iter().zip(residuals.iter()) {
            assert!((a - b).abs() < 1e-10);
        }
        let z: Vec<f64> = (0..n).map(|i| ((i * 13) % 7) as f64 - 3.0).collect();
        let hz = &h * DVector::from_column_slice(&z);
        for (a, b) in geometry.fitted(&z).iter().zip(hz.iter()) {
            assert!((a - b).abs() < 1e-10);
        }
        // every suffix of head 2's readings in time order, and of a mixed order
        let order: Vec<usize> = (0..n).filter(|&i| i % 3 == 1).collect();
        let mixed: Vec<usize> = (0..n).filter(|&i| i % 5 == 2).collect();
        for order in [order, mixed] {
            let quads = geometry.suffix_quads(&order);
            for k in 0..order.len() {
                let direct: f64 = order[k..]
                    .iter()
                    .flat_map(|&a| order[k..].iter().map(move |&b| (a, b)))
                    .map(|(a, b)| h[(a, b)])
                    .sum();
                assert!(
                    (quads[k] - direct).abs() < 1e-9,
                    "suffix {k}: {} against {direct}",
                    quads[k]
                );
            }
        }
    }
}
