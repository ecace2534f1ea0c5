//! Draft A of a key comparison (docs/FORMAT.md §12): every laboratory named by a code
//! letter, so that the participants see the results before they know whose they are.
//!
//! The codes are `A`, `B`, …, `Z`, `AA`, `AB`, … (as a spreadsheet names its columns),
//! assigned to the laboratories in an order drawn at random ([`anonymise`] with a seed),
//! never in the order the laboratories were given nor in the alphabet of their names; the
//! anonymised laboratories are listed in the order of their codes, so that the order of
//! every output (the JSON's `labs`, the figures' series) tells nothing either. The key —
//! which code is which laboratory — is a CSV file of its own, `code,lab` ([`CodeKey`]),
//! read back for the next draft so that Draft A and Draft B keep their letters.

use rand::SeedableRng;
use rand::seq::SliceRandom;

use super::{KeyComparison, LabResult};
use crate::input::Location;
use crate::input::text::{LineIndex, Span, to_u64};

/// The note a comparison anonymised carries: what the names are, without the key.
pub const DRAFT_A_NOTE: &str = "the laboratories are named by code letters assigned in an order \
     drawn at random (Draft A); which laboratory each code is, is known to the pilot alone";

/// One row of a key: a code and the laboratory it stands for.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct CodeEntry {
    /// The code shown in every output, e.g. `C`.
    pub code: String,
    /// The laboratory's name as given (`NAME` of `NAME=RESULT.csv`).
    pub lab: String,
    /// Where the row is in the key file read (its code's field); `None` for a key drawn.
    pub at: Option<Location>,
}

/// The key of a Draft A: which code stands for which laboratory, in the order of the
/// codes ([`code_order`]). Read from its CSV with [`CodeKey::read`], written with
/// [`crate::output::kc::write_key_csv`].
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct CodeKey {
    /// The rows, in the order of their codes (a key read: in the order of the file).
    pub entries: Vec<CodeEntry>,
    /// The key file it was read from, for messages; `None` for a key drawn.
    pub source: Option<String>,
}

/// Why a key cannot be read or used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum CodeKeyError {
    /// The key file breaks a rule: where, and what.
    #[error("{location}: {message}")]
    Key {
        /// The file, line and column.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// A laboratory of the comparison that the key does not name.
    #[error(
        "the laboratory {lab:?} is not in the key {file}: every laboratory needs its code \
         (add a row `CODE,{lab}` with a code no other laboratory has)"
    )]
    NotInKey {
        /// The laboratory.
        lab: String,
        /// The key file.
        file: String,
    },
    /// Two laboratories with one name.
    #[error("the laboratory name {name:?} is given twice ({first} and {second})")]
    DuplicateName {
        /// The name.
        name: String,
        /// The first result of that name.
        first: String,
        /// The second.
        second: String,
    },
}

/// The `i`-th code (from 0): `A` … `Z`, then `AA` … `AZ`, `BA` … `ZZ`, `AAA`, …
///
/// ```
/// use polycal::kc::code_letter;
/// assert_eq!(code_letter(0), "A");
/// assert_eq!(code_letter(25), "Z");
/// assert_eq!(code_letter(26), "AA");
/// assert_eq!(code_letter(27), "AB");
/// assert_eq!(code_letter(26 + 26 * 26), "AAA");
/// ```
pub fn code_letter(i: usize) -> String {
    let mut letters = Vec::new();
    let mut n = i + 1;
    while n > 0 {
        let digit = (n - 1) % 26;
        letters.push(char::from(b'A' + u8::try_from(digit).unwrap_or(0)));
        n = (n - 1) / 26;
    }
    letters.iter().rev().collect()
}

/// The order of codes: shorter first, then by their text (`B` before `AA`, as
/// [`code_letter`] numbers them).
pub fn code_order(a: &str, b: &str) -> std::cmp::Ordering {
    a.chars()
        .count()
        .cmp(&b.chars().count())
        .then_with(|| a.cmp(b))
}

/// The first characters a spreadsheet takes for a formula (docs/FORMAT.md §3.1).
const FORMULA_STARTS: [char; 6] = ['=', '+', '-', '@', '\t', '\r'];

