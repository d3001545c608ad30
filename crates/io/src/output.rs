//! Output files that are never lost: checked before any work, written
//! through a temporary file and renamed into place.
//!
//! * [`check`] runs before the computation: the output must not be one of
//!   the inputs (compared after resolving links, and on Unix also by device
//!   and inode, so hard links are caught too), must not be a directory or a
//!   read-only file, and its directory must exist and accept a new file
//!   (probed by creating and removing the temporary file).
//! * [`write_atomically`] writes into `.NAME.tmp-PID` in the output's own
//!   directory, flushes and syncs it, then renames it onto the output. On
//!   any failure the temporary file is removed and the previous contents of
//!   the output (if any) are untouched: there is never a partial file.
//!
//! * [`Temporary`] is that temporary file, for writers that fill it in
//!   parts (each MPI rank its rows): removed when dropped, renamed onto the
//!   output by [`Temporary::commit`].
//!
//! Every temporary file is recorded while it exists, so that a signal
//! handler can remove them ([`remove_temporaries`]) before the process
//! exits. A file size limit (`ulimit -f`) makes the write fail (when the
//! command ignores `SIGXFSZ`), so it is cleaned up like any other failure.
//! A process killed by a signal in the middle of a write (`SIGKILL`) may
//! leave the temporary file behind, never a truncated output.

use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::error::{FileError, Result};

/// Check, before any work, that `out` can be written (a `.csv` or `.npy`
/// name, not a directory, in a directory that takes a new file) and is none of
/// `inputs` (pairs of the option name and the file, e.g. `("--sources",
/// path)`).
pub fn check(out: &Path, inputs: &[(&'static str, &Path)]) -> Result<()> {
    let unusable = |reason: String| FileError::OutputUnusable {
        path: out.to_path_buf(),
        reason,
    };
    let existing = fs::metadata(out);
    if existing.as_ref().is_ok_and(|m| m.is_dir()) {
        return Err(unusable("is a directory (give a file name)".into()));
    }
    crate::Format::of_output(out)?;
    if let Ok(meta) = existing {
        for &(option, input) in inputs {
            if same_file(out, &meta, input) {
                return Err(FileError::OutputIsInput {
                    out: out.to_path_buf(),
                    option,
                    input: input.to_path_buf(),
                });
            }
        }
        if meta.permissions().readonly() {
            return Err(unusable("the file is read-only".into()));
        }
    }
    let target = resolve(out);
    let dir = directory_of(&target);
    match fs::metadata(&dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            return Err(unusable(format!("{} is not a directory", dir.display())));
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(unusable(format!(
                "directory {} does not exist",
                dir.display()
            )));
        }
        Err(e) => {
            return Err(unusable(format!(
                "directory {} cannot be used ({e})",
                dir.display()
            )));
        }
    }
    // Probe: the temporary file the write will use must be creatable.
    let (file, tmp) = create_temporary(&target).map_err(|e| {
        unusable(format!(
            "cannot create a file in directory {} ({e})",
            dir.display()
        ))
    })?;
    drop(file);
    let _ = fs::remove_file(&tmp);
    forget_temporary(&tmp);
    Ok(())
}

/// Write `path` through `fill`, atomically: a temporary file in the same
/// directory is filled, flushed, synced and renamed onto `path` (onto the
/// file a symbolic link points to, when `path` is one). On failure the
/// temporary file is removed, `path` is untouched, and the error names
/// `path` and the reason.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let mut tmp = Temporary::create(path)?;
    let failed = |source: std::io::Error| FileError::WriteFailed {
        path: path.to_path_buf(),
        source,
    };
    let file = tmp
        .file
        .take()
        .ok_or_else(|| failed(std::io::Error::other("no file")))?;
    let mut out = BufWriter::new(file);
    fill(&mut out).and_then(|()| out.flush()).map_err(failed)?;
    tmp.file = Some(out.into_inner().map_err(|e| failed(e.into_error()))?);
    tmp.commit()
}

/// The temporary file an output is written through: `.NAME.tmp-PID` in the
/// output's own directory. Dropped, it is removed; [`Temporary::commit`]
/// renames it onto the output.
#[derive(Debug)]
pub struct Temporary {
    /// The output it becomes (a link's target when the output is a link).
    target: PathBuf,
    /// The output as named (for messages).
    named: PathBuf,
    /// The temporary file.
    path: PathBuf,
    file: Option<File>,
    /// Renamed onto the output.
    committed: bool,
}

impl Temporary {
    /// Create the (empty) temporary file of the output `out`.
    pub fn create(out: &Path) -> Result<Temporary> {
        let target = resolve(out);
        let (file, path) = create_temporary(&target).map_err(|source| FileError::WriteFailed {
            path: out.to_path_buf(),
            source,
        })?;
        Ok(Temporary {
            target,
            named: out.to_path_buf(),
            path,
            file: Some(file),
            committed: false,
        })
    }

