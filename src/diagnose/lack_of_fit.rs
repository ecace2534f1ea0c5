//! The lack-of-fit test against pure error: a check of a fitted model that needs neither a
//! stated σ nor the time order of the readings.
//!
//! A *cell* is one (setup, step, autocollimator, direction): the readings of a cell have
//! the same α, φ and setup error, so whatever the base model is, it predicts them alike.
//! When cells are read more than once, the scatter within cells estimates σ whatever the
//! model lacks ("pure error"). The *full* model is the fitted model plus one free mean per
//! cell; the fitted model is nested in it (its α, φ, U and direction columns are constant
//! within cells, its other effect columns are kept in the full model). Then
//!
//! ```text
//! F = [(RSS_model − RSS_full) / ν_lack] / [RSS_full / ν_pure]
//! ```
//!
//! with ν_pure = n − cells − rank(effect columns within cells) and ν_lack = dof_model −
//! ν_pure follows F(ν_lack, ν_pure) for Gaussian noise when the model is right, and grows
//! with any structure the model misses between cells, whatever its shape (face to face,
//! position to position, mounting to mounting, one direction against the other).

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::nuisance::StopNuisance;
use crate::measurement::{Direction, MeasurementSet};
use crate::solve::Solution;

/// One cell of repeated readings: (setup, step, autocollimator, direction).
pub type CellKey = (u32, usize, u32, Direction);

/// The readings of every cell, by cell.
pub fn cells(set: &MeasurementSet) -> BTreeMap<CellKey, Vec<usize>> {
    let mut cells: BTreeMap<CellKey, Vec<usize>> = BTreeMap::new();
    for (i, r) in set.readings.iter().enumerate() {
        cells
            .entry((r.setup, r.step, r.ac, r.direction))
            .or_default()
            .push(i);
    }
    cells
}

/// The cells of [`cells`] as one sorted list: every reading's index ordered by its cell's
/// key and then by index (the order of [`cells`]' map and of its members), without a map
/// node or a vector per cell.
#[derive(Debug, Clone)]
struct Cells {
    /// The keys of the cells, ascending.
    keys: Vec<CellKey>,
    /// The readings, cell after cell.
    members: Vec<usize>,
    /// Where each cell's readings start in `members` (one more entry: the end).
    starts: Vec<usize>,
}

impl Cells {
    fn of(set: &MeasurementSet) -> Self {
        let key = |i: usize| {
            let r = &set.readings[i];
            (r.setup, r.step, r.ac, r.direction)
        };
        let sorted = sorted_by_cell(set, &key);
        let mut keys: Vec<CellKey> = Vec::new();
        let mut starts: Vec<usize> = Vec::new();
        for (k, &i) in sorted.iter().enumerate() {
            let cell = key(i);
            if keys.last() != Some(&cell) {
                keys.push(cell);
                starts.push(k);
            }
        }
        starts.push(sorted.len());
        let members = sorted;
        Cells {
            keys,
            members,
            starts,
        }
    }

    fn len(&self) -> usize {
        self.keys.len()
    }

    /// `values` (one per reading) less the mean of each one's cell.
    fn centre(&self, values: &dyn Fn(usize) -> f64) -> Vec<f64> {
        let mut out = vec![0.0; self.members.len()];
        for members in self.values() {
            let mean = members.iter().map(|&i| values(i)).sum::<f64>() / members.len() as f64;
            for &i in members {
                out[i] = values(i) - mean;
            }
        }
        out
    }

    /// Whitened `values` (one per reading) with their cell's whitened mean taken out: the
    /// part orthogonal to every cell's whitened indicator (wᵢ on its readings), as the
    /// full model of a weighted fit leaves it.
    fn centre_weighted(&self, values: &dyn Fn(usize) -> f64, weights: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.members.len()];
        for members in self.values() {
            let (wz, ww) = members.iter().fold((0.0, 0.0), |(wz, ww), &i| {
                (wz + weights[i] * values(i), ww + weights[i] * weights[i])
            });
            let c = if ww > 0.0 { wz / ww } else { 0.0 };
            for &i in members {
                out[i] = values(i) - c * weights[i];
            }
        }
        out
    }

    /// [`Cells::centre`], or [`Cells::centre_weighted`] with `weights`.
    fn centre_with(&self, values: &dyn Fn(usize) -> f64, weights: Option<&[f64]>) -> Vec<f64> {
        match weights {
            Some(w) => self.centre_weighted(values, w),
            None => self.centre(values),
        }
    }

    fn values(&self) -> impl Iterator<Item = &[usize]> {
        self.starts.windows(2).map(|w| &self.members[w[0]..w[1]])
    }

    fn iter(&self) -> impl Iterator<Item = (&CellKey, &[usize])> {
        self.keys.iter().zip(self.values())
    }
}

