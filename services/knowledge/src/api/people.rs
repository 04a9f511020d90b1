//! People counts (`POST /v1/places/{id}/observations`): how many people robots saw in a place.
//! The service keeps a running estimate per place, over the whole day and per hour of day
//! (`tosm:PeopleEstimate` in the perceived graph, so it survives restarts), which the next
//! on-demand databases carry to the simulation in place of the engineer's figure.
//!
//! The estimate moves towards each count by `max(1/n, 0.2)` of the way, `n` the number of
//! counts so far (`tosm::PeopleEstimate::observe`): the plain mean of the first five counts,
//! then an exponentially weighted mean in which the latest count weighs 0.2. Counts are taken
//! in the order they arrive (within a request, in the order given).

use std::collections::BTreeMap;
use std::str::FromStr;
use std::sync::Arc;

use axum::Json;
use axum::extract::{Path, State};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, ErrorBody, ErrorCode, RobotCaller, Role};
use oxigraph::model::{Graph, GraphNameRef, NamedNode, NamedNodeRef, Quad, Term, Triple};
use oxsdatatypes::DateTime;
use serde::{Deserialize, Serialize};
use tosm::{PeopleEstimate, PlaceKind};
use utoipa::ToSchema;

use super::places::find_place;
use super::task::blocking;
use crate::graphs::PERCEIVED_GRAPH;
use crate::on_demand;
use crate::service::{Knowledge, OBSERVATION_BURST, OBSERVATIONS_PER_SECOND};
use crate::store::KnowledgeStore;

/// The most counts one request may carry (a robot's whole burst allowance).
pub const MAX_OBSERVATIONS: usize = 100;
/// The largest count a robot may report for one place: beyond it the count is a fault.
pub const MAX_PEOPLE_COUNT: f64 = 10_000.0;

/// People counts a robot made in one place.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PeopleObservations {
    /// The counts, in the order they were made: 1 to 100.
    #[schema(min_items = 1, max_items = 100)]
    observations: Vec<PeopleObservation>,
}

/// One count.
#[derive(Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PeopleObservation {
    /// How many people were in the place, 0 to 10000 (a mean over a short window may have a
    /// fraction).
    #[schema(minimum = 0, maximum = 10000)]
    count: f64,
    /// When, as an `xsd:dateTime` (RFC 3339: `2025-05-06T12:30:00+02:00`). Its hour, as
    /// written, is the hour of day the count also updates: give the building's local time with
    /// its offset. Without it the count is taken as made now and moves the all-day estimate only.
    #[serde(default)]
    #[schema(example = "2025-05-06T12:30:00+02:00")]
    observed_at: Option<String>,
}

/// A running estimate of the people in a place.
#[derive(Serialize, ToSchema)]
pub struct EstimateView {
    /// The hour of day (0-23) it is for; absent for the whole day.
    #[serde(skip_serializing_if = "Option::is_none")]
    hour: Option<u8>,
    /// The estimated number of people.
    people: f64,
    /// How many counts it is made of.
    observations: u64,
    /// When the latest of them was made (`xsd:dateTime`).
    last_observed_at: Option<String>,
}

impl From<&PeopleEstimate> for EstimateView {
    fn from(e: &PeopleEstimate) -> Self {
        Self {
            hour: e.hour,
            people: e.people,
            observations: e.observations,
            last_observed_at: e.last_observed_at.clone(),
        }
    }
}

/// The place's estimates after the counts were taken.
#[derive(Serialize, ToSchema)]
pub struct PeopleEstimates {
    /// The place's IRI.
    place: String,
    /// How many counts this request added.
    accepted: usize,
    /// Over the whole day.
    estimate: EstimateView,
    /// Per hour of day, for every hour robots have counted in, sorted by hour.
    by_hour: Vec<EstimateView>,
}

