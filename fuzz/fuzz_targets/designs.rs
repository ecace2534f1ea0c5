//! The designs TOML of `polycal plan --designs` (docs/FORMAT.md §5.6): read (by path, so
//! that bytes that are not UTF-8 reach the reader too); every accepted design of at most
//! 800 readings is planned (its uncertainties, not what a diagnosis can see, which takes
//! half a second a design).
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::measurement::Sigma;
use polycal::plan::{Design, PlanOptions, plan};
use polycal_fuzz::{SOURCE, accepted, scratch_file};

fuzz_target!(|data: &[u8]| {
    let base = Design::default();
    let designs = match std::str::from_utf8(data) {
        Ok(text) => accepted(Design::parse_designs_file(text, SOURCE, &base), SOURCE, data),
        Err(_) => {
            let path = scratch_file("designs.toml", data);
            accepted(
                Design::read_designs_file(&path, &base),
                &path.display().to_string(),
                data,
            )
        }
    };
    let Ok(sigma) = Sigma::new(0.05) else {
        return;
    };
    for design in designs.iter().flatten() {
        if design.reading_count() > 800 {
            continue;
        }
        let options = PlanOptions::new(sigma)
            .with_detect(false)
            .with_memory_limit(1 << 30);
        let _ = plan(design, &options);
    }
});
