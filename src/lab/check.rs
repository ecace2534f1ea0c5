//! Talking to each instrument once before a run (`polycal run --check-instruments`):
//! identify it, ask a table's position and one reading of an autocollimator, and say
//! what was found. Nothing moves.

use std::fmt;

use super::driver::{ProfileAutocollimator, ProfileTable, TableOptions};
use super::profile::Profile;
use super::transport::Transport;
use super::{Autocollimator, QueryOptions, RotaryTable};

/// What one instrument answered.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CheckedInstrument {
    /// Its role, e.g. `autocollimator 1` or `rotary table`.
    pub role: String,
    /// Its port.
    pub port: String,
    /// The profile it was spoken to with.
    pub profile: String,
    /// Its identification, when it gave one.
    pub identification: Option<String>,
    /// A table's position, degrees.
    pub position_deg: Option<f64>,
    /// An autocollimator's reading: X and, when valid, Y, arcsec.
    pub reading_arcsec: Option<(f64, Option<f64>)>,
    /// What went wrong, if anything.
    pub problem: Option<String>,
}

impl CheckedInstrument {
    /// An instrument that could not be spoken to at all (its port did not open).
    pub fn failed(role: &str, port: &str, profile: &str, problem: String) -> CheckedInstrument {
        CheckedInstrument {
            role: role.into(),
            port: port.into(),
            profile: profile.into(),
            identification: None,
            position_deg: None,
            reading_arcsec: None,
            problem: Some(problem),
        }
    }
}

impl fmt::Display for CheckedInstrument {
    /// `autocollimator 1 at PORT (PROFILE): IDENTIFICATION; reading X …″, Y …″` or
    /// `… : PROBLEM`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} at {} ({})", self.role, self.port, self.profile)?;
        if let Some(id) = &self.identification {
            write!(f, ": {id:?}")?;
        }
        if let Some(p) = self.position_deg {
            write!(f, "; position {p}°")?;
        }
        if let Some((x, y)) = self.reading_arcsec {
            write!(f, "; reading X {x}″")?;
            match y {
                Some(y) => write!(f, ", Y {y}″")?,
                None => write!(f, ", Y not valid")?,
            }
        }
        match &self.problem {
            Some(problem) => write!(f, "; FAILED: {problem}"),
            None => write!(f, "; ok"),
        }
    }
}

/// Identifies an autocollimator and takes one reading (nothing stored).
pub fn check_autocollimator<T: Transport>(
    role: &str,
    transport: T,
    profile: &Profile,
    options: QueryOptions,
) -> CheckedInstrument {
    let port = transport.port().to_string();
    let mut checked = CheckedInstrument::failed(role, &port, &profile.name, String::new());
    checked.problem = None;
    let mut ac = match ProfileAutocollimator::new(transport, profile, options) {
        Ok(ac) => ac,
        Err(e) => {
            checked.problem = Some(e.to_string());
            return checked;
        }
    };
    let result = ac.start().and_then(|()| {
        checked.identification = Some(ac.identify()?);
        let reading = ac.measure()?;
        checked.reading_arcsec = Some((reading.x_arcsec, reading.y_arcsec));
        Ok(())
    });
    if let Err(e) = result {
        checked.problem = Some(e.to_string());
    }
    checked
}

/// Identifies a table and asks its position (nothing moves: no home search either).
pub fn check_table<T: Transport>(
    role: &str,
    mut transport: T,
    profile: &Profile,
    options: TableOptions,
) -> CheckedInstrument {
    let port = transport.port().to_string();
    let mut checked = CheckedInstrument::failed(role, &port, &profile.name, String::new());
    checked.problem = None;
    if let Err(e) = transport.clear_input() {
        checked.problem = Some(e.to_string());
        return checked;
    }
    let mut table = match ProfileTable::new(transport, profile, options) {
        Ok(table) => table,
        Err(e) => {
            checked.problem = Some(e.to_string());
            return checked;
        }
    };
    let result = (|| {
        checked.identification = Some(table.identify()?);
        checked.position_deg = Some(table.position()?);
        Ok::<_, super::InstrumentError>(())
    })();
    if let Err(e) = result {
        checked.problem = Some(e.to_string());
    }
    checked
}
