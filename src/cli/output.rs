//! The terminal side of standard error: polycal's own `warning:` and `error:` lines
//! (coloured or not), `-q`, and progress bars.
//!
//! Results go to standard output and are never affected by anything here. Colour is on
//! with `--color always`, or with `--color auto` (the default) when standard error is a
//! terminal and `NO_COLOR` is unset or empty. `-q` silences warnings, summaries and
//! progress bars, never errors. Progress bars are drawn only on a terminal.

use std::fmt::Display;
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use clap::builder::styling::{AnsiColor, Style};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::ColorWhen;

/// The style of the `error:` prefix: bold red, as cargo's and clap's.
const ERROR: Style = AnsiColor::Red.on_default().bold();
/// The style of the `warning:` prefix: bold yellow.
const WARNING: Style = AnsiColor::Yellow.on_default().bold();

/// Work shorter than this shows no progress bar.
const PROGRESS_DELAY: Duration = Duration::from_secs(1);

/// How polycal writes to standard error in this process.
#[derive(Debug, Clone, Copy)]
pub struct Output {
    color: bool,
    quiet: bool,
    terminal: bool,
}

impl Output {
    /// From the global options, standard error and `NO_COLOR`.
    pub fn new(when: ColorWhen, quiet: bool) -> Output {
        let terminal = std::io::stderr().is_terminal();
        let no_color = std::env::var_os("NO_COLOR").is_some_and(|v| !v.is_empty());
        Output {
            color: color_on(when, terminal, no_color),
            quiet,
            terminal,
        }
    }

    /// A `warning:` line, unless `-q`.
    pub fn warning(&self, message: impl Display) {
        if !self.quiet {
            self.prefixed(WARNING, "warning", message);
        }
    }

    /// An `error:` line with the error and its causes (always written).
    pub fn error(&self, error: &anyhow::Error) {
        self.error_message(one_line(error));
    }

    /// An `error:` line (always written).
    pub fn error_message(&self, message: impl Display) {
        self.prefixed(ERROR, "error", message);
    }

    /// A line of information (a summary, a hint), unless `-q`.
    pub fn info(&self, message: impl Display) {
        if !self.quiet {
            let message = message.to_string();
            let message = polycal::input::escaped(&message);
            let _ = writeln!(std::io::stderr().lock(), "{message}");
        }
    }

    fn prefixed(&self, style: Style, label: &str, message: impl Display) {
        let message = message.to_string();
        let message = polycal::input::escaped(&message);
        let mut err = std::io::stderr().lock();
        let _ = if self.color {
            writeln!(
                err,
                "{}{label}:{} {message}",
                style.render(),
                style.render_reset()
            )
        } else {
            writeln!(err, "{label}: {message}")
        };
    }

    /// Whether progress bars are drawn: standard error is a terminal and no `-q`.
    pub fn shows_progress(&self) -> bool {
        self.terminal && !self.quiet
    }

    /// A progress bar on standard error, hidden unless [`Output::shows_progress`]; it is
    /// cleared when dropped or finished.
    #[cfg(feature = "lab")]
    pub fn bar(&self) -> ProgressBar {
        let target = if self.shows_progress() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        };
        ProgressBar::with_draw_target(None, target)
    }

    /// The progress hook of a long computation (the Monte Carlo of `solve`): call it
    /// with the trials done and the total (`None` while the total is not known, as in
    /// the adaptive procedure); any thread may call it. The bar appears once the work
    /// has taken a second, on a terminal and without `-q`, and is cleared when the
    /// returned function is dropped.
    ///
    /// ```text
    /// Monte Carlo [##########....................] 352000/1000000 trials · 3s left
    /// Monte Carlo ⠙ 352000 trials · 4s
    /// ```
    pub fn progress_bar(&self, what: &str) -> impl Fn(u64, Option<u64>) + Sync + Send + use<> {
        self.progress_bar_of(what, "trials")
    }

    /// As [`Output::progress_bar`], counting `unit` (the sizes a plan predicts, say):
    ///
    /// ```text
    /// Planning design 1 [##########....................] 12/36 sizes · 8s left
    /// ```
    pub fn progress_bar_of(
        &self,
        what: &str,
        unit: &str,
    ) -> impl Fn(u64, Option<u64>) + Sync + Send + use<> {
        let enabled = self.shows_progress();
        let unit = unit.to_string();
        let bar = ProgressBar::hidden()
            .with_prefix(what.to_string())
            .with_finish(indicatif::ProgressFinish::AndClear);
        let start = Instant::now();
        let shown = AtomicBool::new(false);
        // The length the bar has: `u64::MAX` before the first call, 0 for "unknown".
        let length = AtomicU64::new(u64::MAX);
        move |done: u64, total: Option<u64>| {
            if !enabled {
                return;
            }
            if !shown.load(Ordering::Relaxed) {
                if start.elapsed() < PROGRESS_DELAY {
                    return;
                }
                if !shown.swap(true, Ordering::AcqRel) {
                    bar.set_draw_target(ProgressDrawTarget::stderr());
                }
            }
            let total_or_zero = total.unwrap_or(0);
            if length.swap(total_or_zero, Ordering::AcqRel) != total_or_zero {
                match total {
                    Some(total) => {
                        bar.set_style(style(&format!(
                            "{{prefix}} [{{bar:30}}] {{pos}}/{{len}} {unit} · {{eta}} left"
                        )));
                        bar.set_length(total);
                    }
                    None => {
                        bar.set_style(style(&format!(
                            "{{prefix}} {{spinner}} {{pos}} {unit} · {{elapsed}}"
                        )));
                        bar.unset_length();
                    }
                }
            }
            bar.set_position(done);
        }
    }
}

