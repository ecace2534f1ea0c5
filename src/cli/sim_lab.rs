//! `polycal sim-lab` (feature `lab`): simulated instruments on pseudo-terminals, to try
//! `run` without hardware. All logic lives in the library (`polycal::lab::sim`).

#[cfg(unix)]
use std::io::BufRead;
use std::io::Write;

#[cfg(not(unix))]
use anyhow::bail;
use anyhow::{Result, anyhow};
use clap::ValueEnum;
#[cfg(unix)]
use polycal::lab::sim::Lab;
use polycal::lab::sim::{Devices, Fault, LabConfig};

use super::output::Output;

/// After `polycal sim-lab --help`.
pub const SIM_LAB_EXAMPLES: &str = "\
Examples:
  polycal sim-lab --faces 24 --time-scale 0 --truth-out lab.truth.json
  polycal sim-lab --faces 8 --fault lost-reply:ac1:after=5 --format json
  polycal sim-lab --faces 8 --fault late:ac2:after=7:seconds=1.3 --fault unsolicited:ac1:after=20
  polycal sim-lab --direction -0.3 --drift 2:1.5 --bidirectional
  polycal sim-lab --faces 24 --setups 2 --shift-deg 0,7.5 --time-scale 0

With --setups, a line `remount` on standard input mounts the polygon for the next setup
(the operator's part of `run --setup S`); the lab answers `remounted S` on standard output.";

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
    /// duplicated, unsolicited, swapped, stale, nul-padding (every reply padded with
    /// NUL bytes) or xoff (the table holds the host's output with XOFF for S seconds,
    /// then XON); DEVICE ac1, ac2 or table; repeatable
    /// (docs/FORMAT.md §7.4).
    #[arg(long = "fault")]
    faults: Vec<String>,
    /// The face each simulated autocollimator reads at step 0, autocollimator 1 first
    /// (2 … 16 autocollimators), as `run --ac-faces` takes it.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    ac_faces: Vec<usize>,
    /// The lab's mountings of the polygon, as `simulate` takes them: the lab starts in
    /// the first, and a `remount` line on standard input mounts the next (`run --setup
    /// S --shift D --face-shift K`, K = (S − 1)·--setup-shift mod N).
    #[command(flatten)]
    mountings: super::simulate::MountingsArgs,
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

/// `polycal sim-lab`: serves until killed or standard input closes; a `remount` line on
/// standard input mounts the polygon for the next setup.
pub fn sim_lab(args: &SimLabArgs, out: &Output) -> Result<u8> {
    let faults = args
        .faults
        .iter()
        .map(|spec| {
            spec.parse::<Fault>()
                .map_err(|m| anyhow!("--fault {spec}: {m}"))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut simulation = args.truth.config(
        args.ac_faces.clone(),
        args.mountings.setups,
        args.mountings.setup_shift,
        20.0,
    )?;
    simulation.table_shift_deg = args.mountings.shift_deg.clone();
    let config = LabConfig::new(simulation)
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
    let mountings: Vec<_> = devices.mountings().into_iter().skip(1).collect();
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
        let stdout = super::stdout::stdout();
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
    let run = format!(
        "polycal run {ports} --table {} --faces {faces}{} --cycles 2 --closing --settle 0 --out RUN_DIR",
        paths.table,
        if acs.len() == 2 {
            String::new()
        } else {
            format!(" --ac-faces {}", ac_faces_text)
        },
    );
    // One line at a time: a line of information is shown with its control characters
    // escaped, so a line feed inside one would print as a literal `\n`.
    let mut lines = vec![
        "polycal sim-lab: serving; try".to_string(),
        format!("  {run}"),
    ];
    for m in &mountings {
        lines.push("then type `remount` here (the polygon remounted) and".to_string());
        lines.push(format!("  {run} {}", m.as_options()));
    }
    lines.push(format!(
        "stop with Ctrl-C{}",
        if stdin_is_null() {
            ""
        } else {
            " or by closing standard input (Ctrl-D)"
        }
    ));
    for line in lines {
        out.info(line);
    }
    if stdin_is_null() {
        loop {
            std::thread::park();
        }
    }
    for line in std::io::stdin().lock().lines() {
        let Ok(line) = line else { break };
        match line.trim() {
            "" => {}
            "remount" => match lab.remount() {
                Ok(m) => {
                    // On standard output too, for a script that waits for it.
                    let mut stdout = super::stdout::stdout().lock();
                    writeln!(stdout, "remounted {m}")?;
                    stdout.flush()?;
                    out.info(format_args!(
                        "polycal sim-lab: the polygon is remounted: mounting {m}"
                    ));
                }
                Err(e) => out.warning(format_args!("remount: {e}")),
            },
            other => out.warning(format_args!(
                "sim-lab: {other:?} is not a command (`remount` mounts the polygon for the next setup)"
            )),
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
