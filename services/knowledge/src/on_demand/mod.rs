//! On-demand databases (thesis §3.4): for one robot and one mission, the subset of the graph a
//! mental simulation of that mission needs — the places the route crosses (found through place
//! connectivity), their parents, their metric maps and boundaries, the objects in them, the
//! full robot model, and what is known about people on the route's floors — and nothing else.
//!
//! People walk in from anywhere on a floor, so a mission's database carries the people
//! knowledge of its whole floors: every place on them with an expected number of people or a
//! robots' estimate (with its boundary, where people of that place appear, and the places it is
//! inside of), and every walking route and attractor inside them. Places off the route come
//! without their objects.
//!
//! Only asserted triples are included (not the materialised entailments), sorted, with the
//! stable IRIs of the graph, so two downloads of overlapping missions merge cleanly.

use std::collections::{BTreeSet, HashMap, HashSet, VecDeque};
use std::sync::Arc;

use oxigraph::model::{Graph, NamedNode, NamedNodeRef, Term, Triple};
use tosm::{Place, PlaceKind, vocab};

use crate::store::{KnowledgeStore, StoreError};

mod people;
mod reader;
mod route;
#[cfg(test)]
mod tests;

use people::{PeopleKnowledge, people_on_floors};
use reader::Reader;
use route::{locate, on_floor, shortest_route};

/// A point or a place a mission passes through.
#[derive(Debug, Clone, PartialEq)]
pub enum Waypoint {
    /// Coordinates in a floor's frame, in metres. Without a floor, the floor whose map covers
    /// the point is used (an error if several do).
    Point {
        /// x in metres.
        x: f64,
        /// y in metres.
        y: f64,
        /// The floor's IRI or identifier.
        floor: Option<String>,
    },
    /// A place, by IRI or `tosm:identifier`.
    Place(String),
}

/// A robot and where it must go.
#[derive(Debug, Clone, PartialEq)]
pub struct Mission {
    /// The robot's IRI or identifier.
    pub robot: String,
    /// Where it starts.
    pub start: Waypoint,
    /// Where it must go, in order.
    pub goals: Vec<Waypoint>,
}

/// The subset for one mission.
#[derive(Debug, Clone)]
pub struct OnDemandDatabase {
    /// The triples, sorted.
    pub triples: Vec<Triple>,
    /// The robot's IRI.
    pub robot: String,
    /// The places the route crosses, in route order.
    pub route: Vec<String>,
    /// The floors those places are on.
    pub floors: Vec<String>,
}

/// Why no on-demand database could be made. All but `Store` are the caller's to fix.
#[derive(Debug, thiserror::Error)]
pub enum OnDemandError {
    /// The mission has no goal.
    #[error("the mission has no goals: give at least one")]
    NoGoals,
    /// A coordinate is not a finite number.
    #[error("{which}: coordinates must be finite numbers")]
    NotFinite {
        /// Which waypoint.
        which: String,
    },
    /// No robot with that IRI or identifier.
    #[error("unknown robot {0:?}: no tosm:Robot has that IRI or identifier")]
    UnknownRobot(String),
    /// No place with that IRI or identifier.
    #[error("{which}: unknown place {name:?}")]
    UnknownPlace {
        /// Which waypoint.
        which: String,
        /// The name given.
        name: String,
    },
    /// The graph has the place, but not as the ontology describes one (an engineer's write
    /// left it unreadable): what is wrong with it.
    #[error("{name:?} is in the graph but cannot be read as a place: {problems}")]
    UnreadablePlace {
        /// The name given.
        name: String,
        /// What is wrong with it, and with its metric map.
        problems: String,
    },
    /// The point is in no known place.
    #[error("{which}: the point ({x}, {y}) lies outside every known place{floor_note}")]
    OutsideEveryPlace {
        /// Which waypoint.
        which: String,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// Which floors were searched.
        floor_note: String,
    },
    /// Several floors cover the point.
    #[error("{which}: the point ({x}, {y}) lies on several floors ({floors}); say which floor")]
    AmbiguousFloor {
        /// Which waypoint.
        which: String,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// The candidates.
        floors: String,
    },
    /// No chain of `tosm:isConnectedTo` links joins two waypoints' places.
    #[error("places {from} and {to} are not connected: no route through tosm:isConnectedTo")]
    NotConnected {
        /// The first place.
        from: String,
        /// The second place.
        to: String,
    },
    /// The place is on no floor (a building, or a place outside every floor).
    #[error("{0} is on no floor: only floors and the places on them have a world")]
    NoFloor(String),
    /// Following `tosm:isDirectlyInsideOf` up from a place comes back to a place already
    /// passed: an engineer's mistake in the graph.
    #[error(
        "the tosm:isDirectlyInsideOf chain of {place} loops: {}; a place cannot be inside \
         itself, fix the graph over SPARQL",
        cycle.join(" → ")
    )]
    Cycle {
        /// Where the walk started.
        place: String,
        /// The places of the loop, the first repeated at the end.
        cycle: Vec<String>,
    },
    /// The request was stopped (its client hung up or its deadline passed) before the
    /// database was built.
    #[error("stopped before the database was built: the request was cancelled")]
    Stopped,
    /// Reading the store failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

