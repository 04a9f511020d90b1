//! The plan use case directly, with no HTTP and no job queue: the bundled sample building's
//! floor as its on-demand database (parsed from the Turtle files the service loads), policies
//! in a temporary directory, and a recording stand-in for the background roadmap builds.
#![allow(
    clippy::unwrap_used,
    reason = "a test that cannot set itself up should fail loudly"
)]

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use oxrdf::Graph;
use planner::{
    BuildFuture, FloorDatabase, KnowledgeSource, PlanFailure, PlanPeople, PlanQuery, Planner,
    PolicyRoadmapKey, PolicyStore, RoadmapBuilds, RoadmapStore, SourceError, SourceFuture,
};
use prm::Point2;
use rehearsal::{
    ControllerChoice, ControllerKind, EdgeRolloutParams, PlanOptions, PlanRequest, RoadmapChoice,
    RoadmapKind,
};
use sim::Pose2;

const ROBOT: &str = "https://mentalsim.dev/data/robots/differential-robot";
const FLOOR0: &str = "https://mentalsim.dev/data/buildings/sample-building/floors/0";

/// The sample building and the robot, as the knowledge service holds them.
fn sample_graph() -> Graph {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../ontologies");
    let mut g = Graph::new();
    for rel in [
        "environments/sample-building.ttl",
        "robots/differential-robot.ttl",
    ] {
        let text = std::fs::read(dir.join(rel)).unwrap();
        for t in oxttl::TurtleParser::new().for_slice(&text) {
            g.insert(&t.unwrap());
        }
    }
    g
}

/// Floor 0 for the robot, whatever place is asked for; `F9` does not exist.
struct SampleFloor(Arc<FloorDatabase>);

impl KnowledgeSource for SampleFloor {
    fn floor_database<'a>(&'a self, place: &'a str, _robot: &'a str) -> SourceFuture<'a> {
        Box::pin(async move {
            if place == "F9" {
                return Err(SourceError::NotFound("no place `F9`".into()));
            }
            Ok(Arc::clone(&self.0))
        })
    }
}

/// Records the builds asked for.
#[derive(Default)]
struct Builds(Mutex<Vec<PolicyRoadmapKey>>);

impl RoadmapBuilds for Builds {
    fn ensure<'a>(
        &'a self,
        key: &'a PolicyRoadmapKey,
        _floor: &'a str,
        _robot: &'a str,
        _margin: f64,
    ) -> BuildFuture<'a> {
        self.0.lock().unwrap().push(key.clone());
        Box::pin(async { Ok("job-1".to_owned()) })
    }
}

struct Fixture {
    planner: Planner,
    builds: Arc<Builds>,
    policies: tempfile::TempDir,
    db: Arc<FloorDatabase>,
    _roadmaps: tempfile::TempDir,
}

fn fixture() -> Fixture {
    let db = Arc::new(FloorDatabase::new(
        sample_graph(),
        ROBOT.into(),
        FLOOR0.into(),
        "v1",
    ));
    let policies = tempfile::tempdir().unwrap();
    let roadmaps = tempfile::tempdir().unwrap();
    let builds = Arc::new(Builds::default());
    let planner = Planner::new(
        Arc::new(SampleFloor(Arc::clone(&db))),
        PolicyStore::new(policies.path()),
        Arc::new(rehearsal::RoadmapCache::default()),
        RoadmapStore::new(roadmaps.path()),
        Arc::clone(&builds) as Arc<dyn RoadmapBuilds>,
    );
    Fixture {
        planner,
        builds,
        policies,
        db,
        _roadmaps: roadmaps,
    }
}

/// Two free points of floor 0 for the robot, far apart in one free region.
fn mission(db: &FloorDatabase) -> (Pose2, Point2) {
    let world = db.world().unwrap();
    let cache = rehearsal::RoadmapCache::default();
    let entry = rehearsal::config_space(&world, &cache, "probe", 0.1).unwrap();
    let space = &entry.cspace;
    let region = space.largest_region().unwrap();
    let (lo, hi) = space.bounds();
    let mut free = Vec::new();
    let mut y = lo.y + 0.5;
    while y < hi.y {
        let mut x = lo.x + 0.5;
        while x < hi.x {
            let p = Point2::new(x, y);
            if space.region_of(p) == Some(region) && space.clearance_m(p).unwrap_or(0.0) > 0.4 {
                free.push(p);
            }
            x += 0.5;
        }
        y += 0.5;
    }
    let a = free[0];
    let b = free
        .iter()
        .copied()
        .max_by(|p, q| a.distance(*p).total_cmp(&a.distance(*q)))
        .unwrap();
    assert!(a.distance(b) > 5.0, "a mission worth planning");
    (Pose2::new(a.x, a.y, 0.0), b)
}

fn query(start: Pose2, goal: Point2, options: PlanOptions) -> PlanQuery {
    PlanQuery {
        robot: ROBOT.into(),
        place: "F0".into(),
        request: PlanRequest {
            start,
            goals: vec![goal],
            options,
            stop: rehearsal::Stop::default(),
        },
        people: PlanPeople::AsGiven,
        policy: None,
        controller: None,
        fleet: planner::FleetOptions::default(),
    }
}

