//! The floors `bench fleet` generates for its scenarios, and their missions.
//!
//! Every passage is [`CORRIDOR_WIDTH_M`] wide: one robot fits, two do not pass each other.
//! The rooms at their ends park robots on slots along the room's far wall and side walls, a
//! robot's width plus 0.4 m apart and half that from the walls, leaving the middle of the room
//! open. The robots keep right: a room's departing robots start on the slots right of its middle
//! line (facing its opening), its arriving robots park on the slots left of it, so no goal is
//! another robot's start and the two streams run apart but for the stretch by the opening where
//! their paths converge (the planner fits plans by waiting only, never by another path: two
//! robots whose paths run less than a robot's width plus the margin apart, one each way, take
//! turns).

use std::f64::consts::PI;

use prm::Point2;
use sim::Pose2;
use tosm::{Occupancy, OccupancyGrid};

use super::Scenario;
use crate::error::BenchError;

/// Width of the generated corridors, and of the doorway's opening, metres: one robot of less
/// than 0.4 m radius fits with the plans' 0.1 m safety margin on both sides (the bundled robot,
/// 0.355 m: 0.91 m); two robots of more than 0.25 m radius cannot pass each other (the bundled
/// robot: 1.42 m). [`check_robot`] refuses a robot for which either does not hold.
pub const CORRIDOR_WIDTH_M: f64 = 1.0;

/// Resolution of the generated floors, metres per cell.
const RES_M: f64 = 0.05;
/// Wall around a generated floor, metres.
const BORDER_M: f64 = 0.5;

/// Crossing: length of each of its four arms, from the intersection to the room, metres: a
/// robot waiting in the arm's mouth is clear of the intersection; short, to keep runs quick.
pub const CROSSING_ARM_M: f64 = 4.0;
/// Crossing: a room's width across its arm, metres (with its depth: slots for the bundled robot
/// to send five robots from each arm and take five, `--robots 20`).
const CROSSING_ROOM_WIDTH_M: f64 = 4.0;
/// Crossing: a room's depth along its arm, metres.
const CROSSING_ROOM_DEPTH_M: f64 = 6.0;

/// Doorway: thickness of the wall between the two rooms (the door's passage), metres: a
/// wall's, not a corridor's.
pub const DOOR_WALL_M: f64 = 0.2;
/// Doorway: a room's width along the wall, metres (with its depth: slots for the bundled robot
/// to send ten robots from each room and take ten, `--robots 20`).
const DOORWAY_ROOM_WIDTH_M: f64 = 8.0;
/// Doorway: a room's depth away from the wall, metres.
const DOORWAY_ROOM_DEPTH_M: f64 = 9.0;

/// A rectangle of free floor, metres.
#[derive(Copy, Clone, Debug)]
struct Rect {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
}

/// A room: its far wall's middle, the direction from there to its opening (in the middle of
/// the opposite wall), its width across that direction and its depth along it.
#[derive(Copy, Clone, Debug)]
struct Room {
    far: Point2,
    toward: (f64, f64),
    width: f64,
    depth: f64,
}

impl Room {
    /// The point `depth` from the far wall towards the opening and `across` to the left of the
    /// room's middle line.
    fn at(&self, depth: f64, across: f64) -> Point2 {
        let (dx, dy) = self.toward;
        Point2::new(
            self.far.x + dx * depth - dy * across,
            self.far.y + dy * depth + dx * across,
        )
    }

    fn rect(&self) -> Rect {
        let (a, b) = (
            self.at(0.0, -self.width / 2.0),
            self.at(self.depth, self.width / 2.0),
        );
        Rect {
            x0: a.x.min(b.x),
            y0: a.y.min(b.y),
            x1: a.x.max(b.x),
            y1: a.y.max(b.y),
        }
    }

    /// The middle of the opening.
    fn opening(&self) -> Point2 {
        self.at(self.depth, 0.0)
    }

