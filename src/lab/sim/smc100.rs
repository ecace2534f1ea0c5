//! A simulated SMC100 controller (address 1) driving the [`World`]'s table.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::world::{Refused, Stalls};
use super::{Fault, FaultKind, SimDevice, World, lock};
use crate::lab::profile::format_degrees as format_position;

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
    /// `stall` faults.
    stalls: Stalls,
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
            stalls: Stalls::of(faults),
        }
    }

    fn move_absolute(&mut self, argument: &str, now: Instant) {
        let moves_before = self.moves;
        self.moves += 1;
        let target = match argument.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => v,
            _ => {
                self.last_error = 'C';
                return;
            }
        };
        let fails = self.disable_after.is_some_and(|k| moves_before >= k);
        let short_deg = self.stalls.shortfall_deg(moves_before);
        if let Err(refused) = lock(&self.world).start_move(target, fails, short_deg, now) {
            self.last_error = match refused {
                Refused::NotReferenced => 'H',
                Refused::Homing => 'L',
                Refused::Moving => 'M',
                Refused::Disabled => 'J',
                Refused::OutOfTravel => 'G',
                Refused::AlreadyReferenced => 'D',
            };
        }
    }

    fn home(&mut self, now: Instant) {
        if let Err(refused) = lock(&self.world).start_home(false, now) {
            self.last_error = match refused {
                Refused::Homing => 'E',
                Refused::Disabled => 'J',
                Refused::Moving => 'M',
                _ => 'K',
            };
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
                lock(&self.world).stop_motion(now);
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
