//! Where a mission goes: the place of each waypoint and the fewest-hops route between them
//! through place connectivity.

use std::collections::{BTreeMap, BTreeSet, HashMap, VecDeque};

use tosm::{Place, PlaceKind};

use super::reader::Reader;
use super::{OnDemandError, Waypoint};

/// The place a waypoint is in: the smallest place whose boundary contains the point.
pub(super) fn locate(
    reader: &Reader,
    places: &[Place],
    index: &HashMap<&str, &Place>,
    which: &str,
    waypoint: &Waypoint,
) -> Result<String, OnDemandError> {
    match waypoint {
        Waypoint::Place(name) => {
            let iri = reader.resolve(name)?;
            match iri {
                Some(iri) if index.contains_key(iri.as_str()) => Ok(iri.into_string()),
                _ => Err(OnDemandError::UnknownPlace {
                    which: which.to_owned(),
                    name: name.clone(),
                }),
            }
        }
        Waypoint::Point { x, y, floor } => {
            let (x, y) = (*x, *y);
            if !x.is_finite() || !y.is_finite() {
                return Err(OnDemandError::NotFinite {
                    which: which.to_owned(),
                });
            }
            let floors: Vec<&Place> = match floor {
                Some(name) => {
                    let iri = reader.resolve(name)?;
                    match iri.and_then(|i| index.get(i.as_str()).copied()) {
                        Some(p) if p.kind == PlaceKind::Floor => vec![p],
                        _ => {
                            return Err(OnDemandError::UnknownPlace {
                                which: which.to_owned(),
                                name: name.clone(),
                            });
                        }
                    }
                }
                None => places
                    .iter()
                    .filter(|p| p.kind == PlaceKind::Floor && contains(&p.boundary, x, y))
                    .collect(),
            };
            if floors.len() > 1 {
                return Err(OnDemandError::AmbiguousFloor {
                    which: which.to_owned(),
                    x,
                    y,
                    floors: floors
                        .iter()
                        .map(|f| f.iri.as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                });
            }
            let outside = || OnDemandError::OutsideEveryPlace {
                which: which.to_owned(),
                x,
                y,
                floor_note: match floor {
                    Some(f) => format!(" on floor {f}"),
                    None => String::new(),
                },
            };
            let floor = floors.first().ok_or_else(outside)?;
            if !contains(&floor.boundary, x, y) {
                return Err(outside());
            }
            // The smallest place below this floor whose boundary holds the point; the floor
            // itself only when it has no sub-places at all (a freshly imported map).
            let below: Vec<&Place> = places
                .iter()
                .filter(|p| p.iri != floor.iri && on_floor(index, p, &floor.iri))
                .collect();
            if below.is_empty() {
                return Ok(floor.iri.clone());
            }
            below
                .into_iter()
                .filter(|p| contains(&p.boundary, x, y))
                .min_by(|a, b| polygon_area(&a.boundary).total_cmp(&polygon_area(&b.boundary)))
                .map(|p| p.iri.clone())
                .ok_or_else(outside)
        }
    }
}

pub(super) fn on_floor(index: &HashMap<&str, &Place>, place: &Place, floor: &str) -> bool {
    let mut cursor = place.parent.as_deref();
    let mut hops = 0;
    while let Some(parent) = cursor {
        if parent == floor {
            return true;
        }
        hops += 1;
        if hops > 64 {
            return false;
        }
        cursor = index.get(parent).and_then(|p| p.parent.as_deref());
    }
    false
}

/// Fewest-hops route through `tosm:isConnectedTo`, read in both directions (it is symmetric).
pub(super) fn shortest_route(
    index: &HashMap<&str, &Place>,
    from: &str,
    to: &str,
) -> Result<Vec<String>, OnDemandError> {
    if from == to {
        return Ok(vec![from.to_owned()]);
    }
    let mut neighbours: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for place in index.values() {
        for other in &place.connected {
            neighbours
                .entry(place.iri.as_str())
                .or_default()
                .insert(other.as_str());
            neighbours
                .entry(other.as_str())
                .or_default()
                .insert(place.iri.as_str());
        }
    }
    let mut previous: HashMap<&str, &str> = HashMap::new();
    let mut queue = VecDeque::from([from]);
    while let Some(current) = queue.pop_front() {
        if current == to {
            let mut path = vec![to.to_owned()];
            let mut cursor = to;
            while let Some(&p) = previous.get(cursor) {
                path.push(p.to_owned());
                cursor = p;
            }
            path.reverse();
            return Ok(path);
        }
        for &next in neighbours.get(current).into_iter().flatten() {
            if next != from && !previous.contains_key(next) {
                previous.insert(next, current);
                queue.push_back(next);
            }
        }
    }
    Err(OnDemandError::NotConnected {
        from: from.to_owned(),
        to: to.to_owned(),
    })
}

/// Even-odd point-in-polygon; an empty polygon contains nothing.
pub(super) fn contains(polygon: &[(f64, f64)], x: f64, y: f64) -> bool {
    let mut inside = false;
    let n = polygon.len();
    for i in 0..n {
        let (xi, yi) = polygon[i];
        let (xj, yj) = polygon[(i + n - 1) % n];
        if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
            inside = !inside;
        }
    }
    inside
}

pub(super) fn polygon_area(polygon: &[(f64, f64)]) -> f64 {
    let n = polygon.len();
    (0..n)
        .map(|i| {
            let (x1, y1) = polygon[i];
            let (x2, y2) = polygon[(i + 1) % n];
            x1 * y2 - x2 * y1
        })
        .sum::<f64>()
        .abs()
        / 2.0
}
