//! The run directory's files on a disk that can fill up: lines appended whole or not at
//! all ([`LineFile`]), and a byte budget that makes a full disk testable
//! ([`WriteBudget`]).
//!
//! A write to a full disk fails after writing what still fits, which leaves the start of
//! a line at the end of the file. A [`LineFile`] truncates the file back to its last
//! whole line when a write fails, so that the measurement file and the traffic log end on
//! whole lines whatever happens to the disk (docs/FORMAT.md §7.3).

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

/// How many more bytes the files of a run directory may take before a write fails as it
/// does on a full disk (`No space left on device`, [`io::ErrorKind::StorageFull`]),
/// after writing the bytes that still fit.
///
/// For tests of a full disk: the run directory ([`crate::lab::run::RunDir::open_with_budget`])
/// and the traffic log ([`crate::lab::traffic::TrafficLog::append_to_with_budget`]) write
/// through one. Cloning shares the budget. [`WriteBudget::unlimited`] (the default) is the
/// disk as it is.
///
/// ```
/// use polycal::lab::WriteBudget;
///
/// // 100 bytes more for the traffic log; the other files are not limited.
/// let budget = WriteBudget::for_file("traffic.jsonl", 100);
/// assert_eq!(budget.left_bytes("traffic.jsonl"), Some(100));
/// assert_eq!(budget.left_bytes("manifest.json"), None);
/// assert_eq!(WriteBudget::unlimited().left_bytes("traffic.jsonl"), None);
/// ```
#[derive(Debug, Clone, Default)]
pub struct WriteBudget {
    limit: Option<Arc<Mutex<Limit>>>,
}

#[derive(Debug)]
struct Limit {
    left_bytes: u64,
    /// The one file the limit applies to, or every file.
    file: Option<String>,
}

impl WriteBudget {
    /// No limit: the disk as it is.
    pub fn unlimited() -> WriteBudget {
        WriteBudget::default()
    }

    /// `bytes` more bytes, shared by every file written through this budget, as on a
    /// disk with that much space left.
    pub fn shared(bytes: u64) -> WriteBudget {
        WriteBudget::limited(bytes, None)
    }

    /// `bytes` more bytes for the file named `file_name` (e.g. `traffic.jsonl`; a file
    /// replaced through a temporary file counts under its own name); other files are not
    /// limited.
    pub fn for_file(file_name: &str, bytes: u64) -> WriteBudget {
        WriteBudget::limited(bytes, Some(file_name.to_string()))
    }

    fn limited(bytes: u64, file: Option<String>) -> WriteBudget {
        WriteBudget {
            limit: Some(Arc::new(Mutex::new(Limit {
                left_bytes: bytes,
                file,
            }))),
        }
    }

    /// The bytes the file named `file_name` may still take, or `None` if it is not
    /// limited.
    pub fn left_bytes(&self, file_name: &str) -> Option<u64> {
        let limit = self.limit.as_ref()?;
        let limit = limit.lock().unwrap_or_else(PoisonError::into_inner);
        limit
            .file
            .as_deref()
            .is_none_or(|f| f == file_name)
            .then_some(limit.left_bytes)
    }

    /// Takes up to `wanted` bytes for `file_name`: how many may be written now, or the
    /// error of a full disk when none may.
    fn take(&self, file_name: &str, wanted: usize) -> io::Result<usize> {
        let Some(limit) = &self.limit else {
            return Ok(wanted);
        };
        let mut limit = limit.lock().unwrap_or_else(PoisonError::into_inner);
        if limit.file.as_deref().is_some_and(|f| f != file_name) || wanted == 0 {
            return Ok(wanted);
        }
        if limit.left_bytes == 0 {
            return Err(disk_full());
        }
        let granted = usize::try_from(limit.left_bytes).map_or(wanted, |left| left.min(wanted));
        limit.left_bytes -= granted as u64;
        Ok(granted)
    }

    /// `inner` writing as the file `file_name` through this budget.
    pub(crate) fn writer<W: Write>(&self, file_name: &str, inner: W) -> Budgeted<W> {
        Budgeted {
            inner,
            file_name: file_name.to_string(),
            budget: self.clone(),
        }
    }
}

/// The error a write to a full disk gives.
fn disk_full() -> io::Error {
    #[cfg(unix)]
    {
        io::Error::from_raw_os_error(libc::ENOSPC)
    }
    #[cfg(not(unix))]
    {
        io::Error::from(io::ErrorKind::StorageFull)
    }
}

/// A writer whose bytes count against a [`WriteBudget`].
#[derive(Debug)]
pub(crate) struct Budgeted<W> {
    inner: W,
    file_name: String,
    budget: WriteBudget,
}

