//! A simulated ELCOMAT 3000 (docs/FORMAT.md §7): `s`, `d`, `a`, `r`, `A`, `R`.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::fault::ValueFaults;
use super::{Fault, FaultKind, STREAM_PERIOD, SimDevice, World, lock};

/// A simulated ELCOMAT 3000 looking at the polygon of a shared [`World`].
///
/// Replies end with CR. `d` gives `8 ELCOMAT 3000 (simulated by polycal) S/N SIM-<ac>`;
/// `a` and `r` one measurement of type 4 (absolute) or 2 (relative, here the same
/// values); `A` and `R` start a stream of type 3 or 1 every [`STREAM_PERIOD`], stopped by
/// `s`. Unknown commands get no reply.
#[derive(Debug)]
pub struct ElcomatSim {
    world: Arc<Mutex<World>>,
    ac: u32,
    stream: Option<(char, Instant)>,
    measurements: u64,
    x_invalid: Vec<(u64, u64)>,
    /// The last measurement's X and Y, arcsec.
    last: (f64, f64),
    /// `sign-flip`, `swap-xy` and `drop-digit` faults.
    values: ValueFaults,
}

impl ElcomatSim {
    /// Autocollimator `ac` (1 or 2) of `world`, with its `x-invalid` and value faults.
    pub fn new(world: Arc<Mutex<World>>, ac: u32, faults: &[Fault]) -> ElcomatSim {
        ElcomatSim {
            world,
            ac,
            stream: None,
            measurements: 0,
            last: (0.0, 0.0),
            values: ValueFaults::of(faults),
            x_invalid: faults
                .iter()
                .filter(|f| f.kind == FaultKind::XInvalid)
                .map(|f| (f.after, f.count))
                .collect(),
        }
    }

    fn measurement(&mut self, kind: char, now: Instant) -> String {
        let before = self.measurements;
        self.measurements += 1;
        let (mut axes, x, y) = lock(&self.world).measure(self.ac, now);
        for (after, left) in &mut self.x_invalid {
            if before >= *after && *left > 0 {
                *left -= 1;
                axes = 2;
            }
        }
        self.last = (x, y);
        let (x, y) = self.values.apply(before, x, y);
        format!("{kind} 00{axes} {x:.6} {y:.6}\r")
    }
}

impl SimDevice for ElcomatSim {
    fn handle(&mut self, command: &str, now: Instant) -> Option<String> {
        match command {
            "s" => {
                self.stream = None;
                None
            }
            "d" => Some(format!(
                "8 ELCOMAT 3000 (simulated by polycal {}) S/N SIM-{}\r",
                env!("CARGO_PKG_VERSION"),
                self.ac
            )),
            "a" => Some(self.measurement('4', now)),
            "r" => Some(self.measurement('2', now)),
            "A" => {
                self.stream = Some(('3', now));
                None
            }
            "R" => {
                self.stream = Some(('1', now));
                None
            }
            _ => None,
        }
    }

    fn tick(&mut self, now: Instant) -> Option<String> {
        let (kind, last) = self.stream?;
        if now.saturating_duration_since(last) < STREAM_PERIOD {
            return None;
        }
        self.stream = Some((kind, now));
        Some(self.measurement(kind, now))
    }

    fn events(&self) -> u64 {
        self.measurements
    }

    /// An absolute measurement 99″ beyond the last one in X.
    fn unsolicited(&mut self, _now: Instant) -> String {
        let (x, y) = self.last;
        format!("4 003 {:.6} {y:.6}\r", x + 99.0)
    }
}
