//! The mental-simulation benchmark: environment steps per second on one core and on all cores
//! with 23 beams on a furnished real map, the time to build that world, and IR-SIM and IR-SIM-X
//! (Python subprocesses) on the same map, beam count and episodes, side by side.
//!
//! The world is built the way the service builds it: the ROS map becomes a TOSM metric map, the
//! furniture becomes TOSM objects, and the simulation parser reads them back into a world. The
//! time of that path (map bytes in memory to a world ready to step) is `world_build_s`; reading
//! the files is timed apart because the service reads its database, not files.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;
use sim::{Action, EnvBatch, EnvConfig, NavEnv, ObjectSpec, Observation, Outcome, Shape, World};

use crate::error::{BenchError, io_err};

/// The paper's Gazebo set-up: about 2.4 experiences per second (§5.2: ~1 million experiences in
/// 116 hours).
pub const PAPER_GAZEBO_STEPS_PER_S: f64 = 1_000_000.0 / (116.0 * 3600.0);
/// A bare C grid ray caster with 23 beams and no physics, measured on this machine class.
pub const C_GRID_RAYCASTER_STEPS_PER_S: f64 = 180_000.0;
/// Target: environment steps per second on one core.
pub const TARGET_STEPS_PER_S_ONE_CORE: f64 = 100_000.0;
/// Target: seconds to build the largest map's world from its on-demand database.
pub const TARGET_WORLD_BUILD_S: f64 = 1.0;

/// A Python peer to run beside us.
#[derive(Debug, Clone, PartialEq)]
pub struct PeerOptions {
    /// Interpreter of a virtual environment with the peer installed (`ir-sim` or `irsim-x`: they
    /// install the same `irsim` module, so each needs its own environment).
    pub python: PathBuf,
}

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct SimBenchOptions {
    /// The ROS map_server YAML (default: the largest shared map, cob_ipa_production_plant).
    pub map_yaml: PathBuf,
    /// Laser readings per observation.
    pub beams: usize,
    /// Objects to furnish the map with (a mix of library models and placeholders).
    pub objects: usize,
    /// Timed steps on one core.
    pub steps_one_core: u64,
    /// Environments in the all-core batch.
    pub batch_envs: usize,
    /// Timed steps on all cores, summed over the batch.
    pub steps_all_cores: u64,
    /// Seed of the furniture, the episodes and the environments.
    pub seed: u64,
    /// IR-SIM (PyPI `ir-sim`), if it is to run.
    pub irsim: Option<PeerOptions>,
    /// IR-SIM-X (PyPI `irsim-x`), if it is to run.
    pub irsim_x: Option<PeerOptions>,
    /// The peer script (`services/bench/scripts/irsim_bench.py`).
    pub peer_script: PathBuf,
    /// Steps each peer takes at most.
    pub peer_steps: u64,
    /// Seconds each peer steps at most (IR-SIM is slow on a map this size).
    pub peer_step_seconds: f64,
    /// A peer still running after this long (its world build included) is stopped and reported.
    pub peer_timeout: Duration,
    /// Write a top-down PNG of the furnished world with one episode to this file.
    pub render_png: Option<PathBuf>,
    /// The robot's TOSM description (default: the bundled `ontologies/robots/differential-robot.ttl`).
    pub robot_ttl: PathBuf,
    /// The robot's IRI in that file.
    pub robot_iri: String,
    /// Numbers of people to time one core with, each in its own run (0 is the empty building).
    pub people: Vec<usize>,
}