/// A cell as written, without the apostrophe a writer puts before a formula character.
fn unguarded(cell: &str) -> &str {
    match cell.strip_prefix('\'') {
        Some(rest) if rest.starts_with(FORMULA_STARTS) => rest,
        _ => cell,
    }
}

impl CodeKey {
    /// Reads a key from the bytes of its CSV (`source` names the file in messages): a
    /// header naming the columns `code` and `lab` (others are passed over; `#` comment
    /// lines and blank lines skipped), then one row per laboratory. A cell that begins
    /// with `'` before a formula character is read without it (docs/FORMAT.md §3.1).
    ///
    /// # Errors
    ///
    /// [`CodeKeyError::Key`] naming the file, line and column: text that is not UTF-8
    /// or not CSV, no header with both columns, a row with another number of fields, an
    /// empty code or laboratory, a code with a control character, a code or a
    /// laboratory given twice (naming the first's line), or no row.
    ///
    /// ```
    /// use polycal::kc::CodeKey;
    /// let key = CodeKey::read(b"code,lab\nB,PTB\nA,NPL\n", "key.csv")?;
    /// assert_eq!(key.code_of("NPL"), Some("A"));
    /// let twice = CodeKey::read(b"code,lab\nA,PTB\nA,NPL\n", "key.csv").unwrap_err();
    /// assert!(twice.to_string().starts_with("key.csv:3:1: code \"A\" is given twice"));
    /// # Ok::<(), polycal::kc::CodeKeyError>(())
    /// ```
    pub fn read(bytes: &[u8], source: &str) -> Result<CodeKey, CodeKeyError> {
        let refuse = |(line, column): (u64, u64), message: String| CodeKeyError::Key {
            location: Location::new(source, line, column),
            message,
        };
        let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
        let text = crate::input::text::utf8(bytes).map_err(|(at, m)| refuse(at, m))?;
        let index = LineIndex::new(text);
        let mut csv = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .comment(Some(b'#'))
            .from_reader(text.as_bytes());
        let mut header: Option<(usize, usize, usize)> = None; // (fields, code, lab)
        let mut entries: Vec<CodeEntry> = Vec::new();
        let mut record = csv::StringRecord::new();
        loop {
            let more = csv.read_record(&mut record).map_err(|e| {
                let offset = e
                    .position()
                    .and_then(|p| usize::try_from(p.byte()).ok())
                    .unwrap_or(0);
                refuse(index.location(offset), format!("unreadable CSV: {e}"))
            })?;
            if !more {
                break;
            }
            let mut from = record
                .position()
                .and_then(|p| usize::try_from(p.byte()).ok())
                .unwrap_or(0);
            // the reader's position may lie before the comment and blank lines it skipped
            loop {
                let line = index.line_of(from);
                let content = index.line_text(line);
                let skipped = content.starts_with('#') || content.trim().is_empty();
                match index.starts.get(line + 1) {
                    Some(&next) if skipped && index.starts[line] >= from => from = next,
                    _ => break,
                }
            }
            let span = Span::scan(text.as_bytes(), from, record.len());
            let at = |j: usize| index.location(span.field(j));
            let Some((fields, code_j, lab_j)) = header else {
                let find = |name: &str| record.iter().position(|f| f.trim() == name);
                match (find("code"), find("lab")) {
                    (Some(c), Some(l)) => header = Some((record.len(), c, l)),
                    _ => {
                        let found: Vec<&str> = record.iter().collect();
                        return Err(refuse(
                            at(0),
                            format!(
                                "not a key of code letters: expected the header `code,lab` \
                                 (docs/FORMAT.md §12), found {:?}",
                                found.join(",")
                            ),
                        ));
                    }
                }
                continue;
            };
            if record.len() != fields {
                return Err(refuse(
                    at(0),
                    format!(
                        "{} field(s), but the header has {fields}: a row is `code,lab`",
                        record.len()
                    ),
                ));
            }
            let code = unguarded(record.get(code_j).unwrap_or("")).to_string();
            let lab = unguarded(record.get(lab_j).unwrap_or("")).to_string();
            if code.trim().is_empty() {
                return Err(refuse(
                    at(code_j),
                    format!("no code for the laboratory {lab:?}: every row has its code"),
                ));
            }
            if code.contains(char::is_control) {
                return Err(refuse(
                    at(code_j),
                    format!(
                        "the code {:?} holds a control character: a code is shown in every output",
                        code
                    ),
                ));
            }
            if lab.is_empty() {
                return Err(refuse(
                    at(lab_j),
                    format!(
                        "code {code:?} has no laboratory: every row names the laboratory of its code"
                    ),
                ));
            }
            let line_of = |e: &CodeEntry| e.at.as_ref().map_or(0, Location::line);
            if let Some(first) = entries.iter().find(|e| e.code == code) {
                return Err(refuse(
                    at(code_j),
                    format!(
                        "code {code:?} is given twice (first on line {}): each laboratory has a code of its own",
                        line_of(first)
                    ),
                ));
            }
            if let Some(first) = entries.iter().find(|e| e.lab == lab) {
                return Err(refuse(
                    at(lab_j),
                    format!(
                        "the laboratory {lab:?} is given twice (first on line {}): a laboratory has one code",
                        line_of(first)
                    ),
                ));
            }
            let (line, column) = at(code_j);
            entries.push(CodeEntry {
                code,
                lab,
                at: Some(Location::new(source, line, column)),
            });
        }
        if header.is_none() {
            return Err(refuse(
                (1, 1),
                "empty file: expected the header `code,lab` and a row per laboratory".to_string(),
            ));
        }
        if entries.is_empty() {
            let lines = to_u64(index.starts.len());
            return Err(refuse(
                (lines, 1),
                "the key has a header but no row: a row `code,lab` per laboratory".to_string(),
            ));
        }
        Ok(CodeKey {
            entries,
            source: Some(source.to_string()),
        })
    }

