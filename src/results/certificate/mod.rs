//! Results read back from a Digital Calibration Certificate (docs/FORMAT.md §13.3): the
//! values, U and k a DCC 3.x states for polycal's quantities, as the rows of a result
//! file, so that everything that reads a result file reads a certificate too.
//!
//! A certificate is told from a result file by its content (its first character that is
//! not a byte-order mark or white space is `<`), not by its name. What is read:
//!
//! - every `dcc:quantity` under `dcc:measurementResults` whose `refType` names one of
//!   polycal's quantities ([`quantity_ref_type`]: `polycal_pitchDeviation`,
//!   `polycal_faceDeviation`, `polycal_encoderError`, `polycal_setupError`), its values a
//!   D-SI `si:realListXMLList` with `si:expandedUncXMLList` (U and k) or
//!   `si:standardUncXMLList` (u), in arcseconds, degrees, arcminutes or radians;
//! - the index of each value from the `dcc:quantity` beside it in the same `dcc:list`:
//!   `polycal_faceNumber` (faces), `polycal_tableAngle` (an encoder error's table angle,
//!   its index then the position in the list from 0), or the labels `setupS_acA` of setup
//!   errors; without one, faces 1, 2, … and positions 0, 1, … in list order;
//! - not the results of a diagnosis's final model (`refType` `polycal_finalModel…`): the
//!   certificate's evaluation is the one read.
//!
//! The parse is bounded: a certificate larger than [`MAX_CERTIFICATE_BYTES`] or of more
//! than [`MAX_XML_NODES`] nodes is refused, and so is any document type declaration
//! (DTD): no entity is expanded and nothing outside the file is fetched, so that an XML
//! bomb or an external entity does no harm. Every refusal names the element's path and
//! its line and column.

use std::collections::HashMap;

use roxmltree::{Document, Node, ParsingOptions};

mod dsi;

use super::angle::AngleCheck;
use super::{Quantity, ResultFile};
use crate::input::FileError;

/// The DCC namespace.
const DCC: &str = "https://ptb.de/dcc";
/// The D-SI namespace.
const SI: &str = "https://ptb.de/si";

/// The largest certificate read, bytes (64 MiB): a DCC of 100 000 encoder positions takes
/// a few megabytes.
pub const MAX_CERTIFICATE_BYTES: usize = 64 << 20;

/// The most XML nodes a certificate may have (elements, text, attributes' owners): a
/// bound on the parser's memory whatever the file's shape.
pub const MAX_XML_NODES: u32 = 4_000_000;

/// The `refType` of a quantity's values in a certificate (docs/FORMAT.md §10.3), the one
/// name the writer (`certificate::dcc`) and this reader share.
///
/// ```
/// use polycal::results::{Quantity, certificate::quantity_ref_type};
/// assert_eq!(quantity_ref_type(Quantity::PitchDeviation), "polycal_pitchDeviation");
/// ```
pub fn quantity_ref_type(quantity: Quantity) -> &'static str {
    match quantity {
        Quantity::PitchDeviation => "polycal_pitchDeviation",
        Quantity::FaceDeviation => "polycal_faceDeviation",
        Quantity::EncoderError => "polycal_encoderError",
        Quantity::SetupError => "polycal_setupError",
        Quantity::AngleBlock => "polycal_angleBlock",
    }
}

/// The `refType` of a list of face numbers beside a quantity's values.
pub const FACE_NUMBER_REF_TYPE: &str = "polycal_faceNumber";
/// The `refType` of a list of table angles beside encoder errors (degrees).
pub const TABLE_ANGLE_REF_TYPE: &str = "polycal_tableAngle";
/// The start of the `refType` of a diagnosis's final-model results, not read back.
pub const FINAL_MODEL_REF_TYPE_PREFIX: &str = "polycal_finalModel";

/// A certificate read back: its results as a result file, and what it says of itself.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Certificate {
    /// The results, one row per value (their lines those of the values; no columns).
    pub results: ResultFile,
    /// `dcc:coreData/dcc:beginPerformanceDate`, as written (`YYYY-MM-DD`).
    pub begin_performance_date: Option<String>,
    /// `dcc:coreData/dcc:endPerformanceDate`, as written.
    pub end_performance_date: Option<String>,
    /// `dcc:coreData/dcc:uniqueIdentifier`.
    pub unique_identifier: Option<String>,
    /// The root's `schemaVersion` (3.x).
    pub schema_version: String,
}

/// Whether `bytes` look like XML: the first character after a byte-order mark and white
/// space is `<` (a result file's first is a letter or `#`).
pub fn looks_like_xml(bytes: &[u8]) -> bool {
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    bytes
        .iter()
        .find(|b| !b.is_ascii_whitespace())
        .is_some_and(|&b| b == b'<')
}

