//! People: what a place's implicit model says about them (an engineer's expected numbers, all
//! day and by hour, and robots' running estimates), walking routes and attractors.

use std::collections::{BTreeMap, BTreeSet};

use oxrdf::vocab::xsd;
use oxrdf::{NamedNodeRef, NamedOrBlankNodeRef};

use super::Reader;
use crate::model::{Attractor, PeopleEstimate, PlacePeople, Relation, RelationKind, WalkingRoute};
use crate::vocab as v;

impl<'g> Reader<'g> {
    /// Every subject stating one of the place-level people properties, sorted.
    pub(super) fn people_subjects(&mut self) -> Vec<String> {
        let mut hourly: BTreeSet<String> = BTreeSet::new();
        for t in self.graph.triples_for_predicate(v::HAS_HOURLY_PEOPLE_COUNT) {
            if let oxrdf::TermRef::NamedNode(n) = t.object {
                hourly.insert(n.as_str().to_owned());
            }
        }
        let mut subjects = BTreeSet::new();
        for p in [
            v::EXPECTED_PEOPLE,
            v::HAS_HOURLY_PEOPLE_COUNT,
            v::HAS_PEOPLE_ESTIMATE,
        ] {
            for t in self.graph.triples_for_predicate(p) {
                match t.subject {
                    NamedOrBlankNodeRef::NamedNode(n) => {
                        let s = n.as_str();
                        // An hourly figure states expectedPeople too: it is read with its place.
                        if !(p == v::EXPECTED_PEOPLE
                            && (hourly.contains(s) || self.has_type(s, v::HOURLY_PEOPLE_COUNT)))
                        {
                            subjects.insert(s.to_owned());
                        }
                    }
                    NamedOrBlankNodeRef::BlankNode(b) => {
                        self.problem(
                            &format!("_:{}", b.as_str()),
                            p,
                            "is a blank node; TOSM individuals need an IRI so that downloads merge",
                        );
                    }
                }
            }
        }
        subjects.into_iter().collect()
    }

    /// What `iri` (which states people properties) says about people; `None` with problems
    /// when it is not a place or a value is wrong.
    pub(super) fn place_people(&mut self, iri: &str) -> Option<PlacePeople> {
        let before = self.problems.len();
        if !self.has_type(iri, v::PLACE) {
            let property = [
                v::EXPECTED_PEOPLE,
                v::HAS_HOURLY_PEOPLE_COUNT,
                v::HAS_PEOPLE_ESTIMATE,
            ]
            .into_iter()
            .find(|p| !self.objects(iri, *p).is_empty())
            .unwrap_or(v::EXPECTED_PEOPLE);
            self.problem(
                iri,
                property,
                "only a tosm:Place has an expected number of people or a people estimate, and the graph does not describe this as one",
            );
            return None;
        }
        let expected = self.non_negative(iri, v::EXPECTED_PEOPLE, false);
        let mut by_hour: BTreeMap<u8, f64> = BTreeMap::new();
        for h in self.iris(iri, v::HAS_HOURLY_PEOPLE_COUNT) {
            let hour = self.hour(&h, true);
            let people = self.non_negative(&h, v::EXPECTED_PEOPLE, true);
            if let (Some(hour), Some(people)) = (hour, people)
                && by_hour.insert(hour, people).is_some()
            {
                self.problem(
                    iri,
                    v::HAS_HOURLY_PEOPLE_COUNT,
                    format!("two hourly people counts are for hour {hour}"),
                );
            }
        }
        let estimates = self.estimates(iri);
        if self.problems.len() > before {
            return None;
        }
        Some(PlacePeople {
            place: iri.to_owned(),
            expected,
            by_hour: by_hour.into_iter().collect(),
            estimates,
        })
    }

