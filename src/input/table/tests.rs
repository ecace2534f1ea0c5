//! The reader on a third, tiny description: a key-comparison table of faces with their
//! value, expanded uncertainty U and coverage factor k. Every expectation is derived by
//! hand from the text (lines and character columns counted from 1).

use super::*;
use crate::input::limits;

const FACE: usize = 0;
const VALUE: usize = 1;
const U: usize = 2;
const K: usize = 3;

fn positive(x: f64) -> bool {
    x > 0.0
}

/// face (integer 1 … 1000), value (a reading's limits), u (> 0), k (a coverage factor,
/// optional, 2 if empty).
const KEY_COMPARISON: [Column; 4] = [
    Column::integer("face", 1, 1000),
    Column::number("value", Range::Limit(limits::READING_ARCSEC, "a value")),
    Column::number(
        "u",
        Range::Within {
            contains: positive,
            broken: "is not positive; an expanded uncertainty is more than 0",
        },
    ),
    Column::number(
        "k",
        Range::Limit(limits::COVERAGE_FACTOR, "a coverage factor"),
    )
    .or(Value::Number(2.0)),
];

/// One face of the table.
#[derive(Debug, PartialEq)]
struct Face {
    face: u32,
    value: f64,
    u: f64,
    k: f64,
    line: u64,
}

impl Numbered for Face {
    fn line(&self) -> u64 {
        self.line
    }
}

fn read(text: &str) -> Result<Vec<Face>, TableError> {
    let mut table = Reader::open(text.as_bytes(), "kc.csv", &KEY_COMPARISON)?;
    let mut faces = Vec::new();
    while let Some(row) = table.next_row()? {
        faces.push(Face {
            face: row.integer(FACE)?,
            value: row.number(VALUE)?,
            u: row.number(U)?,
            k: row.number(K)?,
            line: row.line(),
        });
    }
    Ok(faces)
}

