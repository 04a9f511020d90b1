//! People on a mission's floors: every place on them with people knowledge (and what it is
//! inside of), and every walking route and attractor inside them.

use std::collections::{BTreeSet, HashMap};

use oxigraph::model::{NamedNode, NamedNodeRef};
use tosm::{Place, vocab};

use super::reader::Reader;
use super::route::on_floor;
use super::{OnDemandError, containers};

/// What a database adds for the people on its floors: places (off the route) with people
/// knowledge and the places they are inside of, and the walking routes and attractors.
#[derive(Debug, Default)]
pub(super) struct PeopleKnowledge {
    /// Places not already included, described without their objects.
    pub(super) places: BTreeSet<String>,
    /// Walking routes and attractors.
    pub(super) individuals: BTreeSet<NamedNode>,
}

/// The people knowledge of `floors` that `included` does not hold yet.
pub(super) fn people_on_floors(
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
    // From the places on the floors to what is inside them, not from every walking route and
    // attractor of the store to its place: a store of many buildings costs no more per floor.
    for place in index.values().filter(|p| on_one_of_the_floors(p)) {
        if reader.knows_people_in(&place.iri)? {
            add_place(place, &mut out)?;
        }
        let node = NamedNodeRef::new_unchecked(&place.iri);
        let mut walked = false;
        for individual in reader.asserted_subjects(vocab::IS_DIRECTLY_INSIDE_OF, node)? {
            if reader.is_a(individual.as_ref(), vocab::WALKING_ROUTE)?
                || reader.is_a(individual.as_ref(), vocab::ATTRACTOR)?
            {
                walked = true;
                out.individuals.insert(individual);
            }
        }
        if walked {
            add_place(place, &mut out)?;
        }
    }
    Ok(out)
}
