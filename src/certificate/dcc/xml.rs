//! The XML a DCC is written in: elements indented two spaces, text and attributes
//! escaped, and numbers in the lexical forms D-SI 2.1.0 accepts (docs/FORMAT.md §10.3).

use std::fmt::Write;

use super::DccError;

/// The DCC's namespace.
pub const DCC_NAMESPACE: &str = "https://ptb.de/dcc";
/// The D-SI namespace.
pub const SI_NAMESPACE: &str = "https://ptb.de/si";

// Text escaped for XML element content and attribute values (`&`, `<`, `>`, `"`, `'`):
// the figures' escaping as data, one for every XML polycal writes (a bidirectional
// formatting character is carried as written, as in the JSON). Control characters never
// reach it here: the metadata refuses them where it is read (`meta::control_character`)
// and `Xml::text` checks again.
use crate::figure::svg::esc_data as escape;

/// Element text escaped so that it reads back as written: a carriage return as `&#13;`,
/// which a parser's line-end normalisation would otherwise turn into a line feed.
fn escape_text(text: &str) -> String {
    escape(text).replace('\r', "&#13;")
}

/// An attribute value escaped so that it reads back as written: tab, line feed and
/// carriage return as character references, which attribute-value normalisation would
/// otherwise turn into spaces.
fn escape_attribute(text: &str) -> String {
    escape_text(text)
        .replace('\n', "&#10;")
        .replace('\t', "&#9;")
}

/// An XML document being written: open elements are closed in order.
pub struct Xml {
    out: String,
    open: Vec<&'static str>,
}

impl Xml {
    /// A document with its declaration.
    pub fn new() -> Self {
        Self {
            out: String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"),
            open: Vec::new(),
        }
    }

    fn indent(&mut self) {
        for _ in 0..self.open.len() {
            self.out.push_str("  ");
        }
    }

    fn start_tag(&mut self, name: &str, attributes: &[(&str, &str)]) {
        self.indent();
        self.out.push('<');
        self.out.push_str(name);
        for (key, value) in attributes {
            // attribute names are the writer's own; values escaped
            let _ = write!(self.out, " {key}=\"{}\"", escape_attribute(value));
        }
        self.out.push('>');
    }

    /// Opens `name` with its attributes; [`Xml::close`] ends it.
    pub fn open(&mut self, name: &'static str, attributes: &[(&str, &str)]) {
        self.start_tag(name, attributes);
        self.out.push('\n');
        self.open.push(name);
    }

    /// Closes the element opened last.
    pub fn close(&mut self) {
        if let Some(name) = self.open.pop() {
            self.indent();
            let _ = writeln!(self.out, "</{name}>");
        }
    }

    /// `<name attributes>text</name>` with `text` escaped.
    ///
    /// # Errors
    ///
    /// [`DccError::Character`] for a character XML 1.0 cannot carry.
    pub fn text(
        &mut self,
        name: &'static str,
        attributes: &[(&str, &str)],
        text: &str,
    ) -> Result<(), DccError> {
        if let Some((_, c)) = crate::certificate::meta::control_character(text) {
            return Err(DccError::Character {
                element: name,
                code: c as u32,
            });
        }
        self.start_tag(name, attributes);
        self.out.push_str(&escape_text(text));
        let _ = writeln!(self.out, "</{name}>");
        Ok(())
    }

    /// `<name><dcc:content lang="en">text</dcc:content></name>`: the DCC's text type.
    ///
    /// # Errors
    ///
    /// As [`Xml::text`].
    pub fn content(&mut self, name: &'static str, text: &str) -> Result<(), DccError> {
        self.open(name, &[]);
        self.text("dcc:content", &[("lang", "en")], text)?;
        self.close();
        Ok(())
    }

    /// The document.
    pub fn finish(mut self) -> String {
        while !self.open.is_empty() {
            self.close();
        }
        self.out
    }
}

/// A value as D-SI writes a real (`si:value`): the shortest text that reads back to the
/// same double (so a DCC carries the JSON's numbers exactly where no U states them:
/// table angles, En, the fit), `-0` as `0`.
///
/// # Errors
///
/// [`DccError::NotFinite`] for an infinite or NaN value, which D-SI cannot write.
pub fn real(value: f64, what: &str) -> Result<String, DccError> {
    if !value.is_finite() {
        return Err(DccError::NotFinite {
            what: what.to_string(),
        });
    }
    // `{:?}` is Rust's shortest round-trip form: `0.1`, `-2.5`, `1e-7`, `1e16`; all match
    // D-SI's decimal pattern
    Ok(if value == 0.0 {
        "0.0".to_string()
    } else {
        format!("{value:?}")
    })
}

