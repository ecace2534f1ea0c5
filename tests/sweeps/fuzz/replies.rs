//! The bundled profiles' reply templates (docs/FORMAT.md §7, docs/instruments.md): valid
//! reply lines of every bundled instrument, mutated like the files, given to every
//! template and condition. None may panic, and what they accept must be what the profile
//! allows (a valid reading's X and a position finite numbers).

use polycal::lab::profile::{BUNDLED, Profile, ProfileKind};
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
    "1=45.0001",
    "1=1",
    "0",
    "-1024",
    "(c)2015 Physik Instrumente (PI) GmbH & Co. KG, C-863.11, 0115500028, 01.00.00.00",
    "%",
    "%7",
    "%-1675099646",
    "%45.250000",
    "%X",
    "!",
    "#",
    "ESP301 Version 3.0.1 6/1/99",
    "12.500000",
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

/// Every bundled profile's templates and conditions on the mutated line (read as the
/// transport reads it: invalid UTF-8 replaced).
pub fn check(case: &Case) -> Result<(), Box<Finding>> {
    let bytes = case.bytes();
    let line = String::from_utf8_lossy(&bytes).into_owned();
    let bad = |what: &str, detail: String| Finding::of(case, "txt", what.to_string(), detail);
    static PROFILES: std::sync::OnceLock<Vec<Profile>> = std::sync::OnceLock::new();
    let profiles = PROFILES.get_or_init(|| {
        BUNDLED
            .iter()
            .filter_map(|(name, _, _)| Profile::load(name).ok())
            .collect()
    });
    if profiles.len() != BUNDLED.len() {
        return Err(bad("a bundled profile does not read", String::new()));
    }
    for profile in profiles {
        let name = profile.name.as_str();
        let accepted = no_panic(case, "txt", name, || {
            for refusal in &profile.line.refusals {
                let _ = refusal.matches(&line);
            }
            match &profile.kind {
                ProfileKind::Autocollimator(ac) => {
                    let _ = ac.identify.reply.matches(&line);
                    if let Some(c) = ac.measure.reply.matches(&line)
                        && ac.x_valid.holds(&ac.measure.reply, &c)
                        && c.number("x").is_none()
                    {
                        return Err(format!("a valid reading without a finite X: {c:?}"));
                    }
                }
                ProfileKind::Table(table) => {
                    let _ = table.identify.reply.matches(&line);
                    if let Some(c) = table.state.query.reply.matches(&line) {
                        let _ = table.state.ready.holds(&table.state.query.reply, &c);
                        let _ = table.state.moving.holds(&table.state.query.reply, &c);
                    }
                    if let Some(c) = table.position.reply.matches(&line)
                        && c.number("deg").is_none()
                    {
                        return Err(format!("a position that is not a finite number: {c:?}"));
                    }
                }
                _ => {}
            }
            Ok(())
        })?;
        if let Err(detail) = accepted {
            return Err(bad(
                "a template accepted what its profile does not allow",
                format!("{name}: {detail}"),
            ));
        }
    }
    Ok(())
}