impl SimBenchOptions {
    /// Defaults for a map: 23 beams, 200 objects, 300,000 steps on one core, 64 environments and
    /// 1,000,000 steps on all cores, no peers.
    pub fn new(map_yaml: impl Into<PathBuf>) -> Self {
        Self {
            map_yaml: map_yaml.into(),
            beams: 23,
            objects: 200,
            steps_one_core: 300_000,
            batch_envs: 64,
            steps_all_cores: 1_000_000,
            seed: 1,
            irsim: None,
            irsim_x: None,
            peer_script: crate::bench_dir().join("scripts/irsim_bench.py"),
            peer_steps: 20_000,
            peer_step_seconds: 30.0,
            peer_timeout: Duration::from_secs(900),
            render_png: None,
            robot_ttl: crate::bench_dir().join("../../ontologies/robots/differential-robot.ttl"),
            robot_iri: "https://mentalsim.dev/data/robots/differential-robot".to_owned(),
            people: vec![0, 10, 50],
        }
    }
}

/// One peer's figures, as its script reported them, or why there are none.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PeerReport {
    /// PyPI package found by the script.
    pub package: Option<String>,
    /// Its version.
    pub version: Option<String>,
    /// Environment steps per second (its `env.step` with a 2-D lidar of the same beams).
    pub steps_per_s: Option<f64>,
    /// Steps timed.
    pub steps: Option<u64>,
    /// Seconds from the map file to a ready environment.
    pub build_s: Option<f64>,
    /// Seconds of the first (untimed) step, in which IR-SIM builds geometry lazily.
    pub first_step_s: Option<f64>,
    /// Static obstacles (object footprints) it was given besides the map.
    pub obstacles: Option<u64>,
    /// Why there are no figures, when there are none.
    pub error: Option<String>,
}

/// Steps per second on one core with a number of people.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PeopleSteps {
    /// People in the world.
    pub people: usize,
    /// Environment steps per second on one core.
    pub steps_per_s_one_core: f64,
    /// The same per second of the thread's CPU time (Linux).
    pub steps_per_cpu_s_one_core: Option<f64>,
    /// This run's steps per second divided by the empty building's (the first run with 0).
    pub ratio_vs_empty: Option<f64>,
    /// Episodes that ended in a collision with a person or anything else, of all that ended.
    pub collision_share: f64,
}

/// What the benchmark measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimBenchReport {
    /// The map's YAML path.
    pub map: String,
    /// Grid cells (width x height).
    pub map_cells: usize,
    /// Free area of the map, m².
    pub free_area_m2: f64,
    /// Area of the largest region where the robot fits, m² (starts and goals come from it).
    pub free_region_m2: f64,
    /// Objects furnished.
    pub objects: usize,
    /// Laser readings per observation.
    pub beams: usize,
    /// Seconds to read the map files (not part of the world build).
    pub map_read_s: f64,
    /// Seconds from the map's bytes to the on-demand database (decode, TOSM values, RDF).
    pub database_s: f64,
    /// Seconds from the on-demand database to a world ready to step (parse + build).
    pub world_build_s: f64,
    /// Of which: the simulator's own build (grids, distance fields, regions, shapes).
    pub world_raster_s: f64,
    /// Environment steps per second on one core.
    pub steps_per_s_one_core: f64,
    /// Steps timed on one core.
    pub steps_one_core: u64,
    /// The same steps per second of CPU time the stepping thread was given (Linux): on a shared
    /// machine this shows the simulator's own speed when other work takes the core away.
    pub steps_per_cpu_s_one_core: Option<f64>,
    /// Environment steps per second on all cores (rayon batch).
    pub steps_per_s_all_cores: f64,
    /// Steps timed on all cores.
    pub steps_all_cores: u64,
    /// Threads in the batch's pool.
    pub threads: usize,
    /// Environments in the batch.
    pub batch_envs: usize,
    /// Episodes that ended during the one-core run, by outcome: reached, collided, timed out.
    pub episodes_one_core: [u64; 3],
    /// IR-SIM's steps per second.
    pub irsim_steps_per_s: Option<f64>,
    /// IR-SIM-X's steps per second.
    pub irsim_x_steps_per_s: Option<f64>,
    /// IR-SIM in full.
    pub irsim: Option<PeerReport>,
    /// IR-SIM-X in full.
    pub irsim_x: Option<PeerReport>,
    /// Our one-core steps per second divided by IR-SIM's.
    pub ratio_vs_irsim: Option<f64>,
    /// Our one-core steps per second divided by IR-SIM-X's.
    pub ratio_vs_irsim_x: Option<f64>,
    /// Our one-core steps per second divided by the paper's Gazebo experiences per second.
    pub ratio_vs_paper_gazebo: f64,
    /// Our one-core steps per second divided by a bare C grid ray caster's.
    pub ratio_vs_c_grid_raycaster: f64,
    /// One core with people walking about ([`sim::crowd`]), one run per number of people.
    pub with_people: Vec<PeopleSteps>,
    /// Whether both targets are met (≥ 100,000 steps/s on one core, world build ≤ 1 s).
    pub targets_met: bool,
}

