//! Where an export writes, and when what is there may be replaced.
//!
//! USD is one file (`RUN.usda` beside the run by default); OBJ, PLY and VTU write numbered files
//! into a folder (`RUN_export/` by default, created if missing), named after the run so that
//! exports of several formats, or of several runs, share a folder: `RUN_000000.obj`,
//! `RUN_ice_000000.ply`, `RUN_cracks_000000.vtu`, `RUN.pvd`. An export whose files exist is
//! an error unless forced; forced, it replaces them and removes the numbered files of the same
//! run and format that it does not write (a longer export before), and nothing else.
//! A `.usda` is replaced only if it is a USDA file.

use std::path::{Path, PathBuf};

use super::{ExportError, ExportFormat};

/// The files an export may write or replace.
#[derive(Clone, Debug)]
pub(super) struct Target {
    /// The folder the files go to.
    pub dir: PathBuf,
    /// The run's file name without extension: the files' common prefix.
    pub stem: String,
    format: ExportFormat,
}

impl Target {
    /// The target of exporting `run` in `format` to `output` (default beside `run`).
    pub fn new(run: &Path, format: ExportFormat, output: Option<&Path>) -> Self {
        let stem = run.file_stem().unwrap_or_default().to_string_lossy();
        let beside = |suffix: &str| run.with_file_name(format!("{stem}{suffix}"));
        let (dir, stem) = match (format, output) {
            (ExportFormat::Usd, Some(file)) => {
                let stem = file.file_stem().unwrap_or_default().to_string_lossy();
                (parent(file), stem.into_owned())
            }
            (ExportFormat::Usd, None) => (parent(run), stem.into_owned()),
            (_, Some(dir)) => (dir.to_path_buf(), stem.into_owned()),
            (_, None) => (beside("_export"), stem.into_owned()),
        };
        Target { dir, stem, format }
    }

    /// The USD stage's path.
    pub fn usd_file(&self) -> PathBuf {
        self.dir.join(format!("{}.usda", self.stem))
    }

    /// The file of `object` (`None` for a file holding both) of exported frame `number`.
    pub fn frame_file(&self, object: Option<&str>, number: usize) -> PathBuf {
        let ext = self.format.extension();
        match object {
            Some(object) => self
                .dir
                .join(format!("{}_{object}_{number:06}.{ext}", self.stem)),
            None => self.dir.join(format!("{}_{number:06}.{ext}", self.stem)),
        }
    }

    /// What the summary names as the output: the stage or the folder.
    pub fn output(&self) -> PathBuf {
        match self.format {
            ExportFormat::Usd => self.usd_file(),
            _ => self.dir.clone(),
        }
    }

    /// Checks that the export may write `files` (every file it writes): none exists, or
    /// `force`; forced, removes this run's numbered files of the format not among `files`.
    /// Creates the folder (not its parents) if missing.
    pub fn prepare(&self, files: &[PathBuf], force: bool) -> Result<(), ExportError> {
        let io = |path: &Path, context: &str| {
            let context = context.to_string();
            let path = path.to_path_buf();
            move |source| ExportError::Io {
                path,
                context,
                source,
            }
        };
        if self.format == ExportFormat::Usd {
            let file = self.usd_file();
            return match std::fs::symlink_metadata(&file) {
                Err(_) => Ok(()),
                Ok(_) if !force => Err(ExportError::Exists { path: file }),
                Ok(meta) if meta.is_file() && is_usda(&file) => Ok(()),
                Ok(_) => Err(ExportError::Foreign {
                    path: file,
                    reason: "it is not a USDA file".into(),
                }),
            };
        }
        match std::fs::metadata(&self.dir) {
            Ok(meta) if meta.is_dir() => {}
            Ok(_) => {
                return Err(ExportError::Foreign {
                    path: self.dir.clone(),
                    reason: "it is not a folder".into(),
                })
            }
            Err(_) => {
                std::fs::create_dir(&self.dir).map_err(io(&self.dir, "creating the folder"))?;
                return Ok(());
            }
        }
        let mut ours: Vec<PathBuf> = std::fs::read_dir(&self.dir)
            .map_err(io(&self.dir, "listing the folder"))?
            .filter_map(|entry| entry.ok().map(|e| e.path()))
            .filter(|p| self.is_ours(p))
            .collect();
        ours.sort();
        if let Some(first) = ours.first() {
            if !force {
                return Err(ExportError::Exists {
                    path: first.clone(),
                });
            }
        }
        for stale in ours.iter().filter(|p| !files.contains(p)) {
            std::fs::remove_file(stale).map_err(io(stale, "removing an earlier export's file"))?;
        }
        Ok(())
    }

    /// Whether `path` is a file this run's export in this format writes (any frame count).
    fn is_ours(&self, path: &Path) -> bool {
        let Some(name) = path.file_name().map(|n| n.to_string_lossy()) else {
            return false;
        };
        if self.format == ExportFormat::Vtu && *name == format!("{}.pvd", self.stem) {
            return true;
        }
        let Some(rest) = name
            .strip_prefix(self.stem.as_str())
            .and_then(|r| r.strip_prefix('_'))
            .and_then(|r| r.strip_suffix(self.format.extension()))
            .and_then(|r| r.strip_suffix('.'))
        else {
            return false;
        };
        let number = match self.format {
            ExportFormat::Obj => rest,
            _ => match rest.split_once('_') {
                Some(("ice" | "cracks" | "obstacles", number)) => number,
                _ => return false,
            },
        };
        number.len() >= 6 && number.bytes().all(|b| b.is_ascii_digit())
    }
}

/// The folder of `file` (empty for a bare name: the working directory).
fn parent(file: &Path) -> PathBuf {
    file.parent().map(Path::to_path_buf).unwrap_or_default()
}

/// Whether `file` starts like a USD text stage.
fn is_usda(file: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 5];
    std::fs::File::open(file)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && &head == b"#usda"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbered_files_of_the_run_and_format_are_ours_and_nothing_else() {
        let target = Target::new(Path::new("runs/bar.h5"), ExportFormat::Ply, None);
        assert_eq!(target.dir, Path::new("runs/bar_export"));
        let ours = |name: &str| target.is_ours(&target.dir.join(name));
        assert!(ours("bar_ice_000000.ply") && ours("bar_cracks_1234567.ply"));
        for other in [
            "bar_ice_00000.ply",
            "bar_000000.ply",
            "bar_rock_000000.ply",
            "bar_ice_000000.vtu",
            "barn_ice_000000.ply",
            "notes.txt",
        ] {
            assert!(!ours(other), "{other}");
        }
        let obj = Target::new(Path::new("bar.h5"), ExportFormat::Obj, None);
        assert!(obj.is_ours(&obj.frame_file(None, 7)));
        let vtu = Target::new(Path::new("bar.h5"), ExportFormat::Vtu, None);
        assert!(vtu.is_ours(&vtu.dir.join("bar.pvd")));
        let usd = Target::new(Path::new("runs/bar.h5"), ExportFormat::Usd, None);
        assert_eq!(usd.usd_file(), Path::new("runs/bar.usda"));
    }
}
