//! Writing an output file: only where the user meant it, whole or not at all
//! (docs/FORMAT.md §8.1).
//!
//! Every file polycal writes for a user — a report, a DCC, a simulated run and its truth,
//! the figures of a plot directory, a measurement or self-calibration file — goes
//! through [`Outputs`]:
//!
//! - **Where it was meant.** An output that is one of the command's inputs (the same file
//!   by device and inode, whatever the path, hard links and symbolic links included) is
//!   refused, as are two outputs that are one file. Only a regular file is replaced: a
//!   directory, a device node, a FIFO or a socket is refused. A symbolic link the user
//!   names is followed: the file it points to is replaced and the link kept; a link to
//!   nothing is refused. A directory the process cannot write into (its permissions, a
//!   read-only file system) is refused by [`Outputs::check`] before any work, found by
//!   creating a probe file there and removing it at once.
//! - **Whole or not at all.** Each output is written to a new temporary file in the
//!   target's directory, created exclusively (`O_CREAT | O_EXCL`, so a file or link
//!   planted at the name is never opened) under an unpredictable name
//!   (`.NAME.XXXXXXXXXXXXXXXX.polycal-tmp`), given the mode of the file it replaces, and
//!   synced. Only when every output of the command is written are they renamed over their
//!   targets ([`Outputs::commit`]); a failure before that removes every temporary file
//!   and replaces nothing. A reader never sees half a file, and a process killed while
//!   writing leaves the old file (and at most a temporary file under the name above,
//!   which a program's interrupt handler removes with [`remove_temporaries`]).
//!
//! ```
//! use polycal::output_file::Outputs;
//!
//! let dir = std::env::temp_dir().join(format!("polycal-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! let input = dir.join("run.csv");
//! std::fs::write(&input, "face,reading\n")?;
//!
//! let mut outputs = Outputs::new([input.as_path()])?;
//! outputs.write(&dir.join("report.html"), b"<html></html>")?;
//! // the input itself is not an output
//! assert!(outputs.write(&input, b"<html></html>").is_err());
//! let written = outputs.commit()?;
//! assert_eq!(written.len(), 1);
//! assert_eq!(std::fs::read(&input)?, b"face,reading\n");
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fs::{File, Metadata, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// How many unpredictable temporary names are tried before giving up.
const NAME_ATTEMPTS: usize = 16;

/// The temporary files of this process not yet renamed or removed, for
/// [`remove_temporaries`].
static PENDING: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn pending() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    PENDING
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Forgets a temporary file that was renamed, or removes it.
fn settle(temporary: &Path, remove: bool) {
    if remove {
        let _ = std::fs::remove_file(temporary);
    }
    pending().retain(|p| p != temporary);
}

/// Set by [`remove_temporaries`]: no temporary file is created after it.
static CLOSED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Removes every temporary file of this process that is not yet in place: for a
/// program's interrupt handler (a thread woken by Ctrl-C), so that an interrupted
/// command leaves no temporary file behind, only the old files. After it no new
/// temporary file is created (a write then fails as interrupted), so that one being
/// created by another thread at that moment is removed too or never made.
pub fn remove_temporaries() {
    let mut pending = pending();
    CLOSED.store(true, std::sync::atomic::Ordering::SeqCst);
    for temporary in pending.drain(..) {
        let _ = std::fs::remove_file(temporary);
    }
}

/// Whether [`remove_temporaries`] has run: an interrupt is ending the process, and a
/// write that fails now fails because of it (its temporary file removed, or not made).
pub fn interrupted() -> bool {
    CLOSED.load(std::sync::atomic::Ordering::SeqCst)
}

/// Creates the file `path` exclusively through `options`, registered for
/// [`remove_temporaries`] while it is created (under the registry's lock, so that an
/// interrupt removes it whatever the moment); refused once the temporaries are removed.
fn create_registered(options: &OpenOptions, path: &Path) -> io::Result<File> {
    let mut pending = pending();
    if CLOSED.load(std::sync::atomic::Ordering::SeqCst) {
        return Err(io::Error::new(
            io::ErrorKind::Interrupted,
            "interrupted: no file is written any more",
        ));
    }
    pending.push(path.to_path_buf());
    let opened = options.open(path);
    if opened.is_err() {
        pending.retain(|p| p != path);
    }
    opened
}

/// Why an output cannot be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// The output is one of the command's inputs.
    #[error("{output}: is the input {input} (the same file); write the output to another file")]
    SameAsInput {
        /// The output path as given.
        output: PathBuf,
        /// The input path as given.
        input: PathBuf,
    },
    /// Two outputs are one file.
    #[error("{second}: is also the output {first} (the same file); give each output its own file")]
    SameOutput {
        /// The first output named.
        first: PathBuf,
        /// The second.
        second: PathBuf,
    },
    /// The output names something other than a regular file.
    #[error("{path}: is {kind}, not a regular file; polycal replaces only regular files")]
    NotAFile {
        /// The path as given.
        path: PathBuf,
        /// What it is ("a directory", "a character device", …).
        kind: &'static str,
    },
    /// A symbolic link that points to nothing.
    #[error("{path}: is a symbolic link to nothing; name the file to write")]
    DanglingLink {
        /// The path as given.
        path: PathBuf,
    },
    /// The file system refused.
    #[error("{path}: cannot be written: {source}")]
    Io {
        /// The path as given (or the temporary file's).
        path: PathBuf,
        /// The operating system's error.
        source: io::Error,
    },
}

