//! `polycal run` (feature `lab`): its arguments, the operator's side of a run (progress,
//! the remount prompt, the per-cycle lines and the summary) and its handler. All logic
//! lives in the library (`polycal::lab::run`).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Result, anyhow, bail};
use polycal::lab::QueryOptions;
use polycal::lab::driver::{ProfileAutocollimator, ProfileTable, TableOptions};
use polycal::lab::profile::Profile;
use polycal::lab::run::{
    self, Instruments, Mounting, Outcome, Ports, RunDir, RunError, RunSettings,
};
use polycal::lab::serial::SerialTransport;
use polycal::lab::tcp::{TcpTransport, tcp_address};
use polycal::lab::traffic::{LoggedTransport, TrafficLog};
use polycal::lab::transport::Transport;

use super::interrupt::Interrupts;
use super::output::{self, Output};
use super::with_hint;

mod attend;

use attend::{Operator, summary};

/// After `polycal run --help`.
pub const RUN_EXAMPLES: &str = "\
Examples:
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table /dev/ttyUSB2 --faces 24 --cycles 6 --closing --out run1
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table /dev/ttyUSB2 --faces 24 --cycles 6 --closing --out run1 --resume
  polycal run --ac /dev/ttyUSB0 --ac /dev/ttyUSB1 --ac /dev/ttyUSB3 --ac-faces 1,2,9 --table /dev/ttyUSB2 --faces 24 --cycles 6 --closing --out run2
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table /dev/ttyUSB2 --plan plan.json --design B --out run3
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table /dev/ttyUSB2 --faces 24 --cycles 6 --closing --out run1 --setup 2 --shift 7.5
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table tcp://192.168.1.20:50000 --table-profile pi-gcs2 --check-instruments
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table tcp://192.168.1.20:8000 --table-profile aerotech-ascii --faces 24 --cycles 6 --closing --out run4
  polycal solve run1/measurements.csv

Every stop is read --reads times per autocollimator and stored only when the readings
agree; after every cycle the run is evaluated and a reading far off is measured again.
--setup 2, 3, … continue the run in --out in a new mounting: the table goes to the
mounting's step 0 and the run waits for Enter once the polygon is remounted there.
Status 0: completed; 1: completed with readings measured again or suspect, or with a
mounting that does not fit those before it (manifest.json); 2: stopped (docs/FORMAT.md
§7.3, §8).

Instruments of other makes: --ac-profile / --table-profile NAME (bundled: elcomat3000, smc100,
pi-gcs2, aerotech-ascii, esp301) or FILE.toml (docs/instruments.md); a port is a serial device
or tcp://HOST:PORT.

Without instruments, `polycal sim-lab` serves simulated ones and prints a `run` command for them.";

