//! Map import: a ROS map_server map (YAML + PGM/PNG) becomes a TOSM floor with its metric map,
//! in a named graph of its own. The one owner of map ingestion:
//!
//! - [`files`]: a map read from its files ([`RosMapFiles`], [`read_ros_map`], [`find_yamls`]);
//!   `tosm` parses the bytes and does no IO.
//! - here: ROS map → TOSM floor ([`floor_for`], [`floor_triples`]), and the import into the
//!   store ([`import`]).
//! - [`world`]: the mental simulation of a map file (the floor's on-demand database, furniture
//!   and a robot, through the simulation parser), for the CLI's `train` and `eval` and for the
//!   benchmarks, so that they simulate exactly the floor the service would import.

pub mod files;
pub mod world;

use oxigraph::model::{NamedNode, Quad, Triple};
use tosm::{MetricMap, OccupancyGrid, Place, PlaceKind, RosMapError, RosMapMeta, Symbol};

use crate::graphs::MAPS_GRAPH_NS;
use crate::service::Knowledge;
use crate::store::StoreError;

pub use files::{LoadError, RosMapFiles, find_yamls, name_for_path, read_ros_map};
pub use world::{on_demand_database, world_from_map};

/// Where imported floors are named (their graphs under [`MAPS_GRAPH_NS`]).
pub const FLOOR_NS: &str = "https://mentalsim.dev/data/maps/";

/// The IRI of the floor imported as `name`.
pub fn floor_iri(name: &str) -> String {
    format!("{FLOOR_NS}{name}")
}

/// Why an import was refused or failed.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The map itself is wrong: YAML, thresholds, resolution, image.
    #[error("map {name}: {source}")]
    Map {
        /// The map's name.
        name: String,
        /// What is wrong.
        #[source]
        source: RosMapError,
    },
    /// The name cannot be used in an IRI.
    #[error("map name {0:?} must be 1-64 characters of a-z, 0-9, '-' and '_'")]
    BadName(String),
    /// The grid has no free cell: nothing could ever drive there.
    #[error("map {0}: the image has no free cell under its thresholds")]
    NoFreeSpace(String),
    /// The typed model refused the floor (a bug if it happens: the map was validated).
    #[error("map {name}: {message}")]
    Model {
        /// The map's name.
        name: String,
        /// The problems.
        message: String,
    },
    /// Writing to the store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

impl ImportError {
    /// Whether the caller's input is at fault (a 4xx) rather than the service (a 5xx).
    pub fn is_client_error(&self) -> bool {
        !matches!(self, ImportError::Store(_) | ImportError::Model { .. })
    }
}

/// What was imported.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportedFloor {
    /// The floor place's IRI.
    pub floor_iri: String,
    /// The named graph holding it.
    pub graph_iri: String,
    /// Grid width and height in cells.
    pub size: (usize, usize),
    /// Metres per cell.
    pub resolution: f64,
    /// Free area in m².
    pub free_area_m2: f64,
    /// Triples written.
    pub triples: usize,
}

/// Parses and validates a map, without touching the store. Pure.
pub fn parse(name: &str, yaml: &str, image: &[u8]) -> Result<OccupancyGrid, ImportError> {
    let map_err = |source| ImportError::Map {
        name: name.to_owned(),
        source,
    };
    let meta = RosMapMeta::parse_yaml(yaml).map_err(map_err)?;
    let grid = OccupancyGrid::from_ros_map_server(&meta, image).map_err(map_err)?;
    if grid.free_cell_count() == 0 {
        return Err(ImportError::NoFreeSpace(name.to_owned()));
    }
    Ok(grid)
}

/// The floor place for a grid: its boundary is the map's rectangle, its complexity the share
/// of the rectangle that is not free.
pub fn floor_for(name: &str, grid: OccupancyGrid) -> Place {
    let floor_iri = floor_iri(name);
    let (w, h) = (
        grid.width as f64 * grid.resolution,
        grid.height as f64 * grid.resolution,
    );
    let corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)];
    let boundary = corners
        .iter()
        .map(|&(x, y)| grid.grid_frame_to_world(x, y))
        .collect();
    let total = (grid.width * grid.height).max(1) as f64;
    let complexity = 1.0 - grid.free_cell_count() as f64 / total;
    let map = MetricMap::from_grid(&MetricMap::iri_for_floor(&floor_iri), grid);
    Place {
        iri: floor_iri,
        kind: PlaceKind::Floor,
        // The name is the floor's identifier too, so requests can say `"place": "NAME"`.
        symbol: Symbol {
            identifier: Some(name.to_owned()),
            ..Symbol::named(name)
        },
        boundary,
        parent: None,
        connected: Vec::new(),
        complexity: Some(complexity),
        level: Some(0),
        map: Some(map),
    }
}