impl OutputError {
    /// The path the error is about (the output as given).
    pub fn path(&self) -> &Path {
        match self {
            OutputError::SameAsInput { output, .. } => output,
            OutputError::SameOutput { second, .. } => second,
            OutputError::NotAFile { path, .. }
            | OutputError::DanglingLink { path }
            | OutputError::Io { path, .. } => path,
        }
    }
}

impl OutputError {
    /// This error as an I/O error for callers whose error type holds one and names the
    /// path itself: the operating system's error as it is, the others with their reason
    /// (without the path) and the kind that fits.
    pub fn into_io(self) -> io::Error {
        let (kind, reason) = match self {
            OutputError::Io { source, .. } => return source,
            OutputError::SameAsInput { input, .. } => (
                io::ErrorKind::AlreadyExists,
                format!("is the input {} (the same file)", input.display()),
            ),
            OutputError::SameOutput { first, .. } => (
                io::ErrorKind::AlreadyExists,
                format!("is also the output {} (the same file)", first.display()),
            ),
            OutputError::NotAFile { kind, .. } => (
                io::ErrorKind::InvalidInput,
                format!("is {kind}, not a regular file; polycal replaces only regular files"),
            ),
            OutputError::DanglingLink { .. } => (
                io::ErrorKind::NotFound,
                "is a symbolic link to nothing".to_string(),
            ),
        };
        io::Error::new(kind, reason)
    }
}

/// A file's identity: device and inode (on other systems, its canonical path).
#[derive(Debug, Clone, PartialEq, Eq)]
enum Identity {
    #[cfg(unix)]
    Inode(u64, u64),
    Path(PathBuf),
}

#[cfg(unix)]
fn identity_of(_path: &Path, metadata: &Metadata) -> Identity {
    use std::os::unix::fs::MetadataExt;
    Identity::Inode(metadata.dev(), metadata.ino())
}

#[cfg(not(unix))]
fn identity_of(path: &Path, _metadata: &Metadata) -> Identity {
    Identity::Path(std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()))
}

/// Where an output goes: the file to replace (a link followed) and what it is now.
#[derive(Debug)]
struct Target {
    /// The path as given.
    given: PathBuf,
    /// The file replaced: `given`, or the file a link points to.
    file: PathBuf,
    /// Its identity: of the existing file, or of its directory and name.
    identity: Identity,
    /// The existing file's metadata.
    existing: Option<Metadata>,
}

