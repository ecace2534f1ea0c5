//! The Newport SMC100 motion-controller protocol, controller address 1 (docs/FORMAT.md §7).
//!
//! Commands `1<CMD><argument>` end with CR LF; replies `1<CMD><value>` end with CR LF.
//! The driver uses:
//!
//! | command | reply | use |
//! |---|---|---|
//! | `1TS` | `1TS<eeee><ss>` | error bits (4 hex digits) and state (2 hex digits) |
//! | `1OR` | none | home (only when not referenced); a motion |
//! | `1PA<deg>` | none | move absolute; a motion |
//! | `1TE` | `1TE<c>` | the last command's error (`@`: none), asked after every motion command |
//! | `1TP` | `1TP<deg>` | position |
//! | `1ST` | none | stop |
//! | `1VE` | `1VE<text>` | identification (controller version; not in docs/FORMAT.md, standard SMC100) |
//!
//! A move is: `1TS` (must be ready), `1PA<deg>` sent **once**, `1TE` (must be `@`), `1TS`
//! every poll interval until ready, `1TP` (must be within tolerance of the target). A
//! lost or garbled reply to a query is retried; the motion command never is: after a
//! lost reply the driver asks the state and the position again. A disable state
//! (`3C`–`3E`), the configuration state, a lost reference, unexpected states and any
//! error bit are errors.

use std::time::{Duration, Instant};

use super::query::{Resync, query};
use super::transport::Transport;
use super::{InstrumentError, QueryOptions, ReplyError, RotaryTable, StopFlag};

/// State query.
pub const STATE: &str = "1TS\r\n";
/// Position query.
pub const POSITION: &str = "1TP\r\n";
/// Last-error query.
pub const LAST_ERROR: &str = "1TE\r\n";
/// Stop.
pub const STOP: &str = "1ST\r\n";
/// Home search.
pub const HOME: &str = "1OR\r\n";
/// Version (identification).
pub const VERSION: &str = "1VE\r\n";
/// The largest difference between the reported and the commanded position a move
/// accepts unless set otherwise, degrees.
pub const POSITION_TOLERANCE_DEG: f64 = 0.001;

/// How the driver brings the controller back in step after a late or doubtful reply:
/// `1VE`, whose reply no state, position or error reply can be mistaken for.
const RESYNC: Resync = Resync {
    command: VERSION,
    is_reply: |line| parse_version(line).is_ok(),
};

/// The controller state, from the two hex digits of a `1TS` reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControllerState {
    /// `0A`–`11`: not referenced (needs a home search).
    NotReferenced(u8),
    /// `14`: configuration.
    Configuration,
    /// `1E`, `1F`: homing.
    Homing(u8),
    /// `28`: moving.
    Moving,
    /// `32` ready from homing, `33` from moving, `34` from disable.
    Ready(u8),
    /// `3C`–`3E`: disable.
    Disable(u8),
    /// Any other code (jogging, ready T, …): not used by this driver.
    Other(u8),
}

impl ControllerState {
    /// The state of a code.
    pub fn from_code(code: u8) -> ControllerState {
        match code {
            0x0A..=0x11 => ControllerState::NotReferenced(code),
            0x14 => ControllerState::Configuration,
            0x1E | 0x1F => ControllerState::Homing(code),
            0x28 => ControllerState::Moving,
            0x32..=0x34 => ControllerState::Ready(code),
            0x3C..=0x3E => ControllerState::Disable(code),
            _ => ControllerState::Other(code),
        }
    }

    /// The code, as the two hex digits of the protocol.
    pub fn code(self) -> u8 {
        match self {
            ControllerState::NotReferenced(c)
            | ControllerState::Homing(c)
            | ControllerState::Ready(c)
            | ControllerState::Disable(c)
            | ControllerState::Other(c) => c,
            ControllerState::Configuration => 0x14,
            ControllerState::Moving => 0x28,
        }
    }

    /// Whether the controller accepts a motion command.
    pub fn is_ready(self) -> bool {
        matches!(self, ControllerState::Ready(_))
    }

    /// The state's name in the SMC100 manual, e.g. `READY from MOVING`.
    pub fn name(self) -> &'static str {
        match self.code() {
            0x0A => "NOT REFERENCED from RESET",
            0x0B => "NOT REFERENCED from HOMING",
            0x0C => "NOT REFERENCED from CONFIGURATION",
            0x0D => "NOT REFERENCED from DISABLE",
            0x0E => "NOT REFERENCED from READY",
            0x0F => "NOT REFERENCED from MOVING",
            0x10 => "NOT REFERENCED, ESP stage error",
            0x11 => "NOT REFERENCED from JOGGING",
            0x14 => "CONFIGURATION",
            0x1E => "HOMING",
            0x1F => "REFERENCING",
            0x28 => "MOVING",
            0x32 => "READY from HOMING",
            0x33 => "READY from MOVING",
            0x34 => "READY from DISABLE",
            0x3C => "DISABLE from READY",
            0x3D => "DISABLE from MOVING",
            0x3E => "DISABLE from JOGGING",
            _ => "an unexpected state",
        }
    }
}

