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

use std::collections::{BTreeMap, BTreeSet, HashMap, HashSet, VecDeque};
use std::sync::Arc;

use oxigraph::model::vocab::rdf;
use oxigraph::model::{Graph, GraphNameRef, NamedNode, NamedNodeRef, Term, TermRef, Triple};
use tosm::{Place, PlaceKind, vocab};

use crate::graphs::INFERRED_GRAPH;
use crate::store::{KnowledgeStore, StoreError};

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

/// Reads asserted triples out of the store (every graph but the inferred one): the embedded
/// store itself, or the in-memory snapshot of a remote one.
struct Reader {
    store: oxigraph::store::Store,
    location: String,
    owner: KnowledgeStore,
    key: crate::store::CacheKey,
}

impl Reader {
    fn new(store: &KnowledgeStore) -> Result<Self, StoreError> {
        let snapshot = store.snapshot()?;
        Ok(Self {
            store: snapshot,
            location: store.location().to_owned(),
            owner: store.clone(),
            key: store.cache_key(),
        })
    }

    fn err(&self, source: oxigraph::store::StorageError) -> StoreError {
        StoreError::Storage {
            location: self.location.clone(),
            source,
        }
    }

    /// Asserted triples about `subject`.
    fn about(&self, subject: NamedNodeRef<'_>) -> Result<Vec<Triple>, StoreError> {
        let mut out = Vec::new();
        for quad in self
            .store
            .quads_for_pattern(Some(subject.into()), None, None, None)
        {
            let quad = quad.map_err(|e| self.err(e))?;
            if quad.graph_name.as_ref() != GraphNameRef::NamedNode(INFERRED_GRAPH) {
                out.push(Triple::from(quad));
            }
        }
        Ok(out)
    }

    /// Whether `node` has type `class`, asserted or entailed.
    fn is_a(&self, node: NamedNodeRef<'_>, class: NamedNodeRef<'_>) -> Result<bool, StoreError> {
        let mut it = self.store.quads_for_pattern(
            Some(node.into()),
            Some(rdf::TYPE),
            Some(class.into()),
            None,
        );
        match it.next() {
            Some(Ok(_)) => Ok(true),
            Some(Err(e)) => Err(self.err(e)),
            None => Ok(false),
        }
    }

    /// Every individual of `class` (asserted or entailed), sorted.
    fn instances(&self, class: NamedNodeRef<'_>) -> Result<BTreeSet<NamedNode>, StoreError> {
        let mut out = BTreeSet::new();
        for quad in self
            .store
            .quads_for_pattern(None, Some(rdf::TYPE), Some(class.into()), None)
        {
            let quad = quad.map_err(|e| self.err(e))?;
            if let oxigraph::model::NamedOrBlankNode::NamedNode(n) = quad.subject {
                out.insert(n);
            }
        }
        Ok(out)
    }

    /// `subject`'s triples and, recursively, those of the individuals it owns: descriptors
    /// (poses, shapes, boundary points, maps) and, when `parts` is set, robot parts.
    fn closure(
        &self,
        subject: NamedNodeRef<'_>,
        parts: bool,
        out: &mut HashSet<Triple>,
        seen: &mut BTreeSet<NamedNode>,
    ) -> Result<(), StoreError> {
        if !seen.insert(subject.into_owned()) {
            return Ok(());
        }
        for triple in self.about(subject)? {
            if let Term::NamedNode(object) = &triple.object
                && triple.predicate.as_ref() != rdf::TYPE
                && (self.is_a(object.as_ref(), vocab::DESCRIPTOR)?
                    || (parts && self.is_a(object.as_ref(), vocab::ROBOT_PART)?))
            {
                self.closure(object.as_ref(), parts, out, seen)?;
            }
            out.insert(triple);
        }
        Ok(())
    }

