//! Writing typed places, objects, robots and people knowledge as RDF triples, after validating them.
//!
//! Descriptors get IRIs derived from their owner (`<owner>/pose`, `<owner>/shape`,
//! `<place>/boundary/<i>`, `<floor>/map`), never blank nodes, so that two writes of the same
//! value produce the same triples and merge. Real numbers are written as `xsd:decimal`, counts
//! as `xsd:integer`, the map image as `xsd:base64Binary`, matching the ontology's ranges.

use base64::Engine as _;
use oxrdf::vocab::{rdf, xsd};
use oxrdf::{Literal, NamedNode, NamedNodeRef, Term, Triple};

use crate::model::{
    Attractor, Camera, CameraKind, Colour, Joint, JointKind, MetricMap, Object, ObjectClass, Part,
    PeopleEstimate, Physical, Place, PlaceKind, PlacePeople, Pose3, Relation, RelationKind, Robot,
    Shape, Symbol, WalkingRoute, Wheel,
};
use crate::occupancy::OccupancyGrid;
use crate::problems::{Problem, Problems};
use crate::vocab as v;

const OWL_NAMED_INDIVIDUAL: NamedNodeRef<'static> =
    NamedNodeRef::new_unchecked("http://www.w3.org/2002/07/owl#NamedIndividual");

/// The triples describing `place` (with its boundary points and metric map).
pub fn place_to_triples(place: &Place) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    w.place(place);
    w.finish()
}

/// The triples describing `object` (with its pose and shape).
pub fn object_to_triples(object: &Object) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    w.object(object);
    w.finish()
}

/// The triples describing `robot` and all its parts.
pub fn robot_to_triples(robot: &Robot) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    w.robot(robot);
    w.finish()
}

/// The triples of what is known about people in a place: the engineer's expected numbers
/// (`tosm:expectedPeople` on the place, `<place>/people/hour/<h>` by hour) and robots'
/// estimates (as [`people_estimate_to_triples`]). The place itself is not described.
pub fn place_people_to_triples(people: &PlacePeople) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    w.place_people(people);
    w.finish()
}

/// The triples of one people estimate of `place`: `<place> tosm:hasPeopleEstimate <e>` and
/// the estimate `<e>` ([`PeopleEstimate::iri_for`]).
pub fn people_estimate_to_triples(
    place: &str,
    estimate: &PeopleEstimate,
) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    if let Some(s) = w.node(place, place, v::HAS_PEOPLE_ESTIMATE) {
        w.estimate(&s, estimate);
    }
    w.finish()
}

/// The triples describing a walking route (with its points `<route>/point/<i>`).
pub fn walking_route_to_triples(route: &WalkingRoute) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    w.walking_route(route);
    w.finish()
}

/// The triples describing an attractor (with its pose).
pub fn attractor_to_triples(attractor: &Attractor) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    w.attractor(attractor);
    w.finish()
}

/// The triples of a floor's metric map, `<floor_iri> tosm:hasMetricMap <floor_iri/map>` included.
pub fn metric_map_to_triples(floor_iri: &str, map: &MetricMap) -> Result<Vec<Triple>, Problems> {
    let mut w = Writer::default();
    if let Some(floor) = w.node(floor_iri, floor_iri, v::HAS_METRIC_MAP) {
        w.metric_map(&floor, map);
    }
    w.finish()
}

/// The triples of a floor's metric map made of `grid`, whose PNG form is `image_png`.
///
/// `image_png` must follow [`OccupancyGrid::to_png`]'s convention (free 254, occupied 0,
/// unknown 205): the map is stored with the thresholds under which such an image decodes back
/// to `grid`. Pass `grid.to_png()` unless that PNG is already at hand.
pub fn occupancy_grid_to_triples(
    floor_iri: &str,
    grid: &OccupancyGrid,
    image_png: &[u8],
) -> Result<Vec<Triple>, Problems> {
    let map = MetricMap {
        iri: MetricMap::iri_for_floor(floor_iri),
        resolution: grid.resolution,
        origin: grid.origin,
        occupied_thresh: crate::occupancy::CANONICAL_OCCUPIED_THRESH,
        free_thresh: crate::occupancy::CANONICAL_FREE_THRESH,
        negate: false,
        frame_id: crate::model::DEFAULT_MAP_FRAME.to_owned(),
        png: image_png.to_vec(),
        grid: grid.clone(),
    };
    metric_map_to_triples(floor_iri, &map)
}