/// A parsed `1TS` reply.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct TableStatus {
    /// The positioner error bits (0: none).
    pub error_bits: u16,
    /// The controller state.
    pub state: ControllerState,
}

/// The meanings of the SMC100 positioner error bits that are set in `bits`.
pub fn error_bit_names(bits: u16) -> Vec<&'static str> {
    const NAMES: [&str; 10] = [
        "negative end of run",
        "positive end of run",
        "peak current limit",
        "RMS current limit",
        "short circuit detection",
        "following error",
        "homing time-out",
        "wrong ESP stage",
        "DC voltage too low",
        "80 W output power exceeded",
    ];
    (0..16)
        .filter(|i| bits & (1 << i) != 0)
        .map(|i| NAMES.get(i).copied().unwrap_or("reserved bit"))
        .collect()
}

/// The meaning of a `1TE` error code.
pub fn command_error_name(code: char) -> &'static str {
    match code {
        '@' => "no error",
        'A' => "unknown message code or floating point controller address",
        'B' => "controller address not correct",
        'C' => "parameter missing or out of range",
        'D' => "command not allowed",
        'E' => "home sequence already started",
        'G' => "displacement out of limits",
        'H' => "command not allowed in NOT REFERENCED state",
        'I' => "command not allowed in CONFIGURATION state",
        'J' => "command not allowed in DISABLE state",
        'K' => "command not allowed in READY state",
        'L' => "command not allowed in HOMING state",
        'M' => "command not allowed in MOVING state",
        'N' => "current position out of software limit",
        'S' => "communication time-out",
        'U' => "error during EEPROM access",
        'V' => "error during command execution",
        'W' => "command not allowed for PP version",
        'X' => "command not allowed for CC version",
        _ => "unknown error code",
    }
}

/// Parses a `1TS<eeee><ss>` reply.
///
/// ```
/// use polycal::lab::smc100::{parse_status, ControllerState};
/// let s = parse_status("1TS000033").unwrap();
/// assert_eq!((s.error_bits, s.state), (0, ControllerState::Ready(0x33)));
/// assert!(parse_status("1TS00003").is_err());
/// ```
///
/// # Errors
///
/// [`ReplyError::NotThisReply`] without the `1TS` prefix, [`ReplyError::Form`] when six
/// hex digits do not follow it.
pub fn parse_status(line: &str) -> Result<TableStatus, ReplyError> {
    let rest = line.strip_prefix("1TS").ok_or(ReplyError::NotThisReply {
        what: "a state reply",
        form: "1TS<eeee><ss>",
    })?;
    let form = ReplyError::Form {
        what: "a state reply",
        form: "`1TS` and six hex digits (`<eeee><ss>`)",
    };
    if rest.len() != 6 || !rest.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(form);
    }
    let (Ok(error_bits), Ok(code)) = (
        u16::from_str_radix(&rest[..4], 16),
        u8::from_str_radix(&rest[4..], 16),
    ) else {
        return Err(form);
    };
    Ok(TableStatus {
        error_bits,
        state: ControllerState::from_code(code),
    })
}

/// Parses a `1TP<deg>` reply.
///
/// # Errors
///
/// [`ReplyError::NotThisReply`] without the `1TP` prefix, [`ReplyError::NotFinite`] when
/// a finite number does not follow it.
pub fn parse_position(line: &str) -> Result<f64, ReplyError> {
    let rest = line.strip_prefix("1TP").ok_or(ReplyError::NotThisReply {
        what: "a position reply",
        form: "1TP<deg>",
    })?;
    match rest.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(ReplyError::NotFinite {
            name: "position",
            text: rest.to_string(),
        }),
    }
}

/// Parses a `1TE<c>` reply into the code (`@`: no error).
///
/// # Errors
///
/// [`ReplyError::NotThisReply`] without the `1TE` prefix, [`ReplyError::Form`] when one
/// character (`@` or an upper-case letter) does not follow it.
pub fn parse_last_error(line: &str) -> Result<char, ReplyError> {
    let rest = line.strip_prefix("1TE").ok_or(ReplyError::NotThisReply {
        what: "an error reply",
        form: "1TE<c>",
    })?;
    let mut chars = rest.chars();
    match (chars.next(), chars.next()) {
        (Some(c), None) if c == '@' || c.is_ascii_uppercase() => Ok(c),
        _ => Err(ReplyError::Form {
            what: "an error reply",
            form: "`1TE` and one character",
        }),
    }
}

