//! The table of `polycal kc` for people, and its CSV of degrees of equivalence (its JSON
//! is [`crate::kc::KeyComparison`]).

use std::borrow::Cow;
use std::fmt::{self, Write};

use crate::input::{escaped, is_shown_escaped};
use crate::kc::chi2_text;
use crate::kc::{DegreeOfEquivalence, KeyComparison, ReferenceMethod};
use crate::uncertainty::format::table;

/// Writes a key comparison as tables: the header lines naming the formulas, the reference
/// per quantity (x_ref, u_ref, τ, χ², ν, χ²_0.95, consistent), the exclusions with their
/// reasons, the closed vector's test, the degrees of equivalence (d and U(d) per
/// laboratory and quantity, `*` where |d| > U(d)), the pilot's repeats, the notes and the
/// verdict. Numbers are rounded for reading (0.001″, χ² to 0.01, and from 10⁶ on to three
/// significant digits, `1.23e12`); JSON and CSV carry them at full precision.
///
/// A laboratory's name (or any text) with a control character — an escape sequence, a
/// line feed — or a bidirectional formatting character is shown escaped as
/// [`crate::input::escaped`] shows it, so a name cannot recolour the terminal, forge a
/// line of the table, or display as another name.
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: Write>(out: &mut W, kc: &KeyComparison) -> fmt::Result {
    let mut text = String::new();
    write_table_text(&mut text, &names_escaped(kc))?;
    // What the names' escaping cannot reach (a control character in a note, say): every
    // one but the table's own line feeds.
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.write_char('\n')?;
        }
        out.write_str(&escaped(line))?;
    }
    Ok(())
}

/// The comparison with every laboratory's name escaped (and the texts that quote the
/// names: the exclusions' reasons and the notes).
fn names_escaped(kc: &KeyComparison) -> Cow<'_, KeyComparison> {
    let names = kc
        .labs
        .iter()
        .chain(kc.pilot.iter().flat_map(|p| &p.repeats));
    if !names.clone().any(|name| name.contains(is_shown_escaped))
        && !kc.notes.iter().any(|n| n.contains(is_shown_escaped))
        && !kc
            .excluded
            .iter()
            .any(|e| e.reason.contains(is_shown_escaped))
    {
        return Cow::Borrowed(kc);
    }
    let fix = |text: &mut String| *text = escaped(text).into_owned();
    let mut kc = kc.clone();
    kc.labs.iter_mut().for_each(fix);
    kc.kept.iter_mut().for_each(fix);
    kc.notes.iter_mut().for_each(fix);
    for e in &mut kc.excluded {
        fix(&mut e.lab);
        fix(&mut e.reason);
    }
    if let Some(search) = &mut kc.search {
        for step in &mut search.steps {
            step.best.iter_mut().for_each(fix);
        }
    }
    for doe in &mut kc.degrees_of_equivalence {
        fix(&mut doe.lab);
    }
    kc.pairs.for_each_name(fix);
    if let Some(pilot) = &mut kc.pilot {
        pilot.repeats.iter_mut().for_each(fix);
        for doe in &mut pilot.degrees_of_equivalence {
            fix(&mut doe.lab);
        }
    }
    Cow::Owned(kc)
}