    /// The people estimates of `place`: the all-day one first, then by hour.
    pub(super) fn estimates(&mut self, place: &str) -> Vec<PeopleEstimate> {
        let mut found: BTreeMap<Option<u8>, PeopleEstimate> = BTreeMap::new();
        for e in self.iris(place, v::HAS_PEOPLE_ESTIMATE) {
            let before = self.problems.len();
            let hour = self.hour(&e, false);
            let people = self.non_negative(&e, v::ESTIMATED_PEOPLE, true);
            let observations = self.integer(&e, v::OBSERVATION_COUNT, true);
            let observations = match observations.map(u64::try_from) {
                Some(Ok(n)) if n >= 1 => Some(n),
                Some(_) => {
                    self.problem(
                        &e,
                        v::OBSERVATION_COUNT,
                        format!(
                            "must be a whole number >= 1, found {}",
                            observations.unwrap_or_default()
                        ),
                    );
                    None
                }
                None => None,
            };
            let last_observed_at =
                self.literal(&e, v::LAST_OBSERVED_AT, false)
                    .and_then(|(value, dt)| {
                        if dt == xsd::DATE_TIME.as_str() {
                            Some(value)
                        } else {
                            self.problem(
                                &e,
                                v::LAST_OBSERVED_AT,
                                format!("must be an xsd:dateTime, found {value:?} of type <{dt}>"),
                            );
                            None
                        }
                    });
            if self.problems.len() > before {
                continue;
            }
            let (Some(people), Some(observations)) = (people, observations) else {
                continue;
            };
            let estimate = PeopleEstimate {
                hour,
                people,
                observations,
                last_observed_at,
            };
            if found.insert(hour, estimate).is_some() {
                self.problem(
                    place,
                    v::HAS_PEOPLE_ESTIMATE,
                    match hour {
                        Some(h) => format!("two people estimates are for hour {h}"),
                        None => "two people estimates are for the whole day".to_owned(),
                    },
                );
            }
        }
        found.into_values().collect()
    }

    /// `tosm:hourOfDay` of `s`, 0–23.
    fn hour(&mut self, s: &str, required: bool) -> Option<u8> {
        let h = self.integer(s, v::HOUR_OF_DAY, required)?;
        match u8::try_from(h) {
            Ok(h) if h <= 23 => Some(h),
            _ => {
                self.problem(
                    s,
                    v::HOUR_OF_DAY,
                    format!("must be an hour of the day, 0 to 23, found {h}"),
                );
                None
            }
        }
    }

    pub(super) fn walking_route(&mut self, iri: &str) -> Option<WalkingRoute> {
        let before = self.problems.len();
        let name = self.first_string(iri, v::NAME, false);
        let inside_of = self.container_place(iri);
        let points = self.indexed_points(iri, v::HAS_ROUTE_POINT, "route point");
        if points.len() < 2 {
            self.problem(
                iri,
                v::HAS_ROUTE_POINT,
                format!(
                    "a walking route needs at least 2 points, found {}",
                    points.len()
                ),
            );
        }
        if self.problems.len() > before {
            return None;
        }
        Some(WalkingRoute {
            iri: iri.to_owned(),
            name,
            inside_of: inside_of?,
            points,
        })
    }

    pub(super) fn attractor(&mut self, iri: &str) -> Option<Attractor> {
        let before = self.problems.len();
        let name = self.first_string(iri, v::NAME, false);
        let inside_of = self.container_place(iri);
        let pose = self.pose(iri, v::HAS_POSE, true);
        let dwell_s = self.non_negative(iri, v::DWELL_TIME_S, true);
        let mut relations = Vec::new();
        for (p, kind) in [
            (v::IS_IN_FRONT_OF, RelationKind::InFrontOf),
            (v::IS_NEXT_TO, RelationKind::NextTo),
        ] {
            for target in self.iris(iri, p) {
                if target == iri {
                    self.problem(iri, p, "an attractor cannot be related to itself");
                }
                self.check_open_reference(iri, p, &target, v::ENTITY, "a place or an object");
                relations.push(Relation { kind, target });
            }
        }
        relations.sort();
        if self.problems.len() > before {
            return None;
        }
        Some(Attractor {
            iri: iri.to_owned(),
            name,
            inside_of: inside_of?,
            pose: pose?,
            dwell_s: dwell_s?,
            relations,
        })
    }

    /// The place `iri` is directly inside of (required, described in the graph as a place).
    fn container_place(&mut self, iri: &str) -> Option<String> {
        let inside_of = self.iri(iri, v::IS_DIRECTLY_INSIDE_OF, true)?;
        self.check_reference(
            iri,
            v::IS_DIRECTLY_INSIDE_OF,
            &inside_of,
            v::PLACE,
            "a tosm:Place",
        )
        .then_some(inside_of)
    }

    /// The points `owner` has through `property`, ordered by `tosm:pointIndex`; each needs an
    /// index (unique among them) and `tosm:xM`, `tosm:yM`.
    pub(super) fn indexed_points(
        &mut self,
        owner: &str,
        property: NamedNodeRef<'_>,
        what: &str,
    ) -> Vec<(f64, f64)> {
        let points = self.iris(owner, property);
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
                        format!("index {i} is used by two {what}s of <{owner}>"),
                    );
                }
            }
        }
        indexed.into_values().collect()
    }
}
