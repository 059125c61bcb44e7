//! Every file glocal writes goes through here: a reader never sees a half-written file, a
//! failed or killed write leaves whatever was there before untouched, and nothing but a
//! regular file (or a path that does not exist yet) is ever replaced.
//!
//! A write streams into a temporary sibling named `.NAME.glocal-tmp-PID-N`, fsyncs it,
//! renames it over `NAME` and fsyncs the folder, so the rename itself survives a power cut.
//! The temporary name says whose it is: a later write of the same file removes the leftovers
//! of a process that no longer runs (a kill during a long export), and nothing else.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{bail, Context, Result};

/// What every temporary file of ours has in its name.
pub const TEMP_MARK: &str = ".glocal-tmp-";

/// A file being written: call [`AtomicFile::commit`] to put it in place; dropped without a
/// commit, it removes its temporary file and the target stays as it was.
pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `path` after checking it may be replaced (see [`check_output`]).
    pub fn create(path: &Path) -> Result<Self> {
        let target = resolve_output(path)?;
        let dir = folder_of(&target);
        remove_stale_temps(&target);
        let temp = dir.join(temp_name(&target));
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .with_context(|| format!("cannot write {}: folder {} is not writable or does not exist", path.display(), dir.display()))?;
        Ok(Self { target, temp, writer: Some(BufWriter::new(file)) })
    }

    pub fn writer(&mut self) -> &mut impl Write {
        self.writer.as_mut().expect("an uncommitted file has its writer")
    }

    /// Flushes, fsyncs, renames over the target and fsyncs the folder.
    pub fn commit(mut self) -> Result<()> {
        let name = self.target.display().to_string();
        let file = self.writer.take().expect("committed once").into_inner().map_err(|e| e.into_error()).with_context(|| format!("cannot write {name}"))?;
        file.sync_all().with_context(|| format!("cannot write {name}: the disk refused to sync it"))?;
        // Temporary files are created private; a written file should be as readable as any other.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            file.set_permissions(std::fs::Permissions::from_mode(0o644)).ok();
        }
        drop(file);
        std::fs::rename(&self.temp, &self.target).with_context(|| format!("cannot replace {name}"))?;
        // Renamed: nothing left for Drop to clean.
        self.temp = PathBuf::new();
        sync_folder(folder_of(&self.target));
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.temp.as_os_str().is_empty() {
            self.writer.take();
            let _ = std::fs::remove_file(&self.temp);
        }
    }
}

/// Writes `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Streams `fill`'s output to `path` atomically.
pub fn write_atomic_with(path: &Path, fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    fill(file.writer()).with_context(|| format!("cannot write {}", path.display()))?;
    file.commit()
}

/// Moves the file `path` to `kept`, a new name in the same folder (a file that could not be
/// read, kept for the user instead of being overwritten by the next write), and fsyncs the
/// folder so the move survives a power cut. A file already at `kept` is replaced.
pub fn move_aside(path: &Path, kept: &Path) -> Result<()> {
    std::fs::rename(path, kept).with_context(|| format!("cannot move {} aside", path.display()))?;
    sync_folder(folder_of(kept));
    Ok(())
}

/// Refuses an output that is not a regular file (a folder, a FIFO, a device) and one that
/// is the same file as any of `inputs`. A symbolic link is written through to the file it
/// points at. Returns the path that will be replaced.
pub fn check_output(path: &Path, inputs: &[&Path]) -> Result<PathBuf> {
    let target = resolve_output(path)?;
    for input in inputs {
        if same_file(&target, input) {
            bail!("{}: refusing to overwrite the input {} with the output", path.display(), input.display());
        }
    }
    Ok(target)
}

/// Refuses an output whose extension does not name what is written (`expected` without
/// the dot, lower case), so `render --out take.bvh` cannot replace a take with a PNG.
pub fn check_extension(path: &Path, expected: &[&str]) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_lowercase).unwrap_or_default();
    if !expected.contains(&ext.as_str()) {
        let names: Vec<String> = expected.iter().map(|e| format!(".{e}")).collect();
        bail!("{}: this output is written as {}; give a file name ending in it", path.display(), names.join(" or "));
    }
    Ok(())
}

fn resolve_output(path: &Path) -> Result<PathBuf> {
    let name = path.display();
    match std::fs::symlink_metadata(path) {
        Err(_) => {
            if path.file_name().is_none() {
                bail!("{name}: not a file name");
            }
            Ok(path.to_path_buf())
        }
        Ok(meta) if meta.file_type().is_symlink() => {
            let real = std::fs::canonicalize(path).with_context(|| format!("{name} is a symbolic link to nothing; give a real file"))?;
            if !real.is_file() {
                bail!("{name} is a symbolic link to {}, which is not a regular file; refusing to replace it", real.display());
            }
            Ok(real)
        }
        Ok(meta) if meta.is_dir() => bail!("{name} is a folder; give a file name inside it"),
        Ok(meta) if !meta.is_file() => bail!("{name} is not a regular file (a device, FIFO or socket); refusing to replace it"),
        Ok(_) => Ok(path.to_path_buf()),
    }
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

fn file_name_of(path: &Path) -> String {
    path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}

fn temp_name(target: &Path) -> String {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    format!(".{}{TEMP_MARK}{}-{n}", file_name_of(target), std::process::id())
}

/// Removes `.NAME.glocal-tmp-PID-N` files beside `target` whose process is gone.
fn remove_stale_temps(target: &Path) {
    let prefix = format!(".{}{TEMP_MARK}", file_name_of(target));
    let Ok(entries) = std::fs::read_dir(folder_of(target)) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(&prefix) else { continue };
        let pid = rest.split('-').next().and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|pid| !process_alive(pid)) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Whether a process runs (Linux: its /proc entry). Elsewhere a leftover is kept, never a
/// live writer's file removed.
fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    if cfg!(target_os = "linux") {
        Path::new(&format!("/proc/{pid}")).exists()
    } else {
        true
    }
}

fn sync_folder(dir: &Path) {
    // Folders cannot be opened for syncing everywhere (Windows); there the rename stands alone.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// An exclusive lock on a folder for as long as this lives (a second `train` into the same
/// folder is refused instead of racing on its files).
pub struct FolderLock {
    _file: File,
}

impl FolderLock {
    pub fn acquire(dir: &Path) -> Result<Self> {
        let path = dir.join(".glocal.lock");
        let file = OpenOptions::new().create(true).truncate(false).write(true).open(&path).with_context(|| format!("cannot create {}", path.display()))?;
        match file.try_lock() {
            Ok(()) => Ok(Self { _file: file }),
            Err(std::fs::TryLockError::WouldBlock) => bail!("{} is in use by another glocal process (training into the same folder?)", dir.display()),
            Err(std::fs::TryLockError::Error(e)) => Err(e).with_context(|| format!("cannot lock {}", path.display())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_moved_aside_keeps_its_bytes_and_frees_its_name() {
        let dir = tempfile::tempdir().unwrap();
        let (path, kept) = (dir.path().join("autosave.json"), dir.path().join("autosave.broken-1.json"));
        std::fs::write(&path, b"{broken").unwrap();
        move_aside(&path, &kept).unwrap();
        assert!(!path.exists());
        assert_eq!(std::fs::read(&kept).unwrap(), b"{broken");
        let e = move_aside(&path, &kept).unwrap_err();
        assert!(format!("{e:#}").starts_with(&format!("cannot move {} aside", path.display())), "{e:#}");
    }
}
