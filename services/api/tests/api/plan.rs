//! The plan endpoint's side of the executor: requests and reports in the wire types (serde),
//! and each refusal of `rehearsal` with its own API code, `reason` and details. The executor's
//! own behaviour is tested in `rehearsal`'s `tests/rehearsal/executor.rs`.

use std::sync::Arc;

use api::plan::PlanErrorResponse;
use rehearsal::{ClassicalFollower, Controller, PlanError, RoadmapCache};
use sim::{Action, Observation, Pose2, World};
use wire::{AttemptOutcome, ControllerKind, PlanApiRequest, PlanOptions, PlanReport, Point, Pose};

/// What to plan, in the wire types: from a pose through goals.
#[derive(Clone)]
struct PlanRequest {
    start: Pose,
    goals: Vec<Point>,
    options: PlanOptions,
}

/// The executor on a request in the wire types, its report in them.
fn rehearse(
    world: &Arc<World>,
    roadmaps: &RoadmapCache,
    map_version: &str,
    request: &PlanRequest,
    policy: Option<Arc<learning::Policy>>,
) -> Result<PlanReport, PlanError> {
    rehearsal::validate(world, roadmaps, map_version, &core(request), policy).map(PlanReport::from)
}

/// The request in the executor's types.
fn core(request: &PlanRequest) -> rehearsal::PlanRequest {
    rehearsal::PlanRequest {
        start: request.start.into(),
        goals: request.goals.iter().map(|&g| g.into()).collect(),
        options: request.options.clone().into(),
        stop: rehearsal::Stop::default(),
    }
}

fn room() -> Arc<World> {
    fixtures::worlds::walled_room()
}

fn request(goals: &[(f64, f64)]) -> PlanRequest {
    PlanRequest {
        start: Pose::new(2.0, 2.0, 0.0),
        goals: goals.iter().map(|&(x, y)| Point::new(x, y)).collect(),
        options: PlanOptions::default(),
    }
}

#[test]
fn a_validated_plan_serialises_for_the_http_layer() {
    let world = room();
    let cache = RoadmapCache::default();
    let req = request(&[(7.0, 2.0), (12.0, 6.0), (8.0, 1.0)]);
    let report = rehearse(&world, &cache, "room-v1", &req, None).expect("validated");
    assert_eq!(report.controller, ControllerKind::Classical);
    assert!(report.controller_description.contains("rotate-then-go"));
    for (gi, g) in report.goal_indices.iter().zip(&req.goals) {
        assert_eq!(report.waypoints[*gi], *g);
    }
    assert_eq!(
        report.attempts.last().map(|a| a.outcome),
        Some(AttemptOutcome::Reached)
    );
    // Serialises for the HTTP layer.
    let json = serde_json::to_value(&report).expect("json");
    assert_eq!(json["controller"], "classical");
    assert_eq!(json["attempts"][0]["outcome"], "reached");
    assert_eq!(json["roadmap"]["cached"], false);
    let end = &json["trajectory"]
        .as_array()
        .expect("poses")
        .last()
        .expect("a pose");
    assert!(
        end["x"].is_f64() && end["y"].is_f64() && end["yaw"].is_f64(),
        "{end}"
    );
    assert_eq!(
        json["waypoints"].as_array().map(Vec::len),
        Some(report.waypoints.len())
    );
    // The same request again plans on the cached roadmap and gives the same report.
    let again = rehearse(&world, &cache, "room-v1", &req, None).expect("validated");
    assert!(again.roadmap.cached);
    assert_eq!(again.waypoints, report.waypoints);
    assert_eq!(again.trajectory, report.trajectory);
}

