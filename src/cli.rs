//! The `mentalsim` command line: a thin layer that parses arguments and calls the services.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::config::{Config, Overrides};
use crate::startup::{Application, shutdown_signal};

/// Mental simulation service for robot fleets.
#[derive(Debug, Parser)]
#[command(name = "mentalsim", version, about)]
pub struct Cli {
    /// Optional TOML configuration file (keys as in `Config`; environment and flags override it).
    #[arg(long, global = true, env = "MENTALSIM_CONFIG", value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run the knowledge service and the simulation worker in one process.
    Serve {
        /// Address to listen on [default: 127.0.0.1:8080; env: MENTALSIM_BIND].
        #[arg(long, value_name = "ADDR")]
        bind: Option<String>,
        /// Directory for the graph store, job database and tokens [default: ./data; env: MENTALSIM_DATA_DIR].
        #[arg(long, value_name = "DIR")]
        data_dir: Option<PathBuf>,
        /// Keep the knowledge graph in this SPARQL 1.1 store (its query endpoint, or an Oxigraph
        /// server's base URL) instead of the embedded one [env: MENTALSIM_STORE_URL].
        #[arg(long, value_name = "URL")]
        store_url: Option<String>,
    },
    /// Run job workers alone against a shared job database (SQLite file or PostgreSQL), taking
    /// worlds from a knowledge service over HTTP; serves /healthz and /readyz on --bind.
    Worker {
        /// The knowledge service's URL [env: MENTALSIM_KNOWLEDGE_URL].
        #[arg(long, value_name = "URL")]
        knowledge_url: Option<String>,
        /// The job database [default: sqlite://<data_dir>/jobs.sqlite; env: MENTALSIM_DATABASE_URL].
        #[arg(long, value_name = "URL")]
        database_url: Option<String>,
        /// Jobs run at once [default: 1; env: MENTALSIM_WORKER_CONCURRENCY].
        #[arg(long, value_name = "N")]
        concurrency: Option<usize>,
        /// Address of the health endpoints [default: 127.0.0.1:8080; env: MENTALSIM_BIND].
        #[arg(long, value_name = "ADDR")]
        bind: Option<String>,
        /// Data directory (SQLite default, checkpoints, policies) [default: ./data].
        #[arg(long, value_name = "DIR")]
        data_dir: Option<PathBuf>,
    },
    /// Import a ROS map_server map (YAML + PGM/PNG) into a running service as a TOSM floor.
    ImportMap {
        /// The map's YAML file; its `image` is read from beside it.
        yaml: PathBuf,
        /// The floor's name (a-z, 0-9, '-', '_'); defaults to the YAML's directory name.
        #[arg(long)]
        name: Option<String>,
        /// The service's URL.
        #[arg(long, env = "MENTALSIM_URL", default_value = "http://127.0.0.1:8080")]
        url: String,
        /// An engineer's bearer token [default: read from ./data/admin.token].
        #[arg(long, env = "MENTALSIM_TOKEN", hide_env_values = true)]
        token: Option<String>,
    },
    /// Export a floor's world as SDF, or a robot as URDF, as a gz-sim model (SDF) or its
    /// ros_gz_bridge configuration, from a running service.
    Export {
        /// `sdf` (a place's floor), `urdf`, `robot-sdf` or `bridge` (a robot).
        #[arg(value_enum)]
        kind: ExportKind,
        /// The place or robot: IRI or identifier.
        id: String,
        /// Where to write the file [default: standard output].
        #[arg(long)]
        out: Option<PathBuf>,
        /// For `bridge`: the gz-sim world's name, whose clock is bridged [default: gz-sim's
        /// global /clock].
        #[arg(long)]
        world: Option<String>,
        /// The service's URL.
        #[arg(long, env = "MENTALSIM_URL", default_value = "http://127.0.0.1:8080")]
        url: String,
        /// A bearer token [default: read from ./data/admin.token].
        #[arg(long, env = "MENTALSIM_TOKEN", hide_env_values = true)]
        token: Option<String>,
    },
    /// Train a navigation policy (TD3) in the mental simulation of a ROS map; resumes the run
    /// checkpointed in --out unless --fresh.
    Train(crate::train::TrainArgs),
    /// Evaluate an exported policy on random missions (goals 2–10 m away) in any ROS map.
    Eval {
        /// The policy directory (policy.safetensors + policy.json).
        #[arg(long)]
        policy: PathBuf,
        /// The ROS map_server YAML.
        #[arg(long)]
        map: PathBuf,
        /// Missions to run.
        #[arg(long, default_value_t = 200)]
        episodes: usize,
        /// Seed of the mission set.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// Which missions: held-out goals (`in-view`, `anywhere`; the other kind is reported
        /// beside them), or `edges`: every roadmap edge of the map, both directions (PRM-RL).
        #[arg(long, value_enum, default_value_t = crate::train::EvalGoals::InView)]
        goals: crate::train::EvalGoals,
        /// With `--goals edges`: rollouts per edge and direction.
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1000))]
        rollouts: u32,
        /// Write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Run a benchmark and write its figures.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Use an exported policy without the service.
    #[command(subcommand)]
    Policy(PolicyCommand),
}

