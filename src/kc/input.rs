//! The laboratories' results lined up quantity by quantity: every face (pitch deviations),
//! every common table angle (encoder errors) or every angle block with each result's value
//! and standard uncertainty, and the refusals of results that cannot be lined up.

use std::collections::BTreeMap;

use super::{KcError, LabResult};
use crate::results::{ANGLE_TOLERANCE_DEG, Quantity, ResultRow, RowColumns};

/// The results lined up: `values[r][k]` and `u[r][k]` of result `r` (laboratories first,
/// then the pilot's repeats) at position `k`.
#[derive(Debug, Clone)]
pub(crate) struct Aligned {
    /// Face 1 … N, or the first laboratory's index of each common encoder error.
    pub index: Vec<u32>,
    /// The table angle of each common encoder error, degrees (encoder errors matched by
    /// angle only).
    pub angle_deg: Option<Vec<f64>>,
    /// Values, arcseconds, per result and position.
    pub values: Vec<Vec<f64>>,
    /// Standard uncertainties, arcseconds, per result and position.
    pub u: Vec<Vec<f64>>,
    /// The degrees of freedom of each u (∞ where none is stated), per result and position.
    pub dof: Vec<Vec<f64>>,
    /// Whether the positions make a closed vector (pitch deviations, encoder errors less
    /// their mean), or are scalars each on its own (angle blocks).
    pub closed: bool,
    /// Whether each result reports each position (`None`: every result reports every
    /// one). Where it does not, its value is 0 and its u 1, never used.
    pub measured: Option<Vec<Vec<bool>>>,
    /// The nominal angle of each angle block, degrees, where the results state it.
    pub nominal_deg: Option<Vec<Option<f64>>>,
    /// What was left out, in words.
    pub notes: Vec<String>,
}

impl Aligned {
    /// Nothing lined up yet for `results` results: `closed` vectors or scalars, `measured`
    /// kept (some result may not report a position) or not.
    pub(super) fn empty(results: usize, closed: bool, measured: bool) -> Aligned {
        Aligned {
            index: Vec::new(),
            angle_deg: None,
            values: vec![Vec::new(); results],
            u: vec![Vec::new(); results],
            dof: vec![Vec::new(); results],
            closed,
            measured: measured.then(|| vec![Vec::new(); results]),
            nominal_deg: None,
            notes: Vec::new(),
        }
    }

    /// Adds one position (or block) in every result: the value, u and degrees of freedom
    /// of row `rows[r]` of result r, or, where it does not report it (`None`), a
    /// placeholder never used that `measured` marks.
    pub(super) fn push_position(
        &mut self,
        results: &[&LabResult],
        rows: &[Option<usize>],
    ) -> Result<(), KcError> {
        for (r, row) in rows.iter().enumerate() {
            if let Some(measured) = self.measured.as_mut() {
                measured[r].push(row.is_some());
            }
            let (value, u, dof) = match *row {
                Some(i) => {
                    let found = &results[r].rows[i];
                    let u = standard_u(results[r], i, found)?;
                    (found.value, u, found.dof.unwrap_or(f64::INFINITY))
                }
                None => (0.0, 1.0, f64::INFINITY),
            };
            self.values[r].push(value);
            self.u[r].push(u);
            self.dof[r].push(dof);
        }
        Ok(())
    }

    /// Done: refused when no position is compared; `measured` dropped when every result
    /// reports every position.
    pub(super) fn finished(mut self) -> Result<Aligned, KcError> {
        if self.index.is_empty() {
            return Err(KcError::NothingInCommon);
        }
        if self
            .measured
            .as_ref()
            .is_some_and(|m| m.iter().flatten().all(|&m| m))
        {
            self.measured = None;
        }
        Ok(self)
    }
}

