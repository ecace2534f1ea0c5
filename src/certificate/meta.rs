//! What a calibration report says about the calibration besides the numbers: the
//! customer, the artefact, the operator, the instruments, the environment, the run. Three
//! sources, each named where its values are shown: a metadata TOML file, the `# key:
//! value` comment lines of the measurement file, and a run directory's `manifest.json`
//! (docs/FORMAT.md §7.3, §10). Nothing is invented: a field no source gives is shown as
//! missing.

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::input::Location;
use crate::uncertainty::budget_file::location;

use super::ReportError;

/// The metadata keys, in the order a report shows them, with their labels.
pub const KEYS: [(&str, &str); 18] = [
    ("title", "Title"),
    ("certificate", "Certificate number"),
    ("customer", "Customer"),
    ("customer_address", "Customer address"),
    ("artefact", "Artefact (polygon)"),
    ("artefact_serial", "Artefact serial number"),
    ("encoder", "Rotary table / encoder"),
    ("encoder_serial", "Encoder serial number"),
    ("laboratory", "Laboratory"),
    ("location", "Place of calibration"),
    ("date_of_measurement", "Date of measurement"),
    ("operator", "Operator"),
    ("approved_by", "Approved by"),
    ("temperature_c", "Air temperature / °C"),
    ("humidity_percent", "Relative humidity / %"),
    ("pressure_hpa", "Air pressure / hPa"),
    ("environment", "Environment"),
    ("notes", "Notes"),
];

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
}

/// One instrument used in the calibration.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct InstrumentEntry {
    /// Its role, e.g. `autocollimator 1`.
    pub role: Option<String>,
    /// Its name.
    pub name: Option<String>,
    /// Its model.
    pub model: Option<String>,
    /// Its serial number.
    pub serial: Option<String>,
    /// Its calibration (traceability, certificate).
    pub calibration: Option<String>,
    /// Where the entry came from.
    pub source: String,
}

/// The run recorded in a run directory's manifest.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RunRecord {
    /// The manifest's path.
    pub source: String,
    /// Label and value pairs: software, start, end, outcome, readings, settings.
    pub facts: Vec<(String, String)>,
    /// The date the run started (UTC, `YYYY-MM-DD`): the date of measurement when no other
    /// source gives one.
    pub started_date: Option<String>,
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
    title: Option<String>,
    certificate: Option<String>,
    customer: Option<String>,
    customer_address: Option<String>,
    artefact: Option<String>,
    artefact_serial: Option<String>,
    encoder: Option<String>,
    encoder_serial: Option<String>,
    laboratory: Option<String>,
    location: Option<String>,
    date_of_measurement: Option<String>,
    operator: Option<String>,
    approved_by: Option<String>,
    temperature_c: Option<Spanned<f64>>,
    humidity_percent: Option<Spanned<f64>>,
    pressure_hpa: Option<Spanned<f64>>,
    environment: Option<String>,
    notes: Option<String>,
    #[serde(default)]
    instrument: Vec<InstrumentToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct InstrumentToml {
    role: Option<String>,
    name: Option<String>,
    model: Option<String>,
    serial: Option<String>,
    calibration: Option<String>,
}

