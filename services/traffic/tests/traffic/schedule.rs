//! The traffic schedule on real databases: every case runs against SQLite (a file in a
//! temporary directory) and PostgreSQL (a temporary cluster), through the public API, and must
//! behave the same.

#![allow(clippy::unwrap_used)] // reason: tests panic on failure

use std::sync::Arc;
use std::time::Duration;

use crate::common::{Fixture, START_MS, at, straight};
use traffic::{Change, Itinerary, Removal, Schedule, TimedPose, TrafficError};

fixtures::on_both_backends!(
    crate::common::sqlite,
    crate::common::postgres,
    [
        opening_again_migrates_nothing_and_the_queue_still_opens,
        commit_then_snapshot,
        a_stale_version_is_refused_and_nothing_changes,
        a_robots_new_plan_replaces_its_previous_one_on_any_floor,
        a_plan_id_of_another_robot_is_refused,
        cancel_removes_the_itinerary_and_bumps_the_version,
        progress_shifts_the_rest_of_the_schedule_by_the_delay,
        progress_is_only_for_the_plans_own_robot,
        expired_itineraries_leave_snapshots_and_are_purged,
        bad_itineraries_are_refused_naming_what_is_wrong,
        this_processs_changes_are_broadcast_in_order,
        racing_commits_from_two_processes_elect_one_winner_per_version,
        revisions_replace_plans_whose_robots_have_not_set_off_all_or_none,
        a_revision_of_a_robot_that_set_off_is_refused,
        progress_acknowledges_revisions_it_was_sent_and_no_others,
    ]
);

async fn opening_again_migrates_nothing_and_the_queue_still_opens(f: Fixture) {
    f.schedule
        .commit(straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]), 0)
        .await
        .unwrap();
    // The queue's migrator still accepts the database (the schedule keeps its own migration
    // table), and a second schedule on it finds its tables and the committed itinerary.
    let again = f.another_process().await;
    let (version, itineraries) = again.snapshot("f1", START_MS).await.unwrap();
    assert_eq!((version, itineraries.len()), (1, 1));
    let status = f.db.status().await.unwrap();
    assert_eq!(status.applied_migrations, status.expected_migrations);
}

async fn commit_then_snapshot(f: Fixture) {
    let s = &f.schedule;
    assert_eq!(s.snapshot("f1", START_MS).await.unwrap(), (0, vec![]));
    let a = straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]);
    assert_eq!(s.commit(a.clone(), 0).await.unwrap(), 1);
    let b = straight("p2", "r2", "f1", [0.0, 3.0], [5.0, 3.0]);
    assert_eq!(s.commit(b.clone(), 1).await.unwrap(), 2);
    let (version, itineraries) = s.snapshot("f1", START_MS).await.unwrap();
    assert_eq!(version, 2);
    assert_eq!(itineraries, vec![a.clone(), b]);
    // Read back exactly as written.
    assert_eq!(s.get("p1").await.unwrap(), Some(a));
    assert_eq!(s.get("nope").await.unwrap(), None);
    // Other floors are untouched.
    assert_eq!(s.snapshot("f2", START_MS).await.unwrap(), (0, vec![]));
    assert_eq!(s.version("f1").await.unwrap(), 2);
}

async fn a_stale_version_is_refused_and_nothing_changes(f: Fixture) {
    let s = &f.schedule;
    s.commit(straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]), 0)
        .await
        .unwrap();
    let late = straight("p2", "r2", "f1", [0.0, 3.0], [5.0, 3.0]);
    let err = s.commit(late.clone(), 0).await.unwrap_err();
    match &err {
        TrafficError::VersionChanged {
            floor,
            expected,
            now,
        } => assert_eq!((floor.as_str(), *expected, *now), ("f1", 0, 1)),
        other => panic!("{other:?}"),
    }
    assert!(err.to_string().contains("\"f1\""), "{err}");
    // A version from the future is refused too, and a floor never committed to is at 0.
    assert!(matches!(
        s.commit(late.clone(), 7).await,
        Err(TrafficError::VersionChanged { now: 1, .. })
    ));
    let elsewhere = straight("p3", "r3", "f9", [0.0, 0.0], [1.0, 0.0]);
    assert!(matches!(
        s.commit(elsewhere, 1).await,
        Err(TrafficError::VersionChanged { now: 0, .. })
    ));
    assert_eq!(s.version("f9").await.unwrap(), 0);
    let (version, itineraries) = s.snapshot("f1", START_MS).await.unwrap();
    assert_eq!((version, itineraries.len()), (1, 1));
    assert_eq!(s.get("p2").await.unwrap(), None);
}