fn kind_of(metadata: &Metadata) -> &'static str {
    let kind = metadata.file_type();
    if kind.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_fifo() {
            return "a FIFO";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

fn io_error(path: &Path) -> impl FnOnce(io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl Target {
    fn of(given: &Path) -> Result<Target, OutputError> {
        let link = match std::fs::symlink_metadata(given) {
            Ok(m) => Some(m.file_type().is_symlink()),
            Err(e) if e.kind() == io::ErrorKind::NotFound => None,
            Err(e) => return Err(io_error(given)(e)),
        };
        let file = match link {
            Some(true) => match std::fs::canonicalize(given) {
                Ok(real) => real,
                Err(e) if e.kind() == io::ErrorKind::NotFound => {
                    return Err(OutputError::DanglingLink {
                        path: given.to_path_buf(),
                    });
                }
                Err(e) => return Err(io_error(given)(e)),
            },
            _ => given.to_path_buf(),
        };
        if link.is_none() {
            // a new file: known by its directory and name
            let dir = directory_of(&file);
            let dir = std::fs::canonicalize(&dir).map_err(io_error(given))?;
            let name = file.file_name().ok_or_else(|| OutputError::NotAFile {
                path: given.to_path_buf(),
                kind: "a directory",
            })?;
            return Ok(Target {
                given: given.to_path_buf(),
                identity: Identity::Path(dir.join(name)),
                file,
                existing: None,
            });
        }
        let metadata = std::fs::metadata(&file).map_err(io_error(given))?;
        if !metadata.file_type().is_file() {
            return Err(OutputError::NotAFile {
                path: given.to_path_buf(),
                kind: kind_of(&metadata),
            });
        }
        Ok(Target {
            given: given.to_path_buf(),
            identity: identity_of(&file, &metadata),
            file,
            existing: Some(metadata),
        })
    }
}

/// The directory a file is in (`.` for a bare name).
fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// One output written to its temporary file, waiting for [`Outputs::commit`].
#[derive(Debug)]
struct Staged {
    target: Target,
    temporary: PathBuf,
}

/// The outputs of one command: checked against its inputs and each other, written to
/// temporary files, and renamed over their targets together (module documentation).
#[derive(Debug, Default)]
pub struct Outputs {
    inputs: Vec<(PathBuf, Identity)>,
    staged: Vec<Staged>,
}

impl Outputs {
    /// The outputs of a command whose inputs are `inputs` (files that do not exist, and
    /// `-` for standard input, are passed over: they cannot be overwritten).
    ///
    /// # Errors
    ///
    /// None today; kept for inputs that cannot be identified.
    pub fn new<'p>(inputs: impl IntoIterator<Item = &'p Path>) -> Result<Outputs, OutputError> {
        let inputs = inputs
            .into_iter()
            .filter(|p| p.as_os_str() != "-")
            .filter_map(|p| {
                let metadata = std::fs::metadata(p).ok()?;
                Some((p.to_path_buf(), identity_of(p, &metadata)))
            })
            .collect();
        Ok(Outputs {
            inputs,
            staged: Vec::new(),
        })
    }

    /// Checks that `outputs` can be written (none an input, no two the same file, each a
    /// regular file or new, each in a directory the process can write — tried by
    /// [`check_writable_directory`]), before any work is done; leaves nothing.
    ///
    /// # Errors
    ///
    /// As [`Outputs::write`], for the first output that cannot be written.
    pub fn check<'p>(
        &self,
        outputs: impl IntoIterator<Item = &'p Path>,
    ) -> Result<(), OutputError> {
        let mut seen: Vec<Target> = Vec::new();
        for path in outputs {
            let target = self.checked_target(path, seen.iter())?;
            seen.push(target);
        }
        // each directory written into once: a read-only one is refused now, not after
        // the work
        let mut probed: Vec<PathBuf> = Vec::new();
        for target in &seen {
            let dir = directory_of(&target.file);
            if !probed.contains(&dir) {
                probe_directory(&dir).map_err(io_error(&target.given))?;
                probed.push(dir);
            }
        }
        Ok(())
    }

    fn checked_target<'t>(
        &self,
        path: &Path,
        earlier: impl Iterator<Item = &'t Target>,
    ) -> Result<Target, OutputError> {
        let target = Target::of(path)?;
        if let Some((input, _)) = self.inputs.iter().find(|(_, id)| *id == target.identity) {
            return Err(OutputError::SameAsInput {
                output: path.to_path_buf(),
                input: input.clone(),
            });
        }
        for other in earlier {
            if other.identity == target.identity {
                return Err(OutputError::SameOutput {
                    first: other.given.clone(),
                    second: path.to_path_buf(),
                });
            }
        }
        Ok(target)
    }

    /// Writes `bytes` as the output `path` (to its temporary file until
    /// [`Outputs::commit`]).
    ///
    /// # Errors
    ///
    /// [`OutputError::SameAsInput`], [`OutputError::SameOutput`],
    /// [`OutputError::NotAFile`], [`OutputError::DanglingLink`], or
    /// [`OutputError::Io`] when the temporary file cannot be created or written.
    pub fn write(&mut self, path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
        self.write_with(path, |w| w.write_all(bytes))
    }

    /// Writes the output `path` through `write` (to its temporary file until
    /// [`Outputs::commit`]).
    ///
    /// # Errors
    ///
    /// As [`Outputs::write`]; an error of `write` as [`OutputError::Io`].
    pub fn write_with(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    ) -> Result<(), OutputError> {
        let target = self.checked_target(path, self.staged.iter().map(|s| &s.target))?;
        let (file, temporary) = create_temporary(&target)?;
        let written = (|| {
            let mut buffered = io::BufWriter::new(&file);
            write(&mut buffered)?;
            buffered.flush()?;
            drop(buffered);
            file.sync_all()
        })();
        if let Err(source) = written {
            settle(&temporary, true);
            return Err(OutputError::Io {
                path: path.to_path_buf(),
                source,
            });
        }
        self.staged.push(Staged { target, temporary });
        Ok(())
    }

    /// Renames every output written over its target, in the order written; returns the
    /// paths as given.
    ///
    /// # Errors
    ///
    /// [`OutputError::Io`] when a rename fails (the outputs renamed before it stay).
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        let staged = std::mem::take(&mut self.staged);
        let mut written = Vec::with_capacity(staged.len());
        let mut rest = staged.into_iter();
        while let Some(s) = rest.next() {
            if let Err(source) = std::fs::rename(&s.temporary, &s.target.file) {
                settle(&s.temporary, true);
                for later in rest {
                    settle(&later.temporary, true);
                }
                return Err(OutputError::Io {
                    path: s.target.given,
                    source,
                });
            }
            settle(&s.temporary, false);
            sync_directory(&s.target.file);
            written.push(s.target.given);
        }
        Ok(written)
    }
}

