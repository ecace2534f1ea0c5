//! What the tests of the documents (`tests/commands/report_*.rs`,
//! `tests/commands/certificate_dcc.rs`) share: the binary run from the repository root, a
//! fresh temporary directory, and a command's JSON.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

/// `polycal ARGS`, run in the repository root.
pub fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

/// An empty directory of this test process, `polycal-<kind>-<pid>-<name>`.
pub fn temp_dir(kind: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-{kind}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The JSON a command prints (status 0 or 1).
pub fn json(args: &[&str]) -> Value {
    let out = polycal(args);
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

/// Significant digits of a decimal text (`0.10` → 2, `1.99` → 3, `12.7` → 3); a text
/// without a point counts its trailing zeros too.
fn significant_digits(text: &str) -> usize {
    let digits: String = text.chars().filter(char::is_ascii_digit).collect();
    digits.trim_start_matches('0').len()
}

/// Digits after the decimal point of a text (0 without a point).
fn decimals(text: &str) -> i32 {
    text.split_once('.').map_or(0, |(_, d)| d.len() as i32)
}

/// Parses a number as the documents show it (a true minus sign in the HTML).
pub fn shown_number(text: &str) -> f64 {
    text.replace('−', "-")
        .parse()
        .unwrap_or_else(|_| panic!("not a number: {text:?}"))
}

/// Asserts that a value and its U are stated as GUM 7.2.6 says, from the definition
/// (docs/FORMAT.md §10.4): U with two significant digits, rounded up — not below the
/// evaluated U, and above it by less than one unit of its last digit —; the value with
/// U's decimals, within half a unit of that digit of the evaluated value.
pub fn assert_gum_rounded(value_text: &str, u_text: &str, value: f64, u: f64, what: &str) {
    let (v, shown_u) = (shown_number(value_text), shown_number(u_text));
    assert!(u > 0.0, "{what}: U {u}");
    assert_eq!(significant_digits(u_text), 2, "{what}: U {u_text} of {u}");
    let unit = 10f64.powi(-decimals(u_text));
    assert!(
        shown_u >= u * (1.0 - 1e-12) && shown_u - u < unit * (1.0 + 1e-9),
        "{what}: U {u_text} is not {u} rounded up"
    );
    assert_eq!(
        decimals(value_text),
        decimals(u_text),
        "{what}: value {value_text} and U {u_text} end at one decimal place"
    );
    assert!(
        (v - value).abs() <= unit / 2.0 * (1.0 + 1e-9),
        "{what}: {value_text} is not {value} rounded at 10^-{}",
        decimals(u_text)
    );
}

/// Asserts that a coverage factor is stated with three significant digits, within half
/// a unit of its last digit of k.
pub fn assert_k_rounded(k_text: &str, k: f64, what: &str) {
    assert_eq!(significant_digits(k_text), 3, "{what}: k {k_text} of {k}");
    let unit = 10f64.powi(-decimals(k_text));
    assert!(
        (shown_number(k_text) - k).abs() <= unit / 2.0 * (1.0 + 1e-9),
        "{what}: k {k_text} is not {k} rounded"
    );
}

/// `polycal report` of the bundled run (budget, metadata) with `--kc KC` and `extra`,
/// its HTML into `dir/r.html` and its DCC into `dir/c.xml`: status 0 and the DCC valid
/// against the schema asserted; the HTML parsed and the DCC's text returned.
pub fn report_with_kc(dir: &Path, kc: &Path, extra: &[&str]) -> (scraper::Html, String) {
    let html_path = dir.join("r.html");
    let dcc_path = dir.join("c.xml");
    let mut args = vec![
        "report",
        "examples/data/polygon24-2ac-6cycles.csv",
        "--budget",
        "examples/budgets/instrument.toml",
        "--meta",
        "examples/report/meta.toml",
        "--kc",
        kc.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    args.extend_from_slice(&[
        "--out",
        html_path.to_str().unwrap(),
        "--dcc",
        dcc_path.to_str().unwrap(),
    ]);
    let out = polycal(&args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    crate::dcc_schema::assert_valid(&dcc_path);
    (
        scraper::Html::parse_document(&std::fs::read_to_string(&html_path).unwrap()),
        std::fs::read_to_string(&dcc_path).unwrap(),
    )
}
