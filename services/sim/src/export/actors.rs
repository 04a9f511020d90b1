//! The people the knowledge expects, as gz-sim actors walking looped trajectories.

use std::fmt::Write as _;

use crate::spec::WorldSpec;

/// Stops in the round of an actor that walks between the wanderers' points.
pub(super) const WANDER_STOPS: usize = 4;

/// Walking speed of the exported actors, m/s (the middle of the simulation's range).
pub(super) const ACTOR_SPEED: f64 = 1.0;
/// Gazebo Fuel's walking actor (Mingfei's, as gz-sim's own actor examples use it).
pub(super) const ACTOR_MESH: &str =
    "https://fuel.gazebosim.org/1.0/Mingfei/models/actor/tip/files/meshes/walk.dae";

/// The people the knowledge expects, as gz-sim actors: as many as expected (rounded, at least
/// one per route when routes are known), each walking a known route there and back, or the
/// attractors in turn lingering at each; their trajectories loop. Without routes or attractors
/// they walk rounds between the points the simulation's wanderers walk between
/// ([`crate::crowd::Targets::wander_round`]), the shortest way through the free region.
pub(super) fn people_actors(spec: &WorldSpec) -> String {
    let people = &spec.people;
    let mut tracks: Vec<Vec<[f64; 2]>> = people
        .routes
        .iter()
        .filter(|r| r.points.len() >= 2)
        .map(|r| {
            let mut there_and_back = r.points.clone();
            there_and_back.extend(r.points.iter().rev().skip(1));
            there_and_back
        })
        .collect();
    if people.attractors.len() >= 2 {
        let mut tour: Vec<[f64; 2]> = people.attractors.iter().map(|a| a.position).collect();
        tour.push(people.attractors[0].position);
        tracks.push(tour);
    }
    let expected = people.expected_at(None);
    if tracks.is_empty() && expected >= 0.5 {
        // No known way to walk: rounds between the wanderers' points, as many as people.
        if let Ok(world) = crate::World::build(spec.clone()) {
            let targets = world.people_targets();
            #[allow(
                clippy::cast_possible_truncation,
                clippy::cast_sign_loss,
                reason = "a rounded count, capped"
            )]
            let count = (expected.round() as usize).min(crate::crowd::MAX_PEOPLE);
            tracks = (0..count)
                .map(|k| {
                    targets
                        .wander_round(&world, k * WANDER_STOPS, WANDER_STOPS, 1.0)
                        .into_iter()
                        .map(|(x, y)| [x, y])
                        .collect::<Vec<_>>()
                })
                .filter(|t| t.len() >= 2)
                .collect();
        }
    }
    if tracks.is_empty() {
        return String::new();
    }
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a rounded count, capped"
    )]
    let count = (expected.round().max(0.0) as usize).clamp(tracks.len(), crate::crowd::MAX_PEOPLE);
    let dwell = |p: [f64; 2]| {
        people
            .attractors
            .iter()
            .find(|a| a.position == p)
            .map_or(0.0, |a| a.dwell_s.max(0.0))
    };
    let mut s = String::from(
        "    <!-- People the knowledge expects, walking its routes and attractors (else about the floor). -->\n",
    );
    for k in 0..count {
        let track = &tracks[k % tracks.len()];
        // Later walkers of one track start further along it.
        let shift = (k / tracks.len()) % (track.len() - 1);
        let points: Vec<[f64; 2]> = track[shift..]
            .iter()
            .chain(track[1..=shift].iter())
            .copied()
            .collect();
        let _ = writeln!(
            s,
            r#"    <actor name="person_{k}">
      <skin><filename>{ACTOR_MESH}</filename><scale>1.0</scale></skin>
      <animation name="walking"><filename>{ACTOR_MESH}</filename><scale>1.000000</scale><interpolate_x>true</interpolate_x></animation>
      <script>
        <loop>true</loop>
        <delay_start>0</delay_start>
        <auto_start>true</auto_start>
        <trajectory id="{k}" type="walking">"#
        );
        let mut t = 0.0;
        for (i, p) in points.iter().enumerate() {
            let next = points.get(i + 1).or(points.get(i.saturating_sub(1)));
            let yaw = next.map_or(0.0, |q| (q[1] - p[1]).atan2(q[0] - p[0]));
            let _ = writeln!(
                s,
                "          <waypoint><time>{t:.3}</time><pose>{:.4} {:.4} 0 0 0 {yaw:.4}</pose></waypoint>",
                p[0], p[1]
            );
            let linger = dwell(*p);
            if linger > 0.0 {
                t += linger;
                let _ = writeln!(
                    s,
                    "          <waypoint><time>{t:.3}</time><pose>{:.4} {:.4} 0 0 0 {yaw:.4}</pose></waypoint>",
                    p[0], p[1]
                );
            }
            if let Some(q) = points.get(i + 1) {
                t += ((q[0] - p[0]).hypot(q[1] - p[1]) / ACTOR_SPEED).max(0.1);
            }
        }
        s.push_str("        </trajectory>\n      </script>\n    </actor>\n");
    }
    s
}