impl SimBenchReport {
    /// The report as a JSON object.
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or(serde_json::Value::Null)
    }

    /// A few lines for a terminal.
    pub fn summary(&self) -> String {
        let peer = |p: Option<f64>, r: Option<f64>| match (p, r) {
            (Some(p), Some(r)) if p < 10.0 => format!("{p:.3} steps/s (we are {r:.0}x)"),
            (Some(p), Some(r)) => format!("{p:.0} steps/s (we are {r:.0}x)"),
            _ => "not run".to_owned(),
        };
        format!(
            "map {} ({} cells, {} objects, {} beams)\n\
             world build from the on-demand database: {:.3} s (simulator {:.3} s; database from map bytes {:.3} s)\n\
             steps/s one core: {:.0} ({} per CPU second); all cores ({} threads, {} envs): {:.0}\n\
             IR-SIM: {}\nIR-SIM-X: {}\n\
             vs paper's Gazebo (2.4/s): {:.0}x; vs bare C grid ray caster (180k/s): {:.2}x; targets met: {}",
            self.map,
            self.map_cells,
            self.objects,
            self.beams,
            self.world_build_s,
            self.world_raster_s,
            self.database_s,
            self.steps_per_s_one_core,
            self.steps_per_cpu_s_one_core
                .map_or_else(|| "n/a".to_owned(), |v| format!("{v:.0}")),
            self.threads,
            self.batch_envs,
            self.steps_per_s_all_cores,
            peer(self.irsim_steps_per_s, self.ratio_vs_irsim),
            peer(self.irsim_x_steps_per_s, self.ratio_vs_irsim_x),
            self.ratio_vs_paper_gazebo,
            self.ratio_vs_c_grid_raycaster,
            self.targets_met
        ) + &self
            .with_people
            .iter()
            .map(|p| {
                format!(
                    "\nwith {} people: {:.0} steps/s one core ({} of the empty building's)",
                    p.people,
                    p.steps_per_s_one_core,
                    p.ratio_vs_empty
                        .map_or_else(|| "n/a".to_owned(), |r| format!("{r:.2}x"))
                )
            })
            .collect::<String>()
    }
}

/// Furniture for a grid: [`sim::floors::furnish`].
pub use sim::floors::furnish;

/// The mental simulation of a ROS map_server map, built the way the service builds one
/// ([`knowledge::maps::world_from_map`]): the map becomes the floor an import writes,
/// `objects` furniture items are placed from `seed`, the robot comes from its TOSM Turtle, and
/// the simulation parser reads that on-demand database.
pub fn world_from_map(
    yaml_path: &Path,
    robot_ttl: &[u8],
    robot_iri: &str,
    objects: usize,
    seed: u64,
) -> Result<Arc<World>, BenchError> {
    Ok(knowledge::maps::world_from_map(
        yaml_path, robot_ttl, robot_iri, objects, seed,
    )?)
}