/// ROS map → TOSM: the triples of the floor `name` of `grid` ([`floor_for`]), as an import
/// writes them into the floor's graph.
pub fn floor_triples(name: &str, grid: OccupancyGrid) -> Result<Vec<Triple>, ImportError> {
    let floor = floor_for(name, grid);
    tosm::place_to_triples(&floor).map_err(|p| ImportError::Model {
        name: name.to_owned(),
        message: p.to_string(),
    })
}

/// Imports a map as floor `name`, replacing a previous import of the same name. Blocking.
pub fn import(
    knowledge: &Knowledge,
    name: &str,
    yaml: &str,
    image: &[u8],
) -> Result<ImportedFloor, ImportError> {
    valid_name(name)?;
    let grid = parse(name, yaml, image)?;
    let size = (grid.width, grid.height);
    let resolution = grid.resolution;
    let free_area_m2 = grid.free_area_m2();
    let triples = floor_triples(name, grid)?;
    let graph_iri = format!("{MAPS_GRAPH_NS}{name}");
    let graph = NamedNode::new_unchecked(graph_iri.clone());
    let store = knowledge.try_store()?;
    let quads: Vec<Quad> = triples
        .iter()
        .map(|t| t.clone().in_graph(graph.clone()))
        .collect();
    store.replace_graph(&graph.clone().into(), &quads)?;
    knowledge.after_write()?;
    Ok(ImportedFloor {
        floor_iri: floor_iri(name),
        graph_iri,
        size,
        resolution,
        free_area_m2,
        triples: quads.len(),
    })
}

fn valid_name(name: &str) -> Result<(), ImportError> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '_');
    if ok {
        Ok(())
    } else {
        Err(ImportError::BadName(name.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{KnowledgeStore, QueryLimits};
    use edge::Tokens;

    fn knowledge() -> Knowledge {
        Knowledge::new(
            KnowledgeStore::in_memory().unwrap(),
            Tokens::open(),
            QueryLimits::default(),
        )
    }

    const YAML: &str = "image: m.pgm\nresolution: 0.5\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";

    fn pgm(w: usize, h: usize) -> Vec<u8> {
        let mut out = format!("P5\n{w} {h}\n255\n").into_bytes();
        for i in 0..w * h {
            out.push(if i % 7 == 0 { 0 } else { 254 });
        }
        out
    }

    #[test]
    fn a_map_imports_as_a_floor_that_reads_back() {
        let k = knowledge();
        let imported = import(&k, "lab", YAML, &pgm(20, 10)).unwrap();
        assert_eq!(imported.size, (20, 10));
        let store = k.try_store().unwrap();
        let graph: oxigraph::model::Graph = store
            .embedded()
            .unwrap()
            .quads_for_pattern(
                None,
                None,
                None,
                Some(oxigraph::model::NamedNodeRef::new_unchecked(&imported.graph_iri).into()),
            )
            .map(|q| Triple::from(q.unwrap()))
            .collect();
        let places = tosm::read_places(&graph).unwrap();
        assert_eq!(places.len(), 1);
        let map = places[0].map.as_ref().unwrap();
        assert_eq!((map.grid.width, map.grid.height), (20, 10));
        assert!((map.grid.free_area_m2() - imported.free_area_m2).abs() < 1e-9);
        // Importing again under the same name replaces, not duplicates.
        let again = import(&k, "lab", YAML, &pgm(20, 10)).unwrap();
        assert_eq!(again.triples, imported.triples);
    }

    #[test]
    fn bad_maps_are_client_errors_naming_the_problem() {
        let k = knowledge();
        let cases: Vec<(&str, String, Vec<u8>, &str)> = vec![
            ("lab", "image: [".to_owned(), pgm(4, 4), "yaml"),
            ("lab", YAML.replace("0.5", "-0.5"), pgm(4, 4), "resolution"),
            (
                "lab",
                YAML.to_owned(),
                b"P5\n10 10\n255\nxx".to_vec(),
                "image",
            ),
            ("lab", YAML.to_owned(), Vec::new(), "image"),
            ("Bad Name", YAML.to_owned(), pgm(4, 4), "name"),
        ];
        for (name, yaml, image, needle) in cases {
            let err = import(&k, name, &yaml, &image).unwrap_err();
            assert!(err.is_client_error(), "{err}");
            assert!(
                err.to_string().to_lowercase().contains(needle),
                "{needle}: {err}"
            );
        }
    }
}
