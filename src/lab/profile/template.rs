//! Reply and command templates: one description of a line, read in both directions — a
//! driver matches a device's reply against it and takes its fields, the simulated lab
//! writes a reply from it.
//!
//! A template is literal text with fields `{name:kind}` or `{name:kindW}` (W a fixed
//! width in characters):
//!
//! | kind | matches |
//! |---|---|
//! | `f` | a decimal number: optional sign, digits with an optional point, optional exponent |
//! | `d` | decimal digits (with an optional sign when no width is given) |
//! | `x` | hexadecimal digits |
//! | `c` | one character |
//! | `w` | a word: a letter, then letters, digits or `_` |
//! | `s` | any text, at least one character |
//!
//! A space in a template matches one or more spaces or tabs; the reply is trimmed before
//! it is matched. `{{` and `}}` are literal braces. Two fields of variable width may not
//! touch (which characters belong to which could not be told).

use std::fmt;

/// What a field matches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldKind {
    /// A decimal number (`f`).
    Float,
    /// Decimal digits (`d`).
    Decimal,
    /// Hexadecimal digits (`x`).
    Hex,
    /// One character (`c`).
    Char,
    /// A word: a letter, then letters, digits or `_` (`w`).
    Word,
    /// Any text, at least one character (`s`).
    Text,
}

impl FieldKind {
    fn from_letter(letter: char) -> Option<FieldKind> {
        Some(match letter {
            'f' => FieldKind::Float,
            'd' => FieldKind::Decimal,
            'x' => FieldKind::Hex,
            'c' => FieldKind::Char,
            'w' => FieldKind::Word,
            's' => FieldKind::Text,
            _ => return None,
        })
    }

    /// The letter of the kind in a template.
    pub fn letter(self) -> char {
        match self {
            FieldKind::Float => 'f',
            FieldKind::Decimal => 'd',
            FieldKind::Hex => 'x',
            FieldKind::Char => 'c',
            FieldKind::Word => 'w',
            FieldKind::Text => 's',
        }
    }

    /// The radix of a digit field (10 or 16), `None` for the others.
    pub fn radix(self) -> Option<u32> {
        match self {
            FieldKind::Decimal => Some(10),
            FieldKind::Hex => Some(16),
            _ => None,
        }
    }
}

/// One field of a template.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    /// Its name, e.g. `x` or `state`.
    pub name: String,
    /// What it matches.
    pub kind: FieldKind,
    /// Its fixed width in characters, if any.
    pub width: Option<usize>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Token {
    Literal(String),
    Space,
    Field(Field),
}

/// A template that could not be read: what is wrong, and where in the template (a
/// character offset).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{problem}")]
pub struct TemplateError {
    /// 0-based character offset in the template.
    pub offset: usize,
    /// What is wrong.
    pub problem: TemplateProblem,
}

/// What is wrong with a template ([`TemplateError`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TemplateProblem {
    /// A `}` that closes no field.
    #[error("a `}}` without its `{{` (write `}}}}` for a brace)")]
    UnmatchedClose,
    /// A `{` that is never closed.
    #[error("a `{{` without its `}}`")]
    Unclosed,
    /// A field without `:kind`.
    #[error(
        "the field `{{{inside}}}` has no kind: write `{{name:kind}}` with kind f, d, x, c, w or s"
    )]
    NoKind {
        /// What the braces hold.
        inside: String,
    },
    /// A field name that is empty or not letters, digits and `_`.
    #[error("the field `{{{inside}}}`: a name is letters, digits and `_`")]
    BadName {
        /// What the braces hold.
        inside: String,
    },
    /// A kind that is not one of the letters of [`FieldKind`].
    #[error(
        "the field `{{{inside}}}`: the kind is f (number), d (decimal digits), x (hex digits), c (one character), w (a word) or s (text)"
    )]
    BadKind {
        /// What the braces hold.
        inside: String,
    },
    /// A width that is not a whole number ≥ 1.
    #[error("the field `{{{inside}}}`: a width is a whole number from 1")]
    BadWidth {
        /// What the braces hold.
        inside: String,
    },
    /// Two fields of one name.
    #[error("the field `{name}` is named twice")]
    NamedTwice {
        /// The name.
        name: String,
    },
    /// Two fields of variable width next to each other.
    #[error(
        "the fields `{before}` and `{field}` touch: put a literal or a space between them, or give one a width"
    )]
    FieldsTouch {
        /// The first field's name.
        before: String,
        /// The second field's name.
        field: String,
    },
    /// Nothing but spaces.
    #[error("the template is empty")]
    Empty,
}

/// A line template (module docs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Template {
    text: String,
    tokens: Vec<Token>,
}

