//! The mental simulation of a ROS map file, built the way the service builds one: the map
//! becomes the TOSM floor an import writes ([`super::floor_triples`]), furniture becomes TOSM
//! objects inside it, the robot comes from its TOSM Turtle, and the simulation parser reads
//! that on-demand database. What `mentalsim train`, `eval` and the benchmarks run in.

use std::path::Path;
use std::sync::Arc;

use oxigraph::io::{RdfFormat, RdfParser};
use oxigraph::model::{Graph, Triple};
use sim::{ObjectSpec, Shape, World};
use tosm::OccupancyGrid;

use super::files::{LoadError, RosMapFiles, name_for_path};
use super::{floor_iri, floor_triples};

/// The on-demand database of a map, its furniture and a robot: the map becomes the floor an
/// import of it under [`name_for_path`] would write, each object a TOSM object inside it, and
/// the robot's Turtle is read as it is. `yaml_path` names the map (and the errors).
pub fn on_demand_database(
    yaml_path: &Path,
    grid: OccupancyGrid,
    objects: &[ObjectSpec],
    robot_ttl: &[u8],
    robot_iri: &str,
) -> Result<Graph, LoadError> {
    let bad = |message: String| LoadError::World {
        path: yaml_path.to_path_buf(),
        message,
    };
    let name = name_for_path(yaml_path);
    let floor_iri = floor_iri(&name);
    let mut graph = Graph::new();
    let triples = floor_triples(&name, grid).map_err(|e| bad(format!("floor: {e}")))?;
    for t in &triples {
        graph.insert(t);
    }
    for o in objects {
        let object = tosm_object(o, &floor_iri);
        let triples = tosm::object_to_triples(&object).map_err(|p| bad(format!("object: {p}")))?;
        for t in &triples {
            graph.insert(t);
        }
    }
    for quad in RdfParser::from_format(RdfFormat::Turtle).for_slice(robot_ttl) {
        let quad = quad.map_err(|e| bad(format!("robot Turtle: {e}")))?;
        graph.insert(&Triple::from(quad));
    }
    if !graph
        .iter()
        .any(|t| t.subject.to_string() == format!("<{robot_iri}>"))
    {
        return Err(bad(format!(
            "the robot file does not describe <{robot_iri}>"
        )));
    }
    Ok(graph)
}

/// The TOSM object of a simulated object inside `floor_iri`: its class from the local name of
/// its class IRI (an unknown one is a plain object), its shape, pose and colour.
fn tosm_object(o: &ObjectSpec, floor_iri: &str) -> tosm::Object {
    let class_local = o
        .class
        .as_deref()
        .and_then(|c| c.rsplit('#').next())
        .unwrap_or("Object");
    let (class, class_iri) = match class_local {
        "Table" => (tosm::ObjectClass::Table, None),
        "Chair" => (tosm::ObjectClass::Chair, None),
        "Shelf" => (tosm::ObjectClass::Shelf, None),
        "Cabinet" => (tosm::ObjectClass::Cabinet, None),
        "VendingMachine" => (tosm::ObjectClass::VendingMachine, None),
        "Bin" => (tosm::ObjectClass::Bin, None),
        "Door" => (tosm::ObjectClass::Door, None),
        _ => (
            tosm::ObjectClass::Other,
            Some(format!("{}Object", tosm::vocab::NS)),
        ),
    };
    let [r, g, b] = o.colour.to_unit();
    tosm::Object {
        iri: o.id.clone(),
        class_iri: class_iri.unwrap_or_else(|| format!("{}{class_local}", tosm::vocab::NS)),
        class,
        symbol: tosm::Symbol::named(class_local),
        pose: tosm::Pose3::new(o.pose.x, o.pose.y, o.pose.z, o.pose.yaw),
        shape: match o.shape {
            Shape::Box => tosm::Shape::Box {
                length: o.size.x,
                width: o.size.y,
                height: o.size.z,
            },
            Shape::Cylinder => tosm::Shape::Cylinder {
                diameter: o.size.x.max(o.size.y),
                height: o.size.z,
            },
            Shape::Sphere => tosm::Shape::Sphere {
                diameter: o.size.x.max(o.size.y).max(o.size.z),
            },
        },
        colour: Some(tosm::Colour::rgb(r, g, b)),
        colour_name: None,
        physical: tosm::Physical::default(),
        inside_of: floor_iri.to_owned(),
        relations: vec![],
        is_open: None,
        reported_by: None,
        reported_at: None,
    }
}

/// The world of an on-demand database, through the simulation parser.
fn world_from_database(
    yaml_path: &Path,
    graph: &Graph,
    robot_iri: &str,
) -> Result<Arc<World>, LoadError> {
    let spec = sim::parse_on_demand(graph, robot_iri).map_err(|problems| LoadError::World {
        path: yaml_path.to_path_buf(),
        message: format!("the simulation parser refused the on-demand database: {problems}"),
    })?;
    World::build(spec).map_err(|problems| LoadError::World {
        path: yaml_path.to_path_buf(),
        message: format!("the world could not be built: {problems}"),
    })
}

/// The mental simulation of the map_server map at `yaml_path`: its floor, `objects` pieces of
/// furniture placed from `seed` ([`sim::floors::furnish`]), and the robot `robot_iri` described
/// by `robot_ttl`, through the on-demand database and the simulation parser.
pub fn world_from_map(
    yaml_path: &Path,
    robot_ttl: &[u8],
    robot_iri: &str,
    objects: usize,
    seed: u64,
) -> Result<Arc<World>, LoadError> {
    let grid = RosMapFiles::read(yaml_path)?.grid()?;
    let furniture = if objects > 0 {
        sim::floors::furnish(&grid, objects, seed)
    } else {
        Vec::new()
    };
    let graph = on_demand_database(yaml_path, grid, &furniture, robot_ttl, robot_iri)?;
    world_from_database(yaml_path, &graph, robot_iri)
}
