//! The self-calibration truth JSON (docs/FORMAT.md §4.1): read from a file, then asked
//! for its values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::simulate::SelfcalTruth;
use polycal_fuzz::{accepted, scratch_file};

fuzz_target!(|data: &[u8]| {
    let path = scratch_file("selfcal-truth.json", data);
    let Some(truth) = accepted(
        SelfcalTruth::read_path(&path),
        &path.display().to_string(),
        data,
    ) else {
        return;
    };
    for angle in [0.0, 2.5, 90.0, 359.999_999_9, 360.0, -1.0] {
        let _ = truth.encoder_error_at_deg(angle);
    }
    for head in 0..=13 {
        let _ = truth.head_error_of(head);
    }
    for (cycle, step) in [(0, 0), (1, 0), (2, 167), (9, 1000)] {
        let _ = truth.table_error_at(cycle, step);
    }
    let _ = truth.to_json_pretty();
});
