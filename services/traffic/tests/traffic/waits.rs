//! Waits in the schedule's database: what one process posts, another sees, until the plan
//! stops waiting or the wait ends; bad waits are refused naming what is wrong.

use crate::common::{Fixture, at};
use traffic::{TrafficError, Wait};

fixtures::on_both_backends!(
    crate::common::sqlite,
    crate::common::postgres,
    [
        a_wait_posted_by_one_process_is_seen_by_another_until_cleared_or_ended,
        bad_waits_are_refused_naming_what_is_wrong,
    ]
);

fn wait(robot: &str, floor: &str, by: &[&str], until_s: f64) -> Wait {
    Wait {
        robot: robot.to_owned(),
        floor: floor.to_owned(),
        by: by.iter().map(|s| (*s).to_owned()).collect(),
        route: vec![(0.0, 0.0), (1.5, 0.25)],
        radius_m: 0.3,
        cannot_make_way: false,
        until_unix_ms: at(until_s),
    }
}

async fn a_wait_posted_by_one_process_is_seen_by_another_until_cleared_or_ended(f: Fixture) {
    let other = f.another_process().await;
    let a = wait("A", "f1", &["B"], 10.0);
    f.schedule.post_wait(&a).await.unwrap();
    f.schedule
        .post_wait(&wait("C", "f2", &["D"], 10.0))
        .await
        .unwrap();
    // Read back exactly as written, on its own floor only.
    assert_eq!(other.waits_on("f1").await.unwrap(), vec![a.clone()]);
    // Posting again replaces the robot's wait (here: it found no place to make way at).
    let mut again = a.clone();
    again.cannot_make_way = true;
    other.post_wait(&again).await.unwrap();
    let b = wait("B", "f1", &["A"], 4.0);
    other.post_wait(&b).await.unwrap();
    assert_eq!(
        f.schedule.waits_on("f1").await.unwrap(),
        vec![again.clone(), b]
    );
    // B's wait ends at 4 s: it is gone after, A's is not.
    f.clock.set(at(5.0));
    assert_eq!(f.schedule.waits_on("f1").await.unwrap(), vec![again]);
    // A's plan stops waiting.
    other.clear_wait("A").await.unwrap();
    assert!(f.schedule.waits_on("f1").await.unwrap().is_empty());
    assert_eq!(f.schedule.waits_on("f2").await.unwrap().len(), 1);
    // Clearing a wait nobody posted is no error.
    f.schedule.clear_wait("nobody").await.unwrap();
}

async fn bad_waits_are_refused_naming_what_is_wrong(f: Fixture) {
    let cases: Vec<(Wait, &str)> = vec![
        (wait("", "f1", &["B"], 10.0), "robot"),
        (wait("A", &"f".repeat(300), &["B"], 10.0), "floor"),
        (wait("A", "f1", &[""], 10.0), "standing robot"),
        (
            Wait {
                radius_m: f64::NAN,
                ..wait("A", "f1", &["B"], 10.0)
            },
            "radius",
        ),
        (
            Wait {
                route: vec![(f64::INFINITY, 0.0)],
                ..wait("A", "f1", &["B"], 10.0)
            },
            "route",
        ),
    ];
    for (w, names) in cases {
        match f.schedule.post_wait(&w).await {
            Err(TrafficError::Invalid(m)) => assert!(m.contains(names), "{names}: {m}"),
            other => panic!("{names}: {other:?}"),
        }
    }
    assert!(f.schedule.waits_on("f1").await.unwrap().is_empty());
}