    /// The code of a laboratory, when the key has it.
    pub fn code_of(&self, lab: &str) -> Option<&str> {
        self.entries
            .iter()
            .find(|e| e.lab == lab)
            .map(|e| e.code.as_str())
    }

    /// Names as the anonymised comparison knows them: each laboratory's code, and any
    /// other name as given (so that a name that is no laboratory's is refused as such).
    pub fn coded_names<'n>(&self, names: impl IntoIterator<Item = &'n str>) -> Vec<String> {
        names
            .into_iter()
            .map(|n| self.code_of(n).unwrap_or(n).to_string())
            .collect()
    }

    /// Another comparison (the one linked to, [`super::link`]) with its laboratories named
    /// as this key names them: each laboratory of the key by its code, any other marked
    /// `NAME (not coded)` so that it can never be taken for a code.
    pub fn coded_comparison(&self, other: &KeyComparison) -> KeyComparison {
        let code = |name: &str| match self.code_of(name) {
            Some(code) => code.to_string(),
            None => format!("{name} (not coded)"),
        };
        let mut coded = other.clone();
        coded.labs = other.labs.iter().map(|n| code(n)).collect();
        for doe in &mut coded.degrees_of_equivalence {
            doe.lab = code(&doe.lab);
        }
        coded
    }
}