/// `file:line:column` of a field of row `i` of a result (`file:line` when its columns are
/// not known), or `name (row i+1)` for rows given in memory.
pub(super) fn location(result: &LabResult, i: usize, field: Field) -> String {
    match result.lines.get(i) {
        Some(line) => match result.columns.get(i).and_then(|c| field.column(c)) {
            Some(column) => format!("{}:{line}:{column}", result.source),
            None => format!("{}:{line}", result.source),
        },
        None => format!("{} (row {})", result.source, i + 1),
    }
}

/// The field of a row a refusal points at.
#[derive(Debug, Clone, Copy)]
pub(super) enum Field {
    /// The row's `index`.
    Index,
    /// Its `U`.
    ExpandedU,
    /// Its `u`.
    U,
    /// Its `nominal_deg` (else its index).
    Nominal,
    /// Where a missing standard uncertainty would be: `u`, else `k` (U without its k),
    /// else `U`, else the row's index.
    MissingU,
}

impl Field {
    fn column(self, columns: &RowColumns) -> Option<u64> {
        match self {
            Field::Index => Some(columns.index),
            Field::ExpandedU => columns.expanded_u,
            Field::U => columns.u,
            Field::Nominal => columns.nominal_deg.or(Some(columns.index)),
            Field::MissingU => columns
                .u
                .or(columns.k)
                .or(columns.expanded_u)
                .or(Some(columns.index)),
        }
    }
}

/// The standard uncertainty of a row: its `u` when given, else `U/k`; `U` and `u`, where
/// given, must be positive.
pub(super) fn standard_u(result: &LabResult, i: usize, row: &ResultRow) -> Result<f64, KcError> {
    let non_positive = |column: &'static str, value: f64| KcError::NonPositiveUncertainty {
        location: location(
            result,
            i,
            if column == "U" {
                Field::ExpandedU
            } else {
                Field::U
            },
        ),
        quantity: row.quantity,
        index: row.index,
        column,
        value,
    };
    if let Some(expanded_u) = row.expanded_u
        && !(expanded_u > 0.0 && expanded_u.is_finite())
    {
        return Err(non_positive("U", expanded_u));
    }
    let u = if let Some(u) = row.u {
        if !(u > 0.0 && u.is_finite()) {
            return Err(non_positive("u", u));
        }
        u
    } else {
        match (row.expanded_u, row.k) {
            (Some(expanded_u), Some(k)) if k > 0.0 && k.is_finite() => expanded_u / k,
            _ => {
                return Err(KcError::MissingUncertainty {
                    location: location(result, i, Field::MissingU),
                    quantity: row.quantity,
                    index: row.index,
                });
            }
        }
    };
    if u < MIN_STANDARD_U_ARCSEC {
        return Err(KcError::UncertaintyTooSmall {
            location: location(
                result,
                i,
                if row.u.is_some() {
                    Field::U
                } else {
                    Field::ExpandedU
                },
            ),
            quantity: row.quantity,
            index: row.index,
            value: u,
            minimum: MIN_STANDARD_U_ARCSEC,
        });
    }
    Ok(u)
}

/// The smallest standard uncertainty a comparison takes, arcseconds (10⁻⁹″ ≈ 4.8·10⁻¹⁵ rad,
/// far below any angle measurement): smaller ones are refused, not computed with.
pub const MIN_STANDARD_U_ARCSEC: f64 = 1e-9;

/// `file:line:column` of the index of a result's last row of `quantity` (in file order), or
/// the result's file when it has none.
pub(super) fn last_row(result: &LabResult, quantity: Quantity) -> String {
    match rows_of(result, quantity).last() {
        Some(&(i, _)) => location(result, i, Field::Index),
        None => result.source.clone(),
    }
}

/// The rows of `quantity` of one result, with their position in the result.
pub(super) fn rows_of(result: &LabResult, quantity: Quantity) -> Vec<(usize, &ResultRow)> {
    result
        .rows
        .iter()
        .enumerate()
        .filter(|(_, row)| row.quantity == quantity)
        .collect()
}

