//! What a calibration report says about the calibration besides the numbers: the
//! customer, the artefact, the operator, the instruments, the environment, the run. Three
//! sources, each named where its values are shown: a metadata TOML file, the `# key:
//! value` comment lines of the measurement file, and a run directory's `manifest.json`
//! (docs/FORMAT.md §7.3, §10). Nothing is invented: a field no source gives is shown as
//! missing.

use std::path::Path;

use serde::Deserialize;

use super::record::refused_character;
pub use super::record::{InstrumentEntry, RunRecord, control_character};
use toml::Spanned;

use crate::input::Location;
use crate::uncertainty::budget_file::location;

use super::ReportError;

/// The metadata keys, in the order a report shows them, with their labels.
pub const KEYS: [(&str, &str); 32] = [
    ("title", "Title"),
    ("certificate", "Certificate number"),
    ("customer", "Customer"),
    ("customer_address", "Customer address"),
    ("customer_email", "Customer e-mail"),
    ("customer_country", "Country of the customer (ISO 3166-1)"),
    ("artefact", "Artefact (polygon)"),
    ("artefact_manufacturer", "Artefact manufacturer"),
    ("artefact_serial", "Artefact serial number"),
    ("encoder", "Rotary table / encoder"),
    ("encoder_manufacturer", "Encoder manufacturer"),
    ("encoder_serial", "Encoder serial number"),
    ("item_condition", "Condition of the item"),
    ("laboratory", "Laboratory"),
    ("laboratory_address", "Laboratory address"),
    ("laboratory_email", "Laboratory e-mail"),
    ("country", "Country of the laboratory (ISO 3166-1)"),
    ("accreditation_body", "Accreditation body"),
    (
        "accreditation_code",
        "Accreditation number / laboratory code",
    ),
    ("location", "Place of calibration"),
    ("performance_location", "Calibrated at"),
    ("date_of_receipt", "Date of receipt of the item"),
    ("date_of_measurement", "Date of measurement"),
    ("date_of_issue", "Date of issue"),
    ("operator", "Operator"),
    ("approved_by", "Approved by"),
    ("traceability", "Traceability"),
    ("temperature_c", "Air temperature / °C"),
    ("humidity_percent", "Relative humidity / %"),
    ("pressure_hpa", "Air pressure / hPa"),
    ("environment", "Environment"),
    ("notes", "Notes"),
];

/// The places a calibration is performed at, as the DCC names them
/// (`performanceLocation`; docs/FORMAT.md §10): the metadata key `performance_location`
/// takes one of these.
pub const PERFORMANCE_LOCATIONS: [&str; 5] = [
    "laboratory",
    "customer",
    "laboratoryBranch",
    "customerBranch",
    "other",
];

/// Whether `code` is an ISO 3166-1 alpha-2 country code in form: two capital letters
/// (the DCC's `countryCodeISO3166_1`).
pub fn is_country_code(code: &str) -> bool {
    code.len() == 2 && code.bytes().all(|b| b.is_ascii_uppercase())
}

/// The metadata keys whose value must be a day `YYYY-MM-DD` wherever it is given (the
/// metadata file or a comment line), checked when read.
pub const DATE_KEYS: [&str; 2] = ["date_of_receipt", "date_of_issue"];

/// Why the value of a date key is refused.
fn not_a_day(key: &str, value: &str) -> String {
    format!("{key} “{value}” is not a date YYYY-MM-DD (a real day, e.g. 2026-11-03)")
}

/// One metadata field: its value and where it came from, or missing.
#[derive(Debug, Clone, PartialEq)]
pub struct MetaField {
    /// The key (one of [`KEYS`]).
    pub key: &'static str,
    /// The label shown.
    pub label: &'static str,
    /// The value, `None` when no source gives it.
    pub value: Option<String>,
    /// Where the value came from (a file name and line, or the manifest).
    pub source: Option<String>,
    /// Where the value stands: file, line and column of the metadata file's value or of
    /// the comment's; the manifest's file alone. For refusals of its form (the DCC's date).
    pub location: Option<Location>,
}

/// The metadata of a report.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Metadata {
    /// Every key of [`KEYS`], in that order.
    pub fields: Vec<MetaField>,
    /// The instruments, from the metadata file and the manifest.
    pub instruments: Vec<InstrumentEntry>,
    /// The measurement file's comment lines that are not `key: value` of a known key.
    pub file_notes: Vec<String>,
    /// Where two sources give one key different values: which one is shown, and why.
    pub conflicts: Vec<String>,
    /// The run, with a run directory.
    pub run: Option<RunRecord>,
}