    /// Parking slots `spacing` apart and `spacing / 2` from the walls, in a row along the far
    /// wall (centred) and along both side walls towards the opening; those right of the room's
    /// middle line (facing the opening) for the robots that leave, those left of it for the
    /// robots that arrive (on their right as they come in), the middle one to the fewer: robots
    /// keep right.
    fn slots(&self, spacing: f64) -> (Vec<Point2>, Vec<Point2>) {
        let half = spacing / 2.0;
        let mut candidates = Vec::new();
        let across = self.width / 2.0 - half;
        let row = (2.0 * across / spacing + 1e-9).floor() as usize + 1;
        for i in 0..row {
            candidates.push((half, (i as f64 - (row - 1) as f64 / 2.0) * spacing));
        }
        let mut d = half;
        while d <= self.depth - half + 1e-9 {
            candidates.push((d, -across));
            candidates.push((d, across));
            d += spacing;
        }
        let mut kept: Vec<(f64, f64)> = Vec::new();
        for c in candidates {
            if kept
                .iter()
                .all(|p| (p.0 - c.0).hypot(p.1 - c.1) >= spacing - 1e-9)
            {
                kept.push(c);
            }
        }
        let side = |keep: fn(f64) -> bool| -> Vec<Point2> {
            kept.iter()
                .filter(|c| keep(c.1))
                .map(|&(d, a)| self.at(d, a))
                .collect()
        };
        let (mut leaving, mut arriving) = (side(|a| a < -1e-9), side(|a| a > 1e-9));
        if let Some(&(d, a)) = kept.iter().find(|c| c.1.abs() <= 1e-9) {
            if leaving.len() <= arriving.len() {
                leaving.push(self.at(d, a));
            } else {
                arriving.push(self.at(d, a));
            }
        }
        (leaving, arriving)
    }
}

/// The rooms of a generated floor, where its robots start and park.
pub(super) struct Layout {
    rooms: Vec<Room>,
}

/// A `width` × `height` metres floor, all wall but the given rectangles.
fn carve(width: f64, height: f64, free: &[Rect]) -> OccupancyGrid {
    let (w, h) = (
        (width / RES_M).round() as usize,
        (height / RES_M).round() as usize,
    );
    let mut grid =
        OccupancyGrid::filled(w, h, RES_M, Pose2::new(0.0, 0.0, 0.0), Occupancy::Occupied);
    for r in free {
        for cy in 0..h {
            for cx in 0..w {
                let (x, y) = ((cx as f64 + 0.5) * RES_M, (cy as f64 + 0.5) * RES_M);
                if x >= r.x0 && x < r.x1 && y >= r.y0 && y < r.y1 {
                    grid.cells[cy * w + cx] = Occupancy::Free;
                }
            }
        }
    }
    grid
}

/// The floor of a generated scenario; `None` for random missions on the maps.
pub(super) fn generated(scenario: Scenario) -> Option<(OccupancyGrid, Layout)> {
    match scenario {
        Scenario::Random => None,
        Scenario::Corridor => Some(corridor()),
        Scenario::Crossing => Some(crossing()),
        Scenario::Doorway => Some(doorway()),
    }
}

/// Two 4.5 m × 5 m rooms joined by a 12 m corridor [`CORRIDOR_WIDTH_M`] wide (22 m × 6 m). Its
/// missions are its own (two columns of five per room, see [`corridor_missions`]).
fn corridor() -> (OccupancyGrid, Layout) {
    let half = CORRIDOR_WIDTH_M / 2.0;
    let grid = carve(
        22.0,
        6.0,
        &[
            Rect {
                x0: 0.5,
                y0: 0.5,
                x1: 5.0,
                y1: 5.5,
            },
            Rect {
                x0: 17.0,
                y0: 0.5,
                x1: 21.5,
                y1: 5.5,
            },
            Rect {
                x0: 4.9,
                y0: 3.0 - half,
                x1: 17.1,
                y1: 3.0 + half,
            },
        ],
    );
    (grid, Layout { rooms: Vec::new() })
}

