//! Short reads run on the async worker that received them.
//!
//! Every read normally runs on a blocking thread ([`super::Deadline::read`]), so a long query
//! never stalls the async runtime. The hand-off costs two thread wake-ups per request: on a
//! small machine that is more CPU than a short lookup itself (measured: 240 µs of server CPU
//! per request for a query that finds nothing, against 90 µs for `oxigraph serve`, which
//! answers each connection on one thread), and while the threads wake, a core sits idle
//! (measured under `bench knowledge`'s four clients on two cores: 8% idle, against 1–3% for
//! `oxigraph serve`).
//!
//! A query whose last evaluation (same text, same dataset, same format) cost less than
//! [`BUDGET`] of CPU time and [`WALL_BUDGET`] of wall time runs again in place
//! ([`super::Deadline::read_remembered`]), on as many workers as the runtime has. What bounds
//! the time a worker is held is the leash: a watchdog thread cancels an in-place read's token
//! after [`LEASH`] (or at its deadline, if sooner), Oxigraph stops at its next step, and the
//! read runs again on a blocking thread with what is left of its deadline. So a query that was
//! short last time and has become slow (the data grew) holds its worker for at most the leash
//! plus one watchdog tick, once; it is then remembered as long. What is lost in place is the
//! early stop when a client hangs up mid-query: moot within the leash. A query never seen, or
//! long last time, takes the blocking path.
//!
//! All of this is one service's state, [`ReadState`], owned by its `Knowledge`: what runs in
//! place is remembered per service (and per text), the count of reads in place is bounded per
//! service, and each service's watchdog thread ends with it.

use std::collections::HashSet;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};
use std::time::{Duration, Instant};

use oxigraph::sparql::CancellationToken;

/// A read that cost less than this much CPU time last time may run in place: a count over a
/// few thousand rows (3 ms in `bench knowledge`) does, a scan of the store does not.
pub(super) const BUDGET: Duration = Duration::from_millis(5);

/// ... and took less than this much wall time: a read that waited on the disk costs little CPU
/// but would hold its worker for the whole wait. Generous, because on a loaded machine wall
/// time also counts the time other threads held the core.
pub(super) const WALL_BUDGET: Duration = Duration::from_millis(20);

/// How long a read may hold an async worker before it is stopped and sent to a blocking
/// thread (plus up to one watchdog [`TICK`]).
pub(super) const LEASH: Duration = Duration::from_millis(50);

/// What one read cost.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cost {
    /// CPU time of the evaluating thread; `None` when its clock cannot be read.
    pub cpu: Option<Duration>,
    /// Wall time.
    pub wall: Duration,
}

impl Cost {
    fn is_short(&self) -> bool {
        self.cpu.is_some_and(|cpu| cpu < BUDGET) && self.wall < WALL_BUDGET
    }
}

/// Measures a read's [`Cost`] on the thread that evaluates it. CPU time is the measure of
/// work: wall time alone would, on a busy machine, send every query the blocking way exactly
/// when the hand-off costs most.
pub(super) struct CostClock {
    cpu: Option<Duration>,
    wall: Instant,
}

impl CostClock {
    /// Starts measuring on this thread.
    pub(super) fn start() -> Self {
        Self {
            cpu: thread_cpu(),
            wall: Instant::now(),
        }
    }

    /// The cost since `start`, on the same thread.
    pub(super) fn elapsed(&self) -> Cost {
        Cost {
            cpu: thread_cpu()
                .zip(self.cpu)
                .map(|(now, then)| now.saturating_sub(then)),
            wall: self.wall.elapsed(),
        }
    }
}

fn thread_cpu() -> Option<Duration> {
    nix::time::clock_gettime(nix::time::ClockId::CLOCK_THREAD_CPUTIME_ID)
        .ok()
        .map(Duration::from)
}

/// Remembered query keys before the memory is cleared and relearned.
const CAPACITY: usize = 16_384;