/// Reads the results a certificate states; `source` names it in messages.
///
/// ```
/// use polycal::results::certificate::read_certificate;
/// let xml = r#"<?xml version="1.0" encoding="UTF-8"?>
/// <dcc:digitalCalibrationCertificate xmlns:dcc="https://ptb.de/dcc" xmlns:si="https://ptb.de/si" schemaVersion="3.1.2">
///  <dcc:measurementResults><dcc:measurementResult><dcc:results><dcc:result>
///   <dcc:data><dcc:list>
///    <dcc:quantity refType="polycal_faceNumber"><si:realListXMLList>
///     <si:valueXMLList>1 2</si:valueXMLList><si:unitXMLList>\one</si:unitXMLList>
///    </si:realListXMLList></dcc:quantity>
///    <dcc:quantity refType="basic_measurementError polycal_pitchDeviation"><si:realListXMLList>
///     <si:valueXMLList>0.25 -0.25</si:valueXMLList><si:unitXMLList>\arcsecond</si:unitXMLList>
///     <si:expandedUncXMLList><si:uncertaintyXMLList>0.11 0.12</si:uncertaintyXMLList>
///      <si:coverageFactorXMLList>2</si:coverageFactorXMLList>
///      <si:coverageProbabilityXMLList>0.95</si:coverageProbabilityXMLList></si:expandedUncXMLList>
///    </si:realListXMLList></dcc:quantity>
///   </dcc:list></dcc:data>
///  </dcc:result></dcc:results></dcc:measurementResult></dcc:measurementResults>
/// </dcc:digitalCalibrationCertificate>"#;
/// let certificate = read_certificate(xml.as_bytes(), "cert.xml")?;
/// let rows = &certificate.results.rows;
/// assert_eq!((rows[1].index, rows[1].value, rows[1].expanded_u, rows[1].k), (2, -0.25, Some(0.12), Some(2.0)));
/// # Ok::<(), polycal::input::FileError>(())
/// ```
///
/// # Errors
///
/// [`FileError::Invalid`] naming the file, line, column and the element's path: XML that
/// is not well formed or not UTF-8, a DTD, a file too large, a root that is not a DCC 3.x,
/// a value that is not a finite number within its limits, lists of different lengths, a
/// unit polycal does not convert, an uncertainty as a coverage interval, a value stated
/// twice.
pub fn read_certificate(bytes: &[u8], source: &str) -> Result<Certificate, FileError> {
    if bytes.len() > MAX_CERTIFICATE_BYTES {
        return Err(FileError::invalid(
            source,
            (0, 0),
            format!(
                "a certificate of {} bytes: polycal reads certificates of {} bytes at most",
                bytes.len(),
                MAX_CERTIFICATE_BYTES
            ),
        ));
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let (line, column) = byte_position(bytes, e.valid_up_to());
        FileError::invalid(
            source,
            (line, column),
            "the certificate is not UTF-8 text".to_string(),
        )
    })?;
    if let Some(at) = nesting_beyond(text, MAX_XML_DEPTH) {
        return Err(FileError::invalid(
            source,
            byte_position(bytes, at),
            format!(
                "elements nested more than {MAX_XML_DEPTH} deep: polycal reads no deeper \
                 certificate (a DCC nests about 15)"
            ),
        ));
    }
    let options = ParsingOptions {
        allow_dtd: false,
        nodes_limit: MAX_XML_NODES,
    };
    let doc =
        Document::parse_with_options(text, options).map_err(|e| xml_error(source, text, &e))?;
    Reader { doc: &doc, source }.certificate()
}

/// The deepest nesting of elements a certificate may have: the parser descends
/// recursively, so a file of tens of thousands of nested elements would exhaust the stack
/// (an abort, not an error) before any rule is checked.
pub const MAX_XML_DEPTH: usize = 256;