impl Metadata {
    /// The accreditation in words, as both documents state it: the body, and the
    /// laboratory's accreditation number when given; `None` without a body.
    pub fn accreditation(&self) -> Option<String> {
        let body = self.value("accreditation_body")?;
        Some(match self.value("accreditation_code") {
            Some(code) => format!("Accredited by {body}, accreditation number {code}."),
            None => format!("Accredited by {body}."),
        })
    }

    /// Names every source by the file name the documents show: each `(given, shown)`
    /// pair's given path replaced in the fields' and instruments' sources, the run's and
    /// the conflicts (their [`MetaField::location`]s, for messages, keep the path).
    pub fn name_files(&mut self, names: &[(String, String)]) {
        // the longest first: a path that begins another is replaced after it
        let mut names: Vec<&(String, String)> = names.iter().collect();
        names.sort_by_key(|(given, _)| std::cmp::Reverse(given.len()));
        let rename = |text: &mut String| {
            for (given, shown) in &names {
                if !given.is_empty() && given != shown && text.contains(given.as_str()) {
                    *text = text.replace(given.as_str(), shown.as_str());
                }
            }
        };
        for field in &mut self.fields {
            if let Some(source) = &mut field.source {
                rename(source);
            }
        }
        for instrument in &mut self.instruments {
            rename(&mut instrument.source);
        }
        for conflict in &mut self.conflicts {
            rename(conflict);
        }
        if let Some(run) = &mut self.run {
            rename(&mut run.source);
        }
    }

    /// Gives the date of issue, when no source gives one, the day the report is written:
    /// the first ten characters (`YYYY-MM-DD`) of its RFC 3339 UTC time.
    pub fn default_date_of_issue(&mut self, generated_utc: &str) {
        let Some(day) = generated_utc.get(..10) else {
            return;
        };
        if let Some(field) = self
            .fields
            .iter_mut()
            .find(|f| f.key == "date_of_issue" && f.value.is_none())
        {
            field.value = Some(day.to_string());
            field.source = Some("the day the report was written (UTC)".to_string());
        }
    }