/// Parses a `1VE<text>` reply into the text.
///
/// # Errors
///
/// [`ReplyError::NotThisReply`] for anything but `1VE` and some text.
pub fn parse_version(line: &str) -> Result<String, ReplyError> {
    match line.strip_prefix("1VE") {
        Some(text) if !text.trim().is_empty() => Ok(text.trim().to_string()),
        _ => Err(ReplyError::NotThisReply {
            what: "a version reply",
            form: "1VE<text>",
        }),
    }
}

/// A position as sent in `1PA`: up to 6 decimals, trailing zeros dropped (`45`,
/// `51.428571`, `360`).
pub fn format_position(degrees: f64) -> String {
    let text = format!("{degrees:.6}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".to_string()
    } else {
        text.to_string()
    }
}

/// How the SMC100 driver waits and checks.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Smc100Options {
    /// Reply deadline and retries of queries.
    pub query: QueryOptions,
    /// Time between two `1TS` while the table moves or homes.
    pub poll_interval: Duration,
    /// Longest a move or a home search may take.
    pub motion_timeout: Duration,
    /// Largest accepted difference between the reported and the commanded position, degrees.
    pub position_tolerance_deg: f64,
}

impl Smc100Options {
    /// Options with `query` for the queries, 20 ms polling, 120 s per motion and a
    /// 0.001° tolerance.
    pub fn new(query: QueryOptions) -> Smc100Options {
        Smc100Options {
            query,
            poll_interval: Duration::from_millis(20),
            motion_timeout: Duration::from_secs(120),
            position_tolerance_deg: POSITION_TOLERANCE_DEG,
        }
    }

    /// Sets the reply deadline and retries of queries.
    pub fn with_query(mut self, query: QueryOptions) -> Smc100Options {
        self.query = query;
        self
    }

    /// Sets the time between two `1TS` while the table moves or homes.
    pub fn with_poll_interval(mut self, poll_interval: Duration) -> Smc100Options {
        self.poll_interval = poll_interval;
        self
    }

    /// Sets the longest a move or a home search may take.
    pub fn with_motion_timeout(mut self, motion_timeout: Duration) -> Smc100Options {
        self.motion_timeout = motion_timeout;
        self
    }

    /// Sets the largest accepted difference between the reported and the commanded
    /// position, degrees.
    pub fn with_position_tolerance_deg(mut self, position_tolerance_deg: f64) -> Smc100Options {
        self.position_tolerance_deg = position_tolerance_deg;
        self
    }
}

impl Default for Smc100Options {
    /// Default queries, 20 ms polling, 120 s per motion, 0.001° tolerance.
    fn default() -> Self {
        Smc100Options::new(QueryOptions::default())
    }
}

/// The SMC100 driver over any [`Transport`].
#[derive(Debug)]
pub struct Smc100<T> {
    transport: T,
    options: Smc100Options,
    stop: StopFlag,
}

impl<T: Transport> Smc100<T> {
    /// A driver over `transport`.
    pub fn new(transport: T, options: Smc100Options) -> Self {
        Smc100 {
            transport,
            options,
            stop: StopFlag::new(),
        }
    }