/// The rows of `quantity` in `result` ([`rows_of`]), refused when it has none.
pub(super) fn rows_required(
    result: &LabResult,
    quantity: Quantity,
) -> Result<Vec<(usize, &ResultRow)>, KcError> {
    let rows = rows_of(result, quantity);
    if rows.is_empty() {
        return Err(KcError::NoRows {
            lab: result.name.clone(),
            file: result.source.clone(),
            quantity,
        });
    }
    Ok(rows)
}

/// Lines up the pitch deviations: every result must have faces 1 … N, the same N. A
/// result whose pitch deviations do not close beyond the rounding of its digits is noted
/// (its mean is taken out), or refused when the misclosure is gross ([`super::closure`]).
pub(crate) fn pitch(results: &[&LabResult]) -> Result<Aligned, KcError> {
    let mut aligned = faces(results, Quantity::PitchDeviation)?;
    let notes = super::closure::misclosures(results, &aligned)?;
    aligned.notes.extend(notes);
    Ok(aligned)
}

/// The last face of each result's rows of `quantity` that has the most faces, with its
/// source: the N a result one face short of is missing its last face against.
fn most_faces<'a>(results: &[&'a LabResult], quantity: Quantity) -> Option<(u32, &'a str)> {
    results
        .iter()
        .filter_map(|result| {
            let last = result
                .rows
                .iter()
                .filter(|row| row.quantity == quantity)
                .map(|row| row.index)
                .max()?;
            Some((last, result.source.as_str()))
        })
        .fold(None, |most, (last, source)| match most {
            Some((n, _)) if n >= last => most,
            _ => Some((last, source)),
        })
}

/// Lines up a quantity indexed by face (pitch or face deviations): every result must
/// have faces 1 … N of it, the same N (`polycal history` lines up face deviations too).
pub(crate) fn faces(results: &[&LabResult], quantity: Quantity) -> Result<Aligned, KcError> {
    let most = most_faces(results, quantity);
    let mut faces_first: Option<(u32, &str)> = None;
    let (mut values, mut u, mut dof) = (Vec::new(), Vec::new(), Vec::new());
    for result in results {
        let rows = rows_required(result, quantity)?;
        let Some(&(last_at, _)) = rows.iter().max_by_key(|(_, row)| row.index) else {
            continue;
        };
        let faces = result.rows[last_at].index;
        let mut by_face: BTreeMap<u32, usize> = BTreeMap::new();
        for &(i, row) in &rows {
            if row.index == 0 || by_face.insert(row.index, i).is_some() {
                return Err(KcError::Duplicate {
                    location: location(result, i, Field::Index),
                    quantity: row.quantity,
                    index: row.index,
                });
            }
        }
        if let Some((n, with_n)) = most
            && faces.checked_add(1) == Some(n)
        {
            return Err(KcError::LastFaceMissing {
                location: location(result, last_at, Field::Index),
                quantity,
                face: n,
                other_source: with_n.to_string(),
            });
        }
        match faces_first {
            None => faces_first = Some((faces, &result.source)),
            Some((first, first_source)) if first != faces => {
                return Err(KcError::FacesDiffer {
                    location: location(result, last_at, Field::Index),
                    faces,
                    first_source: first_source.to_string(),
                    first_faces: first,
                });
            }
            Some(_) => {}
        }
        let (mut x, mut s, mut nu) = (Vec::new(), Vec::new(), Vec::new());
        for face in 1..=faces {
            let Some(&i) = by_face.get(&face) else {
                return Err(KcError::FaceMissing {
                    location: location(result, last_at, Field::Index),
                    face,
                    faces,
                });
            };
            let row = &result.rows[i];
            x.push(row.value);
            s.push(standard_u(result, i, row)?);
            nu.push(row.dof.unwrap_or(f64::INFINITY));
        }
        values.push(x);
        u.push(s);
        dof.push(nu);
    }
    let faces = faces_first.map_or(0, |(n, _)| n);
    Ok(Aligned {
        index: (1..=faces).collect(),
        angle_deg: None,
        values,
        u,
        dof,
        closed: true,
        measured: None,
        nominal_deg: None,
        notes: Vec::new(),
    })
}

