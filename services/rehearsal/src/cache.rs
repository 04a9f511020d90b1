//! Roadmaps built once per (map version, robot inflation, PRM parameters) and shared.
//!
//! The configuration space (planning grid, distance field, free regions) is kept per (map
//! version, inflation) and shared by every roadmap built on it, so re-sampling a roadmap with a
//! new seed costs only the sampling. Entries are evicted least recently used first. Building
//! happens outside the lock: two requests that miss the same key at once both build, and the
//! second result is dropped, which costs time but never blocks a request on another's build.

use std::collections::{HashMap, VecDeque};
use std::hash::Hash;
use std::sync::{Arc, Mutex, MutexGuard};

use prm::{ConfigSpace, Inflation, PrmParams, Roadmap, RoadmapKey};
use sim::World;

use crate::error::{PlanError, invalid};
use crate::planning_grid::planning_grid;

/// The configuration space of one map version for one robot inflation, with the free area of
/// the uninflated map (the paper's n* is computed from it).
#[derive(Debug)]
pub struct SpaceEntry {
    /// The configuration space.
    pub cspace: Arc<ConfigSpace>,
    /// Free area of the planning grid before inflation, m².
    pub free_area_m2: f64,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct SpaceKey {
    map_version: String,
    radius_bits: u64,
    margin_bits: u64,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct MapKey {
    map_version: String,
    key: RoadmapKey,
}

/// A small least-recently-used map.
#[derive(Debug)]
struct Lru<K, V> {
    capacity: usize,
    map: HashMap<K, V>,
    order: VecDeque<K>,
}

impl<K: Clone + Eq + Hash, V: Clone> Lru<K, V> {
    fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(1),
            map: HashMap::new(),
            order: VecDeque::new(),
        }
    }

    fn get(&mut self, k: &K) -> Option<V> {
        let v = self.map.get(k)?.clone();
        if let Some(i) = self.order.iter().position(|o| o == k) {
            self.order.remove(i);
        }
        self.order.push_back(k.clone());
        Some(v)
    }

    fn insert(&mut self, k: K, v: V) {
        if self.map.insert(k.clone(), v).is_some()
            && let Some(i) = self.order.iter().position(|o| *o == k)
        {
            self.order.remove(i);
        }
        self.order.push_back(k);
        while self.map.len() > self.capacity {
            let Some(old) = self.order.pop_front() else {
                break;
            };
            self.map.remove(&old);
        }
    }

    fn retain(&mut self, keep: impl Fn(&K) -> bool) {
        self.map.retain(|k, _| keep(k));
        self.order.retain(|k| keep(k));
    }
}

#[derive(Debug)]
struct Inner {
    spaces: Lru<SpaceKey, Arc<SpaceEntry>>,
    roadmaps: Lru<MapKey, Arc<Roadmap>>,
    hits: u64,
    misses: u64,
}

/// Counters of a [`RoadmapCache`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CacheStats {
    /// Roadmaps held.
    pub roadmaps: usize,
    /// Configuration spaces held.
    pub spaces: usize,
    /// Roadmap lookups answered from the cache.
    pub hits: u64,
    /// Roadmap lookups that built one.
    pub misses: u64,
}

/// Roadmaps and configuration spaces keyed by a caller-given map version string (for example
/// the on-demand database's map IRI and its modification stamp): a new version is a new key,
/// and [`RoadmapCache::invalidate`] drops an old one.
#[derive(Debug)]
pub struct RoadmapCache {
    inner: Mutex<Inner>,
}

impl Default for RoadmapCache {
    /// Room for 32 roadmaps (five re-samples each of six maps) and 8 configuration spaces.
    fn default() -> Self {
        Self::new(32, 8)
    }
}

impl RoadmapCache {
    /// A cache holding at most `roadmaps` roadmaps and `spaces` configuration spaces.
    pub fn new(roadmaps: usize, spaces: usize) -> Self {
        Self {
            inner: Mutex::new(Inner {
                spaces: Lru::new(spaces),
                roadmaps: Lru::new(roadmaps),
                hits: 0,
                misses: 0,
            }),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        // A panic while holding the lock leaves consistent maps behind (every mutation is one
        // call): keep using them.
        self.inner
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// The configuration space of `world` (whose map version is `map_version`) for `inflation`,
    /// built on a miss.
    pub fn config_space(
        &self,
        map_version: &str,
        world: &World,
        inflation: Inflation,
    ) -> Result<Arc<SpaceEntry>, PlanError> {
        let key = SpaceKey {
            map_version: map_version.to_owned(),
            radius_bits: inflation.robot_radius_m.to_bits(),
            margin_bits: inflation.safety_margin_m.to_bits(),
        };
        if let Some(e) = self.lock().spaces.get(&key) {
            return Ok(e);
        }
        let grid = planning_grid(world).map_err(PlanError::Map)?;
        let free_area_m2 = grid.free_area_m2();
        let cspace =
            ConfigSpace::new(&grid, inflation).map_err(|e| PlanError::Map(e.to_string()))?;
        let entry = Arc::new(SpaceEntry {
            cspace: Arc::new(cspace),
            free_area_m2,
        });
        self.lock().spaces.insert(key, Arc::clone(&entry));
        Ok(entry)
    }

    /// The roadmap with `params` on `space` (from [`RoadmapCache::config_space`] for the same
    /// map version), built on a miss; the flag says whether it came from the cache.
    pub fn roadmap(
        &self,
        map_version: &str,
        space: &SpaceEntry,
        params: &PrmParams,
    ) -> Result<(Arc<Roadmap>, bool), PlanError> {
        self.roadmap_until(map_version, space, params, &grid::Stop::never())
    }

    /// [`RoadmapCache::roadmap`], whose build on a miss stops once `stop` is requested.
    pub fn roadmap_until(
        &self,
        map_version: &str,
        space: &SpaceEntry,
        params: &PrmParams,
        stop: &grid::Stop,
    ) -> Result<(Arc<Roadmap>, bool), PlanError> {
        let key = MapKey {
            map_version: map_version.to_owned(),
            key: RoadmapKey::new(
                space.cspace.map_fingerprint(),
                space.cspace.inflation(),
                params,
            ),
        };
        {
            let mut inner = self.lock();
            if let Some(r) = inner.roadmaps.get(&key) {
                inner.hits += 1;
                return Ok((r, true));
            }
            inner.misses += 1;
        }
        let roadmap =
            Roadmap::build_until(Arc::clone(&space.cspace), params, stop).map_err(|e| match e {
                prm::BuildError::Stopped => PlanError::Stopped,
                prm::BuildError::NoFreeSpace { .. } => PlanError::Map(e.to_string()),
                other => invalid("options.samples", other.to_string()),
            })?;
        let roadmap = Arc::new(roadmap);
        self.lock().roadmaps.insert(key, Arc::clone(&roadmap));
        Ok((roadmap, false))
    }

    /// Drops every entry of `map_version` (the map changed).
    pub fn invalidate(&self, map_version: &str) {
        let mut inner = self.lock();
        inner.spaces.retain(|k| k.map_version != map_version);
        inner.roadmaps.retain(|k| k.map_version != map_version);
    }

    /// What the cache holds and how often it helped.
    pub fn stats(&self) -> CacheStats {
        let inner = self.lock();
        CacheStats {
            roadmaps: inner.roadmaps.map.len(),
            spaces: inner.spaces.map.len(),
            hits: inner.hits,
            misses: inner.misses,
        }
    }
}