/// CPU time this thread has run, seconds, from the scheduler's own account
/// (`/proc/thread-self/schedstat`); `None` where that file does not exist.
fn thread_cpu_s() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// The controller both sides run: turn towards the goal, slow down while turning.
fn heuristic(obs: &Observation) -> Action {
    let b = f64::from(obs.goal_angle);
    Action::new(0.6 * b.cos().max(0.0), (1.5 * b).clamp(-0.5, 0.5))
}

/// Runs the benchmark.
pub fn run_sim_bench(opts: SimBenchOptions) -> Result<SimBenchReport, BenchError> {
    if opts.beams == 0
        || opts.batch_envs == 0
        || opts.steps_one_core == 0
        || opts.steps_all_cores == 0
    {
        return Err(BenchError::BadOption(
            "beams, batch_envs and step counts must be at least 1".into(),
        ));
    }
    let yaml_path = opts.map_yaml.as_path();
    let t = Instant::now();
    let files = knowledge::maps::RosMapFiles::read(yaml_path)?;
    let map_read_s = t.elapsed().as_secs_f64();

    // The furniture is the benchmark's input, like the map: chosen before any timing starts.
    let grid0 = files.grid()?;
    let objects = furnish(&grid0, opts.objects, opts.seed);
    let free_area_m2 = grid0.free_area_m2();
    let map_cells = grid0.cells.len();
    drop(grid0);

    // The on-demand database, as the knowledge service would hold it: the map as a floor with
    // its metric map, the furniture as objects inside it, and the bundled robot.
    let robot_ttl = std::fs::read(&opts.robot_ttl).map_err(io_err(&opts.robot_ttl))?;
    let t = Instant::now();
    let grid = files.grid()?;
    let graph = knowledge::maps::on_demand_database(
        yaml_path,
        grid,
        &objects,
        &robot_ttl,
        &opts.robot_iri,
    )?;
    let database_s = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let spec =
        sim::parse_on_demand(&graph, &opts.robot_iri).map_err(|problems| BenchError::Format {
            path: yaml_path.to_path_buf(),
            message: format!("the simulation parser refused the on-demand database: {problems}"),
        })?;
    let robot = spec.robot.clone();
    let t_raster = Instant::now();
    let world = World::build(spec).map_err(|problems| BenchError::Format {
        path: yaml_path.to_path_buf(),
        message: format!("the world could not be built: {problems}"),
    })?;
    let world_raster_s = t_raster.elapsed().as_secs_f64();
    let world_build_s = t.elapsed().as_secs_f64();

    let config = EnvConfig {
        beams: opts.beams,
        ..EnvConfig::default()
    };
    let env_err = |e: sim::EnvError| BenchError::BadOption(format!("environment: {e}"));

    // One core: a single environment on this thread.
    let mut env = NavEnv::new(Arc::clone(&world), config.clone(), opts.seed).map_err(env_err)?;
    let mut obs = env.reset_random().map_err(env_err)?;
    let mut ends = [0u64; 3];
    let run = |env: &mut NavEnv,
               obs: &mut Observation,
               steps: u64,
               ends: &mut [u64; 3]|
     -> Result<(), BenchError> {
        for _ in 0..steps {
            let r = env.step(heuristic(obs));
            if r.done {
                match r.info.outcome {
                    Outcome::ReachedGoal => ends[0] += 1,
                    Outcome::Collision => ends[1] += 1,
                    Outcome::TimeLimit | Outcome::Running => ends[2] += 1,
                }
                *obs = env.reset_random().map_err(env_err)?;
            } else {
                *obs = r.observation;
            }
        }
        Ok(())
    };
    run(&mut env, &mut obs, 2_000, &mut [0; 3])?; // warm caches
    let cpu0 = thread_cpu_s();
    let t = Instant::now();
    run(&mut env, &mut obs, opts.steps_one_core, &mut ends)?;
    let one_s = t.elapsed().as_secs_f64();
    let one_cpu_s = thread_cpu_s().zip(cpu0).map(|(b, a)| b - a);

    // One core again, with people: the same episodes' driver, one run per number of people.
    let mut with_people: Vec<PeopleSteps> = Vec::new();
    for &people in &opts.people {
        let config = EnvConfig {
            people: sim::PeopleConfig {
                count: Some(people),
                ..sim::PeopleConfig::default()
            },
            ..config.clone()
        };
        if people > 0 {
            // The people's path fields are made once per world; not part of a step.
            world.people_targets().prepare(&world);
        }
        let mut env = NavEnv::new(Arc::clone(&world), config, opts.seed).map_err(env_err)?;
        let mut obs = env.reset_random().map_err(env_err)?;
        let mut ends = [0u64; 3];
        run(&mut env, &mut obs, 2_000, &mut [0; 3])?;
        let cpu0 = thread_cpu_s();
        let t = Instant::now();
        run(&mut env, &mut obs, opts.steps_one_core, &mut ends)?;
        let s = opts.steps_one_core as f64 / t.elapsed().as_secs_f64();
        let cpu = thread_cpu_s()
            .zip(cpu0)
            .map(|(b, a)| opts.steps_one_core as f64 / (b - a));
        let ended = ends.iter().sum::<u64>().max(1) as f64;
        with_people.push(PeopleSteps {
            people,
            steps_per_s_one_core: s,
            steps_per_cpu_s_one_core: cpu,
            ratio_vs_empty: None,
            collision_share: ends[1] as f64 / ended,
        });
    }
    if let Some(empty) = with_people
        .iter()
        .find(|p| p.people == 0)
        .map(|p| p.steps_per_s_one_core)
    {
        for p in &mut with_people {
            p.ratio_vs_empty = Some(p.steps_per_s_one_core / empty);
        }
    }

    // All cores: a rayon batch with auto-reset.
    let mut batch = EnvBatch::new(
        Arc::clone(&world),
        config.clone(),
        opts.batch_envs,
        opts.seed,
        true,
    )
    .map_err(env_err)?;
    let mut observations = batch.reset_random().map_err(env_err)?;
    let rounds = opts.steps_all_cores.div_ceil(opts.batch_envs as u64);
    let mut actions: Vec<Action> = observations.iter().map(heuristic).collect();
    let t = Instant::now();
    for _ in 0..rounds {
        let results = batch.step(&actions).map_err(env_err)?;
        for ((o, a), r) in observations.iter_mut().zip(actions.iter_mut()).zip(results) {
            *o = r.reset_observation.unwrap_or(r.observation);
            *a = heuristic(o);
        }
    }
    let all_s = t.elapsed().as_secs_f64();
    let steps_all = rounds * opts.batch_envs as u64;

    if let Some(path) = &opts.render_png {
        render_episode(&world, &config, opts.seed, path)?;
    }

    // Peers: the same map, beams, robot, object footprints and episodes.
    let mut sampler =
        NavEnv::new(Arc::clone(&world), config.clone(), opts.seed ^ 0xe915).map_err(env_err)?;
    let mut episodes = Vec::new();
    for _ in 0..200 {
        let (s, g) = sampler.sample_start_goal().map_err(env_err)?;
        episodes.push([s.x, s.y, s.yaw, g.0, g.1]);
    }
    let peer_spec = serde_json::json!({
        "yaml": yaml_path.canonicalize().unwrap_or_else(|_| yaml_path.to_path_buf()),
        "beams": opts.beams,
        "steps": opts.peer_steps,
        "max_seconds": opts.peer_step_seconds,
        "control_period": config.control_period,
        "robot_radius": robot.footprint_radius,
        "goal_tolerance": config.goal_tolerance,
        "range_noise": config.noise.range,
        "laser": {
            "range_min": robot.laser.range_min,
            "range_max": robot.laser.range_max,
            "fov": robot.laser.fov,
            "x": robot.laser.mount.x,
            "y": robot.laser.mount.y,
        },
        "obstacles": objects.iter().map(peer_obstacle).collect::<Vec<_>>(),
        "episodes": episodes,
    });
    let irsim = opts
        .irsim
        .as_ref()
        .map(|p| run_peer(p, &opts, &peer_spec, "irsim"));
    let irsim_x = opts
        .irsim_x
        .as_ref()
        .map(|p| run_peer(p, &opts, &peer_spec, "irsim_x"));

    let one = opts.steps_one_core as f64 / one_s;
    let all = steps_all as f64 / all_s;
    let peer_rate = |p: &Option<PeerReport>| p.as_ref().and_then(|r| r.steps_per_s);
    let (irsim_rate, irsim_x_rate) = (peer_rate(&irsim), peer_rate(&irsim_x));
    Ok(SimBenchReport {
        map: yaml_path.display().to_string(),
        map_cells,
        free_area_m2,
        free_region_m2: world.free_region_area_m2(),
        objects: objects.len(),
        beams: opts.beams,
        map_read_s,
        database_s,
        world_build_s,
        world_raster_s,
        steps_per_s_one_core: one,
        steps_one_core: opts.steps_one_core,
        steps_per_cpu_s_one_core: one_cpu_s
            .filter(|s| *s > 0.0)
            .map(|s| opts.steps_one_core as f64 / s),
        steps_per_s_all_cores: all,
        steps_all_cores: steps_all,
        threads: rayon::current_num_threads(),
        batch_envs: opts.batch_envs,
        episodes_one_core: ends,
        irsim_steps_per_s: irsim_rate,
        irsim_x_steps_per_s: irsim_x_rate,
        ratio_vs_irsim: irsim_rate.map(|r| one / r),
        ratio_vs_irsim_x: irsim_x_rate.map(|r| one / r),
        ratio_vs_paper_gazebo: one / PAPER_GAZEBO_STEPS_PER_S,
        ratio_vs_c_grid_raycaster: one / C_GRID_RAYCASTER_STEPS_PER_S,
        targets_met: one >= TARGET_STEPS_PER_S_ONE_CORE && world_build_s <= TARGET_WORLD_BUILD_S,
        irsim,
        irsim_x,
        with_people,
    })
}

