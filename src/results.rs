//! The result file (docs/FORMAT.md §3): one row per estimated quantity.
//!
//! ```text
//! quantity,index,value,U,u,k,angle_deg
//! pitch_deviation,1,0.52,0.46,0.2287,1.993,
//! encoder_error,1,-0.11,0.46,,,15
//! ```
//!
//! Columns may come in any order; `quantity`, `index` and `value` are required; `U`
//! (expanded uncertainty), `u` (standard uncertainty), `k` (coverage factor) and
//! `angle_deg` (the table angle of an encoder error, degrees) are optional, an empty field
//! meaning "not given" (`compare` needs `U`). Column names are case-sensitive (`U` and `u`
//! differ). Columns this version does not know are ignored (docs/FORMAT.md allows adding
//! columns). Lines starting with `#` before the header are comments.
//!
//! Reading is strict: an unknown quantity, an index out of range, a number that is not
//! finite, a negative uncertainty, a duplicate `(quantity, index)` is refused with
//! `file:line:column` and nothing is guessed. So is an `angle_deg` outside 0 ≤ angle < 360,
//! one on a row that is not an encoder error, two encoder errors at the same angle (within
//! [`ANGLE_TOLERANCE_DEG`], around the circle), and a file where some encoder errors carry
//! an angle and others do not.

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::Path;

use crate::input::Location;
use crate::input::kind::{self, FileKind};
use crate::input::limits::{self, Limit};
use serde::{Deserialize, Serialize};

/// The four families of calibrated quantities (docs/FORMAT.md §3), the crate's one list
/// of them: result files, reports, uncertainties and truths name them through this type.
///
/// ```
/// use polycal::results::Quantity;
/// assert_eq!(Quantity::EncoderError.name(), "encoder_error");
/// assert_eq!(Quantity::from_name("pitch_deviation"), Some(Quantity::PitchDeviation));
/// assert_eq!(Quantity::ALL.len(), 4);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// β\[k\], pitch deviation of face k = 1 … N.
    PitchDeviation,
    /// φ\[f\] = β\[1\] + … + β\[f\], face deviation of face f = 1 … N.
    FaceDeviation,
    /// α\[p\], encoder error at step p = 0 … N−1.
    EncoderError,
    /// U\[setup, ac\], setup error of an autocollimator (index: ac, or setup·1000 + ac
    /// with several mountings).
    SetupError,
}

impl Quantity {
    /// The four families in the order results are written.
    pub const ALL: [Quantity; 4] = [
        Quantity::PitchDeviation,
        Quantity::FaceDeviation,
        Quantity::EncoderError,
        Quantity::SetupError,
    ];

    /// The name as spelled in files and JSON, e.g. `pitch_deviation`.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::PitchDeviation => "pitch_deviation",
            Quantity::FaceDeviation => "face_deviation",
            Quantity::EncoderError => "encoder_error",
            Quantity::SetupError => "setup_error",
        }
    }

    /// The family of a name as spelled in files, or `None`.
    pub fn from_name(name: &str) -> Option<Quantity> {
        Quantity::ALL.into_iter().find(|q| q.name() == name)
    }
}

impl ResultsError {
    /// Where the problem is ([`ResultsError::At`]); `None` for an I/O error.
    pub fn location(&self) -> Option<&Location> {
        match self {
            ResultsError::At { location, .. } | ResultsError::WrongKind { location, .. } => {
                Some(location)
            }
            ResultsError::Io { .. } => None,
        }
    }

    /// What the file is, when it is of another kind than a result file
    /// ([`ResultsError::WrongKind`]).
    pub fn found_kind(&self) -> Option<crate::input::kind::FileKind> {
        match self {
            ResultsError::WrongKind { found, .. } => Some(*found),
            _ => None,
        }
    }
}

impl std::fmt::Display for Quantity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl PartialEq<&str> for Quantity {
    fn eq(&self, other: &&str) -> bool {
        self.name() == *other
    }
}

