//! The motion checker's fast path (docs/design.md §5.10): compiled contours, proven
//! covers of each obstacle's unsafe set, and a grid so that an edge meets only the
//! obstacles near it.
//!
//! Nothing here decides "safe" by itself except with a proof:
//! - an obstacle is skipped for a piece only when the piece lies in the workspace and
//!   its bounding box misses the obstacle's proven cover ([`crate::region`])
//!   during every time slab the piece spans;
//! - the others are decided on the compiled restriction ([`crate::fast`]) by
//!   the Bernstein checker, with the exact rational fallback unchanged.

use crate::fast::{FPoly, Frame};
use crate::region::{unsafe_cover, ConstraintBounds, Cover};
use crate::PieceRef;
use riskplan_math::contour::tail::tail_kappa;
use riskplan_math::contour::RiskLevel;
use riskplan_math::poly::Interval;
use riskplan_scene::{ContourCell, Scene};
use std::sync::Arc;

/// Time slabs per horizon for a moving obstacle's covers: a piece is tested against
/// the covers of the slabs it spans; more slabs give tighter boxes at more set-up cost.
pub const TIME_SLABS: usize = 8;

/// Below this many obstacles every obstacle's cover is tested directly (a grid costs
/// more than it saves).
pub const GRID_MIN_OBSTACLES: usize = 16;

/// Grid cells per obstacle (the grid has about this many cells per obstacle, at most
/// [`GRID_MAX_CELLS`]).
pub const GRID_CELLS_PER_OBSTACLE: usize = 4;

/// Upper bound on grid cells.
pub const GRID_MAX_CELLS: usize = 1 << 16;

/// The frame of the compiled contours (docs/design.md §5.10): centred at
/// [`Scene::center`], scaled by powers of two about the workspace's half-widths and half
/// the horizon, so that the compiled numbers do not depend on the scene's units.
pub fn scene_frame(scene: &Scene) -> Frame {
    let ws = &scene.workspace;
    let mut half: Vec<f64> = ws.lower.iter().zip(&ws.upper).map(|(l, u)| 0.5 * u - 0.5 * l).collect();
    half.push(0.5 * scene.horizon.1 - 0.5 * scene.horizon.0);
    Frame::new(&scene.center(), &half)
}

/// One time slab of an obstacle and its proven cover.
#[derive(Clone, Debug)]
struct Slab {
    t: (f64, f64),
    /// Spatial part of the cover; `None`: proven safe everywhere in the slab.
    cover: Option<Vec<(f64, f64)>>,
}

/// An obstacle's covers: per slab (static obstacles: one slab for all time), or none
/// (always checked). A moving obstacle's slabs are equal in length, from `slabs[0].t.0`,
/// so that the slabs a piece spans are found by division.
#[derive(Clone, Debug)]
struct ObstacleCovers {
    /// Shared: the next revision of the scene takes over an unchanged obstacle's covers
    /// without copying them, and dropping an old index frees only what changed.
    slabs: Option<Arc<Vec<Slab>>>,
    /// Whether the slabs cover all time (static obstacle).
    timeless: bool,
}

/// Most time slabs of a pedestrian's covers over the horizon (docs/design.md §3.11):
/// its slabs are as long as it takes to walk its own reach (so that a slab's box is a
/// few times the disk), at least [`TIME_SLABS`], at most this many.
pub const PEDESTRIAN_MAX_SLABS: usize = 4096;

/// A pedestrian's covers from its tail bound at threshold `kappa`: per slab, the box of
/// [`GaussianDisk::slab_box`](riskplan_math::contour::tail::GaussianDisk::slab_box) — microseconds,
/// no search.
fn pedestrian_covers(p: &riskplan_scene::Pedestrian, kappa: f64, horizon: (f64, f64)) -> ObstacleCovers {
    let d = &p.disk;
    let (h0, h1) = horizon;
    let speed = d.velocity.iter().map(|v| v.lo.abs().max(v.hi.abs())).fold(0.0, f64::max);
    let len = h1 - h0;
    let wanted = if speed > 0.0 && d.reach > 0.0 { (len * speed / d.reach).ceil() } else { TIME_SLABS as f64 };
    let n = if wanted.is_finite() {
        (wanted as usize).clamp(TIME_SLABS, PEDESTRIAN_MAX_SLABS)
    } else {
        PEDESTRIAN_MAX_SLABS
    };
    let slabs = (0..n)
        .map(|k| {
            let a = if k == 0 { h0 } else { h0 + len * k as f64 / n as f64 };
            let b = if k + 1 == n { h1 } else { h0 + len * (k + 1) as f64 / n as f64 };
            let cover = d.slab_box(a, b, kappa);
            let finite = cover.iter().all(|c| c.0.is_finite() && c.1.is_finite());
            // a box that is not finite covers everything
            let cover = if finite { cover } else { vec![(f64::NEG_INFINITY, f64::INFINITY); d.dim()] };
            Slab { t: (a, b), cover: Some(cover) }
        })
        .collect();
    ObstacleCovers { slabs: Some(Arc::new(slabs)), timeless: false }
}

/// Below this many obstacles an index builds each obstacle's covers lazily: the motion
/// checker decides an obstacle without covers directly (about a microsecond on the
/// compiled restriction) and asks for its covers only after [`LAZY_COVER_CHECKS`]
/// pieces were checked against it, so that a cold plan pays for the covers of the
/// obstacles its edges keep meeting, not for all (docs/design.md §5.10). From this many
/// on every cover is built at once, and the grid over them.
pub const LAZY_MAX_OBSTACLES: usize = GRID_MIN_OBSTACLES;

/// Fewest obstacles without covers for which [`SceneIndex::ensure_all_on`] builds covers
/// on more than one thread: a cover costs 0.3–1 ms (512 disks: about 0.5 ms each, half of a
/// cold plan's CPU), a scoped thread about 0.1 ms to start; from this many obstacles on a
/// plan builds every cover at once ([`LAZY_MAX_OBSTACLES`]).
pub const PARALLEL_COVERS_MIN: usize = GRID_MIN_OBSTACLES;

