//! A validated plan driven again among the fleet ([`Replay`]): what the rehearsal resolved
//! (the request with its people, the policy, the controller picked), kept with the plan so that
//! its drive among the other robots, and a joint run's, use exactly what validated it.

use std::sync::Arc;

use rehearsal::{ControllerChoice, PlanRequest};
use sim::World;

use crate::{PlanFailure, fleet};

/// What a validated plan needs to be driven again (among the fleet): the request as
/// rehearsed (its people resolved), the policy and the controller picked.
#[derive(Debug)]
pub(crate) struct Replay {
    pub(crate) request: PlanRequest,
    pub(crate) policy: Option<Arc<learning::Policy>>,
    pub(crate) choice: ControllerChoice,
}

impl Replay {
    /// [`Self::among`] on the validating attempts' people and noise, then, while the drive
    /// did not arrive and no other robot was involved (none touched, none within a metre of
    /// where it ended: people or noise stopped it), among up to [`fleet::FRESH_DRAWS`] fresh
    /// draws, as the rehearsal re-samples. The first drive that arrives, else the last. With no
    /// other robot on the floor there is no schedule to check and no fresh draw (the planner
    /// commits the validated plan). Blocks.
    pub(crate) fn among_fresh_draws(
        &self,
        world: &Arc<World>,
        report: &rehearsal::PlanReport,
        others: &sim::OtherRobots,
        holds: &[f64],
        radius_m: f64,
    ) -> Result<rehearsal::AmongReport, PlanFailure> {
        let mut among = self.among(world, report, others, holds, 0)?;
        let draws = if others.robots().is_empty() {
            0
        } else {
            fleet::FRESH_DRAWS
        };
        for draw in 1..=draws {
            let robots_involved = among.met_robot().is_some()
                || !fleet::robots_near_the_end(others, &among, radius_m).is_empty();
            if among.outcome == rehearsal::AttemptOutcome::Reached || robots_involved {
                break;
            }
            among = self.among(world, report, others, holds, draw)?;
        }
        Ok(among)
    }

    /// Drives `report` again among `others` with `holds` ([`rehearsal::drive_among`]), with
    /// the controller picked and the follower behind it, as the rehearsal did, among the
    /// people and noise of `draw` (0: the validating attempts'). Blocks.
    pub(crate) fn among(
        &self,
        world: &Arc<World>,
        report: &rehearsal::PlanReport,
        others: &sim::OtherRobots,
        holds: &[f64],
        draw: u32,
    ) -> Result<rehearsal::AmongReport, PlanFailure> {
        let mut primary = self
            .choice
            .build(self.policy.as_ref(), self.request.options.seed)
            .ok_or_else(|| PlanFailure::internal("the picked controller needs a policy"))?;
        let mut follower = (!matches!(
            self.choice,
            ControllerChoice::Follower | ControllerChoice::ShieldedFollower
        ))
        .then(|| rehearsal::follower_for(&self.request.options));
        rehearsal::drive_among(
            world,
            &self.request,
            report,
            &mut *primary,
            follower
                .as_deref_mut()
                .map(|f| f as &mut dyn rehearsal::Controller),
            others,
            holds,
            draw,
        )
        .map_err(PlanFailure::Plan)
    }
}