/// The fields a reply gave, by name, in the order of the template.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Captures(Vec<(String, String)>);

impl Captures {
    /// Captures from (name, value) pairs.
    pub(crate) fn from_pairs(pairs: Vec<(String, String)>) -> Captures {
        Captures(pairs)
    }

    /// The text of a field, if the template has it.
    pub fn get(&self, name: &str) -> Option<&str> {
        self.0
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// A field as a finite number (for `f`, `d` and `x` fields; `x` read in base 16).
    pub fn number(&self, name: &str) -> Option<f64> {
        let text = self.get(name)?;
        let value = text.parse::<f64>().ok()?;
        value.is_finite().then_some(value)
    }
}

impl Template {
    /// Reads a template.
    ///
    /// ```
    /// use polycal::lab::profile::Template;
    /// let t = Template::parse("1TS{errors:x4}{state:x2}").unwrap();
    /// let c = t.matches("1TS000033").unwrap();
    /// assert_eq!((c.get("errors"), c.get("state")), (Some("0000"), Some("33")));
    /// assert!(t.matches("1TS00003").is_none());
    /// ```
    ///
    /// # Errors
    ///
    /// A [`TemplateError`] at the offending character: an unclosed or unmatched brace, a
    /// field without a name, an unknown kind, a zero width, a name used twice, or two
    /// fields of variable width touching.
    pub fn parse(text: &str) -> Result<Template, TemplateError> {
        let chars: Vec<char> = text.chars().collect();
        let mut tokens = Vec::new();
        let mut literal = String::new();
        let mut i = 0;
        let error = |offset: usize, problem: TemplateProblem| TemplateError { offset, problem };
        let flush = |literal: &mut String, tokens: &mut Vec<Token>| {
            if !literal.is_empty() {
                tokens.push(Token::Literal(std::mem::take(literal)));
            }
        };
        while i < chars.len() {
            let c = chars[i];
            match c {
                '{' if chars.get(i + 1) == Some(&'{') => {
                    literal.push('{');
                    i += 2;
                }
                '}' if chars.get(i + 1) == Some(&'}') => {
                    literal.push('}');
                    i += 2;
                }
                '}' => {
                    return Err(error(i, TemplateProblem::UnmatchedClose));
                }
                '{' => {
                    let Some(close) = chars[i..].iter().position(|&c| c == '}') else {
                        return Err(error(i, TemplateProblem::Unclosed));
                    };
                    let inside: String = chars[i + 1..i + close].iter().collect();
                    let field = parse_field(&inside).map_err(|m| error(i, m))?;
                    if tokens
                        .iter()
                        .any(|t| matches!(t, Token::Field(f) if f.name == field.name))
                    {
                        return Err(error(
                            i,
                            TemplateProblem::NamedTwice {
                                name: field.name.clone(),
                            },
                        ));
                    }
                    flush(&mut literal, &mut tokens);
                    if field.width.is_none()
                        && field.kind != FieldKind::Char
                        && let Some(Token::Field(before)) = tokens.last()
                        && before.width.is_none()
                        && before.kind != FieldKind::Char
                    {
                        return Err(error(
                            i,
                            TemplateProblem::FieldsTouch {
                                before: before.name.clone(),
                                field: field.name.clone(),
                            },
                        ));
                    }
                    tokens.push(Token::Field(field));
                    i += close + 1;
                }
                ' ' | '\t' => {
                    flush(&mut literal, &mut tokens);
                    if !matches!(tokens.last(), Some(Token::Space)) {
                        tokens.push(Token::Space);
                    }
                    i += 1;
                }
                _ => {
                    literal.push(c);
                    i += 1;
                }
            }
        }
        flush(&mut literal, &mut tokens);
        // Leading and trailing spaces: a reply is trimmed before it is matched.
        while matches!(tokens.first(), Some(Token::Space)) {
            tokens.remove(0);
        }
        while matches!(tokens.last(), Some(Token::Space)) {
            tokens.pop();
        }
        if tokens.is_empty() {
            return Err(error(0, TemplateProblem::Empty));
        }
        Ok(Template {
            text: text.to_string(),
            tokens,
        })
    }

    /// The template as written.
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// Its fields, in order.
    pub fn fields(&self) -> impl Iterator<Item = &Field> {
        self.tokens.iter().filter_map(|t| match t {
            Token::Field(f) => Some(f),
            _ => None,
        })
    }

    /// The field named `name`, if the template has it.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields().find(|f| f.name == name)
    }

    /// Matches a whole line (trimmed first); the fields it gave, or `None`.
    pub fn matches(&self, line: &str) -> Option<Captures> {
        let chars: Vec<char> = line.trim().chars().collect();
        let mut captures = Vec::new();
        match_from(&self.tokens, &chars, 0, &mut captures).then_some(Captures(captures))
    }

