//! An Aerotech Ensemble's ASCII command interface, one rotary axis (index 0, named X),
//! as Aerotech's Ensemble help describes it.
//!
//! - A command ends with LF (the CommandTerminatingCharacter's default); every command is
//!   answered by one line: `%` and the value for success, `!` for a command the
//!   controller cannot parse or does not know, `#` for one it understood and could not
//!   execute (the axis faulted or disabled).
//! - Axes are named (`X`) or given by index (`@0`).
//! - `ENABLE`, `DISABLE`, `FAULTACK` (and `ACKNOWLEDGEALL`), `HOME`, `MOVEABS`, `ABORT`,
//!   `WAIT MODE NOWAIT|MOVEDONE|INPOS`; the functions `AXISSTATUS()`, `AXISFAULT()`,
//!   `PFBK()`, `PFBKPROG()`, `PCMD()`, `GETPARM(axis, 140)` (parameter AxisName).
//! - `MOVEABS` waits for the move to end before it answers unless `WAIT MODE NOWAIT` was
//!   given (MOVEDONE is the default); `HOME` always holds the interpreter until the home
//!   cycle has ended (the EPICS driver runs a program of its own to home without
//!   blocking, and could not abort a home search from the ASCII interface). Commands that
//!   come meanwhile wait their turn.
//! - An Ensemble moves an axis that is not homed: homing is not required, the position
//!   is then counted from wherever the controller came up. A disabled or faulted axis
//!   moves for nothing: `#`.
//! - AXISSTATUS bits: 0 Enabled, 1 Homed, 2 InPosition, 3 MoveActive, 14 Homing,
//!   21 ServoControl, 31 EmergencyStop (printed as a signed 32-bit number). AXISFAULT
//!   bits: 0 PositionError, 1 OverCurrent, 11 EmergencyStop. A fault disables the axis
//!   and stays until `FAULTACK`; a fault whose cause is still there (the emergency stop
//!   pressed) comes back at once.

use std::collections::VecDeque;
use std::time::Instant;

use polycal::lab::sim::SimDevice;

use super::{Log, Stage};

const ENABLED: u32 = 1 << 0;
const HOMED: u32 = 1 << 1;
const IN_POSITION: u32 = 1 << 2;
const MOVE_ACTIVE: u32 = 1 << 3;
const HOMING: u32 = 1 << 14;
const SERVO_CONTROL: u32 = 1 << 21;
const ESTOP_INPUT: u32 = 1 << 31;

/// AXISFAULT PositionError.
pub const POSITION_ERROR: u32 = 1 << 0;
/// AXISFAULT EmergencyStop.
pub const ESTOP_FAULT: u32 = 1 << 11;

/// How the controller is found when the session begins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerOn {
    /// Just switched on: disabled, not homed, the counter at 0 wherever the table is.
    Disabled,
    /// Enabled by an earlier session but never homed (AXISSTATUS 0x200005).
    EnabledNotHomed,
    /// A position error latched by an earlier session: the axis disabled, the fault
    /// there until acknowledged; not homed.
    FaultLatched,
    /// The emergency stop pressed: the fault comes back as soon as it is acknowledged.
    EmergencyStop,
    /// Enabled and homed by an earlier session.
    Homed,
}

/// What an answer waits for.
enum Answer {
    Now(String),
    /// The reply once the motion under way ends.
    WhenDone(String),
}

/// The emulated Ensemble.
pub struct Ensemble {
    stage: Stage,
    enabled: bool,
    faults: u32,
    estop: bool,
    /// `WAIT MODE NOWAIT` given.
    no_wait: bool,
    /// The reply held until the motion under way ends (HOME, or MOVEABS without
    /// NOWAIT), and the commands that came meanwhile.
    held: Option<String>,
    queued: VecDeque<String>,
    log: Log,
}

impl Ensemble {
    /// A controller in state `power_on`, recording into `log`.
    pub fn new(power_on: PowerOn, log: Log) -> Ensemble {
        let mut stage = Stage::unknown(137.25);
        let (mut enabled, mut faults, mut estop) = (false, 0, false);
        match power_on {
            PowerOn::Disabled => {}
            PowerOn::EnabledNotHomed => enabled = true,
            PowerOn::FaultLatched => faults = POSITION_ERROR,
            PowerOn::EmergencyStop => {
                faults = ESTOP_FAULT;
                estop = true;
            }
            PowerOn::Homed => {
                stage = Stage::referenced_at(41.5);
                enabled = true;
            }
        }
        Ensemble {
            stage,
            enabled,
            faults,
            estop,
            no_wait: false,
            held: None,
            queued: VecDeque::new(),
            log,
        }
    }

    fn status(&self) -> u32 {
        let mut bits = 0;
        if self.enabled {
            bits |= ENABLED | SERVO_CONTROL;
        }
        if self.stage.referenced() {
            bits |= HOMED;
        }
        if self.stage.busy() {
            bits |= MOVE_ACTIVE;
        } else {
            bits |= IN_POSITION;
        }
        if self.stage.homing() {
            bits |= HOMING;
        }
        if self.estop {
            bits |= ESTOP_INPUT;
        }
        bits
    }

    /// Whether the axis can move: enabled and no fault.
    fn can_move(&self) -> bool {
        self.enabled && self.faults == 0
    }