/// One row of a result file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResultRow {
    /// The family: `pitch_deviation`, `face_deviation`, `encoder_error` or `setup_error`.
    pub quantity: Quantity,
    /// Face 1 … N, step 0 … N−1, or autocollimator number.
    pub index: u32,
    /// Estimate, arcseconds.
    pub value: f64,
    /// Standard uncertainty, arcseconds (column `u`).
    pub u: Option<f64>,
    /// Expanded uncertainty, arcseconds (column `U`).
    #[serde(rename = "U")]
    pub expanded_u: Option<f64>,
    /// Coverage factor (column `k`).
    pub k: Option<f64>,
    /// For `encoder_error` rows: the table angle of that position, degrees, 0 ≤ angle < 360
    /// (column `angle_deg`); `None` on every other row.
    pub angle_deg: Option<f64>,
}

impl ResultRow {
    /// A row with its estimate only: no `U`, `u`, `k` or angle (add them with the
    /// `with_…` methods).
    ///
    /// ```
    /// use polycal::results::{Quantity, ResultRow};
    /// let row = ResultRow::new(Quantity::EncoderError, 1, -0.11)
    ///     .with_expanded_u(0.46)
    ///     .with_angle_deg(15.0);
    /// assert_eq!((row.expanded_u, row.u, row.angle_deg), (Some(0.46), None, Some(15.0)));
    /// ```
    pub fn new(quantity: Quantity, index: u32, value: f64) -> ResultRow {
        ResultRow {
            quantity,
            index,
            value,
            u: None,
            expanded_u: None,
            k: None,
            angle_deg: None,
        }
    }

    /// With an expanded uncertainty `U`, arcseconds.
    pub fn with_expanded_u(mut self, expanded_u: f64) -> ResultRow {
        self.expanded_u = Some(expanded_u);
        self
    }

    /// With a standard uncertainty `u`, arcseconds.
    pub fn with_u(mut self, u: f64) -> ResultRow {
        self.u = Some(u);
        self
    }

    /// With a coverage factor `k`.
    pub fn with_k(mut self, k: f64) -> ResultRow {
        self.k = Some(k);
        self
    }

    /// With the table angle of an encoder error, degrees (checked when the row is
    /// written, read or compared: 0 ≤ angle < 360, `encoder_error` rows only).
    pub fn with_angle_deg(mut self, angle_deg: f64) -> ResultRow {
        self.angle_deg = Some(angle_deg);
        self
    }
}

/// Two table angles of encoder errors closer than this around the circle (degrees) are
/// the same position: within a result file they are refused as a duplicate, and
/// `compare` matches encoder errors of two results by angle within it (docs/FORMAT.md §3,
/// §5.4).
pub const ANGLE_TOLERANCE_DEG: f64 = 1e-6;

/// The distance between two table angles around the circle, degrees, 0 … 180 (so that
/// 359.9999999° and 0° are 1e-7° apart).
///
/// ```
/// use polycal::results::angle_distance_deg;
/// assert!(angle_distance_deg(359.9999999, 0.0) < 1e-6);
/// assert_eq!(angle_distance_deg(10.0, 350.0), 20.0);
/// ```
pub fn angle_distance_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// Whether `angle_deg` is a table angle a result file may carry: finite, 0 ≤ angle < 360.
pub(crate) fn angle_in_range(angle_deg: f64) -> bool {
    angle_deg.is_finite() && (0.0..360.0).contains(&angle_deg)
}

/// What breaks the angle rules of a result file (docs/FORMAT.md §3.2) across its rows;
/// rows are named by their position in the file (0-based), the caller names them by line
/// or by row number.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum AngleProblem {
    /// The angle is not finite or not in 0 ≤ angle < 360.
    OutOfRange,
    /// An angle on a row that is not an encoder error.
    NotEncoder,
    /// Encoder row `without` has no angle while encoder row `with` has one; the problem is
    /// reported at `without` (the first row without an angle).
    Missing {
        /// The first encoder row without an angle.
        without: usize,
        /// An encoder row with one.
        with: usize,
    },
    /// The angle is (within [`ANGLE_TOLERANCE_DEG`]) that of the earlier encoder row
    /// `first`.
    Duplicate {
        /// The earlier row.
        first: usize,
    },
}