async fn a_robots_new_plan_replaces_its_previous_one_on_any_floor(f: Fixture) {
    let s = &f.schedule;
    s.commit(straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]), 0)
        .await
        .unwrap();
    // The same robot, a new plan on the same floor: the old one goes.
    let second = straight("p2", "r1", "f1", [0.0, 1.0], [5.0, 1.0]);
    assert_eq!(s.commit(second.clone(), 1).await.unwrap(), 2);
    assert_eq!(s.snapshot("f1", START_MS).await.unwrap(), (2, vec![second]));
    // On another floor: the old floor loses it and moves to a new version as well.
    let third = straight("p3", "r1", "f2", [0.0, 0.0], [2.0, 0.0]);
    assert_eq!(s.commit(third.clone(), 0).await.unwrap(), 1);
    assert_eq!(s.snapshot("f1", START_MS).await.unwrap(), (3, vec![]));
    assert_eq!(
        s.snapshot("f2", START_MS).await.unwrap(),
        (1, vec![third.clone()])
    );
    assert_eq!(s.get("p1").await.unwrap(), None);
    assert_eq!(s.get("p2").await.unwrap(), None);
    // Committing the same plan again replaces it by itself.
    let mut moved = third;
    moved.tolerance_s = 3.0;
    assert_eq!(s.commit(moved.clone(), 1).await.unwrap(), 2);
    assert_eq!(s.get("p3").await.unwrap(), Some(moved));
}

async fn a_plan_id_of_another_robot_is_refused(f: Fixture) {
    let s = &f.schedule;
    s.commit(straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]), 0)
        .await
        .unwrap();
    let err = s
        .commit(straight("p1", "r2", "f1", [0.0, 3.0], [5.0, 3.0]), 1)
        .await
        .unwrap_err();
    match err {
        TrafficError::PlanIdTaken { plan_id, owner } => {
            assert_eq!((plan_id.as_str(), owner.as_str()), ("p1", "r1"));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(s.version("f1").await.unwrap(), 1);
}

async fn cancel_removes_the_itinerary_and_bumps_the_version(f: Fixture) {
    let s = &f.schedule;
    let a = straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]);
    s.commit(a.clone(), 0).await.unwrap();
    assert_eq!(s.cancel("p1").await.unwrap(), Some(a));
    assert_eq!(s.snapshot("f1", START_MS).await.unwrap(), (2, vec![]));
    assert_eq!(s.cancel("p1").await.unwrap(), None);
    assert_eq!(s.cancel("never").await.unwrap(), None);
    assert_eq!(s.version("f1").await.unwrap(), 2);
    // The robot may commit again against the new version.
    s.commit(straight("p2", "r1", "f1", [0.0, 0.0], [5.0, 0.0]), 2)
        .await
        .unwrap();
}