/// The byte offset of the first start tag nested deeper than `limit`, found in one pass
/// before parsing (comments, CDATA, processing instructions and declarations skipped,
/// quoted attribute values passed over); `None` when the nesting stays within it.
fn nesting_beyond(text: &str, limit: usize) -> Option<usize> {
    let bytes = text.as_bytes();
    let find = |from: usize, pattern: &str| {
        text.get(from..)
            .and_then(|rest| rest.find(pattern))
            .map(|p| from + p + pattern.len())
    };
    let mut depth = 0usize;
    let mut i = 0;
    while let Some(p) = text.get(i..).and_then(|rest| rest.find('<')) {
        let at = i + p;
        let rest = &text[at..];
        let skipped = if rest.starts_with("<!--") {
            find(at, "-->")
        } else if rest.starts_with("<![CDATA[") {
            find(at, "]]>")
        } else if rest.starts_with("<?") {
            find(at, "?>")
        } else if rest.starts_with("<!") {
            find(at, ">")
        } else {
            None
        };
        if let Some(next) = skipped {
            i = next;
            continue;
        }
        if rest.starts_with("<!") || rest.starts_with("<?") {
            return None; // unterminated: the parser says so
        }
        // the end of this tag, quoted values passed over
        let mut quote = None;
        let mut end = None;
        for (k, &b) in bytes.iter().enumerate().skip(at + 1) {
            match (quote, b) {
                (Some(q), _) if b == q => quote = None,
                (Some(_), _) => {}
                (None, b'"' | b'\'') => quote = Some(b),
                (None, b'>') => {
                    end = Some(k);
                    break;
                }
                _ => {}
            }
        }
        let end = end?;
        if rest.starts_with("</") {
            depth = depth.saturating_sub(1);
        } else if bytes.get(end.wrapping_sub(1)) != Some(&b'/') {
            depth += 1;
            if depth > limit {
                return Some(at);
            }
        }
        i = end + 1;
    }
    None
}

/// The 1-based line and character column of byte `at` of `bytes` (valid UTF-8 before it).
fn byte_position(bytes: &[u8], at: usize) -> (u64, u64) {
    let before = bytes.get(..at).unwrap_or(bytes);
    let text = String::from_utf8_lossy(before);
    let line = text.matches('\n').count() as u64 + 1;
    let column = text.rsplit('\n').next().map_or(0, |l| l.chars().count()) as u64 + 1;
    (line, column)
}

/// The refusal of XML the parser could not read.
fn xml_error(source: &str, text: &str, e: &roxmltree::Error) -> FileError {
    let pos = e.pos();
    let mut at = (u64::from(pos.row), u64::from(pos.col));
    let message = match e {
        roxmltree::Error::DtdDetected => {
            // the parser reports the document's start; the declaration's own place is clearer
            if let Some(offset) = text.find("<!DOCTYPE") {
                at = byte_position(text.as_bytes(), offset);
            }
            "the certificate has a document type declaration \
            (<!DOCTYPE …>): polycal reads no DTD, so that no entity is expanded and nothing \
            outside the file is fetched (an XML bomb or an external entity)"
                .to_string()
        }
        roxmltree::Error::NodesLimitReached => format!(
            "the certificate has more than {MAX_XML_NODES} XML nodes: polycal reads no more"
        ),
        other => {
            // roxmltree ends its messages with " at ROW:COL", which the location says
            let text = other.to_string();
            let suffix = format!(" at {}:{}", pos.row, pos.col);
            let text = text.strip_suffix(&suffix).unwrap_or(&text).to_string();
            format!("not well-formed XML: {text}")
        }
    };
    FileError::invalid(source, at, message)
}

/// The reading of one parsed certificate.
struct Reader<'a, 'input> {
    doc: &'a Document<'input>,
    source: &'a str,
}

impl<'a, 'input> Reader<'a, 'input> {
    /// `(line, column)` of a node.
    fn place(&self, node: Node<'_, '_>) -> (u64, u64) {
        let pos = self.doc.text_pos_at(node.range().start);
        (u64::from(pos.row), u64::from(pos.col))
    }

    /// The refusal at `node`, its path first.
    fn refuse(&self, node: Node<'_, '_>, message: impl std::fmt::Display) -> FileError {
        FileError::invalid(
            self.source,
            self.place(node),
            format!("{}: {message}", path(node)),
        )
    }