fn write_table_text<W: Write>(out: &mut W, kc: &KeyComparison) -> fmt::Result {
    let name = kc.quantity.name();
    let position = if kc.angle_deg.is_some() {
        "Angle °"
    } else if kc.quantity == crate::results::Quantity::PitchDeviation {
        "Face"
    } else if kc.quantity == crate::results::Quantity::AngleBlock {
        "Block"
    } else {
        "Index"
    };
    let at = |k: usize| match (&kc.angle_deg, &kc.nominal_deg) {
        (Some(angles), _) => format!("{:.4}", angles[k]),
        (None, Some(nominal)) => match nominal.get(k).copied().flatten() {
            Some(degrees) => format!("{} ({degrees}°)", kc.index[k]),
            None => kc.index[k].to_string(),
        },
        (None, None) => kc.index[k].to_string(),
    };
    writeln!(
        out,
        "Key comparison of {name}, {} laboratories: {}",
        kc.labs.len(),
        kc.labs.join(", ")
    )?;
    write_method(out, kc)?;
    write_reference_table(out, kc, position, &at)?;
    write_decision(out, kc)?;

    writeln!(
        out,
        "\nDegrees of equivalence d_i = x_i − x_ref, U(d_i) = 2·√(u_i² + u_stab² + τ² ∓ u_ref²) \
         (− in the reference, + out of it), arcsec; * where |d| > U(d)"
    )?;
    let mut labs: Vec<&DegreeOfEquivalence> = kc.degrees_of_equivalence.iter().collect();
    if let Some(pilot) = &kc.pilot {
        labs.extend(&pilot.degrees_of_equivalence);
    }
    let mut header = vec![position.to_string()];
    for doe in &labs {
        let mark = if doe.in_reference { "" } else { " (out)" };
        header.push(format!("d {}{mark}", doe.lab));
        header.push(format!("U {}", doe.lab));
    }
    let rows: Vec<Vec<String>> = (0..kc.index.len())
        .map(|k| {
            let mut row = vec![at(k)];
            for doe in &labs {
                let star = if doe.d[k].abs() > doe.expanded_u[k] {
                    " *"
                } else {
                    ""
                };
                row.push(format!("{}{star}", number(doe.d[k], 3)));
                row.push(number(doe.expanded_u[k], 3));
            }
            row
        })
        .collect();
    writeln!(out, "{}", dynamic_table(&header, &rows))?;
    write_pairs(out, kc)?;
    write_link(out, kc, position, &at, &labs)?;

    if let Some(pilot) = &kc.pilot {
        if let Some(statement) = kc.pilot_statement() {
            writeln!(out, "{statement}")?;
        }
        writeln!(
            out,
            "Per quantity (information): χ² about the repeats' weighted mean with ν = {}",
            pilot.chi2_dof
        )?;
        let header = [position, "Mean", "s", "χ²", "Significant", "u_stab"].map(String::from);
        let rows: Vec<[String; 6]> = (0..kc.index.len())
            .map(|k| {
                [
                    at(k),
                    format!("{:.3}", pilot.mean[k]),
                    format!("{:.3}", pilot.spread[k]),
                    chi2_text(pilot.chi2[k], 2),
                    if pilot.significant[k] { "yes" } else { "no" }.to_string(),
                    format!("{:.3}", pilot.stability_u[k]),
                ]
            })
            .collect();
        writeln!(
            out,
            "{}",
            table(&header, &rows, &[false, true, true, true, false, true])
        )?;
    }
    for note in &kc.notes {
        writeln!(out, "Note: {note}")?;
    }
    writeln!(out, "{}", kc.verdict_statement())
}

/// A number with `decimals` decimals, or "—" where none is given (a degree of
/// equivalence where a laboratory does not report an angle block; χ²_0.95(0)).
fn number(x: f64, decimals: usize) -> String {
    if crate::kc::is_given(x) {
        format!("{x:.decimals$}")
    } else {
        "—".to_string()
    }
}

/// The reference method and the decision, in words.
fn write_method<W: Write>(out: &mut W, kc: &KeyComparison) -> fmt::Result {
    let (reference, whole) = (kc.wording().reference(), kc.wording().whole());
    match kc.method {
        ReferenceMethod::WeightedMean => writeln!(
            out,
            "Reference: the {reference} of the laboratories in it; with one u per \
             laboratory the weighted mean x_ref = Σ x_i/u_i² / Σ 1/u_i², u_ref = (Σ 1/u_i²)^(-1/2) \
             (Cox 2002, procedure A)\n\
             Decision: one test at 5 %, the {whole} of every laboratory; when it fails, the \
             largest subset that passes (docs/FORMAT.md §12)"
        )?,
        ReferenceMethod::MandelPaule => writeln!(
            out,
            "Reference: Mandel–Paule, every u_i² widened by τ² such that Σ (x_i − x_ref)²/(u_i²+τ²) \
             = n − 1 (the dark uncertainty of each quantity; τ = 0 when χ² ≤ n − 1), then the \
             {reference}\n\
             Decision: the test of τ = 0 at 5 %, the {whole} of every laboratory; nobody is \
             left out (docs/FORMAT.md §12)"
        )?,
        _ => writeln!(
            out,
            "Reference: DerSimonian–Laird, every u_i² widened by τ² = max(0, (χ² − ν)/(S1 − S2/S1)) \
             (the dark uncertainty of each quantity), then the {reference}; with one u \
             per laboratory x_ref = Σ x_i/(u_i²+τ²) / Σ 1/(u_i²+τ²), u_ref² = 1/Σ 1/(u_i²+τ²)\n\
             Decision: the test of τ = 0 at 5 %, the {whole} of every laboratory; nobody is \
             left out (docs/FORMAT.md §12)"
        )?,
    }
    Ok(())
}

