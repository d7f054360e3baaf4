//! Persistence of acknowledged scene updates.
//!
//! Store: one JSON file per scene, `<data>/scenes/<name>.json` holding
//! `{"name", "revision", "scene"}`, replaced atomically on every update: the new
//! content is written to a temporary file in the same directory, `fsync`ed,
//! renamed over the old file, and the directory is `fsync`ed. A reply to `apply` is
//! sent only after that, so an acknowledged update survives `kill -9` (the rename is
//! atomic: after a crash either the old or the new file is there, never a torn
//! one). Scenes are small (kilobytes) and updates are infrequent next to planning,
//! so a file per scene is simpler and as durable as an embedded database here.

use super::proto::EmbeddedJson;
use serde::{Deserialize, Serialize};
use std::fs::{self, File};
use std::io::Write;
use std::path::{Path, PathBuf};

/// One persisted scene.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StoredScene {
    /// Name.
    pub name: String,
    /// Revision.
    pub revision: u64,
    /// The scene file (format v1).
    pub scene: serde_json::Value,
}

/// The scene store under a data directory.
#[derive(Clone, Debug)]
pub struct Store {
    dir: PathBuf,
}

impl Store {
    /// Opens (creating) `<data>/scenes`.
    pub fn open(data: &Path) -> std::io::Result<Store> {
        let dir = data.join("scenes");
        fs::create_dir_all(&dir)?;
        Ok(Store { dir })
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{name}.json"))
    }

    /// Atomically replaces the stored scene, durably.
    pub fn save(&self, name: &str, revision: u64, scene: &serde_json::Value) -> std::io::Result<()> {
        let rec = StoredScene { name: name.to_string(), revision, scene: scene.clone() };
        let tmp = self.dir.join(format!(".{name}.json.tmp"));
        {
            let mut f = File::create(&tmp)?;
            f.write_all(&serde_json::to_vec(&rec).map_err(std::io::Error::other)?)?;
            f.sync_all()?;
        }
        fs::rename(&tmp, self.path(name))?;
        File::open(&self.dir)?.sync_all()
    }

    /// Removes a stored scene, durably.
    pub fn remove(&self, name: &str) -> std::io::Result<()> {
        match fs::remove_file(self.path(name)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
            _ => {}
        }
        File::open(&self.dir)?.sync_all()
    }

    /// Every stored scene (unreadable files are reported, not fatal).
    pub fn load_all(&self) -> (Vec<StoredScene>, Vec<String>) {
        let mut ok = Vec::new();
        let mut bad = Vec::new();
        let Ok(rd) = fs::read_dir(&self.dir) else { return (ok, bad) };
        for e in rd.flatten() {
            let p = e.path();
            if p.extension().is_none_or(|x| x != "json")
                || p.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.'))
            {
                continue;
            }
            match fs::read(&p)
                .map_err(|e| e.to_string())
                .and_then(|b| serde_json::from_slice::<StoredScene>(&b).map_err(|e| e.to_string()))
            {
                Ok(s) => ok.push(s),
                Err(e) => bad.push(format!("{}: {e}", p.display())),
            }
        }
        (ok, bad)
    }
}

/// Convenience for replies.
pub fn embedded(v: &serde_json::Value) -> EmbeddedJson {
    EmbeddedJson(v.clone())
}
