//! The runner the fuzz targets share: how many cases, which random stream, panics caught
//! with their place, findings saved as reproducers, and one clear message per failure.
//!
//! Environment:
//! - `POLYCAL_FUZZ_CASES=N`: cases per library-level target (default
//!   [`DEFAULT_CASES`]); binary-level targets run N / 16 (at least 4).
//! - `POLYCAL_FUZZ_SEED=S`: the random stream (a number, or `random`); the default is
//!   fixed, so that a run repeats.
//! - `POLYCAL_FUZZ_SURVEY=1`: do not stop at the first failure: run every case, save one
//!   reproducer per kind of failure and list them all at the end (no shrinking).
//!
//! A failing target stops at its first failure, which proptest shrinks to fewer and
//! simpler mutations while the failure stays of the same kind; the message names the
//! kind, the seed file and mutations, the changed lines, and the path of the mutated
//! input saved under `target/tmp/fuzz-failures/`.
#![allow(dead_code)]

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fmt::{Debug, Display};
use std::panic::{self, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::Once;

use proptest::strategy::Strategy;
use proptest::test_runner::{Config, RngSeed, TestCaseError, TestError, TestRunner};

use super::mutate::{Case, diff, show};

/// Cases per library-level target unless `POLYCAL_FUZZ_CASES` says otherwise.
pub const DEFAULT_CASES: u32 = 16384;

/// The default random stream: fixed, so that CI repeats its cases.
const DEFAULT_SEED: u64 = 0x706f_6c79_6361_6c00;

/// Cases per library-level target.
pub fn library_cases() -> u32 {
    match std::env::var("POLYCAL_FUZZ_CASES") {
        Ok(v) => v
            .trim()
            .parse()
            .unwrap_or_else(|_| panic!("POLYCAL_FUZZ_CASES={v:?} is not a number of cases")),
        Err(_) => DEFAULT_CASES,
    }
}

/// Cases per binary-level target (spawning the binary is slow): a sixteenth.
pub fn binary_cases() -> u32 {
    (library_cases() / 16).max(4)
}

fn base_seed() -> Option<u64> {
    match std::env::var("POLYCAL_FUZZ_SEED") {
        Ok(v) if v.trim() == "random" => None,
        Ok(v) => Some(
            v.trim()
                .parse()
                .unwrap_or_else(|_| panic!("POLYCAL_FUZZ_SEED={v:?} is not a number")),
        ),
        Err(_) => Some(DEFAULT_SEED),
    }
}

fn survey() -> bool {
    std::env::var_os("POLYCAL_FUZZ_SURVEY").is_some_and(|v| !v.is_empty() && v != "0")
}

/// What a case found: which assertion failed (`kind`, stable enough to group by), what
/// happened, and the input that did it.
#[derive(Debug, Clone)]
pub struct Finding {
    /// The assertion, e.g. `panic in solve at src/solve/mod.rs:12:5`.
    pub kind: String,
    /// What happened (messages, output).
    pub detail: String,
    /// The mutated input (the file's bytes, or a reply line).
    pub input: Vec<u8>,
    /// The extension of the saved reproducer.
    pub ext: &'static str,
    /// Where the input came from: the seed and its mutations, and the changed lines.
    pub origin: String,
    /// The command that failed and the path of the mutated file in it (binary level):
    /// the message shows it with the saved reproducer instead.
    pub command: Option<(String, String)>,
}

impl Finding {
    /// A finding of `case` (its mutated bytes are the input).
    pub fn of(
        case: &Case,
        ext: &'static str,
        kind: impl Into<String>,
        detail: impl Into<String>,
    ) -> Box<Finding> {
        let input = case.bytes();
        let origin = format!("{case:?}\n{}", diff(&case.seed.bytes, &input));
        Box::new(Finding {
            kind: kind.into(),
            detail: detail.into(),
            input,
            ext,
            origin,
            command: None,
        })
    }

    /// Saves the input (and a `.txt` with the message) under `target/tmp/fuzz-failures/
    /// TARGET/`; returns the input's path.
    fn save(&self, target: &str, n: usize) -> PathBuf {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
            .join("fuzz-failures")
            .join(target);
        let _ = std::fs::create_dir_all(&dir);
        let name: String = self
            .kind
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        let name = format!("{n:02}-{}", name.trim_matches('-'));
        let name = &name[..name.len().min(90)];
        let path = dir.join(format!("{name}.{}", self.ext));
        let _ = std::fs::write(&path, &self.input);
        let _ = std::fs::write(dir.join(format!("{name}.txt")), self.message(target, &path));
        path
    }

    fn message(&self, target: &str, saved: &std::path::Path) -> String {
        let reproduce = match &self.command {
            Some((command, input)) => format!(
                "to reproduce: {}\n",
                command.replace(input.as_str(), &saved.display().to_string())
            ),
            None => String::new(),
        };
        format!(
            "fuzz target `{target}`: {}\n{}\ninput ({} bytes, saved as {}): {}\n{reproduce}origin: {}\n",
            self.kind,
            self.detail.trim_end(),
            self.input.len(),
            saved.display(),
            show(&self.input, 600),
            self.origin
        )
    }
}

thread_local! {
    /// The place and message of the last panic on this thread while [`catch`] runs.
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
    /// Whether [`catch`] is running on this thread (its panics are not printed).
    static QUIET: RefCell<bool> = const { RefCell::new(false) };
}

/// Installs (once) a panic hook that records where a caught panic happened and prints
/// only the others (the harness's own assertion failures).
fn install_hook() {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let default = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if QUIET.with(|q| *q.borrow()) {
                let place = info
                    .location()
                    .map(|l| format!("{}:{}:{}", l.file(), l.line(), l.column()))
                    .unwrap_or_else(|| "an unknown place".to_string());
                // A panic in the standard library (an overflow, an index) is placed by
                // the crate's frame that called it.
                let place = if place.starts_with("src/") {
                    place
                } else {
                    let trace = std::backtrace::Backtrace::force_capture().to_string();
                    match crate_frame(&trace) {
                        Some(frame) => format!("{frame} (in {})", short(&place)),
                        None => place,
                    }
                };
                let message = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                LAST_PANIC.with(|p| *p.borrow_mut() = Some(format!("{place}\t{message}")));
            } else {
                default(info);
            }
        }));
    });
}