async fn progress_shifts_the_rest_of_the_schedule_by_the_delay(f: Fixture) {
    let s = &f.schedule;
    // 0 → 10 m along x at 1 m/s from START_MS.
    let plan = straight("p1", "r1", "f1", [0.0, 0.0], [10.0, 0.0]);
    s.commit(plan.clone(), 0).await.unwrap();
    f.clock.set(at(5.0));
    // At x = 3 m 5 s after the start: scheduled at 3 s, so 2 s late.
    let late = s
        .progress("p1", "r1", at(5.0), (3.0, 0.05), None)
        .await
        .unwrap()
        .itinerary;
    assert!((late.delay_s - 2.0).abs() < 1e-6, "{late:?}");
    assert_eq!(late.expires_unix_ms, plan.expires_unix_ms + 2_000);
    assert_eq!(late.trajectory, plan.trajectory);
    // The rest of the schedule moved: the robot is due at 8 m at 10 s, no longer at 10 m.
    let (x, _) = late.pose_at(at(10.0)).unwrap();
    assert!((x - 8.0).abs() < 1e-6, "{x}");
    let (version, itineraries) = s.snapshot("f1", at(5.0)).await.unwrap();
    assert_eq!((version, itineraries), (2, vec![late.clone()]));
    assert_eq!(s.get("p1").await.unwrap(), Some(late));
    // It catches up: at 7 m at 8 s, 1 s late; searched forward from the last report.
    f.clock.set(at(8.0));
    let caught_up = s
        .progress("p1", "r1", at(8.0), (7.0, 0.0), None)
        .await
        .unwrap()
        .itinerary;
    assert!((caught_up.delay_s - 1.0).abs() < 1e-6, "{caught_up:?}");
    assert_eq!(caught_up.expires_unix_ms, plan.expires_unix_ms + 1_000);
    assert_eq!(s.version("f1").await.unwrap(), 3);
}

async fn progress_is_only_for_the_plans_own_robot(f: Fixture) {
    let s = &f.schedule;
    s.commit(straight("p1", "r1", "f1", [0.0, 0.0], [10.0, 0.0]), 0)
        .await
        .unwrap();
    match s.progress("p1", "r2", at(1.0), (1.0, 0.0), None).await {
        Err(TrafficError::NotYourPlan {
            plan_id,
            robot,
            owner,
        }) => assert_eq!(
            (plan_id.as_str(), robot.as_str(), owner.as_str()),
            ("p1", "r2", "r1")
        ),
        other => panic!("{other:?}"),
    }
    match s.progress("p9", "r1", at(1.0), (1.0, 0.0), None).await {
        Err(TrafficError::NotFound { plan_id }) => assert_eq!(plan_id, "p9"),
        other => panic!("{other:?}"),
    }
    for (x, y) in [(f64::NAN, 0.0), (0.0, f64::INFINITY)] {
        let err = s
            .progress("p1", "r1", at(1.0), (x, y), None)
            .await
            .unwrap_err();
        assert!(matches!(err, TrafficError::Invalid(_)), "{err:?}");
    }
    // Nothing of this changed the floor.
    assert_eq!(s.version("f1").await.unwrap(), 1);
}

async fn expired_itineraries_leave_snapshots_and_are_purged(f: Fixture) {
    let s = &f.schedule;
    let mut short = straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]);
    short.expires_unix_ms = at(10.0);
    s.commit(short.clone(), 0).await.unwrap();
    s.commit(straight("p2", "r2", "f1", [0.0, 3.0], [5.0, 3.0]), 1)
        .await
        .unwrap();
    assert_eq!(s.snapshot("f1", at(10.0)).await.unwrap().1.len(), 2);
    let (version, itineraries) = s.snapshot("f1", at(10.001)).await.unwrap();
    assert_eq!(version, 2, "expiry is not a change");
    assert_eq!(itineraries.len(), 1);
    f.clock.set(at(11.0));
    assert_eq!(s.get("p1").await.unwrap(), None);
    assert!(matches!(
        s.progress("p1", "r1", at(11.0), (5.0, 0.0), None).await,
        Err(TrafficError::NotFound { .. })
    ));
    // The next commit purges the row: its plan id is free again (another robot's now).
    assert_eq!(rows(&f).await, 2);
    let mut again = straight("p1", "r9", "f1", [0.0, 6.0], [5.0, 6.0]);
    again.start_unix_ms = at(11.0);
    again.expires_unix_ms = at(100.0);
    assert_eq!(s.commit(again.clone(), 2).await.unwrap(), 3);
    assert_eq!(rows(&f).await, 2);
    assert_eq!(s.get("p1").await.unwrap(), Some(again));
    // An itinerary that expired before it was committed is refused.
    let mut stale = straight("p3", "r3", "f1", [0.0, 0.0], [1.0, 0.0]);
    stale.expires_unix_ms = at(10.0);
    assert!(matches!(
        s.commit(stale, 3).await,
        Err(TrafficError::Invalid(m)) if m.contains("already past")
    ));
}