/// Arguments of `polycal run`.
#[derive(clap::Args)]
pub struct RunArgs {
    /// Port of autocollimator 1, e.g. /dev/ttyUSB0 or tcp://HOST:PORT (its protocol:
    /// --ac-profile).
    #[arg(long, required_unless_present = "ac", conflicts_with = "ac")]
    ac1: Option<String>,
    /// Port of autocollimator 2.
    #[arg(
        long,
        required_unless_present = "ac",
        conflicts_with = "ac",
        requires = "ac1"
    )]
    ac2: Option<String>,
    /// Port of the next autocollimator, repeatable: autocollimator 1, 2, 3, … in order
    /// (instead of --ac1/--ac2), as many as --ac-faces names.
    #[arg(long, value_name = "PORT")]
    ac: Vec<String>,
    /// The face each autocollimator reads at step 0, autocollimator 1 first, as
    /// `plan` and `simulate` take it (default 1,2: the paper's design).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    ac_faces: Vec<usize>,
    /// Port of the rotary table, a serial device or tcp://HOST:PORT (its protocol:
    /// --table-profile).
    #[arg(long)]
    table: String,
    /// The autocollimators' protocol: a bundled profile (default elcomat3000) or a profile
    /// file FILE.toml (docs/instruments.md). With --resume, the one the run recorded.
    #[arg(long, value_name = "NAME|FILE.toml")]
    ac_profile: Option<String>,
    /// The rotary table's protocol: a bundled profile (default smc100; pi-gcs2,
    /// aerotech-ascii, esp301) or a profile file FILE.toml (docs/instruments.md). With
    /// --resume, the one the run recorded.
    #[arg(long, value_name = "NAME|FILE.toml")]
    table_profile: Option<String>,
    /// Talk to each instrument once — identify it, ask the table's position and one
    /// reading of every autocollimator — say what was found, and stop: nothing moves and
    /// nothing is written.
    #[arg(long)]
    check_instruments: bool,
    /// Number of polygon faces N (= table stops per turn).
    #[arg(long, required_unless_present_any = ["plan", "check_instruments"], conflicts_with = "plan")]
    faces: Option<usize>,
    /// Number of cycles.
    #[arg(long, required_unless_present_any = ["plan", "check_instruments"], conflicts_with = "plan")]
    cycles: Option<u32>,
    /// Add the closing step N (table back at 360°) to every cycle.
    #[arg(long, conflicts_with = "plan")]
    closing: bool,
    /// Run every second cycle counter-clockwise, steps N … 0 (implies --closing).
    #[arg(long, conflicts_with = "plan")]
    bidirectional: bool,
    /// Run exactly the design of a `polycal plan --format json` output: its faces,
    /// autocollimators' faces, cycles, closing step and directions (instead of those
    /// options; docs/FORMAT.md §7.3).
    #[arg(long, value_name = "FILE")]
    plan: Option<PathBuf>,
    /// With --plan: the name of the design to run, when the file holds several.
    #[arg(long, value_name = "NAME", requires = "plan")]
    design: Option<String>,
    /// The polygon's mounting this session measures (docs/FORMAT.md §7.3, Several
    /// mountings): 1 starts the run; 2, 3, … continue the run in --out once the last
    /// mounting is complete, after the polygon is remounted (the run asks, then checks
    /// the table's position).
    #[arg(long, value_name = "S")]
    setup: Option<u32>,
    /// The table's angle at step 0 of this mounting, degrees, 0 ≤ DEG < 360 (default 0,
    /// or the plan's).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    shift: Option<f64>,
    /// Whole faces the polygon is turned in this mounting against the first: at step 0
    /// autocollimator j faces face (its --ac-faces face + K), wrapping (default 0, or the
    /// plan's).
    #[arg(long, value_name = "K")]
    face_shift: Option<usize>,
    /// Wait after the table arrived before reading, seconds.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    settle: f64,
    /// Readings of each autocollimator at a stop (2 … 20); the last READS must agree
    /// before their mean is stored (docs/FORMAT.md §7.3).
    #[arg(long, default_value_t = polycal::lab::run::DEFAULT_READS_PER_STOP)]
    reads: u32,
    /// The autocollimators' noise, σ of one reading, arcsec: readings at a stop agree
    /// within 5·√2·σ, or within the tolerance of the smaller noise their repeats
    /// measure once they show it (σ is its upper bound).
    #[arg(long, value_name = "ARCSEC", default_value_t = polycal::lab::run::DEFAULT_READING_NOISE_ARCSEC, allow_negative_numbers = true)]
    reading_noise: f64,
    /// Directory for measurements.csv, manifest.json and traffic.jsonl.
    #[arg(
        long = "out",
        value_name = "OUT",
        required_unless_present = "check_instruments"
    )]
    out_dir: Option<PathBuf>,
    /// Continue an interrupted run in --out from its first missing reading.
    #[arg(long)]
    resume: bool,
    /// Deadline of one reply, seconds (a query is retried three times after it).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    timeout: f64,
    /// Longest a table move or home search may take, seconds.
    #[arg(long, default_value_t = 120.0, allow_negative_numbers = true)]
    motion_timeout: f64,
}

fn seconds(name: &str, value: f64) -> Result<Duration> {
    if !(value.is_finite() && value > 0.0) {
        bail!("--{name} {value}: must be a number of seconds > 0");
    }
    Duration::try_from_secs_f64(value).map_err(|e| anyhow!("--{name} {value}: {e}"))
}

/// A port: a serial device, or `tcp://HOST:PORT`.
type Port = Box<dyn Transport>;

/// Opens a port with a profile's line settings (a serial device) or connects to it
/// (`tcp://HOST:PORT`).
fn open_raw(path: &str, profile: &Profile) -> Result<Port, polycal::lab::InstrumentError> {
    Ok(match tcp_address(path) {
        Some(_) => Box::new(TcpTransport::connect(path)?),
        None => Box::new(SerialTransport::open(path, &profile.line)?),
    })
}

