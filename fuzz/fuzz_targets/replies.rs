//! The instruments' reply parsers (docs/FORMAT.md §7.1–7.2) on one line, read as the
//! transport reads it (bytes that are not UTF-8 replaced). What a parser accepts must be
//! what the protocol allows.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::lab::elcomat::{parse_identification, parse_measurement};
use polycal::lab::smc100::{parse_last_error, parse_position, parse_status, parse_version};

fuzz_target!(|data: &[u8]| {
    let line = String::from_utf8_lossy(data);
    if let Ok(text) = parse_identification(&line) {
        assert!(!text.trim().is_empty());
    }
    for kind in ['4', '2'] {
        if let Ok(r) = parse_measurement(&line, kind) {
            assert!(r.x_arcsec.is_finite() && r.y_arcsec.is_none_or(f64::is_finite));
        }
    }
    let _ = parse_status(&line).map_err(|e| e.to_string());
    if let Ok(position) = parse_position(&line) {
        assert!(position.is_finite());
    }
    if let Ok(code) = parse_last_error(&line) {
        assert!(code == '@' || code.is_ascii_uppercase());
    }
    let _ = parse_version(&line).map_err(|e| e.to_string());
});