/// The rows in `traffic_itineraries`, expired or not.
async fn rows(f: &Fixture) -> i64 {
    const COUNT: &str = "SELECT COUNT(*) FROM traffic_itineraries";
    match (f.db.sqlite_pool(), f.db.postgres_pool()) {
        (Some(pool), _) => sqlx::query_scalar(COUNT).fetch_one(pool).await.unwrap(),
        (_, Some(pool)) => sqlx::query_scalar(COUNT).fetch_one(pool).await.unwrap(),
        _ => unreachable!(),
    }
}

async fn bad_itineraries_are_refused_naming_what_is_wrong(f: Fixture) {
    let s = &f.schedule;
    let good = || straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]);
    fn pose(t_s: f64) -> TimedPose {
        TimedPose {
            t_s,
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
        }
    }
    type Edit = Box<dyn Fn(&mut Itinerary)>;
    let cases: Vec<(&str, Edit)> = vec![
        ("plan_id is empty", Box::new(|it| it.plan_id.clear())),
        ("robot is empty", Box::new(|it| it.robot = " ".into())),
        (
            "floor is 201 bytes",
            Box::new(|it| it.floor = "f".repeat(201)),
        ),
        (
            "the trajectory is empty",
            Box::new(|it| it.trajectory.clear()),
        ),
        (
            "trajectory[2].t_s is NaN",
            Box::new(|it| it.trajectory[2].t_s = f64::NAN),
        ),
        (
            "trajectory[1].x is inf",
            Box::new(|it| it.trajectory[1].x = f64::INFINITY),
        ),
        (
            "trajectory[0].t_s is -1",
            Box::new(|it| it.trajectory[0].t_s = -1.0),
        ),
        (
            "trajectory[1].t_s is 0, not after",
            Box::new(|it| it.trajectory = vec![pose(0.0), pose(0.0)]),
        ),
        ("radius_m is 0", Box::new(|it| it.radius_m = 0.0)),
        ("radius_m is NaN", Box::new(|it| it.radius_m = f64::NAN)),
        ("tolerance_s is -1", Box::new(|it| it.tolerance_s = -1.0)),
        ("delay_s is NaN", Box::new(|it| it.delay_s = f64::NAN)),
        (
            "is before the trajectory ends",
            Box::new(|it| it.expires_unix_ms = at(4.0)),
        ),
        (
            "lasts 100000 s",
            Box::new(|it| it.trajectory = vec![pose(0.0), pose(100_000.0)]),
        ),
    ];
    for (expected, edit) in cases {
        let mut it = good();
        edit(&mut it);
        match s.commit(it, 0).await {
            Err(TrafficError::Invalid(message)) => {
                assert!(
                    message.contains(expected),
                    "{expected:?} not in {message:?}"
                );
            }
            other => panic!("{expected}: {other:?}"),
        }
    }
    assert!(matches!(
        s.commit(good(), -1).await,
        Err(TrafficError::Invalid(m)) if m.contains("expected_version")
    ));
    // Nothing was written.
    assert_eq!(s.snapshot("f1", START_MS).await.unwrap(), (0, vec![]));
}