/// Most threads that build one index's covers at once ([`SceneIndex::ensure_all_on`]).
pub const MAX_COVER_BUILD_THREADS: usize = 4;

/// Direct checks of one obstacle after which its covers are built: a static obstacle's
/// covers cost about as much as a few hundred direct checks of it (0.3–1 ms against
/// 1–3 µs measured on the reference scenes), the rule of ski rental.
pub const LAZY_COVER_CHECKS: u32 = 256;

/// Obstacles' covers built and kept by every index of the process (a count for the
/// service's metrics, `riskplan_covers_built_total`).
static COVERS_BUILT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// How many obstacles' covers (all their time slabs) the process has built and kept so
/// far, over every scene and risk level; covers taken over from a previous revision are
/// not counted again.
pub fn covers_built_total() -> u64 {
    COVERS_BUILT.load(std::sync::atomic::Ordering::Relaxed)
}

/// Covers and a grid for one scene and one risk level per obstacle. Each obstacle's
/// covers are built once, on demand ([`SceneIndex::ensure`]) or all at once
/// ([`SceneIndex::ensure_all`]); an obstacle without covers is always a candidate.
#[derive(Debug)]
pub struct SceneIndex {
    covers: Vec<std::sync::OnceLock<ObstacleCovers>>,
    /// Pieces checked directly against each obstacle that has no covers yet.
    checks: Vec<std::sync::atomic::AtomicU32>,
    /// Each obstacle's contour cell and risk level the covers were built for (to take
    /// them over in the next revision of the scene when both are unchanged). The cells
    /// are held, so that their identities cannot be reused by other contours.
    keys: Vec<(ContourCell, RiskLevel)>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    horizon: (f64, f64),
    grid: std::sync::OnceLock<Grid>,
    /// Nanoseconds spent building the covers.
    build_nanos: std::sync::atomic::AtomicU64,
    /// Cells evaluated.
    cells: std::sync::atomic::AtomicUsize,
    /// [`SceneIndex::typical_extent`] once every cover is built.
    extent: std::sync::OnceLock<f64>,
}

#[derive(Debug)]
struct Grid {
    n: Vec<usize>,
    size: Vec<f64>,
    cells: Vec<Vec<u32>>,
    always: Vec<u32>,
    /// Entries per cell, on average over the grid.
    mean_entries: f64,
}

impl Grid {
    fn cell_range(&self, lower: &[f64], bbox: &[(f64, f64)]) -> Vec<(usize, usize)> {
        bbox.iter()
            .enumerate()
            .map(|(d, &(lo, hi))| (self.axis_cell(lower, d, lo), self.axis_cell(lower, d, hi)))
            .collect()
    }
    /// The cell of coordinate `v` on axis `d` (clamped to the grid; NaN gives the first).
    fn axis_cell(&self, lower: &[f64], d: usize, v: f64) -> usize {
        (((v - lower[d]) / self.size[d]).floor().max(0.0) as usize).min(self.n[d] - 1)
    }
    fn for_each_cell(&self, range: &[(usize, usize)], mut f: impl FnMut(usize)) {
        let mut idx: Vec<usize> = range.iter().map(|r| r.0).collect();
        loop {
            let mut flat = 0;
            for d in (0..idx.len()).rev() {
                flat = flat * self.n[d] + idx[d];
            }
            f(flat);
            let mut d = 0;
            loop {
                if d == idx.len() {
                    return;
                }
                if idx[d] < range[d].1 {
                    idx[d] += 1;
                    break;
                }
                idx[d] = range[d].0;
                d += 1;
            }
        }
    }
}

/// A set of a scene's obstacles (a bit each), filled by [`SceneIndex::mark_candidates`].
#[derive(Clone, Debug)]
pub struct CandidateSet {
    marked: Vec<u64>,
    /// Scratch: the obstacles tested for the current box.
    tested: Vec<u64>,
}

impl CandidateSet {
    fn mark(&mut self, i: usize) {
        self.marked[i / 64] |= 1 << (i % 64);
    }

    /// The obstacles marked, in increasing order, into `out` (cleared first).
    pub fn emit(&self, out: &mut Vec<usize>) {
        out.clear();
        for (w, &bits) in self.marked.iter().enumerate() {
            let mut b = bits;
            while b != 0 {
                out.push(w * 64 + b.trailing_zeros() as usize);
                b &= b - 1;
            }
        }
    }
}

fn overlaps(a: &[(f64, f64)], b: &[(f64, f64)]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.0 <= y.1 && y.0 <= x.1)
}

impl SceneIndex {
    /// Builds the covers of every obstacle at its risk level (`deltas[i]`), asking
    /// `stop` between obstacles: obstacles left without a cover are always checked.
    pub fn build(scene: &Scene, deltas: &[RiskLevel], stop: &dyn Fn() -> bool) -> SceneIndex {
        SceneIndex::build_reusing(scene, deltas, stop, &[])
    }

    /// [`SceneIndex::build`], taking the covers of every obstacle whose contour and risk
    /// level are unchanged from one of `previous` (indexes of the previous revision of
    /// the scene, same workspace and horizon): an update of some obstacles rebuilds only
    /// theirs.
    pub fn build_reusing(
        scene: &Scene,
        deltas: &[RiskLevel],
        stop: &dyn Fn() -> bool,
        previous: &[Arc<SceneIndex>],
    ) -> SceneIndex {
        let index = SceneIndex::lazy(scene, deltas, previous);
        index.ensure_all(scene, stop);
        index
    }

