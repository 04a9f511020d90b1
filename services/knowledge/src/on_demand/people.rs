//! People on a mission's floors: every place on them with people knowledge (and what it is
//! inside of), and every walking route and attractor inside them.

use std::collections::{BTreeSet, HashMap};

use oxigraph::model::NamedNode;
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
