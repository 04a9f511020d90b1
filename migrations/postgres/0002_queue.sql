-- The job queue on PostgreSQL: the same schema as SQLite after its 0002 (numbered 0002 so that
-- the two backends' versions line up; SQLite's 0001 predates the PostgreSQL backend).
-- Times are Unix milliseconds (BIGINT). JSON is TEXT so a payload reads back byte for byte as
-- written, as on SQLite. Claims use FOR UPDATE SKIP LOCKED.
CREATE TABLE jobs (
    id               TEXT    PRIMARY KEY,
    kind             TEXT    NOT NULL,
    state            TEXT    NOT NULL CHECK (state IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    payload          TEXT    NOT NULL,
    priority         BIGINT  NOT NULL DEFAULT 0,
    attempt          BIGINT  NOT NULL DEFAULT 0,
    max_attempts     BIGINT  NOT NULL DEFAULT 3,
    lease_token      BIGINT  NOT NULL DEFAULT 0,
    run_after_ms     BIGINT  NOT NULL,
    lease_owner      TEXT,
    lease_expires_ms BIGINT,
    heartbeat_ms     BIGINT,
    cancel_requested BOOLEAN NOT NULL DEFAULT FALSE,
    progress         TEXT,
    checkpoint       TEXT,
    checkpoint_blob  BYTEA,
    checkpoint_ms    BIGINT,
    result           TEXT,
    last_error       TEXT,
    created_ms       BIGINT  NOT NULL,
    updated_ms       BIGINT  NOT NULL,
    started_ms       BIGINT,
    finished_ms      BIGINT
);

CREATE INDEX jobs_claimable ON jobs (state, priority DESC, run_after_ms, id);
CREATE INDEX jobs_leases ON jobs (state, lease_expires_ms);
CREATE INDEX jobs_finished ON jobs (finished_ms);

-- Event ids come from an identity sequence. Every event insert runs in the transaction that
-- updates its job's row first, so events of one job are numbered and committed in order.
CREATE TABLE job_events (
    id         BIGINT  GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
    job_id     TEXT    NOT NULL REFERENCES jobs (id) ON DELETE CASCADE,
    kind       TEXT    NOT NULL,
    data       TEXT    NOT NULL,
    created_ms BIGINT  NOT NULL
);

CREATE INDEX job_events_by_job ON job_events (job_id, id);
