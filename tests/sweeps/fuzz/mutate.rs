//! Mutations of valid seed files, as proptest strategies.
//!
//! A case is a seed (one of the bundled example or test files) and one to four mutations
//! applied in turn: byte flips, insertions, deletions, truncation, duplicated, deleted or
//! swapped lines and fields, a field replaced by an extreme value, line ends changed and
//! a byte-order mark put in front. A *line* ends after `\n`; a *field* is a run of bytes
//! between separators (`,`, `=`, `:`, spaces, quotes, brackets and braces), so that the
//! same mutations reach the values of a CSV row, a TOML key or value and a JSON number.
//! Proptest shrinks a failing case to fewer and simpler mutations.

#![allow(dead_code)]

use std::fmt;

use proptest::prelude::*;
use proptest::sample::Index;

#[path = "seeds.rs"]
mod seed_files;
pub use seed_files::{Seed, seed, seeds};

/// Values a field is replaced by: extreme and non-finite numbers, integers too large for
/// any integer type, signed zero, the empty field, very long text, bytes that are not
/// UTF-8, line breaks, a byte-order mark and CSV or TOML syntax.
pub fn extremes() -> Vec<Vec<u8>> {
    let mut v: Vec<Vec<u8>> = [
        "1e300",
        "-1e308",
        "1e-320",
        "NaN",
        "nan",
        "inf",
        "-inf",
        "infinity",
        "1e309",
        "18446744073709551616",
        "4294967296",
        "9223372036854775808",
        "-9223372036854775809",
        "-0",
        "0",
        "-1",
        "+1",
        "",
        "0x10",
        "1_000",
        " 1",
        "\"\"",
        "\"a,b\"",
        "#",
        ",",
        "\r",
        "\n",
        "\r\n",
        "\u{feff}",
        "\u{feff}1",
        "é",
        "\u{1F600}",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    v.push(vec![0xff]);
    v.push(vec![0xc3, 0x28]);
    v.push(vec![0xed, 0xa0, 0x80]);
    v.push(vec![0x00]);
    v.push(b"9".repeat(400));
    v.push(b"x".repeat(70_000));
    v.push([b"1".as_slice(), &b"0".repeat(5000), b".5"].concat());
    v
}

/// Values a number is replaced by: mostly extreme finite numbers (which a reader may
/// accept, so that they reach the computations), and the other extremes.
pub fn numbers() -> Vec<Vec<u8>> {
    let mut v: Vec<Vec<u8>> = [
        "1e300",
        "1e300",
        "-1e308",
        "-1e308",
        "1.7976931348623157e308",
        "1e-320",
        "-1e-300",
        "1e15",
        "-0",
        "0",
        "-1",
        "360",
        "NaN",
        "inf",
        "-inf",
        "1e309",
        "18446744073709551616",
        "4294967296",
        "",
    ]
    .iter()
    .map(|s| s.as_bytes().to_vec())
    .collect();
    v.push([b"1".as_slice(), &b"0".repeat(400)].concat());
    v
}

/// Bytes worth inserting: separators, line breaks, quotes, signs, digits and bytes that
/// are not UTF-8.
const INTERESTING: &[u8] = b",\n\r\"#-+.e0159 =[]{}:\t\xff\xc3\x80\x00";

/// How a line ends.
#[derive(Clone, Copy, Debug)]
pub enum LineEnd {
    Lf,
    CrLf,
    Cr,
    None,
}

impl LineEnd {
    fn bytes(self) -> &'static [u8] {
        match self {
            LineEnd::Lf => b"\n",
            LineEnd::CrLf => b"\r\n",
            LineEnd::Cr => b"\r",
            LineEnd::None => b"",
        }
    }
}

/// One mutation of a file's bytes.
#[derive(Clone)]
pub enum Mutation {
    FlipBit {
        at: Index,
        bit: u8,
    },
    SetByte {
        at: Index,
        byte: u8,
    },
    Insert {
        at: Index,
        bytes: Vec<u8>,
    },
    Delete {
        at: Index,
        len: usize,
    },
    Truncate {
        at: Index,
    },
    DuplicateLine {
        line: Index,
    },
    DeleteLine {
        line: Index,
    },
    SwapLines {
        a: Index,
        b: Index,
    },
    DuplicateField {
        line: Index,
        field: Index,
    },
    SwapFields {
        line: Index,
        a: Index,
        b: Index,
    },
    ReplaceField {
        line: Index,
        field: Index,
        value: Vec<u8>,
    },
    /// The `nth` number of the file (among those with a decimal point when `decimal`
    /// and there are some) replaced by `value`.
    ReplaceNumber {
        nth: Index,
        decimal: bool,
        value: Vec<u8>,
    },
    LineEnd {
        line: Index,
        end: LineEnd,
    },
    AllLineEnds {
        end: LineEnd,
    },
    Bom,
}

