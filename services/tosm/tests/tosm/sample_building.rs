//! Generates `ontologies/environments/sample-building.ttl` from the ROS maps copied beside it
//! and checks that the committed file is up to date.
//!
//! Refresh it with `UPDATE_ONTOLOGIES=1 cargo test -p tosm --test tosm sample_building`.
//! The building: floor 0 is the Fraunhofer IPA apartment lab (rooms, corridors, a hall), floor 1
//! the TUM kitchen lab; both maps are real and copied unchanged with their sources and licences.
//! Room polygons are given in map pixels (image row 0 at the top) and converted with the map's
//! own geometry; the test checks that every vertex and every object's centre lies on a free cell.
//! What is known about people (expected numbers, two walking routes and an attractor) is given
//! the same way; every route point and the attractor keep 0.2 m from anything not free.

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::path::PathBuf;

use oxrdf::{Graph, Triple};
use tosm::{
    Attractor, Colour, MetricMap, Object, ObjectClass, Occupancy, OccupancyGrid, Physical, Place,
    PlaceKind, PlacePeople, Pose3, Relation, RelationKind, RosMapMeta, Shape, Symbol, WalkingRoute,
    vocab,
};

const BUILDING: &str = "https://mentalsim.dev/data/buildings/sample-building";
const OUTPUT: &str = "ontologies/environments/sample-building.ttl";

fn repo_root() -> PathBuf {
    PathBuf::from(
        std::env::var("CARGO_MANIFEST_DIR")
            .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
    )
    .join("../..")
}

/// (slug, kind, name, polygon in image pixels (column, row from the top)).
type PlaceSpec = (&'static str, PlaceKind, &'static str, Vec<(u32, u32)>);

struct FloorSpec {
    level: i64,
    name: &'static str,
    description: &'static str,
    map_dir: &'static str,
    yaml: &'static str,
    places: Vec<PlaceSpec>,
    /// Pairs of place slugs a robot can drive between.
    connections: Vec<(&'static str, &'static str)>,
}

fn floors() -> Vec<FloorSpec> {
    use PlaceKind::*;
    vec![
        FloorSpec {
            level: 0,
            name: "Apartment floor",
            description: "Fraunhofer IPA apartment lab, Stuttgart (cob_environments map).",
            map_dir: "cob_ipa_apartment",
            yaml: "map.yaml",
            places: vec![
                (
                    "bedroom",
                    Room,
                    "Bedroom",
                    vec![(70, 98), (144, 101), (143, 172), (66, 172)],
                ),
                (
                    "office",
                    Room,
                    "Office",
                    vec![(66, 190), (138, 194), (137, 234), (63, 233)],
                ),
                (
                    "storage",
                    Room,
                    "Storage room",
                    vec![(196, 98), (268, 102), (268, 136), (196, 133)],
                ),
                (
                    "guest-room",
                    Room,
                    "Guest room",
                    vec![(195, 150), (266, 154), (262, 245), (192, 242)],
                ),
                (
                    "hallway",
                    Corridor,
                    "Hallway",
                    vec![
                        (160, 104),
                        (177, 104),
                        (178, 258),
                        (205, 262),
                        (205, 290),
                        (168, 292),
                        (167, 335),
                        (144, 335),
                        (142, 292),
                        (113, 290),
                        (113, 256),
                        (158, 254),
                    ],
                ),
                (
                    "hall",
                    Hall,
                    "Hall",
                    vec![
                        (44, 420),
                        (115, 357),
                        (150, 357),
                        (228, 445),
                        (228, 470),
                        (200, 470),
                        (178, 500),
                        (125, 538),
                        (110, 535),
                        (48, 462),
                    ],
                ),
                (
                    "diagonal-corridor",
                    Corridor,
                    "Diagonal corridor",
                    vec![(217, 296), (267, 264), (322, 330), (300, 380)],
                ),
                (
                    "vestibule",
                    Corridor,
                    "Vestibule",
                    vec![
                        (232, 444),
                        (296, 444),
                        (300, 388),
                        (316, 388),
                        (318, 470),
                        (232, 470),
                    ],
                ),
                (
                    "living-room",
                    Room,
                    "Living room",
                    vec![(348, 366), (478, 368), (472, 548), (338, 545)],
                ),
            ],
            connections: vec![
                ("hallway", "bedroom"),
                ("hallway", "office"),
                ("hallway", "storage"),
                ("hallway", "guest-room"),
                ("hallway", "hall"),
                ("hallway", "diagonal-corridor"),
                ("diagonal-corridor", "vestibule"),
                ("hall", "vestibule"),
                ("vestibule", "living-room"),
            ],
        },
        FloorSpec {
            level: 1,
            name: "Kitchen floor",
            description: "TUM kitchen lab, Munich (strands_morse map).",
            map_dir: "strands_tum_kitchen",
            yaml: "tum_kitchen.yaml",
            places: vec![(
                "kitchen",
                Room,
                "Kitchen",
                vec![(14, 14), (126, 14), (126, 220), (14, 220)],
            )],
            connections: vec![],
        },
    ]
}