    /// The temporary file's path (other processes may write into it).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The open temporary file.
    pub fn file(&mut self) -> Result<&mut File> {
        match &mut self.file {
            Some(f) => Ok(f),
            None => Err(FileError::WriteFailed {
                path: self.named.clone(),
                source: std::io::Error::other("the temporary file is closed"),
            }),
        }
    }

    /// Sync the temporary file (keeping the permissions of a file being
    /// replaced) and rename it onto the output. On failure it is removed
    /// and the output is untouched.
    pub fn commit(mut self) -> Result<()> {
        let result = (|| {
            let file = match self.file.take() {
                Some(f) => f,
                None => OpenOptions::new().write(true).open(&self.path)?,
            };
            if let Ok(meta) = fs::metadata(&self.target) {
                file.set_permissions(meta.permissions())?;
            }
            file.sync_all()?;
            drop(file);
            fs::rename(&self.path, &self.target)
        })();
        self.committed = result.is_ok();
        // Dropped on return: the temporary file is removed unless renamed.
        result.map_err(|source| FileError::WriteFailed {
            path: self.named.clone(),
            source,
        })
    }
}

impl Drop for Temporary {
    fn drop(&mut self) {
        drop(self.file.take());
        if !self.committed {
            let _ = fs::remove_file(&self.path);
        }
        forget_temporary(&self.path);
    }
}

static TEMP_FILES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Remember a temporary file to remove on interrupt.
fn register_temporary(path: &Path) {
    if let Ok(mut files) = TEMP_FILES.lock() {
        files.push(path.to_path_buf());
    }
}

/// Forget a temporary file (renamed into place or removed).
fn forget_temporary(path: &Path) {
    if let Ok(mut files) = TEMP_FILES.lock() {
        files.retain(|p| p != path);
    }
}

/// Remove every temporary output file that exists now (for a signal
/// handler's thread, before it exits the process).
pub fn remove_temporaries() {
    // A poisoned lock still holds the list.
    let files = match TEMP_FILES.lock() {
        Ok(f) => f,
        Err(e) => e.into_inner(),
    };
    for f in files.iter() {
        let _ = fs::remove_file(f);
    }
}

/// `path`, or the file it links to when it is a symbolic link to an
/// existing file (so that the link is kept and its target replaced).
pub fn resolve(path: &Path) -> PathBuf {
    match fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => {
            fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
        }
        _ => path.to_path_buf(),
    }
}

/// The directory holding `path` (`.` for a bare file name).
fn directory_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Create a new, empty `.NAME.tmp-PID[-K]` next to `target`.
fn create_temporary(target: &Path) -> std::io::Result<(File, PathBuf)> {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    let dir = directory_of(target);
    let pid = std::process::id();
    let mut last = None;
    for k in 0..100 {
        let tmp_name = if k == 0 {
            format!(".{name}.tmp-{pid}")
        } else {
            format!(".{name}.tmp-{pid}-{k}")
        };
        let tmp = dir.join(tmp_name);
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => {
                register_temporary(&tmp);
                return Ok((f, tmp));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::other("no free temporary file name")))
}

/// Whether `input` is the file `out` (whose metadata is `out_meta`):
/// the same canonical path, or on Unix the same device and inode.
fn same_file(out: &Path, out_meta: &fs::Metadata, input: &Path) -> bool {
    if let (Ok(a), Ok(b)) = (fs::canonicalize(out), fs::canonicalize(input))
        && a == b
    {
        return true;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let Ok(m) = fs::metadata(input) {
            return m.dev() == out_meta.dev() && m.ino() == out_meta.ino();
        }
    }
    #[cfg(not(unix))]
    let _ = out_meta;
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("ferrofmm-output-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn failed_fill_leaves_nothing_and_keeps_the_old_file() {
        let dir = scratch("fail");
        let out = dir.join("o.csv");
        fs::write(&out, "old").unwrap();
        let e = write_atomically(&out, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("disk on fire"))
        })
        .unwrap_err();
        assert!(e.to_string().contains("disk on fire"), "{e}");
        assert_eq!(fs::read_to_string(&out).unwrap(), "old");
        assert_eq!(
            fs::read_dir(&dir).unwrap().count(),
            1,
            "temporary file left"
        );
        write_atomically(&out, |w| w.write_all(b"new")).unwrap();
        assert_eq!(fs::read_to_string(&out).unwrap(), "new");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn same_file_through_links() {
        let dir = scratch("links");
        let a = dir.join("a.npy");
        fs::write(&a, "x").unwrap();
        let meta = fs::metadata(&a).unwrap();
        assert!(same_file(&a, &meta, &dir.join(".").join("a.npy")));
        #[cfg(unix)]
        {
            let hard = dir.join("hard.npy");
            fs::hard_link(&a, &hard).unwrap();
            let hm = fs::metadata(&hard).unwrap();
            assert!(same_file(&hard, &hm, &a));
        }
        let b = dir.join("b.npy");
        fs::write(&b, "x").unwrap();
        assert!(!same_file(&a, &meta, &b));
        fs::remove_dir_all(&dir).unwrap();
    }
}
