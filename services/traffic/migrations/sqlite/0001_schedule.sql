-- The fleet's traffic schedule: one row per committed itinerary (a robot has at most one),
-- and one version per floor, bumped by every commit, cancel and progress report on that floor.
-- Times are Unix milliseconds (INTEGER); durations seconds and lengths metres (REAL).
-- `trajectory` is JSON text: an array of [t_s, x, y, yaw] arrays.
CREATE TABLE traffic_itineraries (
    plan_id      TEXT    PRIMARY KEY,
    floor        TEXT    NOT NULL,
    robot        TEXT    NOT NULL,
    start_ms     INTEGER NOT NULL,
    expires_ms   INTEGER NOT NULL,  -- moves with the delay
    delay_s      REAL    NOT NULL,
    tolerance_s  REAL    NOT NULL,
    radius_m     REAL    NOT NULL,
    progress_t_s REAL,              -- trajectory time of the last progress report's match
    trajectory   TEXT    NOT NULL,
    committed_ms INTEGER NOT NULL,
    updated_ms   INTEGER NOT NULL
);

CREATE UNIQUE INDEX traffic_itineraries_robot ON traffic_itineraries (robot);
CREATE INDEX traffic_itineraries_floor ON traffic_itineraries (floor, expires_ms);
CREATE INDEX traffic_itineraries_expiry ON traffic_itineraries (expires_ms);

-- A floor without a row has version 0.
CREATE TABLE traffic_floors (
    floor   TEXT    PRIMARY KEY,
    version INTEGER NOT NULL
);
