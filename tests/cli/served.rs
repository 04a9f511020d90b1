//! The `mentalsim` processes the CLI tests start, in one place: [`Serve`] (`mentalsim serve`)
//! and [`Worker`] (`mentalsim worker`) start the binary on a free port (`--bind 127.0.0.1:0`),
//! read its standard output up to the URL it prints, and hand back a [`Process`] ([`Service`]
//! for `serve`, with its data directory and admin token). A process is killed and waited on
//! when dropped, so a failed assertion leaves no server behind; its standard output goes on
//! being drained, so it never blocks on a full pipe; its standard error is discarded. The
//! environment is [`mentalsim`]'s (no `MENTALSIM_*` variable of the developer's) plus what the
//! builder's `env` sets.

use std::ffi::OsString;
use std::io::{BufRead, BufReader};
use std::ops::{Deref, DerefMut};
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::Duration;

use fixtures::wait::eventually;
use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;

use super::mentalsim;

/// `mentalsim serve` to start: see [`Serve::new`].
#[must_use = "nothing runs until `start`"]
pub(super) struct Serve {
    data: Option<PathBuf>,
    env: Vec<(OsString, OsString)>,
    check_ready: bool,
}

impl Serve {
    /// `mentalsim serve --bind 127.0.0.1:0` on a new data directory (`data` in a temporary
    /// directory that the [`Service`] owns), with no variables but those [`Serve::env`] sets.
    pub(super) fn new() -> Self {
        Self {
            data: None,
            env: Vec::new(),
            check_ready: false,
        }
    }

    /// Serves from `data` instead (created if absent, left in place when the service is
    /// dropped): to start again on an earlier start's data, or on a particular filesystem.
    pub(super) fn data_dir(mut self, data: impl Into<PathBuf>) -> Self {
        self.data = Some(data.into());
        self
    }

    /// Sets the environment variable `key` to `value` for the service.
    pub(super) fn env(mut self, key: impl Into<OsString>, value: impl Into<OsString>) -> Self {
        self.env.push((key.into(), value.into()));
        self
    }

    /// Asserts, as soon as the URL is printed, that `/readyz` answers ready.
    pub(super) fn check_ready(mut self) -> Self {
        self.check_ready = true;
        self
    }

    /// Starts the service and waits until it has printed its URL (and, with
    /// [`Serve::check_ready`], answers ready).
    ///
    /// # Panics
    /// When it cannot start, prints no URL, or has written no admin token.
    pub(super) fn start(self) -> Service {
        let (dir, data) = match self.data {
            Some(data) => (None, data),
            None => {
                let dir = tempfile::tempdir().unwrap();
                let data = dir.path().join("data");
                (Some(dir), data)
            }
        };
        let mut command = mentalsim();
        command
            .args(["serve", "--bind", "127.0.0.1:0", "--data-dir"])
            .arg(&data)
            .envs(self.env);
        let process = Process::start("mentalsim serve", command);
        if self.check_ready {
            let body = ::reqwest::blocking::get(format!("{}/readyz", process.url))
                .unwrap()
                .text()
                .unwrap();
            assert!(body.contains("\"ready\""), "{body}");
        }
        let token = std::fs::read_to_string(data.join("admin.token"))
            .unwrap()
            .trim()
            .to_owned();
        Service {
            process,
            token,
            data,
            _dir: dir,
        }
    }
}

/// A running `mentalsim serve` (see [`Serve`]): the [`Process`] (its URL, signals, exit), its
/// admin token and its data directory.
pub(super) struct Service {
    process: Process,
    /// The admin token, as the service wrote it to `<data>/admin.token`.
    pub(super) token: String,
    /// Its data directory (`--data-dir`).
    pub(super) data: PathBuf,
    /// The temporary directory around `data` when [`Serve::data_dir`] did not name one:
    /// removed after the process is gone (fields drop in order).
    _dir: Option<tempfile::TempDir>,
}

impl Deref for Service {
    type Target = Process;
    fn deref(&self) -> &Process {
        &self.process
    }
}

impl DerefMut for Service {
    fn deref_mut(&mut self) -> &mut Process {
        &mut self.process
    }
}

/// `mentalsim worker` to start: see [`Worker::new`].
#[must_use = "nothing runs until `start`"]
pub(super) struct Worker {
    knowledge_url: String,
    data: PathBuf,
    database_url: Option<String>,
    env: Vec<(OsString, OsString)>,
}

impl Worker {
    /// `mentalsim worker --bind 127.0.0.1:0 --concurrency 1` with the knowledge service at
    /// `knowledge_url` and its own files in `data` (`--data-dir`), with no variables but those
    /// [`Worker::env`] sets.
    pub(super) fn new(knowledge_url: &str, data: impl Into<PathBuf>) -> Self {
        Self {
            knowledge_url: knowledge_url.to_owned(),
            data: data.into(),
            database_url: None,
            env: Vec::new(),
        }
    }

