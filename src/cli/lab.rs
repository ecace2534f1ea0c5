//! `polycal run` and `polycal sim-lab` (feature `lab`): their arguments and handlers.
//! All logic lives in the library (`polycal::lab`).

use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Result, anyhow, bail};
use clap::ValueEnum;
use polycal::lab::QueryOptions;
use polycal::lab::elcomat::Elcomat3000;
use polycal::lab::run::{
    self, CycleCheck, Instruments, Outcome, Ports, Progress, RunDir, RunError, RunSettings,
};
use polycal::lab::serial::{SerialSettings, SerialTransport};
#[cfg(unix)]
use polycal::lab::sim::Lab;
use polycal::lab::sim::{Devices, Fault, LabConfig};
use polycal::lab::smc100::{Smc100, Smc100Options};
use polycal::lab::traffic::{LoggedTransport, TrafficLog};

use super::interrupt::Interrupts;
use super::output::{self, Output};
use super::with_hint;

/// After `polycal run --help`.
pub const RUN_EXAMPLES: &str = "\
Examples:
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table /dev/ttyUSB2 --faces 24 --cycles 6 --closing --out run1
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table /dev/ttyUSB2 --faces 24 --cycles 6 --closing --out run1 --resume
  polycal run --ac /dev/ttyUSB0 --ac /dev/ttyUSB1 --ac /dev/ttyUSB3 --ac-faces 1,2,9 --table /dev/ttyUSB2 --faces 24 --cycles 6 --closing --out run2
  polycal run --ac1 /dev/ttyUSB0 --ac2 /dev/ttyUSB1 --table /dev/ttyUSB2 --plan plan.json --design B --out run3
  polycal solve run1/measurements.csv

Every stop is read --reads times per autocollimator and stored only when the readings
agree; after every cycle the run is evaluated and a reading far off is measured again.
Status 0: completed; 1: completed with readings measured again or suspect (manifest.json);
2: stopped (docs/FORMAT.md §7.3, §8).

Without instruments, `polycal sim-lab` serves simulated ones and prints a `run` command for them.";

/// After `polycal sim-lab --help`.
pub const SIM_LAB_EXAMPLES: &str = "\
Examples:
  polycal sim-lab --faces 24 --time-scale 0 --truth-out lab.truth.json
  polycal sim-lab --faces 8 --fault lost-reply:ac1:after=5 --format json
  polycal sim-lab --faces 8 --fault late:ac2:after=7:seconds=1.3 --fault unsolicited:ac1:after=20
  polycal sim-lab --direction -0.3 --drift 2:1.5 --bidirectional";

