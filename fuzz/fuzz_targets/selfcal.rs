//! The self-calibration CSV (docs/FORMAT.md §9.2): read, then solved.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::selfcal::{SelfcalOptions, SelfcalSet, solve};
use polycal_fuzz::{SOURCE, accepted};

fuzz_target!(|data: &[u8]| {
    let Some(set) = accepted(SelfcalSet::read_from(data, SOURCE, None), SOURCE, data) else {
        return;
    };
    if set.readings.len() <= 2000 {
        let _ = solve(&set, &SelfcalOptions::new());
    }
});