impl Drop for Outputs {
    /// Outputs never committed leave nothing behind.
    fn drop(&mut self) {
        for s in &self.staged {
            settle(&s.temporary, true);
        }
    }
}

/// Writes one output file `path` whole or not at all (no inputs to check).
///
/// # Errors
///
/// As [`Outputs::write`] and [`Outputs::commit`].
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut outputs = Outputs::default();
    outputs.write(path, bytes)?;
    outputs.commit().map(|_| ())
}

/// Writes one output file `path` through `write`, whole or not at all.
///
/// # Errors
///
/// As [`Outputs::write_with`] and [`Outputs::commit`].
pub fn write_file_with(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> Result<(), OutputError> {
    let mut outputs = Outputs::default();
    outputs.write_with(path, write)?;
    outputs.commit().map(|_| ())
}

/// A new temporary file beside the target, created exclusively under an unpredictable
/// name, with the mode of the file it replaces.
fn create_temporary(target: &Target) -> Result<(File, PathBuf), OutputError> {
    let dir = directory_of(&target.file);
    let name = target
        .file
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut last = None;
    for _ in 0..NAME_ATTEMPTS {
        let temporary = dir.join(format!(
            ".{name}.{:016x}.polycal-tmp",
            rand::random::<u64>()
        ));
        let mut options = OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            // readable by its owner alone until it has the target's mode
            options.mode(0o600);
        }
        // registered as it is created, so that an interrupt at any moment removes it
        match create_registered(&options, &temporary) {
            Ok(file) => {
                if let Err(e) = set_mode(&file, target.existing.as_ref()) {
                    settle(&temporary, true);
                    return Err(io_error(&target.given)(e));
                }
                return Ok((file, temporary));
            }
            // someone else's file: not removed
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(io_error(&target.given)(e)),
        }
    }
    Err(io_error(&target.given)(last.unwrap_or_else(|| {
        io::Error::new(io::ErrorKind::AlreadyExists, "no free temporary name")
    })))
}

