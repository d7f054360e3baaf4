//! The scenes a server holds: validated scenes with their revisions, the shared
//! contour cache, and the store behind them. Updates of one scene are serialised by
//! that scene's write lock (updates of different scenes run side by side) and persisted
//! before they become visible (and before `apply` replies).

use super::error::{invalid, ServiceError};
use super::proto::{Change, ChangeOp, EmbeddedJson, ObstaclePut};
use super::store::Store;
use riskplan_certify::checker::SceneKernel;
use riskplan_scene::{ContourCache, Scene};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, RwLock};

pub use super::proto::MAX_CHANGES;

/// A scene at one revision.
#[derive(Clone, Debug)]
pub struct Entry {
    /// The validated scene with its cached contours.
    pub scene: Arc<Scene>,
    /// What the scene's checkers cache (compiled contours, covers), kept while the
    /// scene is live at this revision.
    pub kernel: SceneKernel,
    /// Revision (increases with every update).
    pub revision: u64,
    /// The scene file as JSON (shared: every request takes an `Entry`, and a deep copy of a
    /// large scene's JSON would add to every plan's round trip).
    pub json: Arc<serde_json::Value>,
}

impl Entry {
    fn new(scene: Scene, revision: u64, json: serde_json::Value) -> Entry {
        let scene = Arc::new(scene);
        Entry { kernel: SceneKernel::new(scene.clone()), scene, revision, json: Arc::new(json) }
    }

    /// The next revision of a scene whose kernel was `previous`: what it built for
    /// unchanged obstacles is taken over.
    fn successor(previous: &SceneKernel, scene: Scene, revision: u64, json: serde_json::Value) -> Entry {
        let scene = Arc::new(scene);
        Entry { kernel: previous.successor(scene.clone()), scene, revision, json: Arc::new(json) }
    }
}

/// A committed change of one scene, as replicas follow it: the scene at `revision`,
/// or (`json` = `None`) its deletion after `revision`.
#[derive(Clone, Debug, PartialEq)]
pub struct Commit {
    /// Scene name.
    pub name: String,
    /// The revision written, or the last live revision of a deleted scene.
    pub revision: u64,
    /// The scene file, `None` for a deletion.
    pub json: Option<serde_json::Value>,
}

impl Commit {
    /// The order of versions of one name: revisions, and at equal revision the
    /// deletion after the scene it deleted.
    pub fn version(&self) -> (u64, bool) {
        (self.revision, self.json.is_none())
    }
}

/// Called with every commit, in commit order per scene (under the scene's write lock).
pub struct CommitListener(Box<dyn Fn(&Commit) + Send + Sync>);

impl CommitListener {
    /// Wraps `f`.
    pub fn new(f: impl Fn(&Commit) + Send + Sync + 'static) -> CommitListener {
        CommitListener(Box::new(f))
    }
}

impl std::fmt::Debug for CommitListener {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("CommitListener")
    }
}

/// All scenes of a server.
#[derive(Debug)]
pub struct Registry {
    /// Told of every commit (the primary publishes them to replicas).
    listener: std::sync::OnceLock<CommitListener>,
    scenes: RwLock<BTreeMap<String, Entry>>,
    /// One write lock per scene name with an update in progress.
    writers: Mutex<BTreeMap<String, Arc<Mutex<()>>>>,
    /// Contours shared between revisions.
    pub cache: ContourCache,
    store: Store,
    /// For names without a live scene: the revision the next creation must exceed
    /// (a tombstone's last revision, or the epoch floor of a quarantined file).
    /// The flag says whether the name was deleted by a client (a tombstone).
    history: Mutex<BTreeMap<String, (u64, bool)>>,
    /// What went wrong while loading the stored scenes (shown by `status`).
    problems: Mutex<Vec<String>>,
    /// The last plan of each robot, by (scene, robot id), for receding-horizon warm
    /// starts (docs/design.md §6.9); at most [`MAX_ROBOT_PLANS`].
    robots: Mutex<std::collections::HashMap<(String, String), Arc<riskplan_scene::Trajectory>>>,
    /// Scenes grown by a request's robot body, by (scene, revision, radius bits); the
    /// last [`MAX_BODY_KERNELS`].
    bodies: Mutex<Vec<(BodyKey, SceneKernel)>>,
    /// What the scenes' kernels found cached and built (the metrics of `serve --metrics`).
    pub kernels: KernelStats,
    /// The number of commits made (live or deleted), sent to every [`Registry::commits`]
    /// receiver: what a read waiting for a revision awaits.
    commits: tokio::sync::watch::Sender<u64>,
}

