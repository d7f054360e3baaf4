//! The bounded job pool of the server: computation runs on blocking threads, at most
//! `workers` at once and `workers + queue` admitted (`busy` beyond), a job that waits
//! past its deadline never starts, and a panic becomes an `internal` error. Running
//! plans hold cancellation flags that shutdown sets.

use super::error::ServiceError;
use super::proto::QueueStatus;
use std::collections::BTreeMap;
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio::sync::Semaphore;

/// Threads for writes (`apply`), besides the workers: an update spends most of its
/// time waiting for the disk (the acknowledged revision is written, `fsync`ed and
/// renamed before the reply: several milliseconds here, against about one of
/// computation), which must not hold a worker that reads could use. Updates of one
/// scene are serialised by its write lock anyway; two lanes let two scenes' updates
/// overlap.
pub const WRITE_LANES: usize = 2;

/// The bounded job pool: `workers` permits for computation and [`WRITE_LANES`] for
/// writes; at most `workers + queue` jobs admitted in all.
#[derive(Debug)]
pub(crate) struct Jobs {
    sem: Arc<Semaphore>,
    writes: Arc<Semaphore>,
    workers: usize,
    capacity: usize,
    admitted: AtomicUsize,
    running: AtomicUsize,
}

impl Jobs {
    pub(crate) fn new(workers: usize, capacity: usize) -> Jobs {
        Jobs {
            sem: Arc::new(Semaphore::new(workers)),
            writes: Arc::new(Semaphore::new(WRITE_LANES)),
            workers,
            capacity,
            admitted: AtomicUsize::new(0),
            running: AtomicUsize::new(0),
        }
    }

    /// Runs `f` on a blocking thread, or answers `busy` at once when full. A job
    /// still waiting for a worker at `deadline` is dropped with `deadline_exceeded`
    /// (its work never starts). A panic in `f` becomes an `internal` error.
    pub(crate) async fn run<T: Send + 'static>(
        &self,
        deadline: Instant,
        f: impl FnOnce() -> Result<T, ServiceError> + Send + 'static,
    ) -> Result<T, ServiceError> {
        self.run_on(&self.sem, deadline, f).await
    }

    /// [`Jobs::run`] for a write (`apply`), on the write lanes ([`WRITE_LANES`]).
    pub(crate) async fn run_write<T: Send + 'static>(
        &self,
        deadline: Instant,
        f: impl FnOnce() -> Result<T, ServiceError> + Send + 'static,
    ) -> Result<T, ServiceError> {
        self.run_on(&self.writes, deadline, f).await
    }

    async fn run_on<T: Send + 'static>(
        &self,
        sem: &Arc<Semaphore>,
        deadline: Instant,
        f: impl FnOnce() -> Result<T, ServiceError> + Send + 'static,
    ) -> Result<T, ServiceError> {
        let limit = self.workers + self.capacity;
        let before = self.admitted.fetch_add(1, Ordering::SeqCst);
        if before >= limit {
            self.admitted.fetch_sub(1, Ordering::SeqCst);
            return Err(ServiceError::Busy(limit));
        }
        let permit = match tokio::time::timeout_at(deadline.into(), sem.clone().acquire_owned()).await {
            Ok(p) if Instant::now() < deadline => p,
            _ => {
                self.admitted.fetch_sub(1, Ordering::SeqCst);
                return Err(ServiceError::DeadlineExceeded("the request waited for a worker past its deadline".into()));
            }
        };
        self.running.fetch_add(1, Ordering::SeqCst);
        let r = tokio::task::spawn_blocking(move || std::panic::catch_unwind(AssertUnwindSafe(f))).await;
        self.running.fetch_sub(1, Ordering::SeqCst);
        self.admitted.fetch_sub(1, Ordering::SeqCst);
        drop(permit);
        match r {
            Ok(Ok(v)) => v,
            Ok(Err(p)) => Err(ServiceError::Internal(format!("a job panicked: {}", panic_text(&p)))),
            Err(e) => Err(ServiceError::Internal(format!("a job failed: {e}"))),
        }
    }

    /// Up to `most` idle workers' permits, taken without waiting, for a job that can
    /// split its work (a large `verify`): the job holds them while it runs, so no other
    /// job starts on those workers meanwhile; on a busy server it gets none and runs on
    /// its own worker alone. Dropping the returned permits gives the workers back.
    pub(crate) fn spare(&self, most: usize) -> Option<tokio::sync::OwnedSemaphorePermit> {
        (1..=most.min(u32::MAX as usize) as u32).rev().find_map(|k| self.sem.clone().try_acquire_many_owned(k).ok())
    }

    pub(crate) fn status(&self) -> QueueStatus {
        let admitted = self.admitted.load(Ordering::SeqCst) as u64;
        let running = self.running.load(Ordering::SeqCst) as u64;
        QueueStatus {
            depth: admitted.saturating_sub(running),
            running,
            workers: self.workers as u64,
            capacity: self.capacity as u64,
        }
    }
}