impl AngleProblem {
    /// The message for the problem found on admitting `row`, `rows` being the rows admitted
    /// before it (so `row`'s position is `rows.len()`) and `place` naming a row by its
    /// position ("line 7", "row 3").
    pub(crate) fn message(
        &self,
        row: &ResultRow,
        rows: &[ResultRow],
        place: impl Fn(usize) -> String,
    ) -> String {
        let describe = |i: usize| match rows.get(i) {
            Some(r) => format!("{} {}", r.quantity, r.index),
            None => format!("{} {}", row.quantity, row.index),
        };
        match self {
            AngleProblem::OutOfRange => format!(
                "angle_deg must be a finite number of degrees, 0 ≤ angle_deg < 360, got {}",
                row.angle_deg
                    .map_or("nothing".to_string(), |a| a.to_string())
            ),
            AngleProblem::NotEncoder => format!(
                "angle_deg is given for {} {}: only encoder_error rows carry a table angle \
                 (leave the field empty)",
                row.quantity, row.index
            ),
            AngleProblem::Missing { without, with } => format!(
                "{} has no angle_deg, but {} on {} has one: either every encoder_error row \
                 carries its table angle or none does",
                describe(*without),
                describe(*with),
                place(*with)
            ),
            AngleProblem::Duplicate { first } => format!(
                "{} {} at angle_deg {} is the position of {} on {} (angles within {:e}° \
                 around the circle are one position)",
                row.quantity,
                row.index,
                row.angle_deg.unwrap_or(f64::NAN),
                describe(*first),
                place(*first),
                ANGLE_TOLERANCE_DEG
            ),
        }
    }
}

/// The angle rules of a result file, checked row by row in file order: angles only on
/// encoder errors, 0 ≤ angle < 360, every encoder error with an angle or none, no two at
/// one position.
#[derive(Debug, Default)]
pub(crate) struct AngleCheck {
    /// The angles seen (non-negative, so their bits sort as the numbers) and their rows.
    seen: BTreeMap<u64, usize>,
    first_with: Option<usize>,
    first_without: Option<usize>,
}

impl AngleCheck {
    /// Admits row `position` (the rows before it admitted already).
    pub(crate) fn admit(&mut self, position: usize, row: &ResultRow) -> Result<(), AngleProblem> {
        if row.quantity != Quantity::EncoderError {
            return match row.angle_deg {
                Some(_) => Err(AngleProblem::NotEncoder),
                None => Ok(()),
            };
        }
        let Some(angle) = row.angle_deg else {
            if let Some(with) = self.first_with {
                return Err(AngleProblem::Missing {
                    without: position,
                    with,
                });
            }
            self.first_without.get_or_insert(position);
            return Ok(());
        };
        if !angle_in_range(angle) {
            return Err(AngleProblem::OutOfRange);
        }
        if let Some(without) = self.first_without {
            return Err(AngleProblem::Missing {
                without,
                with: position,
            });
        }
        self.first_with.get_or_insert(position);
        let angle = angle + 0.0; // −0 is 0
        if let Some(first) = self.near(angle) {
            return Err(AngleProblem::Duplicate { first });
        }
        self.seen.insert(angle.to_bits(), position);
        Ok(())
    }

    /// The earliest row seen whose angle is within the tolerance of `angle`.
    fn near(&self, angle: f64) -> Option<usize> {
        let tolerance = ANGLE_TOLERANCE_DEG;
        let mut windows = vec![(angle - tolerance, angle + tolerance)];
        if angle - tolerance < 0.0 {
            windows.push((angle - tolerance + 360.0, 360.0));
        }
        if angle + tolerance >= 360.0 {
            windows.push((0.0, angle + tolerance - 360.0));
        }
        windows
            .into_iter()
            .flat_map(|(low, high)| {
                // Widened by a hair, then judged by the distance itself.
                let low = (low - tolerance).max(0.0);
                let high = high + tolerance;
                self.seen.range(low.to_bits()..=high.to_bits())
            })
            .filter(|(bits, _)| angle_distance_deg(f64::from_bits(**bits), angle) <= tolerance)
            .map(|(_, &position)| position)
            .min()
    }
}

/// A result file as read: its rows and where each came from.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultFile {
    /// The path, or `<stdin>`.
    pub source: String,
    /// The rows, in file order.
    pub rows: Vec<ResultRow>,
    /// The 1-based line of each row.
    pub lines: Vec<u64>,
    /// The 1-based character columns of each row's fields (empty when not known, as for
    /// rows restored from elsewhere): what a later refusal of a row's value names.
    pub columns: Vec<RowColumns>,
}

