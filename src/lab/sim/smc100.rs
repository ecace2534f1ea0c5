//! A simulated SMC100 controller (address 1) driving the [`World`]'s table.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::world::Motion;
use super::{Fault, FaultKind, SimDevice, World, lock};
use crate::lab::smc100::{POSITION_TOLERANCE_DEG, format_position};

/// Travel limits of the simulated table, degrees.
pub const TRAVEL_DEG: (f64, f64) = (-720.0, 720.0);

/// A simulated SMC100 with a rotary stage.
///
/// It powers up NOT REFERENCED (`0A`) at 0°. Commands (replies end with CR LF):
/// `1TS` → `1TS<eeee><ss>`; `1TP` → `1TP<deg>`; `1TE` → `1TE<c>` (then `@`); `1VE` →
/// `1VE SMC100CC 2.0.0 (simulated by polycal …)`; `1OR` homes (NOT REFERENCED only, else
/// error `K`); `1PA<deg>` moves (READY only: error `H` not referenced, `L` homing, `M`
/// moving, `J` disable; `C` bad number, `G` beyond ±720°); `1ST` stops (READY from
/// MOVING where it is); `1MM0` / `1MM1` disable and enable (not when stuck by a
/// `disable` fault). Other commands set error `A` and get no reply.
#[derive(Debug)]
pub struct Smc100Sim {
    world: Arc<Mutex<World>>,
    last_error: char,
    moves: u64,
    disable_after: Option<u64>,
    /// `stall` faults: (armed after, moves left, shortfall as a fraction of the
    /// position tolerance).
    stalls: Vec<(u64, u64, f64)>,
}

impl Smc100Sim {
    /// The table of `world`, with its `disable` fault if any and its `stall` faults.
    pub fn new(world: Arc<Mutex<World>>, faults: &[Fault]) -> Smc100Sim {
        Smc100Sim {
            world,
            last_error: '@',
            moves: 0,
            disable_after: faults
                .iter()
                .find(|f| f.kind == FaultKind::Disable)
                .map(|f| f.after),
            stalls: faults
                .iter()
                .filter(|f| f.kind == FaultKind::Stall)
                .map(|f| (f.after, f.count, f.stall_fraction))
                .collect(),
        }
    }

    fn move_absolute(&mut self, argument: &str, now: Instant) {
        let moves_before = self.moves;
        self.moves += 1;
        let mut world = lock(&self.world);
        let state = world.table_state(now);
        let target = match argument.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => v,
            _ => {
                self.last_error = 'C';
                return;
            }
        };
        let refused = match state {
            0x0A..=0x11 => Some('H'),
            0x1E | 0x1F => Some('L'),
            0x28 => Some('M'),
            0x3C..=0x3E => Some('J'),
            0x32..=0x34 => None,
            _ => Some('D'),
        };
        if let Some(code) = refused {
            self.last_error = code;
            return;
        }
        if !(TRAVEL_DEG.0..=TRAVEL_DEG.1).contains(&target) {
            self.last_error = 'G';
            return;
        }
        let from = world.table.position;
        // A stall ends the move short of its target, where the encoder then reads.
        let mut target = target;
        for (after, left, fraction) in &mut self.stalls {
            if moves_before >= *after && *left > 0 && target != from {
                *left -= 1;
                target -= (target - from).signum() * *fraction * POSITION_TOLERANCE_DEG;
                break;
            }
        }
        let duration = world.duration(target - from, 0.0);
        world.table.motion = Some(Motion {
            from,
            to: target,
            start: now,
            duration,
            homing: false,
            fails: self.disable_after.is_some_and(|k| moves_before >= k),
        });
        world.update(now);
    }

    fn home(&mut self, now: Instant) {
        let mut world = lock(&self.world);
        match world.table_state(now) {
            0x0A..=0x11 => {
                let from = world.table.position;
                let home_seconds = world.config.home_seconds;
                let duration = world.duration(from, home_seconds);
                world.table.motion = Some(Motion {
                    from,
                    to: 0.0,
                    start: now,
                    duration,
                    homing: true,
                    fails: false,
                });
                world.update(now);
            }
            0x1E | 0x1F => self.last_error = 'E',
            0x3C..=0x3E => self.last_error = 'J',
            0x28 => self.last_error = 'M',
            _ => self.last_error = 'K',
        }
    }
}

impl SimDevice for Smc100Sim {
    fn handle(&mut self, command: &str, now: Instant) -> Option<String> {
        let Some(rest) = command.strip_prefix('1') else {
            return None; // another controller address: not ours
        };
        let name: String = rest.chars().take(2).collect();
        let argument = rest.get(2..).unwrap_or("");
        match name.as_str() {
            "TS" => {
                let state = lock(&self.world).table_state(now);
                Some(format!("1TS0000{state:02X}\r\n"))
            }
            "TP" => {
                let mut world = lock(&self.world);
                world.touch(now);
                let position = world.encoder_position(now);
                Some(format!("1TP{}\r\n", format_position(position)))
            }
            "TE" => {
                let code = std::mem::replace(&mut self.last_error, '@');
                Some(format!("1TE{code}\r\n"))
            }
            "VE" => Some(format!(
                "1VE SMC100CC 2.0.0 (simulated by polycal {})\r\n",
                env!("CARGO_PKG_VERSION")
            )),
            "OR" => {
                self.home(now);
                None
            }
            "PA" => {
                self.move_absolute(argument, now);
                None
            }
            "ST" => {
                let mut world = lock(&self.world);
                world.touch(now);
                if let Some(m) = world.table.motion.take() {
                    world.table.position = m.position_at(now);
                    if m.homing {
                        world.table.referenced = false;
                    } else {
                        world.table.ready_code = 0x33;
                    }
                }
                None
            }
            "MM" => {
                let mut world = lock(&self.world);
                let state = world.table_state(now);
                match (argument.trim(), state) {
                    ("0", 0x32..=0x34) => world.table.disabled = Some(0x3C),
                    ("1", 0x3C..=0x3E) if !world.table.stuck => {
                        world.table.disabled = None;
                        world.table.ready_code = 0x34;
                    }
                    ("1", 0x3C..=0x3E) => self.last_error = 'V',
                    _ => self.last_error = 'D',
                }
                None
            }
            _ => {
                self.last_error = 'A';
                None
            }
        }
    }

    fn tick(&mut self, _now: Instant) -> Option<String> {
        None
    }

    fn events(&self) -> u64 {
        self.moves
    }

    /// A position reply 1° beyond where the table is.
    fn unsolicited(&mut self, now: Instant) -> String {
        let position = lock(&self.world).encoder_position(now);
        format!("1TP{}\r\n", format_position(position + 1.0))
    }
}
