//! The person at the table, as `polycal run` meets them: the progress line, what the
//! check after every cycle found, the remount prompt, and the summary of a completed run.

use std::time::Duration;

use polycal::lab::StopFlag;
use polycal::lab::run::{self, Attendant, CycleCheck, Progress, Remount, RunDir};

use super::RunArgs;
use crate::cli::output::Output;

/// The person at the table, as `run` meets them: the progress bar, the check after
/// every cycle, the remount prompt.
pub(super) struct Operator<'a> {
    pub(super) out: &'a Output,
    pub(super) bar: &'a indicatif::ProgressBar,
    pub(super) stop: &'a StopFlag,
    pub(super) checks: Vec<CycleCheck>,
    /// Why a remount was not confirmed, when it was not.
    pub(super) declined: Option<String>,
}

impl Attendant for Operator<'_> {
    fn progress(&mut self, p: &Progress) {
        show_progress(self.bar, p);
        if let Some(check) = &p.cycle_check {
            self.bar.suspend(|| show_cycle_check(self.out, check));
            self.checks.push(check.clone());
        }
    }

    fn remount(&mut self, remount: &Remount) -> bool {
        let faces = remount
            .faces
            .iter()
            .map(|(ac, face)| format!("face {face} faces autocollimator {ac}"))
            .collect::<Vec<_>>()
            .join(", ");
        let m = remount.mounting;
        // The prompt is shown with -q too: the run waits for it.
        self.bar.suspend(|| {
            eprintln!(
                "polycal run: {m}: the table stands at {}°.\n  Remount the polygon with the table \
                 there, not moved: {faces}.\n  Press Enter once it is mounted (Ctrl-C stops the run):",
                remount.table_deg
            );
        });
        match confirmation(self.stop) {
            Confirmation::Confirmed => true,
            Confirmation::Closed => {
                self.declined = Some(format!(
                    "no confirmation that the polygon is remounted for {m} (standard input closed)"
                ));
                false
            }
            Confirmation::Stopped => false,
        }
    }
}

/// What came of the remount prompt.
enum Confirmation {
    /// A line (Enter) on standard input.
    Confirmed,
    /// Standard input closed without one.
    Closed,
    /// The run was stopped (Ctrl-C) while waiting.
    Stopped,
}

/// Waits for a line on standard input, or for the stop flag.
fn confirmation(stop: &StopFlag) -> Confirmation {
    let (tx, rx) = std::sync::mpsc::channel();
    // The thread may stay blocked in the read after a stop; the process ends soon after.
    let spawned = std::thread::Builder::new()
        .name("remount-prompt".into())
        .spawn(move || {
            let mut line = String::new();
            let read = std::io::stdin().read_line(&mut line);
            let _ = tx.send(matches!(read, Ok(n) if n > 0));
        });
    if spawned.is_err() {
        return Confirmation::Closed;
    }
    loop {
        if stop.is_set() {
            return Confirmation::Stopped;
        }
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(true) => return Confirmation::Confirmed,
            Ok(false) | Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Confirmation::Closed;
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
        }
    }
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

/// `cycle 2`, or `mounting 2, cycle 1` after the first mounting.
fn cycle_name(check: &CycleCheck) -> String {
    match check.setup {
        1 => format!("cycle {}", check.cycle),
        s => format!("mounting {s}, cycle {}", check.cycle),
    }
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
    out.info(format_args!("{}: {closure}{rms}", cycle_name(check)));
    let mounting = match check.setup {
        1 => String::new(),
        s => format!("mounting {s}, "),
    };
    for r in &check.remeasured {
        out.info(format_args!(
            "  measured again: {mounting}cycle {}, step {}, autocollimator {}: {}″ (residual {:+.4}″, σ {:.4}″) replaced by {}″",
            r.cycle, r.step, r.ac, r.first_arcsec, r.residual_arcsec, r.sigma_arcsec, r.reading_arcsec
        ));
    }
    for r in &check.suspect {
        out.warning(format_args!(
            "{mounting}cycle {}, step {}, autocollimator {}: {}″ lies {:+.4}″ off the fit (σ {:.4}″), and measuring its stop again gave {}″: kept, and named suspect in the manifest",
            r.cycle, r.step, r.ac, r.reading_arcsec, r.residual_arcsec, r.sigma_arcsec, r.measured_again_arcsec
        ));
    }
    for w in &check.warnings {
        out.warning(w);
    }
}

/// The end of a completed run: readings, what was measured again, closure and residual
/// RMS per cycle, the diagnosis of the file, and the commands that evaluate it.
pub(super) fn summary(args: &RunArgs, out: &Output, dir: &RunDir, checks: &[CycleCheck]) {
    let m = dir.manifest();
    let file = args.out().join(run::MEASUREMENTS);
    out.info(format_args!(
        "polycal run: {} readings in {}; {} measured again, {} suspect (manifest.json)",
        dir.readings_done(),
        file.display(),
        m.remeasured.len(),
        m.suspect.len()
    ));
    for record in m.mountings.iter().filter(|r| r.misfit.is_some()) {
        out.warning(format_args!(
            "{}: its readings do not fit those of the mountings before it (manifest.json `mountings`): check how the polygon was mounted before evaluating the run",
            record.mounting
        ));
    }
    for check in checks {
        let closure = closure_text(check);
        let rms = check
            .residual_rms_arcsec
            .map_or("—".to_string(), |r| format!("{r:.4}″"));
        out.info(format_args!(
            "  {}: closure {} · residual RMS {rms}",
            cycle_name(check),
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
        d = args.out().display()
    ));
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
    let mounting = match p.setup {
        1 => String::new(),
        s => format!("mounting {s} · "),
    };
    bar.set_message(format!(
        "{mounting}cycle {}/{} step {}/{} · {}/{} readings{refused} · {left}",
        p.cycle.0, p.cycle.1, p.stop.0, p.stop.1, p.done, p.total
    ));
}
