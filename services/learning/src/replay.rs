//! The experience buffer of Algorithm 1 (line 6): a ring of transitions in flat `f32` arrays,
//! sampled uniformly, and saved with a checkpoint so a resumed run keeps its experience. Each
//! transition also keeps the demonstrator's action in its state (the classical follower's, for
//! the behaviour-cloning term of TD3+BC).

use std::path::Path;

use rand::Rng;

use crate::observation::ACTION_DIM;
use crate::policy::{PolicyError, le_bytes, write_atomic};

/// Transitions `(s, a, r, s', d)` and the demonstrator's action `a*` in `s`.
#[derive(Clone, Debug)]
pub struct ReplayBuffer {
    obs_dim: usize,
    capacity: usize,
    len: usize,
    next: usize,
    obs: Vec<f32>,
    actions: Vec<f32>,
    experts: Vec<f32>,
    rewards: Vec<f32>,
    next_obs: Vec<f32>,
    dones: Vec<f32>,
}

/// A sampled batch, row-major, ready to become tensors.
#[derive(Clone, Debug, Default)]
pub struct Batch {
    /// Rows.
    pub size: usize,
    /// `size × obs_dim`.
    pub obs: Vec<f32>,
    /// `size × 2`.
    pub actions: Vec<f32>,
    /// `size × 2`: what the demonstrator would have done in `obs`.
    pub experts: Vec<f32>,
    /// `size`.
    pub rewards: Vec<f32>,
    /// `size × obs_dim`.
    pub next_obs: Vec<f32>,
    /// `size`: 1 where the episode ended in a terminal state (goal or collision).
    pub dones: Vec<f32>,
}

impl ReplayBuffer {
    /// An empty buffer for observations of `obs_dim` values. Memory grows as it fills.
    pub fn new(obs_dim: usize, capacity: usize) -> Self {
        Self {
            obs_dim,
            capacity: capacity.max(1),
            len: 0,
            next: 0,
            obs: Vec::new(),
            actions: Vec::new(),
            experts: Vec::new(),
            rewards: Vec::new(),
            next_obs: Vec::new(),
            dones: Vec::new(),
        }
    }

    /// An empty buffer with room for all `capacity` transitions reserved now, so that filling
    /// it never reallocates; `Err` naming the size when the allocator refuses (a job's
    /// allocation failure is an error of that job, never an abort of the process).
    pub fn try_with_capacity(obs_dim: usize, capacity: usize) -> Result<Self, String> {
        let mut buffer = Self::new(obs_dim, capacity);
        let n = buffer.capacity;
        let too_big = |e: std::collections::TryReserveError| {
            let bytes = (n as f64) * ((2 * obs_dim + 6) as f64) * 4.0;
            format!(
                "cannot allocate a replay buffer of {n} transitions ({:.1} GiB): {e}",
                bytes / f64::from(1u32 << 30)
            )
        };
        for (values, per_row) in [
            (&mut buffer.obs, obs_dim),
            (&mut buffer.next_obs, obs_dim),
            (&mut buffer.actions, 2),
            (&mut buffer.experts, 2),
            (&mut buffer.rewards, 1),
            (&mut buffer.dones, 1),
        ] {
            let len = n.checked_mul(per_row).ok_or_else(|| {
                format!("a replay buffer of {n} transitions of {obs_dim} values overflows")
            })?;
            values.try_reserve_exact(len).map_err(too_big)?;
        }
        Ok(buffer)
    }

