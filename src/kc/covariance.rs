//! A laboratory's own covariance of its pitch deviations: read from a solve result in
//! JSON (docs/FORMAT.md §5.1 `pitch_deviation_covariance`), and checked before the closed
//! vector's GLS uses it (symmetric, positive semi-definite, closed, invertible on the
//! closed subspace).

use nalgebra::DMatrix;
use serde::Deserialize;

use super::closed::closing_projector;
use super::{KcError, LabResult};
use crate::measurement::step_angle_deg;
use crate::results::{Quantity, ResultRow};

/// Relative tolerance of the symmetry test: |C_ij − C_ji| ≤ tol·max_f C_ff.
const SYMMETRY_TOLERANCE: f64 = 1e-9;
/// Relative tolerance of the closure test: |Σ_j C_ij| ≤ tol·Σ_j |C_ij|.
const CLOSURE_TOLERANCE: f64 = 1e-6;
/// Relative tolerance of the eigenvalues: below −tol·λ_max not positive semi-definite;
/// up to +tol·λ_max (on the closed subspace) singular.
const EIGENVALUE_TOLERANCE: f64 = 1e-9;

/// The members of a solve result in JSON that a key comparison reads.
#[derive(Deserialize)]
struct SolveJson {
    faces: usize,
    pitch_deviation: Vec<f64>,
    pitch_deviation_u: Option<Vec<f64>>,
    #[serde(rename = "pitch_deviation_U")]
    pitch_deviation_expanded_u: Option<Vec<f64>>,
    pitch_deviation_k: Option<Vec<Option<f64>>>,
    pitch_deviation_covariance: Option<Vec<Vec<f64>>>,
    encoder_error: Vec<f64>,
    encoder_error_u: Option<Vec<f64>>,
    #[serde(rename = "encoder_error_U")]
    encoder_error_expanded_u: Option<Vec<f64>>,
    encoder_error_k: Option<Vec<Option<f64>>>,
    encoder_angle_deg: Option<Vec<f64>>,
}

/// The rows of one family: value, and u (from U/k when the budget's U is there, else the
/// fit's u); a row without either has no uncertainty (refused later, by row).
fn family_rows(
    quantity: Quantity,
    values: &[f64],
    u: Option<&Vec<f64>>,
    expanded_u: Option<&Vec<f64>>,
    k: Option<&Vec<Option<f64>>>,
    first_index: u32,
) -> Vec<ResultRow> {
    values
        .iter()
        .enumerate()
        .map(|(i, &value)| {
            let mut row = ResultRow::new(quantity, first_index + i as u32, value);
            if let Some(&u) = u.and_then(|u| u.get(i)) {
                row = row.with_u(u);
            }
            if let (Some(&expanded_u), Some(&Some(k))) =
                (expanded_u.and_then(|e| e.get(i)), k.and_then(|k| k.get(i)))
            {
                // the budget's U/k is the standard uncertainty, not the fit's u alone
                row.u = None;
                row = row.with_expanded_u(expanded_u).with_k(k);
            }
            row
        })
        .collect()
}

/// A laboratory's result from a solve result in JSON (docs/FORMAT.md §5.1): its pitch
/// deviations and encoder errors with their standard uncertainties (U/k where the
/// budget's `pitch_deviation_U` and `pitch_deviation_k` are given, else the fit's `…_u`),
/// and, when it carries `pitch_deviation_covariance` (the fit's σ²Q of β, arcsec²), that
/// covariance for the closed vector. With a budget, the budget's variance beyond the
/// fit's, e_f² = max(0, u_f² − C_ff), is taken as independent per face and closed:
/// V = C + P·diag(e²)·P, P = I − J/N. `source` names the file in messages.
///
/// # Errors
///
/// [`KcError::SolveJson`]: not such an object (with serde's line and column), lists not
/// of N entries, or a covariance not N rows of N.
pub fn lab_from_solve_json(
    name: impl Into<String>,
    bytes: &[u8],
    source: &str,
) -> Result<LabResult, KcError> {
    let refused = |message: String| KcError::SolveJson {
        file: source.to_string(),
        message,
    };
    let json: SolveJson = serde_json::from_slice(bytes).map_err(|e| refused(e.to_string()))?;
    let faces = json.faces;
    let lengths = [
        ("pitch_deviation", Some(json.pitch_deviation.len())),
        (
            "pitch_deviation_u",
            json.pitch_deviation_u.as_ref().map(Vec::len),
        ),
        (
            "pitch_deviation_U",
            json.pitch_deviation_expanded_u.as_ref().map(Vec::len),
        ),
        (
            "pitch_deviation_k",
            json.pitch_deviation_k.as_ref().map(Vec::len),
        ),
        (
            "pitch_deviation_covariance",
            json.pitch_deviation_covariance.as_ref().map(Vec::len),
        ),
    ];
    for (member, len) in lengths {
        if let Some(len) = len
            && len != faces
        {
            return Err(refused(format!(
                "{member} has {len} entries, but faces is {faces}"
            )));
        }
    }
    let mut rows = family_rows(
        Quantity::PitchDeviation,
        &json.pitch_deviation,
        json.pitch_deviation_u.as_ref(),
        json.pitch_deviation_expanded_u.as_ref(),
        json.pitch_deviation_k.as_ref(),
        1,
    );
    let mut encoder = family_rows(
        Quantity::EncoderError,
        &json.encoder_error,
        json.encoder_error_u.as_ref(),
        json.encoder_error_expanded_u.as_ref(),
        json.encoder_error_k.as_ref(),
        0,
    );
    for (p, row) in encoder.iter_mut().enumerate() {
        let angle = match &json.encoder_angle_deg {
            Some(angles) => angles.get(p).copied(),
            None => Some(step_angle_deg(p as u32, faces)),
        };
        if let Some(angle) = angle {
            row.angle_deg = Some(angle);
        }
    }
    rows.extend(encoder);
    let covariance = match json.pitch_deviation_covariance {
        None => None,
        Some(matrix) => {
            let mut flat = Vec::with_capacity(faces * faces);
            for (f, row) in matrix.iter().enumerate() {
                if row.len() != faces {
                    return Err(refused(format!(
                        "pitch_deviation_covariance row {} has {} entries, {faces} expected",
                        f + 1,
                        row.len()
                    )));
                }
                flat.extend_from_slice(row);
            }
            if json.pitch_deviation_expanded_u.is_some() {
                add_closed_excess(&mut flat, &rows[..faces]);
            }
            Some(flat)
        }
    };
    let mut lab = LabResult::from_rows(name, rows);
    lab.source = source.to_string();
    lab.covariance = covariance;
    Ok(lab)
}