    /// Writes a line from field values (`value(name)` for each field); a missing value is
    /// written as an empty field. Spaces are written as one space.
    pub fn render(&self, value: &dyn Fn(&Field) -> String) -> String {
        let mut out = String::new();
        for token in &self.tokens {
            match token {
                Token::Literal(text) => out.push_str(text),
                Token::Space => out.push(' '),
                Token::Field(field) => out.push_str(&value(field)),
            }
        }
        out
    }
}

impl fmt::Display for Template {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text)
    }
}

/// `name:kindW` → a field.
fn parse_field(inside: &str) -> Result<Field, TemplateProblem> {
    let Some((name, spec)) = inside.split_once(':') else {
        return Err(TemplateProblem::NoKind {
            inside: inside.to_string(),
        });
    };
    let name = name.trim();
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(TemplateProblem::BadName {
            inside: inside.to_string(),
        });
    }
    let mut spec_chars = spec.trim().chars();
    let Some(kind) = spec_chars.next().and_then(FieldKind::from_letter) else {
        return Err(TemplateProblem::BadKind {
            inside: inside.to_string(),
        });
    };
    let width_text: String = spec_chars.collect();
    let width = if width_text.is_empty() {
        None
    } else {
        match width_text.parse::<usize>() {
            Ok(0) | Err(_) => {
                return Err(TemplateProblem::BadWidth {
                    inside: inside.to_string(),
                });
            }
            Ok(w) => Some(w),
        }
    };
    Ok(Field {
        name: name.to_string(),
        kind,
        width: if kind == FieldKind::Char {
            Some(1)
        } else {
            width
        },
    })
}

fn accepts(kind: FieldKind, c: char) -> bool {
    match kind {
        FieldKind::Float => c.is_ascii_digit() || matches!(c, '+' | '-' | '.' | 'e' | 'E'),
        FieldKind::Decimal => c.is_ascii_digit() || matches!(c, '+' | '-'),
        FieldKind::Hex => c.is_ascii_hexdigit(),
        FieldKind::Word => c.is_ascii_alphanumeric() || c == '_',
        FieldKind::Char | FieldKind::Text => true,
    }
}

/// Whether `text` is a whole value of `field`.
fn valid(field: &Field, text: &str) -> bool {
    if let Some(w) = field.width
        && text.chars().count() != w
    {
        return false;
    }
    match field.kind {
        FieldKind::Float => is_decimal_number(text),
        FieldKind::Decimal => {
            let digits = match field.width {
                Some(_) => text,
                None => text.strip_prefix(['+', '-']).unwrap_or(text),
            };
            !digits.is_empty() && digits.chars().all(|c| c.is_ascii_digit())
        }
        FieldKind::Hex => !text.is_empty() && text.chars().all(|c| c.is_ascii_hexdigit()),
        FieldKind::Char => text.chars().count() == 1,
        FieldKind::Word => text.chars().next().is_some_and(|c| c.is_ascii_alphabetic()),
        FieldKind::Text => !text.is_empty(),
    }
}

/// `[+-]? (digits [. digits?] | . digits) ([eE] [+-]? digits)?`, finite.
fn is_decimal_number(text: &str) -> bool {
    let body = text.strip_prefix(['+', '-']).unwrap_or(text);
    let (mantissa, exponent) = match body.find(['e', 'E']) {
        Some(i) => (&body[..i], Some(&body[i + 1..])),
        None => (body, None),
    };
    let (whole, fraction) = match mantissa.split_once('.') {
        Some((w, f)) => (w, Some(f)),
        None => (mantissa, None),
    };
    let digits = |s: &str| s.chars().all(|c| c.is_ascii_digit());
    let mantissa_ok = digits(whole)
        && fraction.is_none_or(digits)
        && (!whole.is_empty() || fraction.is_some_and(|f| !f.is_empty()));
    let exponent_ok = exponent.is_none_or(|e| {
        let e = e.strip_prefix(['+', '-']).unwrap_or(e);
        !e.is_empty() && digits(e)
    });
    mantissa_ok && exponent_ok && text.parse::<f64>().is_ok_and(f64::is_finite)
}