/// The result of the lack-of-fit test.
#[derive(Debug, Clone, PartialEq)]
pub struct LackOfFit {
    /// F = (lack-of-fit mean square) / (pure-error mean square).
    pub f_statistic: f64,
    /// Degrees of freedom of the lack of fit, ν_lack.
    pub dof_lack: usize,
    /// Degrees of freedom of the pure error, ν_pure.
    pub dof_pure: usize,
    /// The upper `alpha` quantile of F(ν_lack, ν_pure).
    pub limit: f64,
    /// The lower [`LOWER_TAIL_ALPHA`] quantile of F(ν_lack, ν_pure) (0 for noise-free
    /// data): an F below it is a lack of fit too small to be true ([`LackOfFit::too_good`]).
    pub lower_limit: f64,
    /// P(F(ν_lack, ν_pure) > f_statistic).
    pub p_value: f64,
    /// σ from the scatter within cells, √(RSS_full / ν_pure), arcsec.
    pub pure_error_sigma: f64,
    /// Number of cells and of cells read more than once.
    pub cells: usize,
    /// Cells read more than once.
    pub replicated_cells: usize,
    /// Cells whose mean residual stands out most, largest |z| first (at most 8).
    pub worst_cells: Vec<CellResidual>,
    /// Factor levels that carry most of the lack of fit, e.g. "autocollimator 2 carries
    /// 91 % of it over 50 % of the cells".
    pub carriers: Vec<String>,
    /// For a self-calibration with heads between the positions: the band limit of its
    /// model, P/2 — the lowest harmonic order of the encoder error the band-limited model
    /// cannot fit between the positions (the order P/2 itself only as a cosine on the
    /// grid), a cause of a lack of fit no effect term expresses. `None` otherwise.
    pub band_limit_order: Option<usize>,
}

/// The mean residual of one cell, in units of its standard error under the pure error.
#[derive(Debug, Clone, PartialEq)]
pub struct CellResidual {
    /// Mounting.
    pub setup: u32,
    /// Table stop.
    pub step: usize,
    /// Autocollimator.
    pub ac: u32,
    /// Direction of the cycles.
    pub direction: Direction,
    /// Face read.
    pub face: usize,
    /// Readings in the cell.
    pub readings: usize,
    /// Mean residual of the cell in the fitted model, arcsec.
    pub mean_residual_arcsec: f64,
    /// mean·√readings / pure-error σ.
    pub z: f64,
}

/// The false-alarm probability of the lower-tail check of the lack of fit
/// ([`LackOfFit::too_good`]): 0.1 % of clean runs have an F below the lower limit.
pub const LOWER_TAIL_ALPHA: f64 = 0.001;

impl LackOfFit {
    /// Whether the model passes (F within its limit).
    pub fn passed(&self) -> bool {
        self.f_statistic <= self.limit
    }

    /// Whether the lack of fit is too small to be true: F below the lower
    /// [`LOWER_TAIL_ALPHA`] quantile of F(ν_lack, ν_pure). The scatter within the cells
    /// is then larger than the scatter between them can explain: a group of readings (a
    /// cycle logged wrongly, an autocollimator whose noise rose) inflates the pure error,
    /// and the upper test is blind to what the model lacks.
    pub fn too_good(&self) -> bool {
        self.f_statistic < self.lower_limit
    }
}

/// The lack-of-fit test of `solution` (a fit of `set` with the effect `columns`) at
/// false-alarm probability `alpha`; `None` when no cell is repeated or the design leaves
/// no degree of freedom to the lack of fit.
pub fn lack_of_fit(
    set: &MeasurementSet,
    solution: &Solution,
    columns: &[Vec<f64>],
    alpha: f64,
) -> Option<LackOfFit> {
    lack_of_fit_with(set, solution, columns, alpha, None)
}

