//! What a refused file is, so that a refusal says what to do (docs/FORMAT.md §8): a file
//! of another kind given where one kind is expected (a budget given as the measurement
//! file, a measurement file given as a budget or as a result file), and a table written
//! with semicolons or tabs between its fields, or with decimal commas.
//!
//! The kinds are told apart by the first line that is not a comment or blank: a CSV
//! header naming every required column of one kind ([`FileKind::required_columns`]; the
//! measurement, self-calibration and result files' descriptions require exactly those), a TOML key or table (a budget), or a `{` (a JSON
//! document).

/// A kind of file polycal reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FileKind {
    /// A measurement file (CSV, docs/FORMAT.md §2).
    Measurement,
    /// A self-calibration file (CSV, docs/FORMAT.md §9.2).
    SelfCalibration,
    /// A result file (CSV, docs/FORMAT.md §3).
    Result,
    /// A budget or an instrument budget (TOML, docs/FORMAT.md §5.3).
    Budget,
    /// A JSON document (a solve result, a truth file).
    Json,
    /// XML: a Digital Calibration Certificate (docs/FORMAT.md §10.3), read wherever a
    /// result file is (§13.3).
    Certificate,
}

impl FileKind {
    /// The columns a table of this kind must name, by which its header is recognised
    /// (none for a kind that is not a table). Each file kind's own description of its
    /// columns requires exactly these (its unit test checks it).
    pub fn required_columns(self) -> &'static [&'static str] {
        match self {
            FileKind::Measurement => &["cycle", "step", "ac", "face", "reading"],
            FileKind::SelfCalibration => &["cycle", "step", "head", "head_angle", "reading"],
            FileKind::Result => &["quantity", "index", "value"],
            FileKind::Budget | FileKind::Json | FileKind::Certificate => &[],
        }
    }

    /// The kind's short name: `a measurement file`, `a budget`, ….
    pub fn name(self) -> &'static str {
        match self {
            FileKind::Measurement => "a measurement file",
            FileKind::SelfCalibration => "a self-calibration file",
            FileKind::Result => "a result file",
            FileKind::Budget => "a budget",
            FileKind::Json => "a JSON document",
            FileKind::Certificate => "a Digital Calibration Certificate",
        }
    }

    /// The kind in words, with its form and its section of docs/FORMAT.md, e.g. `a budget
    /// (TOML, docs/FORMAT.md §5.3)`.
    pub fn describe(self) -> &'static str {
        match self {
            FileKind::Measurement => {
                "a measurement file (CSV with the columns cycle, step, ac, face, reading; \
                 docs/FORMAT.md §2)"
            }
            FileKind::SelfCalibration => {
                "a self-calibration file (CSV with the columns cycle, step, head, \
                 head_angle, reading; docs/FORMAT.md §9.2)"
            }
            FileKind::Result => {
                "a result file (CSV with the columns quantity, index, value; \
                 docs/FORMAT.md §3)"
            }
            FileKind::Budget => "a budget (TOML, docs/FORMAT.md §5.3)",
            FileKind::Json => "a JSON document",
            FileKind::Certificate => {
                "a Digital Calibration Certificate (XML, docs/FORMAT.md §10.3; read where a \
                 result file is, §13.3)"
            }
        }
    }
}

/// The kind of a CSV whose header names `names`, when they include every required column
/// of one kind.
pub(crate) fn csv_kind(names: &[&str]) -> Option<FileKind> {
    let has_all = |kind: FileKind| kind.required_columns().iter().all(|n| names.contains(n));
    [
        FileKind::Measurement,
        FileKind::SelfCalibration,
        FileKind::Result,
    ]
    .into_iter()
    .find(|&kind| has_all(kind))
}

/// The first line of `text` that is not blank nor a `#` comment, with its 0-based index.
fn first_line(text: &str) -> Option<(usize, &str)> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    text.lines()
        .enumerate()
        .find(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
}

/// What `text` is, judged by its first line that is not blank nor a comment; `None` when
/// it is none of the kinds polycal reads.
///
/// ```
/// use polycal::input::kind::{FileKind, recognize};
/// assert_eq!(recognize("# run 7\ncycle,step,ac,face,reading\n1,0,1,1,0.5\n"), Some(FileKind::Measurement));
/// assert_eq!(recognize("p = 0.95\n[[component]]\n"), Some(FileKind::Budget));
/// assert_eq!(recognize("quantity,index,value,U\n"), Some(FileKind::Result));
/// assert_eq!(recognize("<?xml version=\"1.0\"?>\n<dcc:digitalCalibrationCertificate/>"), Some(FileKind::Certificate));
/// assert_eq!(recognize("a,b\n1,2\n"), None);
/// ```
pub fn recognize(text: &str) -> Option<FileKind> {
    let (_, line) = first_line(text)?;
    let line = line.trim();
    if line.starts_with('{') {
        return Some(FileKind::Json);
    }
    if line.starts_with('<') {
        return Some(FileKind::Certificate);
    }
    if line.starts_with('[') || is_toml_key(line) {
        return Some(FileKind::Budget);
    }
    let names: Vec<&str> = line.split(',').map(str::trim).collect();
    csv_kind(&names)
}

/// Whether a line is a TOML `key = value` (a bare or quoted key before `=`).
fn is_toml_key(line: &str) -> bool {
    let Some((key, _)) = line.split_once('=') else {
        return false;
    };
    let key = key.trim();
    !key.is_empty()
        && (key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c))
            || (key.starts_with('"') && key.ends_with('"') && key.len() >= 2))
}

/// The line of text shown in a message: at most 40 characters, quoted.
fn quoted(line: &str) -> String {
    let line = line.trim();
    let mut shown: String = line.chars().take(40).collect();
    if line.chars().count() > 40 {
        shown.push('…');
    }
    format!("{shown:?}")
}