/// What the kernels of the scenes (their proven covers, the grown-body kernels) found
/// cached and what they built, as the service observes it (`serve --metrics`,
/// proto/README.md "Metrics"). Counters only: recording is an atomic add.
#[derive(Debug, Default)]
pub struct KernelStats {
    covers_hits: AtomicU64,
    covers_misses: AtomicU64,
    body_hits: AtomicU64,
    body_misses: AtomicU64,
    /// Warm-ups by outcome: done, stopped, skipped (`service::warm`).
    warm_ups: [AtomicU64; 3],
}

/// How a background warm-up of a committed scene ended (`service::warm`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarmUpOutcome {
    /// Everything a default plan builds first was built.
    Done,
    /// Stopped by its deadline or shutdown (what was finished is kept).
    Stopped,
    /// Not started (no worker was idle when it was asked for) or abandoned (the scene had a
    /// newer revision by then, which is warmed instead when it is wanted).
    Skipped,
}

/// The counts of [`KernelStats`] at one moment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KernelCounts {
    /// Plan and verify jobs whose scene kernel held every obstacle's covers (the scene
    /// index, complete) at the job's risk levels when the job started (on a scene of
    /// fewer than 16 obstacles an index builds each obstacle's covers on demand:
    /// `certify::checker::LAZY_MAX_OBSTACLES`).
    pub covers_hits: u64,
    /// Plan and verify jobs whose scene kernel did not.
    pub covers_misses: u64,
    /// Obstacles' proven covers built and kept by the process, over every scene and
    /// risk level ([`riskplan_certify::checker::covers_built_total`]; a build cut short by a
    /// deadline is not kept, nor counted).
    pub covers_built: u64,
    /// Requests with a robot body other than the scene's whose grown kernel was kept.
    pub body_hits: u64,
    /// Requests with a robot body other than the scene's whose grown kernel was not
    /// kept: built (or refused, when the body does not fit the scene).
    pub body_misses: u64,
    /// Background warm-ups of committed scenes (`service::warm`) that built everything.
    pub warm_ups_done: u64,
    /// ... that their deadline or shutdown stopped.
    pub warm_ups_stopped: u64,
    /// ... not started (no idle worker) or abandoned for a newer revision.
    pub warm_ups_skipped: u64,
}

impl KernelStats {
    /// Counts one plan or verify job on a kernel that held every obstacle's covers at its
    /// risk levels when it started (`before`) or not.
    pub fn covers(&self, before: bool) {
        let add = |c: &AtomicU64| {
            c.fetch_add(1, Ordering::Relaxed);
        };
        if before {
            add(&self.covers_hits);
        } else {
            add(&self.covers_misses);
        }
    }

    /// The counts now.
    pub fn counts(&self) -> KernelCounts {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        KernelCounts {
            covers_hits: get(&self.covers_hits),
            covers_misses: get(&self.covers_misses),
            covers_built: riskplan_certify::checker::covers_built_total(),
            body_hits: get(&self.body_hits),
            body_misses: get(&self.body_misses),
            warm_ups_done: get(&self.warm_ups[0]),
            warm_ups_stopped: get(&self.warm_ups[1]),
            warm_ups_skipped: get(&self.warm_ups[2]),
        }
    }

    /// Counts a warm-up's outcome.
    pub fn warm_up(&self, outcome: WarmUpOutcome) {
        let k = match outcome {
            WarmUpOutcome::Done => 0,
            WarmUpOutcome::Stopped => 1,
            WarmUpOutcome::Skipped => 2,
        };
        self.warm_ups[k].fetch_add(1, Ordering::Relaxed);
    }
}

/// A grown scene's key: (scene, revision, the body radius's bits).
type BodyKey = (String, u64, u64);

/// Most robot plans kept for warm starts (a robot's entry is replaced by its next plan;
/// past the limit the oldest-looking entries are dropped).
pub const MAX_ROBOT_PLANS: usize = 4096;

/// Scenes grown by a request's body radius kept (docs/design.md §3.12).
pub const MAX_BODY_KERNELS: usize = 8;

/// Revisions of a name created again after its file was lost start above
/// `epoch · EPOCH_STRIDE`, above every revision handed out in earlier runs (which
/// would need 2³² updates of one scene in one run to reach it).
pub const EPOCH_STRIDE: u64 = 1 << 32;