/// [`lack_of_fit`] of a self-calibration's fit with the table's error at every stop taken
/// out ([`StopNuisance`]): the full model is then one mean per cell plus one table error
/// per stop, so the pure error is the scatter within cells beyond the stops' — in a
/// complete layout of cycles × heads at every (step, direction), the interaction of the
/// two-way table: y and every effect column centred within cells, then within stops, and
/// ν_pure = n − cells − (stops − (step, direction) groups) − rank.
pub fn lack_of_fit_with(
    set: &MeasurementSet,
    solution: &Solution,
    columns: &[Vec<f64>],
    alpha: f64,
    nuisance: Option<&StopNuisance>,
) -> Option<LackOfFit> {
    PureError::of(set, nuisance)?.test(set, solution, columns, alpha, nuisance)
}

/// What the lack-of-fit test needs of the readings alone, whatever the model: the cells,
/// the readings centred within them (and within stops, with a stop nuisance), and the
/// stop parameters of the full model. A diagnosis tests many fits of one set: it forms
/// this once ([`PureError::of`]) and tests every fit with it ([`PureError::test`]).
#[derive(Debug, Clone)]
pub struct PureError {
    /// The cells of the set.
    cells: Cells,
    /// The readings centred within their cells (and stops).
    centred_readings: Vec<f64>,
    /// The cells read more than once.
    replicated_cells: usize,
    /// The table errors per stop beyond one per (step, direction), with a stop nuisance.
    stop_parameters: usize,
    /// A weighted fit's whitening factors ([`PureError::of_weighted`]).
    weights: Option<std::sync::Arc<[f64]>>,
}

impl PureError {
    /// The pure-error structure of `set` (with the stop nuisance `nuisance` taken out);
    /// `None` when no cell is read more than once.
    pub fn of(set: &MeasurementSet, nuisance: Option<&StopNuisance>) -> Option<Self> {
        Self::of_weighted(set, nuisance, None)
    }

    /// [`PureError::of`] for weighted fits (reading i weighing `weights[i]`²): the full
    /// model's cells are whitened like the fits' rows, the readings and the columns
    /// tested against it are the whitened ones (the columns given whitened), and the
    /// pure error is Σ wᵢ²(yᵢ − ȳ_w)² over the cells. Not with a stop nuisance.
    pub fn of_weighted(
        set: &MeasurementSet,
        nuisance: Option<&StopNuisance>,
        weights: Option<std::sync::Arc<[f64]>>,
    ) -> Option<Self> {
        let weights = weights.filter(|w| w.len() == set.readings.len() && nuisance.is_none());
        let cells = Cells::of(set);
        let replicated_cells = cells.values().filter(|c| c.len() > 1).count();
        if replicated_cells == 0 {
            return None;
        }
        let w = weights.as_deref();
        let mut centred_readings = cells.centre_with(
            &|i| w.map_or(1.0, |w| w[i]) * set.readings[i].reading_arcsec,
            w,
        );
        let mut stop_parameters = 0;
        if let Some(nuisance) = nuisance {
            nuisance.center_within_stops(&mut centred_readings);
            let mut groups: Vec<(usize, Direction)> =
                set.readings.iter().map(|r| (r.step, r.direction)).collect();
            groups.sort_unstable_by_key(|&(step, d)| (step, d == Direction::Ccw));
            groups.dedup();
            let mut stops: Vec<(u32, usize)> =
                set.readings.iter().map(|r| (r.cycle, r.step)).collect();
            stops.sort_unstable();
            stops.dedup();
            stop_parameters = stops.len().checked_sub(groups.len())?;
        }
        Some(PureError {
            cells,
            centred_readings,
            replicated_cells,
            stop_parameters,
            weights,
        })
    }

