//! `mentalsim bench …`: one argument struct per benchmark, and one function each that hands
//! them to its harness in the `bench` crate and prints (and writes) the figures.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};

use super::{print_json, stop_flag, token_or_default};

/// Benchmarks: each prints its figures and writes them to files.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// The paper's PRM protocol (Table 2, Figure 9) on every ROS map under a directory, beside OMPL.
    Prm(PrmArgs),
    /// Simulator steps per second (one core, all cores) and world build time, beside IR-SIM.
    Sim(SimArgs),
    /// The paper's §5.2: one policy per (β1 = β2, seed), final success and reward curves.
    Beta(BetaArgs),
    /// Job queue throughput (enqueue, claim + complete) on SQLite and a temporary PostgreSQL.
    Queue(QueueArgs),
    /// The paper's Table 3 in the mental simulation: long missions on every ROS map under a
    /// directory with hybrid PRM-RL, pure RL and a classical follower on the PRM path.
    Navigation(NavigationArgs),
    /// Per-edge success of policies on every roadmap edge of every map under a directory (both
    /// directions, K rollouts each), the classical follower beside them with the same seeds
    Edges(EdgesArgs),
    /// N robots ask for plans at once on each map; the committed plans are then driven
    /// together (joint success, robot collisions, stalls, makespan against the robots alone,
    /// plan latency p50/p95).
    Fleet(FleetArgs),
    /// POST /v1/plan latency of a running service under C concurrent robot clients.
    PlanLoad(PlanLoadArgs),
    /// TD3 gradient steps per second, ours beside Stable-Baselines3's, same sizes, one run.
    Learner(LearnerArgs),
    /// On-demand database latency on a 100,000-triple building, and SPARQL query throughput of
    /// our /sparql beside `oxigraph serve` holding the same data.
    Knowledge(KnowledgeArgs),
}

/// What `mentalsim bench prm` takes.
#[derive(Debug, Args)]
pub struct PrmArgs {
    /// Directory searched recursively for ROS map_server YAML files.
    #[arg(long, default_value = "../shared/maps/ros")]
    pub maps: PathBuf,
    /// Runs per map and sample count (the paper: 50).
    #[arg(long, default_value_t = 50)]
    pub runs: usize,
    /// Where prm.csv, prm.md and prm.png go.
    #[arg(long, default_value = "bench-out/prm")]
    pub out: PathBuf,
    /// MovingAI maps and scenarios to run as well.
    #[arg(long)]
    pub movingai: Option<PathBuf>,
    /// Skip OMPL (Python bindings and C++ library).
    #[arg(long)]
    pub no_ompl: bool,
}

/// What `mentalsim bench sim` takes.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// The ROS map_server YAML [default: the largest shared map].
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Laser readings per observation.
    #[arg(long, default_value_t = 23)]
    pub beams: usize,
    /// Python with `ir-sim` installed, to run it side by side.
    #[arg(long)]
    pub irsim_python: Option<PathBuf>,
    /// Python with `irsim-x` installed, to run it side by side.
    #[arg(long)]
    pub irsim_x_python: Option<PathBuf>,
    /// Numbers of people walking about to time one core with, one run each.
    #[arg(long, value_delimiter = ',', default_values_t = [0, 10, 50])]
    pub people: Vec<usize>,
}

/// What `mentalsim bench beta` takes.
#[derive(Debug, Args)]
pub struct BetaArgs {
    /// The ROS map_server YAML of the place.
    #[arg(long)]
    pub map: PathBuf,
    /// Minutes per training.
    #[arg(long, default_value_t = 10.0)]
    pub minutes: f64,
    /// Values of β1 = β2 (the paper: 0, 1, 5).
    #[arg(long, value_delimiter = ',', default_values_t = [0.0, 1.0, 5.0])]
    pub betas: Vec<f64>,
    /// Seeds per value.
    #[arg(long, value_delimiter = ',', default_values_t = [1, 2, 3])]
    pub seeds: Vec<u64>,
    /// Where the runs, beta.md and beta.png go.
    #[arg(long, default_value = "bench-out/beta")]
    pub out: PathBuf,
    /// Training configuration shared by all runs (JSON).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Held-out missions of each final evaluation.
    #[arg(long, default_value_t = 200)]
    pub eval_episodes: usize,
}

/// What `mentalsim bench queue` takes.
#[derive(Debug, Args)]
pub struct QueueArgs {
    /// Write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Jobs per backend.
    #[arg(long, default_value_t = 2000)]
    pub jobs: usize,
    /// Concurrent enqueuers, then concurrent workers.
    #[arg(long, default_value_t = 4)]
    pub concurrency: usize,
    /// A PostgreSQL database to use instead of a temporary cluster.
    #[arg(long, env = "QUEUE_BENCH_POSTGRES_URL", hide_env_values = true)]
    pub postgres_url: Option<String>,
}

