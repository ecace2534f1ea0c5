//! The figures of `polycal kc` (docs/FORMAT.md §12), the classic ones of a key
//! comparison's report: every laboratory's degree of equivalence d_i with its U(d_i) bar
//! around zero per face (`kc-degrees-of-equivalence`; laboratories left out say so in the
//! legend); the reference value per face with its expanded uncertainty 2·u_ref and every
//! laboratory's value x_i = x_ref + d_i (`kc-reference`); the pairwise degrees of
//! equivalence as a matrix of the laboratories (`kc-pairwise`); and with the pilot's
//! repeats each repeat's d_r with U(d_r) (`kc-pilot-stability`). Every laboratory has its
//! own marker and colour, the same in every figure; the reference is black.
//!
//! Classes (docs/FORMAT.md §10): `point` and `error-bar` in panel `main`, with
//! `data-series` `lab<i>` (laboratory i of `labs`, from 0), `reference`, or `repeat<r>`
//! (repeat r of `pilot.repeats`), and `data-index` the position in `index`.

use super::Figure;
use super::chart::{Chart, Point, Series};
use super::svg::{LEFT_PX, Marker, RIGHT_PX, WIDTH_PX, document, esc, header_px, px};
use crate::kc::{DegreeOfEquivalence, KeyComparison};
use crate::results::Quantity;

/// The fixed names of the figures, and the pilot's.
pub(crate) const NAMES: [&str; 3] = ["kc-degrees-of-equivalence", "kc-reference", "kc-pairwise"];
/// The pilot's figure.
pub(crate) const PILOT: &str = "kc-pilot-stability";

/// The markers of successive repeats, in turn.
const MARKERS: [Marker; 2] = [Marker::FilledCircle, Marker::OpenSquare];
/// Laboratory i's own marker and colour, the same in every figure (left out or not).
fn lab_marker(i: usize) -> Marker {
    Marker::Lab(u16::try_from(i).unwrap_or(u16::MAX))
}

/// x of position k: its table angle when matched by angle, else face or index.
fn x_of(kc: &KeyComparison, k: usize) -> f64 {
    match &kc.angle_deg {
        Some(angles) => angles[k],
        None => f64::from(kc.index[k]),
    }
}

fn words(kc: &KeyComparison) -> (&'static str, &'static str, String) {
    match kc.quantity {
        Quantity::PitchDeviation => ("pitch deviations β", "β", "face".to_string()),
        Quantity::AngleBlock => (
            "angle blocks' deviations from nominal",
            "the block",
            "angle block".to_string(),
        ),
        _ if kc.angle_deg.is_some() => ("encoder errors α", "α", "table angle / °".to_string()),
        _ => (
            "encoder errors α",
            "α",
            "encoder position (index)".to_string(),
        ),
    }
}

/// Horizontal offsets spreading `n` series over ±(n − 1)·1.5 px.
fn offset_px(i: usize, n: usize, positions: usize) -> f64 {
    if positions > 200 {
        0.0
    } else {
        (i as f64 - (n as f64 - 1.0) / 2.0) * 3.0
    }
}

fn x_include(kc: &KeyComparison) -> Vec<f64> {
    if kc.angle_deg.is_some() {
        vec![0.0, 360.0]
    } else {
        Vec::new()
    }
}

/// One series of degrees of equivalence, d with U(d) bars.
fn doe_series(
    kc: &KeyComparison,
    id: String,
    label: String,
    marker: Marker,
    dx_px: f64,
    doe: &DegreeOfEquivalence,
) -> Series {
    Series {
        id,
        label,
        marker,
        dx_px,
        // (a block the laboratory does not report has no point, as it has no d)
        points: (0..kc.index.len())
            .filter(|&k| crate::kc::is_given(doe.d[k]))
            .map(|k| Point {
                index: k,
                x: x_of(kc, k),
                y: doe.d[k],
                half: Some(doe.expanded_u[k]),
            })
            .collect(),
    }
}

/// The figures of a key comparison (the pilot's only with its repeats).
pub(crate) fn figures(kc: &KeyComparison) -> Vec<Figure> {
    let mut out = vec![degrees_of_equivalence(kc), reference(kc), pairwise(kc)];
    if kc.pilot.is_some() {
        out.push(pilot(kc));
    }
    out
}

fn method_words(kc: &KeyComparison) -> String {
    let reference = kc.wording().reference();
    match kc.method {
        crate::kc::ReferenceMethod::WeightedMean if kc.wording().is_closed() => {
            format!("{reference} (the weighted mean with one u per laboratory)")
        }
        crate::kc::ReferenceMethod::WeightedMean => reference.to_string(),
        crate::kc::ReferenceMethod::MandelPaule => {
            format!("Mandel–Paule, u widened by τ, {reference}")
        }
        _ => format!("DerSimonian–Laird, u widened by τ, {reference}"),
    }
}