/// How long a reply on `path` is watched for a line after it: two replies' time on a
/// serial line at the profile's rate, or the margin alone over TCP.
fn alone_wait(path: &str, profile: &Profile) -> Duration {
    match tcp_address(path) {
        Some(_) => polycal::lab::profile::ALONE_MARGIN,
        None => profile.line.alone_wait(),
    }
}

/// Opens one instrument's port, logged as `device`; the error names the instrument.
fn open_port(
    path: &str,
    device: &str,
    role: &str,
    profile: &Profile,
    log: &TrafficLog,
) -> Result<LoggedTransport<Port>, PortNotOpened> {
    match open_raw(path, profile) {
        Ok(transport) => Ok(LoggedTransport::new(transport, device, log.clone())),
        Err(error) => {
            log.record(device, path, "error", &error.to_string());
            Err(PortNotOpened {
                role: role.to_string(),
                error,
            })
        }
    }
}

/// An instrument's port that could not be opened, named by the instrument's role
/// (`autocollimator 2`, `rotary table`).
#[derive(Debug, thiserror::Error)]
#[error("{role} at {error}")]
struct PortNotOpened {
    /// The instrument's role.
    role: String,
    /// Why the port could not be opened (it names the port).
    error: polycal::lab::InstrumentError,
}

/// The names of the profiles to speak: --ac-profile and --table-profile; where one is
/// not given, the one a resumed run recorded (docs/FORMAT.md §7.5), else the defaults
/// `elcomat3000` and `smc100`.
fn profile_names(args: &RunArgs) -> (String, String) {
    let recorded = if args.resume && !args.check_instruments {
        run::recorded_profiles(args.out())
    } else {
        None
    };
    let ac = args
        .ac_profile
        .clone()
        .or_else(|| recorded.as_ref().map(|r| r.ac.name.clone()))
        .unwrap_or_else(|| "elcomat3000".to_string());
    let table = args
        .table_profile
        .clone()
        .or_else(|| recorded.as_ref().map(|r| r.table.name.clone()))
        .unwrap_or_else(|| "smc100".to_string());
    (ac, table)
}

/// The profiles named `names` (autocollimators', table's), each checked for its kind of
/// instrument.
fn profiles(names: &(String, String)) -> Result<(Profile, Profile)> {
    let load = |option: &str, name: &str, table: bool| -> Result<Profile> {
        let profile = Profile::load(name).map_err(|e| anyhow!("--{option} {name}: {e}"))?;
        let kind = if table {
            profile.table().map(|_| ())
        } else {
            profile.autocollimator().map(|_| ())
        };
        kind.map_err(|e| anyhow!("--{option} {name}: {e}"))?;
        Ok(profile)
    };
    Ok((
        load("ac-profile", &names.0, false)?,
        load("table-profile", &names.1, true)?,
    ))
}

