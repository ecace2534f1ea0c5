//! The figures of `polycal kc` (docs/FORMAT.md §12), the classic ones of a key
//! comparison's report: every laboratory's degree of equivalence d_i with its U(d_i) bar
//! around zero per face (`kc-degrees-of-equivalence`; laboratories left out drawn with
//! open markers and "left out" in the legend); the reference value per face with its
//! expanded uncertainty 2·u_ref and every laboratory's value x_i = x_ref + d_i
//! (`kc-reference`); and with the pilot's repeats each repeat's d_r with U(d_r)
//! (`kc-pilot-stability`).
//!
//! Classes (docs/FORMAT.md §10): `point` and `error-bar` in panel `main`, with
//! `data-series` `lab<i>` (laboratory i of `labs`, from 0), `reference`, or `repeat<r>`
//! (repeat r of `pilot.repeats`), and `data-index` the position in `index`.

use super::Figure;
use super::chart::{Chart, Point, Series};
use super::svg::Marker;
use crate::kc::{DegreeOfEquivalence, KeyComparison};
use crate::results::Quantity;

/// The fixed names of the figures, and the pilot's.
pub(crate) const NAMES: [&str; 2] = ["kc-degrees-of-equivalence", "kc-reference"];
/// The pilot's figure.
pub(crate) const PILOT: &str = "kc-pilot-stability";

/// The markers of successive repeats, in turn.
const MARKERS: [Marker; 2] = [Marker::FilledCircle, Marker::OpenSquare];
/// The markers of successive laboratories in the reference (open squares are for those
/// left out).
const IN_REFERENCE: [Marker; 2] = [Marker::FilledCircle, Marker::Triangle];

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
        points: (0..kc.index.len())
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
    let mut out = vec![degrees_of_equivalence(kc), reference(kc)];
    if kc.pilot.is_some() {
        out.push(pilot(kc));
    }
    out
}

fn method_words(kc: &KeyComparison) -> &'static str {
    match kc.method {
        crate::kc::ReferenceMethod::WeightedMean => {
            "closed GLS reference (the weighted mean with one u per laboratory)"
        }
        crate::kc::ReferenceMethod::DersimonianLaird => {
            "DerSimonian–Laird, u widened by τ, closed GLS reference"
        }
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
            let (label, marker) = if doe.in_reference {
                (doe.lab.clone(), IN_REFERENCE[i % 2])
            } else {
                (
                    format!("{} (left out of the reference)", doe.lab),
                    Marker::OpenSquare,
                )
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
        "U(d_i) = 2·√(u_i² + τ² − u_ref² + u_stab²) in the reference, + u_ref² when left out"
            .to_string(),
    ];
    if !left_out.is_empty() {
        subtitles.push(format!(
            "left out (open squares): {}; reasons in the JSON's excluded",
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
            marker: if doe.in_reference {
                Marker::Triangle
            } else {
                Marker::OpenSquare
            },
            dx_px: offset_px(i + 1, n, kc.index.len()),
            points: (0..kc.index.len())
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
            "laboratories' values x_i = x_ref + d_i: triangles, open squares those left out; no bars (their U(d_i) in kc-degrees-of-equivalence)"
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
        "each repeat's d_r = y_r − x_ref with U(d_r) = 2·√(u_r² + τ² + u_ref² + u_stab²), k = 2"
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