    /// Claims its jobs from the job database at `url` (`--database-url`).
    pub(super) fn database_url(mut self, url: impl Into<String>) -> Self {
        self.database_url = Some(url.into());
        self
    }

    /// Sets the environment variable `key` to `value` for the worker.
    pub(super) fn env(mut self, key: impl Into<OsString>, value: impl Into<OsString>) -> Self {
        self.env.push((key.into(), value.into()));
        self
    }

    /// Starts the worker and waits until it has printed its health URL (the [`Process`]'s
    /// `url`); it need not be ready yet (see [`Process::wait_ready`]).
    ///
    /// # Panics
    /// When it cannot start or prints no URL.
    pub(super) fn start(self) -> Process {
        let mut command = mentalsim();
        command
            .args(["worker", "--bind", "127.0.0.1:0", "--concurrency", "1"])
            .arg("--knowledge-url")
            .arg(&self.knowledge_url)
            .arg("--data-dir")
            .arg(&self.data)
            .envs(self.env);
        if let Some(url) = &self.database_url {
            command.arg("--database-url").arg(url);
        }
        Process::start("mentalsim worker", command)
    }
}

/// A started `mentalsim` process that printed its URL; killed (SIGKILL) and waited on when
/// dropped unless it has exited.
pub(super) struct Process {
    /// What it is, to name it in failures (`mentalsim serve`).
    what: &'static str,
    child: Child,
    /// The URL it printed (`http://127.0.0.1:<port>`).
    pub(super) url: String,
    /// Its standard output up to and including the line with the URL.
    pub(super) printed: String,
    /// The last signal sent with [`Process::signal`], to name it if the process does not exit.
    signalled: Option<Signal>,
}

impl Process {
    /// Spawns `command` with standard output piped and standard error discarded, reads the
    /// output until a word that starts with `http://`, and drains the rest in a thread.
    fn start(what: &'static str, mut command: Command) -> Self {
        let mut child = command
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("{what} cannot start: {e}"));
        let mut reader = BufReader::new(child.stdout.take().unwrap());
        let mut printed = String::new();
        let url = loop {
            let mut line = String::new();
            let read = reader.read_line(&mut line).unwrap();
            printed.push_str(&line);
            if read == 0 {
                let _ = child.kill();
                let status = child.wait();
                panic!("{what} printed no URL ({status:?}); printed: {printed}");
            }
            if let Some(url) = line.split_whitespace().find(|w| w.starts_with("http://")) {
                break url.to_owned();
            }
        };
        // Keep draining stdout so the child never blocks on a full pipe.
        std::thread::spawn(move || for _ in reader.lines() {});
        Self {
            what,
            child,
            url,
            printed,
            signalled: None,
        }
    }

    /// Its process id.
    pub(super) fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Sends it `signal`.
    pub(super) fn signal(&mut self, signal: Signal) {
        let pid = Pid::from_raw(i32::try_from(self.child.id()).unwrap());
        kill(pid, signal).unwrap();
        self.signalled = Some(signal);
    }

    /// Waits at most `within` for it to exit, and returns how it did.
    ///
    /// # Panics
    /// When it is still running after `within`, naming the last signal sent.
    #[track_caller]
    pub(super) fn wait_exit(&mut self, within: Duration) -> ExitStatus {
        let what = match self.signalled {
            Some(signal) => format!("{} to exit after {signal}", self.what),
            None => format!("{} to exit", self.what),
        };
        let child = &mut self.child;
        eventually(what, within)
            .every(Duration::from_millis(50))
            .until(|| child.try_wait().unwrap())
    }

    /// Stops it with SIGTERM and asserts a clean exit within `within`.
    #[track_caller]
    pub(super) fn stop(&mut self, within: Duration) {
        self.signal(Signal::SIGTERM);
        let status = self.wait_exit(within);
        assert!(status.success(), "{} exit status: {status}", self.what);
    }

    /// Kills it at once (SIGKILL, no chance to clean up) and reaps it.
    pub(super) fn kill_now(&mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    /// Waits at most `within` for its `/readyz` to answer 200.
    #[track_caller]
    pub(super) fn wait_ready(&self, within: Duration) {
        let client = ::reqwest::blocking::Client::new();
        let readyz = format!("{}/readyz", self.url);
        eventually(format!("{} to become ready", self.what), within)
            .every(Duration::from_millis(200))
            .until(|| match client.get(&readyz).send() {
                Ok(r) if r.status() == 200 => Ok(()),
                Ok(r) => Err(format!("{}: {}", r.status(), r.text().unwrap_or_default())),
                Err(e) => Err(e.to_string()),
            });
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        if !matches!(self.child.try_wait(), Ok(Some(_))) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