/// The cancellation flags of running jobs. Shutdown sets them all, so long plans
/// stop within one planner iteration instead of holding the process.
#[derive(Debug, Default)]
pub(crate) struct Cancels {
    flags: Mutex<BTreeMap<u64, Arc<AtomicBool>>>,
    next: AtomicU64,
    shutting_down: AtomicBool,
}

/// A registered cancellation flag; dropping it unregisters the flag.
pub(crate) struct CancelGuard<'a> {
    owner: &'a Cancels,
    id: u64,
    /// The flag to hand to the job.
    pub(crate) flag: Arc<AtomicBool>,
}

impl Drop for CancelGuard<'_> {
    fn drop(&mut self) {
        if let Ok(mut m) = self.owner.flags.lock() {
            m.remove(&self.id);
        }
    }
}

impl Cancels {
    /// A new flag, already set when shutdown has begun.
    pub(crate) fn register(&self) -> CancelGuard<'_> {
        let id = self.next.fetch_add(1, Ordering::Relaxed);
        let flag = Arc::new(AtomicBool::new(self.shutting_down.load(Ordering::SeqCst)));
        if let Ok(mut m) = self.flags.lock() {
            m.insert(id, flag.clone());
        }
        // A shutdown between the load above and the insert must not be missed.
        if self.shutting_down.load(Ordering::SeqCst) {
            flag.store(true, Ordering::SeqCst);
        }
        CancelGuard { owner: self, id, flag }
    }

    /// Sets every flag, now and for jobs registered later.
    pub(crate) fn cancel_all(&self) -> usize {
        self.shutting_down.store(true, Ordering::SeqCst);
        let m = self.flags.lock().map(|m| m.values().cloned().collect::<Vec<_>>()).unwrap_or_default();
        for f in &m {
            f.store(true, Ordering::SeqCst);
        }
        m.len()
    }
}

fn panic_text(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A large job takes the idle workers' permits and no more than it asks; a running
    /// job's worker is not idle; the permits come back when dropped.
    #[tokio::test]
    async fn spare_takes_only_idle_workers() {
        let jobs = Jobs::new(3, 0);
        let all = jobs.spare(8).expect("three idle workers");
        assert_eq!(all.num_permits(), 3);
        assert!(jobs.spare(1).is_none(), "no worker is idle");
        drop(all);
        let two = jobs.spare(2).expect("two of three");
        assert_eq!(two.num_permits(), 2);
        let last = jobs.spare(5).expect("the last one");
        assert_eq!(last.num_permits(), 1);
        assert!(jobs.spare(0).is_none(), "asking for none takes none");
        drop((two, last));
        // inside a job, its own worker is taken: the others are spare
        let spare = jobs.run(Instant::now() + std::time::Duration::from_secs(5), {
            let sem = jobs.sem.clone();
            move || Ok(sem.available_permits())
        });
        assert_eq!(spare.await.unwrap(), 2);
    }
}