fn refusal(text: &str) -> String {
    match read(text) {
        Ok(faces) => panic!("accepted: {faces:?}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn reads_a_described_table() {
    let text =
        "# key comparison\n\nface,note,k,value,u\n1,first,,0.5,0.1\n\n2,\"b, c\",2.5,-0.25,0.2\n";
    let faces = read(text).unwrap();
    assert_eq!(
        faces,
        [
            Face {
                face: 1,
                value: 0.5,
                u: 0.1,
                k: 2.0,
                line: 4
            },
            Face {
                face: 2,
                value: -0.25,
                u: 0.2,
                k: 2.5,
                line: 6
            },
        ]
    );
    // An optional column the header does not name: its default on every row.
    let faces = read("face,value,u\r\n3,1,1\r\n").unwrap();
    assert_eq!((faces[0].face, faces[0].k, faces[0].line), (3, 2.0, 2));
}

#[test]
fn refuses_a_field_at_its_line_and_column() {
    assert_eq!(
        refusal("face,value,u\n1,0.5,-0.1\n"),
        "kc.csv:2:7: column \"u\": \"-0.1\" is not positive; an expanded uncertainty is more than 0"
    );
    assert_eq!(
        refusal("face,value,u\n1,0.5,0.1\n0,0.5,0.1\n"),
        "kc.csv:3:1: column \"face\": \"0\" is not allowed; face must be at least 1"
    );
    assert_eq!(
        refusal("face,value,u\n1001,0.5,0.1\n"),
        "kc.csv:2:1: column \"face\": \"1001\" is too large; face must be at most 1000"
    );
    // Columns count characters, not bytes; a quoted field starts at its quote.
    assert_eq!(
        refusal("face,note,value,u\n1,é,\"x\",0.1\n"),
        "kc.csv:2:5: column \"value\": \"x\" is not a number"
    );
    assert_eq!(
        refusal("face,value,u\n1,1e300,0.1\n"),
        "kc.csv:2:3: column \"value\": \"1e300\" is beyond the limits of a value, \
         −1e6 … 1e6″ (docs/FORMAT.md §2.2)"
    );
    assert_eq!(
        refusal("face,value,u\n1,inf,0.1\n"),
        "kc.csv:2:3: column \"value\": \"inf\" is not a finite number"
    );
    assert_eq!(
        refusal("face,value,u\n1,,0.1\n"),
        "kc.csv:2:3: column \"value\": empty; a number is required"
    );
    assert_eq!(
        refusal("face,value,u,k\n1,0.5,0.1,two\n"),
        "kc.csv:2:11: column \"k\": \"two\" is not a number"
    );
}

#[test]
fn refuses_rows_of_another_length() {
    assert_eq!(
        refusal("face,value,u\n1,0.5\n"),
        "kc.csv:2:6: row has 2 fields but the header has 3: no value for column \"u\""
    );
    assert_eq!(
        refusal("face,value,u\n1,0.5,0.1,9\n"),
        "kc.csv:2:11: row has 4 fields but the header has 3: extra field \"9\""
    );
}

#[test]
fn refuses_a_header_that_does_not_describe_the_table() {
    assert_eq!(
        refusal("face,Value,u\n1,0.5,0.1\n"),
        "kc.csv:1:6: column \"Value\" is not a known column name but looks like \"value\"; \
         names are exact (lower case, no spaces)"
    );
    assert_eq!(
        refusal("face,value,u,face\n"),
        "kc.csv:1:14: column \"face\" appears twice in the header (first at column 1)"
    );
    assert_eq!(
        refusal("face,u,note\n1,0.1,x\n"),
        "kc.csv:1:1: missing required column \"value\"; the header has \"face\", \"u\", \"note\""
    );
    assert_eq!(
        refusal("value\n1\n"),
        "kc.csv:1:1: missing required columns \"face\", \"u\"; the header has \"value\""
    );
}

#[test]
fn refuses_a_table_without_rows_and_says_so() {
    let empty = |text: &str| match read(text) {
        Err(e) => (e.to_string(), e.is_empty_table()),
        Ok(faces) => panic!("accepted: {faces:?}"),
    };
    assert_eq!(
        empty(""),
        (
            "kc.csv:1:1: empty file: expected a header row naming the columns face, value, u"
                .to_string(),
            true
        )
    );
    assert_eq!(
        empty("# a comment\n\n# another\n").0,
        "kc.csv:4:1: no header row: the file has only comment lines; expected a header row \
         naming the columns face, value, u"
    );
    assert_eq!(
        empty("\nface,value,u\n\n"),
        (
            "kc.csv:2:1: no data rows after the header".to_string(),
            true
        )
    );
    assert_eq!(
        empty("face,value,u\n1,x,0.1\n"),
        (
            "kc.csv:2:3: column \"value\": \"x\" is not a number".to_string(),
            false
        )
    );
}

#[test]
fn refuses_bytes_that_are_not_text_and_lines_of_too_many_fields() {
    let err = Reader::open(b"face,value,u\n1,\xff,2\n", "kc.csv", &KEY_COMPARISON)
        .err()
        .unwrap();
    assert_eq!(
        err.to_string(),
        "kc.csv:2:3: not valid UTF-8 (byte 0xff); the file must be UTF-8 text"
    );
    let wide = format!("face,value,u\n1{}\n", ",".repeat(2000));
    assert!(refusal(&wide).starts_with("kc.csv:2:1025: a line of more than 1024 fields"));
}

#[test]
fn locates_a_row_field_for_the_kind_s_own_rules() {
    let text = "face,note,value,u\n1,a,0.5,0.1\n\n2,\"\",\"0.25\",0.1\n";
    let mut table = Reader::open(text.as_bytes(), "kc.csv", &KEY_COMPARISON).unwrap();
    let mut faces = Vec::new();
    while let Some(row) = table.next_row().unwrap() {
        faces.push(Face {
            face: row.integer(FACE).unwrap(),
            value: row.number(VALUE).unwrap(),
            u: row.number(U).unwrap(),
            k: row.number(K).unwrap(),
            line: row.line(),
        });
    }
    let positions = table.finish();
    let loc = Locator::File(&positions);
    assert_eq!(loc.row(1, &faces, VALUE), (4, 6));
    assert_eq!(loc.row(1, &faces, K), (4, 1)); // not in the header: the row's start
    assert_eq!(loc.row_start(0, &faces), (2, 1));
    assert_eq!(loc.header(U), (1, 17));
    assert_eq!(loc.header_start(), (1, 1));
    assert_eq!(loc.field_text(1, VALUE).as_deref(), Some("0.25"));
    assert_eq!(loc.shown(1, VALUE).as_deref(), Some("\"0.25\""));
    assert_eq!(loc.field_text(1, K), None);
    assert_eq!(
        (loc.name(0, &faces), loc.prefix(0, &faces)),
        ("line 2".into(), String::new())
    );

    let memory = Locator::Memory;
    let built = [Face {
        face: 1,
        value: 0.0,
        u: 1.0,
        k: 2.0,
        line: 0,
    }];
    assert_eq!(memory.row(0, &built, VALUE), (0, 0));
    assert_eq!(memory.prefix(0, &built), "reading 1: ");
    assert_eq!(memory.name(0, &built), "reading 1");
    assert_eq!(memory.no_rows(), "no readings");
}

#[test]
fn extra_fields_of_digits_in_a_row_without_points_suggest_decimal_commas() {
    // `0,5` and `0,1` written with decimal commas: five fields for three
    let message = refusal("face,value,u\n1,0,5,0,1\n");
    assert!(
        message.starts_with("kc.csv:2:7: row has 5 fields but the header has 3: extra field \"0\"; if its numbers are written with decimal commas (1,5)"),
        "{message}"
    );
}