    /// An index with no covers built but those of unchanged obstacles taken from
    /// `previous` (as [`SceneIndex::build_reusing`]); the rest are built by
    /// [`SceneIndex::ensure`] and [`SceneIndex::ensure_all`].
    pub fn lazy(scene: &Scene, deltas: &[RiskLevel], previous: &[Arc<SceneIndex>]) -> SceneIndex {
        let same_box = |p: &SceneIndex| {
            p.lower == scene.workspace.lower && p.upper == scene.workspace.upper && p.horizon == scene.horizon
        };
        let previous: Vec<&Arc<SceneIndex>> = previous.iter().filter(|p| same_box(p)).collect();
        let mut keys = Vec::with_capacity(scene.obstacles.len());
        let mut covers = Vec::with_capacity(scene.obstacles.len());
        for (o, delta) in scene.obstacles.iter().zip(deltas) {
            let key = (o.contour.clone(), delta.clone());
            let reused = previous.iter().find_map(|p| {
                let j = p.keys.iter().position(|k| k.0.key() == key.0.key() && k.1 == key.1)?;
                p.covers[j].get().filter(|c| c.slabs.is_some()).cloned()
            });
            keys.push(key);
            let cell = std::sync::OnceLock::new();
            if let Some(c) = reused {
                let _ = cell.set(c);
            }
            covers.push(cell);
        }
        let checks = (0..covers.len()).map(|_| std::sync::atomic::AtomicU32::new(0)).collect();
        SceneIndex {
            covers,
            checks,
            keys,
            horizon: scene.horizon,
            lower: scene.workspace.lower.clone(),
            upper: scene.workspace.upper.clone(),
            grid: std::sync::OnceLock::new(),
            build_nanos: Default::default(),
            cells: Default::default(),
            extent: std::sync::OnceLock::new(),
        }
    }

    /// Builds every obstacle's covers not built yet, asking `stop` between obstacles (and
    /// between a moving obstacle's slabs); once all are built and the scene has
    /// `GRID_MIN_OBSTACLES` or more, the grid over them. `scene` must be the scene the
    /// index was made for.
    pub fn ensure_all(&self, scene: &Scene, stop: &dyn Fn() -> bool) {
        if self.claim_all(scene, stop, &std::sync::atomic::AtomicUsize::new(0)) {
            self.finish_grid(scene);
        }
    }