#[derive(Default)]
struct Writer {
    triples: Vec<Triple>,
    problems: Vec<Problem>,
}

impl Writer {
    fn finish(mut self) -> Result<Vec<Triple>, Problems> {
        self.triples.sort_by_cached_key(ToString::to_string);
        self.triples.dedup();
        Problems(self.problems).into_result(self.triples)
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

    /// A named node for `iri`, or a problem on `owner`'s `property` when it is not an IRI.
    fn node(&mut self, iri: &str, owner: &str, property: NamedNodeRef<'_>) -> Option<NamedNode> {
        match NamedNode::new(iri) {
            Ok(n) => Some(n),
            Err(e) => {
                self.problem(owner, property, format!("<{iri}> is not a valid IRI: {e}"));
                None
            }
        }
    }

    fn add(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, o: impl Into<Term>) {
        self.triples
            .push(Triple::new(s.clone(), p.into_owned(), o.into()));
    }

    fn typed(&mut self, s: &NamedNode, class: NamedNodeRef<'_>) {
        self.add(s, rdf::TYPE, class.into_owned());
        self.add(s, rdf::TYPE, OWL_NAMED_INDIVIDUAL.into_owned());
    }

    fn link(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, target: &str) {
        if let Some(t) = self.node(target, s.as_str(), p) {
            self.add(s, p, t);
        }
    }

    /// A decimal, if finite and accepted by `ok` (described by `range` otherwise).
    fn number(
        &mut self,
        s: &NamedNode,
        p: NamedNodeRef<'_>,
        x: f64,
        ok: fn(f64) -> bool,
        range: &str,
    ) {
        if x.is_finite() && ok(x) {
            self.add(s, p, decimal(x));
        } else {
            self.problem(s.as_str(), p, format!("must be {range}, found {x}"));
        }
    }

    fn any(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, x: f64) {
        self.number(s, p, x, |_| true, "a finite number");
    }

    fn positive(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, x: f64) {
        self.number(s, p, x, |x| x > 0.0, "a finite number > 0");
    }

    fn non_negative(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, x: f64) {
        self.number(s, p, x, |x| x >= 0.0, "a finite number >= 0");
    }

    fn unit(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, x: f64) {
        self.number(s, p, x, |x| (0.0..=1.0).contains(&x), "in [0, 1]");
    }

    fn integer(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, n: i64) {
        self.add(
            s,
            p,
            Literal::new_typed_literal(n.to_string(), xsd::INTEGER),
        );
    }

    fn string(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, text: &str) {
        self.add(s, p, Literal::new_simple_literal(text));
    }

    fn boolean(&mut self, s: &NamedNode, p: NamedNodeRef<'_>, b: bool) {
        self.add(
            s,
            p,
            Literal::new_typed_literal(b.to_string(), xsd::BOOLEAN),
        );
    }

    fn symbol(&mut self, s: &NamedNode, symbol: &Symbol) {
        if symbol.name.trim().is_empty() {
            self.problem(
                s.as_str(),
                v::NAME,
                "is missing (required): the name is empty",
            );
        } else {
            self.string(s, v::NAME, &symbol.name);
        }
        if let Some(id) = &symbol.identifier {
            self.string(s, v::IDENTIFIER, id);
        }
        if let Some(d) = &symbol.description {
            self.string(s, v::DESCRIPTION, d);
        }
    }

    fn pose(&mut self, owner: &NamedNode, p: NamedNodeRef<'_>, pose: &Pose3) {
        let Some(node) = self.node(&format!("{}/pose", owner.as_str()), owner.as_str(), p) else {
            return;
        };
        self.add(owner, p, node.clone());
        self.typed(&node, v::POSE);
        self.any(&node, v::X_M, pose.x);
        self.any(&node, v::Y_M, pose.y);
        self.any(&node, v::Z_M, pose.z);
        self.any(&node, v::ROLL_RAD, pose.roll);
        self.any(&node, v::PITCH_RAD, pose.pitch);
        self.any(&node, v::YAW_RAD, pose.yaw);
    }

    fn shape(&mut self, owner: &NamedNode, shape: &Shape) {
        let Some(node) = self.node(
            &format!("{}/shape", owner.as_str()),
            owner.as_str(),
            v::HAS_SHAPE,
        ) else {
            return;
        };
        self.add(owner, v::HAS_SHAPE, node.clone());
        let class = match shape {
            Shape::Box { .. } => v::BOX_SHAPE,
            Shape::Cylinder { .. } => v::CYLINDER_SHAPE,
            Shape::Sphere { .. } => v::SPHERE_SHAPE,
        };
        self.typed(&node, class);
        let [l, w, h] = shape.size();
        self.positive(&node, v::LENGTH_M, l);
        self.positive(&node, v::WIDTH_M, w);
        self.positive(&node, v::HEIGHT_M, h);
    }

    fn colour(&mut self, s: &NamedNode, c: &Colour) {
        self.unit(s, v::COLOUR_RED, c.r);
        self.unit(s, v::COLOUR_GREEN, c.g);
        self.unit(s, v::COLOUR_BLUE, c.b);
        self.unit(s, v::COLOUR_ALPHA, c.a);
    }

    fn physical(&mut self, s: &NamedNode, p: &Physical) {
        if let Some(m) = p.mass_kg {
            self.positive(s, v::MASS_KG, m);
        }
        if let Some(m) = &p.material {
            self.link(s, v::HAS_MATERIAL, m);
        }
        if let Some(f) = p.friction {
            self.non_negative(s, v::FRICTION_COEFFICIENT, f);
        }
    }

    fn place(&mut self, place: &Place) {
        let Some(s) = self.node(&place.iri, &place.iri, rdf::TYPE) else {
            return;
        };
        let class = match place.kind {
            PlaceKind::Building => v::BUILDING,
            PlaceKind::Floor => v::FLOOR,
            PlaceKind::Corridor => v::CORRIDOR,
            PlaceKind::Room => v::ROOM,
            PlaceKind::Hall => v::HALL,
            PlaceKind::Other => v::PLACE,
        };
        self.typed(&s, class);
        self.symbol(&s, &place.symbol);
        if !place.boundary.is_empty() && place.boundary.len() < 3 {
            self.problem(
                &place.iri,
                v::HAS_BOUNDARY_POINT,
                format!(
                    "a boundary polygon needs at least 3 points, found {}",
                    place.boundary.len()
                ),
            );
        }
        if place.boundary.is_empty()
            && matches!(
                place.kind,
                PlaceKind::Corridor | PlaceKind::Room | PlaceKind::Hall
            )
        {
            self.problem(&place.iri, v::HAS_BOUNDARY_POINT, "is missing (required)");
        }
        for (i, (x, y)) in place.boundary.iter().enumerate() {
            let iri = format!("{}/boundary/{i}", place.iri);
            let Some(point) = self.node(&iri, &place.iri, v::HAS_BOUNDARY_POINT) else {
                continue;
            };
            self.add(&s, v::HAS_BOUNDARY_POINT, point.clone());
            self.typed(&point, v::BOUNDARY_POINT);
            self.integer(&point, v::POINT_INDEX, i64::try_from(i).unwrap_or(i64::MAX));
            self.any(&point, v::X_M, *x);
            self.any(&point, v::Y_M, *y);
        }
        if let Some(parent) = &place.parent {
            self.link(&s, v::IS_DIRECTLY_INSIDE_OF, parent);
        }
        for c in &place.connected {
            if c == &place.iri {
                self.problem(
                    &place.iri,
                    v::IS_CONNECTED_TO,
                    "a place cannot be connected to itself",
                );
            } else {
                self.link(&s, v::IS_CONNECTED_TO, c);
            }
        }
        if let Some(c) = place.complexity {
            self.unit(&s, v::COMPLEXITY, c);
        }
        if let Some(level) = place.level {
            self.integer(&s, v::FLOOR_LEVEL, level);
        }
        match &place.map {
            Some(map) => self.metric_map(&s, map),
            None if place.kind == PlaceKind::Floor => {
                self.problem(
                    &place.iri,
                    v::HAS_METRIC_MAP,
                    "is missing (required for a floor)",
                );
            }
            None => {}
        }
    }

    fn metric_map(&mut self, floor: &NamedNode, map: &MetricMap) {
        let Some(m) = self.node(&map.iri, floor.as_str(), v::HAS_METRIC_MAP) else {
            return;
        };
        self.add(floor, v::HAS_METRIC_MAP, m.clone());
        self.typed(&m, v::OCCUPANCY_GRID_MAP);
        self.positive(&m, v::RESOLUTION_M, map.resolution);
        self.any(&m, v::ORIGIN_X_M, map.origin.x);
        self.any(&m, v::ORIGIN_Y_M, map.origin.y);
        self.any(&m, v::ORIGIN_YAW_RAD, map.origin.yaw);
        self.unit(&m, v::OCCUPIED_THRESHOLD, map.occupied_thresh);
        self.unit(&m, v::FREE_THRESHOLD, map.free_thresh);
        if map.free_thresh >= map.occupied_thresh {
            self.problem(
                &map.iri,
                v::FREE_THRESHOLD,
                format!(
                    "must be below the occupied threshold ({}), found {}",
                    map.occupied_thresh, map.free_thresh
                ),
            );
        }
        self.boolean(&m, v::NEGATE, map.negate);
        if !crate::model::is_ros_frame_name(&map.frame_id) {
            self.problem(
                &map.iri,
                v::FRAME_ID,
                format!(
                    "must be a ROS frame name (letters, digits, _ and /, not starting with a digit or /), found {:?}",
                    map.frame_id
                ),
            );
        }
        self.string(&m, v::FRAME_ID, &map.frame_id);
        let (w, h) = (map.grid.width, map.grid.height);
        if w == 0 || h == 0 || map.grid.cells.len() != w.saturating_mul(h) {
            self.problem(
                &map.iri,
                v::WIDTH_CELLS,
                format!(
                    "the grid must be non-empty with width x height cells, found {w}x{h} and {} cells",
                    map.grid.cells.len()
                ),
            );
        }
        self.integer(&m, v::WIDTH_CELLS, i64::try_from(w).unwrap_or(i64::MAX));
        self.integer(&m, v::HEIGHT_CELLS, i64::try_from(h).unwrap_or(i64::MAX));
        if map.png.is_empty() {
            self.problem(
                &map.iri,
                v::MAP_IMAGE_PNG,
                "is missing (required): the PNG is empty",
            );
        }
        let b64 = base64::engine::general_purpose::STANDARD.encode(&map.png);
        self.add(
            &m,
            v::MAP_IMAGE_PNG,
            Literal::new_typed_literal(b64, xsd::BASE_64_BINARY),
        );
    }

    fn object(&mut self, o: &Object) {
        let Some(s) = self.node(&o.iri, &o.iri, rdf::TYPE) else {
            return;
        };
        let class = match o.class {
            ObjectClass::Door => v::DOOR.as_str(),
            ObjectClass::Table => v::TABLE.as_str(),
            ObjectClass::Chair => v::CHAIR.as_str(),
            ObjectClass::Shelf => v::SHELF.as_str(),
            ObjectClass::Cabinet => v::CABINET.as_str(),
            ObjectClass::Sofa => v::SOFA.as_str(),
            ObjectClass::Bin => v::BIN.as_str(),
            ObjectClass::VendingMachine => v::VENDING_MACHINE.as_str(),
            ObjectClass::Other => o.class_iri.as_str(),
        };
        if let Some(c) = self.node(class, &o.iri, rdf::TYPE) {
            self.add(&s, rdf::TYPE, c);
        }
        if o.class == ObjectClass::Other && o.class_iri != v::OBJECT.as_str() {
            // A class from elsewhere: state tosm:Object too, so readers without the class's
            // axioms still find the object.
            self.add(&s, rdf::TYPE, v::OBJECT.into_owned());
        }
        self.add(&s, rdf::TYPE, OWL_NAMED_INDIVIDUAL.into_owned());
        self.symbol(&s, &o.symbol);
        self.pose(&s, v::HAS_POSE, &o.pose);
        self.shape(&s, &o.shape);
        if let Some(c) = &o.colour {
            self.colour(&s, c);
        }
        if let Some(name) = &o.colour_name {
            self.string(&s, v::COLOUR_NAME, name);
        }
        self.physical(&s, &o.physical);
        if o.inside_of == o.iri {
            self.problem(
                &o.iri,
                v::IS_DIRECTLY_INSIDE_OF,
                "an object cannot be inside itself",
            );
        }
        self.link(&s, v::IS_DIRECTLY_INSIDE_OF, &o.inside_of);
        for Relation { kind, target } in &o.relations {
            let p = match kind {
                RelationKind::InFrontOf => v::IS_IN_FRONT_OF,
                RelationKind::NextTo => v::IS_NEXT_TO,
                RelationKind::InsideOf => v::IS_INSIDE_OF,
            };
            if target == &o.iri {
                self.problem(&o.iri, p, "an object cannot be related to itself");
            } else {
                self.link(&s, p, target);
            }
        }
        if let Some(open) = o.is_open {
            self.boolean(&s, v::IS_OPEN, open);
        }
        if let Some(robot) = &o.reported_by {
            self.link(&s, v::REPORTED_BY, robot);
        }
        if let Some(at) = &o.reported_at {
            self.add(
                &s,
                v::REPORTED_AT,
                Literal::new_typed_literal(at.clone(), xsd::DATE_TIME),
            );
        }
    }

    fn hour(&mut self, s: &NamedNode, hour: u8) {
        if hour <= 23 {
            self.integer(s, v::HOUR_OF_DAY, i64::from(hour));
        } else {
            self.problem(
                s.as_str(),
                v::HOUR_OF_DAY,
                format!("must be an hour of the day, 0 to 23, found {hour}"),
            );
        }
    }

    fn place_people(&mut self, people: &PlacePeople) {
        let Some(s) = self.node(&people.place, &people.place, v::EXPECTED_PEOPLE) else {
            return;
        };
        if let Some(n) = people.expected {
            self.non_negative(&s, v::EXPECTED_PEOPLE, n);
        }
        let mut hours = std::collections::BTreeSet::new();
        for &(hour, n) in &people.by_hour {
            if !hours.insert(hour) {
                self.problem(
                    &people.place,
                    v::HAS_HOURLY_PEOPLE_COUNT,
                    format!("two hourly people counts are for hour {hour}"),
                );
            }
            let Some(h) = self.node(
                &PlacePeople::hour_iri(&people.place, hour),
                &people.place,
                v::HAS_HOURLY_PEOPLE_COUNT,
            ) else {
                continue;
            };
            self.add(&s, v::HAS_HOURLY_PEOPLE_COUNT, h.clone());
            self.typed(&h, v::HOURLY_PEOPLE_COUNT);
            self.hour(&h, hour);
            self.non_negative(&h, v::EXPECTED_PEOPLE, n);
        }
        let mut estimated = std::collections::BTreeSet::new();
        for e in &people.estimates {
            if !estimated.insert(e.hour) {
                self.problem(
                    &people.place,
                    v::HAS_PEOPLE_ESTIMATE,
                    "two people estimates are for the same hours",
                );
            }
            self.estimate(&s, e);
        }
    }

    fn estimate(&mut self, place: &NamedNode, e: &PeopleEstimate) {
        let Some(node) = self.node(
            &PeopleEstimate::iri_for(place.as_str(), e.hour),
            place.as_str(),
            v::HAS_PEOPLE_ESTIMATE,
        ) else {
            return;
        };
        self.add(place, v::HAS_PEOPLE_ESTIMATE, node.clone());
        self.typed(&node, v::PEOPLE_ESTIMATE);
        if let Some(hour) = e.hour {
            self.hour(&node, hour);
        }
        self.non_negative(&node, v::ESTIMATED_PEOPLE, e.people);
        if e.observations == 0 {
            self.problem(
                node.as_str(),
                v::OBSERVATION_COUNT,
                "must be a whole number >= 1, found 0",
            );
        }
        self.integer(
            &node,
            v::OBSERVATION_COUNT,
            i64::try_from(e.observations).unwrap_or(i64::MAX),
        );
        if let Some(at) = &e.last_observed_at {
            self.add(
                &node,
                v::LAST_OBSERVED_AT,
                Literal::new_typed_literal(at.clone(), xsd::DATE_TIME),
            );
        }
    }

    fn optional_name(&mut self, s: &NamedNode, name: Option<&str>) {
        match name {
            Some(n) if n.trim().is_empty() => {
                self.problem(s.as_str(), v::NAME, "must not be blank when given");
            }
            Some(n) => self.string(s, v::NAME, n),
            None => {}
        }
    }

    fn walking_route(&mut self, route: &WalkingRoute) {
        let Some(s) = self.node(&route.iri, &route.iri, rdf::TYPE) else {
            return;
        };
        self.typed(&s, v::WALKING_ROUTE);
        self.optional_name(&s, route.name.as_deref());
        self.link(&s, v::IS_DIRECTLY_INSIDE_OF, &route.inside_of);
        if route.points.len() < 2 {
            self.problem(
                &route.iri,
                v::HAS_ROUTE_POINT,
                format!(
                    "a walking route needs at least 2 points, found {}",
                    route.points.len()
                ),
            );
        }
        for (i, (x, y)) in route.points.iter().enumerate() {
            let iri = format!("{}/point/{i}", route.iri);
            let Some(point) = self.node(&iri, &route.iri, v::HAS_ROUTE_POINT) else {
                continue;
            };
            self.add(&s, v::HAS_ROUTE_POINT, point.clone());
            self.typed(&point, v::ROUTE_POINT);
            self.integer(&point, v::POINT_INDEX, i64::try_from(i).unwrap_or(i64::MAX));
            self.any(&point, v::X_M, *x);
            self.any(&point, v::Y_M, *y);
        }
    }

    fn attractor(&mut self, a: &Attractor) {
        let Some(s) = self.node(&a.iri, &a.iri, rdf::TYPE) else {
            return;
        };
        self.typed(&s, v::ATTRACTOR);
        self.optional_name(&s, a.name.as_deref());
        self.link(&s, v::IS_DIRECTLY_INSIDE_OF, &a.inside_of);
        self.pose(&s, v::HAS_POSE, &a.pose);
        self.non_negative(&s, v::DWELL_TIME_S, a.dwell_s);
        for Relation { kind, target } in &a.relations {
            let p = match kind {
                RelationKind::InFrontOf => v::IS_IN_FRONT_OF,
                RelationKind::NextTo => v::IS_NEXT_TO,
                RelationKind::InsideOf => {
                    self.problem(
                        &a.iri,
                        v::IS_INSIDE_OF,
                        "an attractor's place is its inside_of; other relations are isInFrontOf and isNextTo",
                    );
                    continue;
                }
            };
            if target == &a.iri {
                self.problem(&a.iri, p, "an attractor cannot be related to itself");
            } else {
                self.link(&s, p, target);
            }
        }
    }

    fn part(
        &mut self,
        robot: &NamedNode,
        part: &Part,
        class: NamedNodeRef<'_>,
        via: NamedNodeRef<'_>,
    ) -> Option<NamedNode> {
        let s = self.node(&part.iri, robot.as_str(), via)?;
        self.add(robot, via, s.clone());
        self.typed(&s, class);
        self.symbol(&s, &part.symbol);
        self.pose(&s, v::HAS_MOUNTING_POSE, &part.mounting);
        if let Some(shape) = &part.shape {
            self.shape(&s, shape);
        }
        if let Some(c) = &part.colour {
            self.colour(&s, c);
        }
        self.physical(&s, &part.physical);
        Some(s)
    }

    fn structural_requirements(&mut self, part: &Part) {
        if part.physical.mass_kg.is_none() {
            self.problem(
                &part.iri,
                v::MASS_KG,
                "is missing (required for a structural part)",
            );
        }
        if part.physical.material.is_none() {
            self.problem(
                &part.iri,
                v::HAS_MATERIAL,
                "is missing (required for a structural part)",
            );
        }
    }

    fn robot(&mut self, r: &Robot) {
        let Some(s) = self.node(&r.iri, &r.iri, rdf::TYPE) else {
            return;
        };
        self.typed(
            &s,
            if r.differential_drive {
                v::DIFFERENTIAL_DRIVE_ROBOT
            } else {
                v::ROBOT
            },
        );
        self.symbol(&s, &r.symbol);
        if let Some(x) = r.max_linear_speed {
            self.positive(&s, v::MAX_LINEAR_SPEED_M_PER_S, x);
        }
        if let Some(x) = r.max_angular_speed {
            self.positive(&s, v::MAX_ANGULAR_SPEED_RAD_PER_S, x);
        }
        let d = r.dynamics;
        for (property, x) in [
            (
                v::MAX_LINEAR_ACCELERATION_M_PER_S2,
                d.max_linear_acceleration,
            ),
            (
                v::MAX_LINEAR_DECELERATION_M_PER_S2,
                d.max_linear_deceleration,
            ),
            (
                v::MAX_ANGULAR_ACCELERATION_RAD_PER_S2,
                d.max_angular_acceleration,
            ),
            (
                v::MAX_ANGULAR_DECELERATION_RAD_PER_S2,
                d.max_angular_deceleration,
            ),
            (v::CONTROL_LATENCY_S, d.control_latency),
        ] {
            if let Some(x) = x {
                self.positive(&s, property, x);
            }
        }
        let base_known = r.structure.iter().any(|p| p.part.iri == r.base)
            || r.wheels.iter().any(|w| w.part.iri == r.base);
        if !base_known {
            self.problem(
                &r.iri,
                v::HAS_BASE_PART,
                format!(
                    "refers to <{}>, which is not a structural part of this robot",
                    r.base
                ),
            );
        }
        self.link(&s, v::HAS_BASE_PART, &r.base);
        for p in &r.structure {
            self.structural_requirements(&p.part);
            self.part(&s, &p.part, v::STRUCTURAL_PART, v::HAS_PART);
        }
        for w in &r.wheels {
            self.wheel(&s, w);
        }
        for j in &r.joints {
            self.joint(&s, r, j);
        }
        for l in &r.lasers {
            let Some(n) = self.part(&s, &l.part, v::LASER_RANGE_FINDER, v::HAS_SENSOR) else {
                continue;
            };
            self.non_negative(&n, v::RANGE_MIN_M, l.range_min);
            self.positive(&n, v::RANGE_MAX_M, l.range_max);
            if l.range_min >= l.range_max {
                self.problem(
                    &l.part.iri,
                    v::RANGE_MAX_M,
                    format!(
                        "must exceed rangeMinM ({}), found {}",
                        l.range_min, l.range_max
                    ),
                );
            }
            self.positive(&n, v::VIEW_ANGLE_RAD, l.view_angle);
            if l.samples == 0 {
                self.problem(
                    &l.part.iri,
                    v::SAMPLE_COUNT,
                    "must be a whole number >= 1, found 0",
                );
            }
            self.integer(&n, v::SAMPLE_COUNT, i64::from(l.samples));
            self.positive(&n, v::ANGULAR_RESOLUTION_RAD, l.angular_resolution);
            if let Some(hz) = l.rate_hz {
                self.positive(&n, v::FRAME_RATE_HZ, hz);
            }
        }
        for c in &r.cameras {
            self.camera(&s, c);
        }
    }

    fn wheel(&mut self, robot: &NamedNode, w: &Wheel) {
        let class = match (w.active, w.caster) {
            (true, false) => v::ACTIVE_WHEEL,
            (false, true) => v::CASTER_WHEEL,
            (false, false) => v::PASSIVE_WHEEL,
            (true, true) => {
                self.problem(&w.part.iri, rdf::TYPE, "a caster wheel cannot be active");
                return;
            }
        };
        self.structural_requirements(&w.part);
        let Some(n) = self.part(robot, &w.part, class, v::HAS_PART) else {
            return;
        };
        self.positive(&n, v::WHEEL_RADIUS_M, w.radius);
        if let Some(width) = w.width {
            self.positive(&n, v::WHEEL_WIDTH_M, width);
        }
    }

    fn joint(&mut self, robot: &NamedNode, r: &Robot, j: &Joint) {
        let Some(n) = self.node(&j.iri, robot.as_str(), v::HAS_PART) else {
            return;
        };
        self.add(robot, v::HAS_PART, n.clone());
        self.typed(
            &n,
            match j.kind {
                JointKind::Fixed => v::FIXED_JOINT,
                JointKind::Continuous => v::CONTINUOUS_JOINT,
            },
        );
        self.symbol(&n, &j.symbol);
        for (p, target) in [
            (v::HAS_PARENT_PART, &j.parent),
            (v::HAS_CHILD_PART, &j.child),
        ] {
            if !r.parts().any(|part| &part.iri == target) {
                self.problem(
                    &j.iri,
                    p,
                    format!("refers to <{target}>, which is not a part of robot <{}> (dangling reference)", r.iri),
                );
            }
            self.link(&n, p, target);
        }
        if j.parent == j.child {
            self.problem(
                &j.iri,
                v::HAS_CHILD_PART,
                "a joint must connect two different parts",
            );
        }
        if j.axis.iter().all(|c| *c == 0.0) {
            self.problem(&j.iri, v::AXIS_Y, "a joint axis cannot be the zero vector");
        }
        self.any(&n, v::AXIS_X, j.axis[0]);
        self.any(&n, v::AXIS_Y, j.axis[1]);
        self.any(&n, v::AXIS_Z, j.axis[2]);
    }

    fn camera(&mut self, robot: &NamedNode, c: &Camera) {
        let class = match c.kind {
            CameraKind::Mono => v::CAMERA,
            CameraKind::Stereo => v::STEREO_CAMERA,
            CameraKind::RgbD => v::RGBD_CAMERA,
        };
        let Some(n) = self.part(robot, &c.part, class, v::HAS_SENSOR) else {
            return;
        };
        for (p, px) in [
            (v::IMAGE_WIDTH_PX, c.width_px),
            (v::IMAGE_HEIGHT_PX, c.height_px),
        ] {
            if px == 0 {
                self.problem(&c.part.iri, p, "must be a whole number >= 1, found 0");
            }
            self.integer(&n, p, i64::from(px));
        }
        self.positive(&n, v::FRAME_RATE_HZ, c.fps);
        self.positive(&n, v::HORIZONTAL_FOV_RAD, c.horizontal_fov);
        if let Some(f) = c.vertical_fov {
            self.positive(&n, v::VERTICAL_FOV_RAD, f);
        }
        match c.depth_range {
            Some((min, max)) => {
                self.non_negative(&n, v::RANGE_MIN_M, min);
                self.positive(&n, v::RANGE_MAX_M, max);
                if min >= max {
                    self.problem(
                        &c.part.iri,
                        v::RANGE_MAX_M,
                        format!("must exceed rangeMinM ({min}), found {max}"),
                    );
                }
            }
            None if c.kind != CameraKind::Mono => {
                self.problem(
                    &c.part.iri,
                    v::RANGE_MIN_M,
                    "is missing (required for a depth camera)",
                );
            }
            None => {}
        }
        if let Some(b) = c.baseline {
            self.positive(&n, v::BASELINE_M, b);
        }
    }
}

/// An `xsd:decimal` literal for a finite number (Rust's `Display` never uses an exponent and
/// round-trips exactly through `str::parse`).
fn decimal(x: f64) -> Literal {
    Literal::new_typed_literal(format!("{x}"), xsd::DECIMAL)
}
