//! The idle-time improver: a large-neighbourhood search over a floor's committed plans, in the
//! manner of MAPF-LNS (Li et al., IJCAI 2021), with the robots' own controllers among people.
//!
//! First-come commits fix the order in which robots pass each other: the robot that asked
//! first goes first, wherever it is going. [`Planner::improve`] takes the robot that ends last
//! (then the next, and so on) and the robots it waits for, takes their plans out of the floor's
//! schedule, and fits them again one after the other in other orders (the robot that ends last
//! first, the others in their order of departure, or reversed; or in the same order, which picks
//! up room that cancelled or finished plans left). Each is fitted ([`fleet::fit`]) among the
//! plans it does not replace, the neighbourhood's plans fitted before it and the robots of the
//! neighbourhood still to be fitted, which stand at their starts meanwhile; and each is driven
//! again with its waits among them and the people ([`crate::replay`]), as a plan joining the
//! floor is. The neighbourhood is revised ([`FleetSchedule::revise`], all of it or none, against
//! the floor's version) where the floor's plans are better for it ([`Totals::improves_on`]:
//! neither the makespan nor the sum of times rises and one drops, or the makespan drops by
//! more than the mean time rises).
//!
//! Invariants: nothing is revised that was not driven among the plans it was fitted against
//! (the same rule as a commit's); a plan is revised only while its robot has not set off (it
//! departs at least [`LEAD_MS`] plus its tolerance and [`traffic::REVISION_NOTICE_S`] after the
//! neighbourhood was read, and the schedule refuses a revision of a robot that may have left);
//! the process revises only the plans it planned (it holds their simulations, [`Revisables`]).
//! The improver waits behind every plan for the cores and gives way as soon as one waits.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use traffic::Itinerary;

use crate::fleet::{self, Committed, FleetOptions, FleetOutcome, FleetSchedule};
use crate::{PlanFailure, PlanOutcome, Planner};

/// Most plans re-planned together.
pub const MAX_NEIGHBOURHOOD: usize = 4;
/// How long re-planning a neighbourhood may take, from reading the floor to revising it, ms:
/// a robot of the neighbourhood must not be told to set off sooner than this (plus its
/// tolerance and the notice a revision takes) after the floor was read, and a neighbourhood
/// that took longer is not revised.
pub const LEAD_MS: i64 = 5_000;
/// Least gain a revision is made for, seconds of makespan or of the sum of times.
pub const MIN_GAIN_S: f64 = 0.5;
/// Times a plan of a neighbourhood is fitted again on its own drive (which arrived within the
/// margin of another robot's schedule) before the neighbourhood is given up, as
/// `joining::REFITS_ON_DRIVE` for a plan joining the floor.
const REFITS_ON_DRIVE: u32 = 3;
/// The improver's place in line for the cores: behind every plan.
const IDLE_TICKET: u64 = u64::MAX;

/// A floor's makespan and sum of times, as its committed plans say.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Totals {
    /// From the earliest start to the last arrival among the plans that move, seconds.
    pub makespan_s: f64,
    /// Each moving plan's arrival less its start, summed, seconds.
    pub sum_s: f64,
    /// The plans that move.
    pub plans: usize,
}

impl Totals {
    /// The totals of `plans` (`None` where none moves).
    pub fn of<'a>(plans: impl IntoIterator<Item = &'a Itinerary>) -> Option<Totals> {
        let moving: Vec<&Itinerary> = plans
            .into_iter()
            .filter(|i| !fleet::stands_only(i))
            .collect();
        let origin = moving.iter().map(|i| i.start_unix_ms).min()?;
        let end = moving.iter().map(|i| i.end_unix_ms()).max()?;
        Some(Totals {
            makespan_s: (end - origin) as f64 / 1000.0,
            sum_s: moving
                .iter()
                .map(|i| (i.end_unix_ms() - i.start_unix_ms) as f64 / 1000.0)
                .sum(),
            plans: moving.len(),
        })
    }

    /// Whether `self` is better than `before` by the rule the improver keeps revisions by:
    /// neither the makespan nor the sum of times rises and one drops by [`MIN_GAIN_S`]; or the
    /// makespan drops by that much and more than the mean time rises (makespan plus mean time,
    /// both seconds, drops). The second admits a robot that waited longest going first at a
    /// small cost to the others: on the plant with 10 robots among people, a neighbourhood
    /// that cut the makespan from 168.0 to 152.5 s raised the sum of times by 17.6 s of 924.
    pub fn improves_on(&self, before: &Totals) -> bool {
        let (dm, ds) = (
            before.makespan_s - self.makespan_s,
            before.sum_s - self.sum_s,
        );
        let pareto = dm >= -1e-9 && ds >= -1e-9 && (dm >= MIN_GAIN_S || ds >= MIN_GAIN_S);
        let n = self.plans.max(before.plans).max(1) as f64;
        pareto || (dm >= MIN_GAIN_S && dm + ds / n > 1e-9)
    }
}