    /// The value of `key`, if a source gives it.
    pub fn value(&self, key: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|f| f.key == key)
            .and_then(|f| f.value.as_deref())
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MetaFile {
    title: Option<Spanned<String>>,
    certificate: Option<Spanned<String>>,
    customer: Option<Spanned<String>>,
    customer_address: Option<Spanned<String>>,
    customer_email: Option<Spanned<String>>,
    customer_country: Option<Spanned<String>>,
    artefact: Option<Spanned<String>>,
    artefact_manufacturer: Option<Spanned<String>>,
    artefact_serial: Option<Spanned<String>>,
    encoder: Option<Spanned<String>>,
    encoder_manufacturer: Option<Spanned<String>>,
    encoder_serial: Option<Spanned<String>>,
    item_condition: Option<Spanned<String>>,
    laboratory: Option<Spanned<String>>,
    laboratory_address: Option<Spanned<String>>,
    laboratory_email: Option<Spanned<String>>,
    country: Option<Spanned<String>>,
    accreditation_body: Option<Spanned<String>>,
    accreditation_code: Option<Spanned<String>>,
    location: Option<Spanned<String>>,
    performance_location: Option<Spanned<String>>,
    date_of_receipt: Option<Spanned<String>>,
    date_of_measurement: Option<Spanned<String>>,
    date_of_issue: Option<Spanned<String>>,
    operator: Option<Spanned<String>>,
    approved_by: Option<Spanned<String>>,
    traceability: Option<Spanned<String>>,
    temperature_c: Option<Spanned<f64>>,
    humidity_percent: Option<Spanned<f64>>,
    pressure_hpa: Option<Spanned<f64>>,
    environment: Option<Spanned<String>>,
    notes: Option<Spanned<String>>,
    #[serde(default)]
    instrument: Vec<InstrumentToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InstrumentToml {
    role: Option<Spanned<String>>,
    name: Option<Spanned<String>>,
    model: Option<Spanned<String>>,
    serial: Option<Spanned<String>>,
    calibration: Option<Spanned<String>>,
}

/// Values by key.
type MetaValues = Vec<(&'static str, String, Location)>;

/// The values of a metadata TOML file (docs/FORMAT.md §10) by key, and its instruments.
fn read_meta_file(
    text: &str,
    source: &str,
) -> Result<(MetaValues, Vec<InstrumentEntry>), ReportError> {
    let at = |offset: usize, message: String| ReportError::Meta {
        location: location(source, text, offset),
        message,
    };
    let file: MetaFile = toml::from_str(text).map_err(|e| {
        let offset = e.span().map_or(0, |s| s.start);
        at(offset, e.message().trim().to_string())
    })?;
    let number = |value: Option<Spanned<f64>>, low: f64, high: f64| {
        value
            .map(|v| {
                let (span, v) = (v.span(), *v.get_ref());
                if v.is_finite() && (low..=high).contains(&v) {
                    Ok((format!("{v}"), span.start))
                } else {
                    Err(at(
                        span.start,
                        format!("{v} is not a plausible value ({low} … {high})"),
                    ))
                }
            })
            .transpose()
    };
    let temperature = number(file.temperature_c, -50.0, 100.0)?;
    let humidity = number(file.humidity_percent, 0.0, 100.0)?;
    let pressure = number(file.pressure_hpa, 500.0, 1200.0)?;
    // text as the documents will carry it: no control characters (XML 1.0 and HTML have
    // none), a country code and a place of calibration of the DCC's forms
    let checked = |value: Option<Spanned<String>>| {
        value
            .map(|v| {
                let (span, v) = (v.span(), v.into_inner());
                match control_character(&v) {
                    Some((_, c)) => Err(at(span.start, refused_character(c))),
                    None => Ok((span, v)),
                }
            })
            .transpose()
    };
    let plain = |value: Option<Spanned<String>>| checked(value).map(|v| v.map(|(_, v)| v));
    let placed =
        |value: Option<Spanned<String>>| checked(value).map(|v| v.map(|(span, v)| (v, span.start)));
    let country_code = |key: &str, value: Option<Spanned<String>>| match checked(value)? {
        Some((span, v)) if !is_country_code(&v) => Err(at(
            span.start,
            format!("{key} “{v}” is not an ISO 3166-1 alpha-2 code (two capital letters, e.g. DE)"),
        )),
        other => Ok(other.map(|(span, v)| (v, span.start))),
    };
    let country = country_code("country", file.country)?;
    let customer_country = country_code("customer_country", file.customer_country)?;
    let performance_location = match checked(file.performance_location)? {
        Some((span, v)) if !PERFORMANCE_LOCATIONS.contains(&v.as_str()) => {
            return Err(at(
                span.start,
                format!(
                    "performance_location “{v}” is not one of {}",
                    PERFORMANCE_LOCATIONS.join(", ")
                ),
            ));
        }
        other => other.map(|(span, v)| (v, span.start)),
    };
    // the dates ISO/IEC 17025 7.8.2.1 asks for, days YYYY-MM-DD (the DCC's xs:date)
    let day = |key: &str, value: Option<Spanned<String>>| match checked(value)? {
        Some((span, v)) if !crate::clock::is_date(v.trim()) => {
            Err(at(span.start, not_a_day(key, &v)))
        }
        other => Ok(other.map(|(span, v)| (v.trim().to_string(), span.start))),
    };
    let date_of_receipt = day("date_of_receipt", file.date_of_receipt)?;
    let date_of_issue = day("date_of_issue", file.date_of_issue)?;
    let values: [(&'static str, Option<(String, usize)>); 32] = [
        ("title", placed(file.title)?),
        ("certificate", placed(file.certificate)?),
        ("customer", placed(file.customer)?),
        ("customer_address", placed(file.customer_address)?),
        ("customer_email", placed(file.customer_email)?),
        ("customer_country", customer_country),
        ("artefact", placed(file.artefact)?),
        ("artefact_manufacturer", placed(file.artefact_manufacturer)?),
        ("artefact_serial", placed(file.artefact_serial)?),
        ("encoder", placed(file.encoder)?),
        ("encoder_manufacturer", placed(file.encoder_manufacturer)?),
        ("encoder_serial", placed(file.encoder_serial)?),
        ("item_condition", placed(file.item_condition)?),
        ("laboratory", placed(file.laboratory)?),
        ("laboratory_address", placed(file.laboratory_address)?),
        ("laboratory_email", placed(file.laboratory_email)?),
        ("country", country),
        ("accreditation_body", placed(file.accreditation_body)?),
        ("accreditation_code", placed(file.accreditation_code)?),
        ("location", placed(file.location)?),
        ("performance_location", performance_location),
        ("date_of_receipt", date_of_receipt),
        ("date_of_measurement", placed(file.date_of_measurement)?),
        ("date_of_issue", date_of_issue),
        ("operator", placed(file.operator)?),
        ("approved_by", placed(file.approved_by)?),
        ("traceability", placed(file.traceability)?),
        ("temperature_c", temperature),
        ("humidity_percent", humidity),
        ("pressure_hpa", pressure),
        ("environment", placed(file.environment)?),
        ("notes", placed(file.notes)?),
    ];
    let instruments = file
        .instrument
        .into_iter()
        .map(|i| {
            Ok(InstrumentEntry {
                role: plain(i.role)?,
                name: plain(i.name)?,
                model: plain(i.model)?,
                serial: plain(i.serial)?,
                calibration: plain(i.calibration)?,
                source: source.to_string(),
            })
        })
        .collect::<Result<Vec<_>, ReportError>>()?;
    Ok((
        values
            .into_iter()
            .filter_map(|(k, v)| {
                v.filter(|(v, _)| !v.trim().is_empty())
                    .map(|(v, offset)| (k, v, location(source, text, offset)))
            })
            .collect(),
        instruments,
    ))
}

/// The `#` comment lines before the header of a measurement (or self-calibration) file:
/// `key: value` lines of a known key (the key's case and spaces are free: `Customer:`,
/// `date of measurement:`), with their line numbers, and every other line as a note.
pub fn comment_metadata(text: &str) -> (Vec<(&'static str, String, u64)>, Vec<String>) {
    let mut values = Vec::new();
    let mut notes = Vec::new();
    for (number, line) in (1u64..).zip(text.lines()) {
        let Some(comment) = line.trim_start_matches('\u{feff}').strip_prefix('#') else {
            break; // the header: comments end
        };
        let comment = comment.trim();
        if comment.is_empty() {
            continue;
        }
        let known = comment.split_once(':').and_then(|(key, value)| {
            let key = key.trim().to_lowercase().replace([' ', '-'], "_");
            KEYS.iter()
                .find(|(k, _)| *k == key)
                .map(|(k, _)| (*k, value.trim().to_string()))
        });
        match known {
            Some((key, value)) if !value.is_empty() => values.push((key, value, number)),
            _ => notes.push(comment.to_string()),
        }
    }
    (values, notes)
}

/// Gathers the metadata of a report from its sources: the metadata file's text (with its
/// name), the measurement file's text, and a run directory. A key given by more than one
/// source takes the metadata file's value, then the measurement file's, then the
/// manifest's, and the conflict is listed when the values differ.
///
/// # Errors
///
/// [`ReportError::Meta`] with file, line and column for a metadata file or manifest that
/// is not valid; [`ReportError::Io`] for a manifest that cannot be read.
pub fn gather(
    meta: Option<(&str, &str)>,
    measurement: (&str, &str),
    run_dir: Option<&Path>,
) -> Result<Metadata, ReportError> {
    let (meta_values, mut instruments) = match meta {
        Some((text, source)) => read_meta_file(text, source)?,
        None => (Vec::new(), Vec::new()),
    };
    let (measurement_text, measurement_source) = measurement;
    // the comment lines are shown (as values or notes): no control characters in them
    for (number, line) in (1u64..).zip(measurement_text.lines()) {
        if !line.trim_start_matches('\u{feff}').starts_with('#') {
            break;
        }
        if let Some((offset, c)) = control_character(line) {
            let column = line[..offset].chars().count() as u64 + 1;
            return Err(ReportError::Meta {
                location: Location::new(measurement_source, number, column),
                message: refused_character(c),
            });
        }
    }
    let (comment_values, file_notes) = comment_metadata(measurement_text);
    let run = match run_dir {
        Some(dir) => {
            let (record, ids) = super::manifest::read_manifest(dir)?;
            instruments.extend(ids);
            Some(record)
        }
        None => None,
    };
    let mut conflicts = Vec::new();
    // the first comment line whose date is not a day
    let mut date_error = None;
    let fields = KEYS
        .iter()
        .map(|&(key, label)| {
            let from_meta = meta_values
                .iter()
                .find(|(k, _, _)| *k == key)
                .map(|(_, v, at)| {
                    (
                        v.clone(),
                        meta.map(|m| m.1).unwrap_or_default().to_string(),
                        at.clone(),
                    )
                });
            let from_comment = comment_values
                .iter()
                .filter(|(k, _, _)| *k == key)
                .map(|(_, v, line)| {
                    // the value's column in its comment line
                    let column = measurement_text
                        .lines()
                        .nth(*line as usize - 1)
                        .and_then(|l| l.rfind(v.as_str()).map(|i| l[..i].chars().count()))
                        .map_or(1, |c| c as u64 + 1);
                    (
                        v.clone(),
                        format!("{measurement_source}:{line}"),
                        Location::new(measurement_source, *line, column),
                    )
                })
                .next();
            let from_manifest = (key == "date_of_measurement")
                .then_some(run.as_ref())
                .flatten()
                .and_then(|r| {
                    r.started_date.clone().map(|d| {
                        (
                            d,
                            format!("{} (run started)", r.source),
                            Location::file_only(&r.source),
                        )
                    })
                });
            if let Some((value, _, at)) = from_comment
                .as_ref()
                .filter(|(v, _, _)| DATE_KEYS.contains(&key) && !crate::clock::is_date(v))
            {
                date_error = date_error.take().or(Some(ReportError::Meta {
                    location: at.clone(),
                    message: not_a_day(key, value),
                }));
            }
            let chosen = match (from_meta, from_comment.or(from_manifest)) {
                (Some(m), Some(c)) => {
                    if m.0 != c.0 {
                        conflicts.push(format!(
                            "{label}: “{}” from {} is shown; {} says “{}”",
                            m.0, m.1, c.1, c.0
                        ));
                    }
                    Some(m)
                }
                (m, c) => m.or(c),
            };
            MetaField {
                key,
                label,
                value: chosen.as_ref().map(|c| c.0.clone()),
                source: chosen.as_ref().map(|c| c.1.clone()),
                location: chosen.map(|c| c.2),
            }
        })
        .collect();
    if let Some(error) = date_error {
        return Err(error);
    }
    Ok(Metadata {
        fields,
        instruments,
        file_notes,
        conflicts,
        run,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comment_lines_give_known_keys_and_notes() {
        let text = "# Customer: PTB\n# run 2026-11-03, polygon P-24/7\n# date of measurement: 2026-11-03\n# polycal 0.1.0 simulate: 24 faces\ncycle,step\n# not a comment any more\n";
        let (values, notes) = comment_metadata(text);
        assert_eq!(
            values,
            vec![
                ("customer", "PTB".to_string(), 1),
                ("date_of_measurement", "2026-11-03".to_string(), 3)
            ]
        );
        assert_eq!(
            notes,
            vec![
                "run 2026-11-03, polygon P-24/7",
                "polycal 0.1.0 simulate: 24 faces"
            ]
        );
    }

    #[test]
    fn the_meta_file_wins_and_the_conflict_is_said() {
        let meta = "customer = \"Acme\"\noperator = \"J. Doe\"\n";
        let m = gather(
            Some((meta, "m.toml")),
            ("# customer: Other\n# artefact: P-24\nc\n", "f.csv"),
            None,
        )
        .unwrap();
        assert_eq!(m.value("customer"), Some("Acme"));
        assert_eq!(m.value("artefact"), Some("P-24"));
        assert_eq!(m.value("approved_by"), None);
        assert_eq!(m.conflicts.len(), 1);
        let artefact = m.fields.iter().find(|f| f.key == "artefact").unwrap();
        assert_eq!(artefact.source.as_deref(), Some("f.csv:2"));
    }

    #[test]
    fn a_bad_meta_file_is_located() {
        let err = gather(
            Some(("customer = \"A\"\ncolour = \"red\"\n", "m.toml")),
            ("c\n", "f"),
            None,
        )
        .unwrap_err();
        assert!(err.to_string().starts_with("m.toml:2:1: "), "{err}");
        let err = gather(
            Some(("temperature_c = 2000.0\n", "m.toml")),
            ("c\n", "f"),
            None,
        )
        .unwrap_err();
        assert!(err.to_string().starts_with("m.toml:1:17: "), "{err}");
    }
}