async fn this_processs_changes_are_broadcast_in_order(f: Fixture) {
    let s = &f.schedule;
    let mut changes = s.changes();
    let a = straight("p1", "r1", "f1", [0.0, 0.0], [5.0, 0.0]);
    s.commit(a.clone(), 0).await.unwrap();
    let b = straight("p2", "r1", "f2", [0.0, 0.0], [5.0, 0.0]);
    s.commit(b.clone(), 0).await.unwrap();
    f.clock.set(at(2.0));
    let progressed = s
        .progress("p2", "r1", at(2.0), (1.0, 0.0), None)
        .await
        .unwrap()
        .itinerary;
    s.cancel("p2").await.unwrap();
    let mut seen = Vec::new();
    while let Ok(change) = changes.try_recv() {
        seen.push(change);
    }
    let removed = |floor: &str, version, plan_id: &str, reason| Change::Removed {
        floor: floor.into(),
        version,
        plan_id: plan_id.into(),
        robot: "r1".into(),
        reason,
    };
    assert_eq!(
        seen,
        vec![
            Change::Committed {
                version: 1,
                itinerary: a
            },
            removed("f1", 2, "p1", Removal::Replaced),
            Change::Committed {
                version: 1,
                itinerary: b
            },
            Change::Progressed {
                version: 2,
                itinerary: progressed
            },
            removed("f2", 3, "p2", Removal::Cancelled),
        ]
    );
    assert_eq!((seen[1].floor(), seen[1].version()), ("f1", 2));
    // Another process's commits are seen through the version only.
    let other = f.another_process().await;
    other
        .commit(straight("p3", "r3", "f2", [0.0, 0.0], [5.0, 0.0]), 3)
        .await
        .unwrap();
    assert!(changes.try_recv().is_err());
    assert_eq!(s.version("f2").await.unwrap(), 4);
}

/// Many robots on one floor, committing through two handles with pools of their own (as two
/// API processes would) against the version they read.
async fn racing_commits_from_two_processes_elect_one_winner_per_version(f: Fixture) {
    const ROBOTS: usize = 12;
    let handles = [f.schedule.clone(), f.another_process().await];
    let plan = |i: usize| {
        let y = 2.0 * i as f64;
        straight(&format!("p{i}"), &format!("r{i}"), "f1", [0.0, y], [5.0, y])
    };

    // Round one: everyone commits against version 0 at once. Exactly one wins.
    let barrier = Arc::new(tokio::sync::Barrier::new(ROBOTS));
    let tasks: Vec<_> = (0..ROBOTS)
        .map(|i| {
            let s: Schedule = handles[i % 2].clone();
            let barrier = barrier.clone();
            let it = plan(i);
            tokio::spawn(async move {
                barrier.wait().await;
                s.commit(it, 0).await
            })
        })
        .collect();
    let mut winners = Vec::new();
    for (i, task) in tasks.into_iter().enumerate() {
        match task.await.unwrap() {
            Ok(version) => winners.push((i, version)),
            Err(TrafficError::VersionChanged {
                expected: 0,
                now: 1,
                ..
            }) => {}
            Err(other) => panic!("robot {i}: {other:?}"),
        }
    }
    assert_eq!(winners.len(), 1, "{winners:?}");
    assert_eq!(winners[0].1, 1);
    let first = winners[0].0;

    // Round two: the others retry, each reading a snapshot and committing against its version,
    // until all are in. Every success takes a version no one else got.
    let tasks: Vec<_> = (0..ROBOTS)
        .filter(|&i| i != first)
        .map(|i| {
            let s: Schedule = handles[i % 2].clone();
            let it = plan(i);
            tokio::spawn(async move {
                let mut refused = 0;
                loop {
                    let (version, _) = s.snapshot("f1", START_MS).await.unwrap();
                    match s.commit(it.clone(), version).await {
                        Ok(new) => {
                            assert_eq!(new, version + 1);
                            return (new, refused);
                        }
                        Err(TrafficError::VersionChanged { expected, now, .. }) => {
                            assert_eq!(expected, version);
                            assert!(now > version);
                            refused += 1;
                            tokio::time::sleep(Duration::from_millis(1)).await;
                        }
                        Err(other) => panic!("robot {i}: {other:?}"),
                    }
                }
            })
        })
        .collect();
    let mut versions = vec![1];
    for task in tasks {
        let (version, _refused) = task.await.unwrap();
        versions.push(version);
    }
    versions.sort_unstable();
    let expected: Vec<i64> = (1..=ROBOTS as i64).collect();
    assert_eq!(versions, expected, "one winner per version");
    // No itinerary was lost, none doubled; both processes see the same floor.
    for s in &handles {
        let (version, itineraries) = s.snapshot("f1", START_MS).await.unwrap();
        assert_eq!(version, ROBOTS as i64);
        let mut robots: Vec<String> = itineraries.into_iter().map(|it| it.robot).collect();
        robots.sort();
        let mut all: Vec<String> = (0..ROBOTS).map(|i| format!("r{i}")).collect();
        all.sort();
        assert_eq!(robots, all);
    }
}

