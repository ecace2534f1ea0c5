//! The table of `polycal history` for people (its JSON is [`crate::history::History`]).

use std::fmt::{self, Write};

use crate::history::History;
use crate::input::escaped;

/// Writes a standard's history as a table: the calibrations and their dates, the
/// formulas, per position the drift per year with its u, the value predicted with u and
/// U (and with a largest U the date it is reached), then the decision with its statistic,
/// the model's fit and the notes. Numbers are rounded for reading (0.0001″, χ² to 0.01);
/// the JSON carries them at full precision. A file name with a control character is shown
/// escaped ([`crate::input::escaped`]).
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: Write>(out: &mut W, history: &History) -> fmt::Result {
    let mut text = String::new();
    write_text(&mut text, history)?;
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.write_char('\n')?;
        }
        out.write_str(&escaped(line))?;
    }
    Ok(())
}

fn write_text(out: &mut String, h: &History) -> fmt::Result {
    writeln!(
        out,
        "History of the standard: {} over {} calibrations",
        h.quantity.name(),
        h.dates.len()
    )?;
    for (date, file) in h.dates.iter().zip(&h.files) {
        writeln!(out, "  {date}  {file}")?;
    }
    writeln!(
        out,
        "model per position: x(t) = a + b·(t − t_ref) by generalized least squares, weights \
         from each calibration's u{}; drift b in arcsec per year of 365.25 days",
        if h.quantity == crate::results::Quantity::FaceDeviation {
            ""
        } else {
            " (closed vectors, as kc takes them)"
        }
    )?;
    writeln!(
        out,
        "prediction at {} by the {} model, u² = u²(a) + 2τ·cov(a, b) + τ²·u²(b), U = k·u, k = {}",
        h.at,
        h.model.name(),
        h.k
    )?;
    writeln!(out)?;
    let with_date = h.max_u_date.is_some();
    let angle = h.angle_deg.is_some();
    write!(
        out,
        "{:>6}{}{:>11}{:>11}{:>11}{:>10}{:>10}",
        "index",
        if angle { "  angle/°  " } else { "" },
        "drift″/yr",
        "u(drift)",
        "predicted″",
        "u″",
        "U″"
    )?;
    if with_date {
        write!(out, "  U reaches {}″ on", h.max_u.unwrap_or(f64::NAN))?;
    }
    writeln!(out)?;
    for k in 0..h.index.len() {
        write!(out, "{:>6}", h.index[k])?;
        if let Some(angles) = &h.angle_deg {
            write!(out, "  {:>9.4}", angles[k])?;
        }
        write!(
            out,
            "{:>11.4}{:>11.4}{:>11.4}{:>10.4}{:>10.4}",
            h.drift[k],
            h.drift_u[k],
            h.predicted[k],
            h.predicted_u[k],
            h.k * h.predicted_u[k]
        )?;
        if let Some(dates) = &h.max_u_date {
            write!(
                out,
                "  {}",
                dates[k].as_deref().unwrap_or(match h.model {
                    crate::history::DriftModel::Constant => "never (constant)",
                    _ => "exceeded at every date",
                })
            )?;
        }
        writeln!(out)?;
    }
    writeln!(out)?;
    for note in &h.notes {
        writeln!(out, "{note}")?;
    }
    Ok(())
}
