-- The fleet's traffic schedule on PostgreSQL: the same schema as on SQLite.
-- Times are Unix milliseconds (BIGINT); durations seconds and lengths metres (DOUBLE PRECISION).
-- `trajectory` is JSON text (an array of [t_s, x, y, yaw] arrays), as on SQLite, so that it
-- reads back exactly as written.
CREATE TABLE traffic_itineraries (
    plan_id      TEXT             PRIMARY KEY,
    floor        TEXT             NOT NULL,
    robot        TEXT             NOT NULL,
    start_ms     BIGINT           NOT NULL,
    expires_ms   BIGINT           NOT NULL,
    delay_s      DOUBLE PRECISION NOT NULL,
    tolerance_s  DOUBLE PRECISION NOT NULL,
    radius_m     DOUBLE PRECISION NOT NULL,
    progress_t_s DOUBLE PRECISION,
    trajectory   TEXT             NOT NULL,
    committed_ms BIGINT           NOT NULL,
    updated_ms   BIGINT           NOT NULL
);

CREATE UNIQUE INDEX traffic_itineraries_robot ON traffic_itineraries (robot);
CREATE INDEX traffic_itineraries_floor ON traffic_itineraries (floor, expires_ms);
CREATE INDEX traffic_itineraries_expiry ON traffic_itineraries (expires_ms);

CREATE TABLE traffic_floors (
    floor   TEXT   PRIMARY KEY,
    version BIGINT NOT NULL
);
