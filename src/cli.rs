//! The `mentalsim` command line: a thin layer that parses arguments and calls the services.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::config::{Config, Overrides};
use crate::startup::{Application, shutdown_signal};

mod bench;

pub use self::bench::BenchCommand;

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
        Command::Bench(command) => bench::run(command),
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
