//! Every bundled profile's reply templates (docs/FORMAT.md §7, docs/instruments.md) on one
//! line, read as the transport reads it (bytes that are not UTF-8 replaced). What a
//! template accepts must be what the profile allows: a valid reading's X and a position
//! are finite numbers.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::lab::profile::{BUNDLED, Profile, ProfileKind};

fuzz_target!(|data: &[u8]| {
    let line = String::from_utf8_lossy(data);
    for (name, _, _) in BUNDLED {
        let Ok(profile) = Profile::load(name) else {
            continue;
        };
        for refusal in &profile.line.refusals {
            let _ = refusal.matches(&line);
        }
        match &profile.kind {
            ProfileKind::Autocollimator(ac) => {
                let _ = ac.identify.reply.matches(&line);
                if let Some(c) = ac.measure.reply.matches(&line)
                    && ac.x_valid.holds(&ac.measure.reply, &c)
                {
                    assert!(c.number("x").is_some());
                }
            }
            ProfileKind::Table(table) => {
                let _ = table.identify.reply.matches(&line);
                let _ = table.state.query.reply.matches(&line);
                if let Some(c) = table.position.reply.matches(&line) {
                    assert!(c.number("deg").is_some());
                }
            }
            _ => {}
        }
    }
});