/// Draft A: the laboratories with their names replaced by codes, listed in the order of
/// the codes, and the key. With `key` (a key read, for Draft B), its codes; every
/// laboratory must be in it (it may name more). Without, codes `A`, `B`, … (passing
/// over any name of the pilot's `repeats`, which keep theirs) assigned in an order
/// drawn at random from `seed` (ChaCha8). Each result keeps its `source`, so that a
/// refusal still names the file and line.
///
/// # Errors
///
/// [`CodeKeyError::DuplicateName`] for two laboratories of one name;
/// [`CodeKeyError::NotInKey`] for a laboratory the key lacks; [`CodeKeyError::Key`] at
/// the row of a code that is the name of one of the pilot's repeats.
///
/// ```
/// use polycal::kc::{LabResult, anonymise};
/// let labs: Vec<LabResult> = ["PTB", "NPL", "NIST"]
///     .iter()
///     .map(|n| LabResult::from_rows(*n, Vec::new()))
///     .collect();
/// let (coded, key) = anonymise(&labs, &[], None, 7)?;
/// let names: Vec<&str> = coded.iter().map(|l| l.name.as_str()).collect();
/// assert_eq!(names, ["A", "B", "C"]);
/// // the same key again: the same codes
/// let (again, _) = anonymise(&labs, &[], Some(&key), 8)?;
/// assert_eq!(again, coded);
/// # Ok::<(), polycal::kc::CodeKeyError>(())
/// ```
pub fn anonymise(
    labs: &[LabResult],
    repeats: &[LabResult],
    key: Option<&CodeKey>,
    seed: u64,
) -> Result<(Vec<LabResult>, CodeKey), CodeKeyError> {
    for (i, lab) in labs.iter().enumerate() {
        if let Some(first) = labs[..i].iter().find(|l| l.name == lab.name) {
            return Err(CodeKeyError::DuplicateName {
                name: lab.name.clone(),
                first: first.source.clone(),
                second: lab.source.clone(),
            });
        }
    }
    let is_repeat = |name: &str| repeats.iter().any(|r| r.name == name);
    let key = match key {
        Some(key) => {
            for lab in labs {
                let Some(entry) = key.entries.iter().find(|e| e.lab == lab.name) else {
                    return Err(CodeKeyError::NotInKey {
                        lab: lab.name.clone(),
                        file: key.source.clone().unwrap_or_default(),
                    });
                };
                if is_repeat(&entry.code) {
                    return Err(CodeKeyError::Key {
                        location: entry.at.clone().unwrap_or_else(|| {
                            Location::file_only(key.source.clone().unwrap_or_default())
                        }),
                        message: format!(
                            "code {:?} of the laboratory {:?} is also the name of one of the \
                             pilot's repeats: give the repeat another name",
                            entry.code, entry.lab
                        ),
                    });
                }
            }
            key.clone()
        }
        None => drawn_key(labs, &is_repeat, seed),
    };
    let mut coded: Vec<LabResult> = labs
        .iter()
        .map(|lab| {
            let mut lab = lab.clone();
            if let Some(code) = key.code_of(&lab.name) {
                lab.name = code.to_string();
            }
            lab
        })
        .collect();
    coded.sort_by(|a, b| code_order(&a.name, &b.name));
    Ok((coded, key))
}