/// A progress style from a template of this module, with `#` and `.` as the bar.
pub fn style(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("#.")
}

/// Whether polycal's own prefixes are coloured.
fn color_on(when: ColorWhen, terminal: bool, no_color: bool) -> bool {
    match when {
        ColorWhen::Always => true,
        ColorWhen::Never => false,
        ColorWhen::Auto => terminal && !no_color,
    }
}

/// The error and its causes on one line, `: ` between them; a cause whose text the
/// message before it already contains (an OS error a file error quotes) is left out.
pub fn one_line(error: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut previous: Option<String> = None;
    for cause in error.chain() {
        let text = cause.to_string();
        let repeated = previous.as_deref().is_some_and(|p| p.contains(&text));
        if !repeated && !text.is_empty() {
            parts.push(text.clone());
        }
        previous = Some(text);
    }
    parts.join(": ")
}

#[cfg(test)]
mod tests {
    #[test]
    fn control_characters_are_shown_escaped() {
        use polycal::input::escaped;
        assert_eq!(escaped("plain ünïcode"), "plain ünïcode");
        assert_eq!(
            escaped("a\u{1b}[31mred\nerror: forged\r"),
            "a\\u{1b}[31mred\\nerror: forged\\r"
        );
    }

    use super::*;
    use anyhow::Context;

    #[test]
    fn colour_follows_the_option_the_terminal_and_no_color() {
        for (when, terminal, no_color, on) in [
            (ColorWhen::Always, false, true, true),
            (ColorWhen::Never, true, false, false),
            (ColorWhen::Auto, true, false, true),
            (ColorWhen::Auto, false, false, false),
            (ColorWhen::Auto, true, true, false),
        ] {
            assert_eq!(color_on(when, terminal, no_color), on, "{when:?}");
        }
    }

    #[derive(Debug, thiserror::Error)]
    #[error("{name}: {source}")]
    struct FileError {
        name: String,
        source: std::io::Error,
    }

    #[test]
    fn a_cause_the_message_quotes_is_printed_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file (os error 2)");
        let error = anyhow::Error::new(FileError {
            name: "x.csv".into(),
            source: io,
        });
        assert_eq!(one_line(&error), "x.csv: No such file (os error 2)");
        let error = error.context("cannot solve");
        assert_eq!(
            one_line(&error),
            "cannot solve: x.csv: No such file (os error 2)"
        );
        let plain: Result<(), _> = Err(anyhow::anyhow!("the design is singular"));
        let error = plain.context("a.csv: cannot solve").unwrap_err();
        assert_eq!(
            one_line(&error),
            "a.csv: cannot solve: the design is singular"
        );
    }

    #[test]
    fn a_hidden_progress_bar_takes_calls_from_any_thread() {
        let output = Output {
            color: false,
            quiet: true,
            terminal: false,
        };
        let progress = output.progress_bar("Monte Carlo");
        std::thread::scope(|scope| {
            for t in 0..4 {
                let progress = &progress;
                scope.spawn(move || {
                    for done in 0..100 {
                        progress(t * 100 + done, if t % 2 == 0 { Some(400) } else { None });
                    }
                });
            }
        });
    }
}
