//! What every source of a report's metadata gives alike — an instrument used, the run a
//! manifest records — and the characters a report or certificate cannot hold, refused
//! wherever a value is read ([`super::meta`], [`super::manifest`]).

/// The first character of `text` that XML 1.0 cannot carry and HTML calls a parse error
/// (a control character other than tab, line feed and carriage return), with its byte
/// offset.
pub fn control_character(text: &str) -> Option<(usize, char)> {
    text.char_indices().find(|&(_, c)| {
        (c.is_control() && !matches!(c, '\t' | '\n' | '\r')) || matches!(c, '\u{fffe}' | '\u{ffff}')
    })
}

/// Why a text with the control character `c` is refused.
pub(super) fn refused_character(c: char) -> String {
    format!(
        "a control character (U+{:04X}) cannot be written in a report or certificate",
        c as u32
    )
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
    /// The date the run ended (UTC, `YYYY-MM-DD`), when the manifest records an end.
    pub ended_date: Option<String>,
}