/// Scene names: 1–128 of `A–Z a–z 0–9 _ - .` (no key-expression specials), not starting with '.'.
pub fn valid_scene_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 128
        && !name.starts_with('.')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
}

fn check_name(name: &str) -> Result<(), ServiceError> {
    if valid_scene_name(name) {
        Ok(())
    } else {
        Err(ServiceError::InvalidSceneName(name.to_string()))
    }
}

fn internal(e: impl std::fmt::Display) -> ServiceError {
    ServiceError::Internal(e.to_string())
}

impl Registry {
    /// An empty registry over `store`; [`Registry::load`] reads the stored scenes.
    /// The server answers `status` (state "loading") between the two.
    pub fn new(store: Store) -> Registry {
        Registry {
            listener: std::sync::OnceLock::new(),
            scenes: RwLock::new(BTreeMap::new()),
            writers: Mutex::new(BTreeMap::new()),
            cache: ContourCache::default(),
            store,
            history: Mutex::new(BTreeMap::new()),
            problems: Mutex::new(Vec::new()),
            robots: Mutex::new(std::collections::HashMap::new()),
            bodies: Mutex::new(Vec::new()),
            kernels: KernelStats::default(),
            commits: tokio::sync::watch::Sender::new(0),
        }
    }

    /// The last plan kept for `robot` on `scene`.
    pub fn robot_plan(&self, scene: &str, robot: &str) -> Option<Arc<riskplan_scene::Trajectory>> {
        self.robots.lock().ok()?.get(&(scene.to_string(), robot.to_string())).cloned()
    }

    /// The revision at which scene `name` was deleted, when it is deleted (its
    /// tombstone).
    pub fn deleted_at(&self, name: &str) -> Option<u64> {
        self.history.lock().ok()?.get(name).and_then(|&(rev, deleted)| deleted.then_some(rev))
    }

    /// Keeps `plan` as the last plan of `robot` on `scene`.
    pub fn keep_robot_plan(&self, scene: &str, robot: &str, plan: Arc<riskplan_scene::Trajectory>) {
        if let Ok(mut m) = self.robots.lock() {
            let key = (scene.to_string(), robot.to_string());
            if m.len() >= MAX_ROBOT_PLANS && !m.contains_key(&key) {
                if let Some(k) = m.keys().next().cloned() {
                    m.remove(&k);
                }
            }
            m.insert(key, plan);
        }
    }

    /// The kernel of `entry`'s scene for a robot body of radius `rho` (the entry's own
    /// when the scene has that body): every obstacle grown by it (docs/design.md §3.12),
    /// built once per revision and radius.
    pub fn with_body(&self, entry: &Entry, rho: f64) -> Result<SceneKernel, ServiceError> {
        let bad = |m: String| invalid("robot_radius", m);
        let r = num_rational::BigRational::from_float(rho)
            .filter(|r| !num_traits::Signed::is_negative(r))
            .ok_or_else(|| bad(format!("must be a finite number ≥ 0, got {rho}")))?;
        if r == entry.scene.body {
            return Ok(entry.kernel.clone());
        }
        let key = (entry.scene.name.clone(), entry.revision, rho.to_bits());
        if let Some(k) = self.bodies.lock().map_err(internal)?.iter().find(|e| e.0 == key).map(|e| e.1.clone()) {
            self.kernels.body_hits.fetch_add(1, Ordering::Relaxed);
            return Ok(k);
        }
        self.kernels.body_misses.fetch_add(1, Ordering::Relaxed);
        let grown = entry.scene.with_body(rho, &self.cache).map_err(|e| bad(e.to_string()))?;
        let kernel = SceneKernel::new(Arc::new(grown));
        let mut v = self.bodies.lock().map_err(internal)?;
        if v.len() >= MAX_BODY_KERNELS {
            v.remove(0);
        }
        v.push((key, kernel.clone()));
        Ok(kernel)
    }

