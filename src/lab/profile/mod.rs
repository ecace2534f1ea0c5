//! Instrument profiles: how an autocollimator or a rotary table of any make talks
//! (docs/FORMAT.md §7, *Instruments of other makes*; docs/instruments.md).
//!
//! A profile describes a line-based instrument: its line (serial settings, terminators,
//! the replies that mean a command was refused), the command that identifies it, and
//! — for an autocollimator — the measurement and what makes a reply not a reading, or —
//! for a table — enabling, homing, moving, asking whether a move is done, the position
//! and the last error, each with the reply it gives ([`Template`]) and the
//! [`Condition`]s that read it. What the runner does with them (the drain, the reply
//! deadline, the double reading, the agreement test, never sending a move twice, the
//! position check, resume, the live check) is the runner's and the same for every
//! profile: a profile has no key that could switch it off.
//!
//! Profiles are TOML files. Five are bundled ([`BUNDLED`]), each from its maker's
//! published command set; [`Profile::load`] takes a bundled name or a file's path. A
//! file is checked when read: every error is one [`ProfileError`] naming file, line and
//! column.
//!
//! ```
//! use polycal::lab::profile::{Profile, ProfileKind};
//! let profile = Profile::load("pi-gcs2")?;
//! let ProfileKind::Table(table) = &profile.kind else { panic!("a table") };
//! assert_eq!(table.position.send, "POS? 1");
//! let reply = table.position.reply.matches("1=45.0001").expect("a position reply");
//! assert_eq!(reply.number("deg"), Some(45.0001));
//! # Ok::<(), polycal::lab::profile::ProfileError>(())
//! ```

mod condition;
mod read;
mod template;

use std::collections::BTreeMap;

pub use condition::Condition;
pub use template::{Captures, Field, FieldKind, Template, TemplateError, TemplateProblem};

use crate::input::Location;

/// The bundled profiles: name, what it is, and its TOML text.
pub const BUNDLED: [(&str, &str, &str); 5] = [
    (
        "elcomat3000",
        "Möller-Wedel ELCOMAT 3000 autocollimator",
        include_str!("bundled/elcomat3000.toml"),
    ),
    (
        "smc100",
        "Newport SMC100 motion controller, address 1",
        include_str!("bundled/smc100.toml"),
    ),
    (
        "pi-gcs2",
        "PI GCS 2 controller (C-863, C-884), axis 1",
        include_str!("bundled/pi-gcs2.toml"),
    ),
    (
        "aerotech-ascii",
        "Aerotech Ensemble ASCII command interface, axis @0",
        include_str!("bundled/aerotech-ascii.toml"),
    ),
    (
        "esp301",
        "Newport ESP301 motion controller, axis 1",
        include_str!("bundled/esp301.toml"),
    ),
];

/// A profile that could not be had.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ProfileError {
    /// Neither a bundled name nor a readable file.
    #[error(
        "no bundled profile {name:?} and no such file: the bundled profiles are {list}; a profile of your own is a FILE.toml (docs/instruments.md)"
    )]
    Unknown {
        /// The name or path given.
        name: String,
        /// The bundled names.
        list: String,
    },
    /// The file could not be read.
    #[error("{path}: cannot read the profile: {message}")]
    Io {
        /// The path.
        path: String,
        /// Why.
        message: String,
    },
    /// The file is not a valid profile.
    #[error("{location}: {message}")]
    File {
        /// Where.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// A profile of the other kind of instrument.
    #[error("{name}: a profile of {found}, given for {wanted}")]
    WrongInstrument {
        /// The profile's name.
        name: String,
        /// What it describes.
        found: &'static str,
        /// What it was given for.
        wanted: &'static str,
    },
}

/// Parity of a serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Parity {
    /// None.
    None,
    /// Even.
    Even,
    /// Odd.
    Odd,
}

/// Flow control of a serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FlowControl {
    /// None.
    None,
    /// XON/XOFF.
    Software,
    /// RTS/CTS.
    Hardware,
}

/// The line: serial settings (unused over TCP), terminators, refusals.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LineSettings {
    /// Baud rate.
    pub baud: u32,
    /// Data bits, 5 … 8.
    pub data_bits: u8,
    /// Parity.
    pub parity: Parity,
    /// Stop bits, 1 or 2.
    pub stop_bits: u8,
    /// Flow control.
    pub flow_control: FlowControl,
    /// What the host ends every command with.
    pub command_end: String,
    /// What the device ends every reply with (CR, LF or CR LF; the transport splits
    /// lines at either).
    pub reply_end: String,
    /// Replies that mean the device refused the command it answers (e.g. Aerotech's
    /// `!` and `#`): never a value, and an error when they come.
    pub refusals: Vec<Template>,
}