/// The refusal of a file of kind `found` given where `expected` (a kind's name, or a
/// description when the expected kind has none) is wanted: what it is, and the line that
/// tells (the refusal's line: the first that is not blank nor a comment).
pub(crate) fn other_kind_message(found: FileKind, expected: &str, text: &str) -> String {
    let first = first_line(text).map_or_else(String::new, |(_, l)| format!(" {}:", quoted(l)));
    format!("{first} this is {}, not {expected}", found.describe())
        .trim_start()
        .to_string()
}

/// The 1-based line of `text` that tells its kind ([`recognize`]); 1 when there is none.
pub(crate) fn telling_line(text: &str) -> u64 {
    first_line(text).map_or(1, |(i, _)| {
        u64::try_from(i).unwrap_or(u64::MAX).saturating_add(1)
    })
}

/// A table written with another separator than the comma, or with decimal commas: the
/// message saying so and what to do, given the header's line and the line after it;
/// `None` when the header, split at `;` or a tab, names neither every one of `required`
/// nor the required columns of another kind (a measurement file in semicolons given
/// where a result file is expected is named for its semicolons first).
pub(crate) fn separator_problem(
    header: &str,
    next: Option<&str>,
    required: &[&str],
) -> Option<String> {
    let (separator, name) = [(';', "semicolons (`;`)"), ('\t', "tabs")]
        .into_iter()
        .find(|(sep, _)| {
            let names: Vec<&str> = header.split(*sep).map(str::trim).collect();
            names.len() > 1
                && (required.iter().all(|r| names.contains(r)) || csv_kind(&names).is_some())
        })?;
    let mut message = format!(
        "the fields are separated by {name}, not commas: polycal reads comma-separated \
         files with a point as the decimal mark; write the file with `,` between fields"
    );
    if let Some(decimal) = next.and_then(|line| decimal_comma(line, separator)) {
        message.push_str(&format!(
            " and `.` in numbers (the next line has decimal commas: {})",
            quoted(decimal)
        ));
    }
    message.push_str(
        " (a spreadsheet: export as CSV with the field separator `,` and the decimal mark `.`)",
    );
    Some(message)
}

/// The first field of `line` (split at `separator`) written with a decimal comma
/// (`1,25`, `-0,5`).
fn decimal_comma(line: &str, separator: char) -> Option<&str> {
    line.split(separator)
        .map(str::trim)
        .find(|field| is_decimal_comma(field))
}

/// Whether a field is a number with a decimal comma: digits, one comma, digits.
pub(crate) fn is_decimal_comma(field: &str) -> bool {
    let field = field.strip_prefix(['-', '+']).unwrap_or(field);
    let Some((whole, fraction)) = field.split_once(',') else {
        return false;
    };
    !whole.is_empty()
        && !fraction.is_empty()
        && whole.bytes().all(|b| b.is_ascii_digit())
        && fraction.bytes().all(|b| b.is_ascii_digit())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MEASUREMENT: [&str; 5] = ["cycle", "step", "ac", "face", "reading"];

    #[test]
    fn kinds_are_told_by_their_first_line() {
        assert_eq!(
            recognize("\u{feff}\n# c\ncycle,step,ac,face,reading,direction\n"),
            Some(FileKind::Measurement)
        );
        assert_eq!(
            recognize("cycle,step,head,head_angle,reading\n"),
            Some(FileKind::SelfCalibration)
        );
        assert_eq!(
            recognize("quantity,index,value,U,u,k,angle_deg\n"),
            Some(FileKind::Result)
        );
        assert_eq!(recognize("# budget\np = 0.95\n"), Some(FileKind::Budget));
        assert_eq!(recognize("[[component]]\n"), Some(FileKind::Budget));
        assert_eq!(recognize("\"dof policy\" = 1\n"), Some(FileKind::Budget));
        assert_eq!(recognize("  {\"faces\": 3}"), Some(FileKind::Json));
        assert_eq!(recognize("cycle,step,ac,face\n"), None);
        assert_eq!(recognize("cycle;step;ac;face;reading\n"), None);
        assert_eq!(recognize(""), None);
    }

    #[test]
    fn separators_and_decimal_commas_are_named() {
        let semi = separator_problem(
            "cycle;step;ac;face;reading",
            Some("1;0;1;1;1,25"),
            &MEASUREMENT,
        )
        .unwrap();
        assert!(semi.contains("semicolons"), "{semi}");
        assert!(semi.contains("decimal commas: \"1,25\""), "{semi}");
        let tab = separator_problem(
            "cycle\tstep\tac\tface\treading",
            Some("1\t0\t1\t1\t0.5"),
            &MEASUREMENT,
        )
        .unwrap();
        assert!(tab.contains("tabs"), "{tab}");
        assert!(!tab.contains("decimal commas"), "{tab}");
        assert_eq!(separator_problem("cycle;step;ac", None, &MEASUREMENT), None);
        // another kind's header in semicolons: the separator is named first
        let result = ["quantity", "index", "value"];
        assert!(separator_problem("cycle;step;ac;face;reading", None, &result).is_some());
        assert_eq!(
            separator_problem("cycle,step,ac,face,reading", None, &MEASUREMENT),
            None
        );
    }

    #[test]
    fn decimal_commas() {
        for yes in ["1,25", "-0,5", "+12,0"] {
            assert!(is_decimal_comma(yes), "{yes}");
        }
        for no in ["1.25", "1,", ",5", "1,2,3", "a,b", "", "-"] {
            assert!(!is_decimal_comma(no), "{no}");
        }
    }
}