    /// Loads every stored scene. Files that cannot be read, and scenes that no longer
    /// validate, are quarantined and reported (returned, and kept for `status`).
    /// Call it once, before any update.
    pub fn load(&self) -> Vec<String> {
        let reg = self;
        let loaded = reg.store.load_all();
        let floor = reg.store.epoch().saturating_mul(EPOCH_STRIDE);
        let mut problems = Vec::new();
        let mut history = BTreeMap::new();
        for (name, rev) in loaded.tombstones {
            history.insert(name, (rev, true));
        }
        for (name, why) in loaded.quarantined {
            problems.push(format!("quarantined stored scene '{name}': {why}"));
            history.insert(name, (floor, false));
        }
        for s in loaded.scenes {
            match reg.build(&s.scene) {
                Ok(scene) => {
                    if let Ok(mut m) = reg.scenes.write() {
                        m.insert(s.name.clone(), Entry::new(scene, s.revision, s.scene));
                    }
                }
                Err(e) => {
                    let moved = reg.store.quarantine(&s.name);
                    problems
                        .push(format!("quarantined stored scene '{}' (revision {}): {e}; {moved}", s.name, s.revision));
                    history.insert(s.name, (floor.max(s.revision), false));
                }
            }
        }
        if let Ok(mut h) = reg.history.lock() {
            *h = history;
        }
        if let Ok(mut p) = reg.problems.lock() {
            p.clone_from(&problems);
        }
        problems
    }

    /// Whether `name` has a live scene or was deleted by a client (a tombstone):
    /// preloading must not bring back a scene a client deleted. A quarantined name is
    /// not known: preloading restores it, at a revision above the lost one's.
    pub fn known(&self, name: &str) -> bool {
        self.scenes.read().is_ok_and(|m| m.contains_key(name))
            || self.history.lock().is_ok_and(|h| h.get(name).is_some_and(|&(_, deleted)| deleted))
    }

    /// The problems met while loading (quarantined files).
    pub fn problems(&self) -> Vec<String> {
        self.problems.lock().map(|p| p.clone()).unwrap_or_default()
    }

    /// Runs `f` holding the write lock of scene `name`. The lock is dropped from the
    /// table when no other update of that name waits for it, so hostile names do not
    /// accumulate.
    fn with_write_lock<T>(&self, name: &str, f: impl FnOnce() -> Result<T, ServiceError>) -> Result<T, ServiceError> {
        let lock = self.writers.lock().map_err(internal)?.entry(name.to_string()).or_default().clone();
        let r = {
            let _w = lock.lock().map_err(internal)?;
            f()
        };
        if let Ok(mut m) = self.writers.lock() {
            // the table's reference and ours: nobody else is waiting
            if Arc::strong_count(&lock) == 2 {
                m.remove(name);
            }
        }
        r
    }

    fn build(&self, json: &serde_json::Value) -> Result<Scene, ServiceError> {
        Scene::from_json_cached(&json.to_string(), &self.cache).map_err(ServiceError::InvalidScene)
    }

    /// [`Registry::build`] from the previous revision: unchanged pedestrians are taken
    /// over (docs/design.md §3.11).
    fn build_from(&self, json: &serde_json::Value, previous: Option<&Scene>) -> Result<Scene, ServiceError> {
        let file: riskplan_scene::SceneFile = serde_path_to_error::deserialize(json).map_err(|e| {
            let path = e.path().to_string();
            ServiceError::InvalidScene(riskplan_scene::SceneError {
                path: if path == "." { String::new() } else { path },
                kind: riskplan_scene::SceneErrorKind::Syntax(e.into_inner().to_string()),
            })
        })?;
        Scene::from_file_reusing(file, &self.cache, previous).map_err(ServiceError::InvalidScene)
    }

    /// The scene `name`.
    pub fn get(&self, name: &str) -> Result<Entry, ServiceError> {
        check_name(name)?;
        self.scenes
            .read()
            .map_err(internal)?
            .get(name)
            .cloned()
            .ok_or_else(|| ServiceError::UnknownScene(name.to_string()))
    }

    /// (name, revision, obstacles) of every scene.
    pub fn list(&self) -> Vec<(String, u64, usize)> {
        self.scenes
            .read()
            .map(|m| m.iter().map(|(k, e)| (k.clone(), e.revision, e.scene.obstacles.len())).collect())
            .unwrap_or_default()
    }

    /// Validates, persists and publishes a new version of `name` produced by `edit`
    /// from the current JSON (`None` when the scene does not exist).
    fn update(
        &self,
        name: &str,
        edit: impl FnOnce(Option<&serde_json::Value>) -> Result<serde_json::Value, ServiceError>,
    ) -> Result<u64, ServiceError> {
        check_name(name)?;
        self.with_write_lock(name, || self.update_locked(name, edit))
    }

