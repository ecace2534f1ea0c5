//! Angle blocks (docs/FORMAT.md §12, "Angle blocks"): each block a scalar of its own, not
//! part of a closed vector, compared among the laboratories that report it.
//!
//! With the laboratories i in the reference that report block b (n_b of them) and the
//! weights w_ib = 1/u_ib²:
//!
//! ```text
//! x_ref,b = Σ_i w_ib x_ib / W_b,   u²(x_ref,b) = 1/W_b,   W_b = Σ_i w_ib
//! χ² = Σ_b Σ_i w_ib (x_ib − x_ref,b)²,   ν = Σ_b (n_b − 1)
//! ```
//!
//! — the GLS of independent scalars, whose χ² is the one test of the blocks' consistency
//! at 5 % (the sum of the per-block χ², one decision, not one per block). A pair's test is
//! χ² = Σ_b (x_ab)²/(v_ab) over the blocks both report, ν = their number (no closure takes
//! a degree of freedom). A result that does not report a block has u = +∞ there: no weight,
//! no term, no degree of freedom.
//!
//! Here too the blocks are lined up from the results ([`blocks`]): who reports which block,
//! their nominal angles checked.

use std::collections::BTreeMap;

use super::closed::ClosedFit;
use super::input::{Aligned, Field, last_row, location, rows_required};
use super::{KcError, LabResult};
use crate::results::Quantity;

/// The fit of the independent scalars `x` with standard uncertainties `u` (per result, per
/// block; u = +∞ where a result does not report the block), in the comparison's scaled
/// units. A block no result reports has a reference of NaN (its degrees of equivalence are
/// then not given). `None` with no result or no block reported at all.
pub(crate) fn fit(x: &[&[f64]], u: &[&[f64]]) -> Option<ClosedFit> {
    let blocks = x.first()?.len();
    if x.len() != u.len() || x.iter().chain(u).any(|row| row.len() != blocks) {
        return None;
    }
    let (mut reference, mut reference_variance) = (Vec::new(), Vec::new());
    let (mut chi2, mut dof, mut reported) = (0.0, 0usize, false);
    for b in 0..blocks {
        let terms: Vec<(f64, f64)> = x
            .iter()
            .zip(u)
            .filter(|(_, u)| u[b].is_finite())
            .map(|(x, u)| (x[b], 1.0 / (u[b] * u[b])))
            .collect();
        let total: f64 = terms.iter().map(|(_, w)| w).sum();
        if terms.is_empty() || !(total > 0.0 && total.is_finite()) {
            reference.push(f64::NAN);
            reference_variance.push(f64::NAN);
            continue;
        }
        reported = true;
        let mean = terms.iter().map(|(x, w)| w * x).sum::<f64>() / total;
        chi2 += terms
            .iter()
            .map(|(x, w)| w * (x - mean).powi(2))
            .sum::<f64>();
        dof += terms.len() - 1;
        reference.push(mean);
        reference_variance.push(1.0 / total);
    }
    (reported && chi2.is_finite()).then_some(ClosedFit {
        reference,
        reference_variance,
        chi2,
        dof,
        pieces: None,
    })
}

/// A pair's χ² over the blocks both report: Σ_b d_b²/v_b with `d` the differences and
/// `variance` their variances (NaN or +∞ where either result does not report the block),
/// and ν, the number of those blocks. `None` when they share no block.
pub(crate) fn pair_chi2(d: &[f64], variance: &[f64]) -> Option<(f64, usize)> {
    let terms: Vec<f64> = d
        .iter()
        .zip(variance)
        .filter(|(d, v)| d.is_finite() && v.is_finite() && **v > 0.0)
        .map(|(d, v)| d * d / v)
        .collect();
    (!terms.is_empty()).then(|| (terms.iter().sum(), terms.len()))
}

/// Block → the row of each result reporting it (`None`: not reported), ascending by
/// block: refused for a result without angle blocks and a block stated twice in one result.
fn rows_by_block(results: &[&LabResult]) -> Result<BTreeMap<u32, Vec<Option<usize>>>, KcError> {
    let mut by_block: BTreeMap<u32, Vec<Option<usize>>> = BTreeMap::new();
    for (r, result) in results.iter().enumerate() {
        let rows = rows_required(result, Quantity::AngleBlock)?;
        for (i, row) in rows {
            let slot = by_block
                .entry(row.index)
                .or_insert_with(|| vec![None; results.len()]);
            if slot[r].is_some() {
                return Err(KcError::Duplicate {
                    location: location(result, i, Field::Index),
                    quantity: Quantity::AngleBlock,
                    index: row.index,
                });
            }
            slot[r] = Some(i);
        }
    }
    Ok(by_block)
}

