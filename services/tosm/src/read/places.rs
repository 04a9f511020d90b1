//! Places: buildings, floors, corridors, rooms and halls, with their boundaries and metric maps.

use oxrdf::vocab::rdf;

use super::Reader;
use crate::model::{MetricMap, Place, PlaceKind};
use crate::occupancy::{OccupancyGrid, Pose2, RosMapMeta};
use crate::vocab as v;

impl<'g> Reader<'g> {
    pub(super) fn place(&mut self, iri: &str) -> Option<Place> {
        let before = self.problems.len();
        let types = self.types(iri);
        let kinds: Vec<PlaceKind> = [
            (v::BUILDING, PlaceKind::Building),
            (v::FLOOR, PlaceKind::Floor),
            (v::CORRIDOR, PlaceKind::Corridor),
            (v::ROOM, PlaceKind::Room),
            (v::HALL, PlaceKind::Hall),
        ]
        .into_iter()
        .filter(|(class, _)| types.iter().any(|t| self.is_subclass(t, *class)))
        .map(|(_, k)| k)
        .collect();
        let kind = match kinds.as_slice() {
            [] => PlaceKind::Other,
            [k] => *k,
            _ => {
                self.problem(
                    iri,
                    rdf::TYPE,
                    format!("has disjoint place kinds {kinds:?}"),
                );
                return None;
            }
        };
        let symbol = self.symbol(iri);
        let boundary = self.boundary(iri, kind);
        let parent = self.iri(iri, v::IS_DIRECTLY_INSIDE_OF, false);
        if let Some(p) = &parent {
            self.check_reference(iri, v::IS_DIRECTLY_INSIDE_OF, p, v::PLACE, "a tosm:Place");
        }
        let connected = self.iris(iri, v::IS_CONNECTED_TO);
        // isConnectedTo is symmetric: a connection stated from the other side counts too.
        let connected = self.with_inverse(iri, v::IS_CONNECTED_TO, connected);
        for c in &connected {
            if c == iri {
                self.problem(
                    iri,
                    v::IS_CONNECTED_TO,
                    "a place cannot be connected to itself",
                );
            }
            self.check_open_reference(iri, v::IS_CONNECTED_TO, c, v::PLACE, "a tosm:Place");
        }
        let complexity = self.unit_interval(iri, v::COMPLEXITY, false);
        let level = self.integer(iri, v::FLOOR_LEVEL, false);
        let map = if kind == PlaceKind::Floor || !self.objects(iri, v::HAS_METRIC_MAP).is_empty() {
            self.metric_map(iri, kind == PlaceKind::Floor)
        } else {
            None
        };
        if self.problems.len() > before {
            return None;
        }
        Some(Place {
            iri: iri.to_owned(),
            kind,
            symbol,
            boundary,
            parent,
            connected,
            complexity,
            level,
            map,
        })
    }

    pub(super) fn boundary(&mut self, iri: &str, kind: PlaceKind) -> Vec<(f64, f64)> {
        let polygon = self.indexed_points(iri, v::HAS_BOUNDARY_POINT, "boundary point");
        let needs_polygon = matches!(
            kind,
            PlaceKind::Corridor | PlaceKind::Room | PlaceKind::Hall
        );
        if (needs_polygon && polygon.len() < 3) || (!polygon.is_empty() && polygon.len() < 3) {
            self.problem(
                iri,
                v::HAS_BOUNDARY_POINT,
                format!(
                    "a boundary polygon needs at least 3 points, found {}",
                    polygon.len()
                ),
            );
        }
        polygon
    }

    pub(super) fn metric_map(&mut self, floor: &str, required: bool) -> Option<MetricMap> {
        let map = self.iri(floor, v::HAS_METRIC_MAP, required)?;
        let resolution = self.positive(&map, v::RESOLUTION_M, true);
        let ox = self.number(&map, v::ORIGIN_X_M, true);
        let oy = self.number(&map, v::ORIGIN_Y_M, true);
        let oyaw = self.number(&map, v::ORIGIN_YAW_RAD, false).unwrap_or(0.0);
        let occupied = self.unit_interval(&map, v::OCCUPIED_THRESHOLD, true);
        let free = self.unit_interval(&map, v::FREE_THRESHOLD, true);
        let negate = self.boolean(&map, v::NEGATE, false).unwrap_or(false);
        let frame_id = match self.string(&map, v::FRAME_ID, false) {
            None => crate::model::DEFAULT_MAP_FRAME.to_owned(),
            Some(f) if crate::model::is_ros_frame_name(&f) => f,
            Some(f) => {
                self.problem(
                    &map,
                    v::FRAME_ID,
                    format!(
                        "must be a ROS frame name (letters, digits, _ and /, not starting with a digit or /), found {f:?}"
                    ),
                );
                return None;
            }
        };
        let width = self.count(&map, v::WIDTH_CELLS, true);
        let height = self.count(&map, v::HEIGHT_CELLS, true);
        let png = self.base64(&map, v::MAP_IMAGE_PNG);
        let (resolution, ox, oy, occupied, free, width, height, png) = (
            resolution?,
            ox?,
            oy?,
            occupied?,
            free?,
            width?,
            height?,
            png?,
        );
        let meta = RosMapMeta {
            image: map.clone(),
            resolution,
            origin: Pose2::new(ox, oy, oyaw),
            negate,
            occupied_thresh: occupied,
            free_thresh: free,
            mode: "trinary".to_owned(),
        };
        let grid = match OccupancyGrid::from_ros_map_server(&meta, &png) {
            Ok(grid) => grid,
            Err(e) => {
                self.problem(&map, v::MAP_IMAGE_PNG, e.to_string());
                return None;
            }
        };
        if (grid.width, grid.height) != (width as usize, height as usize) {
            self.problem(
                &map,
                v::WIDTH_CELLS,
                format!(
                    "says {width}x{height} cells but the image is {}x{} pixels",
                    grid.width, grid.height
                ),
            );
            return None;
        }
        Some(MetricMap {
            iri: map,
            resolution,
            origin: meta.origin,
            occupied_thresh: occupied,
            free_thresh: free,
            negate,
            frame_id,
            png,
            grid,
        })
    }
}