    fn update_locked(
        &self,
        name: &str,
        edit: impl FnOnce(Option<&serde_json::Value>) -> Result<serde_json::Value, ServiceError>,
    ) -> Result<u64, ServiceError> {
        let current = self.scenes.read().map_err(internal)?.get(name).cloned();
        let mut json = edit(current.as_ref().map(|e| e.json.as_ref()))?;
        if let Some(o) = json.as_object_mut() {
            o.insert("name".into(), serde_json::Value::String(name.to_string()));
        }
        let scene = self.build_from(&json, current.as_ref().map(|e| e.scene.as_ref()))?;
        let revision = match &current {
            Some(e) => e.revision + 1,
            None => self.history.lock().map_err(internal)?.get(name).map_or(0, |&(rev, _)| rev) + 1,
        };
        self.commit_live(name, revision, json, scene, current.as_ref().map(|e| &e.kernel))?;
        Ok(revision)
    }

    /// Under the scene's write lock: persists `name` at `revision`, tells the
    /// listener, and makes it the live entry.
    fn commit_live(
        &self,
        name: &str,
        revision: u64,
        json: serde_json::Value,
        scene: Scene,
        previous: Option<&SceneKernel>,
    ) -> Result<(), ServiceError> {
        self.store.save(name, revision, &json).map_err(|e| internal(format!("cannot persist scene '{name}': {e}")))?;
        self.notify(name, revision, Some(&json));
        self.history.lock().map_err(internal)?.remove(name);
        // (the new kernel, taking over the old one's work, made before the registry's lock:
        // every request's `get` waits for that lock)
        let entry = match previous {
            Some(k) => Entry::successor(k, scene, revision, json),
            None => Entry::new(scene, revision, json),
        };
        let mut m = self.scenes.write().map_err(internal)?;
        let old = m.insert(name.to_string(), entry);
        self.cache.retain_used(m.values().map(|e| e.scene.as_ref()));
        drop(m);
        self.commits.send_modify(|c| *c += 1);
        // the previous revision is freed outside the lock (readers wait for nothing)
        drop(old);
        Ok(())
    }

    /// Under the scene's write lock: persists the deletion of `name` after `revision`
    /// (a tombstone), tells the listener, and drops the live entry.
    fn commit_deleted(&self, name: &str, revision: u64) -> Result<(), ServiceError> {
        self.store.remove(name, revision).map_err(|e| internal(format!("cannot remove scene '{name}': {e}")))?;
        self.notify(name, revision, None);
        self.history.lock().map_err(internal)?.insert(name.to_string(), (revision, true));
        let mut m = self.scenes.write().map_err(internal)?;
        m.remove(name);
        self.cache.retain_used(m.values().map(|e| e.scene.as_ref()));
        drop(m);
        self.commits.send_modify(|c| *c += 1);
        Ok(())
    }

    fn notify(&self, name: &str, revision: u64, json: Option<&serde_json::Value>) {
        if let Some(l) = self.listener.get() {
            (l.0)(&Commit { name: name.to_string(), revision, json: json.cloned() });
        }
    }

    /// A receiver of the commit count, changed after every later commit (the entry is
    /// live, or the deletion done, by then): a read waiting for a revision awaits it.
    pub fn commits(&self) -> tokio::sync::watch::Receiver<u64> {
        self.commits.subscribe()
    }

    /// Sets the listener told of every later commit (once; later calls are ignored).
    pub fn set_listener(&self, l: CommitListener) {
        let _ = self.listener.set(l);
    }

    /// The data directory's identity (see [`Store::id`]).
    pub fn store_id(&self) -> u64 {
        self.store.id()
    }

    /// The version of every name: live scenes, and deletions (tombstones).
    pub fn index(&self) -> Vec<(String, u64, bool)> {
        let mut out: BTreeMap<String, (u64, bool)> = self
            .history
            .lock()
            .map(|h| h.iter().filter(|(_, &(_, deleted))| deleted).map(|(k, &v)| (k.clone(), v)).collect())
            .unwrap_or_default();
        if let Ok(m) = self.scenes.read() {
            for (k, e) in m.iter() {
                out.insert(k.clone(), (e.revision, false));
            }
        }
        out.into_iter().map(|(k, (r, d))| (k, r, d)).collect()
    }

