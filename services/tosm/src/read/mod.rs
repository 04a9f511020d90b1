//! Reading typed places, objects, robots and people knowledge out of an RDF graph, with validation.
//!
//! The graph needs no reasoning: an individual is recognised by its asserted `rdf:type`, using
//! the ontology's class hierarchy (built in) plus any `rdfs:subClassOf` triples in the graph
//! itself, so data with a class of its own (`ex:Piano rdfs:subClassOf tosm:Object`) is read too.
//! Every problem found is reported with the individual and property it concerns; nothing here
//! panics on bad data.
//!
//! References: a place's parent, an object's container, a joint's parts and a robot's base must
//! be described in the graph. Connections and spatial relations may point outside the graph
//! (an on-demand subset holds only the places on a route), but when their target is in the
//! graph it must be of the right kind.
//!
//! The `Reader` walks the graph: this module holds what it knows of classes and references;
//! `literals` reads single values and the small descriptions built of them (pose, shape,
//! colour); `places`, `objects`, `people` and `robots` read the individuals.

use std::collections::{BTreeMap, BTreeSet};

use oxrdf::vocab::{rdf, rdfs};
use oxrdf::{Graph, NamedNodeRef, NamedOrBlankNodeRef, TermRef};

use crate::model::{Object, People, PeopleEstimate, Place, Robot};
use crate::problems::{Problem, Problems};
use crate::vocab as v;

mod literals;
mod objects;
mod people;
mod places;
mod robots;

/// Reads every place (building, floor, corridor, room, hall) in `graph`, sorted by IRI.
pub fn read_places(graph: &Graph) -> Result<Vec<Place>, Problems> {
    let (places, problems) = read_places_lenient(graph);
    problems.into_result(places)
}

/// Like [`read_places`], but returns the places that could be read along with every problem.
pub fn read_places_lenient(graph: &Graph) -> (Vec<Place>, Problems) {
    let mut r = Reader::new(graph);
    let places = r
        .individuals_of(v::PLACE)
        .into_iter()
        .filter_map(|iri| r.place(&iri))
        .collect();
    (places, Problems(r.problems).normalise())
}

/// Reads every object in `graph`, sorted by IRI.
pub fn read_objects(graph: &Graph) -> Result<Vec<Object>, Problems> {
    let (objects, problems) = read_objects_lenient(graph);
    problems.into_result(objects)
}

/// Like [`read_objects`], but returns the objects that could be read along with every problem.
pub fn read_objects_lenient(graph: &Graph) -> (Vec<Object>, Problems) {
    let mut r = Reader::new(graph);
    let objects = r
        .individuals_of(v::OBJECT)
        .into_iter()
        .filter_map(|iri| r.object(&iri))
        .collect();
    (objects, Problems(r.problems).normalise())
}

/// Reads everything `graph` says about people: places' expected numbers and estimates,
/// walking routes and attractors, each sorted by IRI.
pub fn read_people(graph: &Graph) -> Result<People, Problems> {
    let (people, problems) = read_people_lenient(graph);
    problems.into_result(people)
}

/// Like [`read_people`], but returns what could be read along with every problem.
pub fn read_people_lenient(graph: &Graph) -> (People, Problems) {
    let mut r = Reader::new(graph);
    let places = r
        .people_subjects()
        .into_iter()
        .filter_map(|iri| r.place_people(&iri))
        .collect();
    let routes = r
        .individuals_of(v::WALKING_ROUTE)
        .into_iter()
        .filter_map(|iri| r.walking_route(&iri))
        .collect();
    let attractors = r
        .individuals_of(v::ATTRACTOR)
        .into_iter()
        .filter_map(|iri| r.attractor(&iri))
        .collect();
    let people = People {
        places,
        routes,
        attractors,
    };
    (people, Problems(r.problems).normalise())
}

/// The people estimates `graph` holds for `place` (`tosm:hasPeopleEstimate`), the all-day one
/// first, then by hour; whether `place` is described as a place is not checked.
pub fn read_people_estimates(graph: &Graph, place: &str) -> Result<Vec<PeopleEstimate>, Problems> {
    let mut r = Reader::new(graph);
    let estimates = r.estimates(place);
    Problems(r.problems).into_result(estimates)
}

/// Reads the robot `iri` from `graph`.
pub fn read_robot(graph: &Graph, iri: &str) -> Result<Robot, Problems> {
    let mut r = Reader::new(graph);
    if !r.individuals_of(v::ROBOT).iter().any(|i| i == iri) {
        r.problem(
            iri,
            rdf::TYPE,
            "is not described as a tosm:Robot in the graph",
        );
        return Err(Problems(r.problems).normalise());
    }
    let robot = r.robot(iri);
    match robot {
        Some(robot) => Problems(r.problems).into_result(robot),
        None => Err(Problems(r.problems).normalise()),
    }
}