/// Where a result row's fields start on its line: 1-based character columns, `None` for a
/// column the file does not have.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RowColumns {
    /// The `quantity` field.
    pub quantity: u64,
    /// The `index` field.
    pub index: u64,
    /// The `value` field.
    pub value: u64,
    /// The `U` field.
    pub expanded_u: Option<u64>,
    /// The `u` field.
    pub u: Option<u64>,
    /// The `k` field.
    pub k: Option<u64>,
}

/// The columns a result file must have (docs/FORMAT.md §3).
pub(crate) const REQUIRED_COLUMNS: [&str; 3] = ["quantity", "index", "value"];

/// Why a result file cannot be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ResultsError {
    /// A problem at a place in the file.
    #[error("{location}: {message}")]
    At {
        /// Where: the file (`<stdin>` for standard input), 1-based line and 1-based
        /// character column.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// A file of another kind given as a result file: a measurement file, a budget, …
    /// (docs/FORMAT.md §8). Displayed as `file:line:column: … this is a measurement file
    /// (…), not a result file`.
    #[error("{location}: {message}")]
    WrongKind {
        /// Where: the file and the line that tells its kind.
        location: Location,
        /// What the file is, and what was expected.
        message: String,
        /// What the file is.
        found: crate::input::kind::FileKind,
    },
    /// The file could not be read.
    #[error("{file}: {source}")]
    Io {
        /// The file name.
        file: String,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// Reads a result file strictly; `-` reads standard input. See [`read_result_file`] for
/// the rows' line numbers.
///
/// # Errors
///
/// [`ResultsError::At`] with file, line and column for anything invalid;
/// [`ResultsError::Io`] if the file cannot be read.
pub fn read_results_path(path: impl AsRef<Path>) -> Result<Vec<ResultRow>, ResultsError> {
    read_result_file(path).map(|f| f.rows)
}

/// Reads a result file strictly, keeping each row's line number; `-` reads standard
/// input.
///
/// # Errors
///
/// As [`read_results_path`].
pub fn read_result_file(path: impl AsRef<Path>) -> Result<ResultFile, ResultsError> {
    let path = path.as_ref();
    let (bytes, name) = crate::input::read_bytes(path)
        .map_err(|(file, source)| ResultsError::Io { file, source })?;
    read_results_from(&bytes[..], &name)
}

/// Reads a result file from any reader; `source` names it in messages.
///
/// # Errors
///
/// As [`read_results_path`].
pub fn read_results_from<R: Read>(reader: R, source: &str) -> Result<ResultFile, ResultsError> {
    let bytes = crate::input::read_limited(reader).map_err(|e| ResultsError::Io {
        file: source.to_string(),
        source: e,
    })?;
    let err = |line: u64, column: u64, message: String| ResultsError::At {
        location: Location::new(source, line, column),
        message,
    };
    let text = match crate::input::text::utf8(&bytes) {
        Ok(text) => text,
        Err(((line, column), message)) => return Err(err(line, column, message)),
    };
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);

    // Skip the comment (and blank) lines before the header.
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            offset += line.len();
        } else {
            break;
        }
    }
    let body = &text[offset..];
    let line_offset = text[..offset].matches('\n').count() as u64;
    if body.trim().is_empty() {
        return Err(err(
            line_offset + 1,
            1,
            "no header: expected a header line such as quantity,index,value,U,u,k,angle_deg"
                .to_string(),
        ));
    }

    // Position of field `i` of the record starting at byte `start` of `body`.
    let field_position = |start: u64, i: usize| -> (u64, u64) {
        let (line, column) = field_start(body, start as usize, i);
        (line_offset + line, column)
    };
    let csv_error = |e: csv::Error| -> ResultsError {
        let (line, column, message) = match e.kind() {
            csv::ErrorKind::UnequalLengths {
                pos,
                expected_len,
                len,
            } => {
                // Too many fields: point at the first extra one; too few: at the end.
                let field = (*len).min(*expected_len) as usize;
                let (line, column) = pos
                    .as_ref()
                    .map_or((line_offset + 1, 1), |p| field_position(p.byte(), field));
                (
                    line,
                    column,
                    format!("this row has {len} fields, the header {expected_len}"),
                )
            }
            csv::ErrorKind::Utf8 { pos, .. } => {
                let line = pos.as_ref().map_or(0, |p| p.line());
                (line_offset + line, 1, "not valid UTF-8".to_string())
            }
            _ => (line_offset + 1, 1, e.to_string()),
        };
        err(line, column, message)
    };

    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(false)
        .trim(csv::Trim::All)
        .from_reader(body.as_bytes());
    let mut records = reader.records();
    let header = match records.next() {
        None => {
            return Err(err(
                line_offset + 1,
                1,
                "no header: expected a header line such as quantity,index,value,U,u,k,angle_deg"
                    .to_string(),
            ));
        }
        Some(record) => record.map_err(&csv_error)?,
    };
    let header_start = header.position().map_or(0, |p| p.byte());
    let column_of = |name: &str| -> Result<Option<usize>, ResultsError> {
        let mut found = None;
        for (i, h) in header.iter().enumerate() {
            if h == name {
                if found.is_some() {
                    let (line, column) = field_position(header_start, i);
                    return Err(err(
                        line,
                        column,
                        format!("the column {name:?} appears twice"),
                    ));
                }
                found = Some(i);
            }
        }
        Ok(found)
    };
    let required = |name: &str, found: Option<usize>| {
        found.ok_or_else(|| {
            let (line, _) = field_position(header_start, 0);
            let header_line = body.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
            let next = body.lines().filter(|l| !l.trim().is_empty()).nth(1);
            if let Some(message) = kind::separator_problem(header_line, next, &REQUIRED_COLUMNS) {
                return err(line, 1, message);
            }
            if let Some(found) = kind::recognize(text).filter(|&k| k != FileKind::Result) {
                return ResultsError::WrongKind {
                    location: Location::new(source, line, 1),
                    message: kind::other_kind_message(found, FileKind::Result.name(), text),
                    found,
                };
            }
            err(
                line,
                1,
                format!(
                    "the header has no {name:?} column (required: quantity, index, value; \
                     optional: U, u, k, angle_deg; names are case-sensitive)"
                ),
            )
        })
    };
    let c_quantity = required("quantity", column_of("quantity")?)?;
    let c_index = required("index", column_of("index")?)?;
    let c_value = required("value", column_of("value")?)?;
    let c_expanded = column_of("U")?;
    let c_u = column_of("u")?;
    let c_k = column_of("k")?;
    let c_angle = column_of("angle_deg")?;

    let mut rows: Vec<ResultRow> = Vec::new();
    let mut lines: Vec<u64> = Vec::new();
    let mut columns: Vec<RowColumns> = Vec::new();
    // Where each row's record starts in `body` (for the column of an earlier row's field).
    let mut starts: Vec<u64> = Vec::new();
    let mut angles = AngleCheck::default();
    for record in records {
        let record = record.map_err(&csv_error)?;
        let start = record.position().map_or(0, |p| p.byte());
        let at = |i: usize, message: String| {
            let (line, column) = field_position(start, i);
            err(line, column, message)
        };
        let quantity_text = &record[c_quantity];
        let Some(quantity) = Quantity::from_name(quantity_text) else {
            let quantity = quantity_text;
            return Err(at(
                c_quantity,
                format!(
                    "unknown quantity {quantity:?}: expected pitch_deviation, face_deviation, \
                     encoder_error or setup_error"
                ),
            ));
        };
        let index_text = &record[c_index];
        let index: u32 = index_text.parse().map_err(|_| {
            at(
                c_index,
                format!("index must be a whole number ≥ 0, got {index_text:?}"),
            )
        })?;
        if index == 0 && quantity != Quantity::EncoderError {
            let what = if quantity == Quantity::SetupError {
                "autocollimator numbers start at 1"
            } else {
                "faces are numbered 1 … N"
            };
            return Err(at(c_index, format!("index 0 for {quantity}: {what}")));
        }
        let number = |i: usize, name: &str, limit: Limit| -> Result<f64, ResultsError> {
            let text = &record[i];
            match text.parse::<f64>() {
                Ok(v) if v.is_finite() => limit
                    .check(v, &format!("a result's {name}"))
                    .map_err(|rule| at(i, format!("{name}: {rule}"))),
                _ => Err(at(
                    i,
                    format!("{name} must be a finite number, got {text:?}"),
                )),
            }
        };
        let optional = |column: Option<usize>, name: &str, limit: Limit| match column {
            None => Ok(None),
            Some(i) if record[i].is_empty() => Ok(None),
            Some(i) => {
                let v = number(i, name, limit)?;
                if v < 0.0 {
                    Err(at(i, format!("{name} must not be negative, got {v}")))
                } else {
                    Ok(Some(v))
                }
            }
        };
        let value = number(c_value, "value", limits::RESULT_ARCSEC)?;
        let expanded_u = optional(c_expanded, "U", limits::RESULT_ARCSEC)?;
        let u = optional(c_u, "u", limits::RESULT_ARCSEC)?;
        let k = optional(c_k, "k", limits::COVERAGE_FACTOR)?;
        let angle_deg = match c_angle {
            Some(i) if !record[i].is_empty() => {
                let text = &record[i];
                match text.parse::<f64>() {
                    Ok(v) if angle_in_range(v) => Some(v + 0.0), // −0 is 0
                    _ => {
                        return Err(at(
                            i,
                            format!(
                                "angle_deg must be a finite number of degrees, \
                                 0 ≤ angle_deg < 360, got {text:?}"
                            ),
                        ));
                    }
                }
            }
            _ => None,
        };
        let line = field_position(start, 0).0;
        if let Some(first) = rows
            .iter()
            .position(|r| r.quantity == quantity && r.index == index)
        {
            return Err(at(
                c_quantity,
                format!(
                    "{quantity} {index} appears twice (first on line {})",
                    lines[first]
                ),
            ));
        }
        let row = ResultRow {
            quantity,
            index,
            value,
            u,
            expanded_u,
            k,
            angle_deg,
        };
        if let Err(problem) = angles.admit(rows.len(), &row) {
            let current = rows.len();
            let place = |i: usize| format!("line {}", lines.get(i).copied().unwrap_or(line));
            let message = problem.message(&row, &rows, place);
            // At the angle_deg field of the row the problem is reported at (the first row
            // without an angle for a missing one); the column exists whenever an angle does.
            let (reported, column) = match problem {
                AngleProblem::Missing { without, .. } => (without, c_angle),
                _ => (current, c_angle),
            };
            let column = column.unwrap_or(c_quantity);
            let record_start = starts.get(reported).copied().unwrap_or(start);
            let (line, column) = field_position(record_start, column);
            return Err(err(line, column, message));
        }
        let field_column = |i: usize| field_position(start, i).1;
        columns.push(RowColumns {
            quantity: field_column(c_quantity),
            index: field_column(c_index),
            value: field_column(c_value),
            expanded_u: c_expanded.map(field_column),
            u: c_u.map(field_column),
            k: c_k.map(field_column),
        });
        rows.push(row);
        lines.push(line);
        starts.push(start);
    }
    Ok(ResultFile {
        source: source.to_string(),
        rows,
        lines,
        columns,
    })
}