/// Per quantity: the reference with u_ref and τ, and the χ² as information.
fn write_reference_table<W: Write>(
    out: &mut W,
    kc: &KeyComparison,
    position: &str,
    at: &dyn Fn(usize) -> String,
) -> fmt::Result {
    writeln!(
        out,
        "Per quantity, information only: χ² = Σ (x_i − x̄_w)²/u_i², ν = n − 1, against \
         χ²_0.95(ν)\n"
    )?;
    let header = [
        position,
        "x_ref",
        "u_ref",
        "τ",
        "χ²",
        "ν",
        "χ²_0.95",
        "Passes",
    ]
    .map(String::from);
    let rows: Vec<[String; 8]> = (0..kc.index.len())
        .map(|k| {
            [
                at(k),
                number(kc.reference[k], 3),
                number(kc.reference_u[k], 3),
                format!("{:.3}", kc.tau[k]),
                chi2_text(kc.chi2[k], 2),
                kc.chi2_dof[k].to_string(),
                number(kc.chi2_critical[k], 2),
                if kc.consistent[k] { "yes" } else { "no" }.to_string(),
            ]
        })
        .collect();
    let mut right = [true; 8];
    right[0] = false;
    right[7] = false;
    writeln!(out, "{}", table(&header, &rows, &right))?;
    Ok(())
}

/// The one decision: the test of every laboratory, the search and the exclusions, and the
/// test of those in the reference.
fn write_decision<W: Write>(out: &mut W, kc: &KeyComparison) -> fmt::Result {
    if let Some(v) = &kc.vector_all {
        let who = if kc.not_in_reference.is_empty() {
            "Every laboratory"
        } else {
            "Every laboratory but those kept out of the reference"
        };
        writeln!(out, "{who}: {}", kc.vector_statement(v))?;
    }
    if let Some(search) = &kc.search {
        writeln!(
            out,
            "Largest consistent subset ({}, {} subsets fitted), the best of each size:",
            match search.method {
                crate::kc::SearchMethod::Exhaustive => "every subset tried",
                _ => "greedy",
            },
            search.subsets_tested
        )?;
        for step in &search.steps {
            writeln!(
                out,
                "  {} laboratories: {} — χ² = {}, ν = {}, χ²_0.95(ν) = {:.2}: {}",
                step.size,
                step.best.join(", "),
                chi2_text(step.chi2, 2),
                step.dof,
                step.chi2_critical,
                if step.consistent { "passes" } else { "fails" }
            )?;
        }
    }
    if kc.excluded.is_empty() {
        writeln!(out, "Excluded: none")?;
    } else {
        writeln!(out, "Excluded (left out of every quantity):")?;
        for e in &kc.excluded {
            writeln!(out, "  {}: {}", e.lab, e.reason)?;
        }
    }
    writeln!(out, "In the reference: {}", kc.closed_vector_statement())?;
    Ok(())
}