/// What [`Planner::improve`] did on a floor.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Improvement {
    /// Neighbourhood orders re-planned (fitted and driven, or refused on the way).
    pub tried: u32,
    /// Revisions made.
    pub kept: u32,
    /// The plans revised, in the order revised (a plan may be revised more than once).
    pub revised: Vec<String>,
    /// Drives among the fleet it took.
    pub drives: u32,
    /// The floor's totals when it began (`None`: nothing moves on it).
    pub before: Option<Totals>,
    /// The floor's totals after its last revision (`before` where it made none).
    pub after: Option<Totals>,
}

/// A committed plan this process planned, with what driving it again needs.
#[derive(Debug, Clone)]
struct Revisable {
    outcome: PlanOutcome,
    options: FleetOptions,
}

impl Revisable {
    fn fleet(&self) -> Option<&FleetOutcome> {
        self.outcome.fleet.as_ref()
    }

    fn plan_id(&self) -> &str {
        self.fleet().map_or("", |f| f.itinerary.plan_id.as_str())
    }
}

/// The plans of one floor this process may revise, and the orders already tried among the
/// floor's plans as they are ([`Read::state`]; drives are deterministic: the same order among
/// the same plans is not driven twice).
#[derive(Debug, Default)]
struct FloorPlans {
    plans: Vec<Revisable>,
    tried_at: u64,
    tried: Vec<Vec<String>>,
}

/// The committed plans this process planned, by floor: the improver's to revise.
#[derive(Debug, Default)]
pub(crate) struct Revisables(Mutex<HashMap<String, FloorPlans>>);

impl Revisables {
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, FloorPlans>> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Keeps `outcome` (when it was committed), replacing its robot's earlier plan.
    pub(crate) fn register(&self, outcome: &PlanOutcome, options: FleetOptions) {
        if outcome.fleet.as_ref().and_then(|f| f.version).is_none() {
            return;
        }
        let mut floors = self.lock();
        let floor = floors.entry(outcome.floor.clone()).or_default();
        floor.plans.retain(|r| r.outcome.robot != outcome.robot);
        floor.plans.push(Revisable {
            outcome: outcome.clone(),
            options,
        });
    }

    fn floors(&self) -> Vec<String> {
        let mut floors = self.lock();
        floors.retain(|_, f| !f.plans.is_empty());
        floors.keys().cloned().collect()
    }

    /// The plans of `floor` still in `schedule` (the others are forgotten: cancelled,
    /// replaced or expired).
    fn of(&self, floor: &str, schedule: &[Itinerary]) -> Vec<Revisable> {
        let mut floors = self.lock();
        let Some(f) = floors.get_mut(floor) else {
            return Vec::new();
        };
        f.plans
            .retain(|r| schedule.iter().any(|i| i.plan_id == r.plan_id()));
        f.plans.clone()
    }

    /// Whether `order` was tried at `version` already; marks it tried.
    fn tried(&self, floor: &str, state: u64, order: &[String]) -> bool {
        let mut floors = self.lock();
        let f = floors.entry(floor.to_owned()).or_default();
        if f.tried_at != state {
            f.tried_at = state;
            f.tried.clear();
        }
        if f.tried.iter().any(|o| o == order) {
            return true;
        }
        f.tried.push(order.to_vec());
        false
    }