impl<W: Write> Write for Budgeted<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let granted = self.budget.take(&self.file_name, buf.len())?;
        self.inner.write_all(&buf[..granted])?;
        Ok(granted)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// A file of lines opened for appending, whose every line is written whole or not at
/// all: a write that fails (a full disk) is cut back to the last whole line.
///
/// Lines are written through [`Write`] (e.g. one `write_all` of a row) and then either
/// kept with [`LineFile::commit`] or taken back with [`LineFile::rollback`];
/// [`LineFile::append_line`] does both.
#[derive(Debug)]
pub(crate) struct LineFile {
    out: Budgeted<File>,
    path: PathBuf,
    /// Bytes in the file, as far as this writer knows.
    len_bytes: u64,
    /// Bytes up to the end of the last whole line.
    whole_len_bytes: u64,
}

impl LineFile {
    /// Opens `path` for appending: created if missing (`create_new`: created, and an
    /// error if it exists). The file is taken to end on a whole line.
    pub(crate) fn open(path: &Path, create_new: bool, budget: &WriteBudget) -> io::Result<Self> {
        let mut options = OpenOptions::new();
        options.append(true);
        if create_new {
            options.create_new(true);
        } else {
            options.create(true);
        }
        let file = options.open(path)?;
        let len_bytes = file.metadata()?.len();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(LineFile {
            out: budget.writer(&name, file),
            path: path.to_path_buf(),
            len_bytes,
            whole_len_bytes: len_bytes,
        })
    }

    /// The file.
    pub(crate) fn file(&self) -> &File {
        &self.out.inner
    }

    /// The path it was opened at.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// Takes note that the file was renamed to `path`.
    pub(crate) fn renamed(&mut self, path: PathBuf) {
        self.path = path;
    }

    /// Puts its data on disk (`fsync` of the data).
    pub(crate) fn sync_data(&self) -> io::Result<()> {
        self.file().sync_data()
    }

    /// Takes the file's length anew (after it was cut by another handle); it is taken
    /// to end on a whole line.
    pub(crate) fn reload_len(&mut self) -> io::Result<()> {
        self.len_bytes = self.file().metadata()?.len();
        self.whole_len_bytes = self.len_bytes;
        Ok(())
    }

    /// Keeps everything written so far: it ends on a whole line.
    pub(crate) fn commit(&mut self) {
        self.whole_len_bytes = self.len_bytes;
    }

    /// Cuts the file back to the last whole line (after a failed write).
    pub(crate) fn rollback(&mut self) -> io::Result<()> {
        self.len_bytes = self.whole_len_bytes;
        self.file().set_len(self.whole_len_bytes)?;
        self.sync_data()
    }

    /// Appends `line` (line feed included) with one `write_all`; if that fails, the file
    /// is cut back to its last whole line and the write's error returned.
    pub(crate) fn append_line(&mut self, line: &[u8]) -> io::Result<()> {
        match self.write_all(line) {
            Ok(()) => {
                self.commit();
                Ok(())
            }
            Err(e) => {
                // The write's error is the one to tell; a file that could not be cut back
                // ends on a cut line, which a resumed run removes.
                let _ = self.rollback();
                Err(e)
            }
        }
    }
}

impl Write for LineFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let written = self.out.write(buf)?;
        self.len_bytes += written as u64;
        Ok(written)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("polycal-disk-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_budget_grants_what_fits_then_fails_as_a_full_disk() {
        let budget = WriteBudget::shared(10);
        let mut out = budget.writer("a", Vec::new());
        assert_eq!(out.write(b"0123456").unwrap(), 7);
        assert_eq!(out.write(b"789abc").unwrap(), 3, "what still fits");
        let e = out.write(b"x").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        assert_eq!(out.inner, b"0123456789");
        assert_eq!(out.write(b"").unwrap(), 0, "nothing to write never fails");
        assert_eq!(budget.left_bytes("b"), Some(0), "shared by every file");

        let one = WriteBudget::for_file("a", 2);
        let mut other = one.writer("b", Vec::new());
        other.write_all(b"not limited").unwrap();
        assert_eq!(one.left_bytes("a"), Some(2));
    }

    #[test]
    fn a_failed_line_is_cut_back_to_the_last_whole_line() {
        let path = scratch("line").join("log");
        std::fs::write(&path, "before\n").unwrap();
        let budget = WriteBudget::for_file("log", 12);
        let mut file = LineFile::open(&path, false, &budget).unwrap();
        file.append_line(b"first\n").unwrap();
        let e = file.append_line(b"second line\n").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "before\nfirst\n");
        // The budget's 6 remaining bytes were spent on the cut line; nothing fits now.
        assert!(file.append_line(b"x\n").is_err());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "before\nfirst\n");
        assert!(LineFile::open(&path, true, &budget).is_err(), "create_new");
    }
}
