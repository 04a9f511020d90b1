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

use std::collections::HashSet;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock, PoisonError};
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

/// Keys of reads that were short the last time they ran.
static SHORT: OnceLock<Mutex<HashSet<u64>>> = OnceLock::new();
/// Reads running in place now.
static IN_PLACE: AtomicUsize = AtomicUsize::new(0);
/// Reads run in place since the process started.
static RUN_IN_PLACE: AtomicUsize = AtomicUsize::new(0);

/// How many reads have run in place since the process started.
#[cfg(test)]
pub(super) fn run_in_place() -> usize {
    RUN_IN_PLACE.load(Ordering::Relaxed)
}

fn short() -> &'static Mutex<HashSet<u64>> {
    SHORT.get_or_init(|| Mutex::new(HashSet::new()))
}

/// Remembers what the read `key` cost.
pub(super) fn record(key: u64, cost: Cost) {
    let mut short = short().lock().unwrap_or_else(PoisonError::into_inner);
    if cost.is_short() {
        if short.len() >= CAPACITY {
            short.clear();
        }
        short.insert(key);
    } else {
        short.remove(&key);
    }
}

/// A permit to run `key` in place, when it was short last time, fewer reads than the runtime
/// has workers run in place now, it is a multi-threaded runtime at all, and the watchdog keeps
/// deadlines and leashes.
pub(super) fn permit(key: u64) -> Option<InPlace> {
    let handle = tokio::runtime::Handle::try_current().ok()?;
    if handle.runtime_flavor() != tokio::runtime::RuntimeFlavor::MultiThread {
        return None;
    }
    let spare = handle.metrics().num_workers();
    if !short()
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .contains(&key)
    {
        return None;
    }
    if !watchdog_running() {
        return None;
    }
    let mut running = IN_PLACE.load(Ordering::Relaxed);
    loop {
        if running >= spare {
            return None;
        }
        match IN_PLACE.compare_exchange_weak(
            running,
            running + 1,
            Ordering::AcqRel,
            Ordering::Relaxed,
        ) {
            Ok(_) => {
                RUN_IN_PLACE.fetch_add(1, Ordering::Relaxed);
                return Some(InPlace);
            }
            Err(now) => running = now,
        }
    }
}

/// One read running in place; releases its slot when dropped.
pub(super) struct InPlace;

impl Drop for InPlace {
    fn drop(&mut self) {
        IN_PLACE.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Cancels `token` at `at` unless the returned guard is dropped first.
pub(super) fn watch(token: CancellationToken, at: Instant) -> Watched {
    let mut state = WATCHED.lock().unwrap_or_else(PoisonError::into_inner);
    state.next_id += 1;
    let id = state.next_id;
    state.watched.push((id, at, token));
    Watched { id }
}

/// A token under watch; unwatched when dropped.
pub(super) struct Watched {
    id: u64,
}

impl Drop for Watched {
    fn drop(&mut self) {
        WATCHED
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .watched
            .retain(|(id, _, _)| *id != self.id);
    }
}

struct WatchState {
    next_id: u64,
    watched: Vec<(u64, Instant, CancellationToken)>,
}

/// The tokens under watch, with their deadlines.
static WATCHED: Mutex<WatchState> = Mutex::new(WatchState {
    next_id: 0,
    watched: Vec::new(),
});

/// How often the watchdog looks. Waking it for every new read would cost the very thread
/// wake-up that running in place saves; deadlines are seconds, so a tick is precise enough.
const TICK: Duration = Duration::from_millis(20);

/// Whether the process's one watchdog thread runs, starting it on first use. Every [`TICK`] it
/// cancels the tokens whose deadline has passed. Without it no read may run in place.
fn watchdog_running() -> bool {
    static RUNNING: OnceLock<bool> = OnceLock::new();
    *RUNNING.get_or_init(|| {
        let spawned = std::thread::Builder::new()
            .name("sparql-deadlines".to_owned())
            .spawn(|| {
                loop {
                    std::thread::sleep(TICK);
                    let now = Instant::now();
                    WATCHED
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
        if let Err(e) = &spawned {
            tracing::warn!(error = %e, "no SPARQL deadline watchdog: every query takes the blocking path");
        }
        spawned.is_ok()
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)] // reason: tests
pub(super) mod tests {
    use super::*;

    /// Tests that count permits, which are process-wide, take turns.
    pub(in crate::protocol) static PERMITS: Mutex<()> = Mutex::new(());

    #[test]
    fn the_watchdog_cancels_at_the_deadline_and_not_after_unwatch() {
        assert!(watchdog_running());
        let fires = CancellationToken::new();
        let _watched = watch(fires.clone(), Instant::now() + Duration::from_millis(30));
        let spared = CancellationToken::new();
        drop(watch(
            spared.clone(),
            Instant::now() + Duration::from_millis(30),
        ));
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
        let _turn = PERMITS.lock().unwrap_or_else(PoisonError::into_inner);
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(3)
            .build()
            .unwrap();
        let _entered = runtime.enter();
        let (fast, slow, unseen) = (key(&["fast"]), key(&["slow"]), key(&["unseen"]));
        record(fast, cost(300, 400));
        record(slow, cost(40_000, 40_000));
        assert!(permit(unseen).is_none());
        assert!(permit(slow).is_none());
        let first = permit(fast).expect("short last time");
        let second = permit(fast).expect("a second worker");
        let third = permit(fast).expect("a third worker");
        assert!(permit(fast).is_none(), "one read in place per worker");
        drop((first, second, third));
        assert!(permit(fast).is_some());
        // Slow this time: the next run takes the blocking path.
        record(fast, cost(40_000, 40_000));
        assert!(permit(fast).is_none());
    }

    #[test]
    fn a_current_thread_runtime_never_runs_reads_in_place() {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .build()
            .unwrap();
        let _entered = runtime.enter();
        let fast = key(&["fast on one thread"]);
        record(fast, cost(300, 400));
        assert!(permit(fast).is_none());
    }
}
