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
//!
//! Revisions never repeat for a name: a deleted scene leaves a *tombstone* (the same
//! file with `"deleted": true` and its last revision), and a file that cannot be read
//! is moved to `<data>/quarantine/` and reported; a scene of that name created again
//! starts above every revision of earlier runs, through the store's *epoch* (the
//! number of times the data directory was opened, in `<data>/epoch`).

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
    /// The scene file (format v1); `null` in a tombstone.
    pub scene: serde_json::Value,
    /// A tombstone: the scene was deleted at `revision`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub deleted: bool,
}

/// What [`Store::load_all`] found.
#[derive(Debug, Default)]
pub struct Loaded {
    /// Live scenes.
    pub scenes: Vec<StoredScene>,
    /// Deleted scenes: (name, last revision).
    pub tombstones: Vec<(String, u64)>,
    /// Names whose file could not be read (now in `<data>/quarantine/`), with why.
    pub quarantined: Vec<(String, String)>,
}

/// The scene store under a data directory.
#[derive(Clone, Debug)]
pub struct Store {
    dir: PathBuf,
    quarantine: PathBuf,
    epoch: u64,
    id: u64,
}

impl Store {
    /// Opens (creating) `<data>/scenes`, and starts a new epoch (durably).
    pub fn open(data: &Path) -> std::io::Result<Store> {
        let dir = data.join("scenes");
        fs::create_dir_all(&dir)?;
        let epoch_file = data.join("epoch");
        let epoch = match fs::read_to_string(&epoch_file) {
            Ok(s) => {
                s.trim().parse::<u64>().map_err(|e| {
                    std::io::Error::new(std::io::ErrorKind::InvalidData, format!("{}: {e}", epoch_file.display()))
                })? + 1
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => 1,
            Err(e) => return Err(e),
        };
        let tmp = data.join(".epoch.tmp");
        {
            let mut f = File::create(&tmp)?;
            f.write_all(epoch.to_string().as_bytes())?;
            f.sync_all()?;
        }
        fs::rename(&tmp, &epoch_file)?;
        // the data directory's identity: made once, kept for its life (a replica that
        // sees its primary's identity change resynchronises in full)
        let id_file = data.join("id");
        let id = match fs::read_to_string(&id_file) {
            Ok(s) => s.trim().parse::<u64>().map_err(|e| {
                std::io::Error::new(std::io::ErrorKind::InvalidData, format!("{}: {e}", id_file.display()))
            })?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                let id: u64 = rand::random();
                let tmp = data.join(".id.tmp");
                {
                    let mut f = File::create(&tmp)?;
                    f.write_all(id.to_string().as_bytes())?;
                    f.sync_all()?;
                }
                fs::rename(&tmp, &id_file)?;
                id
            }
            Err(e) => return Err(e),
        };
        File::open(data)?.sync_all()?;
        Ok(Store { dir, quarantine: data.join("quarantine"), epoch, id })
    }

    /// The data directory's identity (random, made when the directory was created).
    pub fn id(&self) -> u64 {
        self.id
    }

    /// This run's epoch (1 for a new data directory, one more at every start).
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(format!("{name}.json"))
    }

    /// Atomically replaces the stored scene, durably.
    pub fn save(&self, name: &str, revision: u64, scene: &serde_json::Value) -> std::io::Result<()> {
        self.write(&StoredScene { name: name.to_string(), revision, scene: scene.clone(), deleted: false })
    }

    fn write(&self, rec: &StoredScene) -> std::io::Result<()> {
        let name = &rec.name;
        let tmp = self.dir.join(format!(".{name}.json.tmp"));
        {
            let mut f = File::create(&tmp)?;
            f.write_all(&serde_json::to_vec(rec).map_err(std::io::Error::other)?)?;
            f.sync_all()?;
        }
        fs::rename(&tmp, self.path(name))?;
        File::open(&self.dir)?.sync_all()
    }

    /// Deletes a stored scene, durably, leaving a tombstone with its last revision.
    pub fn remove(&self, name: &str, revision: u64) -> std::io::Result<()> {
        self.write(&StoredScene { name: name.to_string(), revision, scene: serde_json::Value::Null, deleted: true })
    }

    /// Every stored scene and tombstone. A file that cannot be read or parsed is
    /// moved to `<data>/quarantine/` (kept for inspection, never loaded again) and
    /// reported.
    pub fn load_all(&self) -> Loaded {
        let mut out = Loaded::default();
        let Ok(rd) = fs::read_dir(&self.dir) else { return out };
        for e in rd.flatten() {
            let p = e.path();
            let Some(file) = p.file_name().map(|n| n.to_string_lossy().to_string()) else { continue };
            let Some(stem) = file.strip_suffix(".json").filter(|_| !file.starts_with('.')) else { continue };
            let read = fs::read(&p)
                .map_err(|e| e.to_string())
                .and_then(|b| serde_json::from_slice::<StoredScene>(&b).map_err(|e| e.to_string()))
                .and_then(|s| if s.name == stem { Ok(s) } else { Err(format!("the file names scene '{}'", s.name)) });
            match read {
                Ok(s) if s.deleted => out.tombstones.push((s.name, s.revision)),
                Ok(s) => out.scenes.push(s),
                Err(why) => {
                    let moved = self.quarantine_file(&p, &file);
                    out.quarantined.push((stem.to_string(), format!("{}: {why}; {moved}", p.display())));
                }
            }
        }
        out
    }

    /// Moves a bad file out of the way; says where to.
    fn quarantine_file(&self, p: &Path, file: &str) -> String {
        let to = self.quarantine.join(format!("{file}.epoch-{}", self.epoch));
        match fs::create_dir_all(&self.quarantine).and_then(|_| fs::rename(p, &to)) {
            Ok(()) => format!("moved to {}", to.display()),
            Err(e) => format!("could not be moved to {}: {e}", to.display()),
        }
    }

    /// Moves a scene file that was read but is not a valid scene any more (e.g. after
    /// a change of limits) to the quarantine; says where to.
    pub fn quarantine(&self, name: &str) -> String {
        let file = format!("{name}.json");
        self.quarantine_file(&self.dir.join(&file), &file)
    }
}

/// Convenience for replies.
pub fn embedded(v: &serde_json::Value) -> EmbeddedJson {
    EmbeddedJson(v.clone())
}