/// Whether rows can be written as a result file and read back ([`write_results`]'s
/// checks, without writing): every number finite and within its limits
/// (docs/FORMAT.md §2.2), the angle rules of [`read_results_from`]. A command checks the
/// rows of a file before it writes any, so that a refusal names that file and no output
/// is cut short.
///
/// # Errors
///
/// [`RowsError`]: the first problem, at the quantity and index or the row.
pub fn check_rows(rows: &[ResultRow]) -> Result<(), RowsError> {
    let mut angles = AngleCheck::default();
    for (i, row) in rows.iter().enumerate() {
        let numbers = [
            ("value", Some(row.value), limits::RESULT_ARCSEC),
            ("U", row.expanded_u, limits::RESULT_ARCSEC),
            ("u", row.u, limits::RESULT_ARCSEC),
            ("k", row.k, limits::COVERAGE_FACTOR),
        ];
        for (name, x, limit) in numbers {
            if let Some(x) = x
                && let Err(rule) = limit.check(x, &format!("a result's {name}"))
            {
                return Err(RowsError::Number {
                    quantity: row.quantity,
                    index: row.index,
                    column: name,
                    rule,
                });
            }
        }
        if let Err(problem) = angles.admit(i, row) {
            let place = |i: usize| format!("row {}", i + 1);
            return Err(RowsError::Angle {
                row: i + 1,
                message: problem.message(row, &rows[..i], place),
            });
        }
    }
    Ok(())
}

