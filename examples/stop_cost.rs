//! What one stop of `polycal run` costs on the wire, per table profile (docs/instruments.md,
//! *The cost of a stop*): an 8-face, one-cycle run with the closing step against the
//! simulated lab (instantaneous motion, in memory), every line counted on its way. The
//! drain before every query, the double reading (`--reads 2`), the error query after the
//! move and the state polled until the table is ready are all in the counts; the wire
//! time is the bytes at each profile's baud rate (start, data, parity and stop bits per
//! character). Motion itself adds one more state query per poll interval (20 ms) while
//! the table travels, and `--settle` (default 2 s) waits before the readings.
//!
//! ```sh
//! cargo run --release --example stop_cost
//! ```

use std::sync::{Arc, Mutex};
use std::time::Duration;

use polycal::lab::driver::{ProfileAutocollimator, ProfileTable, TableOptions};
use polycal::lab::profile::Profile;
use polycal::lab::run::{self, Instruments, Ports, RunDir, RunSettings};
use polycal::lab::sim::{Devices, LabConfig, SimStream};
use polycal::lab::transport::{StreamTransport, Transport};
use polycal::lab::{InstrumentError, QueryOptions, StopFlag};
use polycal::simulate::SimulationConfig;

/// Lines and bytes each way on one port.
#[derive(Debug, Default, Clone, Copy)]
struct Count {
    sent_lines: u64,
    sent_bytes: u64,
    received_lines: u64,
    received_bytes: u64,
}

/// A transport that counts what goes through it.
struct Counted<T> {
    inner: T,
    count: Arc<Mutex<Count>>,
    reply_end_bytes: u64,
}

impl<T: Transport> Transport for Counted<T> {
    fn port(&self) -> &str {
        self.inner.port()
    }
    fn send(&mut self, text: &str) -> Result<(), InstrumentError> {
        let mut c = self.count.lock().unwrap_or_else(|p| p.into_inner());
        c.sent_lines += 1;
        c.sent_bytes += text.len() as u64;
        drop(c);
        self.inner.send(text)
    }
    fn read_line(&mut self, timeout: Duration) -> Result<Option<String>, InstrumentError> {
        let line = self.inner.read_line(timeout)?;
        if let Some(l) = &line {
            let mut c = self.count.lock().unwrap_or_else(|p| p.into_inner());
            c.received_lines += 1;
            c.received_bytes += l.len() as u64 + self.reply_end_bytes;
        }
        Ok(line)
    }
    fn clear_input(&mut self) -> Result<(), InstrumentError> {
        self.inner.clear_input()
    }
    fn drain(&mut self) -> Result<Vec<String>, InstrumentError> {
        self.inner.drain()
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    print!("{}", table()?);
    Ok(())
}

/// The table the README shows (`tests/lab/stop_cost_readme.rs` compares the two).
pub fn table() -> Result<String, Box<dyn std::error::Error>> {
    use std::fmt::Write as _;
    let mut out = String::new();
    let faces = 8;
    let settings = RunSettings::new(faces, 1).with_closing(true);
    let stops = (faces + 1) as f64;
    let ac_profile = Profile::load("elcomat3000")?;
    writeln!(
        out,
        "| table profile | table: lines sent / received per stop | table: wire time per stop | autocollimators (both): lines sent / received per stop | their wire time per stop |"
    )?;
    writeln!(out, "|---|---|---|---|---|")?;
    for name in ["smc100", "pi-gcs2", "aerotech-ascii", "esp301"] {
        let table_profile = Profile::load(name)?;
        let lab = LabConfig::new(SimulationConfig {
            faces,
            cycles: 1,
            closing: true,
            seed: 3,
            ..SimulationConfig::default()
        })
        .with_time_scale(0.0)
        .with_ac_profile(ac_profile.clone())
        .with_table_profile(table_profile.clone());
        let Devices {
            autocollimators,
            table,
            ..
        } = Devices::new(lab)?;
        let Ok([ac1, ac2]) = <[_; 2]>::try_from(autocollimators) else {
            return Err("the simulated lab has two autocollimators".into());
        };
        let query = QueryOptions::new(Duration::from_millis(200), 3);
        let ac_count = Arc::new(Mutex::new(Count::default()));
        let table_count = Arc::new(Mutex::new(Count::default()));
        let ac = |label: &str, endpoint| {
            let transport = Counted {
                inner: StreamTransport::new(label, SimStream::new(endpoint)),
                count: Arc::clone(&ac_count),
                reply_end_bytes: ac_profile.line.reply_end.len() as u64,
            };
            ProfileAutocollimator::new(transport, &ac_profile, query)
        };
        let (mut a1, mut a2) = (ac("mem:ac1", ac1)?, ac("mem:ac2", ac2)?);
        let mut t = ProfileTable::new(
            Counted {
                inner: StreamTransport::new("mem:table", SimStream::new(table)),
                count: Arc::clone(&table_count),
                reply_end_bytes: table_profile.line.reply_end.len() as u64,
            },
            &table_profile,
            TableOptions::new(query),
        )?;
        let dir =
            std::env::temp_dir().join(format!("polycal-stop-cost-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut run_dir = RunDir::open(
            &dir,
            &settings,
            &Ports::new(["mem:ac1", "mem:ac2"], "mem:table"),
            false,
        )?;
        let outcome = run::measure(
            &mut run_dir,
            Instruments::new(vec![&mut a1, &mut a2], &mut t),
            &StopFlag::new(),
            None,
            &mut |_| {},
        )?;
        run_dir.finish(&outcome)?;
        std::fs::remove_dir_all(&dir)?;
        let per = |c: Count, p: &Profile| {
            let bytes = (c.sent_bytes + c.received_bytes) as f64 / stops;
            (
                c.sent_lines as f64 / stops,
                c.received_lines as f64 / stops,
                p.line.line_time(bytes.round() as usize).as_secs_f64() * 1000.0,
            )
        };
        let tc = *table_count.lock().unwrap_or_else(|p| p.into_inner());
        let acc = *ac_count.lock().unwrap_or_else(|p| p.into_inner());
        let (ts, tr, tw) = per(tc, &table_profile);
        let (as_, ar, aw) = per(acc, &ac_profile);
        writeln!(
            out,
            "| `{name}` | {ts:.1} / {tr:.1} | {tw:.1} ms | {as_:.1} / {ar:.1} | {aw:.1} ms |"
        )?;
    }
    Ok(out)
}
