//! Runs the navigation benchmark until `mentalsim bench navigation` is wired:
//! `cargo run --release -p bench --example navigation -- --maps DIR --runs N [--policy DIR] --out DIR`.

use std::path::PathBuf;
use std::process::ExitCode;

use bench::navigation::{NavigationBenchOptions, run_navigation_bench};

fn main() -> ExitCode {
    let mut opts = NavigationBenchOptions {
        verbose: true,
        ..NavigationBenchOptions::default()
    };
    let mut args = std::env::args().skip(1);
    while let Some(flag) = args.next() {
        let Some(value) = args.next() else {
            eprintln!("{flag} needs a value");
            return ExitCode::from(2);
        };
        match flag.as_str() {
            "--maps" => opts.maps_dir = PathBuf::from(value),
            "--policy" => opts.policy = Some(PathBuf::from(value)),
            "--out" => opts.out_dir = PathBuf::from(value),
            "--runs" | "--seed" | "--objects" => {
                let Ok(n) = value.parse::<u64>() else {
                    eprintln!("{flag} takes a whole number, got {value}");
                    return ExitCode::from(2);
                };
                match flag.as_str() {
                    "--runs" => opts.runs = usize::try_from(n).unwrap_or(usize::MAX),
                    "--objects" => opts.objects = usize::try_from(n).unwrap_or(usize::MAX),
                    _ => opts.seed = n,
                }
            }
            other => {
                eprintln!("unknown flag {other}");
                return ExitCode::from(2);
            }
        }
    }
    match run_navigation_bench(opts) {
        Ok(report) => {
            println!("{}", report.summary());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
