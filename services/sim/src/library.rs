//! The built-in model library: real shapes (a table as a top on four legs, a door in its frame,
//! …) keyed by TOSM class, and placeholders of an object's own shape for every other class.
//!
//! A model is a list of primitive parts scaled to the object's bounding box, so the laser sees
//! what is at its height (a table's legs, not its top) and exports write the same parts.

use crate::spec::{Colour, ObjectSpec, Pose3, Shape, Size3};

/// A model in the library.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum LibraryModel {
    /// A door: two jambs and a lintel, and a leaf unless the door is open.
    Door,
    /// A table or desk: a top on four legs.
    Table,
    /// A chair: a seat on four legs, with a backrest.
    Chair,
    /// A shelf: side panels, a back panel and boards.
    Shelf,
    /// A cabinet, cupboard or locker: a closed box.
    Cabinet,
}

impl LibraryModel {
    /// Every model, in a stable order.
    pub const ALL: [LibraryModel; 5] = [
        LibraryModel::Door,
        LibraryModel::Table,
        LibraryModel::Chair,
        LibraryModel::Shelf,
        LibraryModel::Cabinet,
    ];

    /// The model's name, as exports write it.
    pub fn name(self) -> &'static str {
        match self {
            LibraryModel::Door => "door",
            LibraryModel::Table => "table",
            LibraryModel::Chair => "chair",
            LibraryModel::Shelf => "shelf",
            LibraryModel::Cabinet => "cabinet",
        }
    }

    /// The model for a TOSM class, given as an IRI (`…#Table`), a prefixed name (`tosm:Table`) or
    /// a local name, ignoring case: a class whose local name contains a model's keyword (a
    /// `SteelDoor` is a door, a `Desk` a table) uses that model.
    pub fn for_class(class: &str) -> Option<LibraryModel> {
        let local = class
            .rsplit(['#', '/', ':'])
            .next()
            .unwrap_or(class)
            .to_ascii_lowercase();
        let has = |words: &[&str]| words.iter().any(|w| local.contains(w));
        // Order matters: a "DoorShelf" is still a shelf-like piece of furniture in a room, and a
        // "TableCabinet" is closed below: the more enclosing model wins.
        if has(&["cabinet", "cupboard", "locker", "wardrobe", "drawer"]) {
            Some(LibraryModel::Cabinet)
        } else if has(&["shelf", "shelv", "rack", "bookcase"]) {
            Some(LibraryModel::Shelf)
        } else if has(&["door", "gate"]) {
            Some(LibraryModel::Door)
        } else if has(&["table", "desk"]) {
            Some(LibraryModel::Table)
        } else if has(&["chair", "stool"]) {
            Some(LibraryModel::Chair)
        } else {
            None
        }
    }
}

/// How an object is represented in the simulation.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Model {
    /// A library model scaled to the object's size.
    Library(LibraryModel),
    /// The object's own shape, size and colour (the paper's red vending machine).
    Placeholder,
}

/// The model used for `object`.
pub fn model_for(object: &ObjectSpec) -> Model {
    object
        .class
        .as_deref()
        .and_then(LibraryModel::for_class)
        .map_or(Model::Placeholder, Model::Library)
}

/// A primitive part of a model, placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Part {
    /// The part's name within its model (`leg_1`, `top`, `body`, …).
    pub name: &'static str,
    /// Primitive shape.
    pub shape: Shape,
    /// Bounding-box size.
    pub size: Size3,
    /// World pose of the part's centre.
    pub pose: Pose3,
    /// Colour.
    pub colour: Colour,
}

/// The parts of `object` in the world frame. Roll and pitch are ignored (objects stand upright;
/// validation says so).
pub fn parts(object: &ObjectSpec) -> Vec<Part> {
    let local = match model_for(object) {
        Model::Placeholder => vec![("body", object.shape, object.size, [0.0; 3])],
        Model::Library(m) => library_parts(m, object.size, object.open),
    };
    let (s, c) = object.pose.yaw.sin_cos();
    local
        .into_iter()
        .map(|(name, shape, size, [lx, ly, lz])| Part {
            name,
            shape,
            size,
            pose: Pose3::new(
                object.pose.x + c * lx - s * ly,
                object.pose.y + s * lx + c * ly,
                object.pose.z + lz,
                object.pose.yaw,
            ),
            colour: object.colour,
        })
        .collect()
}