impl fmt::Debug for Mutation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let i = |x: &Index| x.index(1 << 20);
        match self {
            Mutation::FlipBit { at, bit } => write!(f, "FlipBit(@{}, bit {bit})", i(at)),
            Mutation::SetByte { at, byte } => write!(f, "SetByte(@{}, {byte:#04x})", i(at)),
            Mutation::Insert { at, bytes } => {
                write!(f, "Insert(@{}, {})", i(at), show(bytes, 60))
            }
            Mutation::Delete { at, len } => write!(f, "Delete(@{}, {len})", i(at)),
            Mutation::Truncate { at } => write!(f, "Truncate(@{})", i(at)),
            Mutation::DuplicateLine { line } => write!(f, "DuplicateLine(#{})", i(line)),
            Mutation::DeleteLine { line } => write!(f, "DeleteLine(#{})", i(line)),
            Mutation::SwapLines { a, b } => write!(f, "SwapLines(#{}, #{})", i(a), i(b)),
            Mutation::DuplicateField { line, field } => {
                write!(f, "DuplicateField(#{}, {})", i(line), i(field))
            }
            Mutation::SwapFields { line, a, b } => {
                write!(f, "SwapFields(#{}, {}, {})", i(line), i(a), i(b))
            }
            Mutation::ReplaceField { line, field, value } => write!(
                f,
                "ReplaceField(#{}, {}, {})",
                i(line),
                i(field),
                show(value, 60)
            ),
            Mutation::ReplaceNumber {
                nth,
                decimal,
                value,
            } => write!(
                f,
                "ReplaceNumber(#{}{}, {})",
                i(nth),
                if *decimal { " with a point" } else { "" },
                show(value, 60)
            ),
            Mutation::LineEnd { line, end } => write!(f, "LineEnd(#{}, {end:?})", i(line)),
            Mutation::AllLineEnds { end } => write!(f, "AllLineEnds({end:?})"),
            Mutation::Bom => write!(f, "Bom"),
        }
    }
}

fn line_end() -> impl Strategy<Value = LineEnd> {
    prop_oneof![
        Just(LineEnd::Lf),
        Just(LineEnd::CrLf),
        Just(LineEnd::Cr),
        Just(LineEnd::None)
    ]
}

/// One mutation; field replacements by extreme values are the most frequent.
pub fn mutation() -> impl Strategy<Value = Mutation> {
    let index = any::<Index>;
    let inserted = prop_oneof![
        prop::collection::vec(prop::sample::select(INTERESTING), 1..4),
        prop::collection::vec(any::<u8>(), 1..4),
    ];
    prop_oneof![
        2 => (index(), 0u8..8).prop_map(|(at, bit)| Mutation::FlipBit { at, bit }),
        1 => (index(), any::<u8>()).prop_map(|(at, byte)| Mutation::SetByte { at, byte }),
        2 => (index(), inserted).prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        1 => (index(), 1usize..16).prop_map(|(at, len)| Mutation::Delete { at, len }),
        1 => index().prop_map(|at| Mutation::Truncate { at }),
        1 => index().prop_map(|line| Mutation::DuplicateLine { line }),
        1 => index().prop_map(|line| Mutation::DeleteLine { line }),
        1 => (index(), index()).prop_map(|(a, b)| Mutation::SwapLines { a, b }),
        1 => (index(), index()).prop_map(|(line, field)| Mutation::DuplicateField { line, field }),
        1 => (index(), index(), index()).prop_map(|(line, a, b)| Mutation::SwapFields { line, a, b }),
        4 => (index(), index(), prop::sample::select(extremes()))
            .prop_map(|(line, field, value)| Mutation::ReplaceField { line, field, value }),
        8 => (index(), prop::bool::weighted(0.7), prop::sample::select(numbers()))
            .prop_map(|(nth, decimal, value)| Mutation::ReplaceNumber { nth, decimal, value }),
        1 => (index(), line_end()).prop_map(|(line, end)| Mutation::LineEnd { line, end }),
        1 => line_end().prop_map(|end| Mutation::AllLineEnds { end }),
        1 => Just(Mutation::Bom),
    ]
}

/// A case: which seed, and the mutations applied to it in turn.
#[derive(Clone)]
pub struct Case {
    pub seed: Seed,
    pub mutations: Vec<Mutation>,
}

impl fmt::Debug for Case {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} with {:?}", self.seed.path, self.mutations)
    }
}