/// `straight`, told to start `start_s` after `START_MS` (standing at its start until then).
fn later(plan_id: &str, robot: &str, from: [f64; 2], to: [f64; 2], start_s: f64) -> Itinerary {
    let mut it = straight(plan_id, robot, "f1", from, to);
    for p in &mut it.trajectory {
        p.t_s += start_s;
    }
    it.trajectory.insert(
        0,
        TimedPose {
            t_s: 0.0,
            ..it.trajectory[0]
        },
    );
    it.expires_unix_ms = at(it.trajectory.last().unwrap().t_s + 60.0);
    it
}

async fn revisions_replace_plans_whose_robots_have_not_set_off_all_or_none(f: Fixture) {
    let s = &f.schedule;
    let a = later("p1", "r1", [0.0, 0.0], [5.0, 0.0], 20.0);
    let b = later("p2", "r2", [0.0, 3.0], [5.0, 3.0], 30.0);
    s.commit(a.clone(), 0).await.unwrap();
    s.commit(b.clone(), 1).await.unwrap();
    let mut changes = s.changes();
    // Both earlier, in one revision, against the version they were read at.
    let sooner_a = later("p1", "r1", [0.0, 0.0], [5.0, 0.0], 10.0);
    let sooner_b = later("p2", "r2", [0.0, 3.0], [5.0, 3.0], 12.0);
    let (version, revised) = s
        .revise(vec![sooner_a.clone(), sooner_b.clone()], 2)
        .await
        .unwrap();
    assert_eq!(version, 3);
    assert_eq!(
        revised.iter().map(|it| it.revision).collect::<Vec<_>>(),
        [2, 2]
    );
    let read = s.plan("p1").await.unwrap().unwrap();
    assert_eq!(
        read.itinerary,
        Itinerary {
            revision: 2,
            ..sooner_a.clone()
        }
    );
    assert_eq!(
        read.acknowledged, 1,
        "the robot has not acknowledged it yet"
    );
    assert_eq!(read.itinerary.departs_unix_ms(), at(10.0));
    let seen: Vec<_> = std::iter::from_fn(|| changes.try_recv().ok()).collect();
    assert_eq!(
        seen,
        revised
            .iter()
            .map(|it| Change::Revised {
                version: 3,
                itinerary: it.clone()
            })
            .collect::<Vec<_>>()
    );
    // A stale version changes nothing; nor does a batch with one bad plan (all or none).
    let stale = s.revise(vec![a.clone()], 2).await.unwrap_err();
    assert!(
        matches!(stale, TrafficError::VersionChanged { now: 3, .. }),
        "{stale:?}"
    );
    let elsewhere = later("p2", "r2", [4.0, 3.0], [5.0, 3.0], 12.0);
    let err = s.revise(vec![a.clone(), elsewhere], 3).await.unwrap_err();
    assert!(
        matches!(&err, TrafficError::Invalid(m) if m.contains("p2") && m.contains("stands at")),
        "{err:?}"
    );
    let unknown = s
        .revise(
            vec![a.clone(), later("p9", "r9", [0.0, 6.0], [5.0, 6.0], 10.0)],
            3,
        )
        .await
        .unwrap_err();
    assert!(
        matches!(&unknown, TrafficError::NotFound { plan_id } if plan_id == "p9"),
        "{unknown:?}"
    );
    let twice = s.revise(vec![a.clone(), a.clone()], 3).await.unwrap_err();
    assert!(
        matches!(&twice, TrafficError::Invalid(m) if m.contains("twice")),
        "{twice:?}"
    );
    let thief = Itinerary {
        robot: "r2".into(),
        ..a.clone()
    };
    let err = s.revise(vec![thief], 3).await.unwrap_err();
    assert!(
        matches!(&err, TrafficError::Invalid(m) if m.contains("r1")),
        "{err:?}"
    );
    assert_eq!(s.version("f1").await.unwrap(), 3);
    assert_eq!(s.plan("p1").await.unwrap().unwrap().itinerary.revision, 2);
    // Another process sees the revision.
    let other = f.another_process().await;
    assert_eq!(
        other.plan("p2").await.unwrap().unwrap().itinerary.revision,
        2
    );
    // A new commit of the robot starts again at revision 1.
    s.commit(b.clone(), 3).await.unwrap();
    assert_eq!(s.plan("p2").await.unwrap().unwrap().itinerary.revision, 1);
}