/// What `mentalsim policy` does.
#[derive(Debug, Subcommand)]
pub enum PolicyCommand {
    /// Run a policy's forward pass on JSON lines from stdin, one answer line each on stdout:
    /// an observation `{"ranges": [...], "goal_distance", "goal_angle", "velocity": [v, w]}`
    /// (scaled as the policy was trained), or a network input row `{"input": [...]}`; the answer
    /// is `{"input": [...], "output": [o0, o1], "action": {"linear", "angular"}}`. What a
    /// client's own implementation of the forward pass is checked against.
    Act {
        /// The policy directory (policy.safetensors + policy.json).
        #[arg(long)]
        policy: PathBuf,
    },
}

/// What `mentalsim export` writes.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ExportKind {
    /// SDF 1.9 world for Gazebo.
    Sdf,
    /// URDF robot for ROS and Gazebo.
    Urdf,
    /// SDF 1.9 robot model for gz-sim.
    RobotSdf,
    /// ros_gz_bridge configuration (YAML) for the robot in gz-sim.
    Bridge,
}

/// Benchmarks: each prints its figures and writes them to files.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// The paper's PRM protocol (Table 2, Figure 9) on every ROS map under a directory, beside OMPL.
    Prm {
        /// Directory searched recursively for ROS map_server YAML files.
        #[arg(long, default_value = "../shared/maps/ros")]
        maps: PathBuf,
        /// Runs per map and sample count (the paper: 50).
        #[arg(long, default_value_t = 50)]
        runs: usize,
        /// Where prm.csv, prm.md and prm.png go.
        #[arg(long, default_value = "bench-out/prm")]
        out: PathBuf,
        /// MovingAI maps and scenarios to run as well.
        #[arg(long)]
        movingai: Option<PathBuf>,
        /// Skip OMPL (Python bindings and C++ library).
        #[arg(long)]
        no_ompl: bool,
    },
    /// Simulator steps per second (one core, all cores) and world build time, beside IR-SIM.
    Sim {
        /// The ROS map_server YAML [default: the largest shared map].
        #[arg(long)]
        map: Option<PathBuf>,
        /// Write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Laser readings per observation.
        #[arg(long, default_value_t = 23)]
        beams: usize,
        /// Python with `ir-sim` installed, to run it side by side.
        #[arg(long)]
        irsim_python: Option<PathBuf>,
        /// Python with `irsim-x` installed, to run it side by side.
        #[arg(long)]
        irsim_x_python: Option<PathBuf>,
        /// Numbers of people walking about to time one core with, one run each.
        #[arg(long, value_delimiter = ',', default_values_t = [0, 10, 50])]
        people: Vec<usize>,
    },
    /// The paper's §5.2: one policy per (β1 = β2, seed), final success and reward curves.
    Beta {
        /// The ROS map_server YAML of the place.
        #[arg(long)]
        map: PathBuf,
        /// Minutes per training.
        #[arg(long, default_value_t = 10.0)]
        minutes: f64,
        /// Values of β1 = β2 (the paper: 0, 1, 5).
        #[arg(long, value_delimiter = ',', default_values_t = [0.0, 1.0, 5.0])]
        betas: Vec<f64>,
        /// Seeds per value.
        #[arg(long, value_delimiter = ',', default_values_t = [1, 2, 3])]
        seeds: Vec<u64>,
        /// Where the runs, beta.md and beta.png go.
        #[arg(long, default_value = "bench-out/beta")]
        out: PathBuf,
        /// Training configuration shared by all runs (JSON).
        #[arg(long)]
        config: Option<PathBuf>,
        /// Held-out missions of each final evaluation.
        #[arg(long, default_value_t = 200)]
        eval_episodes: usize,
    },
    /// Job queue throughput (enqueue, claim + complete) on SQLite and a temporary PostgreSQL.
    Queue {
        /// Write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Jobs per backend.
        #[arg(long, default_value_t = 2000)]
        jobs: usize,
        /// Concurrent enqueuers, then concurrent workers.
        #[arg(long, default_value_t = 4)]
        concurrency: usize,
        /// A PostgreSQL database to use instead of a temporary cluster.
        #[arg(long, env = "QUEUE_BENCH_POSTGRES_URL", hide_env_values = true)]
        postgres_url: Option<String>,
    },
    /// The paper's Table 3 in the mental simulation: long missions on every ROS map under a
    /// directory with hybrid PRM-RL, pure RL and a classical follower on the PRM path.
    Navigation {
        /// Directory searched recursively for ROS map_server YAML files.
        #[arg(long, default_value = "../shared/maps/ros")]
        maps: PathBuf,
        /// Runs per method and map (the paper: 10).
        #[arg(long, default_value_t = 10)]
        runs: usize,
        /// An exported policy (policy.safetensors + policy.json); without one only the classical
        /// follower runs.
        #[arg(long)]
        policy: Option<PathBuf>,
        /// Where navigation.csv and navigation.md go.
        #[arg(long, default_value = "bench-out/navigation")]
        out: PathBuf,
        /// Mission length along the roadmap where the map allows, metres (the paper: ~140).
        #[arg(long, default_value_t = 140.0)]
        mission_length_m: f64,
        /// Clearance the roadmap keeps beyond the robot's radius, metres (the plan endpoint's
        /// `options.safety_margin_m`).
        #[arg(long, default_value_t = 0.1)]
        safety_margin_m: f64,
        /// People walking about in every rehearsal, per 100 m² of free region (0: the empty
        /// building; the table runs 0, 1, 2 and 4).
        #[arg(long, default_value_t = 0.0)]
        people: f64,
        /// Base seed of the missions, roadmaps, noise and people: another seed, other
        /// missions and crowds.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Run only these methods (comma-separated names from the table; all by default).
        #[arg(long, value_delimiter = ',')]
        methods: Vec<String>,
        /// Every method's roadmap path with its detours removed (the plan endpoint's
        /// `options.shortcut`; `auto`'s trial keeps its own default).
        #[arg(long)]
        shortcut: bool,
        /// Build the policy-aware roadmap again in every run on that run's geometric roadmap
        /// (the classical methods'), not once per map.
        #[arg(long)]
        policy_roadmap_per_run: bool,
    },
    /// Per-edge success of policies on every roadmap edge of every map under a directory (both
    /// directions, K rollouts each), the classical follower beside them with the same seeds
    Edges {
        /// Directory searched recursively for ROS map_server YAML files.
        #[arg(long, default_value = "../shared/maps/ros")]
        maps: PathBuf,
        /// An exported policy (repeatable: several side by side).
        #[arg(long = "policy")]
        policies: Vec<PathBuf>,
        /// Rollouts per edge direction.
        #[arg(long, default_value_t = 10)]
        rollouts: u32,
        /// At most this many roadmap edges per map (both directions each), a sample drawn with
        /// the seed: a quick look (MPPI drives a few hundred edges in half a minute). Default:
        /// every edge.
        #[arg(long)]
        edges: Option<usize>,
        /// Seed of the roadmaps and rollouts.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// Where edges.csv and edges.md go.
        #[arg(long, default_value = "bench-out/edges")]
        out: PathBuf,
        /// People per 100 m² of free region walking about in the rollouts (repeatable or
        /// comma-separated: each density its own rows; default 0, the empty building).
        #[arg(long, value_delimiter = ',')]
        people: Vec<f64>,
        /// Controllers to drive (repeatable or comma-separated: policy, shield_only,
        /// hybrid_rpp, follower, rpp, mppi; default all).
        #[arg(long = "controller", value_delimiter = ',')]
        controllers: Vec<String>,
    },
    /// N robots ask for plans at once on each map; the committed plans are then driven
    /// together (joint success, robot collisions, stalls, makespan against the robots alone,
    /// plan latency p50/p95).
    Fleet {
        /// Directory searched recursively for ROS map_server YAML files (`random`).
        #[arg(long, default_value = "../shared/maps/ros")]
        maps: PathBuf,
        /// Robots at once.
        #[arg(long, default_value_t = 20)]
        robots: usize,
        /// People per 100 m² of free region.
        #[arg(long, default_value_t = 0.0)]
        people: f64,
        /// `random` missions on every map, or a generated floor: `corridor` (a corridor one
        /// robot wide, half the robots at each end), `crossing` (two such corridors crossing,
        /// the robots split over the rooms at the four ends, each sent to the opposite one) or
        /// `doorway` (two rooms joined by one door a robot wide, half the robots in each).
        #[arg(long, value_parser = ["random", "corridor", "crossing", "doorway"], default_value = "random")]
        scenario: String,
        /// Seed of the missions and simulations.
        #[arg(long, default_value_t = 7)]
        seed: u64,
        /// Most waiting a plan may take to let others pass (`options.max_wait_s`), seconds.
        #[arg(long, default_value_t = 600.0)]
        max_wait_s: f64,
        /// Plans the robots one after another in an order shuffled by SEED instead of all at
        /// once, so that a run whose outcome depends on the plan order can be repeated.
        #[arg(long, value_name = "SEED")]
        order_seed: Option<u64>,
        /// Every robot asks with the same `options.seed`, as robots sending the default options
        /// do (one roadmap and the same draws for all), instead of one seed each.
        #[arg(long)]
        same_seed: bool,
        /// Writes the rows as JSON (one object per map and scenario).
        #[arg(long)]
        json: Option<PathBuf>,
        /// Writes each joint run as `DIR/MAP-SCENARIO.json`, which the console's Traffic page
        /// replays (every robot as it drove among the others, and how it fared).
        #[arg(long, value_name = "DIR")]
        replay: Option<PathBuf>,
    },
    /// POST /v1/plan latency of a running service under C concurrent robot clients.
    PlanLoad {
        /// The service's URL.
        #[arg(long, env = "MENTALSIM_URL", default_value = "http://127.0.0.1:8080")]
        url: String,
        /// A bearer token [default: read from ./data/admin.token].
        #[arg(long, env = "MENTALSIM_TOKEN", hide_env_values = true)]
        token: Option<String>,
        /// Concurrent clients.
        #[arg(long, default_value_t = 50)]
        clients: usize,
        /// Seconds of load.
        #[arg(long, default_value_t = 20.0)]
        seconds: f64,
        /// The plan request (JSON file) [default: across the bundled building's ground floor].
        #[arg(long)]
        body: Option<PathBuf>,
        /// The service's process id, when it runs on this machine: the figures then include
        /// its CPU time per plan (and the load generator's own, which shares the cores).
        #[arg(long, value_name = "PID")]
        server_pid: Option<u32>,
        /// Write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// TD3 gradient steps per second, ours beside Stable-Baselines3's, same sizes, one run.
    Learner {
        /// Write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Timed gradient steps of each learner.
        #[arg(long, default_value_t = 2000)]
        steps: u64,
        /// libtorch intra-op threads of both (0: libtorch's default).
        #[arg(long, default_value_t = 1)]
        threads: usize,
        /// Batch size.
        #[arg(long, default_value_t = 256)]
        batch_size: usize,
        /// Hidden layer widths of actor and critics, comma-separated (the `fast` preset: 64,64).
        #[arg(long, value_delimiter = ',', default_value = "256,256")]
        hidden: Vec<usize>,
        /// Skip Stable-Baselines3.
        #[arg(long)]
        no_sb3: bool,
    },
    /// On-demand database latency on a 100,000-triple building, and SPARQL query throughput of
    /// our /sparql beside `oxigraph serve` holding the same data.
    Knowledge {
        /// Write the figures as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// The `oxigraph` server binary (PyPI `oxigraph`) [default: .venv/bin/oxigraph, else PATH].
        #[arg(long)]
        oxigraph: Option<PathBuf>,
        /// At least this many triples in the store.
        #[arg(long, default_value_t = 100_000)]
        triples: usize,
        /// Timed on-demand requests.
        #[arg(long, default_value_t = 200)]
        requests: usize,
        /// Concurrent SPARQL clients (the same for both servers).
        #[arg(long, default_value_t = 4)]
        clients: usize,
        /// Seconds of measurement per server.
        #[arg(long, default_value_t = 10.0)]
        seconds: f64,
        /// Exit non-zero when the query mix runs below this ratio ours/oxigraph serve (the
        /// figures are still printed and written).
        #[arg(long, value_name = "R", value_parser = positive_ratio)]
        min_ratio: Option<f64>,
    },
}

