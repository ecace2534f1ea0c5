//! The DCC schema check the document tests share (`tests/commands/certificate_dcc.rs`,
//! `tests/commands/report_kc.rs`): xmllint against the vendored DCC 3.1.2 and D-SI 2.1.0
//! schemas (`docs/schema/`), offline through the catalog.
//!
//! xmllint comes from Debian's libxml2-utils. `.ci/run` installs it and sets
//! `POLYCAL_REQUIRE_XMLLINT=1`, which turns its absence into a failure; without that
//! variable a machine without xmllint skips only the validation, saying so on standard
//! error where `cargo test` shows it (`tests/commands/skip_support`).

use std::path::Path;
use std::process::Command;

use crate::skip_support;

/// xmllint's verdict on `file` against the vendored schema: `Some((true, _))` valid,
/// `Some((false, messages))` invalid, `None` when xmllint is not installed and not
/// required. A schema that does not compile (its imports not resolved offline) fails
/// the test: a failure of the set-up, never a pass.
pub fn schema_valid(file: &Path) -> Option<(bool, String)> {
    let schema = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/schema");
    let run = Command::new("xmllint")
        .env("XML_CATALOG_FILES", schema.join("catalog.xml"))
        .args(["--nonet", "--noout", "--schema"])
        .arg(schema.join("dcc.xsd"))
        .arg(file)
        .output();
    match run {
        Ok(out) => {
            let messages = String::from_utf8_lossy(&out.stderr).into_owned();
            assert_ne!(
                out.status.code(),
                Some(5),
                "the schema does not compile: {messages}"
            );
            Some((out.status.success(), messages))
        }
        Err(e) => {
            skip_support::missing(
                "xmllint",
                "the DCC schema validation of every certificate",
                "Debian: apt-get install libxml2-utils",
                "POLYCAL_REQUIRE_XMLLINT",
                &e.to_string(),
            );
            None
        }
    }
}

/// Asserts that `file` validates (when a validator is there).
pub fn assert_valid(file: &Path) {
    if let Some((valid, messages)) = schema_valid(file) {
        assert!(valid, "{} does not validate:\n{messages}", file.display());
    }
}
