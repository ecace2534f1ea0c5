//! The truth JSON of `diagnose --truth` (docs/FORMAT.md §4): read from a file, then asked
//! for its values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::simulate::Truth;
use polycal_fuzz::{accepted, scratch_file};

fuzz_target!(|data: &[u8]| {
    let path = scratch_file("truth.json", data);
    let Some(truth) = accepted(Truth::read_path(&path), &path.display().to_string(), data) else {
        return;
    };
    for face in 0..=truth.faces.saturating_add(1).min(1000) {
        let _ = truth.face_deviation_at(face);
    }
    for angle in [0.0, 7.5, 180.0, 359.999_999_9, 360.0, -15.0] {
        let _ = truth.encoder_error_at_deg(angle);
    }
    let _ = truth.to_json_pretty();
});
