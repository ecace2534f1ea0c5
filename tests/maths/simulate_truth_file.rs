//! Tests of the simulator against hand-derived expectations: the truth file. A drawn
//! truth is written and read back equal, the smallest file is read (the effects' JSON
//! too), bad files are refused naming the file — and, when it is not JSON, the line and
//! column — and a truth with the models and the new effects round-trips, every key of it
//! documented in docs/FORMAT.md.

use std::path::PathBuf;

use polycal::effects::Effect;
use polycal::simulate::{ElevationModel, SimulateError, SimulationConfig, Truth};
use polycal::{Direction, Reading};

use crate::simulate_support::air_conditioned_lab;

fn temp_file(name: &str, contents: &str) -> PathBuf {
    let path = std::env::temp_dir().join(format!(
        "polycal-test-simulate-{}-{name}",
        std::process::id()
    ));
    std::fs::write(&path, contents).unwrap();
    path
}

// ---------------------------------------------------------------- truth file

#[test]
fn truth_json_round_trip() {
    let config = SimulationConfig {
        setups: 2,
        bidirectional: true,
        effects: vec![
            Effect::Drift {
                ac: 1,
                value: 0.1,
                quadratic: None,
            },
            Effect::Direction {
                ac: None,
                value: 0.2,
            },
            Effect::Outlier {
                cycle: 2,
                step: 3,
                ac: 2,
                setup: Some(1),
                value: 1.5,
            },
        ],
        ..SimulationConfig::default()
    };
    let truth = Truth::draw(&config).unwrap();
    let json = truth.to_json_pretty();
    let back: Truth = serde_json::from_str(&json).unwrap();
    assert_eq!(back, truth);
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(value["faces"], 24);
    assert_eq!(value["pitch_deviation"].as_array().unwrap().len(), 24);
    assert_eq!(value["encoder_error"].as_array().unwrap().len(), 24);
    assert_eq!(
        value["effects"][1],
        serde_json::json!({"kind": "direction", "value": 0.2})
    );

    let path = temp_file("roundtrip.json", &json);
    let read = Truth::read_path(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(read, truth);
}

#[test]
fn minimal_truth_file_and_effect_json() {
    let path = temp_file(
        "minimal.json",
        r#"{"faces": 3, "pitch_deviation": [0.5, -0.25, -0.25], "encoder_error": [0.1, 0.2, -0.3],
            "effects": [{"kind": "offset-step", "ac": 2, "cycle": 4, "value": 0.5, "u": 0.01}],
            "comment": "extra fields are fine"}"#,
    );
    let truth = Truth::read_path(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(truth.face_deviation, vec![0.5, 0.25, 0.0]);
    assert!(truth.setup_error.is_empty());
    assert_eq!(truth.noise_arcsec, None);
    assert_eq!(
        truth.effects,
        vec![Effect::OffsetStep {
            ac: 2,
            cycle: 4,
            step: None,
            setup: None,
            value: 0.5
        }]
    );
    assert_eq!(
        serde_json::to_string(&truth.effects[0]).unwrap(),
        r#"{"kind":"offset-step","ac":2,"cycle":4,"value":0.5}"#
    );
    let outlier = Effect::Outlier {
        cycle: 1,
        step: 2,
        ac: 1,
        setup: None,
        value: 3.0,
    };
    assert_eq!(
        serde_json::to_string(&outlier).unwrap(),
        r#"{"kind":"outlier","cycle":1,"step":2,"ac":1,"value":3.0}"#
    );

    // model_reading with no setup errors: α + φ; a face outside 1 … N gives NaN.
    let mut r = Reading {
        setup: 1,
        cycle: 1,
        step: 4,
        ac: 1,
        face: 2,
        reading_arcsec: 0.0,
        direction: Direction::Cw,
        time_seconds: None,
        reading_y_arcsec: None,
        temperature_celsius: None,
        encoder_degrees: None,
        line: 0,
    };
    assert_eq!(truth.model_reading(&r), 0.2 + 0.25);
    r.face = 4;
    assert!(truth.model_reading(&r).is_nan());
}

#[test]
fn bad_truth_files_are_refused_naming_the_file() {
    let missing = std::env::temp_dir().join("polycal-test-simulate-does-not-exist.json");
    let err = Truth::read_path(&missing).unwrap_err();
    assert!(matches!(err, SimulateError::Io { .. }));
    assert!(err.to_string().contains("does-not-exist.json"), "{err}");

    let cases = [
        (
            "syntax.json",
            "{\"faces\": 3,\n \"pitch_deviation\": [1, 2,,]}",
            "syntax.json:2:27:",
        ),
        (
            "missing.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0]}"#,
            "encoder_error",
        ),
        (
            "null.json",
            r#"{"faces": 3, "pitch_deviation": [0, null, 0], "encoder_error": [0, 0, 0]}"#,
            "null.json:1:",
        ),
        (
            "length.json",
            r#"{"faces": 4, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0, 0]}"#,
            "pitch_deviation has 3 values",
        ),
        (
            "facelen.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0], "face_deviation": [0]}"#,
            "face_deviation",
        ),
        (
            "faces.json",
            r#"{"faces": 2, "pitch_deviation": [0, 0], "encoder_error": [0, 0]}"#,
            "faces",
        ),
        (
            "huge.json",
            r#"{"faces": 3, "pitch_deviation": [0, 1e999, 0], "encoder_error": [0, 0, 0]}"#,
            "",
        ),
        (
            "setup.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0],
                "setup_error": [{"setup": 1, "ac": 1, "value": 0}, {"setup": 1, "ac": 1, "value": 1}]}"#,
            "twice",
        ),
        (
            "effect.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0],
                "effects": [{"kind": "wobble", "value": 1}]}"#,
            "wobble",
        ),
        ("empty.json", "", "empty.json:1"),
    ];
    for (name, text, needle) in cases {
        let path = temp_file(name, text);
        let err = Truth::read_path(&path).unwrap_err();
        std::fs::remove_file(&path).ok();
        let msg = err.to_string();
        assert!(msg.contains(name), "{msg:?} lacks the file name");
        assert!(msg.contains(needle), "{msg:?} lacks {needle:?}");
    }
}

