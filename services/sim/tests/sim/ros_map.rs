//! A world built from a real ROS map in the shared maps (`fixtures::shared_fixture`: skipped,
//! saying so, when absent; a failure under CI).

use std::sync::Arc;

use sim::{Action, EnvConfig, FloorMap, NavEnv, OccupancyGrid, RobotSpec, World, WorldSpec};

fn shared_map(folder: &str, yaml: &str) -> Option<(String, OccupancyGrid)> {
    let yaml_path =
        fixtures::shared_fixture(format!("maps/ros/{folder}/{yaml}"), "the shared map")?;
    let text = std::fs::read_to_string(&yaml_path).expect("yaml reads");
    let meta = tosm::RosMapMeta::parse_yaml(&text).expect("yaml parses");
    let image_path = yaml_path.with_file_name(&meta.image);
    let Ok(image) = std::fs::read(&image_path) else {
        fixtures::missing(format!("the shared map image {}", image_path.display()));
        return None;
    };
    let grid = OccupancyGrid::from_ros_map_server(&meta, &image).expect("map decodes");
    Some((folder.to_owned(), grid))
}

#[test]
fn a_world_from_a_real_ros_map() {
    let Some((id, grid)) = shared_map("aws_small_house", "map.yaml") else {
        return;
    };
    let free_area = grid.free_area_m2();
    let spec = WorldSpec {
        id: id.clone(),
        floor: Some(FloorMap {
            id,
            grid,
            wall_height: 2.5,
            frame_id: "map".into(),
        }),
        walls: vec![],
        objects: vec![],
        robot: RobotSpec::example_differential(),
        people: Default::default(),
        notes: vec![],
    };
    let world = World::build(spec).expect("builds");
    let region = world.free_region_area_m2();
    // The largest region where the robot fits is part of the free area, and most of the house.
    assert!(
        region < free_area && region > 0.3 * free_area,
        "{region} of {free_area}"
    );
    let mut env = NavEnv::new(Arc::clone(&world), EnvConfig::default(), 1).expect("env");
    for _ in 0..20 {
        let obs = env.reset_random().expect("reset");
        assert!(obs.ranges.iter().all(|r| (0.05..=10.0).contains(r)));
        for _ in 0..50 {
            if env.step(Action::new(0.5, 0.1)).done {
                break;
            }
        }
    }
}