/// Values by key.
type MetaValues = Vec<(&'static str, String)>;

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
                    Ok(format!("{v}"))
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
    let values: [(&'static str, Option<String>); 18] = [
        ("title", file.title),
        ("certificate", file.certificate),
        ("customer", file.customer),
        ("customer_address", file.customer_address),
        ("artefact", file.artefact),
        ("artefact_serial", file.artefact_serial),
        ("encoder", file.encoder),
        ("encoder_serial", file.encoder_serial),
        ("laboratory", file.laboratory),
        ("location", file.location),
        ("date_of_measurement", file.date_of_measurement),
        ("operator", file.operator),
        ("approved_by", file.approved_by),
        ("temperature_c", temperature),
        ("humidity_percent", humidity),
        ("pressure_hpa", pressure),
        ("environment", file.environment),
        ("notes", file.notes),
    ];
    let instruments = file
        .instrument
        .into_iter()
        .map(|i| InstrumentEntry {
            role: i.role,
            name: i.name,
            model: i.model,
            serial: i.serial,
            calibration: i.calibration,
            source: source.to_string(),
        })
        .collect();
    Ok((
        values
            .into_iter()
            .filter_map(|(k, v)| v.filter(|v| !v.trim().is_empty()).map(|v| (k, v)))
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

/// A run directory's manifest: the run's facts and the instruments' identification.
fn read_manifest(dir: &Path) -> Result<(RunRecord, Vec<InstrumentEntry>), ReportError> {
    let path = dir.join("manifest.json");
    let source = path.display().to_string();
    let (bytes, _) = crate::input::read_bytes(&path)
        .map_err(|(file, source)| ReportError::Io { file, source })?;
    let manifest: serde_json::Value =
        serde_json::from_slice(&bytes).map_err(|e| ReportError::Meta {
            location: Location::new(&source, e.line() as u64, e.column() as u64),
            message: format!("not a run manifest: {e}"),
        })?;
    let Some(object) = manifest.as_object() else {
        return Err(ReportError::Meta {
            location: Location::new(&source, 1, 1),
            message: "not a run manifest: not a JSON object".into(),
        });
    };
    let text_of = |value: &serde_json::Value| match value {
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    };
    let started = object
        .get("started")
        .and_then(serde_json::Value::as_str)
        .and_then(|t| t.get(..10))
        .map(str::to_string);
    let mut facts = Vec::new();
    for (key, label) in [
        ("software", "Software of the run"),
        ("started", "Run started (UTC)"),
        ("ended", "Run ended (UTC)"),
        ("outcome", "How the run ended"),
        ("readings", "Readings on disk"),
        ("expected_readings", "Readings of the complete run"),
    ] {
        match object.get(key) {
            Some(serde_json::Value::Null) | None => {}
            Some(value) => facts.push((label.to_string(), text_of(value))),
        }
    }
    if let Some(settings) = object.get("settings").and_then(|s| s.as_object()) {
        let text: Vec<String> = settings
            .iter()
            .map(|(k, v)| format!("{k} = {}", text_of(v)))
            .collect();
        facts.push(("Run settings".into(), text.join(", ")));
    }
    let mut instruments = Vec::new();
    if let Some(ids) = object.get("instruments").and_then(|s| s.as_object()) {
        for (key, role) in [
            ("ac1", "autocollimator 1"),
            ("ac2", "autocollimator 2"),
            ("table", "rotary table controller"),
        ] {
            if let Some(id) = ids.get(key).filter(|v| !v.is_null()) {
                instruments.push(InstrumentEntry {
                    role: Some(role.into()),
                    name: Some(text_of(id)),
                    source: format!("{source} (identification reply)"),
                    ..InstrumentEntry::default()
                });
            }
        }
    }
    Ok((
        RunRecord {
            source,
            facts,
            started_date: started,
        },
        instruments,
    ))
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
    let (comment_values, file_notes) = comment_metadata(measurement_text);
    let run = match run_dir {
        Some(dir) => {
            let (record, ids) = read_manifest(dir)?;
            instruments.extend(ids);
            Some(record)
        }
        None => None,
    };
    let mut conflicts = Vec::new();
    let fields = KEYS
        .iter()
        .map(|&(key, label)| {
            let from_meta = meta_values
                .iter()
                .find(|(k, _)| *k == key)
                .map(|(_, v)| (v.clone(), meta.map(|m| m.1).unwrap_or_default().to_string()));
            let from_comment = comment_values
                .iter()
                .filter(|(k, _, _)| *k == key)
                .map(|(_, v, line)| (v.clone(), format!("{measurement_source}:{line}")))
                .next();
            let from_manifest = (key == "date_of_measurement")
                .then_some(run.as_ref())
                .flatten()
                .and_then(|r| {
                    r.started_date
                        .clone()
                        .map(|d| (d, format!("{} (run started)", r.source)))
                });
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
                source: chosen.map(|c| c.1),
            }
        })
        .collect();
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
