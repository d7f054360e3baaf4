//! Warming scenes' kernels in the background (docs/design.md §3.11, "Warm-ups"): on a
//! scene of many obstacles a first plan spends most of its time building the proven
//! covers, the final check's box tests and the whole-path reaches (on 512 disks about
//! 0.8 s of a 0.85 s cold plan), and each obstacle's compiled contour and bounds, which
//! plans build where their edges go (without them a first pass of plans took twice a
//! steady plan's time). After each commit that makes most of a scene new (an
//! `apply`, a put, a replica's install) and after the stored scenes are loaded, the server
//! builds them on a thread of its own, so that a plan arriving later finds them built; a
//! plan arriving meanwhile shares the builds.

use super::registry::WarmUpOutcome;
use super::state::State;
use riskplan_app::{warm_up, WarmUp};
use riskplan_scene::motion::Termination;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;

/// Scenes with at least this many obstacles are warmed: from this many on a scene index
/// builds every obstacle's covers at once (`certify::checker::LAZY_MAX_OBSTACLES`); below,
/// a cold plan builds only the covers of the obstacles its edges keep meeting, and is
/// fast (docs/benchmarks.md, "Cold start").
pub const WARM_MIN_OBSTACLES: usize = 16;

/// How often a warm-up looks whether its scene has a newer revision (then it is abandoned):
/// a registry lookup takes a lock and clones the entry, and the builds ask their `stop`
/// often; a warm-up of 512 disks takes about a second.
pub const SUPERSEDED_POLL: std::time::Duration = std::time::Duration::from_millis(10);

/// After `name` was committed whole at `revision` (an `apply` or a put of the scene, a
/// replica's install; not an update of obstacles, which the callers leave out): warms it
/// ([`start`]).
pub(crate) fn after_commit(state: &Arc<State>, name: &str, revision: u64) {
    start(state, vec![(name.to_string(), revision)]);
}

/// After the stored scenes and the `--preload` files are loaded: warms each of them, one
/// after another ([`start`]).
pub(crate) fn after_load(state: &Arc<State>) {
    start(state, state.registry.list().into_iter().map(|(name, revision, _)| (name, revision)).collect());
}

/// Whether `name` at `revision` is to be warmed: warm-ups are on (`serve --no-warm-up`),
/// it is live at that revision, it has at least [`WARM_MIN_OBSTACLES`] obstacles, and
/// fewer than half of them can take over what the previous revision built
/// (`SceneKernel::unchanged`: an update of a few obstacles is not warmed — its next plan
/// builds the rest in milliseconds — so that a crowd's stream of updates does not keep a
/// core busy).
fn wanted(state: &State, name: &str, revision: u64) -> bool {
    state.warm_up
        && state.registry.get(name).is_ok_and(|e| {
            let n = e.scene.obstacles.len();
            e.revision == revision && n >= WARM_MIN_OBSTACLES && e.kernel.unchanged() * 2 < n
        })
}

/// Queues the `scenes` (name, revision) that are [`wanted`] (the latest revision of a name
/// replaces an older one still waiting), and starts the warm-up thread unless it runs:
/// only when a worker is idle at this moment (a busy server warms nothing: the scenes are
/// counted skipped). The thread takes no worker, so a request arriving meanwhile starts at
/// once, on the machine's other cores; it warms the queued scenes one after another until
/// none is left. Never waits; each outcome is counted in `registry.kernels` (the metrics).
fn start(state: &Arc<State>, scenes: Vec<(String, u64)>) {
    let scenes: Vec<(String, u64)> = scenes.into_iter().filter(|(n, r)| wanted(state, n, *r)).collect();
    if scenes.is_empty() {
        return;
    }
    let Ok(runtime) = tokio::runtime::Handle::try_current() else { return };
    {
        let Ok(mut queue) = state.warm_queue.lock() else { return };
        for (name, revision) in scenes {
            queue.retain(|(n, _)| *n != name);
            queue.push((name, revision));
        }
    }
    if state.warming.swap(true, Ordering::SeqCst) {
        // the running thread takes them (it looks at the queue again after it clears
        // the flag)
        return;
    }
    if state.jobs.spare(1).is_none() {
        let dropped = state.warm_queue.lock().map(|mut q| std::mem::take(&mut *q).len()).unwrap_or(0);
        for _ in 0..dropped {
            state.registry.kernels.warm_up(WarmUpOutcome::Skipped);
        }
        state.warming.store(false, Ordering::SeqCst);
        return;
    }
    let st = state.clone();
    runtime.spawn_blocking(move || run(&st));
}

/// Clears the server's "warming" flag when dropped (a panic included).
struct Warming<'a>(&'a State);

impl Drop for Warming<'_> {
    fn drop(&mut self) {
        self.0.warming.store(false, Ordering::SeqCst);
    }
}

/// The warm-up thread: warms queued scenes until the queue is empty after the flag is
/// cleared (a scene queued between the last look and the clearing is taken by this thread
/// again, or by the next one started).
fn run(st: &State) {
    // shutdown sets the flag; the job deadline bounds each scene's warm-up as any job's
    let guard = st.cancels.register();
    loop {
        {
            let _warming = Warming(st);
            while let Some((name, revision)) =
                st.warm_queue.lock().ok().and_then(|mut q| (!q.is_empty()).then(|| q.remove(0)))
            {
                let Some(entry) = st.registry.get(&name).ok().filter(|e| e.revision == revision) else {
                    st.registry.kernels.warm_up(WarmUpOutcome::Skipped);
                    continue;
                };
                tracing::info!(scene = %name, revision, "warm-up started");
                let term = Termination::after(st.max_job_seconds).with_cancel(guard.flag.clone());
                // (a revision replaced meanwhile is abandoned: the new one is queued; looked
                // up at most every SUPERSEDED_POLL, as `stop` is asked between cells)
                let (looked, gone) = (std::cell::Cell::new(Instant::now()), std::cell::Cell::new(false));
                let superseded = || {
                    if !gone.get() && looked.get().elapsed() >= SUPERSEDED_POLL {
                        looked.set(Instant::now());
                        gone.set(!st.registry.get(&name).is_ok_and(|e| e.revision == revision));
                    }
                    gone.get()
                };
                let outcome = match warm_up(&entry.kernel, &|| term.should_stop() || superseded()) {
                    WarmUp::Done => WarmUpOutcome::Done,
                    WarmUp::Stopped if superseded() => WarmUpOutcome::Skipped,
                    WarmUp::Stopped => WarmUpOutcome::Stopped,
                };
                st.registry.kernels.warm_up(outcome);
                tracing::info!(scene = %name, revision, ?outcome, "warm-up");
            }
        }
        // the flag is clear: anything queued since is this thread's again, unless another
        // start took it
        let queued = st.warm_queue.lock().is_ok_and(|q| !q.is_empty());
        if !queued || guard.flag.load(Ordering::SeqCst) || st.warming.swap(true, Ordering::SeqCst) {
            return;
        }
    }
}