    /// Stored transitions.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing is stored.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Adds a transition, overwriting the oldest when full.
    pub fn push(
        &mut self,
        obs: &[f32],
        action: [f32; ACTION_DIM],
        expert: [f32; ACTION_DIM],
        reward: f32,
        next_obs: &[f32],
        done: bool,
    ) {
        debug_assert_eq!(obs.len(), self.obs_dim);
        debug_assert_eq!(next_obs.len(), self.obs_dim);
        let d = if done { 1.0 } else { 0.0 };
        if self.len < self.capacity {
            self.obs.extend_from_slice(obs);
            self.actions.extend_from_slice(&action);
            self.experts.extend_from_slice(&expert);
            self.rewards.push(reward);
            self.next_obs.extend_from_slice(next_obs);
            self.dones.push(d);
            self.len += 1;
        } else {
            let i = self.next;
            let od = self.obs_dim;
            self.obs[i * od..(i + 1) * od].copy_from_slice(obs);
            self.actions[i * ACTION_DIM..(i + 1) * ACTION_DIM].copy_from_slice(&action);
            self.experts[i * ACTION_DIM..(i + 1) * ACTION_DIM].copy_from_slice(&expert);
            self.rewards[i] = reward;
            self.next_obs[i * od..(i + 1) * od].copy_from_slice(next_obs);
            self.dones[i] = d;
        }
        self.next = (self.next + 1) % self.capacity;
    }

    /// Fills `batch` with `size` transitions drawn uniformly with replacement. Nothing is drawn
    /// from an empty buffer.
    pub fn sample_into<R: Rng>(&self, rng: &mut R, size: usize, batch: &mut Batch) {
        let od = self.obs_dim;
        batch.size = 0;
        batch.obs.clear();
        batch.actions.clear();
        batch.experts.clear();
        batch.rewards.clear();
        batch.next_obs.clear();
        batch.dones.clear();
        if self.len == 0 {
            return;
        }
        batch.size = size;
        for _ in 0..size {
            let i = rng.random_range(0..self.len);
            batch.obs.extend_from_slice(&self.obs[i * od..(i + 1) * od]);
            batch
                .actions
                .extend_from_slice(&self.actions[i * ACTION_DIM..(i + 1) * ACTION_DIM]);
            batch
                .experts
                .extend_from_slice(&self.experts[i * ACTION_DIM..(i + 1) * ACTION_DIM]);
            batch.rewards.push(self.rewards[i]);
            batch
                .next_obs
                .extend_from_slice(&self.next_obs[i * od..(i + 1) * od]);
            batch.dones.push(self.dones[i]);
        }
    }