    /// Whether `place` states an expected number of people or has a people estimate
    /// (asserted, in any graph but the inferred one).
    fn knows_people_in(&self, place: &str) -> Result<bool, StoreError> {
        let node = NamedNodeRef::new_unchecked(place);
        for p in [
            vocab::EXPECTED_PEOPLE,
            vocab::HAS_HOURLY_PEOPLE_COUNT,
            vocab::HAS_PEOPLE_ESTIMATE,
        ] {
            for quad in self
                .store
                .quads_for_pattern(Some(node.into()), Some(p), None, None)
            {
                let quad = quad.map_err(|e| self.err(e))?;
                if quad.graph_name.as_ref() != GraphNameRef::NamedNode(INFERRED_GRAPH) {
                    return Ok(true);
                }
            }
        }
        Ok(false)
    }

    /// The asserted IRI value of `subject`'s `property`, if any (the first, in store order).
    fn asserted_object(
        &self,
        subject: NamedNodeRef<'_>,
        property: NamedNodeRef<'_>,
    ) -> Result<Option<String>, StoreError> {
        for quad in self
            .store
            .quads_for_pattern(Some(subject.into()), Some(property), None, None)
        {
            let quad = quad.map_err(|e| self.err(e))?;
            if quad.graph_name.as_ref() != GraphNameRef::NamedNode(INFERRED_GRAPH)
                && let Term::NamedNode(n) = quad.object
            {
                return Ok(Some(n.into_string()));
            }
        }
        Ok(None)
    }

