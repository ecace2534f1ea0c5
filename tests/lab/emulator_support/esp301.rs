//! A Newport ESP301 with a rotary stage on axis 1, as Newport's ESP301 user's manual
//! describes its commands.
//!
//! - A command ends with CR; a reply ends with CR LF. Commands are `[axis]MN[parameter]`
//!   (two letters), several on a line separated by `;`; only queries are answered.
//! - `MO`/`MF` switch the motor on and off, `MO?` tells; `OR` searches home (the counter
//!   set to 0 on the home mark); `PA<pos>` moves; `MD?` is 1 once motion is done, 0
//!   while the axis moves or homes; `TP`/`TP?` the position; `ST` stops; `ID?` the
//!   stage; `VE?` the firmware; `TE?` the oldest error of a queue of ten (0: none) and
//!   `TB?` the same with its time and message.
//! - The ESP301 moves an axis that has not searched home (from wherever the counter came
//!   up). A move or home search with the motor off is error x13 ("motor not enabled",
//!   113 for axis 1) and nothing moves; one during a home search x30 (130). An unknown
//!   command is error 6, an axis other than 1 error 9.
//! - A following error switches the motor off and queues x03 (103); an amplifier fault
//!   that is still there refuses `MO` with x02 (102).

use std::collections::VecDeque;
use std::time::Instant;

use polycal::lab::sim::SimDevice;

use super::{Log, Stage};

/// Error 6: command does not exist.
const NO_SUCH_COMMAND: u32 = 6;
/// Error 7: parameter out of range.
const OUT_OF_RANGE: u32 = 7;
/// Error 9: axis number out of range.
const NO_SUCH_AXIS: u32 = 9;
/// Axis 1, amplifier fault detected.
pub const AMPLIFIER_FAULT: u32 = 102;
/// Axis 1, following error threshold exceeded.
pub const FOLLOWING_ERROR: u32 = 103;
/// Axis 1, motor not enabled.
pub const MOTOR_NOT_ENABLED: u32 = 113;
/// Axis 1, command not allowed during homing.
const DURING_HOMING: u32 = 130;

/// How the controller is found when the session begins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerOn {
    /// Just switched on: motor off, home not searched, the counter at 0.
    MotorOff,
    /// The motor switched on by an earlier session, home never searched.
    MotorOnNotHomed,
    /// A following error in an earlier session: motor off, error 103 in the queue.
    FollowingErrorLatched,
    /// An amplifier fault that is still there: the motor cannot be switched on.
    AmplifierFault,
    /// Motor on and homed by an earlier session.
    Homed,
}

/// The emulated ESP301.
pub struct Esp301 {
    stage: Stage,
    motor: bool,
    amplifier_fault: bool,
    errors: VecDeque<u32>,
    started: Instant,
    log: Log,
}

impl Esp301 {
    /// A controller in state `power_on`, recording into `log`.
    pub fn new(power_on: PowerOn, log: Log) -> Esp301 {
        let mut c = Esp301 {
            stage: Stage::unknown(95.5),
            motor: false,
            amplifier_fault: false,
            errors: VecDeque::new(),
            started: Instant::now(),
            log,
        };
        match power_on {
            PowerOn::MotorOff => {}
            PowerOn::MotorOnNotHomed => c.motor = true,
            PowerOn::FollowingErrorLatched => c.errors.push_back(FOLLOWING_ERROR),
            PowerOn::AmplifierFault => {
                c.amplifier_fault = true;
                c.errors.push_back(AMPLIFIER_FAULT);
            }
            PowerOn::Homed => {
                c.stage = Stage::referenced_at(10.0);
                c.motor = true;
            }
        }
        c
    }

    fn error(&mut self, code: u32) {
        if self.errors.len() == 10 {
            self.errors.pop_front();
        }
        self.errors.push_back(code);
    }