/// Arguments of `polycal run`.
#[derive(clap::Args)]
pub struct RunArgs {
    /// Port of autocollimator 1 (ELCOMAT 3000 protocol), e.g. /dev/ttyUSB0.
    #[arg(long, required_unless_present = "ac", conflicts_with = "ac")]
    ac1: Option<String>,
    /// Port of autocollimator 2 (ELCOMAT 3000 protocol).
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
    /// Port of the rotary table (SMC100 protocol, address 1).
    #[arg(long)]
    table: String,
    /// Number of polygon faces N (= table stops per turn).
    #[arg(long, required_unless_present = "plan", conflicts_with = "plan")]
    faces: Option<usize>,
    /// Number of cycles.
    #[arg(long, required_unless_present = "plan", conflicts_with = "plan")]
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
    /// Wait after the table arrived before reading, seconds.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    settle: f64,
    /// Readings of each autocollimator at a stop (2 … 20); the last READS must agree
    /// before their mean is stored (docs/FORMAT.md §7.3).
    #[arg(long, default_value_t = polycal::lab::run::DEFAULT_READS_PER_STOP)]
    reads: u32,
    /// The autocollimators' noise, σ of one reading, arcsec: readings at a stop agree
    /// within 5·√2·σ.
    #[arg(long, value_name = "ARCSEC", default_value_t = polycal::lab::run::DEFAULT_READING_NOISE_ARCSEC, allow_negative_numbers = true)]
    reading_noise: f64,
    /// Directory for measurements.csv, manifest.json and traffic.jsonl.
    #[arg(long)]
    out: PathBuf,
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

/// Arguments of `polycal sim-lab`.
#[derive(clap::Args)]
pub struct SimLabArgs {
    /// The truth the lab's instruments measure, its noise and effects (as `simulate`);
    /// `--cycles`, `--closing` and `--bidirectional` describe the run the lab follows,
    /// for cycle- and direction-dependent effects; drift follows real time.
    #[command(flatten)]
    truth: super::simulate::TruthArgs,
    /// Table speed, degrees per second.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    speed: f64,
    /// Extra time of a home search, seconds.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    home_seconds: f64,
    /// Factor on every simulated duration (0: instantaneous motion).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    time_scale: f64,
    /// Inject a fault KIND:DEVICE[:after=K][:count=M][:seconds=S]; KIND lost-reply,
    /// garbled, x-invalid, disable, close, late (by S seconds, default 1.5),
    /// duplicated, unsolicited, swapped or stale; DEVICE ac1, ac2 or table; repeatable
    /// (docs/FORMAT.md §7.4).
    #[arg(long = "fault")]
    faults: Vec<String>,
    /// The face each simulated autocollimator reads at step 0, autocollimator 1 first
    /// (2 … 16 autocollimators), as `run --ac-faces` takes it.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    ac_faces: Vec<usize>,
    /// How to print the device paths.
    #[arg(long, value_enum, default_value = "table")]
    format: PathsFormat,
}

/// How `sim-lab` prints its device paths.
#[derive(Clone, Copy, ValueEnum)]
pub enum PathsFormat {
    /// One `NAME PATH` line per device.
    Table,
    /// One JSON object `{"ac1": …, "ac2": …, "table": …}`.
    Json,
}

fn seconds(name: &str, value: f64) -> Result<Duration> {
    if !(value.is_finite() && value > 0.0) {
        bail!("--{name} {value}: must be a number of seconds > 0");
    }
    Duration::try_from_secs_f64(value).map_err(|e| anyhow!("--{name} {value}: {e}"))
}

/// Opens one instrument's port, logged as `device`; the error names the instrument.
fn open_port(
    path: &str,
    device: &str,
    role: &str,
    settings: SerialSettings,
    log: &TrafficLog,
) -> Result<LoggedTransport<SerialTransport>, String> {
    match SerialTransport::open(path, settings) {
        Ok(transport) => Ok(LoggedTransport::new(transport, device, log.clone())),
        Err(e) => {
            log.record(device, path, "error", &e.to_string());
            Err(format!("{role} at {e}"))
        }
    }
}

/// How the library ends the message of readings that did not agree at a stop; the
/// option that states the noise is this command's to name.
const NOISE_ADVICE: &str = "state the autocollimator's real noise";

/// `polycal run`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &RunArgs, out: &Output) -> Result<u8> {
    let settings = RunSettings::new(args.faces.unwrap_or(0), args.cycles.unwrap_or(0))
        .with_closing(args.closing || args.bidirectional)
        .with_bidirectional(args.bidirectional)
        .with_settle_seconds(args.settle)
        .with_reads_per_stop(args.reads)
        .with_reading_noise_arcsec(args.reading_noise)
        .with_ac_faces(args.ac_faces.clone());
    let settings = match &args.plan {
        Some(path) => {
            let (bytes, name) =
                polycal::input::read_bytes(path).map_err(|(file, e)| anyhow!("{file}: {e}"))?;
            run::settings_from_plan(&bytes, &name, args.design.as_deref(), &settings).map_err(
                |e| match e {
                    run::PlanFileError::Several { .. } => {
                        with_hint(e, "--design", "with --design NAME")
                    }
                    e => e.into(),
                },
            )?
        }
        None => {
            // The library names the setting (`faces 2: …`); the option is `--faces`.
            settings.validate().map_err(|e| anyhow!("--{e}"))?;
            settings
        }
    };
    let query = QueryOptions::new(seconds("timeout", args.timeout)?, 3);
    let motion_timeout = seconds("motion-timeout", args.motion_timeout)?;
    let interrupts = Interrupts::install(
        out,
        args.out.join(run::MEASUREMENTS),
        settings.reading_count(),
    )?;
    let result = run_session(args, out, &settings, query, motion_timeout, &interrupts);
    // From here on a second Ctrl-C leaves the last line to this run.
    interrupts.ending();
    result
}