fn match_from(
    tokens: &[Token],
    text: &[char],
    at: usize,
    captures: &mut Vec<(String, String)>,
) -> bool {
    let Some((token, rest)) = tokens.split_first() else {
        return at == text.len();
    };
    match token {
        Token::Literal(literal) => {
            let literal: Vec<char> = literal.chars().collect();
            text.get(at..at + literal.len()) == Some(&literal[..])
                && match_from(rest, text, at + literal.len(), captures)
        }
        Token::Space => {
            let run = text[at..]
                .iter()
                .take_while(|c| **c == ' ' || **c == '\t')
                .count();
            run > 0 && match_from(rest, text, at + run, captures)
        }
        Token::Field(field) => {
            let run = text[at..]
                .iter()
                .take_while(|c| accepts(field.kind, **c))
                .count();
            // Only lengths after which the rest of the template can start: a reply line
            // is at most a few hundred characters, and mutated input must not make the
            // search quadratic in every field.
            let can_follow = |end: usize| match rest.first() {
                None => end == text.len(),
                Some(Token::Literal(l)) => {
                    l.chars().next().is_some_and(|c| text.get(end) == Some(&c))
                }
                Some(Token::Space) => matches!(text.get(end), Some(' ' | '\t')),
                Some(Token::Field(next)) => text.get(end).is_some_and(|c| accepts(next.kind, *c)),
            };
            let lengths: Vec<usize> = match field.width {
                Some(w) if w <= run => vec![w],
                Some(_) => Vec::new(),
                None => (1..=run).rev().filter(|&l| can_follow(at + l)).collect(),
            };
            for length in lengths {
                let value: String = text[at..at + length].iter().collect();
                if !valid(field, &value) {
                    continue;
                }
                captures.push((field.name.clone(), value));
                if match_from(rest, text, at + length, captures) {
                    return true;
                }
                captures.pop();
            }
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elcomat_measurement() {
        let t = Template::parse("4 {status:d3} {x:f} {y:f}").unwrap();
        let c = t.matches("4 003 12.345000 -1.234000").unwrap();
        assert_eq!(c.get("status"), Some("003"));
        assert_eq!(c.number("x"), Some(12.345));
        assert_eq!(c.number("y"), Some(-1.234));
        assert!(t.matches("4  003\t1  2").is_some(), "runs of blanks");
        assert!(t.matches("4 03 1 2").is_none(), "width");
        assert!(t.matches("4 003 1 2 3").is_none(), "extra field");
        assert!(t.matches("2 003 1 2").is_none(), "literal");
        assert!(t.matches("4 003 nan 2").is_none());
        assert!(t.matches("4 003 1e999 2").is_none(), "not finite");
        assert!(t.matches("4 003 1.2.3 2").is_none());
    }

    #[test]
    fn fields_after_literals_and_text() {
        let t = Template::parse("{axis:d}={deg:f}").unwrap();
        let c = t.matches("1=-45.25").unwrap();
        assert_eq!((c.get("axis"), c.number("deg")), (Some("1"), Some(-45.25)));
        let t = Template::parse("(c){text:s}").unwrap();
        assert_eq!(
            t.matches("(c)2015 Physik Instrumente").unwrap().get("text"),
            Some("2015 Physik Instrumente")
        );
        let t = Template::parse("%{v:s}").unwrap();
        assert!(t.matches("%").is_none(), "s takes at least one character");
        let t = Template::parse("1TE{code:c}").unwrap();
        assert_eq!(t.matches("1TE@").unwrap().get("code"), Some("@"));
        assert!(t.matches("1TE@@").is_none());
    }

    #[test]
    fn refused_templates_say_where() {
        let e = Template::parse("1TS{a:x}{b:x}").unwrap_err();
        assert_eq!(e.offset, 8);
        assert!(
            matches!(e.problem, TemplateProblem::FieldsTouch { .. }),
            "{e}"
        );
        assert_eq!(
            e.to_string(),
            "the fields `a` and `b` touch: put a literal or a space between them, or give one a width"
        );
        assert_eq!(
            Template::parse("ab}").unwrap_err().to_string(),
            "a `}` without its `{` (write `}}` for a brace)"
        );
        assert_eq!(
            Template::parse("{x}").unwrap_err().to_string(),
            "the field `{x}` has no kind: write `{name:kind}` with kind f, d, x, c, w or s"
        );
        assert_eq!(Template::parse("a{x:q}").unwrap_err().offset, 1);
        assert_eq!(Template::parse("a{x:f").unwrap_err().offset, 1);
        assert_eq!(Template::parse("ab}").unwrap_err().offset, 2);
        assert!(Template::parse("{x:f} {x:f}").is_err());
        assert!(Template::parse("{x:d0}").is_err());
        assert!(Template::parse("   ").is_err());
        assert!(Template::parse("{{x}}").unwrap().matches("{x}").is_some());
    }

    #[test]
    fn render_writes_what_matches() {
        let t = Template::parse("1TS{errors:x4}{state:x2}").unwrap();
        let line = t.render(&|f| {
            if f.name == "errors" {
                "0000".into()
            } else {
                "33".into()
            }
        });
        assert_eq!(line, "1TS000033");
        assert!(t.matches(&line).is_some());
    }
}