/// Adds the budget's variance beyond the fit's, closed: C + P·diag(e²)·P with
/// e_f² = max(0, u_f² − C_ff), u_f = U_f/k_f of the row.
fn add_closed_excess(flat: &mut [f64], rows: &[ResultRow]) {
    let faces = rows.len();
    let p = closing_projector(faces);
    let excess: Vec<f64> = rows
        .iter()
        .enumerate()
        .map(|(f, row)| match (row.expanded_u, row.k) {
            (Some(expanded_u), Some(k)) if k > 0.0 => {
                ((expanded_u / k).powi(2) - flat[f * faces + f]).max(0.0)
            }
            _ => 0.0,
        })
        .collect();
    for i in 0..faces {
        for j in 0..faces {
            flat[i * faces + j] += (0..faces)
                .map(|f| p[(i, f)] * excess[f] * p[(f, j)])
                .sum::<f64>();
        }
    }
}

/// Checks a laboratory's covariance of its `faces` pitch deviations (row-major): N × N,
/// finite, symmetric (|C_ij − C_ji| ≤ 1e-9·max C_ff), closed (every row's
/// |Σ_j C_ij| ≤ 1e-6·Σ_j |C_ij|), positive semi-definite (no eigenvalue below
/// −1e-9·λ_max) and of rank N − 1 (every eigenvalue on the closed subspace above
/// 1e-9·λ_max). Returns the matrix.
pub(crate) fn checked(lab: &LabResult, faces: usize) -> Result<DMatrix<f64>, KcError> {
    let refused = |reason: String| KcError::Covariance {
        file: lab.source.clone(),
        lab: lab.name.clone(),
        reason,
    };
    let Some(flat) = &lab.covariance else {
        return Err(refused("none given".to_string()));
    };
    if flat.len() != faces * faces {
        return Err(refused(format!(
            "it has {} entries, but the result has {faces} faces ({} entries expected)",
            flat.len(),
            faces * faces
        )));
    }
    if let Some(at) = flat.iter().position(|c| !c.is_finite()) {
        return Err(refused(format!(
            "entry ({}, {}) is not a finite number",
            at / faces + 1,
            at % faces + 1
        )));
    }
    let c = DMatrix::from_row_slice(faces, faces, flat);
    let scale = (0..faces).map(|f| c[(f, f)].abs()).fold(0.0, f64::max);
    if scale == 0.0 {
        return Err(refused("its diagonal is zero".to_string()));
    }
    for i in 0..faces {
        for j in i + 1..faces {
            if (c[(i, j)] - c[(j, i)]).abs() > SYMMETRY_TOLERANCE * scale {
                return Err(refused(format!(
                    "it is not symmetric: entry ({}, {}) = {} but ({}, {}) = {}",
                    i + 1,
                    j + 1,
                    c[(i, j)],
                    j + 1,
                    i + 1,
                    c[(j, i)]
                )));
            }
        }
    }
    for i in 0..faces {
        let sum: f64 = c.row(i).iter().sum();
        let size: f64 = c.row(i).iter().map(|x| x.abs()).sum();
        if sum.abs() > CLOSURE_TOLERANCE * size {
            return Err(refused(format!(
                "it is not closed: row {} sums to {sum:e} arcsec², not 0 (pitch deviations sum \
                 to 0, so every row of their covariance does)",
                i + 1
            )));
        }
    }
    let eigen = c.clone().symmetric_eigen();
    let largest = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    let smallest = eigen
        .eigenvalues
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    if smallest < -EIGENVALUE_TOLERANCE * largest {
        return Err(refused(format!(
            "it is not positive semi-definite: eigenvalue {smallest:e} arcsec² (largest \
             {largest:e})"
        )));
    }
    // The constant direction is the null space of a closed covariance; lift it to λ_max
    // and every other eigenvalue must be positive.
    let lifted = &c + DMatrix::from_element(faces, faces, largest / faces as f64);
    let least = lifted
        .symmetric_eigen()
        .eigenvalues
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    if least <= EIGENVALUE_TOLERANCE * largest {
        return Err(refused(format!(
            "it is singular on the closed subspace: eigenvalue {least:e} arcsec² (largest \
             {largest:e}), so some combination of faces would have no uncertainty"
        )));
    }
    Ok(c)
}
