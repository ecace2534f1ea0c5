//! The Digital Calibration Certificate of a [`CalibrationReport`]: XML valid against the
//! DCC 3.1.2 schema (PTB and the DCC community; `docs/schema/dcc.xsd`) with its results
//! in the D-SI 2.1.0 format (`docs/schema/SI_Format.xsd`), for the customer's software to
//! read the calibration values and their uncertainties without retyping
//! (docs/FORMAT.md §10.3).
//!
//! It is written from the same evaluated report as the HTML document, so the two carry
//! the same numbers: β, φ and α (eqs. (6)–(10) or the least-squares closure) with their
//! expanded uncertainties U, coverage factors k and coverage probability, stated as
//! GUM 7.2.6 says ([`crate::certificate::rounding`]: U to two significant digits rounded
//! up, the value at U's decimal place, k to three significant digits; the text the HTML
//! shows). What the schema requires and no source gives is refused, never invented:
//! [`DccError`] names every missing metadata key at once; a DCC is written whole or not
//! at all.
//!
//! ```
//! use polycal::certificate::{CalibrationReport, ReportInputs};
//!
//! let inputs = ReportInputs::new("examples/data/polygon24-2ac-6cycles.csv")
//!     .with_budget("examples/budgets/instrument.toml")
//!     .with_meta("examples/report/meta.toml")
//!     .with_generated_utc("2026-11-23T12:00:00.000Z");
//! let report = CalibrationReport::build(&inputs)?;
//! let xml = report.to_dcc()?;
//! assert!(xml.contains(r#"schemaVersion="3.1.2""#));
//! assert!(xml.contains("<si:unitXMLList>\\arcsecond</si:unitXMLList>"));
//!
//! // without the metadata the schema requires, no DCC
//! let bare = CalibrationReport::build(
//!     &ReportInputs::new("examples/data/polygon24-2ac-6cycles.csv")
//!         .with_budget("examples/budgets/instrument.toml"),
//! )?;
//! assert!(bare.to_dcc().unwrap_err().to_string().contains("`certificate`"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod calibrated;
mod kc;
mod results;
mod xml;

use super::meta::{InstrumentEntry, Metadata};
use super::{CalibrationReport, Evaluation};
use crate::SOFTWARE_VERSION;
use crate::input::Location;
use xml::Xml;

/// The DCC schema version written (`schemaVersion`).
pub const SCHEMA_VERSION: &str = "3.1.2";

/// The reference of the method, as the DCC's `usedMethod` cites it.
pub const METHOD_REFERENCE: &str = "Hsieh, Lin, Yeh and Watanabe, Calibration of a Rotary Encoder and a Polygon Using a Two-Autocollimator Method, Appl. Sci. 2023, 13, 1865";

/// Why a DCC cannot be written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DccError {
    /// The schema requires what no metadata source gives: every key missing, at once.
    #[error(
        "cannot write the DCC: it needs {}, which no metadata source gives: add {} to the metadata file or as `# key: …` comments of the measurement file (docs/FORMAT.md §10)",
        missing_list(.missing),
        if .missing.len() == 1 { "it" } else { "them" }
    )]
    MissingMetadata {
        /// Every key missing, in the order the metadata file lists them.
        missing: Vec<MissingKey>,
    },
    /// A date that is not `YYYY-MM-DD`.
    #[error(
        "{location}: cannot write the DCC: {key} “{value}” is not a date YYYY-MM-DD, which the DCC's {element} must be"
    )]
    NotADate {
        /// Where the value stands: file, line and column (the manifest's file alone).
        location: Location,
        /// The metadata key.
        key: &'static str,
        /// The value.
        value: String,
        /// The DCC element.
        element: &'static str,
    },
    /// A result without an expanded uncertainty.
    #[error(
        "cannot write the DCC: it states every result with its expanded uncertainty U, and {what} has none: evaluate with an instrument budget (docs/FORMAT.md §5.1)"
    )]
    NoExpandedUncertainty {
        /// Which results.
        what: &'static str,
    },
    /// A number D-SI cannot write (infinite or NaN).
    #[error("cannot write the DCC: {what} is not a finite number")]
    NotFinite {
        /// Which number.
        what: String,
    },
    /// A negative uncertainty.
    #[error("cannot write the DCC: {what} is negative")]
    Negative {
        /// Which number.
        what: String,
    },
    /// A coverage factor D-SI cannot write (below 1, or beyond its decimal form).
    #[error(
        "cannot write the DCC: the coverage factor {k} of {what} is not one D-SI can state (at least 1, decimal)"
    )]
    CoverageFactor {
        /// Which result.
        what: String,
        /// The factor.
        k: f64,
    },
    /// A coverage probability outside (0, 1].
    #[error("cannot write the DCC: the coverage probability {p} is not in (0, 1]")]
    CoverageProbability {
        /// The probability.
        p: f64,
    },
    /// A character XML 1.0 cannot carry.
    #[error(
        "cannot write the DCC: a control character (U+{code:04X}) cannot be written in {element}"
    )]
    Character {
        /// The element.
        element: &'static str,
        /// The character's code point.
        code: u32,
    },
}

