//! Every real ROS map in the shared map collection parses, and its free area matches the table
//! in the collection's README (computed there with map_server's own rules).

use tosm::{OccupancyGrid, RosMapMeta};

/// (folder, yaml file, pixels, free area in m² from the README table).
const MAPS: &[(&str, &str, (usize, usize), f64)] = &[
    ("nav2_depot", "depot.yaml", (604, 307), 449.0),
    ("nav2_warehouse", "warehouse.yaml", (1006, 1674), 1280.0),
    ("aws_small_house", "map.yaml", (500, 500), 158.0),
    ("aws_bookstore", "map.yaml", (384, 384), 155.0),
    (
        "willow_garage_slam",
        "willow-2010-02-18-0.10.yaml",
        (566, 608),
        1092.0,
    ),
    (
        "willow_full_stage",
        "willow-full-0.05.yaml",
        (1165, 945),
        1373.0,
    ),
    ("strands_tum_kitchen", "tum_kitchen.yaml", (148, 238), 72.0),
    ("strands_bham_cs_lg", "cs_lg.yaml", (562, 993), 1129.0),
    ("strands_aaf", "aaf_sim.yaml", (878, 2693), 4088.0),
    ("cob_ipa_apartment", "map.yaml", (544, 768), 310.0),
    ("cob_ipa_production_plant", "map.yaml", (1985, 1536), 3053.0),
];

#[test]
fn every_shared_ros_map_parses_with_the_readme_free_area() {
    let Some(root) = fixtures::shared_fixture("maps/ros", "the shared map collection") else {
        return;
    };
    let listed: std::collections::BTreeSet<String> =
        MAPS.iter().map(|(dir, ..)| (*dir).to_owned()).collect();
    for entry in std::fs::read_dir(&root).expect("read map dir") {
        let name = entry
            .expect("entry")
            .file_name()
            .to_string_lossy()
            .into_owned();
        assert!(
            listed.contains(&name),
            "map folder {name} is not in this test's table"
        );
    }
    for (dir, yaml_name, (w, h), free_area) in MAPS {
        let dir = root.join(dir);
        let yaml = std::fs::read_to_string(dir.join(yaml_name)).expect("read yaml");
        let meta =
            RosMapMeta::parse_yaml(&yaml).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        let image = std::fs::read(dir.join(&meta.image)).expect("read image");
        let grid = OccupancyGrid::from_ros_map_server(&meta, &image)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        assert_eq!((grid.width, grid.height), (*w, *h), "{}", dir.display());
        let area = grid.free_area_m2();
        let error = (area - free_area).abs() / free_area;
        assert!(
            error < 0.01,
            "{}: free area {area:.1} m² vs README {free_area} m²",
            dir.display()
        );
        println!("{}: {w}x{h}, free {area:.1} m²", dir.display());
    }
}