    /// Makes waits for motion watch `stop`: when it is set, the table is stopped (`1ST`)
    /// and the move ends with [`InstrumentError::Interrupted`].
    pub fn with_stop_flag(mut self, stop: StopFlag) -> Self {
        self.stop = stop;
        self
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The state and error bits (`1TS`), as reported.
    pub fn status(&mut self) -> Result<(TableStatus, String), InstrumentError> {
        query(
            &mut self.transport,
            &self.options.query,
            Some(&RESYNC),
            STATE,
            parse_status,
        )
    }

    fn device_error(&self, sent: &str, received: &str, message: String) -> InstrumentError {
        InstrumentError::Device {
            port: self.transport.port().to_string(),
            sent: sent.to_string(),
            received: received.to_string(),
            message,
        }
    }

    /// The state, with error bits, a disable state and the configuration state turned
    /// into errors.
    fn checked_status(&mut self) -> Result<TableStatus, InstrumentError> {
        let (status, line) = self.status()?;
        if status.error_bits != 0 {
            return Err(self.device_error(
                STATE,
                &line,
                format!(
                    "the controller reports error bits {:04X}: {}",
                    status.error_bits,
                    error_bit_names(status.error_bits).join(", ")
                ),
            ));
        }
        match status.state {
            ControllerState::Disable(code) => Err(self.device_error(
                STATE,
                &line,
                format!(
                    "the table is in state {code:02X} ({}): enable it (1MM1) and check the stage, then resume",
                    status.state.name()
                ),
            )),
            ControllerState::Configuration => Err(self.device_error(
                STATE,
                &line,
                "the controller is in CONFIGURATION state (14): leave it (1PW0) first".into(),
            )),
            ControllerState::Other(code) => Err(self.device_error(
                STATE,
                &line,
                format!("the controller is in an unexpected state {code:02X}"),
            )),
            _ => Ok(status),
        }
    }

    /// After a motion command: the controller must not have refused it.
    fn check_accepted(&mut self, motion: &str) -> Result<(), InstrumentError> {
        let (code, line) = query(
            &mut self.transport,
            &self.options.query,
            Some(&RESYNC),
            LAST_ERROR,
            parse_last_error,
        )?;
        if code == '@' {
            return Ok(());
        }
        Err(self.device_error(
            LAST_ERROR,
            &line,
            format!(
                "the controller refused {:?}: error {code} ({})",
                motion,
                command_error_name(code)
            ),
        ))
    }

    /// Polls the state until the controller is ready again after `motion`.
    fn wait_ready(&mut self, motion: &str) -> Result<(), InstrumentError> {
        let deadline = Instant::now() + self.options.motion_timeout;
        loop {
            if self.stop.is_set() {
                let _ = self.stop();
                return Err(InstrumentError::Interrupted {
                    port: self.transport.port().to_string(),
                });
            }
            let status = self.checked_status()?;
            match status.state {
                ControllerState::Ready(_) => return Ok(()),
                ControllerState::Moving | ControllerState::Homing(_) => {}
                ControllerState::NotReferenced(code) => {
                    return Err(self.device_error(
                        STATE,
                        &format!("1TS{:04X}{code:02X}", status.error_bits),
                        format!(
                            "after {motion:?} the table is in state {code:02X} ({}): it lost its reference",
                            status.state.name()
                        ),
                    ));
                }
                _ => {}
            }
            if Instant::now() >= deadline {
                let _ = self.stop();
                return Err(self.device_error(
                    motion,
                    "",
                    format!(
                        "the table was not ready {} s after the motion command; stopped it",
                        self.options.motion_timeout.as_secs_f64()
                    ),
                ));
            }
            self.stop.sleep(self.options.poll_interval);
        }
    }
}

impl<T: Transport> RotaryTable for Smc100<T> {
    fn port(&self) -> &str {
        self.transport.port()
    }

    fn start(&mut self) -> Result<(), InstrumentError> {
        self.transport.clear_input()?;
        let status = self.checked_status()?;
        match status.state {
            ControllerState::Ready(_) => Ok(()),
            ControllerState::NotReferenced(_) => {
                self.transport.send(HOME)?;
                self.check_accepted(HOME)?;
                self.wait_ready(HOME)
            }
            _ => self.wait_ready("(motion in progress at start)"),
        }
    }

    fn identify(&mut self) -> Result<String, InstrumentError> {
        query(
            &mut self.transport,
            &self.options.query,
            None,
            VERSION,
            parse_version,
        )
        .map(|(text, _)| text)
    }

    fn move_to(&mut self, degrees: f64) -> Result<f64, InstrumentError> {
        if self.stop.is_set() {
            return Err(InstrumentError::Interrupted {
                port: self.transport.port().to_string(),
            });
        }
        let status = self.checked_status()?;
        if !status.state.is_ready() {
            return Err(self.device_error(
                STATE,
                &format!("1TS{:04X}{:02X}", status.error_bits, status.state.code()),
                format!(
                    "the table is not ready for a move (state {:02X}: {})",
                    status.state.code(),
                    status.state.name()
                ),
            ));
        }
        let motion = format!("1PA{}\r\n", format_position(degrees));
        self.transport.send(&motion)?;
        self.check_accepted(&motion)?;
        self.wait_ready(&motion)?;
        let (position, line) = query(
            &mut self.transport,
            &self.options.query,
            Some(&RESYNC),
            POSITION,
            parse_position,
        )?;
        if (position - degrees).abs() > self.options.position_tolerance_deg {
            return Err(self.device_error(
                POSITION,
                &line,
                format!("the table stopped at {position}°, not at the commanded {degrees}°"),
            ));
        }
        Ok(position)
    }

    fn position(&mut self) -> Result<f64, InstrumentError> {
        query(
            &mut self.transport,
            &self.options.query,
            Some(&RESYNC),
            POSITION,
            parse_position,
        )
        .map(|(p, _)| p)
    }

    fn stop(&mut self) -> Result<(), InstrumentError> {
        self.transport.send(STOP)
    }
}
