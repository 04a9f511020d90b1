//! Tests that start the real `mentalsim` binary: configuration errors at startup, the printed
//! URL, and graceful shutdown on signals.

#![allow(
    clippy::unwrap_used,
    reason = "a test that cannot set itself up should fail loudly"
)]

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

mod bounds;
mod faults;
mod plan_load;
mod train;
mod worker;

fn mentalsim() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_mentalsim"));
    // The developer's own environment must not leak into the tests.
    for (key, _) in std::env::vars() {
        if key.starts_with("MENTALSIM_") {
            cmd.env_remove(key);
        }
    }
    cmd
}

#[test]
fn non_numeric_port_in_the_environment_stops_startup_naming_key_and_source() {
    let dir = tempfile::tempdir().unwrap();
    let output = mentalsim()
        .args(["serve", "--data-dir"])
        .arg(dir.path())
        .env("MENTALSIM_BIND", "127.0.0.1:eighty")
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("bind"), "{stderr}");
    assert!(stderr.contains("MENTALSIM_BIND"), "{stderr}");
    // Nothing was started, so nothing was created.
    assert!(!dir.path().join("oxigraph").exists());
}

#[test]
fn bad_flag_value_stops_startup() {
    let output = mentalsim()
        .args(["serve", "--bind", "nowhere"])
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("bind"), "{stderr}");
}

fn assert_graceful_stop_on(signal: Signal) {
    assert_stops_on(signal, &[], Duration::from_secs(20));
}

/// A service started by [`serve`]: the process, its URL and its data directory's parent.
struct Served {
    child: std::process::Child,
    url: String,
    dir: tempfile::TempDir,
    /// Its standard output, kept open: what it prints later must not meet a closed pipe.
    _stdout: BufReader<std::process::ChildStdout>,
}

/// Starts `serve` on a free port with `env` and a new data directory, and waits until it is
/// ready (its start printed the admin token's file, then the URL).
fn serve(env: &[(&str, &str)]) -> Served {
    let dir = tempfile::tempdir().unwrap();
    let mut child = mentalsim()
        .args(["serve", "--bind", "127.0.0.1:0", "--data-dir"])
        .arg(dir.path().join("data"))
        .envs(env.iter().copied())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    // The first start also prints where the admin token went; the URL line follows.
    let mut reader = BufReader::new(stdout);
    let mut printed = String::new();
    let mut line = String::new();
    for _ in 0..5 {
        line.clear();
        reader.read_line(&mut line).unwrap();
        printed.push_str(&line);
        if line.contains("http://") {
            break;
        }
    }
    assert!(line.contains("http://127.0.0.1:"), "printed: {printed}");
    assert!(printed.contains("admin.token"), "printed: {printed}");
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://"))
        .unwrap()
        .to_owned();
    let body = reqwest::blocking_get(&format!("{url}/readyz"));
    assert!(body.contains("\"ready\""), "{body}");
    Served {
        child,
        url,
        dir,
        _stdout: reader,
    }
}

/// Starts `serve` with `env`, sends `signal` once it is ready, and asserts a clean exit within
/// `within`.
fn assert_stops_on(signal: Signal, env: &[(&str, &str)], within: Duration) {
    let Served { mut child, dir, .. } = serve(env);
    kill(Pid::from_raw(i32::try_from(child.id()).unwrap()), signal).unwrap();
    let deadline = Instant::now() + within;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "exit status after {signal}: {status}");
            break;
        }
        assert!(
            Instant::now() < deadline,
            "did not stop within {within:?} of {signal}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    // The store was closed cleanly and reopens.
    assert!(dir.path().join("data/oxigraph/CURRENT").is_file());
}

#[test]
fn sigterm_stops_the_server_gracefully() {
    assert_graceful_stop_on(Signal::SIGTERM);
}

/// A blocking task that never ends (started on purpose by the fault-injection variable) does
/// not keep the process alive past the grace period.
#[test]
fn sigterm_stops_the_server_even_with_a_stuck_blocking_task() {
    assert_stops_on(
        Signal::SIGTERM,
        &[
            ("MENTALSIM_FAULT_STUCK_TASK", "1"),
            ("MENTALSIM_SHUTDOWN_GRACE_S", "1"),
        ],
        Duration::from_secs(4),
    );
}

#[test]
fn sigint_stops_the_server_gracefully() {
    assert_graceful_stop_on(Signal::SIGINT);
}

mod reqwest {
    /// A tiny blocking GET over a runtime, to keep this test binary free of async.
    pub fn blocking_get(url: &str) -> String {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        rt.block_on(async { ::reqwest::get(url).await.unwrap().text().await.unwrap() })
    }
}
