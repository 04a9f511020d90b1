//! Top-down pictures of a world, as PNG bytes or SVG text: walls, unknown space, objects in their
//! colours (higher parts over lower ones, as seen from above), the free region, a trajectory,
//! laser beams, the robot and its goal.

use std::collections::HashMap;
use std::fmt::Write as _;

use crate::library::{self, Part};
use crate::spec::{Colour, Pose2, Shape};
use crate::world::World;

/// What to draw over the world.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overlay {
    /// Poses of a trajectory, drawn as a line.
    pub trajectory: Vec<Pose2>,
    /// The robot, drawn as its footprint circle with a heading tick.
    pub robot: Option<Pose2>,
    /// Laser beams as (from, to) world points.
    pub beams: Vec<((f64, f64), (f64, f64))>,
    /// The goal.
    pub goal: Option<(f64, f64)>,
    /// Whether to tint the free region that starts and goals are sampled from.
    pub show_free_region: bool,
    /// Line segments in their own colours (a roadmap's edges), drawn in order over the world
    /// and under the beams.
    pub segments: Vec<Segment>,
}

/// A coloured line segment between two world points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// One end, metres.
    pub from: (f64, f64),
    /// The other end, metres.
    pub to: (f64, f64),
    /// Its colour.
    pub rgb: [u8; 3],
}

impl Overlay {
    /// Adds the beams of a laser scan taken by the robot at `pose` with `beams` equally spaced
    /// readings (nothing when the laser has fewer samples).
    pub fn with_scan(mut self, world: &World, pose: Pose2, beams: usize) -> Self {
        let laser = &world.spec().robot.laser;
        let Some(angles) = laser.beam_angles(beams) else {
            return self;
        };
        let mut ranges = vec![0.0; angles.len()];
        world.scan(pose, &angles, &mut ranges);
        let (s, c) = pose.yaw.sin_cos();
        let m = laser.mount;
        let from = (pose.x + c * m.x - s * m.y, pose.y + s * m.x + c * m.y);
        for (a, r) in angles.iter().zip(&ranges) {
            let h = pose.yaw + m.yaw + a;
            self.beams
                .push((from, (from.0 + r * h.cos(), from.1 + r * h.sin())));
        }
        self
    }
}

/// Size of the picture.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Pixels per metre; `None` for one pixel per grid cell.
    pub pixels_per_metre: Option<f64>,
    /// Neither side of a PNG exceeds this many pixels (the scale shrinks to fit).
    pub max_side: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            pixels_per_metre: None,
            max_side: 4096,
        }
    }
}

/// Why a picture could not be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The scale or size is not usable.
    #[error("invalid render option: {0}")]
    Options(String),
    /// The PNG encoder failed.
    #[error("PNG encoding failed: {0}")]
    Png(#[from] image::ImageError),
}

const FREE: [u8; 3] = [255, 255, 255];
const OCCUPIED: [u8; 3] = [30, 30, 30];
const UNKNOWN: [u8; 3] = [190, 190, 190];
const REGION: [u8; 3] = [225, 238, 255];
const TRAJECTORY: [u8; 3] = [20, 90, 230];
const BEAM: [u8; 3] = [235, 60, 40];
const ROBOT: [u8; 3] = [0, 150, 60];
const GOAL: [u8; 3] = [230, 0, 200];

/// Maps world points to picture coordinates (y down).
#[derive(Copy, Clone, Debug)]
struct View {
    min_x: f64,
    max_y: f64,
    ppm: f64,
    width: u32,
    height: u32,
}