/// Checks that the process can create a file in the directory `dir`, by creating one
/// exclusively (`.polycal-probe.XXXXXXXXXXXXXXXX.polycal-tmp`) and removing it at once:
/// a directory the process may not write (its permissions, a read-only file system) is
/// refused before any work, and nothing is left.
///
/// # Errors
///
/// [`OutputError::Io`] naming `dir`, with the operating system's error (e.g. permission
/// denied).
pub fn check_writable_directory(dir: &Path) -> Result<(), OutputError> {
    probe_directory(dir).map_err(io_error(dir))
}

/// Creates and removes a probe file in `dir` (see [`check_writable_directory`]).
fn probe_directory(dir: &Path) -> io::Result<()> {
    let mut last = None;
    for _ in 0..NAME_ATTEMPTS {
        let probe = dir.join(format!(
            ".polycal-probe.{:016x}.polycal-tmp",
            rand::random::<u64>()
        ));
        let mut options = OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        {
            use std::os::unix::fs::OpenOptionsExt;
            options.mode(0o600);
        }
        match create_registered(&options, &probe) {
            Ok(file) => {
                drop(file);
                settle(&probe, true);
                return Ok(());
            }
            // someone else's file: not removed
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| io::Error::new(io::ErrorKind::AlreadyExists, "no free probe name")))
}

/// The replaced file's mode; a new file's, that of any file the process creates.
#[cfg(unix)]
fn set_mode(file: &File, existing: Option<&Metadata>) -> io::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    let mode = match existing {
        Some(m) => m.permissions().mode() & 0o7777,
        None => 0o666 & !current_umask(),
    };
    file.set_permissions(std::fs::Permissions::from_mode(mode))
}

#[cfg(not(unix))]
fn set_mode(file: &File, existing: Option<&Metadata>) -> io::Result<()> {
    match existing {
        Some(m) => file.set_permissions(m.permissions()),
        None => Ok(()),
    }
}

/// The process's umask, read from `/proc/self/status` (Linux); 0o022 where it cannot be
/// read.
#[cfg(unix)]
fn current_umask() -> u32 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            status
                .lines()
                .find_map(|l| l.strip_prefix("Umask:"))
                .and_then(|v| u32::from_str_radix(v.trim(), 8).ok())
        })
        .unwrap_or(0o022)
}

