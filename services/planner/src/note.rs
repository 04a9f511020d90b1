//! The note a plan's answer carries: why a classical controller validated the plan or some of
//! its legs, when one did.

use crate::controllers::ControllerPick;

/// Why a classical controller validated a plan or some of its legs, when one did.
pub(crate) fn note(
    had_policy: bool,
    pick: &ControllerPick,
    report: &rehearsal::PlanReport,
) -> Option<String> {
    let fallback_legs = report
        .legs
        .iter()
        .filter(|l| l.controller != report.controller)
        .count();
    let name = pick.choice.as_str();
    if !had_policy {
        Some(format!(
            "no trained policy for this robot yet: validated with the classical path follower `{name}`"
        ))
    } else if fallback_legs > 0 {
        Some(format!(
            "{} of {} legs validated with the classical path follower: no attempt with `{name}` validated them (see `legs`)",
            fallback_legs,
            report.legs.len()
        ))
    } else if !pick.choice.needs_policy() {
        Some(format!(
            "validated with the classical controller `{name}` rather than the policy: {}",
            pick.why
        ))
    } else {
        None
    }
}