/// The first frame of a backtrace in the crate's `src/` (`src/file.rs:line:column`).
pub fn crate_frame(trace: &str) -> Option<String> {
    trace.lines().find_map(|line| {
        let at = line.trim().strip_prefix("at ")?;
        let at = at.strip_prefix("./").unwrap_or(at);
        let at = at
            .strip_prefix(concat!(env!("CARGO_MANIFEST_DIR"), "/"))
            .unwrap_or(at);
        at.starts_with("src/").then(|| at.to_string())
    })
}

/// A place in the standard library without the toolchain's path (`alloc/src/…`).
pub fn short(place: &str) -> &str {
    place
        .split_once("/library/")
        .map_or(place, |(_, rest)| rest)
}

/// Runs `f`, catching a panic: `Err((place, message))`.
pub fn catch<T>(f: impl FnOnce() -> T) -> Result<T, (String, String)> {
    install_hook();
    QUIET.with(|q| *q.borrow_mut() = true);
    LAST_PANIC.with(|p| *p.borrow_mut() = None);
    let result = panic::catch_unwind(AssertUnwindSafe(f));
    QUIET.with(|q| *q.borrow_mut() = false);
    result.map_err(|_| {
        let text = LAST_PANIC
            .with(|p| p.borrow_mut().take())
            .unwrap_or_else(|| "an unknown place\t".to_string());
        let (place, message) = text.split_once('\t').unwrap_or((&text, ""));
        (place.to_string(), message.to_string())
    })
}

/// Runs `what` on a case, a panic being a finding `panic in WHAT at PLACE`.
pub fn no_panic<T>(
    case: &Case,
    ext: &'static str,
    what: &str,
    f: impl FnOnce() -> T,
) -> Result<T, Box<Finding>> {
    catch(f).map_err(|(place, message)| {
        Finding::of(
            case,
            ext,
            format!("panic in {what} at {place}"),
            format!("panic message: {message}"),
        )
    })
}

/// Reads a case with `read` (a reader given `source` as the file's name): a panic is a
/// finding, and so is an error whose message does not name `source`. `Ok(Some(value))`
/// when the reader accepted the input, `Ok(None)` when it refused it properly.
pub fn read<T, E: Display>(
    case: &Case,
    ext: &'static str,
    what: &str,
    source: &str,
    read: impl FnOnce() -> Result<T, E>,
) -> Result<Option<T>, Box<Finding>> {
    match no_panic(case, ext, what, read)? {
        Ok(value) => Ok(Some(value)),
        Err(e) => {
            let message = catch(|| e.to_string()).map_err(|(place, m)| {
                Finding::of(
                    case,
                    ext,
                    format!("panic in {what}'s error message at {place}"),
                    m,
                )
            })?;
            if !message.contains(source) {
                return Err(Finding::of(
                    case,
                    ext,
                    format!("{what}: the error does not name the file"),
                    format!("the file was given as {source:?}; the error says: {message}"),
                ));
            }
            if let Some(line) = first_invalid_utf8_line(&case.bytes())
                && !has_position(&message, source, line)
            {
                return Err(Finding::of(
                    case,
                    ext,
                    format!("{what}: a refusal of bytes that are not UTF-8 has no line and column"),
                    format!("the first invalid byte is on line {line}; the error says: {message}"),
                ));
            }
            Ok(None)
        }
    }
}

/// The line of the first byte that is not UTF-8 (lines ending in LF, CR LF or a lone
/// CR, the most any reader counts), or `None` for UTF-8 text.
pub fn first_invalid_utf8_line(bytes: &[u8]) -> Option<u64> {
    let valid = std::str::from_utf8(bytes).err()?.valid_up_to();
    let before = &bytes[..valid];
    let lone_cr = before
        .windows(2)
        .filter(|w| w[0] == b'\r' && w[1] != b'\n')
        .count()
        + usize::from(before.last() == Some(&b'\r'));
    let lf = before.iter().filter(|&&b| b == b'\n').count();
    Some((lf + lone_cr + 1) as u64)
}