/// `polycal run --check-instruments`: each instrument once, what was found, status 0
/// when every one answered as its profile says, else an `error:` line (status 2).
fn check_instruments(
    args: &RunArgs,
    out: &Output,
    ac_profile: &Profile,
    table_profile: &Profile,
) -> Result<u8> {
    use polycal::lab::check::{CheckedInstrument, check_autocollimator, check_table};
    let query = QueryOptions::new(seconds("timeout", args.timeout)?, 3);
    let mut found: Vec<CheckedInstrument> = Vec::new();
    for (i, port) in args.ac_ports().iter().enumerate() {
        let role = format!("autocollimator {}", i + 1);
        found.push(match open_raw(port, ac_profile) {
            Ok(transport) => check_autocollimator(&role, transport, ac_profile, query),
            Err(e) => CheckedInstrument::failed(&role, port, &ac_profile.name, e.to_string()),
        });
    }
    found.push(match open_raw(&args.table, table_profile) {
        Ok(transport) => check_table(
            "rotary table",
            transport,
            table_profile,
            TableOptions::new(query),
        ),
        Err(e) => CheckedInstrument::failed(
            "rotary table",
            &args.table,
            &table_profile.name,
            e.to_string(),
        ),
    });
    for instrument in &found {
        println!("{instrument}");
    }
    let failed: Vec<&CheckedInstrument> = found.iter().filter(|c| c.problem.is_some()).collect();
    if failed.is_empty() {
        out.info(format_args!(
            "polycal run --check-instruments: all {} instruments answered as their profiles say; nothing moved",
            found.len()
        ));
        return Ok(0);
    }
    bail!(
        "{} of {} instruments did not answer as their profiles say: {}",
        failed.len(),
        found.len(),
        failed
            .iter()
            .map(|c| c.role.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// How the library ends the message of readings that did not agree at a stop; the
/// option that states the noise is this command's to name.
const NOISE_ADVICE: &str = "state the autocollimator's real noise";

/// How the library's message of a polygon turned otherwise than the mounting states says
/// to go on: with the mounting stated as it is, not the same command.
const RESTATE_ADVICE: &str = "state the mounting as it is (";

/// `polycal run`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &RunArgs, out: &Output) -> Result<u8> {
    let names = profile_names(args);
    let (ac_profile, table_profile) = profiles(&names)?;
    if args.check_instruments {
        return check_instruments(args, out, &ac_profile, &table_profile);
    }
    let settings = RunSettings::new(args.faces.unwrap_or(0), args.cycles.unwrap_or(0))
        .with_closing(args.closing || args.bidirectional)
        .with_bidirectional(args.bidirectional)
        .with_settle_seconds(args.settle)
        .with_reads_per_stop(args.reads)
        .with_reading_noise_arcsec(args.reading_noise)
        .with_ac_faces(args.ac_faces.clone());
    let planned = match &args.plan {
        Some(path) => {
            let (bytes, name) =
                polycal::input::read_bytes(path).map_err(|(file, e)| anyhow!("{file}: {e}"))?;
            Some(
                run::run_from_plan(&bytes, &name, args.design.as_deref(), &settings).map_err(
                    |e| match e {
                        run::PlanFileError::Several { .. } => {
                            with_hint(e, "--design", "with --design NAME")
                        }
                        e => e.into(),
                    },
                )?,
            )
        }
        None => {
            // The library names the setting (`faces 2: …`); the option is `--faces`.
            settings.validate().map_err(|e| anyhow!("--{e}"))?;
            None
        }
    };
    let settings = planned.as_ref().map_or(settings, |p| p.settings.clone());
    let mounting = mounting(args, planned.as_ref())?;
    evaluable(args, &settings, mounting, planned.as_ref())?;
    let query = QueryOptions::new(seconds("timeout", args.timeout)?, 3);
    let motion_timeout = seconds("motion-timeout", args.motion_timeout)?;
    let interrupts = Interrupts::install(out, args.out().join(run::MEASUREMENTS))?;
    let session = Session {
        args,
        profile_names: &names,
        ac_profile: &ac_profile,
        table_profile: &table_profile,
        out,
        settings: &settings,
        mounting,
        planned: planned.as_ref(),
    };
    let result = session.run(query, motion_timeout, &interrupts);
    // From here on a second Ctrl-C leaves the last line to this run.
    interrupts.ending();
    result
}

/// Refuses, before anything moves, a design `solve` could not evaluate (the harmonics
/// it loses, as `plan` words them): with `--plan`, the whole planned design (all its
/// mountings); without, the run directory's mountings so far and this one, with the hint
/// that a design whose later mountings complete it is run from a plan.
fn evaluable(
    args: &RunArgs,
    settings: &RunSettings,
    mounting: Option<Mounting>,
    planned: Option<&run::PlannedRun>,
) -> Result<()> {
    if let Some(planned) = planned {
        if let Some(why) = run::unevaluable(&planned.settings, &planned.mountings) {
            let plan = args
                .plan
                .as_deref()
                .unwrap_or(std::path::Path::new("--plan"));
            bail!("{}: {why}", plan.display());
        }
        return Ok(());
    }
    // The run so far, when there is one to read (anything else is the run directory's
    // own refusal, given when it is opened).
    let so_far: Option<run::Manifest> = std::fs::read_to_string(args.out().join(run::MANIFEST))
        .ok()
        .and_then(|text| serde_json::from_str(&text).ok());
    let (settings, mut mountings) = match &so_far {
        Some(m) => (
            &m.settings,
            m.mountings.iter().map(|r| r.mounting).collect::<Vec<_>>(),
        ),
        None => (settings, Vec::new()),
    };
    match mounting {
        Some(m) if !mountings.iter().any(|r| r.setup == m.setup) => mountings.push(m),
        None if mountings.is_empty() => mountings.push(Mounting::default()),
        _ => {}
    }
    if let Some(why) = run::unevaluable(settings, &mountings) {
        bail!(
            "{why}; nothing was measured: a design whose later mountings complete it is run \
             from a plan (`polycal plan … --format json > plan.json`, then `polycal run --plan \
             plan.json`)"
        );
    }
    Ok(())
}

/// The mounting the options name: `--setup`, `--shift` and `--face-shift` (with
/// `--plan`, the plan's mounting, which they may only restate); `None` when none is
/// given (the first mounting of a new run, the last one of a resumed run).
fn mounting(args: &RunArgs, planned: Option<&run::PlannedRun>) -> Result<Option<Mounting>> {
    let given = args.setup.is_some() || args.shift.is_some() || args.face_shift.is_some();
    let Some(planned) = planned else {
        return Ok(given.then(|| {
            Mounting::new(args.setup.unwrap_or(1))
                .with_shift_deg(args.shift.unwrap_or(0.0))
                .with_face_shift(args.face_shift.unwrap_or(0))
        }));
    };
    if !given && args.resume {
        return Ok(None);
    }
    let m = planned.mounting(args.setup.unwrap_or(1))?;
    if let Some(shift) = args.shift
        && shift != m.shift_deg
    {
        bail!(
            "--shift {shift}: the plan's mounting {} is at shift {}°",
            m.setup,
            m.shift_deg
        );
    }
    if let Some(k) = args.face_shift
        && k != m.face_shift
    {
        bail!(
            "--face-shift {k}: the plan turns the polygon {} faces in mounting {}",
            m.face_shift,
            m.setup
        );
    }
    Ok(Some(m))
}

/// One `polycal run` session: what its options say.
struct Session<'a> {
    args: &'a RunArgs,
    /// The profiles as given (a bundled name or a file's path): autocollimators', table's.
    profile_names: &'a (String, String),
    ac_profile: &'a Profile,
    table_profile: &'a Profile,
    out: &'a Output,
    settings: &'a RunSettings,
    mounting: Option<Mounting>,
    planned: Option<&'a run::PlannedRun>,
}

impl Session<'_> {
    /// The session of `polycal run` after its arguments were checked.
    fn run(
        &self,
        query: QueryOptions,
        motion_timeout: Duration,
        interrupts: &Interrupts,
    ) -> Result<u8> {
        let Session {
            args,
            out,
            settings,
            ..
        } = *self;
        let ac_ports = args.ac_ports();
        if ac_ports.len() != settings.autocollimators() {
            bail!(
                "{} autocollimator port(s) given for the {} autocollimators of --ac-faces {}: give \
             one --ac PORT per autocollimator, in order",
                ac_ports.len(),
                settings.autocollimators(),
                settings.ac_faces_text()
            );
        }
        let ports = Ports::new(ac_ports.iter().cloned(), args.table.clone());
        let stop = interrupts.stop_flag();
        let mut dir = RunDir::open_mounting(
            args.out(),
            settings,
            &ports,
            self.mounting,
            args.resume,
            &polycal::lab::WriteBudget::unlimited(),
        )
        .map_err(open_hint)?;
        // A resumed run speaks the protocols it started with (nothing is measured else).
        let record =
            |name: &str, profile: &Profile| run::ProfileRecord::new(name, profile.sha256.clone());
        dir.record_profiles(run::RunProfiles::new(
            record(&self.profile_names.0, self.ac_profile),
            record(&self.profile_names.1, self.table_profile),
        ))?;
        interrupts.run_dir_opened(dir.abort_handle(), dir.manifest().expected_readings);
        for warning in dir.warnings() {
            out.warning(warning);
        }
        let file = args.out().join(run::MEASUREMENTS);
        if dir.is_complete() {
            dir.finish(&Outcome::Completed).map_err(|e| {
            anyhow!(
                "{e}; the run is complete ({} readings in {}), but the manifest could not record it; \
                 run the same command again once it can be written",
                dir.readings_done(),
                file.display()
            )
        })?;
            out.info(format_args!(
                "polycal run: {}: {} is complete ({} readings in the run); nothing to do",
                args.out().display(),
                dir.mounting(),
                dir.readings_done()
            ));
            self.next_mounting(&dir);
            return Ok(0);
        }

        let log = match dir.traffic_log() {
            Ok(log) => log,
            Err(e) => {
                let outcome = Outcome::FileError(e.to_string());
                let recorded = dir.finish(&outcome);
                return ended(args, out, &dir, &outcome, recorded, 0, None);
            }
        };
        log.record(
            "",
            "",
            "session",
            &format!(
                "polycal {} run{} {} {} --ac-profile {} --table-profile {}",
                env!("CARGO_PKG_VERSION"),
                if args.resume { " --resume" } else { "" },
                settings.as_options(),
                dir.mounting().as_options(),
                self.profile_names.0,
                self.profile_names.1
            ),
        );
        let opened = (|| {
            let mut acs = Vec::with_capacity(ac_ports.len());
            for (i, port) in ac_ports.iter().enumerate() {
                acs.push(open_port(
                    port,
                    &format!("ac{}", i + 1),
                    &format!("autocollimator {}", i + 1),
                    self.ac_profile,
                    &log,
                )?);
            }
            let table = open_port(
                &args.table,
                "table",
                "rotary table",
                self.table_profile,
                &log,
            )?;
            Ok::<_, PortNotOpened>((acs, table))
        })();
        let (acs, table) = match opened {
            Ok(ports) => ports,
            Err(e) => {
                let outcome = Outcome::InstrumentError(e.to_string());
                let note = match dir.finish(&outcome) {
                    Ok(()) => String::new(),
                    Err(e) => format!("; the manifest could not record it ({e})"),
                };
                // The directory holds the run now: only --resume continues it.
                bail!(
                    "{e}; nothing was measured in this session; {} of {} readings are in {}; \
                     continue with the same command and --resume once the port is there{note}",
                    dir.readings_done(),
                    dir.manifest().expected_readings,
                    file.display()
                );
            }
        };
        // A reply is taken once no line followed it for two replies' time on its line.
        let mut acs = acs
            .into_iter()
            .zip(&ac_ports)
            .map(|(port, path)| {
                let q = query.with_alone_wait(alone_wait(path, self.ac_profile));
                ProfileAutocollimator::new(port, self.ac_profile, q)
            })
            .collect::<Result<Vec<_>, _>>()?;
        let table_query = query.with_alone_wait(alone_wait(&args.table, self.table_profile));
        let mut table = ProfileTable::new(
            table,
            self.table_profile,
            TableOptions::new(table_query).with_motion_timeout(motion_timeout),
        )?
        .with_stop_flag(stop.clone());

        let bar = out.bar();
        bar.set_style(output::style("[{bar:30}] {msg}"));
        interrupts.show_progress(&bar);
        let mut operator = Operator {
            out,
            bar: &bar,
            stop,
            checks: Vec::new(),
            declined: None,
        };
        let before = dir.readings_done();
        let outcome = run::measure_attended(
            &mut dir,
            Instruments::of(&mut acs, &mut table),
            stop,
            Some(&log),
            &mut operator,
        );
        bar.finish_and_clear();
        let outcome = outcome?;
        let recorded = dir.finish(&outcome);
        if outcome == Outcome::Completed && recorded.is_ok() {
            summary(args, out, &dir, &operator.checks);
            self.next_mounting(&dir);
        }
        ended(
            args,
            out,
            &dir,
            &outcome,
            recorded,
            before,
            operator.declined,
        )
    }

    /// After a complete mounting: how the next one is measured (the plan's next mounting,
    /// or the form of the options when mountings were named).
    fn next_mounting(&self, dir: &RunDir) {
        let next = dir.mounting().setup + 1;
        let options = match self.planned {
            Some(planned) => match planned.mounting(next) {
                Ok(m) => m.as_options(),
                Err(_) => return,
            },
            None if self.mounting.is_some() => format!("--setup {next} --shift DEG"),
            None => return,
        };
        self.out.info(format_args!(
        "  next mounting: remount the polygon when the run asks, with the same command and {options}"
    ));
    }
}