#[test]
fn each_bad_input_has_its_own_error() {
    let world = room();
    let cache = RoadmapCache::default();
    let run = |goals: &[(f64, f64)]| rehearse(&world, &cache, "room-v1", &request(goals), None);

    let e = run(&[(5.0, 3.0)]).expect_err("in the wall");
    assert_eq!(e.reason(), "goal_in_obstacle", "{e}");
    let PlanError::Blocked { nearest_free, .. } = &e else {
        panic!("{e:?}")
    };
    let near = nearest_free.expect("a nearest free point");
    assert!(
        (near.x - 5.0).abs() < 1.0 && (near.y - 3.0).abs() < 0.5,
        "{near:?}"
    );
    assert_eq!(e.api_code(), edge::ErrorCode::Unprocessable);
    assert!(e.to_string().contains("nearest free point"), "{e}");
    let details = e.details();
    assert_eq!(details["which"], "goals[0]");
    assert_eq!(details["blocked"], "in_obstacle");
    assert_eq!(details["point"], serde_json::json!({"x": 5.0, "y": 3.0}));
    assert_eq!(details["nearest_free"]["x"], near.x);

    let e = run(&[(20.0, 3.0)]).expect_err("outside");
    assert_eq!(e.reason(), "goal_outside_map", "{e}");

    let e = run(&[(7.0, 2.0), (11.5, 2.5)]).expect_err("sealed box");
    assert_eq!(e.reason(), "unreachable", "{e}");
    let details = e.details();
    assert_eq!(
        (&details["goal_index"], &details["from"]),
        (&serde_json::json!(1), &serde_json::json!("goals[0]"))
    );

    let e = run(&[(f64::NAN, 3.0)]).expect_err("NaN");
    assert_eq!(e.reason(), "invalid_input");
    assert_eq!(e.api_code(), edge::ErrorCode::BadRequest);
    assert!(e.to_string().contains("goals[0].x"), "{e}");

    let e = run(&[]).expect_err("no goals");
    assert_eq!(e.reason(), "invalid_input");

    let mut req = request(&[(7.0, 2.0)]);
    req.start = Pose::new(5.0, 1.0, 0.0);
    let e = rehearse(&world, &cache, "room-v1", &req, None).expect_err("start in the wall");
    assert_eq!(e.reason(), "start_in_obstacle", "{e}");
    assert_eq!(e.details()["which"], "start");

    let mut req = request(&[(7.0, 2.0)]);
    req.options.max_attempts = 0;
    let e = rehearse(&world, &cache, "room-v1", &req, None).expect_err("no attempts");
    assert!(e.to_string().contains("options.max_attempts"), "{e}");
    assert_eq!(e.details()["field"], "options.max_attempts");
    let api = e.to_api_error();
    assert_eq!(api.code(), edge::ErrorCode::BadRequest);
    assert_eq!(api.message(), e.to_string());

    // Request JSON with a typo is refused by serde, not silently defaulted.
    assert!(
        serde_json::from_str::<PlanApiRequest>(
            r#"{"robot": "r", "place": "p", "start": {"x": 1, "y": 1}, "goals": [{"x": 2, "y": 2}], "options": {"max_attempt": 2}}"#
        )
        .is_err()
    );
    let ok: PlanApiRequest = serde_json::from_str(
        r#"{"robot": "r", "place": "p", "start": {"x": 1, "y": 1}, "goals": [{"x": 2, "y": 2}]}"#,
    )
    .expect("defaults");
    assert_eq!(ok.options, PlanOptions::default());
    assert_eq!(
        rehearsal::PlanOptions::from(ok.options),
        rehearsal::PlanOptions::default()
    );
}

/// Drives straight ahead on every attempt (into the inner wall).
struct Reckless;

impl Controller for Reckless {
    fn command(&mut self, _obs: &Observation, _pose: Pose2, _waypoint: (f64, f64)) -> Action {
        Action::new(0.8, 0.0)
    }
    fn kind(&self) -> rehearsal::ControllerKind {
        ClassicalFollower::default().kind()
    }
    fn description(&self) -> String {
        "reckless".into()
    }
}

#[test]
fn no_attempt_validating_is_its_own_error_with_every_reason() {
    let world = room();
    let cache = RoadmapCache::default();
    let mut req = request(&[(7.0, 2.0)]);
    req.options.max_attempts = 3;
    let req = core(&req);
    let e = rehearsal::validate_with(&world, &cache, "room-v1", &req, &mut Reckless)
        .expect_err("fails");
    assert_eq!(e.reason(), "not_validated");
    assert_eq!(e.api_code(), edge::ErrorCode::Conflict);
    let PlanError::NotValidated { attempts } = &e else {
        panic!("{e:?}")
    };
    assert_eq!(attempts.len(), 3);
    let details = e.details();
    assert_eq!(details["attempts"].as_array().map(Vec::len), Some(3));
    assert_eq!(details["attempts"][0]["outcome"], "collision");
    assert!(details["attempts"][0]["end_pose"]["yaw"].is_f64());
    assert_eq!(details["reason"], "not_validated");
}