/// Reads every robot in `graph`, sorted by IRI.
pub fn read_robots(graph: &Graph) -> Result<Vec<Robot>, Problems> {
    let mut r = Reader::new(graph);
    let robots = r
        .individuals_of(v::ROBOT)
        .into_iter()
        .filter_map(|iri| r.robot(&iri))
        .collect();
    Problems(r.problems).into_result(robots)
}

/// The ontology's own subclass axioms that the reader relies on (child, parent).
const BUILT_IN_SUBCLASSES: &[(NamedNodeRef<'static>, NamedNodeRef<'static>)] = &[
    (v::PLACE, v::ENTITY),
    (v::BUILDING, v::PLACE),
    (v::FLOOR, v::PLACE),
    (v::CORRIDOR, v::PLACE),
    (v::ROOM, v::PLACE),
    (v::HALL, v::PLACE),
    (v::OBJECT, v::ENTITY),
    (v::DOOR, v::OBJECT),
    (v::TABLE, v::OBJECT),
    (v::CHAIR, v::OBJECT),
    (v::SHELF, v::OBJECT),
    (v::CABINET, v::OBJECT),
    (v::SOFA, v::OBJECT),
    (v::BIN, v::OBJECT),
    (v::VENDING_MACHINE, v::OBJECT),
    (v::ROBOT, v::ENTITY),
    (v::DIFFERENTIAL_DRIVE_ROBOT, v::ROBOT),
    (v::ROBOT_PART, v::ENTITY),
    (v::STRUCTURAL_PART, v::ROBOT_PART),
    (v::WHEEL, v::STRUCTURAL_PART),
    (v::ACTIVE_WHEEL, v::WHEEL),
    (v::PASSIVE_WHEEL, v::WHEEL),
    (v::CASTER_WHEEL, v::PASSIVE_WHEEL),
    (v::JOINT, v::ROBOT_PART),
    (v::FIXED_JOINT, v::JOINT),
    (v::CONTINUOUS_JOINT, v::JOINT),
    (v::SENSOR, v::ROBOT_PART),
    (v::CAMERA, v::SENSOR),
    (v::STEREO_CAMERA, v::CAMERA),
    (v::RGBD_CAMERA, v::CAMERA),
    (v::LASER_RANGE_FINDER, v::SENSOR),
    (v::POSE, v::DESCRIPTOR),
    (v::SHAPE, v::DESCRIPTOR),
    (v::BOX_SHAPE, v::SHAPE),
    (v::CYLINDER_SHAPE, v::SHAPE),
    (v::SPHERE_SHAPE, v::SHAPE),
    (v::BOUNDARY_POINT, v::DESCRIPTOR),
    (v::METRIC_MAP, v::DESCRIPTOR),
    (v::OCCUPANCY_GRID_MAP, v::METRIC_MAP),
    (v::MATERIAL, v::DESCRIPTOR),
    (v::WALKING_ROUTE, v::ENTITY),
    (v::ATTRACTOR, v::ENTITY),
    (v::ROUTE_POINT, v::DESCRIPTOR),
    (v::HOURLY_PEOPLE_COUNT, v::DESCRIPTOR),
    (v::PEOPLE_ESTIMATE, v::DESCRIPTOR),
];

/// Numbers closer than this are equal when checking a cylinder's or sphere's extents.
const EXTENT_TOLERANCE: f64 = 1e-6;

struct Reader<'g> {
    graph: &'g Graph,
    /// class IRI -> its superclasses (reflexive, transitive).
    ancestors: BTreeMap<String, BTreeSet<String>>,
    problems: Vec<Problem>,
}

impl<'g> Reader<'g> {
    fn new(graph: &'g Graph) -> Self {
        let mut parents: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (child, parent) in BUILT_IN_SUBCLASSES {
            parents
                .entry(child.as_str().to_owned())
                .or_default()
                .insert(parent.as_str().to_owned());
        }
        for t in graph.triples_for_predicate(rdfs::SUB_CLASS_OF) {
            if let (NamedOrBlankNodeRef::NamedNode(c), TermRef::NamedNode(p)) =
                (t.subject, t.object)
            {
                parents
                    .entry(c.as_str().to_owned())
                    .or_default()
                    .insert(p.as_str().to_owned());
            }
        }
        let mut ancestors = BTreeMap::new();
        for class in parents.keys() {
            let mut seen = BTreeSet::from([class.clone()]);
            let mut todo = vec![class.clone()];
            while let Some(c) = todo.pop() {
                for p in parents.get(&c).into_iter().flatten() {
                    if seen.insert(p.clone()) {
                        todo.push(p.clone());
                    }
                }
            }
            ancestors.insert(class.clone(), seen);
        }
        Self {
            graph,
            ancestors,
            problems: Vec::new(),
        }
    }