impl OnDemandError {
    /// Whether the caller is at fault (4xx) rather than the service (5xx).
    pub fn is_client_error(&self) -> bool {
        !matches!(self, OnDemandError::Store(_))
    }
}

/// `start` and the places it is inside of, innermost first, found by `lookup` (IRI → place);
/// the walk ends at a place with no (known) container. A chain that comes back to a place it
/// passed is an error naming the loop, so no walk over the graph can spin.
pub fn containers<'a>(
    lookup: impl Fn(&str) -> Option<&'a Place>,
    start: &'a Place,
) -> Result<Vec<&'a Place>, OnDemandError> {
    let mut chain: Vec<&'a Place> = vec![start];
    let mut cursor = start.parent.as_deref().and_then(&lookup);
    while let Some(p) = cursor {
        if let Some(at) = chain.iter().position(|q| q.iri == p.iri) {
            let mut cycle: Vec<String> = chain[at..].iter().map(|q| q.iri.clone()).collect();
            cycle.push(p.iri.clone());
            return Err(OnDemandError::Cycle {
                place: start.iri.clone(),
                cycle,
            });
        }
        chain.push(p);
        cursor = p.parent.as_deref().and_then(&lookup);
    }
    Ok(chain)
}

/// Every place in the store as typed values, read leniently: a broken place is logged and
/// left out rather than failing every mission. Read once per state of the graph and shared
/// until the next write.
pub fn all_places(store: &KnowledgeStore) -> Result<Arc<Vec<Place>>, StoreError> {
    places_of(&Reader::new(store)?)
}

fn places_of(reader: &Reader) -> Result<Arc<Vec<Place>>, StoreError> {
    if let Some(places) = reader.owner.cached_places(reader.key) {
        return Ok(places);
    }
    let places = Arc::new(read_places(reader)?);
    reader.owner.cache_places(reader.key, places.clone());
    Ok(places)
}

fn read_places(reader: &Reader) -> Result<Vec<Place>, StoreError> {
    let mut triples = HashSet::new();
    let mut seen = BTreeSet::new();
    // Every place once, uncached: the places themselves are what is kept for this state.
    for place in reader.instances(vocab::PLACE)? {
        reader.walk(place.as_ref(), false, &mut triples, &mut seen)?;
    }
    let graph: Graph = triples.into_iter().collect();
    let (places, problems) = tosm::read_places_lenient(&graph);
    if !problems.is_empty() {
        tracing::warn!(%problems, "some places could not be read");
    }
    Ok(places)
}

/// Builds the on-demand database for `mission`. Blocking.
pub fn build(store: &KnowledgeStore, mission: &Mission) -> Result<OnDemandDatabase, OnDemandError> {
    build_until(store, mission, &grid::Stop::never())
}

