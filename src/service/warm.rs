//! Warming committed scenes' kernels in the background (docs/design.md §3.11, "Warm-ups"): on a scene
//! of many obstacles a first plan spends most of its time building the proven covers, the
//! final check's box tests and the whole-path reaches (on 512 disks about 0.8 s of a
//! 0.85 s cold plan). After each commit (an `apply`, a put, a replica's install) and after
//! the stored scenes are loaded, the server builds them on a worker that is idle at that
//! moment, so that a plan arriving later finds them built; a plan arriving meanwhile
//! builds what its search needs while the warm-up builds the rest.

use super::registry::WarmUpOutcome;
use super::state::State;
use crate::app::{warm_up, WarmUp};
use crate::motion::Termination;
use std::sync::atomic::Ordering;
use std::sync::Arc;

/// Scenes with at least this many obstacles are warmed: from this many on a scene index
/// builds every obstacle's covers at once (`certify::scene::LAZY_MAX_OBSTACLES`); below,
/// a cold plan builds only the covers of the obstacles its edges keep meeting, and is
/// fast (docs/benchmarks.md, issue 21 part 3).
pub const WARM_MIN_OBSTACLES: usize = 16;

/// Clears the server's "warming" flag when dropped (the warm-ups' end, or a panic).
struct Warming(Arc<State>);

impl Drop for Warming {
    fn drop(&mut self) {
        self.0.warming.store(false, Ordering::SeqCst);
    }
}

/// After `name` was committed at `revision`: warms it ([`start`]).
pub(crate) fn after_commit(state: &Arc<State>, name: &str, revision: u64) {
    start(state, vec![(name.to_string(), revision)]);
}

/// After the stored scenes and the `--preload` files are loaded: warms each of them, one
/// after another ([`start`]).
pub(crate) fn after_load(state: &Arc<State>) {
    start(state, state.registry.list().into_iter().map(|(name, revision, _)| (name, revision)).collect());
}

/// Warms `scenes` (name, revision) one after another on a blocking thread, when warm-ups
/// are on (`serve --no-warm-up`), no other warm-up is running and a worker is idle now:
/// the warm-up takes no worker, so a request arriving meanwhile starts at once, on the
/// machine's other cores. A scene with fewer than [`WARM_MIN_OBSTACLES`] obstacles, or
/// whose kernel has at least half of its obstacles unchanged from the previous revision
/// (`SceneKernel::unchanged`), is passed over; one whose live revision is no longer
/// `revision` is skipped (the newer revision's own commit warms it). Never waits; each outcome is counted in
/// `registry.kernels` (the metrics).
fn start(state: &Arc<State>, scenes: Vec<(String, u64)>) {
    if !state.warm_up {
        return;
    }
    // (a revision that changed a few obstacles of its predecessor takes over what was
    // built for the others, and its next plan builds the rest in milliseconds: not warmed,
    // so that a stream of small updates — a crowd — does not keep a core busy)
    let big = |name: &str, revision: u64| {
        state.registry.get(name).ok().filter(|e| {
            let n = e.scene.obstacles.len();
            e.revision == revision && n >= WARM_MIN_OBSTACLES && e.kernel.unchanged() * 2 < n
        })
    };
    let scenes: Vec<(String, u64)> = scenes.into_iter().filter(|(n, r)| big(n, *r).is_some()).collect();
    if scenes.is_empty() {
        return;
    }
    let Ok(runtime) = tokio::runtime::Handle::try_current() else { return };
    let skipped = |n: usize| {
        for _ in 0..n {
            state.registry.kernels.warm_up(WarmUpOutcome::Skipped);
        }
    };
    if state.warming.swap(true, Ordering::SeqCst) {
        return skipped(scenes.len());
    }
    let warming = Warming(state.clone());
    if state.jobs.spare(1).is_none() {
        return skipped(scenes.len());
    }
    let st = state.clone();
    runtime.spawn_blocking(move || {
        let _warming = warming;
        // shutdown sets the flag; the job deadline bounds each scene's warm-up as any job
        let guard = st.cancels.register();
        for (name, revision) in scenes {
            let Some(entry) = st.registry.get(&name).ok().filter(|e| e.revision == revision) else {
                st.registry.kernels.warm_up(WarmUpOutcome::Skipped);
                continue;
            };
            let term = Termination::after(st.max_job_seconds).with_cancel(guard.flag.clone());
            let outcome = match warm_up(&entry.kernel, &term) {
                WarmUp::Done => WarmUpOutcome::Done,
                WarmUp::Stopped => WarmUpOutcome::Stopped,
            };
            st.registry.kernels.warm_up(outcome);
            tracing::info!(scene = %name, revision, ?outcome, "warm-up");
        }
    });
}
