//! The dataset archives (`NAME.tar.zst` beside `SHA256SUMS`), read in place: each archive is
//! checked against its sum, then streamed through zstd and tar into memory. Nothing is
//! unpacked on disk, so there is no half-unpacked cache to guard against.

use std::collections::HashSet;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use anyhow::{anyhow, bail, Context, Result};
use sha2::{Digest, Sha256};

/// Where the datasets live: `--data DIR`, else `$GLOCAL_DATA`, else `../shared/data`.
#[derive(Clone, Debug)]
pub struct DataRoot {
    pub dir: PathBuf,
}

impl DataRoot {
    pub fn resolve(explicit: Option<&Path>) -> Self {
        let dir = explicit
            .map(Path::to_path_buf)
            .or_else(|| std::env::var_os("GLOCAL_DATA").map(PathBuf::from))
            .unwrap_or_else(Self::default_dir);
        Self { dir }
    }

    /// `../shared/data` from the working directory, or beside the crate when run elsewhere.
    fn default_dir() -> PathBuf {
        let here = PathBuf::from("../shared/data");
        if here.exists() {
            return here;
        }
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data")
    }

    pub fn file(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Every regular file of `NAME.tar.zst` whose path `keep` accepts, as (path, bytes).
    pub fn read_archive(&self, name: &str, keep: impl Fn(&str) -> bool) -> Result<Vec<(String, Vec<u8>)>> {
        let path = self.file(&format!("{name}.tar.zst"));
        let bytes = std::fs::read(&path).with_context(|| {
            format!("dataset archive {} is missing or unreadable (data folder: {}; set --data or GLOCAL_DATA)", path.display(), self.dir.display())
        })?;
        self.verify(name, &path, &bytes)?;
        let decoder = zstd::stream::read::Decoder::new(bytes.as_slice())
            .with_context(|| format!("{} is not a zstd archive", path.display()))?;
        let mut tar = tar::Archive::new(decoder);
        let mut out = Vec::new();
        let entries = tar.entries().with_context(|| format!("{} is not a tar archive", path.display()))?;
        for entry in entries {
            let mut entry = entry.with_context(|| format!("{} is corrupt", path.display()))?;
            if !entry.header().entry_type().is_file() {
                continue;
            }
            let entry_path = entry.path()?.to_string_lossy().into_owned();
            if !keep(&entry_path) {
                continue;
            }
            let mut buf = Vec::with_capacity(entry.size() as usize);
            entry.read_to_end(&mut buf).with_context(|| format!("{}: entry {entry_path} is truncated", path.display()))?;
            out.push((entry_path, buf));
        }
        Ok(out)
    }

    /// Checks an archive against `SHA256SUMS` once per process.
    fn verify(&self, name: &str, path: &Path, bytes: &[u8]) -> Result<()> {
        static VERIFIED: OnceLock<Mutex<HashSet<PathBuf>>> = OnceLock::new();
        let verified = VERIFIED.get_or_init(Default::default);
        if verified.lock().map_err(|_| anyhow!("checksum cache poisoned"))?.contains(path) {
            return Ok(());
        }
        let sums_path = self.file("SHA256SUMS");
        let sums = std::fs::read_to_string(&sums_path).with_context(|| format!("cannot read {}", sums_path.display()))?;
        let file_name = format!("{name}.tar.zst");
        let expected = sums
            .lines()
            .find_map(|l| {
                let (sum, file) = l.split_once(char::is_whitespace)?;
                (file.trim().trim_start_matches('*') == file_name).then(|| sum.to_lowercase())
            })
            .ok_or_else(|| anyhow!("{} has no line for {file_name}", sums_path.display()))?;
        let actual: String = Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect();
        if actual != expected {
            bail!("{} is corrupt: its SHA-256 is {actual}, SHA256SUMS says {expected}", path.display());
        }
        verified.lock().map_err(|_| anyhow!("checksum cache poisoned"))?.insert(path.to_path_buf());
        Ok(())
    }
}
