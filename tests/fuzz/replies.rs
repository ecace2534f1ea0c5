//! The instruments' reply parsers (docs/FORMAT.md §7.1–7.2): valid reply lines, mutated
//! like the files, given to every parser. A parser must not panic, and what it accepts
//! must be what its protocol allows (finite angles, a valid X axis, a known error code).

use polycal::lab::elcomat::{parse_identification, parse_measurement};
use polycal::lab::smc100::{parse_last_error, parse_position, parse_status, parse_version};
use proptest::prelude::*;

use super::harness::{Finding, no_panic};
use super::mutate::{Case, Seed, mutations};

/// Valid replies of both instruments, as the line reader hands them over (terminator
/// removed).
const REPLIES: &[&str] = &[
    "8 ELCOMAT 3000 S/N 12",
    "8 sim-elcomat 1.0",
    "4 003 12.345000 -1.234000",
    "4 001 -0.5 0.0",
    "2 003 1.0 2.0",
    "4 003 1e3 -1E-3",
    "1TS000033",
    "1TS00000A",
    "1TS000128",
    "1TS80001E",
    "1TP45",
    "1TP51.428571",
    "1TP-0.000001",
    "1TP360",
    "1TE@",
    "1TEC",
    "1VESMC_CC - Controller-driver version 3.0.1",
];

/// A case: a valid reply and one to four mutations.
pub fn case() -> impl Strategy<Value = Case> {
    let seeds: Vec<Seed> = REPLIES
        .iter()
        .map(|r| Seed {
            path: r,
            bytes: r.as_bytes().to_vec(),
        })
        .collect();
    (prop::sample::select(seeds), mutations())
        .prop_map(|(seed, mutations)| Case { seed, mutations })
}

/// Every parser on the mutated line (read as the transport reads it: invalid UTF-8
/// replaced).
pub fn check(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let line = String::from_utf8_lossy(&bytes).into_owned();
    let bad = |what: &str, detail: String| Finding::of(case, "txt", what.to_string(), detail);
    if let Ok(text) = no_panic(case, "txt", "parse_identification", || {
        parse_identification(&line).map_err(|e| e.to_string())
    })? && text.trim().is_empty()
    {
        return Err(bad("parse_identification accepted no text", text));
    }
    for kind in ['4', '2'] {
        let parsed = no_panic(case, "txt", "parse_measurement", || {
            parse_measurement(&line, kind).map_err(|e| e.to_string())
        })?;
        if let Ok(r) = parsed {
            let y_ok = r.y_arcsec.is_none_or(f64::is_finite);
            if !r.x_arcsec.is_finite() || !y_ok || !matches!(r.status % 10, 1 | 3) {
                return Err(bad(
                    "parse_measurement accepted a reading the protocol does not allow",
                    format!("{r:?}"),
                ));
            }
        }
    }
    no_panic(case, "txt", "parse_status", || {
        parse_status(&line).map(|_| ()).map_err(|e| e.to_string())
    })?
    .ok();
    if let Ok(position) = no_panic(case, "txt", "parse_position", || {
        parse_position(&line).map_err(|e| e.to_string())
    })? && !position.is_finite()
    {
        return Err(bad(
            "parse_position accepted a position that is not finite",
            format!("{position}"),
        ));
    }
    if let Ok(code) = no_panic(case, "txt", "parse_last_error", || {
        parse_last_error(&line).map_err(|e| e.to_string())
    })? && !(code == '@' || code.is_ascii_uppercase())
    {
        return Err(bad(
            "parse_last_error accepted an unknown code",
            format!("{code:?}"),
        ));
    }
    no_panic(case, "txt", "parse_version", || {
        parse_version(&line).map(|_| ()).map_err(|e| e.to_string())
    })?
    .ok();
    Ok(())
}
