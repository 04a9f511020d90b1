//! Fixtures: rooms with known geometry and objects.

use sim::{
    Colour, FloorMap, ObjectSpec, Occupancy, OccupancyGrid, Pose2, Pose3, RobotSpec, Shape, Size3,
    WorldSpec,
};

pub const RES: f64 = 0.05;

/// A `w` x `h` metre room whose outermost ring of cells is occupied, so its free interior is
/// `[RES, w - RES] x [RES, h - RES]` in the grid frame.
pub fn room_grid(w: f64, h: f64, origin: Pose2) -> OccupancyGrid {
    let (cols, rows) = ((w / RES).round() as usize, (h / RES).round() as usize);
    let mut g = OccupancyGrid::filled(cols, rows, RES, origin, Occupancy::Free);
    for r in 0..rows {
        for c in 0..cols {
            if r == 0 || c == 0 || r == rows - 1 || c == cols - 1 {
                g.cells[r * cols + c] = Occupancy::Occupied;
            }
        }
    }
    g
}

pub fn room(w: f64, h: f64) -> WorldSpec {
    room_at(w, h, Pose2::new(0.0, 0.0, 0.0))
}

pub fn room_at(w: f64, h: f64, origin: Pose2) -> WorldSpec {
    WorldSpec {
        id: "test-room".into(),
        floor: Some(FloorMap {
            id: "room".into(),
            grid: room_grid(w, h, origin),
            wall_height: 2.5,
            frame_id: "map".into(),
        }),
        walls: vec![],
        objects: vec![],
        robot: RobotSpec::example_differential(),
        people: Default::default(),
        notes: vec![],
    }
}

pub fn object(id: &str, class: Option<&str>, shape: Shape, size: Size3, pose: Pose3) -> ObjectSpec {
    ObjectSpec {
        id: id.into(),
        class: class.map(str::to_owned),
        shape,
        size,
        pose,
        colour: Colour::rgb(200, 30, 30),
        open: false,
    }
}

/// Distance from `(x, y)` along `angle` to the boundary of the axis-aligned box `[x0, x1] x
/// [y0, y1]` that contains the point.
pub fn box_exit(x: f64, y: f64, angle: f64, [x0, y0, x1, y1]: [f64; 4]) -> f64 {
    let (dx, dy) = (angle.cos(), angle.sin());
    let tx = if dx > 0.0 {
        (x1 - x) / dx
    } else if dx < 0.0 {
        (x0 - x) / dx
    } else {
        f64::INFINITY
    };
    let ty = if dy > 0.0 {
        (y1 - y) / dy
    } else if dy < 0.0 {
        (y0 - y) / dy
    } else {
        f64::INFINITY
    };
    tx.min(ty)
}