impl RunArgs {
    /// The run directory (--out; clap requires it unless --check-instruments, which
    /// returns before it is needed).
    pub(super) fn out(&self) -> &std::path::Path {
        self.out_dir.as_deref().unwrap_or(std::path::Path::new("."))
    }

    /// The autocollimators' ports in order: the --ac list, or --ac1 and --ac2.
    fn ac_ports(&self) -> Vec<String> {
        if self.ac.is_empty() {
            [&self.ac1, &self.ac2]
                .into_iter()
                .flatten()
                .cloned()
                .collect()
        } else {
            self.ac.clone()
        }
    }
}

/// The end of a session: its summary (status 0) or its `error:` line, which says when
/// the manifest could not record the outcome (`recorded`); `before`: readings on disk
/// when the session started.
fn ended(
    args: &RunArgs,
    out: &Output,
    dir: &RunDir,
    outcome: &Outcome,
    recorded: Result<(), RunError>,
    before: usize,
    declined: Option<String>,
) -> Result<u8> {
    let done = dir.readings_done();
    let total = dir.manifest().expected_readings;
    let file = args.out().join(run::MEASUREMENTS);
    let restate = matches!(outcome, Outcome::InstrumentError(m) if m.contains(RESTATE_ADVICE));
    let kept = if restate {
        format!("{done} of {total} readings are in {}", file.display())
    } else {
        format!(
            "{done} of {total} readings are in {}; continue with the same command and --resume",
            file.display()
        )
    };
    let what = match outcome {
        Outcome::Completed => {
            if let Err(e) = recorded {
                bail!(
                    "{e}; all {done} readings are in {}, but the manifest could not record that \
                     the run is complete; run the same command with --resume once it can be written",
                    file.display()
                );
            }
            out.info(format_args!(
                "polycal run: completed: {} readings taken, {done} in {}",
                done - before,
                file.display()
            ));
            // Status 1: complete, with readings measured again or suspect, or a mounting
            // that does not fit (§7.3, §8).
            return Ok(u8::from(dir.has_doubts()));
        }
        Outcome::Interrupted => match declined {
            Some(why) => format!("{why}; the run stopped"),
            None => "run interrupted (table stopped)".to_string(),
        },
        Outcome::InstrumentError(message) if message.contains(NOISE_ADVICE) => {
            format!("{message} (--reading-noise); the run stopped")
        }
        Outcome::InstrumentError(message) | Outcome::FileError(message) => {
            format!("{message}; the run stopped")
        }
    };
    let note = match recorded {
        Ok(()) => String::new(),
        // The same error as the one that stopped the run is not told twice.
        Err(RunError::Io { path, source }) if what.contains(&source.to_string()) => format!(
            "; the manifest could not record it either ({})",
            path.display()
        ),
        Err(e) => format!("; the manifest could not record it ({e})"),
    };
    bail!("{what}{note}; {kept}")
}

