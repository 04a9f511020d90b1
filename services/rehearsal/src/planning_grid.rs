//! The planner's grid of a built world: what the roadmap is sampled on.
//!
//! A cell is blocked when the world's walls cover its centre (the floor's occupied and unknown
//! cells, walls from place boundaries, the border) or when an object part the robot can hit
//! (lower than the robot, above the floor) may overlap the cell's square. Objects are therefore
//! planned around as the simulator sees them: a table's legs block, the space between them does
//! not, which is why the executor validates in the simulation rather than trusting the grid.

use prm::PlanningGrid;
use sim::{Shape, World};

/// Cells above this many are refused: the world grid is capped at the same order by `sim`.
const MAX_CELLS: usize = 40_000_000;

/// The planning grid of `world`, axis-aligned over the world's bounds at its resolution.
///
/// For a floor map with zero yaw (every shared map) cell centres coincide with the world's
/// cells, so walls are reproduced exactly; a rotated map is resampled at cell centres.
pub fn planning_grid(world: &World) -> Result<PlanningGrid, String> {
    let [x0, y0, x1, y1] = world.bounds();
    let res = world.resolution();
    let robot = &world.spec().robot;
    let radius = robot.footprint_radius;
    let cols = ((x1 - x0) / res).round();
    let rows = ((y1 - y0) / res).round();
    if !(cols.is_finite() && rows.is_finite() && cols >= 1.0 && rows >= 1.0) {
        return Err(format!(
            "the world's bounds [{x0}, {y0}, {x1}, {y1}] give no grid"
        ));
    }
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "finite, positive and checked against MAX_CELLS below"
    )]
    let (width, height) = (cols as usize, rows as usize);
    if width.saturating_mul(height) > MAX_CELLS {
        return Err(format!(
            "{width}x{height} cells is more than the planner takes"
        ));
    }
    let mut blocked = vec![false; width * height];
    // A wall cell's centre is at distance 0 from a wall square; a free cell's centre at least
    // half a cell away. `wall_clearance` is that distance minus the robot's radius.
    for (row, cells) in blocked.chunks_mut(width).enumerate() {
        let y = y0 + (row as f64 + 0.5) * res;
        for (col, cell) in cells.iter_mut().enumerate() {
            let x = x0 + (col as f64 + 0.5) * res;
            *cell = world.wall_clearance(x, y) + radius < 0.25 * res;
        }
    }
    // Object parts the robot can hit: every cell whose square may overlap the part's footprint.
    let reach = res * std::f64::consts::FRAC_1_SQRT_2;
    for object in &world.spec().objects {
        for part in sim::library::parts(object) {
            let (zmin, zmax) = (
                part.pose.z - part.size.z / 2.0,
                part.pose.z + part.size.z / 2.0,
            );
            if !(zmin < robot.height && zmax > 0.0) {
                continue;
            }
            let (hx, hy) = (part.size.x / 2.0, part.size.y / 2.0);
            let (s, c) = part.pose.yaw.sin_cos();
            let bound = hx.hypot(hy) + reach;
            let inside = |x: f64, y: f64| {
                let (dx, dy) = (x - part.pose.x, y - part.pose.y);
                match part.shape {
                    Shape::Box => {
                        let (lx, ly) = (c * dx + s * dy, -s * dx + c * dy);
                        let ex = (lx.abs() - hx).max(0.0);
                        let ey = (ly.abs() - hy).max(0.0);
                        ex.hypot(ey) <= reach
                    }
                    Shape::Cylinder | Shape::Sphere => dx.hypot(dy) <= hx.max(hy) + reach,
                }
            };
            let to_cell = |v: f64, origin: f64, n: usize| {
                #[allow(
                    clippy::cast_possible_truncation,
                    clippy::cast_sign_loss,
                    reason = "clamped into [0, n - 1] before the cast"
                )]
                let i = ((v - origin) / res).floor().clamp(0.0, (n - 1) as f64) as usize;
                i
            };
            let (c0, c1) = (
                to_cell(part.pose.x - bound, x0, width),
                to_cell(part.pose.x + bound, x0, width),
            );
            let (r0, r1) = (
                to_cell(part.pose.y - bound, y0, height),
                to_cell(part.pose.y + bound, y0, height),
            );
            for row in r0..=r1 {
                let y = y0 + (row as f64 + 0.5) * res;
                for col in c0..=c1 {
                    let x = x0 + (col as f64 + 0.5) * res;
                    if inside(x, y) {
                        blocked[row * width + col] = true;
                    }
                }
            }
        }
    }
    let grid = PlanningGrid {
        width,
        height,
        resolution: res,
        origin_x: x0,
        origin_y: y0,
        blocked,
    };
    grid.validate().map_err(|e| e.to_string())?;
    Ok(grid)
}