impl Case {
    /// The mutated bytes.
    pub fn bytes(&self) -> Vec<u8> {
        let mut bytes = self.seed.bytes.clone();
        for m in &self.mutations {
            apply(&mut bytes, m);
        }
        bytes
    }
}

/// Cases of one of `seeds` (chosen evenly: list a seed twice to weigh it) with one to
/// four mutations.
pub fn case(seeds: Vec<Seed>) -> impl Strategy<Value = Case> {
    assert!(!seeds.is_empty());
    (prop::sample::select(seeds), mutations())
        .prop_map(|(seed, mutations)| Case { seed, mutations })
}

/// One to four mutations, one most often (a single change is more often accepted, and
/// then reaches the computations).
pub fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    prop_oneof![
        3 => prop::collection::vec(mutation(), 1..=1),
        2 => prop::collection::vec(mutation(), 2..=2),
        1 => prop::collection::vec(mutation(), 3..=4),
    ]
}

/// The byte ranges of the lines (each with its `\n`).
fn lines(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &b) in bytes.iter().enumerate() {
        if b == b'\n' {
            out.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < bytes.len() {
        out.push((start, bytes.len()));
    }
    out
}

fn is_separator(b: u8) -> bool {
    matches!(
        b,
        b',' | b'=' | b':' | b' ' | b'\t' | b'"' | b'[' | b']' | b'{' | b'}' | b'\r' | b'\n'
    )
}

/// The byte ranges of the fields of `line` (absolute offsets into the file).
fn fields(bytes: &[u8], (start, end): (usize, usize)) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut field = None;
    for (i, &b) in bytes.iter().enumerate().take(end).skip(start) {
        match (is_separator(b), field) {
            (false, None) => field = Some(i),
            (true, Some(s)) => {
                out.push((s, i));
                field = None;
            }
            _ => {}
        }
    }
    if let Some(s) = field {
        out.push((s, end));
    }
    out
}

/// A line that has fields, and its fields.
fn line_fields(bytes: &[u8], line: &Index) -> Option<Vec<(usize, usize)>> {
    let with_fields: Vec<Vec<(usize, usize)>> = lines(bytes)
        .into_iter()
        .map(|l| fields(bytes, l))
        .filter(|f| !f.is_empty())
        .collect();
    if with_fields.is_empty() {
        return None;
    }
    Some(with_fields[line.index(with_fields.len())].clone())
}

/// Applies one mutation (a no-op where it has nothing to act on).
pub fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let len = bytes.len();
    match m {
        Mutation::FlipBit { at, bit } if len > 0 => bytes[at.index(len)] ^= 1 << bit,
        Mutation::SetByte { at, byte } if len > 0 => bytes[at.index(len)] = *byte,
        Mutation::Insert { at, bytes: new } => {
            let at = at.index(len + 1);
            bytes.splice(at..at, new.iter().copied());
        }
        Mutation::Delete { at, len: n } if len > 0 => {
            let at = at.index(len);
            bytes.drain(at..(at + n).min(len));
        }
        Mutation::Truncate { at } => bytes.truncate(at.index(len + 1)),
        Mutation::DuplicateLine { line } => {
            let lines = lines(bytes);
            if !lines.is_empty() {
                let (s, e) = lines[line.index(lines.len())];
                let mut copy = bytes[s..e].to_vec();
                if copy.last() != Some(&b'\n') {
                    copy.insert(0, b'\n');
                }
                bytes.splice(e..e, copy);
            }
        }
        Mutation::DeleteLine { line } => {
            let lines = lines(bytes);
            if !lines.is_empty() {
                let (s, e) = lines[line.index(lines.len())];
                bytes.drain(s..e);
            }
        }
        Mutation::SwapLines { a, b } => {
            let lines = lines(bytes);
            if lines.len() > 1 {
                let (mut x, mut y) = (lines[a.index(lines.len())], lines[b.index(lines.len())]);
                if x.0 > y.0 {
                    std::mem::swap(&mut x, &mut y);
                }
                if x != y {
                    swap_ranges(bytes, x, y);
                }
            }
        }
        Mutation::DuplicateField { line, field } => {
            if let Some(f) = line_fields(bytes, line) {
                let (s, e) = f[field.index(f.len())];
                let mut copy = bytes[s..e].to_vec();
                copy.push(b',');
                bytes.splice(s..s, copy);
            }
        }
        Mutation::SwapFields { line, a, b } => {
            if let Some(f) = line_fields(bytes, line) {
                let (mut x, mut y) = (f[a.index(f.len())], f[b.index(f.len())]);
                if x.0 > y.0 {
                    std::mem::swap(&mut x, &mut y);
                }
                if x != y {
                    swap_ranges(bytes, x, y);
                }
            }
        }
        Mutation::ReplaceField { line, field, value } => {
            if let Some(f) = line_fields(bytes, line) {
                let (s, e) = f[field.index(f.len())];
                bytes.splice(s..e, value.iter().copied());
            }
        }
        Mutation::ReplaceNumber {
            nth,
            decimal,
            value,
        } => {
            let all: Vec<(usize, usize)> = lines(bytes)
                .into_iter()
                .flat_map(|l| fields(bytes, l))
                .filter(|&(s, e)| is_number(&bytes[s..e]))
                .collect();
            let with_point: Vec<(usize, usize)> = all
                .iter()
                .copied()
                .filter(|&(s, e)| bytes[s..e].contains(&b'.'))
                .collect();
            let pool = if *decimal && !with_point.is_empty() {
                with_point
            } else {
                all
            };
            if !pool.is_empty() {
                let (s, e) = pool[nth.index(pool.len())];
                bytes.splice(s..e, value.iter().copied());
            }
        }
        Mutation::LineEnd { line, end } => {
            let lines = lines(bytes);
            if !lines.is_empty() {
                let (s, e) = lines[line.index(lines.len())];
                let body = strip_end(&bytes[s..e]);
                let new = [body, end.bytes()].concat();
                bytes.splice(s..e, new);
            }
        }
        Mutation::AllLineEnds { end } => {
            let mut out = Vec::with_capacity(len);
            for (s, e) in lines(bytes) {
                let line = &bytes[s..e];
                out.extend_from_slice(strip_end(line));
                if line.ends_with(b"\n") {
                    out.extend_from_slice(end.bytes());
                }
            }
            *bytes = out;
        }
        Mutation::Bom => {
            bytes.splice(0..0, "\u{feff}".bytes());
        }
        _ => {}
    }
}

