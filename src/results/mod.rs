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
//! `angle_deg` (the table angle of an encoder error, degrees), `dof` (the degrees of
//! freedom of u) and `nominal_deg` (an angle block's nominal angle, degrees, on
//! `angle_block` rows) are optional, an empty field
//! meaning "not given" (`compare` needs `U`). Column names are case-sensitive (`U` and `u`
//! differ). Columns this version does not know are ignored (docs/FORMAT.md allows adding
//! columns). Lines starting with `#` before the header are comments.
//!
//! Reading is strict: an unknown quantity, an index out of range, a number that is not
//! finite, a negative uncertainty, a duplicate `(quantity, index)` is refused with
//! `file:line:column` and nothing is guessed. So is an `angle_deg` outside 0 ≤ angle < 360,
//! one on a row that is not an encoder error, two encoder errors at the same angle (within
//! [`ANGLE_TOLERANCE_DEG`], around the circle), and a file where some encoder errors carry
//! an angle and others do not, and a `nominal_deg` outside 0 < angle < 360 or on a row
//! that is not an angle block.
//!
//! The file is read by the crate's one table reader (`input::table`) like the
//! measurement and self-calibration files, with the same rules and messages, in one pass
//! (`read`); its fields are trimmed and unknown columns passed over whatever their names
//! (other programs write result files). The angle rules live in `angle`, shared by the
//! reader, the writer's checks and `compare`.

use std::io::{Read, Write};
use std::path::Path;

use crate::input::FileError;
use crate::input::limits;
use serde::{Deserialize, Serialize};

mod angle;
pub mod certificate;
mod read;

pub(crate) use angle::{AngleCheck, AngleProblem};

/// The families of calibrated quantities (docs/FORMAT.md §3), the crate's one list
/// of them: result files, reports, uncertainties and truths name them through this type.
///
/// ```
/// use polycal::results::Quantity;
/// assert_eq!(Quantity::EncoderError.name(), "encoder_error");
/// assert_eq!(Quantity::from_name("pitch_deviation"), Some(Quantity::PitchDeviation));
/// assert_eq!(Quantity::ALL.len(), 5);
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
    /// The deviation of angle block b = 1, 2, … from its nominal angle: a single angle, not
    /// part of a closed vector (a key comparison's blocks, docs/FORMAT.md §3 and §12).
    AngleBlock,
}

impl Quantity {
    /// The five families in the order results are written.
    pub const ALL: [Quantity; 5] = [
        Quantity::PitchDeviation,
        Quantity::FaceDeviation,
        Quantity::EncoderError,
        Quantity::SetupError,
        Quantity::AngleBlock,
    ];

