-- Waits: a plan waiting for robots standing in its way with no plan yet, one row per waiting
-- robot, so the processes sharing the database see each other's waits (a cycle of waits is
-- found across processes). `body` is the wait as JSON text; `until_ms` (Unix ms) ends it at the
-- latest, so a process that died leaves no wait behind.
CREATE TABLE traffic_waits (
    robot    TEXT   PRIMARY KEY,
    floor    TEXT   NOT NULL,
    until_ms BIGINT NOT NULL,
    body     TEXT   NOT NULL
);

CREATE INDEX traffic_waits_floor ON traffic_waits (floor, until_ms);