/// What `mentalsim bench navigation` takes.
#[derive(Debug, Args)]
pub struct NavigationArgs {
    /// Directory searched recursively for ROS map_server YAML files.
    #[arg(long, default_value = "../shared/maps/ros")]
    pub maps: PathBuf,
    /// Runs per method and map (the paper: 10).
    #[arg(long, default_value_t = 10)]
    pub runs: usize,
    /// An exported policy (policy.safetensors + policy.json); without one only the classical
    /// follower runs.
    #[arg(long)]
    pub policy: Option<PathBuf>,
    /// Where navigation.csv and navigation.md go.
    #[arg(long, default_value = "bench-out/navigation")]
    pub out: PathBuf,
    /// Mission length along the roadmap where the map allows, metres (the paper: ~140).
    #[arg(long, default_value_t = 140.0)]
    pub mission_length_m: f64,
    /// Clearance the roadmap keeps beyond the robot's radius, metres (the plan endpoint's
    /// `options.safety_margin_m`).
    #[arg(long, default_value_t = 0.1)]
    pub safety_margin_m: f64,
    /// People walking about in every rehearsal, per 100 m² of free region (0: the empty
    /// building; the table runs 0, 1, 2 and 4).
    #[arg(long, default_value_t = 0.0)]
    pub people: f64,
    /// Base seed of the missions, roadmaps, noise and people: another seed, other
    /// missions and crowds.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run only these methods (comma-separated names from the table; all by default).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Every method's roadmap path with its detours removed (the plan endpoint's
    /// `options.shortcut`; `auto`'s trial keeps its own default).
    #[arg(long)]
    pub shortcut: bool,
    /// Build the policy-aware roadmap again in every run on that run's geometric roadmap
    /// (the classical methods'), not once per map.
    #[arg(long)]
    pub policy_roadmap_per_run: bool,
}

/// What `mentalsim bench edges` takes.
#[derive(Debug, Args)]
pub struct EdgesArgs {
    /// Directory searched recursively for ROS map_server YAML files.
    #[arg(long, default_value = "../shared/maps/ros")]
    pub maps: PathBuf,
    /// An exported policy (repeatable: several side by side).
    #[arg(long = "policy")]
    pub policies: Vec<PathBuf>,
    /// Rollouts per edge direction.
    #[arg(long, default_value_t = 10)]
    pub rollouts: u32,
    /// At most this many roadmap edges per map (both directions each), a sample drawn with
    /// the seed: a quick look (MPPI drives a few hundred edges in half a minute). Default:
    /// every edge.
    #[arg(long)]
    pub edges: Option<usize>,
    /// Seed of the roadmaps and rollouts.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Where edges.csv and edges.md go.
    #[arg(long, default_value = "bench-out/edges")]
    pub out: PathBuf,
    /// People per 100 m² of free region walking about in the rollouts (repeatable or
    /// comma-separated: each density its own rows; default 0, the empty building).
    #[arg(long, value_delimiter = ',')]
    pub people: Vec<f64>,
    /// Controllers to drive (repeatable or comma-separated: policy, shield_only,
    /// hybrid_rpp, follower, rpp, mppi; default all).
    #[arg(long = "controller", value_delimiter = ',')]
    pub controllers: Vec<String>,
}

