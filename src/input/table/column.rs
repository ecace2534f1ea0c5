//! The description of a table's columns, and what one field of a column may hold: the
//! number rules every CSV reader of the crate applies (integers within bounds, finite
//! numbers within a [`Limit`], words from a list) with their messages.

use crate::input::limits::{Limit, LimitError};

/// One column of a table as a file kind describes it: its name in the header, whether
/// the header must have it, what its fields hold, and what an empty field (or the
/// column's absence) means.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Column {
    /// The exact name in the header (lower case, no spaces).
    pub(crate) name: &'static str,
    /// Whether the header must name it; a required column's fields may not be empty.
    pub(crate) required: bool,
    /// What a field holds.
    pub(crate) kind: Kind,
    /// The value of an optional column's empty field, and of every row when the header
    /// does not name the column; `None`: not recorded.
    pub(crate) default: Option<Value>,
}

/// What the fields of a column hold.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Kind {
    /// A decimal integer `min ..= max` (an optional sign; `-0` is 0, nothing else).
    Integer {
        /// The smallest value allowed.
        min: u128,
        /// The largest value allowed.
        max: u128,
    },
    /// A finite number, within a range.
    Number(Range),
    /// One of a few words, written exactly; the value is the word's index.
    Word {
        /// The words, e.g. `["cw", "ccw"]`.
        words: &'static [&'static str],
        /// What a word is, for messages: `a direction`.
        what: &'static str,
    },
}

/// Which finite numbers a number column allows.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Range {
    /// Those within a limit of docs/FORMAT.md §2.2, and what the values are (`a reading`).
    Limit(Limit, &'static str),
    /// Those a rule of the file kind allows; `broken` follows the quoted field in the
    /// message of one it refuses (`is outside 0 to 360 degrees; …`).
    Within {
        /// Whether a finite number is allowed.
        contains: fn(f64) -> bool,
        /// What a refused number breaks.
        broken: &'static str,
    },
}

/// A field's value, as its column's [`Kind`] reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Value {
    /// An integer column's value.
    Integer(u128),
    /// A number column's value.
    Number(f64),
    /// The index of a word column's word.
    Word(usize),
}

impl Column {
    /// A required integer column, `min ..= max`.
    pub(crate) const fn integer(name: &'static str, min: u128, max: u128) -> Column {
        Column {
            name,
            required: true,
            kind: Kind::Integer { min, max },
            default: None,
        }
    }

    /// A required number column.
    pub(crate) const fn number(name: &'static str, range: Range) -> Column {
        Column {
            name,
            required: true,
            kind: Kind::Number(range),
            default: None,
        }
    }

    /// A required column of words; `what` names a word in messages (`a direction`).
    pub(crate) const fn word(
        name: &'static str,
        words: &'static [&'static str],
        what: &'static str,
    ) -> Column {
        Column {
            name,
            required: true,
            kind: Kind::Word { words, what },
            default: None,
        }
    }

    /// The column made optional: an empty field (or no such column) is not recorded.
    pub(crate) const fn optional(self) -> Column {
        Column {
            required: false,
            default: None,
            ..self
        }
    }

    /// The column made optional: an empty field (or no such column) means `default`.
    pub(crate) const fn or(self, default: Value) -> Column {
        Column {
            required: false,
            default: Some(default),
            ..self
        }
    }

    /// The range of a number column within a limit, and what its values are; `None` for
    /// other columns.
    pub(crate) fn limit(&self) -> Option<(Limit, &'static str)> {
        match self.kind {
            Kind::Number(Range::Limit(limit, what)) => Some((limit, what)),
            _ => None,
        }
    }

    /// Reads one field of the column: its value (`None` for an empty field not
    /// recorded), or why it is refused.
    pub(crate) fn value(&self, text: &str) -> Result<Option<Value>, FieldError> {
        if text.is_empty() && !self.required {
            return Ok(self.default);
        }
        let value = match self.kind {
            Kind::Integer { min, max } => parse_int(text, self.name, min, max).map(Value::Integer),
            Kind::Number(range) => parse_float(text, self.name, range).map(Value::Number),
            Kind::Word { words, what } => match words.iter().position(|w| *w == text) {
                Some(i) => Ok(Value::Word(i)),
                None => Err(FieldError::NotAWord {
                    column: self.name,
                    text: text.to_string(),
                    what,
                    words,
                }),
            },
        };
        value.map(Some)
    }
}