/// A new key: the first codes that are no repeat's name, assigned in a shuffled order.
fn drawn_key(labs: &[LabResult], is_repeat: &dyn Fn(&str) -> bool, seed: u64) -> CodeKey {
    let mut codes: Vec<String> = (0..)
        .map(code_letter)
        .filter(|c| !is_repeat(c))
        .take(labs.len())
        .collect();
    codes.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(seed));
    let mut entries: Vec<CodeEntry> = labs
        .iter()
        .zip(codes)
        .map(|(lab, code)| CodeEntry {
            code,
            lab: lab.name.clone(),
            at: None,
        })
        .collect();
    entries.sort_by(|a, b| code_order(&a.code, &b.code));
    CodeKey {
        entries,
        source: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn labs(names: &[&str]) -> Vec<LabResult> {
        names
            .iter()
            .map(|n| LabResult::from_rows(*n, Vec::new()))
            .collect()
    }

    /// The code each laboratory gets, over many seeds, is uniform: every code as often
    /// for the first laboratory (given first, first in the alphabet) as for the last,
    /// 1/6 of 6 000 draws each within 4.5 σ (σ = √(6000·(1/6)·(5/6)) ≈ 28.9).
    #[test]
    fn codes_follow_neither_the_order_nor_the_alphabet_of_the_names() {
        let names = ["Alpha", "Bravo", "Charlie", "Delta", "Echo", "Foxtrot"];
        let labs = labs(&names);
        let mut counts = [[0usize; 6]; 6];
        for seed in 0..6000 {
            let (_, key) = anonymise(&labs, &[], None, seed).unwrap();
            for (l, name) in names.iter().enumerate() {
                let code = key.code_of(name).unwrap();
                let c = (0..6).position(|i| code_letter(i) == code).unwrap();
                counts[l][c] += 1;
            }
        }
        let sigma = (6000.0_f64 * (1.0 / 6.0) * (5.0 / 6.0)).sqrt();
        for (l, row) in counts.iter().enumerate() {
            for (c, &n) in row.iter().enumerate() {
                assert!(
                    (n as f64 - 1000.0).abs() < 4.5 * sigma,
                    "laboratory {l} got code {c} {n} times of 6000"
                );
            }
        }
    }

    #[test]
    fn the_codes_pass_over_the_names_of_the_pilots_repeats_and_come_in_code_order() {
        let many: Vec<String> = (0..30).map(|i| format!("lab{i}")).collect();
        let names: Vec<&str> = many.iter().map(String::as_str).collect();
        let repeats = labs(&["B", "start"]);
        let (coded, key) = anonymise(&labs(&names), &repeats, None, 3).unwrap();
        let codes: Vec<&str> = coded.iter().map(|l| l.name.as_str()).collect();
        let mut expected: Vec<String> = (0..31).map(code_letter).collect();
        expected.retain(|c| c != "B");
        assert_eq!(codes, expected);
        assert_eq!(key.entries.len(), 30);
        assert!(
            key.entries
                .windows(2)
                .all(|w| code_order(&w[0].code, &w[1].code).is_lt())
        );
    }

    #[test]
    fn a_key_read_refuses_what_it_cannot_use_naming_the_line() {
        let err = |text: &str| {
            CodeKey::read(text.as_bytes(), "k.csv")
                .unwrap_err()
                .to_string()
        };
        assert!(
            err("code,lab\nA,PTB\nB,PTB\n")
                .starts_with("k.csv:3:3: the laboratory \"PTB\" is given twice (first on line 2)")
        );
        assert!(err("code,lab\nA,PTB\n,NPL\n").starts_with("k.csv:3:1: no code"));
        assert!(
            err("code,lab\nA,PTB\nB,\n").starts_with("k.csv:3:3: code \"B\" has no laboratory")
        );
        assert!(err("code,lab\nA,PTB,x\n").starts_with("k.csv:2:1: 3 field(s)"));
        assert!(err("quantity,index,value\n").starts_with("k.csv:1:1: not a key"));
        assert!(err("# only a comment\n").starts_with("k.csv:1:1: empty file"));
        assert!(err("# a comment\n\nquantity,index\n").starts_with("k.csv:3:1: not a key"));
        assert!(err("code,lab\n# note\n\nA,PTB\nA,NPL\n").starts_with("k.csv:5:1: code"));
        assert!(err("code,lab\n").starts_with("k.csv:2:1: the key has a header but no row"));
        let key = CodeKey::read(b"# Draft A\n\nlab,code\n'-x,B\nNPL,A\n", "k.csv").unwrap();
        assert_eq!(key.code_of("-x"), Some("B"));
        assert_eq!(key.entries[1].at, Some(Location::new("k.csv", 5, 5)));
    }

    #[test]
    fn a_laboratory_not_in_the_key_or_a_code_that_is_a_repeats_name_is_refused() {
        let key = CodeKey::read(b"code,lab\nA,PTB\nstart,NPL\n", "k.csv").unwrap();
        let e = anonymise(&labs(&["PTB", "NIST"]), &[], Some(&key), 0).unwrap_err();
        assert_eq!(
            e,
            CodeKeyError::NotInKey {
                lab: "NIST".into(),
                file: "k.csv".into()
            }
        );
        let e = anonymise(&labs(&["PTB", "NPL"]), &labs(&["start"]), Some(&key), 0).unwrap_err();
        assert!(
            e.to_string().starts_with("k.csv:3:1: code \"start\""),
            "{e}"
        );
        let e = anonymise(&labs(&["PTB", "PTB"]), &[], None, 0).unwrap_err();
        assert!(matches!(e, CodeKeyError::DuplicateName { .. }));
    }
}