    /// The lack-of-fit test of `solution`, a fit of `set` (the set this was formed of)
    /// with the effect `columns`, at false-alarm probability `alpha`, as
    /// [`lack_of_fit_with`].
    pub fn test(
        &self,
        set: &MeasurementSet,
        solution: &Solution,
        columns: &[Vec<f64>],
        alpha: f64,
        nuisance: Option<&StopNuisance>,
    ) -> Option<LackOfFit> {
        let cells = &self.cells;
        let n = set.readings.len();
        if self.centred_readings.len() != n {
            return None;
        }
        let wx: Vec<Vec<f64>> = columns
            .iter()
            .map(|x| {
                let mut w = cells.centre_with(&|i| x[i], self.weights.as_deref());
                if let Some(nuisance) = nuisance {
                    nuisance.center_within_stops(&mut w);
                }
                w
            })
            .filter(|w| w.iter().any(|v| v.abs() > 1e-12))
            .collect();
        let (rss_full, rank) = project_out(&self.centred_readings, &wx);
        let dof_pure = n.checked_sub(cells.len() + self.stop_parameters + rank)?;
        let dof_lack = solution.dof.checked_sub(dof_pure)?;
        if dof_pure == 0 || dof_lack == 0 {
            return None;
        }
        let replicated_cells = self.replicated_cells;
        let rss_lack = (solution.rss - rss_full).max(0.0);
        let pure_ms = rss_full / dof_pure as f64;
        let lack_ms = rss_lack / dof_lack as f64;
        let scale = set
            .readings
            .iter()
            .map(|r| r.reading_arcsec.abs())
            .fold(1.0, f64::max);
        let rounding = (64.0 * f64::EPSILON * scale).powi(2);
        let f_statistic = if pure_ms > rounding {
            lack_ms / pure_ms
        } else if lack_ms > rounding {
            f64::INFINITY
        } else {
            // Noise-free data: nothing between cells, nothing within.
            0.0
        };
        let distribution = FisherSnedecor::new(dof_lack as f64, dof_pure as f64).ok()?;
        let limit = distribution.inverse_cdf(1.0 - alpha);
        let lower_limit = if pure_ms > rounding {
            distribution.inverse_cdf(LOWER_TAIL_ALPHA)
        } else {
            0.0
        };
        let p_value = if f_statistic.is_finite() {
            distribution.sf(f_statistic)
        } else {
            0.0
        };
        let pure_error_sigma = pure_ms.sqrt();
        let all_cells: Vec<CellResidual> = cells
            .iter()
            .map(|(&(setup, step, ac, direction), members)| {
                // a weighted fit's residuals are whitened: the cell's mean in arcsec
                let weight = |i: usize| self.weights.as_deref().map_or(1.0, |w| w[i]);
                let mean = members
                    .iter()
                    .map(|&i| solution.residuals[i] / weight(i))
                    .sum::<f64>()
                    / members.len() as f64;
                let z = if pure_error_sigma > 0.0 {
                    mean * (members.len() as f64).sqrt() / pure_error_sigma
                } else {
                    0.0
                };
                CellResidual {
                    setup,
                    step,
                    ac,
                    direction,
                    face: set.readings[members[0]].face,
                    readings: members.len(),
                    mean_residual_arcsec: mean,
                    z,
                }
            })
            .collect();
        let carriers = carriers(&all_cells);
        // the eight largest |z| in the order of a stable sort (ties in cell order)
        let worst_first = |a: &(usize, &CellResidual), b: &(usize, &CellResidual)| {
            b.1.z.abs().total_cmp(&a.1.z.abs()).then(a.0.cmp(&b.0))
        };
        let mut ranked: Vec<(usize, &CellResidual)> = all_cells.iter().enumerate().collect();
        if ranked.len() > WORST_CELLS {
            ranked.select_nth_unstable_by(WORST_CELLS, worst_first);
            ranked.truncate(WORST_CELLS);
        }
        ranked.sort_unstable_by(worst_first);
        let worst_cells = ranked.into_iter().map(|(_, c)| c.clone()).collect();
        Some(LackOfFit {
            f_statistic,
            dof_lack,
            dof_pure,
            limit,
            lower_limit,
            p_value,
            pure_error_sigma,
            cells: cells.len(),
            replicated_cells,
            worst_cells,
            carriers,
            band_limit_order: None,
        })
    }
}