/// Why a run directory was refused, with the option that gets past it: `--resume` for a
/// directory that holds a run, no `--resume` for one that holds none; the settings as
/// this command's options (the library's messages name no option).
fn open_hint(error: RunError) -> anyhow::Error {
    match error {
        RunError::AlreadyHoldsRun { .. } => with_hint(
            error,
            "--resume",
            "continue it with --resume, or choose another --out",
        ),
        RunError::NoRunToResume { .. } => {
            with_hint(error, "--resume", "start one without --resume")
        }
        RunError::OtherSettings {
            path,
            started,
            requested,
        } => anyhow!(
            "{}: the run was started with {}, this command says {} ({}); refusing to resume",
            path.display(),
            started.as_options(),
            requested.as_options(),
            started.differences(&requested).join(", ")
        ),
        RunError::Settings { path, error } => anyhow!("{}: --{error}", path.display()),
        RunError::NotADirectory { .. } => anyhow!("{error}; choose another --out"),
        RunError::MountingIncomplete { setup, .. } => anyhow!(
            "{error}: the same command with --resume --setup {setup} (and that mounting's --shift)"
        ),
        RunError::OtherMounting { recorded, .. } => {
            anyhow!("{error}; the run's mounting is {}", recorded.as_options())
        }
        RunError::NoRunForMounting { .. } => {
            anyhow!("{error}; start the run in its first mounting (--setup 1)")
        }
        error => error.into(),
    }
}