    /// The version a replica compares with its primary's: a live scene or a deletion;
    /// not the floor a quarantined file left (that floor is this server's own).
    pub fn replicated_version(&self, name: &str) -> Option<(u64, bool)> {
        if let Some(r) = self.scenes.read().ok()?.get(name).map(|e| e.revision) {
            return Some((r, false));
        }
        self.history.lock().ok()?.get(name).copied().filter(|&(_, deleted)| deleted)
    }

    /// The current state of `name` as one commit (the revision and the content read
    /// together, under the scene's write lock), `None` when unknown.
    pub fn commit(&self, name: &str) -> Result<Option<Commit>, ServiceError> {
        check_name(name)?;
        self.with_write_lock(name, || {
            if let Some(e) = self.scenes.read().map_err(internal)?.get(name) {
                return Ok(Some(Commit {
                    name: name.to_string(),
                    revision: e.revision,
                    json: Some(e.json.as_ref().clone()),
                }));
            }
            let h = self.history.lock().map_err(internal)?.get(name).copied();
            Ok(h.filter(|&(_, deleted)| deleted).map(|(revision, _)| Commit {
                name: name.to_string(),
                revision,
                json: None,
            }))
        })
    }

    /// A replica drops the live scenes its primary no longer lists (the primary
    /// quarantined them, or its data directory is new); returns their names.
    pub fn drop_missing(&self, listed: &std::collections::BTreeSet<String>) -> Vec<String> {
        let missing: Vec<(String, u64)> = self
            .scenes
            .read()
            .map(|m| m.iter().filter(|(k, _)| !listed.contains(*k)).map(|(k, e)| (k.clone(), e.revision)).collect())
            .unwrap_or_default();
        let mut dropped = Vec::new();
        for (name, revision) in missing {
            let c = Commit { name: name.clone(), revision, json: None };
            if self.install(&c, true).is_ok() {
                dropped.push(name);
            }
        }
        dropped
    }

    /// A replica installs a commit of the primary, with the primary's revision, when
    /// it is newer than what it has; returns whether it did. The scene is validated
    /// and persisted like any update.
    /// `force` (after the primary's identity changed: its data directory is new)
    /// installs whatever the primary has.
    pub fn install(&self, c: &Commit, force: bool) -> Result<bool, ServiceError> {
        check_name(&c.name)?;
        self.with_write_lock(&c.name, || {
            if !force && self.replicated_version(&c.name).is_some_and(|v| v >= c.version()) {
                return Ok(false);
            }
            match &c.json {
                Some(json) => {
                    let current = self.scenes.read().map_err(internal)?.get(&c.name).cloned();
                    let scene = self.build_from(json, current.as_ref().map(|e| e.scene.as_ref()))?;
                    self.commit_live(&c.name, c.revision, json.clone(), scene, current.as_ref().map(|e| &e.kernel))?
                }
                None => self.commit_deleted(&c.name, c.revision)?,
            }
            Ok(true)
        })
    }

    /// Replaces (or creates) a whole scene.
    pub fn put_scene(&self, name: &str, json: serde_json::Value) -> Result<u64, ServiceError> {
        self.update(name, |_| Ok(json))
    }

    /// Applies obstacle changes atomically to an existing scene.
    pub fn apply_changes(&self, name: &str, changes: &[Change]) -> Result<u64, ServiceError> {
        if changes.len() > MAX_CHANGES {
            return Err(ServiceError::LimitExceeded {
                message: format!("{} changes exceed the limit of {MAX_CHANGES} per apply", changes.len()),
                field: Some("changes".into()),
            });
        }
        self.update(name, |cur| {
            let mut json = cur.cloned().ok_or_else(|| ServiceError::UnknownScene(name.to_string()))?;
            for (i, c) in changes.iter().enumerate() {
                match c.op.get() {
                    Ok(ChangeOp::Put) => match (&c.poly, &c.pedestrian) {
                        (Some(poly), None) => {
                            put_obstacle_json(&mut json, &c.id, poly, c.params.as_ref(), &format!("changes[{i}]"))?
                        }
                        (None, Some(EmbeddedJson(p))) => {
                            if c.params.is_some() {
                                return Err(invalid(&format!("changes[{i}].params"), "a pedestrian has no params"));
                            }
                            put_pedestrian_json(&mut json, &c.id, p, &format!("changes[{i}]"))?
                        }
                        _ => {
                            return Err(invalid(
                                &format!("changes[{i}].poly"),
                                "a put needs exactly one of 'poly' and 'pedestrian'",
                            ))
                        }
                    },
                    Ok(ChangeOp::Delete) => {
                        if c.poly.is_some() || c.params.is_some() || c.pedestrian.is_some() {
                            return Err(invalid(&format!("changes[{i}]"), "a delete takes only 'op' and 'id'"));
                        }
                        delete_obstacle_json(&mut json, &c.id, &format!("changes[{i}].id"))?
                    }
                    Err(message) => return Err(invalid(&format!("changes[{i}].op"), message)),
                }
            }
            Ok(json)
        })
    }

