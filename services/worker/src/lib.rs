//! Simulation worker service: durable job queue, job runners, plan endpoint, jobs API.