/// What a read is: its text and everything else that changes its cost.
pub(super) fn key(parts: &[&str]) -> u64 {
    let mut hasher = DefaultHasher::new();
    parts.hash(&mut hasher);
    hasher.finish()
}

/// How one service's reads run: which were short last time, which run in place now, the
/// watchdog that keeps their leashes, and how many run at all.
///
/// Each [`crate::Knowledge`] owns one, so two services in one process (tests start many) learn
/// and count separately: what one was asked says nothing about the other's data. The watchdog
/// thread starts with the first read that may run in place and ends within a [`TICK`] of the
/// state being dropped.
pub(crate) struct ReadState {
    /// Keys of reads that were short the last time they ran.
    short: Mutex<HashSet<u64>>,
    /// Reads running in place now.
    in_place: AtomicUsize,
    /// Reads run in place since the service started.
    run_in_place: AtomicUsize,
    /// Reads running now, in place or on blocking threads (see [`Running`]).
    running: AtomicUsize,
    /// The tokens under watch; `None` when the watchdog thread could not start.
    watchdog: OnceLock<Option<Watchdog>>,
}

impl std::fmt::Debug for ReadState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReadState")
            .field("in_place", &self.in_place.load(Ordering::Relaxed))
            .field("running", &self.running.load(Ordering::Relaxed))
            .finish_non_exhaustive()
    }
}

impl ReadState {
    /// A service's state: nothing remembered, nothing running, no watchdog yet.
    pub(crate) fn new() -> Self {
        Self {
            short: Mutex::new(HashSet::new()),
            in_place: AtomicUsize::new(0),
            run_in_place: AtomicUsize::new(0),
            running: AtomicUsize::new(0),
            watchdog: OnceLock::new(),
        }
    }

    /// How many reads have run in place since the service started.
    #[cfg(test)]
    pub(super) fn run_in_place(&self) -> usize {
        self.run_in_place.load(Ordering::Relaxed)
    }

    /// Reads running now, in place or on blocking threads, including those whose client has
    /// gone and which are still unwinding.
    pub(crate) fn running(&self) -> usize {
        self.running.load(Ordering::Relaxed)
    }

    /// Counts one running read for as long as the guard lives.
    pub(super) fn enter(&self) -> Running<'_> {
        self.running.fetch_add(1, Ordering::Relaxed);
        Running { state: self }
    }

    fn short(&self) -> std::sync::MutexGuard<'_, HashSet<u64>> {
        self.short.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Remembers what the read `key` cost.
    pub(super) fn record(&self, key: u64, cost: Cost) {
        let mut short = self.short();
        if cost.is_short() {
            if short.len() >= CAPACITY {
                short.clear();
            }
            short.insert(key);
        } else {
            short.remove(&key);
        }
    }

    /// A permit to run `key` in place, when it was short last time, fewer reads than the
    /// runtime has workers run in place now, it is a multi-threaded runtime at all, and the
    /// watchdog keeps deadlines and leashes.
    pub(super) fn permit(&self, key: u64) -> Option<InPlace<'_>> {
        let handle = tokio::runtime::Handle::try_current().ok()?;
        if handle.runtime_flavor() != tokio::runtime::RuntimeFlavor::MultiThread {
            return None;
        }
        let spare = handle.metrics().num_workers();
        if !self.short().contains(&key) {
            return None;
        }
        let watchdog = self.watchdog()?;
        let mut running = self.in_place.load(Ordering::Relaxed);
        loop {
            if running >= spare {
                return None;
            }
            match self.in_place.compare_exchange_weak(
                running,
                running + 1,
                Ordering::AcqRel,
                Ordering::Relaxed,
            ) {
                Ok(_) => {
                    self.run_in_place.fetch_add(1, Ordering::Relaxed);
                    return Some(InPlace {
                        state: self,
                        watchdog,
                    });
                }
                Err(now) => running = now,
            }
        }
    }

    /// This service's watchdog, starting its thread on first use; `None` when no thread could
    /// be started, and then no read may run in place.
    fn watchdog(&self) -> Option<&Watchdog> {
        self.watchdog.get_or_init(Watchdog::start).as_ref()
    }
}