/// A part in the object's frame: name, shape, size and centre relative to the bounding-box centre.
type LocalPart = (&'static str, Shape, Size3, [f64; 3]);

/// The parts of a library model filling a bounding box of `size` centred on the origin.
fn library_parts(model: LibraryModel, size: Size3, open: bool) -> Vec<LocalPart> {
    let (hx, hy, hz) = (size.x / 2.0, size.y / 2.0, size.z / 2.0);
    let b = Shape::Box;
    match model {
        LibraryModel::Cabinet => vec![("body", b, size, [0.0; 3])],
        LibraryModel::Table => {
            let top = (0.1 * size.z).min(0.04);
            let leg = (size.x.min(size.y) / 5.0).min(0.05);
            let leg_h = size.z - top;
            let (lx, ly) = (hx - leg / 2.0, hy - leg / 2.0);
            let legz = -hz + leg_h / 2.0;
            vec![
                (
                    "top",
                    b,
                    Size3::new(size.x, size.y, top),
                    [0.0, 0.0, hz - top / 2.0],
                ),
                ("leg_1", b, Size3::new(leg, leg, leg_h), [lx, ly, legz]),
                ("leg_2", b, Size3::new(leg, leg, leg_h), [lx, -ly, legz]),
                ("leg_3", b, Size3::new(leg, leg, leg_h), [-lx, ly, legz]),
                ("leg_4", b, Size3::new(leg, leg, leg_h), [-lx, -ly, legz]),
            ]
        }
        LibraryModel::Chair => {
            // The seat sits at half the height; the backrest rises from it along the -x edge.
            let seat = (0.1 * size.z).min(0.04);
            let seat_top = size.z / 2.0;
            let leg = (size.x.min(size.y) / 6.0).min(0.04);
            let leg_h = seat_top - seat;
            let back = (size.x / 8.0).min(0.04);
            let (lx, ly) = (hx - leg / 2.0, hy - leg / 2.0);
            let legz = -hz + leg_h / 2.0;
            let back_h = size.z - seat_top;
            vec![
                (
                    "seat",
                    b,
                    Size3::new(size.x, size.y, seat),
                    [0.0, 0.0, -hz + seat_top - seat / 2.0],
                ),
                ("leg_1", b, Size3::new(leg, leg, leg_h), [lx, ly, legz]),
                ("leg_2", b, Size3::new(leg, leg, leg_h), [lx, -ly, legz]),
                ("leg_3", b, Size3::new(leg, leg, leg_h), [-lx, ly, legz]),
                ("leg_4", b, Size3::new(leg, leg, leg_h), [-lx, -ly, legz]),
                (
                    "backrest",
                    b,
                    Size3::new(back, size.y, back_h),
                    [-hx + back / 2.0, 0.0, hz - back_h / 2.0],
                ),
            ]
        }
        LibraryModel::Shelf => {
            // Open at +x: side panels, a back panel, a plinth and boards every ~0.4 m.
            let panel = (size.y / 10.0).min(0.02);
            let back = (size.x / 10.0).min(0.01);
            let plinth = (size.z / 10.0).min(0.08);
            let mut parts: Vec<LocalPart> = vec![
                (
                    "side_left",
                    b,
                    Size3::new(size.x, panel, size.z),
                    [0.0, hy - panel / 2.0, 0.0],
                ),
                (
                    "side_right",
                    b,
                    Size3::new(size.x, panel, size.z),
                    [0.0, -hy + panel / 2.0, 0.0],
                ),
                (
                    "back",
                    b,
                    Size3::new(back, size.y, size.z),
                    [-hx + back / 2.0, 0.0, 0.0],
                ),
                (
                    "plinth",
                    b,
                    Size3::new(size.x, size.y, plinth),
                    [0.0, 0.0, -hz + plinth / 2.0],
                ),
            ];
            const BOARD_NAMES: [&str; 8] = [
                "board_1", "board_2", "board_3", "board_4", "board_5", "board_6", "board_7",
                "board_8",
            ];
            let board = panel;
            let span = size.z - plinth;
            #[allow(
                clippy::cast_possible_truncation,
                clippy::cast_sign_loss,
                reason = "a small positive count, clamped to the names available"
            )]
            let n = ((span / 0.4).round() as usize).clamp(1, BOARD_NAMES.len());
            for (k, name) in BOARD_NAMES.iter().take(n).enumerate() {
                let top = plinth + span * (k as f64 + 1.0) / n as f64;
                parts.push((
                    name,
                    b,
                    Size3::new(size.x, size.y, board),
                    [0.0, 0.0, -hz + top - board / 2.0],
                ));
            }
            parts
        }
        LibraryModel::Door => {
            // The leaf spans y (the opening's width) and is `size.x` thick.
            let jamb = (size.y / 10.0).min(0.06);
            let lintel = (size.z / 10.0).min(0.06);
            let mut parts: Vec<LocalPart> = vec![
                (
                    "jamb_left",
                    b,
                    Size3::new(size.x, jamb, size.z),
                    [0.0, hy - jamb / 2.0, 0.0],
                ),
                (
                    "jamb_right",
                    b,
                    Size3::new(size.x, jamb, size.z),
                    [0.0, -hy + jamb / 2.0, 0.0],
                ),
                (
                    "lintel",
                    b,
                    Size3::new(size.x, size.y - 2.0 * jamb, lintel),
                    [0.0, 0.0, hz - lintel / 2.0],
                ),
            ];
            if !open {
                let leaf = (size.x * 0.8).min(0.045);
                parts.push((
                    "leaf",
                    b,
                    Size3::new(leaf, size.y - 2.0 * jamb, size.z - lintel),
                    [0.0, 0.0, -lintel / 2.0],
                ));
            }
            parts
        }
    }
}
