//! Laboratory names that look alike (docs/FORMAT.md §12): two results named `PTB` and
//! `ptb`, `N PL` and `NPL`, or `PTB` and `РТВ` (Cyrillic Р, Т, В) are taken as different
//! laboratories, as named, but a note names both. Names are compared by their skeleton:
//! white space and invisible formatting characters dropped, letters that look Latin
//! mapped to the Latin letter ([`LOOK_ALIKE`], Cyrillic and Greek), then lower case.

use std::collections::HashMap;

use super::LabResult;
use super::input::Aligned;
use crate::input::is_bidi_control;

/// Cyrillic and Greek letters drawn like a Latin letter in common fonts, and that letter.
const LOOK_ALIKE: &[(char, char)] = &[
    // Cyrillic capitals
    ('А', 'A'),
    ('В', 'B'),
    ('Е', 'E'),
    ('Ѕ', 'S'),
    ('І', 'I'),
    ('Ј', 'J'),
    ('К', 'K'),
    ('М', 'M'),
    ('Н', 'H'),
    ('О', 'O'),
    ('Р', 'P'),
    ('С', 'C'),
    ('Т', 'T'),
    ('У', 'Y'),
    ('Х', 'X'),
    // Cyrillic small letters
    ('а', 'a'),
    ('е', 'e'),
    ('і', 'i'),
    ('ј', 'j'),
    ('о', 'o'),
    ('р', 'p'),
    ('с', 'c'),
    ('ѕ', 's'),
    ('у', 'y'),
    ('х', 'x'),
    // Greek capitals
    ('Α', 'A'),
    ('Β', 'B'),
    ('Ε', 'E'),
    ('Ζ', 'Z'),
    ('Η', 'H'),
    ('Ι', 'I'),
    ('Κ', 'K'),
    ('Μ', 'M'),
    ('Ν', 'N'),
    ('Ο', 'O'),
    ('Ρ', 'P'),
    ('Τ', 'T'),
    ('Υ', 'Y'),
    ('Χ', 'X'),
    // Greek small letters
    ('ο', 'o'),
];

/// The skeleton a name is compared by: white space, bidirectional formatting characters
/// and zero-width characters dropped, look-alike letters as their Latin letter, lower
/// case.
pub(crate) fn skeleton(name: &str) -> String {
    name.chars()
        .filter(|&c| !c.is_whitespace() && !is_bidi_control(c) && !is_invisible(c))
        .map(|c| {
            LOOK_ALIKE
                .iter()
                .find(|(other, _)| *other == c)
                .map_or(c, |&(_, latin)| latin)
        })
        .flat_map(char::to_lowercase)
        .collect()
}

/// Characters that show nothing: zero-width space, joiners, word joiner, byte-order mark,
/// soft hyphen.
fn is_invisible(c: char) -> bool {
    matches!(
        c,
        '\u{200B}'..='\u{200D}' | '\u{2060}' | '\u{FEFF}' | '\u{00AD}'
    )
}

/// The note on every two results (laboratories and the pilot's repeats, in the order
/// given) whose names differ but share a skeleton.
pub(crate) fn look_alike_notes(results: &[&LabResult]) -> Vec<String> {
    let mut by_skeleton: HashMap<String, Vec<usize>> = HashMap::new();
    for (r, result) in results.iter().enumerate() {
        by_skeleton
            .entry(skeleton(&result.name))
            .or_default()
            .push(r);
    }
    let mut pairs: Vec<(usize, usize)> = by_skeleton
        .values()
        .flat_map(|group| {
            group
                .iter()
                .enumerate()
                .flat_map(move |(i, &a)| group[i + 1..].iter().map(move |&b| (a, b)))
        })
        .collect();
    pairs.sort_unstable();
    pairs
        .into_iter()
        .map(|(a, b)| {
            let (a, b) = (results[a], results[b]);
            format!(
                "the names {:?} ({}) and {:?} ({}) differ only by case, white space or \
                 look-alike letters{}: they are compared as two laboratories; if they are one, \
                 give its result once",
                a.name,
                a.source,
                b.name,
                b.source,
                code_points(&a.name, &b.name)
            )
        })
        .collect()
}

/// The characters of the two names beyond ASCII, as code points (` (U+0420, U+0422 in
/// the second)`), or nothing when both are ASCII.
fn code_points(a: &str, b: &str) -> String {
    let listed = |name: &str| {
        let points: Vec<String> = name
            .chars()
            .filter(|c| !c.is_ascii())
            .map(|c| format!("U+{:04X}", c as u32))
            .collect();
        points.join(", ")
    };
    match (listed(a), listed(b)) {
        (x, y) if x.is_empty() && y.is_empty() => String::new(),
        (x, y) if x.is_empty() => format!(" ({y} in the second)"),
        (x, y) if y.is_empty() => format!(" ({x} in the first)"),
        (x, y) => format!(" ({x} in the first, {y} in the second)"),
    }
}

/// `aligned` with the notes on look-alike names of `results` before its own.
pub(crate) fn with_look_alike_notes(results: &[&LabResult], mut aligned: Aligned) -> Aligned {
    let mut notes = look_alike_notes(results);
    notes.append(&mut aligned.notes);
    aligned.notes = notes;
    aligned
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skeletons_drop_case_space_invisibles_and_look_alikes() {
        assert_eq!(skeleton("PTB"), "ptb");
        assert_eq!(skeleton("РТВ"), "ptb"); // Cyrillic Er, Te, Ve
        assert_eq!(skeleton("ΡΤΒ"), "ptb"); // Greek Rho, Tau, Beta
        assert_eq!(skeleton(" N PL\t"), "npl");
        assert_eq!(skeleton("NPL\u{202e}"), "npl");
        assert_eq!(skeleton("N\u{200b}PL"), "npl");
        assert_eq!(skeleton("ВІРМ"), "bipm"); // Cyrillic Ve, Byelorussian-Ukrainian I, Er, Em
        assert_eq!(skeleton("сое"), "coe");
        // Different names stay different.
        assert_ne!(skeleton("NPL"), skeleton("NRC"));
        assert_ne!(skeleton("NIST"), skeleton("NIS"));
        // A letter with no Latin look-alike stays itself.
        assert_eq!(skeleton("ДФ"), "дф");
        for (other, latin) in LOOK_ALIKE {
            assert!(!other.is_ascii() && latin.is_ascii_alphabetic(), "{other}");
        }
    }

    fn named(names: &[&str]) -> Vec<LabResult> {
        names
            .iter()
            .map(|n| LabResult::from_rows(*n, Vec::new()))
            .collect()
    }

    #[test]
    fn look_alike_names_are_noted_in_pairs_naming_both() {
        let labs = named(&["PTB", "NPL", "ptb", "РТВ", "NMIJ"]);
        let all: Vec<&LabResult> = labs.iter().collect();
        let notes = look_alike_notes(&all);
        assert_eq!(notes.len(), 3, "{notes:?}");
        assert!(notes[0].starts_with("the names \"PTB\" (PTB) and \"ptb\" (ptb) differ only"));
        assert!(!notes[0].contains("U+"));
        assert!(notes[1].contains("\"PTB\" (PTB) and \"РТВ\""));
        assert!(notes[1].contains("(U+0420, U+0422, U+0412 in the second)"));
        assert!(notes[2].starts_with("the names \"ptb\" (ptb) and \"РТВ\""));
        let distinct = named(&["PTB", "NPL", "NIST"]);
        let all: Vec<&LabResult> = distinct.iter().collect();
        assert!(look_alike_notes(&all).is_empty());
    }
}