    /// Forgets that `order` was tried: its revision was found but lost to the floor changing,
    /// or came too late, and the next round tries it again.
    fn untried(&self, floor: &str, order: &[String]) {
        if let Some(f) = self.lock().get_mut(floor) {
            f.tried.retain(|o| o != order);
        }
    }

    fn revised(&self, floor: &str, revised: Vec<FleetOutcome>) {
        let mut floors = self.lock();
        let Some(f) = floors.get_mut(floor) else {
            return;
        };
        for new in revised {
            if let Some(r) = f
                .plans
                .iter_mut()
                .find(|r| r.plan_id() == new.itinerary.plan_id)
            {
                r.outcome.fleet = Some(new);
            }
        }
    }

    fn outcome(&self, plan_id: &str) -> Option<PlanOutcome> {
        self.lock()
            .values()
            .flat_map(|f| &f.plans)
            .find(|r| r.plan_id() == plan_id)
            .map(|r| r.outcome.clone())
    }
}

/// How one neighbourhood search went.
enum Round {
    /// A neighbourhood was revised: search again on the new schedule.
    Kept,
    /// The floor changed under it: search again.
    Lost,
    /// Nothing left to try (or the time or the cores ran out).
    Done,
}

/// The floor as one search read it.
struct Read {
    version: i64,
    now_ms: i64,
    plans: Vec<Itinerary>,
}

impl Read {
    /// The floor's plans as far as a neighbourhood's fit depends on them: each plan, its
    /// revision, start and delay (to a tenth of a second). The floor's version alone changes
    /// with every progress report, which moves a plan only where its robot is late.
    fn state(&self) -> u64 {
        let mut ids: Vec<String> = self
            .plans
            .iter()
            .map(|i| {
                format!(
                    "{} {} {} {}",
                    i.plan_id,
                    i.revision,
                    i.start_unix_ms,
                    (i.delay_s * 10.0).round()
                )
            })
            .collect();
        ids.sort();
        grid::hash::fnv1a(ids.join("\n").as_bytes())
    }

    fn current(&self, plan_id: &str) -> Option<&Itinerary> {
        self.plans.iter().find(|i| i.plan_id == plan_id)
    }
}

impl Planner {
    /// Improves the schedule of `floor` for up to `budget` (see the module docs); what it did.
    /// Without a fleet schedule, or with no plan of this process on the floor, it does nothing.
    pub async fn improve(&self, floor: &str, budget: Duration) -> Result<Improvement, PlanFailure> {
        let mut out = Improvement::default();
        let Some(schedule) = self.fleet.clone() else {
            return Ok(out);
        };
        let deadline = Instant::now() + budget;
        while Instant::now() < deadline {
            match self
                .improve_once(&*schedule, floor, deadline, &mut out)
                .await?
            {
                Round::Kept | Round::Lost => {}
                Round::Done => break,
            }
        }
        Ok(out)
    }

    /// The floors on which this process holds plans it may revise.
    pub fn revisable_floors(&self) -> Vec<String> {
        self.revisables.floors()
    }

    /// The plan `plan_id` as this process last committed or revised it (`None`: not one of its
    /// plans, or no longer in the schedule when it last looked).
    pub fn committed_outcome(&self, plan_id: &str) -> Option<PlanOutcome> {
        self.revisables.outcome(plan_id)
    }