    fn answer(&mut self, line: &str, now: Instant) -> Answer {
        let upper = line.trim().to_ascii_uppercase();
        if let Some((function, argument)) = function_call(&upper) {
            if function == "GETPARM" {
                let parameter: Vec<&str> = argument.split(',').map(str::trim).collect();
                return Answer::Now(match parameter.as_slice() {
                    [axis, "140"] if is_axis(axis) => "%X\n".into(),
                    _ => {
                        self.log.unknown(line);
                        "!\n".into()
                    }
                });
            }
            if !is_axis(argument) {
                return Answer::Now("!\n".into());
            }
            return Answer::Now(match function {
                "AXISSTATUS" => format!("%{}\n", self.status() as i32),
                "AXISFAULT" => format!("%{}\n", self.faults),
                "PFBK" | "PFBKPROG" | "PCMD" => {
                    format!("%{:.6}\n", self.stage.counter(now))
                }
                _ => {
                    self.log.unknown(line);
                    "!\n".into()
                }
            });
        }
        let words: Vec<&str> = upper.split_whitespace().collect();
        match words.as_slice() {
            ["ENABLE", axis] if is_axis(axis) => {
                if self.faults != 0 {
                    return Answer::Now("#\n".into());
                }
                self.enabled = true;
                Answer::Now("%\n".into())
            }
            ["DISABLE", axis] if is_axis(axis) => {
                self.stage.stop(now);
                self.enabled = false;
                Answer::Now("%\n".into())
            }
            ["FAULTACK", axis] if is_axis(axis) => {
                self.acknowledge();
                Answer::Now("%\n".into())
            }
            ["ACKNOWLEDGEALL"] => {
                self.acknowledge();
                Answer::Now("%\n".into())
            }
            ["WAIT", "MODE", mode] if ["NOWAIT", "MOVEDONE", "INPOS"].contains(mode) => {
                self.no_wait = *mode == "NOWAIT";
                Answer::Now("%\n".into())
            }
            ["ABORT", axis] if is_axis(axis) => {
                self.stage.stop(now);
                Answer::Now("%\n".into())
            }
            ["HOME", axis] if is_axis(axis) => {
                if !self.can_move() {
                    return Answer::Now("#\n".into());
                }
                self.log.home_started();
                self.stage.start_home(now);
                Answer::WhenDone("%\n".into())
            }
            ["MOVEABS", axis, rest @ ..] if is_axis(axis) => self.move_absolute(line, rest, now),
            _ => {
                self.log.unknown(line);
                Answer::Now("!\n".into())
            }
        }
    }

    /// `MOVEABS X 22.5 [F 10 | F10 | XF 10 | XF10]`.
    fn move_absolute(&mut self, line: &str, rest: &[&str], now: Instant) -> Answer {
        let Some(target) = rest.first().and_then(|p| p.parse::<f64>().ok()) else {
            self.log.unknown(line);
            return Answer::Now("!\n".into());
        };
        if !speed_clause(&rest[1..]) {
            self.log.unknown(line);
            return Answer::Now("!\n".into());
        }
        let accepted = self.can_move();
        self.log.motion(line, self.stage.referenced(), accepted);
        if !accepted {
            return Answer::Now("#\n".into());
        }
        self.stage.start_move(target, now);
        if self.no_wait {
            Answer::Now("%\n".into())
        } else {
            Answer::WhenDone("%\n".into())
        }
    }

    /// FAULTACK: clears the faults whose cause is gone.
    fn acknowledge(&mut self) {
        self.faults = if self.estop { ESTOP_FAULT } else { 0 };
    }

    /// Ends the motion whose time is up; releases a held reply and answers the commands
    /// that waited for it, in order.
    fn advance(&mut self, now: Instant) -> String {
        let ended = self.stage.update(now);
        self.log.ended(ended);
        let mut out = String::new();
        while self.held.is_some() && !self.stage.busy() {
            out.push_str(&self.held.take().unwrap_or_default());
            while self.held.is_none() {
                let Some(line) = self.queued.pop_front() else {
                    break;
                };
                match self.answer(&line, now) {
                    Answer::Now(reply) => out.push_str(&reply),
                    Answer::WhenDone(reply) => self.held = Some(reply),
                }
            }
        }
        out
    }
}

/// `NAME(ARGUMENT)`.
fn function_call(line: &str) -> Option<(&str, &str)> {
    let (name, rest) = line.split_once('(')?;
    let argument = rest.strip_suffix(')')?;
    Some((name.trim(), argument.trim()))
}

/// Axis 0 by name or index.
fn is_axis(word: &str) -> bool {
    word == "X" || word == "@0"
}

/// An optional speed: `F 10`, `F10`, `XF 10`, `XF10`, `@0F 10`.
fn speed_clause(words: &[&str]) -> bool {
    let number = |w: &str| w.parse::<f64>().is_ok_and(|v| v > 0.0);
    match words {
        [] => true,
        [f, v] if ["F", "XF", "@0F"].contains(f) => number(v),
        [fv] => ["F", "XF", "@0F"]
            .iter()
            .any(|p| fv.strip_prefix(p).is_some_and(number)),
        _ => false,
    }
}

impl SimDevice for Ensemble {
    fn handle(&mut self, command: &str, now: Instant) -> Option<String> {
        self.log.received(command);
        let mut out = self.advance(now);
        if self.held.is_some() {
            self.queued.push_back(command.to_string());
        } else {
            match self.answer(command, now) {
                Answer::Now(reply) => out.push_str(&reply),
                Answer::WhenDone(reply) => self.held = Some(reply),
            }
        }
        (!out.is_empty()).then_some(out)
    }

    fn tick(&mut self, now: Instant) -> Option<String> {
        let out = self.advance(now);
        (!out.is_empty()).then_some(out)
    }

    fn events(&self) -> u64 {
        0
    }

    fn unsolicited(&mut self, _now: Instant) -> String {
        String::new()
    }
}
