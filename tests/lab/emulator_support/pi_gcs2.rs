//! A PI C-863 (Mercury) with one rotary axis, `1`, speaking GCS 2.0 as PI's command
//! reference describes it.
//!
//! - A command ends with LF, and so does a reply; only queries (`…?`) and the single
//!   characters `#5`, `#7`, `#24` are answered. A refused command is silent: its error
//!   code is kept (the last one) until `ERR?` reads and resets it.
//! - `*IDN?`; `SVO 1 0|1` and `SVO? [1]`; `FRF [1]` (the reference move, servo on only,
//!   else error 5) and `FRF? [1]`; `MOV 1 <pos>` (servo on and axis referenced only,
//!   else error 5, "Unallowable move attempted on unreferenced axis, or move attempted
//!   with servo off", and nothing moves); `POS? [1]`, `ONT? [1]` (on target: servo on,
//!   not moving, not referencing); `ERR?`; `STP`, `HLT [1]` and `#24` (stop, error 10);
//!   `#5` (motion status, a hex mask); `RON? [1]`. An unknown command is error 2, an
//!   unknown axis error 15.
//! - A motion error (error −1024, "position error too large") switches the servo off.

use std::time::Instant;

use polycal::lab::sim::SimDevice;

use super::{Log, Stage};

/// GCS error 2: unknown command.
const UNKNOWN_COMMAND: i32 = 2;
/// GCS error 5: a move on an unreferenced axis or with the servo off.
pub const MOVE_WITHOUT_REF_OR_NO_SERVO: i32 = 5;
/// GCS error 10: stopped by command.
const STOPPED: i32 = 10;
/// GCS error 15: invalid axis identifier.
const INVALID_AXIS: i32 = 15;
/// GCS error −1024: motion error, the servo switched off.
pub const MOTION_ERROR: i32 = -1024;

/// How the controller is found when the session begins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerOn {
    /// Just switched on: servo off, not referenced, the counter at 0.
    ServoOff,
    /// The servo switched on by an earlier session, the axis never referenced.
    ServoOnNotReferenced,
    /// A motion error in an earlier session: servo off, error −1024 not yet read, the
    /// axis still referenced.
    MotionErrorLatched,
    /// The stage is jammed: every time the servo is switched on, a motion error
    /// switches it off again.
    Jammed,
    /// Servo on and referenced by an earlier session.
    Referenced,
}

/// The emulated C-863.
pub struct C863 {
    stage: Stage,
    servo: bool,
    error: i32,
    jammed: bool,
    log: Log,
}

impl C863 {
    /// A controller in state `power_on`, recording into `log`.
    pub fn new(power_on: PowerOn, log: Log) -> C863 {
        let mut c = C863 {
            stage: Stage::unknown(211.75),
            servo: false,
            error: 0,
            jammed: false,
            log,
        };
        match power_on {
            PowerOn::ServoOff => {}
            PowerOn::ServoOnNotReferenced => c.servo = true,
            PowerOn::MotionErrorLatched => {
                c.stage = Stage::referenced_at(63.0);
                c.error = MOTION_ERROR;
            }
            PowerOn::Jammed => c.jammed = true,
            PowerOn::Referenced => {
                c.stage = Stage::referenced_at(63.0);
                c.servo = true;
            }
        }
        c
    }

    fn on_target(&self) -> bool {
        self.servo && !self.stage.busy()
    }

    /// `1=<value>` for axis 1 when the axis list is empty or `1`; `None` (error 15) for
    /// another axis.
    fn axis_reply(&mut self, axes: &[&str], value: String) -> Option<String> {
        if axes.iter().all(|a| *a == "1") {
            Some(format!("1={value}\n"))
        } else {
            self.error = INVALID_AXIS;
            None
        }
    }

    fn answer(&mut self, line: &str, now: Instant) -> Option<String> {
        let words: Vec<&str> = line.split_whitespace().collect();
        let (&command, arguments) = words.split_first()?;
        match command {
            "\u{5}" | "#5" => Some(format!("{}\n", u8::from(self.stage.busy()))),
            "\u{18}" | "#24" | "STP" => {
                self.stage.stop(now);
                self.error = STOPPED;
                None
            }
            "*IDN?" => Some(
                "(c)2017 Physik Instrumente (PI) GmbH & Co. KG, C-863.11, 0117030512, 01.02.01.12\n"
                    .into(),
            ),
            "ERR?" => Some(format!("{}\n", std::mem::take(&mut self.error))),
            "SVO" => {
                match arguments {
                    ["1", "1"] => self.servo_on(),
                    ["1", "0"] => {
                        self.stage.stop(now);
                        self.servo = false;
                    }
                    [_, _] => self.error = INVALID_AXIS,
                    _ => self.error = 1,
                }
                None
            }
            "SVO?" => {
                let value = u8::from(self.servo).to_string();
                self.axis_reply(arguments, value)
            }
            "FRF" => {
                if !arguments.iter().all(|a| *a == "1") {
                    self.error = INVALID_AXIS;
                } else if !self.servo {
                    self.error = MOVE_WITHOUT_REF_OR_NO_SERVO;
                } else {
                    self.log.home_started();
                    self.stage.start_home(now);
                }
                None
            }
            "FRF?" => {
                let value = u8::from(self.stage.referenced()).to_string();
                self.axis_reply(arguments, value)
            }
            "RON?" => self.axis_reply(arguments, "1".into()),
            "MOV" => {
                self.move_absolute(line, arguments, now);
                None
            }
            "POS?" => {
                let value = format!("{:.6}", self.stage.counter(now));
                self.axis_reply(arguments, value)
            }
            "ONT?" => {
                let value = u8::from(self.on_target()).to_string();
                self.axis_reply(arguments, value)
            }
            "HLT" => {
                self.stage.stop(now);
                self.error = STOPPED;
                None
            }
            _ => {
                self.log.unknown(line);
                self.error = UNKNOWN_COMMAND;
                None
            }
        }
    }

    fn servo_on(&mut self) {
        if self.jammed {
            // The position error grows at once: the motion error switches it off again.
            self.servo = false;
            self.error = MOTION_ERROR;
        } else {
            self.servo = true;
        }
    }

    fn move_absolute(&mut self, line: &str, arguments: &[&str], now: Instant) {
        let target = match arguments {
            ["1", value] => value.parse::<f64>().ok().filter(|v| v.is_finite()),
            [_, _] => {
                self.error = INVALID_AXIS;
                return;
            }
            _ => None,
        };
        let Some(target) = target else {
            self.error = 1; // parameter syntax error
            return;
        };
        let accepted = self.servo && self.stage.referenced() && !self.stage.homing();
        self.log.motion(line, self.stage.referenced(), accepted);
        if accepted {
            self.stage.start_move(target, now);
        } else {
            self.error = MOVE_WITHOUT_REF_OR_NO_SERVO;
        }
    }
}

impl SimDevice for C863 {
    fn handle(&mut self, command: &str, now: Instant) -> Option<String> {
        self.log.received(command);
        let ended = self.stage.update(now);
        self.log.ended(ended);
        self.answer(command, now)
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