/// The session of `polycal run` after its arguments were checked.
fn run_session(
    args: &RunArgs,
    out: &Output,
    settings: &RunSettings,
    query: QueryOptions,
    motion_timeout: Duration,
    interrupts: &Interrupts,
) -> Result<u8> {
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
    let ports = Ports::of(&ac_ports, args.table.clone());
    let stop = interrupts.stop_flag();
    let mut dir = RunDir::open(&args.out, settings, &ports, args.resume).map_err(open_hint)?;
    interrupts.run_dir_opened(dir.abort_handle());
    for warning in dir.warnings() {
        out.warning(warning);
    }
    let file = args.out.join(run::MEASUREMENTS);
    if dir.remaining().is_empty() {
        dir.finish(&Outcome::Completed).map_err(|e| {
            anyhow!(
                "{e}; the run is complete ({} readings in {}), but the manifest could not record it; \
                 run the same command again once it can be written",
                dir.readings_done(),
                file.display()
            )
        })?;
        out.info(format_args!(
            "polycal run: {}: the run is complete ({} readings); nothing to do",
            args.out.display(),
            dir.readings_done()
        ));
        return Ok(0);
    }

    let log = match dir.traffic_log() {
        Ok(log) => log,
        Err(e) => {
            let outcome = Outcome::FileError(e.to_string());
            let recorded = dir.finish(&outcome);
            return ended(args, out, &dir, &outcome, recorded, 0);
        }
    };
    log.record(
        "",
        "",
        "session",
        &format!(
            "polycal {} run{} {}",
            env!("CARGO_PKG_VERSION"),
            if args.resume { " --resume" } else { "" },
            settings.as_options()
        ),
    );
    let opened = (|| {
        let mut acs = Vec::with_capacity(ac_ports.len());
        for (i, port) in ac_ports.iter().enumerate() {
            acs.push(open_port(
                port,
                &format!("ac{}", i + 1),
                &format!("autocollimator {}", i + 1),
                SerialSettings::ELCOMAT,
                &log,
            )?);
        }
        let table = open_port(
            &args.table,
            "table",
            "rotary table",
            SerialSettings::SMC100,
            &log,
        )?;
        Ok::<_, String>((acs, table))
    })();
    let (acs, table) = match opened {
        Ok(ports) => ports,
        Err(e) => {
            let outcome = Outcome::InstrumentError(e.clone());
            let note = match dir.finish(&outcome) {
                Ok(()) => String::new(),
                Err(e) => format!("; the manifest could not record it ({e})"),
            };
            bail!(
                "{e}; nothing was measured in this session ({}){note}",
                args.out.display()
            );
        }
    };
    let mut acs: Vec<_> = acs
        .into_iter()
        .map(|port| Elcomat3000::new(port, query))
        .collect();
    let mut table = Smc100::new(
        table,
        Smc100Options::new(query).with_motion_timeout(motion_timeout),
    )
    .with_stop_flag(stop.clone());

    let bar = out.bar();
    bar.set_style(output::style("[{bar:30}] {msg}"));
    interrupts.show_progress(&bar);
    let mut checks: Vec<CycleCheck> = Vec::new();
    let mut on_progress = |p: &Progress| {
        show_progress(&bar, p);
        if let Some(check) = &p.cycle_check {
            bar.suspend(|| show_cycle_check(out, check));
            checks.push(check.clone());
        }
    };
    let before = dir.readings_done();
    let outcome = run::measure(
        &mut dir,
        instruments(&mut acs, &mut table)
            .ok_or_else(|| anyhow!("a run needs two autocollimators at least"))?,
        stop,
        Some(&log),
        &mut on_progress,
    );
    bar.finish_and_clear();
    let outcome = outcome?;
    let recorded = dir.finish(&outcome);
    if outcome == Outcome::Completed && recorded.is_ok() {
        summary(args, out, &dir, &checks);
    }
    ended(args, out, &dir, &outcome, recorded, before)
}