/// Adds robots' counts of the people in a place to its running estimate. Robots and engineers.
///
/// The estimate (over the whole day, and for the hour of day of each count that says when it
/// was made) moves towards each count by max(1/n, 0.2) of the way, n the number of counts so
/// far: the mean of the first five, then an exponentially weighted mean. Simulations of the
/// place's floor use it instead of the engineer's `tosm:expectedPeople`.
#[utoipa::path(post, path = "/v1/places/{id}/observations",
    params(("id" = String, Path, min_length = 1, description = "The place: a floor, room, corridor or hall (IRI or tosm:identifier).")),
    request_body = PeopleObservations,
    responses(
        (status = 200, description = "The counts were added; the place's estimates now.", body = PeopleEstimates),
        (status = 400, description = "The body is not JSON.", body = ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, response = edge::error::responses::Forbidden),
        (status = 404, description = "No place has this IRI or identifier.", body = ErrorBody),
        (status = 409, description = "The place's stored estimate does not read (an engineer's edit broke it): named in the message.", body = ErrorBody),
        (status = 413, response = edge::error::responses::PayloadTooLarge),
        (status = 415, response = edge::error::responses::UnsupportedMediaType),
        (status = 422, description = "The body does not fit the schema (a missing or unknown field, a wrong type), there are no counts or more than 100, a count is negative or above 10000, an observed_at is no xsd:dateTime, or the place is a building. The message names the observation and field.", body = ErrorBody),
        (status = 429, description = "The robot sent more counts than its allowance (20 per second, bursts of 100); Retry-After says when to retry.", body = ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
        (status = 507, response = edge::error::responses::StorageFull),
    ))]
pub(super) async fn report_people_observations(
    State(k): State<Arc<Knowledge>>,
    RobotCaller(principal): RobotCaller,
    Path(id): Path<String>,
    Json(body): Json<PeopleObservations>,
) -> Result<Response, ApiError> {
    k.check_space(0)?;
    let n = body.observations.len();
    // Every request costs its counts (at least one), so that a robot cannot flood the service
    // with requests that are refused later.
    if principal.role == Role::Robot
        && let Err(wait_s) = k.take_observations(&principal.name, n.clamp(1, MAX_OBSERVATIONS))
    {
        return Ok(super::too_many_requests(
            format!(
                "{} sent more than {OBSERVATION_BURST} people counts in a burst \
                 ({OBSERVATIONS_PER_SECOND} per second on average); retry in {wait_s:.1} s",
                principal.name
            ),
            wait_s,
        ));
    }
    let counts = validate(&body.observations)?;
    blocking(move || {
        let store = k.store()?;
        let places = on_demand::all_places(&store)?;
        let place = places[find_place(&places, &id)?].clone();
        if place.kind == PlaceKind::Building {
            return Err(ApiError::new(
                ErrorCode::Unprocessable,
                format!(
                    "{} is a building: count people in a floor, room, corridor or hall",
                    place.iri
                ),
            ));
        }
        let _serialised = k.estimates_lock();
        let mut estimates: BTreeMap<Option<u8>, PeopleEstimate> =
            current_estimates(&store, &place.iri)?
                .into_iter()
                .map(|e| (e.hour, e))
                .collect();
        let now = DateTime::now();
        let mut touched = std::collections::BTreeSet::new();
        for (count, at) in &counts {
            let hours = std::iter::once(None).chain(at.map(|a| Some(a.hour())));
            for hour in hours {
                let previous = estimates.get(&hour);
                let last = latest(
                    previous.and_then(|p| p.last_observed_at.as_deref()),
                    at.unwrap_or(now),
                );
                let next = PeopleEstimate::observe(previous, hour, *count, &last);
                estimates.insert(hour, next);
                touched.insert(hour);
            }
        }
        let graph = NamedNode::new_unchecked(PERCEIVED_GRAPH);
        let mut owned = Vec::new();
        let mut quads: Vec<Quad> = Vec::new();
        for hour in &touched {
            let estimate = &estimates[hour];
            owned.push(NamedNode::new_unchecked(PeopleEstimate::iri_for(
                &place.iri, *hour,
            )));
            let triples = tosm::people_estimate_to_triples(&place.iri, estimate)
                .map_err(|p| ApiError::new(ErrorCode::Unprocessable, p.to_string()))?;
            quads.extend(triples.into_iter().map(|t| t.in_graph(graph.clone())));
        }
        store.replace_subjects(graph.as_ref(), &owned, &quads)?;
        k.after_write()?;
        let estimate = estimates
            .get(&None)
            .map(EstimateView::from)
            .ok_or_else(|| ApiError::internal("no all-day estimate after a count"))?;
        Ok(Json(PeopleEstimates {
            place: place.iri,
            accepted: counts.len(),
            estimate,
            by_hour: estimates
                .values()
                .filter(|e| e.hour.is_some())
                .map(EstimateView::from)
                .collect(),
        })
        .into_response())
    })
    .await
}

