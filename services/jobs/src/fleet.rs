//! The planner's fleet schedule: the `traffic` store in the job database the queue opened
//! (SQLite by default, PostgreSQL beyond one machine), so every API process sharing that
//! database shares the schedule.

use std::future::Future;
use std::sync::Arc;

use planner::PortError;
use planner::fleet::{Committed, FleetFuture, FleetSchedule};
use queue::LazyQueue;
use tokio::sync::OnceCell;
use traffic::{Itinerary, Schedule, TrafficError};

/// The floor schedules in the queue's database, opened on first use.
#[derive(Debug)]
pub struct QueueFleet {
    queue: Arc<LazyQueue>,
    schedule: OnceCell<Schedule>,
}

impl QueueFleet {
    /// The schedule in `queue`'s database.
    pub fn new(queue: Arc<LazyQueue>) -> Self {
        Self {
            queue,
            schedule: OnceCell::new(),
        }
    }

    /// `read` of the schedule, run to its end on a blocking thread (the store's calls block);
    /// `doing` names it in an error.
    async fn read<T, F, Fut>(&self, doing: &'static str, read: F) -> Result<T, PortError>
    where
        T: Send + 'static,
        F: FnOnce(Schedule) -> Fut + Send + 'static,
        Fut: Future<Output = Result<T, TrafficError>>,
    {
        let schedule = self.schedule().await?.clone();
        on_own_thread(doing, move || futures_block_on(read(schedule)))
            .await?
            .map_err(|e| PortError::new(doing, e))
    }

    /// The schedule, opening (and migrating) its tables on first use.
    pub async fn schedule(&self) -> Result<&Schedule, PortError> {
        const DOING: &str = "opening the traffic schedule";
        self.schedule
            .get_or_try_init(|| async {
                let queue = self
                    .queue
                    .get()
                    .await
                    .map_err(|e| PortError::new(DOING, e))?;
                let db = queue.database().clone();
                on_own_thread(DOING, move || futures_block_on(Schedule::open(&db)))
                    .await?
                    .map_err(|e| PortError::new(DOING, e))
            })
            .await
    }
}

impl FleetSchedule for QueueFleet {
    fn snapshot<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, (i64, Vec<Itinerary>)> {
        let floor = floor.to_owned();
        Box::pin(
            self.read("reading the floor's traffic schedule", |s| async move {
                let now = s.now_ms();
                s.snapshot(&floor, now).await
            }),
        )
    }

    fn version<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, i64> {
        let floor = floor.to_owned();
        Box::pin(
            self.read("reading the floor's schedule version", |s| async move {
                s.version(&floor).await
            }),
        )
    }

    fn commit(&self, itinerary: Itinerary, expected_version: i64) -> FleetFuture<'_, Committed> {
        Box::pin(async move {
            let schedule = self.schedule().await?.clone();
            const DOING: &str = "committing to the floor's traffic schedule";
            let committed = on_own_thread(DOING, move || {
                futures_block_on(schedule.commit(itinerary, expected_version))
            })
            .await?;
            match committed {
                Ok(v) => Ok(Committed::Yes(v)),
                Err(TrafficError::VersionChanged { .. }) => Ok(Committed::VersionChanged),
                Err(e @ (TrafficError::Invalid(_) | TrafficError::PlanIdTaken { .. })) => {
                    Ok(Committed::Refused(format!("the traffic schedule: {e}")))
                }
                Err(e) => Err(PortError::new(DOING, e)),
            }
        })
    }

    fn revise(&self, plans: Vec<Itinerary>, expected_version: i64) -> FleetFuture<'_, Committed> {
        Box::pin(async move {
            let schedule = self.schedule().await?.clone();
            const DOING: &str = "revising plans in the floor's traffic schedule";
            let revised = on_own_thread(DOING, move || {
                futures_block_on(schedule.revise(plans, expected_version))
            })
            .await?;
            match revised {
                Ok((v, _)) => Ok(Committed::Yes(v)),
                Err(TrafficError::VersionChanged { .. }) => Ok(Committed::VersionChanged),
                Err(
                    e @ (TrafficError::Invalid(_)
                    | TrafficError::SetOff { .. }
                    | TrafficError::NotFound { .. }),
                ) => Ok(Committed::Refused(format!("the traffic schedule: {e}"))),
                Err(e) => Err(PortError::new(DOING, e)),
            }
        })
    }

    fn planned<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, Vec<traffic::Planned>> {
        let floor = floor.to_owned();
        Box::pin(self.read("reading the floor's plans", |s| async move {
            s.plans_on(&floor).await
        }))
    }

    fn post_wait(&self, wait: traffic::Wait) -> FleetFuture<'_, ()> {
        Box::pin(self.read("saying that a plan waits", |s| async move {
            s.post_wait(&wait).await
        }))
    }

    fn clear_wait<'a>(&'a self, robot: &'a str) -> FleetFuture<'a, ()> {
        let robot = robot.to_owned();
        Box::pin(
            self.read("saying that a plan no longer waits", |s| async move {
                s.clear_wait(&robot).await
            }),
        )
    }

    fn waits<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, Vec<traffic::Wait>> {
        let floor = floor.to_owned();
        Box::pin(
            self.read("reading the plans waiting on the floor", |s| async move {
                s.waits_on(&floor).await
            }),
        )
    }

    fn now_ms(&self) -> i64 {
        self.schedule
            .get()
            .map_or_else(now_unix_ms, Schedule::now_ms)
    }
}

/// The wall clock, ms since the Unix epoch.
fn now_unix_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// Runs `f` on the runtime's blocking pool. The schedule's calls run there, each driven to
/// completion with [`futures_block_on`]: rustc cannot prove sqlx's transaction futures `Send`
/// for every lifetime inside a boxed trait future (the "`Executor` is not general enough"
/// limitation of async generators), and a blocking thread needs no such proof.
async fn on_own_thread<T: Send + 'static>(
    doing: &'static str,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<T, PortError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| PortError::new(doing, e))
}

/// Drives `future` to completion on this (blocking-pool) thread, within the runtime.
fn futures_block_on<F: Future>(future: F) -> F::Output {
    tokio::runtime::Handle::current().block_on(future)
}