/// A truth file that is not JSON is refused with its file, line and column.
#[test]
fn a_bad_truth_file_is_refused_with_line_and_column() {
    let path = std::env::temp_dir().join(format!("polycal-bad-truth-{}.json", std::process::id()));
    std::fs::write(&path, "{\"faces\": 24,\n \"pitch_deviation\": [1,2,}").unwrap();
    let err = polycal::simulate::Truth::read_path(&path).unwrap_err();
    let _ = std::fs::remove_file(&path);
    assert_eq!(
        err.to_string(),
        format!(
            "{}:2:26: not a valid truth file: expected value",
            path.display()
        )
    );
}

// ---------------------------------------------------------------- the truth file with the additions

#[test]
fn truth_with_the_additions_round_trips_and_is_documented() {
    let config = SimulationConfig {
        setups: 2,
        bidirectional: true,
        temperature: Some(air_conditioned_lab()),
        elevation: Some(ElevationModel::default()),
        noise_student_dof: Some(6.0),
        effects: vec![
            Effect::Drift {
                ac: 1,
                value: 0.1,
                quadratic: Some(0.02),
            },
            Effect::OffsetStep {
                ac: 2,
                cycle: 2,
                step: Some(3),
                setup: Some(1),
                value: 0.4,
            },
            Effect::Temperature { ac: 1, value: 0.2 },
            Effect::CrossTalk { ac: 2, value: 0.01 },
        ],
        ..SimulationConfig::default()
    };
    let truth = Truth::draw(&config).unwrap();
    let json = truth.to_json_pretty();
    let path = temp_file("additions.json", &json);
    let read = Truth::read_path(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(read, truth);
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        value["effects"][1],
        serde_json::json!({"kind": "offset-step", "ac": 2, "cycle": 2, "step": 3, "setup": 1, "value": 0.4})
    );
    assert_eq!(
        value["effects"][3],
        serde_json::json!({"kind": "cross-talk", "ac": 2, "value": 0.01})
    );
    // Every key of the truth file is a code span in docs/FORMAT.md.
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/FORMAT.md")).unwrap();
    fn keys(v: &serde_json::Value, out: &mut Vec<String>) {
        match v {
            serde_json::Value::Object(map) => {
                for (k, v) in map {
                    out.push(k.clone());
                    keys(v, out);
                }
            }
            serde_json::Value::Array(list) => list.iter().for_each(|v| keys(v, out)),
            _ => {}
        }
    }
    let mut all = Vec::new();
    keys(&value, &mut all);
    let missing: Vec<&String> = all
        .iter()
        .filter(|k| !doc.contains(&format!("`{k}`")))
        .collect();
    assert!(missing.is_empty(), "not in docs/FORMAT.md: {missing:?}");
}
