//! A throw-away PostgreSQL cluster for tests and benchmarks: `initdb` into a temporary
//! directory, `postgres` listening only on a Unix socket in that directory, stopped and deleted
//! when dropped — or, if the process dies first, by a watchdog shell that notices the parent is
//! gone.
//!
//! PostgreSQL refuses to run as root; when we are root, the cluster runs as the `postgres` user
//! (`runuser`), which owns the directory. The binaries are found in `$MENTALSIM_PG_BIN`, else
//! the newest `/usr/lib/postgresql/*/bin` (Debian's layout), else on `PATH`.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Why the cluster could not be started or used.
#[derive(Debug, thiserror::Error)]
pub enum TempPostgresError {
    /// No `initdb`/`postgres` binaries were found.
    #[error(
        "PostgreSQL binaries not found (set MENTALSIM_PG_BIN, or install postgresql: scripts/setup does)"
    )]
    NotInstalled,
    /// A step failed.
    #[error("temporary PostgreSQL: {0}")]
    Failed(String),
}

/// How the cluster trades durability for speed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Durability {
    /// PostgreSQL's defaults (`fsync = on`, `synchronous_commit = on`): for benchmarks.
    Durable,
    /// `fsync = off`, `synchronous_commit = off`: for tests, where a crash of the machine
    /// does not matter.
    Fast,
}

/// A running temporary cluster.
#[derive(Debug)]
pub struct TempPostgres {
    dir: PathBuf,
    port: u16,
    watchdog: Option<Child>,
}

const PORT: u16 = 5432;

fn failed(what: impl std::fmt::Display) -> TempPostgresError {
    TempPostgresError::Failed(what.to_string())
}

/// The directory holding `initdb` and `postgres`, if PostgreSQL is installed.
pub fn bin_dir() -> Option<PathBuf> {
    let has = |dir: &Path| dir.join("initdb").is_file() && dir.join("postgres").is_file();
    if let Some(dir) = std::env::var_os("MENTALSIM_PG_BIN").map(PathBuf::from) {
        return has(&dir).then_some(dir);
    }
    let mut versions: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| {
            let version = entry.file_name().to_str()?.parse::<u32>().ok()?;
            let bin = entry.path().join("bin");
            has(&bin).then_some((version, bin))
        })
        .collect();
    versions.sort();
    if let Some((_, bin)) = versions.pop() {
        return Some(bin);
    }
    std::env::var_os("PATH")
        .map(|path| std::env::split_paths(&path).collect::<Vec<_>>())
        .unwrap_or_default()
        .into_iter()
        .find(|dir| has(dir))
}

fn running_as_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|out| String::from_utf8_lossy(&out.stdout).trim() == "0")
        .unwrap_or(false)
}

/// `program args…`, as the `postgres` user when we are root.
fn command(as_postgres: bool, program: &Path) -> Command {
    if as_postgres {
        let mut cmd = Command::new("runuser");
        cmd.args(["-u", "postgres", "--"]).arg(program);
        cmd
    } else {
        Command::new(program)
    }
}

fn quote(path: &Path) -> String {
    format!("'{}'", path.display().to_string().replace('\'', "'\\''"))
}