/// The readings' indices ordered by their cell's key (setup, step, ac, direction), then
/// by index: a counting sort over the dense index of the key when that index is small
/// (setups × steps × autocollimators × 2 within a few times the readings, as in every
/// run), a sort otherwise.
fn sorted_by_cell(set: &MeasurementSet, key: &dyn Fn(usize) -> CellKey) -> Vec<usize> {
    let n = set.readings.len();
    let mut setups: Vec<u32> = set.readings.iter().map(|r| r.setup).collect();
    setups.sort_unstable();
    setups.dedup();
    let mut acs: Vec<u32> = set.readings.iter().map(|r| r.ac).collect();
    acs.sort_unstable();
    acs.dedup();
    let steps = set
        .readings
        .iter()
        .map(|r| r.step)
        .max()
        .map_or(0, |s| s + 1);
    let buckets = setups
        .len()
        .checked_mul(steps)
        .and_then(|b| b.checked_mul(acs.len()))
        .and_then(|b| b.checked_mul(2));
    let Some(buckets) = buckets.filter(|&b| b <= 4 * n.max(1024)) else {
        let mut sorted: Vec<usize> = (0..n).collect();
        sorted.sort_by_key(|&i| key(i));
        return sorted;
    };
    // ascending in (setup, step, ac, direction), as the key's order
    let index = |i: usize| -> usize {
        let r = &set.readings[i];
        let s = setups.binary_search(&r.setup).unwrap_or(0);
        let a = acs.binary_search(&r.ac).unwrap_or(0);
        ((s * steps + r.step) * acs.len() + a) * 2 + usize::from(r.direction == Direction::Ccw)
    };
    let indices: Vec<usize> = (0..n).map(index).collect();
    let mut start = vec![0usize; buckets + 1];
    for &b in &indices {
        start[b + 1] += 1;
    }
    for b in 0..buckets {
        start[b + 1] += start[b];
    }
    let mut sorted = vec![0usize; n];
    for (i, &b) in indices.iter().enumerate() {
        sorted[start[b]] = i;
        start[b] += 1;
    }
    sorted
}

/// The cells a lack-of-fit test lists, largest |z| first.
const WORST_CELLS: usize = 8;

/// The levels of autocollimator, mounting and direction that carry at least 60 % of the
/// cells' Σz² while holding at most 2/3 of that share of the cells.
fn carriers(cells: &[CellResidual]) -> Vec<String> {
    let total: f64 = cells.iter().map(|c| c.z * c.z).sum();
    if total <= 0.0 || cells.is_empty() {
        return Vec::new();
    }
    let mut out = Vec::new();
    // a factor's levels keyed by a number, named (and ordered by name) only at the end
    let mut factor = |level: &dyn Fn(&CellResidual) -> u32, name: &dyn Fn(u32) -> String| {
        let mut levels: BTreeMap<u32, (f64, usize)> = BTreeMap::new();
        for c in cells {
            let entry = levels.entry(level(c)).or_default();
            entry.0 += c.z * c.z;
            entry.1 += 1;
        }
        if levels.len() < 2 {
            return;
        }
        let mut named: Vec<(String, (f64, usize))> =
            levels.into_iter().map(|(l, v)| (name(l), v)).collect();
        named.sort_by(|a, b| a.0.cmp(&b.0));
        for (level, (sum, count)) in named {
            let share = sum / total;
            let fraction = count as f64 / cells.len() as f64;
            if share >= 0.6 && share >= 1.5 * fraction {
                out.push(format!(
                    "{level} carries {:.0} % of the lack of fit over {:.0} % of the cells",
                    100.0 * share,
                    100.0 * fraction
                ));
            }
        }
    };
    factor(&|c| c.ac, &|ac| format!("autocollimator {ac}"));
    factor(&|c| c.setup, &|setup| format!("mounting (setup) {setup}"));
    factor(&|c| u32::from(c.direction == Direction::Ccw), &|ccw| {
        if ccw == 1 {
            "the counter-clockwise cycles".to_string()
        } else {
            "the clockwise cycles".to_string()
        }
    });
    out
}

/// ‖y − X b‖² minimised over b, and the rank of X (columns `x`), by a thin SVD of X.
fn project_out(y: &[f64], x: &[Vec<f64>]) -> (f64, usize) {
    let rss_y: f64 = y.iter().map(|v| v * v).sum();
    if x.is_empty() {
        return (rss_y, 0);
    }
    let n = y.len();
    let m = DMatrix::from_fn(n, x.len(), |i, j| x[j][i]);
    let svd = m.svd(true, false);
    let Some(u) = svd.u else {
        return (rss_y, 0);
    };
    let largest = svd.singular_values.iter().copied().fold(0.0, f64::max);
    let yv = DVector::from_column_slice(y);
    let mut explained = 0.0;
    let mut rank = 0;
    for (j, &s) in svd.singular_values.iter().enumerate() {
        if s > 1e-9 * largest {
            rank += 1;
            let c = u.column(j).dot(&yv);
            explained += c * c;
        }
    }
    ((rss_y - explained).max(0.0), rank)
}
