//! The measurement file and the self-calibration file are read by one table reader
//! (`input::table`): a rule of the header or of a row's shape refuses both the same way,
//! with the same message at the same place.

use polycal::measurement::MeasurementSet;
use polycal::selfcal::SelfcalSet;

const MEASUREMENT_HEADER: &str = "cycle,step,ac,face,reading";
const SELFCAL_HEADER: &str = "cycle,step,head,head_angle,reading";

/// The refusals of a measurement file and of a self-calibration file whose text is
/// `before` + the kind's header + `after`.
fn both(before: &str, after: &str) -> (String, String) {
    let measurement = format!("{before}{MEASUREMENT_HEADER}{after}");
    let selfcal = format!("{before}{SELFCAL_HEADER}{after}");
    let m = MeasurementSet::read_from(measurement.as_bytes(), "in.csv", None)
        .expect_err("measurement file accepted")
        .to_string();
    let s = SelfcalSet::read_from(selfcal.as_bytes(), "in.csv", None)
        .expect_err("self-calibration file accepted")
        .to_string();
    (m, s)
}

#[test]
fn a_near_miss_of_a_column_name_is_refused_in_both_files_alike() {
    for (name, like) in [
        ("Cycle", "cycle"),
        ("STEP", "step"),
        (" reading", "reading"),
        ("Direction", "direction"),
        ("time ", "time"),
    ] {
        let (m, s) = both(&format!("# run\n{name},"), "\n");
        let expected = format!(
            "in.csv:2:1: column {name:?} is not a known column name but looks like \
             {like:?}; names are exact (lower case, no spaces)"
        );
        assert_eq!(m, expected);
        assert_eq!(s, expected);
    }
    // The kind's own columns are known to that kind only: `Head-Angle` is a near miss in
    // a self-calibration file, an unknown (ignored) column in a measurement file.
    let selfcal = format!("Head-Angle,{SELFCAL_HEADER}\n");
    let err = SelfcalSet::read_from(selfcal.as_bytes(), "in.csv", None).unwrap_err();
    assert!(err.to_string().starts_with(
        "in.csv:1:1: column \"Head-Angle\" is not a known column name but looks like \
         \"head_angle\""
    ));
}

#[test]
fn a_column_named_twice_or_a_row_of_another_length_is_refused_in_both_files_alike() {
    let (m, s) = both("time,", ",time\n");
    assert!(m.starts_with("in.csv:1:"), "{m}");
    assert_eq!(
        (
            m.split_once(": ").map(|x| x.1),
            s.split_once(": ").map(|x| x.1)
        ),
        (
            Some("column \"time\" appears twice in the header (first at column 1)"),
            Some("column \"time\" appears twice in the header (first at column 1)")
        )
    );
    let (m, s) = both("note,", "\nx,1,0,1,1,0.5\n\n  \ny,1,0,1,1\n");
    let expected = "in.csv:5:10: row has 5 fields but the header has 6: no value for column \
                    \"reading\"";
    assert_eq!((m.as_str(), s.as_str()), (expected, expected));
    let (m, s) = both("", "\n");
    assert_eq!(m, "in.csv:1:1: no data rows after the header");
    assert_eq!(s, m);
}

#[test]
fn a_field_breaking_a_shared_number_rule_is_refused_in_both_files_alike() {
    // Columns of the same name and kind (cycle, step, reading, time, direction) share
    // their rule and message.
    for (fields, expected) in [
        (
            "-1,0",
            "in.csv:2:1: column \"cycle\": \"-1\" is not allowed; cycle must be at least 1",
        ),
        (
            "1,x",
            "in.csv:2:3: column \"step\": \"x\" is not an integer",
        ),
        (
            "99999999999,0",
            "in.csv:2:1: column \"cycle\": \"99999999999\" is too large; cycle must be at most \
             4294967295",
        ),
    ] {
        let (m, s) = both("", &format!("\n{fields},1,1,1\n"));
        assert_eq!((m.as_str(), s.as_str()), (expected, expected));
    }
    let (m, s) = both("time,direction,", "\n1e10,cw,1,0,1,1,0.5\n");
    let expected = "in.csv:2:1: column \"time\": \"1e10\" is beyond the limits of a time, \
                    −1e9 … 1e9 s (docs/FORMAT.md §2.2)";
    assert_eq!((m.as_str(), s.as_str()), (expected, expected));
    let (m, s) = both("time,direction,", "\n1,up,1,0,1,1,0.5\n");
    let expected = "in.csv:2:3: column \"direction\": \"up\" is not a direction; use \"cw\" or \
                    \"ccw\"";
    assert_eq!((m.as_str(), s.as_str()), (expected, expected));
}
