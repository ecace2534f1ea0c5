//! `polycal plan --plot DIR` (docs/FORMAT.md §5.6): the two figures, one series per design,
//! read back from the SVG; a regular file where the directory goes is refused.

use std::path::Path;

use crate::plan_cli_support::{f64s, json_lines, one_error_line, polycal, stderr, temp_dir};

/// The points (`g` of class `point`) of an SVG figure: (series, index, y).
fn points(path: &Path) -> Vec<(String, usize, f64)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let doc =
        roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    doc.descendants()
        .filter(|n| n.has_tag_name("g") && n.attribute("class") == Some("point"))
        .map(|n| {
            let series = n.attribute("data-series").expect("data-series").to_string();
            let index = n
                .attribute("data-index")
                .expect("data-index")
                .parse()
                .unwrap();
            let transform = n.attribute("transform").expect("transform");
            let inner = transform
                .strip_prefix("translate(")
                .and_then(|t| t.strip_suffix(')'))
                .unwrap_or_else(|| panic!("a translate: {transform}"));
            let y: f64 = inner.split(',').nth(1).unwrap().trim().parse().unwrap();
            (series, index, y)
        })
        .collect()
}

/// 7. `--plot DIR`: the two figures, one series per design; a regular file is refused.
#[test]
fn plot_writes_one_series_per_design_and_refuses_a_file() {
    let dir = temp_dir("plot");
    let plots = dir.join("figures");
    let plots_text = plots.display().to_string();
    let designs = [
        "--design",
        "name=A",
        "--design",
        "name=B;ac-faces=1,2,5;cycles=3",
        "--closing",
    ];
    let mut args = vec!["plan", "--sigma", "0.05", "--plot", &plots_text];
    args.extend_from_slice(&designs);
    let out = polycal(&args);
    assert_eq!(out.status.code(), Some(0), "stderr:\n{}", stderr(&out));
    for name in ["plan-encoder-error-u.svg", "plan-pitch-deviation-u.svg"] {
        assert!(plots.join(name).is_file(), "{name} written");
    }

    let alpha = points(&plots.join("plan-encoder-error-u.svg"));
    let series0: Vec<&(String, usize, f64)> = alpha.iter().filter(|p| p.0 == "0").collect();
    let series1: Vec<&(String, usize, f64)> = alpha.iter().filter(|p| p.0 == "1").collect();
    assert_eq!(series0.len(), 24, "one point per position of design A");
    assert!(!series1.is_empty(), "design B drawn");
    let mut indices: Vec<usize> = series0.iter().map(|p| p.1).collect();
    indices.sort_unstable();
    assert_eq!(indices, (0..24).collect::<Vec<_>>());
    let beta = points(&plots.join("plan-pitch-deviation-u.svg"));
    assert!(beta.iter().any(|p| p.0 == "0") && beta.iter().any(|p| p.0 == "1"));

    // every u(α) of B below every u(α) of A (from the JSON of the same designs) puts
    // every point of B lower on the chart (a larger y in SVG coordinates)
    let mut args = vec!["plan", "--sigma", "0.05", "--format", "json"];
    args.extend_from_slice(&designs);
    let lines = json_lines(&args, 0);
    let u_a = f64s(&lines[0]["encoder_error_u"], "A");
    let u_b = f64s(&lines[1]["encoder_error_u"], "B");
    let min_a = u_a.iter().copied().fold(f64::INFINITY, f64::min);
    let max_b = u_b.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!(max_b < min_a, "B's u(α) {max_b} below A's {min_a}");
    let lowest_a = series0
        .iter()
        .map(|p| p.2)
        .fold(f64::NEG_INFINITY, f64::max);
    let highest_b = series1.iter().map(|p| p.2).fold(f64::INFINITY, f64::min);
    assert!(
        highest_b > lowest_a,
        "B's points (y ≥ {highest_b}) lie below A's (y ≤ {lowest_a})"
    );

    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    let file_text = file.display().to_string();
    let err = one_error_line(&polycal(&["plan", "--sigma", "0.05", "--plot", &file_text]));
    assert!(err.contains("is a file, not a directory"), "{err}");
    assert!(file.is_file(), "the file is left as it was");
}