/// Why a field of a column is refused; the message names the column and quotes the text
/// ([`show`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub(crate) enum FieldError {
    /// An empty field of a required integer column.
    #[error("column {column:?}: empty; an integer of at least {min} is required")]
    EmptyInteger {
        /// The column.
        column: &'static str,
        /// The smallest value allowed.
        min: u128,
    },
    /// Text that is not a decimal integer.
    #[error("column {column:?}: {} is not an integer", show(text))]
    NotAnInteger {
        /// The column.
        column: &'static str,
        /// The field's text.
        text: String,
    },
    /// An integer below the column's smallest value (a negative one included).
    #[error(
        "column {column:?}: {} is not allowed; {column} must be at least {min}",
        show(text)
    )]
    BelowMin {
        /// The column.
        column: &'static str,
        /// The field's text.
        text: String,
        /// The smallest value allowed.
        min: u128,
    },
    /// An integer above the column's largest value.
    #[error(
        "column {column:?}: {} is too large; {column} must be at most {max}",
        show(text)
    )]
    AboveMax {
        /// The column.
        column: &'static str,
        /// The field's text.
        text: String,
        /// The largest value allowed.
        max: u128,
    },
    /// An empty field of a required number column.
    #[error("column {column:?}: empty; a number is required")]
    EmptyNumber {
        /// The column.
        column: &'static str,
    },
    /// Text that is not a number.
    #[error("column {column:?}: {} is not a number", show(text))]
    NotANumber {
        /// The column.
        column: &'static str,
        /// The field's text.
        text: String,
    },
    /// A number that is not finite.
    #[error("column {column:?}: {} is not a finite number", show(text))]
    NotFinite {
        /// The column.
        column: &'static str,
        /// The field's text.
        text: String,
    },
    /// A number beyond the column's limit (docs/FORMAT.md §2.2).
    #[error("column {column:?}: {rule}")]
    BeyondLimit {
        /// The column.
        column: &'static str,
        /// The limit it breaks.
        rule: LimitError,
    },
    /// A number that breaks the column's rule.
    #[error("column {column:?}: {} {broken}", show(text))]
    OutsideRange {
        /// The column.
        column: &'static str,
        /// The field's text.
        text: String,
        /// What it breaks ([`Range::Within`]).
        broken: &'static str,
    },
    /// Text that is not one of the column's words.
    #[error(
        "column {column:?}: {} is not {what}; use {}",
        show(text),
        choices(words)
    )]
    NotAWord {
        /// The column.
        column: &'static str,
        /// The field's text.
        text: String,
        /// What a word is: `a direction`.
        what: &'static str,
        /// The words allowed.
        words: &'static [&'static str],
    },
}

/// The words of a word column, quoted, joined by `or`.
fn choices(words: &[&str]) -> String {
    let quoted: Vec<String> = words.iter().map(|w| format!("{w:?}")).collect();
    quoted.join(" or ")
}

/// The offending text for a message: quoted and escaped, cut after 40 characters.
pub(crate) fn show(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{:?}...", text.get(..cut).unwrap_or(text)),
        None => format!("{text:?}"),
    }
}

/// `1 field`, `2 fields`.
pub(crate) fn count(n: usize, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{n} {what}s")
    }
}

/// Parses an integer field `min ..= max`: decimal digits with an optional sign (`-0` is
/// 0), nothing else.
fn parse_int(text: &str, column: &'static str, min: u128, max: u128) -> Result<u128, FieldError> {
    if text.is_empty() {
        return Err(FieldError::EmptyInteger { column, min });
    }
    let digits = text.strip_prefix(['+', '-']).unwrap_or(text);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(FieldError::NotAnInteger {
            column,
            text: text.to_string(),
        });
    }
    let below = || FieldError::BelowMin {
        column,
        text: text.to_string(),
        min,
    };
    let negative = text.starts_with('-');
    match digits.parse::<u128>() {
        Ok(0) if negative && min == 0 => Ok(0),
        Ok(_) if negative => Err(below()),
        Ok(x) if x < min => Err(below()),
        Ok(x) if x <= max => Ok(x),
        _ => Err(FieldError::AboveMax {
            column,
            text: text.to_string(),
            max,
        }),
    }
}

/// Parses a finite number field within its range.
fn parse_float(text: &str, column: &'static str, range: Range) -> Result<f64, FieldError> {
    if text.is_empty() {
        return Err(FieldError::EmptyNumber { column });
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => match range {
            // the text is shown only for a refusal (most fields pass)
            Range::Limit(limit, _) if limit.contains(x) => Ok(x),
            Range::Limit(limit, what) => limit
                .check_shown(x, &show(text), what)
                .map_err(|rule| FieldError::BeyondLimit { column, rule }),
            Range::Within { contains, broken } => {
                if contains(x) {
                    Ok(x)
                } else {
                    Err(FieldError::OutsideRange {
                        column,
                        text: text.to_string(),
                        broken,
                    })
                }
            }
        },
        Ok(_) => Err(FieldError::NotFinite {
            column,
            text: text.to_string(),
        }),
        Err(_) => Err(FieldError::NotANumber {
            column,
            text: text.to_string(),
        }),
    }
}