/// Syncs the directory of `file` so that the rename survives a power cut (best effort).
fn sync_directory(file: &Path) {
    if let Ok(dir) = File::open(directory_of(file)) {
        let _ = dir.sync_all();
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("polycal-output-file-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch directory");
        dir
    }

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .expect("read_dir")
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".polycal-tmp"))
            .collect()
    }

    #[test]
    fn an_input_is_refused_by_any_name() {
        let dir = scratch("input");
        let input = dir.join("m.csv");
        std::fs::write(&input, "x").expect("write");
        let hard = dir.join("hard.csv");
        std::fs::hard_link(&input, &hard).expect("hard link");
        let outputs = Outputs::new([input.as_path()]).expect("outputs");
        for name in [input.clone(), hard, dir.join(".").join("m.csv")] {
            let e = outputs.check([name.as_path()]).expect_err("refused");
            assert!(matches!(e, OutputError::SameAsInput { .. }), "{e}");
        }
        assert_eq!(std::fs::read(&input).expect("read"), b"x");
    }

    #[test]
    fn two_outputs_of_one_file_are_refused_and_nothing_is_written() {
        let dir = scratch("twice");
        let mut outputs = Outputs::default();
        outputs.write(&dir.join("a.json"), b"1").expect("first");
        let e = outputs
            .write(&dir.join(".").join("a.json"), b"2")
            .expect_err("second");
        assert!(matches!(e, OutputError::SameOutput { .. }), "{e}");
        drop(outputs);
        assert!(!dir.join("a.json").exists());
        assert!(leftovers(&dir).is_empty());
    }

    #[test]
    fn a_check_leaves_nothing_behind() {
        let dir = scratch("check");
        let outputs = Outputs::default();
        outputs
            .check([dir.join("a.html").as_path(), dir.join("b.xml").as_path()])
            .expect("can be written");
        check_writable_directory(&dir).expect("writable");
        assert!(leftovers(&dir).is_empty());
        assert!(std::fs::read_dir(&dir).expect("read_dir").next().is_none());
    }

    #[test]
    fn the_mode_of_a_replaced_file_is_kept() {
        use std::os::unix::fs::PermissionsExt;
        let dir = scratch("mode");
        let path = dir.join("r.html");
        std::fs::write(&path, "old").expect("write");
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).expect("chmod");
        write_file(&path, b"new").expect("written");
        let mode = std::fs::metadata(&path)
            .expect("metadata")
            .permissions()
            .mode()
            & 0o777;
        assert_eq!(mode, 0o600);
        assert_eq!(std::fs::read(&path).expect("read"), b"new");
    }

    #[test]
    fn a_fifo_and_a_directory_are_refused() {
        let dir = scratch("kinds");
        let fifo = dir.join("fifo");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            let e = write_file(&fifo, b"x").expect_err("fifo");
            assert!(e.to_string().contains("is a FIFO"), "{e}");
        }
        let e = write_file(&dir, b"x").expect_err("directory");
        assert!(e.to_string().contains("is a directory"), "{e}");
        let e = write_file(Path::new("/dev/null"), b"x").expect_err("device");
        assert!(e.to_string().contains("is a character device"), "{e}");
    }

    #[test]
    fn a_link_is_followed_and_kept_and_a_dangling_one_refused() {
        let dir = scratch("link");
        let real = dir.join("real.html");
        std::fs::write(&real, "old").expect("write");
        let link = dir.join("latest.html");
        std::os::unix::fs::symlink(&real, &link).expect("symlink");
        write_file(&link, b"new").expect("written");
        assert!(
            std::fs::symlink_metadata(&link)
                .expect("link")
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&real).expect("read"), b"new");
        let dangling = dir.join("nothing.html");
        std::os::unix::fs::symlink(dir.join("absent"), &dangling).expect("symlink");
        let e = write_file(&dangling, b"x").expect_err("dangling");
        assert!(matches!(e, OutputError::DanglingLink { .. }), "{e}");
        assert!(!dir.join("absent").exists());
    }

    #[test]
    fn a_failed_writer_leaves_the_old_file_and_no_temporary() {
        let dir = scratch("fail");
        let path = dir.join("out.csv");
        std::fs::write(&path, "old").expect("write");
        let e = write_file_with(&path, |w| {
            w.write_all(b"half")?;
            Err(io::Error::other("disk full"))
        })
        .expect_err("failed");
        assert!(e.to_string().contains("disk full"), "{e}");
        assert_eq!(std::fs::read(&path).expect("read"), b"old");
        assert!(leftovers(&dir).is_empty());
    }
}