/// Whether the encoder errors are matched by angle: every one of every result carries
/// `angle_deg`. Refused when some carry it and others do not (matched by index they would
/// be paired silently by step number): at the first row without an angle, naming a
/// result with angles.
fn matched_by_angle(results: &[&LabResult]) -> Result<bool, KcError> {
    let rows = |result: &LabResult| {
        rows_of(result, Quantity::EncoderError)
            .into_iter()
            .map(|(i, row)| (i, row.index, row.angle_deg.is_some()))
            .collect::<Vec<_>>()
    };
    let Some(with_angles) = results
        .iter()
        .find(|result| rows(result).iter().any(|&(_, _, angle)| angle))
    else {
        return Ok(false);
    };
    for result in results {
        if let Some(&(i, index, _)) = rows(result).iter().find(|&&(_, _, angle)| !angle) {
            return Err(KcError::AngleMissing {
                location: location(result, i, Field::Index),
                index,
                with_angles: with_angles.source.clone(),
            });
        }
    }
    Ok(true)
}

/// One position of an encoder error across the results: the row of each result there.
struct Group {
    key: f64,
    rows: Vec<Option<usize>>,
}

/// Lines up the encoder errors: by table angle (within [`ANGLE_TOLERANCE_DEG`] around the
/// circle) when every encoder error of every result carries `angle_deg`, else by index.
/// Positions not in every result are left out and named in a note (what a standard's
/// history compares, `polycal history`).
pub(crate) fn encoder(results: &[&LabResult]) -> Result<Aligned, KcError> {
    encoder_lined_up(results, None)
}

/// Lines up the encoder errors of the laboratories `results[..labs]` and the pilot's
/// repeats after them as [`encoder`] does, but each laboratory compared on the positions it
/// reports (docs/FORMAT.md §12, "What each laboratory measured"): a position reported by at
/// least two laboratories is kept, and `measured` says who reports it; one reported by
/// fewer is left out and named in a note. The pilot's repeats must report every position
/// kept (their spread is the artefact's stability there).
pub(crate) fn encoder_reported(results: &[&LabResult], labs: usize) -> Result<Aligned, KcError> {
    encoder_lined_up(results, Some(labs))
}

/// Every position of the encoder errors of `results` (by angle within
/// [`ANGLE_TOLERANCE_DEG`] when `by_angle`, else by index), ascending, with the row of each
/// result there; a result without encoder errors, or with two at one position, refused.
fn position_groups(results: &[&LabResult], by_angle: bool) -> Result<Vec<Group>, KcError> {
    // Every (key, result, row), sorted by key.
    let mut all: Vec<(f64, usize, usize)> = Vec::new();
    for (r, result) in results.iter().enumerate() {
        let rows = rows_required(result, Quantity::EncoderError)?;
        for (i, row) in rows {
            let key = match (by_angle, row.angle_deg) {
                (true, Some(angle)) if angle >= 360.0 - ANGLE_TOLERANCE_DEG => angle - 360.0,
                (true, Some(angle)) => angle,
                _ => f64::from(row.index),
            };
            all.push((key, r, i));
        }
    }
    all.sort_by(|a, b| a.0.total_cmp(&b.0));
    let tolerance = if by_angle { ANGLE_TOLERANCE_DEG } else { 0.0 };
    let mut groups: Vec<Group> = Vec::new();
    for (key, r, i) in all {
        let fresh = groups
            .last()
            .is_none_or(|group| key - group.key > tolerance);
        if fresh {
            groups.push(Group {
                key,
                rows: vec![None; results.len()],
            });
        }
        let Some(group) = groups.last_mut() else {
            continue;
        };
        if group.rows[r].is_some() {
            return Err(KcError::Duplicate {
                location: location(results[r], i, Field::Index),
                quantity: Quantity::EncoderError,
                index: results[r].rows[i].index,
            });
        }
        group.rows[r] = Some(i);
    }
    Ok(groups)
}