impl View {
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "sizes are checked to be finite and within max_side"
    )]
    fn new(world: &World, options: &RenderOptions) -> Result<View, RenderError> {
        let b = world.bounds();
        let (w_m, h_m) = (b[2] - b[0], b[3] - b[1]);
        let mut ppm = options.pixels_per_metre.unwrap_or(1.0 / world.resolution());
        if !(ppm.is_finite() && ppm > 0.0) || options.max_side == 0 {
            return Err(RenderError::Options(format!(
                "pixels per metre must be positive and max_side non-zero, got {ppm} and {}",
                options.max_side
            )));
        }
        let side = f64::from(options.max_side);
        ppm = ppm.min(side / w_m).min(side / h_m);
        Ok(View {
            min_x: b[0],
            max_y: b[3],
            ppm,
            width: ((w_m * ppm).ceil() as u32).clamp(1, options.max_side),
            height: ((h_m * ppm).ceil() as u32).clamp(1, options.max_side),
        })
    }

    fn to_px(self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.min_x) * self.ppm, (self.max_y - y) * self.ppm)
    }

    fn to_world(self, px: f64, py: f64) -> (f64, f64) {
        (self.min_x + px / self.ppm, self.max_y - py / self.ppm)
    }
}

/// The world's object parts, lowest top first, so higher parts are drawn over lower ones.
fn parts_by_height(world: &World) -> Vec<(String, Part)> {
    let mut parts: Vec<(String, Part)> = world
        .spec()
        .objects
        .iter()
        .flat_map(|o| library::parts(o).into_iter().map(|p| (o.id.clone(), p)))
        .collect();
    parts.sort_by(|a, b| {
        let top = |p: &Part| p.pose.z + p.size.z / 2.0;
        top(&a.1).total_cmp(&top(&b.1))
    });
    parts
}

/// Corners of a part's footprint (a box) in world coordinates, counter-clockwise.
fn box_corners(p: &Part) -> [(f64, f64); 4] {
    let (s, c) = p.pose.yaw.sin_cos();
    let (hx, hy) = (p.size.x / 2.0, p.size.y / 2.0);
    [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]
        .map(|(lx, ly)| (p.pose.x + c * lx - s * ly, p.pose.y + s * lx + c * ly))
}

/// Footprint radius of a round part.
fn round_radius(p: &Part) -> f64 {
    match p.shape {
        Shape::Sphere => p.size.x.max(p.size.y).max(p.size.z) / 2.0,
        _ => p.size.x.max(p.size.y) / 2.0,
    }
}

/// A PNG picture of `world` with `overlay`, as file bytes.
pub fn png(
    world: &World,
    overlay: &Overlay,
    options: &RenderOptions,
) -> Result<Vec<u8>, RenderError> {
    let view = View::new(world, options)?;
    let mut img = Canvas::new(view.width, view.height);
    // Background: sample the grid at each pixel centre (handles any scale and grid rotation).
    for py in 0..view.height {
        for px in 0..view.width {
            let (x, y) = view.to_world(f64::from(px) + 0.5, f64::from(py) + 0.5);
            let colour = match world.grid_cell(x, y) {
                None => OCCUPIED,
                Some((c, r)) => match world.cell_look(c, r) {
                    Some(true) => UNKNOWN,
                    Some(false) => OCCUPIED,
                    None if overlay.show_free_region && world.region_has_cell(c, r) => REGION,
                    None => FREE,
                },
            };
            img.put(px, py, colour);
        }
    }
    for (_, p) in parts_by_height(world) {
        let col = rgb(p.colour);
        match p.shape {
            Shape::Box => {
                let pts = box_corners(&p).map(|(x, y)| view.to_px(x, y));
                img.fill_convex(&pts, col);
            }
            Shape::Cylinder | Shape::Sphere => {
                let (cx, cy) = view.to_px(p.pose.x, p.pose.y);
                img.fill_circle(cx, cy, round_radius(&p) * view.ppm, col);
            }
        }
    }
    for g in &overlay.segments {
        let (p, q) = (view.to_px(g.from.0, g.from.1), view.to_px(g.to.0, g.to.1));
        img.line(p, q, g.rgb);
    }
    for (a, b) in &overlay.beams {
        let (p, q) = (view.to_px(a.0, a.1), view.to_px(b.0, b.1));
        img.line(p, q, BEAM);
    }
    for w in overlay.trajectory.windows(2) {
        let (p, q) = (view.to_px(w[0].x, w[0].y), view.to_px(w[1].x, w[1].y));
        img.line(p, q, TRAJECTORY);
    }
    if let Some(g) = overlay.goal {
        let (gx, gy) = view.to_px(g.0, g.1);
        let r = (0.15 * view.ppm).max(3.0);
        img.line((gx - r, gy - r), (gx + r, gy + r), GOAL);
        img.line((gx - r, gy + r), (gx + r, gy - r), GOAL);
    }
    if let Some(pose) = overlay.robot {
        let radius = world.spec().robot.footprint_radius;
        let (cx, cy) = view.to_px(pose.x, pose.y);
        img.circle(cx, cy, radius * view.ppm, ROBOT);
        let tip = view.to_px(
            pose.x + radius * pose.yaw.cos(),
            pose.y + radius * pose.yaw.sin(),
        );
        img.line((cx, cy), tip, ROBOT);
    }
    img.encode()
}

