//! Conditions on a reply's fields: what makes a state "ready", a reading valid, an error
//! code "none".
//!
//! A condition names one field of its reply's template and holds when every test it
//! gives holds:
//!
//! | key | holds when the field … |
//! |---|---|
//! | `equals = ["32", "33"]` | is one of the values (hex and letters compared without case) |
//! | `not_equals = ["0000"]` | is none of them |
//! | `ends_with = ["1", "3"]` | ends with one of them |
//! | `bits_set = [2]` | read as a number (in its field's base), has every bit set |
//! | `bits_clear = [3]` | … has every bit clear |

use serde::Deserialize;

use super::template::{Captures, FieldKind, Template};

/// One condition (module docs).
#[derive(Debug, Clone, PartialEq, Eq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct Condition {
    /// The field it tests.
    pub field: String,
    /// The field is one of these.
    #[serde(default)]
    pub equals: Vec<String>,
    /// The field is none of these.
    #[serde(default)]
    pub not_equals: Vec<String>,
    /// The field ends with one of these.
    #[serde(default)]
    pub ends_with: Vec<String>,
    /// Bits (0 = least significant) that must be set.
    #[serde(default)]
    pub bits_set: Vec<u32>,
    /// Bits that must be clear.
    #[serde(default)]
    pub bits_clear: Vec<u32>,
}

/// Why a condition cannot stand on its reply's template (a profile's refusal, located
/// by its reader).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub(crate) enum ConditionError {
    /// The template has no field of the condition's name.
    #[error("the reply `{reply}` has no field `{field}` (its fields: {fields})")]
    NoSuchField {
        /// The reply's template, as written.
        reply: String,
        /// The field the condition names.
        field: String,
        /// The template's fields, or `none`.
        fields: String,
    },
    /// The condition gives no test.
    #[error(
        "the condition on `{field}` tests nothing: give equals, not_equals, ends_with, bits_set or bits_clear"
    )]
    TestsNothing {
        /// The field the condition names.
        field: String,
    },
    /// A bit test on a field that is not digits.
    #[error("bits of `{field}` cannot be tested: it is not a digit field (d or x)")]
    BitsOfText {
        /// The field the condition names.
        field: String,
    },
    /// A bit beyond 63.
    #[error("bit {bit} of `{field}`: bits are 0 … 63")]
    BitOutOfRange {
        /// The bit.
        bit: u32,
        /// The field the condition names.
        field: String,
    },
}

impl Condition {
    /// Checks the condition against its reply's template: the field exists, at least one
    /// test is given, bit tests only on digit fields. The message says what is wrong.
    pub(crate) fn check(&self, template: &Template) -> Result<(), ConditionError> {
        let Some(field) = template.field(&self.field) else {
            let names: Vec<&str> = template.fields().map(|f| f.name.as_str()).collect();
            return Err(ConditionError::NoSuchField {
                reply: template.to_string(),
                field: self.field.clone(),
                fields: if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                },
            });
        };
        if self.equals.is_empty()
            && self.not_equals.is_empty()
            && self.ends_with.is_empty()
            && self.bits_set.is_empty()
            && self.bits_clear.is_empty()
        {
            return Err(ConditionError::TestsNothing {
                field: self.field.clone(),
            });
        }
        if (!self.bits_set.is_empty() || !self.bits_clear.is_empty())
            && field.kind.radix().is_none()
        {
            return Err(ConditionError::BitsOfText {
                field: self.field.clone(),
            });
        }
        if let Some(&bit) = self
            .bits_set
            .iter()
            .chain(&self.bits_clear)
            .find(|&&b| b > 63)
        {
            return Err(ConditionError::BitOutOfRange {
                bit,
                field: self.field.clone(),
            });
        }
        Ok(())
    }

    /// Whether the condition holds for a reply's fields. A field the reply does not have,
    /// or digits that do not read as a number for a bit test, do not hold.
    pub fn holds(&self, template: &Template, captures: &Captures) -> bool {
        let Some(value) = captures.get(&self.field) else {
            return false;
        };
        let same = |a: &str, b: &str| a.eq_ignore_ascii_case(b);
        if !self.equals.is_empty() && !self.equals.iter().any(|e| same(e, value)) {
            return false;
        }
        if self.not_equals.iter().any(|e| same(e, value)) {
            return false;
        }
        if !self.ends_with.is_empty()
            && !self
                .ends_with
                .iter()
                .any(|e| value.len() >= e.len() && same(&value[value.len() - e.len()..], e))
        {
            return false;
        }
        if self.bits_set.is_empty() && self.bits_clear.is_empty() {
            return true;
        }
        let radix = template
            .field(&self.field)
            .and_then(|f| f.kind.radix())
            .unwrap_or(10);
        let digits = value.strip_prefix('+').unwrap_or(value);
        // A negative decimal is a signed register printed as such (Aerotech's AXISSTATUS
        // can read `%-1675099646`): its bits are its two's complement.
        let Ok(number) = i64::from_str_radix(digits, radix)
            .map(|n| n as u64)
            .or_else(|_| u64::from_str_radix(digits, radix))
        else {
            return false;
        };
        self.bits_set.iter().all(|&b| number & (1 << b) != 0)
            && self.bits_clear.iter().all(|&b| number & (1 << b) == 0)
    }

    /// A value of the field that satisfies this condition and every one of `also` (all on
    /// the same field) and none of `not`, for the simulated lab to send; `None` when none
    /// is found among the candidates tried.
    pub fn example(
        template: &Template,
        field: &str,
        all: &[&Condition],
        not: &[&Condition],
    ) -> Option<String> {
        let f = template.field(field)?;
        let width = f.width;
        let pad = |s: String| match width {
            Some(w) if s.len() < w => format!("{}{s}", "0".repeat(w - s.len())),
            _ => s,
        };
        let mut candidates: Vec<String> = Vec::new();
        for c in all.iter().chain(not) {
            candidates.extend(c.equals.iter().cloned());
            candidates.extend(c.ends_with.iter().map(|e| pad(e.clone())));
        }
        let limit: u64 = match f.kind {
            FieldKind::Hex => 1 << 16,
            _ => 100_000,
        };
        let radix = f.kind.radix();
        let from_bits = {
            let mut n = 0u64;
            for c in all {
                for &b in &c.bits_set {
                    n |= 1 << b;
                }
            }
            n
        };
        let numbered = |n: u64| match radix {
            Some(16) => pad(format!("{n:X}")),
            _ => pad(n.to_string()),
        };
        candidates.push(numbered(from_bits));
        let holds_one = |c: &Condition, v: &str| {
            let captures = Captures::single(&c.field, v);
            c.holds(template, &captures)
        };
        let fits = |v: &str| {
            width.is_none_or(|w| v.chars().count() == w)
                && template_field_valid(template, field, v)
                && all.iter().all(|c| holds_one(c, v))
                && !not.iter().any(|c| holds_one(c, v))
        };
        if let Some(found) = candidates.iter().find(|v| fits(v)) {
            return Some(found.clone());
        }
        if matches!(
            f.kind,
            FieldKind::Decimal | FieldKind::Hex | FieldKind::Float
        ) {
            let top = width.map_or(limit, |w| {
                (radix.unwrap_or(10) as u64)
                    .saturating_pow(w as u32)
                    .min(limit)
            });
            return (0..top).map(numbered).find(|v| fits(v));
        }
        ["A", "@", "x", "X", "0"]
            .iter()
            .map(|s| s.to_string())
            .find(|v| fits(v))
    }
}

