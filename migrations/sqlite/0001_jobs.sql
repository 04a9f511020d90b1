-- The durable job queue: one row per job. Times are Unix milliseconds (INTEGER) so that
-- ordering and lease arithmetic are exact on SQLite and PostgreSQL alike.
CREATE TABLE jobs (
    id               TEXT    PRIMARY KEY,               -- UUIDv7: time-ordered
    kind             TEXT    NOT NULL CHECK (kind IN ('train', 'evaluate', 'validate')),
    state            TEXT    NOT NULL CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    payload          TEXT    NOT NULL,                  -- JSON: the job's parameters
    priority         INTEGER NOT NULL DEFAULT 0,
    attempt          INTEGER NOT NULL DEFAULT 0,        -- incremented on every claim; fences stale workers
    max_attempts     INTEGER NOT NULL DEFAULT 3,
    run_after_ms     INTEGER NOT NULL,                  -- not claimable before (retry backoff)
    lease_owner      TEXT,
    lease_expires_ms INTEGER,
    cancel_requested INTEGER NOT NULL DEFAULT 0,
    progress         TEXT,                              -- JSON: steps, episodes, success rate, ...
    result           TEXT,                              -- JSON
    last_error       TEXT,
    created_ms       INTEGER NOT NULL,
    updated_ms       INTEGER NOT NULL,
    finished_ms      INTEGER
);

CREATE INDEX jobs_claimable ON jobs (state, run_after_ms, priority DESC, id);
CREATE INDEX jobs_expired_leases ON jobs (state, lease_expires_ms);