fn rgb(c: Colour) -> [u8; 3] {
    [c.r, c.g, c.b]
}

/// An RGB picture being drawn.
struct Canvas {
    w: u32,
    h: u32,
    data: Vec<u8>,
}

impl Canvas {
    fn new(w: u32, h: u32) -> Canvas {
        Canvas {
            w,
            h,
            data: vec![255; w as usize * h as usize * 3],
        }
    }

    fn put(&mut self, x: u32, y: u32, c: [u8; 3]) {
        if x < self.w && y < self.h {
            let i = (y as usize * self.w as usize + x as usize) * 3;
            self.data[i..i + 3].copy_from_slice(&c);
        }
    }

    #[allow(
        clippy::cast_possible_truncation,
        reason = "coordinates are clamped to the picture before the cast"
    )]
    fn put_f(&mut self, x: f64, y: f64, c: [u8; 3]) {
        if x >= 0.0 && y >= 0.0 && x < f64::from(self.w) && y < f64::from(self.h) {
            #[allow(clippy::cast_sign_loss, reason = "checked non-negative above")]
            self.put(x as u32, y as u32, c);
        }
    }

    /// Pixel-centre bounding box of points, clamped to the picture: x0, y0, x1, y1 inclusive.
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "clamped to the picture before the cast"
    )]
    fn span(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Option<[u32; 4]> {
        let (w, h) = (f64::from(self.w) - 1.0, f64::from(self.h) - 1.0);
        if x1 < 0.0 || y1 < 0.0 || x0 > w + 1.0 || y0 > h + 1.0 {
            return None;
        }
        Some([
            x0.floor().clamp(0.0, w) as u32,
            y0.floor().clamp(0.0, h) as u32,
            x1.ceil().clamp(0.0, w) as u32,
            y1.ceil().clamp(0.0, h) as u32,
        ])
    }

    fn fill_convex(&mut self, pts: &[(f64, f64); 4], c: [u8; 3]) {
        let xs = pts.map(|p| p.0);
        let ys = pts.map(|p| p.1);
        let fold = |v: [f64; 4], f: fn(f64, f64) -> f64, init: f64| v.iter().copied().fold(init, f);
        let Some([x0, y0, x1, y1]) = self.span(
            fold(xs, f64::min, f64::MAX),
            fold(ys, f64::min, f64::MAX),
            fold(xs, f64::max, f64::MIN),
            fold(ys, f64::max, f64::MIN),
        ) else {
            return;
        };
        let mut drew = false;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                // Inside when on the same side of every edge (either winding).
                let mut pos = true;
                let mut neg = true;
                for k in 0..4 {
                    let (a, b) = (pts[k], pts[(k + 1) % 4]);
                    let cross = (b.0 - a.0) * (py - a.1) - (b.1 - a.1) * (px - a.0);
                    pos &= cross >= 0.0;
                    neg &= cross <= 0.0;
                }
                if pos || neg {
                    self.put(x, y, c);
                    drew = true;
                }
            }
        }
        if !drew {
            // Thinner than a pixel: still show it.
            let (cx, cy) = (xs.iter().sum::<f64>() / 4.0, ys.iter().sum::<f64>() / 4.0);
            self.put_f(cx, cy, c);
        }
    }

    fn fill_circle(&mut self, cx: f64, cy: f64, r: f64, c: [u8; 3]) {
        let Some([x0, y0, x1, y1]) = self.span(cx - r, cy - r, cx + r, cy + r) else {
            return;
        };
        let mut drew = false;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (dx, dy) = (f64::from(x) + 0.5 - cx, f64::from(y) + 0.5 - cy);
                if dx * dx + dy * dy <= r * r {
                    self.put(x, y, c);
                    drew = true;
                }
            }
        }
        if !drew {
            self.put_f(cx, cy, c);
        }
    }

    fn circle(&mut self, cx: f64, cy: f64, r: f64, c: [u8; 3]) {
        let n = ((r * 8.0).ceil()).clamp(16.0, 4096.0);
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped to [16, 4096]"
        )]
        let steps = n as usize;
        for k in 0..steps {
            let a = k as f64 / n * std::f64::consts::TAU;
            self.put_f(cx + r * a.cos(), cy + r * a.sin(), c);
        }
    }

    fn line(&mut self, a: (f64, f64), b: (f64, f64), c: [u8; 3]) {
        let len = (b.0 - a.0).abs().max((b.1 - a.1).abs());
        if !len.is_finite() {
            return;
        }
        let n = len.ceil().clamp(1.0, 100_000.0);
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "clamped to [1, 1e5]"
        )]
        let steps = n as usize;
        for k in 0..=steps {
            let t = k as f64 / n;
            self.put_f(a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1), c);
        }
    }

    fn encode(self) -> Result<Vec<u8>, RenderError> {
        use image::ImageEncoder as _;
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out).write_image(
            &self.data,
            self.w,
            self.h,
            image::ExtendedColorType::Rgb8,
        )?;
        Ok(out)
    }
}