    fn message(code: u32) -> &'static str {
        match code {
            0 => "NO ERROR DETECTED",
            NO_SUCH_COMMAND => "COMMAND DOES NOT EXIST",
            OUT_OF_RANGE => "PARAMETER OUT OF RANGE",
            NO_SUCH_AXIS => "AXIS NUMBER OUT OF RANGE",
            AMPLIFIER_FAULT => "AXIS-1 AMPLIFIER FAULT DETECTED",
            FOLLOWING_ERROR => "AXIS-1 FOLLOWING ERROR THRESHOLD EXCEEDED",
            MOTOR_NOT_ENABLED => "AXIS-1 MOTOR NOT ENABLED",
            DURING_HOMING => "AXIS-1 COMMAND NOT ALLOWED DURING HOMING",
            _ => "UNKNOWN ERROR",
        }
    }

    /// One command of a line; its reply, if it is a query.
    fn one(&mut self, command: &str, now: Instant) -> Option<String> {
        let digits = command.chars().take_while(char::is_ascii_digit).count();
        let (axis, rest) = command.split_at(digits);
        let mnemonic: String = rest
            .chars()
            .take(2)
            .collect::<String>()
            .to_ascii_uppercase();
        let parameter = rest.get(2..).unwrap_or("").trim();
        let on_axis = |axis: &str| axis == "1";
        match (mnemonic.as_str(), parameter) {
            ("VE", "?") => Some("ESP301 Version 3.08.20 02/21/17\r\n".into()),
            ("TE", "?") => Some(format!("{}\r\n", self.errors.pop_front().unwrap_or(0))),
            ("TB", "?") => {
                let code = self.errors.pop_front().unwrap_or(0);
                let ms = self.started.elapsed().as_millis();
                Some(format!("{code}, {ms}, {}\r\n", Esp301::message(code)))
            }
            _ if !on_axis(axis) => {
                self.error(NO_SUCH_AXIS);
                None
            }
            ("ID", "?") => Some("URS100BPP, B200418\r\n".into()),
            ("MO", "") => {
                if self.amplifier_fault {
                    self.error(AMPLIFIER_FAULT);
                } else {
                    self.motor = true;
                }
                None
            }
            ("MO", "?") => Some(format!("{}\r\n", u8::from(self.motor))),
            ("MF", "") => {
                self.stage.stop(now);
                self.motor = false;
                None
            }
            ("MD", "?") => Some(format!("{}\r\n", u8::from(!self.stage.busy()))),
            ("TP", "" | "?") => Some(format!("{:.6}\r\n", self.stage.counter(now))),
            ("ST", "") => {
                self.stage.stop(now);
                None
            }
            ("OR", p) if p.is_empty() || p.parse::<u8>().is_ok_and(|m| m <= 6) => {
                if !self.motor {
                    self.error(MOTOR_NOT_ENABLED);
                } else if self.stage.homing() {
                    self.error(DURING_HOMING);
                } else {
                    self.log.home_started();
                    self.stage.start_home(now);
                }
                None
            }
            ("PA", p) if p != "?" => {
                self.move_absolute(command, p, now);
                None
            }
            _ => {
                self.log.unknown(command);
                self.error(NO_SUCH_COMMAND);
                None
            }
        }
    }

    fn move_absolute(&mut self, command: &str, parameter: &str, now: Instant) {
        let Some(target) = parameter.parse::<f64>().ok().filter(|v| v.is_finite()) else {
            self.error(OUT_OF_RANGE);
            return;
        };
        let accepted = self.motor && !self.stage.homing();
        self.log.motion(command, self.stage.referenced(), accepted);
        if !self.motor {
            self.error(MOTOR_NOT_ENABLED);
        } else if self.stage.homing() {
            self.error(DURING_HOMING);
        } else {
            self.stage.start_move(target, now);
        }
    }
}

impl SimDevice for Esp301 {
    fn handle(&mut self, line: &str, now: Instant) -> Option<String> {
        self.log.received(line);
        let ended = self.stage.update(now);
        self.log.ended(ended);
        let replies: String = line
            .split(';')
            .map(str::trim)
            .filter(|c| !c.is_empty())
            .filter_map(|c| self.one(c, now))
            .collect();
        (!replies.is_empty()).then_some(replies)
    }

    fn tick(&mut self, now: Instant) -> Option<String> {
        let ended = self.stage.update(now);
        self.log.ended(ended);
        None
    }

    fn events(&self) -> u64 {
        0
    }

    fn unsolicited(&mut self, _now: Instant) -> String {
        String::new()
    }
}
