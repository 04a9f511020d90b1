//! Tests that start the real `mentalsim` binary: configuration errors at startup, the printed
//! URL, and graceful shutdown on signals.

#![allow(
    clippy::unwrap_used,
    reason = "a test that cannot set itself up should fail loudly"
)]

use std::process::Command;
use std::time::Duration;

use nix::sys::signal::Signal;

use served::Serve;

mod bounds;
mod faults;
mod plan_load;
mod served;
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

/// Starts `serve` with `env`, sends `signal` once it is ready, and asserts a clean exit within
/// `within`.
fn assert_stops_on(signal: Signal, env: &[(&str, &str)], within: Duration) {
    let mut service = env
        .iter()
        .fold(Serve::new(), |serve, &(key, value)| serve.env(key, value))
        .check_ready()
        .start();
    // The first start also prints where the admin token went; the URL line follows.
    let printed = &service.printed;
    assert!(
        service.url.starts_with("http://127.0.0.1:"),
        "printed: {printed}"
    );
    assert!(printed.contains("admin.token"), "printed: {printed}");
    service.signal(signal);
    let status = service.wait_exit(within);
    assert!(status.success(), "exit status after {signal}: {status}");
    // The store was closed cleanly and reopens.
    assert!(service.data.join("oxigraph/CURRENT").is_file());
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
