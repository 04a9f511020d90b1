//! Reading typed places, objects and robots out of an RDF graph, with validation.
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

use std::collections::{BTreeMap, BTreeSet};

use base64::Engine as _;
use oxrdf::vocab::{rdf, rdfs, xsd};
use oxrdf::{Graph, NamedNodeRef, NamedOrBlankNodeRef, TermRef};

use crate::model::{
    Camera, CameraKind, Colour, Joint, JointKind, Laser, MetricMap, Object, ObjectClass, Part,
    Physical, Place, PlaceKind, Pose, Relation, RelationKind, Robot, Shape, StructuralPart, Symbol,
    Wheel,
};
use crate::occupancy::{OccupancyGrid, Pose2, RosMapMeta};
use crate::problems::{Problem, Problems};
use crate::vocab as v;

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

    // ---- single values -------------------------------------------------------------------

    fn objects(&self, s: &str, p: NamedNodeRef<'_>) -> Vec<TermRef<'g>> {
        let mut v: Vec<TermRef<'g>> = self
            .graph
            .objects_for_subject_predicate(NamedNodeRef::new_unchecked(s), p)
            .collect();
        v.sort_by_key(|t| t.to_string());
        v
    }

    /// The one value of a functional property; reports a missing (when required) or repeated one.
    fn one(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<TermRef<'g>> {
        let values = self.objects(s, p);
        match values.as_slice() {
            [] => {
                if required {
                    self.problem(s, p, "is missing (required)");
                }
                None
            }
            [one] => Some(*one),
            many => {
                let shown: Vec<String> = many.iter().map(ToString::to_string).collect();
                self.problem(
                    s,
                    p,
                    format!(
                        "has {} values ({}), expected exactly one",
                        many.len(),
                        shown.join(", ")
                    ),
                );
                None
            }
        }
    }

    fn literal(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
    ) -> Option<(String, String)> {
        match self.one(s, p, required)? {
            TermRef::Literal(l) => Some((l.value().to_owned(), l.datatype().as_str().to_owned())),
            other => {
                self.problem(s, p, format!("must be a literal, found {other}"));
                None
            }
        }
    }

    fn number(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<f64> {
        let (value, datatype) = self.literal(s, p, required)?;
        let numeric = [
            xsd::DECIMAL,
            xsd::DOUBLE,
            xsd::FLOAT,
            xsd::INTEGER,
            xsd::INT,
            xsd::LONG,
            xsd::SHORT,
            xsd::NON_NEGATIVE_INTEGER,
            xsd::POSITIVE_INTEGER,
            xsd::NON_POSITIVE_INTEGER,
            xsd::NEGATIVE_INTEGER,
            xsd::UNSIGNED_INT,
            xsd::UNSIGNED_LONG,
        ];
        let parsed = if numeric.iter().any(|d| d.as_str() == datatype) {
            value.trim().parse::<f64>().ok()
        } else {
            None
        };
        match parsed {
            Some(x) if x.is_finite() => Some(x),
            Some(_) => {
                self.problem(s, p, format!("must be a finite number, found {value:?}"));
                None
            }
            None => {
                self.problem(
                    s,
                    p,
                    format!("must be a number (xsd:decimal), found {value:?} of type <{datatype}>"),
                );
                None
            }
        }
    }

    /// A number that must satisfy `ok`, described by `range` in the problem otherwise.
    fn number_where(
        &mut self,
        s: &str,
        p: NamedNodeRef<'_>,
        required: bool,
        ok: fn(f64) -> bool,
        range: &str,
    ) -> Option<f64> {
        let x = self.number(s, p, required)?;
        if ok(x) {
            Some(x)
        } else {
            self.problem(s, p, format!("must be {range}, found {x}"));
            None
        }
    }

    fn positive(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<f64> {
        self.number_where(s, p, required, |x| x > 0.0, "> 0")
    }

    fn non_negative(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<f64> {
        self.number_where(s, p, required, |x| x >= 0.0, ">= 0")
    }

    fn unit_interval(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<f64> {
        self.number_where(s, p, required, |x| (0.0..=1.0).contains(&x), "in [0, 1]")
    }

    fn integer(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<i64> {
        let (value, datatype) = self.literal(s, p, required)?;
        let integer_types = [
            xsd::INTEGER,
            xsd::INT,
            xsd::LONG,
            xsd::SHORT,
            xsd::NON_NEGATIVE_INTEGER,
            xsd::POSITIVE_INTEGER,
            xsd::NON_POSITIVE_INTEGER,
            xsd::NEGATIVE_INTEGER,
            xsd::UNSIGNED_INT,
            xsd::UNSIGNED_LONG,
        ];
        let parsed = if integer_types.iter().any(|d| d.as_str() == datatype) {
            value.trim().trim_start_matches('+').parse::<i64>().ok()
        } else {
            None
        };
        if parsed.is_none() {
            self.problem(
                s,
                p,
                format!("must be an integer (xsd:integer), found {value:?} of type <{datatype}>"),
            );
        }
        parsed
    }

    fn count(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<u32> {
        let n = self.integer(s, p, required)?;
        match u32::try_from(n) {
            Ok(n) if n > 0 => Some(n),
            _ => {
                self.problem(s, p, format!("must be a whole number >= 1, found {n}"));
                None
            }
        }
    }

    fn boolean(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<bool> {
        let (value, datatype) = self.literal(s, p, required)?;
        match (datatype == xsd::BOOLEAN.as_str(), value.trim()) {
            (true, "true" | "1") => Some(true),
            (true, "false" | "0") => Some(false),
            _ => {
                self.problem(
                    s,
                    p,
                    format!(
                        "must be a boolean (xsd:boolean), found {value:?} of type <{datatype}>"
                    ),
                );
                None
            }
        }
    }

    fn string(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<String> {
        let (value, datatype) = self.literal(s, p, required)?;
        if datatype == xsd::STRING.as_str() || datatype == rdf::LANG_STRING.as_str() {
            Some(value)
        } else {
            self.problem(
                s,
                p,
                format!("must be a string, found {value:?} of type <{datatype}>"),
            );
            None
        }
    }

    /// The first of possibly several strings (names may come in several languages).
    fn first_string(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<String> {
        let values = self.objects(s, p);
        let strings: Vec<String> = values
            .iter()
            .filter_map(|t| match t {
                TermRef::Literal(l) => Some(l.value().to_owned()),
                _ => None,
            })
            .collect();
        if strings.len() != values.len() {
            self.problem(s, p, "must be a string literal, found an IRI or blank node");
        }
        if strings.is_empty() && values.is_empty() && required {
            self.problem(s, p, "is missing (required)");
        }
        strings.into_iter().next()
    }

    fn iri(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<String> {
        match self.one(s, p, required)? {
            TermRef::NamedNode(n) => Some(n.as_str().to_owned()),
            other => {
                self.problem(s, p, format!("must be an IRI, found {other}"));
                None
            }
        }
    }

    fn iris(&mut self, s: &str, p: NamedNodeRef<'_>) -> Vec<String> {
        let mut out = Vec::new();
        for t in self.objects(s, p) {
            match t {
                TermRef::NamedNode(n) => out.push(n.as_str().to_owned()),
                other => self.problem(s, p, format!("must be an IRI, found {other}")),
            }
        }
        out.sort();
        out.dedup();
        out
    }

    // ---- shared parts of the models --------------------------------------------------------

    fn symbol(&mut self, s: &str) -> Symbol {
        Symbol {
            name: self.first_string(s, v::NAME, true).unwrap_or_default(),
            identifier: self.string(s, v::IDENTIFIER, false),
            description: self.first_string(s, v::DESCRIPTION, false),
        }
    }

    fn pose(&mut self, s: &str, p: NamedNodeRef<'_>, required: bool) -> Option<Pose> {
        let pose = self.iri(s, p, required)?;
        if !self.has_type(&pose, v::POSE) && !self.graph_describes(&pose) {
            self.problem(
                s,
                p,
                format!("refers to <{pose}>, which the graph does not describe"),
            );
            return None;
        }
        let x = self.number(&pose, v::X_M, true);
        let y = self.number(&pose, v::Y_M, true);
        let z = self.number(&pose, v::Z_M, false).unwrap_or(0.0);
        let roll = self.number(&pose, v::ROLL_RAD, false).unwrap_or(0.0);
        let pitch = self.number(&pose, v::PITCH_RAD, false).unwrap_or(0.0);
        let yaw = self.number(&pose, v::YAW_RAD, false).unwrap_or(0.0);
        Some(Pose {
            x: x?,
            y: y?,
            z,
            roll,
            pitch,
            yaw,
        })
    }

    fn graph_describes(&self, iri: &str) -> bool {
        self.graph
            .triples_for_subject(NamedNodeRef::new_unchecked(iri))
            .next()
            .is_some()
    }

    fn shape(&mut self, s: &str, required: bool) -> Option<Shape> {
        let shape = self.iri(s, v::HAS_SHAPE, required)?;
        let types = self.types(&shape);
        let kinds: Vec<NamedNodeRef<'static>> = [v::BOX_SHAPE, v::CYLINDER_SHAPE, v::SPHERE_SHAPE]
            .into_iter()
            .filter(|k| types.iter().any(|t| self.is_subclass(t, *k)))
            .collect();
        let kind = match kinds.as_slice() {
            [k] => *k,
            [] => {
                self.problem(
                    &shape,
                    rdf::TYPE,
                    "must be a tosm:BoxShape, tosm:CylinderShape or tosm:SphereShape",
                );
                return None;
            }
            _ => {
                self.problem(&shape, rdf::TYPE, "has more than one shape class");
                return None;
            }
        };
        let length = self.positive(&shape, v::LENGTH_M, true);
        let width = self.positive(&shape, v::WIDTH_M, true);
        let height = self.positive(&shape, v::HEIGHT_M, true);
        let (length, width, height) = (length?, width?, height?);
        if kind == v::BOX_SHAPE {
            return Some(Shape::Box {
                length,
                width,
                height,
            });
        }
        if (length - width).abs() > EXTENT_TOLERANCE {
            self.problem(
                &shape,
                v::WIDTH_M,
                format!("must equal lengthM ({length}) for a round shape, found {width}"),
            );
            return None;
        }
        if kind == v::CYLINDER_SHAPE {
            return Some(Shape::Cylinder {
                diameter: length,
                height,
            });
        }
        if (length - height).abs() > EXTENT_TOLERANCE {
            self.problem(
                &shape,
                v::HEIGHT_M,
                format!("must equal lengthM ({length}) for a sphere, found {height}"),
            );
            return None;
        }
        Some(Shape::Sphere { diameter: length })
    }

    fn colour(&mut self, s: &str) -> Option<Colour> {
        let r = self.unit_interval(s, v::COLOUR_RED, false);
        let g = self.unit_interval(s, v::COLOUR_GREEN, false);
        let b = self.unit_interval(s, v::COLOUR_BLUE, false);
        let a = self.unit_interval(s, v::COLOUR_ALPHA, false);
        match (r, g, b) {
            (Some(r), Some(g), Some(b)) => Some(Colour {
                r,
                g,
                b,
                a: a.unwrap_or(1.0),
            }),
            (None, None, None) => None,
            _ => {
                let mut missing = Vec::new();
                for (p, x) in [
                    (v::COLOUR_RED, r),
                    (v::COLOUR_GREEN, g),
                    (v::COLOUR_BLUE, b),
                ] {
                    if x.is_none() && self.objects(s, p).is_empty() {
                        missing.push(p);
                    }
                }
                for p in missing {
                    self.problem(s, p, "is missing: a colour needs red, green and blue");
                }
                None
            }
        }
    }

    fn physical(&mut self, s: &str, required: bool) -> Physical {
        let mass_kg = self.positive(s, v::MASS_KG, required);
        let material = self.iri(s, v::HAS_MATERIAL, required);
        if let Some(m) = &material {
            let known =
                self.has_type(m, v::MATERIAL) || v::ALL.iter().any(|(_, term)| term.as_str() == m);
            if !known {
                self.problem(
                    s,
                    v::HAS_MATERIAL,
                    format!("refers to <{m}>, which is not a tosm:Material"),
                );
            }
        }
        Physical {
            mass_kg,
            material,
            friction: self.non_negative(s, v::FRICTION_COEFFICIENT, false),
        }
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

    // ---- places ----------------------------------------------------------------------------

    fn place(&mut self, iri: &str) -> Option<Place> {
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

    fn boundary(&mut self, iri: &str, kind: PlaceKind) -> Vec<(f64, f64)> {
        let points = self.iris(iri, v::HAS_BOUNDARY_POINT);
        let mut indexed = BTreeMap::new();
        for point in points {
            let index = self.integer(&point, v::POINT_INDEX, true);
            let x = self.number(&point, v::X_M, true);
            let y = self.number(&point, v::Y_M, true);
            if let (Some(i), Some(x), Some(y)) = (index, x, y) {
                if i < 0 {
                    self.problem(&point, v::POINT_INDEX, format!("must be >= 0, found {i}"));
                } else if indexed.insert(i, (x, y)).is_some() {
                    self.problem(
                        &point,
                        v::POINT_INDEX,
                        format!("index {i} is used by two boundary points of <{iri}>"),
                    );
                }
            }
        }
        let polygon: Vec<(f64, f64)> = indexed.values().copied().collect();
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

    fn metric_map(&mut self, floor: &str, required: bool) -> Option<MetricMap> {
        let map = self.iri(floor, v::HAS_METRIC_MAP, required)?;
        let resolution = self.positive(&map, v::RESOLUTION_M, true);
        let ox = self.number(&map, v::ORIGIN_X_M, true);
        let oy = self.number(&map, v::ORIGIN_Y_M, true);
        let oyaw = self.number(&map, v::ORIGIN_YAW_RAD, false).unwrap_or(0.0);
        let occupied = self.unit_interval(&map, v::OCCUPIED_THRESHOLD, true);
        let free = self.unit_interval(&map, v::FREE_THRESHOLD, true);
        let negate = self.boolean(&map, v::NEGATE, false).unwrap_or(false);
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
            png,
            grid,
        })
    }

    fn base64(&mut self, s: &str, p: NamedNodeRef<'_>) -> Option<Vec<u8>> {
        let (value, _) = self.literal(s, p, true)?;
        let compact: String = value.chars().filter(|c| !c.is_ascii_whitespace()).collect();
        match base64::engine::general_purpose::STANDARD.decode(compact.as_bytes()) {
            Ok(bytes) => Some(bytes),
            Err(e) => {
                self.problem(s, p, format!("must be base64 (xsd:base64Binary): {e}"));
                None
            }
        }
    }

    // ---- objects ---------------------------------------------------------------------------

    fn object(&mut self, iri: &str) -> Option<Object> {
        let before = self.problems.len();
        let (class_iri, class) = self.object_class(iri);
        let symbol = self.symbol(iri);
        let pose = self.pose(iri, v::HAS_POSE, true);
        let shape = self.shape(iri, true);
        let colour = self.colour(iri);
        let colour_name = self.string(iri, v::COLOUR_NAME, false);
        let physical = self.physical(iri, false);
        let inside_of = self.iri(iri, v::IS_DIRECTLY_INSIDE_OF, true);
        if let Some(container) = &inside_of {
            self.check_reference(
                iri,
                v::IS_DIRECTLY_INSIDE_OF,
                container,
                v::ENTITY,
                "a place or an object",
            );
            if container == iri {
                self.problem(
                    iri,
                    v::IS_DIRECTLY_INSIDE_OF,
                    "an object cannot be inside itself",
                );
            }
        }
        let containers = self.container_chain(inside_of.as_deref());
        let mut relations = Vec::new();
        for (p, kind) in [
            (v::IS_IN_FRONT_OF, RelationKind::InFrontOf),
            (v::IS_NEXT_TO, RelationKind::NextTo),
            (v::IS_INSIDE_OF, RelationKind::InsideOf),
        ] {
            let mut targets = self.iris(iri, p);
            if kind == RelationKind::NextTo {
                targets = self.with_inverse(iri, p, targets);
            }
            for target in targets {
                if target == iri {
                    self.problem(iri, p, "an object cannot be related to itself");
                }
                self.check_open_reference(iri, p, &target, v::ENTITY, "a place or an object");
                // The direct container and its own containers are entailed as isInsideOf
                // too; keep them out of the list.
                if kind == RelationKind::InsideOf && containers.contains(&target) {
                    continue;
                }
                relations.push(Relation { kind, target });
            }
        }
        relations.sort();
        let is_open = self.boolean(iri, v::IS_OPEN, false);
        let reported_by = self.iri(iri, v::REPORTED_BY, false);
        let reported_at = self
            .literal(iri, v::REPORTED_AT, false)
            .and_then(|(value, dt)| {
                if dt == xsd::DATE_TIME.as_str() {
                    Some(value)
                } else {
                    self.problem(
                        iri,
                        v::REPORTED_AT,
                        format!("must be an xsd:dateTime, found {value:?} of type <{dt}>"),
                    );
                    None
                }
            });
        if self.problems.len() > before {
            return None;
        }
        Some(Object {
            iri: iri.to_owned(),
            class_iri,
            class,
            symbol,
            pose: pose?,
            shape: shape?,
            colour,
            colour_name,
            physical,
            inside_of: inside_of?,
            relations,
            is_open,
            reported_by,
            reported_at,
        })
    }

    /// The most specific object class of `iri` and the known class it falls under.
    fn object_class(&self, iri: &str) -> (String, ObjectClass) {
        let types: Vec<String> = self
            .types(iri)
            .into_iter()
            .filter(|t| self.is_subclass(t, v::OBJECT))
            .collect();
        // Most specific: a type that no other type is a subclass of.
        let specific = types
            .iter()
            .find(|t| {
                !types.iter().any(|other| {
                    other != *t && self.is_subclass(other, NamedNodeRef::new_unchecked(t))
                })
            })
            .cloned()
            .unwrap_or_else(|| v::OBJECT.as_str().to_owned());
        // A plain tosm:Object may also carry a class from another vocabulary that the graph
        // does not place under tosm:Object (a robot's own label): that class is the more
        // specific one.
        let specific = if specific == v::OBJECT.as_str() {
            self.types(iri)
                .into_iter()
                .find(|t| {
                    !t.starts_with(v::NS)
                        && !t.starts_with("http://www.w3.org/2002/07/owl#")
                        && !t.starts_with("http://www.w3.org/2000/01/rdf-schema#")
                })
                .unwrap_or(specific)
        } else {
            specific
        };
        let known = [
            (v::DOOR, ObjectClass::Door),
            (v::TABLE, ObjectClass::Table),
            (v::CHAIR, ObjectClass::Chair),
            (v::SHELF, ObjectClass::Shelf),
            (v::CABINET, ObjectClass::Cabinet),
            (v::SOFA, ObjectClass::Sofa),
            (v::BIN, ObjectClass::Bin),
            (v::VENDING_MACHINE, ObjectClass::VendingMachine),
        ];
        let class = known
            .iter()
            .find(|(c, _)| self.is_subclass(&specific, *c))
            .map_or(ObjectClass::Other, |(_, k)| *k);
        (specific, class)
    }

    // ---- robots ----------------------------------------------------------------------------

    fn robot(&mut self, iri: &str) -> Option<Robot> {
        let before = self.problems.len();
        let symbol = self.symbol(iri);
        let differential_drive = self.has_type(iri, v::DIFFERENTIAL_DRIVE_ROBOT);
        let max_linear_speed = self.positive(iri, v::MAX_LINEAR_SPEED_M_PER_S, false);
        let max_angular_speed = self.positive(iri, v::MAX_ANGULAR_SPEED_RAD_PER_S, false);
        let base = self.iri(iri, v::HAS_BASE_PART, true);
        let mut part_iris: BTreeSet<String> = BTreeSet::new();
        for p in [v::HAS_PART, v::HAS_SENSOR, v::HAS_BASE_PART] {
            part_iris.extend(self.iris(iri, p));
        }
        let mut robot = Robot {
            iri: iri.to_owned(),
            symbol,
            differential_drive,
            max_linear_speed,
            max_angular_speed,
            base: base.clone().unwrap_or_default(),
            structure: Vec::new(),
            wheels: Vec::new(),
            joints: Vec::new(),
            lasers: Vec::new(),
            cameras: Vec::new(),
        };
        for part in &part_iris {
            self.robot_part(iri, part, &mut robot);
        }
        if let Some(base) = &base {
            let is_structural = robot.structure.iter().any(|p| &p.part.iri == base)
                || robot.wheels.iter().any(|w| &w.part.iri == base);
            if !is_structural && self.problems.len() == before {
                self.problem(
                    iri,
                    v::HAS_BASE_PART,
                    format!("refers to <{base}>, which is not a structural part of this robot"),
                );
            }
        }
        for joint in &robot.joints {
            for (p, target) in [
                (v::HAS_PARENT_PART, &joint.parent),
                (v::HAS_CHILD_PART, &joint.child),
            ] {
                if !part_iris.contains(target) {
                    self.problem(
                        &joint.iri,
                        p,
                        format!("refers to <{target}>, which is not a part of robot <{iri}> (dangling reference)"),
                    );
                }
            }
            if joint.parent == joint.child {
                self.problem(
                    &joint.iri,
                    v::HAS_CHILD_PART,
                    "a joint must connect two different parts",
                );
            }
        }
        if self.problems.len() > before {
            return None;
        }
        Some(robot)
    }

    fn robot_part(&mut self, robot: &str, iri: &str, out: &mut Robot) {
        let types = self.types(iri);
        let is = |r: &Self, c: NamedNodeRef<'_>| types.iter().any(|t| r.is_subclass(t, c));
        if types.is_empty() && !self.graph_describes(iri) {
            self.problem(
                robot,
                v::HAS_PART,
                format!(
                    "refers to <{iri}>, which the graph does not describe (dangling reference)"
                ),
            );
            return;
        }
        if is(self, v::JOINT) {
            if let Some(j) =
                self.joint(iri, is(self, v::CONTINUOUS_JOINT), is(self, v::FIXED_JOINT))
            {
                out.joints.push(j);
            }
            return;
        }
        if is(self, v::WHEEL) {
            let active = is(self, v::ACTIVE_WHEEL);
            let passive = is(self, v::PASSIVE_WHEEL);
            if active == passive {
                self.problem(
                    iri,
                    rdf::TYPE,
                    "a wheel must be exactly one of tosm:ActiveWheel and tosm:PassiveWheel",
                );
            }
            let part = self.part(iri, true);
            let radius = self.positive(iri, v::WHEEL_RADIUS_M, true);
            let width = self.positive(iri, v::WHEEL_WIDTH_M, false);
            if let (Some(part), Some(radius)) = (part, radius) {
                out.wheels.push(Wheel {
                    part,
                    active,
                    caster: is(self, v::CASTER_WHEEL),
                    radius,
                    width,
                });
            }
            return;
        }
        if is(self, v::STRUCTURAL_PART) {
            if let Some(part) = self.part(iri, true) {
                out.structure.push(StructuralPart { part });
            }
            return;
        }
        if is(self, v::LASER_RANGE_FINDER) {
            let part = self.part(iri, false);
            let range_min = self.non_negative(iri, v::RANGE_MIN_M, true);
            let range_max = self.positive(iri, v::RANGE_MAX_M, true);
            let view_angle = self.positive(iri, v::VIEW_ANGLE_RAD, true);
            let samples = self.count(iri, v::SAMPLE_COUNT, true);
            let angular_resolution = self.positive(iri, v::ANGULAR_RESOLUTION_RAD, true);
            let rate_hz = self.positive(iri, v::FRAME_RATE_HZ, false);
            if let (Some(min), Some(max)) = (range_min, range_max)
                && min >= max
            {
                self.problem(
                    iri,
                    v::RANGE_MAX_M,
                    format!("must exceed rangeMinM ({min}), found {max}"),
                );
                return;
            }
            if let (
                Some(part),
                Some(range_min),
                Some(range_max),
                Some(view_angle),
                Some(samples),
                Some(angular_resolution),
            ) = (
                part,
                range_min,
                range_max,
                view_angle,
                samples,
                angular_resolution,
            ) {
                out.lasers.push(Laser {
                    part,
                    range_min,
                    range_max,
                    view_angle,
                    samples,
                    angular_resolution,
                    rate_hz,
                });
            }
            return;
        }
        if is(self, v::CAMERA) {
            let kind = if is(self, v::STEREO_CAMERA) {
                CameraKind::Stereo
            } else if is(self, v::RGBD_CAMERA) {
                CameraKind::RgbD
            } else {
                CameraKind::Mono
            };
            let part = self.part(iri, false);
            let width_px = self.count(iri, v::IMAGE_WIDTH_PX, true);
            let height_px = self.count(iri, v::IMAGE_HEIGHT_PX, true);
            let fps = self.positive(iri, v::FRAME_RATE_HZ, true);
            let horizontal_fov = self.positive(iri, v::HORIZONTAL_FOV_RAD, true);
            let vertical_fov = self.positive(iri, v::VERTICAL_FOV_RAD, false);
            let depth = kind != CameraKind::Mono;
            let range_min = self.non_negative(iri, v::RANGE_MIN_M, depth);
            let range_max = self.positive(iri, v::RANGE_MAX_M, depth);
            let depth_range = match (range_min, range_max) {
                (Some(min), Some(max)) if min >= max => {
                    self.problem(
                        iri,
                        v::RANGE_MAX_M,
                        format!("must exceed rangeMinM ({min}), found {max}"),
                    );
                    return;
                }
                (Some(min), Some(max)) => Some((min, max)),
                _ => None,
            };
            let baseline = self.positive(iri, v::BASELINE_M, false);
            if let (Some(part), Some(width_px), Some(height_px), Some(fps), Some(horizontal_fov)) =
                (part, width_px, height_px, fps, horizontal_fov)
            {
                out.cameras.push(Camera {
                    part,
                    kind,
                    width_px,
                    height_px,
                    fps,
                    horizontal_fov,
                    vertical_fov,
                    depth_range,
                    baseline,
                });
            }
            return;
        }
        self.problem(
            iri,
            rdf::TYPE,
            format!(
                "is a part of robot <{robot}> but not a structural part, wheel, joint, camera or laser range finder"
            ),
        );
    }

    fn part(&mut self, iri: &str, structural: bool) -> Option<Part> {
        let symbol = self.symbol(iri);
        let mounting = self.pose(iri, v::HAS_MOUNTING_POSE, false);
        let mounting = match mounting {
            Some(p) => Some(p),
            None if self.objects(iri, v::HAS_MOUNTING_POSE).is_empty() => {
                self.pose(iri, v::HAS_POSE, false).or_else(|| {
                    if self.objects(iri, v::HAS_POSE).is_empty() {
                        self.problem(iri, v::HAS_MOUNTING_POSE, "is missing (required)");
                    }
                    None
                })
            }
            None => None,
        };
        let shape = self.shape(iri, false);
        let colour = self.colour(iri);
        let physical = self.physical(iri, structural);
        Some(Part {
            iri: iri.to_owned(),
            symbol,
            mounting: mounting?,
            shape,
            colour,
            physical,
        })
    }

    fn joint(&mut self, iri: &str, continuous: bool, fixed: bool) -> Option<Joint> {
        let symbol = self.symbol(iri);
        let kind = match (continuous, fixed) {
            (true, false) => JointKind::Continuous,
            (false, true) => JointKind::Fixed,
            _ => {
                self.problem(
                    iri,
                    rdf::TYPE,
                    "a joint must be exactly one of tosm:FixedJoint and tosm:ContinuousJoint",
                );
                return None;
            }
        };
        let parent = self.iri(iri, v::HAS_PARENT_PART, true);
        let child = self.iri(iri, v::HAS_CHILD_PART, true);
        let ax = self.number(iri, v::AXIS_X, false);
        let ay = self.number(iri, v::AXIS_Y, false);
        let az = self.number(iri, v::AXIS_Z, false);
        let axis = match (ax, ay, az) {
            (None, None, None) => [0.0, 1.0, 0.0],
            (x, y, z) => [x.unwrap_or(0.0), y.unwrap_or(0.0), z.unwrap_or(0.0)],
        };
        if axis.iter().all(|c| *c == 0.0) {
            self.problem(iri, v::AXIS_Y, "a joint axis cannot be the zero vector");
        }
        Some(Joint {
            iri: iri.to_owned(),
            symbol,
            kind,
            parent: parent?,
            child: child?,
            axis,
        })
    }
}
