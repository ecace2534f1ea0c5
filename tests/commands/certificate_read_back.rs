//! Certificates read back (docs/FORMAT.md §13.3): wherever a result file is read, a DCC
//! written by `polycal report --dcc` (or any DCC 3.x stating polycal's quantities) is read
//! by its content. Checked: `compare RESULT.csv CERT.xml` of the same evaluation differs
//! by no more than the certificate's rounding (half a unit of each written value's last
//! digit, read from the XML by this test's own parser), with status 0; a
//! self-calibration's certificate matched by angle; `kc` and `report --reference` take a
//! certificate; another institute's certificate in microradians and degrees with standard
//! uncertainties is converted (hand-computed values); a diagnosis's final model is not
//! what is read; hostile and broken XML (a DTD bomb, an external entity, a 1 GiB file,
//! another root, DCC 2.x, a bad number, a coverage interval, lists of different lengths,
//! a value stated twice) refused with status 2 and one `error:` line naming the place.

use std::path::{Path, PathBuf};

use roxmltree::Document;
use serde_json::Value;

use crate::document_support::{json, polycal};

const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const META: &str = "examples/report/meta.toml";
const SELFCAL: &str = "examples/data/selfa-168.csv";
const SELFCAL_BUDGET: &str = "examples/budgets/selfcal.toml";
const SI: &str = "https://ptb.de/si";

fn temp_dir(name: &str) -> PathBuf {
    crate::document_support::temp_dir("readback", name)
}