fn options(seed: u64) -> PlanOptions {
    PlanOptions {
        seed,
        trajectory_stride: 0,
        ..PlanOptions::default()
    }
}

#[tokio::test]
async fn without_a_policy_the_follower_validates_and_the_note_says_why() {
    let f = fixture();
    let (start, goal) = mission(&f.db);
    let outcome = f
        .planner
        .plan(query(start, goal, options(1)), rehearsal::Stop::new())
        .await
        .unwrap();
    assert_eq!(outcome.report.controller, ControllerKind::Classical);
    assert_eq!(outcome.controller.choice, ControllerChoice::Rpp);
    assert!(outcome.controller.why.contains("no trained policy"));
    assert!(outcome.policy.is_none());
    assert!(outcome.note.unwrap().contains("no trained policy"));

    // The hybrid needs a policy: asked for without one, the plan is refused, naming why.
    let mut q = query(start, goal, options(1));
    q.controller = Some(ControllerChoice::Hybrid);
    let e = f.planner.plan(q, rehearsal::Stop::new()).await.unwrap_err();
    assert!(
        matches!(
            e,
            PlanFailure::Unprocessable(planner::Unusable::NoPolicyFor {
                controller: "hybrid"
            })
        ),
        "{e}"
    );
    assert_eq!(outcome.floor, FLOOR0);
    assert!(outcome.people.is_none());
    assert!(
        f.builds.0.lock().unwrap().is_empty(),
        "no policy, no roadmap build"
    );
}

#[tokio::test]
async fn the_robots_newest_policy_drives_and_its_roadmap_is_asked_for_once_missing() {
    let f = fixture();
    let (start, goal) = mission(&f.db);
    for (id, created) in [("older", 1), ("newer", 2)] {
        let dir = f.policies.path().join(id);
        std::fs::create_dir_all(&dir).unwrap();
        let summary = serde_json::json!({"summary": {"robot": ROBOT, "created_ms": created}});
        learning::policy::write_goal_seeking_policy(&dir, 23, summary).unwrap();
    }
    // `auto` before the policy was measured on this floor state: Regulated Pure Pursuit.
    let outcome = f
        .planner
        .plan(query(start, goal, options(2)), rehearsal::Stop::new())
        .await
        .unwrap();
    assert_eq!(outcome.policy.as_deref(), Some("newer"));
    assert_eq!(outcome.report.controller, ControllerKind::Classical);
    assert_eq!(outcome.controller.choice, ControllerChoice::Rpp);
    assert!(
        outcome.controller.why.contains("not been measured"),
        "{}",
        outcome.controller.why
    );
    // Asked for, the hybrid drives the newest policy.
    let mut q = query(start, goal, options(2));
    q.controller = Some(ControllerChoice::Hybrid);
    let outcome = f.planner.plan(q, rehearsal::Stop::new()).await.unwrap();
    assert_eq!(outcome.report.controller, ControllerKind::Policy);
    assert_eq!(outcome.report.roadmap.kind, RoadmapKind::Geometric);
    // Each plan asks for the missing roadmap (the build service enqueues it once per key).
    let builds = f.builds.0.lock().unwrap().clone();
    assert_eq!(builds.len(), 2, "{builds:?}");
    assert!(
        builds
            .iter()
            .all(|k| k.policy == "newer" && k.floor_state == f.db.version),
        "{builds:?}"
    );

    // Only the policy-aware roadmap: refused while it is being built.
    let mut o = options(2);
    o.roadmap = RoadmapChoice::Policy;
    let mut q = query(start, goal, o);
    q.controller = Some(ControllerChoice::Hybrid);
    let e = f.planner.plan(q, rehearsal::Stop::new()).await.unwrap_err();
    assert!(
        matches!(e, PlanFailure::RoadmapNotReady(planner::RoadmapPending::Building { ref job }) if job == "job-1"),
        "{e}"
    );
}

#[tokio::test]
async fn people_come_from_the_knowledge_at_the_hour_asked() {
    let f = fixture();
    let (start, goal) = mission(&f.db);
    let mut q = query(start, goal, options(3));
    q.people = PlanPeople::Expected { hour: Some(12) };
    let outcome = f.planner.plan(q, rehearsal::Stop::new()).await.unwrap();
    let people = outcome
        .people
        .expect("the sample building expects people at noon");
    assert_eq!(people.source, planner::PeopleSource::Knowledge);
    assert!(people.people > 0);
    assert_eq!(people.attempts, outcome.report.attempts.len());

    let mut q = query(start, goal, options(3));
    q.people = PlanPeople::Expected { hour: Some(24) };
    let e = f.planner.plan(q, rehearsal::Stop::new()).await.unwrap_err();
    assert!(
        matches!(e, PlanFailure::BadRequest(ref f) if f.field == "options.people_hour" && f.message.contains("got 24")),
        "{e}"
    );
}

