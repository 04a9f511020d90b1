-- Plan revisions: every committed itinerary has a revision (1 when committed; each revision of
-- its timing or route before its robot sets off adds one) and the revision its robot last
-- acknowledged in a progress report (the one it drives).
ALTER TABLE traffic_itineraries ADD COLUMN revision INTEGER NOT NULL DEFAULT 1;
ALTER TABLE traffic_itineraries ADD COLUMN acknowledged INTEGER NOT NULL DEFAULT 1;
