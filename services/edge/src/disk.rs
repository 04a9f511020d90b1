//! A full disk is a condition of the machine, not a bug: writes are refused before they start
//! when the data directory's filesystem is nearly full ([`DiskWatch`]), and an error that a
//! full disk caused anyway (RocksDB, SQLite, a checkpoint file) is recognised by its text
//! ([`is_out_of_space`]) and answered 507 `storage_full` rather than 500.

use std::path::{Path, PathBuf};

use crate::{ApiError, ErrorCode};

/// What the operating system, RocksDB and SQLite say when a write finds no space: `ENOSPC`
/// ("No space left on device", os error 28), `EDQUOT` (os error 122) and SQLite's
/// `SQLITE_FULL`.
const OUT_OF_SPACE: [&str; 5] = [
    "no space left on device",
    "(os error 28)",
    "disk quota exceeded",
    "(os error 122)",
    "database or disk is full",
];

/// Whether an error's text says that a write found its disk full.
pub fn is_out_of_space(message: &str) -> bool {
    let lower = message.to_ascii_lowercase();
    OUT_OF_SPACE.iter().any(|needle| lower.contains(needle))
}

/// Whether `e` is a full disk (by kind, or by the text of a wrapped cause).
pub fn io_out_of_space(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded
    ) || is_out_of_space(&e.to_string())
}

/// The 507 for a write that found the disk full; `cause` goes to the log.
pub fn storage_full(cause: &str) -> ApiError {
    tracing::warn!(error = %cause, "a write found the disk full");
    ApiError::new(
        ErrorCode::StorageFull,
        "the service's storage is full: this write failed; retry once space is freed",
    )
}

/// Bytes available to this process on the filesystem holding `path`.
pub fn available_bytes(path: &Path) -> std::io::Result<u64> {
    let stat = rustix::fs::statvfs(path)?;
    Ok(stat.f_bavail.saturating_mul(stat.f_frsize))
}

/// Keeps a reserve of free space on the data directory's filesystem: a write that would eat
/// into it is refused before it starts, so the job database and the graph store always have
/// room to record state changes (a job given back to the queue, an inference rebuild).
#[derive(Debug, Clone)]
pub struct DiskWatch {
    dir: PathBuf,
    min_free_bytes: u64,
}

impl DiskWatch {
    /// Watches the filesystem of `dir`, keeping `min_free_bytes` free.
    pub fn new(dir: impl Into<PathBuf>, min_free_bytes: u64) -> Self {
        Self {
            dir: dir.into(),
            min_free_bytes,
        }
    }

    /// The reserve, bytes.
    pub fn min_free_bytes(&self) -> u64 {
        self.min_free_bytes
    }

    /// Whether writing `bytes` more would leave the reserve free. A directory that cannot be
    /// measured counts as having room: the write itself will then say what is wrong.
    pub fn has_room(&self, bytes: u64) -> bool {
        match available_bytes(&self.dir) {
            Ok(available) => available >= self.min_free_bytes.saturating_add(bytes),
            Err(_) => true,
        }
    }

    /// `Ok` when writing `bytes` leaves the reserve free, else 507 `storage_full` naming the
    /// free space and the reserve.
    pub fn check(&self, bytes: u64) -> Result<(), ApiError> {
        let Ok(available) = available_bytes(&self.dir) else {
            return Ok(());
        };
        if available >= self.min_free_bytes.saturating_add(bytes) {
            return Ok(());
        }
        tracing::warn!(
            dir = %self.dir.display(), available, reserve = self.min_free_bytes, bytes,
            "refusing a write: the data directory's disk is nearly full"
        );
        Err(ApiError::new(
            ErrorCode::StorageFull,
            format!(
                "the service's storage is nearly full ({} free, {} kept in reserve{}): nothing \
                 was stored; retry once space is freed",
                mib(available),
                mib(self.min_free_bytes),
                if bytes > 0 {
                    format!(", {} needed", mib(bytes))
                } else {
                    String::new()
                }
            ),
        ))
    }
}

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recognises_full_disks_by_their_messages_only() {
        for full in [
            "IO error: No space left on device: While appending to file: 000008.log",
            "writing state.json: No space left on device (os error 28)",
            "error returned from database: (code: 13) database or disk is full",
            "Disk quota exceeded (os error 122)",
        ] {
            assert!(is_out_of_space(full), "{full}");
        }
        for other in [
            "permission denied (os error 13)",
            "no such file or directory",
            "the space is not a valid IRI",
            "(os error 280)",
        ] {
            assert!(!is_out_of_space(other), "{other}");
        }
        let e = std::io::Error::from(std::io::ErrorKind::StorageFull);
        assert!(io_out_of_space(&e));
        assert!(!io_out_of_space(&std::io::Error::from(
            std::io::ErrorKind::NotFound
        )));
    }

    #[test]
    fn a_full_disk_is_a_507_not_a_500() {
        let e = ApiError::internal("IO error: No space left on device");
        assert_eq!(e.code(), ErrorCode::StorageFull);
        assert_eq!(e.code().status().as_u16(), 507);
        assert_eq!(
            ApiError::internal("something else").code(),
            ErrorCode::Internal
        );
    }

    #[test]
    fn the_reserve_is_measured_on_the_real_filesystem() {
        let dir = std::env::temp_dir();
        let available = available_bytes(&dir).unwrap();
        assert!(available > 0);
        assert!(DiskWatch::new(&dir, 0).check(0).is_ok());
        let e = DiskWatch::new(&dir, available.saturating_mul(2).max(1 << 40))
            .check(0)
            .unwrap_err();
        assert_eq!(e.code(), ErrorCode::StorageFull);
        assert!(e.message().contains("reserve"), "{}", e.message());
        assert!(!DiskWatch::new(&dir, u64::MAX).has_room(1));
    }
}