impl Default for ReadState {
    fn default() -> Self {
        Self::new()
    }
}

/// One read running in place; releases its slot when dropped.
pub(super) struct InPlace<'a> {
    state: &'a ReadState,
    watchdog: &'a Watchdog,
}

impl InPlace<'_> {
    /// Cancels `token` at `at` unless the returned guard is dropped first.
    pub(super) fn watch(&self, token: CancellationToken, at: Instant) -> Watched<'_> {
        self.watchdog.watch(token, at)
    }
}

impl Drop for InPlace<'_> {
    fn drop(&mut self) {
        self.state.in_place.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Counts one running read; uncounted when dropped.
pub(super) struct Running<'a> {
    state: &'a ReadState,
}

impl Drop for Running<'_> {
    fn drop(&mut self) {
        self.state.running.fetch_sub(1, Ordering::Relaxed);
    }
}

struct WatchState {
    next_id: u64,
    watched: Vec<(u64, Instant, CancellationToken)>,
}

/// The tokens under watch, with their deadlines, and the thread that cancels them. The thread
/// holds only a weak reference: it ends at its next tick once the watchdog is dropped.
struct Watchdog {
    watched: Arc<Mutex<WatchState>>,
    /// Alive as long as the thread runs (it holds the only strong reference): how a test sees
    /// that the thread ended.
    #[cfg(test)]
    thread_alive: std::sync::Weak<()>,
}

/// How often the watchdog looks. Waking it for every new read would cost the very thread
/// wake-up that running in place saves; deadlines are seconds, so a tick is precise enough.
const TICK: Duration = Duration::from_millis(20);

impl Watchdog {
    /// Starts the thread that, every [`TICK`], cancels the tokens whose deadline has passed.
    fn start() -> Option<Self> {
        let watched = Arc::new(Mutex::new(WatchState {
            next_id: 0,
            watched: Vec::new(),
        }));
        let weak = Arc::downgrade(&watched);
        let alive = Arc::new(());
        #[cfg(test)]
        let thread_alive = Arc::downgrade(&alive);
        let spawned = std::thread::Builder::new()
            .name("sparql-deadlines".to_owned())
            .spawn(move || {
                let _alive = alive;
                loop {
                    std::thread::sleep(TICK);
                    let Some(watched) = weak.upgrade() else {
                        return;
                    };
                    let now = Instant::now();
                    watched
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .watched
                        .retain(|(_, at, token)| {
                            if *at <= now {
                                token.cancel();
                                false
                            } else {
                                true
                            }
                        });
                }
            });
        match spawned {
            Ok(_) => Some(Self {
                watched,
                #[cfg(test)]
                thread_alive,
            }),
            Err(e) => {
                tracing::warn!(error = %e, "no SPARQL deadline watchdog: every query takes the blocking path");
                None
            }
        }
    }

    /// Cancels `token` at `at` unless the returned guard is dropped first.
    fn watch(&self, token: CancellationToken, at: Instant) -> Watched<'_> {
        let mut state = self.watched.lock().unwrap_or_else(PoisonError::into_inner);
        state.next_id += 1;
        let id = state.next_id;
        state.watched.push((id, at, token));
        Watched {
            watched: &self.watched,
            id,
        }
    }
}

/// A token under watch; unwatched when dropped.
pub(super) struct Watched<'a> {
    watched: &'a Mutex<WatchState>,
    id: u64,
}

impl Drop for Watched<'_> {
    fn drop(&mut self) {
        self.watched
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .watched
            .retain(|(id, _, _)| *id != self.id);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)] // reason: tests
mod tests {
    use super::*;