    /// The name as spelled in files and JSON, e.g. `pitch_deviation`.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::PitchDeviation => "pitch_deviation",
            Quantity::FaceDeviation => "face_deviation",
            Quantity::EncoderError => "encoder_error",
            Quantity::SetupError => "setup_error",
            Quantity::AngleBlock => "angle_block",
        }
    }

    /// The family of a name as spelled in files, or `None`.
    pub fn from_name(name: &str) -> Option<Quantity> {
        Quantity::ALL.into_iter().find(|q| q.name() == name)
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
    /// The family: `pitch_deviation`, `face_deviation`, `encoder_error`, `setup_error` or
    /// `angle_block`.
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
    /// The degrees of freedom ν of `u` (column `dof`), when the laboratory states them;
    /// `None` for infinitely many (a key comparison's Welch–Satterthwaite ν uses them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dof: Option<f64>,
    /// For `angle_block` rows: the block's nominal angle, degrees, 0 < angle < 360 (column
    /// `nominal_deg`); `None` on every other row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal_deg: Option<f64>,
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
            dof: None,
            nominal_deg: None,
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

    /// With the degrees of freedom ν of its standard uncertainty (ν > 0).
    pub fn with_dof(mut self, dof: f64) -> ResultRow {
        self.dof = Some(dof);
        self
    }

    /// With the nominal angle of an angle block, degrees (checked when the row is written or
    /// read: 0 < angle < 360, `angle_block` rows only).
    pub fn with_nominal_deg(mut self, nominal_deg: f64) -> ResultRow {
        self.nominal_deg = Some(nominal_deg);
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
    /// The `nominal_deg` field.
    pub nominal_deg: Option<u64>,
}

/// Reads a result file strictly; `-` reads standard input. See [`read_result_file`] for
/// the rows' line numbers.
///
/// # Errors
///
/// [`FileError::Invalid`] with file, line and column for anything invalid;
/// [`FileError::Io`] if the file cannot be read.
pub fn read_results_path(path: impl AsRef<Path>) -> Result<Vec<ResultRow>, FileError> {
    read_result_file(path).map(|f| f.rows)
}

/// Reads a result file strictly, keeping each row's line number; `-` reads standard
/// input.
///
/// # Errors
///
/// As [`read_results_path`].
pub fn read_result_file(path: impl AsRef<Path>) -> Result<ResultFile, FileError> {
    let path = path.as_ref();
    let (bytes, name) =
        crate::input::read_bytes(path).map_err(|(file, source)| FileError::Io { file, source })?;
    read_results_from(&bytes[..], &name)
}

/// Reads a result file from any reader; `source` names it in messages.
///
/// The whole input is read, then read through the crate's one table reader in one pass
/// (docs/FORMAT.md §3.2); the first problem found is returned as one
/// [`FileError::Invalid`]. A Digital Calibration Certificate (XML, told by its content)
/// is read too: its results as rows ([`certificate::read_certificate`], docs/FORMAT.md
/// §13.3).
///
/// # Errors
///
/// As [`read_results_path`].
pub fn read_results_from<R: Read>(reader: R, source: &str) -> Result<ResultFile, FileError> {
    let bytes = crate::input::read_limited(reader).map_err(|e| FileError::Io {
        file: source.to_string(),
        source: e,
    })?;
    if certificate::looks_like_xml(&bytes) {
        return certificate::read_certificate(&bytes, source).map(|c| c.results);
    }
    read::parse_bytes(&bytes, source)
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
        if let Some(nominal_deg) = row.nominal_deg
            && (row.quantity != Quantity::AngleBlock || !(nominal_deg > 0.0 && nominal_deg < 360.0))
        {
            return Err(RowsError::Nominal {
                quantity: row.quantity,
                index: row.index,
                nominal_deg,
            });
        }
        if let Some(dof) = row.dof
            && !(dof > 0.0 && dof.is_finite())
        {
            return Err(RowsError::Dof {
                quantity: row.quantity,
                index: row.index,
                dof,
            });
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
///     u: None, expanded_u: None, k: None, angle_deg: None, dof: None, nominal_deg: None,
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
    /// A nominal angle that is not an angle block's (0 < angle < 360 degrees, on an
    /// `angle_block` row).
    #[error(
        "{quantity} {index}: nominal_deg: {nominal_deg} is not an angle block's nominal angle \
         (0 < nominal_deg < 360 degrees, on angle_block rows only)"
    )]
    Nominal {
        /// The quantity of the row.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// The nominal angle given, degrees.
        nominal_deg: f64,
    },
    /// Degrees of freedom that are not a positive, finite number.
    #[error("{quantity} {index}: dof: {dof} is not a positive number of degrees of freedom")]
    Dof {
        /// The quantity of the row.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// The degrees of freedom given.
        dof: f64,
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

/// Writes rows as a result file: header `quantity,index,value,U,u,k,angle_deg` (then `dof`
/// when a row states its degrees of freedom, `nominal_deg` when an angle block states its
/// nominal angle), numbers in Rust's shortest round-trip representation (`{}`), `None` as an
/// empty field (so `angle_deg` is empty on every row but the encoder errors that carry
/// their angle).
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
    let with_dof = rows.iter().any(|r| r.dof.is_some());
    let with_nominal = rows.iter().any(|r| r.nominal_deg.is_some());
    let mut header = vec!["quantity", "index", "value", "U", "u", "k", "angle_deg"];
    header.extend(with_dof.then_some("dof"));
    header.extend(with_nominal.then_some("nominal_deg"));
    writer.write_record(&header).map_err(to_io)?;
    let text = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x}"));
    for row in rows {
        let mut record = vec![
            row.quantity.name().to_string(),
            row.index.to_string(),
            text(Some(row.value)),
            text(row.expanded_u),
            text(row.u),
            text(row.k),
            text(row.angle_deg),
        ];
        record.extend(with_dof.then(|| text(row.dof)));
        record.extend(with_nominal.then(|| text(row.nominal_deg)));
        writer.write_record(&record).map_err(to_io)?;
    }
    writer.flush()
}
