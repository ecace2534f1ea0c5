//! The assertion on a refused table file (`FileError::Invalid`) that the tests of every
//! file kind share: one error type for every table input, one check of its place and words.

use polycal::input::FileError;

/// Asserts that `err` is `Invalid` at `file:line:column` and its message holds `words`.
pub fn assert_invalid(err: &FileError, file: &str, line: u64, column: u64, words: &[&str]) {
    let text = err.to_string();
    let FileError::Invalid { location, message } = err else {
        panic!("expected Invalid, got {text}");
    };
    assert_eq!(
        (location.file(), location.line(), location.column()),
        (file, line, column),
        "wrong location in: {text}"
    );
    assert_eq!(err.location(), Some(location));
    assert!(
        text.starts_with(&format!("{location}: ")),
        "bad prefix: {text}"
    );
    assert!(!message.contains('\n'), "message is not one line: {text}");
    for word in words {
        assert!(text.contains(word), "{word:?} not in: {text}");
    }
}