/// Whether `value` is a whole value of the template's field `name`.
fn template_field_valid(template: &Template, name: &str, value: &str) -> bool {
    let Some(field) = template.field(name) else {
        return false;
    };
    // Render the template with this value and placeholders elsewhere, then read it back.
    let probe = Template::parse(&format!(
        "{{{}:{}{}}}",
        field.name,
        field.kind.letter(),
        field.width.map(|w| w.to_string()).unwrap_or_default()
    ));
    probe.is_ok_and(|t| t.matches(value).is_some_and(|c| c.get(name) == Some(value)))
}

impl Captures {
    /// Captures of one field (for testing a condition on a value alone).
    pub(crate) fn single(name: &str, value: &str) -> Captures {
        Captures::from_pairs(vec![(name.to_string(), value.to_string())])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cond(toml_text: &str) -> Condition {
        toml::from_str(toml_text).unwrap()
    }

    #[test]
    fn smc100_states() {
        let t = Template::parse("1TS{errors:x4}{state:x2}").unwrap();
        let ready = cond("field = \"state\"\nequals = [\"32\", \"33\", \"34\"]");
        let fault = cond("field = \"errors\"\nnot_equals = [\"0000\"]");
        let c = t.matches("1TS000033").unwrap();
        assert!(ready.holds(&t, &c) && !fault.holds(&t, &c));
        let c = t.matches("1TS000128").unwrap();
        assert!(!ready.holds(&t, &c) && fault.holds(&t, &c));
        assert_eq!(
            Condition::example(&t, "state", &[&ready], &[]).as_deref(),
            Some("32")
        );
        assert_eq!(
            Condition::example(&t, "errors", &[], &[&fault]).as_deref(),
            Some("0000")
        );
        assert_eq!(
            Condition::example(&t, "errors", &[&fault], &[]).as_deref(),
            Some("0001")
        );
    }

    #[test]
    fn bits_and_endings() {
        let t = Template::parse("%{status:d}").unwrap();
        let done = cond("field = \"status\"\nbits_set = [2]\nbits_clear = [3]");
        assert!(done.holds(&t, &t.matches("%7").unwrap())); // 0b0111
        assert!(!done.holds(&t, &t.matches("%15").unwrap())); // bit 3 set
        assert!(!done.holds(&t, &t.matches("%3").unwrap())); // bit 2 clear
        assert_eq!(
            Condition::example(&t, "status", &[&done], &[]).as_deref(),
            Some("4")
        );
        let t = Template::parse("4 {status:d3} {x:f} {y:f}").unwrap();
        let x_valid = cond("field = \"status\"\nends_with = [\"1\", \"3\"]");
        assert!(x_valid.holds(&t, &t.matches("4 003 1 2").unwrap()));
        assert!(!x_valid.holds(&t, &t.matches("4 002 1 2").unwrap()));
        assert_eq!(
            Condition::example(&t, "status", &[&x_valid], &[]).as_deref(),
            Some("001")
        );
        assert_eq!(
            Condition::example(&t, "status", &[], &[&x_valid]).as_deref(),
            Some("000")
        );
    }

    #[test]
    fn checked_against_the_template() {
        let t = Template::parse("{v:f}").unwrap();
        assert!(
            cond("field = \"w\"\nequals = [\"1\"]")
                .check(&t)
                .unwrap_err()
                .to_string()
                .contains("no field `w`")
        );
        assert!(
            cond("field = \"v\"\nbits_set = [1]")
                .check(&t)
                .unwrap_err()
                .to_string()
                .contains("not a digit field")
        );
        assert!(
            cond("field = \"v\"")
                .check(&t)
                .unwrap_err()
                .to_string()
                .contains("tests nothing")
        );
    }
}