/// An uncertainty as D-SI writes it (`si:uncertainty`, no sign).
///
/// # Errors
///
/// [`DccError::NotFinite`] for an infinite or NaN value; [`DccError::Negative`] for a
/// negative one.
pub fn uncertainty(value: f64, what: &str) -> Result<String, DccError> {
    if value < 0.0 {
        return Err(DccError::Negative {
            what: what.to_string(),
        });
    }
    real(value.abs(), what)
}

/// A coverage factor as D-SI writes it (`si:coverageFactor`: at least 1, decimal digits
/// without an exponent).
///
/// # Errors
///
/// [`DccError::CoverageFactor`] for a factor below 1, not finite, or too large for the form.
pub fn coverage_factor(k: f64, what: &str) -> Result<String, DccError> {
    let text = format!("{k:?}");
    if !(1.0..1e15).contains(&k) || text.contains('e') {
        return Err(DccError::CoverageFactor {
            what: what.to_string(),
            k,
        });
    }
    Ok(text)
}

/// A coverage probability as D-SI writes it (`si:coverageProbability`: 0 … 1, no
/// exponent).
///
/// # Errors
///
/// [`DccError::CoverageProbability`] outside (0, 1] or not writable without an exponent.
pub fn coverage_probability(p: f64) -> Result<String, DccError> {
    let text = format!("{p:?}");
    if !(p > 0.0 && p <= 1.0) || text.contains('e') {
        return Err(DccError::CoverageProbability { p });
    }
    Ok(text)
}

/// `bytes` in base64 (RFC 4648, with padding): a file a certificate carries
/// (`dcc:dataBase64`).
pub fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if i <= chunk.len() {
                out.push(char::from(ALPHABET[((n >> shift) & 63) as usize]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

#[cfg(test)]
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specials_are_escaped_and_control_characters_refused() {
        assert_eq!(
            escape(r#"a<b & "c" 'd'>"#),
            "a&lt;b &amp; &quot;c&quot; &apos;d&apos;&gt;"
        );
        let mut xml = Xml::new();
        assert!(xml.text("dcc:value", &[], "bell \u{7}").is_err());
        xml.text("dcc:value", &[("refType", "a&b")], "β < 1″")
            .unwrap();
        assert!(
            xml.finish()
                .ends_with("<dcc:value refType=\"a&amp;b\">β &lt; 1″</dcc:value>\n")
        );
    }

    proptest::proptest! {
        /// Any text without a control character reads back from the document as written
        /// (an independent parser: roxmltree); with one, the writer refuses it.
        #[test]
        fn any_text_reads_back_or_is_refused(text in "\\PC*|[\r\n\t&<a]*|.*[\u{0}-\u{1f}\u{7f}-\u{9f}].*") {
            let mut xml = Xml::new();
            xml.open("dcc:root", &[("xmlns:dcc", DCC_NAMESPACE)]);
            let written = xml.text("dcc:content", &[("refType", &text)], &text);
            let refused = crate::certificate::meta::control_character(&text).is_some();
            proptest::prop_assert_eq!(written.is_err(), refused);
            if !refused {
                let document = xml.finish();
                let parsed = roxmltree::Document::parse(&document).map_err(|e| {
                    proptest::test_runner::TestCaseError::fail(format!("{e}: {document}"))
                })?;
                let content = parsed
                    .descendants()
                    .find(|n| n.tag_name().name() == "content")
                    .ok_or_else(|| proptest::test_runner::TestCaseError::fail("no content"))?;
                // exactly as written: line ends and attribute whitespace are escaped, so
                // neither normalisation of a conforming parser changes them
                proptest::prop_assert_eq!(content.text().unwrap_or(""), text.as_str());
                proptest::prop_assert_eq!(content.attribute("refType"), Some(text.as_str()));
            }
        }
    }

    #[test]
    fn base64_is_the_rfc_4648_test_vectors() {
        // RFC 4648 §10
        for (text, encoded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(text.as_bytes()), encoded, "{text:?}");
        }
    }

    #[test]
    fn numbers_take_the_d_si_forms() {
        assert_eq!(real(-0.0, "x").unwrap(), "0.0");
        assert_eq!(real(1e-7, "x").unwrap(), "1e-7");
        assert_eq!(real(0.1 + 0.2, "x").unwrap(), "0.30000000000000004");
        assert!(real(f64::NAN, "x").is_err());
        assert!(real(f64::INFINITY, "x").is_err());
        assert!(uncertainty(-1.0, "x").is_err());
        assert_eq!(coverage_factor(2.0, "x").unwrap(), "2.0");
        assert!(coverage_factor(0.5, "x").is_err());
        assert_eq!(coverage_probability(0.95).unwrap(), "0.95");
        assert!(coverage_probability(1.5).is_err());
    }
}
