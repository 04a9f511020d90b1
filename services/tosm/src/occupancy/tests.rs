//! map_server parity: YAML keys, thresholds, row order, image formats and round trips.

use super::*;

const GOOD: &str = "image: map.pgm\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";

fn meta() -> RosMapMeta {
    RosMapMeta::parse_yaml(GOOD).expect("good yaml")
}

/// Replaces the line that starts with `key:` in GOOD (or drops it when `line` is empty).
fn with_line(key: &str, line: &str) -> String {
    GOOD.lines()
        .map(|l| {
            if l.starts_with(&format!("{key}:")) {
                line.to_owned()
            } else {
                l.to_owned()
            }
        })
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("\n")
}

fn parse_err(yaml: &str) -> RosMapError {
    RosMapMeta::parse_yaml(yaml).expect_err("should be rejected")
}

#[test]
fn parses_a_map_server_yaml() {
    let m = meta();
    assert_eq!(m.image, "map.pgm");
    assert_eq!(m.resolution, 0.05);
    assert_eq!(m.origin, Pose2::new(-1.0, 2.0, 0.0));
    assert!(!m.negate);
    assert_eq!(m.mode, "trinary");
    let m = RosMapMeta::parse_yaml(&with_line("negate", "negate: true")).expect("bool negate");
    assert!(m.negate);
    let m = RosMapMeta::parse_yaml(&format!("{GOOD}mode: scale\n")).expect("mode");
    assert_eq!(m.mode, "scale");
    let m = RosMapMeta::parse_yaml(&with_line("origin", "origin: [0, 0, 0]")).expect("ints");
    assert_eq!(m.origin, Pose2::new(0.0, 0.0, 0.0));
}

#[test]
fn malformed_yaml_is_reported() {
    assert!(matches!(
        parse_err("image: [map.pgm\nresolution: 0.05"),
        RosMapError::MalformedYaml { .. }
    ));
    assert!(matches!(
        parse_err("- just\n- a list\n"),
        RosMapError::NotAMapping { .. }
    ));
    assert!(matches!(parse_err(""), RosMapError::NotAMapping { .. }));
}

#[test]
fn each_missing_key_is_named() {
    for key in [
        "image",
        "resolution",
        "origin",
        "negate",
        "occupied_thresh",
        "free_thresh",
    ] {
        let err = parse_err(&with_line(key, ""));
        assert_eq!(
            err,
            RosMapError::MissingKey {
                key: match key {
                    "image" => "image",
                    "resolution" => "resolution",
                    "origin" => "origin",
                    "negate" => "negate",
                    "occupied_thresh" => "occupied_thresh",
                    _ => "free_thresh",
                }
            }
        );
        assert!(err.to_string().contains(key), "{err}");
    }
}

