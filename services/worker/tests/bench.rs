//! The queue throughput benchmark, as an ignored test (the CLI's `mentalsim bench queue` calls
//! the same `worker::bench::run`):
//!
//! ```sh
//! cargo test -p worker --test bench -- --ignored --nocapture
//! QUEUE_BENCH_JOBS=5000 QUEUE_BENCH_CONCURRENCY=8 cargo test -p worker --test bench -- --ignored --nocapture
//! ```

#![allow(clippy::unwrap_used, clippy::print_stdout)] // reason: a benchmark reports and panics

use worker::bench::{BenchOptions, run};

fn env_usize(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[tokio::test(flavor = "multi_thread")]
#[ignore = "a benchmark: run with --ignored --nocapture"]
async fn queue_throughput() {
    let options = BenchOptions {
        jobs: env_usize("QUEUE_BENCH_JOBS", BenchOptions::default().jobs),
        concurrency: env_usize(
            "QUEUE_BENCH_CONCURRENCY",
            BenchOptions::default().concurrency,
        ),
        postgres_url: std::env::var("QUEUE_BENCH_POSTGRES_URL").ok(),
    };
    let reports = run(&options).await.unwrap();
    println!("queue throughput (durable commits: SQLite synchronous=FULL, PostgreSQL fsync=on)");
    for report in &reports {
        println!("{report}");
    }
    if reports.len() < 2 {
        println!("PostgreSQL skipped: binaries not found and QUEUE_BENCH_POSTGRES_URL not set");
    }
}