/// A plus: two corridors [`CORRIDOR_WIDTH_M`] wide crossing in the middle, each arm
/// [`CROSSING_ARM_M`] long from the intersection to a room. Rooms north, east, south, west.
fn crossing() -> (OccupancyGrid, Layout) {
    let half = CORRIDOR_WIDTH_M / 2.0;
    let middle = BORDER_M + CROSSING_ROOM_DEPTH_M + CROSSING_ARM_M + half;
    let side = 2.0 * middle;
    let room = |far: Point2, toward: (f64, f64)| Room {
        far,
        toward,
        width: CROSSING_ROOM_WIDTH_M,
        depth: CROSSING_ROOM_DEPTH_M,
    };
    let rooms = vec![
        room(Point2::new(middle, side - BORDER_M), (0.0, -1.0)),
        room(Point2::new(side - BORDER_M, middle), (-1.0, 0.0)),
        room(Point2::new(middle, BORDER_M), (0.0, 1.0)),
        room(Point2::new(BORDER_M, middle), (1.0, 0.0)),
    ];
    // The arms reach a cell into the rooms.
    let (lo, hi) = (
        BORDER_M + CROSSING_ROOM_DEPTH_M - RES_M,
        side - BORDER_M - CROSSING_ROOM_DEPTH_M + RES_M,
    );
    let mut free: Vec<Rect> = rooms.iter().map(Room::rect).collect();
    free.push(Rect {
        x0: middle - half,
        y0: lo,
        x1: middle + half,
        y1: hi,
    });
    free.push(Rect {
        x0: lo,
        y0: middle - half,
        x1: hi,
        y1: middle + half,
    });
    (carve(side, side, &free), Layout { rooms })
}

/// Two rooms side by side, the wall between them [`DOOR_WALL_M`] thick with one opening
/// [`CORRIDOR_WIDTH_M`] wide in its middle. Rooms west, east.
fn doorway() -> (OccupancyGrid, Layout) {
    let width = 2.0 * (BORDER_M + DOORWAY_ROOM_DEPTH_M) + DOOR_WALL_M;
    let height = 2.0 * BORDER_M + DOORWAY_ROOM_WIDTH_M;
    let room = |far: Point2, toward: (f64, f64)| Room {
        far,
        toward,
        width: DOORWAY_ROOM_WIDTH_M,
        depth: DOORWAY_ROOM_DEPTH_M,
    };
    let middle = height / 2.0;
    let rooms = vec![
        room(Point2::new(BORDER_M, middle), (1.0, 0.0)),
        room(Point2::new(width - BORDER_M, middle), (-1.0, 0.0)),
    ];
    let wall = BORDER_M + DOORWAY_ROOM_DEPTH_M;
    let half = CORRIDOR_WIDTH_M / 2.0;
    let mut free: Vec<Rect> = rooms.iter().map(Room::rect).collect();
    free.push(Rect {
        x0: wall - RES_M,
        y0: middle - half,
        x1: wall + DOOR_WALL_M + RES_M,
        y1: middle + half,
    });
    (carve(width, height, &free), Layout { rooms })
}

/// Refuses a robot the scenario's passages do not hold one at a time.
pub(super) fn check_robot(
    scenario: Scenario,
    radius: f64,
    safety_margin_m: f64,
) -> Result<(), BenchError> {
    if scenario == Scenario::Random
        || (2.0 * (radius + safety_margin_m) < CORRIDOR_WIDTH_M && CORRIDOR_WIDTH_M < 4.0 * radius)
    {
        return Ok(());
    }
    Err(BenchError::BadOption(format!(
        "the {} scenario is for robots that fit its {CORRIDOR_WIDTH_M} m passages one at a time; this robot's radius is {radius} m",
        scenario.as_str()
    )))
}