    async fn improve_once(
        &self,
        schedule: &dyn FleetSchedule,
        floor: &str,
        deadline: Instant,
        out: &mut Improvement,
    ) -> Result<Round, PlanFailure> {
        let (version, plans) = schedule.snapshot(floor).await?;
        let read = Read {
            version,
            now_ms: schedule.now_ms(),
            plans,
        };
        let before = Totals::of(&read.plans);
        if out.before.is_none() {
            out.before = before;
        }
        out.after = before;
        let Some(before) = before else {
            return Ok(Round::Done);
        };
        let mine = self.revisables.of(floor, &read.plans);
        let revisable: Vec<&Revisable> = mine
            .iter()
            .filter(|r| {
                read.current(r.plan_id()).is_some_and(|it| {
                    r.fleet()
                        .is_some_and(|f| f.itinerary.revision == it.revision)
                        && revisable_until_ms(it) > read.now_ms + LEAD_MS
                })
            })
            .collect();
        // The robots that end last first.
        let mut by_end: Vec<&Itinerary> = read
            .plans
            .iter()
            .filter(|i| !fleet::stands_only(i))
            .collect();
        by_end.sort_by_key(|i| std::cmp::Reverse(i.end_unix_ms()));
        for last in by_end {
            let Some(&r) = revisable.iter().find(|r| r.plan_id() == last.plan_id) else {
                continue;
            };
            let waited: f64 = r
                .fleet()
                .map_or(0.0, |f| f.waits.iter().map(|w| w.wait_s).sum());
            if waited < MIN_GAIN_S {
                continue;
            }
            for order in orders(r, &revisable, &read) {
                if Instant::now() >= deadline || self.cpu.busy() {
                    return Ok(Round::Done);
                }
                let ids: Vec<String> = order.iter().map(|r| r.plan_id().to_owned()).collect();
                if self.revisables.tried(floor, read.state(), &ids) {
                    continue;
                }
                out.tried += 1;
                let Some(placed) = self.replan(&order, &read, out).await? else {
                    continue;
                };
                let after = Totals::of(
                    read.plans
                        .iter()
                        .filter(|i| !ids.contains(&i.plan_id))
                        .chain(placed.iter().map(|f| &f.itinerary)),
                );
                if !after.is_some_and(|a| a.improves_on(&before)) {
                    tracing::debug!(?ids, ?before, ?after, "improver: no gain");
                    continue;
                }
                if schedule.now_ms() > read.now_ms + LEAD_MS {
                    self.revisables.untried(floor, &ids);
                    return Ok(Round::Lost);
                }
                let itineraries = placed.iter().map(|f| f.itinerary.clone()).collect();
                match schedule.revise(itineraries, read.version).await? {
                    Committed::Yes(v) => {
                        let placed: Vec<FleetOutcome> = placed
                            .into_iter()
                            .map(|mut f| {
                                f.itinerary.revision += 1;
                                f.version = Some(v);
                                f
                            })
                            .collect();
                        out.kept += 1;
                        out.revised.extend(ids);
                        out.after = after;
                        tracing::info!(
                            floor,
                            version = v,
                            plans = ?placed.iter().map(|f| (&f.itinerary.robot, f.itinerary.revision)).collect::<Vec<_>>(),
                            makespan_s = after.map(|a| a.makespan_s),
                            sum_s = after.map(|a| a.sum_s),
                            "the floor's plans improved"
                        );
                        self.revisables.revised(floor, placed);
                        return Ok(Round::Kept);
                    }
                    Committed::VersionChanged => {
                        self.revisables.untried(floor, &ids);
                        return Ok(Round::Lost);
                    }
                    Committed::Refused(why) => {
                        tracing::debug!(floor, %why, "a revision was refused");
                    }
                }
            }
        }
        Ok(Round::Done)
    }

    /// The plans of `order` fitted and driven again one after the other (see the module docs),
    /// or `None` where one of them does not fit or its drive is refused.
    async fn replan(
        &self,
        order: &[&Revisable],
        read: &Read,
        out: &mut Improvement,
    ) -> Result<Option<Vec<FleetOutcome>>, PlanFailure> {
        let ids: Vec<&str> = order.iter().map(|r| r.plan_id()).collect();
        let fixed: Vec<Itinerary> = read
            .plans
            .iter()
            .filter(|i| !ids.contains(&i.plan_id.as_str()))
            .cloned()
            .collect();
        let mut placed: Vec<FleetOutcome> = Vec::with_capacity(order.len());
        for (k, r) in order.iter().enumerate() {
            let (Some(old), Some(previous)) = (read.current(r.plan_id()), r.fleet()) else {
                return Ok(None);
            };
            let later = order[k + 1..]
                .iter()
                .filter_map(|l| read.current(l.plan_id()))
                .map(standing_until_departure);
            let others: Vec<Itinerary> = fixed
                .iter()
                .cloned()
                .chain(placed.iter().map(|f| f.itinerary.clone()))
                .chain(later)
                .collect();
            let Some(new) = self.refit(r, old, previous, &others, read, out).await? else {
                return Ok(None);
            };
            placed.push(new);
        }
        Ok(Some(placed))
    }