/// A cycle's closure per autocollimator, `ac1 +0.0123″, ac2 -0.0081″` (empty without
/// the closing step).
fn closure_text(check: &CycleCheck) -> String {
    check
        .closure_arcsec
        .iter()
        .map(|(ac, c)| format!("ac{ac} {c:+.4}″"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// What the check after a cycle found, as it is found: one line for the cycle, one per
/// reading measured again or suspect, a `warning:` line per warning.
fn show_cycle_check(out: &Output, check: &CycleCheck) {
    let closure = closure_text(check);
    let rms = match (
        check.residual_rms_arcsec,
        check.previous_residual_rms_arcsec,
    ) {
        (Some(now), Some(before)) => {
            format!("residual RMS {now:.4}″ (cycles before {before:.4}″)")
        }
        (Some(now), None) => format!("residual RMS {now:.4}″"),
        _ => "residual RMS: too few readings yet".to_string(),
    };
    let closure = if closure.is_empty() {
        String::new()
    } else {
        format!("closure {closure} · ")
    };
    out.info(format_args!("cycle {}: {closure}{rms}", check.cycle));
    for r in &check.remeasured {
        out.info(format_args!(
            "  measured again: cycle {}, step {}, autocollimator {}: {}″ (residual {:+.4}″, σ {:.4}″) replaced by {}″",
            r.cycle, r.step, r.ac, r.first_arcsec, r.residual_arcsec, r.sigma_arcsec, r.reading_arcsec
        ));
    }
    for r in &check.suspect {
        out.warning(format_args!(
            "cycle {}, step {}, autocollimator {}: {}″ lies {:+.4}″ off the fit (σ {:.4}″), and measuring its stop again gave {}″: kept, and named suspect in the manifest",
            r.cycle, r.step, r.ac, r.reading_arcsec, r.residual_arcsec, r.sigma_arcsec, r.measured_again_arcsec
        ));
    }
    for w in &check.warnings {
        out.warning(w);
    }
}

/// The end of a completed run: readings, what was measured again, closure and residual
/// RMS per cycle, the diagnosis of the file, and the commands that evaluate it.
fn summary(args: &RunArgs, out: &Output, dir: &RunDir, checks: &[CycleCheck]) {
    let m = dir.manifest();
    let file = args.out.join(run::MEASUREMENTS);
    out.info(format_args!(
        "polycal run: {} readings in {}; {} measured again, {} suspect (manifest.json)",
        dir.readings_done(),
        file.display(),
        m.remeasured.len(),
        m.suspect.len()
    ));
    for check in checks {
        let closure = closure_text(check);
        let rms = check
            .residual_rms_arcsec
            .map_or("—".to_string(), |r| format!("{r:.4}″"));
        out.info(format_args!(
            "  cycle {}: closure {} · residual RMS {rms}",
            check.cycle,
            if closure.is_empty() {
                "—".into()
            } else {
                closure
            }
        ));
    }
    let verdict = polycal::MeasurementSet::read_path(&file, None)
        .map_err(|e| e.to_string())
        .and_then(|set| {
            polycal::diagnose::diagnose(&set, &polycal::diagnose::DiagnoseOptions::default())
                .map_err(|e| e.to_string())
        });
    match verdict {
        Ok(d) => out.info(format_args!(
            "  diagnose: {}, {} effect(s) found, residual RMS {}",
            if d.adequacy.adequate {
                "adequate"
            } else {
                "NOT adequate"
            },
            d.effects.len(),
            d.after
                .residual_rms()
                .map_or("—".to_string(), |r| format!("{r:.4}″"))
        )),
        Err(e) => out.info(format_args!("  diagnose: could not evaluate the file: {e}")),
    }
    out.info(format_args!(
        "  evaluate: polycal diagnose {f} · polycal solve {f} --budget B.toml · polycal report {f} --run-dir {d} --diagnose --budget B.toml --out {d}/report.html",
        f = file.display(),
        d = args.out.display()
    ));
}

/// The instruments of a run: the autocollimators in order and the table; `None` with
/// fewer than two autocollimators (the settings refuse that before).
fn instruments<'a, A: polycal::lab::Autocollimator, T: polycal::lab::RotaryTable>(
    acs: &'a mut [A],
    table: &'a mut T,
) -> Option<Instruments<'a>> {
    let mut acs = acs
        .iter_mut()
        .map(|a| a as &mut dyn polycal::lab::Autocollimator);
    let (ac1, ac2) = (acs.next(), acs.next());
    let more = acs.collect();
    Some(Instruments {
        ac1: ac1?,
        ac2: ac2?,
        table,
        more,
    })
}

impl RunArgs {
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
) -> Result<u8> {
    let done = dir.readings_done();
    let total = dir.manifest().expected_readings;
    let file = args.out.join(run::MEASUREMENTS);
    let kept = format!(
        "{done} of {total} readings are in {}; continue with the same command and --resume",
        file.display()
    );
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
            // Status 1: complete, with readings measured again or suspect (§8).
            let m = dir.manifest();
            return Ok(u8::from(!m.remeasured.is_empty() || !m.suspect.is_empty()));
        }
        Outcome::Interrupted => "run interrupted (table stopped)".to_string(),
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
        error => error.into(),
    }
}