/// [`build`], giving up with [`OnDemandError::Stopped`] soon after `stop` is requested: it is
/// polled for every waypoint located, every leg routed and every place assembled.
pub fn build_until(
    store: &KnowledgeStore,
    mission: &Mission,
    stop: &grid::Stop,
) -> Result<OnDemandDatabase, OnDemandError> {
    let check = || {
        if stop.requested() {
            Err(OnDemandError::Stopped)
        } else {
            Ok(())
        }
    };
    if mission.goals.is_empty() {
        return Err(OnDemandError::NoGoals);
    }
    let reader = Reader::new(store)?;
    let robot = reader
        .resolve(&mission.robot)?
        .filter(|r| reader.is_a(r.as_ref(), vocab::ROBOT).unwrap_or(false))
        .ok_or_else(|| OnDemandError::UnknownRobot(mission.robot.clone()))?;

    let places = places_of(&reader)?;
    let index: HashMap<&str, &Place> = places.iter().map(|p| (p.iri.as_str(), p)).collect();

    let mut stops = Vec::new();
    stops.push(locate(&reader, &places, &index, "start", &mission.start)?);
    for (i, goal) in mission.goals.iter().enumerate() {
        check()?;
        stops.push(locate(
            &reader,
            &places,
            &index,
            &format!("goals[{i}]"),
            goal,
        )?);
    }

    let mut route: Vec<String> = Vec::new();
    for pair in stops.windows(2) {
        check()?;
        let leg = shortest_route(&index, &pair[0], &pair[1])?;
        for place in leg {
            if route.last() != Some(&place) {
                route.push(place);
            }
        }
    }
    if route.is_empty() {
        route.push(stops[0].clone());
    }

    // The route's places and their ancestors (floors carry the maps, buildings the context).
    let mut included: BTreeSet<String> = BTreeSet::new();
    let mut floors: Vec<String> = Vec::new();
    for place in &route {
        check()?;
        let Some(start) = index.get(place.as_str()) else {
            included.insert(place.clone());
            continue;
        };
        for p in containers(|iri| index.get(iri).copied(), start)? {
            included.insert(p.iri.clone());
            if p.kind == PlaceKind::Floor && !floors.contains(&p.iri) {
                floors.push(p.iri.clone());
            }
        }
    }

    check()?;
    let people = people_on_floors(&reader, &index, &floors, &included)?;
    let triples = assemble(&reader, &included, &people, &robot, &check)?;
    Ok(OnDemandDatabase {
        triples,
        robot: robot.into_string(),
        route,
        floors,
    })
}

/// The triples of the `included` places, the objects inside them (recursively), the `people`
/// knowledge, and the robot, sorted by their N-Triples form so the same input gives
/// byte-identical output.
fn assemble(
    reader: &Reader,
    included: &BTreeSet<String>,
    people: &PeopleKnowledge,
    robot: &NamedNode,
    check: &dyn Fn() -> Result<(), OnDemandError>,
) -> Result<Vec<Triple>, OnDemandError> {
    let store = &reader.store;
    let mut triples = HashSet::new();
    let mut seen = BTreeSet::new();
    for iri in included {
        check()?;
        reader.closure(
            NamedNodeRef::new_unchecked(iri),
            false,
            &mut triples,
            &mut seen,
        )?;
    }
    // Objects directly inside an included place, and objects inside those objects.
    let mut containers: VecDeque<String> = included.iter().cloned().collect();
    while let Some(container) = containers.pop_front() {
        check()?;
        let node = NamedNode::new_unchecked(container);
        for quad in store.quads_for_pattern(
            None,
            Some(vocab::IS_DIRECTLY_INSIDE_OF),
            Some(node.as_ref().into()),
            None,
        ) {
            let quad = quad.map_err(|e| reader.err(e))?;
            if let oxigraph::model::NamedOrBlankNode::NamedNode(object) = quad.subject
                && reader.is_a(object.as_ref(), vocab::OBJECT)?
                && !seen.contains(&object)
            {
                reader.closure(object.as_ref(), false, &mut triples, &mut seen)?;
                containers.push_back(object.into_string());
            }
        }
    }
    // People knowledge: its places without their objects, its routes and attractors.
    for iri in &people.places {
        check()?;
        reader.closure(
            NamedNodeRef::new_unchecked(iri),
            false,
            &mut triples,
            &mut seen,
        )?;
    }
    for individual in &people.individuals {
        reader.closure(individual.as_ref(), false, &mut triples, &mut seen)?;
    }
    reader.closure(robot.as_ref(), true, &mut triples, &mut seen)?;

    // Sorted by their N-Triples form: the same mission gives byte-identical output.
    let mut triples: Vec<(String, Triple)> =
        triples.into_iter().map(|t| (t.to_string(), t)).collect();
    triples.sort_unstable_by(|a, b| a.0.cmp(&b.0));
    Ok(triples.into_iter().map(|(_, t)| t).collect())
}