/// An SVG picture of `world` with `overlay`. Walls are merged into rectangles in the grid's own
/// frame, so a large map stays a few hundred kilobytes; objects carry their identifiers as
/// tooltips.
pub fn svg(
    world: &World,
    overlay: &Overlay,
    options: &RenderOptions,
) -> Result<String, RenderError> {
    let mut opts = *options;
    // An SVG scales freely: default to 20 px/m, and allow larger sides than a PNG.
    if opts.pixels_per_metre.is_none() {
        opts.pixels_per_metre = Some(20.0);
    }
    opts.max_side = opts.max_side.max(16_384);
    let view = View::new(world, &opts)?;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}">"#,
        w = view.width,
        h = view.height
    );
    let _ = writeln!(
        s,
        r#"<rect width="100%" height="100%" fill="{}"/>"#,
        hex(FREE)
    );
    // Grid-local metres to picture pixels.
    let o = world.grid_origin();
    let (sn, cs) = o.yaw.sin_cos();
    let p = view.ppm;
    let _ = writeln!(
        s,
        r#"<g transform="matrix({a:.6} {b:.6} {c:.6} {d:.6} {e:.3} {f:.3})" shape-rendering="crispEdges">"#,
        a = cs * p,
        b = -sn * p,
        c = -sn * p,
        d = -cs * p,
        e = (o.x - view.min_x) * p,
        f = (view.max_y - o.y) * p
    );
    let res = world.resolution();
    for (unknown, colour) in [(false, OCCUPIED), (true, UNKNOWN)] {
        let _ = writeln!(s, r#"<g fill="{}">"#, hex(colour));
        for [x, y, w, h] in merged_runs(world, unknown) {
            let _ = writeln!(
                s,
                r#"<rect x="{:.4}" y="{:.4}" width="{:.4}" height="{:.4}"/>"#,
                f64::from(x) * res,
                f64::from(y) * res,
                f64::from(w) * res,
                f64::from(h) * res
            );
        }
        let _ = writeln!(s, "</g>");
    }
    let _ = writeln!(s, "</g>");
    for (id, part) in parts_by_height(world) {
        let fill = part.colour.to_hex();
        let title = format!("{} ({})", xml_escape(&id), part.name);
        match part.shape {
            Shape::Box => {
                let pts: Vec<String> = box_corners(&part)
                    .iter()
                    .map(|(x, y)| {
                        let (px, py) = view.to_px(*x, *y);
                        format!("{px:.2},{py:.2}")
                    })
                    .collect();
                let _ = writeln!(
                    s,
                    r#"<polygon points="{}" fill="{fill}" stroke="black" stroke-width="0.5"><title>{title}</title></polygon>"#,
                    pts.join(" ")
                );
            }
            Shape::Cylinder | Shape::Sphere => {
                let (cx, cy) = view.to_px(part.pose.x, part.pose.y);
                let _ = writeln!(
                    s,
                    r#"<circle cx="{cx:.2}" cy="{cy:.2}" r="{:.2}" fill="{fill}" stroke="black" stroke-width="0.5"><title>{title}</title></circle>"#,
                    round_radius(&part) * p
                );
            }
        }
    }
    let mut line = |a: (f64, f64), b: (f64, f64), colour: [u8; 3], width: f64| {
        let (p1, p2) = (view.to_px(a.0, a.1), view.to_px(b.0, b.1));
        let _ = writeln!(
            s,
            r#"<line x1="{:.2}" y1="{:.2}" x2="{:.2}" y2="{:.2}" stroke="{}" stroke-width="{width}"/>"#,
            p1.0,
            p1.1,
            p2.0,
            p2.1,
            hex(colour)
        );
    };
    for g in &overlay.segments {
        line(g.from, g.to, g.rgb, 1.5);
    }
    for (a, b) in &overlay.beams {
        line(*a, *b, BEAM, 1.0);
    }
    if overlay.trajectory.len() > 1 {
        let pts: Vec<String> = overlay
            .trajectory
            .iter()
            .map(|q| {
                let (x, y) = view.to_px(q.x, q.y);
                format!("{x:.2},{y:.2}")
            })
            .collect();
        let _ = writeln!(
            s,
            r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="2"/>"#,
            pts.join(" "),
            hex(TRAJECTORY)
        );
    }
    if let Some(g) = overlay.goal {
        let (x, y) = view.to_px(g.0, g.1);
        let _ = writeln!(
            s,
            r#"<circle cx="{x:.2}" cy="{y:.2}" r="{:.2}" fill="none" stroke="{}" stroke-width="2"><title>goal</title></circle>"#,
            (0.15 * p).max(3.0),
            hex(GOAL)
        );
    }
    if let Some(pose) = overlay.robot {
        let r = world.spec().robot.footprint_radius;
        let (x, y) = view.to_px(pose.x, pose.y);
        let (tx, ty) = view.to_px(pose.x + r * pose.yaw.cos(), pose.y + r * pose.yaw.sin());
        let _ = writeln!(
            s,
            r#"<g stroke="{c}" stroke-width="2" fill="none"><title>robot</title><circle cx="{x:.2}" cy="{y:.2}" r="{:.2}"/><line x1="{x:.2}" y1="{y:.2}" x2="{tx:.2}" y2="{ty:.2}"/></g>"#,
            r * p,
            c = hex(ROBOT)
        );
    }
    s.push_str("</svg>\n");
    Ok(s)
}