/// The run's progress line: the bar, cycle, step, readings and time left.
fn show_progress(bar: &indicatif::ProgressBar, p: &Progress) {
    let left = match p.seconds_left {
        Some(s) if s.is_finite() => {
            let s = s.round() as u64;
            format!("{}:{:02}:{:02} left", s / 3600, s / 60 % 60, s % 60)
        }
        _ => "estimating".into(),
    };
    bar.set_length(p.total as u64);
    bar.set_position(p.done as u64);
    let refused = match p.refused {
        0 => String::new(),
        n => format!(" · {n} re-read"),
    };
    bar.set_message(format!(
        "cycle {}/{} step {}/{} · {}/{} readings{refused} · {left}",
        p.cycle.0, p.cycle.1, p.stop.0, p.stop.1, p.done, p.total
    ));
}

/// `polycal sim-lab`: serves until killed or standard input closes.
pub fn sim_lab(args: &SimLabArgs, out: &Output) -> Result<u8> {
    let faults = args
        .faults
        .iter()
        .map(|spec| {
            spec.parse::<Fault>()
                .map_err(|m| anyhow!("--fault {spec}: {m}"))
        })
        .collect::<Result<Vec<_>>>()?;
    let config = LabConfig::new(args.truth.config(args.ac_faces.clone(), 1, 1, 20.0)?)
        .with_speed_deg_per_s(args.speed)
        .with_home_seconds(args.home_seconds)
        .with_time_scale(args.time_scale)
        .with_faults(faults);
    let devices = Devices::new(config)?;
    args.truth.write_truth(&devices.truth())?;
    serve(devices, args.format, out)
}

/// Without pseudo-terminals there is no lab to serve.
#[cfg(not(unix))]
fn serve(_devices: Devices, _format: PathsFormat, _out: &Output) -> Result<u8> {
    bail!("sim-lab needs pseudo-terminals, which this system does not have")
}

/// Serves the devices on pseudo-terminals and prints their paths.
#[cfg(unix)]
fn serve(devices: Devices, format: PathsFormat, out: &Output) -> Result<u8> {
    let faces = devices.truth().faces;
    let ac_faces_text = devices
        .ac_faces()
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(",");
    let lab = Lab::start(devices)?;
    let paths = lab.paths().clone();
    let acs = paths.acs();
    {
        let stdout = std::io::stdout();
        let mut stdout = stdout.lock();
        match format {
            PathsFormat::Table => {
                for (i, path) in acs.iter().enumerate() {
                    writeln!(stdout, "ac{} {path}", i + 1)?;
                }
                writeln!(stdout, "table {}", paths.table)?;
            }
            PathsFormat::Json => writeln!(stdout, "{}", polycal::output::to_json(&paths)?)?,
        }
        stdout.flush()?;
    }
    let ports = if acs.len() == 2 {
        format!("--ac1 {} --ac2 {}", paths.ac1, paths.ac2)
    } else {
        acs.iter()
            .map(|p| format!("--ac {p}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    out.info(format_args!(
        "polycal sim-lab: serving; try\n  polycal run {ports} --table {} --faces {}{} --cycles 2 --closing --settle 0 --out RUN_DIR\nstop with Ctrl-C{}",
        paths.table,
        faces,
        if acs.len() == 2 {
            String::new()
        } else {
            format!(" --ac-faces {}", ac_faces_text)
        },
        if stdin_is_null() {
            ""
        } else {
            " or by closing standard input (Ctrl-D)"
        }
    ));
    if stdin_is_null() {
        loop {
            std::thread::park();
        }
    }
    let mut sink = [0u8; 256];
    let mut stdin = std::io::stdin().lock();
    loop {
        match stdin.read(&mut sink) {
            Ok(0) => break,
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(_) => break,
        }
    }
    lab.shutdown();
    Ok(0)
}

/// Whether standard input is /dev/null (a background job of a script): then the lab
/// serves until killed, as it would never see input close otherwise.
#[cfg(unix)]
fn stdin_is_null() -> bool {
    use std::os::unix::fs::MetadataExt;
    match (
        std::fs::metadata("/dev/stdin"),
        std::fs::metadata("/dev/null"),
    ) {
        (Ok(a), Ok(b)) => a.rdev() == b.rdev() && a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}