/// A metadata key the DCC needs and no source gives.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct MissingKey {
    /// The metadata key.
    pub key: &'static str,
    /// Its label.
    pub label: &'static str,
    /// The DCC element it fills.
    pub element: &'static str,
}

/// The missing keys as a message lists them: `` `key` (label; the DCC's element)``.
fn missing_list(missing: &[MissingKey]) -> String {
    missing
        .iter()
        .map(|m| format!("`{}` ({}; the DCC's {})", m.key, m.label, m.element))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The metadata the DCC cannot do without, by key, with the element each fills: a key
/// no source gives is noted in `missing` (all are named in one refusal) and read as "".
fn required<'a>(
    meta: &'a Metadata,
    missing: &mut Vec<MissingKey>,
    key: &'static str,
    element: &'static str,
) -> &'a str {
    meta.value(key).unwrap_or_else(|| {
        missing.push(MissingKey {
            key,
            label: label_of(key),
            element,
        });
        ""
    })
}

/// The label of a metadata key.
fn label_of(key: &str) -> &'static str {
    super::meta::KEYS
        .iter()
        .find(|(k, _)| *k == key)
        .map_or("", |(_, label)| label)
}

pub use crate::clock::is_date;

/// The performance dates: the date of measurement, and the run's end date when the date
/// is the run's start.
fn performance_dates(meta: &Metadata) -> Result<(String, String), DccError> {
    let Some(begin) = meta.value("date_of_measurement") else {
        return Err(DccError::MissingMetadata {
            missing: vec![MissingKey {
                key: "date_of_measurement",
                label: label_of("date_of_measurement"),
                element: "beginPerformanceDate",
            }],
        });
    };
    if !is_date(begin) {
        let location = meta
            .fields
            .iter()
            .find(|f| f.key == "date_of_measurement")
            .and_then(|f| f.location.clone())
            .unwrap_or_else(|| Location::file_only("metadata"));
        return Err(DccError::NotADate {
            location,
            key: "date_of_measurement",
            value: begin.to_string(),
            element: "beginPerformanceDate",
        });
    }
    let end = meta
        .run
        .as_ref()
        .filter(|r| r.started_date.as_deref() == Some(begin))
        .and_then(|r| r.ended_date.as_deref())
        .filter(|end| is_date(end) && *end >= begin)
        .unwrap_or(begin);
    Ok((begin.to_string(), end.to_string()))
}

