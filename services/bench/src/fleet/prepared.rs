//! A `bench fleet` floor made ready before anything is timed, and what every planning of it
//! (the run, the run alone, the first-come orders of `--orders`) asks with: the planners on
//! the floor's shared roadmaps, the robots' queries, the robots standing at their starts.

use std::path::Path;
use std::sync::Arc;

use planner::{
    FleetOptions, FleetSchedule, FloorDatabase, PlanPeople, PlanQuery, Planner, PolicyStore,
    RoadmapStore,
};
use rayon::prelude::*;
use rehearsal::{PlanOptions, PlanRequest};
use sim::Pose2;
use tosm::OccupancyGrid;

use super::{FleetBenchOptions, Floor, MemorySchedule, NoBuilds, floors, missions};
use crate::error::BenchError;

/// A floor made ready before anything is timed: a database (and world) per robot, the
/// missions, and the floor's configuration space and people in the roadmap cache every
/// planner of the floor shares.
pub(super) struct Prepared {
    pub(super) floor_iri: String,
    pub(super) dbs: Vec<(String, Arc<FloorDatabase>)>,
    pub(super) radius: f64,
    pub(super) missions: Vec<(Pose2, prm::Point2)>,
    /// The roadmap's samples among robots standing, as the planner samples it there.
    pub(super) dense_samples: usize,
    pub(super) people: sim::PeopleConfig,
    pub(super) roadmaps: Arc<rehearsal::RoadmapCache>,
    /// The planners' policy and roadmap store: nothing is stored, a temporary directory.
    pub(super) policies: tempfile::TempDir,
    pub(super) runtime: tokio::runtime::Runtime,
}

pub(super) fn prepare(
    opts: &FleetBenchOptions,
    name: &str,
    yaml: &Path,
    grid: OccupancyGrid,
    layout: Option<&floors::Layout>,
) -> Result<Prepared, BenchError> {
    let floor_iri = knowledge::maps::floor_iri(&knowledge::maps::name_for_path(yaml));
    let ttl = String::from_utf8_lossy(&opts.robot_ttl).into_owned();
    // One database (and world) per robot, built side by side.
    let dbs: Vec<(String, Arc<FloorDatabase>)> = (0..opts.robots)
        .into_par_iter()
        .map(|k| {
            let iri = format!("{}-{k}", opts.robot_iri);
            let turtle = ttl.replace(&opts.robot_iri, &iri);
            let graph = knowledge::maps::on_demand_database(
                yaml,
                grid.clone(),
                &[],
                turtle.as_bytes(),
                &iri,
            )?;
            let db = Arc::new(FloorDatabase::new(
                graph,
                iri.clone(),
                floor_iri.clone(),
                "bench",
            ));
            db.world().map_err(|e| BenchError::Format {
                path: yaml.to_path_buf(),
                message: e.to_string(),
            })?;
            Ok((iri, db))
        })
        .collect::<Result<_, BenchError>>()?;
    let world = dbs[0].1.world().map_err(|e| BenchError::Format {
        path: yaml.to_path_buf(),
        message: e.to_string(),
    })?;
    let radius = world.spec().robot.footprint_radius;
    floors::check_robot(
        opts.scenario,
        radius,
        PlanOptions::default().safety_margin_m,
    )?;
    let missions = missions(opts.scenario, layout, &world, opts.robots, opts.seed)?;
    let policies =
        tempfile::tempdir().map_err(crate::error::io_err(Path::new("temporary directory")))?;
    let roadmaps = Arc::new(rehearsal::RoadmapCache::default());
    // The floor's configuration space, once: every robot's world has the same geometry, so
    // all of them plan on it (as robots of one model do in the service).
    let space = rehearsal::config_space(
        &world,
        &roadmaps,
        world.geometry_key(),
        PlanOptions::default().safety_margin_m,
    )
    .map_err(|source| BenchError::Rehearsal {
        map: name.to_owned(),
        source,
    })?;
    // The floor's people too (where they walk and each target's path field), shared by every
    // robot's world alike: a service that has planned among people on the floor has them.
    if opts.people > 0.0 {
        world.people_targets().prepare(&world);
    }
    Ok(Prepared {
        floor_iri,
        dbs,
        radius,
        missions,
        dense_samples: prm::optimal_samples(space.free_area_m2)
            * rehearsal::executor::STANDING_DENSITY,
        people: sim::PeopleConfig {
            density: opts.people,
            ..sim::PeopleConfig::default()
        },
        roadmaps,
        policies,
        runtime: tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()
            .map_err(crate::error::io_err(Path::new("tokio runtime")))?,
    })
}