fn degrees_of_equivalence(kc: &KeyComparison) -> Figure {
    let (family, symbol, x_label) = words(kc);
    let title = format!("Degrees of equivalence d_i with U(d_i), {family}");
    let n = kc.degrees_of_equivalence.len();
    let series = kc
        .degrees_of_equivalence
        .iter()
        .enumerate()
        .map(|(i, doe)| {
            let marker = lab_marker(i);
            let label = if doe.in_reference {
                doe.lab.clone()
            } else {
                format!("{} (left out of the reference)", doe.lab)
            };
            doe_series(
                kc,
                format!("lab{i}"),
                label,
                marker,
                offset_px(i, n, kc.index.len()),
                doe,
            )
        })
        .collect();
    let left_out: Vec<&str> = kc.excluded.iter().map(|e| e.lab.as_str()).collect();
    let mut subtitles = vec![
        format!(
            "reference: {}; bars: U(d_i), k = 2; a bar not crossing 0 is |d_i| > U(d_i)",
            method_words(kc)
        ),
        "U(d_i) = 2·√(u_i² + u_stab² + τ² − u_ref²) in the reference, + u_ref² when left out"
            .to_string(),
    ];
    if !left_out.is_empty() {
        subtitles.push(format!(
            "left out: {}; reasons in the JSON's excluded",
            left_out.join(", ")
        ));
    }
    let chart = Chart {
        title: title.clone(),
        subtitles,
        x_label,
        y_label: format!("d_i of {symbol} / ″"),
        series,
        x_include: x_include(kc),
    };
    Figure::new(NAMES[0], title, chart.render())
}

fn reference(kc: &KeyComparison) -> Figure {
    let (family, symbol, x_label) = words(kc);
    let title = format!("Reference values x_ref with U, {family}");
    let n = kc.degrees_of_equivalence.len() + 1;
    let mut series = vec![Series {
        id: "reference".into(),
        label: "x_ref (bars: U = 2·u_ref)".into(),
        marker: Marker::FilledCircle,
        dx_px: offset_px(0, n, kc.index.len()),
        points: (0..kc.index.len())
            .map(|k| Point {
                index: k,
                x: x_of(kc, k),
                y: kc.reference[k],
                half: Some(2.0 * kc.reference_u[k]),
            })
            .collect(),
    }];
    for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
        series.push(Series {
            id: format!("lab{i}"),
            label: if doe.in_reference {
                doe.lab.clone()
            } else {
                format!("{} (left out)", doe.lab)
            },
            marker: lab_marker(i),
            dx_px: offset_px(i + 1, n, kc.index.len()),
            points: (0..kc.index.len())
                .filter(|&k| crate::kc::is_given(doe.d[k]))
                .map(|k| Point {
                    index: k,
                    x: x_of(kc, k),
                    y: kc.reference[k] + doe.d[k],
                    half: None,
                })
                .collect(),
        });
    }
    let chart = Chart {
        title: title.clone(),
        subtitles: vec![
            format!(
                "x_ref: {}; bars U = 2·u_ref (k = 2, with u_stab where the pilot's repeats call for it)",
                method_words(kc)
            ),
            "laboratories' values x_i = x_ref + d_i, each with its own marker and colour; no bars (their U(d_i) in kc-degrees-of-equivalence)"
                .to_string(),
        ],
        x_label,
        y_label: format!("{symbol} / ″"),
        series,
        x_include: x_include(kc),
    };
    Figure::new(NAMES[1], title, chart.render())
}

fn pilot(kc: &KeyComparison) -> Figure {
    let (family, symbol, x_label) = words(kc);
    let title = format!("The pilot's repeats of the {family} against the reference");
    let mut subtitles = vec![
        "each repeat's d_r = y_r − x_ref with U(d_r) = 2·√(u_r² + u_stab² + τ² + u_ref²), k = 2"
            .to_string(),
    ];
    let mut series = Vec::new();
    if let Some(pilot) = &kc.pilot {
        let n = pilot.degrees_of_equivalence.len();
        for (r, doe) in pilot.degrees_of_equivalence.iter().enumerate() {
            series.push(doe_series(
                kc,
                format!("repeat{r}"),
                doe.lab.clone(),
                MARKERS[r % 2],
                offset_px(r, n, kc.index.len()),
                doe,
            ));
        }
        // the one test of the repeats, in the words of the table and the documents
        if let Some(statement) = kc.pilot_statement() {
            subtitles.push(statement);
        }
    }
    let chart = Chart {
        title: title.clone(),
        subtitles,
        x_label,
        y_label: format!("d_r of {symbol} / ″"),
        series,
        x_include: x_include(kc),
    };
    Figure::new(PILOT, title, chart.render())
}