/// An object's footprint as a 2-D obstacle for IR-SIM: placeholders exactly, library models by
/// their bounding box (a 2-D simulator cannot see between a table's legs).
fn peer_obstacle(o: &ObjectSpec) -> serde_json::Value {
    match o.shape {
        Shape::Cylinder | Shape::Sphere => serde_json::json!({
            "shape": "circle", "x": o.pose.x, "y": o.pose.y, "radius": o.size.x.max(o.size.y) / 2.0,
        }),
        Shape::Box => serde_json::json!({
            "shape": "rectangle", "x": o.pose.x, "y": o.pose.y, "yaw": o.pose.yaw,
            "length": o.size.x, "width": o.size.y,
        }),
    }
}

/// Runs the peer script under `peer.python`, stopping it after the timeout.
fn run_peer(
    peer: &PeerOptions,
    opts: &SimBenchOptions,
    spec: &serde_json::Value,
    name: &str,
) -> PeerReport {
    let failed = |error: String| PeerReport {
        package: None,
        version: None,
        steps_per_s: None,
        steps: None,
        build_s: None,
        first_step_s: None,
        obstacles: None,
        error: Some(error),
    };
    let spec_path = std::env::temp_dir().join(format!(
        "mentalsim-bench-sim-{}-{name}.json",
        std::process::id()
    ));
    if let Err(e) = std::fs::write(&spec_path, spec.to_string()) {
        return failed(format!("writing {}: {e}", spec_path.display()));
    }
    let child = Command::new(&peer.python)
        .arg(&opts.peer_script)
        .arg(&spec_path)
        .env("MPLBACKEND", "Agg")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn();
    let mut child = match child {
        Ok(c) => c,
        Err(e) => return failed(format!("starting {}: {e}", peer.python.display())),
    };
    let start = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break Ok(s),
            Ok(None) if start.elapsed() > opts.peer_timeout => {
                let _ = child.kill();
                let _ = child.wait();
                break Err(format!("stopped after {} s", opts.peer_timeout.as_secs()));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(200)),
            Err(e) => break Err(e.to_string()),
        }
    };
    let _ = std::fs::remove_file(&spec_path);
    let output = match status {
        Err(e) => return failed(e),
        Ok(_) => match child.wait_with_output() {
            Ok(o) => o,
            Err(e) => return failed(e.to_string()),
        },
    };
    let stdout = String::from_utf8_lossy(&output.stdout);
    let Some(line) = stdout
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
    else {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(5).collect();
        return failed(format!(
            "{} exited with {} and no result: {}",
            peer.python.display(),
            output.status,
            tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
        ));
    };
    match serde_json::from_str::<serde_json::Value>(line) {
        Ok(v) => PeerReport {
            package: v["package"].as_str().map(str::to_owned),
            version: v["version"].as_str().map(str::to_owned),
            steps_per_s: v["steps_per_s"].as_f64(),
            steps: v["steps"].as_u64(),
            build_s: v["build_s"].as_f64(),
            first_step_s: v["first_step_s"].as_f64(),
            obstacles: v["obstacles"].as_u64(),
            error: None,
        },
        Err(e) => failed(format!("unreadable result {line:?}: {e}")),
    }
}

