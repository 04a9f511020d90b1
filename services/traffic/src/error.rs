//! What can go wrong with the traffic schedule: [`TrafficError`].

/// Why a schedule operation failed. Each variant names what is wrong; the HTTP edge maps them
/// to statuses (`Invalid` 422, `VersionChanged` 409, `NotFound` 404, `NotYourPlan` 403, ...).
#[derive(Debug, thiserror::Error)]
pub enum TrafficError {
    /// The itinerary or the request is malformed (the message says which field and why).
    #[error("invalid itinerary: {0}")]
    Invalid(String),
    /// Another commit, cancel or progress report changed the floor since the caller read it.
    #[error(
        "the traffic schedule of floor {floor:?} changed: expected version {expected}, it is now {now}"
    )]
    VersionChanged {
        /// The floor.
        floor: String,
        /// The version the caller planned against.
        expected: i64,
        /// The floor's version now.
        now: i64,
    },
    /// No unexpired itinerary has this plan id.
    #[error("no plan {plan_id:?} in the traffic schedule (unknown, cancelled or expired)")]
    NotFound {
        /// The plan id asked for.
        plan_id: String,
    },
    /// A robot reported progress on another robot's plan.
    #[error("plan {plan_id:?} belongs to robot {owner:?}, not to {robot:?}")]
    NotYourPlan {
        /// The plan id.
        plan_id: String,
        /// The robot that asked.
        robot: String,
        /// The robot the plan belongs to.
        owner: String,
    },
    /// A plan id already committed for another robot was committed again.
    #[error("plan id {plan_id:?} is already committed for robot {owner:?}")]
    PlanIdTaken {
        /// The plan id.
        plan_id: String,
        /// The robot holding it.
        owner: String,
    },
    /// A revision of a plan whose robot may have set off: it drives the plan as it is.
    #[error(
        "plan {plan_id:?} cannot be revised: its robot {robot:?} may have set off (it was told to leave at {departs_unix_ms} ms, Unix time)"
    )]
    SetOff {
        /// The plan id.
        plan_id: String,
        /// Its robot.
        robot: String,
        /// When the robot was told to leave its start, Unix milliseconds.
        departs_unix_ms: i64,
    },
    /// A progress report acknowledged a revision the plan never had.
    #[error(
        "plan {plan_id:?} is at revision {current}: revision {acknowledged} was never sent, so it cannot be acknowledged"
    )]
    UnknownRevision {
        /// The plan id.
        plan_id: String,
        /// The revision acknowledged.
        acknowledged: u32,
        /// The plan's revision.
        current: u32,
    },
    /// A stored row could not be read back (its trajectory JSON is damaged).
    #[error("plan {plan_id:?}: corrupt row in the traffic schedule: {message}")]
    Corrupt {
        /// The plan id of the row.
        plan_id: String,
        /// What is wrong with it.
        message: String,
    },
    /// The database holds a newer schedule schema than this build knows (a newer release
    /// migrated it): running an older build against it could lose data.
    #[error(
        "the traffic schedule in {url} has schema version {found}, newer than this build's {known}"
    )]
    SchemaTooNew {
        /// The database URL (password removed).
        url: String,
        /// The newest migration applied to the database.
        found: i64,
        /// The newest migration this build embeds.
        known: i64,
    },
    /// The database failed.
    #[cfg(feature = "store")]
    #[error("traffic schedule in {url}: {source}")]
    Database {
        /// The database URL (password removed).
        url: String,
        /// The driver's error.
        #[source]
        source: sqlx::Error,
    },
}