async fn a_revision_of_a_robot_that_set_off_is_refused(f: Fixture) {
    let s = &f.schedule;
    let a = later("p1", "r1", [0.0, 0.0], [5.0, 0.0], 10.0);
    s.commit(a.clone(), 0).await.unwrap();
    // Told to leave at 10 s, within 1 s of tolerance: at 7.9 s a revision may still reach it,
    // from 8 s on (tolerance and notice) not.
    f.clock.set(at(7.9));
    assert!(!s.plan("p1").await.unwrap().unwrap().set_off(at(7.9)));
    let (version, _) = s.revise(vec![a.clone()], 1).await.unwrap();
    f.clock.set(at(8.0));
    let err = s.revise(vec![a.clone()], version).await.unwrap_err();
    match err {
        TrafficError::SetOff {
            plan_id,
            departs_unix_ms,
            ..
        } => {
            assert_eq!((plan_id.as_str(), departs_unix_ms), ("p1", at(10.0)));
        }
        other => panic!("{other:?}"),
    }
    // A progress report that matches it past its start: set off, whatever the clock says.
    let b = later("p2", "r2", [0.0, 3.0], [5.0, 3.0], 10.0);
    s.commit(b.clone(), version).await.unwrap();
    f.clock.set(at(2.0));
    let moved = s
        .progress("p2", "r2", at(2.0), (2.0, 3.0), None)
        .await
        .unwrap();
    assert!(moved.set_off(at(2.0)), "{moved:?}");
    let version = s.version("f1").await.unwrap();
    assert!(matches!(
        s.revise(vec![b], version).await,
        Err(TrafficError::SetOff { .. })
    ));
}

async fn progress_acknowledges_revisions_it_was_sent_and_no_others(f: Fixture) {
    let s = &f.schedule;
    let a = later("p1", "r1", [0.0, 0.0], [5.0, 0.0], 20.0);
    s.commit(a.clone(), 0).await.unwrap();
    s.revise(vec![later("p1", "r1", [0.0, 0.0], [5.0, 0.0], 15.0)], 1)
        .await
        .unwrap();
    f.clock.set(at(1.0));
    for never in [0, 3] {
        match s
            .progress("p1", "r1", at(1.0), (0.0, 0.0), Some(never))
            .await
        {
            Err(TrafficError::UnknownRevision {
                plan_id,
                acknowledged,
                current,
            }) => {
                assert_eq!((plan_id.as_str(), acknowledged, current), ("p1", never, 2));
            }
            other => panic!("{other:?}"),
        }
    }
    let acked = s
        .progress("p1", "r1", at(1.0), (0.0, 0.0), Some(2))
        .await
        .unwrap();
    assert_eq!((acked.acknowledged, acked.itinerary.revision), (2, 2));
    // Standing at its start before its time is on time, and not set off.
    assert!(!acked.set_off(at(1.0)), "{acked:?}");
    // An older acknowledgement does not take it back.
    let again = s
        .progress("p1", "r1", at(1.0), (0.0, 0.0), Some(1))
        .await
        .unwrap();
    assert_eq!(again.acknowledged, 2);
    assert_eq!(s.plan("p1").await.unwrap().unwrap().acknowledged, 2);
}