    /// The individual named `name`: an IRI, or the subject of `tosm:identifier "name"`.
    fn resolve(&self, name: &str) -> Result<Option<NamedNode>, StoreError> {
        if name.contains("://") || name.starts_with("urn:") {
            return Ok(NamedNode::new(name).ok());
        }
        let literal = oxigraph::model::Literal::new_simple_literal(name);
        let mut it = self.store.quads_for_pattern(
            None,
            Some(vocab::IDENTIFIER),
            Some(TermRef::Literal(literal.as_ref())),
            None,
        );
        match it.next() {
            Some(Ok(q)) => Ok(match q.subject {
                oxigraph::model::NamedOrBlankNode::NamedNode(n) => Some(n),
                _ => None,
            }),
            Some(Err(e)) => Err(self.err(e)),
            None => Ok(None),
        }
    }
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
    for place in reader.instances(vocab::PLACE)? {
        reader.closure(place.as_ref(), false, &mut triples, &mut seen)?;
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

/// What a database adds for the people on its floors: places (off the route) with people
/// knowledge and the places they are inside of, and the walking routes and attractors.
#[derive(Debug, Default)]
struct PeopleKnowledge {
    /// Places not already included, described without their objects.
    places: BTreeSet<String>,
    /// Walking routes and attractors.
    individuals: BTreeSet<NamedNode>,
}

/// The people knowledge of `floors` that `included` does not hold yet.
fn people_on_floors(
    reader: &Reader,
    index: &HashMap<&str, &Place>,
    floors: &[String],
    included: &BTreeSet<String>,
) -> Result<PeopleKnowledge, OnDemandError> {
    let on_one_of_the_floors = |place: &Place| {
        floors
            .iter()
            .any(|f| place.iri == *f || on_floor(index, place, f))
    };
    let mut out = PeopleKnowledge::default();
    let add_place = |place: &Place, out: &mut PeopleKnowledge| -> Result<(), OnDemandError> {
        for p in containers(|iri| index.get(iri).copied(), place)? {
            if !included.contains(&p.iri) {
                out.places.insert(p.iri.clone());
            }
        }
        Ok(())
    };
    for place in index.values() {
        if on_one_of_the_floors(place) && reader.knows_people_in(&place.iri)? {
            add_place(place, &mut out)?;
        }
    }
    for class in [vocab::WALKING_ROUTE, vocab::ATTRACTOR] {
        for individual in reader.instances(class)? {
            let container =
                reader.asserted_object(individual.as_ref(), vocab::IS_DIRECTLY_INSIDE_OF)?;
            let Some(place) = container.as_deref().and_then(|c| index.get(c).copied()) else {
                continue;
            };
            if on_one_of_the_floors(place) {
                add_place(place, &mut out)?;
                out.individuals.insert(individual);
            }
        }
    }
    Ok(out)
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

/// The place a waypoint is in: the smallest place whose boundary contains the point.
fn locate(
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

fn on_floor(index: &HashMap<&str, &Place>, place: &Place, floor: &str) -> bool {
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
fn shortest_route(
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
fn contains(polygon: &[(f64, f64)], x: f64, y: f64) -> bool {
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

fn polygon_area(polygon: &[(f64, f64)]) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn store() -> KnowledgeStore {
        let store = KnowledgeStore::in_memory().unwrap();
        crate::bundled::load_if_empty(&store).unwrap();
        store
    }

    fn robot() -> String {
        "https://mentalsim.dev/data/robots/differential-robot".to_owned()
    }

    fn places(store: &KnowledgeStore) -> Vec<Place> {
        all_places(store).unwrap().to_vec()
    }

    #[test]
    fn sample_building_places_read_without_problems() {
        let store = store();
        let places = places(&store);
        assert!(
            places
                .iter()
                .any(|p| p.kind == PlaceKind::Floor && p.map.is_some())
        );
        assert!(places.iter().any(|p| p.kind == PlaceKind::Room));
    }

    #[test]
    fn a_stopped_request_builds_nothing() {
        let store = store();
        let floor = places(&store)
            .into_iter()
            .find(|p| p.kind == PlaceKind::Floor)
            .unwrap();
        let mission = Mission {
            robot: robot(),
            start: Waypoint::Place(floor.iri.clone()),
            goals: vec![Waypoint::Place(floor.iri.clone()); 1000],
        };
        let stop = grid::Stop::new();
        assert!(build_until(&store, &mission, &stop).is_ok());
        stop.request();
        assert!(matches!(
            build_until(&store, &mission, &stop),
            Err(OnDemandError::Stopped)
        ));
    }

    #[test]
    fn a_mission_between_two_rooms_holds_the_route_objects_map_and_robot() {
        let store = store();
        let places = places(&store);
        // Two connected rooms that are not the same place.
        let room = places
            .iter()
            .find(|p| {
                p.kind != PlaceKind::Floor
                    && p.kind != PlaceKind::Building
                    && !p.connected.is_empty()
            })
            .unwrap();
        let goal = room.connected[0].clone();
        let mission = Mission {
            robot: robot(),
            start: Waypoint::Place(room.iri.clone()),
            goals: vec![Waypoint::Place(goal.clone())],
        };
        let db = build(&store, &mission).unwrap();
        assert_eq!(db.route, vec![room.iri.clone(), goal]);
        assert_eq!(db.floors.len(), 1);
        let graph: Graph = db.triples.iter().cloned().collect();
        // Self-sufficient: the typed readers find the robot, the route's places and a map.
        tosm::read_robot(&graph, &robot()).unwrap();
        let read = tosm::read_places(&graph).unwrap();
        assert!(read.iter().any(|p| p.map.is_some()));
        // Nothing else: no place off the route except ancestors and the places people are
        // expected in, and no object off the route.
        let about = |iri: &str| {
            graph
                .iter()
                .any(|t| t.subject.to_string() == format!("<{iri}>"))
        };
        let people = tosm::read_people(&graph).unwrap();
        let off_route = places.iter().filter(|p| {
            !db.route.contains(&p.iri)
                && p.kind != PlaceKind::Floor
                && p.kind != PlaceKind::Building
        });
        let mut people_places = 0;
        for p in off_route {
            let has_people = people.places.iter().any(|q| q.place == p.iri);
            people_places += usize::from(has_people);
            assert_eq!(about(&p.iri), has_people, "{} leaked or is missing", p.iri);
        }
        assert!(
            people_places > 0,
            "the sample expects people off this route"
        );
        let objects = tosm::read_objects(&graph).unwrap();
        assert!(
            objects.iter().all(|o| db.route.contains(&o.inside_of)),
            "objects off the route: {objects:?}"
        );
        // The floor's walking routes and attractor, whichever places they are in.
        assert_eq!((people.routes.len(), people.attractors.len()), (2, 1));
        // Deterministic.
        let again = build(&store, &mission).unwrap();
        assert_eq!(again.triples, db.triples);
    }

    #[test]
    fn points_resolve_to_the_smallest_place_holding_them() {
        let store = store();
        let places = places(&store);
        let room = places
            .iter()
            .find(|p| p.kind == PlaceKind::Room && p.boundary.len() >= 3)
            .unwrap();
        let (cx, cy) = room
            .boundary
            .iter()
            .fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
        let n = room.boundary.len() as f64;
        let mission = Mission {
            robot: "R-001".to_owned(),
            start: Waypoint::Point {
                x: cx / n,
                y: cy / n,
                floor: None,
            },
            goals: vec![Waypoint::Place(room.iri.clone())],
        };
        let db = build(&store, &mission).unwrap();
        assert_eq!(db.route, vec![room.iri.clone()]);
    }

    #[test]
    fn bad_missions_name_what_is_wrong() {
        let store = store();
        let any_place = places(&store)[0].iri.clone();
        let mission = |robot: &str, start: Waypoint, goals: Vec<Waypoint>| Mission {
            robot: robot.to_owned(),
            start,
            goals,
        };
        let err = build(
            &store,
            &mission(
                "R-999",
                Waypoint::Place(any_place.clone()),
                vec![Waypoint::Place(any_place.clone())],
            ),
        )
        .unwrap_err();
        assert!(matches!(err, OnDemandError::UnknownRobot(_)), "{err}");
        let err = build(
            &store,
            &mission("R-001", Waypoint::Place(any_place.clone()), vec![]),
        )
        .unwrap_err();
        assert!(matches!(err, OnDemandError::NoGoals), "{err}");
        let far = Waypoint::Point {
            x: 1e6,
            y: 1e6,
            floor: None,
        };
        let err = build(
            &store,
            &mission("R-001", far, vec![Waypoint::Place(any_place.clone())]),
        )
        .unwrap_err();
        assert!(
            matches!(err, OnDemandError::OutsideEveryPlace { .. }),
            "{err}"
        );
        let nan = Waypoint::Point {
            x: f64::NAN,
            y: 0.0,
            floor: None,
        };
        let err = build(
            &store,
            &mission("R-001", nan, vec![Waypoint::Place(any_place.clone())]),
        )
        .unwrap_err();
        assert!(matches!(err, OnDemandError::NotFinite { .. }), "{err}");
        let err = build(
            &store,
            &mission(
                "R-001",
                Waypoint::Place("nowhere".into()),
                vec![Waypoint::Place(any_place)],
            ),
        )
        .unwrap_err();
        assert!(matches!(err, OnDemandError::UnknownPlace { .. }), "{err}");
        assert!(err.is_client_error());
    }

    #[test]
    fn places_on_different_floors_without_a_link_are_not_connected() {
        let store = store();
        let places = places(&store);
        let floors: Vec<&Place> = places
            .iter()
            .filter(|p| p.kind == PlaceKind::Floor)
            .collect();
        assert!(floors.len() >= 2, "the sample building has two floors");
        let index: HashMap<&str, &Place> = places.iter().map(|p| (p.iri.as_str(), p)).collect();
        let a = places
            .iter()
            .find(|p| p.kind == PlaceKind::Room && on_floor(&index, p, &floors[0].iri))
            .unwrap();
        let b = places
            .iter()
            .find(|p| {
                p.kind != PlaceKind::Floor
                    && p.kind != PlaceKind::Building
                    && on_floor(&index, p, &floors[1].iri)
            })
            .unwrap();
        let err = build(
            &store,
            &Mission {
                robot: "R-001".into(),
                start: Waypoint::Place(a.iri.clone()),
                goals: vec![Waypoint::Place(b.iri.clone())],
            },
        )
        .unwrap_err();
        assert!(matches!(err, OnDemandError::NotConnected { .. }), "{err}");
    }
}
