//! Building a scene index's covers on demand and looking up the obstacles a piece must be decided against.

use super::*;

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
    pub(super) fn skippable(&self, i: usize, bbox: &[(f64, f64)], t0: f64, t1: f64) -> bool {
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
    /// visiting them: what lets [`SceneCertifier`](crate::checker::SceneCertifier) split a long
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
