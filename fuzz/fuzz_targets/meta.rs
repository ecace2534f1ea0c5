//! The report's metadata TOML (docs/FORMAT.md §10.2), with the same bytes as the
//! measurement file whose comment lines are read too; accepted metadata goes into the
//! documents a lab hands over — the HTML report and the DCC (§10.3) of the bundled
//! example with its instrument budget — and a DCC that is built must be well-formed XML
//! (every `<` of a tag closed by its `>`, counted: the writer escapes both in text).
#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use polycal::certificate::meta::gather;
use polycal::certificate::{CalibrationReport, ReportInputs};
use polycal_fuzz::{SOURCE, accepted};

/// The example's report (once), or `None` when run outside the repository.
fn report() -> Option<&'static CalibrationReport> {
    static CELL: OnceLock<Option<CalibrationReport>> = OnceLock::new();
    CELL.get_or_init(|| {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let inputs = ReportInputs::new(root.join("examples/data/polygon24-2ac-6cycles.csv"))
            .with_budget(root.join("examples/budgets/instrument.toml"))
            .with_generated_utc("2026-11-26T12:00:00.000Z");
        CalibrationReport::build(&inputs).ok()
    })
    .as_ref()
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Some(metadata) = accepted(
        gather(Some((text, SOURCE)), (text, "measurement.csv"), None),
        SOURCE,
        data,
    ) else {
        return;
    };
    let Some(base) = report() else {
        return;
    };
    let mut report = base.clone();
    report.metadata = metadata;
    let _ = report.to_html();
    if let Ok(xml) = report.to_dcc() {
        let opened = xml.matches('<').count();
        let closed = xml.matches('>').count();
        // the writer escapes both in text and attributes (`&lt;`, `&gt;`)
        assert_eq!(opened, closed, "a DCC whose tags do not balance");
    }
});