impl Prepared {
    /// A planner of the floor on the shared roadmaps, with `schedule` as its traffic schedule
    /// (`None`: none, every robot alone on the floor).
    pub(super) fn planner(&self, schedule: Option<&Arc<MemorySchedule>>) -> Arc<Planner> {
        let planner = Planner::new(
            Arc::new(Floor(self.dbs.iter().cloned().collect())),
            PolicyStore::new(self.policies.path()),
            Arc::clone(&self.roadmaps),
            RoadmapStore::new(self.policies.path().join("roadmaps")),
            Arc::new(NoBuilds),
        );
        Arc::new(match schedule {
            Some(s) => planner.with_fleet(Arc::clone(s) as Arc<dyn FleetSchedule>),
            None => planner,
        })
    }

    /// Every robot's query, all setting off at `t0`; `in_turn`: asked one at a time.
    pub(super) fn queries(
        &self,
        opts: &FleetBenchOptions,
        t0: i64,
        in_turn: bool,
    ) -> Vec<PlanQuery> {
        self.missions
            .iter()
            .zip(&self.dbs)
            .enumerate()
            .map(|(k, ((start, goal), (iri, _)))| PlanQuery {
                robot: iri.clone(),
                place: self.floor_iri.clone(),
                request: PlanRequest {
                    start: *start,
                    goals: vec![*goal],
                    options: PlanOptions {
                        // Each robot its own roadmap and draws, unless every robot asks as a
                        // fleet sending the default options does: one seed, one roadmap.
                        seed: if opts.same_seed {
                            opts.seed
                        } else {
                            opts.seed.wrapping_add(k as u64)
                        },
                        people: self.people.clone(),
                        ..PlanOptions::default()
                    },
                    stop: rehearsal::Stop::default(),
                },
                people: PlanPeople::AsGiven,
                policy: None,
                controller: None,
                fleet: FleetOptions {
                    start_unix_ms: Some(t0),
                    max_wait_s: opts.max_wait_s,
                    // Asked one at a time, nobody else is planning while a plan waits:
                    // refused at once, it asks again after the others.
                    standing_wait_s: if in_turn {
                        0.0
                    } else {
                        FleetOptions::default().standing_wait_s
                    },
                    ..FleetOptions::default()
                },
            })
            .collect()
    }

    /// Every robot is on the floor before any asks for a plan, and the schedule knows where
    /// it stands (as a fleet adapter reports its idle robots): until its plan is committed,
    /// no other plan drives through it, in whatever order they ask.
    pub(super) fn stand_all(
        &self,
        opts: &FleetBenchOptions,
        planner: &Planner,
        queries: &[PlanQuery],
        t0: i64,
        yaml: &Path,
    ) -> Result<(), BenchError> {
        let stand_for_s = opts.max_wait_s + FleetOptions::default().tolerance_s + 1.0;
        for q in queries {
            self.runtime
                .block_on(planner.stand(&q.robot, &q.place, q.request.start, Some(t0), stand_for_s))
                .map_err(|e| BenchError::Format {
                    path: yaml.to_path_buf(),
                    message: format!("{} cannot stand at its start: {e}", q.robot),
                })?;
        }
        Ok(())
    }
}
