//! Who may write a run's file, and when an existing file may be replaced.
//!
//! A writing run holds a lock on its file: an open-file-description (OFD) write lock on the whole
//! file. HDF5's own file locking (`flock`) is switched off in the writer, so readers — `icefem
//! info`/`render`, h5py, ParaView — open a file while it is written and see its complete frames;
//! the OFD lock is a different kind of lock that HDF5 neither takes nor sees, and only tells one
//! run that another one writes the file.
//!
//! A new run never writes into an existing file: it writes a hidden file beside its target
//! (`.NAME.PID.partial`) and renames it onto the target once it has committed a frame after its
//! first step (or finishes), so a run that fails at its start leaves the old file and its
//! sidecars as they were. An existing target is replaced only when it is an icefem file that no
//! run is writing and the caller allows it (`--force`).

use std::os::fd::AsRawFd as _;
use std::path::{Path, PathBuf};

use super::hdf5_io::{check_hdf5_signature, check_icefem_layout, open_read};
use super::OutputError;

/// The write lock of a run on its file, held for as long as the value lives.
pub(super) struct RunLock {
    /// The descriptor the lock belongs to (an OFD lock lives with its open file description).
    _file: std::fs::File,
}

/// An OFD lock request (`F_WRLCK` or `F_UNLCK`) over the whole file.
fn whole_file(kind: libc::c_int) -> libc::flock {
    libc::flock {
        l_type: kind as libc::c_short,
        l_whence: libc::SEEK_SET as libc::c_short,
        l_start: 0,
        l_len: 0,
        l_pid: 0,
    }
}

fn io_error(path: &Path, context: &str, source: std::io::Error) -> OutputError {
    OutputError::Io {
        path: path.to_path_buf(),
        context: context.into(),
        source,
    }
}

impl RunLock {
    /// Takes the write lock on `path`; [`OutputError::InUse`] if another run holds it.
    pub(super) fn acquire(path: &Path) -> Result<Self, OutputError> {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .map_err(|e| io_error(path, "opening to lock it", e))?;
        let request = whole_file(libc::F_WRLCK);
        // SAFETY: `file` is an open descriptor and `request` a valid `flock` for F_OFD_SETLK.
        let status = unsafe { libc::fcntl(file.as_raw_fd(), libc::F_OFD_SETLK, &request) };
        if status == 0 {
            return Ok(Self { _file: file });
        }
        let error = std::io::Error::last_os_error();
        match error.raw_os_error() {
            Some(libc::EAGAIN) | Some(libc::EACCES) => Err(OutputError::InUse {
                path: path.to_path_buf(),
            }),
            _ => Err(io_error(path, "locking", error)),
        }
    }
}

/// Whether a run holds the write lock on `path` (false when it cannot be told).
pub(super) fn is_written(path: &Path) -> bool {
    let Ok(file) = std::fs::File::open(path) else {
        return false;
    };
    let mut request = whole_file(libc::F_WRLCK);
    // SAFETY: `file` is an open descriptor; F_OFD_GETLK fills `request` in.
    let status = unsafe { libc::fcntl(file.as_raw_fd(), libc::F_OFD_GETLK, &mut request) };
    status == 0 && request.l_type != libc::F_UNLCK as libc::c_short
}

/// Checks that a new run may write `target`: it does not exist, or it is an icefem file that no
/// run is writing and `replace` allows replacing it.
pub(super) fn check_target(target: &Path, replace: bool) -> Result<(), OutputError> {
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if target
        .file_name()
        .is_some_and(|n| n.to_string_lossy().contains(':'))
    {
        // XDMF separates file and dataset with ':'; the sidecars could not name the file.
        return Err(OutputError::InvalidInput {
            path: target.to_path_buf(),
            reason: "the file name contains ':', which the XDMF sidecar cannot reference".into(),
        });
    }
    if !dir.is_dir() {
        let missing = std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("directory {} does not exist", dir.display()),
        );
        return Err(io_error(target, "creating the output", missing));
    }
    let meta = match std::fs::metadata(target) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(io_error(target, "looking at the output path", e)),
    };
    let foreign = |reason: String| OutputError::Foreign {
        path: target.to_path_buf(),
        reason,
    };
    if !meta.is_file() {
        return Err(foreign("it is not a regular file".into()));
    }
    match check_hdf5_signature(target) {
        Err(OutputError::NotHdf5 { .. }) => return Err(foreign("it is not an HDF5 file".into())),
        other => other?,
    }
    if is_written(target) {
        return Err(OutputError::InUse {
            path: target.to_path_buf(),
        });
    }
    let file = open_read(target, "opening the existing output")?;
    match check_icefem_layout(target, &file) {
        Err(OutputError::NotIcefem { reason, .. }) => {
            return Err(foreign(format!(
                "an HDF5 file that is not icefem output: {reason}"
            )))
        }
        other => other?,
    }
    if !replace {
        return Err(OutputError::Exists {
            path: target.to_path_buf(),
        });
    }
    Ok(())
}

/// The hidden file a new run writes before it takes `target`'s place: same directory (so the
/// rename is atomic), named after the target and this process.
pub(super) fn partial_path(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    target.with_file_name(format!(".{name}.{}.partial", std::process::id()))
}

/// Removes the hidden files that killed runs left in `target`'s directory: any
/// `.NAME.PID.partial` (whatever its target) whose process no longer exists and that no run
/// holds the lock of. A process that still exists may be a run about to take its place, so its
/// file stays even when unlocked. Best effort.
pub(super) fn remove_stale_partials(target: &Path) {
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = partial_owner(&file) else {
            continue;
        };
        if !process_exists(pid) && !is_written(&entry.path()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The process id in a hidden run file's name `.NAME.PID.partial`, if `file` is one.
fn partial_owner(file: &str) -> Option<libc::pid_t> {
    let stem = file.strip_prefix('.')?.strip_suffix(".partial")?;
    let (name, pid) = stem.rsplit_once('.')?;
    if name.is_empty() || !pid.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    pid.parse().ok().filter(|&p| p > 0)
}

/// Whether a process with id `pid` exists (signal 0 reaches it or is refused permission).
fn process_exists(pid: libc::pid_t) -> bool {
    // SAFETY: signal 0 only checks that the process exists; nothing is sent.
    let status = unsafe { libc::kill(pid, 0) };
    status == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Puts the finished-enough `partial` file in `target`'s place (atomically), unless a run has
/// started writing `target` meanwhile.
pub(super) fn take_place(partial: &Path, target: &Path) -> Result<(), OutputError> {
    if is_written(target) {
        return Err(OutputError::InUse {
            path: target.to_path_buf(),
        });
    }
    std::fs::rename(partial, target)
        .map_err(|e| io_error(target, "moving the new run's file into place", e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hidden_run_files_name_their_process() {
        assert_eq!(partial_owner(".out.h5.1234.partial"), Some(1234));
        assert_eq!(partial_owner(".a.b.usda.77.partial"), Some(77));
        assert_eq!(partial_owner("out.h5.1234.partial"), None);
        assert_eq!(partial_owner(".out.h5.12a4.partial"), None);
        assert_eq!(partial_owner("..1234.partial"), None);
        assert_eq!(partial_owner(".out.h5.0.partial"), None);
        assert!(process_exists(std::process::id() as libc::pid_t));
    }
}
