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
    },
}

/// Runs the command line; the process exit code says whether it worked.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Serve { bind, data_dir } => {
            let overrides = Overrides { bind, data_dir };
            let config = match Config::load(cli.config.as_deref(), &overrides) {
                Ok(config) => config,
                Err(e) => {
                    eprintln!("mentalsim: {e}");
                    return ExitCode::from(2);
                }
            };
            crate::telemetry::init(&config);
            let runtime = match tokio::runtime::Builder::new_multi_thread().enable_all().build() {
                Ok(rt) => rt,
                Err(e) => {
                    eprintln!("mentalsim: cannot start the async runtime: {e}");
                    return ExitCode::FAILURE;
                }
            };
            match runtime.block_on(serve(config)) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    tracing::error!(error = %e, "mentalsim serve failed");
                    eprintln!("mentalsim: {e:#}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}

async fn serve(config: Config) -> anyhow::Result<()> {
    let data_dir = config.data_dir.clone();
    let app = Application::build(config).await?;
    let addr = app.local_addr();
    tracing::info!(%addr, data_dir = %data_dir.display(), "mentalsim listening");
    println!("Mentalsim is listening on http://{addr}  (data: {})", data_dir.display());
    app.run_until(shutdown_signal()).await
}