/// Why rows cannot be written as a result file ([`check_rows`]), at the quantity and
/// index, or the row, where the problem is.
///
/// ```
/// use polycal::results::{check_rows, Quantity, ResultRow, RowsError};
///
/// let row = ResultRow {
///     quantity: Quantity::PitchDeviation, index: 3, value: 1e300,
///     u: None, expanded_u: None, k: None, angle_deg: None,
/// };
/// let refused = check_rows(&[row]).unwrap_err();
/// assert!(matches!(refused, RowsError::Number { index: 3, column: "value", .. }));
/// assert!(refused.to_string().starts_with("pitch_deviation 3: value: 1e300 is beyond"));
/// ```
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RowsError {
    /// A number beyond the limits of its kind (docs/FORMAT.md §2.2).
    #[error("{quantity} {index}: {column}: {rule}")]
    Number {
        /// The quantity of the row.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// The column: `value`, `U`, `u` or `k`.
        column: &'static str,
        /// The rule the number breaks.
        rule: limits::LimitError,
    },
    /// A row that breaks the rules of `angle_deg` (those of [`read_results_from`]).
    #[error("row {row}: {message}")]
    Angle {
        /// The row, 1-based.
        row: usize,
        /// What is wrong, naming the rows involved.
        message: String,
    },
}