/// The pairwise degrees of equivalence as a Draft A report shows them: a matrix, one cell
/// per pair of laboratories, shaded when the pair's one closed-vector test at 5 % fails
/// ([`crate::kc::PairDifference::vector`]), with its χ²/ν, and as information the largest
/// |d_ij|/U(d_ij) over the positions (and where) and how many positions have
/// |d_ij| > U(d_ij) (by chance some do in a consistent pair: that is not the decision);
/// d_ij = x_i − x_j, U(d_ij) = 2·√(u_i² + u_j² + 2u_stab² + 2τ²). Every pair's d_ij and
/// U(d_ij) at every position are in the JSON's `pairs`.
///
/// Classes: `cell` with `data-a`, `data-b` (laboratories' positions in `labs`),
/// `data-chi2`, `data-dof`, `data-consistent` (the pair's test), `data-ratio` (the largest
/// |d|/U), `data-at` (its position in `index`) and `data-exceeding`.
fn pairwise(kc: &KeyComparison) -> Figure {
    let (family, _, _) = words(kc);
    let title = format!("Pairwise degrees of equivalence d_ij = x_i − x_j, {family}");
    let n = kc.labs.len();
    let position = |k: usize| match &kc.angle_deg {
        Some(angles) => format!("{:.4}°", angles[k]),
        None if kc.quantity == Quantity::PitchDeviation => format!("face {}", kc.index[k]),
        None => format!("index {}", kc.index[k]),
    };
    let subtitles = vec![
        "each cell: the pair's closed-vector χ²/ν, shaded when it fails its one test at 5 %; \
         as information the largest |d_ij|/U(d_ij) (where) and the positions with |d_ij| > U"
            .to_string(),
        format!(
            "U(d_ij) = 2·√(u_i² + u_j² + 2u_stab² + 2τ²), k = 2; {} positions; every d_ij with its U in the JSON's pairs",
            kc.index.len()
        ),
    ];
    let top = header_px(&subtitles) + 24.0;
    let label_px = 110.0;
    let cell_px = ((WIDTH_PX - LEFT_PX - RIGHT_PX - label_px) / n.max(1) as f64).clamp(14.0, 90.0);
    let font = (cell_px / 6.0).clamp(5.0, 10.0);
    let left = LEFT_PX + label_px;
    let mut body = String::new();
    use std::fmt::Write;
    for (i, name) in kc.labs.iter().enumerate() {
        let _ = writeln!(
            body,
            r#"<text class="row-label" x="{}" y="{}" font-size="10" text-anchor="end">{}</text>"#,
            px(left - 6.0),
            px(top + (i as f64 + 0.5) * cell_px + 3.5),
            esc(name)
        );
        let _ = writeln!(
            body,
            r#"<text class="column-label" x="{}" y="{}" font-size="10" text-anchor="middle">{}</text>"#,
            px(left + (i as f64 + 0.5) * cell_px),
            px(top - 6.0),
            esc(name)
        );
    }
    let index_of = |name: &str| kc.labs.iter().position(|l| l == name);
    for pair in &kc.pairs {
        let (Some(a), Some(b)) = (index_of(&pair.a), index_of(&pair.b)) else {
            continue;
        };
        let Some((at, ratio)) = pair.largest_ratio() else {
            continue;
        };
        let exceeding = pair.exceeding();
        // A pair without its test (JSON written before it) is not shaded.
        let (chi2, dof, consistent) = pair
            .vector
            .as_ref()
            .map_or((f64::NAN, 0, true), |v| (v.chi2, v.dof, v.consistent));
        let test = if chi2.is_finite() {
            format!("χ² {}/{dof}", crate::kc::chi2_text(chi2, 1))
        } else {
            "not tested".to_string()
        };
        // Both cells of the pair (d_ji = −d_ij): the matrix reads from either side.
        for (row, column) in [(a, b), (b, a)] {
            let (x, y) = (left + column as f64 * cell_px, top + row as f64 * cell_px);
            let fill = if consistent { "#ffffff" } else { "#f4b6a8" };
            let chi2_attribute = if chi2.is_finite() {
                format!(r#" data-chi2="{chi2}" data-dof="{dof}""#)
            } else {
                String::new()
            };
            let _ = writeln!(
                body,
                r##"<rect class="cell" data-a="{row}" data-b="{column}"{chi2_attribute} data-consistent="{consistent}" data-ratio="{ratio}" data-at="{at}" data-exceeding="{exceeding}" x="{}" y="{}" width="{}" height="{}" fill="{fill}" stroke="#000" stroke-width="0.6"/>"##,
                px(x),
                px(y),
                px(cell_px),
                px(cell_px)
            );
            if cell_px >= 30.0 {
                for (line, text) in [
                    test.clone(),
                    format!("{ratio:.2} at {}", position(at)),
                    format!("{exceeding}/{} > U", kc.index.len()),
                ]
                .iter()
                .enumerate()
                {
                    let _ = writeln!(
                        body,
                        r#"<text x="{}" y="{}" font-size="{}" text-anchor="middle">{}</text>"#,
                        px(x + cell_px / 2.0),
                        px(y + cell_px / 2.0 + (line as f64 - 1.0) * (font + 2.0) + font / 3.0),
                        px(font),
                        esc(text)
                    );
                }
            }
        }
    }
    for i in 0..n {
        let _ = writeln!(
            body,
            r##"<rect class="diagonal" x="{}" y="{}" width="{}" height="{}" fill="#d9d9d9" stroke="#000" stroke-width="0.6"/>"##,
            px(left + i as f64 * cell_px),
            px(top + i as f64 * cell_px),
            px(cell_px),
            px(cell_px)
        );
    }
    let height = top + n as f64 * cell_px + 24.0;
    Figure::new(
        NAMES[2],
        title.clone(),
        document(height, &title, &subtitles, &body),
    )
}