/// What `mentalsim bench fleet` takes.
#[derive(Debug, Args)]
pub struct FleetArgs {
    /// Directory searched recursively for ROS map_server YAML files (`random`).
    #[arg(long, default_value = "../shared/maps/ros")]
    pub maps: PathBuf,
    /// Robots at once.
    #[arg(long, default_value_t = 20)]
    pub robots: usize,
    /// People per 100 m² of free region.
    #[arg(long, default_value_t = 0.0)]
    pub people: f64,
    /// `random` missions on every map, or a generated floor: `corridor` (a corridor one
    /// robot wide, half the robots at each end), `crossing` (two such corridors crossing,
    /// the robots split over the rooms at the four ends, each sent to the opposite one) or
    /// `doorway` (two rooms joined by one door a robot wide, half the robots in each).
    #[arg(long, value_parser = ["random", "corridor", "crossing", "doorway"], default_value = "random")]
    pub scenario: String,
    /// Seed of the missions and simulations.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Most waiting a plan may take to let others pass (`options.max_wait_s`), seconds.
    #[arg(long, default_value_t = 600.0)]
    pub max_wait_s: f64,
    /// Plans the robots one after another in an order shuffled by SEED instead of all at
    /// once, so that a run whose outcome depends on the plan order can be repeated.
    #[arg(long, value_name = "SEED")]
    pub order_seed: Option<u64>,
    /// Every robot asks with the same `options.seed`, as robots sending the default options
    /// do (one roadmap and the same draws for all), instead of one seed each.
    #[arg(long)]
    pub same_seed: bool,
    /// The reference beside the run: the same missions planned first-come, one robot after
    /// another, in K orders (the first by robot index, the others shuffled by seeds derived
    /// from --seed), each on a fresh schedule and driven jointly; reports each order's
    /// makespan and the best among those that brought every robot through. 0 to skip; at most
    /// 24. Each order costs about one run planned in turn.
    #[arg(long, value_name = "K", default_value_t = 4)]
    pub orders: usize,
    /// Seconds the planner's idle-time improver works on the floor's schedule once every
    /// robot has its plan, before the joint run (0: none); the row reports the first-come
    /// joint run's makespan beside the revised one's.
    #[arg(long, value_name = "S", default_value_t = 60.0)]
    pub improve_s: f64,
    /// Planners the robots ask (robot k asks planner k mod N), each with its own locks, waits
    /// and improver over the one schedule, as API processes sharing a job database are; at
    /// most 8.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub processes: usize,
    /// Writes the rows as JSON (one object per map and scenario).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Writes each joint run as `DIR/MAP-SCENARIO.json`, which the console's Traffic page
    /// replays (every robot as it drove among the others, and how it fared).
    #[arg(long, value_name = "DIR")]
    pub replay: Option<PathBuf>,
}

/// What `mentalsim bench plan-load` takes.
#[derive(Debug, Args)]
pub struct PlanLoadArgs {
    /// The service's URL.
    #[arg(long, env = "MENTALSIM_URL", default_value = "http://127.0.0.1:8080")]
    pub url: String,
    /// A bearer token [default: read from ./data/admin.token].
    #[arg(long, env = "MENTALSIM_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Concurrent clients.
    #[arg(long, default_value_t = 50)]
    pub clients: usize,
    /// Seconds of load.
    #[arg(long, default_value_t = 20.0)]
    pub seconds: f64,
    /// The plan request (JSON file) [default: across the bundled building's ground floor].
    #[arg(long)]
    pub body: Option<PathBuf>,
    /// The service's process id, when it runs on this machine: the figures then include
    /// its CPU time per plan (and the load generator's own, which shares the cores).
    #[arg(long, value_name = "PID")]
    pub server_pid: Option<u32>,
    /// Write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// What `mentalsim bench learner` takes.
#[derive(Debug, Args)]
pub struct LearnerArgs {
    /// Write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Timed gradient steps of each learner.
    #[arg(long, default_value_t = 2000)]
    pub steps: u64,
    /// libtorch intra-op threads of both (0: libtorch's default).
    #[arg(long, default_value_t = 1)]
    pub threads: usize,
    /// Batch size.
    #[arg(long, default_value_t = 256)]
    pub batch_size: usize,
    /// Hidden layer widths of actor and critics, comma-separated (the `fast` preset: 64,64).
    #[arg(long, value_delimiter = ',', default_value = "256,256")]
    pub hidden: Vec<usize>,
    /// Skip Stable-Baselines3.
    #[arg(long)]
    pub no_sb3: bool,
}

/// What `mentalsim bench knowledge` takes.
#[derive(Debug, Args)]
pub struct KnowledgeArgs {
    /// Write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The `oxigraph` server binary (PyPI `oxigraph`) [default: .venv/bin/oxigraph, else PATH].
    #[arg(long)]
    pub oxigraph: Option<PathBuf>,
    /// At least this many triples in the store.
    #[arg(long, default_value_t = 100_000)]
    pub triples: usize,
    /// Timed on-demand requests.
    #[arg(long, default_value_t = 200)]
    pub requests: usize,
    /// Concurrent SPARQL clients (the same for both servers).
    #[arg(long, default_value_t = 4)]
    pub clients: usize,
    /// Seconds of measurement per server.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Exit non-zero when the query mix runs below this ratio ours/oxigraph serve (the
    /// figures are still printed and written).
    #[arg(long, value_name = "R", value_parser = positive_ratio)]
    pub min_ratio: Option<f64>,
}

/// Runs the benchmark `command` asks for.
/// Logs go to standard error where `RUST_LOG` asks for them (the harnesses print their
/// figures on standard output).
pub(super) fn run(command: BenchCommand) -> anyhow::Result<()> {
    if std::env::var_os("RUST_LOG").is_some() {
        crate::telemetry::init(&crate::config::Config::default());
    }
    match command {
        BenchCommand::Knowledge(args) => knowledge(args),
        BenchCommand::Prm(args) => prm(args),
        BenchCommand::Beta(args) => beta(args),
        BenchCommand::Queue(args) => queue(args),
        BenchCommand::Navigation(args) => navigation(args),
        BenchCommand::Edges(args) => edges(args),
        BenchCommand::Fleet(args) => fleet(args),
        BenchCommand::PlanLoad(args) => plan_load(args),
        BenchCommand::Learner(args) => learner(args),
        BenchCommand::Sim(args) => sim(args),
    }
}

fn positive_ratio(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(r) if r.is_finite() && r > 0.0 => Ok(r),
        _ => Err(format!("`{text}` is not a positive ratio (e.g. 0.9)")),
    }
}

