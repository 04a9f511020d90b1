//! Exported policies on disk: `<policies_dir>/<id>/policy.safetensors` and `policy.json`
//! (`learning::Policy` loads them without libtorch). A policy's [`PolicySummary`] — robot,
//! place, floor, the job that trained it, its held-out evaluation — is `training.summary`
//! inside `policy.json`: written by a training, read back by the listing and by plans.
//!
//! The store keeps an index of the summaries, read again only when the directory changes (an
//! install renames a directory into it, which changes its modification time), so a plan learns
//! the robot's newest policy without reading every `policy.json`.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::SystemTime;

use serde::{Deserialize, Serialize};

/// The weights file's name.
pub const WEIGHTS: &str = "policy.safetensors";
/// The metadata file's name.
pub const METADATA: &str = "policy.json";

/// What a training says about the policy it exported (`training.summary` in `policy.json`).
/// Every field is optional on reading: policies exported by older versions or by hand load.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PolicySummary {
    /// The policy's id (the id of the job that trained it).
    #[serde(default)]
    pub policy_id: Option<String>,
    /// The robot's IRI.
    #[serde(default)]
    pub robot: Option<String>,
    /// The place the job named.
    #[serde(default)]
    pub place: Option<String>,
    /// The floor's IRI.
    #[serde(default)]
    pub floor: Option<String>,
    /// The training job.
    #[serde(default)]
    pub job_id: Option<String>,
    /// When it was exported, Unix milliseconds (0: unknown).
    #[serde(default)]
    pub created_ms: i64,
    /// The held-out evaluation of the exported policy.
    #[serde(default)]
    pub eval: Option<HeldOutEval>,
}

/// The exported policy on held-out missions, with the pure-Rust runtime robots embed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldOutEval {
    /// Missions reached.
    pub success_rate: f64,
    /// Missions that ended in a collision.
    pub collision_rate: f64,
    /// Missions that ran out of time.
    pub timeout_rate: f64,
    /// Mean simulated time of the reached missions, seconds.
    pub mean_time_to_goal_s: Option<f64>,
    /// Missions run.
    pub episodes: usize,
    /// Seed of the missions (one training never used).
    pub seed: u64,
    /// Which goals: `in-view` or `edges`.
    pub goals: String,
}

impl PolicySummary {
    /// Whether the policy was trained for `robot_iri` (the summary names it by IRI or by
    /// identifier).
    pub fn is_for_robot(&self, robot_iri: &str) -> bool {
        self.robot
            .as_deref()
            .is_some_and(|r| r == robot_iri || robot_iri.ends_with(&format!("/{r}")))
    }
}

/// A policy in a listing: its id and summary.
#[derive(Debug, Clone, PartialEq)]
pub struct PolicyEntry {
    /// The policy's id (its directory's name).
    pub id: String,
    /// What its training said.
    pub summary: PolicySummary,
}

/// A listing and the directory's modification time it was read at.
type Listing = (SystemTime, Arc<Vec<PolicyEntry>>);

/// The policies directory.
#[derive(Debug, Clone)]
pub struct PolicyStore {
    dir: PathBuf,
    /// The listing, and the directory's modification time it was read at.
    index: Arc<Mutex<Option<Listing>>>,
}

/// How old a directory's modification time must be before a listing read at it is reused.
const SETTLED: std::time::Duration = std::time::Duration::from_secs(2);

