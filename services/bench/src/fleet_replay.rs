//! The joint run of `bench fleet` as a file the console's Traffic page replays
//! (`--replay DIR`): the floor, every robot's trajectory as it drove in the joint run (as an
//! itinerary of the traffic schedule, so the page draws it as it draws live traffic) and how
//! each robot fared.

use planner::PlanOutcome;
use rehearsal::AmongReport;
use serde::Serialize;
use traffic::{Itinerary, TimedPose};

/// Poses kept per second of a driven trajectory (the simulation steps at 10–20 Hz).
const POSES_PER_S: f64 = 5.0;
/// How long a robot stays on the page after its joint drive ended, seconds.
const PARKED_S: f64 = 30.0;

/// A joint run: what `GET /v1/places/{id}/traffic` answers, for the robots as they drove
/// together, and their outcomes.
#[derive(Debug, Clone, Serialize)]
pub struct JointReplay {
    /// The map's short name.
    pub map: String,
    /// The scenario.
    pub scenario: String,
    /// The floor's IRI (an import of the map under its file name has the same one).
    pub floor: String,
    /// Always 0: not a schedule's version.
    pub version: i64,
    /// Each robot's joint drive.
    pub plans: Vec<Itinerary>,
    /// How each robot fared.
    pub joint: Vec<JointOutcome>,
}

/// How one robot fared in the joint run.
#[derive(Debug, Clone, Serialize)]
pub struct JointOutcome {
    /// The robot's IRI.
    pub robot: String,
    /// `reached`, `collision`, `stalled`, or `error`.
    pub outcome: String,
    /// Why, in words.
    pub reason: String,
    /// When its drive ended, seconds after its plan's start.
    pub time_s: f64,
}

/// The joint run of `planned` (`joint[k]` is `planned[k]`'s drive among the others).
pub fn joint_replay(
    map: &str,
    scenario: &str,
    floor: &str,
    planned: &[PlanOutcome],
    joint: &[Result<AmongReport, String>],
) -> JointReplay {
    let mut plans = Vec::new();
    let mut outcomes = Vec::new();
    for (o, j) in planned.iter().zip(joint) {
        let Some(fleet) = o.fleet.as_ref() else {
            continue;
        };
        match j {
            Ok(r) => {
                let itinerary = driven(&fleet.itinerary, r);
                outcomes.push(JointOutcome {
                    robot: o.robot.clone(),
                    outcome: r.outcome.as_str().to_owned(),
                    reason: r.reason.clone(),
                    time_s: r.time_s,
                });
                plans.extend(itinerary);
            }
            Err(e) => outcomes.push(JointOutcome {
                robot: o.robot.clone(),
                outcome: "error".to_owned(),
                reason: e.clone(),
                time_s: 0.0,
            }),
        }
    }
    JointReplay {
        map: map.to_owned(),
        scenario: scenario.to_owned(),
        floor: floor.to_owned(),
        version: 0,
        plans,
        joint: outcomes,
    }
}

/// The drive `r` as an itinerary like `committed` (same plan, robot, floor, start, radius):
/// its steps thinned to [`POSES_PER_S`], the last one always kept; `None` without steps.
fn driven(committed: &Itinerary, r: &AmongReport) -> Option<Itinerary> {
    let dt = r.control_period_s;
    let every = ((1.0 / POSES_PER_S) / dt).round().max(1.0) as usize;
    let last = r.steps.len().checked_sub(1)?;
    let trajectory: Vec<TimedPose> = r
        .steps
        .iter()
        .enumerate()
        .filter(|(k, _)| k % every == 0 || *k == last)
        .map(|(k, p)| TimedPose {
            t_s: k as f64 * dt,
            x: p.x,
            y: p.y,
            yaw: p.yaw,
        })
        .collect();
    let end_s = trajectory.last().map_or(0.0, |p| p.t_s);
    Some(Itinerary {
        trajectory,
        tolerance_s: 0.0,
        delay_s: 0.0,
        expires_unix_ms: committed.start_unix_ms + ((end_s + PARKED_S) * 1000.0) as i64,
        ..committed.clone()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drive_becomes_a_valid_itinerary_at_five_poses_a_second() {
        let committed = Itinerary {
            plan_id: "p".into(),
            robot: "r".into(),
            floor: "https://f".into(),
            start_unix_ms: 1_000,
            trajectory: vec![TimedPose {
                t_s: 0.0,
                x: 0.0,
                y: 0.0,
                yaw: 0.0,
            }],
            radius_m: 0.3,
            tolerance_s: 2.0,
            expires_unix_ms: 100_000,
            delay_s: 0.0,
            revision: 1,
        };
        let steps: Vec<sim::Pose2> = (0..=31)
            .map(|k| sim::Pose2::new(f64::from(k) * 0.1, 0.0, 0.0))
            .collect();
        let report = AmongReport {
            outcome: rehearsal::AttemptOutcome::Reached,
            reason: "reached".into(),
            time_s: 3.1,
            min_robot_clearance_m: None,
            robots: 0,
            steps,
            control_period_s: 0.1,
            people_draw: 0,
        };
        let it = driven(&committed, &report).unwrap();
        it.check().unwrap();
        let times: Vec<f64> = it.trajectory.iter().map(|p| p.t_s).collect();
        assert_eq!(times.len(), 17, "every second step and the last: {times:?}");
        assert!((times[16] - 3.1).abs() < 1e-9);
        assert_eq!(it.expires_unix_ms, 1_000 + 33_100);
        assert_eq!((it.plan_id.as_str(), it.radius_m), ("p", 0.3));
    }
}
