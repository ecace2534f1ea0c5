//! The binary-level checks: run a `polycal` command on a mutated file and judge what it
//! did by docs/FORMAT.md §8.
//!
//! - the status is 0, 1 or 2 (no signal, no abort, no panic's 101);
//! - standard error never says `panicked`;
//! - status 2: exactly one line of standard error starts with `error:`, and it names the
//!   mutated file's path (for bytes that are not UTF-8, with a line and column:
//!   docs/FORMAT.md §2.1, §3.2, §4, §5.3 and §9.2.1 promise them);
//! - status 0 or 1 with `--format json`: standard output is JSON;
//! - `--format table` or `csv`: standard output never has `inf` or `NaN` as a number.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use super::harness::{Finding, crate_frame, first_invalid_utf8_line, has_position, scratch, short};
use super::mutate::{Case, show};

/// A command that runs longer than this is killed and reported.
const TIME_LIMIT: Duration = Duration::from_secs(60);

/// The repository root (relative paths of the other inputs are from here).
pub fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A file of the repository, as an absolute path.
pub fn repo(path: &str) -> PathBuf {
    root().join(path)
}

/// What a command was asked to print.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Table,
    Json,
    Csv,
    /// No `--format` (`report`, which writes a file).
    None,
}

impl Format {
    fn arg(self) -> Option<&'static str> {
        match self {
            Format::Table => Some("table"),
            Format::Json => Some("json"),
            Format::Csv => Some("csv"),
            Format::None => None,
        }
    }
}

/// One run: the command line after `polycal`, with `{}` standing for the mutated file
/// and `{dir}` for the case's scratch directory.
pub struct Run<'a> {
    /// The fuzz target (names the scratch directory).
    pub target: &'a str,
    /// The case whose bytes are the mutated file.
    pub case: &'a Case,
    /// The mutated file's extension.
    pub ext: &'static str,
    /// The arguments.
    pub args: Vec<String>,
    /// The output format asked for.
    pub format: Format,
}