/// A command and the reply it gives.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Query {
    /// The command, without terminator.
    pub send: String,
    /// Its reply.
    pub reply: Template,
}

/// A command that changes something; `ack` is its reply, when the device gives one.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Command {
    /// The command, without terminator; a move's has `{deg}`.
    pub send: String,
    /// The reply the device gives to it, if any.
    pub ack: Option<Template>,
}

/// How an autocollimator talks.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct AcProfile {
    /// Commands sent on start, each without a reply (e.g. stop a stream); input is
    /// cleared after them.
    pub start: Vec<String>,
    /// Identification; its reply must not pass for any other reply (it brings the device
    /// back in step after a late reply).
    pub identify: Query,
    /// One absolute measurement: fields `x` (arcsec), `y` (arcsec, optional), `status`
    /// (optional, digits).
    pub measure: Query,
    /// When the X axis of a measurement is valid; a reply where it is not is not a
    /// reading.
    pub x_valid: Condition,
    /// When the Y axis is valid (always, when absent and the reply has `y`).
    pub y_valid: Option<Condition>,
}

impl AcProfile {
    /// Reads a measurement reply: its form, X valid (else
    /// [`ReplyError::XNotValid`](crate::lab::ReplyError::XNotValid)), X a finite number, Y
    /// when valid, the status when the reply has one.
    ///
    /// ```
    /// use polycal::lab::profile::Profile;
    /// let elcomat = Profile::load("elcomat3000")?;
    /// let ac = elcomat.autocollimator()?;
    /// let r = ac.reading("4 001 12.5 0.0").unwrap();
    /// assert_eq!((r.status, r.x_arcsec, r.y_arcsec), (1, 12.5, None)); // Y not valid
    /// assert!(ac.reading("4 002 12.5 0.0").is_err()); // X not valid
    /// # Ok::<(), polycal::lab::profile::ProfileError>(())
    /// ```
    ///
    /// # Errors
    ///
    /// The [`ReplyError`](crate::lab::ReplyError) saying what is wrong with the reply.
    pub fn reading(&self, reply: &str) -> Result<crate::lab::AcReading, crate::lab::ReplyError> {
        use crate::lab::ReplyError;
        let template = &self.measure.reply;
        let captures = template
            .matches(reply)
            .ok_or_else(|| ReplyError::NotTheForm {
                form: template.as_str().to_string(),
            })?;
        let status_text = captures.get("status").unwrap_or("").to_string();
        if !self.x_valid.holds(template, &captures) {
            return Err(ReplyError::XNotValid {
                status: status_text,
            });
        }
        let x = captures.number("x").ok_or_else(|| ReplyError::NotFinite {
            name: "X",
            text: captures.get("x").unwrap_or("").to_string(),
        })?;
        let y_valid = self
            .y_valid
            .as_ref()
            .is_none_or(|c| c.holds(template, &captures));
        let y = if y_valid { captures.number("y") } else { None };
        Ok(crate::lab::AcReading::new(
            status_text.parse::<u16>().unwrap_or(0),
            x,
            y,
        ))
    }
}

impl TableProfile {
    /// The position a move command as sent (terminator or not) commands, degrees; `None`
    /// for any other command.
    ///
    /// ```
    /// use polycal::lab::profile::Profile;
    /// let pi = Profile::load("pi-gcs2")?;
    /// assert_eq!(pi.table()?.commanded_deg("MOV 1 22.5\n"), Some(22.5));
    /// assert_eq!(pi.table()?.commanded_deg("POS? 1\n"), None);
    /// # Ok::<(), polycal::lab::profile::ProfileError>(())
    /// ```
    pub fn commanded_deg(&self, command: &str) -> Option<f64> {
        let command = command.trim_end_matches(['\r', '\n']);
        let (before, after) = self.motion.send.split_once("{deg}")?;
        let number = command.strip_prefix(before)?.strip_suffix(after)?;
        number.trim().parse::<f64>().ok().filter(|d| d.is_finite())
    }
}