    /// One plan of a neighbourhood fitted among `others` and driven among them, as a plan
    /// joining the floor is (`None`: it does not fit, or the drive did not arrive clear of them).
    async fn refit(
        &self,
        r: &Revisable,
        old: &Itinerary,
        previous: &FleetOutcome,
        others: &[Itinerary],
        read: &Read,
        out: &mut Improvement,
    ) -> Result<Option<FleetOutcome>, PlanFailure> {
        let (report, options) = (&r.outcome.report, &r.options);
        let dt = report.control_period_s;
        let start = old.start_unix_ms;
        // It sets off no sooner than a revision made by the end of the lead reaches it.
        let earliest_departure = read.now_ms
            + LEAD_MS
            + ((options.tolerance_s + traffic::REVISION_NOTICE_S) * 1000.0).ceil() as i64;
        let start_wait_s = ((earliest_departure - start) as f64 / 1000.0).max(0.0);
        let template = Itinerary {
            trajectory: Vec::new(),
            tolerance_s: options.tolerance_s + fleet::FIT_SLACK_S,
            expires_unix_ms: start + (options.hold_s * 1000.0).round() as i64,
            delay_s: 0.0,
            ..old.clone()
        };
        // Fitted on the rehearsal, then (a drive that arrived within the margin of another
        // robot's schedule) on that drive, a few times, as a plan joining the floor is.
        let mut basis: Option<fleet::Basis> = None;
        let mut drives = 0;
        let (driven, among, waits) = loop {
            let (steps, wait_s, budget_s) = match &basis {
                Some(b) => (
                    &b.steps,
                    0.0,
                    options.max_wait_s + start_wait_s - b.waited_s(),
                ),
                None => (
                    &report.steps,
                    start_wait_s,
                    options.max_wait_s + start_wait_s,
                ),
            };
            let fit = fleet::fit(
                &template,
                steps,
                dt,
                &report.waypoints,
                others,
                budget_s.max(0.0),
                wait_s,
            );
            let fitted = match fit {
                Ok(f) => f,
                Err(e) => {
                    tracing::debug!(robot = %old.robot, why = %e.message, "improver: no fit");
                    return Ok(None);
                }
            };
            let (waits, _) = fleet::on_the_clock(&fitted, start, dt);
            let waits = match &basis {
                Some(b) => fleet::merge_waits(&b.waits, waits, &fitted.waypoint_steps),
                None => waits,
            };
            let among = if others.is_empty() && waits.is_empty() && report.drives_again_alike() {
                fleet::validated_alone(report)
            } else {
                let robots = Arc::new(fleet::simulated_robots(others, start)?);
                let holds = fleet::holds(&waits, start, report.waypoints.len());
                let (replay, world, report) = (
                    Arc::clone(&r.outcome.replay),
                    Arc::clone(&r.outcome.world),
                    report.clone(),
                );
                let radius = old.radius_m;
                out.drives += 1;
                drives += 1;
                self.simulating(IDLE_TICKET, None, move || {
                    replay.among_fresh_draws(&world, &report, &robots, &holds, radius)
                })
                .await??
            };
            if among.outcome != rehearsal::AttemptOutcome::Reached || among.met_robot().is_some() {
                tracing::debug!(robot = %old.robot, reason = %among.reason, "improver: drive refused");
                return Ok(None);
            }
            let driven = Itinerary {
                tolerance_s: options.tolerance_s,
                ..fleet::driven(
                    &fitted.itinerary,
                    start,
                    &among.steps,
                    among.control_period_s,
                )
            };
            match fleet::first_conflict(&driven, others) {
                None => break (driven, among, waits),
                Some(c) if drives > REFITS_ON_DRIVE => {
                    tracing::debug!(robot = %old.robot, with = %c.b_robot, "improver: drive within the margin");
                    return Ok(None);
                }
                Some(_) => {
                    basis = Some(fleet::Basis {
                        steps: among.steps.clone(),
                        waits,
                    });
                }
            }
        };
        let waypoint_times_unix_ms = fleet::waypoint_steps(&among.steps, &report.waypoints)
            .iter()
            .map(|&k| start + (k as f64 * among.control_period_s * 1000.0).round() as i64)
            .collect();
        Ok(Some(FleetOutcome {
            itinerary: driven,
            waypoint_times_unix_ms,
            waits,
            among: (!others.is_empty()).then_some(among),
            others: others.len(),
            drives: previous.drives + drives,
            version: None,
            // A revision's passings are read from the schedule (`GET /v1/plans/{id}`).
            passes_after: Vec::new(),
        }))
    }
}