/// One episode of the heuristic controller, drawn over the world.
fn render_episode(
    world: &Arc<World>,
    config: &EnvConfig,
    seed: u64,
    path: &Path,
) -> Result<(), BenchError> {
    let config = EnvConfig {
        record_trajectory: true,
        ..config.clone()
    };
    let env_err = |e: sim::EnvError| BenchError::BadOption(format!("environment: {e}"));
    let mut env = NavEnv::new(Arc::clone(world), config, seed).map_err(env_err)?;
    let mut obs = env.reset_random().map_err(env_err)?;
    loop {
        let r = env.step(heuristic(&obs));
        obs = r.observation;
        if r.done {
            break;
        }
    }
    let overlay = sim::render::Overlay {
        trajectory: env.trajectory().to_vec(),
        robot: Some(env.pose()),
        goal: Some(env.goal()),
        show_free_region: true,
        ..Default::default()
    }
    .with_scan(world, env.pose(), 23);
    let png =
        sim::render::png(world, &overlay, &sim::render::RenderOptions::default()).map_err(|e| {
            BenchError::Plot {
                path: path.to_path_buf(),
                message: e.to_string(),
            }
        })?;
    std::fs::write(path, png).map_err(io_err(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_run_reports_every_key() {
        let Some(yaml) =
            fixtures::shared_fixture("maps/ros/aws_small_house/map.yaml", "the shared map")
        else {
            return;
        };
        let report = run_sim_bench(SimBenchOptions {
            objects: 20,
            steps_one_core: 2_000,
            steps_all_cores: 2_000,
            batch_envs: 8,
            ..SimBenchOptions::new(&yaml)
        })
        .expect("runs");
        let json = report.to_json();
        for key in [
            "steps_per_s_one_core",
            "steps_per_s_all_cores",
            "world_build_s",
            "beams",
            "irsim_steps_per_s",
            "irsim_x_steps_per_s",
        ] {
            assert!(json.get(key).is_some(), "{key} missing from {json}");
        }
        assert_eq!(report.beams, 23);
        assert!(report.objects > 0 && report.steps_per_s_one_core > 0.0);
        assert!(json["irsim_steps_per_s"].is_null(), "peers not asked for");
    }

    #[test]
    fn a_missing_map_is_an_io_error() {
        let e = run_sim_bench(SimBenchOptions::new("/nonexistent/map.yaml"));
        assert!(matches!(e, Err(BenchError::Io { .. })), "{e:?}");
    }
}