fn floor_iri(level: i64) -> String {
    format!("{BUILDING}/floors/{level}")
}

fn place_iri(level: i64, slug: &str) -> String {
    format!("{}/{slug}", floor_iri(level))
}

fn object_iri(slug: &str) -> String {
    format!("{BUILDING}/objects/{slug}")
}

struct ObjectSpec {
    slug: &'static str,
    class: ObjectClass,
    name: &'static str,
    place: (i64, &'static str),
    pose: Pose3,
    shape: Shape,
    colour: (f64, f64, f64, &'static str),
    mass_kg: f64,
    material: oxrdf::NamedNodeRef<'static>,
    relations: Vec<(RelationKind, &'static str)>,
}

fn object_specs() -> Vec<ObjectSpec> {
    use ObjectClass::*;
    use RelationKind::*;
    let wood = (0.55, 0.35, 0.2, "brown");
    vec![
        ObjectSpec {
            slug: "vending-machine-1",
            class: VendingMachine,
            name: "Beverage vending machine",
            place: (0, "living-room"),
            pose: Pose3::new(4.2, -2.0, 0.915, PI),
            shape: Shape::Box {
                length: 0.8,
                width: 0.9,
                height: 1.83,
            },
            colour: (0.8, 0.05, 0.05, "red"),
            mass_kg: 350.0,
            material: vocab::STEEL,
            relations: vec![],
        },
        ObjectSpec {
            slug: "shelf-1",
            class: Shelf,
            name: "Book shelf",
            place: (0, "living-room"),
            pose: Pose3::new(1.0, 0.25, 0.9, -FRAC_PI_2),
            shape: Shape::Box {
                length: 0.4,
                width: 1.2,
                height: 1.8,
            },
            colour: wood,
            mass_kg: 40.0,
            material: vocab::WOOD,
            relations: vec![],
        },
        ObjectSpec {
            slug: "table-1",
            class: Table,
            name: "Dining table",
            place: (0, "living-room"),
            pose: Pose3::new(1.0, -4.0, 0.375, 0.0),
            shape: Shape::Box {
                length: 1.6,
                width: 0.9,
                height: 0.75,
            },
            colour: wood,
            mass_kg: 30.0,
            material: vocab::WOOD,
            relations: vec![],
        },
        ObjectSpec {
            slug: "chair-1",
            class: Chair,
            name: "Chair",
            place: (0, "living-room"),
            pose: Pose3::new(1.0, -3.2, 0.45, -FRAC_PI_2),
            shape: Shape::Box {
                length: 0.45,
                width: 0.45,
                height: 0.9,
            },
            colour: wood,
            mass_kg: 5.0,
            material: vocab::WOOD,
            relations: vec![(NextTo, "table-1")],
        },
        ObjectSpec {
            slug: "chair-2",
            class: Chair,
            name: "Chair",
            place: (0, "living-room"),
            pose: Pose3::new(2.15, -4.0, 0.45, PI),
            shape: Shape::Box {
                length: 0.45,
                width: 0.45,
                height: 0.9,
            },
            colour: wood,
            mass_kg: 5.0,
            material: vocab::WOOD,
            relations: vec![(InFrontOf, "table-1"), (NextTo, "table-1")],
        },
        ObjectSpec {
            slug: "door-1",
            class: Door,
            name: "Living room door",
            place: (0, "living-room"),
            pose: Pose3::new(-1.9, -2.6, 1.0, FRAC_PI_2),
            shape: Shape::Box {
                length: 0.9,
                width: 0.04,
                height: 2.0,
            },
            colour: (0.6, 0.6, 0.62, "steel grey"),
            mass_kg: 40.0,
            material: vocab::STEEL,
            relations: vec![],
        },
        ObjectSpec {
            slug: "table-2",
            class: Table,
            name: "Round table",
            place: (0, "hall"),
            pose: Pose3::new(-12.7, -3.3, 0.375, 0.0),
            shape: Shape::Cylinder {
                diameter: 1.0,
                height: 0.75,
            },
            colour: (0.95, 0.95, 0.95, "white"),
            mass_kg: 20.0,
            material: vocab::PLASTIC,
            relations: vec![],
        },
        ObjectSpec {
            slug: "chair-3",
            class: Chair,
            name: "Chair",
            place: (0, "hall"),
            pose: Pose3::new(-12.7, -2.45, 0.45, -FRAC_PI_2),
            shape: Shape::Box {
                length: 0.45,
                width: 0.45,
                height: 0.9,
            },
            colour: (0.2, 0.3, 0.6, "blue"),
            mass_kg: 4.0,
            material: vocab::PLASTIC,
            relations: vec![(NextTo, "table-2"), (InFrontOf, "table-2")],
        },
        ObjectSpec {
            slug: "bin-1",
            class: Bin,
            name: "Waste bin",
            place: (1, "kitchen"),
            pose: Pose3::new(-1.5, 2.5, 0.2, 0.0),
            shape: Shape::Cylinder {
                diameter: 0.3,
                height: 0.4,
            },
            colour: (0.3, 0.3, 0.3, "grey"),
            mass_kg: 1.0,
            material: vocab::PLASTIC,
            relations: vec![],
        },
    ]
}

/// Expected people in a place: (floor level, place slug, all day, by hour of day).
type PeopleSpec = (i64, &'static str, f64, Vec<(u8, f64)>);

fn people_specs() -> Vec<PeopleSpec> {
    vec![
        // Someone at the desk most of the working day.
        (0, "office", 1.0, vec![]),
        // Passers-by, busier when people arrive, go to lunch and leave.
        (0, "hallway", 0.5, vec![(8, 1.5), (12, 2.0), (17, 1.5)]),
        (0, "hall", 1.0, vec![(12, 3.0), (13, 2.0)]),
        // The vending machine draws people at lunch and in the afternoon break.
        (0, "living-room", 1.5, vec![(12, 4.0), (13, 3.0), (15, 2.0)]),
        (1, "kitchen", 2.0, vec![(7, 3.0), (12, 5.0), (18, 3.0)]),
    ]
}

/// Walking routes on floor 0: (slug, name, points in image pixels (column, row from the top)).
type RouteSpec = (&'static str, &'static str, Vec<(u32, u32)>);

fn route_specs() -> Vec<RouteSpec> {
    vec![
        (
            "bedroom-door-to-hall",
            "From the bedroom door along the hallway to the hall",
            vec![
                (168, 110),
                (168, 250),
                (156, 275),
                (155, 330),
                (135, 365),
                (120, 420),
            ],
        ),
        (
            "hall-to-vending-machine",
            "From the hall through the vestibule to the vending machine",
            vec![
                (190, 455),
                (250, 457),
                (310, 456),
                (345, 456),
                (380, 445),
                (445, 423),
            ],
        ),
    ]
}

/// Clearance every route point and attractor keeps from cells that are not free, metres.
const PEOPLE_CLEARANCE_M: f64 = 0.2;

/// Whether every cell within `PEOPLE_CLEARANCE_M` of `(x, y)` is free.
fn clear_around(grid: &OccupancyGrid, (x, y): (f64, f64)) -> bool {
    let reach = (PEOPLE_CLEARANCE_M / grid.resolution).ceil() as i64;
    let Some((col, row)) = grid.cell_of(x, y) else {
        return false;
    };
    (-reach..=reach).all(|dr| {
        (-reach..=reach).all(|dc| {
            let (c, r) = (col as i64 + dc, row as i64 + dr);
            c >= 0 && r >= 0 && grid.is_free(c as usize, r as usize)
        })
    })
}

/// World coordinates of the centre of image pixel `(column, row from the top)`.
fn pixel_to_world(grid: &OccupancyGrid, (col, row): (u32, u32)) -> (f64, f64) {
    let grid_row = grid.height - 1 - row as usize;
    let (x, y) = grid.cell_center(col as usize, grid_row);
    // Round to the millimetre so the file stays readable.
    ((x * 1000.0).round() / 1000.0, (y * 1000.0).round() / 1000.0)
}

fn point_in_polygon(polygon: &[(f64, f64)], (x, y): (f64, f64)) -> bool {
    let mut inside = false;
    let n = polygon.len();
    for i in 0..n {
        let (xi, yi) = polygon[i];
        let (xj, yj) = polygon[(i + n - 1) % n];
        if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
            inside = !inside;
        }
    }
    inside
}

/// Share of the polygon's known cells that are occupied (the paper's place complexity).
fn complexity(grid: &OccupancyGrid, polygon: Option<&[(f64, f64)]>) -> f64 {
    let (mut free, mut occupied) = (0usize, 0usize);
    for row in 0..grid.height {
        for col in 0..grid.width {
            if let Some(polygon) = polygon
                && !point_in_polygon(polygon, grid.cell_center(col, row))
            {
                continue;
            }
            match grid.get(col, row) {
                Some(Occupancy::Free) => free += 1,
                Some(Occupancy::Occupied) => occupied += 1,
                _ => {}
            }
        }
    }
    let c = occupied as f64 / (free + occupied).max(1) as f64;
    (c * 1000.0).round() / 1000.0
}

struct Generated {
    places: Vec<Place>,
    objects: Vec<Object>,
    people: Vec<PlacePeople>,
    routes: Vec<WalkingRoute>,
    attractors: Vec<Attractor>,
}

fn generate() -> Generated {
    let maps = repo_root().join("ontologies/environments/maps");
    let mut places = vec![Place {
        iri: BUILDING.to_owned(),
        kind: PlaceKind::Building,
        symbol: Symbol {
            name: "Sample building".to_owned(),
            identifier: Some("B-001".to_owned()),
            description: Some(
                "Mentalsim's bundled sample: two real ROS maps as the floors of one building."
                    .to_owned(),
            ),
        },
        boundary: vec![],
        parent: None,
        connected: vec![],
        complexity: None,
        level: None,
        map: None,
    }];
    let mut polygons: BTreeMap<String, (i64, Vec<(f64, f64)>)> = BTreeMap::new();
    let mut grids = BTreeMap::new();
    for floor in floors() {
        let dir = maps.join(floor.map_dir);
        let yaml = std::fs::read_to_string(dir.join(floor.yaml)).expect("map yaml");
        let meta = RosMapMeta::parse_yaml(&yaml).expect("valid yaml");
        let image = std::fs::read(dir.join(&meta.image)).expect("map image");
        let grid = OccupancyGrid::from_ros_map_server(&meta, &image).expect("valid map");
        let iri = floor_iri(floor.level);
        // The floor's boundary is the map's extent.
        let (w, h) = (
            grid.width as f64 * grid.resolution,
            grid.height as f64 * grid.resolution,
        );
        let boundary: Vec<(f64, f64)> = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
            .iter()
            .map(|(x, y)| {
                let (x, y) = grid.grid_frame_to_world(*x, *y);
                ((x * 1000.0).round() / 1000.0, (y * 1000.0).round() / 1000.0)
            })
            .collect();
        let mut connected: BTreeMap<&str, Vec<String>> = BTreeMap::new();
        for (a, b) in &floor.connections {
            connected
                .entry(a)
                .or_default()
                .push(place_iri(floor.level, b));
            connected
                .entry(b)
                .or_default()
                .push(place_iri(floor.level, a));
        }
        for (slug, kind, name, pixels) in &floor.places {
            for p in pixels {
                let (col, row) = (p.0 as usize, grid.height - 1 - p.1 as usize);
                assert!(
                    grid.is_free(col, row),
                    "{slug}: vertex {p:?} is not on a free cell"
                );
            }
            let polygon: Vec<(f64, f64)> =
                pixels.iter().map(|p| pixel_to_world(&grid, *p)).collect();
            let mut links = connected.remove(slug).unwrap_or_default();
            links.sort();
            polygons.insert(place_iri(floor.level, slug), (floor.level, polygon.clone()));
            places.push(Place {
                iri: place_iri(floor.level, slug),
                kind: *kind,
                symbol: Symbol {
                    name: (*name).to_owned(),
                    identifier: Some(format!("F{}-{slug}", floor.level)),
                    description: None,
                },
                complexity: Some(complexity(&grid, Some(&polygon))),
                boundary: polygon,
                parent: Some(iri.clone()),
                connected: links,
                level: None,
                map: None,
            });
        }
        assert!(
            connected.is_empty(),
            "connections name unknown places: {connected:?}"
        );
        places.push(Place {
            iri: iri.clone(),
            kind: PlaceKind::Floor,
            symbol: Symbol {
                name: floor.name.to_owned(),
                identifier: Some(format!("F{}", floor.level)),
                description: Some(floor.description.to_owned()),
            },
            boundary,
            parent: Some(BUILDING.to_owned()),
            connected: vec![],
            complexity: Some(complexity(&grid, None)),
            level: Some(floor.level),
            map: Some(MetricMap::from_grid(
                &MetricMap::iri_for_floor(&iri),
                grid.clone(),
            )),
        });
        grids.insert(floor.level, grid);
    }
    let mut objects = Vec::new();
    for o in object_specs() {
        let place = place_iri(o.place.0, o.place.1);
        let (level, polygon) = &polygons[&place];
        let grid = &grids[level];
        let centre = (o.pose.x, o.pose.y);
        assert!(
            point_in_polygon(polygon, centre),
            "{}: centre is outside {place}",
            o.slug
        );
        let (col, row) = grid.cell_of(centre.0, centre.1).expect("centre on the map");
        assert!(
            grid.is_free(col, row),
            "{}: centre is not on a free cell",
            o.slug
        );
        let class_iri = match o.class {
            ObjectClass::VendingMachine => vocab::VENDING_MACHINE,
            ObjectClass::Shelf => vocab::SHELF,
            ObjectClass::Table => vocab::TABLE,
            ObjectClass::Chair => vocab::CHAIR,
            ObjectClass::Door => vocab::DOOR,
            ObjectClass::Bin => vocab::BIN,
            _ => vocab::OBJECT,
        };
        let (r, g, b, colour_name) = o.colour;
        objects.push(Object {
            iri: object_iri(o.slug),
            class_iri: class_iri.as_str().to_owned(),
            class: o.class,
            symbol: Symbol {
                name: o.name.to_owned(),
                identifier: Some(format!("O-{}", o.slug)),
                description: None,
            },
            pose: o.pose,
            shape: o.shape,
            colour: Some(Colour::rgb(r, g, b)),
            colour_name: Some(colour_name.to_owned()),
            physical: Physical {
                mass_kg: Some(o.mass_kg),
                material: Some(o.material.as_str().to_owned()),
                friction: None,
            },
            inside_of: place,
            relations: o
                .relations
                .iter()
                .map(|(kind, target)| Relation {
                    kind: *kind,
                    target: object_iri(target),
                })
                .collect(),
            is_open: (o.class == ObjectClass::Door).then_some(true),
            reported_by: None,
            reported_at: None,
        });
    }
    // isNextTo is symmetric: state it from both sides, as a reader entails it anyway.
    let next_to: Vec<(String, String)> = objects
        .iter()
        .flat_map(|o| {
            o.relations
                .iter()
                .filter(|r| r.kind == RelationKind::NextTo)
                .map(|r| (r.target.clone(), o.iri.clone()))
        })
        .collect();
    for (from, to) in next_to {
        if let Some(o) = objects.iter_mut().find(|o| o.iri == from) {
            o.relations.push(Relation {
                kind: RelationKind::NextTo,
                target: to,
            });
        }
    }
    for o in &mut objects {
        o.relations.sort();
        o.relations.dedup();
    }
    places.sort_by(|a, b| a.iri.cmp(&b.iri));
    objects.sort_by(|a, b| a.iri.cmp(&b.iri));
    let mut people: Vec<PlacePeople> = people_specs()
        .into_iter()
        .map(|(level, slug, expected, by_hour)| {
            let place = place_iri(level, slug);
            assert!(polygons.contains_key(&place), "people in unknown {place}");
            PlacePeople {
                place,
                expected: Some(expected),
                by_hour,
                estimates: vec![],
            }
        })
        .collect();
    people.sort_by(|a, b| a.place.cmp(&b.place));
    let floor0 = &grids[&0];
    let mut routes: Vec<WalkingRoute> = route_specs()
        .into_iter()
        .map(|(slug, name, pixels)| {
            let points: Vec<(f64, f64)> =
                pixels.iter().map(|p| pixel_to_world(floor0, *p)).collect();
            // Walkable: every point along every segment (sampled at a quarter cell) is clear.
            for pair in points.windows(2) {
                let ((ax, ay), (bx, by)) = (pair[0], pair[1]);
                let steps = ((bx - ax).hypot(by - ay) / (floor0.resolution / 4.0)).ceil() as usize;
                for k in 0..=steps {
                    let t = k as f64 / steps.max(1) as f64;
                    let at = (ax + t * (bx - ax), ay + t * (by - ay));
                    assert!(
                        clear_around(floor0, at),
                        "{slug}: {at:?} is within {PEOPLE_CLEARANCE_M} m of a wall"
                    );
                }
            }
            WalkingRoute {
                iri: format!("{}/routes/{slug}", floor_iri(0)),
                name: Some(name.to_owned()),
                inside_of: floor_iri(0),
                points,
            }
        })
        .collect();
    routes.sort_by(|a, b| a.iri.cmp(&b.iri));
    // People stand half a metre in front of the vending machine (its front faces along its
    // own +x, the world's -x at yaw pi) and linger a minute.
    let vending = objects
        .iter()
        .find(|o| o.iri == object_iri("vending-machine-1"))
        .expect("the vending machine");
    let [length, _, _] = vending.shape.size();
    let reach = length / 2.0 + 0.5;
    let stand = (
        vending.pose.x + reach * vending.pose.yaw.cos(),
        vending.pose.y + reach * vending.pose.yaw.sin(),
    );
    let stand = (
        (stand.0 * 1000.0).round() / 1000.0,
        (stand.1 * 1000.0).round() / 1000.0,
    );
    let living_room = place_iri(0, "living-room");
    assert!(point_in_polygon(&polygons[&living_room].1, stand));
    assert!(
        clear_around(floor0, stand),
        "the attractor is too close to a wall"
    );
    let attractors = vec![Attractor {
        iri: format!("{}/attractors/vending-machine", floor_iri(0)),
        name: Some("In front of the vending machine".to_owned()),
        inside_of: living_room,
        pose: Pose3::new(
            stand.0,
            stand.1,
            0.0,
            (vending.pose.yaw + PI).rem_euclid(TAU),
        ),
        dwell_s: 60.0,
        relations: vec![Relation {
            kind: RelationKind::InFrontOf,
            target: vending.iri.clone(),
        }],
    }];
    Generated {
        places,
        objects,
        people,
        routes,
        attractors,
    }
}

fn to_turtle(g: &Generated) -> String {
    let mut triples: Vec<Triple> = Vec::new();
    for p in &g.places {
        triples.extend(tosm::place_to_triples(p).expect("valid place"));
    }
    for o in &g.objects {
        triples.extend(tosm::object_to_triples(o).expect("valid object"));
    }
    for p in &g.people {
        triples.extend(tosm::place_people_to_triples(p).expect("valid people figures"));
    }
    for r in &g.routes {
        triples.extend(tosm::walking_route_to_triples(r).expect("valid route"));
    }
    for a in &g.attractors {
        triples.extend(tosm::attractor_to_triples(a).expect("valid attractor"));
    }
    // The door connects the two places it stands between.
    let door = oxrdf::NamedNode::new_unchecked(object_iri("door-1"));
    for place in ["living-room", "vestibule"] {
        triples.push(Triple::new(
            door.clone(),
            vocab::CONNECTS_PLACE.into_owned(),
            oxrdf::NamedNode::new_unchecked(place_iri(0, place)),
        ));
    }
    let ontology = oxrdf::NamedNode::new_unchecked(format!("{BUILDING}.ttl"));
    triples.push(Triple::new(
        ontology.clone(),
        oxrdf::vocab::rdf::TYPE,
        oxrdf::NamedNode::new_unchecked("http://www.w3.org/2002/07/owl#Ontology"),
    ));
    triples.push(Triple::new(
        ontology,
        oxrdf::NamedNode::new_unchecked("http://www.w3.org/2002/07/owl#imports"),
        vocab::ONTOLOGY.into_owned(),
    ));
    triples.sort_by_cached_key(ToString::to_string);
    triples.dedup();
    let mut serializer = oxttl::TurtleSerializer::new()
        .with_prefix("tosm", vocab::NS)
        .and_then(|s| s.with_prefix("owl", "http://www.w3.org/2002/07/owl#"))
        .and_then(|s| s.with_prefix("xsd", "http://www.w3.org/2001/XMLSchema#"))
        .and_then(|s| s.with_prefix("building", format!("{BUILDING}/")))
        .expect("prefixes")
        .for_writer(Vec::new());
    for t in &triples {
        serializer.serialize_triple(t).expect("serialize");
    }
    let body = String::from_utf8(serializer.finish().expect("finish")).expect("utf-8");
    format!(
        "# GENERATED by services/tosm/tests/tosm/sample_building.rs from the maps in maps/; do not edit.\n\
         # Refresh: UPDATE_ONTOLOGIES=1 cargo test -p tosm --test tosm sample_building\n{body}"
    )
}

#[test]
fn sample_building_ttl_is_up_to_date_with_its_maps() {
    let generated = to_turtle(&generate());
    let path = repo_root().join(OUTPUT);
    if std::env::var_os("UPDATE_ONTOLOGIES").is_some() {
        std::fs::write(&path, &generated).expect("write sample building");
        println!("wrote {}", path.display());
        return;
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "{} is out of date with its maps or generator; run \
         UPDATE_ONTOLOGIES=1 cargo test -p tosm --test tosm sample_building",
        path.display()
    );
}

#[test]
fn sample_building_reads_back_to_the_same_values() {
    let generated = generate();
    let ttl = to_turtle(&generated);
    let mut graph = Graph::new();
    for t in oxttl::TurtleParser::new().for_slice(ttl.as_bytes()) {
        graph.insert(&t.expect("valid turtle"));
    }
    let places = tosm::read_places(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(places, generated.places);
    let objects = tosm::read_objects(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(objects, generated.objects);
    let people = tosm::read_people(&graph).unwrap_or_else(|p| panic!("{p}"));
    assert_eq!(people.places, generated.people);
    assert_eq!(people.routes, generated.routes);
    assert_eq!(people.attractors, generated.attractors);
    assert_eq!(
        (
            people.places.len(),
            people.routes.len(),
            people.attractors.len()
        ),
        (5, 2, 1)
    );
    let vending = objects
        .iter()
        .find(|o| o.class == ObjectClass::VendingMachine)
        .expect("vending machine");
    assert_eq!(
        vending.colour.map(|c| (c.r, c.g, c.b)),
        Some((0.8, 0.05, 0.05))
    );
    assert!(matches!(vending.shape, Shape::Box { .. }));
    let floor0 = places
        .iter()
        .find(|p| p.iri == floor_iri(0))
        .expect("floor 0");
    let map = floor0.map.as_ref().expect("floor map");
    assert_eq!((map.grid.width, map.grid.height), (544, 768));
    assert!((map.grid.free_area_m2() - 310.0).abs() < 3.1);
}