    /// [`Self::ensure_all`] as up to `threads` tasks on the rayon pool (at most
    /// `MAX_COVER_BUILD_THREADS`) when at least `PARALLEL_COVERS_MIN` obstacles lack
    /// covers: each task claims the next obstacle not claimed (an atomic counter) and
    /// builds its covers, the same covers as one thread builds (each depends only on its
    /// obstacle). Every task asks `stop` between obstacles (and a moving obstacle's
    /// slabs), and all stop once one has been told to; a task the pool does not get to
    /// leaves its share to the others, and a panic in any task stops the others.
    pub fn ensure_all_on(&self, scene: &Scene, stop: &(dyn Fn() -> bool + Sync), threads: usize) {
        use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
        let missing = self.covers.iter().filter(|c| c.get().is_none()).count();
        let threads = if missing >= PARALLEL_COVERS_MIN { threads.clamp(1, MAX_COVER_BUILD_THREADS) } else { 1 };
        if threads == 1 {
            return self.ensure_all(scene, stop);
        }
        let next = AtomicUsize::new(0);
        let halted = AtomicBool::new(false);
        /// Stops the other threads when its thread ends early: told to stop, or panicking.
        struct Halt<'a>(&'a AtomicBool, bool);
        impl Drop for Halt<'_> {
            fn drop(&mut self) {
                if !self.1 || std::thread::panicking() {
                    self.0.store(true, Ordering::Relaxed);
                }
            }
        }
        let work = || {
            let mut guard = Halt(&halted, false);
            guard.1 = self.claim_all(scene, &|| halted.load(Ordering::Relaxed) || stop(), &next);
        };
        rayon::scope(|sc| {
            for _ in 1..threads {
                sc.spawn(|_| work());
            }
            work();
        });
        if !halted.load(Ordering::Relaxed) {
            self.finish_grid(scene);
        }
    }

    /// Claims obstacles from `next` and builds their covers until none is left (`true`)
    /// or `stop` says stop (`false`).
    fn claim_all(&self, scene: &Scene, stop: &dyn Fn() -> bool, next: &std::sync::atomic::AtomicUsize) -> bool {
        loop {
            if stop() {
                return false;
            }
            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if i >= self.covers.len() {
                return true;
            }
            self.ensure(scene, i, stop);
        }
    }

    /// The grid over every obstacle's covers, once every build was tried.
    fn finish_grid(&self, scene: &Scene) {
        // every build tried (an obstacle whose covers cannot be built, a pedestrian without
        // a tail threshold, is filed as always checked; covers built later only ever skip
        // less through the grid's `always` list, which `candidates` still tests)
        if self.covers.len() >= GRID_MIN_OBSTACLES {
            let _ = self.grid.get_or_init(|| build_grid(scene, &self.covers));
        }
    }

    /// Builds obstacle `i`'s covers if they are not built (`stop` asked between a moving
    /// obstacle's slabs; covers cut short are not kept, the obstacle stays a candidate).
    pub fn ensure(&self, scene: &Scene, i: usize, stop: &dyn Fn() -> bool) {
        if self.covers[i].get().is_some() {
            return;
        }
        let start = std::time::Instant::now();
        let (covers, cells) = obstacle_covers(scene, i, self.keys[i].1.rational(), stop);
        self.cells.fetch_add(cells, std::sync::atomic::Ordering::Relaxed);
        let nanos = u64::try_from(start.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.build_nanos.fetch_add(nanos, std::sync::atomic::Ordering::Relaxed);
        if covers.slabs.is_some() && self.covers[i].set(covers).is_ok() {
            COVERS_BUILT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// Counts one direct check of obstacle `i` (a candidate without covers); `true` when
    /// its covers are due (`LAZY_COVER_CHECKS`).
    pub fn note_direct_check(&self, i: usize) -> bool {
        // (the counter wraps after 2³² checks of an obstacle never covered: harmless)
        self.checks[i].fetch_add(1, std::sync::atomic::Ordering::Relaxed) == LAZY_COVER_CHECKS - 1
    }

    /// Whether obstacle `i` has its covers.
    pub fn has_covers(&self, i: usize) -> bool {
        self.covers[i].get().is_some()
    }

    /// Seconds spent building covers so far.
    pub fn build_seconds(&self) -> f64 {
        self.build_nanos.load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-9
    }

    /// Cells evaluated by the cover searches so far.
    pub fn cells(&self) -> usize {
        self.cells.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Whether every obstacle has its covers (an index cut short by its `stop` has not).
    pub fn complete(&self) -> bool {
        self.covers.iter().all(|c| c.get().is_some_and(|c| c.slabs.is_some()))
    }

    /// Whether obstacle `i` may be skipped for a piece whose spatial bounding box is
    /// `bbox` (inside the workspace) on `[t0, t1]`: its cover misses the box in every
    /// slab the piece spans.
    fn skippable(&self, i: usize, bbox: &[(f64, f64)], t0: f64, t1: f64) -> bool {
        let Some(c) = self.covers[i].get() else { return false };
        let Some(slabs) = &c.slabs else { return false };
        if c.timeless {
            return slabs.iter().all(|s| s.cover.as_ref().is_none_or(|b| !overlaps(b, bbox)));
        }
        let (first, last) = (slabs[0].t.0, slabs[slabs.len() - 1].t.1);
        if !(t0 <= t1 && t0 >= first && t1 <= last) {
            return false;
        }
        // the slabs are equal in length: the ones the piece spans by division, one more
        // on each side against rounding (more slabs only skip less)
        let n = slabs.len();
        let w = (last - first) / n as f64;
        let index = |t: f64| ((t - first) / w).floor();
        let (a, b) = (index(t0), index(t1));
        let (a, b) = if a.is_finite() && b.is_finite() && w > 0.0 {
            ((a.max(1.0) as usize - 1).min(n - 1), (b.max(0.0) as usize + 1).min(n - 1))
        } else {
            (0, n - 1)
        };
        // the division is only a guess (a subnormal slab length is inexact): unless the
        // slabs found span the piece, all of them are examined
        let span = if a <= b && slabs[a].t.0 <= t0 && slabs[b].t.1 >= t1 { &slabs[a..=b] } else { &slabs[..] };
        span.iter().filter(|s| s.t.0 <= t1 && t0 <= s.t.1).all(|s| s.cover.as_ref().is_none_or(|b| !overlaps(b, bbox)))
    }

    /// The obstacles a piece must be checked against, given a proven spatial bounding
    /// box of the piece, in increasing order. **The caller must have proven that the piece
    /// stays in the workspace** (the covers say nothing outside it); `None`: every
    /// obstacle.
    pub fn candidates(&self, bbox: Option<&[(f64, f64)]>, t0: f64, t1: f64, out: &mut Vec<usize>) {
        let mut set = self.candidate_set();
        self.mark_candidates(bbox, t0, t1, &mut set);
        set.emit(out);
    }

    /// About how many obstacles the grid files under `bbox` (its cells in the box times
    /// the grid's mean entries per cell, plus the obstacles always checked), without
    /// visiting them: what lets [`SceneCertifier`](super::SceneCertifier) split a long
    /// piece before looking up its whole box (a diagonal piece's box spans thousands of
    /// cells). `None` without a grid (small scenes: every obstacle is tested directly).
    pub fn expected_candidates(&self, bbox: &[(f64, f64)]) -> Option<f64> {
        let g = self.grid.get()?;
        let clipped: Vec<(f64, f64)> = bbox
            .iter()
            .zip(self.lower.iter().zip(&self.upper))
            .map(|(&(lo, hi), (&l, &u))| (lo.max(l), hi.min(u)))
            .collect();
        let cells: f64 = g.cell_range(&self.lower, &clipped).iter().map(|&(a, b)| (b + 1 - a.min(b)) as f64).product();
        Some(cells * g.mean_entries + g.always.len() as f64)
    }

    /// The obstacles the grid files in the cell of point `x` and the ones always checked
    /// (an obstacle may be in both); `None` without a grid or for a point that is not
    /// finite. For guesses, not decisions.
    pub fn point_candidates(&self, x: &[f64]) -> Option<(&[u32], &[u32])> {
        let g = self.grid.get()?;
        if x.len() != self.lower.len() {
            return None;
        }
        if x.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let flat = (0..x.len()).rev().fold(0, |flat, d| flat * g.n[d] + g.axis_cell(&self.lower, d, x[d]));
        Some((g.cells[flat].as_slice(), g.always.as_slice()))
    }

    /// Whether obstacle `i`'s covers leave the point `x` at time `t` out (the check then
    /// proves the obstacle clear there: E\[P\] < 0 among the rest). For guesses.
    pub fn point_cleared(&self, i: usize, x: &[(f64, f64)], t: f64) -> bool {
        i < self.covers.len() && self.skippable(i, x, t, t)
    }

    /// An empty set of this scene's obstacles, for [`Self::mark_candidates`].
    pub fn candidate_set(&self) -> CandidateSet {
        let words = self.covers.len().div_ceil(64);
        CandidateSet { marked: vec![0; words], tested: vec![0; words] }
    }

    /// Adds to `set` the obstacles a piece (or a part of one) must be checked against,
    /// under the conditions of [`Self::candidates`]; the parts of a piece marked into one
    /// set give the union of their candidates. (A bit per obstacle instead of sorting and
    /// deduplicating the grid cells' lists: a long piece spans hundreds of cells, and on
    /// 512 disks the sorting cost more than checking the obstacles found.)
    pub fn mark_candidates(&self, bbox: Option<&[(f64, f64)]>, t0: f64, t1: f64, set: &mut CandidateSet) {
        let n = self.covers.len();
        // the covers say nothing outside the horizon either (a moving obstacle's slabs
        // end there, and the grid files it only by them): every obstacle then
        let in_horizon = self.horizon.0 <= t0 && t0 <= t1 && t1 <= self.horizon.1;
        let (Some(bbox), true) = (bbox, in_horizon) else {
            (0..n).for_each(|i| set.mark(i));
            return;
        };
        // the piece is in the workspace: clip its (outward-rounded) box to it
        let clipped: Vec<(f64, f64)> = bbox
            .iter()
            .zip(self.lower.iter().zip(&self.upper))
            .map(|(&(lo, hi), (&l, &u))| (lo.max(l), hi.min(u)))
            .collect();
        let bbox = clipped.as_slice();
        // each obstacle's covers are tested once for this box (`tested`), and only when
        // no earlier part marked it
        set.tested.iter_mut().for_each(|w| *w = 0);
        let consider = |i: usize, set: &mut CandidateSet| {
            let (w, b) = (i / 64, 1u64 << (i % 64));
            if (set.marked[w] | set.tested[w]) & b == 0 {
                set.tested[w] |= b;
                if !self.skippable(i, bbox, t0, t1) {
                    set.marked[w] |= b;
                }
            }
        };
        match self.grid.get() {
            None => (0..n).for_each(|i| consider(i, set)),
            Some(g) => {
                let range = g.cell_range(&self.lower, bbox);
                g.for_each_cell(&range, |c| g.cells[c].iter().for_each(|&i| consider(i as usize, set)));
                g.always.iter().for_each(|&i| consider(i as usize, set));
            }
        }
    }

    /// The median over the built covers of their largest side (a length scale for
    /// splitting long pieces: [`SceneIndex::sub_pieces_for`]); `None` before any is built.
    pub fn typical_extent(&self) -> Option<f64> {
        if let Some(&e) = self.extent.get() {
            return Some(e);
        }
        let mut sides: Vec<f64> = self
            .covers
            .iter()
            .filter_map(|c| c.get()?.slabs.as_ref())
            .flat_map(|slabs| slabs.iter().filter_map(|s| s.cover.as_ref()))
            .map(|b| b.iter().map(|(lo, hi)| hi - lo).fold(0.0, f64::max))
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        if sides.is_empty() {
            return None;
        }
        sides.sort_by(f64::total_cmp);
        let e = sides[sides.len() / 2];
        if self.complete() {
            let _ = self.extent.set(e);
        }
        Some(e)
    }

    /// How many equal parts in time a piece whose bounding box is `bbox` is split into
    /// for the cover tests: about its longest side over the covers' typical extent, at
    /// most `MAX_SUB_PIECES` (1: not split).
    pub fn sub_pieces_for(&self, bbox: &[(f64, f64)]) -> usize {
        let side = bbox.iter().map(|(lo, hi)| hi - lo).fold(0.0, f64::max);
        match self.typical_extent() {
            Some(e) if side.is_finite() => ((side / e).ceil() as usize).clamp(1, MAX_SUB_PIECES),
            _ => 1,
        }
    }

    /// The hull over time of each obstacle's cover (`None`: proven safe everywhere or no
    /// cover), for statistics and figures.
    pub fn cover_hulls(&self) -> Vec<Option<Vec<(f64, f64)>>> {
        self.covers
            .iter()
            .map(|c| {
                let boxes: Vec<&Vec<(f64, f64)>> =
                    c.get()?.slabs.as_ref()?.iter().filter_map(|s| s.cover.as_ref()).collect();
                let mut h = (*boxes.first()?).clone();
                for b in &boxes[1..] {
                    for (x, y) in h.iter_mut().zip(b.iter()) {
                        x.0 = x.0.min(y.0);
                        x.1 = x.1.max(y.1);
                    }
                }
                Some(h)
            })
            .collect()
    }

    /// Obstacles with a cover that is not the whole workspace (for statistics).
    pub fn filtered(&self) -> usize {
        self.covers.iter().filter(|c| c.get().is_some_and(|c| c.slabs.is_some())).count()
    }
}

/// Obstacle `i`'s covers at risk level `delta` and the cells its search evaluated:
/// a pedestrian's from its tail bound (§3.11), a static obstacle's one cover for all
/// time, a moving obstacle's per time slab ([`TIME_SLABS`], `stop` asked between
/// slabs; cut short, no slabs: always checked).
fn obstacle_covers(
    scene: &Scene,
    i: usize,
    delta: &num_rational::BigRational,
    stop: &dyn Fn() -> bool,
) -> (ObstacleCovers, usize) {
    let o = &scene.obstacles[i];
    let ws = &scene.workspace;
    let (h0, h1) = scene.horizon;
    if let Some(p) = &o.pedestrian {
        return match tail_kappa(p.disk.dim(), delta) {
            Some(k) => (pedestrian_covers(p, k, scene.horizon), 0),
            None => (ObstacleCovers { slabs: None, timeless: false }, 0),
        };
    }
    let center = scene.center();
    let dynamic = o.is_dynamic();
    let mut split: Vec<bool> = vec![true; scene.dim];
    split.push(dynamic);
    let slab_times: Vec<(f64, f64)> = if dynamic {
        (0..TIME_SLABS)
            .map(|k| {
                let a = if k == 0 { h0 } else { h0 + (h1 - h0) * k as f64 / TIME_SLABS as f64 };
                let b = if k + 1 == TIME_SLABS { h1 } else { h0 + (h1 - h0) * (k + 1) as f64 / TIME_SLABS as f64 };
                (a, b)
            })
            .collect()
    } else {
        vec![(center[scene.dim], center[scene.dim])]
    };
    let mut slabs = Vec::with_capacity(slab_times.len());
    let mut cells = 0;
    for t in slab_times {
        // a moving obstacle's slabs are the largest step between two questions
        if dynamic && stop() {
            return (ObstacleCovers { slabs: None, timeless: false }, cells);
        }
        let mut region: Vec<(f64, f64)> = ws.lower.iter().copied().zip(ws.upper.iter().copied()).collect();
        region.push(t);
        // centre the bounds near the obstacle: interval bounds of a polynomial expanded
        // around a far point lose to cancellation
        let c = obstacle_center(&o.contour, &region);
        let bounds = ConstraintBounds::new(&o.contour, delta, &c);
        let (cover, st) = unsafe_cover(&bounds, &region, &split);
        cells += st.cells;
        let cover = match cover {
            Cover::Empty => None,
            Cover::Box(mut b) => {
                b.truncate(scene.dim);
                Some(b)
            }
        };
        slabs.push(Slab { t, cover });
    }
    (ObstacleCovers { slabs: Some(Arc::new(slabs)), timeless: !dynamic }, cells)
}

/// Points per dimension of the grid on which [`obstacle_center`] looks for the largest
/// E\[P\] (a centre for the bounds, not a decision: any point works, a near one is better).
pub const CENTER_GRID: usize = 16;

/// A point of `region` (space, then a time interval) near the obstacle: the grid point
/// of largest E\[P\] at the middle time, in floats.
pub fn obstacle_center(contour: &riskplan_math::contour::RiskContour, region: &[(f64, f64)]) -> Vec<f64> {
    let dim = region.len() - 1;
    let t = 0.5 * region[dim].0 + 0.5 * region[dim].1;
    let mut best = (f64::NEG_INFINITY, region.iter().map(|(a, b)| 0.5 * a + 0.5 * b).collect::<Vec<f64>>());
    let n = CENTER_GRID;
    let total = n.pow(dim as u32);
    let mut x = vec![0.0; dim + 1];
    x[dim] = t;
    for k in 0..total {
        let mut r = k;
        for (d, xd) in x.iter_mut().enumerate().take(dim) {
            let i = r % n;
            r /= n;
            *xd = region[d].0 + (region[d].1 - region[d].0) * (i as f64 + 0.5) / n as f64;
        }
        let (m, _) = contour.moments_f64(&x);
        if m > best.0 {
            best = (m, x.clone());
        }
    }
    best.1
}

/// Most evaluations of E\[P\] [`refine_center`] spends on one obstacle (about 40 halvings
/// of its step over 2·dim directions: the step shrinks from a grid cell to ~10⁻¹² of it).
pub const CENTER_REFINE_EVALS: usize = 400;

/// [`obstacle_center`] refined by a compass search on E\[P\] at the point's time, inside
/// `region`: from `start`, a step of half a grid cell per axis is tried both ways, taken
/// when E\[P\] grows, halved when no direction helps, within [`CENTER_REFINE_EVALS`]. The
/// grid point may lie half a cell (a sixteenth of the workspace) from the obstacle; the
/// whole-path partition writes P about this point, and its interval ranges widen with the
/// distance from it (docs/design.md §5.14). Any point is sound; a near one is tighter.
pub fn refine_center(contour: &riskplan_math::contour::RiskContour, start: &[f64], region: &[(f64, f64)]) -> Vec<f64> {
    let dim = region.len() - 1;
    let mut x = start.to_vec();
    let value = |x: &[f64]| {
        let m = contour.moments_f64(x).0;
        if m.is_nan() {
            f64::NEG_INFINITY
        } else {
            m
        }
    };
    let mut best = value(&x);
    let mut step: Vec<f64> = (0..dim).map(|d| 0.5 * (region[d].1 - region[d].0) / CENTER_GRID as f64).collect();
    let mut evals = 1;
    while evals + 2 * dim <= CENTER_REFINE_EVALS {
        let mut moved = false;
        for d in 0..dim {
            for sign in [1.0, -1.0] {
                let mut y = x.clone();
                y[d] = (x[d] + sign * step[d]).clamp(region[d].0, region[d].1);
                let v = value(&y);
                evals += 1;
                if v > best {
                    (best, x, moved) = (v, y, true);
                    break;
                }
            }
        }
        if !moved {
            step.iter_mut().for_each(|s| *s *= 0.5);
            if step.iter().zip(region).all(|(s, r)| *s <= 1e-12 * (r.1 - r.0)) {
                break;
            }
        }
    }
    x
}

fn build_grid(scene: &Scene, covers: &[std::sync::OnceLock<ObstacleCovers>]) -> Grid {
    let ws = &scene.workspace;
    let dim = scene.dim;
    let total = (covers.len() * GRID_CELLS_PER_OBSTACLE).clamp(1, GRID_MAX_CELLS);
    let per = ((total as f64).powf(1.0 / dim as f64).floor() as usize).max(1);
    let n = vec![per; dim];
    let size: Vec<f64> = (0..dim).map(|d| (ws.upper[d] - ws.lower[d]) / per as f64).collect();
    let mut grid =
        Grid { n, size, cells: vec![Vec::new(); per.pow(dim as u32)], always: Vec::new(), mean_entries: 0.0 };
    for (i, c) in covers.iter().enumerate() {
        let Some(slabs) = c.get().and_then(|c| c.slabs.as_ref()) else {
            grid.always.push(i as u32);
            continue;
        };
        let boxes: Vec<&Vec<(f64, f64)>> = slabs.iter().filter_map(|s| s.cover.as_ref()).collect();
        if boxes.is_empty() {
            continue;
        }
        let mut hull = boxes[0].clone();
        for b in &boxes[1..] {
            for (h, x) in hull.iter_mut().zip(b.iter()) {
                h.0 = h.0.min(x.0);
                h.1 = h.1.max(x.1);
            }
        }
        let range = grid.cell_range(&ws.lower, &hull);
        let mut touched = Vec::new();
        grid.for_each_cell(&range, |cell| touched.push(cell));
        for cell in touched {
            grid.cells[cell].push(i as u32);
        }
    }
    grid.mean_entries = grid.cells.iter().map(Vec::len).sum::<usize>() as f64 / grid.cells.len() as f64;
    grid
}

/// One part of a piece: its proven spatial bounding box and its time interval.
pub type PartBox = (Vec<(f64, f64)>, (f64, f64));

/// Most parts a piece is split into for the cover tests ([`SceneIndex::sub_pieces_for`]).
pub const MAX_SUB_PIECES: usize = 32;

/// The piece split in time into `k` parts (the same polynomials on sub-intervals):
/// consecutive parts share their floating-point end times, the first starts at `t0` and
/// the last ends at `t1`, so the parts cover the piece whatever the rounding of the times
/// between. `None` unless `t0 ≤ t1`.
pub fn piece_parts<'a>(piece: PieceRef<'a>, k: usize) -> Option<Vec<PieceRef<'a>>> {
    let k = k.max(1);
    let (t0, t1) = (piece.t0, piece.t1);
    if t0.is_nan() || t1.is_nan() || t0 > t1 {
        return None;
    }
    let mut out = Vec::with_capacity(k);
    let mut a = t0;
    for j in 1..=k {
        let b = if j == k { t1 } else { (t0 + (t1 - t0) * (j as f64 / k as f64)).clamp(a, t1) };
        out.push(PieceRef { t0: a, t1: b, coeffs: piece.coeffs });
        a = b;
    }
    Some(out)
}

/// The piece's [`piece_parts`] with each part's proven bounding box ([`piece_bbox`]) and
/// time interval. `None` when a part's box is not available.
pub fn piece_sub_boxes(piece: PieceRef<'_>, k: usize) -> Option<Vec<PartBox>> {
    piece_parts(piece, k)?.into_iter().map(|p| Some((piece_bbox(p)?, (p.t0, p.t1)))).collect()
}

/// A proven bounding box of a piece's positions over its time interval, from the
/// Bernstein coefficients of each coordinate (convex hull property), or `None` when
/// the degree exceeds the compiled capacity or a bound is not finite.
pub fn piece_bbox(piece: PieceRef<'_>) -> Option<Vec<(f64, f64)>> {
    let t0 = Interval::point(piece.t0);
    let h = Interval::point(piece.t1) - t0;
    let lin = FPoly::<{ riskplan_scene::MAX_PIECE_DEGREE + 1 }>::linear(t0, h);
    let mut out = Vec::with_capacity(piece.coeffs.len());
    for row in piece.coeffs {
        let mut acc = FPoly::zero();
        for &c in row.iter().rev() {
            acc = acc.mul(&lin)?;
            acc.add_assign(&FPoly::constant(Interval::point(c)));
        }
        let b = crate::bernstein::bernstein_enclosure(acc.coeffs())?;
        if !(b.lo.is_finite() && b.hi.is_finite()) {
            return None;
        }
        out.push((b.lo, b.hi));
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A part of a piece in the marking test: its box (per axis) and its time interval.
    type MarkingPart = (Vec<(f64, f64)>, (f64, f64));

    proptest! {
        /// The parts' boxes cover the piece: every sampled point of the curve, evaluated
        /// directly (exact rationals, no code of the boxes), lies in the box of a part
        /// whose time interval holds its time — the property that lets the motion checker
        /// drop an obstacle whose cover misses every part.
        #[test]
        fn sub_boxes_cover_the_piece(
            coeffs in prop::collection::vec(prop::collection::vec(-1e3f64..1e3, 1..4), 2),
            t0 in -10.0f64..10.0,
            len in 1e-6f64..20.0,
            k in 1usize..40,
        ) {
            let t1 = t0 + len;
            let pr = PieceRef { t0, t1, coeffs: &coeffs };
            let parts = piece_sub_boxes(pr, k).expect("boxes of a low-degree piece");
            prop_assert_eq!(parts.len(), k);
            prop_assert_eq!(parts[0].1 .0, t0);
            prop_assert_eq!(parts[k - 1].1 .1, t1);
            for w in parts.windows(2) {
                prop_assert_eq!(w[0].1 .1, w[1].1 .0);
            }
            use num_rational::BigRational;
            for s in 0..=64 {
                let t = if s == 64 { t1 } else { t0 + len * s as f64 / 64.0 };
                let t = t.clamp(t0, t1);
                let tq = BigRational::from_float(t).unwrap();
                let x: Vec<BigRational> = coeffs
                    .iter()
                    .map(|row| row.iter().rev().fold(BigRational::from_integer(0.into()), |acc, &c| acc * &tq + BigRational::from_float(c).unwrap()))
                    .collect();
                let inside = parts.iter().any(|(b, (a, z))| {
                    *a <= t && t <= *z
                        && b.iter().zip(&x).all(|(&(lo, hi), v)| {
                            BigRational::from_float(lo).unwrap() <= *v && *v <= BigRational::from_float(hi).unwrap()
                        })
                });
                prop_assert!(inside, "t = {}", t);
            }
        }
    }

    /// `n` disks of uncertain size and centre in a square of side `side` (every seventh
    /// moving along x), from `rng`; the static ones' (index, centre x, centre y, radius).
    fn marking_scene(n: usize, side: f64, rng: &mut rand_chacha::ChaCha8Rng) -> (Scene, Vec<(usize, f64, f64, f64)>) {
        use rand::Rng;
        let mut params = serde_json::Map::new();
        let mut obstacles = Vec::new();
        let mut disks = Vec::new();
        for k in 0..n {
            let (cx, cy, r): (f64, f64, f64) = (
                (rng.random_range(0.0..side) * 100.0f64).round() / 100.0,
                (rng.random_range(0.0..side) * 100.0f64).round() / 100.0,
                (rng.random_range(0.8..1.6) * 100.0f64).round() / 100.0,
            );
            params.insert(format!("s{k}"), serde_json::json!({"dist": "uniform", "low": 0.9, "high": 1.1}));
            params.insert(format!("d{k}"), serde_json::json!({"dist": "normal", "mean": 0, "std": 0.05}));
            if k % 7 == 3 {
                // moving along x at speed ~ 1 (no closed form kept for it)
                obstacles.push(serde_json::json!({"id": format!("m{k}"), "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k} - t)^2 - (x2 - {cy})^2")}));
            } else {
                obstacles.push(serde_json::json!({"id": format!("disk{k}"), "poly": format!("({r}*s{k})^2 - (x1 - {cx} - d{k})^2 - (x2 - {cy})^2")}));
                disks.push((k, cx, cy, r));
            }
        }
        let text = serde_json::json!({
            "format": "riskplan-scene/1", "name": "marking", "dim": 2,
            "workspace": {"lower": [0, 0], "upper": [side, side]}, "horizon": [0, 1], "risk": 0.05,
            "params": params, "obstacles": obstacles,
        })
        .to_string();
        (riskplan_scene::Scene::from_json(&text).unwrap(), disks)
    }

    /// Covers built on several threads are those one thread builds, obstacle for obstacle
    /// (static and moving ones), and so is the grid; a build stopped on several threads
    /// leaves no grid, and a later call completes it.
    #[test]
    fn covers_built_on_several_threads_are_the_ones_built_on_one() {
        use rand::SeedableRng;
        let n = PARALLEL_COVERS_MIN + 9;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (scene, _) = marking_scene(n, 4.0 * (n as f64).sqrt() + 4.0, &mut rng);
        let deltas = vec![scene.risk.clone(); n];
        let one = SceneIndex::lazy(&scene, &deltas, &[]);
        one.ensure_all_on(&scene, &|| false, 1);
        let covers = |ix: &SceneIndex| -> Vec<String> { ix.covers.iter().map(|c| format!("{:?}", c.get())).collect() };
        for threads in [2, 3, MAX_COVER_BUILD_THREADS + 2] {
            let many = SceneIndex::lazy(&scene, &deltas, &[]);
            many.ensure_all_on(&scene, &|| false, threads);
            assert!(many.complete());
            assert_eq!(covers(&many), covers(&one), "{threads} threads");
            assert_eq!(format!("{:?}", many.grid.get()), format!("{:?}", one.grid.get()));
            assert_eq!(many.cells(), one.cells());
        }
        // stopped after a few obstacles (every thread asks the same `stop`): incomplete, no
        // grid; completed by a later call
        let stopped = SceneIndex::lazy(&scene, &deltas, &[]);
        let asked = std::sync::atomic::AtomicUsize::new(0);
        stopped.ensure_all_on(&scene, &|| asked.fetch_add(1, std::sync::atomic::Ordering::Relaxed) >= 5, 2);
        assert!(stopped.covers.iter().filter(|c| c.get().is_some()).count() <= 5);
        assert!(!stopped.complete());
        assert!(stopped.grid.get().is_none());
        stopped.ensure_all_on(&scene, &|| false, 2);
        assert_eq!(covers(&stopped), covers(&one));
    }

    /// Marking the parts of a piece into one set gives exactly the union over the
    /// parts of the obstacles not proven skippable for that part (naive filter per part,
    /// no bitset, no grid), on scene sizes around the 64-bit word boundaries, with moving
    /// obstacles and parts outside the horizon; and every disk a part's box meets at
    /// its certain-collision radius (closed form) is among them.
    #[test]
    fn marked_parts_are_the_union_of_the_parts_candidates() {
        use rand::{Rng, SeedableRng};
        for (n, seed) in [(1usize, 1u64), (15, 2), (16, 3), (63, 4), (64, 5), (65, 6), (129, 7)] {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let side = 4.0 * (n as f64).sqrt() + 4.0;
            let (scene, disks) = marking_scene(n, side, &mut rng);
            let deltas = vec![scene.risk.clone(); n];
            let index = SceneIndex::build(&scene, &deltas, &|| false);
            assert!(index.complete());
            assert_eq!(index.grid.get().is_some(), n >= GRID_MIN_OBSTACLES);
            let (mut nonempty, mut partial) = (0, 0);
            for _ in 0..400 {
                let k = rng.random_range(1..7);
                let parts: Vec<MarkingPart> = (0..k)
                    .map(|_| {
                        let w: f64 = rng.random_range(0.0..3.0);
                        let (x, y) = (rng.random_range(0.0..side - w), rng.random_range(0.0..side - w));
                        let t0: f64 = if rng.random_bool(0.05) { -0.5 } else { rng.random_range(0.0..1.0) };
                        let t1 = if rng.random_bool(0.05) { 1.5 } else { rng.random_range(t0.max(0.0)..=1.0) };
                        (vec![(x, x + w * rng.random_range(0.0..1.0)), (y, y + w)], (t0, t1))
                    })
                    .collect();
                let mut set = index.candidate_set();
                for (b, (a, z)) in &parts {
                    index.mark_candidates(Some(b), *a, *z, &mut set);
                }
                let mut got = Vec::new();
                set.emit(&mut got);
                let mut want: Vec<usize> = (0..n)
                    .filter(|&i| {
                        parts.iter().any(|(b, (a, z))| {
                            let in_h = 0.0 <= *a && a <= z && *z <= 1.0;
                            !in_h || !index.skippable(i, b, *a, *z)
                        })
                    })
                    .collect();
                want.sort_unstable();
                assert_eq!(got, want, "n = {n}, parts {parts:?}");
                // one part at a time, through `candidates`, united
                let mut united: Vec<usize> = Vec::new();
                let mut one = vec![usize::MAX; 3];
                for (b, (a, z)) in &parts {
                    index.candidates(Some(b), *a, *z, &mut one);
                    assert!(one.windows(2).all(|w| w[0] < w[1]));
                    united.extend(&one);
                }
                united.sort_unstable();
                united.dedup();
                assert_eq!(got, united);
                for &(i, cx, cy, r) in &disks {
                    let meets = parts.iter().any(|(b, _)| {
                        let dx = (b[0].0 - cx).max(cx - b[0].1).max(0.0);
                        let dy = (b[1].0 - cy).max(cy - b[1].1).max(0.0);
                        (dx * dx + dy * dy).sqrt() < 0.9 * r - 0.25
                    });
                    assert!(!meets || got.contains(&i), "disk {i} met but not a candidate (n = {n})");
                }
                nonempty += (!got.is_empty()) as usize;
                partial += (got.len() < n) as usize;
            }
            assert!(nonempty > 50 && partial > 50, "n = {n}: {nonempty} nonempty, {partial} partial");
        }
    }
}