#[test]
fn bad_resolutions_are_rejected() {
    for (text, check) in [
        ("resolution: 0", 0.0),
        ("resolution: -0.05", -0.05),
        ("resolution: .inf", f64::INFINITY),
    ] {
        let err = parse_err(&with_line("resolution", text));
        assert_eq!(
            err,
            RosMapError::InvalidResolution { value: check },
            "{text}"
        );
    }
    let err = parse_err(&with_line("resolution", "resolution: .nan"));
    assert!(matches!(err, RosMapError::InvalidResolution { value } if value.is_nan()));
    let err = parse_err(&with_line("resolution", "resolution: fine"));
    assert!(
        matches!(
            err,
            RosMapError::WrongType {
                key: "resolution",
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("\"fine\""), "{err}");
}

#[test]
fn bad_origins_are_rejected() {
    for text in [
        "origin: [1.0, 2.0]",
        "origin: 3",
        "origin: [a, 1, 2]",
        "origin: {x: 1}",
    ] {
        let err = parse_err(&with_line("origin", text));
        assert!(
            matches!(err, RosMapError::WrongType { key: "origin", .. }),
            "{text}: {err:?}"
        );
    }
    let err = parse_err(&with_line("origin", "origin: [.nan, 0, 0]"));
    assert!(matches!(err, RosMapError::InvalidOrigin { .. }), "{err:?}");
}

#[test]
fn bad_thresholds_are_rejected() {
    let err = parse_err(&with_line("occupied_thresh", "occupied_thresh: 1.5"));
    assert_eq!(
        err,
        RosMapError::ThresholdOutOfRange {
            key: "occupied_thresh",
            value: 1.5
        }
    );
    let err = parse_err(&with_line("free_thresh", "free_thresh: -0.1"));
    assert_eq!(
        err,
        RosMapError::ThresholdOutOfRange {
            key: "free_thresh",
            value: -0.1
        }
    );
    let err = parse_err(&with_line("free_thresh", "free_thresh: .nan"));
    assert!(matches!(
        err,
        RosMapError::ThresholdOutOfRange {
            key: "free_thresh",
            ..
        }
    ));
    let err = parse_err(&with_line("free_thresh", "free_thresh: 0.65"));
    assert_eq!(
        err,
        RosMapError::ThresholdsNotOrdered {
            free: 0.65,
            occupied: 0.65
        }
    );
}

#[test]
fn bad_negate_image_and_mode_are_rejected() {
    let err = parse_err(&with_line("negate", "negate: 2"));
    assert!(matches!(err, RosMapError::WrongType { key: "negate", .. }));
    let err = parse_err(&with_line("image", "image: 7"));
    assert!(matches!(err, RosMapError::WrongType { key: "image", .. }));
    let err = parse_err(&format!("{GOOD}mode: fancy\n"));
    assert_eq!(
        err,
        RosMapError::UnknownMode {
            value: "fancy".to_owned()
        }
    );
    let err = parse_err(&format!("{GOOD}mode: 3\n"));
    assert!(matches!(err, RosMapError::WrongType { key: "mode", .. }));
}

fn pgm_p5(width: usize, height: usize, pixels: &[u8]) -> Vec<u8> {
    let mut out = format!("P5\n# test\n{width} {height}\n255\n").into_bytes();
    out.extend_from_slice(pixels);
    out
}

#[test]
fn thresholds_and_row_order_follow_map_server() {
    // Top image row: free (254), unknown (205), occupied (0); bottom row: 255, 100, 128.
    let img = pgm_p5(3, 2, &[254, 205, 0, 255, 100, 128]);
    let grid = OccupancyGrid::from_ros_map_server(&meta(), &img).expect("decodes");
    assert_eq!((grid.width, grid.height), (3, 2));
    use Occupancy::*;
    // Grid row 0 is the image's bottom row. p(100) = 0.608 -> unknown; p(128) = 0.498 -> unknown.
    assert_eq!(
        grid.cells,
        vec![Free, Unknown, Unknown, Free, Unknown, Occupied]
    );
    assert!(grid.is_free(0, 1));
    assert!(!grid.is_free(1, 1), "unknown is not free");
    assert!(!grid.is_free(3, 0), "outside is not free");

    let mut negated = meta();
    negated.negate = true;
    let grid = OccupancyGrid::from_ros_map_server(&negated, &img).expect("decodes");
    // Negated, p = v / 255: 205 -> 0.80 is occupied.
    assert_eq!(
        grid.cells,
        vec![Occupied, Unknown, Unknown, Occupied, Occupied, Free]
    );
}

#[test]
fn threshold_boundaries_are_strict() {
    // p = (255 - v) / 255 must be strictly below free_thresh to be free.
    let mut m = meta();
    m.free_thresh = 50.0 / 255.0;
    m.occupied_thresh = 200.0 / 255.0;
    let img = pgm_p5(4, 1, &[205, 206, 55, 54]);
    let grid = OccupancyGrid::from_ros_map_server(&m, &img).expect("decodes");
    use Occupancy::*;
    assert_eq!(grid.cells, vec![Unknown, Free, Unknown, Occupied]);
}

#[test]
fn ascii_pgm_and_png_decode() {
    let p2 = b"P2\n3 1\n255\n254 205 0\n";
    let grid = OccupancyGrid::from_ros_map_server(&meta(), p2).expect("P2 decodes");
    use Occupancy::*;
    assert_eq!(grid.cells, vec![Free, Unknown, Occupied]);
    let png = grid.to_png();
    let back = OccupancyGrid::from_ros_map_server(&meta(), &png).expect("PNG decodes");
    assert_eq!(back, grid);
}

#[test]
fn raw_and_scale_modes() {
    use Occupancy::*;
    let mut m = meta();
    m.mode = "raw".to_owned();
    let img = pgm_p5(4, 1, &[0, 100, 50, 255]);
    let grid = OccupancyGrid::from_ros_map_server(&m, &img).expect("decodes");
    assert_eq!(grid.cells, vec![Free, Occupied, Unknown, Unknown]);
    m.mode = "scale".to_owned();
    let img = pgm_p5(3, 1, &[254, 150, 0]);
    let grid = OccupancyGrid::from_ros_map_server(&m, &img).expect("decodes");
    assert_eq!(grid.cells, vec![Free, Unknown, Occupied]);
}

#[test]
fn colour_pixels_are_averaged() {
    use image::ImageEncoder;
    // (254+254+254)/3 free; (255+0+0)/3 = 85 -> p = 0.667 occupied; (255,255,0) -> 170 -> p=0.333 unknown.
    let rgb = [254, 254, 254, 255, 0, 0, 255, 255, 0];
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&rgb, 3, 1, image::ExtendedColorType::Rgb8)
        .expect("encode");
    let grid = OccupancyGrid::from_ros_map_server(&meta(), &png).expect("decodes");
    use Occupancy::*;
    assert_eq!(grid.cells, vec![Free, Occupied, Unknown]);
}

#[test]
fn bad_images_are_rejected() {
    let err = OccupancyGrid::from_ros_map_server(&meta(), b"GIF89a....").expect_err("gif");
    assert!(
        matches!(err, RosMapError::UnsupportedImageFormat { .. }),
        "{err:?}"
    );
    let err = OccupancyGrid::from_ros_map_server(&meta(), b"").expect_err("empty");
    assert!(
        matches!(err, RosMapError::UnsupportedImageFormat { .. }),
        "{err:?}"
    );
    let err = OccupancyGrid::from_ros_map_server(&meta(), b"hello world").expect_err("text");
    assert!(
        matches!(err, RosMapError::UnsupportedImageFormat { .. }),
        "{err:?}"
    );
    // PBM (P4) is PNM but not a map_server image.
    let err = OccupancyGrid::from_ros_map_server(&meta(), b"P4\n1 1\n\x00").expect_err("pbm");
    assert!(
        matches!(err, RosMapError::UnsupportedImageFormat { .. }),
        "{err:?}"
    );

    // Truncated: the header promises 3x2 pixels, the data holds 4.
    let truncated = pgm_p5(3, 2, &[1, 2, 3, 4]);
    let err = OccupancyGrid::from_ros_map_server(&meta(), &truncated).expect_err("short");
    assert!(
        matches!(err, RosMapError::BadImage { format: "PGM", .. }),
        "{err:?}"
    );
    // A huge header with no data must not allocate gigabytes or panic.
    let huge = b"P5\n100000 100000\n255\n".to_vec();
    let err = OccupancyGrid::from_ros_map_server(&meta(), &huge).expect_err("huge");
    assert!(matches!(err, RosMapError::TooManyPixels { .. }), "{err:?}");
    let zero = b"P5\n0 0\n255\n".to_vec();
    let err = OccupancyGrid::from_ros_map_server(&meta(), &zero).expect_err("zero");
    assert!(
        matches!(
            err,
            RosMapError::BadImage { .. } | RosMapError::EmptyImage { .. }
        ),
        "{err:?}"
    );

    let png = OccupancyGrid::filled(4, 4, 0.1, Pose2::new(0.0, 0.0, 0.0), Occupancy::Free).to_png();
    let err =
        OccupancyGrid::from_ros_map_server(&meta(), &png[..png.len() / 2]).expect_err("cut PNG");
    assert!(
        matches!(err, RosMapError::BadImage { format: "PNG", .. }),
        "{err:?}"
    );
}

#[test]
fn invalid_meta_built_by_hand_is_rejected_before_decoding() {
    let mut m = meta();
    m.resolution = f64::NAN;
    let img = pgm_p5(1, 1, &[254]);
    assert!(matches!(
        OccupancyGrid::from_ros_map_server(&m, &img),
        Err(RosMapError::InvalidResolution { .. })
    ));
    let mut m = meta();
    m.mode = "binary".to_owned();
    assert!(matches!(
        OccupancyGrid::from_ros_map_server(&m, &img),
        Err(RosMapError::UnknownMode { .. })
    ));
}

#[test]
fn world_and_cell_coordinates() {
    let grid = OccupancyGrid::filled(10, 5, 0.5, Pose2::new(-1.0, 2.0, 0.0), Occupancy::Free);
    assert_eq!(grid.cell_of(-1.0, 2.0), Some((0, 0)));
    assert_eq!(grid.cell_of(-0.76, 2.26), Some((0, 0)));
    assert_eq!(grid.cell_of(3.99, 4.49), Some((9, 4)));
    assert_eq!(grid.cell_of(4.0, 3.0), None);
    assert_eq!(grid.cell_of(-1.01, 3.0), None);
    assert_eq!(grid.cell_of(f64::NAN, 3.0), None);
    assert_eq!(grid.cell_center(0, 0), (-0.75, 2.25));
    assert_eq!(grid.cell_center(9, 4), (3.75, 4.25));
    assert_eq!(grid.free_area_m2(), 12.5);
}

#[test]
fn rotated_origin_is_honoured() {
    let yaw = std::f64::consts::FRAC_PI_2;
    let grid = OccupancyGrid::filled(4, 2, 1.0, Pose2::new(10.0, 0.0, yaw), Occupancy::Free);
    // The grid's x axis points along world +y, its y axis along world -x.
    let (x, y) = grid.cell_center(3, 1);
    assert!((x - 8.5).abs() < 1e-9 && (y - 3.5).abs() < 1e-9, "{x} {y}");
    assert_eq!(grid.cell_of(8.5, 3.5), Some((3, 1)));
    assert_eq!(grid.cell_of(10.5, 0.5), None);
    for row in 0..2 {
        for col in 0..4 {
            let (x, y) = grid.cell_center(col, row);
            assert_eq!(grid.cell_of(x, y), Some((col, row)));
        }
    }
}

#[test]
fn png_round_trip_keeps_every_state() {
    use Occupancy::*;
    let mut grid = OccupancyGrid::filled(3, 2, 0.05, Pose2::new(1.0, 1.0, 0.0), Unknown);
    grid.cells = vec![Free, Occupied, Unknown, Occupied, Free, Free];
    let png = grid.to_png();
    let meta = RosMapMeta::for_grid_png("x.png", 0.05, Pose2::new(1.0, 1.0, 0.0));
    let back = OccupancyGrid::from_ros_map_server(&meta, &png).expect("decodes");
    assert_eq!(back, grid);
    // The top image row holds grid row 1.
    let decoded = image::load_from_memory(&png).expect("png").to_luma8();
    assert_eq!(decoded.as_raw(), &vec![0, 254, 254, 254, 0, 205]);
    assert!(
        OccupancyGrid::filled(0, 3, 1.0, Pose2::new(0.0, 0.0, 0.0), Free)
            .to_png()
            .is_empty()
    );
}

#[test]
fn written_yaml_reads_back_to_equal_values() {
    for m in [
        meta(),
        RosMapMeta::for_grid_png("floor.png", 0.025, Pose2::new(-12.5, 3.0, 0.25)),
    ] {
        let back = RosMapMeta::parse_yaml(&m.to_yaml()).expect("own yaml parses");
        assert_eq!(back, m);
    }
}

#[test]
fn values_that_overflow_and_images_that_declare_too_many_pixels_are_refused() {
    assert!(matches!(
        parse_err(&with_line("resolution", "resolution: 1.0e306")),
        RosMapError::InvalidResolution { .. }
    ));
    assert!(matches!(
        parse_err(&with_line("origin", "origin: [1.0e300, 0.0, 0.0]")),
        RosMapError::InvalidOrigin { .. }
    ));
    // Header only: 20,000 × 20,000 pixels declared in a few bytes.
    let bomb = b"P5\n20000 20000\n255\n\xfe".to_vec();
    let err = OccupancyGrid::from_ros_map_server(&meta(), &bomb).expect_err("refused");
    assert!(
        matches!(
            err,
            RosMapError::TooManyPixels {
                width: 20000,
                height: 20000,
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn a_grid_written_as_pgm_reads_back_the_same() {
    let mut g = OccupancyGrid::filled(5, 3, 0.05, Pose2::new(-1.0, 2.0, 0.3), Occupancy::Free);
    g.cells[0] = Occupancy::Occupied;
    g.cells[7] = Occupancy::Unknown;
    g.cells[14] = Occupancy::Occupied;
    let pgm = g.to_pgm();
    assert!(pgm.starts_with(b"P5\n5 3\n255\n"));
    let meta = RosMapMeta::for_grid_png("map.pgm", g.resolution, g.origin);
    let back = OccupancyGrid::from_ros_map_server(&meta, &pgm).expect("reads back");
    assert_eq!(back, g);
    // The YAML reads back to the same values.
    assert_eq!(RosMapMeta::parse_yaml(&meta.to_yaml()).expect("yaml"), meta);
    let empty = OccupancyGrid::filled(0, 3, 0.05, Pose2::new(0.0, 0.0, 0.0), Occupancy::Free);
    assert!(empty.to_pgm().is_empty());
}

/// Grey maps are read from their bytes, other layouts through RGBA: the same pixels as grey,
/// grey with alpha, RGB and RGBA give the same grid, rows and negation included; in `scale`
/// mode a transparent grey pixel is unknown.
#[test]
fn every_pixel_layout_reads_alike() {
    use image::{ExtendedColorType, ImageEncoder};
    let grey: [u8; 6] = [254, 205, 0, 255, 100, 128];
    let png = |data: &[u8], layout: ExtendedColorType| {
        let mut out = Vec::new();
        image::codecs::png::PngEncoder::new(&mut out)
            .write_image(data, 3, 2, layout)
            .expect("encode");
        out
    };
    let with = |channels: usize, alpha: bool| -> Vec<u8> {
        grey.iter()
            .flat_map(|&v| {
                let mut px = vec![v; channels];
                if alpha {
                    px.push(255);
                }
                px
            })
            .collect()
    };
    let images = [
        png(&grey, ExtendedColorType::L8),
        png(&with(1, true), ExtendedColorType::La8),
        png(&with(3, false), ExtendedColorType::Rgb8),
        png(&with(3, true), ExtendedColorType::Rgba8),
    ];
    for negate in [false, true] {
        let mut m = meta();
        m.negate = negate;
        let expected = OccupancyGrid::from_ros_map_server(&m, &pgm_p5(3, 2, &grey)).expect("pgm");
        for img in &images {
            let grid = OccupancyGrid::from_ros_map_server(&m, img).expect("png");
            assert_eq!(grid, expected, "negate {negate}");
        }
    }
    let mut m = meta();
    m.mode = "scale".to_owned();
    let mut la = with(1, true);
    la[1] = 0; // the first pixel (free, 254) fully transparent
    let grid =
        OccupancyGrid::from_ros_map_server(&m, &png(&la, ExtendedColorType::La8)).expect("png");
    assert_eq!(grid.cells[3], Occupancy::Unknown, "{:?}", grid.cells);
    assert_eq!(grid.cells[4], Occupancy::Unknown, "205 is unknown anyway");
    assert_eq!(grid.cells[5], Occupancy::Occupied);
}