/// Lines up the encoder errors of `results` by angle (every row with one) or by index (none
/// with one): with `labs` (a comparison; the pilot's repeats after them) a position is kept
/// when at least two laboratories report it, and the repeats must report every position
/// kept; without (a plain comparison of results) only positions in every result are kept.
/// What is left out is named in a note. [`encoder`] is it with `labs` `None`,
/// [`encoder_reported`] with `Some(labs)`.
fn encoder_lined_up(results: &[&LabResult], labs: Option<usize>) -> Result<Aligned, KcError> {
    let by_angle = matched_by_angle(results)?;
    let groups = position_groups(results, by_angle)?;
    let mut aligned = Aligned::empty(results.len(), true, labs.is_some());
    aligned.angle_deg = by_angle.then(Vec::new);
    let at = |group: &Group| {
        if by_angle {
            format!("{}°", group.key.max(0.0))
        } else {
            format!("index {}", group.key)
        }
    };
    let mut left_out = Vec::new();
    for group in &groups {
        let kept = match labs {
            None => group.rows.iter().all(Option::is_some),
            Some(labs) => group.rows[..labs].iter().filter(|r| r.is_some()).count() >= 2,
        };
        if let (true, Some(labs)) = (kept, labs)
            && let Some(r) = (labs..results.len()).find(|&r| group.rows[r].is_none())
        {
            return Err(KcError::RepeatMissesPosition {
                location: last_row(results[r], Quantity::EncoderError),
                repeat: results[r].name.clone(),
                position: at(group),
            });
        }
        if !kept {
            left_out.push(left_out_words(group, results, labs, &at(group)));
            continue;
        }
        // the index and the angle of the first result that reports it
        if let Some((r, i)) = group
            .rows
            .iter()
            .enumerate()
            .find_map(|(r, row)| row.map(|i| (r, i)))
        {
            let found = &results[r].rows[i];
            aligned.index.push(found.index);
            if let Some(angles) = aligned.angle_deg.as_mut() {
                angles.push(found.angle_deg.unwrap_or(group.key));
            }
        }
        aligned.push_position(results, &group.rows)?;
    }
    let mut aligned = aligned.finished()?;
    if !left_out.is_empty() {
        aligned.notes.push(format!(
            "encoder errors matched by {}: {} position(s) {} left out: {}",
            if by_angle { "angle" } else { "index" },
            left_out.len(),
            if labs.is_some() {
                "reported by fewer than two laboratories"
            } else {
                "not in every result"
            },
            left_out.join("; ")
        ));
    }
    Ok(aligned)
}

/// A position left out (`at`, in words) with whom: the results it is not in (a plain
/// comparison), or the one laboratory that reports it (`labs`: a comparison).
fn left_out_words(group: &Group, results: &[&LabResult], labs: Option<usize>, at: &str) -> String {
    let missing: Vec<&str> = group
        .rows
        .iter()
        .zip(results)
        .filter(|(row, _)| row.is_none())
        .map(|(_, result)| result.name.as_str())
        .collect();
    let reporting: Vec<&str> = group.rows[..labs.unwrap_or(results.len())]
        .iter()
        .zip(results)
        .filter(|(row, _)| row.is_some())
        .map(|(_, result)| result.name.as_str())
        .collect();
    match (labs, reporting.as_slice()) {
        (None, _) => format!("{at} (not in {})", missing.join(", ")),
        (Some(_), []) => format!("{at} (by the pilot's repeats only)"),
        (Some(_), by) => format!("{at} (by {} only)", by.join(", ")),
    }
}