/// The missions of `n` robots of footprint radius `radius` on a generated floor. Crossing:
/// robot `k` starts in room `k mod 4` and parks in the opposite one. Doorway: robot `k` starts
/// in room `k mod 2` and parks in the other. Starts face the room's opening.
pub(super) fn missions(
    scenario: Scenario,
    layout: &Layout,
    radius: f64,
    n: usize,
) -> Result<Vec<(Pose2, Point2)>, BenchError> {
    if scenario == Scenario::Corridor {
        return Ok(corridor_missions(n));
    }
    let rooms = &layout.rooms;
    let spacing = 2.0 * radius + 0.4;
    let slots: Vec<(Vec<Point2>, Vec<Point2>)> = rooms.iter().map(|r| r.slots(spacing)).collect();
    let m = rooms.len();
    let other = |room: usize| (room + m / 2) % m;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let (from, i) = (k % m, k / m);
        let to = other(from);
        let (Some(s), Some(g)) = (slots[from].0.get(i), slots[to].1.get(i)) else {
            let holds = slots
                .iter()
                .map(|(l, a)| l.len().min(a.len()))
                .min()
                .unwrap_or(0)
                * m;
            return Err(BenchError::BadOption(format!(
                "--robots {n}: the {} scenario's rooms park at most {holds} robots of radius {radius} m",
                scenario.as_str()
            )));
        };
        let o = rooms[from].opening();
        out.push((Pose2::new(s.x, s.y, (o.y - s.y).atan2(o.x - s.x)), *g));
    }
    Ok(out)
}

/// The corridor's rooms, (0.5..5) and (17..21.5) by (0.5..5.5): robots start in the column by
/// the far wall and park in the column nearer the corridor of the other room, so that no goal
/// is another robot's start.
fn corridor_missions(n: usize) -> Vec<(Pose2, Point2)> {
    let column = |x: f64, j: usize| Point2::new(x, 1.2 + 0.9 * (j % 5) as f64);
    (0..n)
        .map(|k| {
            let j = k / 2;
            let (s, g, yaw) = if k % 2 == 0 {
                (
                    column(1.2 + 0.9 * (j / 5) as f64, j),
                    column(18.6 + 0.9 * (j / 5) as f64, j),
                    0.0,
                )
            } else {
                (
                    column(20.8 - 0.9 * (j / 5) as f64, j),
                    column(3.4 - 0.9 * (j / 5) as f64, j),
                    PI,
                )
            };
            (Pose2::new(s.x, s.y, yaw), g)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]

    use super::*;

    fn free_at(grid: &OccupancyGrid, p: Point2) -> bool {
        let (cx, cy) = ((p.x / RES_M) as usize, (p.y / RES_M) as usize);
        grid.cells[cy * grid.width + cx] == Occupancy::Free
    }

    #[test]
    fn missions_start_and_park_apart_on_free_floor() {
        let radius = 0.355;
        let spacing = 2.0 * radius + 0.4;
        for (scenario, n) in [(Scenario::Crossing, 20), (Scenario::Doorway, 20)] {
            let (grid, layout) = generated(scenario).unwrap();
            let m = missions(scenario, &layout, radius, n).unwrap();
            assert_eq!(m.len(), n);
            let points: Vec<Point2> = m
                .iter()
                .flat_map(|(s, g)| [Point2::new(s.x, s.y), *g])
                .collect();
            for (i, p) in points.iter().enumerate() {
                assert!(free_at(&grid, *p), "{scenario:?} {p:?}");
                for q in &points[i + 1..] {
                    assert!(
                        (p.x - q.x).hypot(p.y - q.y) >= spacing - 1e-9,
                        "{p:?} {q:?}"
                    );
                }
            }
            assert!(missions(scenario, &layout, radius, 60).is_err());
        }
    }

    #[test]
    fn passages_are_one_robot_wide() {
        // Across the crossing's north arm and the doorway, free cells span CORRIDOR_WIDTH_M.
        let (c, _) = crossing();
        let middle = c.height as f64 * RES_M / 2.0;
        let y = middle + CORRIDOR_WIDTH_M / 2.0 + CROSSING_ARM_M / 2.0;
        let across = (0..c.width)
            .filter(|&cx| free_at(&c, Point2::new((cx as f64 + 0.5) * RES_M, y)))
            .count();
        assert_eq!(across as f64 * RES_M, CORRIDOR_WIDTH_M);
        let (d, _) = doorway();
        let x = BORDER_M + DOORWAY_ROOM_DEPTH_M + DOOR_WALL_M / 2.0;
        let open = (0..d.height)
            .filter(|&cy| free_at(&d, Point2::new(x, (cy as f64 + 0.5) * RES_M)))
            .count();
        assert_eq!(open as f64 * RES_M, CORRIDOR_WIDTH_M);
    }
}