/// Lines up the angle blocks of the laboratories `results[..labs]` and the pilot's repeats
/// after them: each block a scalar of its own, compared among the laboratories that report
/// it (docs/FORMAT.md §12, "What each laboratory measured"). A block reported by fewer
/// than two laboratories is left out and named in a note; the pilot's repeats must report
/// every block compared (their spread is the artefact's stability on each). Blocks'
/// nominal angles, where stated, must agree between results.
pub(crate) fn blocks(results: &[&LabResult], labs: usize) -> Result<Aligned, KcError> {
    let by_block = rows_by_block(results)?;
    let mut aligned = Aligned::empty(results.len(), false, true);
    let mut nominal: Vec<Option<f64>> = Vec::new();
    let mut left_out = Vec::new();
    for (&block, rows) in &by_block {
        let reporting = rows[..labs].iter().filter(|row| row.is_some()).count();
        if reporting < 2 {
            let by: Vec<&str> = rows[..labs]
                .iter()
                .zip(results)
                .filter(|(row, _)| row.is_some())
                .map(|(_, result)| result.name.as_str())
                .collect();
            left_out.push(match by.as_slice() {
                [] => format!("block {block} (by the pilot's repeats only)"),
                by => format!("block {block} (by {} only)", by.join(", ")),
            });
            continue;
        }
        if let Some(r) = (labs..results.len()).find(|&r| rows[r].is_none()) {
            return Err(KcError::RepeatMissesBlock {
                location: last_row(results[r], Quantity::AngleBlock),
                repeat: results[r].name.clone(),
                block,
            });
        }
        aligned.index.push(block);
        nominal.push(block_nominal(results, rows, block)?);
        aligned.push_position(results, rows)?;
    }
    let mut aligned = aligned.finished()?;
    if nominal.iter().any(Option::is_some) {
        aligned.nominal_deg = Some(nominal);
    }
    if !left_out.is_empty() {
        aligned.notes.push(format!(
            "{} angle block(s) reported by fewer than two laboratories left out (nothing to \
             compare them with): {}",
            left_out.len(),
            left_out.join("; ")
        ));
    }
    Ok(aligned)
}

/// The nominal angle of `block` as the results reporting it (`rows`) state it: `None` when
/// none does; refused at the second when two differ by more than 10⁻⁹ degrees.
fn block_nominal(
    results: &[&LabResult],
    rows: &[Option<usize>],
    block: u32,
) -> Result<Option<f64>, KcError> {
    let mut first: Option<(f64, String)> = None;
    for (r, row) in rows.iter().enumerate() {
        let Some(i) = *row else { continue };
        let Some(nominal) = results[r].rows[i].nominal_deg else {
            continue;
        };
        match &first {
            None => first = Some((nominal, location(results[r], i, Field::Nominal))),
            Some((seen, at)) if (seen - nominal).abs() > 1e-9 => {
                return Err(KcError::NominalsDiffer {
                    location: location(results[r], i, Field::Nominal),
                    block,
                    nominal_deg: nominal,
                    first_nominal_deg: *seen,
                    first_location: at.clone(),
                });
            }
            Some(_) => {}
        }
    }
    Ok(first.map(|(nominal, _)| nominal))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two blocks, three laboratories, C without block 2: worked by hand.
    #[test]
    fn kc_blocks_fit_is_the_per_block_weighted_mean() {
        let inf = f64::INFINITY;
        let x: [&[f64]; 3] = [&[1.0, 2.0], &[2.0, 4.0], &[4.0, 0.0]];
        let u: [&[f64]; 3] = [&[1.0, 1.0], &[1.0, 2.0], &[2.0, inf]];
        let fit = fit(&x, &u).expect("fitted");
        // block 1: weights 1, 1, 1/4: mean = (1 + 2 + 1)/2.25 = 16/9
        assert!((fit.reference[0] - 16.0 / 9.0).abs() < 1e-15);
        assert!((fit.reference_variance[0] - 1.0 / 2.25).abs() < 1e-15);
        // block 2: weights 1, 1/4: mean = (2 + 1)/1.25 = 2.4
        assert!((fit.reference[1] - 2.4).abs() < 1e-15);
        let chi2_1 = (1.0f64 - 16.0 / 9.0).powi(2)
            + (2.0f64 - 16.0 / 9.0).powi(2)
            + (4.0f64 - 16.0 / 9.0).powi(2) / 4.0;
        let chi2_2 = (2.0f64 - 2.4).powi(2) + (4.0f64 - 2.4).powi(2) / 4.0;
        assert!((fit.chi2 - (chi2_1 + chi2_2)).abs() < 1e-14);
        assert_eq!(fit.dof, 2 + 1);
    }

    #[test]
    fn kc_blocks_pair_counts_the_shared_blocks_only() {
        let (chi2, dof) = pair_chi2(&[1.0, f64::NAN, 2.0], &[1.0, 1.0, 4.0]).expect("shared");
        assert_eq!((chi2, dof), (2.0, 2));
        assert!(pair_chi2(&[f64::NAN], &[1.0]).is_none());
    }
}