#[tokio::test]
async fn what_does_not_exist_is_named() {
    let f = fixture();
    let (start, goal) = mission(&f.db);
    let mut q = query(start, goal, options(4));
    q.policy = Some("no-such-policy".into());
    let e = f.planner.plan(q, rehearsal::Stop::new()).await.unwrap_err();
    assert!(
        matches!(e, PlanFailure::NotFound(planner::Missing::Policy(ref id)) if id == "no-such-policy"),
        "{e}"
    );
    let mut q = query(start, goal, options(4));
    q.place = "F9".into();
    let e = f.planner.plan(q, rehearsal::Stop::new()).await.unwrap_err();
    assert!(
        matches!(e, PlanFailure::NotFound(planner::Missing::Knowledge(ref m)) if m.contains("F9")),
        "{e}"
    );
}

/// `auto` with a stored trial: the controller the trial measured best, with its figures as the
/// reason; the trial itself driven for real over the sample floor (every candidate, the same
/// missions).
#[tokio::test]
async fn auto_validates_with_the_controller_the_floors_trial_measured_best() {
    let f = fixture();
    let (start, goal) = mission(&f.db);
    let dir = f.policies.path().join("seeker");
    std::fs::create_dir_all(&dir).unwrap();
    let summary = serde_json::json!({"summary": {"robot": ROBOT, "created_ms": 1}});
    learning::policy::write_goal_seeking_policy(&dir, 23, summary).unwrap();
    let policy = Arc::new(learning::Policy::load(&dir).unwrap());

    // What the `roadmap` job stores: the edges driven by the policy, then the trial.
    let world = f.db.world().unwrap();
    let margin = PlanOptions::default().safety_margin_m;
    let params = EdgeRolloutParams {
        rollouts: 1,
        ..EdgeRolloutParams::default()
    };
    let geometric = planner::roadmaps::geometric_roadmap(
        &world,
        f.planner.roadmaps(),
        world.geometry_key(),
        margin,
    )
    .unwrap();
    let report = rehearsal::drive_edges(
        &world,
        &geometric,
        || rehearsal::PolicyController::new(Arc::clone(&policy)),
        &params,
    )
    .unwrap();
    let policy_roadmap = rehearsal::reweight_with_unkept(&geometric, &report).unwrap();
    let missions = planner::controllers::trial_missions(&geometric, 6, 7);
    assert_eq!(missions.len(), 6);
    let trial = planner::controllers::run_trial(
        &planner::controllers::TrialFloor {
            world: &world,
            roadmaps: f.planner.roadmaps(),
            version: world.geometry_key(),
            policy: Some(&policy),
            policy_roadmap: Some(&policy_roadmap),
        },
        &missions,
        &sim::PeopleConfig::default(),
        7,
    )
    .unwrap();
    let names: Vec<&str> = trial
        .candidates
        .iter()
        .map(|c| c.controller.as_str())
        .collect();
    assert_eq!(
        names,
        ["rpp", "mppi", "hybrid", "hybrid_rpp", "hybrid_path"]
    );
    assert_eq!(trial.missions, 6);
    for c in &trial.candidates {
        // A challenger stops once it can no longer win; RPP, the first, drives every mission.
        assert!(!c.runs.is_empty() && c.runs.len() <= 6, "{}", c.controller);
        assert!(c.wall_ms_per_mission > 0.0);
    }
    assert_eq!(trial.figures(ControllerChoice::Rpp).unwrap().runs.len(), 6);
    let rpp = trial.figures(ControllerChoice::Rpp).unwrap();
    assert!(
        rpp.reached() > 0,
        "RPP reaches goals in the empty sample floor"
    );
    let key = PolicyRoadmapKey::new(
        &f.db.version,
        "seeker",
        &dir,
        margin,
        &EdgeRolloutParams::default(),
    )
    .unwrap();
    let expected = trial.pick(|_| true).unwrap();
    f.planner
        .policy_roadmaps()
        .put(&planner::StoredRoadmap {
            key,
            nodes: geometric.nodes().count(),
            nodes_fingerprint: planner::roadmaps::nodes_fingerprint(&geometric),
            seed: params.seed,
            wall_s: 0.0,
            edges: report
                .edges
                .iter()
                .map(planner::roadmaps::StoredEdge::from)
                .collect(),
            trial: Some(trial),
        })
        .unwrap();

    let mut o = options(5);
    o.people = sim::PeopleConfig::default();
    let outcome = f
        .planner
        .plan(query(start, goal, o), rehearsal::Stop::new())
        .await
        .unwrap();
    assert_eq!(outcome.controller, expected);
    assert_eq!(
        outcome.controller.compared_with,
        Some(ControllerChoice::Rpp)
    );
    assert!(
        outcome
            .controller
            .why
            .starts_with("auto: measured on this floor state over")
    );
    let kind = if expected.choice.needs_policy() {
        ControllerKind::Policy
    } else {
        ControllerKind::Classical
    };
    assert_eq!(outcome.report.controller, kind);
    assert!(
        f.builds.0.lock().unwrap().is_empty(),
        "stored: no build asked"
    );
}