/// A whole floor as one self-sufficient graph: the floor, every place below it and their
/// ancestors, the objects in them, and the robot — what a world export of the floor needs.
/// `robot` may be `None` to take the first robot in the store. Blocking.
pub fn floor_database(
    store: &KnowledgeStore,
    floor: &str,
    robot: Option<&str>,
) -> Result<OnDemandDatabase, OnDemandError> {
    let reader = Reader::new(store)?;
    let robot = match robot {
        Some(name) => reader
            .resolve(name)?
            .filter(|r| reader.is_a(r.as_ref(), vocab::ROBOT).unwrap_or(false))
            .ok_or_else(|| OnDemandError::UnknownRobot(name.to_owned()))?,
        None => reader
            .instances(vocab::ROBOT)?
            .into_iter()
            .next()
            .ok_or_else(|| OnDemandError::UnknownRobot("(any)".to_owned()))?,
    };
    let places = places_of(&reader)?;
    let index: HashMap<&str, &Place> = places.iter().map(|p| (p.iri.as_str(), p)).collect();
    let floor_place = index
        .get(floor)
        .filter(|p| p.kind == PlaceKind::Floor)
        .ok_or_else(|| OnDemandError::UnknownPlace {
            which: "floor".to_owned(),
            name: floor.to_owned(),
        })?;
    let mut included: BTreeSet<String> = places
        .iter()
        .filter(|p| on_floor(&index, p, floor))
        .map(|p| p.iri.clone())
        .collect();
    for p in containers(|iri| index.get(iri).copied(), floor_place)? {
        included.insert(p.iri.clone());
    }
    let route: Vec<String> = included.iter().cloned().collect();
    let floors = vec![floor.to_owned()];
    let people = people_on_floors(&reader, &index, &floors, &included)?;
    let triples = assemble(&reader, &included, &people, &robot, &|| Ok(()))?;
    Ok(OnDemandDatabase {
        triples,
        robot: robot.into_string(),
        route,
        floors,
    })
}

/// The floor a place is on (the place itself when it is a floor), by IRI or identifier.
pub fn floor_of(places: &[Place], place: &str) -> Result<String, OnDemandError> {
    let start = places
        .iter()
        .find(|p| p.iri == place || p.symbol.identifier.as_deref() == Some(place))
        .ok_or_else(|| OnDemandError::UnknownPlace {
            which: "place".to_owned(),
            name: place.to_owned(),
        })?;
    let index: HashMap<&str, &Place> = places.iter().map(|p| (p.iri.as_str(), p)).collect();
    containers(|iri| index.get(iri).copied(), start)?
        .into_iter()
        .find(|p| p.kind == PlaceKind::Floor)
        .map(|p| p.iri.clone())
        .ok_or_else(|| OnDemandError::NoFloor(start.iri.clone()))
}

/// [`floor_database`] of the floor `place` (IRI or identifier) is on: what a mental
/// simulation of that whole floor needs, for `robot` (IRI or identifier; the first robot when
/// `None`). `floors[0]` of the answer is the floor's IRI.
pub fn floor_database_of_place(
    store: &KnowledgeStore,
    place: &str,
    robot: Option<&str>,
) -> Result<OnDemandDatabase, OnDemandError> {
    let places = all_places(store)?;
    let floor = match floor_of(&places, place) {
        Err(OnDemandError::UnknownPlace { .. }) => return Err(unknown_place(store, place)?),
        other => other?,
    };
    floor_database(store, &floor, robot)
}

/// Why no readable place is named `name`: a place in the graph that does not read as one
/// ([`OnDemandError::UnreadablePlace`], with the problems of it and of its metric map), else
/// [`OnDemandError::UnknownPlace`]. The error path only: it reads every place again.
fn unknown_place(store: &KnowledgeStore, name: &str) -> Result<OnDemandError, StoreError> {
    let unknown = OnDemandError::UnknownPlace {
        which: "place".to_owned(),
        name: name.to_owned(),
    };
    let reader = Reader::new(store)?;
    let Some(iri) = reader.resolve(name)? else {
        return Ok(unknown);
    };
    if !reader.is_a(iri.as_ref(), vocab::PLACE)? {
        return Ok(unknown);
    }
    let mut about = vec![iri.as_str().to_owned()];
    for quad in reader.store.quads_for_pattern(
        Some(iri.as_ref().into()),
        Some(vocab::HAS_METRIC_MAP),
        None,
        None,
    ) {
        if let Term::NamedNode(map) = quad.map_err(|e| reader.err(e))?.object {
            about.push(map.into_string());
        }
    }
    let mut triples = HashSet::new();
    let mut seen = BTreeSet::new();
    reader.closure(iri.as_ref(), false, &mut triples, &mut seen)?;
    let graph: Graph = triples.into_iter().collect();
    let (_, problems) = tosm::read_places_lenient(&graph);
    let problems: Vec<String> = problems
        .iter()
        .filter(|p| about.contains(&p.individual))
        .map(ToString::to_string)
        .collect();
    Ok(if problems.is_empty() {
        unknown
    } else {
        OnDemandError::UnreadablePlace {
            name: name.to_owned(),
            problems: problems.join("; "),
        }
    })
}
