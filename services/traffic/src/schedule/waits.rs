//! The schedule's waits ([`crate::Wait`]): one row per waiting robot, written without the
//! write lock (a wait changes no floor's version and no itinerary).

use super::{Schedule, on_pool};
use crate::error::TrafficError;
use crate::wait::Wait;

impl Schedule {
    /// Says that `wait.robot`'s plan waits as `wait` (replacing what it said before), and
    /// forgets waits that ended before now.
    pub async fn post_wait(&self, wait: &Wait) -> Result<(), TrafficError> {
        wait.check()?;
        let body = serde_json::to_string(wait)
            .map_err(|e| TrafficError::Invalid(format!("a wait: {e}")))?;
        let now = self.now_ms();
        let err = |e| self.db_err(e);
        on_pool!(self, |pool, pg| {
            sqlx::query("DELETE FROM traffic_waits WHERE until_ms < $1")
                .bind(now)
                .execute(pool)
                .await
                .map_err(err)?;
            sqlx::query(
                "INSERT INTO traffic_waits (robot, floor, until_ms, body) VALUES ($1, $2, $3, $4) \
                 ON CONFLICT (robot) DO UPDATE SET floor = excluded.floor, \
                 until_ms = excluded.until_ms, body = excluded.body",
            )
            .bind(&wait.robot)
            .bind(&wait.floor)
            .bind(wait.until_unix_ms)
            .bind(body)
            .execute(pool)
            .await
            .map_err(err)?;
        });
        Ok(())
    }

    /// `robot`'s plan no longer waits.
    pub async fn clear_wait(&self, robot: &str) -> Result<(), TrafficError> {
        on_pool!(self, |pool, pg| {
            sqlx::query("DELETE FROM traffic_waits WHERE robot = $1")
                .bind(robot)
                .execute(pool)
                .await
                .map_err(|e| self.db_err(e))?;
        });
        Ok(())
    }

    /// The waits on `floor` that have not ended (by robot).
    pub async fn waits_on(&self, floor: &str) -> Result<Vec<Wait>, TrafficError> {
        let now = self.now_ms();
        let bodies: Vec<String> = on_pool!(self, |pool, pg| {
            sqlx::query_scalar(
                "SELECT body FROM traffic_waits WHERE floor = $1 AND until_ms >= $2 ORDER BY robot",
            )
            .bind(floor)
            .bind(now)
            .fetch_all(pool)
            .await
            .map_err(|e| self.db_err(e))?
        });
        bodies
            .iter()
            .map(|b| {
                serde_json::from_str(b)
                    .map_err(|e| TrafficError::Invalid(format!("a stored wait: {e}")))
            })
            .collect()
    }
}