    fn problem(
        &mut self,
        individual: &str,
        property: NamedNodeRef<'_>,
        message: impl Into<String>,
    ) {
        self.problems
            .push(Problem::new(individual, property.as_str(), message));
    }

    fn is_subclass(&self, class: &str, of: NamedNodeRef<'_>) -> bool {
        class == of.as_str()
            || self
                .ancestors
                .get(class)
                .is_some_and(|a| a.contains(of.as_str()))
    }

    /// Asserted classes of `iri`.
    fn types(&self, iri: &str) -> BTreeSet<String> {
        let node = NamedNodeRef::new_unchecked(iri);
        self.graph
            .objects_for_subject_predicate(node, rdf::TYPE)
            .filter_map(|t| match t {
                TermRef::NamedNode(n) => Some(n.as_str().to_owned()),
                _ => None,
            })
            .collect()
    }

    fn has_type(&self, iri: &str, class: NamedNodeRef<'_>) -> bool {
        self.types(iri).iter().any(|t| self.is_subclass(t, class))
    }

    /// Named individuals with a class that is `class` or below it; blank nodes are reported.
    fn individuals_of(&mut self, class: NamedNodeRef<'_>) -> Vec<String> {
        let classes: Vec<String> = self
            .ancestors
            .keys()
            .filter(|c| self.is_subclass(c, class))
            .cloned()
            .chain(std::iter::once(class.as_str().to_owned()))
            .collect();
        let mut found = BTreeSet::new();
        let mut blank = BTreeSet::new();
        for c in &classes {
            let c = NamedNodeRef::new_unchecked(c);
            for s in self.graph.subjects_for_predicate_object(rdf::TYPE, c) {
                match s {
                    NamedOrBlankNodeRef::NamedNode(n) => {
                        found.insert(n.as_str().to_owned());
                    }
                    NamedOrBlankNodeRef::BlankNode(b) => {
                        blank.insert(format!("_:{}", b.as_str()));
                    }
                }
            }
        }
        for b in blank {
            self.problem(
                &b,
                rdf::TYPE,
                "is a blank node; TOSM individuals need an IRI so that downloads merge",
            );
        }
        found.into_iter().collect()
    }

    fn graph_describes(&self, iri: &str) -> bool {
        self.graph
            .triples_for_subject(NamedNodeRef::new_unchecked(iri))
            .next()
            .is_some()
    }

    /// Checks that `target` is described in the graph as a `class`.
    fn check_reference(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        target: &str,
        class: NamedNodeRef<'_>,
        what: &str,
    ) -> bool {
        if self.has_type(target, class) {
            return true;
        }
        self.problem(
            s,
            p,
            if self.graph_describes(target) {
                format!("refers to <{target}>, which is not {what}")
            } else {
                format!(
                    "refers to <{target}>, which the graph does not describe (dangling reference)"
                )
            },
        );
        false
    }

    /// Checks a reference that may leave the graph: only a target present with the wrong
    /// kind is a problem.
    fn check_open_reference(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        target: &str,
        class: NamedNodeRef<'_>,
        what: &str,
    ) {
        if self.types(target).is_empty() && !self.graph_describes(target) {
            return;
        }
        if !self.has_type(target, class) {
            self.problem(s, p, format!("refers to <{target}>, which is not {what}"));
        }
    }

    /// `values` plus every subject that states `p` towards `iri` (for symmetric properties).
    fn with_inverse(&self, iri: &str, p: NamedNodeRef<'_>, values: Vec<String>) -> Vec<String> {
        let mut all: BTreeSet<String> = values.into_iter().collect();
        for s in self
            .graph
            .subjects_for_predicate_object(p, NamedNodeRef::new_unchecked(iri))
        {
            if let NamedOrBlankNodeRef::NamedNode(n) = s {
                all.insert(n.as_str().to_owned());
            }
        }
        all.into_iter().collect()
    }

    /// `start` and everything it is directly inside of, transitively (cycles stop the walk).
    fn container_chain(&self, start: Option<&str>) -> BTreeSet<String> {
        let mut chain = BTreeSet::new();
        let mut next = start.map(str::to_owned);
        while let Some(c) = next {
            if !chain.insert(c.clone()) {
                break;
            }
            next = self
                .graph
                .object_for_subject_predicate(
                    NamedNodeRef::new_unchecked(&c),
                    v::IS_DIRECTLY_INSIDE_OF,
                )
                .and_then(|t| match t {
                    TermRef::NamedNode(n) => Some(n.as_str().to_owned()),
                    _ => None,
                });
        }
        chain
    }
}