/// Rectangles `[col, row, width, height]` (cells) covering the solid cells of one kind (unknown
/// or not): runs along each row, merged with identical runs in the row below.
fn merged_runs(world: &World, unknown: bool) -> Vec<[u32; 4]> {
    let (w, h) = world.grid_size();
    let mut done: Vec<[u32; 4]> = Vec::new();
    // Open rectangles by (start, end) of their run, as indices into `done`.
    let mut open: HashMap<(u32, u32), usize> = HashMap::new();
    for row in 0..h {
        let mut next_open = HashMap::new();
        let mut col = 0;
        while col < w {
            if world.cell_look(col, row) != Some(unknown) {
                col += 1;
                continue;
            }
            let start = col;
            while col < w && world.cell_look(col, row) == Some(unknown) {
                col += 1;
            }
            let key = (crate::spec::as_u32(start), crate::spec::as_u32(col));
            let idx = match open.remove(&key) {
                Some(i) => {
                    done[i][3] += 1;
                    i
                }
                None => {
                    done.push([key.0, crate::spec::as_u32(row), key.1 - key.0, 1]);
                    done.len() - 1
                }
            };
            next_open.insert(key, idx);
        }
        open = next_open;
    }
    done
}

fn hex(c: [u8; 3]) -> String {
    Colour::rgb(c[0], c[1], c[2]).to_hex()
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