impl Run<'_> {
    /// Writes the mutated file, runs the command and checks it.
    pub fn check(&self) -> Result<(), Box<Finding>> {
        let dir = scratch(self.target);
        let _ = std::fs::remove_dir_all(dir.join("out"));
        std::fs::create_dir_all(dir.join("out")).expect("scratch directory");
        let input = dir.join(format!("mutated.{}", self.ext));
        let bytes = self.case.bytes();
        std::fs::write(&input, &bytes).expect("the mutated file is written");
        let input_text = input.display().to_string();
        let mut args: Vec<OsString> = vec!["--color".into(), "never".into()];
        for a in &self.args {
            args.push(
                a.replace("{}", &input_text)
                    .replace("{dir}", &dir.join("out").display().to_string())
                    .into(),
            );
        }
        if let Some(f) = self.format.arg() {
            args.push("--format".into());
            args.push(f.into());
        }
        let shown = format!(
            "polycal {}",
            args.iter()
                .map(|a| a.to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join(" ")
        );
        let (stdout_path, stderr_path) = (dir.join("stdout"), dir.join("stderr"));
        let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(&args)
            .current_dir(root())
            .env("SOURCE_DATE_EPOCH", "0")
            .env("RUST_BACKTRACE", "1")
            .env_remove("NO_COLOR")
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&stdout_path).expect("stdout file"))
            .stderr(std::fs::File::create(&stderr_path).expect("stderr file"))
            .spawn()
            .expect("polycal runs");
        let start = Instant::now();
        let status = loop {
            if let Some(status) = child.try_wait().expect("wait") {
                break Some(status);
            }
            if start.elapsed() > TIME_LIMIT {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(2));
        };
        let stdout = std::fs::read(&stdout_path).unwrap_or_default();
        let stderr =
            String::from_utf8_lossy(&std::fs::read(&stderr_path).unwrap_or_default()).into_owned();
        let finding = |kind: String, what: &str| {
            let detail = format!(
                "command: {shown}\n(the mutated file is {input_text})\n{what}\nstderr: {}\nstdout: {}",
                show(stderr.as_bytes(), 1500),
                show(&stdout, 600)
            );
            let mut finding = Finding::of(self.case, self.ext, kind, detail);
            finding.command = Some((shown.clone(), input_text.clone()));
            Err(finding)
        };
        let command = self.args.first().map_or("", String::as_str);
        let Some(status) = status else {
            return finding(
                format!("{command}: no result within {} s", TIME_LIMIT.as_secs()),
                "killed",
            );
        };
        if let Some(line) = stderr.lines().find(|l| l.contains("panicked")) {
            let place = line
                .split_once(" at ")
                .map_or(line, |(_, place)| place.trim_end_matches(':'));
            // A panic in the standard library is placed by the crate's frame.
            let place = match crate_frame(&stderr) {
                Some(frame) if !place.starts_with("src/") => {
                    format!("{frame} (in {})", short(place))
                }
                _ => place.to_string(),
            };
            return finding(
                format!("{command}: stderr says panicked at {place}"),
                "a panic",
            );
        }
        let Some(code) = status.code() else {
            return finding(
                format!("{command}: killed by a signal"),
                &format!("{status}"),
            );
        };
        if !(0..=2).contains(&code) {
            return finding(
                format!("{command}: exit status {code}"),
                "statuses are 0, 1 or 2",
            );
        }
        if code == 2 {
            let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
            if errors.len() != 1 {
                return finding(
                    format!("{command}: status 2 with {} `error:` lines", errors.len()),
                    "status 2 must come with exactly one `error:` line",
                );
            }
            if !errors[0].contains(&input_text) {
                return finding(
                    format!("{command}: the error line does not name the mutated file"),
                    &format!("the error line: {}", errors[0]),
                );
            }
            if let Some(line) = first_invalid_utf8_line(&bytes)
                && !has_position(errors[0], &input_text, line)
            {
                return finding(
                    format!(
                        "{command}: a refusal of bytes that are not UTF-8 has no line and column"
                    ),
                    &format!(
                        "the first invalid byte is on line {line}; the error line: {}",
                        errors[0]
                    ),
                );
            }
        }
        let text = String::from_utf8_lossy(&stdout);
        match self.format {
            Format::Json if code != 2 => {
                if let Err(e) = serde_json::from_str::<serde_json::Value>(&text) {
                    return finding(
                        format!("{command}: --format json with status {code} is not JSON"),
                        &format!("serde_json: {e}"),
                    );
                }
            }
            Format::Table | Format::Csv => {
                if let Some(token) = non_finite_number(&text, &bytes) {
                    let format = self.format.arg().unwrap_or_default();
                    return finding(
                        format!("{command}: --format {format} prints {token:?} as a number"),
                        &format!("status {code}"),
                    );
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// The first word of `text` that is a non-finite number as Rust or a CSV would write
/// it: `inf`, `-inf`, `NaN`, `infinity` (any case, any sign), unless it is text copied
/// from `input` (a name that holds the word: the word and a neighbouring word appear in
/// the input as they do in the output).
pub fn non_finite_number(text: &str, input: &[u8]) -> Option<String> {
    let is_word = |c: char| c.is_alphanumeric() || matches!(c, '.' | '+' | '-' | '_');
    for line in text.lines() {
        let mut start = 0;
        for word in line.split(|c: char| !is_word(c)) {
            let (s, e) = (start, start + word.len());
            start = e + line[e..].chars().next().map_or(0, char::len_utf8);
            let bare = word.trim_start_matches(['+', '-']).to_ascii_lowercase();
            if !matches!(bare.as_str(), "inf" | "infinity" | "nan") {
                continue;
            }
            // The word with the previous and with the next word of its line.
            let before = line[..s].trim_end();
            let before = before.rfind(char::is_whitespace).map_or(0, |i| i + 1);
            let after = line[e..].len() - line[e..].trim_start().len() + e;
            let after = line[after..]
                .find(char::is_whitespace)
                .map_or(line.len(), |i| after + i);
            let echoed = [&line[before..e], &line[s..after]]
                .iter()
                .any(|context| context.len() > word.len() && contains(input, context.as_bytes()));
            if !echoed {
                return Some(word.to_string());
            }
        }
    }
    None
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}
