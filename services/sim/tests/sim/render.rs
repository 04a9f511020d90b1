//! Renders are valid PNG and SVG and show what they should.

use sim::render::{Overlay, RenderOptions, png, svg};
use sim::{Colour, Pose2, Pose3, Shape, Size3, World};

use crate::common::{object, room};

fn scene() -> (std::sync::Arc<World>, Overlay) {
    let mut spec = room(10.0, 6.0);
    let mut vending = object(
        "http://example.org/env#vending<1>",
        Some("VendingMachine"),
        Shape::Box,
        Size3::new(0.8, 0.7, 1.8),
        Pose3::new(7.0, 2.0, 0.9, 0.2),
    );
    vending.colour = Colour::rgb(220, 0, 0);
    spec.objects.push(vending);
    spec.objects.push(object(
        "t",
        Some("Table"),
        Shape::Box,
        Size3::new(1.2, 0.8, 0.75),
        Pose3::new(3.0, 4.0, 0.375, 0.0),
    ));
    spec.objects.push(object(
        "bin",
        None,
        Shape::Cylinder,
        Size3::new(0.4, 0.4, 0.6),
        Pose3::new(5.0, 5.0, 0.3, 0.0),
    ));
    let world = World::build(spec).expect("builds");
    let pose = Pose2::new(2.0, 2.0, 0.3);
    let overlay = Overlay {
        trajectory: vec![Pose2::new(1.0, 1.0, 0.0), Pose2::new(1.5, 1.5, 0.0), pose],
        robot: Some(pose),
        goal: Some((8.0, 4.5)),
        show_free_region: true,
        ..Overlay::default()
    }
    .with_scan(&world, pose, 23);
    (world, overlay)
}

#[test]
fn png_decodes_with_the_expected_size_and_colours() {
    let (world, overlay) = scene();
    let bytes = png(&world, &overlay, &RenderOptions::default()).expect("png");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let img = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
        .expect("decodes")
        .to_rgb8();
    assert_eq!((img.width(), img.height()), (200, 120));
    // The vending machine's centre pixel is its red; a wall pixel is dark.
    let px = |x: f64, y: f64| {
        img.get_pixel((x / 0.05) as u32, ((6.0 - y) / 0.05) as u32)
            .0
    };
    assert_eq!(px(7.0, 2.0), [220, 0, 0]);
    assert_eq!(px(0.01, 3.0), [30, 30, 30]);
    assert_eq!(overlay.beams.len(), 23);
    // A segment in its own colour, in free space away from the beams.
    let with_edge = Overlay {
        segments: vec![sim::render::Segment {
            from: (8.5, 1.0),
            to: (9.5, 1.0),
            rgb: [1, 2, 3],
        }],
        ..overlay.clone()
    };
    let img = image::load_from_memory(&png(&world, &with_edge, &RenderOptions::default()).unwrap())
        .unwrap()
        .to_rgb8();
    assert_eq!(
        img.get_pixel((9.0 / 0.05) as u32, ((6.0 - 1.0) / 0.05) as u32)
            .0,
        [1, 2, 3]
    );
    let text = svg(&world, &with_edge, &RenderOptions::default()).unwrap();
    assert!(
        text.contains(r##"stroke="#010203""##),
        "the segment in the SVG"
    );
    // Scaled down to fit.
    let small = png(
        &world,
        &overlay,
        &RenderOptions {
            pixels_per_metre: Some(100.0),
            max_side: 100,
        },
    )
    .expect("png");
    let img = image::load_from_memory(&small).expect("decodes");
    assert!(img.width() <= 100 && img.height() <= 100);
    assert!(
        png(
            &world,
            &overlay,
            &RenderOptions {
                pixels_per_metre: Some(-1.0),
                max_side: 10
            }
        )
        .is_err()
    );
}

#[test]
fn svg_is_well_formed_and_names_objects() {
    let (world, overlay) = scene();
    let text = svg(&world, &overlay, &RenderOptions::default()).expect("svg");
    let doc = roxmltree::Document::parse(&text).expect("well-formed XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "svg");
    assert!(
        text.contains("vending&lt;1&gt;"),
        "escaped identifier as a tooltip"
    );
    assert!(text.contains("#dc0000"), "the placeholder's colour");
    let lines = doc.descendants().filter(|n| n.has_tag_name("line")).count();
    assert!(lines >= 23, "{lines} lines");
    // Wall rectangles are merged: a ring of cells needs only a few.
    let rects = doc.descendants().filter(|n| n.has_tag_name("rect")).count();
    assert!(rects < 10, "{rects} rects");
}