    /// Writes the buffer to `path` (safetensors, with the ring position in its metadata).
    pub fn save(&self, path: &Path) -> Result<(), PolicyError> {
        let od = self.obs_dim;
        let arrays: [(&str, Vec<usize>, Vec<u8>); 6] = [
            ("obs", vec![self.len, od], le_bytes(&self.obs)),
            (
                "actions",
                vec![self.len, ACTION_DIM],
                le_bytes(&self.actions),
            ),
            (
                "experts",
                vec![self.len, ACTION_DIM],
                le_bytes(&self.experts),
            ),
            ("rewards", vec![self.len], le_bytes(&self.rewards)),
            ("next_obs", vec![self.len, od], le_bytes(&self.next_obs)),
            ("dones", vec![self.len], le_bytes(&self.dones)),
        ];
        let views = arrays
            .iter()
            .map(|(name, shape, data)| {
                safetensors::tensor::TensorView::new(safetensors::Dtype::F32, shape.clone(), data)
                    .map(|v| ((*name).to_owned(), v))
                    .map_err(|e| PolicyError::Weights(format!("replay buffer: {e:?}")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let meta = [
            ("obs_dim".to_owned(), od.to_string()),
            ("capacity".to_owned(), self.capacity.to_string()),
            ("next".to_owned(), self.next.to_string()),
        ]
        .into_iter()
        .collect();
        let blob = safetensors::serialize(views, &Some(meta))
            .map_err(|e| PolicyError::Weights(format!("replay buffer: {e:?}")))?;
        write_atomic(path, &blob).map_err(|source| PolicyError::Io {
            path: path.display().to_string(),
            source,
        })
    }

    /// Reads a buffer written by [`ReplayBuffer::save`].
    pub fn load(path: &Path) -> Result<ReplayBuffer, PolicyError> {
        let bytes = std::fs::read(path).map_err(|source| PolicyError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let bad =
            |m: String| PolicyError::Weights(format!("replay buffer {}: {m}", path.display()));
        let (_, header) =
            safetensors::SafeTensors::read_metadata(&bytes).map_err(|e| bad(format!("{e:?}")))?;
        let meta = header.metadata().clone().unwrap_or_default();
        let num = |k: &str| -> Result<usize, PolicyError> {
            meta.get(k)
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| bad(format!("metadata `{k}` missing")))
        };
        let (obs_dim, capacity, next) = (num("obs_dim")?, num("capacity")?, num("next")?);
        let st =
            safetensors::SafeTensors::deserialize(&bytes).map_err(|e| bad(format!("{e:?}")))?;
        let read = |name: &str| -> Result<Vec<f32>, PolicyError> {
            let t = st
                .tensor(name)
                .map_err(|_| bad(format!("`{name}` missing")))?;
            Ok(t.data()
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect())
        };
        let rewards = read("rewards")?;
        let len = rewards.len();
        let buf = ReplayBuffer {
            obs_dim,
            capacity,
            len,
            next,
            obs: read("obs")?,
            actions: read("actions")?,
            experts: read("experts")?,
            rewards,
            next_obs: read("next_obs")?,
            dones: read("dones")?,
        };
        let consistent = buf.obs.len() == len * obs_dim
            && buf.next_obs.len() == len * obs_dim
            && buf.actions.len() == len * ACTION_DIM
            && buf.experts.len() == len * ACTION_DIM
            && buf.dones.len() == len
            && len <= capacity
            && next < capacity.max(1);
        if !consistent {
            return Err(bad("arrays of inconsistent lengths".into()));
        }
        Ok(buf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn a_buffer_the_allocator_refuses_is_an_error_not_an_abort() {
        // 2^40 transitions of 30 values: 2^47 bytes and more, beyond any machine's memory.
        let e = ReplayBuffer::try_with_capacity(30, 1 << 40).unwrap_err();
        assert!(e.contains("cannot allocate"), "{e}");
        assert!(ReplayBuffer::try_with_capacity(30, usize::MAX).is_err());
        let b = ReplayBuffer::try_with_capacity(3, 100).unwrap();
        assert!(b.is_empty());
    }

    #[test]
    fn the_ring_overwrites_the_oldest_and_survives_a_round_trip() {
        let mut b = ReplayBuffer::new(2, 3);
        for i in 0..5 {
            let v = i as f32;
            b.push(
                &[v, v],
                [v, -v],
                [-v, v],
                v,
                &[v + 1.0, v + 1.0],
                i % 2 == 0,
            );
        }
        assert_eq!(b.len(), 3);
        // 0 and 1 were overwritten by 3 and 4.
        let mut rewards = b.rewards.clone();
        rewards.sort_by(f32::total_cmp);
        assert_eq!(rewards, vec![2.0, 3.0, 4.0]);
        let dir = tempfile::tempdir().expect("tmp");
        let path = dir.path().join("replay.safetensors");
        b.save(&path).expect("saved");
        let c = ReplayBuffer::load(&path).expect("loaded");
        assert_eq!((c.len, c.next, c.capacity), (b.len, b.next, b.capacity));
        assert_eq!(c.obs, b.obs);
        assert_eq!(c.dones, b.dones);
        assert_eq!(c.experts, b.experts);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut batch = Batch::default();
        c.sample_into(&mut rng, 16, &mut batch);
        assert_eq!(
            (batch.obs.len(), batch.actions.len(), batch.dones.len()),
            (32, 32, 16)
        );
        assert!(batch.rewards.iter().all(|r| [2.0, 3.0, 4.0].contains(r)));
        // Each row's demonstrator action stays with its transition.
        for (a, e) in batch.actions.chunks(2).zip(batch.experts.chunks(2)) {
            assert_eq!((a[0], a[1]), (-e[0], -e[1]));
        }
        std::fs::write(&path, b"not a buffer").expect("write");
        assert!(ReplayBuffer::load(&path).is_err());
    }
}