/// The last moment `it` may be revised, Unix ms: its departure less its tolerance and the
/// notice a revision takes ([`traffic::Planned::latest_revision_unix_ms`]).
fn revisable_until_ms(it: &Itinerary) -> i64 {
    it.departs_unix_ms()
        - ((it.tolerance_s.max(0.0) + traffic::REVISION_NOTICE_S) * 1000.0).ceil() as i64
}

/// `it`'s robot standing at its start from its start until it sets off: where a robot of a
/// neighbourhood is, at least, before its plan is fitted again.
fn standing_until_departure(it: &Itinerary) -> Itinerary {
    let first = it
        .trajectory
        .first()
        .cloned()
        .unwrap_or(traffic::TimedPose {
            t_s: 0.0,
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
        });
    let until = (it.departure_s() + it.delay_s).max(first.t_s + 0.001);
    Itinerary {
        trajectory: vec![
            first,
            traffic::TimedPose {
                t_s: until,
                ..first
            },
        ],
        expires_unix_ms: it.departs_unix_ms().max(it.start_unix_ms + 1),
        delay_s: 0.0,
        ..it.clone()
    }
}

/// The orders a neighbourhood of `last` (the robot ending last) is re-planned in: it and the
/// robots it waits for that may be revised, as they depart now; `last` first, the others as
/// they depart; `last` first, the others reversed; `last` before each of them alone.
fn orders<'a>(
    last: &'a Revisable,
    revisable: &[&'a Revisable],
    read: &Read,
) -> Vec<Vec<&'a Revisable>> {
    let waits_for: Vec<&str> = last
        .fleet()
        .map(|f| {
            f.waits
                .iter()
                .flat_map(|w| w.for_robots.iter().map(String::as_str))
                .collect()
        })
        .unwrap_or_default();
    let departs = |r: &Revisable| {
        read.current(r.plan_id())
            .map_or(i64::MAX, Itinerary::departs_unix_ms)
    };
    let mut blockers: Vec<&'a Revisable> = revisable
        .iter()
        .copied()
        .filter(|r| r.plan_id() != last.plan_id() && waits_for.contains(&r.outcome.robot.as_str()))
        .collect();
    blockers.sort_by_key(|r| departs(r));
    blockers.truncate(MAX_NEIGHBOURHOOD - 1);
    let mut as_they_depart: Vec<&'a Revisable> = blockers.iter().copied().chain([last]).collect();
    as_they_depart.sort_by_key(|r| departs(r));
    let last_first: Vec<&'a Revisable> = std::iter::once(last)
        .chain(blockers.iter().copied())
        .collect();
    let last_first_reversed: Vec<&'a Revisable> = std::iter::once(last)
        .chain(blockers.iter().rev().copied())
        .collect();
    // Then `last` before each one of them alone: a smaller neighbourhood fits more often.
    let pairs = blockers.iter().map(|&b| vec![last, b]);
    let mut out: Vec<Vec<&'a Revisable>> = Vec::new();
    for o in [as_they_depart, last_first, last_first_reversed]
        .into_iter()
        .chain(pairs)
    {
        let ids = |o: &[&Revisable]| o.iter().map(|r| r.plan_id().to_owned()).collect::<Vec<_>>();
        if !out.iter().any(|p| ids(p) == ids(&o)) {
            out.push(o);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn moving(robot: &str, start_ms: i64, end_s: f64) -> Itinerary {
        let pose = |t_s: f64, x: f64| traffic::TimedPose {
            t_s,
            x,
            y: 0.0,
            yaw: 0.0,
        };
        Itinerary {
            plan_id: format!("plan-{robot}"),
            robot: robot.to_owned(),
            floor: "f".to_owned(),
            start_unix_ms: start_ms,
            trajectory: vec![pose(0.0, 0.0), pose(end_s, 5.0)],
            radius_m: 0.3,
            tolerance_s: 2.0,
            expires_unix_ms: start_ms + (end_s * 1000.0) as i64 + 30_000,
            delay_s: 0.0,
            revision: 1,
        }
    }

    #[test]
    fn totals_count_moving_plans_from_the_earliest_start() {
        let plans = [
            moving("a", 1_000, 10.0),
            moving("b", 3_000, 20.0),
            standing_until_departure(&moving("c", 0, 50.0)),
        ];
        let t = Totals::of(&plans).unwrap();
        assert!((t.makespan_s - 22.0).abs() < 1e-9, "{t:?}");
        assert!((t.sum_s - 30.0).abs() < 1e-9, "{t:?}");
        assert_eq!(Totals::of(&plans[2..]), None);
    }

    #[test]
    fn an_order_whose_revision_was_lost_is_tried_again() {
        let r = Revisables::default();
        let order = vec!["plan-a".to_owned(), "plan-b".to_owned()];
        assert!(!r.tried("f", 7, &order));
        assert!(r.tried("f", 7, &order), "tried already at this state");
        assert!(!r.tried("f", 8, &order), "the floor's plans changed");
        r.untried("f", &order);
        assert!(!r.tried("f", 8, &order), "lost: tried again");
    }

    #[test]
    fn orders_tried_stay_tried_until_a_plan_changes() {
        let read = |plans: Vec<Itinerary>, version| Read {
            version,
            now_ms: 0,
            plans,
        };
        let (a, b) = (moving("a", 0, 10.0), moving("b", 0, 20.0));
        let state = read(vec![a.clone(), b.clone()], 3).state();
        assert_eq!(read(vec![b.clone(), a.clone()], 9).state(), state);
        let late = Itinerary {
            delay_s: 1.5,
            ..b.clone()
        };
        assert_ne!(read(vec![a.clone(), late], 9).state(), state);
        let revised = Itinerary { revision: 2, ..b };
        assert_ne!(read(vec![a, revised], 9).state(), state);
    }

    #[test]
    fn a_revision_is_kept_only_where_the_floor_gains() {
        let t = |makespan_s, sum_s| Totals {
            makespan_s,
            sum_s,
            plans: 3,
        };
        let before = t(100.0, 300.0);
        assert!(t(90.0, 300.0).improves_on(&before));
        assert!(t(100.0, 299.0).improves_on(&before));
        assert!(
            !t(99.8, 299.8).improves_on(&before),
            "gains below the least"
        );
        assert!(
            t(90.0, 320.0).improves_on(&before),
            "the mean time rose by less than the makespan dropped"
        );
        assert!(
            !t(90.0, 331.0).improves_on(&before),
            "the mean time rose by more than the makespan dropped"
        );
        assert!(!t(101.0, 200.0).improves_on(&before), "the makespan rose");
    }

    #[test]
    fn a_robot_of_a_neighbourhood_stands_at_its_start_until_it_departs() {
        let mut it = moving("a", 10_000, 10.0);
        it.trajectory.insert(
            1,
            traffic::TimedPose {
                t_s: 4.0,
                x: 0.0,
                y: 0.0,
                yaw: 0.0,
            },
        );
        let s = standing_until_departure(&it);
        assert!(fleet::stands_only(&s));
        assert_eq!(s.pose_at(13_000), Some((0.0, 0.0)));
        assert_eq!(s.expires_unix_ms, 14_000);
        assert_eq!(s.pose_at(14_500), None);
        assert_eq!(revisable_until_ms(&it), 14_000 - 3_000);
    }
}