fn text(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Writes `RESULT.csv` (`solve`/`selfcal --format csv`) and `CERT.xml` (`report --dcc`)
/// of the same evaluation into `dir`.
fn result_and_certificate(
    dir: &Path,
    command: &str,
    data: &str,
    budget: &str,
) -> (PathBuf, PathBuf) {
    let csv = dir.join("result.csv");
    let out = polycal(&[command, data, "--budget", budget, "--format", "csv"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(&csv, &out.stdout).unwrap();
    let xml = dir.join("cert.xml");
    let html = dir.join("report.html");
    let out = polycal(&[
        "report",
        data,
        "--budget",
        budget,
        "--meta",
        META,
        "--out",
        text(&html),
        "--dcc",
        text(&xml),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (csv, xml)
}

/// Half a unit of the last digit of each number written in the certificate's lists of
/// values (`si:valueXMLList` of a quantity with U), in the order written, by quantity
/// refType word.
fn rounding_halves(xml: &Path, quantity_ref: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(xml).unwrap();
    let doc = Document::parse(&text).unwrap();
    let quantity = doc
        .descendants()
        .find(|n| {
            n.attribute("refType")
                .is_some_and(|r| r.split_whitespace().any(|w| w == quantity_ref))
                && !n.ancestors().any(|a| {
                    a.attribute("refType")
                        .is_some_and(|r| r.contains("finalModel"))
                })
        })
        .unwrap_or_else(|| panic!("{quantity_ref} in the certificate"));
    let values = quantity
        .descendants()
        .find(|n| n.tag_name().name() == "valueXMLList" && n.tag_name().namespace() == Some(SI))
        .unwrap();
    values
        .text()
        .unwrap()
        .split_whitespace()
        .map(|w| {
            let decimals = w.split_once('.').map_or(0, |(_, d)| d.len() as i32);
            0.5 * 10f64.powi(-decimals)
        })
        .collect()
}

/// `compare A B --format json`, with its status.
fn compare(a: &Path, b: &Path) -> (Option<i32>, Value) {
    let out = polycal(&["compare", text(a), text(b), "--format", "json"]);
    let json = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|_| panic!("JSON: {}", String::from_utf8_lossy(&out.stderr)));
    (out.status.code(), json)
}

/// Every compared row of `quantity`: |a − b| within the certificate's rounding of b.
fn assert_within_rounding(rows: &[Value], quantity: &str, halves: &[f64]) {
    let rows: Vec<&Value> = rows.iter().filter(|r| r["quantity"] == quantity).collect();
    assert_eq!(rows.len(), halves.len(), "{quantity}: every value compared");
    for (row, half) in rows.iter().zip(halves) {
        let d = row["difference"].as_f64().unwrap().abs();
        assert!(
            d <= half * (1.0 + 1e-9),
            "{quantity} {}: |a − b| = {d} > {half}",
            row["index"]
        );
    }
}

#[test]
fn a_certificate_compared_with_its_result_file_differs_by_its_rounding_only() {
    let dir = temp_dir("polygon");
    let (csv, xml) = result_and_certificate(&dir, "solve", DATA, BUDGET);
    let (status, json) = compare(&csv, &xml);
    assert_eq!(status, Some(0), "{json}");
    let rows = json["rows"].as_array().unwrap();
    // 24 β, 23 φ, 24 α, 2 setup errors: every value the certificate states
    assert_eq!(rows.len(), 73, "{}", rows.len());
    assert_within_rounding(
        rows,
        "pitch_deviation",
        &rounding_halves(&xml, "polycal_pitchDeviation"),
    );
    assert_within_rounding(
        rows,
        "face_deviation",
        &rounding_halves(&xml, "polycal_faceDeviation"),
    );
    assert_within_rounding(
        rows,
        "encoder_error",
        &rounding_halves(&xml, "polycal_encoderError"),
    );
    // U as written: two significant digits rounded up, never below the result file's
    for row in rows.iter().filter(|r| r["quantity"] != "setup_error") {
        let (ua, ub) = (row["U_a"].as_f64().unwrap(), row["U_b"].as_f64().unwrap());
        assert!(ub >= ua * (1.0 - 1e-12) && ub - ua < 0.01, "U {ua} → {ub}");
    }
    // and the other way round, the certificate first
    let (status, _) = compare(&xml, &csv);
    assert_eq!(status, Some(0));
}

#[test]
fn a_self_calibration_certificate_is_matched_by_angle() {
    let dir = temp_dir("selfcal");
    let (csv, xml) = result_and_certificate(&dir, "selfcal", SELFCAL, SELFCAL_BUDGET);
    let (status, json) = compare(&csv, &xml);
    assert_eq!(status, Some(0), "{json}");
    let rows = json["rows"].as_array().unwrap();
    let halves = rounding_halves(&xml, "polycal_encoderError");
    assert_eq!(halves.len(), 168);
    assert_within_rounding(rows, "encoder_error", &halves);
}

#[test]
fn kc_and_report_reference_take_a_certificate() {
    let dir = temp_dir("kc");
    let (csv, xml) = result_and_certificate(&dir, "solve", DATA, BUDGET);
    let kc = json(&[
        "kc",
        &format!("A={}", text(&xml)),
        &format!("B={}", text(&csv)),
        "--quantity",
        "pitch_deviation",
        "--format",
        "json",
    ]);
    assert_eq!(kc["labs"], serde_json::json!(["A", "B"]));
    let halves = rounding_halves(&xml, "polycal_pitchDeviation");
    let d = &kc["degrees_of_equivalence"][0]["d"];
    for (i, half) in halves.iter().enumerate() {
        // d_A = x_A − x_ref, and x_ref lies between x_A and x_B
        assert!(
            d[i].as_f64().unwrap().abs() <= half * (1.0 + 1e-9),
            "d_A[{i}] = {}",
            d[i]
        );
    }
    let out = polycal(&[
        "report",
        DATA,
        "--budget",
        BUDGET,
        "--reference",
        text(&xml),
        "--out",
        text(&dir.join("r.html")),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A certificate of another writer: face numbers, pitch deviations in microradians with
/// standard uncertainties, encoder errors in degrees at table angles in radians.
const FOREIGN: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<dcc:digitalCalibrationCertificate xmlns:dcc="https://ptb.de/dcc" xmlns:si="https://ptb.de/si" schemaVersion="3.2.1">
  <dcc:administrativeData><dcc:coreData>
    <dcc:uniqueIdentifier>NMI-2025-0042</dcc:uniqueIdentifier>
    <dcc:beginPerformanceDate>2025-06-02</dcc:beginPerformanceDate>
    <dcc:endPerformanceDate>2025-06-04</dcc:endPerformanceDate>
  </dcc:coreData></dcc:administrativeData>
  <dcc:measurementResults><dcc:measurementResult><dcc:results>
    <dcc:result><dcc:data><dcc:list>
      <dcc:quantity refType="polycal_faceNumber"><si:realListXMLList>
        <si:valueXMLList>1 2 3 4</si:valueXMLList><si:unitXMLList>\one</si:unitXMLList>
      </si:realListXMLList></dcc:quantity>
      <dcc:quantity refType="polycal_pitchDeviation"><si:realListXMLList>
        <si:valueXMLList>4.84813681109536 -9.69627362219072 0 4.84813681109536</si:valueXMLList>
        <si:unitXMLList>\micro\radian</si:unitXMLList>
        <si:standardUncXMLList><si:uncertaintyXMLList>0.484813681109536</si:uncertaintyXMLList></si:standardUncXMLList>
      </si:realListXMLList></dcc:quantity>
    </dcc:list></dcc:data></dcc:result>
    <dcc:result><dcc:data><dcc:list>
      <dcc:quantity refType="polycal_tableAngle"><si:realListXMLList>
        <si:valueXMLList>0 1.5707963267948966 3.141592653589793 4.71238898038469</si:valueXMLList>
        <si:unitXMLList>\radian</si:unitXMLList>
      </si:realListXMLList></dcc:quantity>
      <dcc:quantity refType="polycal_encoderError"><si:realListXMLList>
        <si:valueXMLList>0.0005 -0.0005 0.00025 -0.00025</si:valueXMLList>
        <si:unitXMLList>\degree</si:unitXMLList>
        <si:expandedUncXMLList>
          <si:uncertaintyXMLList>0.0001 0.0001 0.0001 0.0001</si:uncertaintyXMLList>
          <si:coverageFactorXMLList>2</si:coverageFactorXMLList>
          <si:coverageProbabilityXMLList>0.95</si:coverageProbabilityXMLList>
        </si:expandedUncXMLList>
      </si:realListXMLList></dcc:quantity>
    </dcc:list></dcc:data></dcc:result>
  </dcc:results></dcc:measurementResult></dcc:measurementResults>
</dcc:digitalCalibrationCertificate>
"#;

#[test]
fn another_writers_certificate_is_converted_to_arcseconds() {
    let dir = temp_dir("foreign");
    let xml = dir.join("nmi.xml");
    std::fs::write(&xml, FOREIGN).unwrap();
    // the same results by hand in arcseconds: 1 µrad = 0.206264806…″, 1° = 3600″,
    // the table at 0°, 90°, 180°, 270°
    let csv = dir.join("hand.csv");
    std::fs::write(
        &csv,
        "quantity,index,value,U,u,k,angle_deg\n\
         pitch_deviation,1,1.0,,0.1,,\n\
         pitch_deviation,2,-2.0,,0.1,,\n\
         pitch_deviation,3,0,,0.1,,\n\
         pitch_deviation,4,1.0,,0.1,,\n\
         encoder_error,0,1.8,0.36,,2,0\n\
         encoder_error,1,-1.8,0.36,,2,90\n\
         encoder_error,2,0.9,0.36,,2,180\n\
         encoder_error,3,-0.9,0.36,,2,270\n",
    )
    .unwrap();
    let out = polycal(&["compare", text(&xml), text(&csv), "--format", "json"]);
    // compare needs U: the pitch deviations' u alone is refused as in a result file, at
    // the line of the value
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let line = FOREIGN
        .lines()
        .position(|l| l.contains("4.84813681109536 -9.69"))
        .unwrap()
        + 1;
    assert!(
        stderr.contains(&format!(
            "nmi.xml:{line}: pitch_deviation 1 has no expanded uncertainty U"
        )),
        "{stderr}"
    );
    // kc takes u: the pitch deviations lined up with the hand file's, d = 0 within 1e-12
    let kc = json(&[
        "kc",
        &format!("NMI={}", text(&xml)),
        &format!("HAND={}", text(&csv)),
        "--quantity",
        "pitch_deviation",
        "--format",
        "json",
    ]);
    for d in kc["degrees_of_equivalence"][0]["d"].as_array().unwrap() {
        assert!(d.as_f64().unwrap().abs() < 1e-12, "{d}");
    }
    let kc = json(&[
        "kc",
        &format!("NMI={}", text(&xml)),
        &format!("HAND={}", text(&csv)),
        "--quantity",
        "encoder_error",
        "--format",
        "json",
    ]);
    assert_eq!(kc["index"].as_array().unwrap().len(), 4, "{kc}");
    for d in kc["degrees_of_equivalence"][0]["d"].as_array().unwrap() {
        assert!(d.as_f64().unwrap().abs() < 1e-12, "{d}");
    }
}

#[test]
fn the_final_model_of_a_diagnosis_is_not_what_is_read() {
    let dir = temp_dir("final");
    let data = dir.join("drift.csv");
    let out = polycal(&[
        "simulate",
        "--drift",
        "2:2.0",
        "--seed",
        "7",
        "--out",
        text(&data),
    ]);
    assert_eq!(out.status.code(), Some(0));
    let xml = dir.join("cert.xml");
    let out = polycal(&[
        "report",
        text(&data),
        "--budget",
        BUDGET,
        "--diagnose",
        "--meta",
        META,
        "--out",
        text(&dir.join("r.html")),
        "--dcc",
        text(&xml),
    ]);
    assert!(out.status.code().is_some_and(|c| c <= 1));
    assert!(
        std::fs::read_to_string(&xml)
            .unwrap()
            .contains("polycal_finalModelPitchDeviations")
    );
    let csv = dir.join("solve.csv");
    let out = polycal(&["solve", text(&data), "--budget", BUDGET, "--format", "csv"]);
    std::fs::write(&csv, &out.stdout).unwrap();
    let (_, json) = compare(&csv, &xml);
    let rows = json["rows"].as_array().unwrap();
    assert_within_rounding(
        rows,
        "pitch_deviation",
        &rounding_halves(&xml, "polycal_pitchDeviation"),
    );
}

/// `compare RESULT XML`'s refusal: status 2, one `error:` line, returned.
fn refused(dir: &Path, name: &str, xml: &[u8]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, xml).unwrap();
    let out = polycal(&[
        "compare",
        "examples/data/polygon24-shift-angle.result.csv",
        text(&path),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "{name}: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{name}: one line: {stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(out.stdout.is_empty());
    stderr
}

#[test]
fn hostile_xml_is_refused_without_harm() {
    let dir = temp_dir("hostile");
    let bomb = br#"<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol2 "&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol9 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
]>
<dcc:digitalCalibrationCertificate xmlns:dcc="https://ptb.de/dcc">&lol9;</dcc:digitalCalibrationCertificate>
"#;
    let e = refused(&dir, "bomb.xml", bomb);
    assert!(e.contains("bomb.xml:2:1: ") && e.contains("DTD"), "{e}");
    let external = br#"<?xml version="1.0"?>
<!DOCTYPE d [<!ENTITY secret SYSTEM "file:///etc/hostname">]>
<d>&secret;</d>
"#;
    let e = refused(&dir, "xxe.xml", external);
    assert!(e.contains("xxe.xml:2:1: ") && e.contains("DTD"), "{e}");
    let hostname = std::fs::read_to_string("/etc/hostname").unwrap_or_default();
    if !hostname.trim().is_empty() {
        assert!(
            !e.contains(hostname.trim()),
            "nothing of the entity's file shown"
        );
    }
    // elements nested 50 000 deep (the parser recurses: a stack overflow would abort)
    let deep = format!(
        "<?xml version=\"1.0\"?>\n{}{}\n",
        "<a>".repeat(50_000),
        "</a>".repeat(50_000)
    );
    let e = refused(&dir, "deep.xml", deep.as_bytes());
    assert!(
        e.contains("deep.xml:2:769: elements nested more than 256 deep"),
        "{e}"
    );
    // a 1 GiB file (sparse): refused by its size before it is read
    let big = dir.join("big.xml");
    let file = std::fs::File::create(&big).unwrap();
    file.set_len(1 << 30).unwrap();
    drop(file);
    let out = polycal(&[
        "compare",
        "examples/data/polygon24-shift-angle.result.csv",
        text(&big),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("big.xml") && stderr.contains("1073741824"),
        "{stderr}"
    );
    std::fs::remove_file(&big).unwrap();
}

#[test]
fn broken_certificates_are_refused_at_the_element() {
    let dir = temp_dir("broken");
    let e = refused(
        &dir,
        "other.xml",
        b"<?xml version=\"1.0\"?>\n<html><body/></html>\n",
    );
    assert!(
        e.contains("other.xml:2:1: html: not a Digital Calibration Certificate"),
        "{e}"
    );
    let old = FOREIGN.replace("schemaVersion=\"3.2.1\"", "schemaVersion=\"2.4.0\"");
    let e = refused(&dir, "old.xml", old.as_bytes());
    assert!(e.contains("old.xml:2:1: ") && e.contains("DCC 3.x"), "{e}");
    // a bad number: its own line and column, and the element's path
    let bad = FOREIGN.replace("-9.69627362219072", "-9.69x");
    let e = refused(&dir, "bad.xml", bad.as_bytes());
    let (line, column) = FOREIGN
        .lines()
        .enumerate()
        .find_map(|(i, l)| l.find("-9.69627362219072").map(|c| (i + 1, c + 1)))
        .unwrap();
    assert!(
        e.contains(&format!("bad.xml:{line}:{column}: dcc:digitalCalibrationCertificate/dcc:measurementResults/dcc:measurementResult/dcc:results/dcc:result[1]/dcc:data/dcc:list/dcc:quantity[2]/si:realListXMLList/si:valueXMLList: \"-9.69x\" is not a finite number")),
        "{e}"
    );
    let interval = FOREIGN.replace(
        "<si:standardUncXMLList><si:uncertaintyXMLList>0.484813681109536</si:uncertaintyXMLList></si:standardUncXMLList>",
        "<si:coverageIntervalXMLList/>",
    );
    let e = refused(&dir, "interval.xml", interval.as_bytes());
    assert!(
        e.contains("si:coverageIntervalXMLList: an uncertainty stated as a coverage interval"),
        "{e}"
    );
    let short = FOREIGN.replace(
        "<si:valueXMLList>1 2 3 4</si:valueXMLList>",
        "<si:valueXMLList>1 2 3</si:valueXMLList>",
    );
    let e = refused(&dir, "short.xml", short.as_bytes());
    assert!(
        e.contains("si:valueXMLList: 3 numbers for the 4 values beside them"),
        "{e}"
    );
    let twice = FOREIGN.replace(
        "<si:valueXMLList>1 2 3 4</si:valueXMLList>",
        "<si:valueXMLList>1 2 2 4</si:valueXMLList>",
    );
    let e = refused(&dir, "twice.xml", twice.as_bytes());
    assert!(e.contains("pitch_deviation 2 is stated twice"), "{e}");
    let unit = FOREIGN.replace("<si:unitXMLList>\\micro\\radian", "<si:unitXMLList>\\metre");
    let e = refused(&dir, "unit.xml", unit.as_bytes());
    assert!(e.contains("the unit \"\\\\metre\" is not an angle"), "{e}");
    let broken = &FOREIGN[..FOREIGN.len() / 2];
    let e = refused(&dir, "cut.xml", broken.as_bytes());
    assert!(
        e.contains("cut.xml:") && e.contains("not well-formed XML"),
        "{e}"
    );
    let none = FOREIGN
        .replace("polycal_pitchDeviation", "x")
        .replace("polycal_encoderError", "y");
    let e = refused(&dir, "none.xml", none.as_bytes());
    assert!(e.contains("states none of polycal's quantities"), "{e}");
}

#[test]
fn history_dates_a_certificate_by_its_performance_date() {
    let dir = temp_dir("history");
    let (csv, xml) = result_and_certificate(&dir, "solve", DATA, BUDGET);
    // the same evaluation a year before (examples/report/meta.toml: measured 2026-11-03)
    let history = json(&[
        "history",
        &format!("{}@2025-11-03", text(&csv)),
        text(&xml),
        "--at",
        "2027-01-01",
        "--format",
        "json",
    ]);
    assert_eq!(
        history["dates"],
        serde_json::json!(["2025-11-03", "2026-11-03"]),
        "{history}"
    );
    assert_eq!(history["model"], "constant", "{history}");
    // the same values a year apart: no drift beyond the certificate's rounding per year
    let halves = rounding_halves(&xml, "polycal_pitchDeviation");
    for (drift, half) in history["drift"].as_array().unwrap().iter().zip(&halves) {
        assert!(
            drift.as_f64().unwrap().abs() <= half * 1.01,
            "{drift} > {half}"
        );
    }
    // a result file has no date of its own
    let out = polycal(&["history", text(&csv), text(&xml)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("a result file carries no date"), "{stderr}");
}
