//! The report's metadata TOML (docs/FORMAT.md §10.2), with the same bytes as the
//! measurement file whose comment lines are read too.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::certificate::meta::gather;
use polycal_fuzz::{SOURCE, accepted};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = accepted(
        gather(Some((text, SOURCE)), (text, "measurement.csv"), None),
        SOURCE,
        data,
    );
});
