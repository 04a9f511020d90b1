-- The job queue proper: any job kind (handlers are registered by kind, so the database does
-- not list them), a fencing token separate from the attempt count, heartbeats, checkpoints,
-- timestamps of the run, and an event log that streams progress with monotonic ids.
--
-- SQLite cannot drop a CHECK constraint, so the table is rebuilt and its rows copied.
-- Times are Unix milliseconds. Booleans are 0/1 (PostgreSQL: BOOLEAN). JSON is TEXT in both
-- backends so a payload reads back byte for byte as it was written.
DROP INDEX jobs_claimable;
DROP INDEX jobs_expired_leases;
ALTER TABLE jobs RENAME TO jobs_v1;

CREATE TABLE jobs (
    id               TEXT    PRIMARY KEY,        -- UUIDv7: time-ordered
    kind             TEXT    NOT NULL,           -- e.g. train, evaluate, validate
    state            TEXT    NOT NULL CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    payload          TEXT    NOT NULL,           -- JSON: the job's parameters
    priority         INTEGER NOT NULL DEFAULT 0, -- higher first
    attempt          INTEGER NOT NULL DEFAULT 0, -- counted attempts (a graceful release gives one back)
    max_attempts     INTEGER NOT NULL DEFAULT 3,
    lease_token      INTEGER NOT NULL DEFAULT 0, -- +1 on every claim, never reused: fences stale workers
    run_after_ms     INTEGER NOT NULL,           -- not claimable before (retry backoff)
    lease_owner      TEXT,
    lease_expires_ms INTEGER,
    heartbeat_ms     INTEGER,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    progress         TEXT,                       -- JSON: steps, episodes, success rate, ETA, ...
    checkpoint       TEXT,                       -- JSON: a reference (path, step, ...) to resume from
    checkpoint_blob  BLOB,                       -- optional bytes stored with the reference
    checkpoint_ms    INTEGER,
    result           TEXT,                       -- JSON
    last_error       TEXT,
    created_ms       INTEGER NOT NULL,
    updated_ms       INTEGER NOT NULL,
    started_ms       INTEGER,                    -- first claim
    finished_ms      INTEGER                     -- reached succeeded, failed or cancelled
);

INSERT INTO jobs (id, kind, state, payload, priority, attempt, max_attempts, lease_token,
                  run_after_ms, lease_owner, lease_expires_ms, cancel_requested, progress,
                  result, last_error, created_ms, updated_ms, finished_ms)
SELECT id, kind, state, payload, priority, attempt, max_attempts, attempt,
       run_after_ms, lease_owner, lease_expires_ms, cancel_requested, progress,
       result, last_error, created_ms, updated_ms, finished_ms
FROM jobs_v1;

DROP TABLE jobs_v1;

CREATE INDEX jobs_claimable ON jobs (state, priority DESC, run_after_ms, id);
CREATE INDEX jobs_leases ON jobs (state, lease_expires_ms);
CREATE INDEX jobs_finished ON jobs (finished_ms);

-- Everything that happened to a job, in order: state changes, progress, checkpoints. The id
-- is monotonic and never reused (AUTOINCREMENT), so an SSE client resumes with Last-Event-ID.
CREATE TABLE job_events (
    id         INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id     TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    kind       TEXT    NOT NULL,                 -- state, progress, checkpoint
    data       TEXT    NOT NULL,                 -- JSON
    created_ms INTEGER NOT NULL
);

CREATE INDEX job_events_by_job ON job_events (job_id, id);