fn positive_ratio(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(r) if r.is_finite() && r > 0.0 => Ok(r),
        _ => Err(format!("`{text}` is not a positive ratio (e.g. 0.9)")),
    }
}

/// Runs the command line; the process exit code says whether it worked.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Serve {
            bind,
            data_dir,
            store_url,
        } => {
            let overrides = Overrides {
                bind,
                data_dir,
                store_url,
                ..Overrides::default()
            };
            return serve_command(cli.config, overrides, false);
        }
        Command::Worker {
            knowledge_url,
            database_url,
            concurrency,
            bind,
            data_dir,
        } => {
            let overrides = Overrides {
                bind,
                data_dir,
                database_url,
                knowledge_url,
                worker_concurrency: concurrency,
                ..Overrides::default()
            };
            return serve_command(cli.config, overrides, true);
        }
        Command::ImportMap {
            yaml,
            name,
            url,
            token,
        } => import_map(&yaml, name, &url, token),
        Command::Export {
            kind,
            id,
            out,
            world,
            url,
            token,
        } => export(kind, &id, out, world.as_deref(), &url, token),
        Command::Train(args) => run_train(args),
        Command::Eval {
            policy,
            map,
            episodes,
            seed,
            goals,
            rollouts,
            json,
        } => crate::train::eval(&policy, &map, episodes, seed, goals, rollouts)
            .and_then(|v| print_json(&v, json)),
        Command::Bench(bench) => run_bench(bench),
        Command::Policy(PolicyCommand::Act { policy }) => crate::train::act(&policy),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("mentalsim: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn serve_command(config_file: Option<PathBuf>, overrides: Overrides, worker: bool) -> ExitCode {
    let config = match Config::load(config_file.as_deref(), &overrides) {
        Ok(config) => config,
        Err(e) => {
            eprintln!("mentalsim: {e}");
            return ExitCode::from(2);
        }
    };
    crate::telemetry::init(&config);
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        // Parsers and the SPARQL evaluator recurse per nesting level: room for what the
        // lexical limits let through (protocol::complexity), with a wide margin. Only the
        // pages a thread touches are committed.
        .thread_stack_size(8 * 1024 * 1024)
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("mentalsim: cannot start the async runtime: {e}");
            return ExitCode::FAILURE;
        }
    };
    if std::env::var_os(FAULT_STUCK_TASK).is_some() {
        tracing::warn!("{FAULT_STUCK_TASK} is set: a blocking task that never ends is running");
        runtime.spawn_blocking(|| {
            loop {
                std::thread::park();
            }
        });
    }
    let run = async move {
        if worker {
            run_worker(config).await
        } else {
            serve(config).await
        }
    };
    let result = runtime.block_on(run);
    // The grace period is over (requests, jobs) and the stores are closed. A blocking task that
    // is still running (a computation that ignores cancellation) must not keep the process
    // alive: the runtime waits for it only briefly.
    runtime.shutdown_timeout(RUNTIME_SHUTDOWN);
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            tracing::error!(error = %e, "mentalsim serve failed");
            eprintln!("mentalsim: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// How long the runtime waits for blocking tasks still running once serving has stopped.
const RUNTIME_SHUTDOWN: std::time::Duration = std::time::Duration::from_millis(500);

/// Fault injection for tests: when set, `serve` and `worker` start a blocking task that never
/// ends, to prove that stopping stops anyway.
const FAULT_STUCK_TASK: &str = "MENTALSIM_FAULT_STUCK_TASK";

fn import_map(
    yaml: &std::path::Path,
    name: Option<String>,
    url: &str,
    token: Option<String>,
) -> anyhow::Result<()> {
    use anyhow::Context;
    let files = knowledge::maps::RosMapFiles::read(yaml)
        .with_context(|| format!("cannot read the map {}", yaml.display()))?;
    let name = match name {
        Some(n) => n,
        None => knowledge::maps::name_for_path(yaml),
    };
    let token = token_or_default(token)?;
    let form = reqwest::blocking::multipart::Form::new()
        .text("name", name.clone())
        .text("yaml", files.yaml)
        .part(
            "image",
            reqwest::blocking::multipart::Part::bytes(files.image).file_name(files.meta.image),
        );
    let response = reqwest::blocking::Client::new()
        .post(format!("{}/v1/maps", url.trim_end_matches('/')))
        .bearer_auth(token)
        .multipart(form)
        .send()
        .with_context(|| format!("cannot reach the service at {url}"))?;
    let status = response.status();
    let body = response.text().unwrap_or_default();
    if !status.is_success() {
        anyhow::bail!("the service refused the map ({status}): {body}");
    }
    println!("{body}");
    Ok(())
}

fn token_or_default(token: Option<String>) -> anyhow::Result<String> {
    use anyhow::Context;
    match token {
        Some(t) => Ok(t),
        None => std::fs::read_to_string("data/admin.token")
            .map(|t| t.trim().to_owned())
            .context("no --token given and ./data/admin.token is not readable"),
    }
}

fn export(
    kind: ExportKind,
    id: &str,
    out: Option<PathBuf>,
    world: Option<&str>,
    url: &str,
    token: Option<String>,
) -> anyhow::Result<()> {
    use anyhow::Context;
    use percent_encoding::{NON_ALPHANUMERIC, utf8_percent_encode};
    let encoded = utf8_percent_encode(id, NON_ALPHANUMERIC);
    let path = match kind {
        ExportKind::Sdf => format!("/v1/places/{encoded}/world.sdf"),
        ExportKind::Urdf => format!("/v1/robots/{encoded}/robot.urdf"),
        ExportKind::RobotSdf => format!("/v1/robots/{encoded}/robot.sdf"),
        ExportKind::Bridge => match world {
            Some(w) => format!(
                "/v1/robots/{encoded}/bridge.yaml?world={}",
                utf8_percent_encode(w, NON_ALPHANUMERIC)
            ),
            None => format!("/v1/robots/{encoded}/bridge.yaml"),
        },
    };
    if world.is_some() && !matches!(kind, ExportKind::Bridge) {
        anyhow::bail!("--world is for `export bridge` only");
    }
    let response = reqwest::blocking::Client::new()
        .get(format!("{}{path}", url.trim_end_matches('/')))
        .bearer_auth(token_or_default(token)?)
        .send()
        .with_context(|| format!("cannot reach the service at {url}"))?;
    let status = response.status();
    let body = response.text().unwrap_or_default();
    if !status.is_success() {
        anyhow::bail!("the service refused the export ({status}): {body}");
    }
    match out {
        Some(path) => {
            std::fs::write(&path, body)
                .with_context(|| format!("cannot write {}", path.display()))?;
            eprintln!("wrote {}", path.display());
        }
        None => print!("{body}"),
    }
    Ok(())
}

/// The project's Python (the virtual environment `scripts/env.sh` activates).
fn venv_python() -> PathBuf {
    std::env::var_os("VIRTUAL_ENV")
        .map(|v| PathBuf::from(v).join("bin/python"))
        .unwrap_or_else(|| PathBuf::from(".venv/bin/python"))
}

/// Prints `value` and writes it to `path` when given.
fn print_json(value: &serde_json::Value, path: Option<PathBuf>) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    println!("{text}");
    if let Some(path) = path {
        std::fs::write(&path, format!("{text}\n"))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// A flag set by SIGINT or SIGTERM, for commands that stop cleanly at the next step.
fn stop_flag() -> anyhow::Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, std::sync::Arc::clone(&stop))?;
    }
    Ok(stop)
}

