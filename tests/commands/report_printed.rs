//! `polycal report` (docs/FORMAT.md §10) printed to PDF by a headless browser: every page
//! carries "Page i of n" and the certificate number, and a self-calibration report keeps
//! every line on an A4 page, read back by poppler's `pdftotext`. Skipped, saying so, where
//! the tools are not installed, unless `POLYCAL_REQUIRE_BROWSER` is set
//! (`tests/commands/skip_support`).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::skip_support;

use crate::report_support::{BUDGET, DATA, META, REFERENCE, report, temp_dir};

/// A program the printing test needs, or `None` (skipped, saying so) when it is not
/// installed and `POLYCAL_REQUIRE_BROWSER` is not set (a `SKIPPED:` line on standard
/// error, `tests/commands/skip_support`); `.ci/run` sets it, so that CI fails.
fn print_tool(program: &str, version: &str) -> Option<()> {
    match Command::new(program).arg(version).output() {
        Ok(out) if out.status.success() => Some(()),
        other => {
            skip_support::missing(
                program,
                "the printed report (every page's \"Page i of n\" and certificate number)",
                "Debian: apt-get install chromium poppler-utils",
                "POLYCAL_REQUIRE_BROWSER",
                &format!("{other:?}"),
            );
            None
        }
    }
}

/// The report `report …` writes into `dir`, printed to PDF by a headless browser
/// (Chromium, with its own header and footer off); `None` (skipped, saying so) without
/// the tools ([`print_tool`]).
fn printed(dir: &Path, args: &[&str]) -> Option<PathBuf> {
    // (poppler's tools take `-v`, not `--version`)
    print_tool("chromium", "--version")?;
    print_tool("pdftotext", "-v")?;
    report(dir, args);
    let pdf = dir.join("report.pdf");
    let out = Command::new("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-pdf-header-footer",
        ])
        .arg(format!("--user-data-dir={}", dir.join("profile").display()))
        .arg(format!("--print-to-pdf={}", pdf.display()))
        .arg(format!("file://{}", dir.join("report.html").display()))
        .output()
        .unwrap();
    assert!(
        pdf.exists(),
        "chromium printed nothing: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(pdf)
}

/// Page `i` of a PDF as text (`pdftotext`, with `extra` options), or `None` past its end.
fn pdf_page(pdf: &Path, i: usize, extra: &[&str]) -> Option<String> {
    let out = Command::new("pdftotext")
        .args(["-f", &i.to_string(), "-l", &i.to_string()])
        .args(extra)
        .arg(pdf)
        .arg("-")
        .output()
        .unwrap();
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The number of pages of a printed report: its first page's "Page 1 of n".
fn printed_pages(pdf: &Path) -> usize {
    let first = pdf_page(pdf, 1, &["-layout"]).unwrap();
    first
        .split("Page 1 of ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no \"Page 1 of n\" on page 1:\n{first}"))
}

/// The report printed to PDF: every page carries "Page i of n" and the certificate
/// number, in the `@page` margin boxes; the text of each page read back by poppler's
/// `pdftotext`.
#[test]
fn every_printed_page_carries_page_i_of_n_and_the_certificate_number() {
    let dir = temp_dir("print");
    let args = [
        DATA,
        "--budget",
        BUDGET,
        "--diagnose",
        "--reference",
        REFERENCE,
        "--meta",
        META,
    ];
    let Some(pdf) = printed(&dir, &args) else {
        return;
    };
    let n = printed_pages(&pdf);
    assert!(n >= 3, "the report has {n} pages");
    for i in 1..=n {
        let text = pdf_page(&pdf, i, &["-layout"]).unwrap_or_else(|| panic!("no page {i}"));
        assert!(
            text.contains(&format!("Page {i} of {n}")),
            "page {i}: no \"Page {i} of {n}\":\n{text}"
        );
        assert!(
            text.contains("Certificate EXAMPLE-2026-117"),
            "page {i}: no certificate number:\n{text}"
        );
    }
    // and no page beyond n
    assert!(pdf_page(&pdf, n + 1, &["-layout"]).is_none_or(|t| t.trim().is_empty()));
}

/// A self-calibration report printed on A4 at its own size, every line on the page: its
/// file's comment line (one unbroken run of 12 head angles, 250 characters) once made
/// Chromium lay the page out wider than A4 and print it shrunk to about 70 %, the line
/// cut at the right edge. Read back word by word (`pdftotext -bbox`, points): the title
/// set in 18 pt is 18 pt high (its box, ascent to descent, 1.0–1.3 times the size;
/// 12.6 pt shrunk), every word lies between the page's margins (15 mm = 42.5 pt each side
/// of 595 pt), and the comment's last words are printed.
#[test]
fn a_printed_self_calibration_report_keeps_every_line_on_the_page() {
    let dir = temp_dir("print-selfcal");
    let meta = dir.join("meta.toml");
    std::fs::write(
        &meta,
        "certificate = \"SC-7\"\nencoder = \"Rotary table RT-300\"\nencoder_serial = \"RT-1\"\n",
    )
    .unwrap();
    let args = [
        "examples/data/selfa-168.csv",
        "--budget",
        "examples/budgets/selfcal.toml",
        "--meta",
        meta.to_str().unwrap(),
    ];
    let Some(pdf) = printed(&dir, &args) else {
        return;
    };
    let number = |text: &str, key: &str| -> f64 {
        text.split(&format!("{key}=\""))
            .nth(1)
            .and_then(|t| t.split('"').next())
            .and_then(|t| t.parse().ok())
            .unwrap_or_else(|| panic!("no {key} in {text}"))
    };
    let n = printed_pages(&pdf);
    let mut text = String::new();
    for i in 1..=n {
        let boxes = pdf_page(&pdf, i, &["-bbox"]).unwrap();
        let width = number(boxes.split("<page ").nth(1).unwrap(), "width");
        assert!(
            (width - 595.0).abs() < 1.0,
            "page {i}: A4 is 595 pt wide, not {width}"
        );
        for word in boxes
            .lines()
            .filter(|l| l.trim_start().starts_with("<word "))
        {
            let (x_min, x_max) = (number(word, "xMin"), number(word, "xMax"));
            assert!(
                x_min >= 42.5 - 2.0 && x_max <= width - 42.5 + 2.0,
                "page {i}: a word outside the margins: {word}"
            );
            if i == 1 && word.contains(">Self-calibration<") && text.is_empty() {
                let height = number(word, "yMax") - number(word, "yMin");
                assert!(
                    (18.0..=23.4).contains(&height),
                    "the 18 pt title is {height} pt high: the page is printed shrunk"
                );
                text.push_str("title ");
            }
        }
        text.push_str(&pdf_page(&pdf, i, &[]).unwrap());
    }
    assert!(text.starts_with("title "), "no title on page 1");
    let words: Vec<&str> = text.split_whitespace().collect();
    for end in ["308.57142857142856", "seed"] {
        assert!(
            words.iter().any(|w| w.ends_with(end)),
            "the comment's {end} is not printed"
        );
    }
    // a self-calibration calibrates an encoder: no polygon named anywhere
    assert!(!text.to_lowercase().contains("polygon"), "{text}");
}