    fn certificate(&self) -> Result<Certificate, FileError> {
        let root = self.doc.root_element();
        if !is(root, DCC, "digitalCalibrationCertificate") {
            let name = root.tag_name();
            return Err(self.refuse(
                root,
                format!(
                    "not a Digital Calibration Certificate: the root element is {{{}}}{}, \
                     not dcc:digitalCalibrationCertificate in the namespace {DCC}",
                    name.namespace().unwrap_or(""),
                    name.name()
                ),
            ));
        }
        let version = root.attribute("schemaVersion").unwrap_or("").to_string();
        if !version.starts_with("3.") {
            return Err(self.refuse(
                root,
                format!(
                    "schemaVersion {version:?}: polycal reads certificates of DCC 3.x \
                     (it writes 3.1.2)"
                ),
            ));
        }
        let core = child(root, DCC, "administrativeData").and_then(|a| child(a, DCC, "coreData"));
        let core_text = |name: &str| {
            core.and_then(|c| child(c, DCC, name))
                .and_then(|n| n.text())
                .map(|t| t.trim().to_string())
        };
        let mut results = ResultFile {
            source: self.source.to_string(),
            rows: Vec::new(),
            lines: Vec::new(),
            columns: Vec::new(),
        };
        let mut first: HashMap<(Quantity, u32), u64> = HashMap::new();
        let mut angles = AngleCheck::default();
        if let Some(measured) = child(root, DCC, "measurementResults") {
            for quantity in measured.descendants().filter(|n| is(*n, DCC, "quantity")) {
                let Some(family) = family(quantity) else {
                    continue;
                };
                if in_final_model(quantity) {
                    continue;
                }
                for (row, line) in self.rows(quantity, family)? {
                    if let Some(earlier) = first.insert((row.quantity, row.index), line) {
                        return Err(self.refuse(
                            quantity,
                            format!(
                                "{} {} is stated twice (first on line {earlier})",
                                row.quantity, row.index
                            ),
                        ));
                    }
                    if let Err(problem) = angles.admit(results.rows.len(), &row) {
                        let lines = &results.lines;
                        let place =
                            |i: usize| format!("line {}", lines.get(i).copied().unwrap_or(line));
                        let message = problem.message(&row, &results.rows, place);
                        return Err(self.refuse(quantity, message));
                    }
                    results.rows.push(row);
                    results.lines.push(line);
                }
            }
        }
        if results.rows.is_empty() {
            return Err(self.refuse(
                root,
                "states none of polycal's quantities: no dcc:quantity under \
                 dcc:measurementResults has the refType polycal_pitchDeviation, \
                 polycal_faceDeviation, polycal_encoderError or polycal_setupError \
                 (docs/FORMAT.md §13.3)",
            ));
        }
        Ok(Certificate {
            results,
            begin_performance_date: core_text("beginPerformanceDate"),
            end_performance_date: core_text("endPerformanceDate"),
            unique_identifier: core_text("uniqueIdentifier"),
            schema_version: version,
        })
    }
}

/// Whether `node` is the element `name` of namespace `ns`.
fn is(node: Node<'_, '_>, ns: &str, name: &str) -> bool {
    node.is_element() && node.tag_name().name() == name && node.tag_name().namespace() == Some(ns)
}

/// The first child element `name` of namespace `ns`.
fn child<'a, 'input>(node: Node<'a, 'input>, ns: &str, name: &str) -> Option<Node<'a, 'input>> {
    node.children().find(|c| is(*c, ns, name))
}

/// Whether the `refType` of `node` has the word `ref_type`.
fn has_ref_type(node: Node<'_, '_>, ref_type: &str) -> bool {
    node.attribute("refType")
        .is_some_and(|r| r.split_whitespace().any(|w| w == ref_type))
}

/// The quantity a `dcc:quantity` states, by its `refType`.
fn family(node: Node<'_, '_>) -> Option<Quantity> {
    Quantity::ALL
        .into_iter()
        .find(|&q| has_ref_type(node, quantity_ref_type(q)))
}

/// Whether `node` lies in a result of a diagnosis's final model.
fn in_final_model(node: Node<'_, '_>) -> bool {
    node.ancestors().any(|a| {
        is(a, DCC, "result")
            && a.attribute("refType").is_some_and(|r| {
                r.split_whitespace()
                    .any(|w| w.starts_with(FINAL_MODEL_REF_TYPE_PREFIX))
            })
    })
}

/// The element's path from the root, with prefixes as the DCC writes them and the
/// position among same-named siblings where there are several: e.g.
/// `dcc:digitalCalibrationCertificate/dcc:measurementResults/…/dcc:quantity[2]`.
fn path(node: Node<'_, '_>) -> String {
    let mut parts: Vec<String> = Vec::new();
    for n in node.ancestors().filter(|n| n.is_element()) {
        let tag = n.tag_name();
        let prefix = match tag.namespace() {
            Some(DCC) => "dcc:",
            Some(SI) => "si:",
            _ => "",
        };
        let same = |s: &Node<'_, '_>| s.is_element() && s.tag_name() == tag;
        // both axes start at the node itself: the position is 1-based, as in XPath
        let position = n.prev_siblings().filter(same).count();
        let several = position > 1 || n.next_siblings().skip(1).any(|s| same(&s));
        let mut part = format!("{prefix}{}", tag.name());
        if several {
            part.push_str(&format!("[{}]", position));
        }
        parts.push(part);
    }
    parts.reverse();
    parts.join("/")
}