    /// Adds or replaces one obstacle.
    pub fn put_obstacle(&self, name: &str, id: &str, put: &ObstaclePut) -> Result<u64, ServiceError> {
        self.update(name, |cur| {
            let mut json = cur.cloned().ok_or_else(|| ServiceError::UnknownScene(name.to_string()))?;
            put_obstacle_json(&mut json, id, &put.poly, put.params.as_ref(), "obstacle")?;
            Ok(json)
        })
    }

    /// Removes one obstacle.
    pub fn delete_obstacle(&self, name: &str, id: &str) -> Result<u64, ServiceError> {
        self.update(name, |cur| {
            let mut json = cur.cloned().ok_or_else(|| ServiceError::UnknownScene(name.to_string()))?;
            delete_obstacle_json(&mut json, id, "id")?;
            Ok(json)
        })
    }

    /// Removes a scene.
    pub fn delete_scene(&self, name: &str) -> Result<(), ServiceError> {
        check_name(name)?;
        self.with_write_lock(name, || {
            let Some(revision) = self.scenes.read().map_err(internal)?.get(name).map(|e| e.revision) else {
                return Err(ServiceError::UnknownScene(name.to_string()));
            };
            self.commit_deleted(name, revision)
        })
    }
}

fn put_obstacle_json(
    json: &mut serde_json::Value,
    id: &str,
    poly: &str,
    params: Option<&EmbeddedJson>,
    path: &str,
) -> Result<(), ServiceError> {
    if id.is_empty() {
        return Err(invalid(&format!("{path}.id"), "an obstacle id must not be empty"));
    }
    if let Some(EmbeddedJson(p)) = params {
        let Some(new) = p.as_object() else {
            return Err(invalid(&format!("{path}.params"), "must be an object {name: distribution}"));
        };
        let obj = json.as_object_mut().ok_or_else(|| internal("scene is not an object"))?;
        let slot = obj.entry("params").or_insert_with(|| serde_json::json!({}));
        let Some(existing) = slot.as_object_mut() else {
            return Err(invalid("params", "the scene's params is not an object"));
        };
        for (k, v) in new {
            existing.insert(k.clone(), v.clone());
        }
    }
    upsert_obstacle(json, id, serde_json::json!({"id": id, "poly": poly}))
}

/// Replaces obstacle `id` of the scene JSON by `entry`, or adds it.
fn upsert_obstacle(json: &mut serde_json::Value, id: &str, entry: serde_json::Value) -> Result<(), ServiceError> {
    let obstacles = json
        .get_mut("obstacles")
        .and_then(|o| o.as_array_mut())
        .ok_or_else(|| invalid("obstacles", "the scene has no obstacle list"))?;
    match obstacles.iter_mut().find(|o| o["id"] == id) {
        Some(o) => *o = entry,
        None => obstacles.push(entry),
    }
    Ok(())
}

fn put_pedestrian_json(
    json: &mut serde_json::Value,
    id: &str,
    pedestrian: &serde_json::Value,
    path: &str,
) -> Result<(), ServiceError> {
    if id.is_empty() {
        return Err(invalid(&format!("{path}.id"), "an obstacle id must not be empty"));
    }
    upsert_obstacle(json, id, serde_json::json!({"id": id, "pedestrian": pedestrian}))
}

fn delete_obstacle_json(json: &mut serde_json::Value, id: &str, path: &str) -> Result<(), ServiceError> {
    let obstacles = json
        .get_mut("obstacles")
        .and_then(|o| o.as_array_mut())
        .ok_or_else(|| invalid("obstacles", "the scene has no obstacle list"))?;
    let before = obstacles.len();
    obstacles.retain(|o| o["id"] != id);
    if obstacles.len() == before {
        return Err(invalid(path, format!("no obstacle '{id}' in the scene")));
    }
    Ok(())
}