/// The DCC of a report (docs/FORMAT.md §10.3).
///
/// # Errors
///
/// [`DccError`]: metadata the schema requires and no source gives, a date not
/// `YYYY-MM-DD`, results without expanded uncertainties, a number D-SI cannot write.
pub fn document(report: &CalibrationReport) -> Result<String, DccError> {
    let mut x = Xml::new();
    x.open(
        "dcc:digitalCalibrationCertificate",
        &[
            ("xmlns:dcc", xml::DCC_NAMESPACE),
            ("xmlns:si", xml::SI_NAMESPACE),
            ("schemaVersion", SCHEMA_VERSION),
        ],
    );
    administrative_data(&mut x, report)?;
    results::measurement_results(&mut x, report)?;
    Ok(x.finish())
}

/// The software: polycal and its version.
fn software(x: &mut Xml, wrapper: &'static str) -> Result<(), DccError> {
    x.open(wrapper, &[]);
    x.open("dcc:software", &[]);
    x.content("dcc:name", "polycal")?;
    x.text("dcc:release", &[], SOFTWARE_VERSION)?;
    x.text("dcc:type", &[], "application")?;
    x.content(
        "dcc:description",
        "Simultaneous calibration of an optical polygon and a rotary encoder by the two-autocollimator method, with uncertainty, diagnosis and self-calibration; wrote this certificate.",
    )?;
    x.close();
    x.close();
    Ok(())
}

/// `administrativeData`: software, core data, items, laboratory, responsible persons,
/// customer, statements.
fn administrative_data(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    let meta = &report.metadata;
    // every required value first: a refusal names every key missing at once, in the
    // order the metadata file lists them
    let mut missing = Vec::new();
    let m = &mut missing;
    let certificate = required(meta, m, "certificate", "uniqueIdentifier");
    let customer = required(meta, m, "customer", "customer name");
    let customer_address = required(meta, m, "customer_address", "customer location");
    let customer_email = required(meta, m, "customer_email", "customer eMail");
    let laboratory = required(meta, m, "laboratory", "calibrationLaboratory name");
    let laboratory_address = required(
        meta,
        m,
        "laboratory_address",
        "calibrationLaboratory location",
    );
    let laboratory_email = required(meta, m, "laboratory_email", "calibrationLaboratory eMail");
    let country = required(meta, m, "country", "countryCodeISO3166_1");
    let performance_location = required(meta, m, "performance_location", "performanceLocation");
    // its form is checked below, once every key is known to be there
    required(meta, m, "date_of_measurement", "beginPerformanceDate");
    let persons: Vec<(&str, &str, bool)> = [
        ("approved_by", "Approved by", true),
        ("operator", "Operator", false),
    ]
    .into_iter()
    .filter_map(|(key, role, main)| meta.value(key).map(|name| (name, role, main)))
    .collect();
    if persons.is_empty() {
        m.push(MissingKey {
            key: "approved_by",
            label: label_of("approved_by"),
            element: "respPerson (approved_by or operator)",
        });
    }
    let polygon = matches!(report.evaluation, Evaluation::Polygon { .. });
    let artefact = if polygon {
        Some((
            required(meta, m, "artefact_manufacturer", "item manufacturer"),
            required(meta, m, "artefact_serial", "item identification"),
        ))
    } else {
        None
    };
    let encoder_manufacturer = required(meta, m, "encoder_manufacturer", "item manufacturer");
    let encoder_serial = required(meta, m, "encoder_serial", "item identification");
    if !missing.is_empty() {
        return Err(DccError::MissingMetadata { missing });
    }
    let (begin, end) = performance_dates(meta)?;

    x.open("dcc:administrativeData", &[]);
    software(x, "dcc:dccSoftware")?;
    x.open("dcc:coreData", &[]);
    x.text("dcc:countryCodeISO3166_1", &[], country)?;
    x.text("dcc:usedLangCodeISO639_1", &[], "en")?;
    x.text("dcc:mandatoryLangCodeISO639_1", &[], "en")?;
    x.text("dcc:uniqueIdentifier", &[], certificate)?;
    // a day, checked when the metadata was read
    if let Some(receipt) = meta.value("date_of_receipt") {
        x.text("dcc:receiptDate", &[], receipt)?;
    }
    x.text("dcc:beginPerformanceDate", &[], &begin)?;
    x.text("dcc:endPerformanceDate", &[], &end)?;
    x.text("dcc:performanceLocation", &[], performance_location)?;
    x.close();

    x.open("dcc:items", &[]);
    if let (Evaluation::Polygon { solve, .. }, Some((manufacturer, serial))) =
        (&report.evaluation, artefact)
    {
        let name = meta.value("artefact").map_or_else(
            || format!("Optical polygon, {} faces", solve.faces),
            str::to_string,
        );
        item(
            x,
            "polygon",
            &name,
            &format!(
                "Optical polygon of {} faces: its pitch deviations β and face deviations φ are calibrated.",
                solve.faces
            ),
            manufacturer,
            serial,
        )?;
    }
    let encoder = meta.value("encoder").unwrap_or("Rotary table with encoder");
    item(
        x,
        "encoder",
        encoder,
        "Rotary table with angle encoder: its encoder errors α are calibrated.",
        encoder_manufacturer,
        encoder_serial,
    )?;
    x.close();

    x.open("dcc:calibrationLaboratory", &[]);
    if let Some(code) = meta.value("accreditation_code") {
        x.text("dcc:calibrationLaboratoryCode", &[], code)?;
    }
    contact(
        x,
        laboratory,
        laboratory_email,
        laboratory_address,
        Some(country),
    )?;
    x.close();

    x.open("dcc:respPersons", &[]);
    for (name, role, main) in persons {
        x.open("dcc:respPerson", &[]);
        x.open("dcc:person", &[]);
        x.content("dcc:name", name)?;
        x.close();
        x.text("dcc:role", &[], role)?;
        if main {
            x.text("dcc:mainSigner", &[], "true")?;
        }
        x.close();
    }
    x.close();

    x.open("dcc:customer", &[]);
    x.content("dcc:name", customer)?;
    x.text("dcc:eMail", &[], customer_email)?;
    x.open("dcc:location", &[]);
    if let Some(country) = meta.value("customer_country") {
        x.text("dcc:countryCode", &[], country)?;
    }
    x.content("dcc:further", customer_address)?;
    x.close();
    x.close();

    statements(x, report)?;
    x.close();
    Ok(())
}