/// The counts and their times, or a 422 naming the first observation and field that is wrong.
fn validate(observations: &[PeopleObservation]) -> Result<Vec<(f64, Option<DateTime>)>, ApiError> {
    let unprocessable = |message: String| ApiError::new(ErrorCode::Unprocessable, message);
    if observations.is_empty() {
        return Err(unprocessable(
            "observations: give at least one count".to_owned(),
        ));
    }
    if observations.len() > MAX_OBSERVATIONS {
        return Err(unprocessable(format!(
            "observations: at most {MAX_OBSERVATIONS} counts per request, got {}",
            observations.len()
        )));
    }
    observations
        .iter()
        .enumerate()
        .map(|(i, o)| {
            if !(o.count.is_finite() && (0.0..=MAX_PEOPLE_COUNT).contains(&o.count)) {
                return Err(unprocessable(format!(
                    "observations[{i}].count: a number of people is 0 to {MAX_PEOPLE_COUNT}, got {}",
                    o.count
                )));
            }
            let at = match &o.observed_at {
                None => None,
                Some(text) => Some(DateTime::from_str(text.trim()).map_err(|e| {
                    unprocessable(format!(
                        "observations[{i}].observed_at: {text:?} is not an xsd:dateTime such as \
                         2025-05-06T12:30:00+02:00 ({e})"
                    ))
                })?),
            };
            Ok((o.count, at))
        })
        .collect()
}

/// The later of a stored `xsd:dateTime` and `at`, as text: counts may arrive out of order, and
/// the estimate says when its latest count was made.
fn latest(stored: Option<&str>, at: DateTime) -> String {
    match stored.and_then(|s| DateTime::from_str(s).ok()) {
        Some(stored) if stored > at => stored.to_string(),
        _ => at.to_string(),
    }
}

/// The estimates of `place` in the perceived graph; 409 when an edit left them unreadable.
fn current_estimates(store: &KnowledgeStore, place: &str) -> Result<Vec<PeopleEstimate>, ApiError> {
    let snapshot = store.snapshot()?;
    let in_perceived = GraphNameRef::NamedNode(NamedNodeRef::new_unchecked(PERCEIVED_GRAPH));
    let place_node = NamedNode::new(place)
        .map_err(|e| ApiError::internal(format!("place IRI <{place}>: {e}")))?;
    let mut graph = Graph::new();
    for link in snapshot.quads_for_pattern(
        Some(place_node.as_ref().into()),
        Some(tosm::vocab::HAS_PEOPLE_ESTIMATE),
        None,
        Some(in_perceived),
    ) {
        let link = link.map_err(|e| store.storage(e))?;
        if let Term::NamedNode(estimate) = &link.object {
            for quad in snapshot.quads_for_pattern(
                Some(estimate.as_ref().into()),
                None,
                None,
                Some(in_perceived),
            ) {
                let quad = quad.map_err(|e| store.storage(e))?;
                graph.insert(&Triple::from(quad));
            }
        }
        graph.insert(&Triple::from(link));
    }
    tosm::read_people_estimates(&graph, place).map_err(|problems| {
        ApiError::new(
            ErrorCode::Conflict,
            format!(
                "the stored people estimates of {place} do not read ({problems}); an engineer \
                 must correct or delete them over SPARQL before counts can be added"
            ),
        )
    })
}
