//! Objects: their class, container, pose, shape and spatial relations.

use oxrdf::NamedNodeRef;
use oxrdf::vocab::xsd;

use super::Reader;
use crate::model::{Object, ObjectClass, Relation, RelationKind};
use crate::vocab as v;

impl<'g> Reader<'g> {
    pub(super) fn object(&mut self, iri: &str) -> Option<Object> {
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
    pub(super) fn object_class(&self, iri: &str) -> (String, ObjectClass) {
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
}