/// One `item` with its manufacturer and serial number.
fn item(
    x: &mut Xml,
    id: &str,
    name: &str,
    description: &str,
    manufacturer: &str,
    serial: &str,
) -> Result<(), DccError> {
    x.open("dcc:item", &[("id", id)]);
    x.content("dcc:name", name)?;
    x.content("dcc:description", description)?;
    x.open("dcc:manufacturer", &[]);
    x.content("dcc:name", manufacturer)?;
    x.close();
    x.open("dcc:identifications", &[]);
    identification(x, "manufacturer", serial, "Serial number")?;
    x.close();
    x.close();
    Ok(())
}

/// One `identification`.
fn identification(x: &mut Xml, issuer: &str, value: &str, name: &str) -> Result<(), DccError> {
    x.open("dcc:identification", &[]);
    x.text("dcc:issuer", &[], issuer)?;
    x.text("dcc:value", &[], value)?;
    x.content("dcc:name", name)?;
    x.close();
    Ok(())
}

/// A `contact`: name, e-mail, and the address as one text (and the country).
fn contact(
    x: &mut Xml,
    name: &str,
    email: &str,
    address: &str,
    country: Option<&str>,
) -> Result<(), DccError> {
    x.open("dcc:contact", &[]);
    x.content("dcc:name", name)?;
    x.text("dcc:eMail", &[], email)?;
    x.open("dcc:location", &[]);
    if let Some(country) = country {
        x.text("dcc:countryCode", &[], country)?;
    }
    x.content("dcc:further", address)?;
    x.close();
    x.close();
    Ok(())
}