/// The link to another comparison, when there is one: the correction Δ with u(Δ) per
/// quantity and every degree of equivalence against the linked reference.
fn write_link(
    out: &mut impl std::fmt::Write,
    kc: &KeyComparison,
    position: &str,
    at: &dyn Fn(usize) -> String,
    labs: &[&DegreeOfEquivalence],
) -> std::fmt::Result {
    let Some(link) = &kc.link else {
        return Ok(());
    };
    let test = match &link.vector {
        Some(v) => format!(
            "the link's one test at 5 %: χ² = {} {} χ²_0.95({}) = {:.2}, {}",
            chi2_text(v.chi2, 2),
            if v.consistent { "≤" } else { ">" },
            v.dof,
            v.chi2_critical,
            if v.consistent {
                "the linking laboratories agree"
            } else {
                "the linking laboratories DISAGREE on the offset"
            }
        ),
        None => link.untested_reason().to_string(),
    };
    writeln!(
        out,
        "\nLinked through {} — Δ = the GLS mean of d(linked) − d(this), their correlations \
         counted; {test}. Against the linked reference: d + Δ{}, U with u(Δ) (k = 2), arcsec",
        link.labs.join(", "),
        if kc.linked_over_own_positions() {
            " less Δ's mean over the laboratory's own positions"
        } else {
            ""
        }
    )?;
    let mut header = vec![position.to_string(), "Δ".to_string(), "u(Δ)".to_string()];
    for doe in labs {
        header.push(format!("d {} linked", doe.lab));
        header.push(format!("U {}", doe.lab));
    }
    let rows: Vec<Vec<String>> = (0..kc.index.len())
        .map(|k| {
            let mut row = vec![
                at(k),
                number(link.correction[k], 3),
                number(link.correction_u[k], 3),
            ];
            for doe in labs {
                let (d, u) = (doe.d_linked.as_ref(), doe.expanded_u_linked.as_ref());
                row.push(d.map_or_else(String::new, |d| number(d[k], 3)));
                row.push(u.map_or_else(String::new, |u| number(u[k], 3)));
            }
            row
        })
        .collect();
    writeln!(out, "{}", dynamic_table(&header, &rows))
}

/// The pairs whose one closed-vector test at 5 % fails, each with its χ² (every pair's d,
/// U and test are in the JSON's `pairs`).
fn write_pairs(out: &mut impl std::fmt::Write, kc: &KeyComparison) -> std::fmt::Result {
    let tested: Vec<_> = kc
        .pairs
        .iter()
        .filter_map(|p| p.vector.map(|v| (p.a, p.b, v)))
        .collect();
    if tested.is_empty() {
        return Ok(());
    }
    let failing: Vec<String> = tested
        .iter()
        .filter(|(_, _, v)| !v.consistent)
        .map(|(a, b, v)| {
            format!(
                "{a}–{b} (χ² = {} > {:.2})",
                chi2_text(v.chi2, 2),
                v.chi2_critical
            )
        })
        .collect();
    let what = match (kc.wording().is_closed(), kc.wording().is_uneven()) {
        (true, false) => format!("closed vector d_ij tested at 5 % (ν = {}", tested[0].2.dof),
        (true, true) => "closed vector d_ij tested at 5 % over the M positions both report \
                         (ν = M − 1"
            .to_string(),
        (false, _) => {
            "blocks tested at 5 % over the blocks both report (ν their number".to_string()
        }
    };
    writeln!(
        out,
        "Pairs: each pair's {what}; its own decision, about 1 pair in 20 fails by chance): {} \
         of {} fail{}{}",
        failing.len(),
        tested.len(),
        if failing.is_empty() { "" } else { ": " },
        failing.join(", ")
    )
}

/// A table with any number of columns, the first left-aligned.
fn dynamic_table(header: &[String], rows: &[Vec<String>]) -> String {
    let columns = header.len();
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |cells: &[String]| {
        let mut text = String::new();
        for (c, cell) in cells.iter().enumerate().take(columns) {
            let pad = " ".repeat(widths[c] - cell.chars().count());
            if c > 0 {
                text.push_str("  ");
            }
            if c == 0 {
                text.push_str(cell);
                text.push_str(&pad);
            } else {
                text.push_str(&pad);
                text.push_str(cell);
            }
        }
        text.trim_end().to_string()
    };
    let mut text = line(header);
    text.push('\n');
    let total: usize = widths.iter().sum::<usize>() + 2 * columns.saturating_sub(1);
    text.push_str(&"-".repeat(total));
    for row in rows {
        text.push('\n');
        text.push_str(&line(row));
    }
    text
}