/// The state query of a table: ready, moving, and optionally not referenced and a fault.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct StateQuery {
    /// The query.
    pub query: Query,
    /// Ready for a move (the last move done).
    pub ready: Condition,
    /// Moving or homing.
    pub moving: Condition,
    /// Not referenced (a home search is due), if the state tells.
    pub not_referenced: Option<Condition>,
    /// A fault: the run stops.
    pub fault: Option<Condition>,
    /// Names of field values for messages: field → value → name.
    pub names: BTreeMap<String, BTreeMap<String, String>>,
    /// Names of a field's bits for messages: field → names of bits 0, 1, ….
    pub bits: BTreeMap<String, Vec<String>>,
}

/// The error query of a table.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ErrorQuery {
    /// The query.
    pub query: Query,
    /// When the reply says "no error".
    pub none: Condition,
    /// Meanings of error codes (value of the condition's field → meaning).
    pub names: BTreeMap<String, String>,
}

/// How a rotary table talks.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct TableProfile {
    /// Identification; its reply must not pass for any other reply.
    pub identify: Query,
    /// Sent on start, in order, before anything moves (servo or motor on, a wait mode),
    /// each followed by the error query; `[[enable]]` in the file.
    pub enable: Vec<Command>,
    /// Home search.
    pub home: Command,
    /// Whether the axis is referenced, if the state does not tell.
    pub referenced: Option<(Query, Condition)>,
    /// Whether a move is done.
    pub state: StateQuery,
    /// Move absolute, `{deg}` in degrees.
    pub motion: Command,
    /// Position: field `deg`.
    pub position: Query,
    /// The last error, asked after every motion command.
    pub error: Option<ErrorQuery>,
    /// Stop at once.
    pub stop: Command,
}

/// What a profile describes.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum ProfileKind {
    /// An autocollimator.
    Autocollimator(Box<AcProfile>),
    /// A rotary table.
    Table(Box<TableProfile>),
}

/// An instrument profile (module docs).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Profile {
    /// Its name (a bundled profile's, or the file's `profile`).
    pub name: String,
    /// What instrument it describes.
    pub description: String,
    /// Where its command set comes from.
    pub source: String,
    /// The line.
    pub line: LineSettings,
    /// The commands.
    pub kind: ProfileKind,
    /// The SHA-256 of the profile's text (its TOML file, or the bundled text), lower-case
    /// hex: a run records it (`manifest.json` `profiles`) so that a resumed run speaks
    /// the same protocol.
    pub sha256: String,
}

impl Profile {
    /// A bundled profile by name, or a profile file (a name ending in `.toml`, or any
    /// path that exists).
    ///
    /// # Errors
    ///
    /// [`ProfileError::Unknown`], [`ProfileError::Io`], [`ProfileError::File`].
    pub fn load(name_or_path: &str) -> Result<Profile, ProfileError> {
        if let Some((name, _, text)) = BUNDLED.iter().find(|(n, _, _)| *n == name_or_path) {
            return read::parse(text, name);
        }
        let path = std::path::Path::new(name_or_path);
        if !name_or_path.ends_with(".toml") && !path.exists() {
            return Err(ProfileError::Unknown {
                name: name_or_path.to_string(),
                list: BUNDLED.map(|(n, _, _)| n).join(", "),
            });
        }
        let text = std::fs::read_to_string(path).map_err(|e| ProfileError::Io {
            path: name_or_path.to_string(),
            message: e.to_string(),
        })?;
        read::parse(&text, name_or_path)
    }

    /// Reads a profile from its TOML text; `source` names it in messages.
    ///
    /// # Errors
    ///
    /// [`ProfileError::File`] at the offending line and column.
    pub fn parse(text: &str, source: &str) -> Result<Profile, ProfileError> {
        read::parse(text, source)
    }

    /// The autocollimator this profile describes.
    ///
    /// # Errors
    ///
    /// [`ProfileError::WrongInstrument`] for a table's profile.
    pub fn autocollimator(&self) -> Result<&AcProfile, ProfileError> {
        match &self.kind {
            ProfileKind::Autocollimator(ac) => Ok(ac),
            ProfileKind::Table(_) => Err(self.wrong("a rotary table", "an autocollimator")),
        }
    }

    /// The table this profile describes.
    ///
    /// # Errors
    ///
    /// [`ProfileError::WrongInstrument`] for an autocollimator's profile.
    pub fn table(&self) -> Result<&TableProfile, ProfileError> {
        match &self.kind {
            ProfileKind::Table(table) => Ok(table),
            ProfileKind::Autocollimator(_) => {
                Err(self.wrong("an autocollimator", "a rotary table"))
            }
        }
    }