    #[test]
    fn the_watchdog_cancels_at_the_deadline_and_not_after_unwatch() {
        let state = ReadState::new();
        let watchdog = state.watchdog().expect("the watchdog runs");
        let fires = CancellationToken::new();
        let _watched = watchdog.watch(fires.clone(), Instant::now() + Duration::from_millis(30));
        let spared = CancellationToken::new();
        drop(watchdog.watch(spared.clone(), Instant::now() + Duration::from_millis(30)));
        let started = Instant::now();
        while !fires.is_cancelled() {
            assert!(
                started.elapsed() < Duration::from_secs(5),
                "never cancelled"
            );
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(started.elapsed() >= Duration::from_millis(25));
        std::thread::sleep(Duration::from_millis(50));
        assert!(!spared.is_cancelled());
    }

    #[test]
    fn the_watchdog_thread_ends_with_its_service() {
        let state = ReadState::new();
        let alive = state
            .watchdog()
            .expect("the watchdog runs")
            .thread_alive
            .clone();
        assert!(alive.upgrade().is_some());
        drop(state);
        let started = Instant::now();
        while alive.upgrade().is_some() {
            assert!(
                started.elapsed() < Duration::from_secs(5),
                "the watchdog thread outlived its service"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn cost(cpu_us: u64, wall_us: u64) -> Cost {
        Cost {
            cpu: Some(Duration::from_micros(cpu_us)),
            wall: Duration::from_micros(wall_us),
        }
    }

    #[test]
    fn a_read_is_short_by_its_cpu_time_and_not_waiting_long() {
        assert!(cost(300, 900).is_short());
        // Preempted on a busy machine: still short.
        assert!(cost(300, 9_000).is_short());
        // Real work.
        assert!(!cost(40_000, 40_000).is_short());
        // Waiting on the disk: little CPU, a long hold.
        assert!(!cost(300, 60_000).is_short());
        // No clock: not known to be short.
        assert!(
            !Cost {
                cpu: None,
                wall: Duration::from_micros(10)
            }
            .is_short()
        );
    }

    #[test]
    fn only_reads_short_last_time_get_a_permit() {
        let state = ReadState::new();
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(3)
            .build()
            .unwrap();
        let _entered = runtime.enter();
        let (fast, slow, unseen) = (key(&["fast"]), key(&["slow"]), key(&["unseen"]));
        state.record(fast, cost(300, 400));
        state.record(slow, cost(40_000, 40_000));
        assert!(state.permit(unseen).is_none());
        assert!(state.permit(slow).is_none());
        let first = state.permit(fast).expect("short last time");
        let second = state.permit(fast).expect("a second worker");
        let third = state.permit(fast).expect("a third worker");
        assert!(state.permit(fast).is_none(), "one read in place per worker");
        drop((first, second, third));
        assert!(state.permit(fast).is_some());
        assert_eq!(state.run_in_place(), 4);
        // Slow this time: the next run takes the blocking path.
        state.record(fast, cost(40_000, 40_000));
        assert!(state.permit(fast).is_none());
    }

    #[test]
    fn each_service_remembers_its_own_reads() {
        let (one, other) = (ReadState::new(), ReadState::new());
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .build()
            .unwrap();
        let _entered = runtime.enter();
        let fast = key(&["fast in one service"]);
        one.record(fast, cost(300, 400));
        let in_place = one.permit(fast).expect("short last time in this service");
        assert!(
            other.permit(fast).is_none(),
            "never run by the other service"
        );
        drop(in_place);
        assert_eq!((one.run_in_place(), other.run_in_place()), (1, 0));
        let running = one.enter();
        assert_eq!((one.running(), other.running()), (1, 0));
        drop(running);
        assert_eq!(one.running(), 0);
    }

    #[test]
    fn a_current_thread_runtime_never_runs_reads_in_place() {
        let state = ReadState::new();
        let runtime = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        let _entered = runtime.enter();
        let fast = key(&["fast on one thread"]);
        state.record(fast, cost(300, 400));
        assert!(state.permit(fast).is_none());
    }
}