/// Writes key comparisons as tables ([`write_table`]), one after another in the order
/// given: one comparison exactly as [`write_table`] writes it; several each under a
/// heading line naming its quantity (`=== Key comparison 1 of 2: pitch_deviation ===`),
/// a blank line between them.
///
/// # Errors
///
/// The writer's error.
pub fn write_tables<W: Write>(out: &mut W, comparisons: &[KeyComparison]) -> fmt::Result {
    if let [kc] = comparisons {
        return write_table(out, kc);
    }
    for (i, kc) in comparisons.iter().enumerate() {
        if i > 0 {
            out.write_char('\n')?;
        }
        writeln!(
            out,
            "=== Key comparison {} of {}: {} ===",
            i + 1,
            comparisons.len(),
            kc.quantity
        )?;
        write_table(out, kc)?;
    }
    Ok(())
}

/// Writes the degrees of equivalence of key comparisons as CSV, under one header
/// `lab,index,angle_deg,d,U,in_reference,quantity`: per comparison in the order given,
/// one row per laboratory per position (the laboratories in the order given, then the
/// pilot's repeats). `index` is the face (or the first laboratory's index of the encoder
/// error), `angle_deg` the table angle of an encoder error matched by angle (else
/// empty), `d` = x_i − x_ref and `U` = U(d_i) at k = 2 in arcseconds at full precision,
/// `in_reference` `true` or `false`, `quantity` the comparison's quantity
/// (`pitch_deviation`, …) on every row, one comparison or several.
///
/// # Errors
///
/// The I/O error of the writer, as a [`csv::Error`].
pub fn write_csv<W: std::io::Write>(
    writer: W,
    comparisons: &[KeyComparison],
) -> Result<(), csv::Error> {
    let mut csv = csv::Writer::from_writer(writer);
    csv.write_record([
        "lab",
        "index",
        "angle_deg",
        "d",
        "U",
        "in_reference",
        "quantity",
    ])?;
    for kc in comparisons {
        let pilot = kc.pilot.iter().flat_map(|p| &p.degrees_of_equivalence);
        for doe in kc.degrees_of_equivalence.iter().chain(pilot) {
            for k in 0..kc.index.len() {
                if !crate::kc::is_given(doe.d[k]) {
                    continue; // an angle block the laboratory does not report
                }
                csv.write_record([
                    text_cell(&doe.lab),
                    kc.index[k].to_string(),
                    kc.angle_deg
                        .as_ref()
                        .map_or(String::new(), |a| a[k].to_string()),
                    doe.d[k].to_string(),
                    doe.expanded_u[k].to_string(),
                    doe.in_reference.to_string(),
                    kc.quantity.name().to_string(),
                ])?;
            }
        }
    }
    csv.flush()?;
    Ok(())
}

/// Writes the key of a Draft A ([`crate::kc::anonymise`]) as CSV: the header `code,lab`,
/// then one row per code in the key's order; a cell quoted when it needs to be, and given
/// a leading `'` when it begins with a formula character (docs/FORMAT.md §3.1), which
/// [`crate::kc::CodeKey::read`] takes off again.
///
/// ```
/// use polycal::kc::CodeKey;
/// let key = CodeKey::read(b"code,lab\nA,\"Lab, Inc\"\nB,=SUM\n", "key.csv")?;
/// let mut csv = Vec::new();
/// polycal::output::kc::write_key_csv(&mut csv, &key)?;
/// assert_eq!(csv, b"code,lab\nA,\"Lab, Inc\"\nB,'=SUM\n");
/// assert_eq!(CodeKey::read(&csv, "again.csv")?.code_of("=SUM"), Some("B"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// The I/O error of the writer, as a [`csv::Error`].
pub fn write_key_csv<W: std::io::Write>(
    writer: W,
    key: &crate::kc::CodeKey,
) -> Result<(), csv::Error> {
    let mut csv = csv::Writer::from_writer(writer);
    csv.write_record(["code", "lab"])?;
    for entry in &key.entries {
        csv.write_record([text_cell(&entry.code), text_cell(&entry.lab)])?;
    }
    csv.flush()?;
    Ok(())
}

/// A text cell (docs/FORMAT.md §3.1): one that begins with `=`, `+`, `-`, `@`, a tab or a
/// carriage return — what a spreadsheet runs as a formula — gets a leading `'` (the CSV
/// writer quotes it when it needs to be).
fn text_cell(text: &str) -> String {
    if text.starts_with(['=', '+', '-', '@', '\t', '\r']) {
        format!("'{text}")
    } else {
        text.to_string()
    }
}
