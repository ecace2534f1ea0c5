//! `polycal budget` end to end: the paper's Table 1 (docs/FORMAT.md §5 JSON), with
//! unrounded arithmetic.

use serde_json::Value;

use crate::cli_support::{assert_status, polycal};

/// `budget` on the paper's Table 1 (docs/FORMAT.md §5 JSON): u_c = 0.22867″ unrounded,
/// ν_eff = 72.6 (the paper prints 74, which only its rounded 0.23″ gives), k = 1.993
/// with fractional ν (the paper uses 2.00), U = 0.456″ (printed 0.46″).
#[test]
fn budget_reproduces_paper_table_1() {
    let out = polycal(&[
        "budget",
        "examples/budgets/paper-table1.toml",
        "--format",
        "json",
    ]);
    assert_status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let get = |k: &str| json[k].as_f64().unwrap();
    assert!((get("combined_u") - 0.2287).abs() < 5e-5);
    assert!((get("dof_eff") - 72.6).abs() < 0.05);
    assert!((get("k") - 1.993).abs() < 5e-4);
    assert!((get("expanded_u") - 0.456).abs() < 5e-4);
    assert_eq!(json["dof_policy"], "fractional");
    assert_eq!(json["p"], 0.95);
    let table =
        String::from_utf8(polycal(&["budget", "examples/budgets/paper-table1.toml"]).stdout)
            .unwrap();
    assert!(table.contains("ν_eff = 72.6"), "{table}");
}