/// Trains until the budget is spent; Ctrl-C (or SIGTERM) stops early with a checkpoint and
/// still exports what was learned.
fn run_train(args: crate::train::TrainArgs) -> anyhow::Result<()> {
    let stop = stop_flag()?;
    let summary = crate::train::train(&args, &stop)?;
    print_json(&serde_json::to_value(&summary)?, None)?;
    eprintln!(
        "wrote the policy, curves.csv, curves.png and eval.json to {}",
        args.out.display()
    );
    Ok(())
}

fn run_bench(command: BenchCommand) -> anyhow::Result<()> {
    match command {
        BenchCommand::Knowledge {
            json,
            oxigraph,
            triples,
            requests,
            clients,
            seconds,
            min_ratio,
        } => knowledge_bench(
            json, oxigraph, triples, requests, clients, seconds, min_ratio,
        ),
        BenchCommand::Prm {
            maps,
            runs,
            out,
            movingai,
            no_ompl,
        } => {
            let python = venv_python();
            let options = bench::prm::PrmBenchOptions {
                maps_dir: maps,
                runs,
                out_dir: out,
                movingai_dir: movingai,
                ompl: (!no_ompl).then(|| bench::prm::OmplOptions {
                    python,
                    ..Default::default()
                }),
                verbose: true,
                ..Default::default()
            };
            let report = bench::prm::run_prm_bench(options)?;
            println!("{}", report.markdown);
            println!("OMPL: {}", report.ompl_status);
            println!(
                "wrote {}, {}, {}",
                report.csv_path.display(),
                report.markdown_path.display(),
                report.plot_path.display()
            );
            Ok(())
        }
        BenchCommand::Beta {
            map,
            minutes,
            betas,
            seeds,
            out,
            config,
            eval_episodes,
        } => {
            let stop = stop_flag()?;
            let options = bench::beta::BetaOptions {
                map,
                robot_ttl: crate::train::bundled_robot_ttl().as_bytes().to_vec(),
                robot_iri: crate::train::ROBOT_IRI.to_owned(),
                minutes,
                betas,
                seeds,
                out: out.clone(),
                config,
                eval_episodes,
            };
            let text = bench::beta::run_beta_experiment(&options, &stop)?;
            println!("{text}");
            eprintln!("wrote beta.md and beta.png to {}", out.display());
            Ok(())
        }
        BenchCommand::Queue {
            json,
            jobs,
            concurrency,
            postgres_url,
        } => {
            let options = bench::queue::BenchOptions {
                jobs,
                concurrency,
                postgres_url,
            };
            let runtime = tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .build()?;
            let reports = runtime.block_on(bench::queue::run(&options))?;
            println!(
                "queue throughput (durable commits: SQLite synchronous=FULL, PostgreSQL fsync=on)"
            );
            for report in &reports {
                println!("{report}");
            }
            if reports.len() < 2 {
                println!("PostgreSQL skipped: binaries not found and --postgres-url not given");
            }
            if let Some(path) = json {
                let text = serde_json::to_string_pretty(&reports)?;
                std::fs::write(&path, format!("{text}\n"))?;
                eprintln!("wrote {}", path.display());
            }
            Ok(())
        }
        BenchCommand::Navigation {
            maps,
            runs,
            policy,
            out,
            mission_length_m,
            safety_margin_m,
            people,
            seed,
            methods,
            shortcut,
            policy_roadmap_per_run,
        } => {
            if !(safety_margin_m.is_finite() && (0.0..=5.0).contains(&safety_margin_m)) {
                anyhow::bail!("--safety-margin-m must lie in [0, 5] metres, got {safety_margin_m}");
            }
            if !(people.is_finite() && (0.0..=50.0).contains(&people)) {
                anyhow::bail!("--people must lie in [0, 50] people per 100 m², got {people}");
            }
            let options = bench::navigation::NavigationBenchOptions {
                maps_dir: maps,
                runs,
                policy,
                out_dir: out,
                mission_length_m,
                safety_margin_m,
                people,
                seed,
                verbose: true,
                methods,
                shortcut,
                policy_roadmap_per_run,
                ..Default::default()
            };
            let report = bench::navigation::run_navigation_bench(options)?;
            println!("{}", report.markdown);
            println!(
                "wrote {} and {}",
                report.csv_path.display(),
                report.markdown_path.display()
            );
            Ok(())
        }
        BenchCommand::Edges {
            maps,
            policies,
            rollouts,
            edges,
            seed,
            out,
            people,
            controllers,
        } => {
            let md = bench::edges::run_edge_bench(&bench::edges::EdgeBenchOptions {
                maps: maps.clone(),
                policies,
                rollouts,
                edges,
                seed,
                out: out.clone(),
                people,
                controllers,
                robot_ttl: crate::train::bundled_robot_ttl().as_bytes().to_vec(),
                robot_iri: crate::train::ROBOT_IRI.to_owned(),
            })?;
            println!("{md}");
            println!(
                "wrote {} and {}",
                out.join("edges.csv").display(),
                out.join("edges.md").display()
            );
            Ok(())
        }
        BenchCommand::Fleet {
            maps,
            robots,
            people,
            scenario,
            seed,
            max_wait_s,
            order_seed,
            same_seed,
            json,
            replay,
        } => {
            use anyhow::Context;
            let rows = bench::fleet::run_fleet_bench(&bench::fleet::FleetBenchOptions {
                maps,
                robots,
                people,
                scenario: scenario.parse().map_err(anyhow::Error::msg)?,
                seed,
                robot_ttl: crate::train::bundled_robot_ttl().as_bytes().to_vec(),
                robot_iri: crate::train::ROBOT_IRI.to_owned(),
                max_wait_s,
                order_seed,
                same_seed,
            })?;
            println!("{}", bench::fleet::markdown(&rows));
            for r in &rows {
                for line in r
                    .refusals
                    .iter()
                    .map(|l| format!("refused: {l}"))
                    .chain(r.joint_failures.iter().map(|l| format!("joint run: {l}")))
                {
                    println!("{} ({}) {line}", r.map, r.scenario);
                }
            }
            if let Some(dir) = replay {
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("cannot create {}", dir.display()))?;
                for r in &rows {
                    let path = dir.join(format!("{}-{}.json", r.map, r.scenario));
                    std::fs::write(&path, serde_json::to_string(&r.replay)?)
                        .with_context(|| format!("cannot write {}", path.display()))?;
                    println!(
                        "wrote {} (open it on the console's Traffic page)",
                        path.display()
                    );
                }
            }
            if let Some(path) = json {
                std::fs::write(&path, serde_json::to_string_pretty(&rows)?)
                    .with_context(|| format!("cannot write {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        BenchCommand::PlanLoad {
            url,
            token,
            clients,
            seconds,
            body,
            server_pid,
            json,
        } => {
            let body = match body {
                Some(path) => serde_json::from_slice(&std::fs::read(&path)?)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
                None => bench::plan_load::default_request(),
            };
            let report = bench::plan_load::run(&bench::plan_load::PlanLoadOptions {
                url,
                token: token_or_default(token)?,
                clients,
                seconds,
                body,
                server_pid,
            })?;
            print_json(&serde_json::to_value(&report)?, json)
        }
        BenchCommand::Learner {
            json,
            steps,
            threads,
            batch_size,
            hidden,
            no_sb3,
        } => {
            if hidden.is_empty() || hidden.contains(&0) {
                anyhow::bail!("--hidden: at least one layer, no zero width");
            }
            let options = bench::learner::LearnerBenchOptions {
                steps,
                threads,
                batch_size,
                hidden,
                python: (!no_sb3).then(venv_python),
                ..Default::default()
            };
            let report = bench::learner::run_learner_bench(&options)?;
            print_json(&serde_json::to_value(&report)?, json)
        }
        BenchCommand::Sim {
            map,
            json,
            beams,
            irsim_python,
            irsim_x_python,
            people,
        } => {
            if let Some(n) = people.iter().find(|n| **n > sim::crowd::MAX_PEOPLE) {
                anyhow::bail!(
                    "--people: at most {} people in a simulation, got {n}",
                    sim::crowd::MAX_PEOPLE
                );
            }
            let map = map.unwrap_or_else(|| {
                PathBuf::from("../shared/maps/ros/cob_ipa_production_plant/map.yaml")
            });
            let mut options = bench::sim::SimBenchOptions::new(map);
            options.beams = beams;
            options.people = people;
            options.irsim = irsim_python.map(|python| bench::sim::PeerOptions { python });
            options.irsim_x = irsim_x_python.map(|python| bench::sim::PeerOptions { python });
            let report = bench::sim::run_sim_bench(options)?;
            let text = serde_json::to_string_pretty(&report)?;
            println!("{text}");
            if let Some(path) = json {
                std::fs::write(&path, format!("{text}\n"))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
    }
}

fn knowledge_bench(
    json: Option<PathBuf>,
    oxigraph: Option<PathBuf>,
    triples: usize,
    requests: usize,
    clients: usize,
    seconds: f64,
    min_ratio: Option<f64>,
) -> anyhow::Result<()> {
    use anyhow::Context;
    let mentalsim = std::env::current_exe().context("cannot locate the mentalsim binary")?;
    let oxigraph = match oxigraph {
        Some(path) => path,
        None => find_oxigraph().context(
            "no `oxigraph` binary: `pip install oxigraph` into .venv (scripts/setup does), or pass --oxigraph",
        )?,
    };
    let mut options = bench::knowledge::KnowledgeBenchOptions::new(mentalsim, oxigraph);
    options.min_triples = triples;
    options.on_demand_requests = requests;
    options.clients = clients;
    options.seconds = seconds;
    let report = bench::knowledge::run_knowledge_bench(options)?;
    println!("{}", report.table());
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&report)?;
        std::fs::write(&path, format!("{text}\n"))
            .with_context(|| format!("cannot write {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(min) = min_ratio {
        report.check_ratio(min).map_err(anyhow::Error::msg)?;
    }
    Ok(())
}

/// The `oxigraph` server: the active venv's, the project's `.venv`, or one on the PATH.
fn find_oxigraph() -> Option<PathBuf> {
    let mut candidates = Vec::new();
    if let Some(venv) = std::env::var_os("VIRTUAL_ENV") {
        candidates.push(PathBuf::from(venv).join("bin/oxigraph"));
    }
    candidates.push(PathBuf::from(".venv/bin/oxigraph"));
    if let Some(path) = std::env::var_os("PATH") {
        candidates.extend(std::env::split_paths(&path).map(|d| d.join("oxigraph")));
    }
    candidates.into_iter().find(|p| p.is_file())
}

async fn serve(config: Config) -> anyhow::Result<()> {
    let data_dir = config.data_dir.clone();
    let graph = match &config.store_url {
        Some(url) => format!("graph store: {url}"),
        None => "graph store: embedded".to_owned(),
    };
    let app = Application::build(config).await?;
    let addr = app.local_addr();
    tracing::info!(%addr, data_dir = %data_dir.display(), %graph, "mentalsim listening");
    println!(
        "Mentalsim is listening on http://{addr}  (data: {}; {graph})",
        data_dir.display()
    );
    app.run_until(shutdown_signal()).await
}

async fn run_worker(config: Config) -> anyhow::Result<()> {
    let process = crate::worker_process::WorkerProcess::build(config).await?;
    let addr = process.local_addr();
    tracing::info!(%addr, "mentalsim worker health endpoints listening");
    println!("Mentalsim worker is running; health on http://{addr}");
    process.run_until(shutdown_signal()).await
}