    fn wrong(&self, found: &'static str, wanted: &'static str) -> ProfileError {
        ProfileError::WrongInstrument {
            name: self.name.clone(),
            found,
            wanted,
        }
    }

    /// The command as sent on the wire: `command` and the line's terminator.
    pub fn wire(&self, command: &str) -> String {
        format!("{command}{}", self.line.command_end)
    }
}

/// The bytes of a long reply line (an ELCOMAT measurement, `4 003 -123.456789 -12.345678`
/// and CR: 30), for [`LineSettings::alone_wait`].
pub const REPLY_BYTES: usize = 30;

/// What [`LineSettings::alone_wait`] adds to the time of the replies on the line: a
/// USB-serial adapter may hold what it received for its latency timer (16 ms, an FTDI's
/// default) before it hands it on; over TCP it is the whole watch.
pub const ALONE_MARGIN: std::time::Duration = std::time::Duration::from_millis(16);

impl LineSettings {
    /// The time `bytes` bytes take on the serial line (start, data, parity and stop bits
    /// each).
    ///
    /// ```
    /// use polycal::lab::profile::Profile;
    /// // An ELCOMAT reply, `4 003 12.345000 -1.234000` and CR: 26 bytes, 13.5 ms.
    /// let line = Profile::load("elcomat3000")?.line;
    /// assert!((line.line_time(26).as_secs_f64() - 0.0135417).abs() < 1e-6);
    /// # Ok::<(), polycal::lab::profile::ProfileError>(())
    /// ```
    pub fn line_time(&self, bytes: usize) -> std::time::Duration {
        let bits = 1
            + u64::from(self.data_bits)
            + u64::from(self.parity != Parity::None)
            + u64::from(self.stop_bits);
        std::time::Duration::from_secs_f64(bytes as f64 * bits as f64 / f64::from(self.baud.max(1)))
    }

    /// How long a reply is watched for a line after it on this line
    /// ([`crate::lab::QueryOptions::alone_wait`]): twice the time of a reply of
    /// [`REPLY_BYTES`] on the line, plus [`ALONE_MARGIN`] — 47.3 ms for an ELCOMAT at
    /// 19200 baud, 26.4 ms for the SMC100 at 57600.
    ///
    /// ```
    /// use polycal::lab::profile::Profile;
    /// let ms = |d: std::time::Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
    /// assert_eq!(ms(Profile::load("elcomat3000")?.line.alone_wait()), 47.3);
    /// assert_eq!(ms(Profile::load("smc100")?.line.alone_wait()), 26.4);
    /// # Ok::<(), polycal::lab::profile::ProfileError>(())
    /// ```
    pub fn alone_wait(&self) -> std::time::Duration {
        self.line_time(2 * REPLY_BYTES) + ALONE_MARGIN
    }
}

/// A bundled profile by name; the bundled profiles are read and checked by the tests
/// (`tests/sweeps/instrument_profiles.rs`), so a failure here is a defect of the build.
pub(crate) fn bundled(name: &str) -> Profile {
    match Profile::load(name) {
        Ok(profile) => profile,
        Err(e) => panic!("the bundled profile {name} does not read: {e}"),
    }
}

/// The position as a move command states it: up to 6 decimals, trailing zeros dropped
/// (`45`, `51.428571`, `360`).
///
/// ```
/// use polycal::lab::profile::format_degrees;
/// assert_eq!(format_degrees(45.0), "45");
/// assert_eq!(format_degrees(360.0 / 7.0), "51.428571");
/// assert_eq!(format_degrees(-0.0000001), "0");
/// ```
pub fn format_degrees(degrees: f64) -> String {
    let text = format!("{degrees:.6}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_string()
    } else {
        text.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_bundled_profile_reads_and_is_of_its_kind() {
        for (name, description, _) in BUNDLED {
            let profile = Profile::load(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(profile.name, name);
            assert_eq!(profile.description, description, "{name}");
            assert!(!profile.source.is_empty(), "{name} names its source");
            let is_ac = name == "elcomat3000";
            assert_eq!(profile.autocollimator().is_ok(), is_ac, "{name}");
            assert_eq!(profile.table().is_ok(), !is_ac, "{name}");
        }
    }
}