/// Ids are the directory names we create (UUIDs); anything else could leave the directory.
pub fn valid_id(id: &str) -> bool {
    !id.is_empty()
        && id.len() <= 128
        && id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

impl PolicyStore {
    /// Policies under `dir`.
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        Self {
            dir: dir.into(),
            index: Arc::default(),
        }
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Where policy `id` lives (it may not exist).
    pub fn path(&self, id: &str) -> Option<PathBuf> {
        valid_id(id).then(|| self.dir.join(id))
    }

    /// Whether policy `id` is installed (its weights exist).
    pub fn exists(&self, id: &str) -> bool {
        self.path(id).is_some_and(|p| p.join(WEIGHTS).is_file())
    }

    /// A fresh staging directory for policy `id`, next to where it will be installed, of one
    /// job attempt (two attempts never share one).
    pub fn staging(&self, id: &str, attempt: u32) -> PathBuf {
        self.dir.join(format!(".{id}.staging-{attempt}"))
    }

    /// Moves a staged policy into place, replacing an earlier export of the same id. The
    /// files and the directory entries are made durable first, the rename after.
    pub fn install(&self, id: &str, staged: &Path) -> std::io::Result<PathBuf> {
        let target = self
            .path(id)
            .ok_or_else(|| std::io::Error::other(format!("invalid policy id {id:?}")))?;
        for entry in std::fs::read_dir(staged)? {
            let path = entry?.path();
            if path.is_file() {
                learning::policy::sync_path(&path)?;
            }
        }
        learning::policy::sync_path(staged)?;
        if target.exists() {
            std::fs::remove_dir_all(&target)?;
        }
        std::fs::rename(staged, &target)?;
        learning::policy::sync_path(&self.dir)?;
        // This process's index is stale whatever the directory's clock granularity says.
        *self.index.lock().unwrap_or_else(PoisonError::into_inner) = None;
        Ok(target)
    }

    /// `policy.json` of policy `id`, whole.
    pub fn metadata(&self, id: &str) -> Option<serde_json::Value> {
        let text = std::fs::read(self.path(id)?.join(METADATA)).ok()?;
        serde_json::from_slice(&text).ok()
    }

    /// The summary in `policy.json` of policy `id` (an empty one when it has none).
    pub fn summary(&self, id: &str) -> Option<PolicySummary> {
        let meta = self.metadata(id)?;
        Some(summary_of(&meta))
    }

    /// Every installed policy, newest first. Reads the summaries again only when the
    /// directory changed since the last listing.
    pub fn list(&self) -> Arc<Vec<PolicyEntry>> {
        let modified = std::fs::metadata(&self.dir).and_then(|m| m.modified()).ok();
        let mut index = self.index.lock().unwrap_or_else(PoisonError::into_inner);
        if let (Some(at), Some((seen, list))) = (modified, index.as_ref())
            && *seen == at
        {
            return Arc::clone(list);
        }
        let list = Arc::new(self.read_all());
        // A directory modified within the last seconds may change again within the same tick
        // of the file system's clock (racy-git's problem): not trusted until it is older.
        let settled = modified.filter(|at| {
            SystemTime::now()
                .duration_since(*at)
                .is_ok_and(|age| age >= SETTLED)
        });
        *index = settled.map(|at| (at, Arc::clone(&list)));
        list
    }

    /// The newest policy trained for the robot `robot_iri`.
    pub fn newest_for(&self, robot_iri: &str) -> Option<String> {
        self.list()
            .iter()
            .find(|p| p.summary.is_for_robot(robot_iri))
            .map(|p| p.id.clone())
    }

    fn read_all(&self) -> Vec<PolicyEntry> {
        let Ok(entries) = std::fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        let mut out: Vec<PolicyEntry> = entries
            .flatten()
            .filter_map(|e| {
                let id = e.file_name().to_str()?.to_owned();
                if !valid_id(&id) || !e.path().join(WEIGHTS).is_file() {
                    return None;
                }
                let summary = self.summary(&id)?;
                Some(PolicyEntry { id, summary })
            })
            .collect();
        out.sort_by(|a, b| {
            b.summary
                .created_ms
                .cmp(&a.summary.created_ms)
                .then_with(|| b.id.cmp(&a.id))
        });
        out
    }
}

/// The summary inside a `policy.json` (`training.summary`); an empty one when it has none or
/// it does not read.
pub fn summary_of(meta: &serde_json::Value) -> PolicySummary {
    serde_json::from_value(meta["training"]["summary"].clone()).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn install(store: &PolicyStore, id: &str, robot: &str, created_ms: i64) {
        let staged = store.staging(id, 1);
        std::fs::create_dir_all(&staged).unwrap();
        std::fs::write(staged.join(WEIGHTS), b"w").unwrap();
        let summary = PolicySummary {
            policy_id: Some(id.to_owned()),
            robot: Some(robot.to_owned()),
            created_ms,
            ..PolicySummary::default()
        };
        let meta = serde_json::json!({"training": {"summary": summary}});
        std::fs::write(staged.join(METADATA), meta.to_string()).unwrap();
        store.install(id, &staged).unwrap();
    }

    #[test]
    fn the_newest_policy_of_a_robot_follows_installs() {
        let dir = tempfile::tempdir().unwrap();
        let store = PolicyStore::new(dir.path());
        assert_eq!(store.newest_for("http://x/robot/r1"), None);
        install(&store, "a", "r1", 10);
        install(&store, "b", "http://x/robot/r2", 20);
        assert_eq!(store.newest_for("http://x/robot/r1").as_deref(), Some("a"));
        assert_eq!(store.newest_for("http://x/robot/r2").as_deref(), Some("b"));
        // Another handle on the same directory (another process) sees the new install too.
        let other = PolicyStore::new(dir.path());
        install(&other, "c", "r1", 30);
        assert_eq!(store.newest_for("http://x/robot/r1").as_deref(), Some("c"));
        let ids: Vec<_> = store.list().iter().map(|p| p.id.clone()).collect();
        assert_eq!(ids, ["c", "b", "a"]);
    }

    #[test]
    fn a_summary_without_fields_reads_as_empty() {
        let s = summary_of(&serde_json::json!({"training": {"summary": {"robot": "r"}}}));
        assert_eq!(s.robot.as_deref(), Some("r"));
        assert_eq!(s.created_ms, 0);
        assert_eq!(summary_of(&serde_json::json!({})), PolicySummary::default());
    }
}