/// `statements`: the uncertainty statement, the place, the notes, what a reader must know.
fn statements(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    let meta = &report.metadata;
    let mut said: Vec<(&str, String)> = vec![(
        "polycal_uncertaintyStatement",
        results::uncertainty_statement(report),
    )];
    if let Some(place) = meta.value("location") {
        said.push((
            "polycal_placeOfCalibration",
            format!("Place of calibration: {place}"),
        ));
    }
    if let Some(title) = meta.value("title") {
        said.push(("polycal_title", title.to_string()));
    }
    if let Some(notes) = meta.value("notes") {
        said.push(("polycal_notes", notes.to_string()));
    }
    for conflict in &meta.conflicts {
        said.push((
            "polycal_metadataConflict",
            format!("Metadata sources disagree: {conflict}"),
        ));
    }
    if let Some(d) = &report.diagnosis {
        said.push((
            "polycal_diagnosisVerdict",
            if d.adequate() {
                "The diagnosis of the measurement found the final model adequate: its residuals are consistent with noise.".to_string()
            } else {
                "The diagnosis of the measurement found the final model NOT adequate: structure is left in the residuals that no known effect explains.".to_string()
            },
        ));
    }
    if let Some(accreditation) = meta.accreditation() {
        said.push(("polycal_accreditation", accreditation));
    }
    // ISO/IEC 17025 7.8.2.1 h), o)
    if let Some(condition) = meta.value("item_condition") {
        said.push((
            "polycal_itemCondition",
            format!("Condition of the item: {condition}"),
        ));
    }
    said.push((
        "polycal_resultsRelateToItem",
        report.results_relate_statement(),
    ));
    x.open("dcc:statements", &[]);
    if let Some(traceability) = meta.value("traceability") {
        x.open("dcc:statement", &[("refType", "polycal_traceability")]);
        x.text("dcc:traceable", &[], "true")?;
        x.content("dcc:declaration", traceability)?;
        x.close();
    }
    // ISO/IEC 17025 7.8.2.1 k): the date of issue, a day (the report's day by default)
    if let Some(issue) = meta.value("date_of_issue").filter(|d| is_date(d)) {
        x.open("dcc:statement", &[("refType", "polycal_dateOfIssue")]);
        x.content("dcc:declaration", &format!("Date of issue: {issue}"))?;
        x.text("dcc:date", &[], issue)?;
        x.close();
    }
    for (kind, text) in said {
        x.open("dcc:statement", &[("refType", kind)]);
        x.content("dcc:declaration", &text)?;
        x.close();
    }
    x.close();
    Ok(())
}

/// One `measuringEquipment` of the metadata's instruments.
fn equipment(x: &mut Xml, entry: &InstrumentEntry, index: usize) -> Result<(), DccError> {
    x.open(
        "dcc:measuringEquipment",
        &[("id", &format!("instrument{}", index + 1))],
    );
    let name = entry
        .name
        .as_deref()
        .or(entry.role.as_deref())
        .unwrap_or("instrument");
    x.content("dcc:name", name)?;
    let mut description: Vec<String> = Vec::new();
    if let Some(role) = &entry.role {
        description.push(format!("Role: {role}"));
    }
    if let Some(calibration) = &entry.calibration {
        description.push(format!("Calibration: {calibration}"));
    }
    description.push(format!("Source: {}", entry.source));
    x.content("dcc:description", &description.join(". "))?;
    if let Some(model) = &entry.model {
        x.text("dcc:model", &[], model)?;
    }
    if let Some(serial) = &entry.serial {
        x.open("dcc:identifications", &[]);
        identification(x, "manufacturer", serial, "Serial number")?;
        x.close();
    }
    x.close();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_real_days() {
        assert!(is_date("2026-11-03"));
        assert!(is_date("2024-02-29"));
        assert!(!is_date("2026-02-29"));
        assert!(!is_date("1900-02-29"));
        assert!(is_date("2000-02-29"));
        assert!(!is_date("2026-13-01"));
        assert!(!is_date("2026-1-03"));
        assert!(!is_date("3 Nov 2026"));
        assert!(!is_date("2026-11-03T10:00"));
    }
}
