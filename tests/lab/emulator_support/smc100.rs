//! A Newport SMC100 (address 1) with a rotary stage, as Newport's SMC100CC user's manual
//! describes its commands and its state diagram.
//!
//! - A command is `1XX[parameter]` ending with CR LF; a reply repeats `1XX` before its
//!   value and ends with CR LF; only queries are answered. A refused command is silent:
//!   its error letter is kept (the last one) until `TE` reads and resets it.
//! - States (`TS`'s last two characters, after four hex digits of positioner errors):
//!   0A NOT REFERENCED from reset, 0D NOT REFERENCED from DISABLE, 1E HOMING, 28
//!   MOVING, 32/33/34 READY from HOMING/MOVING/DISABLE, 3C/3D DISABLE from READY/MOVING.
//! - `OR` searches home in NOT REFERENCED only (else K in READY, J in DISABLE, L while
//!   homing, M while moving); `PA` moves in READY only (else H not referenced, J
//!   disabled, L homing, M moving) — nothing moves; `MM0`/`MM1` enter and leave DISABLE
//!   (READY ↔ DISABLE; H in NOT REFERENCED); `TS`, `TP`, `TE`, `VE`; `ST` stops; `RS`
//!   resets to NOT REFERENCED. An unknown command is error A.
//! - A following error during a move disables the controller (3D) with positioner error
//!   0x0020 until `MM1` leaves DISABLE.

use std::time::Instant;

use polycal::lab::sim::SimDevice;

use super::{Log, Stage};

/// Positioner error: following error.
const FOLLOWING_ERROR: u16 = 0x0020;

/// How the controller is found when the session begins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerOn {
    /// Just switched on: NOT REFERENCED from reset (0A), the counter at 0.
    NotReferenced,
    /// Referenced by an earlier session, then disabled (DISABLE from READY, 3C).
    Disabled,
    /// A following error during an earlier session's move: DISABLE from MOVING (3D),
    /// positioner error 0x0020.
    FollowingError,
    /// Referenced and ready (READY from MOVING, 33).
    Ready,
}

/// The emulated SMC100.
pub struct Smc100 {
    stage: Stage,
    /// The state when at rest (the motion's own state comes from the stage).
    state: u8,
    positioner: u16,
    error: char,
    log: Log,
}

impl Smc100 {
    /// A controller in state `power_on`, recording into `log`.
    pub fn new(power_on: PowerOn, log: Log) -> Smc100 {
        let (stage, state, positioner) = match power_on {
            PowerOn::NotReferenced => (Stage::unknown(301.0), 0x0A, 0),
            PowerOn::Disabled => (Stage::referenced_at(72.0), 0x3C, 0),
            PowerOn::FollowingError => (Stage::referenced_at(72.3), 0x3D, FOLLOWING_ERROR),
            PowerOn::Ready => (Stage::referenced_at(72.0), 0x33, 0),
        };
        Smc100 {
            stage,
            state,
            positioner,
            error: '@',
            log,
        }
    }

    fn update(&mut self, now: Instant) {
        let ended = self.stage.update(now);
        match ended {
            Some((true, _)) => self.state = 0x32,
            Some((false, _)) => self.state = 0x33,
            None => {}
        }
        self.log.ended(ended);
    }

    fn current(&self) -> u8 {
        match (self.stage.homing(), self.stage.busy()) {
            (true, _) => 0x1E,
            (false, true) => 0x28,
            _ => self.state,
        }
    }

    fn not_referenced(state: u8) -> bool {
        (0x0A..=0x11).contains(&state)
    }

    /// The error letter of a command not allowed in `state`.
    fn refusal(state: u8) -> char {
        match state {
            s if Smc100::not_referenced(s) => 'H',
            0x14 => 'I',
            0x1E | 0x1F => 'L',
            0x28 => 'M',
            0x32..=0x35 => 'K',
            0x3C..=0x3E => 'J',
            _ => 'D',
        }
    }

    fn answer(&mut self, line: &str, now: Instant) -> Option<String> {
        let rest = line.strip_prefix('1')?; // another address: not this controller
        let name: String = rest
            .chars()
            .take(2)
            .collect::<String>()
            .to_ascii_uppercase();
        let parameter = rest.get(2..).unwrap_or("").trim();
        let state = self.current();
        match (name.as_str(), parameter) {
            ("TS", "" | "?") => Some(format!("1TS{:04X}{state:02X}\r\n", self.positioner)),
            ("TP", "" | "?") => Some(format!("1TP{:.6}\r\n", self.stage.counter(now))),
            ("TE", "" | "?") => Some(format!(
                "1TE{}\r\n",
                std::mem::replace(&mut self.error, '@')
            )),
            ("VE", "" | "?") => Some("1VE SMC_CC - Controller-driver version  3. 1. 2\r\n".into()),
            ("OR", "") => {
                if Smc100::not_referenced(state) {
                    self.log.home_started();
                    self.stage.start_home(now);
                } else {
                    self.error = Smc100::refusal(state);
                }
                None
            }
            ("PA", p) if p != "?" => {
                let Some(target) = p.parse::<f64>().ok().filter(|v| v.is_finite()) else {
                    self.error = 'C';
                    return None;
                };
                let ready = (0x32..=0x35).contains(&state);
                self.log.motion(line, self.stage.referenced(), ready);
                if ready {
                    self.stage.start_move(target, now);
                } else {
                    self.error = Smc100::refusal(state);
                }
                None
            }
            ("MM", "0") => {
                match state {
                    0x32..=0x35 => self.state = 0x3C,
                    s => self.error = Smc100::refusal(s),
                }
                None
            }
            ("MM", "1") => {
                match state {
                    0x3C..=0x3E => {
                        self.state = 0x34;
                        self.positioner = 0;
                    }
                    s if Smc100::not_referenced(s) => self.error = 'H',
                    _ => self.error = 'D',
                }
                None
            }
            ("ST", "") => {
                let homing = self.stage.homing();
                self.stage.stop(now);
                if homing {
                    self.state = 0x0B;
                } else if state == 0x28 {
                    self.state = 0x33;
                }
                None
            }
            ("RS", "") => {
                let at = self.stage.physical(now);
                self.stage = Stage::unknown(at);
                self.state = 0x0A;
                self.positioner = 0;
                None
            }
            _ => {
                self.log.unknown(line);
                self.error = 'A';
                None
            }
        }
    }
}

impl SimDevice for Smc100 {
    fn handle(&mut self, command: &str, now: Instant) -> Option<String> {
        self.log.received(command);
        self.update(now);
        self.answer(command, now)
    }

    fn tick(&mut self, now: Instant) -> Option<String> {
        self.update(now);
        None
    }

    fn events(&self) -> u64 {
        0
    }

    fn unsolicited(&mut self, _now: Instant) -> String {
        String::new()
    }
}
