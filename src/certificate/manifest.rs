//! A run directory's `manifest.json` as a report reads it (docs/FORMAT.md §7.3, §10.2):
//! the run's facts, its start and end dates, and the instruments' identification
//! replies, each text checked for control characters where the manifest holds it.

use std::path::Path;

use super::ReportError;
use super::record::{InstrumentEntry, RunRecord, control_character, refused_character};
use crate::input::Location;
use crate::uncertainty::budget_file::location;

/// A run directory's manifest: the run's facts and the instruments' identification.
pub(super) fn read_manifest(dir: &Path) -> Result<(RunRecord, Vec<InstrumentEntry>), ReportError> {
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
    let date_of = |key: &str| {
        object
            .get(key)
            .and_then(serde_json::Value::as_str)
            .and_then(|t| t.get(..10))
            .map(str::to_string)
    };
    let (started, ended) = (date_of("started"), date_of("ended"));
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
    let shown = facts
        .iter()
        .map(|(_, v)| v.as_str())
        .chain(instruments.iter().filter_map(|i| i.name.as_deref()));
    for value in shown {
        if let Some((_, c)) = control_character(value) {
            // where the manifest writes it: raw (not JSON) or as an escape
            let text = String::from_utf8_lossy(&bytes);
            let escape = format!("\\u{:04x}", c as u32);
            let offset = text
                .find(&escape)
                .or_else(|| text.find(&escape.to_uppercase().replace("\\U", "\\u")))
                .unwrap_or(0);
            return Err(ReportError::Meta {
                location: location(&source, &text, offset),
                message: refused_character(c),
            });
        }
    }
    Ok((
        RunRecord {
            source,
            facts,
            started_date: started,
            ended_date: ended,
        },
        instruments,
    ))
}
