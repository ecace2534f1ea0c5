//! A validation case as written: its files, `case.toml` and `reference.json`
//! (docs/FORMAT.md §13.1).

use serde::{Deserialize, Serialize};

use super::ValidationError;
use crate::input::Location;

/// A file of a case, by name within the case, with its bytes.
#[derive(Debug, Clone)]
pub struct CaseFile {
    /// The file's name (no directory).
    pub name: String,
    /// Its content.
    pub bytes: Vec<u8>,
}

/// A case's files as read, before they are understood.
#[derive(Debug, Clone)]
pub struct CaseSource {
    /// The case's name (its directory's name).
    pub name: String,
    /// Where it was read (`bundled: examples/validation/NAME` or the directory).
    pub origin: String,
    /// Its files, in name order.
    pub files: Vec<CaseFile>,
}

impl CaseSource {
    /// The file `name` of the case.
    pub fn file(&self, name: &str) -> Option<&CaseFile> {
        self.files.iter().find(|f| f.name == name)
    }

    /// The path of file `name` as messages show it.
    pub(super) fn shown(&self, name: &str) -> String {
        format!("{}/{name}", self.origin.trim_start_matches("bundled: "))
    }
}

/// How a deviation is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Tolerance {
    /// |x − r| divided by the largest |r| of the same list (or of the same field over a
    /// list of objects); a lone number by its own |r|; a reference of 0 in a list of zeros,
    /// or alone, is compared absolutely.
    Relative,
    /// |x − r| / |r| for every number on its own; a reference of 0 must be met exactly.
    RelativeEach,
    /// |x − r| in the number's own unit.
    Absolute,
    /// |x − r| / u, u the `u` polycal states beside the number (an effect's estimate
    /// against the size the data were given).
    StandardUncertainties,
}

/// The evaluation a case runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(super) enum Evaluation {
    Solve,
    Budget,
    MonteCarlo,
    Selfcal,
    Diagnose,
    Compare,
    Kc,
}

impl Evaluation {
    pub(super) fn name(self) -> &'static str {
        match self {
            Evaluation::Solve => "solve",
            Evaluation::Budget => "budget",
            Evaluation::MonteCarlo => "monte-carlo",
            Evaluation::Selfcal => "selfcal",
            Evaluation::Diagnose => "diagnose",
            Evaluation::Compare => "compare",
            Evaluation::Kc => "kc",
        }
    }
}

/// `case.toml`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Spec {
    pub name: String,
    pub description: String,
    pub evaluation: Evaluation,
    pub command: String,
    pub inputs: Vec<String>,
    pub budget: Option<String>,
    pub sigma: Option<f64>,
    pub trials: Option<usize>,
    pub seed: Option<u64>,
    pub labs: Option<Vec<String>>,
    pub tolerance: f64,
    pub tolerance_kind: Tolerance,
    pub tolerance_reason: String,
    pub reference_method: String,
}

/// `reference.json`.
#[derive(Debug, Clone, Deserialize)]
struct ReferenceFile {
    generator: String,
    #[serde(default)]
    generator_version: Option<String>,
    #[serde(default)]
    generated: Option<String>,
    values: serde_json::Value,
}

/// A case understood: its spec, its reference values, its files.
#[derive(Debug, Clone)]
pub(super) struct Case {
    pub source: CaseSource,
    pub spec: Spec,
    pub reference: serde_json::Value,
    pub generator: String,
}

impl Case {
    /// The case's `case.toml` and `reference.json` read, and the files it names checked
    /// present.
    pub(super) fn parse(source: &CaseSource) -> Result<Case, ValidationError> {
        let spec = spec(source)?;
        let refused = |file: &str, message: String| ValidationError::Case {
            location: Location::file_only(source.shown(file)),
            message,
        };
        if spec.name != source.name {
            return Err(refused(
                "case.toml",
                format!(
                    "name {:?} is not the case's directory {:?}",
                    spec.name, source.name
                ),
            ));
        }
        if !(spec.tolerance.is_finite() && spec.tolerance > 0.0) {
            return Err(refused(
                "case.toml",
                "tolerance: expected a number > 0".into(),
            ));
        }
        for input in spec.inputs.iter().chain(&spec.budget) {
            if source.file(input).is_none() {
                return Err(refused(input, "named in case.toml but missing".into()));
            }
        }
        let file = source
            .file("reference.json")
            .ok_or_else(|| refused("reference.json", "missing".into()))?;
        let reference: ReferenceFile =
            serde_json::from_slice(&file.bytes).map_err(|e| ValidationError::Case {
                location: Location::new(
                    source.shown("reference.json"),
                    e.line() as u64,
                    e.column() as u64,
                ),
                message: e.to_string(),
            })?;
        if !reference.values.is_object() {
            return Err(refused(
                "reference.json",
                "`values`: expected an object".into(),
            ));
        }
        let generator = [
            Some(reference.generator),
            reference.generator_version.map(|v| format!("version {v}")),
            reference.generated,
        ]
        .into_iter()
        .flatten()
        .collect::<Vec<_>>()
        .join(", ");
        Ok(Case {
            source: source.clone(),
            spec,
            reference: reference.values,
            generator,
        })
    }

    /// The bytes of input `name` (checked present by [`Case::parse`]).
    pub(super) fn bytes(&self, name: &str) -> &[u8] {
        self.source.file(name).map_or(&[], |f| &f.bytes[..])
    }
}

/// `case.toml` read.
fn spec(source: &CaseSource) -> Result<Spec, ValidationError> {
    let shown = source.shown("case.toml");
    let file = source
        .file("case.toml")
        .ok_or_else(|| ValidationError::Case {
            location: Location::file_only(shown.clone()),
            message: "missing".into(),
        })?;
    let text = std::str::from_utf8(&file.bytes).map_err(|e| ValidationError::Case {
        location: Location::file_only(shown.clone()),
        message: format!("not UTF-8 ({e})"),
    })?;
    toml::from_str(text).map_err(|e| {
        let offset = e.span().map_or(0, |s| s.start);
        ValidationError::Case {
            location: crate::uncertainty::budget_file::location(&shown, text, offset),
            message: e.message().trim_end().to_string(),
        }
    })
}
