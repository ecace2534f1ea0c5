//! `polycal sim-lab` (feature `lab`): simulated instruments on pseudo-terminals, to try
//! `run` without hardware. All logic lives in the library (`polycal::lab::sim`).

#[cfg(unix)]
use std::io::BufRead;
use std::io::Write;

#[cfg(not(unix))]
use anyhow::bail;
use anyhow::{Result, anyhow};
use clap::ValueEnum;
use polycal::lab::profile::Profile;
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
  polycal sim-lab --faces 12 --table-profile pi-gcs2 --tcp --time-scale 0

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
    /// Inject a fault KIND:DEVICE[:after=K][:count=M][:seconds=S|:commands=C][:fraction=F];
    /// KIND lost-reply, garbled, x-invalid, disable, close, late (by S seconds, default
    /// 1.5, or held until C more commands came), duplicated, unsolicited, swapped,
    /// stale, stall (the table's move ends F of its 0.001° tolerance short, default
    /// 0.5), sign-flip, swap-xy or drop-digit (a measurement's value changed, its form
    /// right), nul-padding (every reply padded with NUL bytes) or xoff (the table holds
    /// the host's output with XOFF for S seconds, then XON); DEVICE ac1, ac2 or table;
    /// repeatable (docs/FORMAT.md §7.4).
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
    /// The protocol the simulated autocollimators speak: a bundled profile
    /// (elcomat3000) or a profile file FILE.toml (docs/instruments.md).
    #[arg(long, value_name = "NAME|FILE.toml", default_value = "elcomat3000")]
    ac_profile: String,
    /// The protocol the simulated table speaks: a bundled profile (smc100, pi-gcs2,
    /// aerotech-ascii, esp301) or a profile file FILE.toml.
    #[arg(long, value_name = "NAME|FILE.toml", default_value = "smc100")]
    table_profile: String,
    /// Serve every device on a TCP port of 127.0.0.1 (tcp://127.0.0.1:PORT) instead of
    /// a pseudo-terminal.
    #[arg(long)]
    tcp: bool,
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
    let load = |option: &str, name: &str| {
        Profile::load(name).map_err(|e| anyhow!("--{option} {name}: {e}"))
    };
    let ac_profile = load("ac-profile", &args.ac_profile)?;
    ac_profile
        .autocollimator()
        .map_err(|e| anyhow!("--ac-profile {}: {e}", args.ac_profile))?;
    let table_profile = load("table-profile", &args.table_profile)?;
    table_profile
        .table()
        .map_err(|e| anyhow!("--table-profile {}: {e}", args.table_profile))?;
    let config = LabConfig::new(simulation)
        .with_speed_deg_per_s(args.speed)
        .with_home_seconds(args.home_seconds)
        .with_time_scale(args.time_scale)
        .with_faults(faults)
        .with_ac_profile(ac_profile)
        .with_table_profile(table_profile);
    let devices = Devices::new(config)?;
    args.truth.write_truth(&devices.truth())?;
    serve(devices, args, out)
}

/// Without pseudo-terminals there is no lab to serve.
#[cfg(not(unix))]
fn serve(_devices: Devices, _args: &SimLabArgs, _out: &Output) -> Result<u8> {
    bail!("sim-lab needs pseudo-terminals, which this system does not have")
}

/// Serves the devices on pseudo-terminals and prints their paths.
#[cfg(unix)]
fn serve(devices: Devices, args: &SimLabArgs, out: &Output) -> Result<u8> {
    let format = args.format;
    let faces = devices.truth().faces;
    let mountings: Vec<_> = devices.mountings().into_iter().skip(1).collect();
    let ac_faces_text = devices
        .ac_faces()
        .iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join(",");
    let lab = if args.tcp {
        Lab::start_tcp(devices)?
    } else {
        Lab::start(devices)?
    };
    let paths = lab.paths().clone();
    let acs = &paths.autocollimators;
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
        format!("--ac1 {} --ac2 {}", acs[0], acs[1])
    } else {
        acs.iter()
            .map(|p| format!("--ac {p}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut profiles = String::new();
    if args.ac_profile != "elcomat3000" {
        profiles.push_str(&format!(" --ac-profile {}", args.ac_profile));
    }
    if args.table_profile != "smc100" {
        profiles.push_str(&format!(" --table-profile {}", args.table_profile));
    }
    let run = format!(
        "polycal run {ports} --table {}{profiles} --faces {faces}{} --cycles 2 --closing --settle 0 --out RUN_DIR",
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