/// Writes rows as a result file: header `quantity,index,value,U,u,k,angle_deg`, numbers in
/// Rust's shortest round-trip representation (`{}`), `None` as an empty field (so
/// `angle_deg` is empty on every row but the encoder errors that carry their angle).
///
/// # Errors
///
/// An I/O error, or [`std::io::ErrorKind::InvalidInput`] for what could not be read back:
/// a number that is not finite or beyond its limits (docs/FORMAT.md §2.2), or rows that
/// break the angle rules of
/// [`read_results_from`] (an angle outside 0 ≤ angle < 360 or on a row that is not an
/// encoder error, some encoder errors with an angle and some without, two at one
/// position). The quantity is one of [`Quantity`] by its type.
pub fn write_results<W: Write>(w: W, rows: &[ResultRow]) -> std::io::Result<()> {
    check_rows(rows)
        .map_err(|message| std::io::Error::new(std::io::ErrorKind::InvalidInput, message))?;
    let mut writer = csv::Writer::from_writer(w);
    let to_io = |e: csv::Error| match e.into_kind() {
        csv::ErrorKind::Io(e) => e,
        other => std::io::Error::other(format!("{other:?}")),
    };
    writer
        .write_record(["quantity", "index", "value", "U", "u", "k", "angle_deg"])
        .map_err(to_io)?;
    let text = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x}"));
    for row in rows {
        writer
            .write_record([
                row.quantity.name().to_string(),
                row.index.to_string(),
                text(Some(row.value)),
                text(row.expanded_u),
                text(row.u),
                text(row.k),
                text(row.angle_deg),
            ])
            .map_err(to_io)?;
    }
    writer.flush()
}

/// 1-based line and column (characters) of the end of `text`.
fn line_column(text: &str, offset: usize) -> (u64, u64) {
    let before = &text[..offset];
    let line = before.matches('\n').count() as u64 + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() as u64 + 1)
}

/// Line (1-based, within `body`) and column (1-based, characters) where field `field` of
/// the CSV record starting at byte `start` begins; the end of the record if it has fewer
/// fields. Quoted fields (with commas, doubled quotes or newlines) are stepped over.
fn field_start(body: &str, start: usize, field: usize) -> (u64, u64) {
    let mut start = start.min(body.len());
    // After a CR LF line end the reported record start may be the LF: step over it.
    while matches!(body.as_bytes().get(start), Some(b'\r' | b'\n')) {
        start += 1;
    }
    let (mut line, mut column) = line_column(body, start);
    let mut current = 0;
    let mut in_quotes = false;
    let mut chars = body[start..].chars().peekable();
    while current < field {
        let Some(ch) = chars.next() else { break };
        match ch {
            '"' if in_quotes && chars.peek() == Some(&'"') => {
                chars.next();
                column += 1;
            }
            '"' => in_quotes = !in_quotes,
            ',' if !in_quotes => current += 1,
            '\n' if !in_quotes => break,
            '\n' => {
                line += 1;
                column = 0;
            }
            _ => {}
        }
        column += 1;
    }
    // Step over the padding that Trim::All removed.
    if current == field {
        while let Some(' ' | '\t') = chars.peek() {
            chars.next();
            column += 1;
        }
    }
    (line, column)
}