/// The project's Python (the virtual environment `scripts/env.sh` activates).
fn venv_python() -> PathBuf {
    std::env::var_os("VIRTUAL_ENV")
        .map(|v| PathBuf::from(v).join("bin/python"))
        .unwrap_or_else(|| PathBuf::from(".venv/bin/python"))
}

/// `mentalsim bench prm`: the PRM protocol on every map, beside OMPL unless asked not to.
fn prm(args: PrmArgs) -> anyhow::Result<()> {
    let PrmArgs {
        maps,
        runs,
        out,
        movingai,
        no_ompl,
    } = args;
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

/// `mentalsim bench beta`: one training per (β, seed); Ctrl-C stops it cleanly.
fn beta(args: BetaArgs) -> anyhow::Result<()> {
    let BetaArgs {
        map,
        minutes,
        betas,
        seeds,
        out,
        config,
        eval_episodes,
    } = args;
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

/// `mentalsim bench queue`: the job queue's throughput on SQLite and PostgreSQL.
fn queue(args: QueueArgs) -> anyhow::Result<()> {
    let QueueArgs {
        json,
        jobs,
        concurrency,
        postgres_url,
    } = args;
    let options = bench::queue::BenchOptions {
        jobs,
        concurrency,
        postgres_url,
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let reports = runtime.block_on(bench::queue::run(&options))?;
    println!("queue throughput (durable commits: SQLite synchronous=FULL, PostgreSQL fsync=on)");
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

/// `mentalsim bench navigation`: the paper's Table 3 in the mental simulation.
fn navigation(args: NavigationArgs) -> anyhow::Result<()> {
    let NavigationArgs {
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
    } = args;
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

/// `mentalsim bench edges`: every roadmap edge driven by each controller.
fn edges(args: EdgesArgs) -> anyhow::Result<()> {
    let EdgesArgs {
        maps,
        policies,
        rollouts,
        edges,
        seed,
        out,
        people,
        controllers,
    } = args;
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

/// `mentalsim bench fleet`: robots planning at once, then driven together; the rows, what was
/// refused or failed, and the joint runs for the console's Traffic page.
fn fleet(args: FleetArgs) -> anyhow::Result<()> {
    let FleetArgs {
        maps,
        robots,
        people,
        scenario,
        seed,
        max_wait_s,
        order_seed,
        same_seed,
        orders,
        improve_s,
        processes,
        json,
        replay,
    } = args;
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
        orders,
        improve_s,
        processes,
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

/// `mentalsim bench plan-load`: `POST /v1/plan` under concurrent clients.
fn plan_load(args: PlanLoadArgs) -> anyhow::Result<()> {
    let PlanLoadArgs {
        url,
        token,
        clients,
        seconds,
        body,
        server_pid,
        json,
    } = args;
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

/// `mentalsim bench learner`: TD3 gradient steps per second, beside Stable-Baselines3.
fn learner(args: LearnerArgs) -> anyhow::Result<()> {
    let LearnerArgs {
        json,
        steps,
        threads,
        batch_size,
        hidden,
        no_sb3,
    } = args;
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

/// `mentalsim bench sim`: simulator steps per second, beside IR-SIM when asked.
fn sim(args: SimArgs) -> anyhow::Result<()> {
    let SimArgs {
        map,
        json,
        beams,
        irsim_python,
        irsim_x_python,
        people,
    } = args;
    if let Some(n) = people.iter().find(|n| **n > sim::crowd::MAX_PEOPLE) {
        anyhow::bail!(
            "--people: at most {} people in a simulation, got {n}",
            sim::crowd::MAX_PEOPLE
        );
    }
    let map = map
        .unwrap_or_else(|| PathBuf::from("../shared/maps/ros/cob_ipa_production_plant/map.yaml"));
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

/// `mentalsim bench knowledge`: the on-demand database and SPARQL beside `oxigraph serve`;
/// an error when the query mix runs below `--min-ratio` (after the figures).
fn knowledge(args: KnowledgeArgs) -> anyhow::Result<()> {
    let KnowledgeArgs {
        json,
        oxigraph,
        triples,
        requests,
        clients,
        seconds,
        min_ratio,
    } = args;
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