impl TempPostgres {
    /// Creates and starts a cluster; blocks until it accepts connections (a few seconds).
    pub fn start(durability: Durability) -> Result<Self, TempPostgresError> {
        let bin = bin_dir().ok_or(TempPostgresError::NotInstalled)?;
        let as_postgres = running_as_root();
        let dir =
            std::env::temp_dir().join(format!("mentalsim-pg-{}", uuid::Uuid::new_v4().simple()));
        std::fs::create_dir(&dir).map_err(|e| failed(format!("{}: {e}", dir.display())))?;
        let mut cluster = Self {
            dir: dir.clone(),
            port: PORT,
            watchdog: None,
        };
        if as_postgres {
            let status = Command::new("chown")
                .args(["postgres:postgres"])
                .arg(&dir)
                .status()
                .map_err(|e| failed(format!("chown: {e}")))?;
            if !status.success() {
                return Err(failed(format!("chown postgres {} failed", dir.display())));
            }
        }
        let data = dir.join("data");
        let out = command(as_postgres, &bin.join("initdb"))
            .args([
                "-U",
                "postgres",
                "--auth=trust",
                "-E",
                "UTF8",
                "--no-locale",
                "--no-sync",
                "-D",
            ])
            .arg(&data)
            .stdin(Stdio::null())
            .output()
            .map_err(|e| failed(format!("initdb: {e}")))?;
        if !out.status.success() {
            return Err(failed(format!(
                "initdb failed: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            )));
        }
        let settings = match durability {
            Durability::Durable => "",
            Durability::Fast => "-c fsync=off -c synchronous_commit=off -c full_page_writes=off",
        };
        // The watchdog runs postgres and stops it (then deletes the directory) when asked
        // through the `stop` file, or when this process is gone.
        let script = format!(
            "{postgres} -D {data} -k {dir} -p {PORT} -c listen_addresses= -c max_connections=300 {settings} \
               > {dir}/postgres.log 2>&1 &
             pg=$!
             while [ -d /proc/{parent} ] && [ ! -e {dir}/stop ] && kill -0 $pg 2>/dev/null; do sleep 0.2; done
             kill -INT $pg 2>/dev/null; wait $pg
             rm -rf {dir}",
            postgres = quote(&bin.join("postgres")),
            data = quote(&data),
            dir = quote(&dir),
            parent = std::process::id(),
        );
        let watchdog = command(as_postgres, Path::new("/bin/sh"))
            .args(["-c", &script])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| failed(format!("starting postgres: {e}")))?;
        cluster.watchdog = Some(watchdog);
        cluster.wait_ready(&bin)?;
        Ok(cluster)
    }

    fn wait_ready(&mut self, bin: &Path) -> Result<(), TempPostgresError> {
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let ready = Command::new(bin.join("pg_isready"))
                .arg("-h")
                .arg(&self.dir)
                .args(["-p", &self.port.to_string(), "-U", "postgres", "-q"])
                .status()
                .map(|s| s.success())
                .unwrap_or(false);
            if ready {
                return Ok(());
            }
            let exited = match self.watchdog.as_mut().map(Child::try_wait) {
                Some(Ok(Some(_))) | None => true,
                Some(Ok(None)) => false,
                Some(Err(_)) => true,
            };
            if exited || Instant::now() > deadline {
                let log =
                    std::fs::read_to_string(self.dir.join("postgres.log")).unwrap_or_default();
                return Err(failed(format!("postgres did not start: {}", log.trim())));
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// The URL of database `name` in this cluster (user `postgres`, Unix socket).
    pub fn url(&self, name: &str) -> String {
        format!(
            "postgres://postgres@localhost:{}/{name}?host={}",
            self.port,
            self.dir.display()
        )
    }

    /// Creates database `name` and returns its URL.
    pub async fn create_database(&self, name: &str) -> Result<String, TempPostgresError> {
        use sqlx::Connection;
        let mut admin = sqlx::PgConnection::connect(&self.url("postgres"))
            .await
            .map_err(failed)?;
        sqlx::query(&format!("CREATE DATABASE \"{}\"", name.replace('"', "")))
            .execute(&mut admin)
            .await
            .map_err(failed)?;
        admin.close().await.map_err(failed)?;
        Ok(self.url(name))
    }

    /// Stops the cluster and deletes its directory.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        if let Some(mut watchdog) = self.watchdog.take() {
            if std::fs::write(self.dir.join("stop"), b"").is_err() {
                let _ = watchdog.kill();
            }
            let _ = watchdog.wait();
        }
    }
}

impl Drop for TempPostgres {
    fn drop(&mut self) {
        self.shutdown();
    }
}
