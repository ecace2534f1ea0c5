//! The budget TOML of `polycal budget` (docs/FORMAT.md §5.3): read (by path, so that
//! bytes that are not UTF-8 reach the reader too), then evaluated.
#![no_main]

use libfuzzer_sys::fuzz_target;
use polycal::uncertainty::{BudgetFile, budget_table};
use polycal_fuzz::{SOURCE, accepted, scratch_file};

fuzz_target!(|data: &[u8]| {
    let budget = match std::str::from_utf8(data) {
        Ok(text) => accepted(BudgetFile::from_toml_str(text, SOURCE), SOURCE, data),
        Err(_) => {
            let path = scratch_file("budget.toml", data);
            accepted(
                BudgetFile::read_path(&path),
                &path.display().to_string(),
                data,
            )
        }
    };
    if let Some(result) = budget.and_then(|b| b.evaluate().ok()) {
        let _ = budget_table(&result).to_string();
    }
});
