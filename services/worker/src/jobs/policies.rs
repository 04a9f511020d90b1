//! Exported policies on disk: `<policies_dir>/<id>/policy.safetensors` and `policy.json`
//! (`learning::Policy` loads them without libtorch). A policy's summary — robot, place, floor,
//! the job that trained it, its evaluation — is `training.summary` inside `policy.json`.

use std::path::{Path, PathBuf};

use serde::Serialize;
use serde_json::Value;

/// The weights file's name.
pub const WEIGHTS: &str = "policy.safetensors";
/// The metadata file's name.
pub const METADATA: &str = "policy.json";

/// A policy in a listing.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct PolicySummary {
    /// The policy's id (the id of the job that trained it).
    pub id: String,
    /// The robot's IRI.
    pub robot: Option<String>,
    /// The place the job named.
    pub place: Option<String>,
    /// The floor's IRI.
    pub floor: Option<String>,
    /// The training job.
    pub job_id: Option<String>,
    /// When it was exported (RFC 3339, UTC).
    pub created: Option<String>,
    /// The held-out evaluation of the exported policy: success, collision and timeout rates,
    /// missions run.
    #[schema(value_type = Object)]
    pub eval: Value,
}

/// The policies directory.
#[derive(Debug, Clone)]
pub struct PolicyStore {
    dir: PathBuf,
}

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
        Self { dir: dir.into() }
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Where policy `id` lives (it may not exist).
    pub fn path(&self, id: &str) -> Option<PathBuf> {
        valid_id(id).then(|| self.dir.join(id))
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
        Ok(target)
    }

    /// `policy.json` of policy `id`.
    pub fn metadata(&self, id: &str) -> Option<Value> {
        let text = std::fs::read(self.path(id)?.join(METADATA)).ok()?;
        serde_json::from_slice(&text).ok()
    }

    /// Every policy, newest first.
    pub fn list(&self) -> Vec<PolicySummary> {
        let Ok(entries) = std::fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        let mut out: Vec<(i64, PolicySummary)> = entries
            .flatten()
            .filter_map(|e| {
                let id = e.file_name().to_str()?.to_owned();
                if !valid_id(&id) || !e.path().join(WEIGHTS).is_file() {
                    return None;
                }
                let meta = self.metadata(&id)?;
                Some(summary(&id, &meta))
            })
            .collect();
        out.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| b.1.id.cmp(&a.1.id)));
        out.into_iter().map(|(_, s)| s).collect()
    }
}

/// The listing entry of a policy, from its metadata (and its creation time, for sorting).
pub fn summary(id: &str, meta: &Value) -> (i64, PolicySummary) {
    let s = &meta["training"]["summary"];
    let text = |k: &str| s[k].as_str().map(str::to_owned);
    let created_ms = s["created_ms"].as_i64().unwrap_or(0);
    (
        created_ms,
        PolicySummary {
            id: id.to_owned(),
            robot: text("robot"),
            place: text("place"),
            floor: text("floor"),
            job_id: text("job_id"),
            created: (created_ms > 0).then(|| crate::jobs::rfc3339(created_ms)),
            eval: s["eval"].clone(),
        },
    )
}