/// Whether `message` places the problem in `source`, as `SOURCE:LINE:COLUMN` with a LINE
/// from 1 to `max_line` (docs/FORMAT.md §2.1, §3.2, §4, §5.3, §9.2.1: a file that is not
/// UTF-8 is refused with the line and column of the invalid byte; a reader that stops
/// earlier at another problem names that one's place).
pub fn has_position(message: &str, source: &str, max_line: u64) -> bool {
    message.match_indices(source).any(|(i, _)| {
        let rest = &message[i + source.len()..];
        let mut parts = rest.splitn(4, ':');
        let (Some(""), Some(line), Some(column)) = (parts.next(), parts.next(), parts.next())
        else {
            return false;
        };
        let line: Option<u64> = line.parse().ok();
        let column_ok = !column.is_empty() && column.bytes().all(|b| b.is_ascii_digit());
        column_ok && line.is_some_and(|l| (1..=max_line).contains(&l))
    })
}

/// The scratch directory of this process, thread and `name`, under `target/tmp/`.
fn scratch_path(name: &str) -> PathBuf {
    let thread = format!("{:?}", std::thread::current().id());
    let thread: String = thread.chars().filter(char::is_ascii_digit).collect();
    PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("fuzz-work")
        .join(format!("{name}-{}-{thread}", std::process::id()))
}

/// A scratch directory of this process, thread and `name`, under `target/tmp/` (created;
/// [`run`] removes that of its target at the end).
pub fn scratch(name: &str) -> PathBuf {
    let dir = scratch_path(name);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    dir
}

/// The proptest configuration of a target: `cases` cases, its own fixed random stream,
/// no regression files (reproducers are saved by [`run`]), bounded shrinking.
fn config(target: &str, cases: u32, shrink_iters: u32) -> Config {
    let mut config = Config::with_cases(cases);
    config.failure_persistence = None;
    config.max_shrink_iters = shrink_iters;
    config.max_shrink_time = 60_000;
    config.rng_seed = match base_seed() {
        // The target's name spreads the targets over different streams.
        Some(seed) => RngSeed::Fixed(target.bytes().fold(seed, |h, b| {
            (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
        })),
        None => RngSeed::Random,
    };
    config
}

/// Runs `cases` cases of `strategy` through `check`; panics with a clear message on the
/// first finding, once proptest has shrunk it (keeping its kind). With
/// `POLYCAL_FUZZ_SURVEY=1`, runs every case and lists every kind of finding.
pub fn run<S>(
    target: &str,
    cases: u32,
    shrink_iters: u32,
    strategy: S,
    check: impl Fn(&S::Value) -> Result<(), Box<Finding>>,
) where
    S: Strategy,
    S::Value: Debug,
{
    install_hook();
    let survey = survey();
    let first_kind: RefCell<Option<String>> = RefCell::new(None);
    let found: RefCell<BTreeMap<String, (usize, Finding)>> = RefCell::new(BTreeMap::new());
    let mut runner = TestRunner::new(config(target, cases, if survey { 0 } else { shrink_iters }));
    let result = runner.run(&strategy, |value| {
        let Err(finding) = check(&value) else {
            return Ok(());
        };
        if survey {
            let mut found = found.borrow_mut();
            let entry = found
                .entry(finding.kind.clone())
                .or_insert((0, (*finding).clone()));
            entry.0 += 1;
            if finding.input.len() < entry.1.input.len() {
                entry.1 = *finding;
            }
            return Ok(());
        }
        let mut first = first_kind.borrow_mut();
        let kind = first.get_or_insert_with(|| finding.kind.clone());
        if *kind == finding.kind {
            Err(TestCaseError::fail(finding.kind))
        } else {
            // Another kind of failure while shrinking: not the one being minimised.
            Ok(())
        }
    });
    let failure = match result {
        Ok(()) => None,
        Err(TestError::Fail(_, value)) => {
            let finding = check(&value).expect_err("the shrunk case fails again");
            let path = finding.save(target, 0);
            Some(finding.message(target, &path))
        }
        Err(e) => Some(format!("fuzz target `{target}`: {e}")),
    };
    let found = found.into_inner();
    let failure = failure.or_else(|| {
        (!found.is_empty()).then(|| {
            let mut text = format!(
                "fuzz target `{target}`: {} kinds of failure\n\n",
                found.len()
            );
            for (n, (_, (count, finding))) in found.iter().enumerate() {
                let path = finding.save(target, n + 1);
                text.push_str(&format!(
                    "({count} cases) {}\n",
                    finding.message(target, &path)
                ));
            }
            text
        })
    });
    // The cases ran on this thread: their scratch files are done with.
    let _ = std::fs::remove_dir_all(scratch_path(target));
    if let Some(failure) = failure {
        panic!("{failure}");
    }
}