/// Whether a field is a number: digits, with signs, points and exponents.
fn is_number(field: &[u8]) -> bool {
    field.iter().any(u8::is_ascii_digit)
        && field
            .iter()
            .all(|b| b.is_ascii_digit() || matches!(b, b'.' | b'e' | b'E' | b'+' | b'-'))
}

/// A line without its `\n` or `\r\n`.
fn strip_end(line: &[u8]) -> &[u8] {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    line.strip_suffix(b"\r").unwrap_or(line)
}

/// Swaps two non-overlapping ranges, `x` before `y`.
fn swap_ranges(bytes: &mut Vec<u8>, x: (usize, usize), y: (usize, usize)) {
    if x.1 > y.0 {
        return;
    }
    let mut out = Vec::with_capacity(bytes.len());
    out.extend_from_slice(&bytes[..x.0]);
    out.extend_from_slice(&bytes[y.0..y.1]);
    out.extend_from_slice(&bytes[x.1..y.0]);
    out.extend_from_slice(&bytes[x.0..x.1]);
    out.extend_from_slice(&bytes[y.1..]);
    *bytes = out;
}

/// Bytes as escaped text, cut after `max` characters.
pub fn show(bytes: &[u8], max: usize) -> String {
    let text = bytes.escape_ascii().to_string();
    if text.chars().count() > max {
        let cut: String = text.chars().take(max).collect();
        format!("\"{cut}\"… ({} bytes)", bytes.len())
    } else {
        format!("\"{text}\"")
    }
}

/// Where a mutated file differs from its seed: the changed lines of both, by line
/// number, cut to a readable length.
pub fn diff(seed: &[u8], mutated: &[u8]) -> String {
    let prefix = seed.iter().zip(mutated).take_while(|(a, b)| a == b).count();
    let suffix = seed[prefix..]
        .iter()
        .rev()
        .zip(mutated[prefix..].iter().rev())
        .take_while(|(a, b)| a == b)
        .count();
    if prefix == seed.len() && prefix == mutated.len() {
        return "(unchanged)".to_string();
    }
    // Widen to whole lines.
    let start = seed[..prefix]
        .iter()
        .rposition(|&b| b == b'\n')
        .map_or(0, |i| i + 1);
    let line = seed[..start].iter().filter(|&&b| b == b'\n').count() + 1;
    let end_of = |bytes: &[u8], from: usize| {
        bytes[from..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| from + i + 1)
    };
    let seed_end = end_of(seed, seed.len() - suffix);
    let mutated_end = end_of(mutated, mutated.len() - suffix);
    format!(
        "from line {line}:\n  seed:    {}\n  mutated: {}",
        show(&seed[start..seed_end.max(start)], 400),
        show(&mutated[start..mutated_end.max(start)], 400)
    )
}
